#include "ice/triangle_geometry.h"
#include "ice/mesh_generators.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

namespace ice {
namespace {


/// Unique undirected edges of a triangle list, with the faces (and corners) that use them.
struct EdgeTopology {
  std::vector<std::array<int, 2>> endpoints;     ///< (smaller, larger) vertex index per edge
  std::vector<std::array<int, 2>> face_corners;  ///< up to two face*3+corner entries, -1 if absent
  Eigen::MatrixXi face_edge;                     ///< m×3, edge id of the corner-k edge of each face

  bool is_boundary(std::size_t e) const { return face_corners[e][1] < 0; }
};

/// Finds the edges by sorting 64-bit corner keys: O(m log m), no quadratic search.
/// Throws std::invalid_argument on an edge with more than two incident faces.
EdgeTopology build_edge_topology(const Faces& F) {
  const Eigen::Index m = F.rows();
  std::vector<std::pair<std::uint64_t, int>> corner_keys;
  corner_keys.reserve(static_cast<std::size_t>(3 * m));
  for (Eigen::Index f = 0; f < m; ++f)
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint64_t>(F(f, k));
      const auto b = static_cast<std::uint64_t>(F(f, (k + 1) % 3));
      const std::uint64_t key = (std::min(a, b) << 32) | std::max(a, b);
      corner_keys.emplace_back(key, static_cast<int>(3 * f + k));
    }
  std::sort(corner_keys.begin(), corner_keys.end());

  EdgeTopology topology;
  topology.face_edge.resize(m, 3);
  for (std::size_t i = 0; i < corner_keys.size();) {
    std::size_t j = i;
    while (j < corner_keys.size() && corner_keys[j].first == corner_keys[i].first) ++j;
    if (j - i > 2) throw std::invalid_argument("loop_subdivide: non-manifold edge (more than two faces)");
    const int edge = static_cast<int>(topology.endpoints.size());
    const std::uint64_t key = corner_keys[i].first;
    topology.endpoints.push_back({static_cast<int>(key >> 32), static_cast<int>(key & 0xffffffffu)});
    topology.face_corners.push_back({corner_keys[i].second, j - i == 2 ? corner_keys[i + 1].second : -1});
    for (std::size_t c = i; c < j; ++c)
      topology.face_edge(corner_keys[c].second / 3, corner_keys[c].second % 3) = edge;
    i = j;
  }
  return topology;
}

/// The 1-to-4 split shared by midpoint and Loop subdivision: corner k of a face keeps its vertex, edge
/// points get indices n + edge id, and the four children keep the parent's orientation.
Faces split_faces(const Faces& F, const EdgeTopology& topology, int vertex_count) {
  Faces children(4 * F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int v0 = F(f, 0), v1 = F(f, 1), v2 = F(f, 2);
    const int e0 = vertex_count + topology.face_edge(f, 0);  // on edge v0-v1
    const int e1 = vertex_count + topology.face_edge(f, 1);  // on edge v1-v2
    const int e2 = vertex_count + topology.face_edge(f, 2);  // on edge v2-v0
    children.row(4 * f + 0) << v0, e0, e2;
    children.row(4 * f + 1) << v1, e1, e0;
    children.row(4 * f + 2) << v2, e2, e1;
    children.row(4 * f + 3) << e0, e1, e2;
  }
  return children;
}

/// Vertex opposite the edge stored in a face*3+corner entry.
int opposite_vertex(const Faces& F, int face_corner) {
  return F(face_corner / 3, (face_corner % 3 + 2) % 3);
}

TriangleMesh loop_subdivide_once(const TriangleMesh& mesh) {
  const Positions& V = mesh.V;
  const int n = static_cast<int>(V.rows());
  const EdgeTopology topology = build_edge_topology(mesh.F);
  const std::size_t edge_count = topology.endpoints.size();

  // One pass over edges gathers both the edge points and the one-ring sums the vertex rules need.
  Positions fine(n + static_cast<Eigen::Index>(edge_count), 3);
  Positions ring_sum = Positions::Zero(n, 3);
  Positions boundary_sum = Positions::Zero(n, 3);
  std::vector<int> valence(n, 0), boundary_valence(n, 0);
  for (std::size_t e = 0; e < edge_count; ++e) {
    const int a = topology.endpoints[e][0], b = topology.endpoints[e][1];
    ++valence[a];
    ++valence[b];
    ring_sum.row(a) += V.row(b);
    ring_sum.row(b) += V.row(a);
    const Eigen::Index row = n + static_cast<Eigen::Index>(e);
    if (topology.is_boundary(e)) {
      ++boundary_valence[a];
      ++boundary_valence[b];
      boundary_sum.row(a) += V.row(b);
      boundary_sum.row(b) += V.row(a);
      fine.row(row) = 0.5 * (V.row(a) + V.row(b));
    } else {
      const int c = opposite_vertex(mesh.F, topology.face_corners[e][0]);
      const int d = opposite_vertex(mesh.F, topology.face_corners[e][1]);
      fine.row(row) = 0.375 * (V.row(a) + V.row(b)) + 0.125 * (V.row(c) + V.row(d));
    }
  }
  for (int v = 0; v < n; ++v) {
    if (boundary_valence[v] == 2) {
      fine.row(v) = 0.75 * V.row(v) + 0.125 * boundary_sum.row(v);
    } else if (boundary_valence[v] == 0 && valence[v] > 0) {
      const double k = valence[v];
      const double c = 0.375 + 0.25 * std::cos(2.0 * kPi / k);
      const double beta = (0.625 - c * c) / k;
      fine.row(v) = (1.0 - k * beta) * V.row(v) + beta * ring_sum.row(v);
    } else {
      fine.row(v) = V.row(v);  // isolated, or a pinch of several boundary curves: keep it as a corner
    }
  }
  return {std::move(fine), split_faces(mesh.F, topology, n)};
}

/// Midpoint subdivision followed by projection to the sphere (for the icosphere).
TriangleMesh subdivide_on_sphere(const TriangleMesh& mesh, double radius) {
  const int n = static_cast<int>(mesh.V.rows());
  const EdgeTopology topology = build_edge_topology(mesh.F);
  Positions fine(n + static_cast<Eigen::Index>(topology.endpoints.size()), 3);
  fine.topRows(n) = mesh.V;
  for (std::size_t e = 0; e < topology.endpoints.size(); ++e) {
    const Eigen::RowVector3d mid =
        0.5 * (mesh.V.row(topology.endpoints[e][0]) + mesh.V.row(topology.endpoints[e][1]));
    fine.row(n + static_cast<Eigen::Index>(e)) = radius * mid.normalized();
  }
  return {std::move(fine), split_faces(mesh.F, topology, n)};
}

}  // namespace

TriangleMesh make_icosphere(int subdivisions, double radius) {
  if (subdivisions < 0 || !(radius > 0))
    throw std::invalid_argument("make_icosphere: need subdivisions >= 0 and radius > 0");
  // Icosahedron vertices: cyclic permutations of (0, ±1, ±φ).
  const double phi = 0.5 * (1.0 + std::sqrt(5.0));
  TriangleMesh mesh;
  mesh.V.resize(12, 3);
  int row = 0;
  for (int axis = 0; axis < 3; ++axis)
    for (double s1 : {-1.0, 1.0})
      for (double s2 : {-1.0, 1.0}) {
        Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
        p((axis + 1) % 3) = s1;
        p((axis + 2) % 3) = s2 * phi;
        mesh.V.row(row++) = p;
      }
  // Faces are the vertex triples that are pairwise at edge distance 2; orient them outward. Deriving
  // them avoids a hand-typed (and easily mis-oriented) face table.
  std::vector<std::array<int, 3>> faces;
  auto adjacent = [&](int a, int b) { return std::abs((mesh.V.row(a) - mesh.V.row(b)).norm() - 2.0) < 1e-9; };
  for (int a = 0; a < 12; ++a)
    for (int b = a + 1; b < 12; ++b)
      for (int c = b + 1; c < 12; ++c) {
        if (!adjacent(a, b) || !adjacent(b, c) || !adjacent(a, c)) continue;
        const Eigen::Vector3d pa = mesh.V.row(a), pb = mesh.V.row(b), pc = mesh.V.row(c);
        const bool outward = (pb - pa).cross(pc - pa).dot(pa + pb + pc) > 0;
        faces.push_back(outward ? std::array<int, 3>{a, b, c} : std::array<int, 3>{a, c, b});
      }
  mesh.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (std::size_t f = 0; f < faces.size(); ++f)
    mesh.F.row(static_cast<Eigen::Index>(f)) << faces[f][0], faces[f][1], faces[f][2];
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) mesh.V.row(v) = radius * mesh.V.row(v).normalized();

  for (int level = 0; level < subdivisions; ++level) mesh = subdivide_on_sphere(mesh, radius);
  return mesh;
}

TriangleMesh make_torus(int major_segments, int minor_segments, double major_radius,
                        double minor_radius) {
  if (major_segments < 3 || minor_segments < 3 || !(minor_radius > 0) || !(major_radius > minor_radius))
    throw std::invalid_argument("make_torus: need segments >= 3 and major_radius > minor_radius > 0");
  TriangleMesh mesh;
  mesh.V.resize(major_segments * minor_segments, 3);
  mesh.F.resize(2 * major_segments * minor_segments, 3);
  auto index = [&](int i, int j) { return (i % major_segments) * minor_segments + (j % minor_segments); };
  for (int i = 0; i < major_segments; ++i) {
    const double u = 2.0 * kPi * i / major_segments;
    for (int j = 0; j < minor_segments; ++j) {
      const double v = 2.0 * kPi * j / minor_segments;
      const double ring = major_radius + minor_radius * std::cos(v);
      mesh.V.row(index(i, j)) << ring * std::cos(u), ring * std::sin(u), minor_radius * std::sin(v);
    }
  }
  // ∂/∂u × ∂/∂v points away from the tube centre line, so (i,j),(i+1,j),(i+1,j+1) is outward.
  int f = 0;
  for (int i = 0; i < major_segments; ++i)
    for (int j = 0; j < minor_segments; ++j) {
      mesh.F.row(f++) << index(i, j), index(i + 1, j), index(i + 1, j + 1);
      mesh.F.row(f++) << index(i, j), index(i + 1, j + 1), index(i, j + 1);
    }
  return mesh;
}

TriangleMesh make_flat_disk(int rings, double radius, double jitter, std::uint32_t seed) {
  if (rings < 1 || !(radius > 0) || !(jitter >= 0 && jitter <= 0.3))
    throw std::invalid_argument("make_flat_disk: need rings >= 1, radius > 0, 0 <= jitter <= 0.3");
  const double spacing = radius / rings;
  auto ring_start = [](int k) { return k == 0 ? 0 : 1 + 3 * (k - 1) * k; };  // first index of ring k
  auto ring_size = [](int k) { return k == 0 ? 1 : 6 * k; };

  TriangleMesh mesh;
  mesh.V.resize(ring_start(rings + 1), 3);
  mesh.V.row(0).setZero();
  for (int k = 1; k <= rings; ++k)
    for (int j = 0; j < ring_size(k); ++j) {
      const double angle = 2.0 * kPi * j / ring_size(k);
      mesh.V.row(ring_start(k) + j) << k * spacing * std::cos(angle), k * spacing * std::sin(angle), 0.0;
    }

  mesh.F.resize(6 * rings * rings, 3);
  int f = 0;
  for (int j = 0; j < 6; ++j) mesh.F.row(f++) << 0, ring_start(1) + j, ring_start(1) + (j + 1) % 6;
  // Zip ring k-1 to ring k by advancing along whichever ring has the nearer next angle; comparing the
  // fractions (i+1)/n_in and (o+1)/n_out in integers keeps ties exact.
  for (int k = 2; k <= rings; ++k) {
    const int n_in = ring_size(k - 1), n_out = ring_size(k);
    const int in0 = ring_start(k - 1), out0 = ring_start(k);
    int i = 0, o = 0;
    while (i < n_in || o < n_out) {
      const bool advance_outer = i == n_in || (o < n_out && (o + 1) * n_in <= (i + 1) * n_out);
      if (advance_outer) {
        mesh.F.row(f++) << in0 + i % n_in, out0 + o % n_out, out0 + (o + 1) % n_out;
        ++o;
      } else {
        mesh.F.row(f++) << in0 + i % n_in, out0 + o % n_out, in0 + (i + 1) % n_in;
        ++i;
      }
    }
  }

  if (jitter > 0) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int v = 0; v < ring_start(rings); ++v) {  // interior vertices only
      const double angle = 2.0 * kPi * unit(rng);
      const double length = jitter * spacing * std::sqrt(unit(rng));  // uniform in a small disk
      mesh.V(v, 0) += length * std::cos(angle);
      mesh.V(v, 1) += length * std::sin(angle);
    }
  }
  return mesh;
}

TriangleMesh make_genus2(int cells_per_unit, double scale) {
  if (cells_per_unit < 1 || !(scale > 0))
    throw std::invalid_argument("make_genus2: need cells_per_unit >= 1 and scale > 0");
  constexpr int kNx = 5, kNy = 3;
  auto solid = [](int x, int y, int z) {
    if (x < 0 || x >= kNx || y < 0 || y >= kNy || z != 0) return false;
    return !(y == 1 && (x == 1 || x == 3));  // the two holes
  };

  // Lattice points are shared between voxel faces through a dense index over the bounding box.
  const int n = cells_per_unit;
  const std::array<int, 3> extent{kNx * n + 1, kNy * n + 1, n + 1};
  std::vector<int> lattice_index(static_cast<std::size_t>(extent[0]) * extent[1] * extent[2], -1);
  std::vector<Eigen::RowVector3d> points;
  auto vertex = [&](const std::array<int, 3>& p) {
    int& id = lattice_index[(static_cast<std::size_t>(p[2]) * extent[1] + p[1]) * extent[0] + p[0]];
    if (id < 0) {
      id = static_cast<int>(points.size());
      points.emplace_back(scale * p[0] / n, scale * p[1] / n, scale * p[2] / n);
    }
    return id;
  };

  std::vector<std::array<int, 3>> faces;
  for (int x = 0; x < kNx; ++x)
    for (int y = 0; y < kNy; ++y) {
      if (!solid(x, y, 0)) continue;
      const std::array<int, 3> voxel{x, y, 0};
      for (int axis = 0; axis < 3; ++axis)
        for (int side : {-1, 1}) {
          std::array<int, 3> neighbour = voxel;
          neighbour[axis] += side;
          if (solid(neighbour[0], neighbour[1], neighbour[2])) continue;
          // With u = axis+1, v = axis+2 (cyclic), e_u × e_v = e_axis, so the (u,v)-ordered square
          // faces +axis; reverse it for the -axis side.
          const int u = (axis + 1) % 3, v = (axis + 2) % 3;
          for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
              std::array<int, 4> quad{};
              const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
              for (int c = 0; c < 4; ++c) {
                std::array<int, 3> p{voxel[0] * n, voxel[1] * n, voxel[2] * n};
                p[axis] += side > 0 ? n : 0;
                p[u] += i + du[c];
                p[v] += j + dv[c];
                quad[c] = vertex(p);
              }
              if (side < 0) std::swap(quad[1], quad[3]);
              faces.push_back({quad[0], quad[1], quad[2]});
              faces.push_back({quad[0], quad[2], quad[3]});
            }
        }
    }

  TriangleMesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v) mesh.V.row(static_cast<Eigen::Index>(v)) = points[v];
  mesh.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (std::size_t f = 0; f < faces.size(); ++f)
    mesh.F.row(static_cast<Eigen::Index>(f)) << faces[f][0], faces[f][1], faces[f][2];
  return mesh;
}

TriangleMesh loop_subdivide(const TriangleMesh& mesh, int levels) {
  if (levels < 0) throw std::invalid_argument("loop_subdivide: levels must be >= 0");
  TriangleMesh result = mesh;
  for (int level = 0; level < levels; ++level) result = loop_subdivide_once(result);
  return result;
}

}  // namespace ice
