#pragma once
/// \file cholesky.h
/// Sparse Cholesky factorisation of symmetric positive definite matrices through CHOLMOD
/// (supernodal, so the dense kernels run on the system BLAS/LAPACK).
#include <memory>
#include <stdexcept>
#include <string>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace fem {

/// Thrown when a matrix handed to CholeskySolver is not (numerically) positive definite, e.g. a
/// closed-surface Laplacian without a constraint. `column()` is the column where elimination broke
/// down: CHOLMOD's L->minor, or the first column whose pivot fell below the relative pivot tolerance.
class NotPositiveDefinite : public std::runtime_error {
 public:
  NotPositiveDefinite(Eigen::Index column, const std::string& what)
      : std::runtime_error(what), column_(column) {}
  Eigen::Index column() const { return column_; }

 private:
  Eigen::Index column_;
};

/// The fill-reducing ordering of CholeskySolver's analysis.
enum class CholeskyOrdering {
  automatic,          ///< CHOLMOD's default strategy: AMD, then METIS if AMD's fill is high; the best kept
  amd,                ///< approximate minimum degree only (the cheapest analysis)
  metis,              ///< METIS nested dissection only
  nested_dissection,  ///< CHOLMOD's own nested dissection (NESDIS: METIS partitions, CAMD on the parts)
};
const char* to_string(CholeskyOrdering ordering);

/// LLᵀ factorisation with a fill-reducing ordering (CholeskyOrdering; CHOLMOD's default strategy
/// unless set_ordering() says otherwise).
///
/// Usage: `analyze(A)` once per sparsity pattern, then `factorize(A)` for every matrix with that
/// pattern (e.g. M + tL for several t), then `solve(b)` for any number of right-hand sides.
/// `compute(A)` does both steps. Only the lower triangle of A is read (A is assumed symmetric).
/// Uses CHOLMOD's long-integer (cholmod_l_*) interface throughout. Not thread-safe: solve() uses the
/// solver's CHOLMOD workspace, so give each thread its own solver.
class CholeskySolver {
 public:
  CholeskySolver();
  /// Analyses and factorises A (see compute()).
  explicit CholeskySolver(const Eigen::SparseMatrix<double>& A);
  ~CholeskySolver();
  CholeskySolver(CholeskySolver&&) noexcept;
  CholeskySolver& operator=(CholeskySolver&&) noexcept;
  CholeskySolver(const CholeskySolver&) = delete;
  CholeskySolver& operator=(const CholeskySolver&) = delete;

  /// Symbolic analysis (ordering, supernodes) of A's lower-triangle pattern. Discards any factor.
  /// Throws std::invalid_argument if A is not square, std::runtime_error if CHOLMOD fails.
  void analyze(const Eigen::SparseMatrix<double>& A);

  /// Numeric factorisation reusing the current analysis. Precondition: A has the same lower-triangle
  /// sparsity pattern as the analysed matrix (throws std::invalid_argument otherwise; if nothing was
  /// analysed yet, analyses first). Throws NotPositiveDefinite if CHOLMOD reports a non-positive pivot
  /// or a pivot L_jj² falls below pivot_tolerance()·A_jj (numerically singular, which a singular
  /// matrix would otherwise pass on round-off about half the time).
  void factorize(const Eigen::SparseMatrix<double>& A);

  /// analyze(A) followed by factorize(A).
  void compute(const Eigen::SparseMatrix<double>& A);

  /// Solves A x = b. Precondition: a successful factorize(); b.rows() == A.rows().
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const;
  /// Solves A X = B for all columns of B in one CHOLMOD call. (Named apart from solve() so that
  /// Eigen expressions passed as b are not ambiguous.)
  Eigen::MatrixXd solve_multiple(const Eigen::MatrixXd& B) const;

  /// Relative pivot threshold used by factorize() (default 1e-12: a pivot this small means
  /// κ(A) ≳ 1e12, and it sits above the pivots of singular closed-surface Laplacians;
  /// docs/measurements.md, "CHOLMOD: orderings and pivots").
  double pivot_tolerance() const { return pivot_tolerance_; }
  void set_pivot_tolerance(double tolerance) { pivot_tolerance_ = tolerance; }

  /// The ordering of the next analyze(); automatic by default.
  CholeskyOrdering ordering() const { return ordering_; }
  void set_ordering(CholeskyOrdering ordering) { ordering_ = ordering; }

  bool is_factorized() const;
  /// True when CHOLMOD chose a supernodal factor (it is asked to always do so).
  bool is_supernodal() const;
  Eigen::Index rows() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double pivot_tolerance_ = 1e-12;
  CholeskyOrdering ordering_ = CholeskyOrdering::automatic;
};

}  // namespace fem
