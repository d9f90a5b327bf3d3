#include "exact_geodesics.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_shortest_path.h>

#include <limits>
#include <stdexcept>
#include <string>

namespace ice_bench {

namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
using ShortestPaths = CGAL::Surface_mesh_shortest_path<CGAL::Surface_mesh_shortest_path_traits<Kernel, SurfaceMesh>>;
}  // namespace

Eigen::MatrixXd exact_geodesic_distances(const ice::TriangleMesh& mesh, const std::vector<ice::Index>& sources) {
  const auto n = static_cast<ice::Index>(mesh.V.rows());
  SurfaceMesh surface;
  std::vector<SurfaceMesh::Vertex_index> handles;
  handles.reserve(static_cast<std::size_t>(n));
  for (ice::Index v = 0; v < n; ++v) handles.push_back(surface.add_vertex({mesh.V(v, 0), mesh.V(v, 1), mesh.V(v, 2)}));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    if (surface.add_face(handles[mesh.F(f, 0)], handles[mesh.F(f, 1)], handles[mesh.F(f, 2)]) ==
        SurfaceMesh::null_face())
      throw std::invalid_argument("exact geodesics: CGAL's Surface_mesh refuses face " + std::to_string(f) +
                                  " (not an oriented 2-manifold there)");
  Eigen::MatrixXd distances(n, static_cast<Eigen::Index>(sources.size()));
  for (std::size_t s = 0; s < sources.size(); ++s) {
    if (sources[s] < 0 || sources[s] >= n) throw std::invalid_argument("exact geodesics: source vertex out of range");
    ShortestPaths paths(surface);
    paths.add_source_point(handles[sources[s]]);
    paths.build_sequence_tree();
    for (ice::Index v = 0; v < n; ++v) {
      const double d = paths.shortest_distance_to_source_points(handles[v]).first;
      // CGAL answers a negative distance for a vertex no source reaches.
      distances(v, static_cast<Eigen::Index>(s)) = d >= 0 ? d : std::numeric_limits<double>::infinity();
    }
  }
  return distances;
}

}  // namespace ice_bench
