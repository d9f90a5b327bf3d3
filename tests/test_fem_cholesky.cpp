// fem::CholeskySolver (CHOLMOD): agreement with Eigen's SimplicialLDLT, reuse of the symbolic
// analysis, multi-column solves, and the NotPositiveDefinite report.
#include <catch2/catch.hpp>

#include <Eigen/SparseCholesky>

#include "fem/cholesky.h"
#include "fem/operators.h"
#include "ice/mesh_generators.h"

namespace {

struct Operators {
  fem::SparseMatrix laplacian, mass;
};

Operators sphere_operators(int level) {
  const ice::TriangleMesh mesh = ice::make_icosphere(level);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  return {fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths)), fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths))};
}

}  // namespace

TEST_CASE("cholesky: solves match Eigen's SimplicialLDLT", "[fem][cholesky]") {
  const Operators ops = sphere_operators(4);
  const fem::SparseMatrix A = ops.mass + 1e-3 * ops.laplacian;
  fem::CholeskySolver cholmod(A);
  REQUIRE(cholmod.is_factorized());
  CHECK(cholmod.is_supernodal());
  CHECK(cholmod.rows() == A.rows());
  Eigen::SimplicialLDLT<fem::SparseMatrix> reference(A);
  REQUIRE(reference.info() == Eigen::Success);

  const Eigen::VectorXd b = Eigen::VectorXd::Random(A.rows());
  const Eigen::VectorXd x = cholmod.solve(b);
  const Eigen::VectorXd expected = reference.solve(b);
  CHECK((x - expected).norm() <= 1e-10 * expected.norm());
  CHECK((A * x - b).norm() <= 1e-12 * b.norm());

  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(A.rows(), 5);
  const Eigen::MatrixXd X = cholmod.solve_multiple(B);
  REQUIRE(X.cols() == 5);
  for (int c = 0; c < 5; ++c) CHECK((X.col(c) - reference.solve(Eigen::VectorXd(B.col(c)))).norm() <= 1e-10 * X.col(c).norm());
}

TEST_CASE("cholesky: factor reuse for a matrix with the same pattern", "[fem][cholesky]") {
  const Operators ops = sphere_operators(3);
  fem::CholeskySolver solver;
  const fem::SparseMatrix first = ops.mass + 0.1 * ops.laplacian;
  solver.analyze(first);
  CHECK_FALSE(solver.is_factorized());
  CHECK_THROWS_AS(solver.solve(Eigen::VectorXd::Ones(first.rows())), std::logic_error);
  const Eigen::VectorXd b = Eigen::VectorXd::Random(first.rows());
  for (double t : {0.1, 0.01, 2.0}) {
    const fem::SparseMatrix A = ops.mass + t * ops.laplacian;  // same pattern for every t
    solver.factorize(A);
    const Eigen::VectorXd x = solver.solve(b);
    Eigen::SimplicialLDLT<fem::SparseMatrix> reference(A);
    CHECK((x - reference.solve(b)).norm() <= 1e-10 * x.norm());
  }
  // A different pattern is refused rather than silently mis-factored.
  fem::SparseMatrix diagonal = ops.mass;
  CHECK_THROWS_AS(solver.factorize(diagonal), std::invalid_argument);
  // A move keeps the factor.
  fem::CholeskySolver moved = std::move(solver);
  CHECK(moved.is_factorized());
  CHECK((moved.solve(b) - Eigen::SimplicialLDLT<fem::SparseMatrix>(ops.mass + 2.0 * ops.laplacian).solve(b)).norm() <=
        1e-10 * b.norm());
}

TEST_CASE("cholesky: closed-surface Laplacian is reported as not positive definite", "[fem][cholesky]") {
  for (int level = 1; level <= 4; ++level) {
    INFO("icosphere level " << level);
    const Operators ops = sphere_operators(level);
    fem::CholeskySolver solver;
    try {
      solver.compute(ops.laplacian);
      FAIL("singular Laplacian was factorised");
    } catch (const fem::NotPositiveDefinite& error) {
      CHECK(error.column() >= 0);
      CHECK(error.column() < ops.laplacian.rows());
      CHECK_FALSE(solver.is_factorized());
    }
  }
  // An indefinite matrix fails inside CHOLMOD itself.
  fem::SparseMatrix indefinite(3, 3);
  indefinite.insert(0, 0) = 1.0;
  indefinite.insert(1, 1) = -1.0;
  indefinite.insert(2, 2) = 1.0;
  CHECK_THROWS_AS(fem::CholeskySolver(indefinite), fem::NotPositiveDefinite);
  // Pinning one vertex makes it definite.
  const Operators ops = sphere_operators(2);
  fem::SparseMatrix pinned = ops.laplacian;
  pinned.coeffRef(0, 0) += 1.0;
  CHECK_NOTHROW(fem::CholeskySolver(pinned));
}

TEST_CASE("every CHOLMOD ordering gives the same solution", "[fem][cholesky]") {
  // A 2D grid Laplacian plus a small shift: SPD, with enough fill for the orderings to differ.
  const int side = 40, n = side * side;
  std::vector<Eigen::Triplet<double>> entries;
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) {
      const int v = i * side + j;
      entries.emplace_back(v, v, 4.01);
      if (i + 1 < side) entries.emplace_back(v, v + side, -1), entries.emplace_back(v + side, v, -1);
      if (j + 1 < side) entries.emplace_back(v, v + 1, -1), entries.emplace_back(v + 1, v, -1);
    }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(entries.begin(), entries.end());
  Eigen::VectorXd b(n);
  for (int v = 0; v < n; ++v) b(v) = std::sin(0.37 * v) + 0.1;
  for (const fem::CholeskyOrdering ordering : {fem::CholeskyOrdering::automatic, fem::CholeskyOrdering::amd,
                                               fem::CholeskyOrdering::metis, fem::CholeskyOrdering::nested_dissection}) {
    INFO(fem::to_string(ordering));
    fem::CholeskySolver solver;
    solver.set_ordering(ordering);
    solver.compute(A);
    const Eigen::VectorXd x = solver.solve(b);
    CHECK((A * x - b).norm() <= 1e-12 * b.norm());
  }
}
