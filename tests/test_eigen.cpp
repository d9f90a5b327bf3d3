// The Laplace–Beltrami eigenbasis (fem/eigen.h, ice/proxy/eigen.h): on the unit sphere the
// eigenvalues approach l(l + 1) with multiplicity 2l + 1; a mesh of c components has c zero
// eigenvalues; the proxy's eigenvalues are upper bounds of the fine ones (Galerkin: Rayleigh
// quotients), its vectors M-orthonormal on the input mesh and close to the fine eigenspaces;
// descriptors keep their sums.
#include <catch2/catch.hpp>

#include <dlfcn.h>

#include <cmath>
#include <stdexcept>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "dense_blas.h"
#include "fem/cholesky.h"
#include "fem/eigen.h"
#include "fem/operators.h"
#include "fem/topology.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/proxy/eigen.h"
#include "ice/proxy/store.h"
#include "test_support.h"

namespace {

using ice_test::unit_sphere;

struct Pencil {
  fem::SparseMatrix L, M;
};

// Appends `part`, moved by `shift`, to `mesh` as a component of its own.
void append_component(ice::TriangleMesh& mesh, const ice::TriangleMesh& part, const Eigen::RowVector3d& shift) {
  const Eigen::Index offset = mesh.V.rows(), faces = mesh.F.rows();
  mesh.V.conservativeResize(offset + part.V.rows(), 3);
  mesh.V.bottomRows(part.V.rows()) = part.V.rowwise() + shift;
  mesh.F.conservativeResize(faces + part.F.rows(), 3);
  mesh.F.bottomRows(part.F.rows()) = part.F.array() + static_cast<fem::Index>(offset);
}

Pencil pencil(const ice::TriangleMesh& mesh) {
  const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  return {fem::cotan_laplacian(fine),
          fem::mass_matrix(fine, fem::MassKind::lumped)};
}

double orthonormality_defect(const Eigen::MatrixXd& V, const fem::SparseMatrix& M) {
  return (V.transpose() * (M * V) - Eigen::MatrixXd::Identity(V.cols(), V.cols())).cwiseAbs().maxCoeff();
}

}  // namespace

TEST_CASE("eigenpairs of the unit sphere: l(l+1) with multiplicity 2l+1, M-orthonormal, small residuals", "[eigen]") {
  const Pencil p = pencil(unit_sphere());
  const fem::Eigenpairs e = fem::smallest_eigenpairs(p.L, p.M, 16);
  REQUIRE(e.values.size() == 16);
  CHECK(std::abs(e.values(0)) < 1e-8);
  for (int j = 1; j < 16; ++j) {
    CHECK(e.values(j) >= e.values(j - 1));
    const int l = j < 4 ? 1 : j < 9 ? 2 : 3;  // 3 pairs of l = 1, 5 of l = 2, 7 of l = 3
    CHECK(e.values(j) == Approx(l * (l + 1)).epsilon(0.01));
  }
  CHECK(orthonormality_defect(e.vectors, p.M) < 1e-8);
  CHECK(fem::eigen_residuals(p.L, p.M, e.values, e.vectors).maxCoeff() < 1e-6);
  // The reference's own angles to itself are zero, clusters included.
  CHECK(fem::eigenspace_angles(e.vectors, e.vectors, e.values, p.M).maxCoeff() < 1e-6);
}

TEST_CASE("eigenpairs: one zero eigenvalue per component; bad k is refused", "[eigen]") {
  ice::TriangleMesh two = unit_sphere();
  const ice::TriangleMesh other = ice::make_icosphere(3, 0.5);
  const auto n = two.V.rows();
  two.V.conservativeResize(n + other.V.rows(), 3);
  two.V.bottomRows(other.V.rows()) = other.V.rowwise() + Eigen::RowVector3d(3, 0, 0);
  two.F.conservativeResize(two.F.rows() + other.F.rows(), 3);
  two.F.bottomRows(other.F.rows()) = other.F.array() + static_cast<int>(n);
  const Pencil p = pencil(two);
  const fem::Eigenpairs e = fem::smallest_eigenpairs(p.L, p.M, 4);
  CHECK(std::abs(e.values(0)) < 1e-8);
  CHECK(std::abs(e.values(1)) < 1e-8);
  CHECK(e.values(2) == Approx(2.0).epsilon(0.01));  // the unit sphere's first nonzero one
  CHECK_THROWS_AS(fem::smallest_eigenpairs(p.L, p.M, 0), std::invalid_argument);
  CHECK_THROWS_AS(fem::smallest_eigenpairs(p.L, p.M, static_cast<int>(p.L.rows())), std::invalid_argument);
}

TEST_CASE("proxy eigenbasis: upper bounds, M-orthonormal on the input mesh, near the fine eigenspaces", "[eigen][proxy]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const Pencil p = pencil(mesh);
  const int k = 16;
  const fem::Eigenpairs fine = fem::smallest_eigenpairs(p.L, p.M, k + 8);
  ice::proxy::EigenbasisOptions options;
  options.coarsening.coarsen.target_vertices = 500;
  const ice::proxy::EigenSolver solver(mesh, options);
  const ice::proxy::Eigenbasis basis = solver.compute(k);
  REQUIRE(basis.vectors.rows() == mesh.V.rows());
  REQUIRE(basis.vectors.cols() == k);
  CHECK(orthonormality_defect(basis.vectors, p.M) < 1e-9);
  // Rayleigh quotients on the input mesh equal the coarse eigenvalues (Galerkin operators).
  for (int j = 0; j < k; ++j) {
    const Eigen::VectorXd phi = basis.vectors.col(j);
    CHECK(phi.dot(p.L * phi) == Approx(basis.values(j)).margin(1e-9).epsilon(1e-9));
    CHECK(basis.values(j) >= fine.values(j) - 1e-9);  // Courant–Fischer
    if (j > 0) CHECK(basis.values(j) <= fine.values(j) * 1.05);
  }
  const Eigen::VectorXd angles = fem::eigenspace_angles(basis.vectors, fine.vectors, fine.values, p.M);
  CHECK(angles.maxCoeff() < 0.2);
  CHECK_THROWS_AS(solver.compute(0), std::invalid_argument);
  CHECK_THROWS_AS(solver.compute(static_cast<int>(solver.proxy().coarse_laplacian().rows())), std::invalid_argument);

  SECTION("the comparison with the fine eigenpairs, and with themselves") {
    const ice::proxy::EigenbasisErrors errors = ice::proxy::eigenbasis_errors(basis.values, basis.vectors, fine, p.M);
    CHECK(errors.zero_modes == 1);  // the sphere's constants
    CHECK(errors.relative(0) == 0);
    for (int j = 1; j < k; ++j) CHECK(errors.relative(j) == Approx((basis.values(j) - fine.values(j)) / fine.values(j)));
    CHECK(errors.relative_max == Approx(errors.relative.maxCoeff()));
    CHECK(errors.relative_median > 0);
    CHECK(errors.relative_median <= errors.relative_max);
    CHECK(errors.angle_max == Approx(angles.maxCoeff()));
    fem::Eigenpairs itself;
    itself.values = basis.values;
    itself.vectors = basis.vectors;
    const ice::proxy::EigenbasisErrors none = ice::proxy::eigenbasis_errors(basis.values, basis.vectors, itself, p.M);
    CHECK(none.relative_max == 0);
    CHECK(none.angle_max < 1e-6);
    CHECK_THROWS_AS(ice::proxy::eigenbasis_errors(fine.values, fine.vectors, itself, p.M), std::invalid_argument);  // k + 8 > k
    CHECK(ice::proxy::median(Eigen::Vector4d(4, 1, 3, 2)) == 2.5);
    CHECK(ice::proxy::median(Eigen::VectorXd()) == 0);
  }

  SECTION("descriptors keep their sums; an eigenfunction is reconstructed exactly") {
    const Eigen::VectorXd mass = p.M.diagonal();
    Eigen::VectorXd times(3);
    times << 0.01, 0.1, 1.0;
    const Eigen::MatrixXd hks = ice::proxy::heat_kernel_signature(basis, times);
    for (Eigen::Index t = 0; t < times.size(); ++t)
      CHECK(mass.dot(hks.col(t)) == Approx((-times(t) * basis.values.cwiseMax(0.0).array()).exp().sum()).epsilon(1e-9));
    Eigen::VectorXd energies(2);
    energies << std::log(2.0), std::log(6.0);
    const Eigen::MatrixXd wks = ice::proxy::wave_kernel_signature(basis, energies, 0.5);
    for (Eigen::Index e = 0; e < energies.size(); ++e) CHECK(mass.dot(wks.col(e)) == Approx(1.0).epsilon(1e-9));
    CHECK(ice::proxy::reconstruction_error(basis, mass, basis.vectors.col(5)) < 1e-9);
    CHECK(ice::proxy::reconstruction_error(basis, mass, Eigen::VectorXd::Ones(mass.size())) < 1e-6);
    Eigen::VectorXd rough(mass.size());
    for (Eigen::Index v = 0; v < rough.size(); ++v) rough(v) = (v % 2 == 0) ? 1.0 : -1.0;
    CHECK(ice::proxy::reconstruction_error(basis, mass, rough) > 0.5);
  }
}

TEST_CASE("proxy eigenbasis: by default through P smoothed twice, closer to the fine eigenvalues than once", "[eigen][proxy]") {
  // A real mesh at 5 %: bear, 13,826 vertices -> 692 coarse, 30 pairs (median errors 1.23 % once,
  // 0.75 % twice when measured).
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("bear.off"));
  const Pencil p = pencil(mesh);
  const int k = 30;
  const fem::Eigenpairs fine = fem::smallest_eigenpairs(p.L, p.M, k);
  REQUIRE(ice::proxy::resolve_prolongation(ice::proxy::Prolongation::automatic, fem::CoarseOperatorKind::galerkin, false,
                                           ice::proxy::ProlongationUse::eigenpairs) == fem::ProlongationKind::smoothed_twice);
  REQUIRE(ice::proxy::resolve_prolongation(ice::proxy::Prolongation::automatic, fem::CoarseOperatorKind::galerkin, true,
                                           ice::proxy::ProlongationUse::eigenpairs) == fem::ProlongationKind::barycentric);
  double median[3] = {0, 0, 0};
  const ice::proxy::Prolongation choices[3] = {ice::proxy::Prolongation::automatic, ice::proxy::Prolongation::smoothed,
                                               ice::proxy::Prolongation::smoothed_twice};
  for (int c = 0; c < 3; ++c) {
    ice::proxy::EigenbasisOptions options;
    options.coarsening.coarsen.target_ratio = 0.05;
    options.prolongation = choices[c];
    const ice::proxy::EigenSolver solver(mesh, options);
    const fem::CoarseProxy& proxy = solver.proxy();
    const fem::ProlongationKind kind = c == 1 ? fem::ProlongationKind::smoothed : fem::ProlongationKind::smoothed_twice;
    REQUIRE(proxy.prolongation_kind() == kind);
    // Twice is the smoothing applied to the smoothed P: rows still sum to 1.
    if (c == 2) {
      const fem::SparseMatrix twice = fem::smoothed_prolongation(
          fem::smoothed_prolongation(proxy.barycentric_prolongation(), proxy.fine_laplacian()), proxy.fine_laplacian());
      REQUIRE(ice_test::relative_difference(proxy.prolongation(), twice) == 0.0);
      const Eigen::VectorXd rows = proxy.prolongation() * Eigen::VectorXd::Ones(proxy.prolongation().cols());
      REQUIRE((rows.array() - 1).abs().maxCoeff() < 1e-12);
    }
    const ice::proxy::Eigenbasis basis = solver.compute(k);
    for (int j = 0; j < k; ++j) REQUIRE(basis.values(j) >= fine.values(j) - 1e-9);  // still upper bounds (Galerkin)
    median[c] = ice::proxy::eigenbasis_errors(basis.values, basis.vectors, fine, p.M).relative_median;
  }
  INFO("median eigenvalue error: auto " << median[0] << ", smoothed " << median[1] << ", twice " << median[2]);
  // Set-ups through the two never share a store entry.
  const auto key = [&](fem::ProlongationKind kind) {
    return ice::proxy::proxy_setup_key(mesh, ice::CoarseSpaceOptions{}, ice::FineGeometry::intrinsic_delaunay,
                                       fem::CoarseOperatorKind::galerkin, kind);
  };
  REQUIRE(!(key(fem::ProlongationKind::smoothed) == key(fem::ProlongationKind::smoothed_twice)));
  REQUIRE(median[0] == median[2]);
  REQUIRE(median[2] < 0.8 * median[1]);
  // Dirichlet conditions keep refusing any smoothing.
  ice::proxy::EigenbasisOptions dirichlet;
  dirichlet.boundary = ice::proxy::EigenBoundary::dirichlet;
  dirichlet.prolongation = ice::proxy::Prolongation::smoothed_twice;
  dirichlet.coarsening.coarsen.target_ratio = 0.2;
  REQUIRE_THROWS_AS(ice::proxy::EigenSolver(ice::load_mesh(ice_test::project_mesh("cat_head.obj")), dirichlet), std::invalid_argument);
}

TEST_CASE("Dirichlet eigenpairs of the unit disk: Bessel zeros squared; the proxy's vanish on the boundary", "[eigen][proxy]") {
  const ice::TriangleMesh disk = ice::make_flat_disk(24);  // 1,801 vertices
  const Pencil p = pencil(disk);
  const std::vector<fem::Index> boundary = fem::boundary_vertices(disk.F);
  REQUIRE(!boundary.empty());
  const fem::Eigenpairs fine = fem::smallest_eigenpairs_dirichlet(p.L, p.M, boundary, 6);
  // j_{0,1}², j_{1,1}² (twice), j_{2,1}² (twice), j_{0,2}²
  const double expected[] = {5.7832, 14.6820, 14.6820, 26.3746, 26.3746, 30.4713};
  for (int j = 0; j < 6; ++j) CHECK(fine.values(j) == Approx(expected[j]).epsilon(0.02));
  for (fem::Index v : boundary) CHECK(fine.vectors.row(v).isZero(0.0));
  CHECK(fem::eigen_residuals(p.L, p.M, fine.values, fine.vectors, boundary).maxCoeff() < 1e-6);

  ice::proxy::EigenbasisOptions options;
  options.boundary = ice::proxy::EigenBoundary::dirichlet;
  options.coarsening.coarsen.target_vertices = 500;
  const ice::proxy::EigenSolver solver(disk, options);
  const ice::proxy::Eigenbasis basis = solver.compute(6);
  CHECK(orthonormality_defect(basis.vectors, p.M) < 1e-9);
  for (fem::Index v : boundary) CHECK(basis.vectors.row(v).isZero(0.0));
  for (int j = 0; j < 6; ++j) {
    CHECK(basis.values(j) >= fine.values(j) - 1e-9);  // the coarse functions are a subspace of the fine Dirichlet ones
    CHECK(basis.values(j) <= fine.values(j) * 1.05);
  }
}

namespace {

// How refined pairs compare with a reference computed to 1e-12: the relative eigenvalue errors
// (zero modes against the largest value) and, both ways, the angles to the other's eigenspaces.
struct Agreement {
  double value_error = 0, angle_to_reference = 0, reference_to_refined = 0;
};

Agreement agreement(const Eigen::VectorXd& values, const Eigen::MatrixXd& vectors, const fem::Eigenpairs& reference,
                    const fem::SparseMatrix& M) {
  const Eigen::Index k = values.size();
  Agreement a;
  const double largest = reference.values.head(k).cwiseAbs().maxCoeff();
  for (Eigen::Index j = 0; j < k; ++j) {
    const double scale = fem::is_zero_mode(reference.values(j), largest) ? largest : reference.values(j);
    a.value_error = std::max(a.value_error, std::abs(values(j) - reference.values(j)) / scale);
  }
  a.angle_to_reference = fem::eigenspace_angles(vectors, reference.vectors, reference.values, M).maxCoeff();
  // No reference pair missing: each reference vector lies in the refined eigenspace of its value.
  a.reference_to_refined = fem::eigenspace_angles(reference.vectors.leftCols(k), vectors, values, M).maxCoeff();
  return a;
}

fem::EigenOptions tight_reference() {
  fem::EigenOptions options;
  options.tolerance = 1e-13;
  return options;
}

}  // namespace

TEST_CASE("refined eigenbasis: every pair to the tolerance, the fine eigenpairs to 1e-8, none missing or repeated", "[eigen][proxy][refine]") {
  // The sphere's eigenvalues come in clusters of 2l + 1 (1, 3, 5, 7: k = 16 closes the fourth): the
  // refinement must find whole eigenspaces, not vectors of them.
  const ice::TriangleMesh& mesh = unit_sphere();
  const Pencil p = pencil(mesh);
  const int k = 16;
  const fem::Eigenpairs fine = fem::smallest_eigenpairs(p.L, p.M, k + 4, tight_reference());
  ice::proxy::EigenbasisOptions options;
  options.coarsening.coarsen.target_vertices = 200;  // a coarse start: eigenvalues a few per cent off
  options.refine.tolerance = 1e-6;
  // Both methods: the augmented subspace method (the default: coarse directions) and LOBPCG.
  int expected_directions = 2 * (k + 4);
  SECTION("augmented subspace method") {}
  SECTION("LOBPCG") {
    options.refine.coarse_directions = 0;
    expected_directions = 0;
  }
  SECTION("in the input's numbering (a hierarchy without its breadth-first order)") {
    options.refine.hierarchy.reorder = false;
  }
  const ice::proxy::EigenSolver solver(mesh, options);
  REQUIRE(solver.hierarchy().fine_vertices == mesh.V.rows());
  CHECK(solver.hierarchy().fine_order.empty() == !options.refine.hierarchy.reorder);
  const ice::proxy::Eigenbasis basis = solver.compute(k);
  REQUIRE(basis.refined);
  REQUIRE(basis.converged);
  REQUIRE(basis.vectors.cols() == k);
  CHECK(basis.guard == 4);
  CHECK(basis.coarse_directions == expected_directions);
  CHECK(basis.refine_iterations >= 1);
  const Eigen::VectorXd residuals = fem::eigen_residuals(p.L, p.M, basis.values, basis.vectors);
  CHECK(residuals.maxCoeff() <= 1e-6);
  // The same residuals as eigen_residuals', but for the zero mode's scale (the largest of all m pairs).
  CHECK((residuals - basis.residuals).tail(k - 1).cwiseAbs().maxCoeff() < 1e-12);
  CHECK(basis.residuals(0) <= 1e-6);
  CHECK(orthonormality_defect(basis.vectors, p.M) < 1e-10);
  const Agreement a = agreement(basis.values, basis.vectors, fine, p.M);
  CHECK(a.value_error < 1e-8);
  CHECK(a.angle_to_reference < 1e-6);
  CHECK(a.reference_to_refined < 1e-6);
  // The proxy route's start was far from that.
  ice::proxy::EigenbasisOptions proxy_only = options;
  proxy_only.refine.tolerance = 0;
  const ice::proxy::Eigenbasis start = ice::proxy::EigenSolver(mesh, proxy_only).compute(k);
  CHECK_FALSE(start.refined);
  CHECK(agreement(start.values, start.vectors, fine, p.M).value_error > 1e-3);
}

TEST_CASE("refined eigenbasis: k no more than the zero modes still converges", "[eigen][proxy][refine]") {
  // The first k pairs are all round-off: judged against the guards' scale, not their own.
  const ice::TriangleMesh& mesh = unit_sphere();
  ice::proxy::EigenbasisOptions options;
  options.coarsening.coarsen.target_vertices = 200;
  options.refine.tolerance = 1e-6;
  options.refine.max_iterations = 30;
  const ice::proxy::Eigenbasis basis = ice::proxy::eigenbasis(mesh, 1, options);
  REQUIRE(basis.converged);
  CHECK(std::abs(basis.values(0)) < 1e-10);
  const Eigen::VectorXd constant = basis.vectors.col(0) / basis.vectors(0, 0);
  CHECK((constant.array() - 1).abs().maxCoeff() < 1e-8);
}

TEST_CASE("pairs that are all zero modes (more components than pairs): judged against the spectrum's scale", "[eigen][refine]") {
  // 12 separate spheres, 10 pairs: every eigenvalue is round-off, so none can be the scale of the others.
  ice::TriangleMesh many;
  many.V.resize(0, 3);
  many.F.resize(0, 3);
  const ice::TriangleMesh one = ice::make_icosphere(1, 1.0);
  for (int copy = 0; copy < 12; ++copy) append_component(many, one, Eigen::RowVector3d(3.0 * copy, 0, 0));
  const Pencil p = pencil(many);
  const double spectrum = p.L.diagonal().sum() / p.M.diagonal().sum();
  CHECK(fem::zero_mode_scale(1e-14, p.L, p.M) == spectrum);
  CHECK(fem::zero_mode_scale(0.5 * spectrum, p.L, p.M) == 0.5 * spectrum);
  const fem::Eigenpairs fine = fem::smallest_eigenpairs(p.L, p.M, 10);
  CHECK(fine.values.cwiseAbs().maxCoeff() < 1e-10 * spectrum);
  CHECK(fem::eigen_residuals(p.L, p.M, fine.values, fine.vectors).maxCoeff() <= 1e-8);
  fem::CholeskySolver inverse;
  inverse.compute(fem::SparseMatrix(p.L + 1.0 * p.M));
  const fem::BlockPreconditioner exact = [&inverse](const Eigen::MatrixXd& R) { return inverse.solve_multiple(R); };
  std::srand(3);
  Eigen::MatrixXd vectors = Eigen::MatrixXd::Random(many.V.rows(), 10);
  Eigen::VectorXd values = Eigen::VectorXd::Zero(10);
  fem::EigenRefineOptions options;
  options.tolerance = 1e-8;
  options.max_iterations = 50;
  const fem::EigenRefineReport report = fem::refine_eigenpairs(p.L, p.M, values, vectors, 6, exact, {}, options);
  CHECK(report.converged);
  CHECK(values.head(6).cwiseAbs().maxCoeff() < 1e-10 * spectrum);
  CHECK(fem::eigen_residuals(p.L, p.M, values.head(6), vectors.leftCols(6)).maxCoeff() <= 1e-8);
}

TEST_CASE("the refined route's coarse size: a fixed number of coarse vertices per coarse pair", "[eigen][proxy][refine]") {
  ice::proxy::EigenRefinement refinement;
  // k = 100: guard 25, 2 (k + guard) = 250 coarse directions, 375 pairs.
  CHECK(ice::proxy::refined_coarse_vertices(100, refinement) == 375 * refinement.coarse_vertices_per_pair);
  // k = 1: guard 4, 10 directions.
  CHECK(ice::proxy::refined_coarse_vertices(1, refinement) == 15 * refinement.coarse_vertices_per_pair);
  refinement.coarse_directions = 0;  // LOBPCG: the k + guard refined pairs only
  CHECK(ice::proxy::refined_coarse_vertices(100, refinement) == 125 * refinement.coarse_vertices_per_pair);
  refinement.coarse_vertices_per_pair = 8;
  refinement.guard = 10;
  CHECK(ice::proxy::refined_coarse_vertices(100, refinement) == 110 * 8);
  CHECK_THROWS_AS(ice::proxy::refined_coarse_vertices(0, refinement), std::invalid_argument);
  refinement.coarse_vertices_per_pair = 0;
  CHECK_THROWS_AS(ice::proxy::refined_coarse_vertices(10, refinement), std::invalid_argument);
}

TEST_CASE("refined eigenbasis on a real mesh and under Dirichlet conditions", "[eigen][proxy][refine]") {
  SECTION("spot, Neumann") {
    const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("spot.obj"));
    const Pencil p = pencil(mesh);
    const int k = 20;
    const fem::Eigenpairs fine = fem::smallest_eigenpairs(p.L, p.M, k, tight_reference());
    ice::proxy::EigenbasisOptions options;
    options.coarsening.coarsen.target_vertices = 300;
    options.refine.tolerance = 1e-6;
    const ice::proxy::Eigenbasis basis = ice::proxy::eigenbasis(mesh, k, options);
    REQUIRE(basis.converged);
    CHECK(fem::eigen_residuals(p.L, p.M, basis.values, basis.vectors).maxCoeff() <= 1e-6);
    const Agreement a = agreement(basis.values, basis.vectors, fine, p.M);
    CHECK(a.value_error < 1e-8);
    CHECK(a.reference_to_refined < 1e-6);
  }
  SECTION("the unit disk, Dirichlet") {
    const ice::TriangleMesh disk = ice::make_flat_disk(24);  // 1,801 vertices
    const Pencil p = pencil(disk);
    const std::vector<fem::Index> boundary = fem::boundary_vertices(disk.F);
    const fem::Eigenpairs fine = fem::smallest_eigenpairs_dirichlet(p.L, p.M, boundary, 8, tight_reference());
    ice::proxy::EigenbasisOptions options;
    options.boundary = ice::proxy::EigenBoundary::dirichlet;
    options.coarsening.coarsen.target_vertices = 300;
    options.refine.tolerance = 1e-7;
    const ice::proxy::Eigenbasis basis = ice::proxy::eigenbasis(disk, 8, options);
    REQUIRE(basis.converged);
    for (fem::Index v : boundary) CHECK(basis.vectors.row(v).isZero(0.0));
    CHECK(fem::eigen_residuals(p.L, p.M, basis.values, basis.vectors, boundary).maxCoeff() <= 1e-7);
    CHECK(agreement(basis.values, basis.vectors, fine, p.M).value_error < 1e-8);
  }
  SECTION("a coarse space as large as the mesh: the fine eigensolver directly, Neumann and Dirichlet") {
    const ice::TriangleMesh disk = ice::make_flat_disk(12);
    const Pencil p = pencil(disk);
    const std::vector<fem::Index> boundary = fem::boundary_vertices(disk.F);
    for (const bool dirichlet : {false, true}) {
      INFO("Dirichlet " << dirichlet);
      const std::vector<fem::Index> fixed = dirichlet ? boundary : std::vector<fem::Index>{};
      const fem::Eigenpairs fine = fem::smallest_eigenpairs_dirichlet(p.L, p.M, fixed, 6, tight_reference());
      ice::proxy::EigenbasisOptions options;
      if (dirichlet) options.boundary = ice::proxy::EigenBoundary::dirichlet;
      options.coarsening.coarsen.target_vertices = disk.V.rows();
      options.refine.tolerance = 1e-8;
      const ice::proxy::EigenSolver solver(disk, options);
      CHECK(solver.hierarchy().prolongations.empty());  // none is needed
      const ice::proxy::Eigenbasis basis = solver.compute(6);
      CHECK(basis.fine_eigensolve);
      CHECK(basis.refined);
      CHECK(basis.converged);
      CHECK(basis.refine_iterations == 0);
      CHECK(basis.residuals.maxCoeff() <= 1e-8);
      CHECK(fem::eigen_residuals(p.L, p.M, basis.values, basis.vectors, fixed).maxCoeff() <= 1e-8);
      const Agreement a = agreement(basis.values, basis.vectors, fine, p.M);
      CHECK(a.value_error < 1e-10);
      CHECK(a.reference_to_refined < 1e-6);
      for (fem::Index v : fixed) CHECK(basis.vectors.row(v).isZero(0.0));
    }
    // A tolerance below the residuals the eigensolver reaches on spot: its pairs polished to it
    // (LOBPCG preconditioned by the exact inverse of L + σM).
    const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("spot.obj"));
    const Pencil spot = pencil(mesh);
    ice::proxy::EigenbasisOptions options;
    options.coarsening.coarsen.target_vertices = mesh.V.rows();
    options.refine.tolerance = 1e-12;
    const ice::proxy::Eigenbasis polished = ice::proxy::eigenbasis(mesh, 6, options);
    CHECK(polished.fine_eigensolve);
    REQUIRE(polished.residual_history.front() > 1e-12);
    CHECK(polished.refine_iterations >= 1);
    CHECK(polished.converged);
    CHECK(fem::eigen_residuals(spot.L, spot.M, polished.values, polished.vectors).maxCoeff() <= 1e-12);
    CHECK(agreement(polished.values, polished.vectors, fem::smallest_eigenpairs(spot.L, spot.M, 6, tight_reference()),
                    spot.M).value_error < 1e-10);
    // k = 1, the zero mode alone: judged against the guards' scale, it needs no polish.
    options.refine.tolerance = 1e-8;
    const ice::proxy::Eigenbasis constant = ice::proxy::eigenbasis(mesh, 1, options);
    CHECK(constant.converged);
    CHECK(constant.refine_iterations == 0);
    CHECK(std::abs(constant.values(0)) < 1e-8);
  }
}

TEST_CASE("refine_eigenpairs: from random vectors to the smallest pairs of two components; bad input refused", "[eigen][refine]") {
  // Two spheres: two zero modes, then each sphere's clusters interleaved. Random start vectors know
  // nothing of that; an exact preconditioner ((L + σM)⁻¹ by CHOLMOD) makes the iteration quick.
  ice::TriangleMesh two = ice::make_icosphere(2, 1.0);
  append_component(two, ice::make_icosphere(2, 0.7), Eigen::RowVector3d::Zero());
  const Pencil p = pencil(two);
  const int k = 8, m = 14;  // 0, 0, 2 (x3), 4.08 (x3): k closes a cluster
  const fem::Eigenpairs fine = fem::smallest_eigenpairs(p.L, p.M, m, tight_reference());
  fem::CholeskySolver inverse;
  inverse.compute(fem::SparseMatrix(p.L + 1.0 * p.M));
  const fem::BlockPreconditioner exact = [&inverse](const Eigen::MatrixXd& R) { return inverse.solve_multiple(R); };
  std::srand(7);
  Eigen::MatrixXd vectors = Eigen::MatrixXd::Random(two.V.rows(), m);
  Eigen::VectorXd values = Eigen::VectorXd::Zero(m);
  const fem::EigenRefineReport report = fem::refine_eigenpairs(p.L, p.M, values, vectors, k, exact);
  REQUIRE(report.converged);
  CHECK(report.history.front() > report.history.back());
  CHECK(report.residuals.maxCoeff() <= 1e-6);
  CHECK(std::abs(values(0)) < 1e-8);
  CHECK(std::abs(values(1)) < 1e-8);  // one constant per sphere
  const Agreement a = agreement(values.head(k), vectors.leftCols(k), fine, p.M);
  CHECK(a.value_error < 1e-8);
  CHECK(a.reference_to_refined < 1e-6);
  CHECK(orthonormality_defect(vectors, p.M) < 1e-10);
  // The same preconditioner applied in place: the same iterations and numbers.
  const fem::InPlacePreconditioner in_place = [&inverse](const Eigen::MatrixXd& R, const std::vector<Eigen::Index>& columns,
                                                         Eigen::MatrixXd& X) {
    Eigen::MatrixXd chosen(R.rows(), static_cast<Eigen::Index>(columns.size()));
    for (std::size_t c = 0; c < columns.size(); ++c) chosen.col(static_cast<Eigen::Index>(c)) = R.col(columns[c]);
    const Eigen::MatrixXd W = inverse.solve_multiple(chosen);  // as `exact` solves them
    for (std::size_t c = 0; c < columns.size(); ++c) X.col(columns[c]) -= W.col(static_cast<Eigen::Index>(c));
  };
  std::srand(7);
  Eigen::MatrixXd same_start = Eigen::MatrixXd::Random(two.V.rows(), m);
  Eigen::VectorXd same_values = Eigen::VectorXd::Zero(m);
  const fem::EigenRefineReport same = fem::refine_eigenpairs(p.L, p.M, same_values, same_start, k, in_place);
  CHECK(same.iterations == report.iterations);
  CHECK(same_values == values);
  CHECK(same_start == vectors);
  const fem::InPlacePreconditioner none;
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.M, same_values, same_start, k, none), std::invalid_argument);

  Eigen::VectorXd v = values;
  Eigen::MatrixXd X = vectors;
  fem::EigenRefineOptions bad;
  bad.tolerance = 0;
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.M, v, X, k, exact, {}, bad), std::invalid_argument);
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.M, v, X, m + 1, exact), std::invalid_argument);
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.L, v, X, k, exact), std::invalid_argument);  // M not diagonal
  const fem::BlockPreconditioner wrong = [](const Eigen::MatrixXd& R) { return Eigen::MatrixXd(R.rows(), 1); };
  Eigen::MatrixXd random = Eigen::MatrixXd::Random(two.V.rows(), m);
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.M, v, random, k, wrong), std::invalid_argument);
  std::vector<fem::Index> outside{static_cast<fem::Index>(two.V.rows())};
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.M, v, X, k, exact, outside), std::invalid_argument);
  // Stopped by its iteration limit: reported, not thrown; values and vectors are the Ritz pairs reached.
  fem::EigenRefineOptions one;
  one.max_iterations = 1;
  Eigen::MatrixXd start = Eigen::MatrixXd::Random(two.V.rows(), m);
  Eigen::VectorXd reached;
  const fem::EigenRefineReport early = fem::refine_eigenpairs(p.L, p.M, reached, start, k, exact, {}, one);
  CHECK_FALSE(early.converged);
  CHECK(early.iterations == 1);
  CHECK(early.history.size() == 2);
  CHECK(reached.size() == m);
  CHECK(early.residuals.maxCoeff() > 1e-6);
  // The augmented subspace method, its coarse space the exact pairs beyond m (P = I): from the fine
  // pairs perturbed by 1 %, back to them.
  fem::SparseMatrix identity(two.V.rows(), two.V.rows());
  identity.setIdentity();
  {
    const int g = 10;
    const fem::Eigenpairs more = fem::smallest_eigenpairs(p.L, p.M, m + g, tight_reference());
    fem::EigenCoarseDirections beyond;
    beyond.prolongation = &identity;
    beyond.coarse_vectors = more.vectors.rightCols(g);
    beyond.laplacian_gram = beyond.coarse_vectors.transpose() * (p.L * beyond.coarse_vectors);
    beyond.mass_gram = beyond.coarse_vectors.transpose() * (p.M * beyond.coarse_vectors);
    Eigen::MatrixXd near = more.vectors.leftCols(m) + 0.01 * Eigen::MatrixXd::Random(two.V.rows(), m);
    const Eigen::MatrixXd near_start = near;
    Eigen::VectorXd near_values;
    const fem::EigenRefineReport augmented = fem::refine_eigenpairs(p.L, p.M, near_values, near, k, exact, {}, {}, &beyond);
    REQUIRE(augmented.converged);
    CHECK(augmented.residuals.maxCoeff() <= 1e-6);
    CHECK(fem::eigen_residuals(p.L, p.M, near_values.head(k), near.leftCols(k)).tail(k - 2).maxCoeff() <= 1e-6);
    const Agreement b = agreement(near_values.head(k), near.leftCols(k), fine, p.M);
    CHECK(b.value_error < 1e-8);
    CHECK(b.reference_to_refined < 1e-6);
    CHECK(orthonormality_defect(near, p.M) < 1e-10);
    // In place, from the same start: the same numbers.
    Eigen::MatrixXd near_again = near_start;
    Eigen::VectorXd again_values;
    const fem::EigenRefineReport again =
        fem::refine_eigenpairs(p.L, p.M, again_values, near_again, k, in_place, {}, {}, &beyond);
    CHECK(again.iterations == augmented.iterations);
    CHECK(again_values == near_values);
    CHECK(near_again == near);
  }
  // Coarse directions that do not match the pencil are refused.
  fem::EigenCoarseDirections mismatched;
  mismatched.prolongation = &identity;
  mismatched.coarse_vectors = Eigen::MatrixXd::Random(two.V.rows(), 3);
  mismatched.laplacian_gram = Eigen::MatrixXd::Identity(2, 2);
  mismatched.mass_gram = Eigen::MatrixXd::Identity(3, 3);
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.M, v, X, k, exact, {}, {}, &mismatched), std::invalid_argument);
  // So are coarse directions that do not vanish at a Dirichlet row (the vectors must).
  fem::EigenCoarseDirections nonzero;
  nonzero.prolongation = &identity;
  nonzero.coarse_vectors = Eigen::MatrixXd::Ones(two.V.rows(), 1);
  nonzero.laplacian_gram = Eigen::MatrixXd::Zero(1, 1);
  nonzero.mass_gram = Eigen::MatrixXd::Identity(1, 1);
  const std::vector<fem::Index> first_row{0};
  CHECK_THROWS_AS(fem::refine_eigenpairs(p.L, p.M, v, X, k, exact, first_row, {}, &nonzero), std::invalid_argument);
  ice::proxy::EigenbasisOptions negative;
  negative.refine.tolerance = -1;
  CHECK_THROWS_AS(ice::proxy::EigenSolver(unit_sphere(), negative), std::invalid_argument);
}

TEST_CASE("stored coarse eigenpairs: a second eigenbasis loads them bit for bit; forged or damaged ones are rebuilt", "[eigen][proxy][store]") {
  namespace fs = std::filesystem;
  using ice::proxy::CacheStatus;
  const fs::path dir = ice_test::fresh_store("eigenpairs");
  const ice::TriangleMesh& sphere = unit_sphere();
  ice::proxy::EigenbasisOptions options;
  options.coarsening.coarsen.target_vertices = 300;
  options.store.directory = dir;
  const int k = 16;
  ice::proxy::EigenbasisOptions unstored = options;
  unstored.store = {};
  const ice::proxy::Eigenbasis plain = ice::proxy::eigenbasis(sphere, k, unstored);
  CHECK(plain.cache.status == CacheStatus::off);
  const ice::proxy::EigenSolver solver(sphere, options);
  const ice::proxy::Eigenbasis cold = solver.compute(k);
  CHECK(cold.cache.status == CacheStatus::miss);
  const auto same = [&](const ice::proxy::Eigenbasis& b) {
    CHECK(b.values == cold.values);
    CHECK(b.vectors == cold.vectors);
  };
  same(plain);  // the store changes nothing in the numbers
  const ice::proxy::Eigenbasis warm = ice::proxy::EigenSolver(sphere, options).compute(k);
  CHECK(warm.cache.status == CacheStatus::hit);
  same(warm);
  // Another k is another entry; so are Dirichlet conditions (none on a sphere: the same pencil) or options.
  CHECK(solver.compute(k + 1).cache.status == CacheStatus::miss);
  ice::proxy::EigenbasisOptions looser = options;
  looser.eigen.tolerance = 1e-8;
  CHECK(ice::proxy::EigenSolver(sphere, looser).compute(k).cache.status == CacheStatus::miss);

  // Entries that pass the store's checksum but are not this pencil's pairs: an eigenvalue changed a
  // little (its residual no longer the stored one) or a lot (a residual no converged pair has), a
  // vector scaled (the same residual, not M-normal).
  const ice::proxy::Store store(options.store);
  std::string hex;
  for (const ice::proxy::StoreEntryInfo& e : store.list())
    if (e.kind == "eigenpairs" && e.key == warm.cache.keys.at(0)) hex = e.key;
  REQUIRE(hex.size() == 32);
  ice::proxy::StoreKey key;
  key.high = std::stoull(hex.substr(0, 16), nullptr, 16);
  key.low = std::stoull(hex.substr(16), nullptr, 16);
  REQUIRE(key.hex() == hex);
  const Pencil coarse{solver.proxy().coarse_laplacian(), solver.proxy().coarse_mass()};
  const fem::Eigenpairs pairs = fem::smallest_eigenpairs(coarse.L, coarse.M, k);
  const Eigen::VectorXd residuals = fem::eigen_residuals(coarse.L, coarse.M, pairs.values, pairs.vectors);
  const char* defects[] = {"residuals differ", "M-orthonormal", "residual is too large"};
  for (int forgery = 0; forgery < 3; ++forgery) {
    Eigen::VectorXd values = pairs.values;
    Eigen::MatrixXd vectors = pairs.vectors;
    if (forgery == 0) values(k - 1) *= 1 + 1e-7;  // the largest: the order holds
    if (forgery == 1) vectors.col(5) *= 2;
    if (forgery == 2) values(k - 1) *= 1.01;
    const double shift = pairs.shift;
    ice::proxy::EntryWriter writer;
    writer.put("values", values.data(), static_cast<std::size_t>(k));
    writer.put("residuals", residuals.data(), static_cast<std::size_t>(k));
    writer.put_matrix("vectors", vectors);
    writer.put_int("restarts", pairs.restarts);
    writer.put("shift", &shift, 1);
    REQUIRE(store.save("eigenpairs", key, writer));
    const ice::proxy::Eigenbasis rebuilt = solver.compute(k);
    INFO("forgery " << forgery << ": " << rebuilt.cache.damage);
    CHECK(rebuilt.cache.status == CacheStatus::rebuilt);
    CHECK(rebuilt.cache.damage.find(defects[forgery]) != std::string::npos);
    same(rebuilt);
    CHECK(solver.compute(k).cache.status == CacheStatus::hit);
  }
  // A byte flipped in the file: the store's checksum.
  const fs::path file = store.entry_path("eigenpairs", key);
  std::vector<char> bytes = ice_test::read_bytes(file);
  bytes[bytes.size() / 2] ^= 0x10;
  ice_test::write_bytes(file, bytes);
  const ice::proxy::Eigenbasis flipped = solver.compute(k);
  CHECK(flipped.cache.status == CacheStatus::rebuilt);
  same(flipped);
  fs::remove_all(dir);
}

TEST_CASE("subspace iteration: the first pairs to the tolerance, as the Lanczos eigensolver's; the rest a basis of the low spectrum",
          "[eigen]") {
  ice::TriangleMesh two = unit_sphere();
  append_component(two, ice::make_icosphere(3, 0.5), Eigen::RowVector3d(3, 0, 0));
  const Pencil p = pencil(two);
  const int count = 40, accurate = 12;
  fem::SubspaceIterationOptions options;
  options.tolerance = 1e-9;
  // The references: `count` pairs, of which the first `accurate` compared (asked for only those, the
  // Lanczos eigensolver misses one of a triple eigenvalue here; it misses some of the last ones too).
  const fem::Eigenpairs reference = fem::smallest_eigenpairs(p.L, p.M, count, tight_reference());
  const auto check = [&](const fem::Eigenpairs& e, const fem::Eigenpairs& lanczos, const std::vector<fem::Index>& fixed) {
    REQUIRE(e.values.size() == count);
    REQUIRE(e.vectors.cols() == count);
    CHECK(e.restarts >= 1);
    for (int j = 1; j < count; ++j) CHECK(e.values(j) >= e.values(j - 1));
    CHECK(orthonormality_defect(e.vectors, p.M) < 1e-10);
    for (fem::Index v : fixed) CHECK(e.vectors.row(v).isZero(0.0));
    const Eigen::VectorXd residuals = fem::eigen_residuals(p.L, p.M, e.values, e.vectors, fixed);
    CHECK(residuals.head(accurate).maxCoeff() <= 2 * options.tolerance);
    const double scale = lanczos.values.cwiseAbs().maxCoeff();
    for (int j = 0; j < accurate; ++j) CHECK(std::abs(e.values(j) - lanczos.values(j)) <= 1e-8 * scale);
    // All are Ritz pairs: the vectors L-orthogonal, their Rayleigh quotients the values.
    const Eigen::MatrixXd stiffness = e.vectors.transpose() * (p.L * e.vectors);
    CHECK((stiffness - Eigen::MatrixXd(e.values.asDiagonal())).cwiseAbs().maxCoeff() <= 1e-9 * e.values.maxCoeff());
  };
  const fem::Eigenpairs e = fem::subspace_eigenpairs(p.L, p.M, count, accurate, options);
  check(e, reference, {});
  CHECK(std::abs(e.values(0)) < 1e-8);  // two components: two zero modes
  CHECK(std::abs(e.values(1)) < 1e-8);
  CHECK(e.values(2) > 1);
  // Deterministic: a second call gives the same bits.
  const fem::Eigenpairs again = fem::subspace_eigenpairs(p.L, p.M, count, accurate, options);
  CHECK(again.values == e.values);
  CHECK(again.vectors == e.vectors);
  // Dirichlet conditions at some vertices of the first component: no zero mode left there.
  std::vector<fem::Index> fixed;
  for (fem::Index v = 0; v < 40; v += 3) fixed.push_back(v);
  const fem::Eigenpairs dirichlet = fem::subspace_eigenpairs_dirichlet(p.L, p.M, fixed, count, accurate, options);
  check(dirichlet, fem::smallest_eigenpairs_dirichlet(p.L, p.M, fixed, count, tight_reference()), fixed);
  CHECK(std::abs(dirichlet.values(0)) < 1e-8);  // the second component's constant
  CHECK(dirichlet.values(1) > 1e-3);

  const auto n = static_cast<int>(p.L.rows());
  CHECK_THROWS_AS(fem::subspace_eigenpairs(p.L, p.M, count, 0, options), std::invalid_argument);
  CHECK_THROWS_AS(fem::subspace_eigenpairs(p.L, p.M, count, count + 1, options), std::invalid_argument);
  CHECK_THROWS_AS(fem::subspace_eigenpairs(p.L, p.M, n, accurate, options), std::invalid_argument);
  CHECK_THROWS_AS(fem::subspace_eigenpairs(p.L, fem::SparseMatrix(p.M.topLeftCorner(n - 1, n - 1)), count, accurate, options),
                  std::invalid_argument);
  {  // Very unequal components (a sphere and 60 tiny ones, whose huge eigenvalues make the trace's
     // Weyl estimate of the shift far too large): still converged, 61 zero modes, then the sphere's.
    ice::TriangleMesh many = ice::make_icosphere(3, 1.0);
    for (int c = 0; c < 60; ++c) append_component(many, ice::make_icosphere(1, 1e-3), Eigen::RowVector3d(3 + c, 0, 0));
    const Pencil q = pencil(many);
    const fem::Eigenpairs u = fem::subspace_eigenpairs(q.L, q.M, 140, 70, options);
    const Eigen::VectorXd r = fem::eigen_residuals(q.L, q.M, u.values, u.vectors);
    CHECK(r.head(70).maxCoeff() <= 2 * options.tolerance);
    CHECK(u.values(60) < 1e-8);
    CHECK(u.values(61) == Approx(2.0).epsilon(0.02));  // the unit sphere's l = 1
    CHECK(u.values(68) == Approx(6.0).epsilon(0.02));  // its l = 2
    CHECK(u.values(69) == Approx(12.0).epsilon(0.02));  // its l = 3
    CHECK(u.shift > -1e-2 * u.values(139));  // the shift came down to the block's scale
  }
  fem::SubspaceIterationOptions one = options;
  one.max_iterations = 1;
  CHECK_THROWS_AS(fem::subspace_eigenpairs(p.L, p.M, count, accurate, one), std::runtime_error);
  one.tolerance = 0;
  CHECK_THROWS_AS(fem::subspace_eigenpairs(p.L, p.M, count, accurate, one), std::invalid_argument);
}

TEST_CASE("the refined route's coarse pairs in the store: loaded by the next solver, the same basis bit for bit",
          "[eigen][proxy][refine][store]") {
  namespace fs = std::filesystem;
  using ice::proxy::CacheStatus;
  const fs::path dir = ice_test::fresh_store("refined-eigenpairs");
  ice::proxy::EigenbasisOptions options;
  options.coarsening.coarsen.target_vertices = 300;
  options.refine.tolerance = 1e-7;
  options.store.directory = dir;
  const ice::proxy::Eigenbasis cold = ice::proxy::eigenbasis(unit_sphere(), 12, options);
  CHECK(cold.cache.status == CacheStatus::miss);
  REQUIRE(cold.converged);
  const ice::proxy::Eigenbasis warm = ice::proxy::eigenbasis(unit_sphere(), 12, options);
  CHECK(warm.cache.status == CacheStatus::hit);
  CHECK(warm.values == cold.values);
  CHECK(warm.vectors == cold.vectors);
  // Another coarse tolerance is another entry.
  options.refine.coarse_tolerance = 1e-5;
  CHECK(ice::proxy::eigenbasis(unit_sphere(), 12, options).cache.status == CacheStatus::miss);
  // One subspace iteration cannot meet (1e-300): the Lanczos eigensolver gives the coarse pairs
  // instead, and the refinement reaches the same basis.
  ice::proxy::EigenbasisOptions unreachable = options;
  unreachable.store = {};
  unreachable.refine.coarse_tolerance = 1e-300;
  const ice::proxy::Eigenbasis fallback = ice::proxy::eigenbasis(unit_sphere(), 12, unreachable);
  REQUIRE(fallback.converged);
  CHECK((fallback.values - cold.values).cwiseAbs().maxCoeff() <= 1e-8 * cold.values.cwiseAbs().maxCoeff());
  options.refine.coarse_tolerance = 0;
  CHECK_THROWS_AS(ice::proxy::eigenbasis(unit_sphere(), 12, options), std::invalid_argument);
  fs::remove_all(dir);
}

TEST_CASE("Gram products cut by rows: equal to one product, the same for any thread count, the BLAS's threads restored",
          "[eigen][refine]") {
  // 140,000 rows: over the two parts of 65,536 rows below which the products are not cut.
  const Eigen::Index n = 140000;
  std::srand(7);
  const Eigen::MatrixXd A = Eigen::MatrixXd::Random(n, 3), B = Eigen::MatrixXd::Random(n, 2);
  const Eigen::VectorXd root_w = Eigen::VectorXd::Random(n).cwiseAbs();
  using OpenBlasThreads = int (*)();
  const auto blas_threads = reinterpret_cast<OpenBlasThreads>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
  const int threads_before = blas_threads ? blas_threads() : 0;
  Eigen::MatrixXd C2, C3, S2, S3;
  fem::detail::gram_by_rows(A, B, C2, 2);
  fem::detail::gram_by_rows(A, B, C3, 3);
  fem::detail::self_gram_by_rows(A, root_w, S2, 2);
  fem::detail::self_gram_by_rows(A, root_w, S3, 3);
  const Eigen::MatrixXd exact = A.transpose() * B;
  const Eigen::MatrixXd exact_self = A.transpose() * root_w.cwiseAbs2().asDiagonal() * A;
  CHECK((C2 - exact).norm() <= 1e-12 * exact.norm());
  CHECK((S2 - exact_self).norm() <= 1e-12 * exact_self.norm());
  CHECK(S2 == S2.transpose());
  CHECK(C2 == C3);  // the parts are fixed by the row count, not by the threads
  CHECK(S2 == S3);
  if (blas_threads) CHECK(blas_threads() == threads_before);
  Eigen::MatrixXd bad;
  CHECK_THROWS_AS(fem::detail::gram_by_rows(A, B.topRows(10), bad, 2), std::logic_error);
}
