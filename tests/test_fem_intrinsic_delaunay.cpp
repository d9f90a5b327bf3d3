// The fine solve on the intrinsic Delaunay triangulation (iDT) of a poor input: on a planar disk
// whose triangulation was made deliberately bad by edge flips (all lengths still exact), the plain
// cotan Laplacian has negative weights and heat-method distances degrade; the iDT of the same surface
// has none and recovers accurate distances (the exact distance from the centre vertex is the straight-line one).
#include <catch2/catch.hpp>

#include <random>

#include "fem/errors.h"
#include "fem/operators.h"
#include "fem/problems.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_generators.h"

using namespace ice;

namespace {

int negative_weights(const Eigen::SparseMatrix<double>& L) {
  int count = 0;
  for (Eigen::Index c = 0; c < L.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, c); it; ++it)
      count += it.row() != it.col() && it.value() > 1e-12;  // PSD convention: off-diagonal = −w
  return count;
}

}  // namespace

TEST_CASE("heat-method distances on a bad triangulation: intrinsic Delaunay repairs them", "[fem][intrinsic]") {
  const TriangleMesh disk = make_flat_disk(16, 1.0, 0.2, 3);
  auto T = IntrinsicTriangulation::from_mesh(disk.V, disk.F);
  // Spoil the triangulation: flip random edges (on a flat mesh these are ordinary planar flips).
  std::mt19937 rng(12);
  std::vector<Index> edges;
  for (Index h = 0; h < T.num_halfedge_slots(); h += 2)
    if (!T.is_boundary_edge(h)) edges.push_back(h);
  int flips = 0;
  for (int round = 0; round < 4; ++round) {
    std::shuffle(edges.begin(), edges.end(), rng);
    for (Index h : edges) flips += T.flip(h);
  }
  REQUIRE(flips > 1000);
  const CompactMesh bad = T.compact();
  auto delaunay = T;
  delaunay.flip_to_delaunay();
  const CompactMesh good = delaunay.compact();
  // No vertex was removed: compact vertex ids are the input ids.
  REQUIRE(bad.to_input.size() == static_cast<std::size_t>(disk.V.rows()));

  const auto L_bad = fem::cotan_laplacian(bad);
  const auto L_good = fem::cotan_laplacian(good);
  CHECK(negative_weights(L_bad) > 100);
  CHECK(negative_weights(L_good) == 0);

  // The disk is convex, so the geodesic distance from the centre vertex is the straight-line one.
  const int centre = 0;
  Eigen::VectorXd exact(disk.V.rows());
  for (Eigen::Index v = 0; v < disk.V.rows(); ++v) exact(v) = (disk.V.row(v) - disk.V.row(centre)).head<2>().norm();
  const auto distance = [&](const CompactMesh& mesh) {
    fem::HeatGeodesicSolver solver(fem::heat_method_operators(mesh, fem::MassKind::lumped, 1.0));
    return solver.distance({centre});
  };
  const Eigen::VectorXd d_bad = distance(bad), d_good = distance(good);
  const auto e_bad = fem::distance_errors(d_bad, exact), e_good = fem::distance_errors(d_good, exact);
  INFO("mean relative error: bad triangulation " << e_bad.mean_relative << ", iDT " << e_good.mean_relative);
  INFO("max relative error: bad triangulation " << e_bad.max_relative << ", iDT " << e_good.max_relative);
  CHECK(e_good.mean_relative < 0.02);
  CHECK(e_good.mean_relative < 0.5 * e_bad.mean_relative);
  CHECK(e_good.max_relative < e_bad.max_relative);
  CHECK(d_good.minCoeff() > -1e-9);
}
