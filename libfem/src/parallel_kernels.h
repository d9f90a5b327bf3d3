#pragma once
// Internal to libfem (not installed): bandwidth-bound kernels over compressed sparse matrices and
// vectors, threaded with OpenMP when available. They split outer indices (rows) into `threads`
// contiguous ranges when there are at least kParallelRows of them; smaller problems run serially
// (thread start-up would cost more than the pass). Two cores stream a matrix ~1.7x faster than one
// on the 2-core test machine.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <algorithm>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace fem {
namespace detail {

constexpr Eigen::Index kParallelRows = 50000;
using RowMajorSparse = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

/// OpenMP's default thread count (OMP_NUM_THREADS or the cores), 1 without OpenMP.
inline int default_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

inline int active_threads(Eigen::Index n, int threads) { return n >= kParallelRows ? std::max(threads, 1) : 1; }

// out[o] = Σ value·in[inner] over the stored entries of outer index o (column o of a column-major
// matrix, row o of a row-major one), or out[o] += that sum with `accumulate`: y = A x for a symmetric
// column-major A (column i is row i), c = Pᵀ r for a column-major P, x += P c for a row-major copy
// of P. Every output is one gather, so the outer indices split among threads without conflicts.
template <class Matrix>
void gather_product(const Matrix& M, const double* in, double* out, bool accumulate, int threads,
                    Eigen::Index work_size) {
  const auto* start = M.outerIndexPtr();
  const auto* inner = M.innerIndexPtr();
  const double* value = M.valuePtr();
  const Eigen::Index n = M.outerSize();
#pragma omp parallel for schedule(static) num_threads(active_threads(work_size, threads))
  for (Eigen::Index o = 0; o < n; ++o) {
    double s = 0;
    for (auto p = start[o]; p < start[o + 1]; ++p) s += value[p] * in[inner[p]];
    out[o] = accumulate ? out[o] + s : s;
  }
}

// out = Mᵀ in for k vectors stored row by row (in: M.outerSize() rows, out: M.innerSize() rows, k
// values each) and a row-major M (a compressed row-major P: out = Pᵀ in), the rows of `in` given a
// tile at a time by tile(top, rows, buffer) — a pointer to rows [top, top + rows), k values each,
// which it may write into `buffer` (kScatterTileRows · k doubles of the calling thread), so that a
// fine-size row-major input need not be written and read back, and a column-major one can be read
// column by column (gathering each row across columns waits on memory). Reads the rows once, in
// order, and scatters into `out`, which is small when M is tall (a prolongation). Rows are cut into
// `kScatterBlocks` fixed blocks, each accumulated into its own copy of `out` on any thread, and the
// copies added in block order: the result does not depend on the thread count.
constexpr int kScatterBlocks = 8;
constexpr Eigen::Index kScatterTileRows = 64;
template <class RowMajorMatrix, class Tile>
void scatter_transpose_tile_source(const RowMajorMatrix& M, Tile&& tile, double* out, Eigen::Index k, int threads) {
  const auto* start = M.outerIndexPtr();
  const auto* inner = M.innerIndexPtr();
  const double* value = M.valuePtr();
  const Eigen::Index n = M.outerSize(), m = M.innerSize();
  const Eigen::Index blocks = n >= kParallelRows ? kScatterBlocks : 1;
  std::vector<double> partial(static_cast<std::size_t>((blocks - 1) * m * k), 0.0);
#pragma omp parallel for schedule(static, 1) num_threads(active_threads(n, threads))
  for (Eigen::Index b = 0; b < blocks; ++b) {
    double* acc = b == 0 ? out : partial.data() + (b - 1) * m * k;
    if (b == 0) std::fill(out, out + m * k, 0.0);
    std::vector<double> buffer(static_cast<std::size_t>(kScatterTileRows * k));
    const Eigen::Index last = n * (b + 1) / blocks;
    for (Eigen::Index top = n * b / blocks; top < last; top += kScatterTileRows) {
      const Eigen::Index rows = std::min(kScatterTileRows, last - top);
      const double* rows_in = tile(top, rows, buffer.data());
      for (Eigen::Index r = top; r < top + rows; ++r) {
        const double* x = rows_in + (r - top) * k;
        for (auto p = start[r]; p < start[r + 1]; ++p) {
          double* y = acc + static_cast<Eigen::Index>(inner[p]) * k;
          const double w = value[p];
          for (Eigen::Index c = 0; c < k; ++c) y[c] += w * x[c];
        }
      }
    }
  }
  for (Eigen::Index b = 1; b < blocks; ++b) {
    const double* acc = partial.data() + (b - 1) * m * k;
    for (Eigen::Index i = 0; i < m * k; ++i) out[i] += acc[i];
  }
}

// The same with the rows stored: in[r·k + c].
template <class RowMajorMatrix>
void scatter_transpose_rows(const RowMajorMatrix& M, const double* in, double* out, Eigen::Index k, int threads) {
  scatter_transpose_tile_source(M, [in, k](Eigen::Index top, Eigen::Index, double*) { return in + top * k; }, out, k,
                                threads);
}

// out.col(first + c)(i) = finish(i, c, (M X)(i, c)) for rows i < M.outerSize() and c < width, X the
// k-column row-major block `in` (entry c of row r at in[r·k + c]) and a row-major M: gathered a tile
// of rows at a time into a small buffer, then written out into the columns — no fine-size row-major
// result is written and read back. Each (M X)(i, c) is gather_product's ordered sum for column c, to
// the bit.
template <class RowMajorMatrix, class Finish>
void gather_product_to_columns(const RowMajorMatrix& M, const double* in, Eigen::Index k, Eigen::Index width,
                               Eigen::MatrixXd& out, Eigen::Index first, int threads, Finish finish) {
  constexpr Eigen::Index kTileRows = 64;
  const auto* start = M.outerIndexPtr();
  const auto* inner = M.innerIndexPtr();
  const double* value = M.valuePtr();
  const Eigen::Index n = M.outerSize();
#pragma omp parallel num_threads(active_threads(n * k, threads))
  {
    std::vector<double> tile(static_cast<std::size_t>(kTileRows * k));
#pragma omp for schedule(static)
    for (Eigen::Index t = 0; t < (n + kTileRows - 1) / kTileRows; ++t) {
      const Eigen::Index begin = t * kTileRows, end = std::min(n, begin + kTileRows);
      for (Eigen::Index o = begin; o < end; ++o) {
        double* y = tile.data() + (o - begin) * k;
        for (Eigen::Index c = 0; c < k; ++c) y[c] = 0;
        for (auto p = start[o]; p < start[o + 1]; ++p) {
          const double w = value[p];
          const double* x = in + static_cast<Eigen::Index>(inner[p]) * k;
          for (Eigen::Index c = 0; c < k; ++c) y[c] += w * x[c];
        }
      }
      for (Eigen::Index c = 0; c < width; ++c) {
        double* o = out.col(first + c).data();
        for (Eigen::Index i = begin; i < end; ++i) o[i] = finish(i, c, tile[static_cast<std::size_t>((i - begin) * k + c)]);
      }
    }
  }
}

// out = M C, or out += M C with `accumulate`, for a row-major M (out: M.outerSize() rows) and a
// column-major C (M.innerSize() rows, out.cols() columns): chunks of 8 columns of C copied row by
// row, so M is streamed once per chunk (gather_product_to_columns; each entry is gather_product's
// ordered sum for its column, to the bit). Chunks of 8: M is small beside the rows of out when it is
// a prolongation, and 16 or 32 columns were no faster (docs/measurements.md, "The eigenbasis").
template <class RowMajorMatrix>
void product_to_columns(const RowMajorMatrix& M, const Eigen::MatrixXd& C, Eigen::MatrixXd& out, bool accumulate,
                        int threads) {
  using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  constexpr Eigen::Index kChunk = 8;
  RowMatrix chunk(C.rows(), kChunk);
  for (Eigen::Index first = 0; first < C.cols(); first += kChunk) {
    const Eigen::Index width = std::min(kChunk, C.cols() - first);
    chunk.leftCols(width) = C.middleCols(first, width);
    if (width < kChunk) chunk.rightCols(kChunk - width).setZero();
    gather_product_to_columns(M, chunk.data(), kChunk, width, out, first, threads,
                              [&out, first, accumulate](Eigen::Index i, Eigen::Index c, double u) {
                                return accumulate ? out(i, first + c) + u : u;
                              });
  }
}

// Vector kernels.
inline double dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b, int threads) {
  const Eigen::Index n = a.size();
  double sum = 0;
#pragma omp parallel for schedule(static) reduction(+ : sum) num_threads(active_threads(n, threads))
  for (Eigen::Index i = 0; i < n; ++i) sum += a[i] * b[i];
  return sum;
}
// y += alpha x
inline void axpy(double alpha, const Eigen::VectorXd& x, Eigen::VectorXd& y, int threads) {
  const Eigen::Index n = x.size();
#pragma omp parallel for schedule(static) num_threads(active_threads(n, threads))
  for (Eigen::Index i = 0; i < n; ++i) y[i] += alpha * x[i];
}
// y += c (every entry)
inline void add_constant(double c, Eigen::VectorXd& y, int threads) {
  const Eigen::Index n = y.size();
#pragma omp parallel for schedule(static) num_threads(active_threads(n, threads))
  for (Eigen::Index i = 0; i < n; ++i) y[i] += c;
}
// p = z + beta p
inline void xpby(const Eigen::VectorXd& z, double beta, Eigen::VectorXd& p, int threads) {
  const Eigen::Index n = z.size();
#pragma omp parallel for schedule(static) num_threads(active_threads(n, threads))
  for (Eigen::Index i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
}

}  // namespace detail
}  // namespace fem
