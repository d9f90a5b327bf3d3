// ice-coarsen: ICE-coarsen a triangle mesh and write the coarse intrinsic mesh, the prolongation
// matrix, the fine-to-coarse map and an extrinsic preview.
//
// Outputs (in OUTDIR, created if needed; existing files are only replaced with --force):
//
//  coarse.ilm — the coarse intrinsic mesh, plain text ("ICE intrinsic mesh", version 2; the format
//    is documented, written and read by ice/intrinsic_mesh_io.h): the counts, one line per face
//    (corners, the three edge lengths in the FaceLengths convention, the three twins saying how the
//    faces are glued: the mesh is a Δ-complex, so connectivity cannot be taken from vertex pairs), and
//    one line per coarse vertex naming its input vertex (-1: inserted by --refine-angle). Lengths
//    are printed in the shortest form that reads back to the same double.
//  prolongation.mtx — P in Matrix Market "coordinate real general" form (1-based), rows = input
//    vertices, columns = coarse vertices; rows sum to 1, at most 3 entries per row (scipy.io.mmread).
//  map.csv — input_vertex,coarse_vertex,coarse_face,b0,b1,b2: where every input vertex lies on the
//    coarse mesh. coarse_vertex is -1 for removed vertices; coarse_face is a coarse face containing
//    the point and b0..b2 its barycentric coordinates w.r.t. that face's corners (for a surviving
//    vertex: a face around it, with 1 at its corner).
//  preview.obj — the coarse faces drawn with the surviving vertices' input positions. Only a preview:
//    the coarse mesh is intrinsic (its lengths are not distances between those positions).
//  coarse_edges.obj (with --trace, ICE only) — the coarse edges traced on the input surface
//    (ice/coarse_tracing.h): one OBJ polyline ("l") per traced edge, its points on the input
//    triangles; edges that could not be traced are listed in a comment. Open it with the input mesh
//    (MeshLab, Blender, ParaView) to see the coarse mesh as the intrinsic method made it.
//
// Exit codes: see app_common.h (0 ok, 1 unreadable input, 2 defective mesh, 3 output not written,
// 4 bad command line, 5 computation failed, e.g. --validate found a problem).
#include <array>
#include <map>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <iostream>
#include <optional>

#include "tool_main.h"
#include "app_common.h"
#include "ice/coarse_tracing.h"
#include "ice/coarsen.h"
#include "ice/intrinsic_mesh_io.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/large_array.h"
#include "ice/mesh_io.h"
#include "ice/prolongation.h"
#include "ice/proxy/setup.h"
#include "ice/qem.h"

namespace ice_coarsen_tool {

const std::string kTool = "ice-coarsen";
namespace fs = std::filesystem;

// Shortest text that reads back to the same double.
struct Num {
  double value;
};
std::ostream& operator<<(std::ostream& out, Num x) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x.value);
  return out.write(buffer, result.ptr - buffer);
}

void check_stream(std::ofstream& out, const std::string& path) {
  out.flush();
  if (!out) throw app::AppError(app::kNotWritten, path + ": write failed");
}

std::ofstream open_output(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw app::AppError(app::kNotWritten, path + ": cannot be opened for writing");
  return out;
}

void write_matrix_market(const std::string& path, Eigen::SparseMatrix<double> P) {
  P.makeCompressed();
  std::ofstream out = open_output(path);
  out << "%%MatrixMarket matrix coordinate real general\n"
      << "% ICE prolongation: rows = input vertices, columns = coarse vertices (1-based); rows sum to 1\n"
      << P.rows() << ' ' << P.cols() << ' ' << P.nonZeros() << '\n';
  for (Eigen::Index c = 0; c < P.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(P, c); it; ++it)
      out << it.row() + 1 << ' ' << c + 1 << ' ' << Num{it.value()} << '\n';
  check_stream(out, path);
}

void write_map(const std::string& path, const std::vector<ice::CoarsePoint>& map) {
  std::ofstream out = open_output(path);
  out << "input_vertex,coarse_vertex,coarse_face,b0,b1,b2\n";
  for (std::size_t p = 0; p < map.size(); ++p) {
    const ice::CoarsePoint& q = map[p];
    out << p << ',' << q.coarse_vertex << ',' << q.face << ',' << Num{q.bary[0]} << ',' << Num{q.bary[1]} << ','
        << Num{q.bary[2]} << '\n';
  }
  check_stream(out, path);
}

void write_preview(const std::string& path, const ice::TriangleMesh& mesh, const ice::CoarseSpace& space) {
  const ice::CompactMesh& coarse = space.mesh;
  std::ofstream out = open_output(path);
  out << "# EXTRINSIC PREVIEW ONLY of an intrinsic coarse mesh (ice-coarsen): the surviving vertices at their input "
         "positions (vertices inserted by refinement at their points of the input surface), joined by the coarse "
         "faces; the true coarse geometry is the edge lengths in coarse.ilm\n";
  out.precision(17);
  const ice::Positions positions = ice::coarse_vertex_positions(mesh, space);
  for (Eigen::Index v = 0; v < positions.rows(); ++v)
    out << "v " << Num{positions(v, 0)} << ' ' << Num{positions(v, 1)} << ' ' << Num{positions(v, 2)} << '\n';
  for (Eigen::Index f = 0; f < coarse.F.rows(); ++f)
    out << "f " << coarse.F(f, 0) + 1 << ' ' << coarse.F(f, 1) + 1 << ' ' << coarse.F(f, 2) + 1 << '\n';
  check_stream(out, path);
}

// coarse_edges.obj: the traced coarse edges as polylines on the input surface.
ice::CoarseTracing write_traced_edges(const std::string& path, const ice::TriangleMesh& mesh, const ice::CoarseSpace& space) {
  const ice::CoarseTracing tracing = ice::trace_coarse_mesh(mesh, space);
  std::ofstream out = open_output(path);
  out << "# coarse edges of an intrinsic coarse mesh traced on its input surface (ice-coarsen --trace): one polyline "
         "per edge, from its tail to its head coarse vertex\n"
      << "# " << tracing.traced << " of " << tracing.edges.size() << " edges traced\n";
  for (const ice::TracedEdge& edge : tracing.edges)
    if (edge.status != ice::TraceStatus::traced)
      out << "# not traced: edge " << edge.tail << " -> " << edge.head << " (" << ice::to_string(edge.status) << ")\n";
  long long next = 1;
  for (const ice::TracedEdge& edge : tracing.edges) {
    if (edge.status != ice::TraceStatus::traced) continue;
    const ice::Positions points = ice::traced_polyline(mesh.V, mesh.F, edge);
    for (Eigen::Index i = 0; i < points.rows(); ++i)
      out << "v " << Num{points(i, 0)} << ' ' << Num{points(i, 1)} << ' ' << Num{points(i, 2)} << '\n';
    out << 'l';
    for (Eigen::Index i = 0; i < points.rows(); ++i) out << ' ' << next + i;
    out << '\n';
    next += points.rows();
  }
  check_stream(out, path);
  return tracing;
}

// preview.obj of a QEM coarsening: the QEM mesh itself (its positions, the survivors' input
// positions, are its geometry).
void write_qem_preview(const std::string& path, const ice::TriangleMesh& mesh, const ice::CoarseSpace& space) {
  std::ofstream out = open_output(path);
  out << "# QEM mesh (ice-coarsen --method qem): extrinsic, these positions are its geometry\n";
  const ice::Positions positions = ice::coarse_vertex_positions(mesh, space);
  for (Eigen::Index v = 0; v < positions.rows(); ++v)
    out << "v " << Num{positions(v, 0)} << ' ' << Num{positions(v, 1)} << ' ' << Num{positions(v, 2)} << '\n';
  const ice::Faces& F = space.mesh.F;
  for (Eigen::Index f = 0; f < F.rows(); ++f) out << "f " << F(f, 0) + 1 << ' ' << F(f, 1) + 1 << ' ' << F(f, 2) + 1 << '\n';
  check_stream(out, path);
}

// --validate for QEM: the prolongation's invariants and the map's faces.
std::string validate_qem(const ice::QemResult& qem, const Eigen::SparseMatrix<double>& P) {
  std::string problems;
  Eigen::SparseMatrix<double, Eigen::RowMajor> R = P;
  for (Eigen::Index i = 0; i < R.rows() && problems.size() < 2000; ++i) {
    double sum = 0;
    int nnz = 0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(R, i); it; ++it, ++nnz) {
      sum += it.value();
      if (!(it.value() >= 0 && it.value() <= 1)) problems += "P(" + std::to_string(i) + ",.) outside [0, 1]\n";
    }
    if (std::abs(sum - 1) > 1e-12 || nnz > 3 || nnz == 0)
      problems += "row " + std::to_string(i) + " of P: sum " + std::to_string(sum) + ", " + std::to_string(nnz) + " entries\n";
  }
  for (const ice::QemPoint& q : qem.map)
    if (q.face < 0 || q.face >= qem.coarse.F.rows()) {
      problems += "a map entry has no face\n";
      break;
    }
  return problems;
}

// "target_reached after 1,234 removals (5 failed attempts); last cost …, next cost …", or for QEM
// "target_reached after 1,234 QEM collapses".
std::string stop_line(const ice::CoarseSpaceSummary& summary) {
  std::ostringstream line;
  line << ice::to_string(summary.stop_reason()) << " after " << app::thousands(summary.removed());
  if (summary.qem) return line.str() + " QEM collapses";
  const ice::CoarsenResult& r = *summary.ice;
  line << " removals (" << r.failed_removals << " failed attempts); last cost " << r.last_cost << ", next cost ";
  // +inf: no vertex is left that could be removed; NaN: cancelled during the parallel phase.
  if (std::isinf(r.next_cost)) line << "none (no removable vertex left)";
  else if (std::isnan(r.next_cost)) line << "unknown (cancelled)";
  else line << r.next_cost;
  return line.str();
}

std::vector<ice::Index> read_lock_file(const std::string& path, const ice::LoadResult& loaded) {
  std::vector<ice::Index> locked;
  const app::FileVertexMap vertices(loaded);
  for (double x : app::read_number_file(path)) {
    if (x != std::floor(x)) throw app::AppError(app::kUnreadable, path + ": '" + std::to_string(x) + "' is not a vertex index");
    locked.push_back(vertices.mesh_vertex(x, "--lock: vertex"));
  }
  return locked;
}

}  // namespace ice_coarsen_tool

int ice_coarsen_tool::main(int argc, char** argv) {
  ice::keep_freed_memory_for_reuse();  // one job per process: reuse freed arrays instead of re-faulting them
  CLI::App cli{
      "ice-coarsen: simplify a triangle mesh intrinsically (ICE). Vertices are removed from an intrinsic "
      "triangulation of the input,\ncheapest first by the intrinsic curvature error, so the coarse mesh keeps "
      "the input surface's metric and every input\nvertex keeps a location on it. Writes OUTDIR/coarse.ilm "
      "(coarse faces + edge lengths), prolongation.mtx (input x coarse\nmatrix), map.csv (where each input "
      "vertex lies) and preview.obj (an extrinsic preview).\n\n"
      "Examples:\n  ice-coarsen spot.obj --vertices 500 -o spot_500\n"
      "  ice-coarsen bunny.off --ratio 0.05 --keep-boundary -o out --report out/report.json\n\n"
      "Exit status: 0 ok, 1 unreadable input, 2 defective mesh, 3 output not written, 4 bad command line, "
      "5 computation failed."};
  std::string input, outdir, report_path, lock_path;
  app::TargetOptions target;
  bool keep_boundary = false, quiet = false, force = false, repair = false, validate = false, trace = false;
  cli.add_option("mesh", input, "Input mesh (.obj, .off, .ply, .stl)")->required();
  target.add_to(cli, true);
  cli.add_flag("--keep-boundary", keep_boundary, "Never remove boundary vertices");
  cli.add_option("--lock", lock_path, "File of vertex indices (0-based, whitespace/comma separated, # comments) never removed");
  cli.add_option("--output,-o", outdir, "Output directory (created if needed)")->required();
  cli.add_option("--report", report_path, "Also write a JSON report (sizes, stop reason, costs, timings, memory)");
  cli.add_flag("--quiet,-q", quiet, "No progress bar");
  cli.add_flag("--force", force, "Overwrite existing output files");
  cli.add_flag("--trace", trace,
               "Also write coarse_edges.obj: the coarse edges traced on the input surface as polylines (ICE only)");
  cli.add_flag("--repair", repair, "Apply the safe mesh repairs before coarsening (see ice-info --repair)");
  cli.add_flag("--validate", validate, "Check every invariant of the coarse triangulation afterwards (fails loudly)");
  app::CacheOptions cache;
  cache.add_to(cli);
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&] {
    std::vector<std::string> names{"coarse.ilm", "prolongation.mtx", "map.csv", "preview.obj"};
    if (trace) {
      if (target.method == ice::CoarseningMethod::qem)
        throw app::AppError(app::kUsage, "--trace draws ICE's intrinsic edges on the input surface; a QEM mesh has "
                                         "positions of its own (preview.obj)");
      names.push_back("coarse_edges.obj");
    }
    std::vector<std::string> outputs;
    for (const auto& name : names) outputs.push_back((fs::path(outdir) / name).string());
    std::error_code ec;
    if (fs::exists(outdir, ec) && !fs::is_directory(outdir, ec))
      throw app::AppError(app::kNotWritten, "--output " + outdir + ": exists and is not a directory");
    for (const auto& path : outputs)
      if (fs::is_directory(outdir, ec)) app::check_output(path, force, "--output");  // else made below
    if (!report_path.empty()) app::check_output(report_path, force, "--report");

    app::Stopwatch clock;
    const ice::LoadResult loaded = app::load_input_mesh(input, repair);
    const ice::TriangleMesh& mesh = loaded.mesh;
    const long long n = mesh.V.rows();
    ice::CoarsenOptions options;
    target.apply(options, n);
    options.remove_boundary = !keep_boundary;
    if (!lock_path.empty()) options.locked_vertices = read_lock_file(lock_path, loaded);
    const double t_load = clock.lap();

    // ICE, or the QEM baseline (--method qem): same outputs, from the QEM mesh (extrinsic lengths in
    // coarse.ilm, the closest-point map in map.csv, the QEM mesh itself as preview.obj).
    const bool qem = target.method == ice::CoarseningMethod::qem;
    ice::CoarseSpaceOptions space_options;
    space_options.method = target.method;
    space_options.coarsen = options;
    space_options.refinement = target.refinement();
    // --validate reads the method's state, --trace its history: neither is stored, so both bypass the store.
    space_options.keep_method_state = validate || trace;
    space_options.record_history = trace;  // --trace draws the coarse edges exactly from it
    ice::proxy::MappedSpaceOptions mapped_options;
    mapped_options.coarsening = space_options;
    mapped_options.store = cache.store();
    mapped_options.builder = [quiet](const ice::TriangleMesh& m, const ice::CoarseSpaceOptions& o, ice::FineMesh*) {
      return app::build_coarse_space_with_progress(m, o, !quiet);
    };
    const ice::proxy::MappedSpace mapped = ice::proxy::build_mapped_space(mesh, mapped_options);
    const ice::proxy::CacheReport& stored = mapped.cache;
    if (stored.status == ice::proxy::CacheStatus::rebuilt)
      app::warn(kTool, "the stored coarse space was damaged and is rebuilt: " + stored.damage);
    const ice::CoarseSpace& space = mapped.coarse;
    const ice::CoarseSpaceSummary& summary = space.summary;
    const ice::CompactMesh& coarse = space.mesh;
    const double t_coarsen = clock.lap() - stored.load_seconds - stored.save_seconds;
    app::warn_if_target_missed(kTool, summary, options);
    if (validate) {
      const std::string problems = qem ? validate_qem(*space.qem_result, space.P) : space.triangulation->validate();
      if (!problems.empty())
        throw app::AppError(app::kFailed, "--validate: the coarse triangulation is INVALID (nothing written):\n" + problems);
    }
    const double t_validate = validate ? clock.lap() : 0.0;

    fs::create_directories(outdir, ec);
    if (ec) throw app::AppError(app::kNotWritten, "--output " + outdir + ": cannot create the directory: " + ec.message());
    ice::write_intrinsic_mesh(outputs[0], coarse, static_cast<ice::Index>(n),
                              std::string(qem ? "QEM" : "intrinsic") + " mesh written by ice-coarsen from " + input);
    write_matrix_market(outputs[1], space.P);
    write_map(outputs[2], mapped.map);
    if (qem)
      write_qem_preview(outputs[3], mesh, space);
    else
      write_preview(outputs[3], mesh, space);
    const double t_write = clock.lap();
    std::optional<ice::CoarseTracing> tracing;
    if (trace) tracing = write_traced_edges(outputs[4], mesh, space);
    const double t_trace = trace ? clock.lap() : 0.0;

    const bool hit = stored.status == ice::proxy::CacheStatus::hit;
    const double rate = hit ? 0.0 : summary.removed() / std::max(t_coarsen, 1e-9);
    if (!report_path.empty()) {
      nlohmann::json report = app::report_header(kTool, input);
      report["input"] = {{"vertices", n}, {"faces", mesh.F.rows()}};
      report["options"] = {{"method", ice::proxy::spelling(target.method)},
                           {"target_vertices", options.target_vertices},
                           {"target_ratio", options.target_ratio},
                           {"max_error", std::isfinite(options.max_error) ? nlohmann::json(options.max_error) : nlohmann::json(nullptr)},
                           {"area_weight", options.area_weight},
                           {"normalize_curvature", options.normalize_curvature},
                           {"coarsen_threads", options.threads},
                           // the regions that ran: 1 when no parallel phase did (small mesh, target, QEM)
                           {"coarsen_regions", summary.ice && summary.ice->parallel_removed > 0 ? ice::coarsening_regions(options) : 1},
                           {"keep_boundary", keep_boundary},
                           {"locked_vertices", options.locked_vertices.size()}};
      report["coarse"] = ice::proxy::coarsen_json(summary);
      if (qem) report["qem"] = ice::proxy::qem_json(*summary.qem, summary.target_reached);
      report["timings_s"] = {{"load", t_load}, {"coarsen", t_coarsen}, {"write", t_write},
                             {"cache_load", stored.load_seconds}, {"cache_save", stored.save_seconds}};
      report["cache"] = ice::proxy::cache_json(stored, mapped_options.store);
      if (validate) report["timings_s"]["validate"] = t_validate;
      if (tracing) {
        std::map<std::string, long long> untraced;
        for (const ice::TracedEdge& edge : tracing->edges)
          if (edge.status != ice::TraceStatus::traced) ++untraced[ice::to_string(edge.status)];
        report["trace"] = {{"edges", tracing->edges.size()},
                           {"traced", tracing->traced},
                           {"untraced", untraced},
                           {"length_ratio_min", tracing->length_ratio_min},
                           {"length_ratio_max", tracing->length_ratio_max}};
        report["timings_s"]["trace"] = t_trace;
      }
      report["removals_per_second"] = rate;
      report["validated"] = validate;
      report["outputs"] = outputs;
      report["peak_rss_mb"] = app::peak_rss_mb();
      app::write_json_file(report_path, report, force);
    }

    const long long nc = static_cast<long long>(coarse.to_input.size());
    std::cout << kTool << ": " << input << ": " << app::thousands(n) << " vertices, " << app::thousands(mesh.F.rows())
              << " faces -> " << app::thousands(nc) << " vertices, " << app::thousands(coarse.F.rows()) << " faces ("
              << app::percent(double(nc) / double(n)) << " of the vertices)\n"
              << "  stop: " << stop_line(summary) << '\n'
              << (summary.refinement ? "  refine: " + app::refinement_line(summary) + "\n" : std::string())
              << "  time: load " << app::fixed(t_load, 3) << " s, "
              << (hit ? "coarse space and map from the store " + app::fixed(stored.load_seconds, 3) + " s (nothing coarsened), "
                      : "coarsen " + app::fixed(t_coarsen, 3) + " s (" + app::thousands(static_cast<long long>(rate)) +
                            " removals/s), ")
              << (validate ? "validate " + app::fixed(t_validate, 3) + " s (ok), " : std::string())
              << "write " << app::fixed(t_write, 3) << " s; peak memory " << app::fixed(app::peak_rss_mb(), 0) << " MiB\n"
              << (tracing ? "  trace: " + app::thousands(tracing->traced) + " of " +
                                app::thousands(static_cast<long long>(tracing->edges.size())) +
                                " coarse edges traced on the input surface in " + app::fixed(t_trace, 3) + " s\n"
                          : std::string())
              << "  wrote " << (fs::path(outdir) / (trace ? "{coarse.ilm, prolongation.mtx, map.csv, preview.obj, coarse_edges.obj}"
                                                        : "{coarse.ilm, prolongation.mtx, map.csv, preview.obj}")).string()
              << (report_path.empty() ? "" : " and " + report_path) << '\n';
    return app::kOk;
  });
}
