#pragma once
/// \file vertex_star.h
/// A snapshot of one vertex's star (its corners' edge lengths and neighbours), read in a single walk
/// by IntrinsicTriangulation::read_star, and the one-vertex flattening (CETM) solved on it. Sits
/// below the triangulation: nothing here sees the half-edge structure.
///
/// Why a snapshot: a cost evaluation in the coarsener needs the star three times (Newton for the
/// flattening scale, the curvature change at every neighbour, the transport to every neighbour).
/// Walking the half-edge structure once into a contiguous array, and keeping the per-corner areas
/// Newton computed, avoids both the repeated pointer chasing and the repeated square roots.
///
/// Scaling model: flattening v multiplies every edge incident to v by e^{u/2} (a self-edge, incident
/// twice, by e^u). The star is flat when its angle sum is 2π (interior) or π (boundary).
#include <cstdint>
#include <vector>

#include "ice/mesh.h"
#include "ice/triangle_geometry.h"

namespace ice {

/// One corner of the star of a centre vertex v: the face of the outgoing half-edge h.
struct StarCorner {
  Index halfedge = kInvalid;       ///< h, outgoing from v
  Index in_halfedge = kInvalid;    ///< prev(h), ending at v (its twin is the next outgoing half-edge)
  Index out_vertex = kInvalid;     ///< head(h)
  Index in_vertex = kInvalid;      ///< tail(prev(h))
  double l_out = 0, l_in = 0, l_opposite = 0;  ///< lengths of h, prev(h), next(h)
  /// How many endpoints of each of those edges are v (1 or 2 for h and prev(h); 0–2 for next(h)).
  std::uint8_t m_out = 1, m_in = 1, m_opposite = 0;
  double four_area = 0;       ///< 4 × the face's area as read (filled by flatten_star)
  double four_area_flat = 0;  ///< 4 × the face's area once flattened (filled by flatten_star)
};

/// Outcome of flattening one vertex.
struct FlattenResult {
  bool success = false;
  double log_scale = 0;  ///< u: the vertex's edges were scaled by e^{u/2} (self-edges by e^u)
  int iterations = 0;
};

struct VertexStar {
  Index centre = kInvalid;
  bool boundary = false;
  double angle_sum = 0;  ///< Θ_v as stored by the triangulation
  std::vector<StarCorner> corners;
  /// 2π for an interior vertex, π on the boundary.
  double flat_angle_sum() const;
};

/// True when the star's neighbours — every corner's out_vertex and, at a boundary vertex, the last
/// corner's in_vertex — are pairwise distinct and none is the centre (no self- or multi-edges at
/// the centre: the usual case). Then neighbour k (k = 0..corners−1, plus the extra boundary one) is
/// corner k's out_vertex, and every face of the star is a different face. Branch-free for up to 16
/// neighbours (false beyond).
bool has_distinct_neighbours(const VertexStar& star);

/// Solves for the log-scale u that makes the star flat, by damped Newton from `initial_log_scale`,
/// to |Θ(u) − flat| ≤ tolerance × flat. On success also fills every corner's `four_area` (at u = 0)
/// and `four_area_flat` (at the returned u). On failure (no valid scale: a face would degenerate)
/// success is false. Deterministic.
FlattenResult flatten_star(VertexStar& star, double tolerance, double initial_log_scale = 0);

/// Fills `four_area` and `four_area_flat` for a known scale u (for callers that cached u).
void star_areas(VertexStar& star, double log_scale);

/// How much the two corners of a star face away from the centre shrink when the star is scaled by
/// e^{u/2} (self-edges by e^u): θ(before) − θ(after) at out_vertex and at in_vertex, i.e. the
/// curvature those vertices gain. Needs the corner's four_area and four_area_flat; `half_scale` is
/// e^{u/2}. Each difference is the argument of z_before·conj(z_after), z = (cosine part) + i·4·area,
/// so it costs no atan2 for the usual small changes and loses no digits to cancellation.
struct CornerAngleChange {
  double at_out = 0, at_in = 0;
};
inline CornerAngleChange corner_angle_change(const StarCorner& corner, double half_scale) {
  const double scale[3] = {1.0, half_scale, half_scale * half_scale};
  const double a = corner.l_out, b = corner.l_in, o = corner.l_opposite;
  const double a2 = a * scale[corner.m_out], b2 = b * scale[corner.m_in], o2 = o * scale[corner.m_opposite];
  const double area4 = corner.four_area, area4_after = corner.four_area_flat;
  const double cos_out = (a - b) * (a + b) + o * o, cos_out_after = (a2 - b2) * (a2 + b2) + o2 * o2;
  const double cos_in = (b - a) * (b + a) + o * o, cos_in_after = (b2 - a2) * (b2 + a2) + o2 * o2;
  return {atan2_small(area4 * cos_out_after - cos_out * area4_after, cos_out * cos_out_after + area4 * area4_after),
          atan2_small(area4 * cos_in_after - cos_in * area4_after, cos_in * cos_in_after + area4 * area4_after)};
}

}  // namespace ice
