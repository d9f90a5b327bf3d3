// Polishing the proxy (fem::PolishOptions): from the plain proxy towards the fine solution by
// two-level-preconditioned CG on the fine system, with an error estimate and a tolerance.
// Properties checked: the error falls as polishing grows and reaches round-off; the estimate bounds
// the true error within the stated factor; a tolerance is met; Dirichlet values stay exact; heat
// steps converge to the fine backward-Euler trajectory; the multigrid error estimate is 0 at the
// exact solution.
#include <catch2/catch.hpp>

#include <vector>

#include <Eigen/Eigenvalues>

#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "fem/topology.h"
#include "ice/coarse_space.h"
#include "ice/mesh_io.h"
#include "test_support.h"

namespace {

struct PolishFixture {
  ice::TriangleMesh mesh;
  ice::FineMesh fine;
  ice::CoarseSpace space;
  Eigen::VectorXd f;

  PolishFixture(const std::string& name, double ratio, std::vector<ice::Index> locked = {}) {
    mesh = ice::load_mesh(ice_test::project_mesh(name));
    ice::CoarseSpaceOptions options;
    options.coarsen.target_ratio = ratio;
    options.coarsen.locked_vertices = std::move(locked);
    space = ice::build_coarse_space(mesh, options);
    fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
    const Eigen::Index n = mesh.V.rows();
    f.resize(n);
    // Smooth but not tiny at the coarse scale: two waves along the bounding box.
    const Eigen::RowVector3d low = mesh.V.colwise().minCoeff(), size = mesh.V.colwise().maxCoeff() - low;
    for (Eigen::Index i = 0; i < n; ++i)
      f(i) = std::sin(6 * (mesh.V(i, 0) - low(0)) / size(0)) + std::cos(5 * (mesh.V(i, 1) - low(1)) / size(1));
  }
  fem::CoarseProxy proxy(fem::CoarseOperatorKind kind = fem::CoarseOperatorKind::intrinsic) const {
    return fem::CoarseProxy(ice::intrinsic_mesh(fine.F, fine.L), ice::intrinsic_mesh(space.mesh.F, space.mesh.L), space.P, {kind});
  }
};

fem::PolishOptions iterations(int count) {
  fem::PolishOptions options;
  options.iterations = count;
  return options;
}

}  // namespace

TEST_CASE("polishing the Poisson proxy converges to the fine solution; the estimate tracks the error",
          "[fem][polish]") {
  for (const char* name : {"lion-head.off", "fandisk.off"}) {
    INFO(name);
    const PolishFixture fx(name, 0.05);
    for (fem::CoarseOperatorKind kind : {fem::CoarseOperatorKind::intrinsic, fem::CoarseOperatorKind::galerkin}) {
      INFO((kind == fem::CoarseOperatorKind::intrinsic ? "intrinsic" : "galerkin"));
      const fem::CoarseProxy proxy = fx.proxy(kind);
      const fem::SparseMatrix& M = proxy.fine_mass();
      const Eigen::VectorXd reference = fem::PoissonSolver::zero_mean(proxy.fine_laplacian(), M).solve(fx.f);
      const double plain = fem::relative_l2_error(fem::ProxyPoissonSolver(proxy).solve(fx.f), reference, M);
      double previous = plain;
      for (int count : {1, 2, 4, 8, 40}) {
        INFO("polish " << count);
        const fem::ProxyPoissonSolver solver(proxy, {}, iterations(count));
        REQUIRE(solver.is_polishing());
        CHECK(solver.polish_setup_seconds() > 0);
        fem::PolishReport report;
        const Eigen::VectorXd u = solver.solve(fx.f, {}, nullptr, &report);
        const double error = fem::relative_l2_error(u, reference, M);
        CHECK(std::abs((M * u).sum()) <= 1e-10 * (M * u.cwiseAbs()).sum());  // zero mean kept
        CHECK(report.error_estimates.size() == static_cast<std::size_t>(report.iterations + 1));
        CHECK(report.iterations <= count);
        CHECK_FALSE(report.reached_tolerance);  // none asked for
        if (count == 40) {
          CHECK(error < 1e-9);  // round-off of the fine solve: polishing converges to it
          continue;
        }
        CHECK(report.iterations == count);
        CHECK(error < 0.7 * previous);  // every step of this ladder gains (measured: 2.5-60x per step)
        previous = error;
        // From the iteration the tolerance test starts at, the estimate is within the factor it relies
        // on (PolishOptions::estimate_safety) and not wildly pessimistic (measured over 40 meshes:
        // true / estimate 0.045–1.63).
        const fem::PolishOptions defaults;
        if (count >= defaults.cycle.error_min_iterations) {
          CHECK(report.estimated_error > error / defaults.estimate_safety);
          CHECK(report.estimated_error < 25 * error);
        }
      }
    }
  }
}

TEST_CASE("polishing to a tolerance meets it", "[fem][polish]") {
  for (const char* name : {"lion-head.off", "fandisk.off", "elephant-with-holes.off"}) {
    INFO(name);
    const PolishFixture fx(name, 0.05);
    const fem::CoarseProxy proxy = fx.proxy();
    const fem::SparseMatrix& M = proxy.fine_mass();
    const Eigen::VectorXd reference = fem::PoissonSolver::zero_mean(proxy.fine_laplacian(), M).solve(fx.f);
    int previous_iterations = 0;
    for (double tolerance : {1e-2, 1e-3, 1e-6}) {
      INFO("tolerance " << tolerance);
      fem::PolishOptions options;
      options.tolerance = tolerance;
      const fem::ProxyPoissonSolver solver(proxy, {}, options);
      fem::PolishReport report;
      const Eigen::VectorXd u = solver.solve(fx.f, {}, nullptr, &report);
      CHECK(report.reached_tolerance);
      CHECK(report.estimated_error * options.estimate_safety <= tolerance);
      CHECK(fem::relative_l2_error(u, reference, M) <= tolerance);
      CHECK(report.iterations >= previous_iterations);  // a tighter tolerance never takes fewer
      previous_iterations = report.iterations;
    }
  }
}

TEST_CASE("polishing with Dirichlet values keeps them exact", "[fem][polish]") {
  const ice::TriangleMesh boundary_mesh = ice::load_mesh(ice_test::project_mesh("lion-head.off"));
  const std::vector<int> fixed = fem::boundary_vertices(boundary_mesh.F);
  const PolishFixture fx("lion-head.off", 0.05, std::vector<ice::Index>(fixed.begin(), fixed.end()));
  Eigen::VectorXd values(static_cast<Eigen::Index>(fixed.size()));
  for (std::size_t i = 0; i < fixed.size(); ++i) values(static_cast<Eigen::Index>(i)) = fx.mesh.V(fixed[i], 2);
  const fem::CoarseProxy proxy = fx.proxy();
  const fem::SparseMatrix& M = proxy.fine_mass();
  const Eigen::VectorXd reference =
      fem::PoissonSolver::dirichlet(proxy.fine_laplacian(), M, fixed).solve(fx.f, values);
  const double plain = fem::relative_l2_error(fem::ProxyPoissonSolver(proxy, fixed).solve(fx.f, values), reference, M);
  fem::PolishReport report;
  const Eigen::VectorXd u = fem::ProxyPoissonSolver(proxy, fixed, iterations(6)).solve(fx.f, values, nullptr, &report);
  for (std::size_t i = 0; i < fixed.size(); ++i) CHECK(u(fixed[i]) == values(static_cast<Eigen::Index>(i)));
  CHECK(report.iterations == 6);
  CHECK(fem::relative_l2_error(u, reference, M) < 0.01 * plain);
}

TEST_CASE("polished heat steps approach the fine backward-Euler trajectory", "[fem][polish]") {
  const PolishFixture fx("lion-head.off", 0.05);
  const fem::CoarseProxy proxy = fx.proxy();
  const fem::SparseMatrix& M = proxy.fine_mass();
  const double area = M.sum(), time_step = 0.002 * area;
  const int steps = 3;
  const Eigen::VectorXd reference = fem::HeatSolver(proxy.fine_laplacian(), M, time_step).integrate(fx.f, steps);
  for (fem::RestrictionKind restriction : {fem::RestrictionKind::l2_projection, fem::RestrictionKind::injection}) {
    INFO((restriction == fem::RestrictionKind::injection ? "injection" : "L2 projection"));
    const double plain =
        fem::relative_l2_error(fem::ProxyHeatSolver(proxy, time_step, restriction).integrate(fx.f, steps), reference, M);
    fem::PolishReport report;
    const Eigen::VectorXd polished =
        fem::ProxyHeatSolver(proxy, time_step, restriction, iterations(3)).integrate(fx.f, steps, nullptr, &report);
    CHECK(report.iterations == 3 * steps);
    CHECK(fem::relative_l2_error(polished, reference, M) < 0.05 * plain);
    fem::PolishOptions tolerance;
    tolerance.tolerance = 1e-6;
    const Eigen::VectorXd tight =
        fem::ProxyHeatSolver(proxy, time_step, restriction, tolerance).integrate(fx.f, steps, nullptr, &report);
    CHECK(report.reached_tolerance);
    CHECK(fem::relative_l2_error(tight, reference, M) <= 1e-6);
  }
}

TEST_CASE("multigrid error estimate: zero at the exact solution, refused before setup", "[fem][polish][multigrid]") {
  const PolishFixture fx("lion-head.off", 0.05);
  const fem::CoarseProxy proxy = fx.proxy();
  const fem::SparseMatrix A = proxy.fine_mass() + 0.01 * proxy.fine_laplacian();
  fem::MultigridSolver solver({proxy.prolongation()});
  CHECK_THROWS_AS(solver.set_error_norm(Eigen::VectorXd::Ones(A.rows()), false), std::invalid_argument);
  solver.setup(A);
  CHECK_THROWS_AS(solver.set_error_norm(Eigen::VectorXd::Ones(3), false), std::invalid_argument);
  CHECK_THROWS_AS(solver.set_error_norm(-Eigen::VectorXd::Ones(A.rows()), false), std::invalid_argument);
  const Eigen::VectorXd b = proxy.fine_mass() * fx.f;
  const Eigen::VectorXd exact = fem::CholeskySolver(A).solve(b);
  solver.set_error_norm(proxy.fine_mass() * Eigen::VectorXd::Ones(A.rows()), false);
  solver.solve(b, {}, exact);
  REQUIRE(solver.report().error_estimates.size() == 1);
  CHECK(solver.report().error_estimates.front() < 1e-12);
  CHECK(solver.report().iterations == 0);
  // From zero the first estimate is about 1 (the whole solution is error) and falls to the tolerance.
  fem::MultigridOptions options;
  options.error_tolerance = 1e-7;
  options.tolerance = 1e-15;
  solver.set_options(options);
  const Eigen::VectorXd x = solver.solve(b);
  CHECK(solver.report().converged);
  CHECK(solver.report().error_estimates.front() > 0.3);
  CHECK(solver.report().error_estimates.back() <= 1e-7);
  CHECK(fem::relative_l2_error(x, exact, proxy.fine_mass()) < 1e-6);
  // Turned off: no estimates.
  solver.set_error_norm(Eigen::VectorXd(), false);
  solver.solve(b);
  CHECK(solver.report().error_estimates.empty());
}

TEST_CASE("Galerkin coarse operators: symmetric, positive semidefinite, constants the only null space",
          "[fem][coarse_proxy][galerkin]") {
  for (const char* name : {"lion-head.off", "spot.obj"}) {
    INFO(name);
    const PolishFixture fx(name, 0.05);
    const fem::CoarseProxy proxy = fx.proxy(fem::CoarseOperatorKind::galerkin);
    const Eigen::MatrixXd L = Eigen::MatrixXd(proxy.coarse_laplacian());
    const Eigen::MatrixXd M = Eigen::MatrixXd(proxy.coarse_mass());
    const double scale = L.cwiseAbs().maxCoeff();
    CHECK((L - L.transpose()).cwiseAbs().maxCoeff() <= 1e-13 * scale);
    CHECK((M - M.transpose()).cwiseAbs().maxCoeff() <= 1e-13 * M.cwiseAbs().maxCoeff());
    // P·1 = 1 and L·1 = 0 on the fine mesh, so constants stay in the null space.
    CHECK((L * Eigen::VectorXd::Ones(L.rows())).cwiseAbs().maxCoeff() <= 1e-10 * scale);
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> laplacian(L);
    CHECK(laplacian.eigenvalues()(0) >= -1e-10 * scale);
    CHECK(laplacian.eigenvalues()(1) > 1e-8 * scale);  // connected: a one-dimensional null space
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> mass(M);
    CHECK(mass.eigenvalues()(0) > 0);
    CHECK(M.sum() == Approx(proxy.fine_mass().sum()).epsilon(1e-12));  // the same total area
  }
}
