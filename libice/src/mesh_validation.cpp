#include "ice/mesh_validation.h"
#include "ice/triangle_geometry.h"

#include "corner_fans.h"
#include "run_tasks.h"
#include "soup_duplicates.h"
#include "vertex_buckets.h"
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

namespace {

// ---- the stages of validate_mesh ----------------------------------------------------------------

// Soups of at least this many faces are validated on two threads (below it, starting a thread
// costs more than the work it takes over).
constexpr int kParallelValidationFaces = 100000;

// What the stages share: the soup and what earlier stages found about it.
struct SoupScan {
  SoupScan(const PolygonSoup& soup)
      : V(soup.V), polys(soup.polygons), nv(static_cast<int>(soup.V.rows())), nf(static_cast<int>(soup.polygons.size())) {}
  const Positions& V;
  const std::vector<std::vector<int>>& polys;
  const int nv, nf;
  // Plain copies for the hot loops (Eigen element access is slow in unoptimised sanitizer builds).
  std::vector<Eigen::Vector3d> P;
  std::vector<char> finite;
  double diagonal = 0;
  std::vector<char> well_formed, referenced;
  // Half-edges grouped by undirected edge, and each well-formed face's first corner.
  std::vector<std::size_t> corner_offset;
  std::vector<HalfEdgeUse> uses;
  std::vector<char> on_boundary, vertex_non_manifold;
  std::vector<std::size_t> corner_fan;  // each corner's fan (its smallest corner), corner_offset numbering
  std::vector<std::uint64_t> unique_edges, non_manifold_edge_keys;
  // Face graph through two-face edges: (face, other face, parity 1 if they must flip relative to each other).
  std::vector<std::array<int, 3>> links;
  std::vector<int> component;  // of each referenced vertex
};

// Finiteness and bounding box; the diagonal scales the degeneracy tests.
void scan_vertices(SoupScan& s, ValidationReport& r) {
  s.P.resize(static_cast<std::size_t>(s.nv));
  s.finite.resize(static_cast<std::size_t>(s.nv));
  for (int i = 0; i < s.nv; ++i) {
    s.P[i] = s.V.row(i).transpose();
    s.finite[i] = s.P[i].allFinite();
  }
  bool any_finite = false;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (int i = 0; i < s.nv; ++i) {
    if (!s.finite[i]) {
      r.non_finite_vertices.add(i);
      continue;
    }
    any_finite = true;
    lo = lo.cwiseMin(s.P[i]);
    hi = hi.cwiseMax(s.P[i]);
  }
  if (any_finite) {
    r.bbox_min = lo;
    r.bbox_max = hi;
  }
  s.diagonal = any_finite ? (hi - lo).norm() : 0.0;
}

// Exactly coincident positions (finite vertices only): every vertex but the smallest of a group.
void find_duplicate_positions(const SoupScan& s, ValidationReport& r) {
  const std::vector<int> first = detail::first_coincident_vertex(s.V);
  for (int v = 0; v < s.nv; ++v)
    if (first[v] != v) r.duplicate_positions.add(v);
}

// Per-face checks (size, indices, repeats, zero area); marks well-formed faces and referenced vertices.
void scan_faces(SoupScan& s, ValidationReport& r) {
  s.well_formed.assign(static_cast<std::size_t>(s.nf), 0);
  s.referenced.assign(static_cast<std::size_t>(s.nv), 0);
  for (int f = 0; f < s.nf; ++f) {
    const auto& poly = s.polys[f];
    if (poly.size() != 3) r.non_triangle_faces.add(f);
    const bool in_range = std::all_of(poly.begin(), poly.end(), [&](int v) { return v >= 0 && v < s.nv; });
    if (!in_range) {
      r.out_of_range_faces.add(f);
      continue;
    }
    if (has_repeated_index(poly)) {
      r.repeated_index_faces.add(f);
      continue;
    }
    if (poly.size() < 3) continue;
    s.well_formed[f] = 1;
    for (int v : poly) s.referenced[v] = 1;

    if (!std::all_of(poly.begin(), poly.end(), [&](int v) { return s.finite[v] != 0; }))
      continue;  // already reported through its vertices
    bool degenerate;
    if (poly.size() == 3) {
      degenerate = is_degenerate_triangle(s.V, poly[0], poly[1], poly[2], s.diagonal);
    } else {
      double longest2 = 0;
      for (std::size_t k = 0; k < poly.size(); ++k)
        longest2 = std::max(longest2, (s.V.row(poly[(k + 1) % poly.size()]) - s.V.row(poly[k])).squaredNorm());
      const double coincide = 1e-14 * s.diagonal;
      degenerate = longest2 <= coincide * coincide ||
                   polygon_double_area(s.V, poly).norm() <= kDegenerateRelativeTolerance * longest2;
    }
    if (degenerate) r.zero_area_faces.add(f);
  }
  for (int v = 0; v < s.nv; ++v)
    if (!s.referenced[v]) r.unreferenced_vertices.add(v);
}

// Faces with the same vertex set as an earlier well-formed face.
void find_duplicate_faces(const SoupScan& s, ValidationReport& r) {
  for (int f : detail::later_duplicate_faces(s.polys, s.well_formed, s.nv)) r.duplicate_faces.add(f);
}

// Edges: their faces (boundary, two, more), orientation agreement, lengths; the fans around each
// vertex (corners linked through two-face edges) give the non-manifold vertices.
void scan_edges(SoupScan& s, ValidationReport& r) {
  const auto& polys = s.polys;
  const int nv = s.nv, nf = s.nf;
  s.corner_offset.assign(static_cast<std::size_t>(nf) + 1, 0);
  for (int f = 0; f < nf; ++f) s.corner_offset[f + 1] = s.corner_offset[f] + (s.well_formed[f] ? polys[f].size() : 0);
  const std::size_t n_corners = s.corner_offset[nf];
  std::vector<HalfEdgeUse>& uses = s.uses;
  uses.reserve(n_corners);
  for (int f = 0; f < nf; ++f) {
    if (!s.well_formed[f]) continue;
    const auto& poly = polys[f];
    for (std::size_t k = 0; k < poly.size(); ++k) {
      const int a = poly[k], b = poly[(k + 1) % poly.size()];
      uses.push_back({edge_key(a, b), f, static_cast<int>(k), a < b});
    }
  }
  // By (key, face): the uses were made face by face, so a stable order by the smaller vertex, then
  // by the larger one within it, is that order.
  detail::sort_by_vertex(
      uses, nv, [](const HalfEdgeUse& use) { return static_cast<Index>(use.key >> 32); },
      [](const HalfEdgeUse& x, const HalfEdgeUse& y) { return (x.key & 0xffffffffu) < (y.key & 0xffffffffu); });

  // The corners of a use's face at the edge's smaller and larger vertex: the use runs from its
  // corner to the next one, from the smaller vertex to the larger when `forward`.
  const auto corners_of = [&](const HalfEdgeUse& use) -> std::array<std::size_t, 2> {
    const std::size_t begin = s.corner_offset[use.face], size = s.corner_offset[use.face + 1] - begin;
    const std::size_t tail = begin + static_cast<std::size_t>(use.corner);
    const std::size_t head = begin + (static_cast<std::size_t>(use.corner) + 1) % size;
    return use.forward ? std::array<std::size_t, 2>{tail, head} : std::array<std::size_t, 2>{head, tail};
  };

  s.unique_edges.reserve(uses.size() / 2 + 1);
  s.links.reserve(uses.size());
  DisjointSets fans(n_corners);  // corners at one vertex linked through two-face edges
  s.on_boundary.assign(static_cast<std::size_t>(nv), 0);
  double len_min = std::numeric_limits<double>::infinity(), len_max = 0, len_sum = 0;
  std::size_t len_count = 0;
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    const std::size_t valence = j - i;
    const VertexPair ab = edge_pair(uses[i].key);
    s.unique_edges.push_back(uses[i].key);
    if (s.finite[ab[0]] && s.finite[ab[1]]) {
      const double len = (s.P[ab[0]] - s.P[ab[1]]).norm();
      len_min = std::min(len_min, len);
      len_max = std::max(len_max, len);
      len_sum += len;
      ++len_count;
    }
    if (valence == 1) {
      s.on_boundary[ab[0]] = s.on_boundary[ab[1]] = 1;
    } else if (valence == 2) {
      const HalfEdgeUse& x = uses[i];
      const HalfEdgeUse& y = uses[i + 1];
      if (x.forward == y.forward) r.inconsistent_edges.add(ab);
      const auto cx = corners_of(x), cy = corners_of(y);
      fans.unite(cx[0], cy[0]);  // the corners at the smaller vertex
      fans.unite(cx[1], cy[1]);  // and at the larger
      const int parity = x.forward == y.forward ? 1 : 0;
      s.links.push_back({x.face, y.face, parity});
      s.links.push_back({y.face, x.face, parity});
    } else {
      r.non_manifold_edges.add(ab);
      s.non_manifold_edge_keys.push_back(uses[i].key);
    }
    i = j;
  }
  r.n_edges = s.unique_edges.size();
  if (len_count > 0) {
    r.edge_length_min = len_min;
    r.edge_length_max = len_max;
    r.edge_length_mean = len_sum / static_cast<double>(len_count);
  }

  // Non-manifold vertices: more than one fan.
  s.corner_fan.resize(n_corners);
  std::vector<int> fan_count(static_cast<std::size_t>(nv), 0);
  for (int f = 0; f < nf; ++f) {
    if (!s.well_formed[f]) continue;
    for (std::size_t k = 0; k < polys[f].size(); ++k) {
      const std::size_t c = s.corner_offset[f] + k;
      s.corner_fan[c] = fans.find(c);
      if (s.corner_fan[c] == c) ++fan_count[polys[f][k]];
    }
  }
  s.vertex_non_manifold.assign(static_cast<std::size_t>(nv), 0);
  for (int v = 0; v < nv; ++v)
    if (fan_count[v] > 1) {
      r.non_manifold_vertices.add(v);
      s.vertex_non_manifold[v] = 1;
    }
}

// Connected components through shared vertices, with their sizes, boundary loops, manifoldness and
// orientation consistency.
void find_components(SoupScan& s, ValidationReport& r) {
  const auto& polys = s.polys;
  const int nv = s.nv, nf = s.nf;
  DisjointSets vertex_sets(static_cast<std::size_t>(std::max(nv, 0)));
  for (int f = 0; f < nf; ++f)
    if (s.well_formed[f])
      for (int v : polys[f]) vertex_sets.unite(static_cast<std::size_t>(polys[f][0]), static_cast<std::size_t>(v));
  std::vector<int> component_of_root(static_cast<std::size_t>(nv), -1);
  s.component.assign(static_cast<std::size_t>(nv), -1);
  for (int v = 0; v < nv; ++v) {
    if (!s.referenced[v]) continue;
    const std::size_t root = vertex_sets.find(v);
    if (component_of_root[root] < 0) {
      component_of_root[root] = static_cast<int>(r.components.size());
      r.components.emplace_back();
    }
    s.component[v] = component_of_root[root];
    ++r.components[s.component[v]].n_vertices;
  }
  auto& comps = r.components;
  const std::vector<int>& component = s.component;
  for (int f = 0; f < nf; ++f)
    if (s.well_formed[f]) ++comps[component[polys[f][0]]].n_faces;
  for (std::uint64_t key : s.unique_edges) ++comps[component[edge_pair(key)[0]]].n_edges;
  for (std::uint64_t key : s.non_manifold_edge_keys) comps[component[edge_pair(key)[0]]].manifold = false;
  for (int v = 0; v < nv; ++v)
    if (s.vertex_non_manifold[v]) comps[component[v]].manifold = false;
  // Boundary loops: the boundary edges' connected pieces (one root per loop).
  DisjointSets boundary_graph(static_cast<std::size_t>(std::max(nv, 0)));
  for (std::size_t i = 0; i < s.uses.size();) {
    std::size_t j = i;
    while (j < s.uses.size() && s.uses[j].key == s.uses[i].key) ++j;
    if (j - i == 1) {
      const VertexPair ab = edge_pair(s.uses[i].key);
      boundary_graph.unite(ab[0], ab[1]);
    }
    if (j - i == 2 && s.uses[i].forward == s.uses[i + 1].forward)  // per-component consistency
      comps[component[polys[s.uses[i].face][0]]].consistently_oriented = false;
    i = j;
  }
  for (int v = 0; v < nv; ++v)
    if (s.on_boundary[v] && boundary_graph.find(v) == static_cast<std::size_t>(v)) ++comps[component[v]].n_boundary_loops;
}

// Orientability: 2-colour the face graph of two-face edges by flip parity; a conflict makes the
// component non-orientable.
void check_orientability(const SoupScan& s, ValidationReport& r) {
  const int nf = s.nf;
  std::vector<std::size_t> link_offset(static_cast<std::size_t>(nf) + 1, 0);  // CSR by first face
  for (const auto& l : s.links) ++link_offset[l[0] + 1];
  for (int f = 0; f < nf; ++f) link_offset[f + 1] += link_offset[f];
  std::vector<std::pair<int, int>> face_links(s.links.size());
  {
    std::vector<std::size_t> fill(link_offset.begin(), link_offset.end() - 1);
    for (const auto& l : s.links) face_links[fill[l[0]]++] = {l[1], l[2]};
  }
  std::vector<int> flip(static_cast<std::size_t>(nf), -1);
  std::vector<int> stack;
  for (int seed = 0; seed < nf; ++seed) {
    if (!s.well_formed[seed] || flip[seed] >= 0) continue;
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
    if (conflict) r.components[s.component[s.polys[seed][0]]].orientable = false;
  }
}

// Per-component Euler characteristic and genus, then the sums.
void sum_topology(ValidationReport& r) {
  bool all_genus_defined = !r.components.empty();
  long genus_sum = 0;
  for (ComponentInfo& c : r.components) {
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
}

}  // namespace

std::vector<std::size_t> detail::corner_fans(const PolygonSoup& soup) {
  ValidationReport unused;
  SoupScan s(soup);
  scan_vertices(s, unused);
  scan_faces(s, unused);
  scan_edges(s, unused);
  return std::move(s.corner_fan);
}

ValidationReport validate_mesh(const PolygonSoup& soup) {
  ValidationReport r;
  SoupScan s(soup);
  r.n_vertices = static_cast<std::size_t>(s.nv);
  r.n_faces = static_cast<std::size_t>(s.nf);
  scan_vertices(s, r);
  scan_faces(s, r);
  // The exact-duplicate searches (two sorts) need only the positions and the well-formed faces and
  // fill their own fields of the report: on large soups they run on a second thread beside the
  // edge, component and orientation stages (1.6M vertices: about a third of the validation).
  const auto stage = [&](int task) {
    if (task == 0) {
      find_duplicate_positions(s, r);
      find_duplicate_faces(s, r);
    } else {
      scan_edges(s, r);
      find_components(s, r);
      check_orientability(s, r);
    }
  };
  const int threads = s.nf >= kParallelValidationFaces ? 2 : 1;
  detail::run_tasks(threads, 2, stage);
  sum_topology(r);
  return r;
}

}  // namespace ice
