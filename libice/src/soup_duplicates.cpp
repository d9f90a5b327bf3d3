#include "soup_duplicates.h"

#include "vertex_buckets.h"

#include <algorithm>
#include <array>
#include <numeric>
#include <utility>

#include <Eigen/Core>

namespace ice::detail {

std::vector<int> first_coincident_vertex(const Positions& V) {
  const int nv = static_cast<int>(V.rows());
  // Plain copies: Eigen element access is slow in unoptimised sanitizer builds.
  std::vector<Eigen::Vector3d> P(static_cast<std::size_t>(nv));
  std::vector<int> order;
  order.reserve(static_cast<std::size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    P[i] = V.row(i).transpose();
    if (P[i].allFinite()) order.push_back(i);  // finite only, so the sort order is strict
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    for (int k = 0; k < 3; ++k)
      if (P[a][k] != P[b][k]) return P[a][k] < P[b][k];
    return a < b;
  });
  std::vector<int> first(static_cast<std::size_t>(nv));
  std::iota(first.begin(), first.end(), 0);
  for (std::size_t i = 1; i < order.size(); ++i)
    if (P[order[i]] == P[order[i - 1]]) first[order[i]] = first[order[i - 1]];  // a group's smallest id
  return first;
}

std::vector<int> later_duplicate_faces(const std::vector<std::vector<int>>& faces, const std::vector<char>& include,
                                       Index vertices) {
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
      std::vector<int> key = faces[f];
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
