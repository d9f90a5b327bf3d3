// refine_eigenpairs (fem/eigen.h): the augmented subspace method or LOBPCG on the fine pencil, started
// from approximate pairs.
#include "fem/eigen.h"
#include "ice/wall_time.h"
#include "dense_blas.h"
#include "parallel_kernels.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace fem {

namespace {

using Clock = std::chrono::steady_clock;
using Dense = Eigen::MatrixXd;

// C = op(A) op(B) (+ C when `accumulate`), A and B dense column-major; op = transpose when asked.
void product(const Dense& A, bool transpose_a, const Dense& B, bool transpose_b, Dense& C, bool accumulate = false,
             double alpha = 1.0) {
  const Eigen::Index rows = transpose_a ? A.cols() : A.rows(), cols = transpose_b ? B.rows() : B.cols();
  if (!accumulate) C.resize(rows, cols);
  detail::gemm(A, transpose_a, B, transpose_b, C, alpha, accumulate ? 1.0 : 0.0);
}

// Aᵀ B.
Dense gram(const Dense& A, const Dense& B, int threads) {
  Dense C;
  detail::gram_by_rows(A, B, C, threads);
  return C;
}

// Aᵀ diag(w) B, a band of rows at a time: no n-row copy of diag(w) B is kept.
Dense mass_gram(const Dense& A, const Eigen::VectorXd& w, const Dense& B) {
  constexpr Eigen::Index kBand = 4096;
  Dense C = Dense::Zero(A.cols(), B.cols());
  if (A.cols() == 0 || B.cols() == 0) return C;
  Dense band;
  for (Eigen::Index first = 0; first < A.rows(); first += kBand) {
    const Eigen::Index rows = std::min(kBand, A.rows() - first);
    band.noalias() = w.segment(first, rows).asDiagonal() * B.middleRows(first, rows);
    detail::gemm(A.middleRows(first, rows), true, band, false, C, 1.0, 1.0);
  }
  return C;
}

// Aᵀ diag(w) A for w >= 0 from √w (half mass_gram's products); both triangles filled.
Dense mass_self_gram(const Dense& A, const Eigen::VectorXd& root_w, int threads) {
  Dense C;
  detail::self_gram_by_rows(A, root_w, C, threads);
  return C;
}

// A Y.
Dense block_product(const Dense& A, const Dense& Y) {
  Dense C;
  product(A, false, Y, false, C);
  return C;
}

// Columns [first, first + W) of L X for a symmetric L (column i is row i): one pass over L for the
// W columns, each entry summed in the order of L's column i, as gather_product sums it.
template <int W>
void sparse_times_columns(const SparseMatrix& L, const Dense& X, Dense& out, Eigen::Index first, int width, int threads) {
  const auto* start = L.outerIndexPtr();
  const auto* inner = L.innerIndexPtr();
  const double* value = L.valuePtr();
  const Eigen::Index n = L.rows();
  const double* x = X.data() + first * n;
  double* y = out.data() + first * n;
  const int w = W > 0 ? W : width;
#pragma omp parallel for schedule(static) num_threads(detail::active_threads(n, threads))
  for (Eigen::Index i = 0; i < n; ++i) {
    double sum[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (auto p = start[i]; p < start[i + 1]; ++p) {
      const double a = value[p];
      const double* row = x + inner[p];
      for (int c = 0; c < w; ++c) sum[c] += a * row[c * n];
    }
    for (int c = 0; c < w; ++c) y[c * n + i] = sum[c];
  }
}

// L X for a symmetric L, 8 columns per pass over L: L is read from memory once per 8 columns, and
// the 8 columns' rows near row i are in cache when L's numbering is local (refined_eigenbasis
// numbers the fine vertices breadth-first). Each entry is summed in one order whatever the threads.
void sparse_times(const SparseMatrix& L, const Dense& X, Dense& out, int threads) {
  constexpr int kChunk = 8;
  out.resize(L.rows(), X.cols());  // kept when it has that size already
  for (Eigen::Index first = 0; first < X.cols(); first += kChunk) {
    const int width = static_cast<int>(std::min<Eigen::Index>(kChunk, X.cols() - first));
    if (width == kChunk)
      sparse_times_columns<kChunk>(L, X, out, first, width, threads);
    else
      sparse_times_columns<0>(L, X, out, first, width, threads);
  }
}

Dense symmetrised(const Dense& G) { return 0.5 * (G + G.transpose()); }

// Coefficients B of an orthonormal basis of a Gram matrix G's numerically independent part
// (BᵀGB = I): G = V S Vᵀ, directions with S below `drop`·max S left out, B = V S^-1/2 (SVQB).
Dense independent_orthonormal_basis(const Dense& G, double drop) {
  Eigen::SelfAdjointEigenSolver<Dense> solver(symmetrised(G));
  const Eigen::VectorXd& s = solver.eigenvalues();
  const double largest = s.size() ? s.maxCoeff() : 0;
  Eigen::Index first = 0;
  while (first < s.size() && !(s(first) > drop * largest)) ++first;
  const Eigen::Index kept = s.size() - first;
  return solver.eigenvectors().rightCols(kept) * s.tail(kept).cwiseSqrt().cwiseInverse().asDiagonal();
}

// The `count` smallest Ritz pairs of the pencil (GL, GM) on GM's numerically independent part
// (a search space that lost rank leaves directions out): BᵀGL B diagonalised. Columns of the
// returned coefficients are GM-orthonormal.
struct Ritz {
  Eigen::VectorXd values;
  Dense coefficients;
};

Ritz ritz_pairs(const Dense& GL, const Dense& GM, Eigen::Index count, double drop, const char* who = "refine_eigenpairs") {
  const Dense B = independent_orthonormal_basis(GM, drop);
  if (B.cols() < count)
    throw std::runtime_error(std::string(who) + ": the search space lost rank (linearly dependent vectors)");
  Eigen::SelfAdjointEigenSolver<Dense> stiffness(symmetrised(B.transpose() * GL * B));
  return {stiffness.eigenvalues().head(count), B * stiffness.eigenvectors().leftCols(count)};
}

// A itself when compressed, else a compressed copy of it in `copy` (the threaded products read the
// compressed arrays directly).
const SparseMatrix& compressed(const SparseMatrix& A, SparseMatrix& copy) {
  if (A.isCompressed()) return A;
  copy = A;
  copy.makeCompressed();
  return copy;
}

// A pair's relative residual ‖Lφ − θMφ‖ / (scale ‖Mφ‖) from the two norms, a zero mode's scale
// `largest` instead of |θ| (as eigen_residuals judges it); infinite when the denominator vanishes.
double relative_residual(double residual_norm, double mass_norm, double theta, double largest) {
  const double denominator = (is_zero_mode(theta, largest) ? largest : std::abs(theta)) * mass_norm;
  return denominator > 0 ? residual_norm / denominator : std::numeric_limits<double>::infinity();
}

Dense column_subset(const Dense& A, const std::vector<Eigen::Index>& which) {
  Dense out(A.rows(), static_cast<Eigen::Index>(which.size()));
  for (std::size_t c = 0; c < which.size(); ++c) out.col(static_cast<Eigen::Index>(c)) = A.col(which[c]);
  return out;
}

// Pᵀ Y and Pᵀ diag(w) Y together for a row-major P (n × N_c) and a column-major n × q block Y: a
// chunk of columns at a time, a tile of fine rows read column by column and scattered into the
// coarse rows (the same order of sums whatever the thread count: scatter_transpose_tile_source).
void restrict_block(const detail::RowMajorSparse& P, const Dense& LY, const Dense& Y, const Eigen::VectorXd& w,
                    Dense& restricted_LY, Dense& restricted_MY, int threads) {
  constexpr Eigen::Index kChunk = 8;
  const Eigen::Index q = Y.cols(), coarse = P.cols();
  restricted_LY.resize(coarse, q);
  restricted_MY.resize(coarse, q);
  std::vector<double> rows(static_cast<std::size_t>(coarse * 2 * kChunk));
  for (Eigen::Index first = 0; first < q; first += kChunk) {
    const Eigen::Index width = std::min(kChunk, q - first), k = 2 * width;
    detail::scatter_transpose_tile_source(
        P,
        [&](Eigen::Index top, Eigen::Index count, double* tile) {
          for (Eigen::Index c = 0; c < width; ++c) {
            const double* ly = LY.col(first + c).data() + top;
            const double* y = Y.col(first + c).data() + top;
            for (Eigen::Index i = 0; i < count; ++i) {
              tile[i * k + c] = ly[i];
              tile[i * k + width + c] = w(top + i) * y[i];
            }
          }
          return static_cast<const double*>(tile);
        },
        rows.data(), k, threads);
    for (Eigen::Index i = 0; i < coarse; ++i)
      for (Eigen::Index c = 0; c < width; ++c) {
        restricted_LY(i, first + c) = rows[static_cast<std::size_t>(i * k + c)];
        restricted_MY(i, first + c) = rows[static_cast<std::size_t>(i * k + width + c)];
      }
  }
}

// refine_eigenpairs with either kind of preconditioner (exactly one given).
EigenRefineReport refine(const SparseMatrix& given_L, const SparseMatrix& M, Eigen::VectorXd& values, Eigen::MatrixXd& vectors,
                         int k, const BlockPreconditioner* block, const InPlacePreconditioner* in_place,
                         const std::vector<Index>& fixed, const EigenRefineOptions& options,
                         const EigenCoarseDirections* coarse) {
  const auto start = Clock::now();
  SparseMatrix compressed_L;
  const SparseMatrix& L = compressed(given_L, compressed_L);
  const Eigen::Index n = L.rows(), m = vectors.cols();
  if (L.cols() != n || M.rows() != n || M.cols() != n || vectors.rows() != n)
    throw std::invalid_argument("refine_eigenpairs: L, M (" + std::to_string(M.rows()) + " x " + std::to_string(M.cols()) +
                                ") and the vectors (" + std::to_string(vectors.rows()) + " rows) do not match L's size " +
                                std::to_string(n));
  if (!(options.tolerance > 0) || options.max_iterations < 1)
    throw std::invalid_argument("refine_eigenpairs: need tolerance > 0 and max_iterations >= 1");
  if (block ? !*block : !in_place || !*in_place) throw std::invalid_argument("refine_eigenpairs: no preconditioner");
  std::vector<char> is_fixed(static_cast<std::size_t>(n), 0);
  for (Index i : fixed) {
    if (i < 0 || i >= n) throw std::invalid_argument("refine_eigenpairs: Dirichlet index " + std::to_string(i) + " out of range");
    is_fixed[static_cast<std::size_t>(i)] = 1;
  }
  const Eigen::Index free_count = n - std::count(is_fixed.begin(), is_fixed.end(), 1);
  if (k < 1 || k > m || m >= free_count)
    throw std::invalid_argument("refine_eigenpairs: need 1 <= k <= m < free unknowns (k = " + std::to_string(k) +
                                ", m = " + std::to_string(m) + ", " + std::to_string(free_count) + " free unknowns)");
  const Eigen::Index g = coarse ? coarse->coarse_vectors.cols() : 0;
  if (coarse) {
    const SparseMatrix* P = coarse->prolongation;
    if (!P || P->rows() != n || coarse->coarse_vectors.rows() != P->cols() || coarse->laplacian_gram.rows() != g ||
        coarse->laplacian_gram.cols() != g || coarse->mass_gram.rows() != g || coarse->mass_gram.cols() != g)
      throw std::invalid_argument("refine_eigenpairs: the coarse directions' prolongation, vectors and Gram matrices do "
                                  "not match (" + std::to_string(n) + " fine rows)");
  }
  // G must vanish at the Dirichlet rows, as the vectors do (a barycentric P's row at a coarse vertex
  // that Ψ leaves out is zero there).
  detail::RowMajorSparse coarse_rows;
  if (coarse) {
    coarse_rows = *coarse->prolongation;
    for (Index i : fixed) {
      Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(g);
      for (detail::RowMajorSparse::InnerIterator it(coarse_rows, i); it; ++it)
        row += it.value() * coarse->coarse_vectors.row(it.col());
      if (!row.isZero(0))
        throw std::invalid_argument("refine_eigenpairs: the coarse directions do not vanish at the Dirichlet row " +
                                    std::to_string(i));
    }
  }
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
  // √M for the symmetric mass Gram matrices (M's diagonal is positive off `fixed`, where the vectors
  // are zero: a negative entry there is left out with its zero rows).
  const Eigen::VectorXd root_mass = mass.cwiseMax(0).cwiseSqrt();
  EigenRefineReport report;
  const auto L_times_into = [&](const Dense& Y, Dense& LY) {
    const auto product_start = Clock::now();
    sparse_times(L, Y, LY, threads);
    report.sparse_seconds += ice::seconds_since(product_start);
  };
  const auto L_times = [&](const Dense& Y) {
    Dense LY;
    L_times_into(Y, LY);
    return LY;
  };
  const auto clear_fixed_rows = [&](Dense& A) {
    for (Index i : fixed) A.row(i).setZero();
  };
  // Directions whose mass-Gram eigenvalue is below this share of the largest are dependent: ~1e-12
  // keeps what double precision can still orthonormalise (a basis of condition number up to ~1e6);
  // the Gram matrices are always computed in full, so what is kept is used exactly.
  constexpr double kDrop = 1e-12;
  // M-orthonormalises the columns of V, dropping the numerically dependent ones: each column
  // normalised, then the Gram matrix's independent part.
  const auto orthonormalise = [&](Dense& V) {
    const Dense G = mass_self_gram(V, root_mass, threads);
    Eigen::VectorXd scale = G.diagonal().cwiseMax(0).cwiseSqrt();
    const double largest_scale = scale.size() ? scale.maxCoeff() : 0;
    for (Eigen::Index j = 0; j < scale.size(); ++j) scale(j) = scale(j) > 1e-14 * largest_scale ? 1 / scale(j) : 0;
    V = block_product(V, scale.asDiagonal() * independent_orthonormal_basis(scale.asDiagonal() * G * scale.asDiagonal(), 1e-10));
  };

  // Memory: LOBPCG holds X and, at most, four more blocks of n rows and up to m columns (R or the
  // new directions W with P, their L-products, or the updated X with the next step); the augmented
  // subspace method X and at most one more (R, L U, or the updated X) and a few preconditioned
  // columns. M is diagonal and applied on the fly.
  // The caller's vectors are worked on in place of a copy (an n × m block less at the peak); a throw
  // after the argument checks leaves them valid but unspecified.
  Dense X = std::move(vectors);
  vectors.resize(n, 0);
  Eigen::VectorXd theta;
  clear_fixed_rows(X);
  {
    // Rayleigh–Ritz on the start vectors: M-orthonormal Ritz vectors whatever the start. L X is
    // freed before the rotated X is made (no third n × m block).
    Dense LX = L_times(X);
    const auto phase_start = Clock::now();
    const Dense XLX = gram(X, LX, threads);
    LX.resize(0, 0);
    const Ritz r = ritz_pairs(XLX, mass_self_gram(X, root_mass, threads), m, kDrop);
    X = block_product(X, r.coefficients);
    report.dense_seconds += ice::seconds_since(phase_start);
    theta = r.values;
  }
  Eigen::VectorXd residual(m);
  // The residuals R = L X − M X Θ of the current pairs (outside the Dirichlet rows), their relative
  // norms in `residual`; zero modes are judged against the largest |λ| of all m pairs: the guards'
  // are not round-off even when the first k are all zero modes (k at most the component count); when
  // all m are, against the spectrum's scale (zero_mode_scale).
  // One pass over R per column: the Dirichlet rows are cleared first (X and M X are 0 there).
  const auto residuals_of = [&](Dense& R) {
    clear_fixed_rows(R);
    const double largest = std::max(zero_mode_scale(theta.cwiseAbs().maxCoeff(), L, M), std::numeric_limits<double>::min());
#pragma omp parallel for schedule(static) num_threads(detail::active_threads(n, threads))
    for (Eigen::Index j = 0; j < m; ++j) {
      double mass_norm2 = 0, residual_norm2 = 0;
      for (Eigen::Index i = 0; i < n; ++i) {
        const double mx = mass(i) * X(i, j);
        const double r = R(i, j) -= theta(j) * mx;
        mass_norm2 += mx * mx;
        residual_norm2 += r * r;
      }
      residual(j) = relative_residual(std::sqrt(residual_norm2), std::sqrt(mass_norm2), theta(j), largest);
    }
  };
  // After the residuals of an iteration: records them and says whether to stop (converged, or the
  // iteration limit reached).
  const auto stop_at = [&](int iteration) {
    report.history.push_back(residual.head(k).maxCoeff());
    report.iterations = iteration;
    report.converged = residual.head(k).maxCoeff() <= options.tolerance;
    return report.converged || iteration == options.max_iterations;
  };
  // Soft locking: converged pairs stay in the Rayleigh–Ritz but get no new direction.
  const auto still_active = [&] {
    std::vector<Eigen::Index> active;
    for (Eigen::Index j = 0; j < m; ++j)
      if (residual(j) > options.tolerance) active.push_back(j);
    return active;
  };
  // T R for the active columns of R (an in-place preconditioner subtracts from a zero block).
  const auto preconditioned = [&](const Dense& R, const std::vector<Eigen::Index>& active) {
    const bool all = static_cast<Eigen::Index>(active.size()) == R.cols();
    const Dense RA = all ? Dense() : column_subset(R, active);
    const auto precondition_start = Clock::now();
    Dense W;
    if (block) {
      W = (*block)(all ? R : RA);
    } else {
      W = Dense::Zero(n, static_cast<Eigen::Index>(active.size()));
      std::vector<Eigen::Index> columns(active.size());
      std::iota(columns.begin(), columns.end(), Eigen::Index{0});
      (*in_place)(all ? R : RA, columns, W);
      W = -W;
    }
    report.precondition_seconds += ice::seconds_since(precondition_start);
    if (W.rows() != n || W.cols() != static_cast<Eigen::Index>(active.size()))
      throw std::invalid_argument("refine_eigenpairs: the preconditioner returned a block of the wrong size");
    clear_fixed_rows(W);
    return W;
  };

  if (coarse) {
    // The augmented subspace method: Rayleigh–Ritz on [U, G], U = X − T R. Per iteration: L X (the
    // residuals), the preconditioner, L U, Uᵀ L U and Uᵀ M U, G's products through the coarse
    // space (one restriction of L U and M U), and X = U Y_U + P (Ψ Y_G).
    const Dense& psi = coarse->coarse_vectors;
    // One n × m block beside X holds R, then L U, then the next X (their lifetimes do not overlap),
    // and the next X's storage is swapped with X's: a fresh n × m allocation per product would have
    // the kernel map and zero its pages again (docs/measurements.md, the refined eigenbasis).
    Dense scratch;
    for (int iteration = 0;; ++iteration) {
      Dense& R = scratch;
      L_times_into(X, R);
      residuals_of(R);
      if (stop_at(iteration)) break;
      const std::vector<Eigen::Index> active = still_active();
      // U = X − T R: in place, or a few columns at a time (no n × m block of T R is held beside X
      // and R; the preconditioner solves columns independently anyway).
      if (in_place) {
        const auto precondition_start = Clock::now();
        (*in_place)(R, active, X);
        report.precondition_seconds += ice::seconds_since(precondition_start);
        clear_fixed_rows(X);
      } else {
        constexpr std::size_t kColumnsPerCall = 32;
        for (std::size_t first = 0; first < active.size(); first += kColumnsPerCall) {
          const std::vector<Eigen::Index> some(
              active.begin() + static_cast<std::ptrdiff_t>(first),
              active.begin() + static_cast<std::ptrdiff_t>(std::min(active.size(), first + kColumnsPerCall)));
          const Dense W = preconditioned(R, some);
#pragma omp parallel for schedule(static) num_threads(detail::active_threads(n, threads))
          for (std::size_t c = 0; c < some.size(); ++c) X.col(some[c]) -= W.col(static_cast<Eigen::Index>(c));
        }
      }
      // X now holds U. The Gram matrices of [U, G]: U's own computed in full, G's given.
      Dense GL(m + g, m + g), GM(m + g, m + g);
      {
        Dense& LU = scratch;
        L_times_into(X, LU);
        auto phase_start = Clock::now();
        GL.topLeftCorner(m, m) = gram(X, LU, threads);
        GM.topLeftCorner(m, m) = mass_self_gram(X, root_mass, threads);
        report.dense_seconds += ice::seconds_since(phase_start);
        phase_start = Clock::now();
        Dense restricted_LU, restricted_MU;
        restrict_block(coarse_rows, LU, X, mass, restricted_LU, restricted_MU, threads);
        // (Pᵀ L U)ᵀ Ψ and (Pᵀ M U)ᵀ Ψ by the BLAS: coarse-size products of m × N_c × g, several times
        // slower in Eigen built for the baseline instruction set.
        detail::gemm(restricted_LU, true, psi, false, GL.topRightCorner(m, g));
        detail::gemm(restricted_MU, true, psi, false, GM.topRightCorner(m, g));
        report.coarse_seconds += ice::seconds_since(phase_start);
      }
      GL.bottomRightCorner(g, g) = coarse->laplacian_gram;
      GM.bottomRightCorner(g, g) = coarse->mass_gram;
      GL.triangularView<Eigen::StrictlyLower>() = GL.transpose();
      GM.triangularView<Eigen::StrictlyLower>() = GM.transpose();
      auto phase_start = Clock::now();
      const Ritz r = ritz_pairs(GL, GM, m, kDrop);
      Dense& moved = scratch;
      product(X, false, r.coefficients.topRows(m), false, moved);
      report.dense_seconds += ice::seconds_since(phase_start);
      phase_start = Clock::now();
      Dense coarse_coefficients(psi.rows(), m);  // Ψ Y_G
      detail::gemm(psi, false, r.coefficients.bottomRows(g), false, coarse_coefficients);
      detail::product_to_columns(coarse_rows, coarse_coefficients, moved, true, threads);
      report.coarse_seconds += ice::seconds_since(phase_start);
      clear_fixed_rows(moved);
      X.swap(moved);
      theta = r.values;
    }
  } else {
    // LOBPCG: Rayleigh–Ritz on [X, W, P].
    Dense P(n, 0);
    for (int iteration = 0;; ++iteration) {
      // Residuals R = L X − M X Θ, outside the Dirichlet rows; X's Gram blocks from the same L X
      // (computed, not assumed: the Rayleigh–Ritz then corrects any drift of X from M-orthonormality).
      Dense R = L_times(X);
      auto phase_start = Clock::now();
      const Dense XLX = gram(X, R, threads), XMX = mass_self_gram(X, root_mass, threads);
      report.dense_seconds += ice::seconds_since(phase_start);
      residuals_of(R);
      if (stop_at(iteration)) break;
      const std::vector<Eigen::Index> active = still_active();
      Dense W = preconditioned(R, active);
      R.resize(0, 0);
      // The rest of the iteration is dense products but for the L products (timed apart).
      phase_start = Clock::now();
      const double sparse_before = report.sparse_seconds;
      // The new directions: W M-orthogonal to X, then W and P each M-orthonormal (their mutual and
      // X–P products are computed, not assumed).
      product(X, false, mass_gram(X, mass, W), false, W, true, -1.0);
      orthonormalise(W);
      if (P.cols() > 0) orthonormalise(P);
      const Eigen::Index a = W.cols(), p = P.cols(), q = a + p;
      if (q == 0) {
        report.dense_seconds += ice::seconds_since(phase_start) - (report.sparse_seconds - sparse_before);
        break;
      }  // nothing new to search: the residuals are below what round-off can improve
      // Rayleigh–Ritz on [X, W, P], every Gram block computed (X, W and P are M-orthonormal only to
      // the accuracy of their last orthonormalisation).
      Dense GL(m + q, m + q), GM(m + q, m + q);
      GL.topLeftCorner(m, m) = XLX;
      GM.topLeftCorner(m, m) = XMX;
      {
        const Dense LW = L_times(W);
        GL.block(0, m, m, a) = gram(X, LW, threads);
        GL.block(m, m, a, a) = gram(W, LW, threads);
      }
      GM.block(0, m, m, a) = mass_gram(X, mass, W);
      GM.block(m, m, a, a) = mass_self_gram(W, root_mass, threads);
      if (p > 0) {
        const Dense LP = L_times(P);
        GL.block(0, m + a, m, p) = gram(X, LP, threads);
        GL.block(m, m + a, a, p) = gram(W, LP, threads);
        GL.block(m + a, m + a, p, p) = gram(P, LP, threads);
        GM.block(0, m + a, m, p) = mass_gram(X, mass, P);
        GM.block(m, m + a, a, p) = mass_gram(W, mass, P);
        GM.block(m + a, m + a, p, p) = mass_self_gram(P, root_mass, threads);
      }
      GL.triangularView<Eigen::StrictlyLower>() = GL.transpose();
      GM.triangularView<Eigen::StrictlyLower>() = GM.transpose();
      const Ritz r = ritz_pairs(GL, GM, m, kDrop);
      const Dense YX = r.coefficients.topRows(m), YW = r.coefficients.middleRows(m, a), YP = r.coefficients.bottomRows(p);
      // The step of the pairs still active, for the next iteration's search space; X moves by it.
      Dense step = block_product(W, column_subset(YW, active));
      if (p > 0) product(P, false, column_subset(YP, active), false, step, true);
      {
        Dense moved = block_product(X, YX);
        product(W, false, YW, false, moved, true);
        if (p > 0) product(P, false, YP, false, moved, true);
        X = std::move(moved);
      }
      P = std::move(step);
      theta = r.values;
      report.dense_seconds += ice::seconds_since(phase_start) - (report.sparse_seconds - sparse_before);
    }
  }
  values = std::move(theta);
  vectors = std::move(X);
  report.residuals = residual.head(k);
  report.seconds = ice::seconds_since(start);
  return report;
}

}  // namespace

EigenRefineReport refine_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, Eigen::VectorXd& values,
                                    Eigen::MatrixXd& vectors, int k, const BlockPreconditioner& preconditioner,
                                    const std::vector<Index>& fixed, const EigenRefineOptions& options,
                                    const EigenCoarseDirections* coarse) {
  return refine(L, M, values, vectors, k, &preconditioner, nullptr, fixed, options, coarse);
}

EigenRefineReport refine_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, Eigen::VectorXd& values,
                                    Eigen::MatrixXd& vectors, int k, const InPlacePreconditioner& preconditioner,
                                    const std::vector<Index>& fixed, const EigenRefineOptions& options,
                                    const EigenCoarseDirections* coarse) {
  return refine(L, M, values, vectors, k, nullptr, &preconditioner, fixed, options, coarse);
}

Eigenpairs subspace_eigenpairs(const SparseMatrix& L, const SparseMatrix& M, int count, int accurate,
                               const SubspaceIterationOptions& options) {
  const Eigen::Index n = L.rows();
  if (L.cols() != n || M.rows() != n || M.cols() != n)
    throw std::invalid_argument("subspace_eigenpairs: L (" + std::to_string(L.rows()) + " x " + std::to_string(L.cols()) +
                                ") and M (" + std::to_string(M.rows()) + " x " + std::to_string(M.cols()) +
                                ") must be square and of one size");
  if (accurate < 1 || accurate > count || count >= n)
    throw std::invalid_argument("subspace_eigenpairs: need 1 <= accurate <= count < n (accurate = " + std::to_string(accurate) +
                                ", count = " + std::to_string(count) + ", n = " + std::to_string(n) + ")");
  if (!(options.tolerance > 0) || options.max_iterations < 1)
    throw std::invalid_argument("subspace_eigenpairs: need tolerance > 0 and max_iterations >= 1");
  const double spectrum = L.diagonal().sum() / M.diagonal().sum();
  if (!(spectrum > 0) || !std::isfinite(spectrum))
    throw std::invalid_argument("subspace_eigenpairs: L's and M's diagonals must be positive");
  double c = spectrum / static_cast<double>(n);
  const int threads = options.threads > 0 ? options.threads : detail::default_threads();
  SparseMatrix compressed_M;
  const SparseMatrix& mass = compressed(M, compressed_M);
  Eigenpairs out;
  CholeskySolver inverse;
  inverse.set_ordering(options.ordering);
  auto phase_start = Clock::now();
  inverse.compute(SparseMatrix(L + c * M));
  out.factor_seconds = ice::seconds_since(phase_start);
  Dense Q(n, count);
  {
    std::mt19937_64 random(20230801);
    std::normal_distribution<double> normal;
    for (Eigen::Index j = 0; j < Q.size(); ++j) Q.data()[j] = normal(random);
  }
  Dense B;  // M Q, then kept as (M Y) C
  sparse_times(mass, Q, B, threads);
  Q.resize(0, 0);
  Dense MY, LY, GL, GM, LQ;
  for (int iteration = 1;; ++iteration) {
    phase_start = Clock::now();
    const Dense Y = inverse.solve_multiple(B);
    out.solve_seconds += ice::seconds_since(phase_start);
    out.operations += count;
    sparse_times(mass, Y, MY, threads);
    LY = B - c * MY;  // L Y = (L + cM) Y − c M Y: no product with L
    product(Y, true, LY, false, GL);
    product(Y, true, MY, false, GM);
    const Ritz r = ritz_pairs(GL, GM, count, 1e-12, "subspace_eigenpairs");
    product(Y, false, r.coefficients, false, Q);
    product(MY, false, r.coefficients, false, B);
    product(LY, false, r.coefficients.leftCols(accurate), false, LQ);
    // The first `accurate` pairs' relative residuals, zero modes judged as eigen_residuals judges them.
    const double largest = zero_mode_scale(r.values.cwiseAbs().maxCoeff(), L, M);
    double worst = 0;
    for (Eigen::Index j = 0; j < accurate; ++j) {
      const double residual = relative_residual((LQ.col(j) - r.values(j) * B.col(j)).norm(), B.col(j).norm(), r.values(j), largest);
      worst = std::max(worst, std::isfinite(residual) ? residual : std::numeric_limits<double>::infinity());
    }
    if (worst <= options.tolerance) {
      out.shift = -c;
      out.values = r.values;
      out.vectors = std::move(Q);
      out.restarts = iteration;
      return out;
    }
    if (iteration == options.max_iterations)
      throw std::runtime_error("subspace_eigenpairs: the first " + std::to_string(accurate) + " of " + std::to_string(count) +
                               " pairs did not converge within " + std::to_string(options.max_iterations) +
                               " iterations (largest residual " + std::to_string(worst) + ")");
    // A shift far above the block's spectrum (Weyl's estimate misjudges meshes of very unequal
    // components) slows every pair; a thousandth of the block's largest Ritz value keeps the rate
    // λ_j / λ_count within 10⁻³ and the zero modes' amplification under ~10³. Refactored (same
    // pattern) only when that is a tenth of the shift or less, so even meshes keep Weyl's.
    const double target = 1e-3 * r.values(count - 1);
    if (target > 0 && target <= 0.1 * c) {
      c = target;
      phase_start = Clock::now();
      inverse.factorize(SparseMatrix(L + c * M));
      out.factor_seconds += ice::seconds_since(phase_start);
    }
  }
}

}  // namespace fem
