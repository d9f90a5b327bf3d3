#include "app_common.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <new>
#include <sstream>

#include "fem/curvature_correction.h"
#include "fem/topology.h"
#include "ice/prolongation.h"
#include "view_page.h"

namespace app {

namespace fs = std::filesystem;

// ---- input ------------------------------------------------------------------------------------------

ice::LoadResult load_input_mesh(const std::string& path, bool repair) {
  ice::LoadOptions options;
  options.repair = repair;
  return load_input_mesh(path, options);
}

ice::LoadResult load_input_mesh(const std::string& path, const ice::LoadOptions& options) {
  ice::LoadResult loaded = ice::load_mesh_with_report(path, options);
  // The tools work on the mesh; the raw soup (a second copy of the positions and the faces, 100 MB
  // at 1.6M vertices) would only raise their peak memory. Its vertex count stays in input_report.
  loaded.file.soup = ice::PolygonSoup{};
  return loaded;
}

FileVertexMap::FileVertexMap(const ice::LoadResult& loaded)
    : mesh_of_file_(loaded.input_report.n_vertices, -1) {
  for (std::size_t i = loaded.source_vertex.size(); i-- > 0;)  // backwards: the first mesh vertex wins
    mesh_of_file_[static_cast<std::size_t>(loaded.source_vertex[i])] = static_cast<int>(i);
}

int FileVertexMap::mesh_vertex(long long file_vertex, const std::string& what) const {
  const auto n_file = static_cast<long long>(mesh_of_file_.size());
  if (file_vertex < 0 || file_vertex >= n_file)
    throw AppError(kUsage, what + " " + std::to_string(file_vertex) + " is out of range: the mesh has " +
                               thousands(n_file) + " vertices (valid: 0.." + std::to_string(n_file - 1) + ")");
  const int v = mesh_of_file_[static_cast<std::size_t>(file_vertex)];
  if (v < 0)
    throw AppError(kUsage, what + " " + std::to_string(file_vertex) + " was removed by --repair (unreferenced or welded)");
  return v;
}

int FileVertexMap::find(double file_vertex) const {
  if (!(file_vertex >= 0 && file_vertex < static_cast<double>(mesh_of_file_.size()))) return -1;
  return mesh_of_file_[static_cast<std::size_t>(file_vertex)];
}

int FileVertexMap::mesh_vertex(double file_vertex, const std::string& what) const {
  const auto n_file = static_cast<long long>(mesh_of_file_.size());
  if (!(std::abs(file_vertex) < 9.0e15))  // beyond, the conversion to long long is undefined
    throw AppError(kUsage, what + " " + fixed(file_vertex, 0) + " is out of range: the mesh has " + thousands(n_file) +
                               " vertices (valid: 0.." + std::to_string(n_file - 1) + ")");
  return mesh_vertex(static_cast<long long>(file_vertex), what);
}

std::vector<double> read_number_file(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw AppError(kUnreadable, path + ": no such file");
  std::ifstream in(path);
  if (!in) throw AppError(kUnreadable, path + ": cannot be opened");
  std::vector<double> values;
  std::string line;
  long long line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    for (char& c : line)
      if (c == ',' || c == ';' || c == '\t' || c == '\r') c = ' ';
    std::istringstream tokens(line);
    std::string token;
    while (tokens >> token) {
      std::size_t used = 0;
      double value = 0;
      try {
        value = std::stod(token, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != token.size() || !std::isfinite(value))
        throw AppError(kUnreadable, path + ":" + std::to_string(line_number) + ": '" + token + "' is not a finite number");
      values.push_back(value);
    }
  }
  if (in.bad()) throw AppError(kUnreadable, path + ": read error");
  return values;
}

void require_fixed_in_every_component(const ice::LoadResult& loaded, const std::vector<int>& fixed_vertices,
                                      const std::string& path) {
  if (fixed_vertices.empty() || loaded.report.components.size() <= 1) return;
  const ice::TriangleMesh& mesh = loaded.mesh;
  const fem::ComponentLabels components = fem::vertex_components(mesh.F, static_cast<fem::Index>(mesh.V.rows()));
  const std::vector<char> held = fem::components_holding(components, fixed_vertices);
  std::vector<char> has_face(held.size(), 0);  // vertices no face uses are components of their own
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) has_face[static_cast<std::size_t>(components.label[static_cast<std::size_t>(mesh.F(f, 0))])] = 1;
  for (std::size_t c = 0; c < held.size(); ++c)
    if (has_face[c] && !held[c]) {
      const auto v = static_cast<std::size_t>(components.first[c]);
      const long long file_vertex = v < loaded.source_vertex.size() ? loaded.source_vertex[v] : static_cast<long long>(v);
      throw AppError(kUsage, path + ": the mesh has " + std::to_string(loaded.report.components.size()) +
                                 " connected components and the one of vertex " + std::to_string(file_vertex) +
                                 " has no --fix vertex: fix a value in every component, or none (the zero-mean "
                                 "problem, solved on each component)");
    }
}

// ---- coarsening -------------------------------------------------------------------------------------

namespace {
// `build` of `options` with a progress bar over the removals from `start_vertices`.
template <class Build>
ice::CoarseSpace with_progress_bar(ice::Index start_vertices, ice::CoarseSpaceOptions options, bool show_progress, Build&& build) {
  ProgressBar bar("coarsening", show_progress && stderr_is_terminal());  // QEM reports no progress: nothing drawn
  options.coarsen.progress_interval = 250;
  options.coarsen.progress = [&bar, clock = Stopwatch(), start_vertices](const ice::CoarsenProgress& p) {
    const double total = std::max<double>(1, start_vertices - p.target);
    const double rate = p.removed / std::max(1e-9, clock.seconds());
    bar.update(p.removed / total, thousands(p.vertices) + " -> " + thousands(p.target) + " vertices, " +
                                      thousands(static_cast<long long>(rate)) + " removals/s");
    return true;
  };
  ice::CoarseSpace space = build(options);
  bar.finish();
  return space;
}
}  // namespace

ice::CoarseSpace build_coarse_space_with_progress(const ice::TriangleMesh& mesh, ice::CoarseSpaceOptions options,
                                                 bool show_progress, ice::FineMesh* fine_delaunay) {
  return with_progress_bar(static_cast<ice::Index>(mesh.V.rows()), std::move(options), show_progress,
                           [&](const ice::CoarseSpaceOptions& o) { return ice::build_coarse_space(mesh, o, fine_delaunay); });
}

void warn_if_target_missed(const std::string& tool, const ice::CoarseSpaceSummary& summary,
                           const ice::CoarsenOptions& options) {
  if (summary.qem) {
    if (!summary.target_reached)
      warn(tool, "QEM stopped at " + thousands(summary.coarse_vertices) + " vertices: no further collapse is legal");
    return;
  }
  const ice::CoarsenResult& result = *summary.ice;
  // On a tufted cover the coarsener counts the cover's copies; the coarse vertices are the merged ones.
  const std::string where = summary.tufted_cover ? thousands(summary.coarse_vertices) + " vertices (" +
                                                       thousands(result.output_vertices) + " on the tufted cover)"
                                                 : thousands(result.output_vertices) + " vertices";
  if (result.stop_reason == ice::StopReason::NothingRemovable)
    warn(tool, "stopped at " + where + ": no further vertex could be removed (locked, boundary kept, or topology)");
  else if (result.stop_reason == ice::StopReason::ErrorThreshold && (options.target_vertices > 0 || options.target_ratio > 0))
    warn(tool, "stopped at " + where + ": the next removal would cost " + std::to_string(result.next_cost) + " > --max-error");
}

namespace {
ice::CoarseSpaceOptions pde_space_options(const ice::CoarsenOptions& options, const PdeOptions& opt, bool keep_method_state,
                                          bool record_history) {
  ice::CoarseSpaceOptions space_options;
  space_options.keep_method_state = keep_method_state;
  space_options.record_history = record_history;
  space_options.method = opt.target.method;
  space_options.qem_geometry = opt.qem_geometry;
  space_options.nonmanifold = opt.nonmanifold;
  space_options.coarsen = options;
  space_options.refinement = opt.target.refinement();
  return space_options;
}
}  // namespace

namespace {
// ice::build_coarse_space of `space_options` for a PDE tool: a progress bar, the --qem-operators idt
// failure named, a warning if the target was missed, the summary recorded in `run`.
ice::CoarseSpace coarsen_space_for_pde(const ice::TriangleMesh& mesh, const ice::CoarseSpaceOptions& space_options,
                                       const PdeOptions& opt, PdeRun& run, ice::FineMesh* fine_delaunay) {
  ice::CoarseSpace space;
  try {
    space = build_coarse_space_with_progress(mesh, space_options, !opt.quiet, fine_delaunay);
  } catch (const std::runtime_error& e) {
    if (opt.qem_geometry == ice::QemGeometry::intrinsic_delaunay && opt.target.method == ice::CoarseningMethod::qem)
      throw AppError(kFailed, std::string("--qem-operators idt: ") + e.what());
    throw;
  }
  warn_if_target_missed(run.tool, space.summary, space_options.coarsen);
  run.coarsening = space.summary;
  return space;
}
}  // namespace

ice::CoarseSpace coarsen_for_pde(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                 PdeRun& run, bool keep_method_state, bool record_history) {
  return coarsen_space_for_pde(mesh, pde_space_options(options, opt, keep_method_state, record_history), opt, run, nullptr);
}

ice::CoarseSpace coarsen_copies_for_pde(const ice::TuftedCover& cover, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                        PdeRun& run) {
  const ice::CoarseSpaceOptions space_options = pde_space_options(options, opt, /*keep_method_state=*/true, false);
  ice::CoarseSpace space;
  try {
    space = with_progress_bar(static_cast<ice::Index>(cover.to_input.size()), space_options, !opt.quiet,
                              [&](const ice::CoarseSpaceOptions& o) { return ice::build_coarse_space_on_copies(cover, o); });
  } catch (const std::invalid_argument& e) {  // QEM or refinement asked of a cover
    throw AppError(kUsage, opt.mesh + ": " + e.what());
  }
  // Counted as the other tools count a cover: the input vertices that keep a coarse copy, of the input's.
  ice::CoarseSpaceSummary summary = space.summary;
  std::vector<char> kept(static_cast<std::size_t>(cover.input_vertex_count), 0);
  for (ice::Index copy : space.mesh.to_input) kept[static_cast<std::size_t>(cover.to_input[static_cast<std::size_t>(copy)])] = 1;
  summary.coarse_vertices = static_cast<ice::Index>(std::count(kept.begin(), kept.end(), 1));
  summary.input_vertices = cover.input_vertex_count;
  summary.tufted_cover = true;
  warn_if_target_missed(run.tool, summary, space_options.coarsen);
  run.coarsening = summary;
  run.tufted_cover = true;
  return space;
}

ice::proxy::MultigridHierarchy stored_hierarchy(const std::string& tool, const ice::TriangleMesh& mesh, const MultigridCli& mg,
                                                const PdeOptions& opt, const ice::proxy::Store& store) {
  ice::HierarchyOptions options = mg.hierarchy;
  options.nonmanifold = opt.nonmanifold;
  ice::proxy::MultigridHierarchy hierarchy = ice::proxy::multigrid_hierarchy(mesh, options, store);
  if (hierarchy.cache.status == ice::proxy::CacheStatus::rebuilt)
    warn(tool, "the stored hierarchy was damaged and is rebuilt: " + hierarchy.cache.damage);
  return hierarchy;
}

ice::proxy::ProxySetup build_pde_proxy(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                       PdeRun& run, Stopwatch& clock, bool assemble_proxy, bool need_fine,
                                       bool keep_method_state, const ice::proxy::Store& store) {
  // An output file draws the coarse mesh on the surface (write_result_fields) exactly: ICE's state is
  // kept with its history for it. Traced lengths (keep_method_state) need the state alone (the walk).
  // The store holds coarse spaces without the method's state: such runs set up from scratch.
  // A mesh solved on its tufted cover: the coarse mesh is the cover's, which no output draws.
  const bool covered = ice::solved_on_tufted_cover(mesh, opt.nonmanifold);
  const bool drawn = outputs_draw_coarse_mesh(opt, covered);
  ice::proxy::ProxySetupOptions setup_options;
  setup_options.coarsening = pde_space_options(options, opt, keep_method_state || drawn, drawn);
  // Decided here once: a manifold mesh is not checked again below.
  setup_options.coarsening.nonmanifold = covered ? ice::NonmanifoldInput::tufted_cover : ice::NonmanifoldInput::refuse;
  setup_options.fine = opt.fine_geometry();
  setup_options.operators = opt.operators;
  setup_options.prolongation = ice::proxy::prolongation_choice(opt.prolongation);
  setup_options.assemble = assemble_proxy;
  setup_options.need_fine_mesh = need_fine;
  setup_options.fine_operators = true;
  setup_options.restored_fine_mesh = [&mesh, geometry = opt.fine_geometry(),
                                       nonmanifold = setup_options.coarsening.nonmanifold](ice::IntrinsicMesh& fine) {
    fine = static_cast<ice::IntrinsicMesh&&>(ice::fine_mesh(mesh, geometry, nonmanifold));  // the tool's mesh outlives its proxy
  };
  setup_options.store = store;
  setup_options.builder = [&opt, &run](const ice::TriangleMesh& m, const ice::CoarseSpaceOptions& space_options,
                                       ice::FineMesh* fine_delaunay) {
    return coarsen_space_for_pde(m, space_options, opt, run, fine_delaunay);
  };
  ice::proxy::ProxySetup setup = ice::proxy::build_proxy_setup(mesh, setup_options);
  clock.lap();
  clock.rewind(setup.times.assemble);  // the assembly goes to the caller's next lap (its assemble phase)
  const bool hit = setup.cache.status == ice::proxy::CacheStatus::hit;
  if (setup.cache.status == ice::proxy::CacheStatus::rebuilt)
    warn(run.tool, "the stored setup was damaged and is rebuilt: " + setup.cache.damage);
  if (hit) warn_if_target_missed(run.tool, setup.coarse.summary, options);  // a build warns as it coarsens
  run.record_cache(setup.cache, store);
  run.coarsening = setup.coarse.summary;
  run.coarsen = setup.times.coarsen;  // a hit's load is run.cache.load_seconds
  run.fine_mesh = setup.times.fine_mesh;
  run.fine_built = need_fine || (assemble_proxy && !hit);
  if (hit) run.proxy_uses_fine_mesh = false;  // only the reference's, now
  run.idt_flips = setup.fine.flips;
  run.tufted_cover = covered;
  return setup;
}

ice::SurfaceEdgeLengths stored_marching_lengths(PdeRun& run, Stopwatch& clock, const ice::TriangleMesh& mesh,
                                               ice::proxy::MappedSpace& space, const ice::proxy::Store& store, bool traced,
                                               ice::proxy::CurvatureCorrection correction, double divisor) {
  const std::string damage_before = space.cache.damage;
  const double stored_before = space.cache.load_seconds + space.cache.save_seconds;
  ice::SurfaceEdgeLengths lengths =
      ice::proxy::stored_marching_lengths(mesh, space, store, traced, correction, divisor, &space.cache);
  if (space.cache.damage != damage_before)
    warn(run.tool, "stored marching lengths were damaged and are made again: " + space.cache.damage);
  // Their entries' load and save are the cache's, not the caller's phase.
  clock.rewind(stored_before - (space.cache.load_seconds + space.cache.save_seconds));
  run.record_cache(space.cache, store);
  // What a hit loaded: everything, or the space alone (its marching lengths made now and stored).
  run.stored_setup = space.cache.save_seconds > 0
                         ? "coarse space and map from the store (nothing coarsened; marching lengths made and stored)"
                         : "coarse space, map and marching lengths from the store (nothing coarsened or traced)";
  return lengths;
}

bool outputs_draw_coarse_mesh(const PdeOptions& opt, bool tufted_cover) {
  return (!opt.output.empty() || !opt.html.empty()) && opt.target.method == ice::CoarseningMethod::ice && !tufted_cover;
}

ice::proxy::MappedSpace mapped_space_for_pde(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options,
                                             const PdeOptions& opt, PdeRun& run, const ice::proxy::Store& store,
                                             bool need_map, bool record_history, ice::FineMesh* fine_delaunay) {
  ice::proxy::MappedSpaceOptions space_options;
  space_options.coarsening = pde_space_options(options, opt, record_history, record_history);
  space_options.store = store;
  space_options.builder = [&opt, &run](const ice::TriangleMesh& m, const ice::CoarseSpaceOptions& coarsening,
                                       ice::FineMesh* fine_delaunay) {
    return coarsen_space_for_pde(m, coarsening, opt, run, fine_delaunay);  // warns if the target was missed
  };
  ice::proxy::MappedSpace space;
  const Stopwatch clock;
  try {
    space = ice::proxy::build_mapped_space(mesh, space_options, fine_delaunay);
  } catch (const std::invalid_argument& e) {  // bad options
    throw AppError(kUsage, opt.mesh + ": " + e.what());
  }
  const double seconds = clock.seconds();
  if (need_map && space.map.empty())
    throw AppError(kUsage, opt.mesh + ": --qem-operators idt has no fine-to-coarse map onto its coarse mesh (its closest-point "
                                      "map lies in the QEM mesh's faces); use extrinsic");
  const bool hit = space.cache.status == ice::proxy::CacheStatus::hit;
  if (space.cache.status == ice::proxy::CacheStatus::rebuilt)
    warn(run.tool, "the stored coarse space was damaged and is rebuilt: " + space.cache.damage);
  if (hit) warn_if_target_missed(run.tool, space.coarse.summary, options);
  run.coarsening = space.coarse.summary;
  run.tufted_cover = space.coarse.summary.tufted_cover;
  // Coarsening and the map: 0 on a hit, whose load is run.cache.load_seconds; the fine mesh made on
  // the way is the caller's phase.
  run.coarsen = hit ? 0.0
                    : seconds - space.cache.load_seconds - space.cache.save_seconds - space.coarse.summary.fine_mesh_seconds;
  run.fine_mesh = space.coarse.summary.fine_mesh_seconds;
  run.stored_setup = "coarse space and map from the store (nothing coarsened)";
  run.record_cache(space.cache, store);
  return space;
}

void add_curvature_correction_option(CLI::App& cli, ice::proxy::CurvatureCorrection& correction) {
  add_choice(cli, "--curvature-correction", correction,
             choice_names<ice::proxy::CurvatureCorrection>(),
             "Coarse marching on lengths scaled by exp(K l^2/d), K the curvature each coarse face flattens "
             "('auto': ICE meshes, not covers)");
}

void add_coarse_lengths_option(CLI::App& cli, const std::string& name, ice::proxy::CoarseLengths& choice) {
  add_choice(cli, name, choice,
             choice_names<ice::proxy::CoarseLengths>(),
             "Marching on coarse edge lengths traced on the surface ('traced', ICE only) or the coarse mesh's "
             "own ('intrinsic': QEM, covers)");
}

std::optional<ice::CoarseTracing> trace_for_outputs(const PdeOptions& opt, const ice::TriangleMesh& mesh,
                                                    const ice::CoarseSpace& space) {
  if ((opt.output.empty() && opt.html.empty()) || !space.triangulation) return std::nullopt;
  return ice::trace_coarse_mesh(mesh, space);
}

void write_result_fields(const PdeOptions& opt, const ice::TriangleMesh& mesh, const std::string& name,
                         const Eigen::VectorXd& result, const Eigen::VectorXd& reference,
                         std::vector<ice::ScalarField> extra, const ice::CoarseTracing* tracing) {
  if (opt.output.empty()) return;
  std::vector<ice::ScalarField> fields{{name, result}};
  if (reference.size() != 0) {
    fields.push_back({"reference", reference});
    fields.push_back({"error", result - reference});
  }
  for (ice::ScalarField& field : extra) fields.push_back(std::move(field));
  const bool gltf = opt.output_is_gltf();
  std::vector<ice::Positions> lines;
  if (tracing) {
    fields.push_back({"patch", patch_values(*tracing)});
    for (const ice::TracedEdge& edge : tracing->edges)
      if (edge.status == ice::TraceStatus::traced) lines.push_back(ice::traced_polyline(mesh.V, mesh.F, edge));
    // PLY has no lines beside a mesh: they go to a companion file of points and edges.
    if (const std::string edges = opt.coarse_edges_output(); !gltf && !edges.empty())
      ice::write_ply_polylines(edges, lines, {opt.force, !opt.ascii});
  }
  if (gltf) {
    ice::GltfWriteOptions options;
    options.overwrite = opt.force;
    options.colour_field = reference.size() != 0 ? "error" : name;
    ice::write_gltf_with_fields(opt.output, mesh, fields, lines, options);
  } else {
    ice::write_ply_with_fields(opt.output, mesh, fields, {opt.force, !opt.ascii});
  }
}

void print_written(std::ostream& out, const PdeOptions& opt, const ice::CoarseTracing* tracing) {
  if (!opt.output.empty())
    out << "  wrote " << opt.output
        << (tracing ? " (patch labels; " + thousands(tracing->traced) + " of " +
                          thousands(static_cast<long long>(tracing->edges.size())) + " coarse edges traced on the surface" +
                          (opt.output_is_gltf() ? ", drawn as lines)" : ")")
                    : std::string())
        << '\n';
  if (tracing && !opt.output.empty() && !opt.coarse_edges_output().empty())
    out << "  wrote " << opt.coarse_edges_output() << " (the traced coarse edges as lines)\n";
  if (!opt.html.empty()) out << "  wrote " << opt.html << " (open it in a browser)\n";
  if (!opt.report.empty()) out << "  wrote " << opt.report << '\n';
}

void write_result_page(const PdeOptions& opt, const ice::TriangleMesh& mesh, const std::string& title,
                       const std::string& problem, const std::string& name, const Eigen::VectorXd& result,
                       const Eigen::VectorXd& reference, const ice::CoarseSpace& space,
                       const ice::CoarseTracing* tracing, const nlohmann::json& error_json, bool points) {
  if (opt.html.empty()) return;
  ViewMesh view = view_mesh(fs::path(opt.mesh).filename().string(), mesh, kDisplayVertices);
  view.points = points;
  view.fields.push_back(view_field(view, name, problem, "solution", "", result));
  const std::string method = space.summary.method == ice::CoarseningMethod::ice ? "ICE" : "QEM";
  if (reference.size() != 0) {
    view.fields.push_back(view_field(view, "reference (fine)", problem, "solution", "", reference));
    view.fields.push_back(view_field(view, "|error|", problem, "error", method, (result - reference).cwiseAbs()));
  }
  ViewMethod drawn = view_method(method, mesh, space, tracing);
  if (error_json.is_object() && error_json.contains("rel_l2") && error_json["rel_l2"].is_number())
    drawn.errors[problem] = error_json["rel_l2"].get<double>();
  if (tracing) view.fields.push_back(view_field(view, "patch", "", "label", method, patch_values(*tracing)));
  view.methods.push_back(std::move(drawn));
  write_view_page(opt.html, title, {view}, "", opt.force);
}

Eigen::VectorXd demo_poisson_rhs(const ice::TriangleMesh& mesh) {
  const Eigen::Index n = mesh.V.rows();
  const double sigma = 0.1 * (mesh.V.colwise().maxCoeff() - mesh.V.colwise().minCoeff()).norm();
  const double weights[3] = {1.0, -1.0, 1.0};
  Eigen::VectorXd f = Eigen::VectorXd::Zero(n);
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::Index centre = 0;
    mesh.V.col(axis).maxCoeff(&centre);
    const Eigen::RowVector3d c = mesh.V.row(centre);
    for (Eigen::Index i = 0; i < n; ++i)
      f(i) += weights[axis] * std::exp(-(mesh.V.row(i) - c).squaredNorm() / (2 * sigma * sigma));
  }
  return f;
}

Eigen::VectorXd remove_mean(const Eigen::VectorXd& f, const Eigen::SparseMatrix<double>& mass) {
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(f.size());
  const Eigen::VectorXd m1 = mass * ones;
  // The same reduction on both sides: a constant f has a mean of exactly that constant, and becomes 0.
  return f.array() - m1.dot(f) / m1.dot(ones);
}



}  // namespace app
