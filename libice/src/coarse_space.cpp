#include "ice/coarse_space.h"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "ice/prolongation.h"
#include "ice/qem.h"

namespace ice {

const char* to_string(CoarseningMethod method) { return method == CoarseningMethod::qem ? "qem" : "ice"; }

const char* to_string(QemGeometry geometry) {
  return geometry == QemGeometry::intrinsic_delaunay ? "intrinsic_delaunay" : "extrinsic";
}

const char* to_string(FineGeometry geometry) {
  return geometry == FineGeometry::intrinsic_delaunay ? "intrinsic_delaunay" : "input";
}

Index CoarseSpaceSummary::removed() const { return ice ? ice->removed : qem ? qem->collapses : 0; }

StopReason CoarseSpaceSummary::stop_reason() const {
  if (ice) return ice->stop_reason;
  return target_reached ? StopReason::TargetReached : StopReason::NothingRemovable;
}

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

// The sizes every summary carries, from the finished space.
void record_sizes(CoarseSpace& space, CoarseningMethod method, Index input_vertices) {
  space.summary.method = method;
  space.summary.input_vertices = input_vertices;
  space.summary.coarse_vertices = space.mesh.num_vertices();
  space.summary.coarse_faces = static_cast<Index>(space.mesh.F.rows());
}

CoarseSpace ice_coarse_space(const TriangleMesh& mesh, const CoarseSpaceOptions& options) {
  IntrinsicTriangulation T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  CoarseSpace space;
  const CoarsenResult result = coarsen(T, options.coarsen);
  space.mesh = T.compact();
  space.P = prolongation(T, space.mesh);
  space.summary.target_reached = result.stop_reason == StopReason::TargetReached;
  space.summary.ice = result;
  if (options.keep_method_state) space.triangulation = std::move(T);
  record_sizes(space, CoarseningMethod::ice, static_cast<Index>(mesh.V.rows()));
  return space;
}

}  // namespace

CoarseSpace coarse_space_from_qem(QemResult qem, QemGeometry geometry, bool keep_method_state) {
  const auto start = Clock::now();
  CoarseSpace space;
  QemOutcome outcome;
  if (geometry == QemGeometry::intrinsic_delaunay) {
    int flips = 0;
    try {
      space.mesh = qem_intrinsic_delaunay_mesh(qem, &flips);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("the QEM mesh cannot be triangulated intrinsically: ") + e.what());
    }
    outcome.intrinsic_delaunay_flips = flips;
  } else {
    space.mesh = qem_extrinsic_mesh(qem);
  }
  space.P = std::move(qem.P);
  outcome.collapses = qem.collapses;
  outcome.guard_relaxed = qem.guard_relaxed;
  outcome.max_distance = qem.max_distance;
  outcome.mean_distance = qem.mean_distance;
  outcome.decimate_seconds = qem.decimate_seconds;
  outcome.map_seconds = qem.map_seconds;
  outcome.geometry = geometry;
  space.summary.target_reached = qem.target_reached;
  space.summary.qem = outcome;
  record_sizes(space, CoarseningMethod::qem, qem.input_vertices);
  if (keep_method_state) space.qem_result = std::move(qem);
  space.summary.seconds = seconds_since(start);
  return space;
}

CoarseSpace build_coarse_space(const TriangleMesh& mesh, const CoarseSpaceOptions& options) {
  const auto start = Clock::now();
  CoarseSpace space;
  if (options.method == CoarseningMethod::qem) {
    if (std::isfinite(options.coarsen.max_error))
      throw std::invalid_argument("build_coarse_space: max_error bounds the ICE error metric; QEM takes a vertex target");
    QemOptions q;
    q.target_vertices = options.coarsen.target_vertices;
    q.target_ratio = options.coarsen.target_ratio;
    q.locked_vertices = options.coarsen.locked_vertices;
    q.remove_boundary = options.coarsen.remove_boundary;
    space = coarse_space_from_qem(qem_coarsen(mesh, q), options.qem_geometry, options.keep_method_state);
  } else {
    space = ice_coarse_space(mesh, options);
  }
  space.summary.seconds = seconds_since(start);
  return space;
}

std::vector<CoarsePoint> fine_to_coarse_map(const CoarseSpace& space) {
  std::vector<CoarsePoint> map;
  if (space.qem_result) {
    if (space.summary.qem && space.summary.qem->geometry != QemGeometry::extrinsic)
      throw std::invalid_argument(
          "fine_to_coarse_map: the closest-point map of QEM lies in the QEM mesh's faces, not in the faces of its "
          "intrinsic Delaunay triangulation (see CoarseSpace::qem_result->map)");
    map.reserve(space.qem_result->map.size());
    for (const QemPoint& q : space.qem_result->map) map.push_back({q.coarse_vertex, q.face, q.bary});
    return map;
  }
  if (!space.triangulation)
    throw std::invalid_argument("fine_to_coarse_map: build the coarse space with keep_method_state");
  const IntrinsicTriangulation& T = *space.triangulation;
  // Face slot -> compact face (compact() lists the live slots in order, corners from halfedge(f)).
  std::vector<Index> compact_face(static_cast<std::size_t>(T.num_face_slots()), kInvalid);
  Index next_face = 0;
  for (Index f = 0; f < T.num_face_slots(); ++f)
    if (T.face_alive(f)) compact_face[f] = next_face++;
  map.resize(static_cast<std::size_t>(T.num_input_vertices()));
  for (Index p = 0; p < T.num_input_vertices(); ++p) {
    const SurfacePoint s = T.location(p);
    CoarsePoint& point = map[p];
    point.coarse_vertex = space.mesh.from_input[p];
    Index face = s.face;
    point.bary = s.bary;
    if (s.is_vertex()) {  // the face of its outgoing half-edge, weight 1 at that corner
      const Index h = T.vertex_halfedge(s.vertex);
      face = T.face(h);
      Index g = T.halfedge(face);
      point.bary = {0, 0, 0};
      for (int k = 0; k < 3; ++k, g = T.next(g))
        if (g == h) point.bary[k] = 1;
    }
    point.face = compact_face[face];
  }
  return map;
}

FineMesh fine_mesh(const TriangleMesh& mesh, FineGeometry geometry) {
  FineMesh fine;
  fine.geometry = geometry;
  if (geometry == FineGeometry::input) {
    fine.F = mesh.F;
    fine.L = face_lengths_from_positions(mesh.V, mesh.F);
    return fine;
  }
  IntrinsicTriangulation T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  fine.flips = T.flip_to_delaunay();
  CompactMesh compact = T.compact();  // no vertex removed: compact indices are input indices
  fine.F = std::move(compact.F);
  fine.L = std::move(compact.L);
  return fine;
}

}  // namespace ice
