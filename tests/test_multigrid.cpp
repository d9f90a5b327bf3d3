// Tests of the ICE hierarchy (ice/hierarchy.h) and the Galerkin multigrid solver (fem/multigrid.h):
// agreement with CHOLMOD on real meshes (closed and open, with and without Dirichlet vertices),
// monotone PCG convergence, recorded convergence factors, matrix updates, option checks.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>

#include "fem/cholesky.h"
#include "fem/multigrid.h"
#include "fem/operators.h"
#include "fem/problems.h"
#include "ice/hierarchy.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "test_support.h"

namespace {

struct Setup {
  ice::TriangleMesh mesh;
  ice::Hierarchy hierarchy;
  fem::SparseMatrix L, M;
};

// Loads a project-set mesh and builds its hierarchy once per test binary run (coarsening is the slow part).
const Setup& mesh_setup(const std::string& name) {
  static std::map<std::string, Setup> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return it->second;
  Setup s;
  s.mesh = ice::load_mesh(ice_test::project_mesh(name));
  ice::HierarchyOptions options;
  options.coarsest_vertices = 150;  // several levels even on small meshes
  s.hierarchy = ice::build_hierarchy(s.mesh, options);
  // Operators on the intrinsic Delaunay triangulation of the input (same vertices; what the tools
  // use by default): non-negative cotan weights. The raw extrinsic Laplacian is tested separately.
  ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_mesh(s.mesh.V, s.mesh.F);
  T.flip_to_delaunay();
  const ice::CompactMesh idt = T.compact();
  s.L = fem::cotan_laplacian(idt);
  s.M = fem::mass_matrix(idt, fem::MassKind::lumped);
  return cache.emplace(name, std::move(s)).first->second;
}

// A smooth-plus-rough right-hand side, deterministic.
Eigen::VectorXd test_rhs(const Setup& s) {
  const Eigen::Index n = s.mesh.V.rows();
  Eigen::VectorXd f(n);
  for (Eigen::Index i = 0; i < n; ++i)
    f(i) = std::sin(3 * s.mesh.V(i, 0)) + std::cos(5 * s.mesh.V(i, 1)) + 0.3 * std::sin(17.0 * static_cast<double>(i));
  return s.M * f;
}

using ice_test::relative_difference;

// Boundary vertices of a mesh (vertices of edges with one face).
std::vector<int> boundary_vertices(const ice::Faces& F) {
  std::map<std::pair<int, int>, int> count;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      ++count[{std::min(a, b), std::max(a, b)}];
    }
  std::vector<int> out;
  for (const auto& [edge, c] : count)
    if (c == 1) {
      out.push_back(edge.first);
      out.push_back(edge.second);
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// Scale-free shift: ε = 1e-2 / (mean vertex area) makes εM comparable to a low mode of L.
double shift(const Setup& s) { return 1e-2 * s.M.rows() / s.M.sum(); }

}  // namespace

TEST_CASE("hierarchy levels shrink by the ratio, prolongations are barycentric and consistent", "[multigrid][hierarchy][meshes]") {
  const Setup& s = mesh_setup("spot.obj");
  const ice::Hierarchy& H = s.hierarchy;
  REQUIRE(H.num_levels() >= 3);
  REQUIRE(H.prolongations.size() == static_cast<std::size_t>(H.num_levels() - 1));
  CHECK(H.levels[0].num_vertices() == s.mesh.V.rows());
  CHECK(H.levels.back().num_vertices() <= 150);
  for (int k = 0; k + 1 < H.num_levels(); ++k) {
    INFO("level " << k);
    const auto& P = H.prolongations[static_cast<std::size_t>(k)];
    const double n = H.levels[static_cast<std::size_t>(k)].num_vertices();
    const double nc = H.levels[static_cast<std::size_t>(k) + 1].num_vertices();
    CHECK(P.rows() == n);
    CHECK(P.cols() == nc);
    if (k + 2 < H.num_levels()) CHECK(nc <= 0.3 * n);  // ratio 0.25 (+ rounding); the last level stops at 150
    const Eigen::VectorXd row_sums = P * Eigen::VectorXd::Ones(P.cols());
    CHECK((row_sums.array() - 1).abs().maxCoeff() < 1e-12);
    CHECK(P.coeffs().minCoeff() >= 0);
  }
  // A coarse vertex is a fine vertex: prolonging the coarse copy of a linear function reproduces it
  // closely (barycentric interpolation on the intrinsic coarse mesh), and exactly at coarse vertices.
  const int last = H.num_levels() - 1;
  const Eigen::SparseMatrix<double> P = H.prolongation_to_fine(last);
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::VectorXd g = s.mesh.V.col(axis);
    Eigen::VectorXd gc(H.levels.back().num_vertices());
    for (Eigen::Index i = 0; i < gc.size(); ++i) gc(i) = g(H.levels.back().to_fine[static_cast<std::size_t>(i)]);
    const Eigen::VectorXd e = P * gc - g;
    CHECK(e.cwiseAbs().maxCoeff() < 0.2 * (g.maxCoeff() - g.minCoeff()));  // measured 8-12 % at 150 vertices
    for (Eigen::Index i = 0; i < gc.size(); ++i) CHECK(std::abs(e(H.levels.back().to_fine[static_cast<std::size_t>(i)])) < 1e-12);
  }
  CHECK(H.grid_complexity() < 1.4);
  CHECK(H.coarsen_seconds <= H.seconds);
}

TEST_CASE("multigrid PCG equals CHOLMOD on closed and open real meshes (L + eps M)", "[multigrid][meshes]") {
  for (const char* name : {"spot.obj", "lion-head.off"}) {
    INFO(name);
    const Setup& s = mesh_setup(name);
    const fem::SparseMatrix A = s.L + shift(s) * s.M;
    const Eigen::VectorXd b = test_rhs(s);
    const Eigen::VectorXd reference = fem::CholeskySolver(A).solve(b);
    for (double tolerance : {1e-6, 1e-10}) {
      INFO("tolerance " << tolerance);
      fem::MultigridOptions options;
      options.tolerance = tolerance;
      fem::MultigridSolver solver(s.hierarchy.prolongations, options);
      solver.setup(A);
      CHECK(solver.num_levels() == s.hierarchy.num_levels());
      const Eigen::VectorXd x = solver.solve(b);
      const fem::MultigridReport& r = solver.report();
      CHECK(r.converged);
      CHECK(r.relative_residual <= tolerance);
      CHECK((A * (x - reference)).norm() <= tolerance * b.norm());
      CHECK(relative_difference(x, reference) < 1e3 * tolerance);
      CHECK(r.residuals.size() == static_cast<std::size_t>(r.iterations) + 1);
      CHECK(r.convergence_factor > 0);
      // Measured (symmetric Gauss-Seidel V(1,1) in PCG): spot 0.12-0.13, lion-head 0.25-0.28 (a scan
      // with 4.5° corners, which a point smoother handles less well; camelhead, a raw scan with sliver
      // triangles, was 0.21-0.25).
      CHECK(r.convergence_factor < (std::string(name) == "spot.obj" ? 0.2 : 0.35));
    }
  }
}

TEST_CASE("multigrid with Dirichlet vertices equals the eliminated CHOLMOD solve", "[multigrid][dirichlet][meshes]") {
  SECTION("closed mesh, a few scattered Dirichlet vertices with values") {
    const Setup& s = mesh_setup("spot.obj");
    const std::vector<int> fixed{2100, 0, 2900, 700, 1400};  // not sorted: values follow this order
    Eigen::VectorXd values(5);
    values << 1, -1, 0.5, 2, 0;
    const Eigen::VectorXd b = test_rhs(s);
    const Eigen::VectorXd reference = fem::ConstrainedSolver(s.L, fixed).solve(b, values);
    fem::MultigridSolver solver(s.hierarchy.prolongations, {});
    solver.setup(s.L, fixed);
    const Eigen::VectorXd x = solver.solve(b, values);
    CHECK(solver.report().converged);
    CHECK(solver.report().convergence_factor < 0.2);
    CHECK(relative_difference(x, reference) < 1e-5);
    for (std::size_t i = 0; i < fixed.size(); ++i) CHECK(x(fixed[i]) == values(static_cast<Eigen::Index>(i)));
  }
  SECTION("open mesh, the whole boundary Dirichlet (most coarse boundary unknowns are dropped)") {
    const Setup& s = mesh_setup("lion-head.off");
    const std::vector<int> boundary = boundary_vertices(s.mesh.F);
    REQUIRE(boundary.size() > 30);  // lion-head: one loop of 36 vertices
    Eigen::VectorXd values(static_cast<Eigen::Index>(boundary.size()));
    for (std::size_t i = 0; i < boundary.size(); ++i) values(static_cast<Eigen::Index>(i)) = s.mesh.V(boundary[i], 2);
    const Eigen::VectorXd b = test_rhs(s);
    const Eigen::VectorXd reference = fem::ConstrainedSolver(s.L, boundary).solve(b, values);
    fem::MultigridOptions options;
    options.tolerance = 1e-10;
    fem::MultigridSolver solver(s.hierarchy.prolongations, options);
    solver.setup(s.L, boundary);
    CHECK(solver.level_operator(0).rows() == s.L.rows() - static_cast<Eigen::Index>(boundary.size()));
    const Eigen::VectorXd x = solver.solve(b, values);
    CHECK(solver.report().converged);
    CHECK(solver.report().convergence_factor < 0.3);  // measured 0.14 (lion-head), 0.18-0.24 (camelhead)
    CHECK(relative_difference(x, reference) < 1e-7);
    // Zero Dirichlet values and a V-cycle solver give the same answer too.
    options.mode = fem::MultigridMode::vcycle;
    solver.set_options(options);
    const Eigen::VectorXd x0 = solver.solve(b);
    CHECK(solver.report().converged);
    CHECK(relative_difference(x0, fem::ConstrainedSolver(s.L, boundary).solve(b)) < 1e-7);
  }
  SECTION("pinned zero-mean Poisson on a closed mesh (what poisson-coarse --solver multigrid does)") {
    const Setup& s = mesh_setup("spot.obj");
    Eigen::VectorXd b = test_rhs(s);
    b.array() -= b.sum() / static_cast<double>(b.size());
    const Eigen::VectorXd reference = fem::ConstrainedSolver(s.L, {0}).solve(b);
    fem::MultigridSolver solver(s.hierarchy.prolongations, {});
    solver.setup(s.L, {0});
    const Eigen::VectorXd x = solver.solve(b);
    CHECK(solver.report().converged);
    CHECK(relative_difference(x, reference) < 1e-5);
  }
}

TEST_CASE("multigrid also converges on the raw extrinsic Laplacian (negative cotan weights)", "[multigrid][meshes]") {
  const Setup& s = mesh_setup("lion-head.off");
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(s.mesh.V, s.mesh.F);
  const fem::SparseMatrix A = fem::cotan_laplacian(ice::intrinsic_mesh(s.mesh.F, lengths)) + shift(s) * s.M;
  const Eigen::VectorXd b = test_rhs(s);
  fem::MultigridSolver solver(s.hierarchy.prolongations, {});
  solver.setup(A);
  const Eigen::VectorXd x = solver.solve(b);
  CHECK(solver.report().converged);
  CHECK(solver.report().convergence_factor < 0.4);  // measured 0.28-0.29
  CHECK(relative_difference(x, fem::CholeskySolver(A).solve(b)) < 1e-5);
}

TEST_CASE("PCG error falls monotonically in the energy norm, residuals nearly monotonically", "[multigrid][meshes]") {
  for (const char* name : {"spot.obj", "lion-head.off"}) {
    INFO(name);
    const Setup& s = mesh_setup(name);
    const fem::SparseMatrix A = s.L + shift(s) * s.M;
    const Eigen::VectorXd b = test_rhs(s);
    const Eigen::VectorXd exact = fem::CholeskySolver(A).solve(b);
    fem::MultigridOptions options;
    options.tolerance = 1e-11;
    for (int k = 1;; ++k) {  // the k-th iterate is the result of a run capped at k iterations
      options.max_iterations = k;
      fem::MultigridSolver solver(s.hierarchy.prolongations, options);
      solver.setup(A);
      static double previous_energy;
      const Eigen::VectorXd e = solver.solve(b) - exact;
      const double energy = std::sqrt(e.dot(A * e));
      if (k > 1) CHECK(energy < previous_energy);
      previous_energy = energy;
      if (solver.report().converged || k > 40) {
        const std::vector<double>& res = solver.report().residuals;
        for (std::size_t i = 1; i < res.size(); ++i) CHECK(res[i] <= 1.05 * res[i - 1]);
        CHECK(solver.report().converged);
        break;
      }
    }
  }
}

TEST_CASE("one hierarchy serves many right-hand sides and matrices with the same pattern", "[multigrid][meshes]") {
  const Setup& s = mesh_setup("lion-head.off");
  const double h2 = s.M.sum() / static_cast<double>(s.M.rows());  // ~ mean edge length squared
  fem::MultigridOptions options;
  options.tolerance = 1e-10;
  fem::MultigridSolver solver(s.hierarchy.prolongations, options);
  solver.setup(s.M + h2 * s.L);
  for (double t : {h2, 10 * h2, 100 * h2}) {
    INFO("t = " << t);
    const fem::SparseMatrix A = s.M + t * s.L;
    solver.update_matrix(A);
    fem::CholeskySolver direct(A);
    for (int j = 0; j < 3; ++j) {
      Eigen::VectorXd b = test_rhs(s);
      for (Eigen::Index i = 0; i < b.size(); ++i) b(i) *= 1 + 0.5 * std::sin(0.01 * static_cast<double>(i * (j + 1)));
      const Eigen::VectorXd x = solver.solve(b);
      CHECK(solver.report().converged);
      CHECK(relative_difference(x, direct.solve(b)) < 1e-7);
    }
  }
}

TEST_CASE("multigrid smoothers and modes all converge; V-cycle alone is slower than PCG", "[multigrid][meshes]") {
  const Setup& s = mesh_setup("spot.obj");
  const fem::SparseMatrix A = s.L + shift(s) * s.M;
  const Eigen::VectorXd b = test_rhs(s);
  const Eigen::VectorXd reference = fem::CholeskySolver(A).solve(b);
  std::map<std::string, int> iterations;
  for (auto smoother : {fem::MultigridSmoother::gauss_seidel, fem::MultigridSmoother::symmetric_gauss_seidel,
                        fem::MultigridSmoother::chebyshev})
    for (auto mode : {fem::MultigridMode::pcg, fem::MultigridMode::vcycle}) {
      const std::string label = std::string(fem::to_string(smoother)) + "/" + fem::to_string(mode);
      INFO(label);
      fem::MultigridOptions options;
      options.smoother = smoother;
      options.mode = mode;
      options.smoothing_steps = smoother == fem::MultigridSmoother::chebyshev ? 2 : 1;
      fem::MultigridSolver solver(s.hierarchy.prolongations, options);
      solver.setup(A);
      const Eigen::VectorXd x = solver.solve(b);
      CHECK(solver.report().converged);
      CHECK(relative_difference(x, reference) < 1e-5);
      iterations[label] = solver.report().iterations;
    }
  CHECK(iterations["gauss_seidel/pcg"] <= iterations["gauss_seidel/vcycle"]);
  CHECK(iterations["symmetric_gauss_seidel/pcg"] <= iterations["gauss_seidel/pcg"]);
}

TEST_CASE("multigrid refuses bad input", "[multigrid]") {
  const Setup& s = mesh_setup("spot.obj");
  std::vector<fem::SparseMatrix> bad = s.hierarchy.prolongations;
  std::swap(bad[0], bad[1]);
  CHECK_THROWS_AS(fem::MultigridSolver(bad), std::invalid_argument);
  fem::MultigridOptions options;
  options.smoothing_steps = 0;
  CHECK_THROWS_AS(fem::MultigridSolver(s.hierarchy.prolongations, options), std::invalid_argument);
  fem::MultigridSolver solver(s.hierarchy.prolongations);
  CHECK_THROWS_AS(solver.solve(Eigen::VectorXd::Zero(s.L.rows())), std::logic_error);
  CHECK_THROWS_AS(solver.setup(fem::SparseMatrix(3, 3)), std::invalid_argument);
  CHECK_THROWS_AS(solver.setup(s.L, {-1}), std::invalid_argument);
  CHECK_THROWS_AS(solver.setup(s.L, {3, 5, 3}), std::invalid_argument);  // a repeat: which value would hold?
  solver.setup(s.L, {0});
  CHECK_THROWS_AS(solver.solve(Eigen::VectorXd::Zero(2)), std::invalid_argument);
  CHECK_THROWS_AS(solver.solve(Eigen::VectorXd::Zero(s.L.rows()), Eigen::VectorXd::Zero(2)), std::invalid_argument);
  // A zero right-hand side is solved at once.
  const Eigen::VectorXd x = solver.solve(Eigen::VectorXd::Zero(s.L.rows()));
  CHECK(x.norm() == 0);
  CHECK(solver.report().iterations == 0);
  CHECK_THROWS_AS(ice::build_hierarchy(s.mesh, [] { ice::HierarchyOptions o; o.ratio = 1.5; return o; }()),
                  std::invalid_argument);
  // Bad faces or lengths, with and without the breadth-first numbering.
  for (const bool reorder : {true, false}) {
    ice::HierarchyOptions o;
    o.reorder = reorder;
    ice::Faces F = s.mesh.F;
    const ice::FaceLengths L = ice::face_lengths_from_positions(s.mesh.V, s.mesh.F);
    CHECK_THROWS_AS(ice::build_hierarchy(ice::IntrinsicMesh{F, ice::FaceLengths(L.topRows(L.rows() - 1)), {}, static_cast<ice::Index>(s.mesh.V.rows())}, o), std::invalid_argument);
    ice::IntrinsicMesh glued = ice::intrinsic_mesh(s.mesh);
    const ice::Hierarchy by_pairs = ice::build_hierarchy(glued, o);
    // The same gluing given explicitly: the same levels, up to round-off (the triangulation numbers its
    // edges in another order, so flips and sums run in another order).
    glued.twin = ice::glue_by_vertex_pairs(glued.F);
    const ice::Hierarchy by_twin = ice::build_hierarchy(glued, o);
    REQUIRE(by_twin.num_levels() == by_pairs.num_levels());
    for (std::size_t k = 0; k < by_pairs.prolongations.size(); ++k) {
      CHECK(by_twin.prolongations[k].nonZeros() == by_pairs.prolongations[k].nonZeros());
      CHECK(relative_difference(by_twin.prolongations[k], by_pairs.prolongations[k]) < 1e-4);
    }
    CHECK(by_twin.levels.back().twin.size() == 3 * static_cast<std::size_t>(by_twin.levels.back().F.rows()));
    glued.twin.pop_back();
    CHECK_THROWS_AS(ice::build_hierarchy(glued, o), std::invalid_argument);
    // An open mesh given with its gluing (its boundary sides kInvalid).
    ice::IntrinsicMesh open = ice::intrinsic_mesh(ice::load_mesh(ice_test::project_mesh("cat_head.obj")));
    open.twin = ice::glue_by_vertex_pairs(open.F);
    REQUIRE(std::count(open.twin.begin(), open.twin.end(), ice::kInvalid) > 0);
    ice::HierarchyOptions small = o;
    small.coarsest_vertices = 20;
    const ice::Hierarchy open_levels = ice::build_hierarchy(open, small);
    CHECK(open_levels.num_levels() >= 2);
    CHECK_THROWS_AS(ice::build_hierarchy(ice::intrinsic_mesh(F, L, static_cast<ice::Index>(s.mesh.V.rows()) + 1), o),
                    std::invalid_argument);  // a vertex no face uses
    F(3, 1) = -2;
    CHECK_THROWS_AS(ice::build_hierarchy(ice::intrinsic_mesh(F, L), o), std::invalid_argument);
  }
  // A locality order that is not a permutation of the unknowns.
  fem::MultigridSolver ordered(s.hierarchy.prolongations);
  std::vector<int> order = s.hierarchy.fine_order;
  order.pop_back();
  ordered.set_locality_order(order);
  CHECK_THROWS_AS(ordered.setup(s.L), std::invalid_argument);
  order.push_back(order.front());
  ordered.set_locality_order(order);
  CHECK_THROWS_AS(ordered.setup(s.L), std::invalid_argument);
}

TEST_CASE("the hierarchy's locality order numbers the solver's unknowns: the same solution as with RCM of A", "[multigrid][meshes]") {
  const Setup& s = mesh_setup("lion-head.off");
  const fem::SparseMatrix A = s.L + shift(s) * s.M;
  const Eigen::VectorXd b = test_rhs(s);
  REQUIRE(s.hierarchy.fine_order.size() == static_cast<std::size_t>(A.rows()));
  fem::MultigridOptions options;
  options.tolerance = 1e-10;
  fem::MultigridSolver own(s.hierarchy.prolongations, options), given(s.hierarchy.prolongations, options);
  given.set_locality_order(s.hierarchy.fine_order);
  own.setup(A);
  given.setup(A);
  CHECK(given.free_order() == s.hierarchy.fine_order);
  const Eigen::VectorXd x_own = own.solve(b), x_given = given.solve(b);
  CHECK(given.report().converged);
  CHECK(std::abs(given.report().iterations - own.report().iterations) <= 1);
  CHECK(relative_difference(x_given, x_own) < 1e-8);
  // Constrained unknowns are left out of the given order, which the others keep.
  given.setup(A, {0, 7});
  std::vector<int> expected;
  for (int v : s.hierarchy.fine_order)
    if (v != 0 && v != 7) expected.push_back(v);
  CHECK(given.free_order() == expected);
}

TEST_CASE("hierarchy variants (metric-ordered sets, plain greedy ICE, input numbering) give valid multigrid levels", "[multigrid][hierarchy][meshes]") {
  const Setup& s = mesh_setup("spot.obj");
  const fem::SparseMatrix A = s.L + shift(s) * s.M;
  const Eigen::VectorXd b = test_rhs(s);
  const Eigen::VectorXd reference = fem::CholeskySolver(A).solve(b);
  for (int variant = 0; variant < 3; ++variant) {
    INFO("variant " << variant);
    ice::HierarchyOptions options;
    options.coarsest_vertices = 150;
    options.locked_vertices = {0, 1000};
    if (variant == 0) options.coarsening = ice::LevelCoarsening::independent_sets_by_metric;
    if (variant == 1) options.coarsening = ice::LevelCoarsening::greedy;
    if (variant == 2) options.reorder = false;  // coarsened in the input's numbering
    const ice::Hierarchy H = ice::build_hierarchy(s.mesh, options);
    REQUIRE(H.num_levels() >= 3);
    for (const auto& level : H.levels) {  // locked vertices survive on every level
      CHECK(std::count(level.to_fine.begin(), level.to_fine.end(), 0) == 1);
      CHECK(std::count(level.to_fine.begin(), level.to_fine.end(), 1000) == 1);
    }
    for (const auto& P : H.prolongations) {
      const Eigen::VectorXd row_sums = P * Eigen::VectorXd::Ones(P.cols());
      CHECK((row_sums.array() - 1).abs().maxCoeff() < 1e-12);
    }
    // P_0's rows are in the input's numbering: a level-1 vertex prolongs to its own fine vertex.
    int identity_rows = 0;
    for (ice::Index i = 0; i < H.levels[1].num_vertices(); ++i)
      identity_rows += H.prolongations[0].coeff(H.levels[1].to_fine[static_cast<std::size_t>(i)], i) == 1.0;
    CHECK(identity_rows == H.levels[1].num_vertices());
    fem::MultigridSolver solver(H.prolongations);
    solver.setup(A);
    const Eigen::VectorXd x = solver.solve(b);
    CHECK(solver.report().converged);
    CHECK(relative_difference(x, reference) < 1e-5);
  }
}

TEST_CASE("solve_multiple equals column-by-column solves, with and without Dirichlet values", "[multigrid][meshes]") {
  const Setup& s = mesh_setup("lion-head.off");
  const std::vector<int> boundary = boundary_vertices(s.mesh.F);
  const Eigen::Index n = s.L.rows(), k = 4;
  Eigen::MatrixXd B(n, k), values(static_cast<Eigen::Index>(boundary.size()), k);
  for (Eigen::Index c = 0; c < k; ++c) {
    Eigen::VectorXd b = test_rhs(s);
    for (Eigen::Index i = 0; i < n; ++i) b(i) *= 1 + 0.5 * std::sin(0.003 * static_cast<double>(i) * (c + 1));
    B.col(c) = b;
    for (std::size_t i = 0; i < boundary.size(); ++i) values(static_cast<Eigen::Index>(i), c) = std::cos(c + s.mesh.V(boundary[i], 0));
  }
  for (auto smoother : {fem::MultigridSmoother::symmetric_gauss_seidel, fem::MultigridSmoother::gauss_seidel,
                        fem::MultigridSmoother::chebyshev})
    for (auto mode : {fem::MultigridMode::pcg, fem::MultigridMode::vcycle}) {
      INFO(fem::to_string(smoother) << " / " << fem::to_string(mode));
      fem::MultigridOptions options;
      options.tolerance = 1e-10;
      options.smoother = smoother;
      options.mode = mode;
      fem::MultigridSolver solver(s.hierarchy.prolongations, options);
      solver.setup(s.L, boundary);
      const Eigen::MatrixXd X = solver.solve_multiple(B, values);
      REQUIRE(solver.reports().size() == static_cast<std::size_t>(k));
      fem::ConstrainedSolver direct(s.L, boundary);
      for (Eigen::Index c = 0; c < k; ++c) {
        INFO("column " << c);
        const fem::MultigridReport report = solver.reports()[static_cast<std::size_t>(c)];
        CHECK(report.converged);
        CHECK(relative_difference(X.col(c), direct.solve(B.col(c), values.col(c))) < 1e-7);
        const Eigen::VectorXd x = solver.solve(B.col(c), values.col(c));
        CHECK(std::abs(solver.report().iterations - report.iterations) <= 1);  // same iteration up to round-off
        CHECK(relative_difference(X.col(c), x) < 1e-7);
      }
    }
}

TEST_CASE("apply_vcycle_multiple is one V-cycle per column from zero: solve_multiple's numbers, symmetric positive definite", "[multigrid][meshes]") {
  const Setup& s = mesh_setup("lion-head.off");
  const std::vector<int> boundary = boundary_vertices(s.mesh.F);
  const Eigen::Index n = s.L.rows(), k = 11;  // a chunk of 8 and one of 3
  Eigen::MatrixXd R(n, k);
  for (Eigen::Index c = 0; c < k; ++c) {
    Eigen::VectorXd b = test_rhs(s);
    for (Eigen::Index i = 0; i < n; ++i) b(i) *= 1 + 0.5 * std::sin(0.003 * static_cast<double>(i) * (c + 1));
    R.col(c) = b;
  }
  R.col(4).setZero();  // a zero column stays zero
  const fem::SparseMatrix A = s.L + shift(s) * s.M;
  fem::MultigridOptions options;
  options.mode = fem::MultigridMode::vcycle;
  options.max_iterations = 1;
  options.tolerance = std::numeric_limits<double>::min();
  fem::MultigridSolver solver(s.hierarchy.prolongations, options);
  CHECK_THROWS_AS(solver.apply_vcycle_multiple(R), std::logic_error);
  solver.setup(A, boundary);
  CHECK_THROWS_AS(solver.apply_vcycle_multiple(R.topRows(n - 1)), std::invalid_argument);
  const Eigen::MatrixXd Z = solver.apply_vcycle_multiple(R);
  const Eigen::MatrixXd cycled = solver.solve_multiple(R);
  REQUIRE(Z.rows() == n);
  REQUIRE(Z.cols() == k);
  CHECK((Z - cycled).cwiseAbs().maxCoeff() == 0.0);  // from zero (the first sweep skips the zeros) as from a zeroed X
  CHECK(Z.col(4).isZero(0));
  // Subtracted in place from chosen columns: the same cycle (to round-off: a chunk of another width
  // runs another kernel), the other columns untouched.
  const Eigen::MatrixXd X0 = Eigen::MatrixXd::Random(n, k);
  Eigen::MatrixXd X = X0;
  const std::vector<Eigen::Index> chosen{10, 0, 2, 5, 9};
  solver.subtract_vcycle_columns(R, chosen, X);
  for (Eigen::Index c = 0; c < k; ++c) {
    const bool listed = std::find(chosen.begin(), chosen.end(), c) != chosen.end();
    if (listed)
      CHECK((X0.col(c) - X.col(c) - Z.col(c)).norm() <= 1e-12 * Z.col(c).norm());
    else
      CHECK(X.col(c) == X0.col(c));
  }
  CHECK_THROWS_AS(solver.subtract_vcycle_columns(R, {k}, X), std::invalid_argument);
  Eigen::MatrixXd narrow = X0.leftCols(k - 1);
  CHECK_THROWS_AS(solver.subtract_vcycle_columns(R, chosen, narrow), std::invalid_argument);
  // One vector (its own kernel width): the same.
  CHECK((solver.apply_vcycle_multiple(R.leftCols(1)) - solver.solve_multiple(R.leftCols(1))).cwiseAbs().maxCoeff() == 0.0);
  for (int i : boundary) CHECK(Z.row(i).isZero(0));
  // B = the V-cycle operator on the free rows: rᵀ B s = sᵀ B r and rᵀ B r > 0.
  Eigen::MatrixXd free_R = R;
  for (int i : boundary) free_R.row(i).setZero();
  for (Eigen::Index a = 0; a < k; ++a) {
    if (a == 4) continue;
    CHECK(free_R.col(a).dot(Z.col(a)) > 0);
    for (Eigen::Index b = a + 1; b < k; ++b)
      CHECK(std::abs(free_R.col(a).dot(Z.col(b)) - free_R.col(b).dot(Z.col(a))) <=
            1e-10 * std::sqrt(free_R.col(a).dot(Z.col(a)) * free_R.col(b).dot(Z.col(b))));
  }
}

TEST_CASE("a large level's independent sets go range by range: the hierarchy is the same for any thread count, every level Delaunay",
          "[multigrid][hierarchy][threads][meshes]") {
  // 99k vertices: level 0 (50,000+ vertices) removes its sets in 16 index ranges, on the threads.
  const ice::TriangleMesh mesh = ice::loop_subdivide(ice::load_mesh(ice_test::project_mesh("bear.off")), 1);
  REQUIRE(mesh.V.rows() >= 50000);
  ice::HierarchyOptions options;
  options.threads = 1;
  const ice::Hierarchy serial = ice::build_hierarchy(mesh, options);
  options.threads = 2;
  const ice::Hierarchy threaded = ice::build_hierarchy(mesh, options);
  REQUIRE(serial.num_levels() == threaded.num_levels());
  REQUIRE(serial.num_levels() >= 4);
  for (std::size_t k = 0; k < serial.prolongations.size(); ++k) {
    INFO("level " << k);
    const auto& a = serial.prolongations[k];
    const auto& b = threaded.prolongations[k];
    REQUIRE(a.rows() == b.rows());
    REQUIRE(a.cols() == b.cols());
    CHECK(a.nonZeros() == b.nonZeros());
    CHECK((Eigen::SparseMatrix<double>(a - b)).coeffs().cwiseAbs().maxCoeff() == 0.0);
    CHECK(serial.levels[k + 1].to_fine == threaded.levels[k + 1].to_fine);
  }
  // The seams between the ranges are made Delaunay again, and so is every coarse level.
  for (int k = 1; k < threaded.num_levels(); ++k) {
    INFO("level " << k);
    const ice::HierarchyLevel& level = threaded.levels[static_cast<std::size_t>(k)];
    const ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_lengths(level.F, level.L);
    ice::Index non_delaunay = 0;
    for (ice::Index h = 0; h < T.num_halfedge_slots(); h += 2)
      if (T.halfedge_alive(h) && !T.is_delaunay(h, 1e-8)) ++non_delaunay;
    CHECK(non_delaunay == 0);
  }
}

TEST_CASE("threaded multigrid solves equal serial ones on a 55k-vertex mesh", "[multigrid][threads][meshes]") {
  // bear Loop-subdivided once: 55,000+ unknowns (a boundary too), so the finest level takes the
  // threaded kernels (50,000 rows and more). With 2 threads the Gauss–Seidel sweeps split the rows in two
  // ranges (coupled through a snapshot: a different but equally good smoother); Chebyshev steps,
  // products, transfers and CG vector operations split rows too, which changes round-off only. The
  // solution, the iteration counts and the convergence factor must not depend on it; nor on the
  // locality ordering (options.reorder).
  const ice::TriangleMesh mesh = ice::loop_subdivide(ice::load_mesh(ice_test::project_mesh("spot_subdiv.obj")), 1);
  REQUIRE(mesh.V.rows() >= 50000);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const fem::SparseMatrix M = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths));
  const fem::SparseMatrix A = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths)) + (1.0 / M.sum()) * M;
  Eigen::VectorXd f(mesh.V.rows());
  for (Eigen::Index i = 0; i < f.size(); ++i) f(i) = std::sin(3 * mesh.V(i, 0)) + 0.3 * std::sin(17.0 * static_cast<double>(i));
  const Eigen::VectorXd b = M * f;
  const ice::Hierarchy H = ice::build_hierarchy(mesh);
  for (auto smoother : {fem::MultigridSmoother::symmetric_gauss_seidel, fem::MultigridSmoother::chebyshev}) {
    Eigen::VectorXd reference;
    int reference_iterations = 0;
    // Reordered on 1 and 2 threads, then in the input order on 2: the thread count and the ordering
    // each changed once against the same reference.
    for (const auto& [reorder, threads] : {std::pair{true, 1}, std::pair{true, 2}, std::pair{false, 2}}) {
      INFO(fem::to_string(smoother) << ", reorder " << reorder << ", threads " << threads);
      fem::MultigridOptions options;
      options.smoother = smoother;
      options.threads = threads;
      options.reorder = reorder;
      options.tolerance = 1e-10;
      fem::MultigridSolver solver(H.prolongations, options);
      solver.setup(A);
      const Eigen::VectorXd x = solver.solve(b);
      CHECK(solver.report().converged);
      CHECK(solver.report().convergence_factor < 0.2);
      CHECK((A * x - b).norm() <= 1e-9 * b.norm());
      std::vector<int> order = solver.free_order();
      if (!reorder) CHECK(std::is_sorted(order.begin(), order.end()));
      std::sort(order.begin(), order.end());
      bool permutation = true;  // one assertion, not one per unknown (the sanitizer build's time)
      for (std::size_t i = 0; i < order.size(); ++i) permutation = permutation && order[i] == static_cast<int>(i);
      REQUIRE(permutation);
      if (reference.size() == 0) {
        reference = x;
        reference_iterations = solver.report().iterations;
      } else {
        CHECK(relative_difference(x, reference) < 1e-8);
        CHECK(std::abs(solver.report().iterations - reference_iterations) <= 1);
      }
      // Several right-hand sides at once take the same threaded, reordered paths.
      if (smoother == fem::MultigridSmoother::symmetric_gauss_seidel) {
        Eigen::MatrixXd B(b.size(), 3);
        B << b, 2 * b, M * Eigen::VectorXd::Ones(b.size());
        const Eigen::MatrixXd X = solver.solve_multiple(B);
        CHECK(relative_difference(X.col(0), reference) < 1e-8);
        CHECK(relative_difference(X.col(1), 2 * reference) < 1e-8);
        CHECK((A * X.col(2) - B.col(2)).norm() <= 1e-9 * B.col(2).norm());
      }
    }
  }
}

TEST_CASE("a single-precision smoother changes neither the answer nor the iteration count", "[multigrid][meshes]") {
  // The V-cycle's sweeps and residuals read float values; CG (and the finest level of a stationary
  // V-cycle iteration) stay double, so both modes still reach 1e-10 and the CHOLMOD solution.
  const Setup& s = mesh_setup("spot.obj");
  const fem::SparseMatrix A = s.L + shift(s) * s.M;
  const Eigen::VectorXd b = test_rhs(s);
  const Eigen::VectorXd reference = fem::CholeskySolver(A).solve(b);
  for (auto mode : {fem::MultigridMode::pcg, fem::MultigridMode::vcycle}) {
    int iterations[2] = {0, 0};
    for (bool single : {false, true}) {
      INFO(fem::to_string(mode) << ", single precision " << single);
      fem::MultigridOptions options;
      options.mode = mode;
      options.single_precision_smoother = single;
      options.tolerance = 1e-10;
      fem::MultigridSolver solver(s.hierarchy.prolongations, options);
      solver.setup(A);
      const Eigen::VectorXd x = solver.solve(b);
      CHECK(solver.report().converged);
      CHECK(relative_difference(x, reference) < 1e-8);
      iterations[single] = solver.report().iterations;
    }
    CHECK(std::abs(iterations[1] - iterations[0]) <= 1);
  }
}

TEST_CASE("boundary loops are coarsened at the rate of a curve; PCG on open meshes converges like on closed ones",
          "[multigrid][hierarchy][meshes]") {
  // Each level keeps r = 1/4 of the vertices, so a boundary loop should keep √r = 1/2 of its own. An
  // independent set on a loop takes every other vertex per pass, and a level takes about six passes:
  // before the boundary rule the loops kept 1/64 of their vertices, boundary rows of P reached 8–14
  // edges away and PCG converged at 0.32 per iteration on lion-head (0.07 on spot).
  const Setup& s = mesh_setup("lion-head.off");
  const ice::Hierarchy& H = s.hierarchy;
  REQUIRE(H.num_levels() >= 3);
  for (int k = 0; k + 2 < H.num_levels(); ++k) {  // the last level stops at coarsest_vertices
    INFO("level " << k);
    const double boundary = static_cast<double>(boundary_vertices(H.levels[static_cast<std::size_t>(k)].F).size());
    const double coarse_boundary = static_cast<double>(boundary_vertices(H.levels[static_cast<std::size_t>(k) + 1].F).size());
    CHECK(coarse_boundary >= 0.4 * boundary);
    CHECK(coarse_boundary <= 0.65 * boundary);
  }
  // Every fine boundary vertex is interpolated from coarse vertices at most 4 edges away.
  const ice::Faces& F = H.levels[0].F;
  const Eigen::Index n = s.mesh.V.rows();
  std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(n));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) neighbours[static_cast<std::size_t>(F(f, k))].push_back(F(f, (k + 1) % 3)),
        neighbours[static_cast<std::size_t>(F(f, (k + 1) % 3))].push_back(F(f, k));
  const Eigen::SparseMatrix<double, Eigen::RowMajor> P = H.prolongations[0];
  int farthest = 0;
  for (int v : boundary_vertices(F)) {
    std::map<int, int> hops{{v, 0}};
    std::vector<int> frontier{v};
    for (int d = 1; d <= 6; ++d) {
      std::vector<int> next;
      for (int u : frontier)
        for (int w : neighbours[static_cast<std::size_t>(u)])
          if (hops.emplace(w, d).second) next.push_back(w);
      frontier = std::move(next);
    }
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(P, v); it; ++it) {
      const auto found = hops.find(H.levels[1].to_fine[static_cast<std::size_t>(it.col())]);
      farthest = std::max(farthest, found == hops.end() ? 99 : found->second);
    }
  }
  CHECK(farthest <= 4);
  // Zero-mean Neumann problem as the tools pose it (vertex 0 pinned).
  fem::MultigridSolver mg(H.prolongations);
  mg.setup(s.L, {0});
  Eigen::VectorXd b = test_rhs(s);
  b.array() -= b.mean();
  mg.solve(b);
  CHECK(mg.report().converged);
  CHECK(mg.report().convergence_factor < 0.22);  // measured 0.180 (0.197 without anchors); 0.30-0.32 before
}

TEST_CASE("strong-neighbour anchors speed multigrid up on a real mesh with slivers", "[multigrid][hierarchy][meshes]") {
  // lion-head has needle triangles (13 % of its vertices have a corner under 15 degrees after
  // intrinsic Delaunay flips), where the slowest V-cycle mode sat once the boundary was fixed.
  const Setup& s = mesh_setup("lion-head.off");
  Eigen::VectorXd b = test_rhs(s);
  b.array() -= b.mean();
  auto factor = [&](double share) {
    ice::HierarchyOptions options;
    options.coarsest_vertices = 150;
    options.strong_neighbour_share = share;
    fem::MultigridSolver mg(ice::build_hierarchy(s.mesh, options).prolongations);
    mg.setup(s.L, {0});
    mg.solve(b);
    CHECK(mg.report().converged);
    return mg.report().convergence_factor;
  };
  const double with_anchors = factor(0.5), without = factor(0);
  INFO("PCG factor with anchors " << with_anchors << ", without " << without);
  CHECK(with_anchors < 0.95 * without);  // measured 0.180 against 0.197
  ice::HierarchyOptions bad;
  bad.strong_neighbour_share = 1.5;
  CHECK_THROWS_AS(ice::build_hierarchy(s.mesh, bad), std::invalid_argument);
}

namespace {

// Boundary vertices of the intrinsic Delaunay triangulation of `mesh` whose strongest cotan link (at
// least half of their summed non-negative weights) leaves their boundary loop: to an interior vertex,
// or across to another hole (scan_test1_vcg: two boundary vertices 0.59 apart between two holes).
std::vector<int> boundary_vertices_tied_off_loop(const ice::TriangleMesh& mesh) {
  ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  T.flip_to_delaunay();
  std::vector<int> tied;
  for (ice::Index v = 0; v < T.num_vertices(); ++v) {
    if (!T.is_boundary_vertex(v)) continue;
    double total = 0, strongest = 0;
    ice::Index neighbour = ice::kInvalid, last = T.vertex_halfedge(v);
    T.for_each_outgoing(v, [&](ice::Index h) {
      const double w = std::max(0.0, T.cotan_weight(h));
      total += w;
      if (w > strongest && T.head(h) != v) strongest = w, neighbour = T.head(h);
      last = h;
    });
    const bool along_loop = neighbour == T.head(T.vertex_halfedge(v)) || neighbour == T.tail(T.prev(last));
    if (neighbour != ice::kInvalid && strongest >= 0.5 * total && !along_loop) tied.push_back(static_cast<int>(v));
  }
  return tied;
}

}  // namespace

TEST_CASE("a boundary vertex tied off its loop stays on the coarse level", "[multigrid][hierarchy][meshes]") {
  // Removing a boundary vertex interpolates it along its loop's new edge, never from the vertex it is
  // tied to, so the hierarchy keeps such vertices (strong_neighbour_share also governs the boundary
  // walk). Measured on elephant-with-holes (48 % boundary vertices): 337 of 405 kept at level 1
  // against 199 without the rule.
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("elephant-with-holes.off"));
  const std::vector<int> tied = boundary_vertices_tied_off_loop(mesh);
  REQUIRE(tied.size() > 100);
  auto kept = [&](double share) {
    ice::HierarchyOptions options;
    options.max_levels = 2;
    options.strong_neighbour_share = share;
    const ice::Hierarchy H = ice::build_hierarchy(mesh, options);
    std::vector<char> coarse(static_cast<std::size_t>(mesh.V.rows()), 0);
    for (ice::Index f : H.levels[1].to_fine) coarse[static_cast<std::size_t>(f)] = 1;
    return static_cast<double>(std::count_if(tied.begin(), tied.end(), [&](int v) { return coarse[static_cast<std::size_t>(v)]; }));
  };
  const double with_rule = kept(0.5), without = kept(0);
  INFO(tied.size() << " tied boundary vertices; kept " << with_rule << " with the rule, " << without << " without");
  CHECK(with_rule > 0.75 * static_cast<double>(tied.size()));
  CHECK(with_rule > 1.4 * without);
}

TEST_CASE("extended set: multigrid on raw scans converges at most 0.2 per PCG iteration", "[multigrid][extended]") {
  // The scans with holes and slivers of the extended set, posed as poisson-coarse --solver multigrid
  // poses them (intrinsic Delaunay Laplacian, vertex 0 pinned, zero-mean right-hand side, default
  // hierarchy). Measured with the tool's right-hand side: camelhead 0.136, face_scan 0.116,
  // bunny_zipper_holes 0.112, scan_test1_vcg 0.150 (0.31 before boundary vertices tied off their loop
  // were kept, 0.27-0.32 for all four before the boundary rules).
  ICE_SKIP_WITHOUT_EXTENDED_SET();
  for (const char* name : {"camelhead.off", "face_scan.obj", "bunny_zipper_holes.obj", "scan_test1_vcg.ply"}) {
    INFO(name);
    const ice::TriangleMesh mesh = ice::load_mesh(ice_test::extended_mesh(name), ice::LoadOptions{true, false});
    ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    T.flip_to_delaunay();
    const ice::CompactMesh idt = T.compact();
    const fem::SparseMatrix L = fem::cotan_laplacian(idt);
    const fem::SparseMatrix M = fem::mass_matrix(idt, fem::MassKind::lumped);
    Eigen::VectorXd f(mesh.V.rows());
    for (Eigen::Index i = 0; i < f.size(); ++i) f(i) = std::sin(0.1 * mesh.V(i, 0)) + 0.3 * std::sin(17.0 * static_cast<double>(i));
    Eigen::VectorXd b = M * f;
    b.array() -= b.mean();
    fem::MultigridSolver mg(ice::build_hierarchy(mesh, {}).prolongations);
    mg.setup(L, {0});
    mg.solve(b);
    CHECK(mg.report().converged);
    CHECK(mg.report().convergence_factor <= 0.2);
  }
}

TEST_CASE("PoissonSolver with a multigrid backend solves the same problems as with CHOLMOD", "[multigrid][problems][meshes]") {
  // Zero-mean Neumann on a closed mesh (compatible right-hand side, pinned vertex, re-centring)
  // and Dirichlet with values on an open one: the multigrid answer agrees with the factorisation to
  // about the tolerance, and the solver reports its convergence.
  for (const std::string name : {"spot.obj", "lion-head.off"}) {
    INFO(name);
    const Setup& s = mesh_setup(name);
    const Eigen::Index n = s.mesh.V.rows();
    Eigen::VectorXd f(n);
    for (Eigen::Index i = 0; i < n; ++i) f(i) = std::sin(3 * s.mesh.V(i, 0)) + std::cos(5 * s.mesh.V(i, 1));
    fem::MultigridOptions options;
    options.tolerance = 1e-10;
    const fem::PoissonMultigrid multigrid{s.hierarchy.prolongations, options, false, s.hierarchy.fine_order};

    const fem::PoissonSolver direct = fem::PoissonSolver::zero_mean(s.L, s.M);
    const fem::PoissonSolver iterative = fem::PoissonSolver::zero_mean(s.L, s.M, multigrid);
    CHECK(direct.multigrid() == nullptr);
    REQUIRE(iterative.multigrid() != nullptr);
    const Eigen::VectorXd u_direct = direct.solve(f), u_iterative = iterative.solve(f);
    CHECK(iterative.multigrid()->report().converged);
    CHECK(relative_difference(u_iterative, u_direct) < 1e-7);
    CHECK(std::abs(s.M.diagonal().dot(u_iterative)) < 1e-9 * s.M.diagonal().sum() * u_direct.cwiseAbs().maxCoeff());

    const std::vector<int> fixed = {0, static_cast<int>(n / 2), static_cast<int>(n - 1)};
    const Eigen::VectorXd values = Eigen::Vector3d(1.0, -2.0, 0.5);
    const Eigen::VectorXd d_direct = fem::PoissonSolver::dirichlet(s.L, s.M, fixed).solve(f, values);
    const Eigen::VectorXd d_iterative = fem::PoissonSolver::dirichlet(s.L, s.M, fixed, multigrid).solve(f, values);
    CHECK(relative_difference(d_iterative, d_direct) < 1e-7);
    for (std::size_t k = 0; k < fixed.size(); ++k) CHECK(d_iterative(fixed[k]) == values(static_cast<Eigen::Index>(k)));
  }
}
