// The geodesic distance oracle (fem/distance_oracle.h) against the fine heat method.
//
//  - BM_FineHeatAllPairs/<Loop levels>/<block>/<sources>/<threads>: heat-method distances on the
//    fine mesh from `sources` sources (0: every vertex, i.e. all pairs) with blocked
//    multi-right-hand-side solves of `block` sources (HeatGeodesicSolver::distances_from_each);
//    assemble + factor + solves. With 1 thread one factorisation (CHOLMOD's multi-column solves
//    gain ~10 % from a second BLAS thread here); with 2, one solver per thread (two
//    factorisations, blocks shared out), the strongest use of two cores. Counter all_pairs_s: the
//    time extrapolated to every source.
//  - BM_DistanceOracle/<Loop levels>/<coarse vertices>/<method>: the oracle's precompute (all coarse
//    pairs; method 0 marching, 1 heat method) after the coarsening, which is timed once apart
//    (counter coarsen_s, including the fine-to-coarse map).
//  - BM_OracleQueries/<Loop levels>/<coarse vertices>: 10 million random pairs (counter pairs_per_s).
//  - BM_OracleSamples/<Loop levels>/<coarse vertices>: 1,000 farthest-point samples, then their
//    1,000 x 1,000 matrix (counters sampling_s, matrix_s).
//  - BM_FineHeatSolve/<Loop levels>: one heat-method solve on the fine mesh (assemble, factor, solve).
//  - BM_TracedLengths/<Loop levels>/<coarse vertices>/<way>: the coarse edges' lengths on the input
//    surface (geodesic-coarse --coarse-lengths traced): way 0 the walk over the map
//    (ice::surface_edge_lengths, what the tools use), 1 the exact tracing through the coarsening's
//    recorded history (ice::trace_coarse_mesh, then ice::traced_edge_lengths); both on the default
//    threads. The coarsening is not timed; counter triangulation_MB: the coarsening's state the way
//    needs kept (with the history for way 1).
// spot_subdiv (24,755 vertices) is level 0; level 3 is 1,584,194 vertices.
#include <chrono>
#include <random>

#ifdef _OPENMP
#include <omp.h>
#else
inline int omp_get_thread_num() { return 0; }
#endif

#include "bench_support.h"
#include "fem/distance_oracle.h"
#include "fem/problems.h"
#include "ice/coarse_space.h"
#include "ice/coarse_tracing.h"

namespace {

using ice_bench::seconds_since;

struct OracleInput {
  ice::CoarseSpace space;
  std::vector<ice::CoarsePoint> map;
  double coarsen_seconds = 0;
};

/// The coarse space (ICE, geodesic defaults) and its map, made once per (levels, size).
const OracleInput& oracle_input(int levels, int coarse_vertices) {
  static std::map<std::pair<int, int>, OracleInput> cache;
  auto it = cache.find({levels, coarse_vertices});
  if (it == cache.end()) {
    const ice::TriangleMesh& mesh = ice_bench::subdivided_mesh("spot_subdiv.obj", levels);
    ice::CoarseSpaceOptions options;
    options.coarsen = ice::recommended_coarsen_options(ice::ProxyUse::geodesic);
    options.coarsen.target_vertices = coarse_vertices;
    options.coarsen.threads = 2;
    options.keep_method_state = true;
    OracleInput input;
    auto start = std::chrono::steady_clock::now();
    input.space = ice::build_coarse_space(mesh, options);
    input.map = ice::fine_to_coarse_map(input.space);
    input.coarsen_seconds = seconds_since(start);
    it = cache.emplace(std::make_pair(levels, coarse_vertices), std::move(input)).first;
  }
  return it->second;
}

const fem::DistanceOracle& oracle_of(int levels, int coarse_vertices) {
  static std::map<std::pair<int, int>, std::unique_ptr<fem::DistanceOracle>> cache;
  auto& slot = cache[{levels, coarse_vertices}];
  if (!slot) {
    const OracleInput& input = oracle_input(levels, coarse_vertices);
    slot = std::make_unique<fem::DistanceOracle>(input.space.mesh, input.map);
  }
  return *slot;
}

void BM_FineHeatAllPairs(benchmark::State& state) {
  const int levels = static_cast<int>(state.range(0));
  const auto block = static_cast<ice::Index>(state.range(1));
  const int threads = static_cast<int>(state.range(3));
  const ice::TriangleMesh& mesh = ice_bench::subdivided_mesh("spot_subdiv.obj", levels);
  const auto n = static_cast<ice::Index>(mesh.V.rows());
  const ice::Index sources = state.range(2) > 0 ? static_cast<ice::Index>(state.range(2)) : n;
  const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  double solve_seconds = 0, setup_seconds = 0;
  for (auto _ : state) {
    auto start = std::chrono::steady_clock::now();
    std::vector<std::unique_ptr<fem::HeatGeodesicSolver>> solvers(static_cast<std::size_t>(threads));
#pragma omp parallel for num_threads(threads)
    for (int t = 0; t < threads; ++t)
      solvers[static_cast<std::size_t>(t)] = std::make_unique<fem::HeatGeodesicSolver>(
          fem::heat_method_operators(fine, fem::MassKind::lumped, 1.0));
    setup_seconds = seconds_since(start);
    double checksum = 0;
    const ice::Index blocks = (sources + block - 1) / block;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) reduction(+ : checksum)
    for (ice::Index b = 0; b < blocks; ++b) {
      std::vector<ice::Index> ids;
      for (ice::Index s = b * block; s < std::min(sources, (b + 1) * block); ++s) ids.push_back(s);
      const Eigen::MatrixXd d = solvers[static_cast<std::size_t>(omp_get_thread_num())]->distances_from_each(ids);
      checksum += d(0, 0);
    }
    solve_seconds = seconds_since(start);
    benchmark::DoNotOptimize(checksum);
  }
  state.counters["vertices"] = n;
  state.counters["setup_s"] = setup_seconds;
  state.counters["solves_s"] = solve_seconds;
  state.counters["all_pairs_s"] = setup_seconds + solve_seconds * n / sources;
}
BENCHMARK(BM_FineHeatAllPairs)
    ->ArgsProduct({{0}, {64, 256, 1024}, {2048}, {1, 2}})
    ->Args({0, 256, 0, 1})  // every source: the measured fine all-pairs
    ->Args({0, 256, 0, 2})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

void BM_DistanceOracle(benchmark::State& state) {
  const int levels = static_cast<int>(state.range(0));
  const OracleInput& input = oracle_input(levels, static_cast<int>(state.range(1)));
  fem::DistanceOracleOptions options;
  options.method = state.range(2) == 0 ? fem::CoarseDistanceMethod::marching : fem::CoarseDistanceMethod::heat_method;
  std::size_t bytes = 0;
  for (auto _ : state) {
    const fem::DistanceOracle oracle(input.space.mesh, input.map, options);
    bytes = oracle.memory_bytes();
    benchmark::DoNotOptimize(oracle.coarse_distance(0, 1));
  }
  state.counters["vertices"] = static_cast<double>(input.map.size());
  state.counters["coarse"] = static_cast<double>(input.space.mesh.to_input.size());
  state.counters["coarsen_s"] = input.coarsen_seconds;
  state.counters["memory_MB"] = static_cast<double>(bytes) / 1e6;
}
BENCHMARK(BM_DistanceOracle)
    ->Args({0, 1000, 0})
    ->Args({0, 1000, 1})
    ->Args({3, 1000, 0})
    ->Args({3, 4000, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_OracleQueries(benchmark::State& state) {
  const fem::DistanceOracle& oracle = oracle_of(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  constexpr int kPairs = 10'000'000;
  std::mt19937 rng(3);
  std::uniform_int_distribution<ice::Index> vertex(0, static_cast<ice::Index>(oracle.fine_size() - 1));
  std::vector<std::array<ice::Index, 2>> pairs(kPairs);
  for (auto& pair : pairs) pair = {vertex(rng), vertex(rng)};
  for (auto _ : state) benchmark::DoNotOptimize(oracle.distances(pairs).sum());
  state.counters["pairs_per_s"] = benchmark::Counter(kPairs, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_OracleQueries)->Args({0, 1000})->Args({3, 1000})->Args({3, 4000})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_OracleSamples(benchmark::State& state) {
  const fem::DistanceOracle& oracle = oracle_of(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  double sampling = 0, matrix = 0;
  for (auto _ : state) {
    auto start = std::chrono::steady_clock::now();
    const std::vector<ice::Index> samples = oracle.farthest_point_samples(1000);
    sampling = seconds_since(start);
    const Eigen::MatrixXf D = oracle.distance_matrix(samples, samples);
    matrix = seconds_since(start);
    benchmark::DoNotOptimize(D.sum());
  }
  state.counters["sampling_s"] = sampling;
  state.counters["matrix_s"] = matrix;
}
BENCHMARK(BM_OracleSamples)->Args({0, 1000})->Args({3, 1000})->Args({3, 4000})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FineHeatSolve(benchmark::State& state) {
  const ice::TriangleMesh& mesh = ice_bench::subdivided_mesh("spot_subdiv.obj", static_cast<int>(state.range(0)));
  const auto n = static_cast<ice::Index>(mesh.V.rows());
  const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  for (auto _ : state) {
    const fem::HeatGeodesicSolver solver(fem::heat_method_operators(fine, fem::MassKind::lumped, 1.0));
    benchmark::DoNotOptimize(solver.distance({0}).sum());
  }
  state.counters["vertices"] = n;
}
BENCHMARK(BM_FineHeatSolve)->Arg(0)->Arg(3)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

void BM_TracedLengths(benchmark::State& state) {
  const int levels = static_cast<int>(state.range(0));
  const bool exact = state.range(2) == 1;
  const ice::TriangleMesh& mesh = ice_bench::subdivided_mesh("spot_subdiv.obj", levels);
  ice::CoarseSpaceOptions options;
  options.coarsen = ice::recommended_coarsen_options(ice::ProxyUse::geodesic);
  options.coarsen.target_vertices = static_cast<ice::Index>(state.range(1));
  options.coarsen.threads = 2;
  options.keep_method_state = true;
  options.record_history = exact;
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(space);
  ice::Index edges = 0, traced = 0;
  for (auto _ : state) {
    if (exact) {
      const ice::CoarseTracing tracing = ice::trace_coarse_mesh(mesh, space);
      benchmark::DoNotOptimize(ice::traced_edge_lengths(mesh.V, mesh.F, space.mesh, tracing).sum());
      edges = static_cast<ice::Index>(tracing.edges.size());
      traced = tracing.traced;
    } else {
      const ice::SurfaceEdgeLengths lengths = ice::surface_edge_lengths(mesh, space.mesh, map, space.inserted);
      benchmark::DoNotOptimize(lengths.lengths.sum());
      edges = lengths.edges;
      traced = lengths.traced;
    }
  }
  state.counters["vertices"] = static_cast<double>(mesh.V.rows());
  state.counters["edges"] = static_cast<double>(edges);
  state.counters["traced"] = static_cast<double>(traced);
  state.counters["triangulation_MB"] = static_cast<double>(space.triangulation->memory_bytes()) / 1e6;
}
BENCHMARK(BM_TracedLengths)
    ->ArgsProduct({{0}, {1000}, {0, 1}})
    ->ArgsProduct({{3}, {15842}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
