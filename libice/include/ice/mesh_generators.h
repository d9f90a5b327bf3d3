#pragma once
/// \file mesh_generators.h
/// Procedural test meshes (sphere, torus, disk, genus-2 plate) and Loop subdivision.
///
/// Every generator returns a manifold, consistently oriented `TriangleMesh` whose triangles are
/// counter-clockwise seen from outside (closed surfaces have positive signed volume; the disk faces +z).
#include <cstdint>

#include "ice/mesh.h"

namespace ice {

/// Icosphere: a regular icosahedron, midpoint-subdivided `subdivisions` times, every vertex projected
/// onto the sphere of radius `radius` centred at the origin.
/// Counts: V = 10·4^s + 2, F = 20·4^s. Euler characteristic 2.
/// Preconditions: subdivisions >= 0, radius > 0 (throws std::invalid_argument otherwise).
TriangleMesh make_icosphere(int subdivisions, double radius = 1.0);

/// Torus of revolution around the z axis with centre-line radius `major_radius` and tube radius
/// `minor_radius`; `major_segments` × `minor_segments` quads, each split into two triangles.
/// Counts: V = major·minor, F = 2·major·minor. Euler characteristic 0.
/// Preconditions: major_segments >= 3, minor_segments >= 3, major_radius > minor_radius > 0.
TriangleMesh make_torus(int major_segments, int minor_segments, double major_radius,
                        double minor_radius);

/// Planar triangulated disk in the z = 0 plane, centred at the origin. Ring k (1..rings) carries 6k
/// vertices at radius k·radius/rings; consecutive rings are zipped together by angle, which gives
/// nearly equilateral triangles. If `jitter` > 0 every interior vertex is moved by a uniformly random
/// offset of length at most jitter·(radius/rings), drawn from a std::mt19937 seeded with `seed`, so the
/// mesh is not too regular; boundary vertices stay on the circle.
/// Counts: V = 1 + 3·rings·(rings+1), F = 6·rings². Euler characteristic 1.
/// Preconditions: rings >= 1, radius > 0, 0 <= jitter <= 0.3 (larger jitter could fold triangles).
TriangleMesh make_flat_disk(int rings, double radius = 1.0, double jitter = 0.0,
                            std::uint32_t seed = 1);

/// Genus-2 surface: the boundary of a 5×3×1 plate of unit voxels with the two voxels (1,1,0) and
/// (3,1,0) removed (two holes). Every 2×2 block of the plate keeps 3 voxels, so the boundary is a
/// manifold. Each unit voxel face is split into `cells_per_unit`² squares, each square into two
/// triangles. The plate spans [0,5]×[0,3]×[0,1] scaled by `scale`.
/// Euler characteristic -2.
/// Preconditions: cells_per_unit >= 1, scale > 0.
TriangleMesh make_genus2(int cells_per_unit = 1, double scale = 1.0);

/// Loop subdivision (Loop 1987), applied `levels` times. Each level splits every triangle into four
/// and smooths: interior vertices with Loop's weights β(n) = (5/8 − (3/8 + ¼cos(2π/n))²)/n, interior
/// edge points 3/8·(a+b) + 1/8·(c+d); boundary vertices 3/4·v + 1/8·(b₀+b₁), boundary edge points
/// the midpoint, so boundary curves are subdivided as cubic B-splines independent of the interior.
/// Vertices where the boundary is not a single curve (more than two boundary edges) stay fixed.
/// Counts after one level: V' = V + E, F' = 4F. Vertex order: old vertices keep their indices, edge
/// points follow. Runs in O(F log F) per level (edges found by sorting corner keys).
/// Preconditions: edge-manifold input (every edge has one or two incident faces; throws
/// std::invalid_argument otherwise), levels >= 0.
TriangleMesh loop_subdivide(const TriangleMesh& mesh, int levels = 1);

}  // namespace ice
