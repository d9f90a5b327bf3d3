#include "ice/mesh_repair.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <array>
#include <numeric>
#include <unordered_map>

#include "corner_fans.h"
#include "soup_duplicates.h"

namespace ice {

namespace {

bool finite_row(const Positions& V, int i) {
  return std::isfinite(V(i, 0)) && std::isfinite(V(i, 1)) && std::isfinite(V(i, 2));
}

template <class Corners>
bool indices_in_range(const Corners& poly, int nv) {
  return std::all_of(poly.begin(), poly.end(), [&](int v) { return v >= 0 && v < nv; });
}

double bounding_box_diagonal(const Positions& V) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  bool any = false;
  for (int i = 0; i < V.rows(); ++i) {
    if (!finite_row(V, i)) continue;
    lo = lo.cwiseMin(V.row(i).transpose());
    hi = hi.cwiseMax(V.row(i).transpose());
    any = true;
  }
  return any ? (hi - lo).norm() : 0.0;
}

/// Shape quality of a triangle: 2·area / (longest edge)², 0 for degenerate or non-finite ones.
double triangle_shape(const Positions& V, int a, int b, int c) {
  const Eigen::Vector3d pa = V.row(a), pb = V.row(b), pc = V.row(c);
  const Eigen::Vector3d ab = pb - pa, ac = pc - pa, bc = pc - pb;
  const double longest2 = std::max({ab.squaredNorm(), ac.squaredNorm(), bc.squaredNorm()});
  if (!(longest2 > 0) || !std::isfinite(longest2)) return 0.0;
  return ab.cross(ac).norm() / longest2;
}

/// Fan triangulation of `poly` from the corner whose fan has the best worst-triangle shape.
std::vector<std::array<int, 3>> best_fan(const Positions& V, const std::vector<int>& poly) {
  const std::size_t n = poly.size();
  std::size_t best_start = 0;
  double best_quality = -1;
  for (std::size_t s = 0; s < n; ++s) {
    double worst = std::numeric_limits<double>::infinity();
    for (std::size_t i = 1; i + 1 < n; ++i)
      worst = std::min(worst, triangle_shape(V, poly[s], poly[(s + i) % n], poly[(s + i + 1) % n]));
    if (worst > best_quality) {
      best_quality = worst;
      best_start = s;
    }
  }
  std::vector<std::array<int, 3>> triangles;
  for (std::size_t i = 1; i + 1 < n; ++i)
    triangles.push_back({poly[best_start], poly[(best_start + i) % n], poly[(best_start + i + 1) % n]});
  return triangles;
}

/// Re-orient orientable, inconsistently oriented components of a manifold triangle soup in place.
void orient_components(PolygonSoup& soup, RepairLog& log) {
  const auto& V = soup.V;
  auto& polys = soup.polygons;
  const int nf = static_cast<int>(polys.size());
  struct Use {
    std::uint64_t key;
    int face;
    bool forward;
  };
  std::vector<Use> uses;
  for (int f = 0; f < nf; ++f)
    for (std::size_t k = 0; k < polys[f].size(); ++k) {
      const int a = polys[f][k], b = polys[f][(k + 1) % polys[f].size()];
      const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
      uses.push_back({(lo << 32) | hi, f, a < b});
    }
  std::sort(uses.begin(), uses.end(), [](const Use& x, const Use& y) { return x.key < y.key; });
  std::vector<std::vector<std::pair<int, int>>> links(static_cast<std::size_t>(nf));
  std::vector<char> has_boundary(static_cast<std::size_t>(nf), 0);
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 2) {
      const int parity = uses[i].forward == uses[i + 1].forward ? 1 : 0;
      links[uses[i].face].emplace_back(uses[i + 1].face, parity);
      links[uses[i + 1].face].emplace_back(uses[i].face, parity);
    } else if (j - i == 1) {
      has_boundary[uses[i].face] = 1;
    }
    i = j;
  }

  std::vector<int> flip(static_cast<std::size_t>(nf), -1);
  for (int seed = 0; seed < nf; ++seed) {
    if (flip[seed] >= 0) continue;
    std::vector<int> members{seed};
    flip[seed] = 0;
    bool conflict = false, needs_flip = false, open = false;
    for (std::size_t head = 0; head < members.size(); ++head) {
      const int f = members[head];
      open = open || has_boundary[f];
      for (const auto& [g, parity] : links[f]) {
        needs_flip = needs_flip || parity;
        const int wanted = flip[f] ^ parity;
        if (flip[g] < 0) {
          flip[g] = wanted;
          members.push_back(g);
        } else if (flip[g] != wanted) {
          conflict = true;
        }
      }
    }
    if (conflict || !needs_flip) continue;  // non-orientable (reported later) or already consistent

    bool invert;
    if (open) {
      const auto flipped = std::count_if(members.begin(), members.end(), [&](int f) { return flip[f] == 1; });
      invert = 2 * static_cast<std::size_t>(flipped) > members.size();
    } else {
      // Signed volume relative to a corner of the component (translation-invariant, no cancellation at 1e6).
      const Eigen::Vector3d origin = V.row(polys[seed][0]);
      double volume = 0;
      for (int f : members) {
        const auto& t = polys[f];
        Eigen::Vector3d p0 = V.row(t[0]).transpose() - origin, p1 = V.row(t[1]).transpose() - origin,
                        p2 = V.row(t[2]).transpose() - origin;
        volume += (flip[f] ? -1.0 : 1.0) * p0.dot(p1.cross(p2));
      }
      invert = volume < 0;
    }
    for (int f : members) {
      if ((flip[f] == 1) == invert) continue;  // final orientation: flipped iff flip[f] xor invert
      std::reverse(polys[f].begin(), polys[f].end());
      ++log.flipped_faces;
    }
    ++log.reoriented_components;
  }
}

/// Gives every fan of faces around a vertex its own copy of the vertex (same position, same source
/// id), on a triangle soup whose edges are manifold: afterwards every vertex is manifold. Two corners
/// at a vertex are in one fan when their faces share an edge at that vertex. Returns the copies made.
std::size_t split_non_manifold_vertices(PolygonSoup& soup, std::vector<int>& source_vertex) {
  auto& faces = soup.polygons;
  const std::size_t nf = faces.size();
  const std::vector<std::size_t> fan = detail::corner_fans(soup);  // corner 3f + k: every face is a valid triangle
  // The first fan met keeps the vertex; every other fan gets a copy.
  std::vector<std::size_t> first_fan(static_cast<std::size_t>(soup.V.rows()), SIZE_MAX);
  std::unordered_map<std::size_t, int> copy_of_fan;  // fan root -> its new vertex
  std::vector<Eigen::RowVector3d> new_points;
  for (std::size_t c = 0; c < 3 * nf; ++c) {
    const std::size_t root = fan[c];
    int& v = faces[c / 3][c % 3];
    std::size_t& first = first_fan[static_cast<std::size_t>(v)];
    if (first == SIZE_MAX) first = root;
    if (first == root) continue;
    const auto [it, made] =
        copy_of_fan.emplace(root, static_cast<int>(soup.V.rows() + static_cast<Eigen::Index>(new_points.size())));
    if (made) {
      new_points.push_back(soup.V.row(v));
      source_vertex.push_back(source_vertex[static_cast<std::size_t>(v)]);
    }
    v = it->second;
  }
  if (new_points.empty()) return 0;
  const Eigen::Index old_rows = soup.V.rows();
  soup.V.conservativeResize(old_rows + static_cast<Eigen::Index>(new_points.size()), 3);
  for (std::size_t i = 0; i < new_points.size(); ++i) soup.V.row(old_rows + static_cast<Eigen::Index>(i)) = new_points[i];
  return new_points.size();
}

}  // namespace

bool RepairLog::empty() const { return summary().empty(); }

std::vector<std::string> RepairLog::summary() const {
  std::vector<std::string> lines;
  auto add = [&](std::size_t n, const char* what) {
    if (n > 0) lines.push_back(std::to_string(n) + ' ' + what);
  };
  add(welded_vertices, "coincident vertices welded");
  add(collapsed_repeated_corners, "repeated consecutive face corners collapsed");
  add(removed_degenerate_faces, "faces with fewer than 3 distinct corners removed");
  add(triangulated_polygons, "polygons triangulated");
  add(removed_zero_area_faces, "zero-area faces removed");
  add(removed_duplicate_faces, "duplicate faces removed");
  add(removed_unreferenced_vertices, "unreferenced vertices removed");
  add(split_non_manifold_vertices, "vertex copies made to split non-manifold vertices (one per extra fan)");
  add(flipped_faces, "faces flipped for consistent orientation");
  add(reoriented_components, "components re-oriented");
  return lines;
}

RepairResult repair_mesh(const PolygonSoup& input, const RepairOptions& options) {
  RepairResult out;
  RepairLog& log = out.log;
  const Positions& V = input.V;
  const int nv = static_cast<int>(V.rows());
  const double diagonal = bounding_box_diagonal(V);

  // 1. welding map (identity unless asked)
  std::vector<int> weld(static_cast<std::size_t>(nv));
  std::iota(weld.begin(), weld.end(), 0);
  if (options.weld_duplicate_positions) {
    weld = detail::first_coincident_vertex(V);
    for (int v = 0; v < static_cast<int>(weld.size()); ++v) log.welded_vertices += weld[v] != v;
  }

  // 2.–4. faces
  PolygonList faces;
  faces.reserve(input.polygons.size(), input.polygons.corner_count());
  std::vector<int> face_source;
  for (std::size_t f = 0; f < input.polygons.size(); ++f) {
    const auto original = input.polygons[f];
    if (!indices_in_range(original, nv)) {  // cannot be repaired: keep for the report
      faces.push_back(original);
      face_source.push_back(static_cast<int>(f));
      continue;
    }
    if (original.size() == 3) {  // fast path: the common well-formed triangle
      const int a = weld[original[0]], b = weld[original[1]], c = weld[original[2]];
      if (a != b && b != c && a != c) {
        faces.push_back({a, b, c});
        face_source.push_back(static_cast<int>(f));
        continue;
      }
    }
    std::vector<int> poly = original.to_vector();
    for (int& v : poly) v = weld[v];
    // Remove cyclically consecutive repeats (a b b c -> a b c; a b c a -> a b c).
    std::vector<int> collapsed;
    for (std::size_t k = 0; k < poly.size(); ++k)
      if (collapsed.empty() || collapsed.back() != poly[k]) collapsed.push_back(poly[k]);
    while (collapsed.size() > 1 && collapsed.front() == collapsed.back()) collapsed.pop_back();
    log.collapsed_repeated_corners += poly.size() - collapsed.size();
    std::vector<int> distinct = collapsed;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    if (distinct.size() < 3) {
      ++log.removed_degenerate_faces;
      continue;
    }
    if (distinct.size() != collapsed.size() || collapsed.size() == 3 || !options.triangulate_polygons) {
      faces.push_back(collapsed);  // non-consecutive repeats stay and get reported
      face_source.push_back(static_cast<int>(f));
      continue;
    }
    ++log.triangulated_polygons;
    for (const auto& t : best_fan(V, collapsed)) {
      faces.push_back({t[0], t[1], t[2]});
      face_source.push_back(static_cast<int>(f));
    }
  }

  // zero-area triangles, then duplicates (same vertex set; keep the first)
  std::vector<char> keep(faces.size(), 1);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const auto t = faces[f];
    if (t.size() != 3 || !indices_in_range(t, nv)) continue;
    const Eigen::Vector3d a = V.row(t[0]), b = V.row(t[1]), c = V.row(t[2]);
    if (!a.allFinite() || !b.allFinite() || !c.allFinite()) continue;  // reported, not fixed
    if (is_degenerate_triangle(V, t[0], t[1], t[2], diagonal)) {
      keep[f] = 0;
      ++log.removed_zero_area_faces;
    }
  }
  {
    std::vector<char> include(faces.size());
    for (std::size_t f = 0; f < faces.size(); ++f) include[f] = keep[f] && indices_in_range(faces[f], nv);
    for (int f : detail::later_duplicate_faces(faces, include, nv)) {
      keep[f] = 0;
      ++log.removed_duplicate_faces;
    }
  }
  PolygonList kept;
  kept.reserve(faces.size(), faces.corner_count());
  for (std::size_t f = 0; f < faces.size(); ++f)
    if (keep[f]) {
      kept.push_back(faces[f]);
      out.source_face.push_back(face_source[f]);
    }

  // 5. drop unreferenced vertices (only possible when every index is in range)
  const bool remappable = std::all_of(kept.corners().begin(), kept.corners().end(), [&](int v) { return v >= 0 && v < nv; });
  if (remappable) {
    std::vector<int> new_id(static_cast<std::size_t>(nv), -1);
    for (int v : kept.corners())
      if (new_id[v] < 0) new_id[v] = 0;
    int next = 0;
    for (int v = 0; v < nv; ++v)
      if (new_id[v] == 0) {
        new_id[v] = next++;
        out.source_vertex.push_back(v);
      }
    log.removed_unreferenced_vertices = static_cast<std::size_t>(nv - next);
    out.soup.V.resize(next, 3);
    for (int i = 0; i < next; ++i) out.soup.V.row(i) = V.row(out.source_vertex[i]);
    for (std::size_t f = 0; f < kept.size(); ++f)
      for (int& v : kept[f]) v = new_id[v];
  } else {
    out.soup.V = V;
    out.source_vertex.resize(static_cast<std::size_t>(nv));
    std::iota(out.source_vertex.begin(), out.source_vertex.end(), 0);
  }
  out.soup.polygons = std::move(kept);

  // 6. non-manifold vertices (a fan of faces touching the rest at one vertex, common in scans): one
  // copy of the vertex per fan, only when every face is a triangle in range and every edge manifold
  out.report = validate_mesh(out.soup);
  {
    const ValidationReport& r = out.report;
    if (!r.non_manifold_vertices.empty() && r.non_manifold_edges.empty() && r.non_triangle_faces.empty() &&
        r.out_of_range_faces.empty() && r.repeated_index_faces.empty()) {
      log.split_non_manifold_vertices = split_non_manifold_vertices(out.soup, out.source_vertex);
      out.report = validate_mesh(out.soup);
    }
  }

  // 7. orientation, only on a well-formed manifold triangle mesh
  const ValidationReport& r = out.report;
  if (!r.inconsistent_edges.empty() && r.manifold() && r.non_triangle_faces.empty() &&
      r.out_of_range_faces.empty() && r.repeated_index_faces.empty()) {
    orient_components(out.soup, log);
    out.report = validate_mesh(out.soup);
  }
  return out;
}

}  // namespace ice
