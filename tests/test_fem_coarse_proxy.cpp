// Coarse-proxy pipelines: identity prolongation reproduces fine solutions; on nested spheres the
// Galerkin proxy satisfies Galerkin orthogonality and both proxies approximate the fine solutions.
#include <catch2/catch.hpp>

#include <map>
#include <set>
#include <vector>

#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "ice/mesh_generators.h"

namespace {

fem::SparseMatrix identity(Eigen::Index n) {
  fem::SparseMatrix I(n, n);
  I.setIdentity();
  return I;
}

/// Prolongation from icosphere(level) to icosphere(level+1), found from geometry and connectivity
/// only: coarse vertices reappear at identical positions, and every other fine vertex is an edge point
/// adjacent to exactly two of them (weights ½, ½).
fem::SparseMatrix nested_sphere_prolongation(const ice::TriangleMesh& coarse, const ice::TriangleMesh& fine) {
  std::map<std::vector<double>, int> coarse_at;
  for (Eigen::Index v = 0; v < coarse.V.rows(); ++v)
    coarse_at[{coarse.V(v, 0), coarse.V(v, 1), coarse.V(v, 2)}] = static_cast<int>(v);
  std::vector<int> coarse_of(static_cast<std::size_t>(fine.V.rows()), -1);
  for (Eigen::Index v = 0; v < fine.V.rows(); ++v) {
    const auto it = coarse_at.find({fine.V(v, 0), fine.V(v, 1), fine.V(v, 2)});
    if (it != coarse_at.end()) coarse_of[static_cast<std::size_t>(v)] = it->second;
  }
  std::vector<std::set<int>> coarse_neighbours(static_cast<std::size_t>(fine.V.rows()));
  for (Eigen::Index f = 0; f < fine.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = fine.F(f, k), b = fine.F(f, (k + 1) % 3);
      if (coarse_of[b] >= 0) coarse_neighbours[a].insert(coarse_of[b]);
      if (coarse_of[a] >= 0) coarse_neighbours[b].insert(coarse_of[a]);
    }
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index v = 0; v < fine.V.rows(); ++v) {
    if (coarse_of[v] >= 0) {
      triplets.emplace_back(v, coarse_of[v], 1.0);
      continue;
    }
    REQUIRE(coarse_neighbours[v].size() == 2);
    for (int c : coarse_neighbours[v]) triplets.emplace_back(v, c, 0.5);
  }
  fem::SparseMatrix P(fine.V.rows(), coarse.V.rows());
  P.setFromTriplets(triplets.begin(), triplets.end());
  return P;
}

}  // namespace

TEST_CASE("coarse proxy with P = identity reproduces the fine solutions", "[fem][coarse_proxy]") {
  const ice::TriangleMesh mesh = ice::make_torus(24, 12, 2.0, 0.6);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const Eigen::Index n = mesh.V.rows();
  const fem::SparseMatrix L = fem::cotan_laplacian(mesh.F, lengths);
  const fem::SparseMatrix M = fem::mass_matrix(mesh.F, lengths);
  const Eigen::VectorXd f = (mesh.V.col(0).array() * mesh.V.col(2).array() + mesh.V.col(1).array()).matrix();

  const Eigen::VectorXd poisson = fem::PoissonSolver::zero_mean(L, M).solve(f);
  const Eigen::VectorXd heat = fem::HeatSolver(L, M, 0.01).integrate(f, 5);
  const Eigen::VectorXd distance = fem::HeatGeodesicSolver(fem::heat_method_operators(mesh.F, lengths)).distance({7});

  for (fem::CoarseOperatorKind kind : {fem::CoarseOperatorKind::intrinsic, fem::CoarseOperatorKind::galerkin}) {
    INFO((kind == fem::CoarseOperatorKind::intrinsic ? "intrinsic" : "galerkin"));
    const fem::CoarseProxy proxy(mesh.F, lengths, mesh.F, lengths, identity(n), kind);
    CHECK(fem::SparseMatrix(proxy.coarse_laplacian() - L).norm() <= 1e-14 * L.norm());
    CHECK(fem::relative_l2_error(fem::ProxyPoissonSolver(proxy).solve(f), poisson, M) < 1e-12);
    for (fem::RestrictionKind restriction : {fem::RestrictionKind::l2_projection, fem::RestrictionKind::injection})
      CHECK(fem::relative_l2_error(fem::ProxyHeatSolver(proxy, 0.01, restriction).integrate(f, 5), heat, M) < 1e-12);
    CHECK(fem::max_abs_error(fem::ProxyGeodesicSolver(proxy).distance({7}), distance) < 1e-12 * distance.maxCoeff());
  }
}

TEST_CASE("coarse proxy on nested icospheres", "[fem][coarse_proxy]") {
  const ice::TriangleMesh coarse = ice::make_icosphere(3);
  const ice::TriangleMesh fine = ice::make_icosphere(4);
  const ice::FaceLengths coarse_lengths = ice::face_lengths_from_positions(coarse.V, coarse.F);
  const ice::FaceLengths fine_lengths = ice::face_lengths_from_positions(fine.V, fine.F);
  const fem::SparseMatrix P = nested_sphere_prolongation(coarse, fine);
  const fem::SparseMatrix L = fem::cotan_laplacian(fine.F, fine_lengths);
  const fem::SparseMatrix M = fem::mass_matrix(fine.F, fine_lengths);

  // Smooth data: f = z + xy (spherical harmonics of degree 1 and 2).
  const Eigen::ArrayXd x = fine.V.col(0), y = fine.V.col(1), z = fine.V.col(2);
  const Eigen::VectorXd f = (z + x * y).matrix();
  const Eigen::VectorXd poisson = fem::PoissonSolver::zero_mean(L, M).solve(f);
  Eigen::Index source = 0;
  fine.V.col(2).maxCoeff(&source);
  const Eigen::VectorXd distance =
      fem::HeatGeodesicSolver(fem::heat_method_operators(fine.F, fine_lengths)).distance({static_cast<int>(source)});

  for (fem::CoarseOperatorKind kind : {fem::CoarseOperatorKind::intrinsic, fem::CoarseOperatorKind::galerkin}) {
    const bool galerkin = kind == fem::CoarseOperatorKind::galerkin;
    INFO((galerkin ? "galerkin" : "intrinsic"));
    const fem::CoarseProxy proxy(fine.F, fine_lengths, coarse.F, coarse_lengths, P, kind);
    const Eigen::VectorXd u = fem::ProxyPoissonSolver(proxy).solve(f);
    const double poisson_error = fem::relative_l2_error(u, poisson, M);
    UNSCOPED_INFO((galerkin ? "galerkin" : "intrinsic") << " proxy Poisson relative L2 error " << poisson_error);
    CHECK(poisson_error < 0.02);
    if (galerkin) {
      // Galerkin orthogonality: the fine error is L-orthogonal to the coarse space.
      const Eigen::VectorXd residual = P.transpose() * (L * (poisson - u));
      CHECK(residual.norm() < 1e-10 * (P.transpose() * (L * poisson)).norm());
    }
    const fem::DistanceErrors errors = fem::distance_errors(fem::ProxyGeodesicSolver(proxy).distance({static_cast<int>(source)}), distance);
    UNSCOPED_INFO("  geodesic vs fine heat method: mean " << errors.mean_relative << ", max " << errors.max_relative);
    CHECK(errors.mean_relative < 0.02);

    // Restrictions: injection recovers coarse nodal values; the Galerkin L² projection is exact on span P.
    const Eigen::VectorXd coarse_values = coarse.V.col(0) + 2.0 * coarse.V.col(1);
    CHECK(fem::max_abs_error(proxy.restrict_values(proxy.prolong(coarse_values), fem::RestrictionKind::injection),
                             coarse_values) == 0.0);
    if (galerkin)
      CHECK(fem::max_abs_error(proxy.restrict_values(proxy.prolong(coarse_values), fem::RestrictionKind::l2_projection),
                               coarse_values) < 1e-12);
    const Eigen::VectorXd heat = fem::HeatSolver(L, M, 0.01).integrate(f, 10);
    const double heat_error = fem::relative_l2_error(
        fem::ProxyHeatSolver(proxy, 0.01, fem::RestrictionKind::l2_projection).integrate(f, 10), heat, M);
    UNSCOPED_INFO("  heat relative L2 error " << heat_error);
    CHECK(heat_error < 0.02);
  }
}

TEST_CASE("coarse proxy rejects a prolongation whose rows do not sum to 1", "[fem][coarse_proxy]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(1);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const fem::SparseMatrix P = 0.5 * identity(mesh.V.rows());
  CHECK_THROWS_AS(fem::CoarseProxy(mesh.F, lengths, mesh.F, lengths, P, fem::CoarseOperatorKind::galerkin),
                  std::invalid_argument);
  const fem::SparseMatrix wrong_size = identity(mesh.V.rows() - 1);
  CHECK_THROWS_AS(fem::CoarseProxy(mesh.F, lengths, mesh.F, lengths, wrong_size, fem::CoarseOperatorKind::intrinsic),
                  std::invalid_argument);
}
