#pragma once
// Internal to libfem (not installed): building compressed column-major matrices column by column,
// and compressed views of possibly uncompressed inputs.
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "fem/operators.h"

namespace fem {
namespace detail {

/// M itself when compressed, else a compressed copy kept in `copy` (kernels walk outer ranges).
inline const SparseMatrix& compressed(const SparseMatrix& M, SparseMatrix& copy) {
  if (M.isCompressed()) return M;
  copy = M;
  copy.makeCompressed();
  return copy;
}

/// A rows × cols matrix whose column c holds the (row, value) pairs that `entries(c, out)` appends
/// to `out` (in any order; they are sorted by row). `capacity`: expected non-zeros (a reservation).
/// With threads > 1, ranges of columns are gathered on that many threads (`entries` is then called
/// concurrently) and copied into place: the same matrix.
template <class Entries>
SparseMatrix assemble_columns(Eigen::Index rows, Eigen::Index cols, Eigen::Index capacity, Entries&& entries, int threads = 1) {
  // Ranges of columns gathered into arrays of their own, then copied into place.
  threads = std::max(threads, 1);
  const int tasks = threads > 1 ? 4 * threads : 1;
  const auto bound = [&](int t) { return static_cast<Eigen::Index>(static_cast<long long>(cols) * t / tasks); };
  std::vector<std::vector<Index>> inner_of(static_cast<std::size_t>(tasks)), count_of(static_cast<std::size_t>(tasks));
  std::vector<std::vector<double>> values_of(static_cast<std::size_t>(tasks));
  if (tasks == 1) {
    inner_of[0].reserve(static_cast<std::size_t>(capacity));
    values_of[0].reserve(static_cast<std::size_t>(capacity));
  }
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) if (threads > 1)
  for (int t = 0; t < tasks; ++t) {
    std::vector<std::pair<int, double>> column;
    auto& inner = inner_of[static_cast<std::size_t>(t)];
    auto& values = values_of[static_cast<std::size_t>(t)];
    auto& counts = count_of[static_cast<std::size_t>(t)];
    for (Eigen::Index c = bound(t); c < bound(t + 1); ++c) {
      column.clear();
      entries(c, column);
      std::sort(column.begin(), column.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      for (const auto& [row, value] : column) {
        inner.push_back(row);
        values.push_back(value);
      }
      counts.push_back(static_cast<Index>(column.size()));
    }
  }
  SparseMatrix M(rows, cols);
  std::vector<Index> offset(static_cast<std::size_t>(tasks) + 1, 0);
  for (int t = 0; t < tasks; ++t)
    offset[static_cast<std::size_t>(t) + 1] = offset[static_cast<std::size_t>(t)] + static_cast<Index>(inner_of[static_cast<std::size_t>(t)].size());
  M.resizeNonZeros(static_cast<Eigen::Index>(offset.back()));
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) if (threads > 1)
  for (int t = 0; t < tasks; ++t) {
    Index at = offset[static_cast<std::size_t>(t)];
    Eigen::Index c = bound(t);
    for (const Index count : count_of[static_cast<std::size_t>(t)]) {
      M.outerIndexPtr()[c++] = at;
      at += count;
    }
    std::copy(inner_of[static_cast<std::size_t>(t)].begin(), inner_of[static_cast<std::size_t>(t)].end(), M.innerIndexPtr() + offset[static_cast<std::size_t>(t)]);
    std::copy(values_of[static_cast<std::size_t>(t)].begin(), values_of[static_cast<std::size_t>(t)].end(), M.valuePtr() + offset[static_cast<std::size_t>(t)]);
  }
  M.outerIndexPtr()[cols] = offset.back();
  return M;
}

/// Coarse unknowns that a prolongation P reaches weakly would make Pᵀ A P singular: vertices inserted
/// by refinement where the fine mesh is sparse can have an empty column (no fine vertex in their
/// faces, or weights below 1e-9), or columns that together span fewer fine vertices than they are
/// (two inserted vertices sharing one fine vertex: dependent columns). Both are stabilised on the
/// diagonal, relative to the mean of its other entries (the operator's scale):
///  - unreached columns get that mean: decoupled; their right-hand sides Pᵀb are zero, so they
///    solve to zero, and P never carries them to the fine mesh;
///  - columns whose weights sum to less than 1 (less than one fine vertex's worth; never a vertex
///    that exists on the fine mesh, whose own weight is 1) get 1e-8 times it: any dependence among
///    them is lifted, which moves the prolonged solution by about 1e-8 relative to the coarse
///    operator's smallest eigenvalue.
/// Returns how many unknowns were stabilised.
template <class Scalar, class Prolongation>
Index stabilise_weak_coarse_unknowns(const Prolongation& P, Eigen::SparseMatrix<Scalar, Eigen::ColMajor, Index>& coarse) {
  std::vector<std::pair<Index, bool>> weak;  // (unknown, unreached)
  for (Eigen::Index c = 0; c < P.outerSize(); ++c) {
    double largest = 0, sum = 0;
    for (typename Prolongation::InnerIterator it(P, c); it; ++it) {
      largest = std::max(largest, static_cast<double>(std::abs(it.value())));
      sum += static_cast<double>(std::abs(it.value()));
    }
    if (largest < 1e-9) weak.emplace_back(static_cast<Index>(c), true);
    else if (sum < 1) weak.emplace_back(static_cast<Index>(c), false);
  }
  if (weak.empty()) return 0;
  double diagonal_sum = 0;
  Eigen::Index diagonal_count = 0;
  for (Eigen::Index c = 0; c < coarse.rows(); ++c) {
    const double d = static_cast<double>(std::abs(coarse.coeff(c, c)));
    if (d > 0) diagonal_sum += d, ++diagonal_count;
  }
  const double mean = diagonal_count > 0 ? diagonal_sum / static_cast<double>(diagonal_count) : 1.0;
  for (const auto& [c, unreached] : weak) coarse.coeffRef(c, c) += Scalar(unreached ? mean : 1e-8 * mean);
  coarse.makeCompressed();
  return static_cast<Index>(weak.size());
}

}  // namespace detail
}  // namespace fem
