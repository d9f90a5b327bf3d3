// refine_eigenpairs (fem/eigen.h): LOBPCG on the fine pencil, started from approximate pairs.
#include "fem/eigen.h"
#include "ice/wall_time.h"
#include "parallel_kernels.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace fem {

namespace {

using Clock = std::chrono::steady_clock;
using Dense = Eigen::MatrixXd;

// Row blocks of the tall products: fixed in number, so that every sum is taken in the same order
// whatever the thread count (results do not depend on it).
constexpr Eigen::Index kRowBlocks = 64;

struct RowBlock {
  Eigen::Index first, size;
};

RowBlock row_block(Eigen::Index n, Eigen::Index b) {
  const Eigen::Index lo = n * b / kRowBlocks, hi = n * (b + 1) / kRowBlocks;
  return {lo, hi - lo};
}

int threads_for(Eigen::Index rows, int threads) { return detail::active_threads(rows, threads); }

// Aᵀ diag(w) B (w empty: Aᵀ B), n × a and n × b blocks.
Dense weighted_gram(const Dense& A, const Eigen::VectorXd& w, const Dense& B, int threads) {
  const Eigen::Index n = A.rows();
  std::vector<Dense> parts(static_cast<std::size_t>(kRowBlocks));
#pragma omp parallel for schedule(dynamic) num_threads(threads_for(n, threads))
  for (Eigen::Index b = 0; b < kRowBlocks; ++b) {
    const RowBlock r = row_block(n, b);
    Dense& part = parts[static_cast<std::size_t>(b)];
    if (w.size() == 0)
      part.noalias() = A.middleRows(r.first, r.size).transpose() * B.middleRows(r.first, r.size);
    else
      part.noalias() =
          A.middleRows(r.first, r.size).transpose() * (w.segment(r.first, r.size).asDiagonal() * B.middleRows(r.first, r.size));
  }
  Dense sum = Dense::Zero(A.cols(), B.cols());
  for (const Dense& part : parts) sum += part;
  return sum;
}

// A Y (n × a times a × c), row block by row block.
Dense block_product(const Dense& A, const Dense& Y, int threads) {
  const Eigen::Index n = A.rows();
  Dense out(n, Y.cols());
#pragma omp parallel for schedule(dynamic) num_threads(threads_for(n, threads))
  for (Eigen::Index b = 0; b < kRowBlocks; ++b) {
    const RowBlock r = row_block(n, b);
    out.middleRows(r.first, r.size).noalias() = A.middleRows(r.first, r.size) * Y;
  }
  return out;
}

// L X for a symmetric L, column by column (each column's sum in one order).
Dense sparse_times(const SparseMatrix& L, const Dense& X, int threads) {
  Dense out(L.rows(), X.cols());
#pragma omp parallel for schedule(dynamic) num_threads(threads_for(L.rows(), threads))
  for (Eigen::Index j = 0; j < X.cols(); ++j) {
    Eigen::VectorXd column(L.rows());
    detail::gather_product(L, X.col(j).data(), column.data(), false, 1, 0);
    out.col(j) = column;
  }
  return out;
}

Dense symmetrised(const Dense& G) { return 0.5 * (G + G.transpose()); }

// The `count` smallest Ritz pairs of the pencil (GL, GM) on its numerically independent part:
// GM = V S Vᵀ, directions with S below `drop`·max S left out (a search space that lost rank),
// the rest made orthonormal (B = V S^-1/2) and BᵀGL B diagonalised. Columns of the returned Y
// are GM-orthonormal coefficient vectors.
struct Ritz {
  Eigen::VectorXd values;
  Dense coefficients;
};

Ritz ritz_pairs(const Dense& GL, const Dense& GM, Eigen::Index count, double drop) {
  Eigen::SelfAdjointEigenSolver<Dense> mass(symmetrised(GM));
  const Eigen::VectorXd& s = mass.eigenvalues();
  const double largest = s.size() ? s.maxCoeff() : 0;
  Eigen::Index first = 0;
  while (first < s.size() && !(s(first) > drop * largest)) ++first;
  const Eigen::Index kept = s.size() - first;
  if (kept < count) throw std::runtime_error("refine_eigenpairs: the search space lost rank (linearly dependent vectors)");
  const Dense B = mass.eigenvectors().rightCols(kept) * s.tail(kept).cwiseSqrt().cwiseInverse().asDiagonal();
  Eigen::SelfAdjointEigenSolver<Dense> stiffness(symmetrised(B.transpose() * GL * B));
  return {stiffness.eigenvalues().head(count), B * stiffness.eigenvectors().leftCols(count)};
}

Dense column_subset(const Dense& A, const std::vector<Eigen::Index>& which) {
  Dense out(A.rows(), static_cast<Eigen::Index>(which.size()));
  for (std::size_t c = 0; c < which.size(); ++c) out.col(static_cast<Eigen::Index>(c)) = A.col(which[c]);
  return out;
}

}  // namespace

EigenRefineReport refine_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, Eigen::VectorXd& values,
                                    Eigen::MatrixXd& vectors, int k, const BlockPreconditioner& preconditioner,
                                    const std::vector<Index>& fixed, const EigenRefineOptions& options) {
  const auto start = Clock::now();
  const Eigen::Index n = L.rows(), m = vectors.cols();
  if (L.cols() != n || M.rows() != n || M.cols() != n || vectors.rows() != n || values.size() != m)
    throw std::invalid_argument("refine_eigenpairs: L, M (" + std::to_string(M.rows()) + " x " + std::to_string(M.cols()) +
                                "), the vectors (" + std::to_string(vectors.rows()) + " rows) and " +
                                std::to_string(values.size()) + " values do not match L's size " + std::to_string(n));
  if (!(options.tolerance > 0) || options.max_iterations < 1)
    throw std::invalid_argument("refine_eigenpairs: need tolerance > 0 and max_iterations >= 1");
  if (!preconditioner) throw std::invalid_argument("refine_eigenpairs: no preconditioner");
  std::vector<char> is_fixed(static_cast<std::size_t>(n), 0);
  for (Index i : fixed) {
    if (i < 0 || i >= n) throw std::invalid_argument("refine_eigenpairs: Dirichlet index " + std::to_string(i) + " out of range");
    is_fixed[static_cast<std::size_t>(i)] = 1;
  }
  const Eigen::Index free_count = n - std::count(is_fixed.begin(), is_fixed.end(), 1);
  if (k < 1 || k > m || m >= free_count)
    throw std::invalid_argument("refine_eigenpairs: need 1 <= k <= m < free unknowns (k = " + std::to_string(k) +
                                ", m = " + std::to_string(m) + ", " + std::to_string(free_count) + " free unknowns)");
  Eigen::VectorXd mass(n);
  for (Eigen::Index j = 0; j < M.outerSize(); ++j) {
    mass(j) = 0;
    for (SparseMatrix::InnerIterator it(M, j); it; ++it) {
      if (it.row() != j && it.value() != 0) throw std::invalid_argument("refine_eigenpairs: M must be diagonal (lumped)");
      if (it.row() == j) mass(j) = it.value();
    }
    if (!is_fixed[static_cast<std::size_t>(j)] && !(mass(j) > 0))
      throw std::invalid_argument("refine_eigenpairs: M's diagonal must be positive (row " + std::to_string(j) + ")");
  }
  const int threads = options.threads > 0 ? options.threads : detail::default_threads();
  const auto clear_fixed_rows = [&](Dense& A) {
    for (Index i : fixed) A.row(i).setZero();
  };
  // Directions whose mass-Gram eigenvalue is below this share of the largest are dependent: ~1e-12
  // keeps what double precision can still orthonormalise (a condition number up to ~1e6).
  constexpr double kDrop = 1e-12;

  EigenRefineReport report;
  Dense X = vectors;
  clear_fixed_rows(X);
  Dense LX = sparse_times(L, X, threads);
  {
    // Rayleigh–Ritz on the start vectors: M-orthonormal Ritz vectors whatever the start.
    const Ritz r = ritz_pairs(weighted_gram(X, {}, LX, threads), weighted_gram(X, mass, X, threads), m, kDrop);
    X = block_product(X, r.coefficients, threads);
    LX = sparse_times(L, X, threads);
    values = r.values;
  }
  Dense P(n, 0);
  for (int iteration = 0;; ++iteration) {
    // Residuals R = L X − M X Θ, outside the Dirichlet rows.
    Dense MX = mass.asDiagonal() * X;
    Dense R = LX - MX * values.asDiagonal();
    clear_fixed_rows(R);
    for (Index i : fixed) MX.row(i).setZero();
    const double largest = std::max(values.head(k).cwiseAbs().maxCoeff(), std::numeric_limits<double>::min());
    Eigen::VectorXd residual(m);
    for (Eigen::Index j = 0; j < m; ++j) {
      const double scale = is_zero_mode(values(j), largest) ? largest : std::abs(values(j));
      const double denominator = scale * MX.col(j).norm();
      residual(j) = denominator > 0 ? R.col(j).norm() / denominator : std::numeric_limits<double>::infinity();
    }
    report.history.push_back(residual.head(k).maxCoeff());
    report.iterations = iteration;
    if (residual.head(k).maxCoeff() <= options.tolerance) {
      report.converged = true;
      break;
    }
    if (iteration == options.max_iterations) break;
    // Soft locking: converged pairs stay in X (and in the Rayleigh–Ritz) but get no new directions.
    std::vector<Eigen::Index> active;
    for (Eigen::Index j = 0; j < m; ++j)
      if (residual(j) > options.tolerance) active.push_back(j);
    const auto precondition_start = Clock::now();
    Dense W = preconditioner(column_subset(R, active));
    report.precondition_seconds += ice::seconds_since(precondition_start);
    if (W.rows() != n || W.cols() != static_cast<Eigen::Index>(active.size()))
      throw std::invalid_argument("refine_eigenpairs: the preconditioner returned a block of the wrong size");
    clear_fixed_rows(W);
    // The new directions [W, P], M-orthogonal to X (classical Gram–Schmidt twice) and M-orthonormal
    // among themselves (each column normalised, then the Gram matrix's independent part).
    Dense Q(n, W.cols() + P.cols());
    Q << W, P;
    W.resize(0, 0);
    for (int pass = 0; pass < 2; ++pass) Q -= block_product(X, weighted_gram(X, mass, Q, threads), threads);
    {
      const Eigen::VectorXd norms = weighted_gram(Q, mass, Q, threads).diagonal().cwiseMax(0).cwiseSqrt();
      const double largest_norm = norms.size() ? norms.maxCoeff() : 0;
      std::vector<Eigen::Index> kept;
      for (Eigen::Index j = 0; j < norms.size(); ++j)
        if (norms(j) > 1e-14 * largest_norm && norms(j) > 0) kept.push_back(j);
      Q = column_subset(Q, kept);
      for (std::size_t c = 0; c < kept.size(); ++c) Q.col(static_cast<Eigen::Index>(c)) /= norms(kept[c]);
      Eigen::SelfAdjointEigenSolver<Dense> gram(symmetrised(weighted_gram(Q, mass, Q, threads)));
      const Eigen::VectorXd& s = gram.eigenvalues();
      Eigen::Index first = 0;
      while (first < s.size() && !(s(first) > 1e-10 * s.maxCoeff())) ++first;
      const Eigen::Index rank = s.size() - first;
      Q = block_product(Q, gram.eigenvectors().rightCols(rank) * s.tail(rank).cwiseSqrt().cwiseInverse().asDiagonal(), threads);
      Q -= block_product(X, weighted_gram(X, mass, Q, threads), threads);  // what the scaling brought back of X
    }
    const Eigen::Index q = Q.cols();
    if (q == 0) break;  // nothing new to search: the residuals are below what round-off can improve
    const Dense LQ = sparse_times(L, Q, threads);
    // Rayleigh–Ritz on [X, Q], the Gram matrices computed in full (not assumed) so that the
    // returned vectors are M-orthonormal to round-off after any number of iterations.
    Dense GL(m + q, m + q), GM(m + q, m + q);
    GL.topLeftCorner(m, m) = weighted_gram(X, {}, LX, threads);
    GL.topRightCorner(m, q) = weighted_gram(X, {}, LQ, threads);
    GL.bottomLeftCorner(q, m) = GL.topRightCorner(m, q).transpose();
    GL.bottomRightCorner(q, q) = weighted_gram(Q, {}, LQ, threads);
    GM.topLeftCorner(m, m) = weighted_gram(X, mass, X, threads);
    GM.topRightCorner(m, q) = weighted_gram(X, mass, Q, threads);
    GM.bottomLeftCorner(q, m) = GM.topRightCorner(m, q).transpose();
    GM.bottomRightCorner(q, q) = weighted_gram(Q, mass, Q, threads);
    const Ritz r = ritz_pairs(GL, GM, m, kDrop);
    const Dense YX = r.coefficients.topRows(m), YQ = r.coefficients.bottomRows(q);
    // The step of the pairs still active, for the next iteration's search space.
    P = block_product(Q, column_subset(YQ, active), threads);
    X = block_product(X, YX, threads) + block_product(Q, YQ, threads);
    clear_fixed_rows(X);
    LX = sparse_times(L, X, threads);
    values = r.values;
  }
  vectors = std::move(X);
  report.residuals = eigen_residuals(L, M, values.head(k), vectors.leftCols(k), fixed);
  report.seconds = ice::seconds_since(start);
  return report;
}

}  // namespace fem
