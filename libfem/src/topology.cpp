#include "fem/topology.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>

namespace fem {

std::vector<Index> boundary_vertices(const ice::Faces& F) {
  // Sort undirected edge keys; a key that occurs once is a boundary edge.
  std::vector<std::uint64_t> keys;
  keys.reserve(static_cast<std::size_t>(3 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint64_t>(F(f, k)), b = static_cast<std::uint64_t>(F(f, (k + 1) % 3));
      keys.push_back((std::min(a, b) << 32) | std::max(a, b));
    }
  std::sort(keys.begin(), keys.end());
  std::vector<Index> vertices;
  for (std::size_t i = 0; i < keys.size();) {
    std::size_t j = i;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    if (j - i == 1) {
      vertices.push_back(static_cast<int>(keys[i] >> 32));
      vertices.push_back(static_cast<int>(keys[i] & 0xffffffffu));
    }
    i = j;
  }
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  return vertices;
}

Index connected_components(const SparseMatrix& A) {
  // Union–find with path halving over the non-zeros.
  std::vector<Index> parent(static_cast<std::size_t>(A.rows()));
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<Index>(i);
  const auto root = [&parent](Index i) {
    while (parent[static_cast<std::size_t>(i)] != i) {
      parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
      i = parent[static_cast<std::size_t>(i)];
    }
    return i;
  };
  Index components = static_cast<Index>(A.rows());
  for (Eigen::Index j = 0; j < A.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(A, j); it; ++it) {
      if (it.value() == 0) continue;
      const Index a = root(static_cast<Index>(it.row())), b = root(static_cast<Index>(it.col()));
      if (a != b) {
        parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
        --components;
      }
    }
  return components;
}

void require_connected(const SparseMatrix& A, const char* what) {
  const Index components = connected_components(A);
  if (components > 1)
    throw std::invalid_argument(std::string(what) + ": the mesh has " + std::to_string(components) +
                                " connected components; this solver pins one vertex and needs a connected mesh "
                                "(solve each component apart)");
}

}  // namespace fem
