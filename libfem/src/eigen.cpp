#include "fem/eigen.h"
#include "ice/wall_time.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymGEigsShiftSolver.h>

namespace fem {

namespace {

using Clock = std::chrono::steady_clock;

// (L − σM)⁻¹ by CHOLMOD, in the shape Spectra's shift-invert mode asks of its operator.
class CholmodShiftInvert {
 public:
  using Scalar = double;
  CholmodShiftInvert(const SparseMatrix& L, const SparseMatrix& M, CholeskyOrdering ordering) : L_(L), M_(M) {
    factor_.set_ordering(ordering);
  }
  Eigen::Index rows() const { return L_.rows(); }
  Eigen::Index cols() const { return L_.cols(); }
  void set_shift(double sigma) {
    const auto start = Clock::now();
    factor_.compute(SparseMatrix(L_ - sigma * M_));
    factor_seconds += ice::seconds_since(start);
  }
  void perform_op(const double* x_in, double* y_out) const {
    const auto start = Clock::now();
    const Eigen::Map<const Eigen::VectorXd> x(x_in, rows());
    Eigen::Map<Eigen::VectorXd>(y_out, rows()) = factor_.solve(x);
    solve_seconds += ice::seconds_since(start);
    ++operations;
  }
  double factor_seconds = 0;
  mutable double solve_seconds = 0;
  mutable long long operations = 0;

 private:
  const SparseMatrix& L_;
  const SparseMatrix& M_;
  CholeskySolver factor_;
};

}  // namespace

Eigenpairs smallest_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, int k, const EigenOptions& options) {
  const Eigen::Index n = L.rows();
  if (L.cols() != n || M.rows() != n || M.cols() != n)
    throw std::invalid_argument("smallest_eigenpairs: L (" + std::to_string(L.rows()) + " x " + std::to_string(L.cols()) +
                                ") and M (" + std::to_string(M.rows()) + " x " + std::to_string(M.cols()) +
                                ") must be square and of one size");
  if (k < 1 || k >= n)
    throw std::invalid_argument("smallest_eigenpairs: asked for " + std::to_string(k) + " eigenpairs of a problem of size " +
                                std::to_string(n) + " (1 <= k < n)");
  if (!(options.tolerance > 0) || options.max_restarts < 1)
    throw std::invalid_argument("smallest_eigenpairs: tolerance must be > 0 and max_restarts >= 1");
  Eigen::Index basis = options.basis_size;
  if (basis == 0) basis = std::min<Eigen::Index>(n, std::max<Eigen::Index>(2 * k + 1, k + 20));
  if (basis <= k || basis > n)
    throw std::invalid_argument("smallest_eigenpairs: the Lanczos basis size must exceed k and be at most n");
  // σ < 0 keeps L − σM positive definite. Its size: 1e-8 of the scale of L's largest eigenvalues
  // (trace(L)/trace(M)), far below the smallest nonzero eigenvalue of any mesh up to ~10⁸
  // vertices, so the ordering of the wanted eigenvalues around σ is that of the eigenvalues.
  const double scale = L.diagonal().sum() / M.diagonal().sum();
  if (!(scale > 0) || !std::isfinite(scale))
    throw std::invalid_argument("smallest_eigenpairs: L's and M's diagonals must be positive");
  const double sigma = -1e-8 * scale;
  CholmodShiftInvert op(L, M, options.ordering);
  Spectra::SparseSymMatProd<double> mass(M);
  Spectra::SymGEigsShiftSolver<CholmodShiftInvert, Spectra::SparseSymMatProd<double>, Spectra::GEigsMode::ShiftInvert> solver(
      op, mass, k, basis, sigma);
  solver.init();
  solver.compute(Spectra::SortRule::LargestMagn, options.max_restarts, options.tolerance);
  if (solver.info() != Spectra::CompInfo::Successful)
    throw std::runtime_error("smallest_eigenpairs: the Lanczos iteration did not converge for " + std::to_string(k) +
                             " eigenpairs within " + std::to_string(options.max_restarts) + " restarts");
  Eigenpairs out;
  const Eigen::VectorXd values = solver.eigenvalues();
  const Eigen::MatrixXd vectors = solver.eigenvectors();
  std::vector<Eigen::Index> order(static_cast<std::size_t>(values.size()));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return values(a) < values(b); });
  out.values.resize(k);
  out.vectors.resize(n, k);
  for (int j = 0; j < k; ++j) {
    out.values(j) = values(order[static_cast<std::size_t>(j)]);
    Eigen::VectorXd v = vectors.col(order[static_cast<std::size_t>(j)]);
    v /= std::sqrt(v.dot(M * v));  // M-normalised (Spectra's are already, up to round-off)
    out.vectors.col(j) = v;
  }
  out.shift = sigma;
  out.restarts = static_cast<int>(solver.num_iterations());
  out.operations = op.operations;
  out.factor_seconds = op.factor_seconds;
  out.solve_seconds = op.solve_seconds;
  return out;
}

namespace {

// `solve` (the pairs of a pencil, count k) applied to the pencil restricted to the indices off `fixed`,
// the vectors extended by zeros at `fixed`; `who` names the caller in the errors.
template <class Solve>
Eigenpairs on_free_indices(const char* who, const SparseMatrix& L, const SparseMatrix& M, const std::vector<Index>& fixed,
                           int k, Solve&& solve) {
  if (fixed.empty()) return solve(L, M);
  const Eigen::Index n = L.rows();
  std::vector<Index> free_index(static_cast<std::size_t>(n), 0);
  for (Index v : fixed) {
    if (v < 0 || v >= n) throw std::invalid_argument(std::string(who) + ": fixed index " + std::to_string(v) + " is out of range");
    free_index[static_cast<std::size_t>(v)] = -1;
  }
  std::vector<Index> free;
  for (Eigen::Index i = 0; i < n; ++i)
    if (free_index[static_cast<std::size_t>(i)] == 0) {
      free_index[static_cast<std::size_t>(i)] = static_cast<Index>(free.size());
      free.push_back(static_cast<Index>(i));
    }
  const auto nf = static_cast<Eigen::Index>(free.size());
  if (k >= nf)
    throw std::invalid_argument(std::string(who) + ": asked for " + std::to_string(k) + " eigenpairs, " +
                                std::to_string(nf) + " unknowns are free (k < free unknowns)");
  // The free rows and columns of a symmetric matrix.
  const auto restrict_to_free = [&](const SparseMatrix& A) {
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(static_cast<std::size_t>(A.nonZeros()));
    for (Eigen::Index c = 0; c < A.outerSize(); ++c) {
      const Index fc = free_index[static_cast<std::size_t>(c)];
      if (fc < 0) continue;
      for (SparseMatrix::InnerIterator it(A, c); it; ++it) {
        const Index fr = free_index[static_cast<std::size_t>(it.row())];
        if (fr >= 0) entries.emplace_back(fr, fc, it.value());
      }
    }
    SparseMatrix out(nf, nf);
    out.setFromTriplets(entries.begin(), entries.end());
    return out;
  };
  Eigenpairs pairs = solve(restrict_to_free(L), restrict_to_free(M));
  Eigen::MatrixXd full = Eigen::MatrixXd::Zero(n, pairs.vectors.cols());
  for (Eigen::Index i = 0; i < nf; ++i) full.row(free[static_cast<std::size_t>(i)]) = pairs.vectors.row(i);
  pairs.vectors = std::move(full);
  return pairs;
}

}  // namespace

Eigenpairs smallest_eigenpairs_dirichlet(const SparseMatrix& L, const SparseMatrix& M, const std::vector<Index>& fixed,
                                         int k, const EigenOptions& options) {
  return on_free_indices("smallest_eigenpairs_dirichlet", L, M, fixed, k,
                         [&](const SparseMatrix& Lf, const SparseMatrix& Mf) { return smallest_eigenpairs(Lf, Mf, k, options); });
}

Eigenpairs subspace_eigenpairs_dirichlet(const SparseMatrix& L, const SparseMatrix& M, const std::vector<Index>& fixed,
                                         int count, int accurate, const SubspaceIterationOptions& options) {
  return on_free_indices("subspace_eigenpairs_dirichlet", L, M, fixed, count,
                         [&](const SparseMatrix& Lf, const SparseMatrix& Mf) {
                           return subspace_eigenpairs(Lf, Mf, count, accurate, options);
                         });
}

double zero_mode_scale(double largest, const SparseMatrix& L, const SparseMatrix& M) {
  const double spectrum = L.diagonal().sum() / M.diagonal().sum();
  return std::isfinite(spectrum) && spectrum > 0 && !(largest > 1e-8 * spectrum) ? spectrum : largest;
}

Eigen::VectorXd eigen_residuals(const SparseMatrix& L, const SparseMatrix& M, const Eigen::VectorXd& values,
                                const Eigen::MatrixXd& vectors, const std::vector<Index>& fixed) {
  if (vectors.cols() != values.size() || vectors.rows() != L.rows() || M.rows() != L.rows())
    throw std::invalid_argument("eigen_residuals: sizes disagree");
  Eigen::VectorXd keep = Eigen::VectorXd::Ones(L.rows());
  for (Index v : fixed) {
    if (v < 0 || v >= L.rows()) throw std::invalid_argument("eigen_residuals: fixed index out of range");
    keep(v) = 0;
  }
  const double largest = zero_mode_scale(values.size() > 0 ? values.cwiseAbs().maxCoeff() : 0.0, L, M);
  Eigen::VectorXd out(values.size());
  for (Eigen::Index j = 0; j < values.size(); ++j) {
    const Eigen::VectorXd Mphi = M * vectors.col(j);
    const double scale = is_zero_mode(values(j), largest) ? largest : std::abs(values(j));
    const double denominator = scale * Mphi.cwiseProduct(keep).norm();
    out(j) = denominator > 0 ? (L * vectors.col(j) - values(j) * Mphi).cwiseProduct(keep).norm() / denominator : 0.0;
  }
  return out;
}

Eigen::VectorXd eigenspace_angles(const Eigen::MatrixXd& approximate, const Eigen::MatrixXd& reference,
                                  const Eigen::VectorXd& reference_values, const SparseMatrix& M, double cluster) {
  if (approximate.rows() != reference.rows() || approximate.cols() > reference.cols() ||
      reference_values.size() != reference.cols() || M.rows() != reference.rows())
    throw std::invalid_argument("eigenspace_angles: sizes disagree");
  if (approximate.cols() == 0) return Eigen::VectorXd();
  const Eigen::MatrixXd MA = M * approximate;
  const Eigen::MatrixXd coefficients = reference.transpose() * MA;  // reference is M-orthonormal
  const double scale = reference_values.cwiseAbs().maxCoeff();
  Eigen::VectorXd out(approximate.cols());
  for (Eigen::Index j = 0; j < approximate.cols(); ++j) {
    const double lambda = reference_values(j);
    const double width = cluster * std::max(std::abs(lambda), 1e-8 * scale);
    double inside = 0;  // ‖projection onto the cluster‖²
    for (Eigen::Index i = 0; i < reference.cols(); ++i)
      if (std::abs(reference_values(i) - lambda) <= width) inside += coefficients(i, j) * coefficients(i, j);
    const double norm2 = approximate.col(j).dot(MA.col(j));
    const double cosine = norm2 > 0 ? std::min(1.0, std::sqrt(inside / norm2)) : 0.0;
    out(j) = std::acos(cosine);
  }
  return out;
}

}  // namespace fem
