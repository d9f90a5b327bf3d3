#include "fem/curvature_correction.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "fem/topology.h"
#include "ice/triangle_geometry.h"

namespace fem {

namespace {
using ice::kPi;
}  // namespace

Eigen::VectorXd angle_defects(const ice::IntrinsicMesh& mesh) {
  const Faces& F = mesh.F;
  const FaceLengths& L = mesh.L;
  const Eigen::Index vertex_count = checked_vertex_count(mesh);
  const Eigen::MatrixXd angles = corner_angles(L);
  Eigen::VectorXd angle_sum = Eigen::VectorXd::Zero(vertex_count);
  std::vector<char> used(static_cast<std::size_t>(vertex_count), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      angle_sum(F(f, k)) += angles(f, k);
      used[static_cast<std::size_t>(F(f, k))] = 1;
    }
  Eigen::VectorXd defect(vertex_count);
  for (Eigen::Index v = 0; v < vertex_count; ++v)
    defect(v) = used[static_cast<std::size_t>(v)] ? 2 * kPi - angle_sum(v) : 0.0;
  for (const Index v : boundary_vertices(F)) defect(v) = 0.0;
  return defect;
}

CoarseCurvature coarse_curvature(const ice::IntrinsicMesh& fine, const SparseMatrix& P) {
  const char* who = "curvature_corrected_lengths: ";
  if (checked_vertex_count(fine) != P.rows())
    throw std::invalid_argument(std::string(who) + "the fine mesh's vertex count is not P's row count");
  for (Eigen::Index k = 0; k < P.outerSize(); ++k)
    for (SparseMatrix::InnerIterator it(P, k); it; ++it)
      if (!(it.value() >= 0)) throw std::invalid_argument(std::string(who) + "P has a negative or non-finite weight");
  return {P.transpose() * angle_defects(fine), P.transpose() * lumped_vertex_areas(fine)};
}

FaceLengths curvature_corrected_lengths(const ice::IntrinsicMesh& fine, const ice::IntrinsicMesh& coarse,
                                        const SparseMatrix& P, double divisor) {
  if (coarse.F.rows() > 0 && (coarse.F.minCoeff() < 0 || coarse.F.maxCoeff() >= P.cols()))
    throw std::invalid_argument("curvature_corrected_lengths: a coarse vertex beyond P's columns");
  return curvature_corrected_lengths(coarse, coarse_curvature(fine, P), divisor);
}

FaceLengths curvature_corrected_lengths(const ice::IntrinsicMesh& coarse, const CoarseCurvature& gathered, double divisor) {
  const char* who = "curvature_corrected_lengths: ";
  const Faces& coarse_faces = coarse.F;
  const FaceLengths& coarse_lengths = coarse.L;
  const Eigen::VectorXd& curvature = gathered.curvature;
  const Eigen::VectorXd& area = gathered.area;
  if (!(divisor > 0) || !std::isfinite(divisor)) throw std::invalid_argument(std::string(who) + "the divisor must be positive");
  if (coarse_lengths.rows() != coarse_faces.rows() || coarse_faces.cols() != 3 || coarse_lengths.cols() != 3)
    throw std::invalid_argument(std::string(who) + "coarse faces and lengths of different shapes");
  if (curvature.size() != area.size() ||
      (coarse_faces.rows() > 0 && (coarse_faces.minCoeff() < 0 || coarse_faces.maxCoeff() >= curvature.size())))
    throw std::invalid_argument(std::string(who) + "the gathered curvature is not of the coarse vertices");

  // One scale per edge: sides with the same ends and length are one edge (as the marching reads
  // them), numbered in the order of their keys.
  struct Side {
    Index low, high;
    double length;
    Eigen::Index side;  // 3f + k
  };
  std::vector<Side> sides;
  sides.reserve(static_cast<std::size_t>(3 * coarse_faces.rows()));
  for (Eigen::Index f = 0; f < coarse_faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Index u = coarse_faces(f, k), w = coarse_faces(f, (k + 1) % 3);
      sides.push_back({std::min(u, w), std::max(u, w), coarse_lengths(f, k), 3 * f + k});
    }
  const auto key = [](const Side& s) { return std::tuple(s.low, s.high, s.length); };
  std::sort(sides.begin(), sides.end(), [&](const Side& p, const Side& q) { return key(p) < key(q); });
  std::vector<Eigen::Index> edge_of(sides.size());
  std::vector<double> scale;
  for (std::size_t i = 0; i < sides.size(); ++i) {
    if (i == 0 || key(sides[i]) != key(sides[i - 1])) {
      const Side& s = sides[i];
      const double mass = area(s.low) + area(s.high);
      const double density = mass > 0 ? (curvature(s.low) + curvature(s.high)) / mass : 0.0;
      // exp rather than 1 + x: the same to second order, and positive where a strongly negatively
      // curved patch (a handle's saddle) would make 1 + x vanish.
      scale.push_back(std::exp(density * s.length * s.length / divisor));
    }
    edge_of[static_cast<std::size_t>(sides[i].side)] = static_cast<Eigen::Index>(scale.size()) - 1;
  }
  // Scale, then give back their lengths to the edges of faces the scaling made invalid, until none
  // is (each round only removes scales, and the given lengths are valid: it ends).
  FaceLengths corrected(coarse_lengths.rows(), 3);
  for (bool changed = true; changed;) {
    changed = false;
    for (Eigen::Index f = 0; f < coarse_faces.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        corrected(f, k) = coarse_lengths(f, k) * scale[static_cast<std::size_t>(edge_of[static_cast<std::size_t>(3 * f + k)])];
    for (Eigen::Index f = 0; f < coarse_faces.rows(); ++f) {
      const double a = corrected(f, 0), b = corrected(f, 1), c = corrected(f, 2);
      const double slack = 1e-9 * (a + b + c);
      if (a + b - c > slack && b + c - a > slack && c + a - b > slack) continue;
      for (int k = 0; k < 3; ++k) {
        double& edge_scale = scale[static_cast<std::size_t>(edge_of[static_cast<std::size_t>(3 * f + k)])];
        if (edge_scale != 1.0) edge_scale = 1.0, changed = true;
      }
    }
  }
  return corrected;
}

}  // namespace fem
