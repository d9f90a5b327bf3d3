#pragma once
/// Exact polyhedral geodesic distances on an input mesh, for the benchmarks that measure distance
/// errors against the truth rather than against the fine heat method (whose own error, 0.6-8 % on
/// the shared meshes, is of the size of the proxy errors being compared). Built only where CGAL
/// (Debian's libcgal-dev) is found: a benchmark dependency, not one of the libraries.
#include <vector>

#include <Eigen/Core>

#include "ice/mesh.h"

namespace ice_bench {

/// Distances along the surface of (mesh.V, mesh.F) from each of `sources` (vertex indices) to every
/// vertex: column s holds the distances from sources[s] (CGAL's Surface_mesh_shortest_path, the
/// Xin–Wang exact algorithm). +∞ where a vertex is not reachable (another component).
/// Precondition: an oriented 2-manifold (with or without boundary) whose faces CGAL's Surface_mesh
/// accepts; std::invalid_argument names the first face it refuses.
Eigen::MatrixXd exact_geodesic_distances(const ice::TriangleMesh& mesh, const std::vector<ice::Index>& sources);

}  // namespace ice_bench
