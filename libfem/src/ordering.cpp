#include "fem/ordering.h"

#include <algorithm>
#include <stdexcept>

namespace fem {

namespace {

// Breadth-first search from `root` over unvisited vertices (mark != stamp), marking them with
// `stamp`. Appends the visited vertices to `out` in visiting order, neighbours of each vertex in
// increasing (degree, index) when `sorted` (probes only need the levels). Returns the number of levels (the root's eccentricity + 1) and leaves
// the first vertex of the last level in *last_level_begin (an index into out).
int breadth_first(const SparseMatrix& A, const std::vector<int>& degree, int root, std::vector<int>& mark, int stamp,
                  bool sorted, std::vector<int>& out, std::size_t* last_level_begin) {
  const auto* start = A.outerIndexPtr();
  const auto* inner = A.innerIndexPtr();
  std::size_t level_begin = out.size();
  out.push_back(root);
  mark[static_cast<std::size_t>(root)] = stamp;
  int levels = 1;
  std::vector<int> neighbours;
  std::size_t head = level_begin, level_end = out.size();
  while (true) {
    for (; head < level_end; ++head) {
      const int v = out[head];
      neighbours.clear();
      for (auto p = start[v]; p < start[v + 1]; ++p) {
        const int u = inner[p];
        if (mark[static_cast<std::size_t>(u)] == stamp) continue;
        mark[static_cast<std::size_t>(u)] = stamp;
        neighbours.push_back(u);
      }
      if (sorted)
        std::sort(neighbours.begin(), neighbours.end(), [&](int a, int b) {
        return degree[static_cast<std::size_t>(a)] != degree[static_cast<std::size_t>(b)]
                   ? degree[static_cast<std::size_t>(a)] < degree[static_cast<std::size_t>(b)]
                   : a < b;
      });
      out.insert(out.end(), neighbours.begin(), neighbours.end());
    }
    if (out.size() == level_end) break;  // no new level
    level_begin = level_end;
    level_end = out.size();
    ++levels;
  }
  *last_level_begin = level_begin;
  return levels;
}

}  // namespace

std::vector<int> reverse_cuthill_mckee(const SparseMatrix& A) {
  if (A.rows() != A.cols()) throw std::invalid_argument("reverse_cuthill_mckee: the matrix must be square");
  const int n = static_cast<int>(A.rows());
  SparseMatrix compressed_copy;  // the search walks outer ranges
  if (!A.isCompressed()) {
    compressed_copy = A;
    compressed_copy.makeCompressed();
  }
  const SparseMatrix& pattern = A.isCompressed() ? A : compressed_copy;
  std::vector<int> degree(static_cast<std::size_t>(n), 0);
  for (int v = 0; v < n; ++v)
    for (SparseMatrix::InnerIterator it(pattern, v); it; ++it)
      if (it.row() != v) ++degree[static_cast<std::size_t>(v)];

  // Component roots are tried in increasing degree (then index), the usual start for the
  // pseudo-peripheral search.
  std::vector<int> by_degree(static_cast<std::size_t>(n));
  for (int v = 0; v < n; ++v) by_degree[static_cast<std::size_t>(v)] = v;
  std::stable_sort(by_degree.begin(), by_degree.end(),
                   [&](int a, int b) { return degree[static_cast<std::size_t>(a)] < degree[static_cast<std::size_t>(b)]; });

  std::vector<int> order;
  order.reserve(static_cast<std::size_t>(n));
  std::vector<int> mark(static_cast<std::size_t>(n), 0);  // 0: unvisited in the final numbering
  std::vector<int> probe;
  int stamp = 1;
  for (int candidate : by_degree) {
    if (mark[static_cast<std::size_t>(candidate)] == 1) continue;
    // George–Liu: move the root to a low-degree vertex of the last level while the eccentricity
    // grows (capped: each search is a full pass over the component, and the first move gives
    // most of the gain on meshes).
    int root = candidate, levels = 0;
    for (int attempt = 0; attempt < 3; ++attempt) {
      probe.clear();
      std::size_t last_begin = 0;
      ++stamp;
      const int probe_levels = breadth_first(pattern, degree, root, mark, stamp, false, probe, &last_begin);
      for (int v : probe) mark[static_cast<std::size_t>(v)] = 0;  // undo (they were unvisited)
      if (probe_levels <= levels) break;
      levels = probe_levels;
      int best = probe[last_begin];
      for (std::size_t i = last_begin; i < probe.size(); ++i)
        if (degree[static_cast<std::size_t>(probe[i])] < degree[static_cast<std::size_t>(best)]) best = probe[i];
      if (best == root) break;
      root = best;
    }
    std::size_t unused = 0;
    breadth_first(pattern, degree, root, mark, 1, true, order, &unused);
  }
  std::reverse(order.begin(), order.end());
  return order;
}

Eigen::Index bandwidth(const SparseMatrix& A) {
  Eigen::Index band = 0;
  for (Eigen::Index j = 0; j < A.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(A, j); it; ++it) band = std::max<Eigen::Index>(band, std::abs(it.row() - j));
  return band;
}

SparseMatrix permute_symmetric(const SparseMatrix& A, const std::vector<int>& order) {
  const Eigen::Index n = A.rows();
  if (A.cols() != n || static_cast<Eigen::Index>(order.size()) != n)
    throw std::invalid_argument("permute_symmetric: the matrix must be square with one order entry per row");
  std::vector<int> new_index(static_cast<std::size_t>(n), -1);
  for (Eigen::Index i = 0; i < n; ++i) {
    const int old = order[static_cast<std::size_t>(i)];
    if (old < 0 || old >= n || new_index[static_cast<std::size_t>(old)] >= 0)
      throw std::invalid_argument("permute_symmetric: order is not a permutation");
    new_index[static_cast<std::size_t>(old)] = static_cast<int>(i);
  }
  SparseMatrix B(n, n);
  B.resizeNonZeros(A.nonZeros());
  auto* outer = B.outerIndexPtr();
  outer[0] = 0;
  std::vector<std::pair<int, double>> column;
  Eigen::Index nnz = 0;
  for (Eigen::Index j = 0; j < n; ++j) {
    column.clear();
    for (SparseMatrix::InnerIterator it(A, order[static_cast<std::size_t>(j)]); it; ++it)
      column.emplace_back(new_index[static_cast<std::size_t>(it.row())], it.value());
    std::sort(column.begin(), column.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [row, value] : column) {
      B.innerIndexPtr()[nnz] = row;
      B.valuePtr()[nnz] = value;
      ++nnz;
    }
    outer[j + 1] = static_cast<int>(nnz);
  }
  return B;
}

}  // namespace fem
