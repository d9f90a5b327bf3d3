// Model problems on generated meshes against analytic solutions: Poisson (Dirichlet on a disk,
// zero-mean on a sphere), backward-Euler heat flow, heat-method geodesic distance.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "fem/errors.h"
#include "fem/problems.h"
#include "fem/topology.h"
#include "ice/coarse_space.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "test_support.h"

namespace {

struct Discretisation {
  ice::TriangleMesh mesh;
  ice::FaceLengths lengths;
  fem::SparseMatrix laplacian, mass;
};

Discretisation discretise(ice::TriangleMesh mesh) {
  Discretisation d;
  d.lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  d.laplacian = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, d.lengths, mesh.V.rows()));
  d.mass = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, d.lengths, mesh.V.rows()), fem::MassKind::lumped);
  d.mesh = std::move(mesh);
  return d;
}

int highest_vertex(const ice::TriangleMesh& mesh) {
  Eigen::Index top = 0;
  mesh.V.col(2).maxCoeff(&top);
  return static_cast<int>(top);
}

}  // namespace

TEST_CASE("Poisson, Dirichlet on a disk: linear functions exactly, smooth ones at second order", "[fem][problems]") {
  SECTION("linear precision") {
    const Discretisation d = discretise(ice::make_flat_disk(6, 1.0, 0.25, 21));
    const std::vector<int> boundary = fem::boundary_vertices(d.mesh.F);
    REQUIRE(boundary.size() == 36);
    const Eigen::VectorXd exact = (0.5 + 2.0 * d.mesh.V.col(0).array() - 3.0 * d.mesh.V.col(1).array()).matrix();
    Eigen::VectorXd boundary_values(static_cast<Eigen::Index>(boundary.size()));
    for (std::size_t i = 0; i < boundary.size(); ++i) boundary_values(static_cast<Eigen::Index>(i)) = exact(boundary[i]);
    const fem::PoissonSolver solver = fem::PoissonSolver::dirichlet(d.laplacian, d.mass, boundary);
    const Eigen::VectorXd u = solver.solve(Eigen::VectorXd::Zero(exact.size()), boundary_values);
    CHECK(fem::max_abs_error(u, exact) < 1e-12);
  }
  SECTION("convergence for u = eˣ sin y + x²y (−Δu = −2y)") {
    double previous = INFINITY;
    for (int rings : {4, 8, 16}) {
      const Discretisation d = discretise(ice::make_flat_disk(rings, 1.0, 0.2, 5));
      const Eigen::ArrayXd x = d.mesh.V.col(0), y = d.mesh.V.col(1);
      const Eigen::VectorXd exact = (x.exp() * y.sin() + x * x * y).matrix();
      const Eigen::VectorXd source = (-2.0 * y).matrix();
      const std::vector<int> boundary = fem::boundary_vertices(d.mesh.F);
      Eigen::VectorXd boundary_values(static_cast<Eigen::Index>(boundary.size()));
      for (std::size_t i = 0; i < boundary.size(); ++i) boundary_values(static_cast<Eigen::Index>(i)) = exact(boundary[i]);
      const fem::PoissonSolver solver = fem::PoissonSolver::dirichlet(d.laplacian, d.mass, boundary);
      const double error = fem::relative_l2_error(solver.solve(source, boundary_values), exact, d.mass);
      UNSCOPED_INFO("disk rings " << rings << ": relative L2 error " << error);
      CHECK(error < previous / 2.5);
      previous = error;
    }
    CHECK(previous < 1e-3);
  }
}

TEST_CASE("Poisson, zero mean on a sphere: −Δu = z gives u = R²z/2", "[fem][problems]") {
  const double radius = 1.5;
  double previous = INFINITY;
  for (int level = 2; level <= 4; ++level) {
    const Discretisation d = discretise(ice::make_icosphere(level, radius));
    const fem::PoissonSolver solver = fem::PoissonSolver::zero_mean(d.laplacian, d.mass);
    REQUIRE(solver.is_zero_mean());
    const Eigen::VectorXd z = d.mesh.V.col(2);
    // An added constant is projected out of the source.
    const Eigen::VectorXd u = solver.solve((z.array() + 3.0).matrix());
    const Eigen::VectorXd ones = Eigen::VectorXd::Ones(u.size());
    CHECK(std::abs(ones.dot(d.mass * u)) < 1e-12);
    const double error = fem::relative_l2_error(u, 0.5 * radius * radius * z, d.mass);
    UNSCOPED_INFO("icosphere level " << level << ": relative L2 error " << error);
    CHECK(error < previous / 3.0);
    previous = error;
    // The discrete equation holds exactly for the compatible right-hand side.
    const Eigen::VectorXd f_mean_free = (z.array() - ones.dot(d.mass * z) / ones.dot(d.mass * ones)).matrix();
    CHECK((d.laplacian * u - d.mass * f_mean_free).norm() < 1e-10 * (d.mass * f_mean_free).norm());
    // Every fill-reducing ordering solves the same system (to round-off).
    for (fem::CholeskyOrdering ordering : {fem::CholeskyOrdering::amd, fem::CholeskyOrdering::metis,
                                           fem::CholeskyOrdering::nested_dissection}) {
      const Eigen::VectorXd v = fem::PoissonSolver::zero_mean(d.laplacian, d.mass, {}, ordering).solve((z.array() + 3.0).matrix());
      CHECK((v - u).norm() <= 1e-10 * u.norm());
    }
  }
  CHECK(previous < 0.01);
}

TEST_CASE("heat flow: backward Euler conserves heat and damps spherical harmonics", "[fem][problems]") {
  const Discretisation d = discretise(ice::make_icosphere(4));
  const double tau = 1e-3;
  const int steps = 200;  // T = 0.2
  const fem::HeatSolver heat(d.laplacian, d.mass, tau);
  const Eigen::VectorXd z = d.mesh.V.col(2);
  const Eigen::VectorXd u0 = (z.array() + 1.0).matrix();
  const Eigen::VectorXd u = heat.integrate(u0, steps);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(u.size());
  CHECK(ones.dot(d.mass * u) == Approx(ones.dot(d.mass * u0)).epsilon(1e-12));  // Neumann: total heat kept
  // −Δz = 2z on the unit sphere: u = 1 + z·e^{−2T}; backward Euler damps by (1 + 2τ)^{−steps}.
  const Eigen::VectorXd exact = (1.0 + z.array() * std::exp(-2.0 * tau * steps)).matrix();
  CHECK(fem::relative_l2_error(u, exact, d.mass) < 2e-3);
  CHECK(heat.integrate(u0, 0) == u0);
  CHECK_THROWS_AS(fem::HeatSolver(d.laplacian, d.mass, 0.0), std::invalid_argument);
}

TEST_CASE("heat-method geodesics on spheres converge to R·θ", "[fem][problems][geodesic]") {
  const double radius = 2.0;
  double previous_mean = INFINITY;
  for (int level = 2; level <= 5; ++level) {
    const Discretisation d = discretise(ice::make_icosphere(level, radius));
    const fem::HeatGeodesicSolver solver(fem::heat_method_operators(ice::intrinsic_mesh(d.mesh.F, d.lengths)));
    REQUIRE(solver.operators().boundary_vertices.empty());
    const int source = highest_vertex(d.mesh);
    const Eigen::VectorXd phi = solver.distance({source});
    const Eigen::RowVector3d pole = d.mesh.V.row(source) / radius;
    Eigen::VectorXd exact(phi.size());
    for (Eigen::Index v = 0; v < phi.size(); ++v)
      exact(v) = radius * std::acos(std::clamp(pole.dot(d.mesh.V.row(v) / radius), -1.0, 1.0));
    CHECK(phi(source) == Approx(0.0).margin(1e-14));
    const fem::DistanceErrors errors = fem::distance_errors(phi, exact);
    UNSCOPED_INFO("icosphere level " << level << " (" << phi.size() << " vertices): mean " << errors.mean_relative
                                     << ", max " << errors.max_relative << " (relative to max distance)");
    CHECK(errors.mean_relative < previous_mean);
    CHECK(errors.max_relative < 0.05);
    previous_mean = errors.mean_relative;
  }
  CHECK(previous_mean < 0.01);
}

TEST_CASE("heat-method geodesics stay finite where the heat solution is subnormal", "[fem][problems][geodesic]") {
  // A short time step on a long torus: u falls below 1e-308 (subnormal doubles, 250 vertices) and
  // to 0 on the far side, as it does at t = h² on meshes of a million vertices. Normalising such a
  // gradient divided the face area by a subnormal norm: ∞, and ∞ · 0 made every distance NaN.
  const double major = 4.0, minor = 0.5;
  const Discretisation d = discretise(ice::make_torus(800, 8, major, minor));
  fem::HeatMethodOperators ops = fem::heat_method_operators(ice::intrinsic_mesh(d.mesh.F, d.lengths), fem::MassKind::lumped, 0.04);
  const fem::HeatGeodesicSolver solver(std::move(ops));
  const Eigen::VectorXd phi = solver.distance({0});
  REQUIRE(phi.allFinite());
  CHECK(phi(0) == Approx(0.0).margin(1e-14));
  CHECK(phi.minCoeff() > -0.05);
  CHECK(phi.maxCoeff() < M_PI * (major + minor) + M_PI * minor);  // half way round, outside, then across
}

TEST_CASE("heat-method geodesics on a disk with boundary", "[fem][problems][geodesic]") {
  double previous_mean = INFINITY;
  for (int rings : {8, 16, 32}) {
    const Discretisation d = discretise(ice::make_flat_disk(rings, 1.0, 0.2, 17));
    const fem::HeatGeodesicSolver solver(fem::heat_method_operators(ice::intrinsic_mesh(d.mesh.F, d.lengths)));
    REQUIRE(solver.operators().boundary_vertices.size() == static_cast<std::size_t>(6 * rings));
    const Eigen::VectorXd phi = solver.distance({0});  // the centre vertex (jittered)
    const Eigen::VectorXd exact = (d.mesh.V.rowwise() - d.mesh.V.row(0)).rowwise().norm();
    const fem::DistanceErrors errors = fem::distance_errors(phi, exact);
    UNSCOPED_INFO("disk rings " << rings << ": mean " << errors.mean_relative << ", max " << errors.max_relative);
    CHECK(errors.mean_relative < previous_mean);
    previous_mean = errors.mean_relative;
  }
  CHECK(previous_mean < 0.02);
  // Two sources: the distance is the smaller of the two, both sources at 0.
  const Discretisation d = discretise(ice::make_flat_disk(16, 1.0, 0.0, 1));
  const fem::HeatGeodesicSolver solver(fem::heat_method_operators(ice::intrinsic_mesh(d.mesh.F, d.lengths)));
  Eigen::Index left = 0, right = 0;
  d.mesh.V.col(0).minCoeff(&left);
  d.mesh.V.col(0).maxCoeff(&right);
  const Eigen::VectorXd phi = solver.distance({static_cast<int>(left), static_cast<int>(right)});
  const Eigen::VectorXd exact = (d.mesh.V.rowwise() - d.mesh.V.row(left)).rowwise().norm().cwiseMin(
      (d.mesh.V.rowwise() - d.mesh.V.row(right)).rowwise().norm());
  CHECK(fem::distance_errors(phi, exact).mean_relative < 0.03);
}

TEST_CASE("Dirichlet values follow the caller's order of the constrained vertices; repeats are refused",
          "[fem][problems]") {
  // A linear function is reproduced exactly from its boundary values, so values given in any order
  // must land on their own vertices; a permutation of (vertices, values) gives the same solution.
  const Discretisation d = discretise(ice::make_flat_disk(6, 1.0, 0.25, 21));
  std::vector<int> boundary = fem::boundary_vertices(d.mesh.F);
  std::reverse(boundary.begin(), boundary.end());
  std::swap(boundary[0], boundary[7]);
  const Eigen::VectorXd exact = (0.5 + 2.0 * d.mesh.V.col(0).array() - 3.0 * d.mesh.V.col(1).array()).matrix();
  Eigen::VectorXd values(static_cast<Eigen::Index>(boundary.size()));
  for (std::size_t i = 0; i < boundary.size(); ++i) values(static_cast<Eigen::Index>(i)) = exact(boundary[i]);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(exact.size());
  CHECK(fem::max_abs_error(fem::PoissonSolver::dirichlet(d.laplacian, d.mass, boundary).solve(zero, values), exact) <
        1e-12);
  const fem::ConstrainedSolver direct(d.laplacian, boundary);
  const Eigen::VectorXd x = direct.solve(d.mass * zero, values);
  for (std::size_t i = 0; i < boundary.size(); ++i) CHECK(x(boundary[i]) == values(static_cast<Eigen::Index>(i)));
  CHECK(direct.constrained() == boundary);

  std::vector<int> repeated = {boundary[0], boundary[1], boundary[0]};
  CHECK_THROWS_AS(fem::ConstrainedSolver(d.laplacian, repeated), std::invalid_argument);
  CHECK_THROWS_AS(fem::PoissonSolver::dirichlet(d.laplacian, d.mass, repeated), std::invalid_argument);
}

TEST_CASE("several components: zero-mean Poisson and heat-method geodesics equal each component solved apart",
          "[fem][problems][components]") {
  // A sphere and a torus side by side (vertex numbers interleave nothing: the torus's follow).
  const ice::TriangleMesh sphere = ice::make_icosphere(3);
  ice::TriangleMesh torus = ice::make_torus(24, 12, 1.0, 0.35);
  torus.V.col(0).array() += 4.0;
  ice::TriangleMesh both;
  const Eigen::Index ns = sphere.V.rows(), nt = torus.V.rows();
  both.V.resize(ns + nt, 3);
  both.V << sphere.V, torus.V;
  both.F.resize(sphere.F.rows() + torus.F.rows(), 3);
  both.F << sphere.F, (torus.F.array() + static_cast<int>(ns)).matrix();
  const Discretisation d_both = discretise(both), d_sphere = discretise(sphere), d_torus = discretise(torus);

  const fem::ComponentLabels components = fem::component_labels(d_both.laplacian);
  REQUIRE(components.count() == 2);
  CHECK(components.first == std::vector<fem::Index>{0, static_cast<fem::Index>(ns)});
  CHECK(fem::vertex_components(both.F, ns + nt).label == components.label);

  // A source with a non-zero mean on each component: each is made compatible on its own.
  Eigen::VectorXd f(ns + nt);
  for (Eigen::Index i = 0; i < ns + nt; ++i) f[i] = both.V(i, 2) + 0.3 * both.V(i, 1) + (i < ns ? 1.0 : -2.0);
  const Eigen::VectorXd u = fem::PoissonSolver::zero_mean(d_both.laplacian, d_both.mass).solve(f);
  const Eigen::VectorXd u_sphere = fem::PoissonSolver::zero_mean(d_sphere.laplacian, d_sphere.mass).solve(f.head(ns));
  const Eigen::VectorXd u_torus = fem::PoissonSolver::zero_mean(d_torus.laplacian, d_torus.mass).solve(f.tail(nt));
  CHECK((u.head(ns) - u_sphere).cwiseAbs().maxCoeff() < 1e-10 * u_sphere.cwiseAbs().maxCoeff());
  CHECK((u.tail(nt) - u_torus).cwiseAbs().maxCoeff() < 1e-10 * u_torus.cwiseAbs().maxCoeff());
  // zero mass-weighted mean on each
  const Eigen::VectorXd m = d_both.mass * Eigen::VectorXd::Ones(ns + nt);
  CHECK(std::abs(m.head(ns).dot(u.head(ns))) < 1e-12);
  CHECK(std::abs(m.tail(nt).dot(u.tail(nt))) < 1e-12);

  // Dirichlet needs a value in each component, and says which one lacks it.
  CHECK_THROWS_WITH(fem::PoissonSolver::dirichlet(d_both.laplacian, d_both.mass, {3}),
                    Catch::Contains("2 connected components") && Catch::Contains("vertex " + std::to_string(ns)));
  CHECK_NOTHROW(fem::PoissonSolver::dirichlet(d_both.laplacian, d_both.mass, {3, static_cast<fem::Index>(ns + 5)}));

  // Geodesics from a sphere vertex: the sphere's distances, +inf on the torus; and from one source
  // on each, each component's own.
  // (one time step for all: t = h² follows the mean edge length, which the union averages)
  fem::HeatMethodOperators ops_both = fem::heat_method_operators(ice::intrinsic_mesh(both.F, d_both.lengths));
  fem::HeatMethodOperators ops_sphere = fem::heat_method_operators(ice::intrinsic_mesh(sphere.F, d_sphere.lengths));
  fem::HeatMethodOperators ops_torus = fem::heat_method_operators(ice::intrinsic_mesh(torus.F, d_torus.lengths));
  ops_sphere.time_step = ops_torus.time_step = ops_both.time_step;
  const fem::HeatGeodesicSolver geodesic_both(std::move(ops_both));
  const fem::HeatGeodesicSolver geodesic_sphere(std::move(ops_sphere));
  const fem::HeatGeodesicSolver geodesic_torus(std::move(ops_torus));
  const Eigen::VectorXd d = geodesic_both.distance({7});
  const Eigen::VectorXd d_alone = geodesic_sphere.distance({7});
  CHECK((d.head(ns) - d_alone).cwiseAbs().maxCoeff() < 1e-9);
  CHECK((d.tail(nt).array() == std::numeric_limits<double>::infinity()).all());
  const Eigen::VectorXd d2 = geodesic_both.distance({7, static_cast<fem::Index>(ns + 11)});
  CHECK((d2.head(ns) - d_alone).cwiseAbs().maxCoeff() < 1e-9);
  CHECK((d2.tail(nt) - geodesic_torus.distance({11})).cwiseAbs().maxCoeff() < 1e-9);
  const Eigen::MatrixXd each = geodesic_both.distances_from_each({7, static_cast<fem::Index>(ns + 11)});
  CHECK((each.col(0).head(ns) - d_alone).cwiseAbs().maxCoeff() < 1e-9);
  CHECK((each.col(0).tail(nt).array() == std::numeric_limits<double>::infinity()).all());
  CHECK((each.col(1).head(ns).array() == std::numeric_limits<double>::infinity()).all());
  CHECK((each.col(1).tail(nt) - geodesic_torus.distance({11})).cwiseAbs().maxCoeff() < 1e-9);

  // Errors leave out the vertices neither reaches; one +inf against a finite value is an infinite error.
  Eigen::VectorXd approx = d;
  approx.head(ns) *= 1.01;
  const fem::DistanceErrors e = fem::distance_errors(approx, d);
  CHECK(e.max_relative == Approx(0.01).epsilon(1e-9));
  CHECK(std::isfinite(fem::relative_l2_error(approx, d, d_both.mass)));
  approx[ns] = 1.0;
  CHECK(std::isinf(fem::distance_errors(approx, d).max_relative));
}

TEST_CASE("boundary_vertices: the ends of the sides no other face shares, Δ-complexes too", "[fem][topology]") {
  // Against counting sides by their end vertices (one side: a boundary edge; loop sides of a
  // Δ-complex count once per face side, as the intrinsic Delaunay triangulation makes them).
  const auto by_side_count = [](const ice::Faces& F) {
    std::map<std::pair<int, int>, int> count;
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k) ++count[std::minmax(F(f, k), F(f, (k + 1) % 3))];
    std::set<int> ends;
    for (const auto& [side, faces] : count)
      if (faces == 1) ends.insert({side.first, side.second});
    return std::vector<int>(ends.begin(), ends.end());
  };
  const ice::TriangleMesh holes = ice::load_mesh(ice_test::project_mesh("elephant-with-holes.off"));
  const ice::TriangleMesh disk = ice::make_flat_disk(5);
  for (const ice::Faces& F : {holes.F, disk.F, ice::fine_mesh(holes, ice::FineGeometry::intrinsic_delaunay).F,
                              ice::Faces(ice::make_icosphere(1).F)}) {
    CHECK(fem::boundary_vertices(F) == by_side_count(F));
  }
  CHECK(fem::boundary_vertices(ice::make_icosphere(1).F).empty());
  CHECK(!fem::boundary_vertices(disk.F).empty());
  // A loop side on the boundary: the face (0, 0, 1), its loop side 0 → 0 glued to nothing and its
  // sides 0 → 1 and 1 → 0 to each other (a cone).
  ice::Faces loop(1, 3);
  loop << 0, 0, 1;
  CHECK(fem::boundary_vertices(loop) == std::vector<int>{0});
  CHECK(by_side_count(loop) == std::vector<int>{0});
}
