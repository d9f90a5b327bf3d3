// geodesic-coarse: geodesic distance on a mesh, solved on an ICE coarse proxy and carried to the
// input vertices; optionally compared with the heat method on the fine mesh.
//
// Pipeline (every phase timed apart): load → coarsen (ice::build_coarse_space: ICE from the input's
// intrinsic triangulation, or QEM; includes the coarse mesh and the prolongation P) → fine mesh
// (ice::fine_mesh: the reference's discretisation, intrinsic Delaunay by default) → assemble
// (fem::CoarseProxy; with --coarse-distances heat the coarse heat-method operators) → factor
// (fem::ProxyGeodesicSolver: the marching's mesh, or the heat method's factorisations) → solve and
// prolong, timed by the solver: by default fast marching on the coarse mesh from the sources'
// points and the squared distance interpolated to the input vertices; with the heat method, its
// solve from the restricted sources Pᵀ e_s and P φ_c shifted to vanish on average at the sources
// (the heat step uses the lumped coarse mass, which matters for Galerkin operators: see
// fem::CoarseProxy::coarse_heat_method_operators). Then the reference: fem::HeatGeodesicSolver on
// the fine mesh (assemble, factor, solve) and the errors of the proxy's distance against it.
//
// Distance-oracle modes (--all-pairs, --pairs FILE, --sample K): load → coarsen (keeping the
// fine-to-coarse map) → fem::DistanceOracle (all coarse pairs by fast marching with exact planar
// updates, or by the heat method) → the queries → outputs; the reference is the fine heat method
// from --check-sources random sources in one blocked solve, with errors per pair (near and far
// pairs apart) and the fine all-pairs time extrapolated from that block.
//
// Exit codes: see app_common.h (0 ok, 1 unreadable, 2 defective/unsuitable mesh, 3 output not written,
// 4 bad command line, 5 computation failed).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <utility>

#include "tool_main.h"
#include "app_common.h"
#include "fem/coarse_proxy.h"
#include "fem/distance_oracle.h"
#include "fem/errors.h"
#include "fem/problems.h"
#include "ice/large_array.h"
#include "ice/proxy/geodesics.h"
#include "ice/scalar_field_io.h"

namespace geodesic_coarse_tool {

// Traced coarse lengths refuse a mesh read with --nonmanifold tufted that needs its cover
// (ice::proxy::refuse_tracing_on_cover says why): a usage error naming the file.
void refuse_tracing_on_cover(const app::PdeOptions& opt, bool covered, const std::string& what) {
  try {
    ice::proxy::refuse_tracing_on_cover(covered, what);
  } catch (const std::invalid_argument& e) {
    throw app::AppError(app::kUsage, opt.mesh + ": " + e.what());
  }
}

const std::string kTool = "geodesic-coarse";

/// The largest finite entry (distances are +inf on components without a source), 0 if none.
template <class Derived>
double largest_finite(const Eigen::DenseBase<Derived>& values) {
  if (values.size() == 0) return 0;
  using Scalar = typename Derived::Scalar;
  const auto finite = values.unaryExpr([](Scalar v) { return std::isfinite(v) ? v : Scalar(0); });
  return std::max(0.0, static_cast<double>(finite.maxCoeff()));
}

/// What the distance-oracle modes were asked for.
struct OracleRequest {
  bool all_pairs = false;
  std::string pairs_path;      ///< --pairs: two vertex indices per pair
  long long sample_count = 0;  ///< --sample K
  long long first_sample = 0;
  bool first_sample_given = false;  ///< otherwise the mesh's first vertex (also when --repair dropped file vertex 0)
  std::string matrix_path;     ///< --matrix (.npy or .mtx)
  std::string pairs_output;    ///< --pairs-out (.csv)
  fem::CoarseDistanceMethod method = fem::CoarseDistanceMethod::marching;
  ice::proxy::CoarseLengths lengths = ice::proxy::CoarseLengths::automatic;  ///< --coarse-lengths
  bool traced_lengths = false;  ///< what `lengths` resolves to: marching on the coarse edges' lengths on the surface
  int subdivisions = fem::ProxyGeodesicOptions{}.subdivisions;  ///< --marching-subdivisions (coarse marching)
  ice::proxy::CurvatureCorrection curvature_correction = ice::proxy::CurvatureCorrection::automatic;  ///< --curvature-correction
  int check_sources = 16;
  bool active() const { return all_pairs || !pairs_path.empty() || sample_count > 0; }
  std::string mode() const { return all_pairs ? "all_pairs" : !pairs_path.empty() ? "pairs" : "sample"; }
};

/// Largest fine mesh whose full distance matrix --all-pairs --matrix writes (65,536² floats = 16 GiB).
constexpr long long kMaxAllPairsMatrixVertices = 65536;

nlohmann::json error_stats(const std::vector<double>& errors) {
  if (errors.empty()) return {{"pairs", 0}};
  double sum = 0;
  for (double e : errors) sum += e;
  return {{"pairs", errors.size()},
          {"mean_rel", sum / static_cast<double>(errors.size())},
          {"p95_rel", app::quantile(errors, 0.95)},
          {"max_rel", *std::max_element(errors.begin(), errors.end())}};
}

/// One figure of an error_stats object as printed: "none" without pairs.
std::string stat_of(const nlohmann::json& stats, const char* key = "mean_rel") {
  return stats.contains(key) ? app::percent(stats[key]) : std::string("none");
}

/// Outputs this run has begun to write, removed again unless the run completes (a later failure
/// must not leave files that look like results).
struct OutputsOfThisRun {
  std::vector<std::string> paths;
  bool complete = false;
  ~OutputsOfThisRun() {
    if (complete) return;
    std::error_code ec;
    for (const std::string& path : paths) std::filesystem::remove(path, ec);
  }
};

int run_oracle(const app::PdeOptions& opt, const OracleRequest& request) {
  using app::AppError;
  if (opt.target.method == ice::CoarseningMethod::qem && opt.qem_geometry == ice::QemGeometry::intrinsic_delaunay)
    throw AppError(app::kUsage, "--qem-operators idt has no fine-to-coarse map onto its coarse mesh; use extrinsic");
  if (!request.matrix_path.empty()) app::check_output(request.matrix_path, opt.force, "--matrix");
  if (!request.pairs_output.empty()) app::check_output(request.pairs_output, opt.force, "--pairs-out");
  app::PdeRun run = app::PdeRun::start(kTool, opt, false);

  // ---- load
  app::Stopwatch clock;
  const ice::LoadResult loaded = app::load_input_mesh(opt.mesh, opt.load_options());
  const ice::TriangleMesh& mesh = loaded.mesh;
  // On a tufted cover: the coarse mesh's own lengths (--coarse-lengths auto), the fine reference the cover's.
  const bool covered = ice::solved_on_tufted_cover(mesh, opt.nonmanifold);
  if (covered && request.lengths == ice::proxy::CoarseLengths::traced) refuse_tracing_on_cover(opt, true, "--coarse-lengths traced");
  const bool traced_lengths = request.traced_lengths && !covered;
  const long long n = mesh.V.rows();
  const app::FileVertexMap vertices(loaded);
  std::vector<std::array<ice::Index, 2>> pairs;
  std::vector<std::array<long long, 2>> file_pairs;
  if (!request.pairs_path.empty()) {
    const std::vector<double> numbers = app::read_number_file(request.pairs_path);
    if (numbers.size() % 2 != 0)
      throw AppError(app::kUnreadable, request.pairs_path + ": an odd count of numbers (" + std::to_string(numbers.size()) +
                                           "); expected two vertex indices per pair");
    for (std::size_t i = 0; i < numbers.size(); i += 2) {
      std::array<long long, 2> file_pair{};
      std::array<ice::Index, 2> pair{};
      for (int k = 0; k < 2; ++k) {
        const double value = numbers[i + static_cast<std::size_t>(k)];
        if (value != std::floor(value))
          throw AppError(app::kUnreadable, request.pairs_path + ": pair " + std::to_string(i / 2 + 1) +
                                               " has a non-integer vertex index");
        int v = vertices.find(value);
        if (v < 0) v = vertices.mesh_vertex(value, request.pairs_path + ": pair " + std::to_string(i / 2 + 1) + ": vertex");
        file_pair[static_cast<std::size_t>(k)] = static_cast<long long>(value);
        pair[static_cast<std::size_t>(k)] = v;
      }
      file_pairs.push_back(file_pair);
      pairs.push_back(pair);
    }
  }
  ice::Index first_sample = 0;
  if (request.sample_count > 0) {
    if (request.sample_count > n)
      throw AppError(app::kUsage, "--sample " + std::to_string(request.sample_count) + " exceeds the " +
                                      std::to_string(n) + " vertices of the mesh");
    if (request.sample_count > kMaxAllPairsMatrixVertices)
      throw AppError(app::kUsage, "--sample " + std::to_string(request.sample_count) + ": the K x K matrix is limited to K <= " +
                                      std::to_string(kMaxAllPairsMatrixVertices) + " (16 GiB)");
    if (request.first_sample_given)
      first_sample = vertices.mesh_vertex(request.first_sample, "--first-sample: vertex");
  }
  if (request.all_pairs && !request.matrix_path.empty() && n > kMaxAllPairsMatrixVertices)
    throw AppError(app::kUsage, "--all-pairs --matrix: the " + std::to_string(n) + "x" + std::to_string(n) +
                                    " matrix would need " + std::to_string(n * n * 4 / (1LL << 30)) +
                                    " GiB; query pairs (--pairs) or samples (--sample) instead");
  ice::CoarsenOptions coarsen_options;
  opt.target.apply(coarsen_options, n);
  run.fine_vertices = n;
  run.fine_faces = mesh.F.rows();
  run.load = clock.lap();

  // ---- the coarse space with its map and traced lengths (through the store), then the oracle
  const ice::proxy::Store store = opt.store();
  ice::proxy::MappedSpace mapped = app::mapped_space_for_pde(mesh, coarsen_options, opt, run, store, /*need_map=*/true);
  const ice::CoarseSpace& space = mapped.coarse;
  clock.lap();  // run.coarsen, and the cache's load and save
  const ice::SurfaceEdgeLengths lengths = app::stored_marching_lengths(run, clock, mesh, mapped, store, traced_lengths,
                                                                      request.curvature_correction, fem::kOracleCorrectionDivisor);
  fem::DistanceOracleOptions oracle_options;
  oracle_options.method = request.method;
  oracle_options.subdivisions = request.subdivisions;
  const fem::DistanceOracle oracle(ice::with_lengths(space.mesh, lengths.lengths), mapped.map, oracle_options);
  const double oracle_seconds = clock.lap();  // with the tracing of --coarse-lengths traced and the correction

  // ---- the queries
  nlohmann::json timings = {{"load", run.load}, {"coarsen", run.coarsen}, {"oracle", oracle_seconds},
                            {"cache_load", run.cache.load_seconds}, {"cache_save", run.cache.save_seconds}};
  nlohmann::json report = app::report_header(kTool, opt.mesh);
  report["cache"] = run.cache_json.is_null() ? nlohmann::json{{"status", "off"}} : run.cache_json;
  report["mode"] = request.mode();
  std::vector<ice::Index> samples;
  OutputsOfThisRun outputs;
  if (request.all_pairs && !request.matrix_path.empty()) {
    outputs.paths.push_back(request.matrix_path);
    ice::NpyMatrixWriter writer(request.matrix_path, n, n, opt.force);
    std::vector<ice::Index> all(static_cast<std::size_t>(n));
    for (ice::Index v = 0; v < n; ++v) all[static_cast<std::size_t>(v)] = v;
    constexpr ice::Index kRowsPerBlock = 256;
    for (ice::Index first = 0; first < n; first += kRowsPerBlock) {
      const std::vector<ice::Index> rows(all.begin() + first, all.begin() + std::min<long long>(first + kRowsPerBlock, n));
      writer.write_rows(oracle.distance_matrix(rows, all));
    }
    writer.close();
    timings["matrix"] = clock.lap();
  }
  Eigen::VectorXd pair_distances;
  if (!request.pairs_path.empty()) {
    pair_distances = oracle.distances(pairs);
    const double seconds = clock.lap();
    timings["queries"] = seconds;
    report["queries"] = {{"pairs", pairs.size()}, {"seconds", seconds},
                         {"per_second", seconds > 0 ? static_cast<double>(pairs.size()) / seconds : 0.0}};
    if (!request.pairs_output.empty()) {
      outputs.paths.push_back(request.pairs_output);
      std::ofstream out(request.pairs_output);
      out.precision(9);
      out << "u,v,distance\n";
      for (std::size_t i = 0; i < pairs.size(); ++i)
        out << file_pairs[i][0] << ',' << file_pairs[i][1] << ',' << pair_distances(static_cast<Eigen::Index>(i)) << '\n';
      out.flush();
      if (!out) throw AppError(app::kNotWritten, request.pairs_output + ": write failed");
      timings["write"] = clock.lap();
    }
  }
  if (request.sample_count > 0) {
    samples = oracle.farthest_point_samples(static_cast<ice::Index>(request.sample_count), first_sample);
    timings["sampling"] = clock.lap();
    const Eigen::MatrixXf matrix = oracle.distance_matrix(samples, samples);
    timings["matrix"] = clock.lap();
    if (!request.matrix_path.empty()) {
      outputs.paths.push_back(request.matrix_path);
      ice::write_dense_matrix(request.matrix_path, matrix, opt.force);
    }
    timings["write"] = clock.lap();
    std::vector<long long> file_samples;
    for (ice::Index v : samples) file_samples.push_back(loaded.source_vertex[static_cast<std::size_t>(v)]);
    report["samples"] = file_samples;
    report["sample_matrix"] = {{"size", samples.size()}, {"max_distance", largest_finite(matrix)}};
  }

  // ---- reference: the fine heat method from random sources, in one blocked solve
  nlohmann::json accuracy, speedup;
  if (!opt.no_reference) {
    const ice::FineMesh fine = ice::fine_mesh(mesh, opt.fine_geometry(), covered ? ice::NonmanifoldInput::tufted_cover
                                                                                 : ice::NonmanifoldInput::refuse);
    run.fine_mesh = clock.lap();
    fem::HeatMethodOperators fine_ops = fem::heat_method_operators(fine, fem::MassKind::lumped, 1.0);
    run.ref_assemble = clock.lap();
    const fem::HeatGeodesicSolver fine_solver(std::move(fine_ops));
    run.ref_factor = clock.lap();
    std::mt19937 rng(1);
    std::uniform_int_distribution<ice::Index> vertex(0, static_cast<ice::Index>(n - 1));
    std::vector<ice::Index> sources;
    for (int i = 0; i < request.check_sources; ++i) sources.push_back(vertex(rng));
    const Eigen::MatrixXd reference = fine_solver.distances_from_each(sources);
    run.ref_solve = clock.lap();
    const fem::PairErrors errors = fem::relative_pair_errors(oracle, sources, reference);
    accuracy = {{"reference", "fine heat method (same t rule), per pair |d - d_ref| / d_ref"},
                {"sources", sources.size()},
                {"all", error_stats(errors.all())},
                {"far", error_stats(errors.far)},
                {"near", error_stats(errors.near)}};
    // Fine all-pairs by the heat method with one factorisation and blocked solves, extrapolated from
    // the block of check sources: an upper bound, since a block of 16 costs more per source than
    // the best block size (256 on spot_subdiv: 92 s extrapolated from 256, 112 s from 64).
    const double fine_all_pairs =
        run.ref_assemble + run.ref_factor + run.ref_solve * static_cast<double>(n) / static_cast<double>(sources.size());
    speedup = {{"fine_all_pairs_estimate_s", fine_all_pairs},
               {"precompute_vs_fine_all_pairs", fine_all_pairs / oracle_seconds},
               {"precompute_with_coarsening_vs_fine_all_pairs", fine_all_pairs / (oracle_seconds + run.coarsen)}};
    timings["fine_mesh"] = run.fine_mesh;
    timings["reference"] = {{"assemble", run.ref_assemble}, {"factor", run.ref_factor}, {"solve", run.ref_solve}};
  }

  report["method"] = ice::proxy::spelling(space.summary.method);
  if (!space.summary.qem) report["metric"] = {{"area_weight", opt.target.area_weight}, {"normalize_curvature", opt.target.normalize_curvature}};
  report["input"] = {{"vertices", n}, {"faces", mesh.F.rows()}};
  report["coarse"] = ice::proxy::coarsen_json(space.summary);
  report["coarse_lengths"] = request.traced_lengths ? "traced" : "intrinsic";
  report["curvature_corrected"] = ice::proxy::corrects_curvature(request.curvature_correction, space.summary.method);
  if (request.method == fem::CoarseDistanceMethod::marching) report["marching_subdivisions"] = request.subdivisions;
  report["oracle"] = {{"coarse_distances", fem::to_string(request.method)},
                      {"coarse_vertices", oracle.coarse_size()},
                      {"memory_bytes", oracle.memory_bytes()},
                      {"coarse_distances_s", oracle.times().coarse_distances}};
  report["timings_s"] = timings;
  if (!accuracy.is_null()) report["accuracy"] = accuracy;
  if (!speedup.is_null()) report["speedup"] = speedup;
  report["peak_rss_mb"] = app::peak_rss_mb();
  if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);
  outputs.complete = true;

  std::cout << kTool << ": " << app::thousands(n) << " vertices -> " << app::thousands(oracle.coarse_size())
            << " coarse vertices (" << ice::proxy::spelling(space.summary.method) << "); distance oracle ("
            << fem::to_string(request.method) << ") in " << app::fixed(oracle_seconds, 3) << " s, "
            << app::fixed(static_cast<double>(oracle.memory_bytes()) / (1 << 20), 1) << " MiB; coarsening "
            << app::fixed(run.coarsen, 3) << " s"
            << (run.cache.status == ice::proxy::CacheStatus::hit
                    ? " (set up from the store in " + app::fixed(run.cache.load_seconds, 3) + " s)"
                    : "")
            << '\n';
  if (report.contains("queries"))
    std::cout << "  " << app::thousands(static_cast<long long>(pairs.size())) << " pairs answered in "
              << app::fixed(report["queries"]["seconds"], 4) << " s\n";
  if (!samples.empty())
    std::cout << "  " << samples.size() << " farthest-point samples in " << app::fixed(timings["sampling"], 3)
              << " s, their distance matrix in " << app::fixed(timings["matrix"], 4) << " s\n";
  const long long sources_count = accuracy.is_null() ? 0 : static_cast<long long>(accuracy["sources"]);
  if (!accuracy.is_null())
    std::cout << "  error vs the fine heat method (" << request.check_sources << " sources, every vertex): mean "
              << stat_of(accuracy["all"]) << ", 95th percentile " << stat_of(accuracy["all"], "p95_rel")
              << "; far pairs " << stat_of(accuracy["far"]) << ", near pairs (sharing a coarse vertex) "
              << stat_of(accuracy["near"]) << "\n  fine heat-method all-pairs extrapolated from this block of "
              << sources_count << " sources ~"
              << app::fixed(speedup["fine_all_pairs_estimate_s"], 1) << " s: the oracle is "
              << app::fixed(speedup["precompute_vs_fine_all_pairs"], 0) << "x faster to make every pair answerable, "
              << app::fixed(speedup["precompute_with_coarsening_vs_fine_all_pairs"], 0)
              << "x counting the coarsening (small blocks cost more per source than the best, ~256: an upper "
                 "bound; ice_bench's BM_FineHeatAllPairs measures the strongest fine all-pairs)\n";
  if (!request.matrix_path.empty()) std::cout << "  wrote " << request.matrix_path << '\n';
  if (!request.pairs_output.empty()) std::cout << "  wrote " << request.pairs_output << '\n';
  if (!opt.report.empty()) std::cout << "  wrote " << opt.report << '\n';
  return app::kOk;
}

}  // namespace geodesic_coarse_tool

int geodesic_coarse_tool::main(int argc, char** argv) {
  ice::keep_freed_memory_for_reuse();  // one job per process: reuse freed arrays instead of re-faulting them
  CLI::App cli{
      "geodesic-coarse: geodesic distance from sources (or between any vertices: the oracle modes) through a small "
      "ICE\ncoarse proxy, carried back to every vertex and (by default) compared with the fine heat method.\n\n"
      "Examples:\n  geodesic-coarse spot.obj --source 0 --ratio 0.05\n"
      "  geodesic-coarse bunny.off --source 10,250 --vertices 1000 --operators galerkin -o dist.ply --report r.json\n\n"
      "Exit status: 0 ok, 1 unreadable input, 2 defective or disconnected mesh, 3 output not written,\n"
      "4 bad command line (e.g. source out of range), 5 computation failed."};
  app::PdeOptions opt;
  std::string sources_text;
  OracleRequest oracle;
  cli.add_option("--source,-s", sources_text,
                 "Source vertices, 0-based, comma separated (e.g. 0,1500)");
  cli.add_flag("--all-pairs", oracle.all_pairs,
               "Oracle: precompute all coarse pairs (--matrix: the n x n matrix)");
  cli.add_option("--pairs", oracle.pairs_path,
                 "Oracle: answer the vertex pairs in FILE (two 0-based indices each)");
  cli.add_option("--sample", oracle.sample_count,
                 "Oracle: K farthest-point samples and their distance matrix (--matrix)")
      ->check(app::integer_between(1, 1LL << 31));
  const CLI::Option* first_sample_option =
      cli.add_option("--first-sample", oracle.first_sample,
                     "With --sample: the first sample (default: vertex 0)");
  cli.add_option("--matrix", oracle.matrix_path,
                 "With --all-pairs or --sample: write the distance matrix (.npy; .mtx with --sample)");
  cli.add_option("--pairs-out", oracle.pairs_output, "With --pairs: write u,v,distance per pair (.csv)");
  app::add_choice(cli, "--coarse-distances", oracle.method,
                  {{"marching", fem::CoarseDistanceMethod::marching}, {"heat", fem::CoarseDistanceMethod::heat_method}},
                  "Coarse distances: 'marching' (more accurate) or 'heat' (the coarse heat method)");
  app::add_coarse_lengths_option(cli, "--coarse-lengths", oracle.lengths);
  app::add_curvature_correction_option(cli, oracle.curvature_correction);
  const CLI::Option* subdivisions_option = cli.add_option(
      "--marching-subdivisions", oracle.subdivisions,
      "Split the coarse mesh 1:4 this many times for marching (more accurate, slower)")
      ->check(CLI::Range(0, fem::kMaxMarchingSubdivisions))
      ->capture_default_str();
  cli.add_option("--check-sources", oracle.check_sources,
                 "Oracle: random sources of the fine heat-method reference")
      ->check(app::integer_between(1, 100000))
      ->capture_default_str();
  opt.target.use_defaults_for(ice::ProxyUse::geodesic);  // the metric measured best for geodesics
  opt.add_to(cli, "'distance', 'reference', 'error'");
  opt.add_nonmanifold_option(cli);
  opt.add_cache_options(cli);
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&]() -> int {
    const int modes = (sources_text.empty() ? 0 : 1) + (oracle.all_pairs ? 1 : 0) + (oracle.pairs_path.empty() ? 0 : 1) +
                      (oracle.sample_count > 0 ? 1 : 0);
    if (modes != 1)
      throw app::AppError(app::kUsage, "give exactly one of --source, --all-pairs, --pairs FILE and --sample K");
    if (!oracle.matrix_path.empty() && !oracle.all_pairs && oracle.sample_count == 0)
      throw app::AppError(app::kUsage, "--matrix goes with --all-pairs or --sample");
    if (oracle.all_pairs && !oracle.matrix_path.empty() && std::filesystem::path(oracle.matrix_path).extension() != ".npy")
      throw app::AppError(app::kUsage, "--all-pairs --matrix writes .npy only (the matrix is written in row blocks)");
    if (!oracle.matrix_path.empty() && std::filesystem::path(oracle.matrix_path).extension() != ".npy" &&
        std::filesystem::path(oracle.matrix_path).extension() != ".mtx")
      throw app::AppError(app::kUsage, "--matrix: use a .npy or .mtx file name");
    oracle.first_sample_given = first_sample_option->count() > 0;
    if (oracle.first_sample_given && oracle.sample_count == 0)
      throw app::AppError(app::kUsage, "--first-sample goes with --sample");
    if (!oracle.pairs_output.empty() && oracle.pairs_path.empty())
      throw app::AppError(app::kUsage, "--pairs-out goes with --pairs");
    if (subdivisions_option->count() > 0 && oracle.method != fem::CoarseDistanceMethod::marching)
      throw app::AppError(app::kUsage, "--marching-subdivisions goes with coarse marching, not --coarse-distances heat");
    const bool traced_asked = oracle.lengths == ice::proxy::CoarseLengths::traced;
    if (traced_asked && oracle.method != fem::CoarseDistanceMethod::marching)
      throw app::AppError(app::kUsage, "--coarse-lengths traced is for coarse marching, not --coarse-distances heat");
    oracle.traced_lengths = ice::proxy::traces_lengths(oracle.lengths, opt.target.method,
                                                oracle.method == fem::CoarseDistanceMethod::marching);
    if (traced_asked && opt.target.method != ice::CoarseningMethod::ice)
      throw app::AppError(app::kUsage, "--coarse-lengths traced needs ICE's coarse mesh (QEM's edges are straight segments: "
                                       "nothing to trace)");
    if (oracle.active() && (!opt.output.empty() || !opt.html.empty()))
      throw app::AppError(app::kUsage, "--output and --html show a distance field (--source); the oracle modes write --matrix or --pairs-out");
    if (oracle.active()) {
      opt.check_outputs();
      return run_oracle(opt, oracle);
    }
    opt.check_outputs();
    const std::vector<long long> file_sources = app::parse_index_list(sources_text, "--source");
    app::PdeRun run = app::PdeRun::start(kTool, opt, opt.operators == fem::CoarseOperatorKind::galerkin &&
                                                                oracle.method == fem::CoarseDistanceMethod::heat_method);

    // ---- load
    app::Stopwatch clock;
    const ice::LoadResult loaded = app::load_input_mesh(opt.mesh, opt.load_options());
    const ice::TriangleMesh& mesh = loaded.mesh;
    // On a tufted cover marching runs on the coarse mesh's own lengths (--coarse-lengths auto).
    const bool covered = ice::solved_on_tufted_cover(mesh, opt.nonmanifold);
    if (covered && traced_asked) refuse_tracing_on_cover(opt, true, "--coarse-lengths traced");
    if (covered) oracle.traced_lengths = false;
    const long long n = mesh.V.rows();
    std::vector<int> sources;
    const app::FileVertexMap vertices(loaded);
    for (long long s : file_sources) sources.push_back(vertices.mesh_vertex(s, "--source: vertex"));
    ice::CoarsenOptions coarsen_options;
    opt.target.apply(coarsen_options, n);
    run.fine_vertices = n;
    run.fine_faces = mesh.F.rows();
    run.load = clock.lap();

    // ---- coarsen, fine discretisation, then the proxy (fem::ProxyGeodesicSolver): assemble, factor,
    // restrict + solve and prolong, the last two timed by the solver
    const bool marching = oracle.method == fem::CoarseDistanceMethod::marching;
    const ice::proxy::Store store = opt.store();
    ice::proxy::ProxySetup pde;
    std::optional<fem::ProxyGeodesicSolver> proxy_solver;
    std::optional<std::pair<ice::Index, ice::Index>> traced_counts;  // --coarse-lengths traced: edges, traced
    if (marching) {  // no coarse operators: the coarse mesh, P and the lengths are all the marching reads
      // The coarse space with its map and traced lengths through the store; the fine mesh is for a
      // reference (made on the way when the space is built, else now).
      const bool share_fine = run.has_reference && opt.fine_geometry() == ice::FineGeometry::intrinsic_delaunay;
      ice::proxy::MappedSpace space = app::mapped_space_for_pde(mesh, coarsen_options, opt, run, store, oracle.traced_lengths,
                                                                app::outputs_draw_coarse_mesh(opt, covered), share_fine ? &pde.fine : nullptr);
      clock.lap();
      if (run.has_reference && pde.fine.vertex_count == 0) {
        pde.fine = ice::fine_mesh(mesh, opt.fine_geometry(), covered ? ice::NonmanifoldInput::tufted_cover : ice::NonmanifoldInput::refuse);
        run.fine_mesh = clock.lap();
      }
      run.fine_built = run.has_reference;
      run.idt_flips = pde.fine.flips;
      run.coarse_solver = oracle.traced_lengths ? "coarse fast marching on traced lengths" : "coarse fast marching";
      const ice::SurfaceEdgeLengths lengths = app::stored_marching_lengths(
          run, clock, mesh, space, store, oracle.traced_lengths, oracle.curvature_correction,
          ice::proxy::curvature_divisor(ice::proxy::MarchingUse::single_source));
      if (oracle.traced_lengths) traced_counts = {lengths.edges, lengths.traced};
      run.assemble = clock.lap();  // the tracing of --coarse-lengths traced and the correction
      pde.coarse = std::move(space.coarse);
      proxy_solver.emplace(ice::with_lengths(pde.coarse.mesh, lengths.lengths), pde.coarse.P, oracle.subdivisions);
    } else {
      pde = app::build_pde_proxy(mesh, coarsen_options, opt, run, clock, /*assemble_proxy=*/true, /*need_fine=*/true,
                                 /*keep_method_state=*/false, store);
      fem::HeatMethodOperators coarse_ops = pde.proxy->coarse_heat_method_operators();  // lumped mass for Galerkin
      run.assemble = clock.lap();
      proxy_solver.emplace(*pde.proxy, std::move(coarse_ops));
    }
    run.factor = clock.lap();
    fem::ProxyPhaseTimes phases;
    const Eigen::VectorXd distance = proxy_solver->distance(sources, &phases);
    run.solve = phases.restriction + phases.coarse_solve;
    run.prolong = phases.prolongation;
    clock.lap();

    // ---- reference
    nlohmann::json error_json;
    Eigen::VectorXd reference;
    if (run.has_reference) {
      fem::HeatMethodOperators fine_ops = fem::heat_method_operators(pde.fine, fem::MassKind::lumped, 1.0);
      run.ref_assemble = clock.lap();
      const fem::HeatGeodesicSolver fine_solver(std::move(fine_ops));
      run.ref_factor = clock.lap();
      reference = fine_solver.distance(sources);
      run.ref_solve = clock.lap();
      const fem::DistanceErrors d = fem::distance_errors(distance, reference);
      error_json = {{"rel_l2", fem::relative_l2_error(distance, reference, fine_solver.operators().mass)},
                    {"max_abs", fem::max_abs_error(distance, reference)},
                    {"mean_rel", d.mean_relative},
                    {"max_rel", d.max_relative},
                    {"max_reference_distance", largest_finite(reference)}};
      clock.lap();
    }

    // ---- outputs
    const std::optional<ice::CoarseTracing> tracing = app::trace_for_outputs(opt, mesh, pde.coarse);
    const ice::CoarseTracing* traced = tracing && (!opt.output.empty() || !opt.html.empty()) ? &*tracing : nullptr;
    app::write_result_fields(opt, mesh, "distance", distance, reference, {}, traced);
    app::write_result_page(opt, mesh, "geodesic-coarse: " + std::filesystem::path(opt.mesh).filename().string(), "geodesic",
                           "distance", distance, reference, pde.coarse, traced, error_json, loaded.point_cloud);
    run.write = clock.lap();
    nlohmann::json report = run.report();
    if (traced) report["trace"] = {{"edges", traced->edges.size()}, {"traced", traced->traced}};
    report["sources"] = file_sources;
    report["coarse_distances"] = fem::to_string(oracle.method);
    report["coarse_lengths"] = oracle.traced_lengths ? "traced" : "intrinsic";
    if (marching)
      report["curvature_corrected"] = ice::proxy::corrects_curvature(oracle.curvature_correction, pde.coarse.summary.method,
                                                                     pde.coarse.summary.tufted_cover);
    if (marching) report["marching_subdivisions"] = oracle.subdivisions;
    if (traced_counts) report["coarse_lengths_traced_edges"] = {{"edges", traced_counts->first}, {"traced", traced_counts->second}};
    report["max_distance"] = largest_finite(distance);
    // Several components: the vertices of those without a source are not reached.
    const Eigen::Index unreached = (distance.array() == std::numeric_limits<double>::infinity()).count();
    if (unreached > 0) report["unreached_vertices"] = unreached;
    if (run.has_reference) report["error"] = error_json;
    if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

    run.print_summary(std::cout);
    std::cout << "  sources: " << sources_text << "; prolonged max distance " << largest_finite(distance);
    if (unreached > 0) std::cout << " (" << unreached << " vertices in components without a source: +inf)";
    std::cout << '\n';
    if (run.has_reference)
      std::cout << "  error vs fine: mean " << app::percent(error_json["mean_rel"]) << ", max "
                << app::percent(error_json["max_rel"]) << " of the max distance "
                << static_cast<double>(error_json["max_reference_distance"]) << "; relative L2 "
                << app::percent(error_json["rel_l2"]) << ", max abs " << static_cast<double>(error_json["max_abs"]) << '\n';
    app::print_written(std::cout, opt, traced);
    return app::kOk;
  });
}
