#include "soup_duplicates.h"

#include "vertex_buckets.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <utility>

#include <Eigen/Core>

namespace ice::detail {

std::vector<int> first_coincident_vertex(const Positions& V) {
  const int nv = static_cast<int>(V.rows());
  // Vertices in increasing order into an open-addressing table keyed by exact position (O(V),
  // where sorting the positions was a third of the validation at 1.6M vertices): a vertex whose
  // position is already there takes that (smaller) vertex.
  std::vector<Eigen::Vector3d> P(static_cast<std::size_t>(nv));  // plain copies: fast in sanitizer builds too
  for (int i = 0; i < nv; ++i) P[i] = V.row(i).transpose();
  std::size_t slots = 16;
  while (slots < 2 * static_cast<std::size_t>(nv)) slots *= 2;
  std::vector<int> table(slots, -1);
  const auto bits = [](double x) {
    std::uint64_t b;
    const double canonical = x == 0.0 ? 0.0 : x;  // -0.0 == 0.0: one key for both
    std::memcpy(&b, &canonical, sizeof b);
    return b;
  };
  std::vector<int> first(static_cast<std::size_t>(nv));
  std::iota(first.begin(), first.end(), 0);
  for (int i = 0; i < nv; ++i) {
    const Eigen::Vector3d& p = P[i];
    if (!p.allFinite()) continue;  // never merged
    std::uint64_t h = bits(p[0]) * 0x9E3779B97F4A7C15ull;
    h = (h ^ (h >> 29) ^ bits(p[1])) * 0xBF58476D1CE4E5B9ull;
    h = (h ^ (h >> 31) ^ bits(p[2])) * 0x94D049BB133111EBull;
    h ^= h >> 32;
    for (std::size_t slot = h & (slots - 1);; slot = (slot + 1) & (slots - 1)) {
      const int j = table[slot];
      if (j < 0) {
        table[slot] = i;
        break;
      }
      if (P[j] == p) {
        first[i] = j;
        break;
      }
    }
  }
  return first;
}

std::vector<int> later_duplicate_faces(const PolygonList& faces, const std::vector<char>& include, Index vertices) {
  // Triangles by sorted corners (a < b < c): ordered by a (a counting sort), then by (b, c, face);
  // within a run of equal corner sets every face after the first is a duplicate.
  std::vector<std::array<int, 4>> triangles;
  std::vector<std::pair<std::vector<int>, int>> polygons;  // rare: faces with more corners, sorted whole
  for (std::size_t f = 0; f < faces.size(); ++f) {
    if (!include[f]) continue;
    if (faces[f].size() == 3) {
      std::array<int, 4> key{faces[f][0], faces[f][1], faces[f][2], static_cast<int>(f)};
      std::sort(key.begin(), key.begin() + 3);
      triangles.push_back(key);
    } else {
      std::vector<int> key = faces[f].to_vector();
      std::sort(key.begin(), key.end());
      polygons.emplace_back(std::move(key), static_cast<int>(f));
    }
  }
  sort_by_vertex(
      triangles, vertices, [](const std::array<int, 4>& t) { return t[0]; },
      [](const std::array<int, 4>& p, const std::array<int, 4>& q) {
        return p[1] != q[1] ? p[1] < q[1] : p[2] != q[2] ? p[2] < q[2] : p[3] < q[3];
      });
  std::sort(polygons.begin(), polygons.end());
  std::vector<int> later;
  for (std::size_t i = 1; i < triangles.size(); ++i) {
    const auto& p = triangles[i];
    const auto& q = triangles[i - 1];
    if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]) later.push_back(p[3]);
  }
  for (std::size_t i = 1; i < polygons.size(); ++i)
    if (polygons[i].first == polygons[i - 1].first) later.push_back(polygons[i].second);
  std::sort(later.begin(), later.end());
  return later;
}

}  // namespace ice::detail
