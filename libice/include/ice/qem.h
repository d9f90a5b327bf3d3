#pragma once
/// \file qem.h
/// The QEM baseline: extrinsic simplification by quadric error metrics (Garland–Heckbert) through
/// OpenMesh's Decimater with its quadric module, plus a map from every input vertex to a point on the
/// coarse mesh, so that the same prolongation P as for ICE (ice/prolongation.h) exists.
///
/// Simplification. OpenMesh's `DecimaterT` with `ModQuadricT` as the priority module performs
/// *halfedge* collapses (v0 → v1, v1 keeps its position), cheapest quadric error first, down to exactly
/// `target` vertices. The coarse vertices are therefore a subset of the input vertices, at their input
/// positions (`to_input`, `from_input`), as for ICE. A binary `ModNormalFlippingT` guard (face normals
/// may turn by at most `max_normal_deviation_degrees`) keeps the coarse mesh from folding over, as any
/// sensible QEM set-up does; if the guarded run cannot reach the target (every remaining collapse is
/// illegal), the decimation continues without the guard and `guard_relaxed` says so. OpenMesh refuses
/// collapses that would change the topology (link condition, boundary rules), so a target below what
/// the topology allows stops early (`target_reached == false`).
///
/// The map: CLOSEST-POINT PROJECTION, not successive tracking. A surviving input vertex maps to
/// itself (exactly: a coarse face around it with barycentric coordinate 1 at its corner). A collapsed
/// input vertex maps to the closest point of the coarse mesh (Euclidean distance in R³), restricted to
/// coarse faces of its own connected component, found with an axis-aligned bounding-box tree over the
/// coarse faces (`TriangleBvh`, median splits; exact nearest-triangle query with box pruning). The
/// barycentric coordinates of a closest point are in [0, 1] by construction. Known weakness of
/// projection (why the ICE paper's authors tracked points through every collapse in their multigrid
/// work): where the coarse surface passes close to another part of the fine surface (thin parts,
/// deep folds), a fine vertex can land on the wrong sheet, and the map is not guaranteed bijective.
/// `QemResult::max_distance` / `mean_distance` report how far points moved.
///
/// Coarse operators for the PDE comparison come from the coarse mesh's own positions
/// (`qem_extrinsic_mesh`: faces + extrinsic lengths) or from its intrinsic Delaunay triangulation
/// (`qem_intrinsic_delaunay_mesh`: the same vertices, edges flipped intrinsically until Delaunay).
/// Both keep the QEM vertex set and numbering, so P is the same for both; only the operators change.
#include <array>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "ice/intrinsic_triangulation.h"
#include "ice/mesh.h"

namespace ice {

struct QemOptions {
  /// Stop at this many vertices (0: use target_ratio, ⌈ratio·n⌉, as ice::coarsen does).
  Index target_vertices = 0;
  double target_ratio = 0;
  /// Input vertices never collapsed (they keep their position and survive).
  std::vector<Index> locked_vertices;
  /// false: boundary vertices are locked too.
  bool remove_boundary = true;
  /// Normal-flip guard in degrees (≤ 0: no guard).
  double max_normal_deviation_degrees = 90;
};

/// Where one input vertex lies on the QEM mesh.
struct QemPoint {
  Index coarse_vertex = kInvalid;         ///< the coarse vertex when the input vertex survives
  Index face = kInvalid;                  ///< a coarse face containing the point
  std::array<double, 3> bary{0, 0, 0};    ///< barycentric coordinates w.r.t. that face's corners
  double distance = 0;                    ///< |input position − mapped point| (0 for survivors)
};

struct QemResult {
  TriangleMesh coarse;                    ///< coarse positions (input positions of survivors) and faces (CCW)
  std::vector<Index> to_input;            ///< coarse vertex → input vertex
  std::vector<Index> from_input;          ///< input vertex → coarse vertex, kInvalid if collapsed
  std::vector<QemPoint> map;              ///< one per input vertex
  Eigen::SparseMatrix<double> P;          ///< input vertices × coarse vertices (see ice/prolongation.h)
  Index input_vertices = 0;
  Index target_vertices = 0;
  Index collapses = 0;
  bool target_reached = false;
  bool guard_relaxed = false;             ///< the normal-flip guard had to be dropped to reach the target
  double max_distance = 0, mean_distance = 0;  ///< over collapsed vertices (absolute units)
  double decimate_seconds = 0;            ///< OpenMesh decimation (incl. building its mesh)
  double map_seconds = 0;                 ///< tree + closest points + P
};

/// QEM-simplifies `mesh` (a clean, oriented, manifold triangle mesh, e.g. from ice::load_mesh) and
/// maps every input vertex onto the result. Throws std::invalid_argument on a bad target or a mesh
/// OpenMesh cannot represent.
QemResult qem_coarsen(const TriangleMesh& mesh, const QemOptions& options);

/// P from a map: a survivor's row is e_{coarse_vertex}; any other row holds its barycentric
/// coordinates in the columns of its face's corners (exact zeros dropped). Rows sum to 1.
Eigen::SparseMatrix<double> prolongation_from_map(const std::vector<QemPoint>& map, const Faces& coarse_faces,
                                                  Index coarse_vertices);

/// The QEM mesh as a CompactMesh with extrinsic lengths (|x_i − x_j|), to_input/from_input as in
/// the result. Same vertex numbering as result.coarse.
CompactMesh qem_extrinsic_mesh(const QemResult& result);

/// The intrinsic Delaunay triangulation of the QEM mesh (IntrinsicTriangulation::from_mesh,
/// flip_to_delaunay, compact): same vertices and numbering, so result.P applies unchanged; the faces
/// differ (and need not match result.map's faces). `flips` receives the number of flips.
/// Throws std::invalid_argument when the QEM mesh has a degenerate face.
CompactMesh qem_intrinsic_delaunay_mesh(const QemResult& result, int* flips = nullptr);

/// An axis-aligned bounding-box tree over the triangles of an extrinsic mesh, answering exact
/// closest-point queries. Optional per-face labels restrict a query to faces with a given label.
class TriangleBvh {
 public:
  TriangleBvh(const Positions& V, const Faces& F, std::vector<Index> face_labels = {});

  struct Hit {
    Index face = kInvalid;                ///< kInvalid when no face qualifies
    std::array<double, 3> bary{0, 0, 0};  ///< of the closest point, w.r.t. F(face, 0..2), each in [0, 1]
    double squared_distance = 0;
  };
  /// Closest point on the faces (with label == `label` unless label == kInvalid).
  Hit closest_point(const Eigen::Vector3d& p, Index label = kInvalid) const;

  Index num_nodes() const { return static_cast<Index>(nodes_.size()); }

 private:
  struct Node {
    Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
    Index first = 0, count = 0;  ///< leaf: faces order_[first, first+count)
    Index left = kInvalid, right = kInvalid;
  };
  Index build(Index first, Index count, std::vector<Eigen::Vector3d>& centroids);
  Positions V_;  // copies: the tree does not depend on the caller's arrays
  Faces F_;
  std::vector<Index> labels_;
  std::vector<Index> order_;
  std::vector<Node> nodes_;
};

/// Closest point of triangle (a, b, c) to p: barycentric coordinates (each in [0, 1], summing to 1).
std::array<double, 3> closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                                const Eigen::Vector3d& b, const Eigen::Vector3d& c);

}  // namespace ice
