// The coarse-proxy pipeline against the fine solve, side by side in one run (zero-mean Poisson with
// the demo-style smooth source; OpenBLAS under CHOLMOD with OPENBLAS_NUM_THREADS threads; the
// proxy's fine-size passes with OMP_NUM_THREADS threads, default all cores):
//
//   ice_bench --benchmark_filter=Proxy
//
// Sizes: spot_subdiv.obj (24,755 vertices) Loop-subdivided 0, 1, 2, 3 times: 24,755 / 98,986 /
// 395,906 / 1,583,586 vertices. Budgets: 1 % and 5 % of the vertices. Every phase is a counter
// (seconds): the fine one-shot (assemble + analyse/factor + solve), the proxy one-shot (coarsen +
// assemble + factor + solve + prolong), the per-right-hand-side costs — of the first solve
// (speedup_per_rhs) and the mean of 5 more (speedup_per_rhs_warm) — and their ratios.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "fem/operators.h"
#include "fem/problems.h"
#include "ice/coarse_space.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "bench_support.h"

using namespace ice;

namespace {

using ice_bench::seconds_since;

const TriangleMesh& spot_subdiv(int levels) { return ice_bench::subdivided_mesh("spot_subdiv.obj", levels); }

// A smooth source: a sum of two Gaussian bumps of opposite sign (its mean is removed by the solvers).
Eigen::VectorXd smooth_source(const Positions& V) {
  const double sigma = 0.15 * (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
  Eigen::Index a = 0, b = 0;
  V.col(0).maxCoeff(&a);
  V.col(0).minCoeff(&b);
  Eigen::VectorXd f(V.rows());
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    f(i) = std::exp(-(V.row(i) - V.row(a)).squaredNorm() / (2 * sigma * sigma)) -
           std::exp(-(V.row(i) - V.row(b)).squaredNorm() / (2 * sigma * sigma));
  return f;
}

// Args: Loop subdivisions of spot_subdiv (0–3), coarse budget in percent, coarsening threads (1: the
// exact serial greedy order, one region; more: the default regions on that many threads), the
// fine CHOLMOD's fill-reducing ordering (fem::CholeskyOrdering: 0 CHOLMOD's default strategy, 1 AMD
// only, the fastest at 1.6M vertices: BM_MultigridCholmod).
void BM_ProxyVsFine(benchmark::State& state) {
  const TriangleMesh& m = spot_subdiv(static_cast<int>(state.range(0)));
  const double budget = state.range(1) / 100.0;
  const int threads = static_cast<int>(state.range(2));
  const auto ordering = static_cast<fem::CholeskyOrdering>(state.range(3));
  const Eigen::VectorXd f = smooth_source(m.V);
  ice::IntrinsicMesh fine_mesh{m.F, {}, {}, static_cast<ice::Index>(m.V.rows())};  // its lengths are timed below
  for (auto _ : state) {
    auto t = std::chrono::steady_clock::now();
    // Fine one-shot.
    fine_mesh.L = face_lengths_from_positions(m.V, m.F);
    const auto Lf = fem::cotan_laplacian(fine_mesh);
    const auto Mf = fem::mass_matrix(fine_mesh, fem::MassKind::lumped);
    const double fine_assemble = seconds_since(t);
    const auto fine = fem::PoissonSolver::zero_mean(Lf, Mf, {}, ordering);
    const double fine_factor = seconds_since(t);
    const Eigen::VectorXd u_fine = fine.solve(f);
    const double fine_solve = seconds_since(t);
    // Proxy one-shot: the library's pipeline (triangulation, coarsening, coarse mesh and P).
    CoarseSpaceOptions options;
    options.coarsen.target_ratio = budget;
    options.coarsen.threads = threads;
    options.coarsen.regions = threads == 1 ? 1 : 0;
    CoarseSpace space = build_coarse_space(m, options);
    const CompactMesh& coarse = space.mesh;
    const double coarsen_time = seconds_since(t);
    const fem::CoarseProxy proxy(fine_mesh, coarse, std::move(space.P), {fem::CoarseOperatorKind::intrinsic});
    const double proxy_assemble = seconds_since(t);
    const fem::ProxyPoissonSolver solver(proxy);
    const double proxy_factor = seconds_since(t);
    const Eigen::VectorXd u_proxy = solver.solve(f);  // restrict + coarse solve + prolong
    const double proxy_solve = seconds_since(t);

    // Per right-hand side once warm (several solves with the same factorisations, as a user with
    // many right-hand sides sees): the mean of kRepeat further solves of each.
    constexpr int kRepeat = 5;
    double fine_repeat = 0, proxy_repeat = 0;
    for (int r = 0; r < kRepeat; ++r) {
      t = std::chrono::steady_clock::now();
      benchmark::DoNotOptimize(fine.solve(f).data());
      fine_repeat += seconds_since(t) / kRepeat;
      benchmark::DoNotOptimize(solver.solve(f).data());
      proxy_repeat += seconds_since(t) / kRepeat;
    }

    const double fine_total = fine_assemble + fine_factor + fine_solve;
    const double proxy_total = coarsen_time + proxy_assemble + proxy_factor + proxy_solve;
    state.counters["vertices"] = static_cast<double>(m.V.rows());
    state.counters["coarse_vertices"] = static_cast<double>(coarse.to_input.size());
    state.counters["coarsen_threads"] = threads;
    state.counters["fine_ordering_amd"] = ordering == fem::CholeskyOrdering::amd;
    state.counters["fine_assemble_s"] = fine_assemble;
    state.counters["fine_factor_s"] = fine_factor;
    state.counters["fine_solve_s"] = fine_solve;
    state.counters["coarsen_s"] = coarsen_time;
    state.counters["proxy_assemble_s"] = proxy_assemble;
    state.counters["proxy_factor_s"] = proxy_factor;
    state.counters["proxy_solve_prolong_s"] = proxy_solve;
    state.counters["speedup_one_shot"] = fine_total / proxy_total;
    state.counters["speedup_per_rhs"] = fine_solve / proxy_solve;
    state.counters["fine_solve_warm_s"] = fine_repeat;
    state.counters["proxy_solve_prolong_warm_s"] = proxy_repeat;
    state.counters["speedup_per_rhs_warm"] = fine_repeat / proxy_repeat;
    state.counters["rel_l2_error"] = fem::relative_l2_error(u_proxy, u_fine, proxy.fine_mass());
  }
}
BENCHMARK(BM_ProxyVsFine)
    ->ArgsProduct({{0, 1, 2, 3}, {1, 5}, {1}, {0}})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();
// The largest size again with the coarsener's parallel mode (wall time: it runs on two threads), and
// against the fastest CHOLMOD configuration (AMD only), serial and parallel.
BENCHMARK(BM_ProxyVsFine)
    ->Args({3, 1, 2, 0})
    ->Args({3, 5, 2, 0})
    ->Args({3, 1, 1, 1})
    ->Args({3, 1, 2, 1})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

}  // namespace

namespace {

// The polished proxy (fem::PolishOptions) against the fastest fine direct solve (CHOLMOD, AMD only),
// in one run: per tolerance, the iterations, the true error against CHOLMOD's solution, and the cost
// of one polished solve (restrict + coarse solve + prolong + polish iterations, warm: the mean of 3)
// against the fine analyse + factor + solve and against the fine triangular solves alone. The polish
// setup (fine Laplacian, Galerkin PᵀLP and its factorisation, smoother data) is reported apart: it is
// paid once per coarse space, like the proxy's own factorisation.
// Args: Loop subdivisions of spot_subdiv (0–3), coarse budget in percent, coarse operators (0
// intrinsic, 1 Galerkin).
void BM_PolishedProxy(benchmark::State& state) {
  const TriangleMesh& m = spot_subdiv(static_cast<int>(state.range(0)));
  const double budget = state.range(1) / 100.0;
  const auto kind = state.range(2) ? fem::CoarseOperatorKind::galerkin : fem::CoarseOperatorKind::intrinsic;
  const Eigen::VectorXd f = smooth_source(m.V);
  const std::map<std::string, double> tolerances = {{"5e-3", 5e-3}, {"1e-3", 1e-3}, {"1e-6", 1e-6}};
  ice::IntrinsicMesh fine_mesh{m.F, {}, {}, static_cast<ice::Index>(m.V.rows())};  // its lengths are timed below
  for (auto _ : state) {
    auto t = std::chrono::steady_clock::now();
    fine_mesh.L = face_lengths_from_positions(m.V, m.F);
    const auto Lf = fem::cotan_laplacian(fine_mesh);
    const auto Mf = fem::mass_matrix(fine_mesh, fem::MassKind::lumped);
    seconds_since(t);
    const auto fine = fem::PoissonSolver::zero_mean(Lf, Mf, {}, fem::CholeskyOrdering::amd);
    const double fine_factor = seconds_since(t);
    const Eigen::VectorXd u_fine = fine.solve(f);
    const double fine_solve = seconds_since(t);
    CoarseSpaceOptions options;
    options.coarsen.target_ratio = budget;
    CoarseSpace space = build_coarse_space(m, options);
    const double coarsen_time = seconds_since(t);
    const fem::CoarseProxy proxy(fine_mesh, space.mesh, std::move(space.P), {kind});
    const double proxy_assemble = seconds_since(t);
    state.counters["vertices"] = static_cast<double>(m.V.rows());
    state.counters["coarse_vertices"] = static_cast<double>(proxy.coarse_size());
    state.counters["fine_factor_s"] = fine_factor;
    state.counters["fine_solve_s"] = fine_solve;
    state.counters["coarsen_s"] = coarsen_time;
    state.counters["proxy_assemble_s"] = proxy_assemble;
    state.counters["plain_error"] = fem::relative_l2_error(fem::ProxyPoissonSolver(proxy).solve(f), u_fine, Mf);
    for (const auto& [name, tolerance] : tolerances) {
      fem::PolishOptions polish;
      polish.tolerance = tolerance;
      t = std::chrono::steady_clock::now();
      const fem::ProxyPoissonSolver solver(proxy, {}, polish);
      const double setup = seconds_since(t);
      fem::PolishReport report;
      const Eigen::VectorXd u = solver.solve(f, {}, nullptr, &report);
      seconds_since(t);
      constexpr int kRepeat = 3;
      for (int r = 0; r < kRepeat; ++r) benchmark::DoNotOptimize(solver.solve(f).data());
      const double per_solve = seconds_since(t) / kRepeat;
      state.counters["T" + name + "_iterations"] = report.iterations;
      state.counters["T" + name + "_error"] = fem::relative_l2_error(u, u_fine, Mf);
      state.counters["T" + name + "_setup_s"] = setup;  // coarse factor + polish setup
      state.counters["T" + name + "_per_solve_s"] = per_solve;
      state.counters["T" + name + "_fine_factor_solve_over_per_solve"] = (fine_factor + fine_solve) / per_solve;
      state.counters["T" + name + "_fine_solve_over_per_solve"] = fine_solve / per_solve;
    }
  }
}
BENCHMARK(BM_PolishedProxy)
    ->ArgsProduct({{0, 3}, {1, 5}, {0, 1}})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

}  // namespace

namespace {

// Stream bandwidth of this machine on `threads` threads: a = b + s·c over arrays of 1 GiB each (beyond any cache),
// the best of 3 passes (bytes: two reads and one write per element; write-allocate traffic not
// counted, so the figure is what a kernel that streams its arrays once can reach).
double stream_bandwidth(int threads) {
  constexpr std::size_t kCount = std::size_t(128) << 20;
  std::vector<double> a(kCount), b(kCount, 1.0), c(kCount, 2.0);
  double best = 0;
  for (int pass = 0; pass < 3; ++pass) {
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::thread> team;
    for (int t = 0; t < threads; ++t)
      team.emplace_back([&, t] {
        const std::size_t begin = kCount * t / threads, end = kCount * (t + 1) / threads;
        for (std::size_t i = begin; i < end; ++i) a[i] = b[i] + 0.5 * c[i];
      });
    for (std::thread& thread : team) thread.join();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    best = std::max(best, 3.0 * sizeof(double) * kCount / seconds);
  }
  benchmark::DoNotOptimize(a.data());
  return best;
}

// The proxy's cold setup phase by phase (ICE to 1 %, Galerkin operators of the smoothed P on the
// fine intrinsic Delaunay mesh, as poisson-coarse and ice::proxy::PoissonSolver set up by default),
// each fine-size pass beside its bandwidth bound: the bytes it must at least read and write (its inputs and outputs once) over
// the measured stream bandwidth. The removals are the coarsener's own (BM_Coarsen, BM_RemovalsOnly).
// Args: Loop subdivisions of spot_subdiv (2: 395,906 vertices; 3: 1,583,586), coarsening threads.
//
//   ice_bench --benchmark_filter=ProxySetupPhases
void BM_ProxySetupPhases(benchmark::State& state) {
  const TriangleMesh& m = spot_subdiv(static_cast<int>(state.range(0)));
  const int threads = static_cast<int>(state.range(1));
  const double bandwidth = stream_bandwidth(threads);
  for (auto _ : state) {
    auto t = std::chrono::steady_clock::now();
    CoarseSpaceOptions options;
    options.coarsen.target_ratio = 0.01;
    options.coarsen.threads = threads;
    options.coarsen.regions = threads == 1 ? 1 : 0;  // one thread: the serial greedy order
    FineMesh fine;
    CoarseSpace space = build_coarse_space(m, options, &fine);
    const double coarsen = seconds_since(t);
    const double n = static_cast<double>(m.V.rows()), faces = static_cast<double>(fine.F.rows());
    const fem::SparseMatrix L = fem::cotan_laplacian(fine);
    const double laplacian = seconds_since(t);
    const fem::SparseMatrix M = fem::mass_matrix(fine, fem::MassKind::lumped);
    const double mass = seconds_since(t);
    // The default prolongation of a Galerkin proxy without Dirichlet vertices: P smoothed once.
    const fem::SparseMatrix smoothed = fem::smoothed_prolongation(space.P, L);
    const double smoothing = seconds_since(t);
    const auto [Lc, Mc] = fem::galerkin(smoothed, L, M);
    const double galerkin = seconds_since(t);
    const fem::PoissonSolver coarse_solver = fem::PoissonSolver::zero_mean(Lc, Mc);  // as the proxy solver factors
    const double factor = seconds_since(t);
    benchmark::DoNotOptimize(&coarse_solver);
    const CoarseSpaceSummary& summary = space.summary;
    const double removals = summary.ice->seconds;
    // Bytes each pass must move at least: faces (3 ints) and lengths (3 doubles) in; a matrix out
    // or in as its column starts, row indices and values.
    const auto matrix_bytes = [](const fem::SparseMatrix& A) { return 4.0 * (A.cols() + 1) + 12.0 * A.nonZeros(); };
    const double mesh_bytes = faces * (12 + 24);
    const double P_bytes = matrix_bytes(space.P);
    state.counters["vertices"] = n;
    state.counters["coarse_vertices"] = static_cast<double>(space.P.cols());
    state.counters["stream_GBps"] = bandwidth / 1e9;
    state.counters["triangulation_s"] = summary.triangulation_seconds;
    state.counters["fine_idt_s"] = summary.fine_mesh_seconds;
    state.counters["removals_s"] = removals;
    state.counters["prolongation_s"] = summary.prolongation_seconds;
    state.counters["laplacian_s"] = laplacian;
    state.counters["laplacian_bound_s"] = (mesh_bytes + matrix_bytes(L)) / bandwidth;
    state.counters["mass_s"] = mass;
    state.counters["mass_bound_s"] = (mesh_bytes + 8 * n) / bandwidth;
    // Smoothing: P and L read, the smoothed P written. Galerkin: the smoothed P read three times
    // (its columns, and a row-major copy written and read), L and M's diagonal once.
    state.counters["smoothing_s"] = smoothing;
    state.counters["smoothing_bound_s"] = (P_bytes + matrix_bytes(L) + matrix_bytes(smoothed)) / bandwidth;
    state.counters["smoothed_P_per_row"] = static_cast<double>(smoothed.nonZeros()) / n;
    state.counters["galerkin_s"] = galerkin;
    state.counters["galerkin_bound_s"] = (3 * matrix_bytes(smoothed) + matrix_bytes(L) + 8 * n) / bandwidth;
    state.counters["coarse_factor_s"] = factor;
    state.counters["non_removal_s"] = coarsen - removals + laplacian + mass + smoothing + galerkin + factor;
    state.counters["setup_s"] = coarsen + laplacian + mass + smoothing + galerkin + factor;
  }
}
BENCHMARK(BM_ProxySetupPhases)->Args({2, 2})->Args({3, 1})->Args({3, 2})->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace
