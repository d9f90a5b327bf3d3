#include "fem/ordering.h"

#include "ice/graph_ordering.h"
#include "sparse_columns.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace fem {

std::vector<Index> reverse_cuthill_mckee(const SparseMatrix& A) {
  if (A.rows() != A.cols()) throw std::invalid_argument("reverse_cuthill_mckee: the matrix must be square");
  SparseMatrix copy;
  const SparseMatrix& C = detail::compressed(A, copy);
  return ice::reverse_cuthill_mckee(static_cast<int>(C.rows()), C.outerIndexPtr(), C.innerIndexPtr());
}

Eigen::Index bandwidth(const SparseMatrix& A) {
  Eigen::Index band = 0;
  for (Eigen::Index j = 0; j < A.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(A, j); it; ++it) band = std::max<Eigen::Index>(band, std::abs(it.row() - j));
  return band;
}

namespace {

// new_index[old] = new for order[new] = old, a permutation of 0..n−1 (std::invalid_argument naming
// `who` otherwise).
std::vector<Index> inverse_permutation(const std::vector<Index>& order, Eigen::Index n, const char* who) {
  if (static_cast<Eigen::Index>(order.size()) != n)
    throw std::invalid_argument(std::string(who) + ": " + std::to_string(order.size()) + " order entries for " +
                                std::to_string(n) + " rows");
  std::vector<Index> new_index(static_cast<std::size_t>(n), -1);
  for (Eigen::Index i = 0; i < n; ++i) {
    const int old = order[static_cast<std::size_t>(i)];
    if (old < 0 || old >= n || new_index[static_cast<std::size_t>(old)] >= 0)
      throw std::invalid_argument(std::string(who) + ": order is not a permutation");
    new_index[static_cast<std::size_t>(old)] = static_cast<int>(i);
  }
  return new_index;
}

}  // namespace

SparseMatrix permute_symmetric(const SparseMatrix& A, const std::vector<Index>& order) {
  const Eigen::Index n = A.rows();
  if (A.cols() != n) throw std::invalid_argument("permute_symmetric: the matrix must be square");
  const std::vector<Index> new_index = inverse_permutation(order, n, "permute_symmetric");
  return detail::assemble_columns(n, n, A.nonZeros(), [&](Eigen::Index j, std::vector<std::pair<int, double>>& column) {
    for (SparseMatrix::InnerIterator it(A, order[static_cast<std::size_t>(j)]); it; ++it)
      column.emplace_back(new_index[static_cast<std::size_t>(it.row())], it.value());
  });
}

SparseMatrix permute_rows(const SparseMatrix& P, const std::vector<Index>& order) {
  const std::vector<Index> new_index = inverse_permutation(order, P.rows(), "permute_rows");
  return detail::assemble_columns(P.rows(), P.cols(), P.nonZeros(), [&](Eigen::Index j, std::vector<std::pair<int, double>>& column) {
    for (SparseMatrix::InnerIterator it(P, j); it; ++it) column.emplace_back(new_index[static_cast<std::size_t>(it.row())], it.value());
  });
}

}  // namespace fem
