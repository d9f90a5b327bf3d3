#include "fem/geometry.h"

#include "ice/triangle_geometry.h"

#include <algorithm>
#include <cmath>

namespace fem {
namespace {

/// Throws unless (a, b, c) are positive finite lengths satisfying the triangle inequality up to
/// kTriangleInequalityTolerance·perimeter.
void check_face(Eigen::Index f, double a, double b, double c) {
  if (!(std::isfinite(a) && std::isfinite(b) && std::isfinite(c)) || !(a > 0 && b > 0 && c > 0))
    throw InvalidTriangle(f, "edge lengths must be positive and finite");
  const double slack = kTriangleInequalityTolerance * (a + b + c);
  if (a > b + c + slack || b > a + c + slack || c > a + b + slack)
    throw InvalidTriangle(f, "edge lengths violate the triangle inequality");
}

}  // namespace

void validate_lengths(const FaceLengths& L) {
  for (Eigen::Index f = 0; f < L.rows(); ++f) check_face(f, L(f, 0), L(f, 1), L(f, 2));
}

Eigen::VectorXd face_areas(const FaceLengths& L) {
  Eigen::VectorXd areas(L.rows());
  for (Eigen::Index f = 0; f < L.rows(); ++f) {
    check_face(f, L(f, 0), L(f, 1), L(f, 2));
    areas(f) = ice::triangle_area(L(f, 0), L(f, 1), L(f, 2));
  }
  return areas;
}

Eigen::MatrixXd corner_angles(const FaceLengths& L) {
  Eigen::MatrixXd angles(L.rows(), 3);
  for (Eigen::Index f = 0; f < L.rows(); ++f) {
    check_face(f, L(f, 0), L(f, 1), L(f, 2));
    // The project's one angle formula (atan2 of 4·area and the law-of-cosines numerator): accurate
    // for needles and caps alike.
    for (int k = 0; k < 3; ++k)
      angles(f, k) = ice::angle_opposite(L(f, (k + 2) % 3), L(f, k), L(f, (k + 1) % 3));
  }
  return angles;
}

Eigen::MatrixXd corner_cotangents(const FaceLengths& L) {
  Eigen::MatrixXd cotangents(L.rows(), 3);
  for (Eigen::Index f = 0; f < L.rows(); ++f) {
    check_face(f, L(f, 0), L(f, 1), L(f, 2));
    const double area = ice::triangle_area(L(f, 0), L(f, 1), L(f, 2));
    if (!(area > 0)) throw InvalidTriangle(f, "zero area: cotangents are infinite");
    for (int k = 0; k < 3; ++k) {
      const double a = L(f, (k + 2) % 3), b = L(f, k), opposite = L(f, (k + 1) % 3);
      cotangents(f, k) = (a * a + b * b - opposite * opposite) / (4.0 * area);
    }
  }
  return cotangents;
}

Eigen::Matrix<double, 3, 2> layout_triangle(double l0, double l1, double l2) {
  // Corner 2 is at distance l2 from corner 0 and l1 from corner 1; its height comes from the stable
  // area rather than sqrt(l2² − x²), which cancels badly for thin triangles.
  const double x = (l0 * l0 + l2 * l2 - l1 * l1) / (2.0 * l0);
  const double y = 2.0 * ice::triangle_area(l0, l1, l2) / l0;
  Eigen::Matrix<double, 3, 2> corners;
  corners << 0.0, 0.0, l0, 0.0, x, y;
  return corners;
}

Eigen::MatrixXd face_layouts(const FaceLengths& L) {
  Eigen::MatrixXd layouts(L.rows(), 6);
  for (Eigen::Index f = 0; f < L.rows(); ++f) {
    check_face(f, L(f, 0), L(f, 1), L(f, 2));
    const Eigen::Matrix<double, 3, 2> corners = layout_triangle(L(f, 0), L(f, 1), L(f, 2));
    for (int k = 0; k < 3; ++k) {
      layouts(f, 2 * k) = corners(k, 0);
      layouts(f, 2 * k + 1) = corners(k, 1);
    }
  }
  return layouts;
}

double mean_edge_length(const FaceLengths& L) {
  if (L.size() == 0) throw std::invalid_argument("mean_edge_length: empty mesh");
  return L.mean();
}

}  // namespace fem
