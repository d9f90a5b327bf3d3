// Benchmarks of the finite-element kernels and the QEM baseline (single thread):
// assemble (cotan Laplacian + lumped mass), factor (CHOLMOD, zero-mean Poisson), solve, prolong
// (P·u), QEM decimation and its closest-point map.
//
//   ice_bench --benchmark_filter='Assemble|Factor|Solve|Prolong|Qem'
//
// The argument is the number of Loop subdivisions of spot.obj (2,930 vertices): 0, 1, 2 give 2,930,
// 11,716 and 46,850 vertices, so a regression shows as a change at a given size and the scaling is
// visible. Prolongation uses an ICE coarsening to 5% of the vertices.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <map>
#include <string>

#include "fem/operators.h"
#include "fem/problems.h"
#include "ice/coarsen.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/prolongation.h"
#include "ice/qem.h"
#include "bench_support.h"

using namespace ice;

namespace {

// Loop-subdivided spot, loaded once per process per level.
const TriangleMesh& spot(int subdivisions) { return ice_bench::subdivided_mesh("spot.obj", subdivisions); }

void set_size(benchmark::State& state, const TriangleMesh& m) {
  state.counters["vertices"] = static_cast<double>(m.V.rows());
  state.SetItemsProcessed(state.iterations() * m.V.rows());
}

void BM_Assemble(benchmark::State& state) {
  const TriangleMesh& m = spot(static_cast<int>(state.range(0)));
  const ice::IntrinsicMesh mesh = ice::intrinsic_mesh(m);
  for (auto _ : state) {
    fem::SparseMatrix A = fem::cotan_laplacian(mesh);
    fem::SparseMatrix M = fem::mass_matrix(mesh);
    benchmark::DoNotOptimize(A.nonZeros() + M.nonZeros());
  }
  set_size(state, m);
}
BENCHMARK(BM_Assemble)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);

void BM_Factor(benchmark::State& state) {
  const TriangleMesh& m = spot(static_cast<int>(state.range(0)));
  const ice::IntrinsicMesh mesh = ice::intrinsic_mesh(m);
  const fem::SparseMatrix A = fem::cotan_laplacian(mesh), M = fem::mass_matrix(mesh);
  for (auto _ : state) {
    fem::PoissonSolver solver = fem::PoissonSolver::zero_mean(A, M);
    benchmark::DoNotOptimize(&solver);
  }
  set_size(state, m);
}
BENCHMARK(BM_Factor)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);

void BM_Solve(benchmark::State& state) {
  const TriangleMesh& m = spot(static_cast<int>(state.range(0)));
  const ice::IntrinsicMesh mesh = ice::intrinsic_mesh(m);
  const fem::SparseMatrix A = fem::cotan_laplacian(mesh), M = fem::mass_matrix(mesh);
  const fem::PoissonSolver solver = fem::PoissonSolver::zero_mean(A, M);
  const Eigen::VectorXd f = m.V.col(0).array().sin();
  for (auto _ : state) {
    Eigen::VectorXd u = solver.solve(f);
    benchmark::DoNotOptimize(u.data());
  }
  set_size(state, m);
}
BENCHMARK(BM_Solve)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);

void BM_Prolong(benchmark::State& state) {
  const TriangleMesh& m = spot(static_cast<int>(state.range(0)));
  IntrinsicTriangulation T = IntrinsicTriangulation::from_mesh(m.V, m.F);
  CoarsenOptions options;
  options.target_ratio = 0.05;
  coarsen(T, options);
  const CompactMesh coarse = T.compact();
  const Eigen::SparseMatrix<double> P = prolongation(T, coarse);
  const Eigen::VectorXd uc = Eigen::VectorXd::LinSpaced(P.cols(), 0, 1);
  for (auto _ : state) {
    Eigen::VectorXd u = P * uc;
    benchmark::DoNotOptimize(u.data());
  }
  set_size(state, m);
}
BENCHMARK(BM_Prolong)->DenseRange(0, 2)->Unit(benchmark::kMicrosecond);

// QEM decimation to 5% + closest-point map (the baseline's "coarsen" phase in ice-report).
void BM_QemCoarsen(benchmark::State& state) {
  const TriangleMesh& m = spot(static_cast<int>(state.range(0)));
  QemOptions options;
  options.target_ratio = 0.05;
  for (auto _ : state) {
    QemResult r = qem_coarsen(m, options);
    benchmark::DoNotOptimize(r.P.nonZeros());
    state.counters["map_share"] = r.map_seconds / (r.map_seconds + r.decimate_seconds);
  }
  set_size(state, m);
}
BENCHMARK(BM_QemCoarsen)->DenseRange(0, 1)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace
