#pragma once
/// \file geometry.h
/// Per-face intrinsic geometry computed from edge lengths alone.
///
/// All functions take per-face lengths `L` (m×3) in the ice/mesh.h convention: L(f,k) is the length
/// of the edge from corner k to corner (k+1)%3. Hence corner k is adjacent to edges k and (k+2)%3 and
/// opposite edge (k+1)%3. Nothing here needs positions or connectivity, so the same code serves the
/// input mesh, an intrinsic retriangulation and a coarse proxy.
#include <Eigen/Core>
#include <stdexcept>
#include <string>

#include "ice/mesh.h"

namespace fem {

using ice::FaceLengths;
using ice::Faces;
/// Vertex and unknown indices (vertex lists, Dirichlet and constrained sets, orderings): ice::Index,
/// which is also the sparse matrices' storage index. Sizes and counts are Eigen::Index.
using ice::Index;

/// Thrown when a face's lengths are not those of a Euclidean triangle (non-positive or non-finite
/// length, or the triangle inequality violated beyond round-off), or a positive area is required and
/// the face is degenerate.
class InvalidTriangle : public std::domain_error {
 public:
  InvalidTriangle(Eigen::Index face, const std::string& what)
      : std::domain_error("face " + std::to_string(face) + ": " + what), face_(face) {}
  Eigen::Index face() const { return face_; }

 private:
  Eigen::Index face_;
};

/// Relative slack (w.r.t. the perimeter) tolerated in the triangle inequality: lengths that violate it
/// by less than this are treated as a degenerate (flat) triangle instead of an error.
inline constexpr double kTriangleInequalityTolerance = 1e-12;

/// Throws InvalidTriangle for the first face whose lengths are not positive and finite or violate the
/// triangle inequality by more than kTriangleInequalityTolerance·perimeter.
void validate_lengths(const FaceLengths& L);

/// Face areas (m) by Kahan's stable Heron formula (ice::triangle_area).
/// Flat faces give 0. Throws InvalidTriangle as validate_lengths.
Eigen::VectorXd face_areas(const FaceLengths& L);

/// Corner angles (m×3): entry (f,k) is the interior angle at corner k, opposite edge (k+1)%3.
/// Computed by ice::angle_opposite (atan2 of 4·area and the law-of-cosines numerator, stable for
/// needles and caps; the triangle inequality is checked first). Angles of each face sum to π.
Eigen::MatrixXd corner_angles(const FaceLengths& L);

/// Cotangents of the corner angles (m×3), cot = (a² + b² − c²) / (4·area) with a, b the adjacent and c
/// the opposite edge. Throws InvalidTriangle on a face of zero area (its cotangents are infinite).
Eigen::MatrixXd corner_cotangents(const FaceLengths& L);

/// 2D layout of one triangle from its lengths (l0 = |c0c1|, l1 = |c1c2|, l2 = |c2c0|): rows are the
/// corners, corner 0 at the origin, corner 1 on the +x axis, corner 2 in the upper half plane, so the
/// layout is counter-clockwise. Preconditions: valid lengths (not checked here).
Eigen::Matrix<double, 3, 2> layout_triangle(double l0, double l1, double l2);

/// Layouts of all faces, m×6: (x0, y0, x1, y1, x2, y2) in each face's own frame (see layout_triangle).
/// Throws InvalidTriangle as validate_lengths.
Eigen::MatrixXd face_layouts(const FaceLengths& L);

/// Mean edge length; every interior edge is counted from both faces, which is the usual "h" of the
/// heat method up to boundary effects.
double mean_edge_length(const FaceLengths& L);

}  // namespace fem
