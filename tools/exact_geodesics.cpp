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

// The mesh as CGAL's Surface_mesh, with the handle of every vertex.
void build_surface(const ice::TriangleMesh& mesh, SurfaceMesh& surface, std::vector<SurfaceMesh::Vertex_index>& handles) {
  const auto n = static_cast<ice::Index>(mesh.V.rows());
  handles.reserve(static_cast<std::size_t>(n));
  for (ice::Index v = 0; v < n; ++v) handles.push_back(surface.add_vertex({mesh.V(v, 0), mesh.V(v, 1), mesh.V(v, 2)}));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    if (surface.add_face(handles[mesh.F(f, 0)], handles[mesh.F(f, 1)], handles[mesh.F(f, 2)]) ==
        SurfaceMesh::null_face())
      throw std::invalid_argument("exact geodesics: CGAL's Surface_mesh refuses face " + std::to_string(f) +
                                  " (not an oriented 2-manifold there)");
}

}  // namespace

Eigen::MatrixXd exact_geodesic_distances(const ice::TriangleMesh& mesh, const std::vector<ice::Index>& sources) {
  const auto n = static_cast<ice::Index>(mesh.V.rows());
  SurfaceMesh surface;
  std::vector<SurfaceMesh::Vertex_index> handles;
  build_surface(mesh, surface, handles);
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

namespace {
// The path sequence's events, from the end vertex to the source (CGAL's order): a vertex's handle,
// or −1 for an edge crossing. One point of shortest_path_points_to_source_points per event.
struct SequenceRecorder {
  std::vector<long long> events;
  void operator()(SurfaceMesh::Halfedge_index, double) { events.push_back(-1); }
  void operator()(SurfaceMesh::Vertex_index v) { events.push_back(static_cast<long long>(v.idx())); }
  void operator()(SurfaceMesh::Face_index, ShortestPaths::Barycentric_coordinates) { events.push_back(-2); }
};
}  // namespace

void for_each_exact_path(const ice::TriangleMesh& mesh, ice::Index source,
                         const std::function<void(ice::Index, const ExactPath&)>& visit) {
  const auto n = static_cast<ice::Index>(mesh.V.rows());
  if (source < 0 || source >= n) throw std::invalid_argument("exact geodesics: source vertex out of range");
  SurfaceMesh surface;
  std::vector<SurfaceMesh::Vertex_index> handles;
  build_surface(mesh, surface, handles);
  ShortestPaths paths(surface);
  paths.add_source_point(handles[source]);
  paths.build_sequence_tree();
  std::vector<Kernel::Point_3> points;
  const auto direction = [](const Kernel::Point_3& from, const Kernel::Point_3& to) {
    const Eigen::Vector3d d(to.x() - from.x(), to.y() - from.y(), to.z() - from.z());
    return Eigen::Vector3d(d / d.norm());
  };
  ExactPath path;
  for (ice::Index v = 0; v < n; ++v) {
    if (v == source || paths.shortest_distance_to_source_points(handles[v]).first < 0) continue;
    SequenceRecorder sequence;
    paths.shortest_path_sequence_to_source_points(handles[v], sequence);
    points.clear();
    paths.shortest_path_points_to_source_points(handles[v], std::back_inserter(points));  // v first, the source last
    if (points.size() < 2 || points.size() != sequence.events.size())
      throw std::logic_error("exact geodesics: a path's points and sequence disagree");
    const std::size_t last = points.size() - 1;
    path.back = direction(points[0], points[1]);
    path.departure = direction(points[last], points[last - 1]);
    path.through.clear();
    for (std::size_t k = last - 1; k >= 1; --k)
      if (sequence.events[k] >= 0)
        path.through.push_back({static_cast<ice::Index>(sequence.events[k]), direction(points[k], points[k + 1]),
                                direction(points[k], points[k - 1])});
    visit(v, path);
  }
}

}  // namespace ice_bench
