#include "ice/triangle_geometry.h"
#include "ice/vertex_star.h"

#include <cmath>
#include <type_traits>

namespace ice {
double VertexStar::flat_angle_sum() const { return boundary ? kPi : 2 * kPi; }

bool has_distinct_neighbours(const VertexStar& star) {
  // Compared against a fixed-width array (8 or 16) padded with distinct non-vertices, so the inner
  // loop has a constant trip count (unrolled, no mispredicted exits): a search per neighbour
  // mispredicts.
  const int count = static_cast<int>(star.corners.size());
  const int neighbours = count + (star.boundary ? 1 : 0);
  const auto distinct = [&](auto width) {
    constexpr int kWidth = decltype(width)::value;
    Index ids[kWidth];
    for (int k = 0; k < kWidth; ++k) ids[k] = -2 - k;
    for (int k = 0; k < count; ++k) ids[k] = star.corners[k].out_vertex;
    if (star.boundary) ids[count] = star.corners[count - 1].in_vertex;
    bool all = true;
    for (int k = 0; k < neighbours; ++k) {
      int same = 0;
      for (int j = 0; j < kWidth; ++j) same += ids[j] == ids[k];
      all &= (same == 1) & (ids[k] != star.centre);
    }
    return all;
  };
  if (count == 0) return false;
  if (neighbours <= 8) return distinct(std::integral_constant<int, 8>());
  if (neighbours <= 16) return distinct(std::integral_constant<int, 16>());
  return false;
}

void star_areas(VertexStar& star, double log_scale) {
  const double half = std::exp(0.5 * log_scale);
  const double scale[3] = {1.0, half, half * half};
  for (StarCorner& c : star.corners) {
    c.four_area = 4.0 * triangle_area(c.l_out, c.l_in, c.l_opposite);
    c.four_area_flat = 4.0 * triangle_area(c.l_out * scale[c.m_out], c.l_in * scale[c.m_in], c.l_opposite * scale[c.m_opposite]);
  }
}

FlattenResult flatten_star(VertexStar& star, double tolerance, double initial_log_scale) {
  FlattenResult result;
  const double target = star.flat_angle_sum();
  const int count = static_cast<int>(star.corners.size());
  StarCorner* corners = star.corners.data();

  // Θ(u) − target, with the faces' areas at u left in four_area_flat. Near the target
  // (|Θ(0) − target| < π/2, and Newton moves Θ monotonically towards it) the residual is the
  // argument of the product of the corners' unit complex numbers times e^{−i·target}: one atan2 per
  // evaluation instead of one per corner. False when a face degenerates.
  const bool use_product = std::abs(star.angle_sum - target) < 0.5 * kPi;
  const auto evaluate = [&](double u, bool with_theta, double& residual) -> bool {
    const double half = std::exp(0.5 * u);
    const double scale[3] = {1.0, half, half * half};
    double theta = 0;
    double re = 1, im = 0;  // running product of e^{iθ_c}
    for (int k = 0; k < count; ++k) {
      StarCorner& s = corners[k];
      const double a = s.l_out * scale[s.m_out], b = s.l_in * scale[s.m_in], o = s.l_opposite * scale[s.m_opposite];
      const double four_area = 4.0 * triangle_area(a, b, o);
      if (!(four_area > 0)) return false;
      s.four_area_flat = four_area;
      if (with_theta) {
        const double cosine_part = (a - o) * (a + o) + b * b;  // = 2ab·cos θ; 4·area = 2ab·sin θ
        if (use_product) {
          const double inv = 1.0 / (2 * a * b);
          const double cr = cosine_part * inv, ci = four_area * inv;
          const double nr = re * cr - im * ci;
          im = re * ci + im * cr;
          re = nr;
        } else {
          theta += std::atan2(four_area, cosine_part);
        }
      }
    }
    if (with_theta) {
      // e^{iΘ}·e^{−i·target}: target is π (boundary) or 2π, so the factor is −1 or 1.
      residual = use_product ? std::atan2(target == kPi ? -im : im, target == kPi ? -re : re) : theta - target;
    }
    return true;
  };
  // dΘ/du at the u of the latest successful evaluate (whose areas are in four_area_flat); only
  // needed when another Newton step follows.
  const auto derivative_at = [&](double u) {
    const double half = std::exp(0.5 * u);
    const double scale[3] = {1.0, half, half * half};
    double derivative = 0;
    for (int k = 0; k < count; ++k) {
      const StarCorner& s = corners[k];
      const double a = s.l_out * scale[s.m_out], b = s.l_in * scale[s.m_in], o = s.l_opposite * scale[s.m_opposite];
      // Corners of this face: at v (between a and b), x = head(h) (between a and o), y = tail(prev h).
      const double inverse_area = 1.0 / s.four_area_flat;
      const double cot_x = ((a - b) * (a + b) + o * o) * inverse_area, cot_y = ((b - a) * (b + a) + o * o) * inverse_area;
      derivative += -0.5 * (cot_x + cot_y) + (s.m_out == 2 ? 0.5 * cot_y : 0.0) + (s.m_in == 2 ? 0.5 * cot_x : 0.0);
    }
    return derivative;
  };

  // From u = 0 the stored angle sum is Θ(0): no trigonometry, and the areas computed are the
  // star's areas as read. A warm start that degenerates a face falls back to u = 0.
  double u = initial_log_scale, residual = star.angle_sum - target;
  if (u != 0 && !evaluate(u, true, residual)) u = 0;
  if (u == 0) {
    if (!evaluate(0, false, residual)) return result;
    residual = star.angle_sum - target;
    for (StarCorner& s : star.corners) s.four_area = s.four_area_flat;
  } else {
    for (StarCorner& s : star.corners) s.four_area = 4.0 * triangle_area(s.l_out, s.l_in, s.l_opposite);
  }
  for (int iteration = 0; iteration < 60; ++iteration) {
    if (std::abs(residual) <= tolerance * target) {
      result.success = true;
      result.log_scale = u;
      result.iterations = iteration;
      return result;
    }
    const double derivative = derivative_at(u);
    if (!(derivative < 0)) return result;
    // Damped Newton: halve the step until the triangles stay valid and the residual shrinks.
    double step = -residual / derivative;
    bool accepted = false;
    for (int halving = 0; halving < 40 && !accepted; ++halving, step *= 0.5) {
      double next_residual;
      if (evaluate(u + step, true, next_residual) && std::abs(next_residual) < std::abs(residual)) {
        u += step, residual = next_residual;
        accepted = true;
      }
    }
    if (!accepted) {
      // No progress possible in floating point: accept when already at round-off level (the
      // rejected trials overwrote the flat areas, so evaluate the accepted scale once more).
      if (std::abs(residual) <= 1e-11 * target && evaluate(u, false, residual)) {
        result.success = true;
        result.log_scale = u;
        result.iterations = iteration;
      }
      return result;
    }
  }
  return result;
}

}  // namespace ice
