#pragma once
/// \file multigrid.h
/// Galerkin multigrid for sparse symmetric positive definite systems on a fine mesh, given the
/// prolongations of a mesh hierarchy (ice/hierarchy.h builds them by repeated ICE coarsening; any
/// P_k with n_k rows and n_{k+1} columns works).
///
/// Levels. Level 0 is the system A x = b over the free unknowns. Level k+1's operator is the
/// Galerkin product A_{k+1} = P_kᵀ A_k P_k (exactly symmetrised). The coarsest level is solved by
/// CHOLMOD (fem::CholeskySolver).
///
/// Constrained (Dirichlet) unknowns. x is prescribed at the constrained indices C, which are
/// eliminated as in fem::ConstrainedSolver: the solver works on A_FF x_F = b_F − A_FC x_C over the
/// free indices F. Through the levels, P_0 is restricted to its free rows; a coarse column that is
/// then empty (a coarse unknown supported only on constrained vertices) is dropped, and the rows of
/// P_1 of dropped unknowns are dropped in turn, and so on. Every coarse space is thus spanned by
/// prolonged functions that vanish on C, which is what Galerkin coarsening of the eliminated system
/// requires; no level sees the constrained rows.
///
/// Cycles. A V-cycle smooths (ν pre-smoothing steps), restricts the residual with P_kᵀ, recurses,
/// prolongs the correction with P_k and smooths again (ν post-smoothing steps). The smoothers are
/// chosen so that the V-cycle is a symmetric positive definite operator and thus a valid
/// preconditioner for conjugate gradients:
///  - gauss_seidel: pre = ν forward sweeps, post = ν backward sweeps;
///  - symmetric_gauss_seidel: pre and post = ν (forward + backward) sweeps;
///  - chebyshev: a degree-d Chebyshev polynomial in D⁻¹A (Jacobi) on [λ/`chebyshev_ratio`, 1.1·λ],
///    λ the largest eigenvalue of D⁻¹A_k estimated by power iteration; pre = post.
/// Mode `vcycle` iterates V-cycles (stationary); mode `pcg` runs conjugate gradients preconditioned
/// by one V-cycle per iteration (the default and the faster one).
///
/// Convergence is judged by the relative residual ‖b_F − A_FF x_F‖₂ / ‖b_F − A_FC x_C‖₂ (so a
/// zero initial guess starts at 1). In PCG mode the recorded residuals are those of the CG
/// recurrence; the final relative_residual is recomputed from the returned x.
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "fem/cholesky.h"
#include "fem/operators.h"

namespace fem {

enum class MultigridMode { vcycle, pcg };
enum class MultigridSmoother { gauss_seidel, symmetric_gauss_seidel, chebyshev };

const char* to_string(MultigridMode mode);
const char* to_string(MultigridSmoother smoother);

struct MultigridOptions {
  MultigridMode mode = MultigridMode::pcg;
  MultigridSmoother smoother = MultigridSmoother::symmetric_gauss_seidel;
  /// ν: pre- and post-smoothing steps per level (>= 1).
  int smoothing_steps = 1;
  /// Chebyshev: polynomial degree (>= 1) and the ratio of the interval's ends.
  int chebyshev_degree = 3;
  double chebyshev_ratio = 30;
  /// Stop when the relative residual is at most this (> 0).
  double tolerance = 1e-8;
  /// Upper bound on cycles (vcycle) or CG iterations (pcg) (>= 1).
  int max_iterations = 200;
  /// Threads of solve()'s matrix products, residuals, restrictions, prolongations, Chebyshev steps
  /// and CG vector operations on levels of at least 50,000 unknowns (0: OpenMP's default, i.e.
  /// OMP_NUM_THREADS or all cores; 1: serial), and of the Gauss–Seidel sweeps when `reorder` is on:
  /// the rows are split into one contiguous range per thread, each swept exactly, the ranges
  /// coupled through the values at the start of the sweep (hybrid Gauss–Seidel; deterministic for a
  /// given thread count, a slightly different smoother: iteration counts nearly unchanged;
  /// docs/measurements.md, "Multigrid solver").
  /// Otherwise only the order of the CG dot products' sums depends on it (round-off).
  int threads = 0;
  /// Number the free unknowns by reverse Cuthill–McKee (fem/ordering.h) and each coarse level in
  /// the order of the fine unknowns it prolongs to. Neighbouring unknowns then sit close in memory
  /// (much faster solves on meshes in a scattered order; docs/measurements.md, "Multigrid solver"),
  /// and contiguous index ranges are compact regions, so the threaded Gauss–Seidel's split cuts few
  /// couplings. Internal only: inputs and results keep the caller's
  /// order. Applies at the next setup().
  bool reorder = true;
  /// Gauss–Seidel sweeps and the V-cycle's residuals read the level operators' values rounded to
  /// float: a third less memory traffic in the passes that dominate a solve. The V-cycle stays a
  /// fixed symmetric positive definite operator (one symmetric matrix for smoothing and residuals),
  /// and CG's products, residuals and the returned x stay double, so any tolerance is reached.
  /// Chebyshev, and the finest level in `vcycle` mode (whose fixed point must solve A x = b), always
  /// use double.
  bool single_precision_smoother = true;
  /// Also stop when the estimated relative error (see MultigridSolver::set_error_norm) is at most
  /// this; 0: the estimates, if an error norm is set, are only recorded. Either criterion stops.
  double error_tolerance = 0;
  /// In PCG mode the error criterion applies from this iteration on: the estimate's Lanczos
  /// correction (set_error_norm) needs a few iterations to find the cycle's weakest eigenvalue; the
  /// default is where the estimate became reliable (docs/measurements.md, "Polishing: the error
  /// estimate").
  int error_min_iterations = 3;
};

/// Outcome of one solve.
struct MultigridReport {
  /// The relative residual reached `tolerance`, or the error estimate `error_tolerance`.
  bool converged = false;
  int iterations = 0;
  /// Relative residual before the first and after every iteration (size iterations + 1).
  std::vector<double> residuals;
  /// Relative residual of the returned x (recomputed).
  double relative_residual = 0;
  /// Geometric mean of the residual ratios: (residuals.back() / residuals.front())^(1/iterations).
  double convergence_factor = 0;
  double seconds = 0;
  /// With an error norm set (MultigridSolver::set_error_norm; single-vector solve() only): the
  /// estimated relative error of the iterate before the first and after every iteration (size
  /// iterations + 1), the last one that of the returned x; empty otherwise.
  std::vector<double> error_estimates;
};

/// Sizes and setup cost of the levels.
struct MultigridLevelInfo {
  Eigen::Index unknowns = 0;
  Eigen::Index nonzeros = 0;
};

class MultigridSolver {
 public:
  /// prolongations[k] is P_k (n_k × n_{k+1}); consecutive sizes must match (std::invalid_argument).
  /// An empty list gives a one-level "multigrid", i.e. a CHOLMOD solve.
  explicit MultigridSolver(std::vector<SparseMatrix> prolongations, MultigridOptions options = {});
  ~MultigridSolver();
  MultigridSolver(MultigridSolver&&) noexcept;
  MultigridSolver& operator=(MultigridSolver&&) noexcept;

  /// Builds the levels for A (n_0 × n_0, symmetric; A_FF positive definite) with x prescribed at
  /// `constrained` (indices in range, each at most once; values follow this order): restricted prolongations, Galerkin
  /// operators, smoother data, coarsest factorisation (analysis + numeric). Throws
  /// std::invalid_argument on bad sizes or indices, NotPositiveDefinite if the coarsest operator is
  /// not positive definite.
  void setup(const SparseMatrix& A, std::vector<Index> constrained = {});

  /// With options().reorder: number the fine unknowns by `order` (order[new] = old, a permutation
  /// of 0..n_0−1, checked by setup()) instead of by reverse Cuthill–McKee on A's graph, e.g.
  /// ice::Hierarchy::fine_order, the same kind of order of the same mesh (saves the ordering's time;
  /// docs/measurements.md, "Multigrid solver"). Empty: RCM again. Applies at the next setup().
  void set_locality_order(std::vector<Index> order) { locality_order_ = std::move(order); }

  /// Replaces the matrix by one with the same sparsity pattern and the same constrained set (e.g.
  /// M + tL for another t): redoes only the Galerkin products, the smoother data and the coarsest
  /// numeric factorisation (its symbolic analysis is reused). Precondition: setup() was called.
  void update_matrix(const SparseMatrix& A);

  /// Solves A x = b with x(constrained[i]) = constrained_values(i) (empty: zeros), starting from 0
  /// on the free unknowns. Rows of b at constrained indices are ignored. Returns the full-length x;
  /// the convergence history is in report(). Does not throw when max_iterations is reached:
  /// check report().converged.
  Eigen::VectorXd solve(const Eigen::VectorXd& b, const Eigen::VectorXd& constrained_values = {});
  /// Same, starting from `initial_guess` (full length; its constrained entries are ignored).
  Eigen::VectorXd solve(const Eigen::VectorXd& b, const Eigen::VectorXd& constrained_values,
                        const Eigen::VectorXd& initial_guess);

  /// Solves for every column of B at once (k right-hand sides, constrained_values: one column per
  /// right-hand side, or empty for zeros): in chunks of kBlockColumns columns, whose
  /// conjugate-gradient (or V-cycle) iterations run in lockstep, every V-cycle smoothing,
  /// restricting and prolonging the chunk's vectors together, so the operators are streamed from
  /// memory once per sweep for all of them. Column j stops when it reaches the tolerance. Results
  /// equal k calls of solve() up to round-off; reports() holds one report per column (report() then
  /// holds a column that did not converge, if any, else the one of most iterations; `seconds` is the
  /// whole block's). With an error norm (set_error_norm) the columns go through solve() one by one,
  /// each with its estimates and error criterion.
  Eigen::MatrixXd solve_multiple(const Eigen::MatrixXd& B, const Eigen::MatrixXd& constrained_values = {});
  const std::vector<MultigridReport>& reports() const { return reports_; }
  /// The widest chunk of columns solve_multiple() iterates together.
  static constexpr Eigen::Index kBlockColumns = 8;

  /// Makes solve() estimate the relative error of its iterates against the exact solution x*:
  /// ‖B r‖_w / ‖x + B r‖_w (the error over the estimated solution), with r = b − A x, B one V-cycle (the preconditioned residual, which PCG
  /// computes anyway; an extra V-cycle per iteration in `vcycle` mode) and ‖v‖_w² = Σ w_i v_i² over
  /// all n_0 unknowns (constrained ones have no error). With `remove_weighted_mean`, both vectors
  /// lose their w-weighted mean first: for problems posed up to a constant (zero-mean Poisson with
  /// one pinned unknown), whose error counts after re-centring.
  /// Why it estimates the error: B r = B A (x* − x), so B r − (x* − x) = −(I − BA)(x* − x), and
  /// ‖I − BA‖_A is the V-cycle's convergence factor ρ: in the energy norm the estimate lies within
  /// [1 − ρ, 1 + ρ] times the true error. In the w-norm no such bound holds in general (the ratios
  /// observed are in docs/measurements.md, "Polishing: the error estimate"). In PCG mode the
  /// estimate is divided by the smallest eigenvalue of BA seen so far (the smallest Ritz value of CG's Lanczos tridiagonal): a
  /// component of the error along an eigenvector with eigenvalue μ appears in Br shrunk by μ. The
  /// criterion `error_tolerance` then applies from iteration `error_min_iterations` on, and the reported
  /// history is rescaled with the final factor. Weights must be >= 0 and of size n_0.
  /// An empty `weights` turns the estimates off.
  void set_error_norm(Eigen::VectorXd weights, bool remove_weighted_mean);

  /// One V-cycle on the free system, z ≈ A_FF⁻¹ r from z = 0 (the preconditioner). Sizes: free count.
  Eigen::VectorXd apply_vcycle(const Eigen::VectorXd& r);
  /// One V-cycle from zero for every column of R (n_0 rows, the caller's numbering; rows at
  /// constrained indices ignored): the preconditioner of a block method. Returns Z (n_0 × R.cols()),
  /// 0 at the constrained indices. The cycle of the solver's options (a pcg-mode solver's: its
  /// preconditioner); with MultigridMode::vcycle the same numbers as solve_multiple() with
  /// max_iterations 1, without its residuals (three fine-level products per chunk) and reports. In
  /// chunks of kBlockColumns. Throws std::logic_error before setup(), std::invalid_argument when
  /// R has the wrong number of rows.
  Eigen::MatrixXd apply_vcycle_multiple(const Eigen::MatrixXd& R);
  /// X.col(c) −= Z.col(c) for each listed column c, Z = apply_vcycle_multiple's cycle applied to
  /// R.col(c), without forming Z or a copy of R's columns: each chunk's columns read from R and
  /// subtracted from X in place (X's rows at constrained indices left as they are; the same
  /// numbers as subtracting apply_vcycle_multiple's result). Throws as apply_vcycle_multiple, and
  /// std::invalid_argument when X's shape differs from R's or a column is out of range.
  void subtract_vcycle_columns(const Eigen::MatrixXd& R, const std::vector<Eigen::Index>& columns, Eigen::MatrixXd& X);

  const MultigridReport& report() const { return report_; }
  const MultigridOptions& options() const { return options_; }
  void set_options(const MultigridOptions& options);

  int num_levels() const;
  std::vector<MultigridLevelInfo> level_info() const;
  /// Σ nnz(A_k) / nnz(A_0).
  double operator_complexity() const;
  /// The operator of level k (level 0: A_FF), in the solver's internal order of the unknowns:
  /// row i of level 0 is unknown free_order()[i].
  const SparseMatrix& level_operator(int k) const;
  Eigen::Index size() const { return size_; }
  const std::vector<Index>& constrained() const { return constrained_; }
  /// The free unknowns in the solver's internal order (a permutation of the unconstrained indices;
  /// increasing unless options().reorder).
  const std::vector<Index>& free_order() const { return free_; }
  /// Seconds of the last setup() or update_matrix() (Galerkin products + coarse factorisation).
  double setup_seconds() const { return setup_seconds_; }

 private:
  struct Level;
  void check_options(const MultigridOptions& options) const;
  int threads() const;
  void build_operators(const SparseMatrix& A, bool reuse_analysis);
  void vcycle(std::size_t k, bool from_zero = false);
  template <class Sink>
  void vcycle_chunks(const char* who, const Eigen::MatrixXd& R, const std::vector<Eigen::Index>& columns, Sink&& sink);
  void smooth(std::size_t k, bool pre, bool from_zero = false);
  void chebyshev(std::size_t k);
  Eigen::MatrixXd solve_block_columns(const Eigen::MatrixXd& B, const Eigen::MatrixXd& constrained_values);
  void apply_vcycle_block(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>& R,
                          Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& Z);

  MultigridOptions options_;
  std::vector<SparseMatrix> prolongations_;  ///< as given
  std::vector<std::unique_ptr<Level>> levels_;
  CholeskySolver coarsest_;
  Eigen::Index size_ = 0;
  std::vector<Index> constrained_;
  std::vector<Index> free_index_;   ///< free index of each unknown, −1 if constrained
  std::vector<Index> free_;         ///< free -> original index
  SparseMatrix free_constrained_; ///< A_FC
  MultigridReport report_;
  std::vector<MultigridReport> reports_;
  double setup_seconds_ = 0;
  Eigen::VectorXd error_weights_;  ///< in the caller's order; empty: no estimates
  bool error_remove_mean_ = false;
  /// ‖z‖_w / ‖x + z‖_w for free-order vectors x (iterate) and z (its correction estimate), with the
  /// weights of the free unknowns in that order (w_free); see set_error_norm.
  double estimate_error(const Eigen::VectorXd& x, const Eigen::VectorXd& z, const Eigen::VectorXd& w_free,
                        const Eigen::VectorXd& constrained_values) const;
  bool is_setup_ = false;
  bool reordered_ = false;  ///< setup() used the locality ordering (threaded sweeps need it)
  std::vector<Index> locality_order_;  ///< set_locality_order's, or empty
};

}  // namespace fem
