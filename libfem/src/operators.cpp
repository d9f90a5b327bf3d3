#include "fem/operators.h"

#include <stdexcept>
#include <vector>

namespace fem {
namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

Eigen::Index resolve_vertex_count(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count) {
  if (F.cols() != 3 || L.cols() != 3 || F.rows() != L.rows())
    throw std::invalid_argument("fem: F and L must both be m×3 with the same m");
  const Eigen::Index needed = F.size() == 0 ? 0 : Eigen::Index(F.maxCoeff()) + 1;
  if (F.size() > 0 && F.minCoeff() < 0) throw std::invalid_argument("fem: negative vertex index in F");
  if (vertex_count < 0) return needed;
  if (vertex_count < needed) throw std::invalid_argument("fem: vertex_count smaller than max index + 1");
  return vertex_count;
}

SparseMatrix from_triplets(Eigen::Index rows, Eigen::Index cols, const Triplets& triplets) {
  SparseMatrix matrix(rows, cols);
  matrix.setFromTriplets(triplets.begin(), triplets.end());  // sums duplicates
  return matrix;
}

}  // namespace

SparseMatrix cotan_laplacian(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count) {
  const Eigen::Index n = resolve_vertex_count(F, L, vertex_count);
  const Eigen::MatrixXd cot = corner_cotangents(L);
  Triplets triplets;
  triplets.reserve(static_cast<std::size_t>(12 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      // Corner k is opposite edge (k+1)%3, which joins corners k+1 and k+2.
      const int i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3);
      const double w = 0.5 * cot(f, k);
      triplets.emplace_back(i, j, -w);
      triplets.emplace_back(j, i, -w);
      triplets.emplace_back(i, i, w);
      triplets.emplace_back(j, j, w);
    }
  return from_triplets(n, n, triplets);
}

Eigen::VectorXd lumped_vertex_areas(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count) {
  const Eigen::Index n = resolve_vertex_count(F, L, vertex_count);
  const Eigen::VectorXd areas = face_areas(L);
  Eigen::VectorXd vertex_areas = Eigen::VectorXd::Zero(n);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) vertex_areas(F(f, k)) += areas(f) / 3.0;
  return vertex_areas;
}

SparseMatrix mass_matrix(const Faces& F, const FaceLengths& L, MassKind kind, Eigen::Index vertex_count) {
  const Eigen::Index n = resolve_vertex_count(F, L, vertex_count);
  if (kind == MassKind::lumped) {
    const Eigen::VectorXd vertex_areas = lumped_vertex_areas(F, L, n);
    SparseMatrix mass(n, n);
    mass.reserve(Eigen::VectorXi::Ones(n));
    for (Eigen::Index v = 0; v < n; ++v) mass.insert(v, v) = vertex_areas(v);
    mass.makeCompressed();
    return mass;
  }
  const Eigen::VectorXd areas = face_areas(L);
  Triplets triplets;
  triplets.reserve(static_cast<std::size_t>(9 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) triplets.emplace_back(F(f, a), F(f, b), areas(f) / (a == b ? 6.0 : 12.0));
  return from_triplets(n, n, triplets);
}

SparseMatrix gradient(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count) {
  const Eigen::Index n = resolve_vertex_count(F, L, vertex_count);
  validate_lengths(L);
  Triplets triplets;
  triplets.reserve(static_cast<std::size_t>(6 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Matrix<double, 3, 2> p = layout_triangle(L(f, 0), L(f, 1), L(f, 2));
    const double twice_area = L(f, 0) * p(2, 1);  // base l0 times height of corner 2
    if (!(twice_area > 0)) throw InvalidTriangle(f, "zero area: gradient undefined");
    for (int k = 0; k < 3; ++k) {
      // ∇φ_k is the opposite edge (counter-clockwise) rotated by +90°, divided by 2A.
      const Eigen::RowVector2d edge = p.row((k + 2) % 3) - p.row((k + 1) % 3);
      triplets.emplace_back(2 * f, F(f, k), -edge(1) / twice_area);
      triplets.emplace_back(2 * f + 1, F(f, k), edge(0) / twice_area);
    }
  }
  return from_triplets(2 * F.rows(), n, triplets);
}

SparseMatrix divergence(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count) {
  const SparseMatrix G = gradient(F, L, vertex_count);
  const Eigen::VectorXd areas = face_areas(L);
  Eigen::VectorXd weights(2 * areas.size());
  for (Eigen::Index f = 0; f < areas.size(); ++f) weights(2 * f) = weights(2 * f + 1) = areas(f);
  return SparseMatrix(-(G.transpose() * weights.asDiagonal()));
}

SparseMatrix galerkin(const SparseMatrix& P, const SparseMatrix& A) {
  if (A.rows() != A.cols() || A.cols() != P.rows())
    throw std::invalid_argument("galerkin: need square A with as many rows as P");
  const SparseMatrix product = SparseMatrix(P.transpose()) * (A * P);
  return SparseMatrix(0.5 * (product + SparseMatrix(product.transpose())));
}

}  // namespace fem
