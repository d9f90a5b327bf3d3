#pragma once
/// \file refinement.h
/// Intrinsic Delaunay refinement (the ICE paper's §6.3; Chew's second algorithm on an intrinsic
/// triangulation): insert the circumcentre of a face with an angle below the bound, found by tracing
/// a straight line from the face's barycentre across the intrinsic faces; when that line reaches the
/// boundary, split the boundary edge it hits at its midpoint instead; restore Delaunay by flips after
/// each insertion. Every input vertex stays tracked (insertions and flips re-locate the points
/// exactly), so the prolongation of the refined mesh follows (ice/prolongation.h: inserted vertices
/// get columns of their own).
///
///   ice::RefinementOptions options;            // defaults: 25°, at most 1.5 times the vertices
///   const ice::RefinementResult r = ice::refine_delaunay(T, options);
///
/// Termination: every insertion is counted against `max_vertex_ratio`; faces whose smallest angle
/// sits at a vertex with an angle sum below 60° (a sharp cone or boundary corner, where no
/// triangulation has all angles above a bound near Θ/2 and Delaunay refinement would spiral) are
/// left as they are and counted, and so are faces with a side shorter than 1e-3 × the mean side at the
/// start (sliver components of scans) and faces whose circumcentre would make a face thinner than
/// a flip may (IntrinsicTriangulation::insert_vertex refuses it).
#include <array>
#include <vector>

#include "ice/intrinsic_triangulation.h"

namespace ice {

struct RefinementOptions {
  /// Smallest corner angle wanted, degrees, in (0, 30]: Chew's algorithm terminates for bounds up to
  /// about 30° away from small input angles. Throws std::invalid_argument outside.
  double min_angle_degrees = 25;
  /// Stop once the live vertices reach this multiple of their count at the start (≥ 1).
  double max_vertex_ratio = 1.5;
};

struct RefinementResult {
  Index inserted = 0;          ///< vertices inserted (circumcentres and boundary midpoints)
  Index boundary_splits = 0;   ///< of which boundary midpoints
  Index flips = 0;             ///< Delaunay flips (including the initial flip_to_delaunay)
  double min_angle_before = 0, min_angle_after = 0;  ///< degrees, over all live faces
  Index faces_below_bound = 0;  ///< after refinement
  Index sharp_vertex_faces = 0;  ///< of those, faces left because their small angle is at a sharp vertex
  Index tiny_faces = 0;          ///< of those, faces left because a side is below 1e-3 × the mean side
  bool bound_reached = false;  ///< every face has all angles ≥ the bound
  bool budget_exhausted = false;
};

/// Refines T (first flipped to intrinsic Delaunay) until every face's smallest angle is at least
/// options.min_angle_degrees, except faces whose small angle is at a vertex with Θ < 60°, or until
/// the vertex budget is spent. Postconditions: T is intrinsic Delaunay, validate() holds, every
/// input vertex is tracked, Gauss–Bonnet is unchanged (inserted vertices are flat: Θ = 2π, or π on
/// the boundary).
RefinementResult refine_delaunay(IntrinsicTriangulation& T, const RefinementOptions& options = {});

/// Smallest corner angle of the live faces of T, in degrees (180 for a mesh without faces).
double min_corner_angle_degrees(const IntrinsicTriangulation& T);

/// Where a vertex inserted by refinement lies on the input surface: a face of the input mesh
/// (a row of the `F` given to locate_inserted_vertices) and barycentric coordinates w.r.t. its corners
/// (each in [0, 1], summing to 1).
struct InputSurfacePoint {
  Index face = kInvalid;
  std::array<double, 3> bary{0, 0, 0};
};

/// The input-surface location of every live inserted vertex of T, in slot order. `F` are the input
/// faces in T's input vertex numbering. The location is read off the fine-to-coarse map: the input
/// triangles are laid out by the images of their vertices in the intrinsic faces around the inserted
/// vertex (unfolded), and the one containing it (or, at round-off, the nearest) gives the face and the
/// coordinates.
std::vector<InputSurfacePoint> locate_inserted_vertices(const IntrinsicTriangulation& T, const Faces& F);

}  // namespace ice
