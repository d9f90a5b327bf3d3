#include "fem/topology.h"

#include <algorithm>
#include <cstdint>
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

}  // namespace fem
