// The recipe floor (ICE::proxy): its policies, and each one-call function against the pipeline it
// stands for (the same numbers, bit for bit) and against the exact solution on the unit sphere.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "fem/operators.h"
#include "ice/mesh_generators.h"
#include "ice/proxy/geodesics.h"
#include "ice/proxy/heat.h"
#include "ice/proxy/poisson.h"
#include "ice/proxy/vectors.h"
#include "ice/triangle_geometry.h"
#include "test_support.h"

namespace {

using ice::kPi;

using ice_test::unit_sphere;

/// Great-circle distances from vertex s of the unit sphere.
Eigen::VectorXd great_circle(const ice::TriangleMesh& mesh, int s) {
  Eigen::VectorXd d(mesh.V.rows());
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v)
    d(v) = std::acos(std::clamp(mesh.V.row(v).normalized().dot(mesh.V.row(s).normalized()), -1.0, 1.0));
  return d;
}

}  // namespace

TEST_CASE("proxy policies: prolongation, lengths, correction, targets, spellings", "[proxy]") {
  using ice::proxy::Prolongation;
  const auto galerkin = fem::CoarseOperatorKind::galerkin, intrinsic = fem::CoarseOperatorKind::intrinsic;
  CHECK(ice::proxy::resolve_prolongation(Prolongation::automatic, galerkin, false) == fem::ProlongationKind::smoothed);
  CHECK(ice::proxy::resolve_prolongation(Prolongation::automatic, galerkin, true) == fem::ProlongationKind::barycentric);
  CHECK(ice::proxy::resolve_prolongation(Prolongation::automatic, intrinsic, false) == fem::ProlongationKind::barycentric);
  CHECK(ice::proxy::resolve_prolongation(Prolongation::barycentric, galerkin, false) == fem::ProlongationKind::barycentric);
  CHECK_THROWS_AS(ice::proxy::resolve_prolongation(Prolongation::smoothed, intrinsic, false), std::invalid_argument);
  CHECK_THROWS_AS(ice::proxy::resolve_prolongation(Prolongation::smoothed, galerkin, true), std::invalid_argument);

  using ice::CoarseningMethod;
  using ice::proxy::CoarseLengths;
  CHECK(ice::proxy::traces_lengths(CoarseLengths::automatic, CoarseningMethod::ice, true));
  CHECK_FALSE(ice::proxy::traces_lengths(CoarseLengths::automatic, CoarseningMethod::qem, true));
  CHECK_FALSE(ice::proxy::traces_lengths(CoarseLengths::traced, CoarseningMethod::ice, false));  // no marching
  CHECK(ice::proxy::corrects_curvature(ice::proxy::CurvatureCorrection::automatic, CoarseningMethod::ice));
  CHECK_FALSE(ice::proxy::corrects_curvature(ice::proxy::CurvatureCorrection::automatic, CoarseningMethod::qem));
  CHECK(ice::proxy::corrects_curvature(ice::proxy::CurvatureCorrection::on, CoarseningMethod::qem));
  CHECK_FALSE(ice::proxy::corrects_curvature(ice::proxy::CurvatureCorrection::automatic, CoarseningMethod::ice, true));
  CHECK(ice::proxy::corrects_curvature(ice::proxy::CurvatureCorrection::on, CoarseningMethod::ice, true));
  CHECK(ice::proxy::curvature_divisor(ice::proxy::MarchingUse::all_pairs) <
        ice::proxy::curvature_divisor(ice::proxy::MarchingUse::single_source));

  CHECK(ice::proxy::target_vertices(1000, 0.05) == 50);
  CHECK(ice::proxy::target_vertices(1001, 0.05) == 51);  // ceil, as ice::coarsen rounds
  CHECK(ice::proxy::target_vertices(1000, 0.05, 300) == 300);
  CHECK(ice::proxy::target_vertices(1000, 0.05, 5000) == 1000);

  // Every value has one spelling that parses back to it; aliases parse, unknown names are refused.
  for (const auto& [name, value] : ice::proxy::spellings<ice::QemGeometry>())
    CHECK(ice::proxy::parse<ice::QemGeometry>(ice::proxy::spelling(value), "q") == value);
  for (const auto& [name, value] : ice::proxy::spellings<Prolongation>())
    CHECK(ice::proxy::parse<Prolongation>(name, "p") == value);
  CHECK(ice::proxy::parse<ice::FineGeometry>("idt", "fine") == ice::FineGeometry::intrinsic_delaunay);
  CHECK(ice::proxy::spelling(ice::FineGeometry::intrinsic_delaunay) == "intrinsic_delaunay");
  CHECK_THROWS_WITH(ice::proxy::parse<ice::proxy::VectorSolver>("fast", "solver"),
                    Catch::Contains("'sweep', 'diffusion'") && Catch::Contains("'fast'"));
}

TEST_CASE("solve_poisson is the proxy pipeline and solves -Laplace(u) = z on the sphere", "[proxy]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const Eigen::VectorXd f = mesh.V.col(2);  // -Δz = 2z on the unit sphere: u = z / 2
  const Eigen::VectorXd u = ice::proxy::solve_poisson(mesh, f);

  // The pipeline it stands for, step by step: the same numbers to the last bit.
  const ice::CoarseSpace coarse = ice::build_coarse_space(mesh, ice::proxy::default_coarsening(ice::ProxyUse::poisson_heat));
  const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  const fem::CoarseProxy proxy(ice::intrinsic_mesh(fine.F, fine.L), ice::intrinsic_mesh(coarse.mesh.F, coarse.mesh.L), coarse.P, {fem::CoarseOperatorKind::galerkin, fem::MassKind::lumped, fem::ProlongationKind::smoothed});
  CHECK(u == fem::ProxyPoissonSolver(proxy).solve(f));
  CHECK(coarse.mesh.num_vertices() == ice::proxy::target_vertices(static_cast<ice::Index>(mesh.V.rows()), 0.05));

  const Eigen::VectorXd exact = f / 2;
  const Eigen::VectorXd mass = proxy.fine_mass() * Eigen::VectorXd::Ones(u.size());
  CHECK(std::abs(mass.dot(u)) < 1e-10 * mass.sum());  // zero mean
  CHECK((u - exact).norm() < 0.05 * exact.norm());

  // Dirichlet values stay where they are fixed; the prolongation is then the barycentric one.
  ice::proxy::PoissonOptions dirichlet;
  dirichlet.fixed_vertices = {0, 100, 2000};
  const ice::proxy::PoissonSolver solver(mesh, dirichlet);
  CHECK(solver.proxy().prolongation_kind() == fem::ProlongationKind::barycentric);
  const Eigen::VectorXd values = Eigen::Vector3d(1.0, -2.0, 0.5);
  const Eigen::VectorXd held = solver.solve(Eigen::VectorXd::Zero(mesh.V.rows()), values);
  for (int k = 0; k < 3; ++k) CHECK(held(dirichlet.fixed_vertices[static_cast<std::size_t>(k)]) == Approx(values(k)).margin(1e-12));
  ice::proxy::PoissonOptions out_of_range;
  out_of_range.fixed_vertices = {static_cast<ice::Index>(mesh.V.rows())};
  CHECK_THROWS_AS(ice::proxy::PoissonSolver(mesh, out_of_range), std::invalid_argument);
}

TEST_CASE("heat_flow conserves the total heat and smooths towards its mean", "[proxy]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  Eigen::VectorXd u0 = Eigen::VectorXd::Zero(mesh.V.rows());
  u0(0) = 1.0;
  const ice::proxy::HeatSolver solver(mesh, 1e-2);
  const Eigen::VectorXd u = solver.integrate(u0, 10);
  const Eigen::VectorXd mass = solver.proxy().fine_mass() * Eigen::VectorXd::Ones(u.size());
  CHECK(mass.dot(u) == Approx(mass.dot(u0)).epsilon(1e-9));
  CHECK(u.maxCoeff() < u0.maxCoeff());
  CHECK(u == ice::proxy::heat_flow(mesh, u0, 1e-2, 10));
  CHECK_THROWS_AS(ice::proxy::HeatSolver(mesh, 0.0), std::invalid_argument);
}

TEST_CASE("geodesic_distance marches on traced, corrected lengths and follows great circles", "[proxy]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const ice::proxy::GeodesicSolver solver(mesh);
  CHECK(solver.traced_lengths());  // an ICE coarse space: the measured default traces its edges
  const Eigen::VectorXd d = solver.distance({0});
  CHECK(d(0) == Approx(0).margin(1e-12));
  const Eigen::VectorXd exact = great_circle(mesh, 0);
  // 128 coarse vertices on the sphere: a few percent of pi at most (the cut locus), far less on average.
  CHECK((d - exact).cwiseAbs().mean() < 0.01 * kPi);
  CHECK((d - exact).cwiseAbs().maxCoeff() < 0.05 * kPi);
  CHECK(d == ice::proxy::geodesic_distance(mesh, {0}));

  // The pipeline it stands for: traced lengths, corrected for single sources, one subdivision.
  ice::CoarseSpaceOptions coarsening = ice::proxy::default_coarsening(ice::ProxyUse::geodesic);
  coarsening.keep_method_state = true;
  const ice::CoarseSpace coarse = ice::build_coarse_space(mesh, coarsening);
  const ice::SurfaceEdgeLengths lengths =
      ice::proxy::marching_lengths(mesh, coarse, true, ice::proxy::CurvatureCorrection::automatic);
  CHECK(d == fem::ProxyGeodesicSolver(ice::intrinsic_mesh(coarse.mesh.F, lengths.lengths), coarse.P, 1).distance({0}));

  // The coarse heat method: near the same distances.
  ice::proxy::GeodesicOptions heat;
  heat.method = fem::CoarseDistanceMethod::heat_method;
  const Eigen::VectorXd h = ice::proxy::geodesic_distance(mesh, {0}, heat);
  CHECK((h - exact).cwiseAbs().maxCoeff() < 0.1 * kPi);
  heat.lengths = ice::proxy::CoarseLengths::traced;
  CHECK_THROWS_AS(ice::proxy::GeodesicSolver(mesh, heat), std::invalid_argument);
}

TEST_CASE("distance_oracle: symmetric, zero on the diagonal, near great circles", "[proxy]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const fem::DistanceOracle oracle = ice::proxy::distance_oracle(mesh);
  const Eigen::VectorXd exact = great_circle(mesh, 5);
  for (ice::Index v : {0, 17, 900, 2561}) {
    CHECK(oracle.distance(5, v) == Approx(oracle.distance(v, 5)).margin(1e-12));
    CHECK(std::abs(oracle.distance(5, v) - exact(v)) < 0.03 * kPi);
  }
  CHECK(oracle.distance(17, 17) == 0);
}

TEST_CASE("transport_vectors keeps a transported vector's length", "[proxy]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const Eigen::VectorXcd field = ice::proxy::transport_vectors(mesh, {0}, {fem::Complex(1.0, 0.0)});
  REQUIRE(field.size() == mesh.V.rows());
  CHECK(std::abs(field(0) - fem::Complex(1.0, 0.0)) < 1e-9);
  const Eigen::VectorXd from_source = great_circle(mesh, 0);
  std::vector<double> lengths;
  for (Eigen::Index v = 0; v < field.size(); ++v)
    if (from_source(v) < 0.8 * kPi) lengths.push_back(std::abs(field(v)));  // away from the cut locus
  std::nth_element(lengths.begin(), lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2), lengths.end());
  CHECK(lengths[lengths.size() / 2] == Approx(1.0).epsilon(0.02));
  ice::proxy::VectorTransportOptions diffusion;
  diffusion.solver = ice::proxy::VectorSolver::diffusion;
  const ice::proxy::VectorTransportSolver solver(mesh, diffusion);
  CHECK(solver.diffusion() != nullptr);
  CHECK(std::abs(solver.transport({0}, {fem::Complex(0.0, 2.0)})(0) - fem::Complex(0.0, 2.0)) < 1e-6);
}
