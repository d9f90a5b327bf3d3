// libfem geometry and operators: intrinsic (length-only) quantities against independent extrinsic
// formulas, algebraic properties of L, M, G, D, and the Laplace–Beltrami spectrum of the sphere.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "fem/cholesky.h"
#include "fem/coarse_proxy.h"
#include "fem/geometry.h"
#include "fem/operators.h"
#include "ice/coarse_space.h"
#include "ice/triangle_geometry.h"
#include "ice/mesh_generators.h"
#include "test_support.h"

namespace {

using ice::kPi;

Eigen::Vector3d position(const ice::TriangleMesh& mesh, int v) { return mesh.V.row(v).transpose(); }

/// Extrinsic cotangent Laplacian, assembled densely-by-triplets from 3D vectors: cot = dot/|cross|.
fem::SparseMatrix extrinsic_laplacian(const ice::TriangleMesh& mesh) {
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int apex = mesh.F(f, k), i = mesh.F(f, (k + 1) % 3), j = mesh.F(f, (k + 2) % 3);
      const Eigen::Vector3d a = position(mesh, i) - position(mesh, apex);
      const Eigen::Vector3d b = position(mesh, j) - position(mesh, apex);
      const double half_cot = 0.5 * a.dot(b) / a.cross(b).norm();
      triplets.emplace_back(i, j, -half_cot);
      triplets.emplace_back(j, i, -half_cot);
      triplets.emplace_back(i, i, half_cot);
      triplets.emplace_back(j, j, half_cot);
    }
  fem::SparseMatrix L(mesh.V.rows(), mesh.V.rows());
  L.setFromTriplets(triplets.begin(), triplets.end());
  return L;
}

Eigen::VectorXd extrinsic_vertex_areas(const ice::TriangleMesh& mesh) {
  Eigen::VectorXd areas = Eigen::VectorXd::Zero(mesh.V.rows());
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d p0 = position(mesh, mesh.F(f, 0));
    const double area = 0.5 * (position(mesh, mesh.F(f, 1)) - p0).cross(position(mesh, mesh.F(f, 2)) - p0).norm();
    for (int k = 0; k < 3; ++k) areas(mesh.F(f, k)) += area / 3.0;
  }
  return areas;
}

using ice_test::relative_difference;

void require_intrinsic_matches_extrinsic(const ice::TriangleMesh& mesh, double tolerance) {
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths, mesh.V.rows()));
  const fem::SparseMatrix reference = extrinsic_laplacian(mesh);
  CHECK(relative_difference(L, reference) < tolerance);
  // Entry-wise too, relative to the largest diagonal (Frobenius can hide a few bad entries).
  CHECK(fem::SparseMatrix(L - reference).coeffs().cwiseAbs().maxCoeff() <
        tolerance * reference.diagonal().cwiseAbs().maxCoeff());
  const Eigen::VectorXd mass = fem::lumped_vertex_areas(ice::intrinsic_mesh(mesh.F, lengths, mesh.V.rows()));
  const Eigen::VectorXd mass_reference = extrinsic_vertex_areas(mesh);
  CHECK((mass - mass_reference).cwiseAbs().maxCoeff() < tolerance * mass_reference.maxCoeff());
  CHECK(((mass - mass_reference).cwiseAbs().array() <= tolerance * mass_reference.array()).all());
}

ice::TriangleMesh sphere_like_test_mesh() { return ice::make_icosphere(2); }

}  // namespace

TEST_CASE("geometry: angles, cotangents, areas and layouts from lengths", "[fem][geometry]") {
  const ice::TriangleMesh mesh = ice::make_flat_disk(5, 1.0, 0.25, 3);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const Eigen::MatrixXd angles = fem::corner_angles(lengths);
  const Eigen::MatrixXd cotangents = fem::corner_cotangents(lengths);
  const Eigen::VectorXd areas = fem::face_areas(lengths);
  const Eigen::MatrixXd layouts = fem::face_layouts(lengths);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    CHECK(angles.row(f).sum() == Approx(kPi).epsilon(1e-14));
    const Eigen::Vector3d p0 = position(mesh, mesh.F(f, 0)), p1 = position(mesh, mesh.F(f, 1)),
                          p2 = position(mesh, mesh.F(f, 2));
    CHECK(areas(f) == Approx(0.5 * (p1 - p0).cross(p2 - p0).norm()).epsilon(1e-13));
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d apex = position(mesh, mesh.F(f, k));
      const Eigen::Vector3d a = position(mesh, mesh.F(f, (k + 1) % 3)) - apex;
      const Eigen::Vector3d b = position(mesh, mesh.F(f, (k + 2) % 3)) - apex;
      CHECK(angles(f, k) == Approx(std::atan2(a.cross(b).norm(), a.dot(b))).epsilon(1e-12));
      CHECK(cotangents(f, k) == Approx(a.dot(b) / a.cross(b).norm()).epsilon(1e-12));
      // The layout reproduces the edge from corner k to corner k+1.
      const Eigen::Vector2d from(layouts(f, 2 * k), layouts(f, 2 * k + 1));
      const Eigen::Vector2d to(layouts(f, 2 * ((k + 1) % 3)), layouts(f, 2 * ((k + 1) % 3) + 1));
      CHECK((to - from).norm() == Approx(lengths(f, k)).epsilon(1e-13));
    }
    CHECK(layouts(f, 5) > 0);  // counter-clockwise
  }
}

TEST_CASE("geometry: degenerate and invalid triangles", "[fem][geometry]") {
  // Needle: Kahan's formula keeps full relative accuracy where naive Heron loses most digits.
  // Sides 1, 1, 2e-8 (isosceles): area = ½·2e-8·sqrt(1 − 1e-16) ≈ 1e-8.
  ice::FaceLengths needle(1, 3);
  needle << 1.0, 1.0, 2e-8;
  CHECK(fem::face_areas(needle)(0) == Approx(1e-8 * std::sqrt(1.0 - 1e-16)).epsilon(1e-12));

  ice::FaceLengths flat(1, 3);
  flat << 1.0, 2.0, 1.0;  // collinear: allowed, zero area, angles 0/π/0
  CHECK(fem::face_areas(flat)(0) == 0.0);
  const Eigen::MatrixXd angles = fem::corner_angles(flat);
  CHECK(angles(0, 1) == Approx(0.0).margin(1e-7));
  CHECK(angles.sum() == Approx(kPi));
  CHECK_THROWS_AS(fem::corner_cotangents(flat), fem::InvalidTriangle);

  ice::FaceLengths broken(2, 3);
  broken << 1.0, 1.0, 1.0, 1.0, 3.0, 1.0;
  try {
    fem::corner_angles(broken);
    FAIL("triangle inequality violation not reported");
  } catch (const fem::InvalidTriangle& error) {
    CHECK(error.face() == 1);
  }
  CHECK_THROWS_AS(fem::face_areas(broken), fem::InvalidTriangle);
  ice::FaceLengths negative(1, 3);
  negative << 1.0, -1.0, 1.0;
  CHECK_THROWS_AS(fem::face_areas(negative), fem::InvalidTriangle);
}

TEST_CASE("operators: intrinsic L and M equal the extrinsic ones on generated meshes", "[fem][operators]") {
  require_intrinsic_matches_extrinsic(ice::make_icosphere(3, 2.5), 1e-12);
  require_intrinsic_matches_extrinsic(ice::make_torus(40, 16, 3.0, 1.0), 1e-12);
  require_intrinsic_matches_extrinsic(ice::make_flat_disk(10, 1.0, 0.25, 5), 1e-12);
  require_intrinsic_matches_extrinsic(ice::loop_subdivide(ice::make_genus2(2), 1), 1e-12);
}

namespace {

/// Minimal reader for the plain triangle OBJ/OFF files used here (ice::load_mesh validates and repairs,
/// which is far slower under AddressSanitizer and not what these tests are about). OBJ: "v x y z" and
/// "f a b c" with 1-based, optionally slashed indices; OFF: header, counts, vertices, "3 a b c" faces.
ice::TriangleMesh load_plain(const std::string& path) {
  INFO(path);
  std::ifstream in(path);
  REQUIRE(in.good());
  std::vector<double> coordinates;
  std::vector<int> indices;
  if (path.size() > 4 && path.substr(path.size() - 4) == ".off") {
    std::string header;
    long vertex_count = 0, face_count = 0, edge_count = 0;
    in >> header >> vertex_count >> face_count >> edge_count;
    REQUIRE(header == "OFF");
    coordinates.resize(static_cast<std::size_t>(3 * vertex_count));
    for (double& c : coordinates) in >> c;
    for (long f = 0; f < face_count; ++f) {
      int corners = 0, a = 0, b = 0, c = 0;
      in >> corners >> a >> b >> c;
      REQUIRE(corners == 3);
      indices.insert(indices.end(), {a, b, c});
    }
  } else {
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream tokens(line);
      std::string tag;
      tokens >> tag;
      if (tag == "v") {
        double x = 0, y = 0, z = 0;
        tokens >> x >> y >> z;
        coordinates.insert(coordinates.end(), {x, y, z});
      } else if (tag == "f") {
        std::string corner;
        int count = 0;
        while (tokens >> corner) {
          indices.push_back(std::stoi(corner.substr(0, corner.find('/'))) - 1);
          ++count;
        }
        REQUIRE(count == 3);
      }
    }
  }
  REQUIRE_FALSE(in.bad());
  ice::TriangleMesh mesh;
  mesh.V = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      coordinates.data(), static_cast<Eigen::Index>(coordinates.size() / 3), 3);
  mesh.F = Eigen::Map<Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      indices.data(), static_cast<Eigen::Index>(indices.size() / 3), 3);
  REQUIRE(mesh.F.rows() > 100);
  REQUIRE(mesh.F.minCoeff() >= 0);
  REQUIRE(mesh.F.maxCoeff() < mesh.V.rows());
  return mesh;
}

}  // namespace

TEST_CASE("operators: intrinsic L and M equal the extrinsic ones on real meshes", "[fem][operators][meshes]") {
  // Meshes without near-degenerate faces (Σl²/A below ~500): agreement to 1e-12.
  for (const std::string& path : ice_test::mesh_sweep({"spot.obj", "lion-head.off", "elephant.off", "fandisk.off"},
                                                      {"camelhead.off", "fertility.off", "fandisk.obj"})) {
    INFO("mesh " << path);
    require_intrinsic_matches_extrinsic(load_plain(path), 1e-12);
  }
}

TEST_CASE("operators: cotangents from lengths are as accurate as the lengths allow", "[fem][operators][meshes]") {
  // Rounding the lengths perturbs a face's area by about ε·κ² relative, κ = Σl²/A, so on near-needles
  // no length-based formula can match positions to 1e-12. boxpart (a CAD part) has faces with
  // κ ≈ 1.6e5, bunny_closed κ ≈ 4e4; the measured error stays below 0.05·ε·κ²·(1 + |cot|) on every
  // real mesh tried.
  for (const std::string& path : ice_test::mesh_sweep({"boxpart.obj"}, {"bunny_closed.off"})) {
    INFO("mesh " << path);
    const ice::TriangleMesh mesh = load_plain(path);
    const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
    const Eigen::MatrixXd cotangents = fem::corner_cotangents(lengths);
    const Eigen::VectorXd areas = fem::face_areas(lengths);
    const double eps = std::numeric_limits<double>::epsilon();
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
      const double kappa = lengths.row(f).squaredNorm() / areas(f);
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d apex = position(mesh, mesh.F(f, k));
        const Eigen::Vector3d a = position(mesh, mesh.F(f, (k + 1) % 3)) - apex;
        const Eigen::Vector3d b = position(mesh, mesh.F(f, (k + 2) % 3)) - apex;
        const double reference = a.dot(b) / a.cross(b).norm();
        if (!(std::abs(cotangents(f, k) - reference) <= eps * kappa * kappa * (1.0 + std::abs(reference))))
          FAIL_CHECK("face " << f << " corner " << k << ": cot " << cotangents(f, k) << " vs " << reference
                             << " (kappa " << kappa << ")");
      }
    }
  }
}

TEST_CASE("operators: L symmetric, rows sum to zero, positive semidefinite", "[fem][operators]") {
  for (const ice::TriangleMesh& mesh : {sphere_like_test_mesh(), ice::make_flat_disk(5, 1.0, 0.2, 9),
                                        ice::make_genus2(1)}) {
    const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
    const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths));
    const double scale = L.diagonal().maxCoeff();
    CHECK(fem::SparseMatrix(L - fem::SparseMatrix(L.transpose())).norm() <= 1e-14 * L.norm());
    CHECK((L * Eigen::VectorXd::Ones(L.cols())).cwiseAbs().maxCoeff() < 1e-13 * scale);
    const Eigen::VectorXd eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(L)).eigenvalues();
    CHECK(eigenvalues.minCoeff() > -1e-12 * scale);
    // Connected: exactly one zero eigenvalue (the constants).
    CHECK(eigenvalues(1) > 1e-6 * scale);
  }
}

TEST_CASE("operators: the intrinsic mesh they take, and its checks", "[fem][operators]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(1);
  const ice::IntrinsicMesh sphere = ice::intrinsic_mesh(mesh);
  CHECK(sphere.F == mesh.F);
  CHECK(sphere.L == ice::face_lengths_from_positions(mesh.V, mesh.F));
  CHECK(sphere.twin.empty());
  CHECK(sphere.num_vertices() == mesh.V.rows());
  CHECK(ice::intrinsic_mesh(mesh.F, sphere.L).vertex_count == mesh.V.rows());  // the vertices F names
  CHECK(ice::intrinsic_mesh(ice::Faces(0, 3), ice::FaceLengths(0, 3)).vertex_count == 0);
  const ice::IntrinsicMesh doubled = ice::with_lengths(sphere, 2 * sphere.L);
  CHECK(doubled.F == sphere.F);
  CHECK(doubled.vertex_count == sphere.vertex_count);
  CHECK(fem::mass_matrix(doubled).sum() == Approx(4 * fem::mass_matrix(sphere).sum()).epsilon(1e-12));
  CHECK(fem::SparseMatrix(fem::cotan_laplacian(doubled) - fem::cotan_laplacian(sphere)).norm() < 1e-12);  // scale-free
  // A vertex no face uses: its row and column are empty, its lumped area 0.
  const ice::IntrinsicMesh wider = ice::intrinsic_mesh(mesh.F, sphere.L, sphere.vertex_count + 1);
  CHECK(fem::cotan_laplacian(wider).rows() == sphere.vertex_count + 1);
  CHECK(fem::lumped_vertex_areas(wider)(sphere.vertex_count) == 0);
  // Broken invariants are refused, whichever operator reads them.
  ice::IntrinsicMesh too_few = sphere;
  too_few.vertex_count = sphere.vertex_count - 1;
  ice::IntrinsicMesh short_lengths = sphere;
  short_lengths.L.conservativeResize(sphere.L.rows() - 1, 3);
  ice::IntrinsicMesh negative = sphere;
  negative.F(0, 0) = -1;
  for (const ice::IntrinsicMesh* bad : {&too_few, &short_lengths, &negative}) {
    CHECK_THROWS_AS(fem::cotan_laplacian(*bad), std::invalid_argument);
    CHECK_THROWS_AS(fem::mass_matrix(*bad), std::invalid_argument);
    CHECK_THROWS_AS(fem::gradient(*bad), std::invalid_argument);
    CHECK_THROWS_AS(fem::heat_method_operators(*bad), std::invalid_argument);
  }
}

TEST_CASE("operators: mass matrices, gradient and divergence", "[fem][operators]") {
  const ice::TriangleMesh mesh = ice::make_torus(20, 10, 2.0, 0.7);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const Eigen::VectorXd areas = fem::face_areas(lengths);
  const fem::SparseMatrix lumped = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths), fem::MassKind::lumped);
  const fem::SparseMatrix consistent = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths), fem::MassKind::consistent);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(mesh.V.rows());
  CHECK(lumped.nonZeros() == mesh.V.rows());
  CHECK(ones.dot(lumped * ones) == Approx(areas.sum()).epsilon(1e-13));
  CHECK(ones.dot(consistent * ones) == Approx(areas.sum()).epsilon(1e-13));
  // Consistent mass integrates products of linear functions exactly: ∫x² over each flat face.
  const Eigen::VectorXd x = mesh.V.col(0);
  double exact = 0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const double a = x(mesh.F(f, 0)), b = x(mesh.F(f, 1)), c = x(mesh.F(f, 2));
    exact += areas(f) / 6.0 * (a * a + b * b + c * c + a * b + b * c + c * a);
  }
  CHECK(x.dot(consistent * x) == Approx(exact).epsilon(1e-13));

  const fem::SparseMatrix G = fem::gradient(ice::intrinsic_mesh(mesh.F, lengths));
  const fem::SparseMatrix D = fem::divergence(ice::intrinsic_mesh(mesh.F, lengths));
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths));
  REQUIRE(G.rows() == 2 * mesh.F.rows());
  REQUIRE(D.cols() == 2 * mesh.F.rows());
  // Constants have zero gradient; L is the stiffness matrix Gᵀ A G; D G = −L.
  CHECK((G * ones).cwiseAbs().maxCoeff() < 1e-12);
  Eigen::VectorXd area_weights(2 * areas.size());
  for (Eigen::Index f = 0; f < areas.size(); ++f) area_weights(2 * f) = area_weights(2 * f + 1) = areas(f);
  const fem::SparseMatrix stiffness = G.transpose() * area_weights.asDiagonal() * G;
  CHECK(relative_difference(stiffness, L) < 1e-12);
  CHECK(relative_difference(fem::SparseMatrix(-(D * G)), L) < 1e-12);
  // The gradient of an ambient linear function is the tangential part of its direction: its length
  // on each face equals |a − (a·n)n| (frames differ per face, lengths do not).
  const Eigen::Vector3d direction(0.3, -0.5, 0.8);
  const Eigen::VectorXd g = G * (mesh.V * direction);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d p0 = position(mesh, mesh.F(f, 0));
    const Eigen::Vector3d n = (position(mesh, mesh.F(f, 1)) - p0).cross(position(mesh, mesh.F(f, 2)) - p0).normalized();
    const double tangential = (direction - direction.dot(n) * n).norm();
    CHECK(std::hypot(g(2 * f), g(2 * f + 1)) == Approx(tangential).epsilon(1e-12));
  }
}

namespace {

/// The cotangent Laplacian as Eigen assembles it from triplets (duplicates summed in triplet order).
fem::SparseMatrix triplet_laplacian(const ice::Faces& F, const ice::FaceLengths& lengths, Eigen::Index n) {
  const Eigen::MatrixXd cot = fem::corner_cotangents(lengths);
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3);
      const double w = 0.5 * cot(f, k);
      triplets.emplace_back(i, j, -w);
      triplets.emplace_back(j, i, -w);
      triplets.emplace_back(i, i, w);
      triplets.emplace_back(j, j, w);
    }
  fem::SparseMatrix L(n, n);
  L.setFromTriplets(triplets.begin(), triplets.end());
  return L;
}

/// Same shape, same stored entries in the same places, the same values to the last bit.
bool identical(const fem::SparseMatrix& A, const fem::SparseMatrix& B) {
  if (A.rows() != B.rows() || A.cols() != B.cols() || A.nonZeros() != B.nonZeros() || !A.isCompressed() ||
      !B.isCompressed())
    return false;
  for (Eigen::Index c = 0; c <= A.outerSize(); ++c)
    if (A.outerIndexPtr()[c] != B.outerIndexPtr()[c]) return false;
  for (Eigen::Index e = 0; e < A.nonZeros(); ++e)
    if (A.innerIndexPtr()[e] != B.innerIndexPtr()[e] ||
        std::memcmp(A.valuePtr() + e, B.valuePtr() + e, sizeof(double)) != 0)
      return false;
  return true;
}

}  // namespace

TEST_CASE("operators: the cotangent Laplacian equals Eigen's triplet assembly bit for bit", "[fem][operators]") {
  SECTION("a mesh large enough for the threaded assembly, and an unused vertex") {
    // 60,000 vertices: above the size (50,000 faces, 50,000 columns) at which faces and columns are
    // split among threads.
    const ice::TriangleMesh mesh = ice::make_torus(300, 200, 1.0, 0.3);
    REQUIRE(mesh.V.rows() >= 50000);
    const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
    CHECK(identical(fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths)), triplet_laplacian(mesh.F, lengths, mesh.V.rows())));
    const Eigen::Index n = mesh.V.rows() + 1;
    const fem::SparseMatrix with_unused = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths, n));
    CHECK(identical(with_unused, triplet_laplacian(mesh.F, lengths, n)));
    CHECK(with_unused.col(n - 1).nonZeros() == 0);
  }
  SECTION("multiple edges: two triangles glued along all three sides (a Δ-complex sphere)") {
    ice::Faces F(2, 3);
    F << 0, 1, 2, 0, 2, 1;
    ice::FaceLengths lengths(2, 3);
    lengths << 1.0, 1.3, 0.9, 0.9, 1.3, 1.0;  // side k of each face joins its corners k and k+1
    const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(F, lengths));
    CHECK(identical(L, triplet_laplacian(F, lengths, 3)));
    CHECK(L.nonZeros() == 9);
    CHECK((Eigen::MatrixXd(L) * Eigen::Vector3d::Ones()).cwiseAbs().maxCoeff() < 1e-15);
  }
  SECTION("a face with a repeated vertex (a self-edge of a Δ-complex)") {
    ice::Faces F(2, 3);
    F << 0, 0, 1, 0, 1, 2;
    ice::FaceLengths lengths(2, 3);
    lengths << 1.0, 0.8, 0.8, 0.8, 1.1, 0.9;
    CHECK(identical(fem::cotan_laplacian(ice::intrinsic_mesh(F, lengths)), triplet_laplacian(F, lengths, 3)));
  }
  SECTION("real meshes of the project set, and their intrinsic coarse meshes (Δ-complexes)") {
    for (const std::string& path : ice_test::mesh_sweep({"spot_subdiv.obj", "elephant.off", "blobby_3cc.off"})) {
      INFO("mesh " << path);
      const ice::TriangleMesh mesh = load_plain(path);
      const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
      CHECK(identical(fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths, mesh.V.rows())),
                      triplet_laplacian(mesh.F, lengths, mesh.V.rows())));
      ice::CoarseSpaceOptions options;
      options.coarsen.target_vertices = 24;
      const ice::CoarseSpace coarse = ice::build_coarse_space(mesh, options);
      const ice::CompactMesh& C = coarse.mesh;
      CHECK(identical(fem::cotan_laplacian(C), triplet_laplacian(C.F, C.L, C.num_vertices())));
    }
  }
}

TEST_CASE("operators: Galerkin products", "[fem][operators]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(1);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths));
  fem::SparseMatrix identity(L.rows(), L.rows());
  identity.setIdentity();
  CHECK(relative_difference(fem::galerkin(identity, L), L) < 1e-15);
  // Against a dense product with a random non-negative P whose rows sum to 1.
  Eigen::MatrixXd P_dense = (Eigen::MatrixXd::Random(L.rows(), 7).array() + 1.0).matrix();
  P_dense = P_dense.array().colwise() / P_dense.rowwise().sum().array();
  const fem::SparseMatrix P = P_dense.sparseView();
  const Eigen::MatrixXd expected = P_dense.transpose() * Eigen::MatrixXd(L) * P_dense;
  const Eigen::MatrixXd coarse = Eigen::MatrixXd(fem::galerkin(P, L));
  CHECK((coarse - expected).norm() < 1e-12 * expected.norm());
  CHECK((coarse - coarse.transpose()).norm() == 0.0);
  CHECK((coarse * Eigen::VectorXd::Ones(7)).cwiseAbs().maxCoeff() < 1e-12 * coarse.norm());
  // Pᵀ L P and Pᵀ M P in one pass equal the two products apart, to the last bit.
  const fem::SparseMatrix M = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths));
  const auto [coarse_L, coarse_M] = fem::galerkin(P, L, M);
  CHECK(identical(coarse_L, fem::galerkin(P, L)));
  CHECK(identical(coarse_M, fem::galerkin(P, M)));
  CHECK_THROWS_AS(fem::galerkin(P, L, L), std::invalid_argument);  // not diagonal
}

TEST_CASE("operators: Galerkin products and the smoothed P split among threads", "[fem][operators]") {
  // More than 50,000 fine vertices, the size at which these passes split among threads; a P whose
  // rows reach three scattered coarse columns each (weights 0.6, 0.3, 0.1), as a coarse space of a
  // mesh numbered without locality does.
  const ice::TriangleMesh mesh = ice::make_torus(300, 200, 1.0, 0.3);
  const Eigen::Index n = mesh.V.rows(), nc = n / 40;
  REQUIRE(n >= 50000);
  std::vector<Eigen::Triplet<double>> weights;
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index c = (i * 7919) % nc;
    weights.emplace_back(i, c, 0.6);
    weights.emplace_back(i, (c + 1) % nc, 0.3);
    weights.emplace_back(i, (c + 17) % nc, 0.1);
  }
  fem::SparseMatrix P(n, nc);
  P.setFromTriplets(weights.begin(), weights.end());
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths)), M = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths));
  const auto [coarse_L, coarse_M] = fem::galerkin(P, L, M);
  CHECK(identical(coarse_L, fem::galerkin(P, L, 1)));  // the serial products, apart
  CHECK(identical(coarse_M, fem::galerkin(P, M, 1)));
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(nc);
  CHECK((coarse_L * ones).cwiseAbs().maxCoeff() < 1e-12 * coarse_L.diagonal().maxCoeff());
  CHECK(std::abs(ones.dot(coarse_M * ones) - M.sum()) < 1e-12 * M.sum());  // P·1 = 1 keeps the area
  const double omega = 2.0 / 3.0;
  const Eigen::VectorXd scale = (omega / L.diagonal().array()).matrix();
  fem::SparseMatrix expected = P - scale.asDiagonal() * (L * P);
  expected.prune(0.0);
  expected.makeCompressed();
  const fem::SparseMatrix smoothed = fem::smoothed_prolongation(P, L, omega);
  CHECK(identical(smoothed, expected));
  CHECK((smoothed * ones - Eigen::VectorXd::Ones(n)).cwiseAbs().maxCoeff() < 1e-12);  // L·1 = 0 keeps P·1 = 1
}

TEST_CASE("operators: Galerkin products of an ICE coarse space, fused", "[fem][operators]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(5);
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.02;
  const ice::CoarseSpace coarse = ice::build_coarse_space(mesh, options);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths)), M = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths));
  const auto [coarse_L, coarse_M] = fem::galerkin(coarse.P, L, M);
  CHECK(identical(coarse_L, fem::galerkin(coarse.P, L, 1)));  // the serial product
  CHECK(identical(coarse_M, fem::galerkin(coarse.P, M, 1)));
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(coarse_L.rows());
  CHECK((coarse_L * ones).cwiseAbs().maxCoeff() < 1e-12 * coarse_L.diagonal().maxCoeff());
  CHECK(std::abs(ones.dot(coarse_M * ones) - M.sum()) < 1e-12 * M.sum());  // P·1 = 1 keeps the area
  // The smoothed prolongation, row by row, equals Eigen's expression of it to the last bit.
  const double omega = 2.0 / 3.0;
  const Eigen::VectorXd scale = (omega / L.diagonal().array()).matrix();
  fem::SparseMatrix expected = coarse.P - scale.asDiagonal() * (L * coarse.P);
  expected.prune(0.0);
  expected.makeCompressed();
  const fem::SparseMatrix smoothed = fem::smoothed_prolongation(coarse.P, L, omega);
  CHECK(identical(smoothed, expected));
  CHECK((smoothed * Eigen::VectorXd::Ones(smoothed.cols()) - Eigen::VectorXd::Ones(smoothed.rows())).cwiseAbs().maxCoeff() <
        1e-12);  // L·1 = 0: smoothing keeps P·1 = 1
  // A Galerkin proxy keeps both products with a consistent (not diagonal) mass as with a lumped one.
  for (const fem::MassKind mass : {fem::MassKind::lumped, fem::MassKind::consistent}) {
    const fem::CoarseProxy proxy(ice::intrinsic_mesh(mesh.F, lengths), ice::intrinsic_mesh(coarse.mesh.F, coarse.mesh.L), coarse.P, {fem::CoarseOperatorKind::galerkin, mass});
    CHECK(identical(proxy.coarse_laplacian(), coarse_L));
    CHECK(identical(proxy.coarse_mass(), fem::galerkin(coarse.P, fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths), mass))));
  }
}

namespace {

/// Smallest `count` generalised eigenvalues of (L, M) by block inverse iteration with a shift σ:
/// X ← (L + σM)⁻¹ M X, then Rayleigh–Ritz. Converges for eigenvalue i at rate (λ_i + σ)/(λ_block + σ).
Eigen::VectorXd smallest_generalized_eigenvalues(const fem::SparseMatrix& L, const fem::SparseMatrix& M, int count) {
  const int block = count + 8;
  fem::CholeskySolver shifted(fem::SparseMatrix(L + M));
  Eigen::MatrixXd X = Eigen::MatrixXd::Random(L.rows(), block);
  Eigen::VectorXd ritz_values;
  for (int iteration = 0; iteration < 60; ++iteration) {
    X = shifted.solve_multiple(Eigen::MatrixXd(M * X));
    const Eigen::MatrixXd reduced_L = X.transpose() * (L * X), reduced_M = X.transpose() * (M * X);
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> ritz(0.5 * (reduced_L + reduced_L.transpose()),
                                                                   0.5 * (reduced_M + reduced_M.transpose()));
    X = X * ritz.eigenvectors();  // M-orthonormal Ritz vectors, sorted by value
    const Eigen::VectorXd values = ritz.eigenvalues().head(count);
    if (ritz_values.size() == count && (values - ritz_values).cwiseAbs().maxCoeff() < 1e-12 * values.maxCoeff()) {
      ritz_values = values;
      break;
    }
    ritz_values = values;
  }
  return ritz_values;
}

}  // namespace

TEST_CASE("operators: sphere spectrum converges to l(l+1)/R²", "[fem][operators][spectrum]") {
  const double radius = 2.0;
  double previous_error = INFINITY;
  for (int level = 1; level <= 4; ++level) {
    const ice::TriangleMesh mesh = ice::make_icosphere(level, radius);
    const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
    const Eigen::VectorXd values = smallest_generalized_eigenvalues(
        fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths)), fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths)), 9);
    Eigen::VectorXd exact(9);
    exact << 0, 2, 2, 2, 6, 6, 6, 6, 6;
    exact /= radius * radius;
    CHECK(std::abs(values(0)) < 1e-10);
    const double error = ((values - exact).tail(8).array() / exact.tail(8).array()).abs().maxCoeff();
    UNSCOPED_INFO("icosphere level " << level << " (" << mesh.V.rows() << " vertices): max relative error of l=1,2 eigenvalues "
                            << error << " (λ1 = " << values(1) << ", λ4..8 = " << values(4) << ".." << values(8) << ")");
    CHECK(error < previous_error / 3.0);  // second order: the error drops about 4× per level
    previous_error = error;
  }
  CHECK(previous_error < 0.01);
}
