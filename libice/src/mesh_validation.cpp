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
#include <sstream>
#include <thread>
#include <type_traits>

namespace ice {

namespace {

using detail::DisjointSets;

/// Twice the vector area of a polygon (Newell's formula), for faces with more than three corners.
Eigen::Vector3d polygon_double_area(const Positions& V, PolygonList::Corners<const Index> poly) {
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
bool has_repeated_index(PolygonList::Corners<const Index> poly) {
  if (poly.size() > 32) {  // big polygons: sort a copy instead
    std::vector<int> sorted = poly.to_vector();
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
  std::vector<Index> corners(3 * static_cast<std::size_t>(mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) corners[3 * static_cast<std::size_t>(f) + k] = mesh.F(f, k);
  soup.polygons = PolygonList::triangles(std::move(corners));
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

bool ValidationReport::clean_but_for_sheets() const {
  return non_triangle_faces.empty() && out_of_range_faces.empty() && repeated_index_faces.empty() &&
         non_finite_vertices.empty() && unreferenced_vertices.empty() && duplicate_faces.empty() && zero_area_faces.empty();
}

ValidationReport validate_mesh(const TriangleMesh& mesh) { return validate_mesh(to_polygon_soup(mesh)); }

namespace {

// ---- the stages of validate_mesh ----------------------------------------------------------------

// Soups of at least this many faces are validated on several threads (below it, starting a thread
// costs more than the work it takes over), in a fixed number of tasks, so that the report (even the
// rounding of the edge-length mean's partial sums) does not depend on the thread count.
constexpr int kParallelValidationFaces = 100000;
constexpr int kValidationTasks = 16;

int validation_threads(int faces) {
  if (faces < kParallelValidationFaces) return 1;
  return std::clamp(detail::available_threads(), 2, 8);
}

// What the stages share: the soup and what earlier stages found about it.
struct SoupScan {
  SoupScan(const PolygonSoup& soup)
      : V(soup.V), polys(soup.polygons), nv(static_cast<int>(soup.V.rows())), nf(static_cast<int>(soup.polygons.size())) {}
  const Positions& V;
  const PolygonList& polys;
  const int nv, nf;
  // Plain copies for the hot loops (Eigen element access is slow in unoptimised sanitizer builds).
  std::vector<Eigen::Vector3d> P;
  std::vector<char> finite;
  double diagonal = 0;
  std::vector<char> well_formed, referenced;
  // Each well-formed face's first corner, and the corners grouped by vertex (CSR: the faces of each
  // vertex's star in increasing order).
  std::vector<std::size_t> corner_offset, star_offset;
  std::vector<int> star_face;
  const int* triangles = nullptr;  // the corner array when every face is a well-formed triangle
  // What each vertex's star scan found (VertexFlag bits) and how many edges it owns.
  std::vector<unsigned char> vertex_flags;
  std::vector<int> owned_edges;
  std::vector<VertexPair> boundary_edges;
  std::vector<std::size_t> corner_fan;  // each corner's fan (its smallest corner), corner_offset numbering; filled when sized
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

// Per-face checks (size, indices, repeats, zero area); marks the well-formed faces.
// The offenders of faces [begin, end) (one range of scan_faces).
struct FaceFindings {
  Offenders<int> non_triangle_faces, out_of_range_faces, repeated_index_faces, zero_area_faces;
};

void scan_face_range(SoupScan& s, int begin, int end, FaceFindings& r) {
  for (int f = begin; f < end; ++f) {
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
}

template <class T>
void append(Offenders<T>& to, const Offenders<T>& from) {
  for (const T& element : from.first)
    if (to.first.size() < kMaxOffenders) to.first.push_back(element);
  to.count += from.count;
}

// Per-face checks in face ranges on `threads` threads, merged in face order.
void scan_faces(SoupScan& s, ValidationReport& r, int threads) {
  s.well_formed.assign(static_cast<std::size_t>(s.nf), 0);
  const int tasks = threads > 1 ? kValidationTasks : 1;
  std::vector<FaceFindings> parts(static_cast<std::size_t>(tasks));
  const auto bound = [&](int t) { return static_cast<int>(static_cast<long long>(s.nf) * t / tasks); };
  detail::run_tasks(threads, tasks, [&](int t) { scan_face_range(s, bound(t), bound(t + 1), parts[t]); });
  for (const FaceFindings& part : parts) {
    append(r.non_triangle_faces, part.non_triangle_faces);
    append(r.out_of_range_faces, part.out_of_range_faces);
    append(r.repeated_index_faces, part.repeated_index_faces);
    append(r.zero_area_faces, part.zero_area_faces);
  }
}

// Faces with the same vertex set as an earlier well-formed face.
void find_duplicate_faces(const SoupScan& s, ValidationReport& r) {
  for (int f : detail::later_duplicate_faces(s.polys, s.well_formed, s.nv)) r.duplicate_faces.add(f);
}

// The corners of the well-formed faces grouped by vertex (each vertex's star), faces in increasing
// order; corners are numbered face by face (corner_offset). Referenced vertices are those with a star.
void group_corners_by_vertex(SoupScan& s, int threads) {
  const auto& polys = s.polys;
  const int nv = s.nv, nf = s.nf;
  s.corner_offset.assign(static_cast<std::size_t>(nf) + 1, 0);
  for (int f = 0; f < nf; ++f) s.corner_offset[f + 1] = s.corner_offset[f] + (s.well_formed[f] ? polys[f].size() : 0);
  // A counting sort of the corners by vertex; with threads each takes a range of vertices (and
  // reads every face, which is cheap beside the scattered writes it shares out).
  s.star_offset.assign(static_cast<std::size_t>(nv) + 1, 0);
  const auto vertex_bound = [&](int t) { return static_cast<int>(static_cast<long long>(nv) * t / threads); };
  const auto for_each_corner = [&](int t, auto&& visit) {
    const int lo = vertex_bound(t), hi = vertex_bound(t + 1);
    for (int f = 0; f < nf; ++f)
      if (s.well_formed[f])
        for (int v : polys[f])
          if (v >= lo && v < hi) visit(f, v);
  };
  detail::run_tasks(threads, threads, [&](int t) {
    for_each_corner(t, [&](int, int v) { ++s.star_offset[static_cast<std::size_t>(v) + 1]; });
  });
  for (int v = 0; v < nv; ++v) s.star_offset[v + 1] += s.star_offset[v];
  s.star_face.resize(s.star_offset[nv]);
  std::vector<std::size_t> fill(s.star_offset.begin(), s.star_offset.end() - 1);
  detail::run_tasks(threads, threads, [&](int t) {
    for_each_corner(t, [&](int f, int v) { s.star_face[fill[v]++] = f; });
  });
  s.referenced.resize(static_cast<std::size_t>(nv));
  for (int v = 0; v < nv; ++v) s.referenced[v] = s.star_offset[v + 1] > s.star_offset[v];
  // Every face a well-formed triangle: faces are read straight from the corner array.
  const std::vector<std::size_t>& offsets = polys.offsets();
  bool triangles = s.corner_offset[nf] == 3 * static_cast<std::size_t>(nf);  // all well formed, if all have 3 corners
  for (int f = 0; triangles && f < nf; ++f) triangles = offsets[f + 1] - offsets[f] == 3;
  if (triangles) s.triangles = polys.corners().data();
}

void find_unreferenced_vertices(const SoupScan& s, ValidationReport& r) {
  for (int v = 0; v < s.nv; ++v)
    if (!s.referenced[v]) r.unreferenced_vertices.add(v);
}

// What one range of vertices found about the edges it owns (an edge is owned by its smaller vertex,
// so every edge is seen once and the offenders come in (smaller, larger) order, range by range).
struct StarFindings {
  Offenders<VertexPair> non_manifold_edges, inconsistent_edges;
  Offenders<int> non_manifold_vertices;
  std::size_t n_edges = 0, length_count = 0;
  double length_min = std::numeric_limits<double>::infinity(), length_max = 0, length_sum = 0;
  std::vector<VertexPair> boundary_edges;
  std::vector<std::array<int, 3>> links;  // (face, other face, parity), only when asked
};

// Bits of SoupScan::vertex_flags, each written only by the vertex's own range.
enum VertexFlag : unsigned char {
  kOnBoundary = 1,          // has an edge with one face
  kNonManifoldVertex = 2,   // its faces form more than one fan
  kOwnsNonManifoldEdge = 4, // the smaller end of an edge with more than two faces
  kOwnsInconsistentEdge = 8 // the smaller end of an inconsistently oriented edge
};

// One vertex star at a time: every edge at v is a run of equal neighbours among v's corners (a face
// uses the edge {v, u} through exactly one corner at v, as its next or previous corner), so the
// run's length is the edge's face count; corners of a two-face edge's faces are in one fan. Local
// to the star, hence cache-friendly and split over threads by vertex ranges.
void scan_stars(SoupScan& s, int begin, int end, StarFindings& out, bool want_links) {
  // One use of an edge at v packed for sorting: neighbour (high 32 bits), the corner's index in the
  // star, and whether the face runs v -> neighbour (lowest bit).
  std::vector<std::uint64_t> uses;
  const auto neighbour_of = [](std::uint64_t use) { return static_cast<int>(use >> 32); };
  const auto corner_of = [](std::uint64_t use) { return static_cast<int>((use & 0xffffffffu) >> 1); };
  const auto outgoing = [](std::uint64_t use) { return (use & 1u) != 0; };
  DisjointSets fans(0);  // the star's corners, joined across its two-face edges
  std::vector<std::size_t> corner_id;
  for (int v = begin; v < end; ++v) {
    const std::size_t star_begin = s.star_offset[v];
    const int m = static_cast<int>(s.star_offset[v + 1] - star_begin);
    if (m == 0) continue;
    uses.clear();
    corner_id.resize(static_cast<std::size_t>(m));
    for (int i = 0; i < m; ++i) {
      const int f = s.star_face[star_begin + i];
      const auto pack = [&](int neighbour, bool out) {
        return (static_cast<std::uint64_t>(neighbour) << 32) | (static_cast<std::uint64_t>(i) << 1) | (out ? 1u : 0u);
      };
      if (s.triangles) {  // the common case: one cache line per face, corner ids 3f + k
        const int* t = s.triangles + 3 * static_cast<std::size_t>(f);
        const int k = t[0] == v ? 0 : t[1] == v ? 1 : 2;
        corner_id[i] = 3 * static_cast<std::size_t>(f) + static_cast<std::size_t>(k);
        uses.push_back(pack(t[k == 2 ? 0 : k + 1], true));
        uses.push_back(pack(t[k == 0 ? 2 : k - 1], false));
        continue;
      }
      const auto& poly = s.polys[f];
      const std::size_t n = poly.size();
      std::size_t k = 0;
      while (poly[k] != v) ++k;
      corner_id[i] = s.corner_offset[f] + k;
      uses.push_back(pack(poly[(k + 1) % n], true));
      uses.push_back(pack(poly[(k + n - 1) % n], false));
    }
    if (uses.size() > 32) {
      std::sort(uses.begin(), uses.end());
    } else {
      for (std::size_t i = 1; i < uses.size(); ++i) {
        const std::uint64_t use = uses[i];
        std::size_t j = i;
        for (; j > 0 && use < uses[j - 1]; --j) uses[j] = uses[j - 1];
        uses[j] = use;
      }
    }
    fans.reset(static_cast<std::size_t>(m));
    unsigned char flags = 0;
    for (std::size_t i = 0; i < uses.size();) {
      std::size_t j = i;
      const int u = neighbour_of(uses[i]);
      while (j < uses.size() && neighbour_of(uses[j]) == u) ++j;
      const std::size_t valence = j - i;
      const bool owner = u > v;
      if (valence == 1) flags |= kOnBoundary;
      if (valence == 2) {
        fans.unite(static_cast<std::size_t>(corner_of(uses[i])), static_cast<std::size_t>(corner_of(uses[i + 1])));
      }
      if (owner) {
        const VertexPair edge{v, u};
        ++out.n_edges;
        ++s.owned_edges[v];
        if (s.finite[v] && s.finite[u]) {
          const double length = (s.P[v] - s.P[u]).norm();
          out.length_min = std::min(out.length_min, length);
          out.length_max = std::max(out.length_max, length);
          out.length_sum += length;
          ++out.length_count;
        }
        if (valence == 1) {
          out.boundary_edges.push_back(edge);
        } else if (valence == 2) {
          const bool same_direction = outgoing(uses[i]) == outgoing(uses[i + 1]);
          if (same_direction) {
            out.inconsistent_edges.add(edge);
            flags |= kOwnsInconsistentEdge;
          }
          if (want_links) {
            const int f = s.star_face[star_begin + corner_of(uses[i])];
            const int g = s.star_face[star_begin + corner_of(uses[i + 1])];
            out.links.push_back({f, g, same_direction ? 1 : 0});
            out.links.push_back({g, f, same_direction ? 1 : 0});
          }
        } else {
          out.non_manifold_edges.add(edge);
          flags |= kOwnsNonManifoldEdge;
        }
      }
      i = j;
    }
    std::size_t fan_count = 0;
    for (std::size_t i = 0; i < static_cast<std::size_t>(m); ++i) fan_count += fans.find(i) == i;
    if (fan_count > 1) {
      out.non_manifold_vertices.add(v);
      flags |= kNonManifoldVertex;
    }
    s.vertex_flags[v] = flags;
    if (!s.corner_fan.empty())  // a fan is named by its smallest corner: the root's (roots are minima)
      for (std::size_t i = 0; i < static_cast<std::size_t>(m); ++i) s.corner_fan[corner_id[i]] = corner_id[fans.find(i)];
  }
}

// Vertex ranges [bounds[t], bounds[t+1]) of about equal corner counts, for `tasks` tasks.
std::vector<int> star_ranges(const SoupScan& s, int tasks) {
  std::vector<int> bounds{0};
  const std::size_t corners = s.star_offset[s.nv];
  for (int t = 1; t < tasks; ++t) {
    const std::size_t wanted = corners * static_cast<std::size_t>(t) / static_cast<std::size_t>(tasks);
    const auto it = std::lower_bound(s.star_offset.begin(), s.star_offset.end(), wanted);
    const auto vertex = static_cast<int>(std::min<std::ptrdiff_t>(it - s.star_offset.begin(), s.nv));
    bounds.push_back(std::max(bounds.back(), vertex));
  }
  bounds.push_back(s.nv);
  return bounds;
}

// The ranges' findings in vertex order, into the report (and the boundary edges and links into the scan).
void report_edges(SoupScan& s, std::vector<StarFindings>& parts, ValidationReport& r) {
  std::size_t length_count = 0;
  double length_min = std::numeric_limits<double>::infinity(), length_max = 0, length_sum = 0;
  s.boundary_edges.clear();
  s.links.clear();
  r.n_edges = 0;
  r.non_manifold_edges = {};
  r.inconsistent_edges = {};
  r.non_manifold_vertices = {};
  for (const StarFindings& part : parts) {
    append(r.non_manifold_edges, part.non_manifold_edges);
    append(r.inconsistent_edges, part.inconsistent_edges);
    append(r.non_manifold_vertices, part.non_manifold_vertices);
    r.n_edges += part.n_edges;
    length_count += part.length_count;
    length_min = std::min(length_min, part.length_min);
    length_max = std::max(length_max, part.length_max);
    length_sum += part.length_sum;
    s.boundary_edges.insert(s.boundary_edges.end(), part.boundary_edges.begin(), part.boundary_edges.end());
    s.links.insert(s.links.end(), part.links.begin(), part.links.end());
  }
  if (length_count > 0) {
    r.edge_length_min = length_min;
    r.edge_length_max = length_max;
    r.edge_length_mean = length_sum / static_cast<double>(length_count);
  }
}

// Edges (their faces: boundary, two, more; orientation agreement; lengths) and the fans around each
// vertex (the non-manifold vertices), star by star in `tasks()` vertex ranges that may run beside
// other work; with `want_links` also the face graph for the orientability check.
class EdgeScan {
 public:
  EdgeScan(SoupScan& s, int threads, bool want_links) : s_(s), want_links_(want_links) {
    s.vertex_flags.assign(static_cast<std::size_t>(s.nv), 0);
    s.owned_edges.assign(static_cast<std::size_t>(s.nv), 0);
    bounds_ = star_ranges(s, threads > 1 ? kValidationTasks : 1);
    parts_.resize(bounds_.size() - 1);
  }
  int tasks() const { return static_cast<int>(parts_.size()); }
  void run(int task) { scan_stars(s_, bounds_[task], bounds_[task + 1], parts_[task], want_links_); }
  void report(ValidationReport& r) { report_edges(s_, parts_, r); }

 private:
  SoupScan& s_;
  bool want_links_;
  std::vector<int> bounds_;
  std::vector<StarFindings> parts_;
};

void scan_edges(SoupScan& s, ValidationReport& r, int threads, bool want_links) {
  EdgeScan scan(s, threads, want_links);
  detail::run_tasks(threads, scan.tasks(), [&](int task) { scan.run(task); });
  scan.report(r);
}

// Connected components through shared vertices, with their vertex and face counts.
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
  for (int f = 0; f < nf; ++f)
    if (s.well_formed[f]) ++r.components[s.component[polys[f][0]]].n_faces;
}

// What the star scans found, per component: edge counts, manifoldness, orientation consistency,
// boundary loops.
void summarise_components(const SoupScan& s, ValidationReport& r) {
  const int nv = s.nv;
  auto& comps = r.components;
  const std::vector<int>& component = s.component;
  for (int v = 0; v < nv; ++v) {
    if (!s.referenced[v]) continue;
    ComponentInfo& c = comps[component[v]];
    c.n_edges += static_cast<std::size_t>(s.owned_edges[v]);
    if (s.vertex_flags[v] & (kNonManifoldVertex | kOwnsNonManifoldEdge)) c.manifold = false;
    if (s.vertex_flags[v] & kOwnsInconsistentEdge) c.consistently_oriented = false;
  }
  // Boundary loops: the boundary edges' connected pieces (one root per loop).
  DisjointSets boundary_graph(static_cast<std::size_t>(std::max(nv, 0)));
  for (const VertexPair& edge : s.boundary_edges) boundary_graph.unite(edge[0], edge[1]);
  for (int v = 0; v < nv; ++v)
    if ((s.vertex_flags[v] & kOnBoundary) && boundary_graph.find(v) == static_cast<std::size_t>(v))
      ++comps[component[v]].n_boundary_loops;
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
  scan_faces(s, unused, 1);
  group_corners_by_vertex(s, 1);
  s.corner_fan.resize(s.corner_offset[s.nf]);
  scan_edges(s, unused, 1, false);
  return std::move(s.corner_fan);
}

ValidationReport validate_mesh(const PolygonSoup& soup) {
  ValidationReport r;
  SoupScan s(soup);
  r.n_vertices = static_cast<std::size_t>(s.nv);
  r.n_faces = static_cast<std::size_t>(s.nf);
  const int threads = validation_threads(s.nf);
  // The stages fill disjoint fields of the report. The exact-duplicate searches (a hash table, a
  // counting sort) and the components run as tasks beside the edge scan's vertex ranges, which the
  // threads take as they come free.
  scan_vertices(s, r);
  scan_faces(s, r, threads);
  group_corners_by_vertex(s, threads);
  find_unreferenced_vertices(s, r);
  EdgeScan edges(s, threads, false);
  detail::run_tasks(threads, 2 + edges.tasks(), [&](int task) {
    if (task == 0) {
      find_duplicate_positions(s, r);
      find_duplicate_faces(s, r);
    } else if (task == 1) {
      find_components(s, r);
    } else {
      edges.run(task - 2);
    }
  });
  edges.report(r);
  summarise_components(s, r);
  // All two-face edges consistently oriented proves every component orientable; only a soup with
  // an inconsistent edge needs the face graph's 2-colouring.
  if (!r.inconsistent_edges.empty()) {
    scan_edges(s, r, threads, true);
    check_orientability(s, r);
  }
  sum_topology(r);
  return r;
}

}  // namespace ice
