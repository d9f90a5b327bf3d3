#include "ice/mesh_validation.h"
#include "ice/triangle_geometry.h"

#include "disjoint_sets.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <sstream>
#include <type_traits>

namespace ice {

namespace {

using detail::DisjointSets;

/// One directed use of an undirected edge by a face corner.
struct HalfEdgeUse {
  std::uint64_t key;  ///< (min << 32) | max of the endpoint ids.
  int face;
  int corner;         ///< The half-edge goes from corner to corner+1 of `face`.
  bool forward;       ///< True if it goes from the smaller to the larger vertex id.
};

std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b));
  const auto hi = static_cast<std::uint64_t>(std::max(a, b));
  return (lo << 32) | hi;
}

VertexPair edge_pair(std::uint64_t key) {
  return {static_cast<int>(key >> 32), static_cast<int>(key & 0xffffffffu)};
}

/// Twice the vector area of a polygon (Newell's formula), for faces with more than three corners.
Eigen::Vector3d polygon_double_area(const Positions& V, const std::vector<int>& poly) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const Eigen::Vector3d origin = V.row(poly[0]).transpose();  // translation-invariant: subtract a corner
  for (std::size_t k = 0; k < poly.size(); ++k) {
    const Eigen::Vector3d p = V.row(poly[k]).transpose() - origin;
    const Eigen::Vector3d q = V.row(poly[(k + 1) % poly.size()]).transpose() - origin;
    sum += p.cross(q);
  }
  return sum;
}

/// True if a corner list names a vertex twice (quadratic scan: faces are small).
bool has_repeated_index(const std::vector<int>& poly) {
  if (poly.size() > 32) {  // big polygons: sort a copy instead
    std::vector<int> sorted = poly;
    std::sort(sorted.begin(), sorted.end());
    return std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end();
  }
  for (std::size_t i = 1; i < poly.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (poly[i] == poly[j]) return true;
  return false;
}

std::string join_ids(const std::vector<int>& ids) {
  std::ostringstream out;
  for (std::size_t i = 0; i < ids.size(); ++i) out << (i ? ", " : "") << ids[i];
  return out.str();
}

std::string join_pairs(const std::vector<VertexPair>& pairs) {
  std::ostringstream out;
  for (std::size_t i = 0; i < pairs.size(); ++i) out << (i ? ", " : "") << pairs[i][0] << '-' << pairs[i][1];
  return out.str();
}

template <class T>
void describe(std::vector<std::string>& lines, const Offenders<T>& offenders, const char* what,
              const char* id_kind) {
  if (offenders.empty()) return;
  std::ostringstream line;
  line << offenders.count << ' ' << what << " (first " << id_kind << ": ";
  if constexpr (std::is_same_v<T, VertexPair>)
    line << join_pairs(offenders.first);
  else
    line << join_ids(offenders.first);
  line << (offenders.count > offenders.first.size() ? ", ...)" : ")");
  lines.push_back(line.str());
}

}  // namespace

PolygonSoup to_polygon_soup(const TriangleMesh& mesh) {
  PolygonSoup soup;
  soup.V = mesh.V;
  soup.polygons.resize(static_cast<std::size_t>(mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    soup.polygons[f] = {mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
  return soup;
}

bool is_zero_area_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                           double diagonal) {
  // Plain arithmetic: this runs once per face and must stay cheap in unoptimised builds too.
  const double* pa = a.data();
  const double* pb = b.data();
  const double* pc = c.data();
  double ab[3], ac[3], bc[3];
  for (int k = 0; k < 3; ++k) {
    ab[k] = pb[k] - pa[k];
    ac[k] = pc[k] - pa[k];
    bc[k] = pc[k] - pb[k];
  }
  auto dot = [](const double* u, const double* v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
  const double longest2 = std::max({dot(ab, ab), dot(ac, ac), dot(bc, bc)});
  if (!std::isfinite(longest2)) return true;  // non-finite corners
  const double coincide = 1e-14 * diagonal;
  if (longest2 <= coincide * coincide) return true;
  const double n[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
  return std::sqrt(dot(n, n)) <= kDegenerateRelativeTolerance * longest2;
}

bool is_degenerate_triangle(const Positions& V, int a, int b, int c, double diagonal) {
  if (is_zero_area_triangle(V.row(a).transpose(), V.row(b).transpose(), V.row(c).transpose(), diagonal)) return true;
  return !triangle_inequality_holds(edge_length(V, a, b), edge_length(V, b, c), edge_length(V, c, a));
}

std::vector<std::string> ValidationReport::defects() const {
  std::vector<std::string> lines;
  describe(lines, non_triangle_faces, "non-triangle faces", "faces");
  describe(lines, out_of_range_faces, "faces with out-of-range vertex indices", "faces");
  describe(lines, repeated_index_faces, "faces with a repeated vertex index", "faces");
  describe(lines, non_finite_vertices, "vertices with non-finite coordinates", "vertices");
  describe(lines, unreferenced_vertices, "unreferenced vertices", "vertices");
  describe(lines, duplicate_faces, "duplicate faces", "faces");
  describe(lines, zero_area_faces, "zero-area faces", "faces");
  describe(lines, non_manifold_edges, "non-manifold edges", "edges");
  describe(lines, non_manifold_vertices, "non-manifold vertices", "vertices");
  describe(lines, inconsistent_edges, "inconsistently oriented edges", "edges");
  if (non_orientable_components > 0)
    lines.push_back(std::to_string(non_orientable_components) + " non-orientable components");
  return lines;
}

ValidationReport validate_mesh(const TriangleMesh& mesh) { return validate_mesh(to_polygon_soup(mesh)); }

ValidationReport validate_mesh(const PolygonSoup& soup) {
  ValidationReport r;
  const Positions& V = soup.V;
  const auto& polys = soup.polygons;
  const int nv = static_cast<int>(V.rows());
  const int nf = static_cast<int>(polys.size());
  r.n_vertices = static_cast<std::size_t>(nv);
  r.n_faces = static_cast<std::size_t>(nf);

  // Plain copies for the hot loops (Eigen element access is slow in unoptimised sanitizer builds).
  std::vector<Eigen::Vector3d> P(static_cast<std::size_t>(nv));
  std::vector<char> finite(static_cast<std::size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    P[i] = V.row(i).transpose();
    finite[i] = P[i].allFinite();
  }

  // ---- vertices: finiteness and bounding box ----
  bool any_finite = false;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (int i = 0; i < nv; ++i) {
    if (!finite[i]) {
      r.non_finite_vertices.add(i);
      continue;
    }
    any_finite = true;
    lo = lo.cwiseMin(P[i]);
    hi = hi.cwiseMax(P[i]);
  }
  if (any_finite) {
    r.bbox_min = lo;
    r.bbox_max = hi;
  }
  const double diagonal = any_finite ? (hi - lo).norm() : 0.0;

  // ---- duplicate positions (exact), finite vertices only so the sort order is strict ----
  {
    std::vector<int> order;
    order.reserve(static_cast<std::size_t>(nv));
    for (int i = 0; i < nv; ++i)
      if (finite[i]) order.push_back(i);
    auto less = [&](int a, int b) {
      for (int k = 0; k < 3; ++k)
        if (P[a][k] != P[b][k]) return P[a][k] < P[b][k];
      return a < b;
    };
    std::sort(order.begin(), order.end(), less);
    std::vector<int> dups;
    for (std::size_t i = 1; i < order.size(); ++i)
      if (P[order[i]] == P[order[i - 1]]) dups.push_back(order[i]);
    std::sort(dups.begin(), dups.end());
    for (int v : dups) r.duplicate_positions.add(v);
  }

  // ---- per-face checks; collect well-formed faces ----
  std::vector<char> well_formed(static_cast<std::size_t>(nf), 0);
  std::vector<char> referenced(static_cast<std::size_t>(nv), 0);
  for (int f = 0; f < nf; ++f) {
    const auto& poly = polys[f];
    if (poly.size() != 3) r.non_triangle_faces.add(f);
    const bool in_range = std::all_of(poly.begin(), poly.end(), [&](int v) { return v >= 0 && v < nv; });
    if (!in_range) {
      r.out_of_range_faces.add(f);
      continue;
    }
    if (has_repeated_index(poly)) {
      r.repeated_index_faces.add(f);
      continue;
    }
    if (poly.size() < 3) continue;
    well_formed[f] = 1;
    for (int v : poly) referenced[v] = 1;

    if (!std::all_of(poly.begin(), poly.end(), [&](int v) { return finite[v] != 0; }))
      continue;  // already reported through its vertices
    bool degenerate;
    if (poly.size() == 3) {
      degenerate = is_degenerate_triangle(V, poly[0], poly[1], poly[2], diagonal);
    } else {
      double longest2 = 0;
      for (std::size_t k = 0; k < poly.size(); ++k)
        longest2 = std::max(longest2, (V.row(poly[(k + 1) % poly.size()]) - V.row(poly[k])).squaredNorm());
      const double coincide = 1e-14 * diagonal;
      degenerate = longest2 <= coincide * coincide ||
                   polygon_double_area(V, poly).norm() <= kDegenerateRelativeTolerance * longest2;
    }
    if (degenerate) r.zero_area_faces.add(f);
  }
  for (int v = 0; v < nv; ++v)
    if (!referenced[v]) r.unreferenced_vertices.add(v);

  // ---- duplicate faces: same vertex set as an earlier well-formed face ----
  {
    std::vector<std::array<int, 4>> triangles;                 // sorted corners + face id
    std::vector<std::pair<std::vector<int>, int>> polygons;  // rare: faces with more corners
    for (int f = 0; f < nf; ++f) {
      if (!well_formed[f]) continue;
      if (polys[f].size() == 3) {
        std::array<int, 4> key{polys[f][0], polys[f][1], polys[f][2], f};
        std::sort(key.begin(), key.begin() + 3);
        triangles.push_back(key);
      } else {
        std::vector<int> key = polys[f];
        std::sort(key.begin(), key.end());
        polygons.emplace_back(std::move(key), f);
      }
    }
    std::sort(triangles.begin(), triangles.end());
    std::sort(polygons.begin(), polygons.end());
    std::vector<int> dups;
    for (std::size_t i = 1; i < triangles.size(); ++i)
      if (std::equal(triangles[i].begin(), triangles[i].begin() + 3, triangles[i - 1].begin()))
        dups.push_back(triangles[i][3]);
    for (std::size_t i = 1; i < polygons.size(); ++i)
      if (polygons[i].first == polygons[i - 1].first) dups.push_back(polygons[i].second);
    std::sort(dups.begin(), dups.end());
    for (int f : dups) r.duplicate_faces.add(f);
  }

  // ---- half-edges grouped by undirected edge ----
  std::vector<std::size_t> corner_offset(static_cast<std::size_t>(nf) + 1, 0);
  for (int f = 0; f < nf; ++f) corner_offset[f + 1] = corner_offset[f] + (well_formed[f] ? polys[f].size() : 0);
  const std::size_t n_corners = corner_offset[nf];
  std::vector<HalfEdgeUse> uses;
  uses.reserve(n_corners);
  for (int f = 0; f < nf; ++f) {
    if (!well_formed[f]) continue;
    const auto& poly = polys[f];
    for (std::size_t k = 0; k < poly.size(); ++k) {
      const int a = poly[k], b = poly[(k + 1) % poly.size()];
      uses.push_back({edge_key(a, b), f, static_cast<int>(k), a < b});
    }
  }
  std::sort(uses.begin(), uses.end(), [](const HalfEdgeUse& x, const HalfEdgeUse& y) {
    return x.key != y.key ? x.key < y.key : x.face < y.face;
  });

  // Corner of face f at vertex v, found by a short scan (faces are small).
  auto corner_of = [&](int f, int v) -> std::size_t {
    const auto& poly = polys[f];
    for (std::size_t k = 0; k < poly.size(); ++k)
      if (poly[k] == v) return corner_offset[f] + k;
    return corner_offset[f];  // unreachable for an edge of f
  };

  DisjointSets fans(n_corners);           // corners at one vertex linked through two-face edges
  DisjointSets boundary_graph(static_cast<std::size_t>(std::max(nv, 0)));
  std::vector<char> on_boundary(static_cast<std::size_t>(nv), 0);
  // Face graph through two-face edges: (face, other face, parity 1 if they must flip relative to each other).
  std::vector<std::array<int, 3>> links;
  std::vector<std::uint64_t> unique_edges;
  std::vector<std::uint64_t> non_manifold_edge_keys;
  double len_min = std::numeric_limits<double>::infinity(), len_max = 0, len_sum = 0;
  std::size_t len_count = 0;

  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    const std::size_t valence = j - i;
    const VertexPair ab = edge_pair(uses[i].key);
    unique_edges.push_back(uses[i].key);
    if (finite[ab[0]] && finite[ab[1]]) {
      const double len = (P[ab[0]] - P[ab[1]]).norm();
      len_min = std::min(len_min, len);
      len_max = std::max(len_max, len);
      len_sum += len;
      ++len_count;
    }
    if (valence == 1) {
      boundary_graph.unite(ab[0], ab[1]);
      on_boundary[ab[0]] = on_boundary[ab[1]] = 1;
    } else if (valence == 2) {
      const HalfEdgeUse& x = uses[i];
      const HalfEdgeUse& y = uses[i + 1];
      if (x.forward == y.forward) r.inconsistent_edges.add(ab);
      for (int v : ab) fans.unite(corner_of(x.face, v), corner_of(y.face, v));
      const int parity = x.forward == y.forward ? 1 : 0;
      links.push_back({x.face, y.face, parity});
      links.push_back({y.face, x.face, parity});
    } else {
      r.non_manifold_edges.add(ab);
      non_manifold_edge_keys.push_back(uses[i].key);
    }
    i = j;
  }
  r.n_edges = unique_edges.size();
  if (len_count > 0) {
    r.edge_length_min = len_min;
    r.edge_length_max = len_max;
    r.edge_length_mean = len_sum / static_cast<double>(len_count);
  }

  // ---- non-manifold vertices: more than one fan ----
  std::vector<int> fan_count(static_cast<std::size_t>(nv), 0);
  for (int f = 0; f < nf; ++f) {
    if (!well_formed[f]) continue;
    for (std::size_t k = 0; k < polys[f].size(); ++k) {
      const std::size_t c = corner_offset[f] + k;
      if (fans.find(c) == c) ++fan_count[polys[f][k]];
    }
  }
  std::vector<char> vertex_non_manifold(static_cast<std::size_t>(nv), 0);
  for (int v = 0; v < nv; ++v)
    if (fan_count[v] > 1) {
      r.non_manifold_vertices.add(v);
      vertex_non_manifold[v] = 1;
    }

  // ---- connected components through shared vertices ----
  DisjointSets vertex_sets(static_cast<std::size_t>(std::max(nv, 0)));
  for (int f = 0; f < nf; ++f)
    if (well_formed[f])
      for (int v : polys[f]) vertex_sets.unite(static_cast<std::size_t>(polys[f][0]), static_cast<std::size_t>(v));
  std::vector<int> component_of_root(static_cast<std::size_t>(nv), -1);
  std::vector<int> component(static_cast<std::size_t>(nv), -1);
  for (int v = 0; v < nv; ++v) {
    if (!referenced[v]) continue;
    const std::size_t root = vertex_sets.find(v);
    if (component_of_root[root] < 0) {
      component_of_root[root] = static_cast<int>(r.components.size());
      r.components.emplace_back();
    }
    component[v] = component_of_root[root];
    ++r.components[component[v]].n_vertices;
  }
  auto& comps = r.components;
  for (int f = 0; f < nf; ++f)
    if (well_formed[f]) ++comps[component[polys[f][0]]].n_faces;
  for (std::uint64_t key : unique_edges) ++comps[component[edge_pair(key)[0]]].n_edges;
  for (std::uint64_t key : non_manifold_edge_keys) comps[component[edge_pair(key)[0]]].manifold = false;
  for (int v = 0; v < nv; ++v)
    if (vertex_non_manifold[v]) comps[component[v]].manifold = false;
  for (int v = 0; v < nv; ++v)
    if (on_boundary[v] && boundary_graph.find(v) == static_cast<std::size_t>(v)) ++comps[component[v]].n_boundary_loops;
  for (std::size_t i = 0; i < uses.size();) {  // per-component consistency (offender lists are samples)
    std::size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 2 && uses[i].forward == uses[i + 1].forward)
      comps[component[polys[uses[i].face][0]]].consistently_oriented = false;
    i = j;
  }

  // ---- orientability: 2-colour the face graph of two-face edges by flip parity ----
  std::vector<std::size_t> link_offset(static_cast<std::size_t>(nf) + 1, 0);  // CSR by first face
  for (const auto& l : links) ++link_offset[l[0] + 1];
  for (int f = 0; f < nf; ++f) link_offset[f + 1] += link_offset[f];
  std::vector<std::pair<int, int>> face_links(links.size());
  {
    std::vector<std::size_t> fill(link_offset.begin(), link_offset.end() - 1);
    for (const auto& l : links) face_links[fill[l[0]]++] = {l[1], l[2]};
  }
  std::vector<int> flip(static_cast<std::size_t>(nf), -1);
  std::vector<int> stack;
  for (int seed = 0; seed < nf; ++seed) {
    if (!well_formed[seed] || flip[seed] >= 0) continue;
    flip[seed] = 0;
    stack.assign(1, seed);
    bool conflict = false;
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      for (std::size_t l = link_offset[f]; l < link_offset[f + 1]; ++l) {
        const auto [g, parity] = face_links[l];
        const int wanted = flip[f] ^ parity;
        if (flip[g] < 0) {
          flip[g] = wanted;
          stack.push_back(g);
        } else if (flip[g] != wanted) {
          conflict = true;
        }
      }
    }
    if (conflict) comps[component[polys[seed][0]]].orientable = false;
  }

  // ---- per-component Euler characteristic and genus, then sums ----
  bool all_genus_defined = !comps.empty();
  long genus_sum = 0;
  for (ComponentInfo& c : comps) {
    c.euler_characteristic = static_cast<long>(c.n_vertices) - static_cast<long>(c.n_edges) +
                             static_cast<long>(c.n_faces);
    if (!c.orientable) ++r.non_orientable_components;
    const long twice_genus = 2 - c.euler_characteristic - static_cast<long>(c.n_boundary_loops);
    if (c.manifold && c.orientable && twice_genus >= 0 && twice_genus % 2 == 0)
      c.genus = static_cast<int>(twice_genus / 2);
    else
      all_genus_defined = false;
    r.euler_characteristic += c.euler_characteristic;
    r.n_boundary_loops += c.n_boundary_loops;
    genus_sum += std::max(c.genus, 0);
  }
  r.genus = all_genus_defined ? static_cast<int>(genus_sum) : -1;
  return r;
}

}  // namespace ice
