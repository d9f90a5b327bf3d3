#include "fem/multigrid.h"

#include <Eigen/Eigenvalues>

#include "fem/ordering.h"
#include "parallel_kernels.h"
#include "sparse_columns.h"
#include "ice/wall_time.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

namespace fem {

namespace {

using namespace detail;
using Clock = std::chrono::steady_clock;

// y = A x for a symmetric compressed column-major A.
void multiply(const SparseMatrix& A, const double* x, double* y, int threads) {
  gather_product(A, x, y, false, threads, A.outerSize());
}

using Block = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Threaded Gauss–Seidel ("hybrid" Gauss–Seidel): the rows are split into `parts` contiguous ranges,
// each swept by one thread; a coupling to a row of another range reads that row's value from the
// start of the sweep (a snapshot in the halo), a coupling within the range the current value. Each
// range is thus an exact Gauss–Seidel sweep and the ranges are coupled like block Jacobi; the
// result depends on `parts` but not on thread timing. The backward sweep over the same ranges is
// the transpose of the forward one, so the symmetric smoother stays symmetric (valid inside CG).
// It only pays in the solver's locality order (options.reorder), where a range is a compact region
// and the split cuts few couplings (in a Loop-subdivided mesh's own order it cost 5 more PCG
// iterations at 99k unknowns, tolerance 1e-10). `column` is A's inner index array with every cross-range reference j replaced by
// n + (j's halo slot).
struct SweepSplit {
  int parts = 1;
  std::vector<Eigen::Index> bounds;  // range t is rows [bounds[t], bounds[t+1])
  std::vector<Index> column;
  std::vector<Index> halo;             // slot -> row
};

SweepSplit make_split(const SparseMatrix& A, int parts) {
  SweepSplit split;
  const Eigen::Index n = A.outerSize();
  split.parts = parts;
  for (int t = 0; t <= parts; ++t) split.bounds.push_back(n * t / parts);
  const auto* start = A.outerIndexPtr();
  const auto* inner = A.innerIndexPtr();
  split.column.assign(inner, inner + A.nonZeros());
  std::vector<Index> slot(static_cast<std::size_t>(n), -1);
  for (int t = 0; t < parts; ++t)
    for (Eigen::Index i = split.bounds[static_cast<std::size_t>(t)]; i < split.bounds[static_cast<std::size_t>(t) + 1]; ++i)
      for (auto p = start[i]; p < start[i + 1]; ++p) {
        const int j = inner[p];
        if (j >= split.bounds[static_cast<std::size_t>(t)] && j < split.bounds[static_cast<std::size_t>(t) + 1]) continue;
        int& s = slot[static_cast<std::size_t>(j)];
        if (s < 0) {
          s = static_cast<int>(split.halo.size());
          split.halo.push_back(j);
        }
        split.column[static_cast<std::size_t>(p)] = static_cast<int>(n) + s;
      }
  return split;
}

// The one kernel over rows [lo, hi) of a compressed symmetric A (column i read as row i), for k
// vectors stored row-major (row i holds unknown i of the k systems; k = 1 is a plain vector). The
// column count is a template parameter for 1..16 (the k-wide loops live in registers and
// vectorise), runtime otherwise (K = 0). Mode 0: out = b − A x; mode 1: out = A x; mode 2 / 3: a
// forward / backward Gauss–Seidel sweep on x; mode 4: a forward sweep from x = 0, which neither
// reads x before writing it nor gathers the unknowns not yet swept (the same numbers as mode 2 on a
// zeroed x, without that pass over x). A column index c ≥ n reads row c − n of `halo`.
template <int K>
struct Width {
  static constexpr Eigen::Index get(Eigen::Index) { return K; }
};
template <>
struct Width<0> {
  static Eigen::Index get(Eigen::Index k) { return k; }
};

template <int K, int Mode, class Value>
void row_kernel(const SparseMatrix& A, const Value* value, const int* column, const double* halo, const double* inv_diag,
                const double* b, double* x, double* out, Eigen::Index k_runtime, Eigen::Index lo, Eigen::Index hi) {
  const auto* start = A.outerIndexPtr();
  const Eigen::Index n = A.outerSize(), k = Width<K>::get(k_runtime);
  constexpr int kMax = K > 0 ? K : 64;
  double local[kMax];
  std::vector<double> heap;
  double* s = local;
  if (K == 0 && k > kMax) {
    heap.resize(static_cast<std::size_t>(k));
    s = heap.data();
  }
  for (Eigen::Index step = lo; step < hi; ++step) {
    const Eigen::Index i = Mode == 3 ? hi - 1 - (step - lo) : step;
    if (Mode == 1) {
      for (Eigen::Index c = 0; c < k; ++c) s[c] = 0;
    } else {
      for (Eigen::Index c = 0; c < k; ++c) s[c] = b[i * k + c];
    }
    for (auto p = start[i]; p < start[i + 1]; ++p) {
      const Eigen::Index j = column[p];
      if (Mode == 4 && j >= i) continue;  // still zero (a halo column is >= n)
      const double a = Mode == 1 ? -static_cast<double>(value[p]) : static_cast<double>(value[p]);
      const double* xr = j < n ? x + j * k : halo + (j - n) * k;
      for (Eigen::Index c = 0; c < k; ++c) s[c] -= a * xr[c];
    }
    if (Mode <= 1) {
      for (Eigen::Index c = 0; c < k; ++c) out[i * k + c] = s[c];
    } else if (Mode == 4) {
      const double d = inv_diag[i];
      for (Eigen::Index c = 0; c < k; ++c) x[i * k + c] = s[c] * d;
    } else {
      const double d = inv_diag[i];
      for (Eigen::Index c = 0; c < k; ++c) x[i * k + c] += s[c] * d;
    }
  }
}

// Runs row_kernel over all rows with A's pattern and `value` (A's values, or a float copy of them):
// products and residuals split among `threads` (no dependencies), sweeps by `split` when it has
// several parts, else serially.
template <int K, int Mode, class Value>
void run_rows(const SparseMatrix& A, const Value* value, const SweepSplit* split, const double* inv_diag, const double* b,
              double* x, double* out, Eigen::Index k, int threads, std::vector<double>& halo) {
  const Eigen::Index n = A.outerSize();
  const int* column = A.innerIndexPtr();
  if (Mode <= 1) {
    const int parts = active_threads(n, threads);
#pragma omp parallel for schedule(static, 1) num_threads(parts)
    for (int t = 0; t < parts; ++t)
      row_kernel<K, Mode>(A, value, column, nullptr, inv_diag, b, x, out, k, n * t / parts, n * (t + 1) / parts);
    return;
  }
  if (split == nullptr || split->parts <= 1) {
    row_kernel<K, Mode>(A, value, column, nullptr, inv_diag, b, x, out, k, 0, n);
    return;
  }
  if (Mode != 4) {  // mode 4 reads no other part's unknowns (all still zero)
    halo.resize(split->halo.size() * static_cast<std::size_t>(k));
    for (std::size_t slot = 0; slot < split->halo.size(); ++slot)
      for (Eigen::Index c = 0; c < k; ++c)
        halo[slot * static_cast<std::size_t>(k) + static_cast<std::size_t>(c)] = x[split->halo[slot] * k + c];
  }
#pragma omp parallel for schedule(static, 1) num_threads(split->parts)
  for (int t = 0; t < split->parts; ++t)
    row_kernel<K, Mode>(A, value, split->column.data(), halo.data(), inv_diag, b, x, out, k,
                        split->bounds[static_cast<std::size_t>(t)], split->bounds[static_cast<std::size_t>(t) + 1]);
}

template <int Mode, class Value>
void rows_dispatch(const SparseMatrix& A, const Value* value, const SweepSplit* split, const double* inv_diag,
                   const double* b, double* x, double* out, Eigen::Index k, int threads, std::vector<double>& halo) {
  switch (k) {
#define ICE_MG_CASE(K) \
  case K:              \
    return run_rows<K, Mode>(A, value, split, inv_diag, b, x, out, k, threads, halo);
    ICE_MG_CASE(1) ICE_MG_CASE(2) ICE_MG_CASE(3) ICE_MG_CASE(4) ICE_MG_CASE(5) ICE_MG_CASE(6) ICE_MG_CASE(7)
    ICE_MG_CASE(8) ICE_MG_CASE(9) ICE_MG_CASE(10) ICE_MG_CASE(11) ICE_MG_CASE(12) ICE_MG_CASE(13)
    ICE_MG_CASE(14) ICE_MG_CASE(15) ICE_MG_CASE(16)
#undef ICE_MG_CASE
    default:
      return run_rows<0, Mode>(A, value, split, inv_diag, b, x, out, k, threads, halo);
  }
}

// The values a level's smoother and V-cycle residual read: A's, or their float copy (made on
// first use) with options.single_precision_smoother. Either way one symmetric matrix is used for
// smoothing and residuals, so the V-cycle stays a symmetric positive definite operator. Chebyshev
// always uses A's own, and so does the finest level of a stationary V-cycle iteration (`exact`):
// its fixed point must solve A x = b, not the rounded system.
struct SmootherValues {
  const double* wide = nullptr;
  const float* narrow = nullptr;
};
template <class LevelData>
SmootherValues cycle_values(LevelData& L, const MultigridOptions& options, std::size_t k) {
  const bool exact = options.mode == MultigridMode::vcycle && k == 0;
  if (exact || options.smoother == MultigridSmoother::chebyshev || !options.single_precision_smoother)
    return {L.A.valuePtr(), nullptr};
  if (L.values32.empty())  // cleared whenever the operator changes
    L.values32.assign(L.A.valuePtr(), L.A.valuePtr() + L.A.nonZeros());
  return {nullptr, L.values32.data()};
}

// Calls f with the values pointer that is set (float or double).
template <class F>
void with_values(SmootherValues values, F&& f) {
  if (values.narrow != nullptr)
    f(values.narrow);
  else
    f(values.wide);
}

// One Gauss–Seidel sweep on k vectors (x_i += (b_i − (A x)_i) / a_ii), forward or backward; with
// `from_zero` (forward only) the first sweep from x = 0, x's prior contents not read.
void gauss_seidel(const SparseMatrix& A, SmootherValues values, const SweepSplit* split, const Eigen::VectorXd& inv_diag,
                  const double* b, double* x, Eigen::Index k, bool forward, int threads, std::vector<double>& halo,
                  bool from_zero = false) {
  with_values(values, [&](const auto* value) {
    if (from_zero) {  // widths of one vector and of a block solve's chunk compiled apart, others at run time
      if (k == 1)
        run_rows<1, 4>(A, value, split, inv_diag.data(), b, x, nullptr, k, threads, halo);
      else if (k == MultigridSolver::kBlockColumns)
        run_rows<MultigridSolver::kBlockColumns, 4>(A, value, split, inv_diag.data(), b, x, nullptr, k, threads, halo);
      else
        run_rows<0, 4>(A, value, split, inv_diag.data(), b, x, nullptr, k, threads, halo);
    } else if (forward) {
      rows_dispatch<2>(A, value, split, inv_diag.data(), b, x, nullptr, k, threads, halo);
    } else {
      rows_dispatch<3>(A, value, split, inv_diag.data(), b, x, nullptr, k, threads, halo);
    }
  });
}

// r = b − A x for k vectors with the given values (threaded).
void residual_rows(const SparseMatrix& A, SmootherValues values, const double* b, const double* x, double* r,
                   Eigen::Index k, int threads) {
  std::vector<double> unused;
  with_values(values, [&](const auto* value) {
    rows_dispatch<0>(A, value, nullptr, nullptr, b, const_cast<double*>(x), r, k, threads, unused);
  });
}

// The level's split for `threads` (made on first use or when the thread count changed; reset
// whenever the operator changes), or null for a serial sweep. A template so that it can take the
// solver's private Level.
template <class LevelData>
const SweepSplit* level_split(LevelData& L, int threads) {
  const int parts = active_threads(L.A.rows(), threads);
  if (parts <= 1) return nullptr;
  if (L.split.parts != parts) L.split = make_split(L.A, parts);
  return &L.split;
}

// The column a block solve's report() stands for: a column that did not converge if any (the
// largest residual among those), else the one of most iterations.
std::size_t worst_report(const std::vector<MultigridReport>& reports) {
  std::size_t worst = 0;
  const auto worse = [](const MultigridReport& a, const MultigridReport& b) {
    if (a.converged != b.converged) return !a.converged;
    if (!a.converged) return a.relative_residual > b.relative_residual;
    return a.iterations > b.iterations;
  };
  for (std::size_t c = 1; c < reports.size(); ++c)
    if (worse(reports[c], reports[worst])) worst = c;
  return worst;
}

// Block kernels: X, B, R are n × k row-major.
void residual_block(const SparseMatrix& A, const Block& B, const Block& X, Block& R, int threads) {
  residual_rows(A, {A.valuePtr(), nullptr}, B.data(), X.data(), R.data(), X.cols(), threads);
}
void multiply_block(const SparseMatrix& A, const Block& X, Block& Y, int threads) {
  std::vector<double> unused;
  rows_dispatch<1>(A, A.valuePtr(), nullptr, nullptr, nullptr, const_cast<double*>(X.data()), Y.data(), X.cols(), threads,
                   unused);
}

// C = Pᵀ R (restriction, a gather per column of the column-major P) and X += P C (prolongation, a
// gather per row of the row-major copy), both split among threads.
void restrict_block(const SparseMatrix& P, const Block& R, Block& C, int threads) {
  const Eigen::Index k = R.cols(), m = P.outerSize();
  C.resize(P.cols(), k);
  if (k == 1) return gather_product(P, R.data(), C.data(), false, threads, P.rows());
#pragma omp parallel for schedule(static) num_threads(active_threads(P.rows(), threads))
  for (Eigen::Index j = 0; j < m; ++j) {
    double* c = C.data() + j * k;
    for (Eigen::Index q = 0; q < k; ++q) c[q] = 0;
    for (auto p = P.outerIndexPtr()[j]; p < P.outerIndexPtr()[j + 1]; ++p) {
      const double w = P.valuePtr()[p];
      const double* r = R.data() + static_cast<Eigen::Index>(P.innerIndexPtr()[p]) * k;
      for (Eigen::Index q = 0; q < k; ++q) c[q] += w * r[q];
    }
  }
}
void prolong_add_block(const RowMajorSparse& P_rows, const Block& C, Block& X, int threads) {
  const Eigen::Index k = X.cols(), n = P_rows.outerSize();
  if (k == 1) return gather_product(P_rows, C.data(), X.data(), true, threads, n);
#pragma omp parallel for schedule(static) num_threads(active_threads(n, threads))
  for (Eigen::Index i = 0; i < n; ++i) {
    double* x = X.data() + i * k;
    for (auto p = P_rows.outerIndexPtr()[i]; p < P_rows.outerIndexPtr()[i + 1]; ++p) {
      const double w = P_rows.valuePtr()[p];
      const double* c = C.data() + static_cast<Eigen::Index>(P_rows.innerIndexPtr()[p]) * k;
      for (Eigen::Index q = 0; q < k; ++q) x[q] += w * c[q];
    }
  }
}
// Column-wise dot products of two row-major blocks (per-thread partial sums added in thread order:
// deterministic for a given thread count).
Eigen::VectorXd column_dots(const Block& X, const Block& Y, int threads) {
  const Eigen::Index k = X.cols(), n = X.rows();
  const int parts = active_threads(n, threads);
  Eigen::MatrixXd partial = Eigen::MatrixXd::Zero(k, parts);
  const double* x = X.data();
  const double* y = Y.data();
#pragma omp parallel for schedule(static, 1) num_threads(parts)
  for (int t = 0; t < parts; ++t) {
    double* d = partial.data() + t * k;
    for (Eigen::Index i = n * t / parts * k, end = n * (t + 1) / parts * k; i < end; i += k)
      for (Eigen::Index q = 0; q < k; ++q) d[q] += x[i + q] * y[i + q];
  }
  return partial.rowwise().sum();
}
// Y.col(q) += a(q) X.col(q), row by row.
void axpy_columns(const Eigen::VectorXd& a, const Block& X, Block& Y, int threads) {
  const Eigen::Index k = X.cols(), n = X.rows();
  const double* x = X.data();
  double* y = Y.data();
#pragma omp parallel for schedule(static) num_threads(active_threads(n, threads))
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index q = 0; q < k; ++q) y[i * k + q] += a[q] * x[i * k + q];
}

// Rows of P kept and renumbered through `row_map` (old row -> new row or −1), columns that keep no
// entry dropped. The surviving columns are numbered in order of their first new row when
// `order_by_rows` (so a locality ordering of the rows carries over to the columns: a coarse unknown
// lands next to the fine unknowns it prolongs to), else in their old order. `column_map` receives
// old column -> new column or −1. Inner indices sorted.
SparseMatrix restrict_prolongation(const SparseMatrix& P, const std::vector<Index>& row_map, Eigen::Index new_rows,
                                   bool order_by_rows, std::vector<Index>& column_map, int threads) {
  column_map.assign(static_cast<std::size_t>(P.cols()), -1);
  std::vector<std::pair<int, int>> survivors;  // (first new row, old column)
  for (Eigen::Index j = 0; j < P.outerSize(); ++j) {
    int first = -1;
    for (SparseMatrix::InnerIterator it(P, j); it; ++it) {
      const int r = row_map[static_cast<std::size_t>(it.row())];
      if (r >= 0 && it.value() != 0.0 && (first < 0 || r < first)) first = r;
    }
    if (first >= 0) survivors.emplace_back(order_by_rows ? first : 0, static_cast<int>(j));
  }
  if (order_by_rows) std::sort(survivors.begin(), survivors.end());
  for (std::size_t c = 0; c < survivors.size(); ++c) column_map[static_cast<std::size_t>(survivors[c].second)] = static_cast<int>(c);
  return assemble_columns(new_rows, static_cast<Eigen::Index>(survivors.size()), P.nonZeros(),
                          [&](Eigen::Index c, std::vector<std::pair<int, double>>& column) {
                            for (SparseMatrix::InnerIterator it(P, survivors[static_cast<std::size_t>(c)].second); it; ++it) {
                              const int r = row_map[static_cast<std::size_t>(it.row())];
                              if (r >= 0 && it.value() != 0.0) column.emplace_back(r, it.value());
                            }
                          }, active_threads(P.cols(), threads));
}

// The free–free block of A in the order `free` (free[i] = original index of free unknown i;
// free_index its inverse, −1 at constrained indices) and the free–constrained block (free rows,
// constrained columns). Inner indices sorted.
void split_matrix(const SparseMatrix& A, const std::vector<Index>& free, const std::vector<Index>& free_index,
                  const std::vector<Index>& constrained, SparseMatrix& A_ff, SparseMatrix& A_fc, int threads) {
  const Eigen::Index free_count = static_cast<Eigen::Index>(free.size());
  A_ff = assemble_columns(free_count, free_count, A.nonZeros(), [&](Eigen::Index c, std::vector<std::pair<int, double>>& column) {
    for (SparseMatrix::InnerIterator it(A, free[static_cast<std::size_t>(c)]); it; ++it) {
      const int fi = free_index[static_cast<std::size_t>(it.row())];
      if (fi >= 0) column.emplace_back(fi, it.value());
    }
  }, active_threads(free_count, threads));
  A_fc = assemble_columns(free_count, static_cast<Eigen::Index>(constrained.size()), 0,
                          [&](Eigen::Index c, std::vector<std::pair<int, double>>& column) {
                            for (SparseMatrix::InnerIterator it(A, constrained[static_cast<std::size_t>(c)]); it; ++it) {
                              const int fi = free_index[static_cast<std::size_t>(it.row())];
                              if (fi >= 0) column.emplace_back(fi, it.value());
                            }
                          });
}

}  // namespace

const char* to_string(MultigridMode mode) { return mode == MultigridMode::pcg ? "pcg" : "vcycle"; }
const char* to_string(MultigridSmoother smoother) {
  switch (smoother) {
    case MultigridSmoother::gauss_seidel: return "gauss_seidel";
    case MultigridSmoother::symmetric_gauss_seidel: return "symmetric_gauss_seidel";
    case MultigridSmoother::chebyshev: return "chebyshev";
  }
  return "?";
}

struct MultigridSolver::Level {
  SparseMatrix A;  ///< operator (compressed, both triangles)
  SparseMatrix P;  ///< restricted prolongation to the next level (not on the coarsest)
  RowMajorSparse P_rows;  ///< the same, row-major (prolongation gathers per row, in parallel)
  Eigen::VectorXd inv_diag;
  double lambda_max = 0;  ///< Chebyshev: largest eigenvalue estimate of D⁻¹A
  Block X, B, R, D;            ///< work blocks (n × k row-major; k = 1 for solve())
  SweepSplit split;            ///< threaded Gauss–Seidel ranges (parts = 1: serial)
  std::vector<float> values32; ///< A's values rounded to float (single_precision_smoother)
  std::vector<double> halo;    ///< the split's snapshot of cross-range values
};

MultigridSolver::MultigridSolver(std::vector<SparseMatrix> prolongations, MultigridOptions options)
    : options_(options), prolongations_(std::move(prolongations)) {
  check_options(options_);
  for (std::size_t k = 0; k + 1 < prolongations_.size(); ++k)
    if (prolongations_[k].cols() != prolongations_[k + 1].rows())
      throw std::invalid_argument("MultigridSolver: P_" + std::to_string(k) + " has " +
                                  std::to_string(prolongations_[k].cols()) + " columns but P_" + std::to_string(k + 1) +
                                  " has " + std::to_string(prolongations_[k + 1].rows()) + " rows");
  for (SparseMatrix& P : prolongations_) P.makeCompressed();
}

MultigridSolver::~MultigridSolver() = default;
MultigridSolver::MultigridSolver(MultigridSolver&&) noexcept = default;
MultigridSolver& MultigridSolver::operator=(MultigridSolver&&) noexcept = default;

int MultigridSolver::threads() const { return options_.threads > 0 ? options_.threads : default_threads(); }

void MultigridSolver::check_options(const MultigridOptions& o) const {
  if (o.smoothing_steps < 1) throw std::invalid_argument("MultigridSolver: smoothing_steps must be >= 1");
  if (o.threads < 0) throw std::invalid_argument("MultigridSolver: threads must be >= 0");
  if (o.chebyshev_degree < 1) throw std::invalid_argument("MultigridSolver: chebyshev_degree must be >= 1");
  if (!(o.chebyshev_ratio > 1)) throw std::invalid_argument("MultigridSolver: chebyshev_ratio must be > 1");
  if (!(o.tolerance > 0)) throw std::invalid_argument("MultigridSolver: tolerance must be > 0");
  if (o.max_iterations < 1) throw std::invalid_argument("MultigridSolver: max_iterations must be >= 1");
  if (!(o.error_tolerance >= 0)) throw std::invalid_argument("MultigridSolver: error_tolerance must be >= 0");
  if (o.error_min_iterations < 1) throw std::invalid_argument("MultigridSolver: error_min_iterations must be >= 1");
}

void MultigridSolver::set_error_norm(Eigen::VectorXd weights, bool remove_weighted_mean) {
  if (weights.size() != 0 && (!is_setup_ || weights.size() != size_))
    throw std::invalid_argument("MultigridSolver::set_error_norm: call setup() first; one weight per unknown");
  if (weights.size() != 0 && !(weights.minCoeff() >= 0))
    throw std::invalid_argument("MultigridSolver::set_error_norm: weights must be >= 0");
  error_weights_ = std::move(weights);
  error_remove_mean_ = remove_weighted_mean;
}

double MultigridSolver::estimate_error(const Eigen::VectorXd& x, const Eigen::VectorXd& z, const Eigen::VectorXd& w_free,
                                       const Eigen::VectorXd& constrained_values) const {
  // Constrained unknowns: x is the prescribed value, the error estimate 0.
  const auto x_constrained = [&](std::size_t c) {
    return constrained_values.size() ? constrained_values(static_cast<Eigen::Index>(c)) : 0.0;
  };
  const Eigen::Index nf = w_free.size();
  double mean_x = 0, mean_z = 0;
  if (error_remove_mean_) {
    double total = w_free.sum();
    mean_x = w_free.dot(x);
    mean_z = w_free.dot(z);
    for (std::size_t c = 0; c < constrained_.size(); ++c) {
      total += error_weights_(constrained_[c]);
      mean_x += error_weights_(constrained_[c]) * x_constrained(c);
    }
    if (total > 0) {
      mean_x /= total;
      mean_z /= total;
    }
  }
  double error2 = 0, solution2 = 0;
  for (Eigen::Index i = 0; i < nf; ++i) {
    const double dz = z(i) - mean_z, dx = x(i) + dz - mean_x;
    error2 += w_free(i) * dz * dz;
    solution2 += w_free(i) * dx * dx;
  }
  for (std::size_t c = 0; c < constrained_.size(); ++c) {
    const double dz = -mean_z, dx = x_constrained(c) + dz - mean_x;
    error2 += error_weights_(constrained_[c]) * dz * dz;
    solution2 += error_weights_(constrained_[c]) * dx * dx;
  }
  if (solution2 > 0) return std::sqrt(error2 / solution2);
  return error2 > 0 ? std::numeric_limits<double>::infinity() : 0.0;
}

void MultigridSolver::set_options(const MultigridOptions& options) {
  check_options(options);
  const bool smoother_changed = options.smoother != options_.smoother;
  options_ = options;
  if (smoother_changed && is_setup_) {
    // λ estimates are only computed for Chebyshev; recompute the smoother data.
    for (std::size_t k = 0; k + 1 < levels_.size(); ++k) levels_[k]->lambda_max = 0;
  }
}

int MultigridSolver::num_levels() const { return static_cast<int>(levels_.size()); }

std::vector<MultigridLevelInfo> MultigridSolver::level_info() const {
  std::vector<MultigridLevelInfo> info;
  for (const auto& level : levels_) info.push_back({level->A.rows(), level->A.nonZeros()});
  return info;
}

double MultigridSolver::operator_complexity() const {
  if (levels_.empty() || levels_[0]->A.nonZeros() == 0) return 0;
  double total = 0;
  for (const auto& level : levels_) total += static_cast<double>(level->A.nonZeros());
  return total / static_cast<double>(levels_[0]->A.nonZeros());
}

const SparseMatrix& MultigridSolver::level_operator(int k) const {
  if (k < 0 || k >= num_levels()) throw std::out_of_range("MultigridSolver::level_operator: no such level");
  return levels_[static_cast<std::size_t>(k)]->A;
}

void MultigridSolver::setup(const SparseMatrix& A, std::vector<Index> constrained) {
  const auto start = Clock::now();
  if (A.rows() != A.cols()) throw std::invalid_argument("MultigridSolver::setup: A must be square");
  const Eigen::Index n = A.rows();
  if (!prolongations_.empty() && prolongations_[0].rows() != n)
    throw std::invalid_argument("MultigridSolver::setup: A has " + std::to_string(n) + " rows but P_0 has " +
                                std::to_string(prolongations_[0].rows()));
  // Kept in the caller's order: constrained value c belongs to constrained[c]. Checked before any
  // member changes, so a refused call leaves an earlier setup intact.
  std::vector<Index> free_index(static_cast<std::size_t>(n), 0);
  for (int c : constrained) {
    if (c < 0 || c >= n)
      throw std::invalid_argument("MultigridSolver::setup: constrained index " + std::to_string(c) + " out of range");
    if (free_index[static_cast<std::size_t>(c)] != 0)
      throw std::invalid_argument("MultigridSolver::setup: constrained index " + std::to_string(c) + " given twice");
    free_index[static_cast<std::size_t>(c)] = -1;
  }
  free_index_ = std::move(free_index);
  size_ = n;
  constrained_ = std::move(constrained);
  // The free unknowns in increasing order, or with options.reorder for locality: reverse
  // Cuthill–McKee on A's graph, constrained unknowns left out (they only cut the graph; the order
  // stays local). The coarse levels inherit it through restrict_prolongation's column order.
  reordered_ = options_.reorder;
  std::vector<Index> candidates(static_cast<std::size_t>(n));
  if (reordered_ && !locality_order_.empty()) {
    if (static_cast<Eigen::Index>(locality_order_.size()) != n)
      throw std::invalid_argument("MultigridSolver::setup: the locality order has " + std::to_string(locality_order_.size()) +
                                  " entries for " + std::to_string(n) + " unknowns");
    std::vector<char> seen(static_cast<std::size_t>(n), 0);
    for (Index v : locality_order_) {
      if (v < 0 || v >= n || seen[static_cast<std::size_t>(v)])
        throw std::invalid_argument("MultigridSolver::setup: the locality order is not a permutation");
      seen[static_cast<std::size_t>(v)] = 1;
    }
    candidates = locality_order_;
  } else if (reordered_) {
    candidates = reverse_cuthill_mckee(A);
  } else {
    std::iota(candidates.begin(), candidates.end(), 0);
  }
  free_.clear();
  for (int v : candidates)
    if (free_index_[static_cast<std::size_t>(v)] >= 0) {
      free_index_[static_cast<std::size_t>(v)] = static_cast<int>(free_.size());
      free_.push_back(v);
    }

  // Restricted prolongations: free rows on level 0, then the surviving columns level by level.
  levels_.clear();
  std::vector<Index> row_map = free_index_;
  Eigen::Index rows = static_cast<Eigen::Index>(free_.size());
  for (const SparseMatrix& P : prolongations_) {
    auto level = std::make_unique<Level>();
    if (rows == 0) break;
    std::vector<Index> column_map;
    level->P = restrict_prolongation(P, row_map, rows, options_.reorder, column_map, threads());
    level->P_rows = level->P;
    if (level->P.cols() == 0) break;
    rows = level->P.cols();
    row_map = std::move(column_map);
    levels_.push_back(std::move(level));
  }
  levels_.push_back(std::make_unique<Level>());  // the coarsest (no P)
  is_setup_ = false;
  build_operators(A, /*reuse_analysis=*/false);
  is_setup_ = true;
  setup_seconds_ = ice::seconds_since(start);
}

void MultigridSolver::update_matrix(const SparseMatrix& A) {
  if (!is_setup_) throw std::logic_error("MultigridSolver::update_matrix: call setup() first");
  if (A.rows() != size_ || A.cols() != size_)
    throw std::invalid_argument("MultigridSolver::update_matrix: A has the wrong size");
  const auto start = Clock::now();
  build_operators(A, /*reuse_analysis=*/true);
  setup_seconds_ = ice::seconds_since(start);
}

void MultigridSolver::build_operators(const SparseMatrix& A, bool reuse_analysis) {
  Level& fine = *levels_[0];
  split_matrix(A, free_, free_index_, constrained_, fine.A, free_constrained_, threads());
  for (std::size_t k = 0; k < levels_.size(); ++k) {
    Level& level = *levels_[k];
    if (k > 0) {
      level.A = galerkin(levels_[k - 1]->P, levels_[k - 1]->A, threads());
    }
    level.A.makeCompressed();
    const Eigen::Index n = level.A.rows();
    level.inv_diag = level.A.diagonal();
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!(level.inv_diag(i) > 0))
        throw NotPositiveDefinite(i, "MultigridSolver: level " + std::to_string(k) + " has a non-positive diagonal entry at " +
                                         std::to_string(i));
      level.inv_diag(i) = 1.0 / level.inv_diag(i);
    }
    level.lambda_max = 0;
    level.split = SweepSplit();  // remade for the new operator on first use
    level.values32.clear();
  }
  const SparseMatrix& coarsest = levels_.back()->A;
  if (coarsest.rows() == 0) return;  // everything constrained
  if (reuse_analysis) {
    try {
      coarsest_.factorize(coarsest);
    } catch (const std::invalid_argument&) {  // the Galerkin pattern changed (should not happen)
      coarsest_.compute(coarsest);
    }
  } else {
    coarsest_.compute(coarsest);
  }
}

void MultigridSolver::chebyshev(std::size_t k) {
  Level& L = *levels_[k];
  const Eigen::Index n = L.A.rows(), columns = L.X.cols();
  if (L.lambda_max == 0) {
    // An upper bound of the spectrum of D⁻¹A, guaranteed (Gershgorin: max_i Σ_j |a_ij| / a_ii; at
    // most 2 for a Laplacian-like matrix). A power-iteration estimate is cheaper to use but lies
    // below λ_max; the polynomial then amplifies the top of the spectrum, the V-cycle stops being
    // positive definite and CG breaks down (observed at 1.6M unknowns with 15 iterations).
    const auto* start = L.A.outerIndexPtr();
    const double* value = L.A.valuePtr();
    double bound = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      double row_sum = 0;
      for (auto p = start[i]; p < start[i + 1]; ++p) row_sum += std::abs(value[p]);
      bound = std::max(bound, row_sum * L.inv_diag[i]);
    }
    L.lambda_max = bound;
  }
  const double upper = L.lambda_max, lower = L.lambda_max / options_.chebyshev_ratio;
  const double theta = 0.5 * (upper + lower), delta = 0.5 * (upper - lower);
  const double sigma = theta / delta;
  double rho = 1.0 / sigma;
  // Each step: d = keep·d + gain·D⁻¹(b − A x), then x += d, column by column; the residual and the
  // direction are one pass over A, the update a second, vector-only pass (x must not change while
  // A x is formed).
  L.D.resize(n, columns);
  const auto* start = L.A.outerIndexPtr();
  const auto* row = L.A.innerIndexPtr();
  const double* value = L.A.valuePtr();
  const double* b = L.B.data();
  const double* inv_diag = L.inv_diag.data();
  double* x = L.X.data();
  double* d = L.D.data();
  const int parts = active_threads(n, threads());
  const auto step_direction = [&](double keep, double gain) {
#pragma omp parallel for schedule(static) num_threads(parts)
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index q = 0; q < columns; ++q) {
        double r = b[i * columns + q];
        for (auto p = start[i]; p < start[i + 1]; ++p) r -= value[p] * x[row[p] * columns + q];
        double& direction = d[i * columns + q];
        direction = (keep == 0 ? 0.0 : keep * direction) + gain * r * inv_diag[i];
      }
    }
#pragma omp parallel for schedule(static) num_threads(parts)
    for (Eigen::Index i = 0; i < n * columns; ++i) x[i] += d[i];
  };
  step_direction(0.0, 1.0 / theta);
  for (int step = 1; step < options_.chebyshev_degree; ++step) {
    const double rho_next = 1.0 / (2 * sigma - rho);
    step_direction(rho_next * rho, 2 * rho_next / delta);
    rho = rho_next;
  }
}

namespace {

// `options.smoothing_steps` applications of the chosen smoother: Gauss–Seidel forward before the
// coarse correction and backward after (so the V-cycle stays symmetric), symmetric Gauss–Seidel both
// ways each time, or one Chebyshev pass. Shared by the single- and the block-vector cycles.
template <class Sweep, class Chebyshev>
void smoothing_steps(const MultigridOptions& options, bool pre, Sweep&& sweep, Chebyshev&& chebyshev) {
  for (int s = 0; s < options.smoothing_steps; ++s) {
    switch (options.smoother) {
      case MultigridSmoother::gauss_seidel:
        sweep(pre);
        break;
      case MultigridSmoother::symmetric_gauss_seidel:
        sweep(true);
        sweep(false);
        break;
      case MultigridSmoother::chebyshev:
        chebyshev();
        break;
    }
  }
}

}  // namespace

// `options.smoothing_steps` of the smoother on levels_[k]: X improved for B, every column at once.
// `from_zero`: X is to start at 0 and its contents are not read (the first sweep is a forward one).
void MultigridSolver::smooth(std::size_t k, bool pre, bool from_zero) {
  Level& L = *levels_[k];
  const SweepSplit* split = options_.smoother == MultigridSmoother::chebyshev || !reordered_ ? nullptr : level_split(L, threads());
  const SmootherValues values = cycle_values(L, options_, k);
  const auto sweep = [&](bool forward) {
    gauss_seidel(L.A, values, split, L.inv_diag, L.B.data(), L.X.data(), L.X.cols(), forward, threads(), L.halo, from_zero);
    from_zero = false;
  };
  smoothing_steps(options_, pre, sweep, [&] { chebyshev(k); });
}

// Improves levels_[k]->X for the right-hand sides levels_[k]->B (n × k row-major; one column for
// solve(), several for solve_multiple(): the same arithmetic per column either way). `from_zero`:
// from X = 0, X's contents not read (sized here); the first Gauss–Seidel sweep then skips the
// zeros instead of a pass that writes them (the same numbers).
void MultigridSolver::vcycle(std::size_t k, bool from_zero) {
  Level& L = *levels_[k];
  if (k + 1 == levels_.size()) {
    const Eigen::MatrixXd rhs = L.B;  // column-major for CHOLMOD
    L.X = coarsest_.solve_multiple(rhs);
    return;
  }
  if (from_zero) {
    L.X.resize(L.B.rows(), L.B.cols());
    if (options_.smoother == MultigridSmoother::chebyshev) {  // the Gauss–Seidel smoothers start forward
      L.X.setZero();
      from_zero = false;
    }
  }
  smooth(k, true, from_zero);
  L.R.resize(L.X.rows(), L.X.cols());
  residual_rows(L.A, cycle_values(L, options_, k), L.B.data(), L.X.data(), L.R.data(), L.X.cols(), threads());
  Level& C = *levels_[k + 1];
  restrict_block(L.P, L.R, C.B, threads());  // C.B = Pᵀ R
  vcycle(k + 1, true);
  prolong_add_block(L.P_rows, C.X, L.X, threads());  // X += P C.X
  smooth(k, false);
}

Eigen::VectorXd MultigridSolver::apply_vcycle(const Eigen::VectorXd& r) {
  if (!is_setup_) throw std::logic_error("MultigridSolver: call setup() first");
  Level& L = *levels_[0];
  if (r.size() != L.A.rows()) throw std::invalid_argument("MultigridSolver::apply_vcycle: wrong size");
  L.B = r;
  vcycle(0, true);
  return L.X.col(0);
}

Eigen::VectorXd MultigridSolver::solve(const Eigen::VectorXd& b, const Eigen::VectorXd& constrained_values) {
  return solve(b, constrained_values, Eigen::VectorXd());
}

Eigen::VectorXd MultigridSolver::solve(const Eigen::VectorXd& b, const Eigen::VectorXd& constrained_values,
                                       const Eigen::VectorXd& initial_guess) {
  if (!is_setup_) throw std::logic_error("MultigridSolver::solve: call setup() first");
  const auto start = Clock::now();
  if (b.size() != size_) throw std::invalid_argument("MultigridSolver::solve: b has the wrong size");
  if (constrained_values.size() != 0 && constrained_values.size() != static_cast<Eigen::Index>(constrained_.size()))
    throw std::invalid_argument("MultigridSolver::solve: need one value per constrained index");
  if (initial_guess.size() != 0 && initial_guess.size() != size_)
    throw std::invalid_argument("MultigridSolver::solve: initial guess has the wrong size");
  const Eigen::Index nf = static_cast<Eigen::Index>(free_.size());
  Eigen::VectorXd rhs(nf), x(nf);
  for (Eigen::Index i = 0; i < nf; ++i) rhs(i) = b(free_[static_cast<std::size_t>(i)]);
  if (constrained_values.size() != 0 && nf > 0) rhs.noalias() -= free_constrained_ * constrained_values;
  if (initial_guess.size() != 0)
    for (Eigen::Index i = 0; i < nf; ++i) x(i) = initial_guess(free_[static_cast<std::size_t>(i)]);
  else
    x.setZero();

  report_ = MultigridReport();
  Level& L = *levels_[0];
  const SparseMatrix& A = L.A;
  const int t = threads();
  const auto norm = [&](const Eigen::VectorXd& v) { return std::sqrt(dot(v, v, t)); };
  const double norm_b = norm(rhs);
  Eigen::VectorXd r(nf);
  residual_rows(A, {A.valuePtr(), nullptr}, rhs.data(), x.data(), r.data(), 1, t);
  const double scale = norm_b > 0 ? norm_b : 1.0;
  double res = norm(r) / scale;
  report_.residuals.push_back(res);
  // Error estimates (set_error_norm): z = B r is PCG's preconditioned residual; in vcycle mode an
  // extra V-cycle. `done` is either stopping criterion.
  // In PCG mode the raw estimate ‖Br‖/‖x + Br‖ is divided by the smallest eigenvalue μ of BA seen
  // so far (the smallest Ritz value of CG's Lanczos tridiagonal, from its α and β): an error
  // component along an eigenvector of BA with eigenvalue μ shows up in Br shrunk by μ, and μ_min is
  // where the V-cycle is weakest (1 − its convergence factor). Ritz values approach μ_min from
  // above, so the factor grows towards its true value as iterations proceed; the reported history is
  // rescaled with the final factor.
  const bool estimating = error_weights_.size() != 0 && nf > 0;
  Eigen::VectorXd z, w_free;  // the weights in the solver's order of the free unknowns, gathered once
  if (estimating) {
    w_free.resize(nf);
    for (Eigen::Index i = 0; i < nf; ++i) w_free(i) = error_weights_(free_[static_cast<std::size_t>(i)]);
  }
  std::vector<double> raw_estimates, alphas, betas;
  double estimate_factor = 1;
  const auto update_factor = [&] {
    const std::size_t j = alphas.size();
    if (j == 0 || j > 200) return;  // beyond 200 iterations keep the last (the eigensolve is O(j²))
    Eigen::VectorXd diagonal(static_cast<Eigen::Index>(j)), off(static_cast<Eigen::Index>(j > 0 ? j - 1 : 0));
    for (std::size_t i = 0; i < j; ++i) {
      diagonal(static_cast<Eigen::Index>(i)) = 1 / alphas[i] + (i > 0 ? betas[i - 1] / alphas[i - 1] : 0.0);
      if (i + 1 < j) off(static_cast<Eigen::Index>(i)) = std::sqrt(betas[i]) / alphas[i];
    }
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> lanczos;
    lanczos.computeFromTridiagonal(diagonal, off, Eigen::EigenvaluesOnly);
    const double smallest = lanczos.eigenvalues().minCoeff();
    if (smallest > 0) estimate_factor = std::max(estimate_factor, 1 / std::min(smallest, 1.0));
  };
  const auto record_estimate = [&] {
    if (!estimating) return;
    if (options_.mode == MultigridMode::vcycle) z = apply_vcycle(r);
    raw_estimates.push_back(estimate_error(x, z, w_free, constrained_values));
    report_.error_estimates.push_back(raw_estimates.back() * estimate_factor);
  };
  // The error criterion needs a settled Lanczos factor in PCG mode (MultigridOptions::error_min_iterations).
  const auto done = [&] {
    const bool error_known =
        options_.mode == MultigridMode::vcycle || report_.iterations >= std::max(1, options_.error_min_iterations);
    return res <= options_.tolerance || (estimating && error_known && options_.error_tolerance > 0 &&
                                         report_.error_estimates.back() <= options_.error_tolerance);
  };
  if (options_.mode == MultigridMode::pcg && nf > 0) z = apply_vcycle(r);
  record_estimate();
  if (nf > 0 && !done()) {
    if (options_.mode == MultigridMode::vcycle) {
      L.B = rhs;
      L.X = x;
      while (report_.iterations < options_.max_iterations) {
        vcycle(0);
        residual_rows(A, {A.valuePtr(), nullptr}, rhs.data(), L.X.data(), r.data(), 1, t);
        res = norm(r) / scale;
        ++report_.iterations;
        report_.residuals.push_back(res);
        if (estimating) {  // the estimate's V-cycle uses the level's work blocks: restore them after it
          x = L.X.col(0);
          record_estimate();
          L.B = rhs;
          L.X = x;
        }
        if (done()) break;
      }
      x = L.X.col(0);
    } else {
      Eigen::VectorXd p = z, Ap(nf);
      double rz = dot(r, z, t);
      while (report_.iterations < options_.max_iterations) {
        multiply(A, p.data(), Ap.data(), t);
        const double pAp = dot(p, Ap, t);
        if (!(pAp > 0) || !(rz > 0)) break;  // breakdown (converged to round-off or not SPD)
        const double alpha = rz / pAp;
        axpy(alpha, p, x, t);
        axpy(-alpha, Ap, r, t);
        res = norm(r) / scale;
        ++report_.iterations;
        report_.residuals.push_back(res);
        if (estimating) {
          alphas.push_back(alpha);
          update_factor();
          z = apply_vcycle(r);
          record_estimate();
        }
        if (done()) break;
        if (!estimating) z = apply_vcycle(r);
        const double rz_next = dot(r, z, t);
        if (estimating) betas.push_back(rz_next / rz);
        xpby(z, rz_next / rz, p, t);
        rz = rz_next;
      }
    }
  }
  for (std::size_t k = 0; k < raw_estimates.size(); ++k) report_.error_estimates[k] = raw_estimates[k] * estimate_factor;
  residual_rows(A, {A.valuePtr(), nullptr}, rhs.data(), x.data(), r.data(), 1, t);
  report_.relative_residual = nf > 0 ? norm(r) / scale : 0.0;
  report_.converged = report_.relative_residual <= options_.tolerance ||
                      (nf > 0 && report_.residuals.back() <= options_.tolerance &&
                       report_.relative_residual <= 10 * options_.tolerance) ||
                      (estimating && options_.error_tolerance > 0 &&
                       report_.error_estimates.back() <= options_.error_tolerance);
  if (report_.iterations > 0 && report_.residuals.front() > 0 && report_.residuals.back() > 0)
    report_.convergence_factor =
        std::pow(report_.residuals.back() / report_.residuals.front(), 1.0 / report_.iterations);

  Eigen::VectorXd out(size_);
  for (Eigen::Index i = 0; i < nf; ++i) out(free_[static_cast<std::size_t>(i)]) = x(i);
  for (std::size_t c = 0; c < constrained_.size(); ++c)
    out(constrained_[c]) = constrained_values.size() ? constrained_values(static_cast<Eigen::Index>(c)) : 0.0;
  report_.seconds = ice::seconds_since(start);
  return out;
}

void MultigridSolver::apply_vcycle_block(const Eigen::Ref<const Block>& R, Block& Z) {
  Level& L = *levels_[0];
  L.B = R;
  vcycle(0, true);
  Z.swap(L.X);
}

// One V-cycle from zero per listed column of R, kBlockColumns at a time: each chunk's free rows
// gathered into the finest level's B, the cycle, then sink(row, column, value) for every free row
// (in the caller's numbering) and listed column with the cycle's value there. `who` names the caller
// in the errors.
template <class Sink>
void MultigridSolver::vcycle_chunks(const char* who, const Eigen::MatrixXd& R, const std::vector<Eigen::Index>& columns,
                                    Sink&& sink) {
  if (!is_setup_) throw std::logic_error(std::string("MultigridSolver::") + who + ": call setup() first");
  if (R.rows() != size_) throw std::invalid_argument(std::string("MultigridSolver::") + who + ": R has the wrong number of rows");
  for (Eigen::Index c : columns)
    if (c < 0 || c >= R.cols()) throw std::invalid_argument(std::string("MultigridSolver::") + who + ": a column is out of range");
  const Eigen::Index k = static_cast<Eigen::Index>(columns.size()), nf = static_cast<Eigen::Index>(free_.size());
  if (nf == 0) return;
  Level& L = *levels_[0];
  const int t = threads();
  for (Eigen::Index first = 0; first < k; first += kBlockColumns) {
    const Eigen::Index width = std::min<Eigen::Index>(kBlockColumns, k - first);
    const Eigen::Index* chunk = columns.data() + first;
    L.B.resize(nf, width);
#pragma omp parallel for schedule(static) num_threads(active_threads(nf, t))
    for (Eigen::Index i = 0; i < nf; ++i)
      for (Eigen::Index c = 0; c < width; ++c) L.B(i, c) = R(free_[static_cast<std::size_t>(i)], chunk[c]);
    vcycle(0, true);
#pragma omp parallel for schedule(static) num_threads(active_threads(nf, t))
    for (Eigen::Index i = 0; i < nf; ++i)
      for (Eigen::Index c = 0; c < width; ++c) sink(free_[static_cast<std::size_t>(i)], chunk[c], L.X(i, c));
  }
}

Eigen::MatrixXd MultigridSolver::apply_vcycle_multiple(const Eigen::MatrixXd& R) {
  std::vector<Eigen::Index> all(static_cast<std::size_t>(R.cols()));
  std::iota(all.begin(), all.end(), Eigen::Index{0});
  Eigen::MatrixXd Z = Eigen::MatrixXd::Zero(R.rows(), R.cols());
  vcycle_chunks("apply_vcycle_multiple", R, all,
                [&Z](Eigen::Index row, Eigen::Index column, double value) { Z(row, column) = value; });
  return Z;
}

void MultigridSolver::subtract_vcycle_columns(const Eigen::MatrixXd& R, const std::vector<Eigen::Index>& columns,
                                              Eigen::MatrixXd& X) {
  if (X.rows() != R.rows() || X.cols() != R.cols())
    throw std::invalid_argument("MultigridSolver::subtract_vcycle_columns: X and R differ in shape");
  vcycle_chunks("subtract_vcycle_columns", R, columns,
                [&X](Eigen::Index row, Eigen::Index column, double value) { X(row, column) -= value; });
}

Eigen::MatrixXd MultigridSolver::solve_multiple(const Eigen::MatrixXd& Bfull, const Eigen::MatrixXd& constrained_values) {
  if (!is_setup_) throw std::logic_error("MultigridSolver::solve_multiple: call setup() first");
  const Eigen::Index k = Bfull.cols();
  if (Bfull.rows() != size_) throw std::invalid_argument("MultigridSolver::solve_multiple: B has the wrong number of rows");
  if (constrained_values.size() != 0 &&
      (constrained_values.rows() != static_cast<Eigen::Index>(constrained_.size()) || constrained_values.cols() != k))
    throw std::invalid_argument("MultigridSolver::solve_multiple: constrained values must be |C| x k");
  const auto start = Clock::now();
  if (error_weights_.size() != 0) {
    // The error estimate and its stopping rule belong to solve(): with an error norm, column by column.
    Eigen::MatrixXd out(size_, k);
    std::vector<MultigridReport> all;
    for (Eigen::Index j = 0; j < k; ++j) {
      out.col(j) = solve(Bfull.col(j), constrained_values.size() != 0 ? Eigen::VectorXd(constrained_values.col(j))
                                                                      : Eigen::VectorXd());
      all.push_back(report_);
    }
    reports_ = std::move(all);
    if (k > 0) report_ = reports_[worst_report(reports_)];
    return out;
  }
  if (k <= kBlockColumns) return solve_block_columns(Bfull, constrained_values);
  // Wider blocks in chunks: a sweep's memory traffic is the matrix's (once per chunk) plus every
  // column's vectors, so past a few columns the vectors dominate and wider chunks only cost memory
  // and cache (docs/measurements.md, "Block V-cycles": 4, 8, 16 and 100 columns at 1.66M).
  Eigen::MatrixXd out(size_, k);
  std::vector<MultigridReport> all;
  all.reserve(static_cast<std::size_t>(k));
  for (Eigen::Index first = 0; first < k; first += kBlockColumns) {
    const Eigen::Index width = std::min<Eigen::Index>(kBlockColumns, k - first);
    out.middleCols(first, width) = solve_block_columns(
        Bfull.middleCols(first, width),
        constrained_values.size() != 0 ? Eigen::MatrixXd(constrained_values.middleCols(first, width)) : Eigen::MatrixXd());
    all.insert(all.end(), reports_.begin(), reports_.end());
  }
  reports_ = std::move(all);
  const double seconds = ice::seconds_since(start);
  for (MultigridReport& r : reports_) r.seconds = seconds;  // the whole block's, as for one chunk
  report_ = reports_[worst_report(reports_)];
  return out;
}

Eigen::MatrixXd MultigridSolver::solve_block_columns(const Eigen::MatrixXd& Bfull, const Eigen::MatrixXd& constrained_values) {
  const auto start = Clock::now();
  const Eigen::Index k = Bfull.cols();
  const Eigen::Index nf = static_cast<Eigen::Index>(free_.size());
  Block rhs(nf, k), X = Block::Zero(nf, k);
  for (Eigen::Index i = 0; i < nf; ++i) rhs.row(i) = Bfull.row(free_[static_cast<std::size_t>(i)]);
  if (constrained_values.size() != 0 && nf > 0) rhs.noalias() -= free_constrained_ * constrained_values;
  reports_.assign(static_cast<std::size_t>(k), MultigridReport());
  const SparseMatrix& A = levels_[0]->A;
  const int t = threads();
  Block R(nf, k);
  residual_block(A, rhs, X, R, t);
  Eigen::VectorXd scale = rhs.colwise().norm().transpose();
  for (Eigen::Index c = 0; c < k; ++c)
    if (!(scale(c) > 0)) scale(c) = 1;
  std::vector<char> active(static_cast<std::size_t>(k), 0);
  Eigen::Index remaining = 0;
  for (Eigen::Index c = 0; c < k; ++c) {
    const double res = R.col(c).norm() / scale(c);
    reports_[static_cast<std::size_t>(c)].residuals.push_back(res);
    active[static_cast<std::size_t>(c)] = nf > 0 && res > options_.tolerance;
    remaining += active[static_cast<std::size_t>(c)];
  }
  if (remaining > 0) {
    if (options_.mode == MultigridMode::vcycle) {
      Level& L = *levels_[0];
      for (int it = 0; it < options_.max_iterations && remaining > 0; ++it) {
        L.B = rhs;
        L.X = X;
        vcycle(0);
        residual_block(A, rhs, L.X, R, t);
        for (Eigen::Index c = 0; c < k; ++c) {
          if (!active[static_cast<std::size_t>(c)]) continue;
          X.col(c) = L.X.col(c);
          MultigridReport& rep = reports_[static_cast<std::size_t>(c)];
          const double res = R.col(c).norm() / scale(c);
          ++rep.iterations;
          rep.residuals.push_back(res);
          if (res <= options_.tolerance) {
            active[static_cast<std::size_t>(c)] = 0;
            --remaining;
          }
        }
      }
    } else {
      // Inactive (converged) columns get zero step lengths and keep their iterates.
      Block Z, P, AP(nf, k);
      apply_vcycle_block(R, Z);
      P = Z;
      Eigen::VectorXd rz = column_dots(R, Z, t), alpha(k), beta(k);
      for (int it = 0; it < options_.max_iterations && remaining > 0; ++it) {
        multiply_block(A, P, AP, t);
        const Eigen::VectorXd pAp = column_dots(P, AP, t);
        for (Eigen::Index c = 0; c < k; ++c) {
          alpha(c) = 0;
          if (!active[static_cast<std::size_t>(c)]) continue;
          if (!(pAp(c) > 0) || !(rz(c) > 0)) {  // breakdown
            active[static_cast<std::size_t>(c)] = 0;
            --remaining;
            continue;
          }
          alpha(c) = rz(c) / pAp(c);
        }
        axpy_columns(alpha, P, X, t);
        axpy_columns(-alpha, AP, R, t);
        const Eigen::VectorXd rr = column_dots(R, R, t);
        for (Eigen::Index c = 0; c < k; ++c) {
          if (alpha(c) == 0) continue;
          MultigridReport& rep = reports_[static_cast<std::size_t>(c)];
          const double res = std::sqrt(rr(c)) / scale(c);
          ++rep.iterations;
          rep.residuals.push_back(res);
          if (res <= options_.tolerance) {
            active[static_cast<std::size_t>(c)] = 0;
            --remaining;
          }
        }
        if (remaining == 0) break;
        apply_vcycle_block(R, Z);
        const Eigen::VectorXd rz_next = column_dots(R, Z, t);
        for (Eigen::Index c = 0; c < k; ++c) beta(c) = active[static_cast<std::size_t>(c)] ? rz_next(c) / rz(c) : 0.0;
        // P = Z + beta P for active columns; inactive columns are left as they are.
        const double* z = Z.data();
        double* pp = P.data();
        const char* on = active.data();
#pragma omp parallel for schedule(static) num_threads(active_threads(nf, t))
        for (Eigen::Index i = 0; i < nf; ++i)
          for (Eigen::Index q = 0; q < k; ++q)
            if (on[q]) pp[i * k + q] = z[i * k + q] + beta(q) * pp[i * k + q];
        for (Eigen::Index c = 0; c < k; ++c)
          if (active[static_cast<std::size_t>(c)]) rz(c) = rz_next(c);
      }
    }
  }
  residual_block(A, rhs, X, R, t);
  Eigen::MatrixXd out(size_, k);
  for (Eigen::Index i = 0; i < nf; ++i) out.row(free_[static_cast<std::size_t>(i)]) = X.row(i);
  for (std::size_t c = 0; c < constrained_.size(); ++c)
    out.row(constrained_[c]) = constrained_values.size() ? Eigen::RowVectorXd(constrained_values.row(static_cast<Eigen::Index>(c)))
                                                          : Eigen::RowVectorXd::Zero(k);
  const double seconds = ice::seconds_since(start);
  for (Eigen::Index c = 0; c < k; ++c) {
    MultigridReport& rep = reports_[static_cast<std::size_t>(c)];
    rep.relative_residual = nf > 0 ? R.col(c).norm() / scale(c) : 0.0;
    rep.converged = rep.relative_residual <= options_.tolerance ||
                    (rep.residuals.back() <= options_.tolerance && rep.relative_residual <= 10 * options_.tolerance);
    if (rep.iterations > 0 && rep.residuals.front() > 0 && rep.residuals.back() > 0)
      rep.convergence_factor = std::pow(rep.residuals.back() / rep.residuals.front(), 1.0 / rep.iterations);
    rep.seconds = seconds;
  }
  if (k > 0) report_ = reports_[worst_report(reports_)];
  return out;
}

}  // namespace fem
