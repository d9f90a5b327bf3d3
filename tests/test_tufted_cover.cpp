// The tufted cover (ice/tufted_cover.h): a closed, oriented Δ-complex for any triangle mesh, whose
// Laplacian summed over each vertex's copies is twice the mesh's own on a manifold and the robust
// Laplacian elsewhere; coarse spaces of it on the input's vertices.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <stdexcept>
#include <vector>

#include <Eigen/Eigenvalues>

#include "fem/cholesky.h"
#include "fem/curvature_correction.h"
#include "fem/distance_oracle.h"
#include "fem/multigrid.h"
#include "fem/operators.h"
#include "fem/problems.h"
#include "fem/topology.h"
#include "ice/coarse_space.h"
#include "ice/hierarchy.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/mesh_validation.h"
#include "ice/proxy/geodesics.h"
#include "ice/proxy/poisson.h"
#include "ice/proxy/vectors.h"
#include "ice/tufted_cover.h"
#include "test_support.h"

namespace {

using ice::Index;

// The gluing is a fixed-point-free involution of the closed cover's 6m sides, joining sides with the
// same ends (as input vertices and as copies) in opposite directions and of equal length; the cover
// makes a valid triangulation; every input vertex has a copy, copies sit at its position.
void check_cover(const ice::TriangleMesh& mesh, const ice::TuftedCover& cover) {
  const Index m = static_cast<Index>(mesh.F.rows());
  REQUIRE(cover.mesh.F.rows() == 2 * m);
  REQUIRE(cover.twin.size() == static_cast<std::size_t>(6 * m));
  REQUIRE(cover.input_vertex_count == mesh.V.rows());
  REQUIRE(cover.to_input.size() == static_cast<std::size_t>(cover.mesh.V.rows()));
  const ice::Faces& C = cover.mesh.F;
  const auto from = [&](Index s) { return C(s / 3, s % 3); };
  const auto to = [&](Index s) { return C(s / 3, (s % 3 + 1) % 3); };
  for (Index s = 0; s < 6 * m; ++s) {
    const Index t = cover.twin[static_cast<std::size_t>(s)];
    REQUIRE(t >= 0);
    REQUIRE(t != s);
    REQUIRE(cover.twin[static_cast<std::size_t>(t)] == s);
    REQUIRE(from(s) == to(t));
    REQUIRE(to(s) == from(t));
  }
  for (Index f = 0; f < m; ++f)
    for (int k = 0; k < 3; ++k) {
      REQUIRE(cover.to_input[static_cast<std::size_t>(C(f, k))] == mesh.F(f, k));
      REQUIRE(cover.to_input[static_cast<std::size_t>(C(m + f, k))] == mesh.F(f, k == 0 ? 0 : 3 - k));
    }
  std::vector<char> has_copy(static_cast<std::size_t>(mesh.V.rows()), 0);
  for (std::size_t c = 0; c < cover.to_input.size(); ++c) {
    has_copy[static_cast<std::size_t>(cover.to_input[c])] = 1;
    REQUIRE(cover.mesh.V.row(static_cast<Eigen::Index>(c)) == mesh.V.row(cover.to_input[c]));
    if (c > 0) REQUIRE(cover.to_input[c - 1] <= cover.to_input[c]);  // copies consecutive, input order
  }
  for (char c : has_copy) REQUIRE(c == 1);
  const ice::IntrinsicMesh intrinsic = cover.intrinsic_mesh();
  const ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_glued_faces(intrinsic.F, intrinsic.L, intrinsic.twin);
  REQUIRE(T.validate().empty());
  // Gauss–Bonnet on the closed cover: its angle defects sum to 2π χ.
  const long chi = static_cast<long>(cover.mesh.V.rows()) - 3L * m + 2L * m;
  REQUIRE(fem::angle_defects(intrinsic).sum() == Approx(2 * ice::kPi * static_cast<double>(chi)).margin(1e-9));
}

// Symmetric, positive semidefinite, with one zero eigenvalue per connected component of the input.
void check_robust_laplacian(const ice::TriangleMesh& mesh, const fem::SparseMatrix& L) {
  const Eigen::MatrixXd A(L);
  REQUIRE((A - A.transpose()).norm() <= 1e-12 * A.norm());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(A);
  const Eigen::VectorXd values = eigen.eigenvalues();
  const double scale = values.cwiseAbs().maxCoeff();
  REQUIRE(values.minCoeff() >= -1e-10 * scale);
  const Index components = fem::vertex_components(mesh.F, static_cast<Index>(mesh.V.rows())).count();
  Index zeros = 0;
  for (Eigen::Index i = 0; i < values.size(); ++i) zeros += values(i) <= 1e-10 * scale ? 1 : 0;
  REQUIRE(zeros == components);
}

// A Möbius strip of `segments` quads (non-orientable, one boundary loop).
ice::TriangleMesh moebius_strip(int segments) {
  ice::TriangleMesh mesh;
  mesh.V.resize(2 * segments, 3);
  for (int i = 0; i < segments; ++i) {
    const double u = 2 * ice::kPi * i / segments;
    for (int side = 0; side < 2; ++side) {
      const double v = side == 0 ? 0.4 : -0.4;
      mesh.V.row(2 * i + side) << (1 + v * std::cos(u / 2)) * std::cos(u), (1 + v * std::cos(u / 2)) * std::sin(u), v * std::sin(u / 2);
    }
  }
  mesh.F.resize(2 * segments, 3);
  for (int i = 0; i < segments; ++i) {
    const int top = 2 * i, bottom = 2 * i + 1;
    const bool last = i + 1 == segments;  // the strip closes with a half twist: top meets bottom
    const int next_top = last ? 1 : 2 * (i + 1), next_bottom = last ? 0 : 2 * (i + 1) + 1;
    mesh.F.row(2 * i) << top, bottom, next_bottom;
    mesh.F.row(2 * i + 1) << top, next_bottom, next_top;
  }
  return mesh;
}

// Two tetrahedra sharing the edge 0–1 (closed surfaces touching along an edge): around that edge the
// outside is glued twice, so two copies of 0 and 1 are joined by two edges.
ice::TriangleMesh tetrahedra_sharing_an_edge() {
  ice::TriangleMesh mesh;
  mesh.V.resize(6, 3);
  mesh.V << 0, 0, 0, 0, 0, 1, 1, 0, 0.5, 0.5, 1, 0.5, -1, 0, 0.5, -0.5, -1, 0.5;
  mesh.F.resize(8, 3);
  // Tetrahedron (0, 1, 2, 3) and (0, 1, 4, 5), each oriented outwards.
  mesh.F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3,  //
      0, 4, 1, 0, 1, 5, 0, 5, 4, 1, 4, 5;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {  // outward: positive volume with the tetrahedron's centroid
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const Eigen::Vector3d centroid = f < 4 ? (mesh.V.row(0) + mesh.V.row(1) + mesh.V.row(2) + mesh.V.row(3)).transpose() / 4
                                           : (mesh.V.row(0) + mesh.V.row(1) + mesh.V.row(4) + mesh.V.row(5)).transpose() / 4;
    if ((b - a).cross(c - a).dot(a - centroid) < 0) std::swap(mesh.F(f, 1), mesh.F(f, 2));
  }
  return mesh;
}

// A square sheet (n × n quads) with a fin standing on its middle row, down and up: the n edges along
// that row have four faces each (non-manifold edges). n even.
ice::TriangleMesh sheet_with_fin(int n) {
  const int row = n / 2, side = n + 1;
  std::vector<Eigen::RowVector3d> points;
  std::vector<Index> sheet(static_cast<std::size_t>(side * side)), fin(static_cast<std::size_t>(side * side));
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      sheet[static_cast<std::size_t>(i * side + j)] = static_cast<Index>(points.size());
      points.emplace_back(double(i) / n, double(j - row) / n, 0.0);
    }
  for (int i = 0; i <= n; ++i)
    for (int k = 0; k <= n; ++k) {
      if (k == row) {
        fin[static_cast<std::size_t>(i * side + k)] = sheet[static_cast<std::size_t>(i * side + row)];
        continue;
      }
      fin[static_cast<std::size_t>(i * side + k)] = static_cast<Index>(points.size());
      points.emplace_back(double(i) / n, 0.0, double(k - row) / n);
    }
  ice::TriangleMesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t p = 0; p < points.size(); ++p) mesh.V.row(static_cast<Eigen::Index>(p)) = points[p];
  mesh.F.resize(4 * n * n, 3);
  Eigen::Index f = 0;
  for (const std::vector<Index>* grid : {&sheet, &fin})
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const auto at = [&](int a, int b) { return (*grid)[static_cast<std::size_t>(a * side + b)]; };
        mesh.F.row(f++) << at(i, j), at(i + 1, j), at(i + 1, j + 1);
        mesh.F.row(f++) << at(i, j), at(i + 1, j + 1), at(i, j + 1);
      }
  return mesh;
}

ice::TriangleMesh load_keeping_sheets(const std::string& name, bool repair = true) {
  ice::LoadOptions options;
  options.repair = repair;
  options.keep_nonmanifold = true;
  return ice::load_mesh(ice_test::project_mesh(name), options);
}

/// Two unit icospheres (subdivided 3 times) sharing one vertex, the first's top `top` and the
/// second's bottom: a non-manifold vertex, where the cover's separate sheets meet at the vertex alone.
/// `bottom` is the first's bottom, `far_top` the second's top, `n` one sphere's vertex count.
struct TouchingSpheres {
  ice::TriangleMesh mesh;
  Index n = 0, top = 0, bottom = 0, far_top = 0;
};
TouchingSpheres touching_spheres() {
  const ice::TriangleMesh sphere = ice::make_icosphere(3);
  TouchingSpheres result;
  const Index n = result.n = sphere.V.rows();
  Index top = 0, bottom = 0;
  for (Index v = 0; v < n; ++v) {
    if (sphere.V(v, 2) > sphere.V(top, 2)) top = v;
    if (sphere.V(v, 2) < sphere.V(bottom, 2)) bottom = v;
  }
  ice::TriangleMesh& mesh = result.mesh;
  mesh.V.resize(2 * n - 1, 3);
  mesh.V.topRows(n) = sphere.V;
  std::vector<Index> second(static_cast<std::size_t>(n));
  for (Index v = 0, next = n; v < n; ++v) {
    second[static_cast<std::size_t>(v)] = v == bottom ? top : next;
    if (v != bottom) mesh.V.row(next++) = sphere.V.row(v) + Eigen::RowVector3d(0, 0, sphere.V(top, 2) - sphere.V(bottom, 2));
  }
  mesh.F.resize(2 * sphere.F.rows(), 3);
  mesh.F.topRows(sphere.F.rows()) = sphere.F;
  for (Eigen::Index f = 0; f < sphere.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) mesh.F(sphere.F.rows() + f, k) = second[static_cast<std::size_t>(sphere.F(f, k))];
  result.top = top;
  result.bottom = bottom;
  result.far_top = second[static_cast<std::size_t>(top)];
  return result;
}

}  // namespace

TEST_CASE("tufted cover of a manifold: two sheets, the Laplacian twice the mesh's to 1e-12", "[cover]") {
  for (const char* name : {"cat_head.obj", "eight.off"}) {  // an open disk, a closed genus-2 surface
    INFO(name);
    const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh(name));
    REQUIRE_FALSE(ice::needs_tufted_cover(mesh));
    const ice::TuftedCover cover = ice::tufted_cover(mesh);
    check_cover(mesh, cover);
    // A closed surface: an inside and an outside copy of every vertex; a disk: boundary vertices
    // have one copy (front and back meet there), interior ones two.
    const ice::ValidationReport report = ice::validate_mesh(mesh);
    std::vector<int> copies(static_cast<std::size_t>(mesh.V.rows()), 0);
    for (Index v : cover.to_input) ++copies[static_cast<std::size_t>(v)];
    std::vector<char> on_boundary(static_cast<std::size_t>(mesh.V.rows()), 0);
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)  // a side without its reverse is a boundary side
      for (int k = 0; k < 3; ++k) {
        bool paired = false;
        for (Eigen::Index g = 0; g < mesh.F.rows() && !paired; ++g)
          for (int l = 0; l < 3; ++l)
            paired = paired || (mesh.F(g, l) == mesh.F(f, (k + 1) % 3) && mesh.F(g, (l + 1) % 3) == mesh.F(f, k));
        if (!paired) on_boundary[static_cast<std::size_t>(mesh.F(f, k))] = on_boundary[static_cast<std::size_t>(mesh.F(f, (k + 1) % 3))] = 1;
      }
    for (std::size_t v = 0; v < copies.size(); ++v) REQUIRE(copies[v] == (on_boundary[v] ? 1 : 2));
    REQUIRE((report.n_boundary_loops > 0) == (std::count(on_boundary.begin(), on_boundary.end(), 1) > 0));
    // On the input's own triangles: the cover's cotan Laplacian and mass, gathered on the input
    // vertices, are twice the mesh's.
    const ice::FineMesh fine = ice::fine_mesh(cover, ice::FineGeometry::input);
    const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh));
    REQUIRE(ice_test::relative_difference(fem::cotan_laplacian(fine), fem::SparseMatrix(2 * L)) <= 1e-12);
    const fem::SparseMatrix M = fem::mass_matrix(ice::intrinsic_mesh(mesh));
    REQUIRE(ice_test::relative_difference(fem::mass_matrix(fine), fem::SparseMatrix(2 * M)) <= 1e-12);
  }
}

TEST_CASE("tufted cover of non-manifold and non-orientable meshes: closed, and its Laplacian robust", "[cover]") {
  struct Case {
    const char* name;
    ice::TriangleMesh mesh;
  };
  std::vector<Case> cases;
  cases.push_back({"triple_vierbein.obj (20 non-manifold edges)", load_keeping_sheets("triple_vierbein.obj")});
  cases.push_back({"hourglass_ico.obj (a non-manifold vertex)", load_keeping_sheets("hourglass_ico.obj", false)});  // (repair splits it)
  cases.push_back({"Moebius strip", moebius_strip(16)});
  cases.push_back({"two tetrahedra sharing an edge", tetrahedra_sharing_an_edge()});
  for (const Case& c : cases) {
    INFO(c.name);
    const ice::TriangleMesh& mesh = c.mesh;
    REQUIRE(ice::needs_tufted_cover(mesh));
    const ice::TuftedCover cover = ice::tufted_cover(mesh);
    check_cover(mesh, cover);
    // The intrinsic Delaunay Laplacian of the cover on the input's vertices (the robust Laplacian):
    // symmetric, positive semidefinite, its kernel the constants of each component; every edge's
    // cotan weight non-negative (Delaunay); P·1 = 1 for a coarse space of the cover.
    const ice::FineMesh fine = ice::fine_mesh(cover, ice::FineGeometry::intrinsic_delaunay);
    REQUIRE(fine.vertex_count == mesh.V.rows());
    const fem::SparseMatrix L = fem::cotan_laplacian(fine);
    check_robust_laplacian(mesh, L);
    for (int k = 0; k < L.outerSize(); ++k)
      for (fem::SparseMatrix::InnerIterator it(L, k); it; ++it)
        if (it.row() != it.col()) REQUIRE(it.value() <= 1e-12 * L.diagonal().cwiseAbs().maxCoeff());
    ice::CoarseSpaceOptions options;
    options.coarsen.target_ratio = 0.5;
    options.keep_method_state = true;
    ice::FineMesh shared;
    const ice::CoarseSpace space = ice::build_coarse_space(cover, options, &shared);
    REQUIRE(shared.F == fine.F);  // the fine mesh handed out is fine_mesh()'s
    REQUIRE(shared.L == fine.L);
    REQUIRE(space.P.rows() == mesh.V.rows());
    REQUIRE(space.P.cols() == space.mesh.num_vertices());
    const Eigen::VectorXd row_sums = space.P * Eigen::VectorXd::Ones(space.P.cols());
    REQUIRE((row_sums.array() - 1).abs().maxCoeff() <= 1e-12);
    REQUIRE(space.P.coeffs().minCoeff() >= 0);
    REQUIRE(space.summary.input_vertices == mesh.V.rows());
    // The coarse mesh: the cover's coarse triangulation (valid) with copies merged (names only).
    const ice::IntrinsicTriangulation& kept = *space.triangulation;
    REQUIRE(kept.validate().empty());
    REQUIRE(space.mesh.F.rows() == kept.num_faces());
    for (std::size_t s = 0; s < space.mesh.twin.size(); ++s) {
      const Index t = space.mesh.twin[s];
      REQUIRE(t >= 0);
      REQUIRE(space.mesh.twin[static_cast<std::size_t>(t)] == static_cast<Index>(s));
      const auto corner = [&](Index side, int k) { return space.mesh.F(side / 3, (side % 3 + k) % 3); };
      REQUIRE(corner(static_cast<Index>(s), 0) == corner(t, 1));
      REQUIRE(corner(static_cast<Index>(s), 1) == corner(t, 0));
      REQUIRE(space.mesh.L(static_cast<Eigen::Index>(s / 3), static_cast<Eigen::Index>(s % 3)) ==
              Approx(space.mesh.L(static_cast<Eigen::Index>(t / 3), static_cast<Eigen::Index>(t % 3))).epsilon(1e-12));
    }
    for (std::size_t c = 0; c < space.mesh.to_input.size(); ++c) {
      const Index v = space.mesh.to_input[c];
      REQUIRE(v >= 0);
      REQUIRE(v < mesh.V.rows());
    }
    for (Eigen::Index v = 0; v < mesh.V.rows(); ++v)
      if (space.mesh.from_input[static_cast<std::size_t>(v)] != ice::kInvalid)
        REQUIRE(space.mesh.to_input[static_cast<std::size_t>(space.mesh.from_input[static_cast<std::size_t>(v)])] == v);
  }
}

TEST_CASE("tufted cover: two closed surfaces sharing an edge give the outside two edges between one pair", "[cover]") {
  const ice::TriangleMesh mesh = tetrahedra_sharing_an_edge();
  const ice::TuftedCover cover = ice::tufted_cover(mesh);
  // 0 and 1: inside the first, inside the second, outside both; the others: inside and outside.
  std::vector<int> copies(6, 0);
  for (Index v : cover.to_input) ++copies[static_cast<std::size_t>(v)];
  REQUIRE(copies == std::vector<int>{3, 3, 2, 2, 2, 2});
  // Vertex pairs cannot glue it: glue_by_vertex_pairs refuses (the outside's two 0–1 edges).
  REQUIRE_THROWS_AS(ice::glue_by_vertex_pairs(cover.mesh.F), std::invalid_argument);
}

TEST_CASE("tufted cover: bad input is refused, the loader keeps sheets only when asked", "[cover]") {
  ice::TriangleMesh mesh = moebius_strip(8);
  mesh.F(0, 1) = mesh.F(0, 0);
  REQUIRE_THROWS_WITH(ice::tufted_cover(mesh), Catch::Contains("face 0 repeats a vertex"));
  mesh.F(0, 1) = 99;
  REQUIRE_THROWS_WITH(ice::tufted_cover(mesh), Catch::Contains("out of range"));
  REQUIRE_THROWS_WITH(ice::load_mesh(ice_test::project_mesh("triple_vierbein.obj"), ice::LoadOptions{true, false, false}),
                      Catch::Contains("--nonmanifold tufted"));
  const ice::TriangleMesh kept = load_keeping_sheets("triple_vierbein.obj");
  REQUIRE(kept.F.rows() > 0);
  ice::CoarseSpaceOptions qem;
  qem.method = ice::CoarseningMethod::qem;
  REQUIRE_THROWS_WITH(ice::build_coarse_space(ice::tufted_cover(kept), qem), Catch::Contains("ICE only"));
  // A cover damaged by hand is refused, naming the defect, before anything indexes through it.
  const ice::TuftedCover cover = ice::tufted_cover(kept);
  ice::TuftedCover damaged = cover;
  damaged.twin[5] = damaged.twin[6];
  REQUIRE_THROWS_WITH(ice::build_hierarchy(damaged), Catch::Contains("side 5 is not glued"));
  damaged = cover;
  damaged.twin.pop_back();
  REQUIRE_THROWS_WITH(ice::build_coarse_space(damaged, ice::CoarseSpaceOptions{}), Catch::Contains("3 sides per face"));
  damaged = cover;
  damaged.to_input[0] = cover.input_vertex_count;
  REQUIRE_THROWS_WITH(ice::build_hierarchy(damaged), Catch::Contains("out of range"));
  damaged = cover;
  damaged.input_vertex_count += 1;
  REQUIRE_THROWS_WITH(ice::build_hierarchy(damaged), Catch::Contains("has no copy"));
}

TEST_CASE("tufted cover through the recipes: a manifold mesh to the same bits, a non-manifold one near its fine solve", "[cover][proxy]") {
  // An oriented manifold is coarsened as it is with or without the option: the same arrays.
  const ice::TriangleMesh spot = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  ice::CoarseSpaceOptions options = ice::proxy::default_coarsening(ice::ProxyUse::poisson_heat);
  const ice::CoarseSpace plain = ice::build_coarse_space(spot, options);
  options.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  const ice::CoarseSpace covered = ice::build_coarse_space(spot, options);
  REQUIRE(covered.mesh.F == plain.mesh.F);
  REQUIRE(covered.mesh.L == plain.mesh.L);
  REQUIRE(covered.mesh.twin == plain.mesh.twin);
  REQUIRE(ice_test::relative_difference(covered.P, plain.P) == 0.0);
  REQUIRE(ice::fine_mesh(spot, ice::FineGeometry::intrinsic_delaunay, ice::NonmanifoldInput::tufted_cover).L ==
          ice::fine_mesh(spot, ice::FineGeometry::intrinsic_delaunay).L);

  // A non-manifold mesh: refused without the option, solved on its cover with it, the proxy's
  // solution near the fine robust Laplacian's (zero-mean and Dirichlet).
  const ice::TriangleMesh mesh = load_keeping_sheets("triple_vierbein.obj");
  REQUIRE_THROWS_AS(ice::proxy::PoissonSolver(mesh), std::invalid_argument);
  ice::proxy::PoissonOptions poisson;
  poisson.coarsening.coarsen.target_ratio = 0.5;
  poisson.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  Eigen::VectorXd f(mesh.V.rows());
  for (Eigen::Index i = 0; i < f.size(); ++i) f(i) = std::sin(3 * mesh.V(i, 0)) + mesh.V(i, 1) * mesh.V(i, 2);
  for (const bool dirichlet : {false, true}) {
    INFO((dirichlet ? "Dirichlet" : "zero-mean"));
    poisson.fixed_vertices = dirichlet ? std::vector<Index>{0, 40} : std::vector<Index>{};
    const ice::proxy::PoissonSolver solver(mesh, poisson);
    REQUIRE(solver.fine_mesh().vertex_count == mesh.V.rows());
    const Eigen::VectorXd u = solver.solve(f);
    const fem::SparseMatrix L = fem::cotan_laplacian(solver.fine_mesh());
    const fem::SparseMatrix M = fem::mass_matrix(solver.fine_mesh());
    const fem::PoissonSolver fine = dirichlet ? fem::PoissonSolver::dirichlet(L, M, poisson.fixed_vertices)
                                              : fem::PoissonSolver::zero_mean(L, M);
    const Eigen::VectorXd reference = fine.solve(f);
    const double error = std::sqrt((u - reference).dot(M * (u - reference)) / reference.dot(M * reference));
    INFO("relative L2 error " << error);
    REQUIRE(error < 0.1);
    if (dirichlet) REQUIRE(u(40) == 0.0);
  }
}

TEST_CASE("tufted cover: geodesics by the heat method near the fine heat method on the cover, and by marching",
          "[cover][proxy][geodesic]") {
  const ice::TriangleMesh mesh = load_keeping_sheets("triple_vierbein.obj");
  ice::proxy::GeodesicOptions options;
  options.coarsening.coarsen.target_ratio = 0.5;
  options.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  const ice::proxy::GeodesicSolver marching(mesh, options);
  const Eigen::VectorXd marched = marching.distance({0});
  REQUIRE(marched.allFinite());  // one piece: marching crosses the non-manifold edges to every sheet
  REQUIRE(marched(0) == Approx(0.0).margin(1e-12));
  // The marching follows the coarse mesh's gluing where sides repeat (sheets meeting along an edge):
  // paired by ends and lengths alone, the same mesh marches otherwise; a broken gluing is refused.
  ice::IntrinsicMesh glued = ice::with_lengths(marching.coarse_space().mesh, marching.lengths().lengths);
  const fem::SparseMatrix& P = marching.coarse_space().P;
  REQUIRE(fem::ProxyGeodesicSolver(glued, P, options.subdivisions).distance({0}) == marched);
  ice::IntrinsicMesh unglued = glued;
  unglued.twin.clear();
  CHECK_FALSE(fem::ProxyGeodesicSolver(unglued, P, options.subdivisions).distance({0}) == marched);
  std::swap(glued.twin[static_cast<std::size_t>(glued.twin[0])], glued.twin[static_cast<std::size_t>(glued.twin[3])]);
  REQUIRE_THROWS_WITH(fem::ProxyGeodesicSolver(glued, P, options.subdivisions), Catch::Contains("gluing"));
  options.method = fem::CoarseDistanceMethod::heat_method;
  const ice::proxy::GeodesicSolver solver(mesh, options);
  const ice::IntrinsicMesh& fine = solver.proxy()->fine_mesh();
  const fem::HeatGeodesicSolver fine_solver(fem::heat_method_operators(fine, fem::MassKind::lumped, 1.0));
  const fem::SparseMatrix& M = fine_solver.operators().mass;
  for (const Index source : {Index{0}, Index{40}}) {
    INFO("source " << source);
    const Eigen::VectorXd d = solver.distance({source});
    const Eigen::VectorXd reference = fine_solver.distance({source});
    const double error = std::sqrt((d - reference).dot(M * (d - reference)) / reference.dot(M * reference));
    INFO("relative L2 error against the fine heat method " << error);
    REQUIRE(d.allFinite());
    REQUIRE(d(source) == Approx(0.0).margin(1e-12));
    REQUIRE(error < 0.1);
  }
  // A manifold mesh: the option changes nothing, marching included.
  const ice::TriangleMesh spot = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  ice::proxy::GeodesicOptions manifold;
  const Eigen::VectorXd plain = ice::proxy::geodesic_distance(spot, {0}, manifold);
  manifold.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  REQUIRE(ice::proxy::geodesic_distance(spot, {0}, manifold) == plain);
}

TEST_CASE("tufted cover: a multigrid hierarchy on the input's vertices solves the robust Laplacian", "[cover][multigrid]") {
  // An oriented manifold gets the same hierarchy with or without the option.
  const ice::TriangleMesh spot = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  ice::HierarchyOptions options;
  const ice::Hierarchy plain = ice::build_hierarchy(spot, options);
  options.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  const ice::Hierarchy same = ice::build_hierarchy(spot, options);
  REQUIRE(same.num_levels() == plain.num_levels());
  for (std::size_t k = 0; k < plain.prolongations.size(); ++k)
    REQUIRE(ice_test::relative_difference(same.prolongations[k], plain.prolongations[k]) == 0.0);
  REQUIRE(same.fine_order == plain.fine_order);

  struct Case {
    const char* name;
    ice::TriangleMesh mesh;
    int min_levels;
  };
  std::vector<Case> cases;
  cases.push_back({"a sheet with a fin (40 non-manifold edges)", sheet_with_fin(40), 4});
  cases.push_back({"triple_vierbein.obj", load_keeping_sheets("triple_vierbein.obj"), 2});
  cases.push_back({"a Moebius strip (non-orientable)", moebius_strip(40), 2});
  for (const Case& c : cases) {
    INFO(c.name);
    const ice::TriangleMesh& mesh = c.mesh;
    const Index n = static_cast<Index>(mesh.V.rows());
    REQUIRE_THROWS_AS(ice::build_hierarchy(mesh, ice::HierarchyOptions{}), std::invalid_argument);
    options.coarsest_vertices = 12;
    const Index locked = n / 3;
    options.locked_vertices = {locked};
    const ice::Hierarchy H = ice::build_hierarchy(mesh, options);
    INFO("levels " << H.num_levels() << ", stopped: " << H.stop_reason);
    REQUIRE(H.num_levels() >= c.min_levels);
    REQUIRE(H.levels[0].vertex_count == n);
    for (int k = 0; k < H.num_levels(); ++k) {
      // Each level's unknowns are distinct input vertices, the locked one among them.
      const ice::HierarchyLevel& level = H.levels[static_cast<std::size_t>(k)];
      REQUIRE(level.to_fine.size() == static_cast<std::size_t>(level.vertex_count));
      std::vector<Index> sorted = level.to_fine;
      std::sort(sorted.begin(), sorted.end());
      REQUIRE(std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end());
      REQUIRE((sorted.front() >= 0 && sorted.back() < n));
      REQUIRE(std::binary_search(sorted.begin(), sorted.end(), locked));
      if (k + 1 == H.num_levels()) break;
      // P_k: level k × level k+1, non-negative, rows summing to 1 (constants are kept).
      const Eigen::SparseMatrix<double>& P = H.prolongations[static_cast<std::size_t>(k)];
      REQUIRE(P.rows() == level.vertex_count);
      REQUIRE(P.cols() == H.levels[static_cast<std::size_t>(k) + 1].vertex_count);
      REQUIRE(P.cols() < P.rows());
      const Eigen::VectorXd row_sums = P * Eigen::VectorXd::Ones(P.cols());
      REQUIRE((row_sums.array() - 1).abs().maxCoeff() < 1e-12);
      REQUIRE(P.coeffs().minCoeff() >= 0);
    }
    std::vector<Index> order = H.fine_order, identity(static_cast<std::size_t>(n));
    std::sort(order.begin(), order.end());
    std::iota(identity.begin(), identity.end(), 0);
    REQUIRE(order == identity);

    // PCG with its V-cycles on L + εM of the cover's robust Laplacian reaches CHOLMOD's solution.
    const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay, ice::NonmanifoldInput::tufted_cover);
    const fem::SparseMatrix L = fem::cotan_laplacian(fine), M = fem::mass_matrix(fine);
    const fem::SparseMatrix A = L + 1e-3 * (L.diagonal().sum() / M.diagonal().sum()) * M;
    Eigen::VectorXd f(n);
    for (Index i = 0; i < n; ++i) f(i) = std::sin(3 * mesh.V(i, 0)) + mesh.V(i, 1) * mesh.V(i, 2) + (i % 7 == 0 ? 1.0 : 0.0);
    const Eigen::VectorXd b = M * f;
    const Eigen::VectorXd reference = fem::CholeskySolver(A).solve(b);
    fem::MultigridOptions multigrid;
    multigrid.tolerance = 1e-10;
    fem::MultigridSolver solver(H.prolongations, multigrid);
    solver.set_locality_order(H.fine_order);
    solver.setup(A);
    const Eigen::VectorXd x = solver.solve(b);
    const fem::MultigridReport& r = solver.report();
    INFO("iterations " << r.iterations << ", convergence factor " << r.convergence_factor);
    REQUIRE(r.converged);
    REQUIRE(r.convergence_factor < 0.3);
    REQUIRE(ice_test::relative_difference(x, reference) < 1e-7);
  }
}

TEST_CASE("tufted cover: a covered setup through the store and a file, loaded bit for bit with the cover's fine mesh",
          "[cover][store]") {
  const ice::TriangleMesh mesh = sheet_with_fin(16);
  const ice_test::TempDir dir;
  ice::proxy::ProxySetupOptions options;
  options.coarsening.coarsen.target_ratio = 0.2;
  options.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  options.fine_operators = true;
  options.store = ice::proxy::Store({dir.file("store"), ice::proxy::kDefaultStoreBytes});
  const ice::proxy::ProxySetup made = ice::proxy::build_proxy_setup(mesh, options);
  REQUIRE(made.cache.status == ice::proxy::CacheStatus::miss);
  REQUIRE(made.cache.save_error.empty());
  REQUIRE(made.coarse.summary.tufted_cover);
  const fem::SparseMatrix robust = fem::cotan_laplacian(
      ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay, ice::NonmanifoldInput::tufted_cover));
  const auto same_setup = [&](const ice::proxy::ProxySetup& loaded) {
    REQUIRE(loaded.coarse.summary.tufted_cover);
    REQUIRE(loaded.coarse.mesh.F == made.coarse.mesh.F);
    REQUIRE(loaded.coarse.mesh.L == made.coarse.mesh.L);
    REQUIRE(loaded.coarse.mesh.twin == made.coarse.mesh.twin);
    REQUIRE(loaded.coarse.mesh.to_input == made.coarse.mesh.to_input);
    REQUIRE(ice_test::relative_difference(loaded.coarse.P, made.coarse.P) == 0.0);
    REQUIRE(ice_test::relative_difference(loaded.proxy->coarse_laplacian(), made.proxy->coarse_laplacian()) == 0.0);
    // The restored proxy's fine operators are the cover's robust ones, made again from the mesh.
    REQUIRE(ice_test::relative_difference(loaded.proxy->fine_laplacian(), robust) == 0.0);
  };
  const ice::proxy::ProxySetup warm = ice::proxy::build_proxy_setup(mesh, options);
  REQUIRE(warm.cache.status == ice::proxy::CacheStatus::hit);
  same_setup(warm);
  // A file of the user's choosing.
  ice::proxy::save_proxy_setup_file(dir.file("fin.ice"), mesh, made);
  same_setup(ice::proxy::load_proxy_setup_file(dir.file("fin.ice"), mesh));
  // An oriented manifold keeps the key it has without the option.
  const ice::TriangleMesh spot = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  ice::CoarseSpaceOptions plain;
  ice::CoarseSpaceOptions covered = plain;
  covered.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  const auto key = [&](const ice::TriangleMesh& m, const ice::CoarseSpaceOptions& o) {
    return ice::proxy::proxy_setup_key(m, o, ice::FineGeometry::intrinsic_delaunay, fem::CoarseOperatorKind::galerkin,
                                       fem::ProlongationKind::barycentric).hex();
  };
  REQUIRE(key(spot, covered) == key(spot, plain));
  REQUIRE(key(mesh, covered) != key(mesh, plain));
}

TEST_CASE("tufted cover: mirror sheets are coarsened once, a vertex's coarse copies are one coarse vertex", "[cover][proxy]") {
  // Two icosahedra touching at a vertex: four closed sheets, two mirror pairs. Coarsening both of a
  // pair would give every coarse basis function twice (a singular Galerkin mass).
  const ice::TriangleMesh mesh = load_keeping_sheets("hourglass_ico.obj", false);
  const ice::TuftedCover cover = ice::tufted_cover(mesh);
  const ice::TuftedCover distinct = ice::distinct_sheets(cover);
  REQUIRE(distinct.mesh.F.rows() == mesh.F.rows());  // one sheet of each icosahedron
  const ice::IntrinsicMesh reduced = distinct.intrinsic_mesh();
  REQUIRE(ice::IntrinsicTriangulation::from_glued_faces(reduced.F, reduced.L, reduced.twin).validate().empty());
  ice::proxy::PoissonOptions poisson;
  poisson.coarsening.coarsen.target_ratio = 0.5;
  poisson.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  const ice::proxy::PoissonSolver solver(mesh, poisson);
  const Eigen::SparseMatrix<double> P = solver.coarse_space().P;
  const Eigen::MatrixXd mass = Eigen::MatrixXd(P.transpose() * fem::mass_matrix(solver.fine_mesh()) * P);
  REQUIRE(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(mass).eigenvalues().minCoeff() > 1e-8 * mass.diagonal().maxCoeff());
  Eigen::VectorXd f = mesh.V.col(2);
  const Eigen::VectorXd u = solver.solve(f);
  const fem::SparseMatrix L = fem::cotan_laplacian(solver.fine_mesh());
  const fem::SparseMatrix M = fem::mass_matrix(solver.fine_mesh());
  const Eigen::VectorXd reference = fem::PoissonSolver::zero_mean(L, M).solve(f);
  REQUIRE(std::sqrt((u - reference).dot(M * (u - reference)) / reference.dot(M * reference)) < 0.2);
  // Coarse vertices are input vertices: each at most once, P·1 = 1.
  const ice::CompactMesh& coarse = solver.coarse_space().mesh;
  REQUIRE(P.cols() == coarse.vertex_count);
  std::vector<int> seen(static_cast<std::size_t>(mesh.V.rows()), 0);
  for (Index c = 0; c < coarse.vertex_count; ++c) {
    const Index v = coarse.to_input[static_cast<std::size_t>(c)];
    REQUIRE(++seen[static_cast<std::size_t>(v)] == 1);
    REQUIRE(coarse.from_input[static_cast<std::size_t>(v)] == c);
  }
  REQUIRE((P * Eigen::VectorXd::Ones(P.cols()) - Eigen::VectorXd::Ones(P.rows())).cwiseAbs().maxCoeff() < 1e-12);
  // The vertex where the two touch has a copy on each sheet: locked, they are one coarse vertex, so a
  // Dirichlet value there holds exactly.
  Index shared_vertex = 0;
  std::vector<int> copies(static_cast<std::size_t>(mesh.V.rows()), 0);
  for (Index v : distinct.to_input)
    if (++copies[static_cast<std::size_t>(v)] > 1) shared_vertex = v;
  REQUIRE(copies[static_cast<std::size_t>(shared_vertex)] > 1);
  poisson.fixed_vertices = {shared_vertex};
  const ice::proxy::PoissonSolver pinned(mesh, poisson);
  Eigen::VectorXd value(1);
  value << 0.25;
  const Eigen::VectorXd v = pinned.solve(f, value);
  REQUIRE(v(shared_vertex) == Approx(0.25).margin(1e-12));
  const Eigen::VectorXd pinned_reference = fem::PoissonSolver::dirichlet(L, M, {shared_vertex}).solve(f, value);
  const double pinned_error =
      std::sqrt((v - pinned_reference).dot(M * (v - pinned_reference)) / pinned_reference.dot(M * pinned_reference));
  // As good as on each icosahedron alone (a manifold), pinned at the vertex where they touch.
  double worst_half = 0;
  // The halves: faces joined across edges (growing from face 0 until nothing is added).
  std::vector<int> part(static_cast<std::size_t>(mesh.F.rows()), 1);
  part[0] = 0;
  for (bool grown = true; grown;) {
    grown = false;
    for (Eigen::Index t = 0; t < mesh.F.rows(); ++t)
      for (Eigen::Index u = 0; u < mesh.F.rows(); ++u) {
        if (part[static_cast<std::size_t>(t)] != 0 || part[static_cast<std::size_t>(u)] == 0) continue;
        int common = 0;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) common += mesh.F(t, a) == mesh.F(u, b);
        if (common == 2) part[static_cast<std::size_t>(u)] = 0, grown = true;
      }
  }
  for (const int which : {0, 1}) {
    ice::TriangleMesh half;
    std::vector<Index> index(static_cast<std::size_t>(mesh.V.rows()), ice::kInvalid), faces;
    for (Eigen::Index t = 0; t < mesh.F.rows(); ++t)
      if (part[static_cast<std::size_t>(t)] == which) faces.push_back(static_cast<Index>(t));
    REQUIRE(faces.size() == 20);
    half.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
    std::vector<Index> vertices;
    for (std::size_t t = 0; t < faces.size(); ++t)
      for (int k = 0; k < 3; ++k) {
        Index& i = index[static_cast<std::size_t>(mesh.F(faces[t], k))];
        if (i == ice::kInvalid) {
          i = static_cast<Index>(vertices.size());
          vertices.push_back(mesh.F(faces[t], k));
        }
        half.F(static_cast<Eigen::Index>(t), k) = i;
      }
    half.V.resize(static_cast<Eigen::Index>(vertices.size()), 3);
    for (std::size_t i = 0; i < vertices.size(); ++i) half.V.row(static_cast<Eigen::Index>(i)) = mesh.V.row(vertices[i]);
    REQUIRE(!ice::needs_tufted_cover(half));
    ice::proxy::PoissonOptions manifold = poisson;
    manifold.coarsening.nonmanifold = ice::NonmanifoldInput::refuse;
    manifold.fixed_vertices = {index[static_cast<std::size_t>(shared_vertex)]};
    const ice::proxy::PoissonSolver alone(half, manifold);
    const Eigen::VectorXd g = half.V.col(2), w = alone.solve(g, value);
    const fem::SparseMatrix L1 = fem::cotan_laplacian(alone.fine_mesh()), M1 = fem::mass_matrix(alone.fine_mesh());
    const Eigen::VectorXd half_reference = fem::PoissonSolver::dirichlet(L1, M1, manifold.fixed_vertices).solve(g, value);
    worst_half = std::max(worst_half, std::sqrt((w - half_reference).dot(M1 * (w - half_reference)) /
                                                half_reference.dot(M1 * half_reference)));
  }
  INFO("pinned at the shared vertex " << pinned_error << ", the worse half alone " << worst_half);
  REQUIRE(pinned_error <= 1.5 * worst_half);
  poisson.fixed_vertices.clear();
  poisson.operators = fem::CoarseOperatorKind::intrinsic;
  REQUIRE_THROWS_WITH(ice::proxy::PoissonSolver(mesh, poisson), Catch::Contains("Galerkin"));
}

TEST_CASE("tufted cover: spheres touching at a vertex stay joined there on the coarse mesh, and marching crosses",
          "[cover][proxy][geodesic]") {
  const TouchingSpheres spheres = touching_spheres();
  const ice::TriangleMesh& mesh = spheres.mesh;
  const Index n = spheres.n, top = spheres.top, bottom = spheres.bottom;
  REQUIRE(ice::needs_tufted_cover(mesh));
  ice::CoarseSpaceOptions coarsening;
  coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  for (const double ratio : {0.01, 0.05, 0.25}) {
    INFO("ratio " << ratio);
    coarsening.coarsen.target_ratio = ratio;
    const ice::CoarseSpace space = ice::build_coarse_space(mesh, coarsening);
    // The junction is a coarse vertex, and the coarse mesh one piece as the input is.
    REQUIRE(space.mesh.from_input[static_cast<std::size_t>(top)] != ice::kInvalid);
    std::vector<std::vector<Index>> neighbours(static_cast<std::size_t>(space.mesh.vertex_count));
    for (Eigen::Index f = 0; f < space.mesh.F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        neighbours[static_cast<std::size_t>(space.mesh.F(f, k))].push_back(space.mesh.F(f, (k + 1) % 3));
    std::vector<char> reached(neighbours.size(), 0);
    std::vector<Index> stack{0};
    reached[0] = 1;
    Index count = 1;
    while (!stack.empty()) {
      const Index u = stack.back();
      stack.pop_back();
      for (Index w : neighbours[static_cast<std::size_t>(u)])
        if (!reached[static_cast<std::size_t>(w)]) reached[static_cast<std::size_t>(w)] = 1, ++count, stack.push_back(w);
    }
    REQUIRE(count == space.mesh.vertex_count);
  }
  coarsening.coarsen.target_ratio = 0.25;  // fine enough for distances within 5 %
  // Marching from the first sphere's bottom reaches the second sphere through the junction: there the
  // distance is about π (half a great circle) and at the second's top about 2π.
  ice::proxy::GeodesicOptions options;
  options.coarsening = coarsening;
  const Eigen::VectorXd d = ice::proxy::GeodesicSolver(mesh, options).distance({bottom});
  REQUIRE(d.allFinite());
  const Index far_top = spheres.far_top;
  CHECK(d(top) == Approx(M_PI).epsilon(0.05));
  CHECK(d(far_top) == Approx(2 * M_PI).epsilon(0.05));
  CHECK(d.tail(n - 1).minCoeff() >= d(top) - 1e-9);  // the second sphere lies past the junction
}

TEST_CASE("tufted cover: a map by one copy per vertex, the distance oracle across a junction, marching through the store",
          "[cover][proxy][geodesic][store]") {
  const TouchingSpheres spheres = touching_spheres();
  const ice::TriangleMesh& mesh = spheres.mesh;
  ice::CoarseSpaceOptions coarsening = ice::proxy::GeodesicOptions{}.coarsening;
  coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  coarsening.coarsen.target_ratio = 0.25;
  coarsening.keep_method_state = true;
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, coarsening);
  REQUIRE(space.summary.tufted_cover);
  // Every vertex's point: in a coarse face, its survivors at their coarse vertex, and weighing only
  // coarse vertices its row of P (the mean of its copies') weighs.
  const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(space);
  REQUIRE(map.size() == static_cast<std::size_t>(mesh.V.rows()));
  const Eigen::SparseMatrix<double, Eigen::RowMajor> rows = space.P;
  for (Index i = 0; i < mesh.V.rows(); ++i) {
    const ice::CoarsePoint& p = map[static_cast<std::size_t>(i)];
    INFO("vertex " << i);
    REQUIRE(p.face >= 0);
    REQUIRE(p.face < space.mesh.F.rows());
    REQUIRE(p.coarse_vertex == space.mesh.from_input[static_cast<std::size_t>(i)]);
    REQUIRE(p.bary[0] + p.bary[1] + p.bary[2] == Approx(1.0).margin(1e-12));
    for (int k = 0; k < 3; ++k) {
      const double b = p.bary[static_cast<std::size_t>(k)];
      REQUIRE(b >= -1e-12);
      if (b > 0) REQUIRE(rows.coeff(i, space.mesh.F(p.face, k)) > 0);
      if (p.coarse_vertex != ice::kInvalid && b == 1) REQUIRE(space.mesh.F(p.face, k) == p.coarse_vertex);
    }
    if (p.coarse_vertex != ice::kInvalid) REQUIRE(std::max({p.bary[0], p.bary[1], p.bary[2]}) == 1.0);
  }
  // The oracle crosses the junction as marching does: about π to it and 2π to the second sphere's top.
  ice::proxy::OracleOptions oracle_options;
  oracle_options.coarsening = coarsening;
  oracle_options.coarsening.keep_method_state = false;
  const ice_test::TempDir store;
  oracle_options.store.directory = store.file("");
  ice::proxy::CacheReport cache;
  const fem::DistanceOracle oracle = ice::proxy::distance_oracle(mesh, oracle_options, {}, nullptr, &cache);
  CHECK(cache.status == ice::proxy::CacheStatus::miss);
  CHECK(oracle.distance(spheres.bottom, spheres.top) == Approx(M_PI).epsilon(0.05));
  CHECK(oracle.distance(spheres.bottom, spheres.far_top) == Approx(2 * M_PI).epsilon(0.05));
  CHECK(oracle.distance(spheres.far_top, spheres.bottom) == oracle.distance(spheres.bottom, spheres.far_top));
  // Against coarse marching from a source on the same coarse mesh: the same distances within a few
  // per cent of their scale (the oracle interpolates between coarse vertices).
  ice::proxy::GeodesicOptions marching;
  marching.coarsening = oracle_options.coarsening;
  const Eigen::VectorXd from_bottom = ice::proxy::GeodesicSolver(mesh, marching).distance({spheres.bottom});
  double worst = 0;
  for (Index v = 0; v < mesh.V.rows(); ++v) worst = std::max(worst, std::abs(oracle.distance(spheres.bottom, v) - from_bottom(v)));
  CHECK(worst < 0.05 * from_bottom.maxCoeff());
  // A second oracle and marching through the store load the covered space and map, bit for bit.
  const fem::DistanceOracle warm = ice::proxy::distance_oracle(mesh, oracle_options, {}, nullptr, &cache);
  CHECK(cache.status == ice::proxy::CacheStatus::hit);
  const std::vector<std::array<Index, 2>> pairs{{spheres.bottom, spheres.far_top}, {5, 700}, {17, spheres.top}};
  CHECK(warm.distances(pairs) == oracle.distances(pairs));
  marching.store.directory = store.file("");
  const ice::proxy::GeodesicSolver stored(mesh, marching);
  CHECK(stored.cache().status == ice::proxy::CacheStatus::hit);
  CHECK(stored.distance({spheres.bottom}) == from_bottom);
  // A saved covered space loads back with its map, and a map that weighs a coarse vertex its row of
  // P does not (vertex 5 of the first sphere placed on the second) is refused.
  const std::string file = store.file("covered.ice");
  ice::proxy::save_mapped_space_file(file, mesh, space, map);
  CHECK(ice::proxy::load_mapped_space_file(file, mesh).map.size() == map.size());
  std::vector<ice::CoarsePoint> moved = map;
  moved[5].face = map[static_cast<std::size_t>(spheres.far_top)].face;
  moved[5].bary = {1.0 / 3, 1.0 / 3, 1.0 / 3};
  ice::proxy::save_mapped_space_file(file, mesh, space, moved, true);
  REQUIRE_THROWS_WITH(ice::proxy::load_mapped_space_file(file, mesh), Catch::Contains("weighs a coarse vertex"));
  // Traced lengths are refused on a cover, before any work.
  oracle_options.lengths = ice::proxy::CoarseLengths::traced;
  REQUIRE_THROWS_WITH(ice::proxy::distance_oracle(mesh, oracle_options), Catch::Contains("tufted cover"));
}

namespace {
/// Median angle in degrees between the rows of two n × 3 fields.
double median_angle_degrees(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  std::vector<double> angles;
  for (Eigen::Index v = 0; v < a.rows(); ++v) {
    const Eigen::Vector3d x = a.row(v).transpose(), y = b.row(v).transpose();
    angles.push_back(std::atan2(x.cross(y).norm(), x.dot(y)) * 180 / M_PI);
  }
  std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(angles.size() / 2), angles.end());
  return angles[angles.size() / 2];
}

/// The fine vector heat method on the solver's copies, through the same sources, as 3D vectors on the input.
Eigen::MatrixXd fine_field(const ice::proxy::VectorTransportSolver& solver, const std::vector<Index>& sources,
                           const Eigen::MatrixXd& directions) {
  const ice::proxy::CopySources on_copies = ice::proxy::sources_on_copies(*solver.cover(), solver.tangent_mesh(), sources, directions);
  const fem::VectorHeatSolver fine(*solver.tangent_mesh().operators);
  return ice::proxy::ambient_on_input(*solver.cover(), solver.tangent_mesh(), fine.interpolate(on_copies.copies, on_copies.vectors));
}
}  // namespace

TEST_CASE("tufted cover: vector fields on the copies of its sheets, near the fine vector heat method", "[cover][proxy][vector]") {
  ice::proxy::VectorTransportOptions options;
  options.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  options.coarsening.coarsen.target_ratio = 0.25;
  {
    // Sheets meeting along non-manifold edges: the field crosses them to every vertex.
    const ice::TriangleMesh mesh = load_keeping_sheets("triple_vierbein.obj");
    options.coarsening.coarsen.target_ratio = 0.5;
    const ice::proxy::VectorTransportSolver solver(mesh, options);
    REQUIRE(solver.cover());
    REQUIRE(solver.coarse_space().P.rows() == static_cast<Eigen::Index>(solver.cover()->to_input.size()));
    REQUIRE(solver.tangent_mesh().mesh.vertex_count == static_cast<Index>(solver.cover()->to_input.size()));
    const Eigen::MatrixXd direction = mesh.V.row(mesh.F(0, 1)) - mesh.V.row(mesh.F(0, 0));
    const std::vector<Index> sources{mesh.F(0, 0)};
    const Eigen::MatrixXd field = solver.transport_directions(sources, direction);
    REQUIRE(field.rows() == mesh.V.rows());
    REQUIRE(field.allFinite());
    CHECK(field.rowwise().norm().minCoeff() > 0);
    const double angle = median_angle_degrees(field, fine_field(solver, sources, direction));
    INFO("median angle against the fine method " << angle << " degrees");
    CHECK(angle < 10.0);
  }
  // Spheres touching at a vertex: tangent on the first, near the fine method; no tangent plane joins
  // the sheets at a point, so the field stays on the source's sphere (zero on the other, as the fine
  // method's).
  const TouchingSpheres spheres = touching_spheres();
  const ice::TriangleMesh& mesh = spheres.mesh;
  options.coarsening.coarsen.target_ratio = 0.25;
  const ice::proxy::VectorTransportSolver solver(mesh, options);
  const std::vector<Index> sources{spheres.bottom};
  const Eigen::MatrixXd direction = Eigen::RowVector3d(1, 0, 0);
  const Eigen::MatrixXd field = solver.transport_directions(sources, direction);
  const Eigen::MatrixXd reference = fine_field(solver, sources, direction);
  for (Index v = 0; v < spheres.n; ++v) {
    if (v == spheres.top) continue;  // the junction: the mean of its copies'
    INFO("vertex " << v);
    REQUIRE(field.row(v).norm() > 0);
    CHECK(std::abs(field.row(v).dot(mesh.V.row(v).normalized())) < 0.1 * field.row(v).norm());
  }
  // At the source, the given direction (tangent there up to the faces' tilt), of its length.
  CHECK(field.row(spheres.bottom).dot(direction.row(0)) > 0.95 * field.row(spheres.bottom).norm());
  CHECK(field.row(spheres.bottom).norm() == Approx(1.0).epsilon(0.05));
  CHECK(field.bottomRows(spheres.n - 1).norm() == 0);
  CHECK(reference.bottomRows(spheres.n - 1).norm() == 0);
  const double angle = median_angle_degrees(field.topRows(spheres.n), reference.topRows(spheres.n));
  INFO("median angle against the fine method " << angle << " degrees");
  CHECK(angle < 5.0);
  {
    // A flat square sheet with an upright one standing on its middle line (sheets meeting along
    // non-manifold edges): a vertical direction at a vertex of that line is normal to the flat sheet
    // and lies in the upright one, which carries it (the flat copies take none, nothing is refused).
    ice::TriangleMesh tee;
    const int size = 5;  // vertices per side of the flat sheet; the upright one is size × 3, on y = 0
    std::vector<Eigen::RowVector3d> points;
    const auto flat = [&](int i, int j) { return i * size + j; };  // x = i - 2, y = j - 2
    for (int i = 0; i < size; ++i)
      for (int j = 0; j < size; ++j) points.emplace_back(i - 2.0, j - 2.0, 0.0);
    const auto upright = [&](int i, int k) { return k == 0 ? flat(i, size / 2) : size * size + i * 2 + (k - 1); };  // z = k
    for (int i = 0; i < size; ++i)
      for (int k = 1; k <= 2; ++k) points.emplace_back(i - 2.0, 0.0, static_cast<double>(k));
    std::vector<std::array<Index, 3>> faces;
    for (int i = 0; i + 1 < size; ++i) {
      for (int j = 0; j + 1 < size; ++j) {
        faces.push_back({flat(i, j), flat(i + 1, j), flat(i + 1, j + 1)});
        faces.push_back({flat(i, j), flat(i + 1, j + 1), flat(i, j + 1)});
      }
      for (int k = 0; k < 2; ++k) {
        faces.push_back({upright(i, k), upright(i + 1, k), upright(i + 1, k + 1)});
        faces.push_back({upright(i, k), upright(i + 1, k + 1), upright(i, k + 1)});
      }
    }
    tee.V.resize(static_cast<Eigen::Index>(points.size()), 3);
    for (std::size_t v = 0; v < points.size(); ++v) tee.V.row(static_cast<Eigen::Index>(v)) = points[v];
    tee.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
    for (std::size_t f = 0; f < faces.size(); ++f)
      for (int k = 0; k < 3; ++k) tee.F(static_cast<Eigen::Index>(f), k) = faces[f][static_cast<std::size_t>(k)];
    REQUIRE(ice::needs_tufted_cover(tee));
    ice::proxy::VectorTransportOptions tee_options;
    tee_options.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
    tee_options.coarsening.coarsen.target_ratio = 0.8;
    const Index junction = flat(size / 2, size / 2);  // the middle of the line, inside both sheets
    const Eigen::MatrixXd up =
        ice::proxy::transport_directions(tee, {junction}, Eigen::MatrixXd(Eigen::RowVector3d(0, 0, 1)), tee_options);
    REQUIRE(up.allFinite());
    const Index above = upright(size / 2, 1);
    CHECK(up.row(above).norm() > 0);
    CHECK(up.row(above)(2) > 0.9 * up.row(above).norm());  // still vertical: a flat sheet transports it unturned
    // A source on a sheet's boundary (the flat sheet's corner): the sheets keep their boundary (no
    // fold onto their other side), so along the flat sheet the vector stays as given, to the far corner.
    const Eigen::MatrixXd along =
        ice::proxy::transport_directions(tee, {flat(0, 0)}, Eigen::MatrixXd(Eigen::RowVector3d(1, 0, 0)), tee_options);
    const Eigen::RowVector3d far = along.row(flat(size - 1, size - 1));
    CHECK(far(0) > 0.99 * far.norm());
    // Of the direction's length everywhere it reaches (the copies it does not reach weigh nothing).
    for (Index v = 0; v < tee.V.rows(); ++v) {
      INFO("vertex " << v);
      CHECK(along.row(v).norm() == Approx(1.0).epsilon(0.05));
    }
    // A cover made with its boundary tufts folds there: a source at the fold is refused, saying so.
    const ice::TuftedCover tufted = ice::distinct_sheets(ice::tufted_cover(tee));
    const ice::proxy::TangentMesh folded = ice::proxy::tangent_mesh(tufted, ice::FineGeometry::input, false);
    REQUIRE_THROWS_WITH(ice::proxy::sources_on_copies(tufted, folded, {flat(0, 0)}, Eigen::MatrixXd(Eigen::RowVector3d(1, 0, 0))),
                        Catch::Contains("a face and its mirror image meet"));
  }
  // A zero direction has nothing to project: refused, naming the source.
  REQUIRE_THROWS_WITH(solver.transport_directions(sources, Eigen::MatrixXd::Zero(1, 3)), Catch::Contains("normal to the surface"));
  // A manifold mesh: the option changes nothing.
  const ice::TriangleMesh sphere = ice::make_icosphere(3);
  ice::proxy::VectorTransportOptions manifold;
  manifold.coarsening.coarsen.target_ratio = 0.25;
  const Eigen::MatrixXd plain = ice::proxy::VectorTransportSolver(sphere, manifold).transport_directions({0}, direction);
  manifold.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  const ice::proxy::VectorTransportSolver optioned(sphere, manifold);
  CHECK_FALSE(optioned.cover());
  CHECK(optioned.transport_directions({0}, direction) == plain);
}
