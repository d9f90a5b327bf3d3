#pragma once
/// \file triangle_geometry.h
/// Geometry of a single triangle from its three side lengths, and small planar helpers.
///
/// Everything in ICE that needs angles, areas or layouts of a triangle goes through these functions,
/// so the numerical choices are made once:
///  - areas use Kahan's stable form of Heron's formula (sides sorted, parenthesised as he prescribes);
///  - angles use atan2(4·area, a² + b² − c²), accurate for needle and cap triangles alike, where
///    acos of the law of cosines loses half the digits near 0 and π;
///  - a violated triangle inequality is *not* clamped away: `triangle_inequality_holds` reports it
///    and callers decide (the area of such a "triangle" is reported as 0).
#include <algorithm>
#include <array>
#include <cmath>

namespace ice {

/// π, to double precision (one definition for libice, libfem and the tools).
constexpr double kPi = 3.14159265358979323846;

/// A point or vector of the plane (used for local layouts of faces and diamonds).
struct Vec2 {
  double x = 0, y = 0;
  Vec2 operator+(Vec2 o) const { return {x + o.x, y + o.y}; }
  Vec2 operator-(Vec2 o) const { return {x - o.x, y - o.y}; }
  Vec2 operator*(double s) const { return {x * s, y * s}; }
  double norm() const { return std::hypot(x, y); }
};

/// z component of the cross product (a × b).
inline double cross(Vec2 a, Vec2 b) { return a.x * b.y - a.y * b.x; }
/// Twice the signed area of the triangle (a, b, c): positive when counter-clockwise.
inline double orient2d(Vec2 a, Vec2 b, Vec2 c) { return cross(b - a, c - a); }

/// Sixteen times the squared area, by Kahan's stable Heron formula; negative when the triangle
/// inequality fails.
inline double heron_16_area_squared(double a, double b, double c) {
  // Sort so that hi >= mid >= lo, by min/max (branch-free: the order of a star's sides is
  // unpredictable, and this runs for every corner of every Newton step of every cost evaluation).
  const double larger = std::max(a, b), smaller = std::min(a, b);
  const double hi = std::max(larger, c), rest = std::min(larger, c);
  const double mid = std::max(smaller, rest), lo = std::min(smaller, rest);
  return (hi + (mid + lo)) * (lo - (hi - mid)) * (lo + (hi - mid)) * (hi + (mid - lo));
}

/// True when a, b, c are positive, finite and every side is strictly shorter than the sum of the
/// other two (a non-degenerate triangle).
inline bool triangle_inequality_holds(double a, double b, double c) {
  if (!(a > 0 && b > 0 && c > 0) || !std::isfinite(a + b + c)) return false;
  return heron_16_area_squared(a, b, c) > 0;
}

/// Area of the triangle with side lengths a, b, c (0 for degenerate or invalid input).
inline double triangle_area(double a, double b, double c) {
  const double q = heron_16_area_squared(a, b, c);
  return q > 0 ? 0.25 * std::sqrt(q) : 0.0;
}

/// Sine of the smallest angle of the triangle (0 when degenerate): a scale-free shape measure.
inline double smallest_angle_sine(double a, double b, double c) {
  // The smallest angle is opposite the shortest side; sin = 2·area / (product of the other two).
  const double longest = std::max({a, b, c}), shortest = std::min({a, b, c});
  const double middle = a + b + c - longest - shortest;
  return 2.0 * triangle_area(a, b, c) / (longest * middle);
}

/// The angle between sides a and b, i.e. opposite side c, in [0, π].
inline double angle_opposite(double a, double b, double c) {
  return std::atan2(4.0 * triangle_area(a, b, c), (a - c) * (a + c) + b * b);
}

/// atan2(y, x) for the usually tiny angle differences of local updates: a short odd series when
/// x > 0 and |y/x| < 0.02 (truncation below 1e-13 relative), atan2 otherwise.
inline double atan2_small(double y, double x) {
  if (x > 0 && std::abs(y) < 0.02 * x) {
    const double t = y / x, t2 = t * t;
    return t * (1 - t2 * (1.0 / 3 - t2 * (1.0 / 5 - t2 * (1.0 / 7))));
  }
  return std::atan2(y, x);
}

/// Cotangent of the angle between sides a and b (opposite side c). Infinite for a degenerate
/// triangle, as the formula says; callers on valid triangulations never see that.
inline double cot_opposite(double a, double b, double c) {
  return ((a - c) * (a + c) + b * b) / (4.0 * triangle_area(a, b, c));
}

/// The third corner of a triangle laid out in the plane: given corners p0 and p1 at distance
/// `base` (the known edge length), and the lengths d0 = |p2 − p0| and d1 = |p2 − p1|, returns p2 on
/// the left of the directed segment p0 → p1 (so (p0, p1, p2) is counter-clockwise).
inline Vec2 layout_third_point(Vec2 p0, Vec2 p1, double base, double d0, double d1) {
  const Vec2 along = (p1 - p0) * (1.0 / (p1 - p0).norm());
  const Vec2 left{-along.y, along.x};
  const double x = ((base - d1) * (base + d1) + d0 * d0) / (2.0 * base);
  const double y = 2.0 * triangle_area(base, d0, d1) / base;
  return p0 + along * x + left * y;
}

/// Barycentric coordinates of q in the triangle (p0, p1, p2) (which must have positive area).
/// Coordinates may be slightly negative for points on or just outside an edge.
inline std::array<double, 3> barycentric(Vec2 q, Vec2 p0, Vec2 p1, Vec2 p2) {
  const double total = orient2d(p0, p1, p2);
  const double b0 = orient2d(q, p1, p2) / total;
  const double b1 = orient2d(p0, q, p2) / total;
  return {b0, b1, 1.0 - b0 - b1};
}

/// Clamps round-off negatives of barycentric coordinates to 0 and renormalises to sum 1.
inline std::array<double, 3> clamp_barycentric(std::array<double, 3> b) {
  for (double& c : b) c = std::max(c, 0.0);
  const double sum = b[0] + b[1] + b[2];
  for (double& c : b) c /= sum;
  return b;
}

}  // namespace ice
