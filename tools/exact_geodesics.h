#pragma once
/// Exact polyhedral geodesic distances on an input mesh, for the benchmarks that measure distance
/// errors against the truth rather than against the fine heat method (whose own error, 0.6-8 % on
/// the shared meshes, is of the size of the proxy errors being compared). Built only where CGAL
/// (Debian's libcgal-dev) is found: a benchmark dependency, not one of the libraries.
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ice/mesh.h"

namespace ice_bench {

/// The largest mesh (in vertices) the accuracy tools compute exact geodesics on unless told
/// otherwise: the memory of CGAL's sequence trees grows faster than the mesh (vector-accuracy on
/// dragon_vrip_bin, 437,645 vertices, was killed at 24 GB after 5 minutes). A larger mesh is
/// skipped with a message (`--max-vertices N` in vector-accuracy and oracle-accuracy,
/// `--exact-max-vertices N` in ice-report).
inline constexpr long long kDefaultExactMaxVertices = 100000;

/// True, after saying so on stderr (prefixed by `tool`), when a mesh of n vertices is above
/// max_vertices (a tool's `--max-vertices N`) and is to be skipped.
inline bool skip_for_exact_geodesics(const char* tool, const std::string& path, long long n, long long max_vertices) {
  if (n <= max_vertices) return false;
  std::fprintf(stderr, "%s: skipping %s: %lld vertices, above --max-vertices %lld (the exact geodesics' memory grows faster than the mesh)\n",
               tool, path.c_str(), n, max_vertices);
  return true;
}

/// Distances along the surface of (mesh.V, mesh.F) from each of `sources` (vertex indices) to every
/// vertex: column s holds the distances from sources[s] (CGAL's Surface_mesh_shortest_path, the
/// Xin–Wang exact algorithm). +∞ where a vertex is not reachable (another component).
/// Precondition: an oriented 2-manifold (with or without boundary) whose faces CGAL's Surface_mesh
/// accepts; std::invalid_argument names the first face it refuses.
Eigen::MatrixXd exact_geodesic_distances(const ice::TriangleMesh& mesh, const std::vector<ice::Index>& sources);

/// The exact shortest path from a source to a vertex, by the directions that parallel transport
/// along it needs (unit 3D vectors, each in the plane of the face its segment runs in): `departure`
/// leaves the source along the path, `back` leaves the end vertex back along it, and at every mesh
/// vertex the path runs through (a saddle, or along an edge), in order from the source, `back`
/// (towards the source) and `ahead` (towards the end). Between vertices a transported vector keeps
/// its angle with the path.
struct ExactPath {
  struct Through {
    ice::Index vertex;
    Eigen::Vector3d back, ahead;
  };
  Eigen::Vector3d departure, back;
  std::vector<Through> through;
};
/// Calls visit(v, path) for every vertex v other than `source` that the source reaches, from one
/// sequence tree (CGAL's Surface_mesh_shortest_path). Precondition as exact_geodesic_distances.
void for_each_exact_path(const ice::TriangleMesh& mesh, ice::Index source,
                         const std::function<void(ice::Index, const ExactPath&)>& visit);

}  // namespace ice_bench
