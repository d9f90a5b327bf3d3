// Tests of fem/ordering.h: reverse Cuthill–McKee is a permutation that shrinks the bandwidth of a
// scrambled mesh matrix, numbers each component contiguously, and permute_symmetric moves entries
// exactly.
#include <catch2/catch.hpp>

#include <algorithm>
#include <numeric>
#include <random>

#include "fem/operators.h"
#include "fem/ordering.h"
#include "ice/mesh_generators.h"

namespace {

// The mesh with its vertices renumbered by a fixed random permutation (the worst case for
// locality: neighbours anywhere in the vector).
ice::TriangleMesh scrambled(const ice::TriangleMesh& mesh, unsigned seed) {
  const Eigen::Index n = mesh.V.rows();
  std::vector<int> new_index(static_cast<std::size_t>(n));
  std::iota(new_index.begin(), new_index.end(), 0);
  std::mt19937 random(seed);
  std::shuffle(new_index.begin(), new_index.end(), random);
  ice::TriangleMesh out = mesh;
  for (Eigen::Index v = 0; v < n; ++v) out.V.row(new_index[static_cast<std::size_t>(v)]) = mesh.V.row(v);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) out.F(f, k) = new_index[static_cast<std::size_t>(mesh.F(f, k))];
  return out;
}

fem::SparseMatrix laplacian(const ice::TriangleMesh& mesh) {
  return fem::cotan_laplacian(ice::intrinsic_mesh(mesh));
}

bool is_permutation_of_range(std::vector<int> order, std::size_t n) {
  if (order.size() != n) return false;
  std::sort(order.begin(), order.end());
  for (std::size_t i = 0; i < n; ++i)
    if (order[i] != static_cast<int>(i)) return false;
  return true;
}

}  // namespace

TEST_CASE("ordering: reverse Cuthill-McKee shrinks the bandwidth of a scrambled mesh", "[fem][ordering]") {
  const ice::TriangleMesh mesh = scrambled(ice::make_icosphere(5), 7);  // 10,242 vertices
  const fem::SparseMatrix L = laplacian(mesh);
  const std::vector<int> order = fem::reverse_cuthill_mckee(L);
  REQUIRE(is_permutation_of_range(order, static_cast<std::size_t>(L.rows())));
  const fem::SparseMatrix B = fem::permute_symmetric(L, order);
  const Eigen::Index before = fem::bandwidth(L), after = fem::bandwidth(B);
  INFO("bandwidth " << before << " -> " << after);
  CHECK(before > L.rows() / 2);
  // A sphere's breadth-first levels are at most about a great circle's worth of vertices
  // (2π·√(n/4π) ≈ 180 here); a band of a few of them.
  CHECK(after < 600);
  // Deterministic.
  CHECK(fem::reverse_cuthill_mckee(L) == order);
}

TEST_CASE("ordering: permute_symmetric moves every entry, nothing else", "[fem][ordering]") {
  const ice::TriangleMesh mesh = scrambled(ice::make_torus(12, 8, 2.0, 0.5), 3);
  const fem::SparseMatrix L = laplacian(mesh);
  const std::vector<int> order = fem::reverse_cuthill_mckee(L);
  const fem::SparseMatrix B = fem::permute_symmetric(L, order);
  CHECK(B.nonZeros() == L.nonZeros());
  const Eigen::MatrixXd dense_L(L), dense_B(B);
  for (Eigen::Index i = 0; i < B.rows(); ++i)
    for (Eigen::Index j = 0; j < B.cols(); ++j)
      REQUIRE(dense_B(i, j) == dense_L(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]));
  for (Eigen::Index j = 0; j < B.outerSize(); ++j)  // sorted inner indices
    for (auto p = B.outerIndexPtr()[j] + 1; p < B.outerIndexPtr()[j + 1]; ++p)
      CHECK(B.innerIndexPtr()[p - 1] < B.innerIndexPtr()[p]);
  std::vector<int> not_a_permutation = order;
  not_a_permutation[0] = not_a_permutation[1];
  CHECK_THROWS_AS(fem::permute_symmetric(L, not_a_permutation), std::invalid_argument);
  CHECK_THROWS_AS(fem::reverse_cuthill_mckee(fem::SparseMatrix(3, 4)), std::invalid_argument);
}

TEST_CASE("ordering: permute_rows moves every row of a rectangular matrix, its columns stay", "[fem][ordering]") {
  const ice::TriangleMesh mesh = scrambled(ice::make_torus(12, 8, 2.0, 0.5), 3);
  const fem::SparseMatrix L = laplacian(mesh);
  const fem::SparseMatrix P = L.leftCols(40);  // tall, as a prolongation
  const std::vector<int> order = fem::reverse_cuthill_mckee(L);
  const fem::SparseMatrix B = fem::permute_rows(P, order);
  CHECK(B.nonZeros() == P.nonZeros());
  const Eigen::MatrixXd dense_P(P), dense_B(B);
  for (Eigen::Index i = 0; i < B.rows(); ++i)
    for (Eigen::Index j = 0; j < B.cols(); ++j) REQUIRE(dense_B(i, j) == dense_P(order[static_cast<std::size_t>(i)], j));
  for (Eigen::Index j = 0; j < B.outerSize(); ++j)  // sorted inner indices
    for (auto p = B.outerIndexPtr()[j] + 1; p < B.outerIndexPtr()[j + 1]; ++p)
      CHECK(B.innerIndexPtr()[p - 1] < B.innerIndexPtr()[p]);
  CHECK_THROWS_AS(fem::permute_rows(P.topRows(P.rows() - 1), order), std::invalid_argument);
  std::vector<int> not_a_permutation = order;
  not_a_permutation[0] = not_a_permutation[1];
  CHECK_THROWS_AS(fem::permute_rows(P, not_a_permutation), std::invalid_argument);
}

TEST_CASE("ordering: each connected component is numbered contiguously", "[fem][ordering]") {
  // Two spheres and an isolated unknown, interleaved by a scrambling.
  const ice::TriangleMesh a = ice::make_icosphere(2), b = ice::make_icosphere(3);
  ice::TriangleMesh both;
  both.V.resize(a.V.rows() + b.V.rows() + 1, 3);
  both.V << a.V, b.V, Eigen::RowVector3d(5, 5, 5);
  both.F.resize(a.F.rows() + b.F.rows(), 3);
  both.F << a.F, (b.F.array() + static_cast<int>(a.V.rows())).matrix();
  const std::size_t n = static_cast<std::size_t>(both.V.rows());
  std::vector<int> component(n, 0);
  for (std::size_t v = static_cast<std::size_t>(a.V.rows()); v + 1 < n; ++v) component[v] = 1;
  component[n - 1] = 2;
  // Scramble, carrying the component labels along.
  std::vector<int> new_index(n);
  std::iota(new_index.begin(), new_index.end(), 0);
  std::mt19937 random(11);
  std::shuffle(new_index.begin(), new_index.end(), random);
  ice::TriangleMesh mesh = both;
  std::vector<int> label(n);
  for (std::size_t v = 0; v < n; ++v) {
    mesh.V.row(new_index[v]) = both.V.row(static_cast<Eigen::Index>(v));
    label[static_cast<std::size_t>(new_index[v])] = component[v];
  }
  for (Eigen::Index f = 0; f < both.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) mesh.F(f, k) = new_index[static_cast<std::size_t>(both.F(f, k))];
  const std::vector<int> order = fem::reverse_cuthill_mckee(laplacian(mesh));
  REQUIRE(is_permutation_of_range(order, n));
  int changes = 0;
  for (std::size_t i = 1; i < n; ++i) changes += label[static_cast<std::size_t>(order[i])] != label[static_cast<std::size_t>(order[i - 1])];
  CHECK(changes == 2);
}
