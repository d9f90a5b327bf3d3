// Galerkin multigrid on ICE hierarchies against CHOLMOD (and hypre's BoomerAMG-preconditioned CG
// when ICE_HAVE_HYPRE) on Loop-subdivided fandisk meshes: 2, 3, 4 levels = 103,570 / 414,274 /
// 1,657,090 vertices.
//
// System: the screened Poisson matrix A = L + εM (cotan Laplacian + lumped mass of the subdivided
// mesh, ε = 1 / total area: as ill-conditioned as a Poisson problem on the surface), right-hand side
// b = M f with a smooth-plus-rough f; every solver is asked for ‖b − Ax‖₂ ≤ 1e-8 ‖b‖₂.
//
// Every benchmark runs once per size (Iterations(1)) and reports seconds as counters:
//   multigrid:  hierarchy_s (ICE coarsening), numeric_setup_s (Galerkin products + coarsest CHOLMOD),
//               setup_s = both, solve_s, iterations, factor (convergence factor per PCG iteration),
//               cold_s = setup_s + solve_s, solve10_s (10 more right-hand sides one by one), total10_s =
//               setup_s + solve10_s, block10_s (the same 10 together, MultigridSolver::solve_multiple),
//               block_total10_s = setup_s + block10_s,
//               peak_mb (peak growth of the malloc heap in use during setup + solves, sampled every 2 ms;
//               the fine matrix, mesh and right-hand sides exist before and are not counted)
//   cholmod:    (per ordering: default strategy, AMD, METIS, nested dissection) analyze_s, factor_s, solve_s, cold_s, solve10_s, total10_s = analyze + factor + 10 solves,
//               block10_s (the same 10 in one supernodal solve with a 10-column right-hand side),
//               block_total10_s = analyze + factor + block10_s, peak_mb
//   boomeramg:  setup_s, solve_s, iterations, factor, cold_s, solve10_s, total10_s, peak_mb
//   amgcl:      (with -DICE_AMGCL_DIR, per tolerance: 1e-8 and 1e-4) the same counters
// and, for 100 right-hand sides (set up once, solve many): BM_MultigridBlock100 (ICE, the hierarchy from
// a store, block V-cycles), BM_MultigridCholmodBlock100 (AMD, one block solve), BM_MultigridAMGCL100.
// Run: ice_bench --benchmark_filter=Multigrid (a few minutes; the 1.6M hierarchy dominates).
#include <benchmark/benchmark.h>

#include <malloc.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>
#include <fstream>
#include <map>
#include <string>

#include "bench_support.h"
#include "fem/cholesky.h"
#include "fem/multigrid.h"
#include "fem/operators.h"
#include "ice/hierarchy.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/proxy/multigrid.h"

#ifdef ICE_HAVE_AMGCL
#include <amgcl/adapter/crs_tuple.hpp>
#include <amgcl/amg.hpp>
#include <amgcl/backend/builtin.hpp>
#include <amgcl/coarsening/smoothed_aggregation.hpp>
#include <amgcl/make_solver.hpp>
#include <amgcl/relaxation/spai0.hpp>
#include <amgcl/solver/cg.hpp>
#endif

#ifdef ICE_HAVE_HYPRE
#include <HYPRE.h>
#include <HYPRE_krylov.h>
#include <HYPRE_parcsr_ls.h>
#include <mpi.h>
#endif

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Heap bytes in use (glibc mallinfo2: arena + mmapped blocks), in MiB. Unlike the RSS this does not
// hide allocations that re-use pages freed by earlier benchmarks.
double rss_mb() {
  const struct mallinfo2 m = mallinfo2();
  return static_cast<double>(m.uordblks + m.hblkhd) / (1024.0 * 1024.0);
}

// Peak growth of the heap in use over the lifetime of the object, sampled every 2 ms by a thread
// (memory allocated with mmap outside malloc, e.g. by MPI, is not seen).
class PeakMemory {
 public:
  PeakMemory() : base_(rss_mb()), peak_(base_), thread_([this] {
    while (!stop_) {
      const double r = rss_mb();
      double p = peak_.load();
      while (r > p && !peak_.compare_exchange_weak(p, r)) {
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }) {}
  ~PeakMemory() { stop(); }
  /// Peak growth in MiB so far (stops sampling).
  double stop() {
    if (!stop_.exchange(true)) thread_.join();
    return std::max(0.0, std::max(peak_.load(), rss_mb()) - base_);
  }

 private:
  double base_;
  std::atomic<double> peak_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

struct Problem {
  ice::TriangleMesh mesh;
  fem::SparseMatrix A, M;
  Eigen::MatrixXd B;  // 11 right-hand sides
};

const Problem& problem(int levels) {
  static std::map<int, Problem> cache;
  auto it = cache.find(levels);
  if (it != cache.end()) return it->second;
  Problem p;
  p.mesh = ice::loop_subdivide(ice::load_mesh(ice_bench::mesh_path("fandisk.obj")), levels);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(p.mesh.V, p.mesh.F);
  const ice::IntrinsicMesh intrinsic = ice::intrinsic_mesh(p.mesh.F, lengths);
  p.M = fem::mass_matrix(intrinsic);
  p.A = fem::cotan_laplacian(intrinsic) + (1.0 / p.M.sum()) * p.M;
  const Eigen::Index n = p.mesh.V.rows();
  p.B.resize(n, 11);
  for (int j = 0; j < 11; ++j) {
    Eigen::VectorXd f(n);
    for (Eigen::Index i = 0; i < n; ++i)
      f(i) = std::sin((j + 1) * 0.1 * p.mesh.V(i, 0)) + std::cos(0.07 * p.mesh.V(i, 1) + j) +
             0.3 * std::sin(17.0 * static_cast<double>(i) + j);
    p.B.col(j) = p.M * f;
  }
  return cache.emplace(levels, std::move(p)).first->second;
}

// 100 more right-hand sides of the same kind, for the many-sources benchmarks (made on first use).
const Eigen::MatrixXd& hundred_sources(int levels) {
  static std::map<int, Eigen::MatrixXd> cache;
  auto it = cache.find(levels);
  if (it != cache.end()) return it->second;
  const Problem& p = problem(levels);
  const Eigen::Index n = p.mesh.V.rows();
  Eigen::MatrixXd F(n, 100);
  for (int j = 0; j < 100; ++j)
    for (Eigen::Index i = 0; i < n; ++i)
      F(i, j) = std::sin((j + 1) * 0.013 * p.mesh.V(i, 0)) + std::cos(0.07 * p.mesh.V(i, 1) + 0.3 * j) +
                0.3 * std::sin(17.0 * static_cast<double>(i) + j);
  return cache.emplace(levels, p.M * F).first->second;
}

void BM_MultigridICE(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fandisk.obj")) return;
  const Problem& p = problem(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    PeakMemory memory;
    auto t = Clock::now();
    const ice::Hierarchy H = ice::build_hierarchy(p.mesh);
    const double hierarchy = since(t);
    t = Clock::now();
    fem::MultigridOptions options;
    options.tolerance = 1e-8;
    fem::MultigridSolver solver(H.prolongations, options);
    solver.set_locality_order(H.fine_order);
    solver.setup(p.A);
    const double numeric = since(t);
    t = Clock::now();
    Eigen::VectorXd x = solver.solve(p.B.col(0));
    const double solve = since(t);
    const fem::MultigridReport first = solver.report();
    t = Clock::now();
    int iterations10 = 0;
    for (int j = 1; j <= 10; ++j) {
      x = solver.solve(p.B.col(j));
      iterations10 += solver.report().iterations;
      if (!solver.report().converged) state.SkipWithError("multigrid did not converge");
    }
    const double solve10 = since(t);
    t = Clock::now();
    const Eigen::MatrixXd X = solver.solve_multiple(p.B.rightCols(10));
    const double block10 = since(t);
    int block_iterations = 0;
    for (const auto& r : solver.reports()) {
      block_iterations = std::max(block_iterations, r.iterations);
      if (!r.converged) state.SkipWithError("multigrid (block) did not converge");
    }
    benchmark::DoNotOptimize(x.data());
    benchmark::DoNotOptimize(X.data());
    state.counters["vertices"] = static_cast<double>(p.A.rows());
    state.counters["levels"] = H.num_levels();
    state.counters["block10_s"] = block10;
    state.counters["block10_iterations"] = block_iterations;
    state.counters["block_total10_s"] = hierarchy + numeric + block10;
    state.counters["hierarchy_s"] = hierarchy;
    state.counters["numeric_setup_s"] = numeric;
    state.counters["setup_s"] = hierarchy + numeric;
    state.counters["solve_s"] = solve;
    state.counters["iterations"] = first.iterations;
    state.counters["factor"] = first.convergence_factor;
    state.counters["rel_residual"] = first.relative_residual;
    state.counters["cold_s"] = hierarchy + numeric + solve;
    state.counters["solve10_s"] = solve10;
    state.counters["iterations10_mean"] = iterations10 / 10.0;
    state.counters["total10_s"] = hierarchy + numeric + solve10;
    state.counters["op_complexity"] = solver.operator_complexity();
    state.counters["peak_mb"] = memory.stop();
    if (!first.converged) state.SkipWithError("multigrid did not converge");
  }
}

// Set up once, solve many: 100 right-hand sides by block V-cycles, the hierarchy loaded from a store
// (ice::proxy::multigrid_hierarchy; made and saved before the timing), against CHOLMOD-AMD's block
// solve (analyse + factor + one 100-column solve). Counters: load_s (the stored hierarchy),
// numeric_setup_s, block100_s, warm100_s = all three; cholmod: analyze_s, factor_s, block100_s, total100_s.
void BM_MultigridBlock100(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fandisk.obj")) return;
  const int levels = static_cast<int>(state.range(0));
  const Problem& p = problem(levels);
  const Eigen::MatrixXd& B = hundred_sources(levels);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "ice-bench-hierarchy-store";
  const ice::proxy::Store store({dir, ice::proxy::kDefaultStoreBytes});
  ice::proxy::multigrid_hierarchy(p.mesh, {}, store);  // cold: made and saved, untimed
  for (auto _ : state) {
    PeakMemory memory;
    auto t = Clock::now();
    const ice::proxy::MultigridHierarchy H = ice::proxy::multigrid_hierarchy(p.mesh, {}, store);
    const double load = since(t);
    if (H.cache.status != ice::proxy::CacheStatus::hit) state.SkipWithError("the stored hierarchy was not found");
    t = Clock::now();
    fem::MultigridSolver solver(H.prolongations, fem::MultigridOptions{});
    solver.set_locality_order(H.fine_order);
    solver.setup(p.A);
    const double numeric = since(t);
    t = Clock::now();
    const Eigen::MatrixXd X = solver.solve_multiple(B);
    const double block = since(t);
    double iterations = 0;
    for (const auto& r : solver.reports()) {
      iterations += r.iterations;
      if (!r.converged) state.SkipWithError("multigrid (block) did not converge");
    }
    benchmark::DoNotOptimize(X.data());
    state.counters["vertices"] = static_cast<double>(p.A.rows());
    state.counters["load_s"] = load;
    state.counters["numeric_setup_s"] = numeric;
    state.counters["block100_s"] = block;
    state.counters["iterations_mean"] = iterations / 100.0;
    state.counters["warm100_s"] = load + numeric + block;
    state.counters["peak_mb"] = memory.stop();
  }
}
BENCHMARK(BM_MultigridBlock100)->Arg(3)->Arg(4)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

void BM_MultigridCholmodBlock100(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fandisk.obj")) return;
  const int levels = static_cast<int>(state.range(0));
  const Problem& p = problem(levels);
  const Eigen::MatrixXd& B = hundred_sources(levels);
  for (auto _ : state) {
    PeakMemory memory;
    fem::CholeskySolver chol;
    chol.set_ordering(fem::CholeskyOrdering::amd);
    auto t = Clock::now();
    chol.analyze(p.A);
    const double analyze = since(t);
    t = Clock::now();
    chol.factorize(p.A);
    const double factor = since(t);
    t = Clock::now();
    const Eigen::MatrixXd X = chol.solve_multiple(B);
    const double block = since(t);
    benchmark::DoNotOptimize(X.data());
    state.counters["vertices"] = static_cast<double>(p.A.rows());
    state.counters["analyze_s"] = analyze;
    state.counters["factor_s"] = factor;
    state.counters["block100_s"] = block;
    state.counters["total100_s"] = analyze + factor + block;
    state.counters["peak_mb"] = memory.stop();
  }
}
BENCHMARK(BM_MultigridCholmodBlock100)->Arg(3)->Arg(4)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// Second argument: the fill-reducing ordering (fem::CholeskyOrdering: 0 CHOLMOD's default strategy,
// 1 AMD only, 2 METIS only, 3 CHOLMOD's nested dissection): a careful user picks the fastest.
void BM_MultigridCholmod(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fandisk.obj")) return;
  const Problem& p = problem(static_cast<int>(state.range(0)));
  const auto ordering = static_cast<fem::CholeskyOrdering>(state.range(1));
  state.SetLabel(fem::to_string(ordering));
  for (auto _ : state) {
    PeakMemory memory;
    fem::CholeskySolver chol;
    chol.set_ordering(ordering);
    auto t = Clock::now();
    chol.analyze(p.A);
    const double analyze = since(t);
    t = Clock::now();
    chol.factorize(p.A);
    const double factor = since(t);
    t = Clock::now();
    Eigen::VectorXd x = chol.solve(p.B.col(0));
    const double solve = since(t);
    const double residual = (p.B.col(0) - p.A * x).norm() / p.B.col(0).norm();
    t = Clock::now();
    for (int j = 1; j <= 10; ++j) x = chol.solve(p.B.col(j));
    const double solve10 = since(t);
    t = Clock::now();
    const Eigen::MatrixXd X = chol.solve_multiple(p.B.rightCols(10));
    const double block10 = since(t);
    benchmark::DoNotOptimize(x.data());
    benchmark::DoNotOptimize(X.data());
    state.counters["vertices"] = static_cast<double>(p.A.rows());
    state.counters["analyze_s"] = analyze;
    state.counters["factor_s"] = factor;
    state.counters["solve_s"] = solve;
    state.counters["rel_residual"] = residual;
    state.counters["cold_s"] = analyze + factor + solve;
    state.counters["solve10_s"] = solve10;
    state.counters["total10_s"] = analyze + factor + solve10;
    state.counters["block10_s"] = block10;
    state.counters["block_total10_s"] = analyze + factor + block10;
    state.counters["peak_mb"] = memory.stop();
  }
}

#ifdef ICE_HAVE_HYPRE
// BoomerAMG-preconditioned CG with the settings commonly recommended for 2D/surface Poisson
// problems: HMIS coarsening, extended+i interpolation (≤ 4 entries per row), strength threshold
// 0.25, hybrid symmetric Gauss–Seidel, one V(1,1)-cycle per CG iteration.
void BM_MultigridBoomerAMG(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fandisk.obj")) return;
  const Problem& p = problem(static_cast<int>(state.range(0)));
  static bool initialized = false;
  if (!initialized) {
    int flag = 0;
    MPI_Initialized(&flag);
    if (!flag) MPI_Init(nullptr, nullptr);
    HYPRE_Init();
    initialized = true;
  }
  const HYPRE_Int n = static_cast<HYPRE_Int>(p.A.rows());
  for (auto _ : state) {
    PeakMemory memory;
    auto t = Clock::now();
    HYPRE_IJMatrix ij;
    HYPRE_IJMatrixCreate(MPI_COMM_WORLD, 0, n - 1, 0, n - 1, &ij);
    HYPRE_IJMatrixSetObjectType(ij, HYPRE_PARCSR);
    std::vector<HYPRE_Int> sizes(static_cast<std::size_t>(n));
    for (HYPRE_Int i = 0; i < n; ++i) sizes[static_cast<std::size_t>(i)] = static_cast<HYPRE_Int>(p.A.outerIndexPtr()[i + 1] - p.A.outerIndexPtr()[i]);
    HYPRE_IJMatrixSetRowSizes(ij, sizes.data());
    HYPRE_IJMatrixInitialize(ij);
    std::vector<HYPRE_Int> cols;
    std::vector<double> vals;
    for (HYPRE_Int i = 0; i < n; ++i) {  // A is symmetric: column i is row i
      cols.clear();
      vals.clear();
      for (fem::SparseMatrix::InnerIterator it(p.A, i); it; ++it) {
        cols.push_back(static_cast<HYPRE_Int>(it.row()));
        vals.push_back(it.value());
      }
      HYPRE_Int count = static_cast<HYPRE_Int>(cols.size());
      HYPRE_IJMatrixSetValues(ij, 1, &count, &i, cols.data(), vals.data());
    }
    HYPRE_IJMatrixAssemble(ij);
    HYPRE_ParCSRMatrix A;
    HYPRE_IJMatrixGetObject(ij, reinterpret_cast<void**>(&A));
    std::vector<HYPRE_Int> rows(static_cast<std::size_t>(n));
    for (HYPRE_Int i = 0; i < n; ++i) rows[static_cast<std::size_t>(i)] = i;
    const auto make_vector = [&](const double* values, HYPRE_IJVector& v, HYPRE_ParVector& par) {
      HYPRE_IJVectorCreate(MPI_COMM_WORLD, 0, n - 1, &v);
      HYPRE_IJVectorSetObjectType(v, HYPRE_PARCSR);
      HYPRE_IJVectorInitialize(v);
      HYPRE_IJVectorSetValues(v, n, rows.data(), values);
      HYPRE_IJVectorAssemble(v);
      HYPRE_IJVectorGetObject(v, reinterpret_cast<void**>(&par));
    };
    Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
    HYPRE_IJVector ijb, ijx;
    HYPRE_ParVector b, x;
    make_vector(p.B.col(0).data(), ijb, b);
    make_vector(zero.data(), ijx, x);
    const double convert = since(t);

    t = Clock::now();
    HYPRE_Solver pcg, amg;
    HYPRE_ParCSRPCGCreate(MPI_COMM_WORLD, &pcg);
    HYPRE_PCGSetTol(pcg, 1e-8);
    HYPRE_PCGSetMaxIter(pcg, 500);
    HYPRE_PCGSetTwoNorm(pcg, 1);
    HYPRE_BoomerAMGCreate(&amg);
    HYPRE_BoomerAMGSetTol(amg, 0.0);
    HYPRE_BoomerAMGSetMaxIter(amg, 1);
    HYPRE_BoomerAMGSetCoarsenType(amg, 10);  // HMIS
    HYPRE_BoomerAMGSetInterpType(amg, 6);    // extended+i
    HYPRE_BoomerAMGSetPMaxElmts(amg, 4);
    HYPRE_BoomerAMGSetStrongThreshold(amg, 0.25);
    HYPRE_BoomerAMGSetRelaxType(amg, 6);  // hybrid symmetric Gauss-Seidel
    HYPRE_BoomerAMGSetNumSweeps(amg, 1);
    HYPRE_BoomerAMGSetPrintLevel(amg, 0);
    HYPRE_PCGSetPrecond(pcg, reinterpret_cast<HYPRE_PtrToSolverFcn>(HYPRE_BoomerAMGSolve),
                        reinterpret_cast<HYPRE_PtrToSolverFcn>(HYPRE_BoomerAMGSetup), amg);
    HYPRE_ParCSRPCGSetup(pcg, A, b, x);
    const double setup = since(t);
    t = Clock::now();
    HYPRE_ParCSRPCGSolve(pcg, A, b, x);
    const double solve = since(t);
    HYPRE_Int iterations = 0;
    double residual = 0;
    HYPRE_PCGGetNumIterations(pcg, &iterations);
    HYPRE_PCGGetFinalRelativeResidualNorm(pcg, &residual);
    t = Clock::now();
    for (int j = 1; j <= 10; ++j) {
      HYPRE_IJVectorSetValues(ijb, n, rows.data(), p.B.col(j).data());
      HYPRE_IJVectorSetValues(ijx, n, rows.data(), zero.data());
      HYPRE_ParCSRPCGSolve(pcg, A, b, x);
    }
    const double solve10 = since(t);
    state.counters["vertices"] = n;
    state.counters["convert_s"] = convert;
    state.counters["setup_s"] = setup;
    state.counters["solve_s"] = solve;
    state.counters["iterations"] = iterations;
    state.counters["factor"] = iterations > 0 ? std::pow(residual, 1.0 / iterations) : 0.0;
    state.counters["rel_residual"] = residual;
    state.counters["cold_s"] = setup + solve;
    state.counters["solve10_s"] = solve10;
    state.counters["total10_s"] = setup + solve10;
    state.counters["peak_mb"] = memory.stop();
    HYPRE_BoomerAMGDestroy(amg);
    HYPRE_ParCSRPCGDestroy(pcg);
    HYPRE_IJVectorDestroy(ijb);
    HYPRE_IJVectorDestroy(ijx);
    HYPRE_IJMatrixDestroy(ij);
  }
}
BENCHMARK(BM_MultigridBoomerAMG)->Arg(2)->Arg(3)->Arg(4)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
#endif

#ifdef ICE_HAVE_AMGCL
// AMGCL's smoothed aggregation with SPAI(0) smoothing preconditioning CG, its builtin OpenMP
// backend in double precision (its default setup, what its tutorials use for Poisson problems).
using AmgclBackend = amgcl::backend::builtin<double>;
using AmgclSolver = amgcl::make_solver<amgcl::amg<AmgclBackend, amgcl::coarsening::smoothed_aggregation, amgcl::relaxation::spai0>,
                                       amgcl::solver::cg<AmgclBackend>>;

// A as AMGCL's CRS arrays (A is symmetric: its column-major arrays are its row-major ones).
struct AmgclMatrix {
  explicit AmgclMatrix(const fem::SparseMatrix& A)
      : n(A.rows()), ptr(A.outerIndexPtr(), A.outerIndexPtr() + A.rows() + 1),
        col(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros()), val(A.valuePtr(), A.valuePtr() + A.nonZeros()) {}
  auto crs() { return std::tie(n, ptr, col, val); }
  ptrdiff_t n;
  std::vector<ptrdiff_t> ptr, col;
  std::vector<double> val;
};

// CG to ‖b − Ax‖ ≤ 10^−exponent ‖b‖, at most 500 iterations.
AmgclSolver::params amgcl_params(long exponent) {
  AmgclSolver::params prm;
  prm.solver.tol = std::pow(10.0, -static_cast<double>(exponent));
  prm.solver.maxiter = 500;
  return prm;
}

// Second argument: the tolerance's exponent (8: ‖b − Ax‖ ≤ 1e-8 ‖b‖, as the others; 4: about the
// proxy's accuracy).
void BM_MultigridAMGCL(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fandisk.obj")) return;
  const Problem& p = problem(static_cast<int>(state.range(0)));
  state.SetLabel("tol 1e-" + std::to_string(state.range(1)));
  for (auto _ : state) {
    PeakMemory memory;
    auto t = Clock::now();
    AmgclMatrix A(p.A);
    const ptrdiff_t n = A.n;
    const double convert = since(t);
    t = Clock::now();
    AmgclSolver solve(A.crs(), amgcl_params(state.range(1)));
    const double setup = since(t);
    std::vector<double> b(p.B.col(0).data(), p.B.col(0).data() + n), x(static_cast<std::size_t>(n), 0.0);
    t = Clock::now();
    auto [iterations, residual] = solve(b, x);
    const double solve1 = since(t);
    t = Clock::now();
    for (int j = 1; j <= 10; ++j) {
      b.assign(p.B.col(j).data(), p.B.col(j).data() + n);
      std::fill(x.begin(), x.end(), 0.0);
      solve(b, x);
    }
    const double solve10 = since(t);
    benchmark::DoNotOptimize(x.data());
    state.counters["vertices"] = static_cast<double>(n);
    state.counters["convert_s"] = convert;
    state.counters["setup_s"] = setup;
    state.counters["solve_s"] = solve1;
    state.counters["iterations"] = static_cast<double>(iterations);
    state.counters["factor"] = iterations > 0 ? std::pow(residual, 1.0 / static_cast<double>(iterations)) : 0.0;
    state.counters["rel_residual"] = residual;
    state.counters["cold_s"] = setup + solve1;
    state.counters["solve10_s"] = solve10;
    state.counters["total10_s"] = setup + solve10;
    state.counters["peak_mb"] = memory.stop();
  }
}
BENCHMARK(BM_MultigridAMGCL)->ArgsProduct({{2, 3, 4}, {8, 4}})->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// The 100 right-hand sides of BM_MultigridBlock100 one after another (AMGCL has no block solve for
// a scalar system): setup_s, solve100_s, total100_s. Second argument as above.
void BM_MultigridAMGCL100(benchmark::State& state) {
  if (!ice_bench::has_mesh(state, "fandisk.obj")) return;
  const int levels = static_cast<int>(state.range(0));
  const Problem& p = problem(levels);
  const Eigen::MatrixXd& B = hundred_sources(levels);
  state.SetLabel("tol 1e-" + std::to_string(state.range(1)));
  for (auto _ : state) {
    AmgclMatrix A(p.A);
    const ptrdiff_t n = A.n;
    auto t = Clock::now();
    AmgclSolver solve(A.crs(), amgcl_params(state.range(1)));
    const double setup = since(t);
    std::vector<double> b(static_cast<std::size_t>(n)), x(static_cast<std::size_t>(n));
    double iterations = 0;
    t = Clock::now();
    for (int j = 0; j < 100; ++j) {
      b.assign(B.col(j).data(), B.col(j).data() + n);
      std::fill(x.begin(), x.end(), 0.0);
      iterations += static_cast<double>(std::get<0>(solve(b, x)));
    }
    const double solve100 = since(t);
    benchmark::DoNotOptimize(x.data());
    state.counters["vertices"] = static_cast<double>(n);
    state.counters["setup_s"] = setup;
    state.counters["solve100_s"] = solve100;
    state.counters["iterations_mean"] = iterations / 100.0;
    state.counters["total100_s"] = setup + solve100;
  }
}
BENCHMARK(BM_MultigridAMGCL100)->ArgsProduct({{3, 4}, {8, 4}})->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
#endif

BENCHMARK(BM_MultigridICE)->Arg(2)->Arg(3)->Arg(4)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(BM_MultigridCholmod)
    ->ArgsProduct({{2, 3, 4}, {0, 1, 2, 3}})
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime();

}  // namespace
