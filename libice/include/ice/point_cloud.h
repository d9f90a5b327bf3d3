#pragma once
/// \file point_cloud.h
/// Triangles for a point cloud, so that it can be solved on like a mesh: its points' local Delaunay
/// fans (Sharp & Crane, "A Laplacian for Nonmanifold Triangle Meshes", SGP 2020, §5.3), made
/// consistent. The result is a triangle soup, inconsistently oriented (and here and there
/// non-manifold) in general, whose tufted cover (ice/tufted_cover.h) is the point cloud's intrinsic
/// triangulation.
///
/// The fans of a triangle's three corners need not agree: nearly cocircular neighbours, seen in
/// different tangent planes, take different diagonals, and the union of the fans then covers such a
/// place twice. Sharp & Crane keep every fan's triangles and divide the operators by 3; on the cover
/// such overlaps are folded sheets that ICE cannot remove vertices from (coarsening stalled far above
/// its target, with large errors, where the choice below does not: docs/measurements.md, "Point
/// clouds"). Here each distinct triangle is a candidate, and candidates are kept in
/// order of the number of fans that have them, then of their circumradius (the Delaunay choice of a
/// quad's diagonal), unless they cover, at one of their corners, directions of that corner's tangent
/// plane that a kept triangle covers already.
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
  /// Keep the two sides of thin parts apart: the tangent plane from the nearest third of the
  /// neighbours (all of them where those nearly lie on a line), and neighbours 45° or more off it
  /// left out of the fan (unless the fan would be left empty). For clouds whose thin parts (limbs,
  /// fins, tubes) are sampled only a few points across, where the neighbours reach across and their
  /// triangles join the two sides; it also splits the two faces of a wall sampled on both sides, and
  /// can leave a thin edge's or limb's sides unjoined (a cloud of more components). Off by default:
  /// scans' coarse errors rose with it, and 3 of 55 clouds drawn from CGAL's meshes fell apart
  /// (docs/measurements.md, "Clouds: thin parts kept apart").
  bool separate_thin_parts = false;
};

/// The consistent local Delaunay triangles of a point cloud. A point's fan: the Delaunay triangles
/// incident to point i in the triangulation of i and its nearest neighbours projected onto i's
/// tangent plane, oriented counter-clockwise in that plane (see PointCloudOptions::separate_thin_parts);
/// triangles of zero area (ice::is_degenerate_triangle) left out, and so are those whose
/// circumcentre lies farther from i than its farthest neighbour (slivers along the neighbourhood's
/// hull) unless all of the fan's do. Of the fans' distinct triangles (each in the orientation of the
/// lowest point whose fan has it) those the choice above keeps, plus, for a point left on no
/// triangle, its fan's. Faces are sorted (lexicographically by their corners as stored); the result
/// does not depend on options.threads.
/// Preconditions (std::invalid_argument otherwise): `points` is n × 3 with n ≥ 3, finite, no two points
/// at the same position; options.neighbours ≥ 2.
/// Postcondition: every point lies on a face; otherwise std::invalid_argument names the first point
/// that does not (its neighbours and it lie on one line).
Faces point_cloud_triangles(const Positions& points, const PointCloudOptions& options = {});

}  // namespace ice
