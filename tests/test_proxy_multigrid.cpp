// The exact route set up once: the multigrid hierarchy in the store (ice/proxy/multigrid.h) gives
// the built one's prolongations to the last bit and is never used when damaged; many right-hand
// sides go through block V-cycles (fem::PoissonSolver::solve_multiple_weighted) with each column's
// single-solve answer; heat steps by multigrid follow CHOLMOD's.
#include <catch2/catch.hpp>

#include <filesystem>
#include <vector>

#include "fem/errors.h"
#include "fem/operators.h"
#include "fem/problems.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/proxy/multigrid.h"
#include "test_support.h"

namespace fs = std::filesystem;
using ice::proxy::CacheStatus;
using ice_test::fresh_store;
using ice_test::read_bytes;
using ice_test::write_bytes;

namespace {

using ice_test::unit_sphere;

ice::HierarchyOptions small_levels() {
  ice::HierarchyOptions options;
  options.coarsest_vertices = 60;  // several levels on 2,562 vertices
  return options;
}

ice::proxy::Store store_in(const fs::path& dir) { return ice::proxy::Store({dir, ice::proxy::kDefaultStoreBytes}); }

bool same_prolongations(const ice::proxy::MultigridHierarchy& a, const ice::proxy::MultigridHierarchy& b) {
  if (a.prolongations.size() != b.prolongations.size() || a.fine_order != b.fine_order) return false;
  for (std::size_t k = 0; k < a.prolongations.size(); ++k)
    if (!a.prolongations[k].isApprox(b.prolongations[k], 0.0) || a.prolongations[k].nonZeros() != b.prolongations[k].nonZeros())
      return false;
  return true;
}

struct FineSystem {
  fem::SparseMatrix L, M;
};

FineSystem fine_system(const ice::TriangleMesh& mesh) {
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  return {fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths, mesh.V.rows())),
          fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths, mesh.V.rows()), fem::MassKind::lumped)};
}

// k smooth-ish sources of zero mean per column: products of coordinates.
Eigen::MatrixXd product_sources(const ice::TriangleMesh& mesh, int k) {
  Eigen::MatrixXd F(mesh.V.rows(), k);
  for (int j = 0; j < k; ++j)
    for (Eigen::Index v = 0; v < F.rows(); ++v)
      F(v, j) = mesh.V(v, j % 3) * mesh.V(v, (j + 1) % 3) + 0.1 * j * mesh.V(v, (j + 2) % 3);
  return F;
}

}  // namespace

TEST_CASE("stored hierarchy: a warm load equals the build to the last bit; other options miss", "[proxy][store][multigrid]") {
  const fs::path dir = fresh_store("hierarchy-warm");
  const ice::proxy::Store store = store_in(dir);
  const ice::TriangleMesh& mesh = unit_sphere();
  const ice::proxy::MultigridHierarchy plain = ice::proxy::multigrid_hierarchy(mesh, small_levels());
  CHECK(plain.cache.status == CacheStatus::off);
  REQUIRE(plain.num_levels() >= 3);
  CHECK(plain.level_vertices(0) == mesh.V.rows());
  CHECK(plain.grid_complexity() > 1.0);
  const ice::proxy::MultigridHierarchy cold = ice::proxy::multigrid_hierarchy(mesh, small_levels(), store);
  CHECK(cold.cache.status == CacheStatus::miss);
  CHECK(cold.cache.save_error.empty());
  const ice::proxy::MultigridHierarchy warm = ice::proxy::multigrid_hierarchy(mesh, small_levels(), store);
  CHECK(warm.cache.status == CacheStatus::hit);
  CHECK(warm.cache.keys == cold.cache.keys);
  CHECK(same_prolongations(plain, cold));
  CHECK(same_prolongations(plain, warm));
  CHECK(warm.stop_reason == plain.stop_reason);
  CHECK(warm.grid_complexity() == plain.grid_complexity());
  // An entry stays below 200 bytes per input vertex.
  CHECK(fs::file_size(dir / ("hierarchy-" + warm.cache.keys.at(0) + ".ice")) < 200 * static_cast<std::uintmax_t>(mesh.V.rows()));

  // The same exact solve from either.
  const FineSystem s = fine_system(mesh);
  const Eigen::VectorXd f = product_sources(mesh, 1).col(0);
  const fem::PoissonSolver a = fem::PoissonSolver::zero_mean(s.L, s.M, plain.poisson_multigrid({}));
  const fem::PoissonSolver b = fem::PoissonSolver::zero_mean(s.L, s.M, warm.poisson_multigrid({}));
  CHECK(a.solve(f) == b.solve(f));

  ice::HierarchyOptions other = small_levels();
  other.ratio = 0.3;
  CHECK(ice::proxy::multigrid_hierarchy(mesh, other, store).cache.status == CacheStatus::miss);
  other = small_levels();
  other.locked_vertices = {5, 3, 5};
  const ice::proxy::MultigridHierarchy locked = ice::proxy::multigrid_hierarchy(mesh, other, store);
  CHECK(locked.cache.status == CacheStatus::miss);
  other.locked_vertices = {3, 5};  // the same set
  CHECK(ice::proxy::multigrid_hierarchy(mesh, other, store).cache.status == CacheStatus::hit);
  fs::remove_all(dir);
}

TEST_CASE("stored hierarchy: damaged entries are reported, never used, and rebuilt", "[proxy][store][multigrid]") {
  const fs::path dir = fresh_store("hierarchy-damage");
  const ice::proxy::Store store = store_in(dir);
  const ice::TriangleMesh& mesh = unit_sphere();
  const ice::proxy::MultigridHierarchy plain = ice::proxy::multigrid_hierarchy(mesh, small_levels());
  const ice::proxy::MultigridHierarchy cold = ice::proxy::multigrid_hierarchy(mesh, small_levels(), store);
  const fs::path entry = dir / ("hierarchy-" + cold.cache.keys.at(0) + ".ice");
  const std::vector<char> good = read_bytes(entry);
  REQUIRE(!good.empty());

  std::vector<char> flipped = good;
  flipped[flipped.size() / 2] ^= 0x04;
  std::vector<char> truncated(good.begin(), good.begin() + good.size() / 3);
  for (const auto& bytes : {flipped, truncated}) {
    write_bytes(entry, bytes);
    const ice::proxy::MultigridHierarchy rebuilt = ice::proxy::multigrid_hierarchy(mesh, small_levels(), store);
    CHECK(rebuilt.cache.status == CacheStatus::rebuilt);
    CHECK(!rebuilt.cache.damage.empty());
    CHECK(same_prolongations(rebuilt, plain));
    CHECK(ice::proxy::multigrid_hierarchy(mesh, small_levels(), store).cache.status == CacheStatus::hit);
  }

  // Another mesh's entry under this key (its header made to match): its arrays do not fit this mesh.
  const ice::TriangleMesh other = ice::make_icosphere(3);
  const ice::proxy::MultigridHierarchy made = ice::proxy::multigrid_hierarchy(other, small_levels(), store);
  std::vector<char> moved = read_bytes(dir / ("hierarchy-" + made.cache.keys.at(0) + ".ice"));
  std::copy(good.begin() + 32, good.begin() + 48, moved.begin() + 32);
  write_bytes(entry, moved);
  const ice::proxy::MultigridHierarchy rebuilt = ice::proxy::multigrid_hierarchy(mesh, small_levels(), store);
  CHECK(rebuilt.cache.status == CacheStatus::rebuilt);
  CHECK(same_prolongations(rebuilt, plain));
  fs::remove_all(dir);
}

TEST_CASE("multigrid Poisson: a block of sources equals the solves one by one", "[multigrid][block]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const FineSystem s = fine_system(mesh);
  const ice::proxy::MultigridHierarchy h = ice::proxy::multigrid_hierarchy(mesh, small_levels());
  // More columns than one chunk of block V-cycles (fem::MultigridSolver::kBlockColumns).
  const Eigen::MatrixXd F = product_sources(mesh, static_cast<int>(fem::MultigridSolver::kBlockColumns) + 3);
  const Eigen::MatrixXd B = s.M * F;
  SECTION("zero mean") {
    const fem::PoissonSolver mg = fem::PoissonSolver::zero_mean(s.L, s.M, h.poisson_multigrid({}));
    const fem::PoissonSolver direct = fem::PoissonSolver::zero_mean(s.L, s.M);
    const Eigen::MatrixXd U = mg.solve_multiple_weighted(B);
    REQUIRE(mg.multigrid()->reports().size() == static_cast<std::size_t>(F.cols()));
    for (const fem::MultigridReport& r : mg.multigrid()->reports()) CHECK(r.converged);
    const std::vector<fem::MultigridReport> block = mg.multigrid()->reports();
    for (Eigen::Index j = 0; j < F.cols(); ++j) {
      const Eigen::VectorXd single = mg.solve_weighted(B.col(j));
      // The same iterations, so the answers differ only by the block kernels' order of sums.
      REQUIRE(mg.multigrid()->report().iterations == block[static_cast<std::size_t>(j)].iterations);
      CHECK((U.col(j) - single).norm() <= 1e-10 * single.norm());
      CHECK(fem::relative_l2_error(U.col(j), direct.solve_weighted(B.col(j)), s.M) < 1e-6);
    }
  }
  SECTION("Dirichlet, with values per column") {
    const std::vector<fem::Index> fixed = {0, 100, 2000};
    const fem::PoissonSolver mg = fem::PoissonSolver::dirichlet(s.L, s.M, fixed, h.poisson_multigrid({}));
    Eigen::MatrixXd values(3, F.cols());
    for (Eigen::Index j = 0; j < F.cols(); ++j) values.col(j) << 1.0 * j, -1.0, 0.5;
    const Eigen::MatrixXd U = mg.solve_multiple_weighted(B, values);
    const std::vector<fem::MultigridReport> block = mg.multigrid()->reports();
    for (Eigen::Index j = 0; j < F.cols(); ++j) {
      const Eigen::VectorXd single = mg.solve_weighted(B.col(j), values.col(j));
      REQUIRE(mg.multigrid()->report().iterations == block[static_cast<std::size_t>(j)].iterations);
      CHECK((U.col(j) - single).norm() <= 1e-10 * single.norm());
      for (int c = 0; c < 3; ++c) CHECK(U(fixed[static_cast<std::size_t>(c)], j) == values(c, j));
    }
  }
}

TEST_CASE("multigrid heat steps follow CHOLMOD's; a trajectory's columns equal integrate", "[multigrid][heat]") {
  const ice::TriangleMesh& mesh = unit_sphere();
  const FineSystem s = fine_system(mesh);
  const ice::proxy::MultigridHierarchy h = ice::proxy::multigrid_hierarchy(mesh, small_levels());
  fem::MultigridOptions options;
  options.tolerance = 1e-10;
  const double tau = 0.05;  // diffusion-dominated: several V-cycles per solve from 0
  const fem::HeatSolver mg(s.L, s.M, tau, h.poisson_multigrid(options));
  const fem::HeatSolver direct(s.L, s.M, tau);
  REQUIRE(mg.multigrid() != nullptr);
  CHECK(direct.multigrid() == nullptr);
  const Eigen::VectorXd u0 = product_sources(mesh, 1).col(0);
  std::vector<int> written;
  std::vector<fem::MultigridReport> steps;
  const Eigen::MatrixXd states = mg.trajectory(u0, 7, 3, &written, &steps);
  CHECK(written == std::vector<int>{3, 6, 7});
  REQUIRE(steps.size() == 7);
  for (const fem::MultigridReport& r : steps) CHECK(r.converged);
  const Eigen::MatrixXd reference = direct.trajectory(u0, 7, 3);
  REQUIRE(reference.cols() == 3);
  for (Eigen::Index j = 0; j < 3; ++j) {
    CHECK(fem::relative_l2_error(states.col(j), reference.col(j), s.M) < 1e-8);
    CHECK(reference.col(j) == direct.integrate(u0, written[static_cast<std::size_t>(j)]));
  }
  // Each step starts from the previous state, within O(τ) of the next: step 7 (from u₆) takes no
  // more iterations than its system M u₆ solved from 0.
  mg.solve_weighted(s.M * states.col(1));
  CHECK(steps.back().iterations <= mg.multigrid()->report().iterations);
  CHECK(fem::output_steps(10, 5) == std::vector<int>{5, 10});
  CHECK(fem::output_steps(1, 5) == std::vector<int>{1});
  CHECK_THROWS_AS(fem::output_steps(0, 1), std::invalid_argument);
}

TEST_CASE("hierarchy files: an explicit save loads back bit for bit, for its own mesh only; a broken hierarchy is not saved",
          "[proxy][store][multigrid]") {
  const fs::path dir = fresh_store("hierarchy-file");
  fs::create_directories(dir);
  const fs::path file = dir / "sphere-levels.ice";
  const ice::TriangleMesh& mesh = unit_sphere();
  const ice::proxy::MultigridHierarchy made = ice::proxy::multigrid_hierarchy(mesh, small_levels());
  ice::proxy::save_multigrid_hierarchy_file(file, mesh, made);
  CHECK_THROWS_AS(ice::proxy::save_multigrid_hierarchy_file(file, mesh, made), ice::MeshError);
  const ice::proxy::MultigridHierarchy loaded = ice::proxy::load_multigrid_hierarchy_file(file, mesh);
  CHECK(same_prolongations(loaded, made));
  CHECK(loaded.fine_order == made.fine_order);
  CHECK(loaded.stop_reason == made.stop_reason);

  ice::TriangleMesh moved = mesh;
  moved.F.row(0) = moved.F.row(0).reverse().eval();
  CHECK_THROWS_WITH(ice::proxy::load_multigrid_hierarchy_file(file, moved), Catch::Contains("another mesh"));
  std::vector<char> flipped = read_bytes(file);
  flipped[flipped.size() - 9] ^= 0x01;
  write_bytes(file, flipped);
  CHECK_THROWS_WITH(ice::proxy::load_multigrid_hierarchy_file(file, mesh), Catch::Contains("checksum"));

  ice::proxy::MultigridHierarchy broken = made;  // a row of P0 no longer sums to 1
  broken.prolongations[0].valuePtr()[0] *= 0.5;
  CHECK_THROWS_WITH(ice::proxy::save_multigrid_hierarchy_file(dir / "broken.ice", mesh, broken), Catch::Contains("does not sum to 1"));
  CHECK(!fs::exists(dir / "broken.ice"));
  fs::remove_all(dir);
}
