#pragma once
/// \file eigen.h
/// The k smallest eigenpairs of the generalised symmetric problem L φ = λ M φ (L symmetric positive
/// semidefinite, M symmetric positive definite): the Laplace–Beltrami eigenbasis of a mesh (cotan L,
/// lumped or consistent M), or of a coarse proxy (its Galerkin pair PᵀLP, PᵀMP).
///
/// Method: implicitly restarted Lanczos in shift-invert mode (Spectra's SymGEigsShiftSolver) with
/// (L − σM)⁻¹ applied by a CHOLMOD factorisation, σ < 0 so that L − σM is positive definite even
/// with L's null space (constants, one per connected component): the eigenvalues nearest σ, i.e.
/// the smallest, converge first.
#include <cmath>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "fem/cholesky.h"
#include "fem/operators.h"

namespace fem {

struct EigenOptions {
  /// Spectra's convergence tolerance: a Ritz value θ of the shifted-inverted problem is accepted when
  /// its residual estimate is at most tolerance·|θ| (> 0).
  double tolerance = 1e-10;
  /// Upper bound on Lanczos restarts (>= 1).
  int max_restarts = 1000;
  /// Lanczos basis size; 0: min(n, max(2k + 1, k + 20)). Must exceed k and be at most n.
  Eigen::Index basis_size = 0;
  /// The fill-reducing ordering of L − σM's factorisation.
  CholeskyOrdering ordering = CholeskyOrdering::amd;
};

struct Eigenpairs {
  Eigen::VectorXd values;   ///< k eigenvalues, increasing
  Eigen::MatrixXd vectors;  ///< n × k, M-orthonormal (φᵢᵀ M φⱼ = δᵢⱼ), column j for values(j)
  double shift = 0;         ///< the σ used
  int restarts = 0;         ///< Lanczos restarts used
  long long operations = 0; ///< solves with L − σM
  double factor_seconds = 0, solve_seconds = 0;
};

/// The k smallest eigenpairs of L φ = λ M φ. Preconditions: L and M square, of one size n, symmetric;
/// 1 <= k < n (std::invalid_argument otherwise, naming the sizes). Throws std::runtime_error when
/// the iteration does not converge within options.max_restarts, NotPositiveDefinite when L − σM is
/// not positive definite (M not positive definite, L not semidefinite).
/// Postconditions: values increasing; a mesh of c connected components has c eigenvalues ≈ 0 (to
/// round-off); vectors M-orthonormal to round-off.
Eigenpairs smallest_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, int k, const EigenOptions& options = {});

/// The k smallest eigenpairs with φ = 0 at the `fixed` indices (Dirichlet conditions): those of the
/// pencil restricted to the other indices, the vectors extended by zeros (full length n). `fixed`
/// may hold repeats; an empty list is smallest_eigenpairs. Preconditions as there, with k below the
/// count of free indices (std::invalid_argument naming it).
Eigenpairs smallest_eigenpairs_dirichlet(const SparseMatrix& L, const SparseMatrix& M, const std::vector<Index>& fixed,
                                         int k, const EigenOptions& options = {});

struct SubspaceIterationOptions {
  /// Stop when each of the first `accurate` Ritz pairs has a relative residual (eigen_residuals) at
  /// most this (> 0).
  double tolerance = 1e-6;
  /// Upper bound on iterations (>= 1); not converging within it throws.
  int max_iterations = 200;
  /// The fill-reducing ordering of L + cM's factorisation.
  CholeskyOrdering ordering = CholeskyOrdering::amd;
  /// Threads of the products with M (0: OpenMP's default); the dense products run on BLAS's.
  int threads = 0;
};

/// The `count` smallest Ritz pairs of L φ = λ M φ by block inverse iteration (subspace iteration)
/// with a Rayleigh–Ritz step per iteration, until the first `accurate` of them are eigenpairs to
/// options.tolerance: a basis of the low spectrum whose first pairs are converged and whose last
/// ones only approximate eigenpairs — what a coarse start and the coarse directions of
/// refine_eigenpairs need, at a fraction of smallest_eigenpairs's cost for all `count` pairs.
/// Each iteration applies (L + cM)⁻¹ M to the block (one CHOLMOD factorisation, one block solve),
/// c = trace(L) / (n trace(M)) (Weyl's law's scale of the lowest nonzero eigenvalue: the zero modes
/// are amplified no more than ~λ_count / c over the others, so the block's Gram matrices stay well
/// conditioned), lowered to a thousandth of the block's largest Ritz value when that is a tenth of
/// c or less (meshes of very unequal components, whose trace misleads Weyl's estimate); pair j
/// converges at about (λ_j + c) / (λ_count+1 + c) per iteration. The start block is pseudo-random
/// with a fixed seed: the result is deterministic.
/// Preconditions: L, M square of one size n, symmetric, L semidefinite, M positive definite;
/// 1 <= accurate <= count < n (std::invalid_argument otherwise). Throws std::runtime_error when the
/// first `accurate` pairs do not converge within options.max_iterations or the block loses rank.
/// Postconditions: values increasing, vectors M-orthonormal to round-off; Eigenpairs::restarts holds
/// the iterations, `shift` −c.
Eigenpairs subspace_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, int count, int accurate,
                               const SubspaceIterationOptions& options = {});

/// subspace_eigenpairs with φ = 0 at the `fixed` indices, as smallest_eigenpairs_dirichlet.
Eigenpairs subspace_eigenpairs_dirichlet(const SparseMatrix& L, const SparseMatrix& M, const std::vector<Index>& fixed,
                                         int count, int accurate, const SubspaceIterationOptions& options = {});

/// Refinement of approximate eigenpairs on the pencil itself (refine_eigenpairs).
struct EigenRefineOptions {
  /// Stop when each of the first k pairs has a relative residual (eigen_residuals) at most this (> 0).
  double tolerance = 1e-6;
  /// Upper bound on iterations (>= 1).
  int max_iterations = 200;
  /// Threads of the sparse products, the coarse directions' restrictions and prolongations and the
  /// residuals (0: OpenMP's default); the dense products run on BLAS's.
  int threads = 0;
};

struct EigenRefineReport {
  bool converged = false;
  int iterations = 0;
  /// The relative residuals of the first k pairs returned (the convergence test's).
  Eigen::VectorXd residuals;
  /// Largest residual of the first k pairs before the first and after every iteration.
  std::vector<double> history;
  double seconds = 0;
  double precondition_seconds = 0;  ///< of those, in the preconditioner
  double sparse_seconds = 0;        ///< of those, in the products with L (L X, L U)
  double dense_seconds = 0;         ///< of those, in the dense products and the small Rayleigh–Ritz eigensolves
  double coarse_seconds = 0;        ///< of those, in the coarse directions' restrictions and prolongations
};

/// Applies an approximation of (L + σM)⁻¹ (symmetric positive definite, σ > 0: e.g. a multigrid
/// V-cycle) to every column of a block; rows at the Dirichlet indices of the result must be 0.
using BlockPreconditioner = std::function<Eigen::MatrixXd(const Eigen::MatrixXd&)>;

/// The same kind of preconditioner T applied in place: X.col(c) −= T R.col(c) for each listed
/// column c (X of R's shape; its rows at the Dirichlet indices left as they are). With it the
/// augmented subspace method holds no copy of R's columns and no block of T R beside X and R (e.g.
/// MultigridSolver::subtract_vcycle_columns).
using InPlacePreconditioner =
    std::function<void(const Eigen::MatrixXd& R, const std::vector<Eigen::Index>& columns, Eigen::MatrixXd& X)>;

/// A coarse space that refine_eigenpairs adds, fixed, to every Rayleigh–Ritz step: the fine vectors
/// G = P Ψ, e.g. a Galerkin proxy's coarse eigenvectors beyond the m refined, prolonged (never formed:
/// every product with G goes through the coarse space, Gᵀ Y = Ψᵀ (Pᵀ Y)).
struct EigenCoarseDirections {
  const SparseMatrix* prolongation = nullptr;  ///< P, n × N_c (not owned; outlives the call)
  Eigen::MatrixXd coarse_vectors;               ///< Ψ, N_c × g, linearly independent
  /// Gᵀ L G = Ψᵀ (Pᵀ L P) Ψ and Gᵀ M G = Ψᵀ (Pᵀ M P) Ψ (g × g) with refine_eigenpairs' L and M: with
  /// Galerkin coarse operators (fem::CoarseProxy's), Ψᵀ Lc Ψ and Ψᵀ Mc Ψ.
  Eigen::MatrixXd laplacian_gram, mass_gram;
};

/// Improves m approximate eigenvectors of L φ = λ M φ (`vectors`, n × m) until the first k pairs
/// have relative residuals ‖Lφ − λMφ‖₂ / (|λ| ‖Mφ‖₂) at most options.tolerance (as eigen_residuals,
/// but zero modes judged against the largest |λ| of all m pairs). T R below are the residuals R of
/// the pairs not yet converged with the preconditioner applied. Two methods:
/// - without `coarse`: the locally optimal block preconditioned conjugate gradient method (LOBPCG,
///   Knyazev 2001): each iteration takes the Rayleigh–Ritz pairs of span[X, T R, P] in the M inner
///   product — X the current vectors, P the previous step — and keeps the smallest m. The m − k
///   extra pairs (guards) speed up the k-th: its convergence depends on the gap λ_k / λ_{m+1}.
/// - with `coarse` (G = P Ψ): the augmented subspace method (Xu & Zhou 2001; Xie, Zhang & Xu 2019):
///   the Rayleigh–Ritz pairs of span[X − T R, G], one preconditioned inverse-iteration step per
///   vector, the coarse space G catching the smooth error components that the step leaves (those of
///   eigenvalues above the m sought, which limit LOBPCG through the gap). Its rate is about the
///   preconditioner's (a V-cycle's), not the gap's, and an iteration has several times fewer n × m
///   dense products than LOBPCG's (docs/measurements.md, "The refined eigenbasis by the augmented
///   subspace method").
/// Either converges to the smallest eigenpairs from a start close to them: prolonged proxy vectors
/// start within a few per cent (LOBPCG from any linearly independent start).
/// On return `values` (m, increasing: the Ritz values; their input is not read) and `vectors` are the
/// m Ritz pairs, M-orthonormal to round-off. A throw from the argument checks, before any product,
/// leaves both as given; any later throw (the search space lost rank, the preconditioner's own throw
/// or a block of the wrong size from it) leaves them valid but unspecified: the vectors are worked on
/// in place, not copied.
/// Preconditions: L symmetric (not checked), M diagonal with positive entries off `fixed`, fixed in
/// range, 1 <= k <= m < n − |fixed|, `coarse` (if given) of matching sizes and G zero at the rows in
/// `fixed` (std::invalid_argument otherwise); the vectors' rows at `fixed` (Dirichlet) are set to
/// zero and stay zero. Throws std::runtime_error when the search space loses rank (linearly dependent
/// start vectors, or a coarse space containing them). Does not throw when max_iterations is
/// reached: check converged.
EigenRefineReport refine_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, Eigen::VectorXd& values,
                                    Eigen::MatrixXd& vectors, int k, const BlockPreconditioner& preconditioner,
                                    const std::vector<Index>& fixed = {}, const EigenRefineOptions& options = {},
                                    const EigenCoarseDirections* coarse = nullptr);
/// refine_eigenpairs with the preconditioner applied in place (the same iterations and numbers).
EigenRefineReport refine_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, Eigen::VectorXd& values,
                                    Eigen::MatrixXd& vectors, int k, const InPlacePreconditioner& preconditioner,
                                    const std::vector<Index>& fixed = {}, const EigenRefineOptions& options = {},
                                    const EigenCoarseDirections* coarse = nullptr);

/// Whether the eigenvalue `lambda` of a basis whose largest |λ| is `largest` is a zero mode (a
/// constant on a component, converged only to round-off): |λ| ≤ 1e-6 · largest. The one rule the
/// residuals, the descriptors and the tools' error statistics use.
inline bool is_zero_mode(double lambda, double largest) { return std::abs(lambda) <= 1e-6 * largest; }

/// The `largest` to judge zero modes by (is_zero_mode, eigen_residuals): the largest |λ| of the basis
/// as given, unless that is itself round-off — at most 1e-8 of trace(L)/trace(M), the spectrum's
/// scale that smallest_eigenpairs sets its shift from: every pair a zero mode, on a mesh of at least as
/// many components as pairs — then that scale.
double zero_mode_scale(double largest, const SparseMatrix& L, const SparseMatrix& M);

/// The relative residual of each pair, ‖Lφ − λMφ‖₂ / (|λ| ‖Mφ‖₂); a zero mode (is_zero_mode) is
/// judged against the largest |λ| given instead (the scale of the basis it
/// was converged in) rather than dividing by ~0. Rows at the `fixed` (Dirichlet) indices, where the
/// vectors are prescribed to be 0, are left out of both norms.
Eigen::VectorXd eigen_residuals(const SparseMatrix& L, const SparseMatrix& M, const Eigen::VectorXd& values,
                                const Eigen::MatrixXd& vectors, const std::vector<Index>& fixed = {});

/// For each column j of `approximate` (n × k), the angle in radians between it and the span of the
/// columns of `reference` (M-orthonormal, increasing eigenvalues `reference_values`) whose
/// eigenvalues lie within `cluster` (relative) of reference_values(j): the eigenspace it
/// approximates, which a repeated or nearly repeated eigenvalue makes wider than one vector. In the
/// M inner product. Preconditions: same row counts, approximate.cols() <= reference.cols().
Eigen::VectorXd eigenspace_angles(const Eigen::MatrixXd& approximate, const Eigen::MatrixXd& reference,
                                  const Eigen::VectorXd& reference_values, const SparseMatrix& M, double cluster = 1e-2);

}  // namespace fem
