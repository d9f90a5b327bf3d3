#pragma once
/// \file mesh_repair.h
/// Cheap, safe repairs of raw polygon input. "Safe" means: a repair never moves a vertex, never
/// invents geometry beyond splitting a polygon along its own diagonals or giving each fan of faces at
/// a non-manifold vertex its own copy of that vertex (the surfaces only touched there), and every
/// change is counted in the `RepairLog`. Anything that would need a judgement call (non-manifold
/// edges, non-orientable surfaces, non-finite coordinates, out-of-range indices) is left in place and
/// shows up in the final report, so the caller can refuse the mesh with a precise message.
#include <cstddef>
#include <string>
#include <vector>

#include "ice/mesh_validation.h"

namespace ice {

/// Which optional repairs `repair_mesh` may perform.
struct RepairOptions {
  /// Merge vertices with exactly equal positions (off by default: coincident vertices may be intended,
  /// e.g. a cut seam, and welding them can create non-manifold vertices).
  bool weld_duplicate_positions = false;
  /// Split polygons with more than three corners into triangles.
  bool triangulate_polygons = true;
};

/// What `repair_mesh` changed.
struct RepairLog {
  std::size_t welded_vertices = 0;           ///< Vertices merged into an earlier coincident one.
  std::size_t triangulated_polygons = 0;     ///< Polygons split into triangles.
  std::size_t collapsed_repeated_corners = 0;///< Cyclically consecutive repeated corners removed.
  std::size_t removed_degenerate_faces = 0;  ///< Faces with < 3 distinct corners after collapsing.
  std::size_t removed_zero_area_faces = 0;
  std::size_t removed_duplicate_faces = 0;
  std::size_t removed_unreferenced_vertices = 0;
  /// Copies made of non-manifold vertices: each extra fan of faces around a vertex gets its own copy
  /// (same position and file id), when every face is a triangle and every edge manifold.
  std::size_t split_non_manifold_vertices = 0;
  std::size_t flipped_faces = 0;             ///< Faces reversed to make orientation consistent.
  std::size_t reoriented_components = 0;

  bool empty() const;
  /// One human-readable line per non-zero entry.
  std::vector<std::string> summary() const;
};

/// Result of `repair_mesh`: the repaired soup, where each element came from, and its validation.
struct RepairResult {
  PolygonSoup soup;
  std::vector<Index> source_vertex;  ///< source_vertex[i]: input vertex id of output vertex i.
  std::vector<Index> source_face;    ///< source_face[f]: input face id output face f was cut from.
  RepairLog log;
  ValidationReport report;         ///< Validation of `soup`; `report.clean()` says if repair succeeded.
};

/// Apply the safe repairs, in this order:
///  1. weld exactly coincident vertices (only if `options.weld_duplicate_positions`);
///  2. remove cyclically consecutive repeated corners; drop faces left with < 3 distinct corners;
///  3. triangulate polygons (fan from the corner that maximises the worst triangle's shape);
///  4. drop zero-area triangles, then duplicate faces (same vertex set; the first copy is kept);
///  5. drop unreferenced vertices (skipped while out-of-range indices remain: they cannot be remapped);
///  6. if the result is manifold, re-orient every orientable component consistently: closed components
///     so that their signed volume is positive (outward normals), open ones so that the fewest faces flip.
/// Never throws on bad data. Non-manifold, non-orientable, non-finite or out-of-range input is passed
/// through and reported in `RepairResult::report`.
RepairResult repair_mesh(const PolygonSoup& soup, const RepairOptions& options = {});

}  // namespace ice
