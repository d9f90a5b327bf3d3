// Benchmarks of the intrinsic triangulation and ICE coarsening (single thread).
//
//   ice_bench --benchmark_filter='Flip|Delaunay|Flatten|Coarsen'
//
// Inputs come from the project set (data/default/) or, for fertility.off, the extended set (skipped
// without it; see tests/mesh_sets.h); large inputs are made by
// Loop subdivision: fertility.off (4,494 vertices) subdivided 4 times has 1,150,214 vertices.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>

#include <cstdlib>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <sys/resource.h>

#include "ice/coarse_space.h"
#include "ice/coarsen.h"
#include "ice/error_metric.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/point_cloud.h"
#include "bench_support.h"

using namespace ice;

namespace {

const ice::TriangleMesh& mesh(const std::string& name, int subdivisions = 0) {
  return ice_bench::subdivided_mesh(name, subdivisions);
}

double peak_rss_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

std::vector<Index> shuffled_interior_edges(const IntrinsicTriangulation& T, unsigned seed) {
  std::vector<Index> edges;
  for (Index h = 0; h < T.num_halfedge_slots(); h += 2)
    if (T.halfedge_alive(h) && !T.is_boundary_edge(h)) edges.push_back(h);
  std::shuffle(edges.begin(), edges.end(), std::mt19937(seed));
  return edges;
}

// Intrinsic flips of random edges of spot_subdiv (24,755 vertices).
void BM_Flip(benchmark::State& state) {
  const TriangleMesh& m = mesh("spot_subdiv.obj");
  auto T = IntrinsicTriangulation::from_mesh(m.V, m.F);
  const std::vector<Index> edges = shuffled_interior_edges(T, 1);
  std::size_t next = 0;
  std::int64_t flips = 0;
  for (auto _ : state) {
    flips += T.flip(edges[next]);
    if (++next == edges.size()) next = 0;
  }
  state.counters["flips_per_s"] = benchmark::Counter(static_cast<double>(flips), benchmark::Counter::kIsRate);
  state.counters["success_ratio"] = static_cast<double>(flips) / state.iterations();
}
BENCHMARK(BM_Flip);

// Intrinsic flips sweeping the edges in storage order (spatially coherent, as in Delaunay flipping
// or coarsening), pass after pass: the flip's own cost, where BM_Flip adds random memory access.
void BM_FlipSequential(benchmark::State& state) {
  const TriangleMesh& m = mesh("spot_subdiv.obj");
  auto T = IntrinsicTriangulation::from_mesh(m.V, m.F);
  Index h = 0;
  std::int64_t flips = 0;
  for (auto _ : state) {
    flips += T.flip(h);
    h += 2;
    if (h >= T.num_halfedge_slots()) h = 0;
  }
  state.counters["flips_per_s"] = benchmark::Counter(static_cast<double>(flips), benchmark::Counter::kIsRate);
  state.counters["success_ratio"] = static_cast<double>(flips) / state.iterations();
}
BENCHMARK(BM_FlipSequential);

// Global flip to intrinsic Delaunay of a Loop-subdivided mesh whose edges were first flipped at
// random (a third of all edges), so that there is work to do.
void BM_FlipToDelaunay(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fertility.off")) return;
  const TriangleMesh& m = mesh("fertility.off", static_cast<int>(state.range(0)));
  std::int64_t flips = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto T = IntrinsicTriangulation::from_mesh(m.V, m.F);
    const std::vector<Index> edges = shuffled_interior_edges(T, 2);
    for (std::size_t i = 0; i < edges.size() / 3; ++i) T.flip(edges[i]);
    state.ResumeTiming();
    flips += T.flip_to_delaunay();
  }
  state.counters["vertices"] = static_cast<double>(m.V.rows());
  state.counters["flips"] = static_cast<double>(flips) / state.iterations();
}
BENCHMARK(BM_FlipToDelaunay)->Arg(2)->Arg(4)->Unit(benchmark::kMillisecond)->Iterations(1);

// Cost of flattening one vertex (the dry run used by the error metric, and the committed one).
void BM_ComputeFlattening(benchmark::State& state) {
  const TriangleMesh& m = mesh("spot_subdiv.obj");
  const auto T = IntrinsicTriangulation::from_mesh(m.V, m.F);
  Index v = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(T.compute_flattening(v, state.range(0) == 0 ? 1e-13 : 1e-7));
    if (++v == T.num_vertices()) v = 0;
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ComputeFlattening)->Arg(0)->Arg(1);

// Memory of the triangulation type itself.
void BM_BytesPerVertex(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fertility.off")) return;
  const TriangleMesh& m = mesh("fertility.off", static_cast<int>(state.range(0)));
  double bytes = 0;
  for (auto _ : state) {
    const auto T = IntrinsicTriangulation::from_mesh(m.V, m.F);
    bytes = static_cast<double>(T.memory_bytes());
  }
  state.counters["vertices"] = static_cast<double>(m.V.rows());
  state.counters["bytes_per_vertex"] = bytes / m.V.rows();
}
BENCHMARK(BM_BytesPerVertex)->Arg(4)->Unit(benchmark::kMillisecond)->Iterations(1);

// ICE coarsening: arg 0 = the case (0: spot_subdiv 24,755 -> 1,000; 1: fertility Loop x4,
// 1.15M -> 10,000), arg 1 = threads (1: the exact serial greedy order, one region; 2: the default
// regions on two threads). Wall time (UseRealTime): the parallel mode's work runs on several threads.
void BM_Coarsen(benchmark::State& state) {
  const bool large = state.range(0) == 1;
  if (large && !ice_bench::has_mesh(state, "fertility.off")) return;
  const TriangleMesh& m = large ? mesh("fertility.off", 4) : mesh("spot_subdiv.obj");
  CoarsenOptions options;
  options.target_vertices = large ? 10000 : 1000;
  options.threads = static_cast<int>(state.range(1));
  options.regions = options.threads == 1 ? 1 : 0;
  CoarsenResult result;
  const double rss_before = peak_rss_mb();
  for (auto _ : state) {
    state.PauseTiming();
    auto T = IntrinsicTriangulation::from_mesh(m.V, m.F);
    state.ResumeTiming();
    result = coarsen(T, options);
  }
  state.counters["input_vertices"] = static_cast<double>(m.V.rows());
  state.counters["threads"] = options.threads;
  state.counters["parallel_removed"] = result.parallel_removed;
  state.counters["removals_per_s"] = result.removed / result.seconds;
  state.counters["evaluations_per_removal"] = static_cast<double>(result.cost_evaluations) / result.removed;
  state.counters["max_cost"] = result.max_cost;
  state.counters["peak_rss_mb"] = peak_rss_mb();
  state.counters["rss_growth_bytes_per_vertex"] = (peak_rss_mb() - rss_before) * 1024 * 1024 / m.V.rows();
}
BENCHMARK(BM_Coarsen)->Args({0, 1})->Args({0, 2})->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_Coarsen)->Args({1, 1})->Args({1, 2})->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

// A point cloud against the mesh it comes from: spot_subdiv Loop ×3 (1,584,194 vertices) coarsened
// to 5 % with its fine intrinsic Delaunay mesh, as the tools set up a proxy (arg 0), and the same
// vertices as a point cloud (arg 1): its consistent local Delaunay triangles, then the coarse space and
// fine mesh through their tufted cover. The default coarsening (regions in parallel) both; the
// triangles use the hardware's threads. Counters: the phases' seconds.
void BM_PointCloudCoarsening(benchmark::State& state) {
  const bool cloud = state.range(0) == 1;
  const TriangleMesh& m = mesh("spot_subdiv.obj", 3);
  CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.nonmanifold = NonmanifoldInput::tufted_cover;
  double triangles_seconds = 0, coarse_seconds = 0;
  Index coarse_vertices = 0;
  const double rss_before = peak_rss_mb();
  for (auto _ : state) {
    auto mark = std::chrono::steady_clock::now();
    TriangleMesh input{m.V, cloud ? point_cloud_triangles(m.V) : m.F};
    triangles_seconds = cloud ? ice_bench::seconds_since(mark) : 0.0;
    FineMesh fine;
    const CoarseSpace space = build_coarse_space(input, options, &fine);
    coarse_seconds = ice_bench::seconds_since(mark);
    coarse_vertices = space.mesh.vertex_count;
    benchmark::DoNotOptimize(fine.L.data());
  }
  state.counters["input_vertices"] = static_cast<double>(m.V.rows());
  state.counters["coarse_vertices"] = coarse_vertices;
  state.counters["triangles_s"] = triangles_seconds;
  state.counters["coarse_space_and_fine_mesh_s"] = coarse_seconds;
  state.counters["peak_rss_growth_mb"] = peak_rss_mb() - rss_before;
}
BENCHMARK(BM_PointCloudCoarsening)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

// The removals of BM_Coarsen without what makes them greedy: no cost evaluation, no queue. Passes
// over the vertices in index order each remove an independent set (a vertex is skipped when it or a
// neighbour was touched earlier in the pass), through the same steps as coarsen(): one Newton
// flattening (compute_flattening, then reused as the hint), the metric's prepared records,
// remove_vertex, the Delaunay flips around it, the records written. Boundary vertices are left.
// What any order of removals costs at least, so it bounds how fast ICE coarsening can be made by
// changing the order alone (issue #22: the 300 k removals/s floor, the one-shot proxy's floors).
void BM_RemovalsOnly(benchmark::State& state) {
  const bool large = state.range(0) == 1;
  if (large && !ice_bench::has_mesh(state, "fertility.off")) return;
  const TriangleMesh& m = large ? mesh("fertility.off", 4) : mesh("spot_subdiv.obj");
  const Index target = large ? 10000 : 1000;
  Index removed = 0, failed = 0;
  double seconds = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto T = IntrinsicTriangulation::from_mesh(m.V, m.F);
    state.ResumeTiming();
    const auto start = std::chrono::steady_clock::now();
    T.maintain_frames(true);
    IntrinsicErrorMetric metric(T, 0.0);
    IntrinsicErrorMetric::RemovalPlan plan;
    const Index n = T.num_input_vertices();
    std::vector<std::uint8_t> touched(static_cast<std::size_t>(n)), failures(static_cast<std::size_t>(n));
    std::vector<Index> around, changed;
    removed = failed = 0;
    for (Index removed_in_pass = 1; removed_in_pass > 0 && T.num_vertices() > target;) {
      removed_in_pass = 0;
      std::fill(touched.begin(), touched.end(), 0);
      for (Index v = 0; v < n && T.num_vertices() > target; ++v) {
        if (!T.vertex_alive(v) || touched[v] || failures[v] >= 3 || T.is_boundary_vertex(v)) continue;
        bool free = true;
        around.clear();
        T.for_each_outgoing(v, [&](Index h) {
          around.push_back(T.head(h));
          free = free && !touched[T.head(h)];
        });
        if (!free) continue;
        const FlattenResult flattening = T.compute_flattening(v);
        if (!flattening.success || !metric.prepare_removal(T, v, plan, flattening.log_scale)) {
          ++failures[v];
          continue;
        }
        changed.clear();
        if (T.remove_vertex(v, &changed, &around, flattening.log_scale) == RemovalStatus::Removed) {
          metric.apply_removal(plan);
          ++removed, ++removed_in_pass;
        } else {
          ++failed, ++failures[v];
        }
        T.flip_to_delaunay_around(changed, &around);
        touched[v] = 1;
        for (Index u : around) touched[u] = 1;
      }
    }
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  state.counters["input_vertices"] = static_cast<double>(m.V.rows());
  state.counters["removed"] = static_cast<double>(removed);
  state.counters["failed"] = static_cast<double>(failed);
  state.counters["removals_per_s"] = removed / seconds;
}
BENCHMARK(BM_RemovalsOnly)->Arg(0)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_RemovalsOnly)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

}  // namespace
