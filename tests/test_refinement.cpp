// Intrinsic Delaunay refinement: vertex insertion and edge splits keep every tracked point exactly
// where it was; refinement reaches its angle bound (or its budget) and keeps the invariants; the
// inserted vertices lie in faces of the input with valid coordinates; the pipeline's P follows.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

#include "fem/cholesky.h"
#include "fem/operators.h"
#include "ice/coarse_space.h"
#include "ice/coarsen.h"
#include "ice/intrinsic_mesh_io.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/prolongation.h"
#include "ice/refinement.h"
#include "ice/triangle_geometry.h"
#include "test_support.h"

namespace {

using ice::Index;
using ice::kPi;

// On a flat mesh every vertex — input or inserted — has a place in the plane; every tracked point
// must sit where its face's corners put it. Inserted vertices get their place from the corners of
// the face they were put in, so the check covers insert_vertex's and split_edge's bookkeeping.
struct PlanarCheck {
  const ice::TriangleMesh& mesh;
  std::vector<Eigen::Vector2d> place;  // by vertex slot
  explicit PlanarCheck(const ice::TriangleMesh& m) : mesh(m) {
    for (Eigen::Index v = 0; v < m.V.rows(); ++v) place.emplace_back(m.V(v, 0), m.V(v, 1));
  }
  Eigen::Vector2d corner(const ice::IntrinsicTriangulation& T, Index f, int k) const {
    Index h = T.halfedge(f);
    for (int i = 0; i < k; ++i) h = T.next(h);
    return place[static_cast<std::size_t>(T.tail(h))];
  }
  Eigen::Vector2d at(const ice::IntrinsicTriangulation& T, Index f, const std::array<double, 3>& b) const {
    return b[0] * corner(T, f, 0) + b[1] * corner(T, f, 1) + b[2] * corner(T, f, 2);
  }
  // Largest distance of a tracked point from its input position, and of an edge length from the
  // distance of its ends' places.
  double worst(const ice::IntrinsicTriangulation& T) const {
    double worst = 0;
    for (Index p = 0; p < T.num_input_vertices(); ++p) {
      const ice::SurfacePoint s = T.location(p);
      if (s.is_vertex()) continue;
      worst = std::max(worst, (at(T, s.face, s.bary) - place[static_cast<std::size_t>(p)]).norm());
    }
    for (Index h = 0; h < T.num_halfedge_slots(); ++h)
      if (T.halfedge_alive(h))
        worst = std::max(worst, std::abs(T.length(h) - (place[static_cast<std::size_t>(T.tail(h))] -
                                                         place[static_cast<std::size_t>(T.head(h))]).norm()));
    return worst;
  }
};

ice::IntrinsicTriangulation coarsened_disk(const ice::TriangleMesh& disk, Index target) {
  ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_mesh(disk.V, disk.F);
  ice::CoarsenOptions options;
  options.target_vertices = target;
  options.remove_boundary = false;  // removing a boundary vertex straightens the boundary: not planar-exact
  ice::coarsen(T, options);
  return T;
}

std::array<double, 3> face_corner_angles(const ice::IntrinsicTriangulation& T, Index f) {
  const Index h = T.halfedge(f);
  return {T.corner_angle(h), T.corner_angle(T.next(h)), T.corner_angle(T.next(T.next(h)))};
}

}  // namespace

TEST_CASE("insert_vertex and split_edge keep tracked points in place on a flat mesh", "[refinement]") {
  const ice::TriangleMesh disk = ice::make_flat_disk(10, 1.0, 0.2);
  ice::IntrinsicTriangulation T = coarsened_disk(disk, 40);
  PlanarCheck check(disk);
  REQUIRE(check.worst(T) < 1e-12);
  const double curvature = T.total_curvature();
  // A vertex inside each of a few faces, then splits of an interior and a boundary edge.
  int inserted = 0;
  for (Index f = 0; f < T.num_face_slots() && inserted < 5; ++f) {
    if (!T.face_alive(f)) continue;
    const std::array<double, 3> b{0.2, 0.3, 0.5};
    const Eigen::Vector2d where = check.at(T, f, b);
    const Index v = T.insert_vertex(f, b);
    REQUIRE(v == T.num_vertex_slots() - 1);
    CHECK(T.is_inserted_vertex(v));
    check.place.push_back(where);
    CHECK(T.angle_sum(v) == Approx(2 * kPi).epsilon(1e-12));
    ++inserted;
  }
  Index interior = ice::kInvalid, boundary = ice::kInvalid;
  for (Index h = 0; h < T.num_halfedge_slots(); ++h) {
    if (!T.halfedge_alive(h) || T.is_exterior(h)) continue;
    if (T.is_boundary_edge(h) && boundary == ice::kInvalid) boundary = h;
    if (!T.is_boundary_edge(h) && interior == ice::kInvalid) interior = h;
  }
  REQUIRE(interior != ice::kInvalid);
  REQUIRE(boundary != ice::kInvalid);
  for (const Index h : {interior, boundary}) {
    const Eigen::Vector2d from = check.place[static_cast<std::size_t>(T.tail(h))], to = check.place[static_cast<std::size_t>(T.head(h))];
    const Index v = T.split_edge(h, 0.4);
    REQUIRE(v != ice::kInvalid);
    check.place.push_back(from + 0.4 * (to - from));
    CHECK(T.angle_sum(v) == Approx(h == boundary ? kPi : 2 * kPi).epsilon(1e-12));
    CHECK(T.is_boundary_vertex(v) == (h == boundary));
  }
  CHECK(T.validate() == "");
  CHECK(check.worst(T) < 1e-12);
  CHECK(T.total_curvature() == Approx(curvature).margin(1e-9));  // inserted vertices are flat
  // The exported mesh lists inserted vertices last, without an input vertex.
  const ice::CompactMesh C = T.compact();
  CHECK(C.num_vertices() == T.num_vertices());
  for (Index c = 0; c < C.num_vertices(); ++c)
    CHECK((C.to_input[static_cast<std::size_t>(c)] == ice::kInvalid) == (c >= C.num_vertices() - 7));
  // A refined triangulation is not coarsened in place.
  CHECK_THROWS_AS(ice::coarsen(T, ice::CoarsenOptions{}), std::invalid_argument);
}

TEST_CASE("refinement of a flat disk's coarse mesh: bound reached, points and inserted vertices exact", "[refinement]") {
  const ice::TriangleMesh disk = ice::make_flat_disk(12, 1.0, 0.3);
  ice::IntrinsicTriangulation T = coarsened_disk(disk, 60);
  ice::RefinementOptions options;
  options.max_vertex_ratio = 20;  // a disk with a coarse boundary needs many boundary midpoints
  const ice::RefinementResult r = ice::refine_delaunay(T, options);
  INFO("inserted " << r.inserted << " (" << r.boundary_splits << " on the boundary), angle " << r.min_angle_before
                   << " -> " << r.min_angle_after);
  CHECK(T.validate() == "");
  // Corners below the bound may remain only at sharp boundary vertices (Θ < 60°).
  CHECK(r.faces_below_bound == r.sharp_vertex_faces);
  CHECK(r.inserted > 0);
  // Every inserted vertex is located in an input face; on a flat mesh its point there is where the
  // intrinsic edge lengths put it: each edge's length is the distance of its ends' places.
  const std::vector<ice::InputSurfacePoint> located = ice::locate_inserted_vertices(T, disk.F);
  REQUIRE(static_cast<Index>(located.size()) == r.inserted);
  PlanarCheck check(disk);
  for (const ice::InputSurfacePoint& p : located) {
    REQUIRE(p.face >= 0);
    REQUIRE(p.face < disk.F.rows());
    CHECK(std::min({p.bary[0], p.bary[1], p.bary[2]}) >= 0);
    CHECK(p.bary[0] + p.bary[1] + p.bary[2] == Approx(1).epsilon(1e-12));
    Eigen::Vector2d where = Eigen::Vector2d::Zero();
    for (int k = 0; k < 3; ++k) where += p.bary[static_cast<std::size_t>(k)] * check.place[static_cast<std::size_t>(disk.F(p.face, k))];
    check.place.push_back(where);
  }
  CHECK(check.worst(T) < 1e-9);
}

TEST_CASE("refinement of a coarse spot to 25 degrees", "[refinement]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.keep_method_state = true;
  const ice::CoarseSpace plain = ice::build_coarse_space(mesh, options);
  options.refinement = ice::RefinementOptions{};
  const ice::CoarseSpace refined = ice::build_coarse_space(mesh, options);
  REQUIRE(refined.summary.refinement);
  const ice::RefinementResult& r = *refined.summary.refinement;
  const ice::IntrinsicTriangulation& T = *refined.triangulation;
  CHECK(T.validate() == "");
  CHECK(r.bound_reached);
  CHECK(r.min_angle_after >= 25 - 1e-9);
  CHECK(r.min_angle_before < 25);
  for (Index f = 0; f < T.num_face_slots(); ++f)
    if (T.face_alive(f))
      for (double a : face_corner_angles(T, f)) CHECK(a >= 25 * kPi / 180 - 1e-9);
  for (Index h = 0; h < T.num_halfedge_slots(); ++h)
    if (T.halfedge_alive(h)) CHECK(T.is_delaunay(h, 1e-9));
  CHECK(T.total_curvature() == Approx(2 * kPi * T.euler_characteristic()).margin(1e-8));
  // The budget: at most 1.5x the coarse vertices.
  const Index before = plain.mesh.num_vertices(), after = refined.mesh.num_vertices();
  CHECK(after == before + r.inserted);
  CHECK(after <= 1.5 * before);
  // The coarse mesh: lengths satisfy the triangle inequality; inserted vertices last.
  for (Eigen::Index f = 0; f < refined.mesh.F.rows(); ++f) {
    const double a = refined.mesh.L(f, 0), b = refined.mesh.L(f, 1), c = refined.mesh.L(f, 2);
    CHECK((a < b + c && b < a + c && c < a + b));
  }
  for (Index c = 0; c < after; ++c)
    CHECK((refined.mesh.to_input[static_cast<std::size_t>(c)] == ice::kInvalid) == (c >= before));
  // P: rows of barycentric coordinates (non-negative, summing to 1), one column per coarse vertex.
  REQUIRE(refined.P.rows() == mesh.V.rows());
  REQUIRE(refined.P.cols() == after);
  const Eigen::VectorXd row_sums = refined.P * Eigen::VectorXd::Ones(after);
  CHECK((row_sums.array() - 1).abs().maxCoeff() < 1e-12);
  for (Eigen::Index k = 0; k < refined.P.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(refined.P, k); it; ++it) CHECK(it.value() >= 0);
  // The map agrees with P.
  const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(refined);
  for (Index i = 0; i < mesh.V.rows(); i += 37) {
    const ice::CoarsePoint& p = map[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k)
      if (p.bary[static_cast<std::size_t>(k)] > 0.5) CHECK(refined.P.coeff(i, refined.mesh.F(p.face, k)) >= p.bary[static_cast<std::size_t>(k)] - 1e-12);
  }
  // Inserted vertices: in input faces with valid coordinates, and their 3D points about where the
  // intrinsic lengths put them. (Not exactly: ICE's flattening makes the coarse lengths differ from
  // distances on the input; a point in a wrong face would be off by a whole coarse edge.)
  REQUIRE(static_cast<Index>(refined.inserted.size()) == r.inserted);
  const ice::Positions positions = ice::coarse_vertex_positions(mesh, refined);
  for (const ice::InputSurfacePoint& p : refined.inserted) {
    REQUIRE(p.face >= 0);
    REQUIRE(p.face < mesh.F.rows());
    CHECK(std::min({p.bary[0], p.bary[1], p.bary[2]}) >= 0);
    CHECK(p.bary[0] + p.bary[1] + p.bary[2] == Approx(1).epsilon(1e-12));
  }
  std::vector<double> ratios;
  for (Eigen::Index f = 0; f < refined.mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Index a = refined.mesh.F(f, k), b = refined.mesh.F(f, (k + 1) % 3);
      if (a < before && b < before) continue;
      ratios.push_back((positions.row(a) - positions.row(b)).norm() / refined.mesh.L(f, k));
    }
  std::sort(ratios.begin(), ratios.end());
  INFO("chord / length at inserted vertices: " << ratios.front() << " .. " << ratios.back() << ", median " << ratios[ratios.size() / 2]);
  CHECK(ratios.front() > 0.5);
  CHECK(ratios.back() < 1.5);
  CHECK(std::abs(ratios[ratios.size() / 2] - 1) < 0.1);
}

TEST_CASE("refinement with boundaries: budget, invariants, file round trip", "[refinement]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("elephant-with-holes.off"));
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.keep_method_state = true;
  options.refinement = ice::RefinementOptions{};
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const ice::RefinementResult& r = *space.summary.refinement;
  CHECK(space.triangulation->validate() == "");
  CHECK(r.boundary_splits > 0);
  CHECK(r.min_angle_after > r.min_angle_before);
  const Index coarse = space.mesh.num_vertices();
  CHECK(coarse <= 1.5 * (coarse - r.inserted) + 1);
  CHECK((r.bound_reached || r.budget_exhausted || r.faces_below_bound == r.sharp_vertex_faces + r.tiny_faces));
  // The .ilm file keeps inserted vertices (v -1) and reads back exactly.
  const std::string path = (std::filesystem::temp_directory_path() / "ice_test_refined.ilm").string();
  ice::write_intrinsic_mesh(path, space.mesh, static_cast<Index>(mesh.V.rows()));
  const ice::IntrinsicMeshFile file = ice::read_intrinsic_mesh(path);
  std::filesystem::remove(path);
  CHECK(file.to_input == space.mesh.to_input);
  CHECK(file.F == space.mesh.F);
  CHECK(file.L == space.mesh.L);
  CHECK(file.twin == space.mesh.twin);
  CHECK(ice::triangulation_of(file, path).validate() == "");
}

TEST_CASE("refinement refuses bad options and QEM", "[refinement]") {
  ice::IntrinsicTriangulation T = coarsened_disk(ice::make_flat_disk(4), 10);
  ice::RefinementOptions options;
  options.min_angle_degrees = 0;
  CHECK_THROWS_AS(ice::refine_delaunay(T, options), std::invalid_argument);
  options.min_angle_degrees = 31;
  CHECK_THROWS_AS(ice::refine_delaunay(T, options), std::invalid_argument);
  options.min_angle_degrees = 25;
  options.max_vertex_ratio = 0.5;
  CHECK_THROWS_AS(ice::refine_delaunay(T, options), std::invalid_argument);
  ice::CoarseSpaceOptions space_options;
  space_options.method = ice::CoarseningMethod::qem;
  space_options.coarsen.target_ratio = 0.5;
  space_options.refinement = ice::RefinementOptions{};
  CHECK_THROWS_AS(ice::build_coarse_space(ice::make_icosphere(2), space_options), std::invalid_argument);
}

TEST_CASE("Galerkin operators of a refined coarse space stay positive definite", "[refinement][fem]") {
  // lion-head at 5 % refined to 25°: some inserted vertices have few or no fine vertices in their
  // faces (dependent or empty columns of P), which made PᵀAP singular before fem::galerkin
  // stabilised them.
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("lion-head.off"));
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.refinement = ice::RefinementOptions{};
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  const fem::SparseMatrix L = fem::cotan_laplacian(fine);
  const fem::SparseMatrix M = fem::mass_matrix(fine, fem::MassKind::lumped);
  Index weak = 0;
  for (Eigen::Index c = 0; c < space.P.cols(); ++c) weak += space.P.col(c).sum() < 1 ? 1 : 0;
  INFO(weak << " of " << space.P.cols() << " coarse columns weigh less than one fine vertex");
  CHECK(weak > 0);
  const fem::SparseMatrix A = fem::galerkin(space.P, fem::SparseMatrix(L + M));
  CHECK_NOTHROW(fem::CholeskySolver(A));
  // Where P is full (no refinement), galerkin() is the plain product.
  ice::CoarseSpaceOptions plain = options;
  plain.refinement.reset();
  const ice::CoarseSpace unrefined = ice::build_coarse_space(mesh, plain);
  const fem::SparseMatrix product = unrefined.P.transpose() * fem::SparseMatrix(L * unrefined.P);
  CHECK((Eigen::MatrixXd(fem::galerkin(unrefined.P, L)) - Eigen::MatrixXd(product)).cwiseAbs().maxCoeff() < 1e-12);
}
