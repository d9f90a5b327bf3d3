#pragma once
/// \file point_cloud.h
/// Triangles for a point cloud, so that it can be solved on like a mesh: each point's local Delaunay
/// fan (Sharp & Crane, "A Laplacian for Nonmanifold Triangle Meshes", SGP 2020, §5.3). The union of
/// the fans is a triangle soup, non-manifold and inconsistently oriented in general, whose tufted
/// cover (ice/tufted_cover.h) is the point cloud's intrinsic triangulation.
///
/// Sharp & Crane keep each triangle once per fan it appears in (up to three times) and divide the
/// operators by 3; here each distinct triangle is kept once. Where the fans of a triangle's three
/// points agree, the two give the same operator, and on a consistently sampled surface the soup is
/// then the manifold mesh itself, a third of the size; where the fans disagree (e.g. both diagonals
/// of a nearly cocircular quad), the union counts each such triangle fully.
#include <vector>

#include "ice/mesh.h"

namespace ice {

/// Options of `point_cloud_triangles`.
struct PointCloudOptions {
  /// Neighbours of each point whose projection onto the point's tangent plane (the least-squares plane
  /// of the point and its neighbours) is triangulated; the paper's default. At most n − 1 are used.
  int neighbours = 30;
  /// Threads of the per-point pass (0: one per hardware thread). The result does not depend on it.
  int threads = 0;
};

/// The triangles of every point's local Delaunay fan: the Delaunay triangles incident to point i in the
/// triangulation of i and its nearest neighbours projected onto i's tangent plane, each oriented
/// counter-clockwise in that plane; every distinct triangle (vertex set) once, in the orientation of
/// the lowest point whose fan has it; triangles of zero area (ice::is_degenerate_triangle) left out.
/// Faces are sorted (lexicographically by their corners as stored).
/// Preconditions (std::invalid_argument otherwise): `points` is n × 3 with n ≥ 3, finite, no two points
/// at the same position; options.neighbours ≥ 2.
/// Postcondition: every point lies on a face; otherwise std::invalid_argument names the first point
/// that does not (its neighbours and it lie on one line).
Faces point_cloud_triangles(const Positions& points, const PointCloudOptions& options = {});

}  // namespace ice
