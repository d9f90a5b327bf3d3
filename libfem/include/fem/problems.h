#pragma once
/// \file problems.h
/// Model PDE solvers on one discretisation: Poisson, backward-Euler heat flow, heat-method geodesic
/// distance. Every solver factors its matrices once (CHOLMOD) in the constructor and then solves any
/// number of right-hand sides; PoissonSolver can use Galerkin multigrid instead (PoissonMultigrid).
///
/// The solvers take operators rather than a mesh, so the same code runs on the fine mesh, on an
/// intrinsic coarse mesh, or with Galerkin coarse operators (fem/coarse_proxy.h). `laplacian` is the
/// positive semidefinite cotangent Laplacian (or a Galerkin product of it) and `mass` a mass matrix.
#include <memory>
#include <optional>
#include <vector>

#include "fem/cholesky.h"
#include "fem/multigrid.h"
#include "fem/operators.h"
#include "fem/topology.h"

namespace fem {

/// Solves A x = b where x is prescribed on a set of "constrained" indices, eliminating them:
/// A_FF x_F = b_F − A_FC x_C over the free indices F. The rows of b at constrained indices are
/// ignored. A_FF is factored once. Precondition: A_FF symmetric positive definite (throws
/// NotPositiveDefinite otherwise); constrained indices in range, each at most once (std::invalid_argument
/// otherwise); constrained values are taken in the order of `constrained`.
class ConstrainedSolver {
 public:
  /// `ordering`: the fill-reducing ordering of A_FF's factorisation (fem/cholesky.h).
  ConstrainedSolver(const SparseMatrix& A, std::vector<Index> constrained,
                    CholeskyOrdering ordering = CholeskyOrdering::automatic);

  /// Full-length solution; x(constrained[i]) = constrained_values(i). An empty `constrained_values`
  /// means all zeros.
  Eigen::VectorXd solve(const Eigen::VectorXd& b, const Eigen::VectorXd& constrained_values = {}) const;
  /// The same for every column of B, in one CHOLMOD call (blocked right-hand sides: dense kernels
  /// instead of one triangular sweep per column); column j of `constrained_values` (one row per
  /// constrained index; empty: zeros) is column j's constrained values.
  Eigen::MatrixXd solve_multiple(const Eigen::MatrixXd& B, const Eigen::MatrixXd& constrained_values = {}) const;

  const std::vector<Index>& constrained() const { return constrained_; }
  Eigen::Index size() const { return size_; }

 private:
  Eigen::Index size_ = 0;
  std::vector<Index> constrained_;
  std::vector<Index> free_;  ///< free index of each original index, -1 for constrained ones
  SparseMatrix free_constrained_coupling_;  ///< A_FC
  CholeskySolver factor_;                   ///< of A_FF
};

/// PoissonSolver's system solved by Galerkin multigrid (fem/multigrid.h) on these prolongations of
/// a hierarchy of the same mesh (ice::build_hierarchy) instead of a Cholesky factorisation: setup
/// (Galerkin products, coarsest factorisation) in the constructor, each solve iterates to
/// options.tolerance (relative residual).
struct PoissonMultigrid {
  std::vector<SparseMatrix> prolongations;
  MultigridOptions options;
  /// Estimate each iterate's relative error in the mass norm (MultigridSolver::set_error_norm;
  /// after re-centring in zero-mean mode), which options.error_tolerance can stop on. Off by
  /// default: an exact solve to a residual tolerance does not need it.
  bool estimate_error = false;
  /// The fine unknowns' locality order (MultigridSolver::set_locality_order), e.g.
  /// ice::Hierarchy::fine_order; empty: the solver orders A's graph itself.
  std::vector<Index> locality_order;
};

/// Poisson equation L u = M f, the P1 discretisation of −Δu = f (L is positive semidefinite).
///  - Dirichlet: u prescribed at given vertices, at least one per connected component
///    (std::invalid_argument naming a component without one).
///  - Zero-mean ("Neumann"), for closed surfaces or natural boundary conditions: the mass-weighted
///    right-hand side b = M f is first made compatible by removing its mean
///    (b ← b − M1·(1ᵀb)/(1ᵀM1), i.e. f minus its area-weighted mean), one vertex is pinned to 0,
///    and the solution is re-centred to zero mass-weighted mean (1ᵀM u = 0). Because b is compatible,
///    the pinned solution satisfies every equation, so pinning introduces no error. On a mesh of
///    several connected components (of L's graph) all of this is done on each: compatible and
///    re-centred per component, one vertex pinned in each (its smallest), as if each were solved
///    apart.
class PoissonSolver {
 public:
  /// Without `multigrid`, CHOLMOD (exact) with the fill-reducing `ordering` (CHOLMOD's default
  /// strategy, or one the caller found faster: on large meshes AMD alone can analyse and factor
  /// faster, see docs/measurements.md, "CHOLMOD: orderings and pivots"); with it, Galerkin multigrid
  /// (see PoissonMultigrid).
  static PoissonSolver dirichlet(const SparseMatrix& laplacian, const SparseMatrix& mass,
                                 std::vector<Index> dirichlet_vertices, std::optional<PoissonMultigrid> multigrid = {},
                                 CholeskyOrdering ordering = CholeskyOrdering::automatic);
  static PoissonSolver zero_mean(const SparseMatrix& laplacian, const SparseMatrix& mass,
                                 std::optional<PoissonMultigrid> multigrid = {},
                                 CholeskyOrdering ordering = CholeskyOrdering::automatic);

  /// u for the nodal source f (right-hand side M f). `dirichlet_values` align with the Dirichlet
  /// vertices (empty: zeros); ignored in zero-mean mode.
  Eigen::VectorXd solve(const Eigen::VectorXd& f, const Eigen::VectorXd& dirichlet_values = {}) const;
  /// Same with an already mass-weighted right-hand side b (= M f, or a restriction Pᵀ M f).
  Eigen::VectorXd solve_weighted(const Eigen::VectorXd& b, const Eigen::VectorXd& dirichlet_values = {}) const;
  /// Same, iterating from `initial_guess` (full length; any constant shift is fine in zero-mean
  /// mode) with multigrid; CHOLMOD ignores it.
  Eigen::VectorXd solve_weighted(const Eigen::VectorXd& b, const Eigen::VectorXd& dirichlet_values,
                                 const Eigen::VectorXd& initial_guess) const;
  /// solve_weighted for every column of B (mass-weighted right-hand sides) at once: one CHOLMOD
  /// call for all columns (each column equal to its own solve within round-off of the block
  /// kernels), or one block multigrid solve (MultigridSolver::solve_multiple: each column equal to
  /// its own solve within round-off). Column j of `dirichlet_values` (one row per
  /// Dirichlet vertex; empty: zeros) is column j's values.
  Eigen::MatrixXd solve_multiple_weighted(const Eigen::MatrixXd& B, const Eigen::MatrixXd& dirichlet_values = {}) const;

  bool is_zero_mean() const { return zero_mean_; }
  const SparseMatrix& mass() const { return mass_; }
  /// The multigrid solver (its report() describes the last solve, level_info() the levels), or
  /// null with CHOLMOD. A multigrid-backed PoissonSolver must not solve on two threads at once.
  const MultigridSolver* multigrid() const { return multigrid_.get(); }

 private:
  PoissonSolver(const SparseMatrix& laplacian, const SparseMatrix& mass, std::vector<Index> constrained,
                ComponentLabels components, bool zero_mean, std::optional<PoissonMultigrid> multigrid,
                CholeskyOrdering ordering);
  Eigen::VectorXd solve_constrained(const Eigen::VectorXd& b, const Eigen::VectorXd& values,
                                    const Eigen::VectorXd& initial_guess = {}) const;
  SparseMatrix mass_;
  Eigen::VectorXd mass_of_one_;  ///< M·1
  bool zero_mean_;
  ComponentLabels components_;  ///< zero-mean mode: L's components (first[] are the pinned vertices)
  std::unique_ptr<ConstrainedSolver> direct_;   ///< CHOLMOD, or
  std::unique_ptr<MultigridSolver> multigrid_;  ///< multigrid (its solve records a report: not const)
};

/// The step counts a trajectory of `steps` steps writes out: every, 2·every, … up to steps, and
/// steps itself when it is not a multiple. Preconditions: steps >= 1, every >= 1
/// (std::invalid_argument otherwise).
std::vector<int> output_steps(int steps, int every);

/// Heat flow ∂u/∂t = Δu with natural (Neumann) boundary conditions by backward Euler:
/// (M + τL) u_{k+1} = M u_k. The matrix M + τL is factored once, or (with a multigrid setup) its
/// Galerkin levels are built once and each step iterates from the previous state.
/// Preconditions: τ > 0; M + τL positive definite (true for a valid mesh and a positive mass).
class HeatSolver {
 public:
  /// `ordering`: the fill-reducing ordering of M + τL's factorisation (fem/cholesky.h).
  HeatSolver(const SparseMatrix& laplacian, const SparseMatrix& mass, double time_step,
             CholeskyOrdering ordering = CholeskyOrdering::automatic);
  /// M + τL solved by Galerkin multigrid on `multigrid`'s prolongations (a hierarchy of the same
  /// mesh; the struct is the one PoissonSolver takes) to multigrid.options.tolerance (relative
  /// residual ‖b − Ax‖/‖b‖); step() starts from the state it steps from, solve_weighted() from 0.
  /// The solver's report() describes the last solve. multigrid.estimate_error is not used.
  HeatSolver(const SparseMatrix& laplacian, const SparseMatrix& mass, double time_step, PoissonMultigrid multigrid);

  /// One implicit step from nodal values u.
  Eigen::VectorXd step(const Eigen::VectorXd& u) const;
  /// `steps` implicit steps from u0 (steps >= 0), i.e. the state at time steps·τ.
  Eigen::VectorXd integrate(const Eigen::VectorXd& u0, int steps) const;
  /// The states after the steps output_steps(steps, every) lists, one column each (their step
  /// counts in `steps_written`); column j equals integrate(u0, that count) to the last bit. With
  /// multigrid, `step_reports` (if given) receives each step's report (iterations, convergence).
  Eigen::MatrixXd trajectory(const Eigen::VectorXd& u0, int steps, int every, std::vector<int>* steps_written = nullptr,
                             std::vector<MultigridReport>* step_reports = nullptr) const;
  /// (M + τL)⁻¹ b for a mass-weighted right-hand side b.
  Eigen::VectorXd solve_weighted(const Eigen::VectorXd& b) const;
  /// The same for every column of B, in one CHOLMOD call (or one block multigrid solve).
  Eigen::MatrixXd solve_multiple_weighted(const Eigen::MatrixXd& B) const;

  double time_step() const { return time_step_; }
  const SparseMatrix& mass() const { return mass_; }
  /// The multigrid solver, or null with CHOLMOD. A multigrid-backed HeatSolver must not solve on
  /// two threads at once.
  const MultigridSolver* multigrid() const { return multigrid_.get(); }

 private:
  SparseMatrix mass_;
  double time_step_;
  CholeskySolver factor_;
  std::unique_ptr<MultigridSolver> multigrid_;  ///< its solve records a report: not const
};

/// Everything the heat method needs on one function space with n unknowns. Gradients are evaluated
/// on k "integration faces", which are the mesh's own faces for an intrinsic discretisation, or the
/// fine faces for a Galerkin coarse space (gradient = G_fine·P).
struct HeatMethodOperators {
  SparseMatrix laplacian;              ///< n×n, = gradientᵀ·diag(areas)·gradient for P1 elements
  SparseMatrix mass;                   ///< n×n
  SparseMatrix gradient;               ///< 2k×n, per-face gradients in local 2D frames
  Eigen::VectorXd face_areas;          ///< k areas weighting the per-face vectors
  std::vector<Index> boundary_vertices;  ///< of the n unknowns; empty for closed surfaces
  double time_step = 0;                ///< t of the heat step
};

/// The heat method's operators on an intrinsic mesh: cotan Laplacian, mass of `mass_kind`, per-face
/// gradient, face areas, boundary vertices from F (by vertex pairs), and t = (time_factor·h)², h the
/// mean edge length (time_factor = 1 is the paper's t = h²).
HeatMethodOperators heat_method_operators(const ice::IntrinsicMesh& mesh, MassKind mass_kind = MassKind::lumped,
                                          double time_factor = 1.0);

/// Geodesic distance by the heat method (Crane, Weischedel, Wardetzky 2013):
///  1. heat: (M + tL) u = δ, with δ the source indicator (or weights);
///     with a boundary, u is the average of the Neumann solution and the Dirichlet one (u = 0 on the
///     boundary), the paper's recommended boundary treatment;
///  2. X = −∇u/|∇u| per face (X = 0 where ∇u vanishes exactly);
///  3. Poisson L φ = Gᵀ·diag(A)·X (= −∇·X in the integrated sense), solved with one vertex pinned
///     per connected component; its right-hand side sums to zero on each because G·1 = 0 there, so
///     pinning is exact;
///  4. φ shifted so its source-weighted mean is 0 on each component (the value at a single source
///     is 0); on a component without a source φ is +∞ (no heat reaches it: no distance).
/// Factorisations of M + tL (both boundary variants) and of the pinned L happen in the constructor.
/// Sources on the boundary get no heat in the Dirichlet variant, so near them the result is that of
/// the Neumann solution alone.
/// Limitation: u decays roughly like exp(−d/√t); beyond a few hundred mean edge lengths from the
/// sources it drops below round-off and distances there become unreliable.
class HeatGeodesicSolver {
 public:
  explicit HeatGeodesicSolver(HeatMethodOperators operators);

  /// Distance to the given source vertices (non-empty, in range).
  Eigen::VectorXd distance(const std::vector<Index>& sources) const;
  /// Distance from a weighted source: δ = source_weights (non-negative, not all zero); the result is
  /// shifted so that Σ w_i φ_i / Σ w_i = 0.
  Eigen::VectorXd distance_from_weights(const Eigen::VectorXd& source_weights) const;
  /// Distances from each of `sources` separately: column j is distance({sources[j]}) up to
  /// round-off. The columns go through each factorisation together (blocked multi-right-hand-side
  /// solves), which is how many-source and all-pairs heat-method distances are computed: callers
  /// pass blocks of a few hundred sources (memory: 3 dense n × k matrices).
  Eigen::MatrixXd distances_from_each(const std::vector<Index>& sources) const;

  const HeatMethodOperators& operators() const { return operators_; }

 private:
  Eigen::MatrixXd normalized_field(const Eigen::MatrixXd& face_gradients) const;
  HeatMethodOperators operators_;
  ComponentLabels components_;  ///< of the Laplacian's graph (first[] are the pinned vertices)
  HeatSolver neumann_heat_;
  std::unique_ptr<ConstrainedSolver> dirichlet_heat_;  ///< only with a boundary
  ConstrainedSolver pinned_poisson_;
};

}  // namespace fem
