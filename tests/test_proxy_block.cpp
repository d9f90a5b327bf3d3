// Set up once, solve many times: a block of Poisson sources through the proxy agrees with the
// single solves; heat steps on the coarse level with only some states prolonged equal the single
// integrations to the last bit; float64 .npy files round-trip, and bad ones are refused.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "fem/problems.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/proxy/heat.h"
#include "ice/proxy/poisson.h"
#include "ice/scalar_field_io.h"
#include "test_support.h"

namespace fs = std::filesystem;

namespace {

using ice_test::relative_difference;
using ice_test::unit_sphere;

// k smooth sources on the sphere: x, y z, x² − z, ...
Eigen::MatrixXd cosine_sources(const ice::TriangleMesh& mesh, Eigen::Index k) {
  Eigen::MatrixXd F(mesh.V.rows(), k);
  for (Eigen::Index v = 0; v < F.rows(); ++v)
    for (Eigen::Index j = 0; j < k; ++j) {
      const double x = mesh.V(v, 0), y = mesh.V(v, 1), z = mesh.V(v, 2);
      F(v, j) = std::cos(static_cast<double>(j + 1) * x) + static_cast<double>(j) * y * z - 0.3 * static_cast<double>(j % 3) * z;
    }
  return F;
}

}  // namespace

TEST_CASE("block Poisson: each column equals its single solve within round-off", "[proxy][block]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  ice::proxy::PoissonOptions options;
  options.coarsening.coarsen.target_vertices = 300;
  const Eigen::MatrixXd F = cosine_sources(mesh, 37);  // more than one chunk of 32 columns
  SECTION("zero-mean Neumann, smoothed P") {
    const ice::proxy::PoissonSolver solver(mesh, options);
    const Eigen::MatrixXd U = solver.solve_block(F);
    REQUIRE(U.cols() == F.cols());
    for (Eigen::Index j = 0; j < F.cols(); ++j) {
      const Eigen::VectorXd u = solver.solve(Eigen::VectorXd(F.col(j)));
      CHECK(relative_difference(U.col(j), u) < 1e-12);
    }
    // Zero mass-weighted mean in every column.
    const Eigen::VectorXd m1 = solver.proxy().fine_mass() * Eigen::VectorXd::Ones(mesh.V.rows());
    CHECK((m1.transpose() * U).cwiseAbs().maxCoeff() < 1e-12 * U.cwiseAbs().maxCoeff() * m1.sum());
  }
  SECTION("Dirichlet, a column of values each") {
    options.fixed_vertices = {0, 100, 2000};
    const ice::proxy::PoissonSolver solver(mesh, options);
    Eigen::MatrixXd values(3, F.cols());
    for (Eigen::Index j = 0; j < F.cols(); ++j) values.col(j) << 1.0, -0.5 * static_cast<double>(j), 0.25;
    const Eigen::MatrixXd U = solver.solve_block(F, values);
    for (Eigen::Index j = 0; j < F.cols(); ++j) {
      const Eigen::VectorXd u = solver.solve(Eigen::VectorXd(F.col(j)), Eigen::VectorXd(values.col(j)));
      CHECK(relative_difference(U.col(j), u) < 1e-12);
      for (int i = 0; i < 3; ++i) CHECK(U(options.fixed_vertices[static_cast<std::size_t>(i)], j) == values(i, j));
    }
    CHECK_THROWS_AS(solver.solve_block(F, Eigen::MatrixXd::Zero(2, F.cols())), std::invalid_argument);
  }
  SECTION("polishing goes column by column, as the single solve") {
    options.polish.iterations = 2;
    const ice::proxy::PoissonSolver solver(mesh, options);
    const Eigen::MatrixXd U = solver.solve_block(F.leftCols(3));
    for (Eigen::Index j = 0; j < 3; ++j) CHECK(U.col(j) == solver.solve(Eigen::VectorXd(F.col(j))));
  }
  CHECK_THROWS_AS(ice::proxy::PoissonSolver(mesh, options).solve_block(F.topRows(10)), std::invalid_argument);
}

TEST_CASE("fine block solves: CHOLMOD's block solve equals the single solves within round-off", "[fem][block]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const ice::FaceLengths L = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const auto n = static_cast<fem::Index>(mesh.V.rows());
  const fem::SparseMatrix lap = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, L, n)), M = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, L, n), fem::MassKind::lumped);
  const Eigen::MatrixXd F = cosine_sources(mesh, 5);
  const fem::PoissonSolver zero_mean = fem::PoissonSolver::zero_mean(lap, M);
  const Eigen::MatrixXd U = zero_mean.solve_multiple_weighted(M * F);
  const fem::PoissonSolver dirichlet = fem::PoissonSolver::dirichlet(lap, M, {3, 77});
  Eigen::MatrixXd values(2, F.cols());
  values.setRandom();
  const Eigen::MatrixXd W = dirichlet.solve_multiple_weighted(M * F, values);
  for (Eigen::Index j = 0; j < F.cols(); ++j) {
    CHECK(relative_difference(U.col(j), zero_mean.solve(Eigen::VectorXd(F.col(j)))) < 1e-12);
    CHECK(relative_difference(W.col(j), dirichlet.solve(Eigen::VectorXd(F.col(j)), Eigen::VectorXd(values.col(j)))) < 1e-12);
  }
}

TEST_CASE("heat steps on the coarse level: the listed states equal the single integrations bit for bit", "[proxy][block]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  ice::proxy::HeatOptions options;
  options.coarsening.coarsen.target_vertices = 300;
  const Eigen::VectorXd u0 = cosine_sources(mesh, 2).col(1);
  for (const auto restriction : {fem::RestrictionKind::l2_projection, fem::RestrictionKind::injection}) {
    options.restriction = restriction;
    const ice::proxy::HeatSolver heat(mesh, 2e-3, options);
    std::vector<int> listed;
    const Eigen::MatrixXd states = heat.steps(u0, 23, 5, &listed);
    CHECK(listed == std::vector<int>{5, 10, 15, 20, 23});
    REQUIRE(states.cols() == 5);
    for (std::size_t j = 0; j < listed.size(); ++j) CHECK(states.col(static_cast<Eigen::Index>(j)) == heat.integrate(u0, listed[j]));
    // Heat flow smooths: the field's spread shrinks from state to state.
    for (Eigen::Index j = 1; j < states.cols(); ++j) {
      const auto spread = [](const Eigen::VectorXd& v) { return v.maxCoeff() - v.minCoeff(); };
      CHECK(spread(states.col(j)) < spread(states.col(j - 1)));
    }
  }
  // Against the route that prolongs every step (each step restricted from the fine field and
  // prolonged back), by default (the L2 projection, whose restriction of a prolonged state returns
  // it): the same states up to round-off (issue #60 asks within 1 %). Injection reads a smoothed P's
  // state at the coarse vertices only, so that route drifts from it: not compared.
  {
    options.restriction = fem::RestrictionKind::l2_projection;
    const ice::proxy::HeatSolver heat(mesh, 2e-3, options);
    std::vector<int> listed;
    const Eigen::MatrixXd states = heat.steps(u0, 20, 5, &listed);
    Eigen::VectorXd u = u0;
    std::size_t next = 0;
    for (int step = 1; step <= 20; ++step) {
      u = heat.integrate(u, 1);
      if (next < listed.size() && listed[next] == step) {
        const double difference = (states.col(static_cast<Eigen::Index>(next)) - u).norm() / u.norm();
        INFO("step " << step << ": relative difference " << difference);
        CHECK(difference < 1e-12);
        ++next;
      }
    }
    CHECK(next == listed.size());
  }
  const ice::proxy::HeatSolver heat(mesh, 2e-3, options);
  CHECK_THROWS_AS(heat.steps(u0, 0, 1), std::invalid_argument);
  CHECK_THROWS_AS(heat.steps(u0, 10, 0), std::invalid_argument);
  options.polish.iterations = 1;
  CHECK_THROWS_AS(ice::proxy::HeatSolver(mesh, 2e-3, options).steps(u0, 10, 5), std::invalid_argument);
}

TEST_CASE("float64 .npy: round trip, float32 and Fortran order read, bad files refused", "[io][npy]") {
  const fs::path dir = fs::temp_directory_path() / ("ice-npy-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  Eigen::MatrixXd m(4, 3);
  m << 1, 2, 3, 4, 5, 6, 7, 8, 9, 1e-300, -0.0, 3.141592653589793;
  const std::string path = (dir / "m.npy").string();
  ice::write_npy_matrix(path, m, false);
  CHECK(ice::read_npy_matrix(path) == m);
  CHECK_THROWS_AS(ice::write_npy_matrix(path, m, false), ice::MeshError);  // never replaced unasked
  ice::write_npy_matrix(path, m.leftCols(1), true);
  CHECK(ice::read_npy_matrix(path) == m.leftCols(1));

  // A hand-made header: float32, Fortran order, 1-D.
  const auto write_raw = [&](const std::string& name, const std::string& header_dict, const std::string& payload) {
    std::string header = header_dict;
    while ((10 + header.size() + 1) % 64 != 0) header.push_back(' ');
    header.push_back('\n');
    std::ofstream out(dir / name, std::ios::binary);
    out.write("\x93NUMPY\x01\x00", 8);
    const char length[2] = {static_cast<char>(header.size() & 0xff), static_cast<char>(header.size() >> 8)};
    out.write(length, 2);
    out << header << payload;
    return (dir / name).string();
  };
  const float values[6] = {1, 2, 3, 4, 5, 6};
  const std::string payload(reinterpret_cast<const char*>(values), sizeof values);
  const Eigen::MatrixXd fortran = ice::read_npy_matrix(write_raw("f.npy", "{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3), }", payload));
  Eigen::MatrixXd expected(2, 3);
  expected << 1, 3, 5, 2, 4, 6;
  CHECK(fortran == expected);
  CHECK(ice::read_npy_matrix(write_raw("v.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (6,), }", payload)).cols() == 1);
  CHECK_THROWS_WITH(ice::read_npy_matrix(write_raw("i.npy", "{'descr': '<i8', 'fortran_order': False, 'shape': (3,), }", payload)),
                    Catch::Contains("float64 or float32"));
  CHECK_THROWS_WITH(ice::read_npy_matrix(write_raw("t.npy", "{'descr': '<f8', 'fortran_order': False, 'shape': (9,), }", payload)),
                    Catch::Contains("truncated"));
  CHECK_THROWS_WITH(ice::read_npy_matrix(write_raw("d.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 2, 3), }", payload)),
                    Catch::Contains("3 dimensions"));
  const float nan_values[1] = {std::numeric_limits<float>::quiet_NaN()};
  CHECK_THROWS_WITH(ice::read_npy_matrix(write_raw("n.npy", "{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }",
                                                   std::string(reinterpret_cast<const char*>(nan_values), 4))),
                    Catch::Contains("not finite"));
  std::ofstream((dir / "x.npy").string()) << "hello";
  CHECK_THROWS_WITH(ice::read_npy_matrix((dir / "x.npy").string()), Catch::Contains("not a NumPy"));
  fs::remove_all(dir);
}
