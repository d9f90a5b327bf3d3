// QEM baseline: OpenMesh Decimater + ModQuadric, closest-point map through an AABB tree. See qem.h.
#include "ice/qem.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "ice/triangle_geometry.h"
#include "ice/wall_time.h"

// OpenMesh's PropertyT<VectorT>::push_back value-initialises a VectorT whose constructor leaves it
// uninitialised, which GCC reports (at the instantiation in this file) as -Wmaybe-uninitialized.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// OpenMesh's headers are read with their assertions off in every build: each property access
// asserts its type by building and comparing type-name strings, most of the Decimater's time in
// assertion-enabled (sanitizer) builds (docs/measurements.md, "The test command's time"); the
// handles here are typed, so that check cannot fail. This file's own assertions are restored below.
#ifndef NDEBUG
#define ICE_QEM_ASSERTIONS_ON
#define NDEBUG
#include <cassert>
#endif
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModAspectRatioT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>
#ifdef ICE_QEM_ASSERTIONS_ON
#undef NDEBUG
#undef ICE_QEM_ASSERTIONS_ON
#include <cassert>
#endif

namespace ice {

namespace {

struct DoubleTraits : public OpenMesh::DefaultTraits {
  typedef OpenMesh::Vec3d Point;
  typedef OpenMesh::Vec3d Normal;
};
using OmMesh = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;
using Decimater = OpenMesh::Decimater::DecimaterT<OmMesh>;
using ModQuadric = OpenMesh::Decimater::ModQuadricT<OmMesh>;
using ModNormalFlipping = OpenMesh::Decimater::ModNormalFlippingT<OmMesh>;
using ModAspectRatio = OpenMesh::Decimater::ModAspectRatioT<OmMesh>;

// Collapses that would make a face with longest edge² / (2·area) above this are illegal. Halfedge
// collapses keep input positions, so two coincident input vertices (65 in CGAL's
// elephant-with-holes) could meet in one face with a zero-length edge: a coarse mesh no triangulation
// can be built from. At 1e6 a face's lengths still carry its shape (height/longest ≥ 1e-6, far above
// what the strict triangle inequality in double precision needs).
constexpr float kMaxCollapseAspectRatio = 1e6f;

// Connected component of every vertex (union–find over face corners).
std::vector<Index> vertex_components(Index n, const Faces& F) {
  std::vector<Index> parent(static_cast<std::size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](Index x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 1; k < 3; ++k) {
      const Index a = find(F(f, 0)), b = find(F(f, k));
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  for (Index v = 0; v < n; ++v) parent[v] = find(v);
  return parent;
}

// Runs one decimation pass to `target` vertices; returns the number of collapses.
std::size_t decimate(OmMesh& om, std::size_t target, double max_normal_deviation) {
  Decimater decimater(om);
  ModQuadric::Handle quadric;
  decimater.add(quadric);
  decimater.module(quadric).unset_max_err();  // priority module, no error bound
  ModAspectRatio::Handle aspect;
  decimater.add(aspect);
  decimater.module(aspect).set_binary(true);
  decimater.module(aspect).set_aspect_ratio(kMaxCollapseAspectRatio);
  ModNormalFlipping::Handle normals;
  if (max_normal_deviation > 0) {
    decimater.add(normals);
    decimater.module(normals).set_max_normal_deviation(max_normal_deviation);
  }
  if (!decimater.initialize()) throw std::logic_error("qem_coarsen: OpenMesh decimater failed to initialise");
  return decimater.decimate_to(target);
}

}  // namespace

std::array<double, 3> closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                                const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Voronoi regions of the triangle's features, tested in turn (vertices, edges, interior).
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double t = d1 / (d1 - d3);
    return {1 - t, t, 0};
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double t = d2 / (d2 - d6);
    return {1 - t, 0, t};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - t, t};
  }
  const double sum = va + vb + vc;
  if (!(sum > 0)) {  // degenerate triangle: the best of its three edges
    std::array<double, 3> best{1, 0, 0};
    double best_d = std::numeric_limits<double>::infinity();
    const Eigen::Vector3d corners[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& s = corners[k];
      const Eigen::Vector3d e = corners[(k + 1) % 3] - s;
      const double len2 = e.squaredNorm();
      const double t = len2 > 0 ? std::clamp((p - s).dot(e) / len2, 0.0, 1.0) : 0.0;
      const double d = (s + t * e - p).squaredNorm();
      if (d < best_d) {
        best_d = d;
        best = {0, 0, 0};
        best[k] = 1 - t;
        best[(k + 1) % 3] = t;
      }
    }
    return best;
  }
  const double v = vb / sum, w = vc / sum;
  return {std::max(0.0, 1 - v - w), v, w};
}

// ---- TriangleBvh ------------------------------------------------------------------------------------

TriangleBvh::TriangleBvh(const Positions& V, const Faces& F, std::vector<Index> face_labels)
    : V_(V), F_(F), labels_(std::move(face_labels)) {
  if (!labels_.empty() && static_cast<Eigen::Index>(labels_.size()) != F.rows())
    throw std::invalid_argument("TriangleBvh: one label per face expected");
  const Index m = static_cast<Index>(F.rows());
  order_.resize(static_cast<std::size_t>(m));
  std::iota(order_.begin(), order_.end(), 0);
  std::vector<Eigen::Vector3d> centroids(static_cast<std::size_t>(m));
  for (Index f = 0; f < m; ++f)
    centroids[f] = (V.row(F(f, 0)) + V.row(F(f, 1)) + V.row(F(f, 2))).transpose() / 3.0;
  nodes_.reserve(static_cast<std::size_t>(m) / 2 + 1);
  if (m > 0) build(0, m, centroids);
}

Index TriangleBvh::build(Index first, Index count, std::vector<Eigen::Vector3d>& centroids) {
  constexpr Index kLeafSize = 4;
  const Index id = static_cast<Index>(nodes_.size());
  nodes_.emplace_back();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  Eigen::Vector3d clo = lo, chi = hi;
  for (Index i = first; i < first + count; ++i) {
    const Index f = order_[i];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d x = V_.row(F_(f, k)).transpose();
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
    clo = clo.cwiseMin(centroids[f]);
    chi = chi.cwiseMax(centroids[f]);
  }
  nodes_[id].lo = lo;
  nodes_[id].hi = hi;
  if (count <= kLeafSize) {
    nodes_[id].first = first;
    nodes_[id].count = count;
    return id;
  }
  int axis = 0;
  (chi - clo).maxCoeff(&axis);
  const Index mid = first + count / 2;
  std::nth_element(order_.begin() + first, order_.begin() + mid, order_.begin() + first + count,
                   [&](Index a, Index b) { return centroids[a][axis] < centroids[b][axis]; });
  const Index left = build(first, mid - first, centroids);
  const Index right = build(mid, first + count - mid, centroids);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

TriangleBvh::Hit TriangleBvh::closest_point(const Eigen::Vector3d& p, Index label) const {
  Hit best;
  best.squared_distance = std::numeric_limits<double>::infinity();
  if (nodes_.empty()) return best;
  const auto box_distance = [&](const Node& n) {
    return (n.lo - p).cwiseMax(p - n.hi).cwiseMax(0.0).squaredNorm();
  };
  Index stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (box_distance(node) >= best.squared_distance) continue;
    if (node.left == kInvalid) {
      for (Index i = node.first; i < node.first + node.count; ++i) {
        const Index f = order_[i];
        if (label != kInvalid && !labels_.empty() && labels_[f] != label) continue;
        const Eigen::Vector3d a = V_.row(F_(f, 0)), b = V_.row(F_(f, 1)), c = V_.row(F_(f, 2));
        const std::array<double, 3> w = closest_point_on_triangle(p, a, b, c);
        const double d = (w[0] * a + w[1] * b + w[2] * c - p).squaredNorm();
        if (d < best.squared_distance) best = {f, w, d};
      }
      continue;
    }
    // Nearer child last, so it is popped first.
    const double dl = box_distance(nodes_[node.left]), dr = box_distance(nodes_[node.right]);
    if (top + 2 > 128) throw std::logic_error("TriangleBvh: tree too deep");
    if (dl < dr) {
      stack[top++] = node.right;
      stack[top++] = node.left;
    } else {
      stack[top++] = node.left;
      stack[top++] = node.right;
    }
  }
  return best;
}

// ---- QEM --------------------------------------------------------------------------------------------

Eigen::SparseMatrix<double> prolongation_from_map(const std::vector<QemPoint>& map, const Faces& coarse_faces,
                                                  Index coarse_vertices) {
  const Index rows = static_cast<Index>(map.size());
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(3 * map.size());
  for (Index p = 0; p < rows; ++p) {
    const QemPoint& q = map[p];
    if (q.coarse_vertex != kInvalid) {
      entries.emplace_back(p, q.coarse_vertex, 1.0);
      continue;
    }
    for (int k = 0; k < 3; ++k)
      if (q.bary[k] != 0.0) entries.emplace_back(p, coarse_faces(q.face, k), q.bary[k]);
  }
  Eigen::SparseMatrix<double> P(rows, coarse_vertices);
  P.setFromTriplets(entries.begin(), entries.end());
  return P;
}

QemResult qem_coarsen(const TriangleMesh& mesh, const QemOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const Index n = static_cast<Index>(mesh.V.rows());
  QemResult r;
  r.input_vertices = n;
  Index target = options.target_vertices;
  if (target == 0 && options.target_ratio > 0)
    target = static_cast<Index>(std::ceil(options.target_ratio * static_cast<double>(n)));
  if (target < 1 || target > n)
    throw std::invalid_argument("qem_coarsen: target of " + std::to_string(target) + " vertices out of range 1.." +
                                std::to_string(n));
  r.target_vertices = target;

  // ---- OpenMesh mesh with the input index of every vertex
  OmMesh om;
  om.request_vertex_status();  // held by us too, so the Decimaters' release keeps the flags
  om.request_edge_status();
  om.request_face_status();
  om.request_face_normals();
  OpenMesh::VPropHandleT<int> input_index;
  om.add_property(input_index);
  std::vector<OmMesh::VertexHandle> handles(static_cast<std::size_t>(n));
  for (Index v = 0; v < n; ++v) {
    handles[v] = om.add_vertex(OmMesh::Point(mesh.V(v, 0), mesh.V(v, 1), mesh.V(v, 2)));
    om.property(input_index, handles[v]) = v;
  }
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const auto fh = om.add_face(handles[mesh.F(f, 0)], handles[mesh.F(f, 1)], handles[mesh.F(f, 2)]);
    if (!fh.is_valid())
      throw std::invalid_argument("qem_coarsen: face " + std::to_string(f) +
                                  " cannot be added to an OpenMesh mesh (non-manifold or inconsistently oriented input)");
  }
  om.update_face_normals();
  for (Index v : options.locked_vertices) {
    if (v < 0 || v >= n) throw std::invalid_argument("qem_coarsen: locked vertex out of range");
    om.status(handles[v]).set_locked(true);
  }
  if (!options.remove_boundary)
    for (Index v = 0; v < n; ++v)
      if (om.is_boundary(handles[v])) om.status(handles[v]).set_locked(true);

  // ---- decimate (guarded, then unguarded if the target was not reached)
  std::size_t collapses = decimate(om, static_cast<std::size_t>(target), options.max_normal_deviation_degrees);
  Index remaining = n - static_cast<Index>(collapses);
  if (remaining > target && options.max_normal_deviation_degrees > 0) {
    // A new decimater initialises its modules over every element, and the first pass left deleted
    // ones behind whose handles dangle (invalid reads, then crashes: an octahedron to 3 vertices).
    // The vertex properties (input index, lock status) move with their vertices.
    om.garbage_collection();
    collapses += decimate(om, static_cast<std::size_t>(target), 0.0);
    r.guard_relaxed = true;
    remaining = n - static_cast<Index>(collapses);
  }
  r.collapses = static_cast<Index>(collapses);
  r.target_reached = remaining == target;
  om.garbage_collection();

  const Index nc = static_cast<Index>(om.n_vertices());
  r.to_input.resize(static_cast<std::size_t>(nc));
  r.from_input.assign(static_cast<std::size_t>(n), kInvalid);
  r.coarse.V.resize(nc, 3);
  for (const auto vh : om.vertices()) {
    const Index c = vh.idx(), v = om.property(input_index, vh);
    r.to_input[c] = v;
    r.from_input[v] = c;
    r.coarse.V.row(c) = mesh.V.row(v);  // halfedge collapses keep positions: exact input coordinates
  }
  r.coarse.F.resize(static_cast<Eigen::Index>(om.n_faces()), 3);
  for (const auto fh : om.faces()) {
    int k = 0;
    for (const auto vh : om.fv_range(fh)) r.coarse.F(fh.idx(), k++) = vh.idx();
  }
  om.remove_property(input_index);
  // The aspect-ratio guard makes degenerate faces impossible; a mesh that has one anyway must not be
  // handed on (its lengths would not form a triangulation, and a written file could not be read back).
  const FaceLengths coarse_lengths = face_lengths_from_positions(r.coarse.V, r.coarse.F);
  for (Eigen::Index f = 0; f < r.coarse.F.rows(); ++f)
    if (!triangle_inequality_holds(coarse_lengths(f, 0), coarse_lengths(f, 1), coarse_lengths(f, 2)))
      throw std::runtime_error("qem_coarsen: the QEM mesh has a degenerate face (" + std::to_string(f) +
                               "); please report this input");
  r.decimate_seconds = seconds_since(start);

  // ---- map: survivors exactly, the others by closest point on their own component
  const auto map_start = std::chrono::steady_clock::now();
  const std::vector<Index> component = vertex_components(n, mesh.F);
  std::vector<Index> face_label(static_cast<std::size_t>(r.coarse.F.rows()));
  for (Eigen::Index f = 0; f < r.coarse.F.rows(); ++f) face_label[f] = component[r.to_input[r.coarse.F(f, 0)]];
  std::vector<Index> face_at(static_cast<std::size_t>(nc), kInvalid);  // a face around each coarse vertex
  std::vector<int> corner_at(static_cast<std::size_t>(nc), 0);
  for (Eigen::Index f = 0; f < r.coarse.F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (face_at[r.coarse.F(f, k)] == kInvalid) {
        face_at[r.coarse.F(f, k)] = static_cast<Index>(f);
        corner_at[r.coarse.F(f, k)] = k;
      }
  const TriangleBvh tree(r.coarse.V, r.coarse.F, face_label);
  r.map.resize(static_cast<std::size_t>(n));
  double sum_distance = 0;
  Index moved = 0;
  for (Index v = 0; v < n; ++v) {
    QemPoint& q = r.map[v];
    const Index c = r.from_input[v];
    if (c != kInvalid) {
      q.coarse_vertex = c;
      q.face = face_at[c];
      q.bary = {0, 0, 0};
      q.bary[corner_at[c]] = 1;
      continue;
    }
    const TriangleBvh::Hit hit = tree.closest_point(mesh.V.row(v).transpose(), component[v]);
    if (hit.face == kInvalid) throw std::logic_error("qem_coarsen: a component lost all its faces");
    q.face = hit.face;
    double sum = 0;
    for (int k = 0; k < 3; ++k) sum += (q.bary[k] = std::clamp(hit.bary[k], 0.0, 1.0));
    for (double& b : q.bary) b /= sum;
    q.distance = std::sqrt(hit.squared_distance);
    r.max_distance = std::max(r.max_distance, q.distance);
    sum_distance += q.distance;
    ++moved;
  }
  r.mean_distance = moved > 0 ? sum_distance / moved : 0.0;
  r.P = prolongation_from_map(r.map, r.coarse.F, nc);
  r.map_seconds = seconds_since(map_start);
  return r;
}

CompactMesh qem_extrinsic_mesh(const QemResult& result) {
  CompactMesh m;
  m.F = result.coarse.F;
  m.L = face_lengths_from_positions(result.coarse.V, result.coarse.F);
  m.twin = glue_by_vertex_pairs(m.F);  // a manifold mesh: its vertex pairs name its edges
  m.to_input = result.to_input;
  m.vertex_count = static_cast<Index>(m.to_input.size());
  m.from_input = result.from_input;
  return m;
}

CompactMesh qem_intrinsic_delaunay_mesh(const QemResult& result, int* flips) {
  IntrinsicTriangulation T = IntrinsicTriangulation::from_mesh(result.coarse.V, result.coarse.F);
  const int count = T.flip_to_delaunay();
  if (flips) *flips = count;
  CompactMesh c = T.compact();  // no vertex removed: compact index = QEM vertex index
  CompactMesh m;
  m.F = std::move(c.F);
  m.L = std::move(c.L);
  m.twin = std::move(c.twin);  // flips can make multi-edges: keep the gluing
  m.to_input = result.to_input;
  m.vertex_count = static_cast<Index>(m.to_input.size());
  m.from_input = result.from_input;
  return m;
}

}  // namespace ice
