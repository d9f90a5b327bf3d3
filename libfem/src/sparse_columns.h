#pragma once
// Internal to libfem (not installed): building compressed column-major matrices column by column,
// and compressed views of possibly uncompressed inputs.
#include <algorithm>
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
template <class Entries>
SparseMatrix assemble_columns(Eigen::Index rows, Eigen::Index cols, Eigen::Index capacity, Entries&& entries) {
  std::vector<Index> starts{0}, inner;
  std::vector<double> values;
  inner.reserve(static_cast<std::size_t>(capacity));
  values.reserve(static_cast<std::size_t>(capacity));
  std::vector<std::pair<int, double>> column;
  for (Eigen::Index c = 0; c < cols; ++c) {
    column.clear();
    entries(c, column);
    std::sort(column.begin(), column.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [row, value] : column) {
      inner.push_back(row);
      values.push_back(value);
    }
    starts.push_back(static_cast<int>(inner.size()));
  }
  SparseMatrix M(rows, cols);
  M.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(starts.begin(), starts.end(), M.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), M.innerIndexPtr());
  std::copy(values.begin(), values.end(), M.valuePtr());
  return M;
}

}  // namespace detail
}  // namespace fem
