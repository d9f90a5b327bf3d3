// Coarse-proxy pipelines: identity prolongation reproduces fine solutions; on nested spheres the
// Galerkin proxy satisfies Galerkin orthogonality and both proxies approximate the fine solutions.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "coarse_marching.h"  // libfem's private marching mesh and subdivision
#include "fem/coarse_proxy.h"
#include "fem/curvature_correction.h"
#include "fem/geometry.h"
#include "fem/errors.h"
#include "ice/mesh_generators.h"

namespace {

fem::SparseMatrix identity(Eigen::Index n) {
  fem::SparseMatrix I(n, n);
  I.setIdentity();
  return I;
}

/// Prolongation from icosphere(level) to icosphere(level+1), found from geometry and connectivity
/// only: coarse vertices reappear at identical positions, and every other fine vertex is an edge point
/// adjacent to exactly two of them (weights ½, ½).
fem::SparseMatrix nested_sphere_prolongation(const ice::TriangleMesh& coarse, const ice::TriangleMesh& fine) {
  std::map<std::vector<double>, int> coarse_at;
  for (Eigen::Index v = 0; v < coarse.V.rows(); ++v)
    coarse_at[{coarse.V(v, 0), coarse.V(v, 1), coarse.V(v, 2)}] = static_cast<int>(v);
  std::vector<int> coarse_of(static_cast<std::size_t>(fine.V.rows()), -1);
  for (Eigen::Index v = 0; v < fine.V.rows(); ++v) {
    const auto it = coarse_at.find({fine.V(v, 0), fine.V(v, 1), fine.V(v, 2)});
    if (it != coarse_at.end()) coarse_of[static_cast<std::size_t>(v)] = it->second;
  }
  std::vector<std::set<int>> coarse_neighbours(static_cast<std::size_t>(fine.V.rows()));
  for (Eigen::Index f = 0; f < fine.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = fine.F(f, k), b = fine.F(f, (k + 1) % 3);
      if (coarse_of[b] >= 0) coarse_neighbours[a].insert(coarse_of[b]);
      if (coarse_of[a] >= 0) coarse_neighbours[b].insert(coarse_of[a]);
    }
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index v = 0; v < fine.V.rows(); ++v) {
    if (coarse_of[v] >= 0) {
      triplets.emplace_back(v, coarse_of[v], 1.0);
      continue;
    }
    REQUIRE(coarse_neighbours[v].size() == 2);
    for (int c : coarse_neighbours[v]) triplets.emplace_back(v, c, 0.5);
  }
  fem::SparseMatrix P(fine.V.rows(), coarse.V.rows());
  P.setFromTriplets(triplets.begin(), triplets.end());
  return P;
}

/// Two nested icospheres (levels `level` and `level + 1`), their lengths and the prolongation between them.
struct NestedSpheres {
  ice::TriangleMesh coarse, fine;
  ice::FaceLengths coarse_lengths, fine_lengths;
  fem::SparseMatrix P;
};
NestedSpheres nested_spheres(int level) {
  NestedSpheres s;
  s.coarse = ice::make_icosphere(level);
  s.fine = ice::make_icosphere(level + 1);
  s.coarse_lengths = ice::face_lengths_from_positions(s.coarse.V, s.coarse.F);
  s.fine_lengths = ice::face_lengths_from_positions(s.fine.V, s.fine.F);
  s.P = nested_sphere_prolongation(s.coarse, s.fine);
  return s;
}

/// The 1:4 midpoint split of a mesh (new vertices at the edge midpoints, after the old ones) and its
/// prolongation (old vertices: their coarse vertex; midpoints: ½, ½ of the edge's ends).
std::pair<ice::TriangleMesh, fem::SparseMatrix> midpoint_split(const ice::TriangleMesh& coarse) {
  std::map<std::pair<int, int>, int> midpoint;
  std::vector<Eigen::RowVector3d> points;
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index v = 0; v < coarse.V.rows(); ++v) {
    points.push_back(coarse.V.row(v));
    triplets.emplace_back(v, v, 1.0);
  }
  const auto middle = [&](int a, int b) {
    const auto key = std::minmax(a, b);
    const auto [it, added] = midpoint.emplace(key, static_cast<int>(points.size()));
    if (added) {
      points.push_back(0.5 * (coarse.V.row(a) + coarse.V.row(b)));
      triplets.emplace_back(it->second, a, 0.5);
      triplets.emplace_back(it->second, b, 0.5);
    }
    return it->second;
  };
  ice::TriangleMesh fine;
  fine.F.resize(4 * coarse.F.rows(), 3);
  for (Eigen::Index f = 0; f < coarse.F.rows(); ++f) {
    const int a = coarse.F(f, 0), b = coarse.F(f, 1), c = coarse.F(f, 2);
    const int ab = middle(a, b), bc = middle(b, c), ca = middle(c, a);
    fine.F.row(4 * f) << a, ab, ca;
    fine.F.row(4 * f + 1) << ab, b, bc;
    fine.F.row(4 * f + 2) << ca, bc, c;
    fine.F.row(4 * f + 3) << ab, bc, ca;
  }
  fine.V.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v) fine.V.row(static_cast<Eigen::Index>(v)) = points[v];
  fem::SparseMatrix P(fine.V.rows(), coarse.V.rows());
  P.setFromTriplets(triplets.begin(), triplets.end());
  return {fine, P};
}

/// A hexagon of equilateral triangles of unit side, `rings` rings around the origin (acute
/// everywhere, where fast marching with planar updates is exact for point sources).
ice::TriangleMesh equilateral_hexagon(int rings) {
  std::map<std::pair<int, int>, int> index;
  std::vector<std::array<double, 3>> points;
  const auto inside = [&](int i, int j) { return std::abs(i) <= rings && std::abs(j) <= rings && std::abs(i + j) <= rings; };
  for (int i = -rings; i <= rings; ++i)
    for (int j = -rings; j <= rings; ++j)
      if (inside(i, j)) {
        index[{i, j}] = static_cast<int>(points.size());
        points.push_back({i + 0.5 * j, std::sqrt(3.0) / 2 * j, 0.0});
      }
  std::vector<std::array<int, 3>> faces;
  for (const auto& [at, v] : index) {
    const auto [i, j] = at;
    if (inside(i + 1, j) && inside(i, j + 1)) faces.push_back({v, index[{i + 1, j}], index[{i, j + 1}]});
    if (inside(i + 1, j) && inside(i + 1, j - 1)) faces.push_back({v, index[{i + 1, j - 1}], index[{i + 1, j}]});
  }
  ice::TriangleMesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v)
    mesh.V.row(static_cast<Eigen::Index>(v)) << points[v][0], points[v][1], points[v][2];
  mesh.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (std::size_t f = 0; f < faces.size(); ++f)
    mesh.F.row(static_cast<Eigen::Index>(f)) << faces[f][0], faces[f][1], faces[f][2];
  return mesh;
}

}  // namespace

TEST_CASE("coarse proxy with P = identity reproduces the fine solutions", "[fem][coarse_proxy]") {
  const ice::TriangleMesh mesh = ice::make_torus(24, 12, 2.0, 0.6);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const Eigen::Index n = mesh.V.rows();
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(mesh.F, lengths));
  const fem::SparseMatrix M = fem::mass_matrix(ice::intrinsic_mesh(mesh.F, lengths));
  const Eigen::VectorXd f = (mesh.V.col(0).array() * mesh.V.col(2).array() + mesh.V.col(1).array()).matrix();

  const Eigen::VectorXd poisson = fem::PoissonSolver::zero_mean(L, M).solve(f);
  const Eigen::VectorXd heat = fem::HeatSolver(L, M, 0.01).integrate(f, 5);
  const Eigen::VectorXd distance = fem::HeatGeodesicSolver(fem::heat_method_operators(ice::intrinsic_mesh(mesh.F, lengths))).distance({7});

  for (fem::CoarseOperatorKind kind : {fem::CoarseOperatorKind::intrinsic, fem::CoarseOperatorKind::galerkin}) {
    INFO((kind == fem::CoarseOperatorKind::intrinsic ? "intrinsic" : "galerkin"));
    const fem::CoarseProxy proxy(ice::intrinsic_mesh(mesh.F, lengths), ice::intrinsic_mesh(mesh.F, lengths), identity(n), {kind});
    CHECK(fem::SparseMatrix(proxy.coarse_laplacian() - L).norm() <= 1e-14 * L.norm());
    CHECK(fem::relative_l2_error(fem::ProxyPoissonSolver(proxy).solve(f), poisson, M) < 1e-12);
    for (fem::RestrictionKind restriction : {fem::RestrictionKind::l2_projection, fem::RestrictionKind::injection})
      CHECK(fem::relative_l2_error(fem::ProxyHeatSolver(proxy, 0.01, restriction).integrate(f, 5), heat, M) < 1e-12);
    fem::ProxyGeodesicOptions heat_method;
    heat_method.method = fem::CoarseDistanceMethod::heat_method;
    CHECK(fem::max_abs_error(fem::ProxyGeodesicSolver(proxy, heat_method).distance({7}), distance) < 1e-12 * distance.maxCoeff());
  }
}

TEST_CASE("coarse proxy on nested icospheres", "[fem][coarse_proxy]") {
  const auto [coarse, fine, coarse_lengths, fine_lengths, P] = nested_spheres(3);
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(fine.F, fine_lengths));
  const fem::SparseMatrix M = fem::mass_matrix(ice::intrinsic_mesh(fine.F, fine_lengths));

  // Smooth data: f = z + xy (spherical harmonics of degree 1 and 2).
  const Eigen::ArrayXd x = fine.V.col(0), y = fine.V.col(1), z = fine.V.col(2);
  const Eigen::VectorXd f = (z + x * y).matrix();
  const Eigen::VectorXd poisson = fem::PoissonSolver::zero_mean(L, M).solve(f);
  Eigen::Index source = 0;
  fine.V.col(2).maxCoeff(&source);
  const Eigen::VectorXd distance =
      fem::HeatGeodesicSolver(fem::heat_method_operators(ice::intrinsic_mesh(fine.F, fine_lengths))).distance({static_cast<int>(source)});

  for (fem::CoarseOperatorKind kind : {fem::CoarseOperatorKind::intrinsic, fem::CoarseOperatorKind::galerkin}) {
    const bool galerkin = kind == fem::CoarseOperatorKind::galerkin;
    INFO((galerkin ? "galerkin" : "intrinsic"));
    const fem::CoarseProxy proxy(ice::intrinsic_mesh(fine.F, fine_lengths), ice::intrinsic_mesh(coarse.F, coarse_lengths), P, {kind});
    const Eigen::VectorXd u = fem::ProxyPoissonSolver(proxy).solve(f);
    const double poisson_error = fem::relative_l2_error(u, poisson, M);
    UNSCOPED_INFO((galerkin ? "galerkin" : "intrinsic") << " proxy Poisson relative L2 error " << poisson_error);
    CHECK(poisson_error < 0.02);
    if (galerkin) {
      // Galerkin orthogonality: the fine error is L-orthogonal to the coarse space.
      const Eigen::VectorXd residual = P.transpose() * (L * (poisson - u));
      CHECK(residual.norm() < 1e-10 * (P.transpose() * (L * poisson)).norm());
    }
    fem::ProxyGeodesicOptions heat_method;
    heat_method.method = fem::CoarseDistanceMethod::heat_method;
    for (const fem::ProxyGeodesicOptions& options : {fem::ProxyGeodesicOptions{}, heat_method}) {
      const fem::DistanceErrors errors =
          fem::distance_errors(fem::ProxyGeodesicSolver(proxy, options).distance({static_cast<int>(source)}), distance);
      UNSCOPED_INFO("  geodesic (" << fem::to_string(options.method) << ") vs fine heat method: mean "
                                   << errors.mean_relative << ", max " << errors.max_relative);
      CHECK(errors.mean_relative < 0.02);
    }

    // Restrictions: injection recovers coarse nodal values; the Galerkin L² projection is exact on span P.
    const Eigen::VectorXd coarse_values = coarse.V.col(0) + 2.0 * coarse.V.col(1);
    CHECK(fem::max_abs_error(proxy.restrict_values(proxy.prolong(coarse_values), fem::RestrictionKind::injection),
                             coarse_values) == 0.0);
    if (galerkin)
      CHECK(fem::max_abs_error(proxy.restrict_values(proxy.prolong(coarse_values), fem::RestrictionKind::l2_projection),
                               coarse_values) < 1e-12);
    const Eigen::VectorXd heat = fem::HeatSolver(L, M, 0.01).integrate(f, 10);
    const double heat_error = fem::relative_l2_error(
        fem::ProxyHeatSolver(proxy, 0.01, fem::RestrictionKind::l2_projection).integrate(f, 10), heat, M);
    UNSCOPED_INFO("  heat relative L2 error " << heat_error);
    CHECK(heat_error < 0.02);
  }
}

TEST_CASE("coarse proxy rejects a prolongation whose rows do not sum to 1", "[fem][coarse_proxy]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(1);
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(mesh.V, mesh.F);
  const fem::SparseMatrix P = 0.5 * identity(mesh.V.rows());
  CHECK_THROWS_AS(fem::CoarseProxy(ice::intrinsic_mesh(mesh.F, lengths), ice::intrinsic_mesh(mesh.F, lengths), P, {fem::CoarseOperatorKind::galerkin}),
                  std::invalid_argument);
  const fem::SparseMatrix wrong_size = identity(mesh.V.rows() - 1);
  CHECK_THROWS_AS(fem::CoarseProxy(ice::intrinsic_mesh(mesh.F, lengths), ice::intrinsic_mesh(mesh.F, lengths), wrong_size, {fem::CoarseOperatorKind::intrinsic}),
                  std::invalid_argument);
}

TEST_CASE("geodesics by coarse marching are the straight-line distance on a flat mesh", "[fem][coarse_proxy]") {
  // On a flat convex patch the distance is |y − s|. On acute coarse triangles the marching's planar
  // updates reach it at the coarse vertices, and the squared-distance interpolation is exact inside
  // flat faces, so the fine vertices of a nested (midpoint-split) mesh get it too, from sources at
  // old vertices and at midpoints (points on coarse edges) alike. The heat method smooths: it is
  // only close.
  const ice::TriangleMesh coarse = equilateral_hexagon(6);
  const auto [fine, P] = midpoint_split(coarse);
  const ice::FaceLengths coarse_lengths = ice::face_lengths_from_positions(coarse.V, coarse.F);
  const ice::FaceLengths fine_lengths = ice::face_lengths_from_positions(fine.V, fine.F);
  const fem::CoarseProxy proxy(ice::intrinsic_mesh(fine.F, fine_lengths), ice::intrinsic_mesh(coarse.F, coarse_lengths), P, {fem::CoarseOperatorKind::galerkin});
  const fem::ProxyGeodesicSolver marching(proxy);
  CHECK(marching.method() == fem::CoarseDistanceMethod::marching);
  fem::ProxyGeodesicOptions heat_options;
  heat_options.method = fem::CoarseDistanceMethod::heat_method;
  const fem::ProxyGeodesicSolver heat(proxy, heat_options);
  const int midpoint = static_cast<int>(coarse.V.rows()) + 5;
  for (int source : {0, 17, midpoint}) {
    INFO("source " << source);
    const Eigen::VectorXd exact = (fine.V.rowwise() - fine.V.row(source)).rowwise().norm();
    const Eigen::VectorXd d = marching.distance({source});
    CHECK(d(source) == 0.0);
    CHECK(fem::max_abs_error(d, exact) <= 1e-6 * exact.maxCoeff());  // the marching's face layouts are floats
    const double heat_error = fem::distance_errors(heat.distance({source}), exact).mean_relative;
    CHECK(heat_error > 1e-4);
    CHECK(heat_error < 0.05);
  }
  // Two sources: the nearer one's distance, exact where both ends of the fine vertex's coarse edge
  // are clearly nearer to one source; where the two fronts meet, interpolated linearly (within half
  // a coarse edge, which is 1 here).
  const int far_midpoint = static_cast<int>(fine.V.rows()) - 1;
  const Eigen::VectorXd to_first = (fine.V.rowwise() - fine.V.row(0)).rowwise().norm();
  const Eigen::VectorXd to_second = (fine.V.rowwise() - fine.V.row(far_midpoint)).rowwise().norm();
  const Eigen::VectorXd both = marching.distance({0, far_midpoint});
  Eigen::Index clear = 0;
  for (Eigen::Index v = 0; v < fine.V.rows(); ++v) {
    const double nearer = std::min(to_first(v), to_second(v));
    CHECK(std::abs(both(v) - nearer) <= 0.5);
    if (std::abs(to_first(v) - to_second(v)) > 2.0) {  // both coarse ends (1/2 away) on the same side
      ++clear;
      CHECK(std::abs(both(v) - nearer) <= 1e-6 * to_first.maxCoeff());
    }
  }
  CHECK(clear > fine.V.rows() / 2);
  // Without a CoarseProxy (no operators assembled): the same answer.
  const fem::ProxyGeodesicSolver bare(ice::intrinsic_mesh(coarse.F, coarse_lengths), P);
  // (To round-off: the two take P through different paths, and which of two equal candidates a
  // vertex keeps its virtual source from can differ by the last bit.)
  CHECK((bare.distance({17, midpoint}) - marching.distance({17, midpoint})).cwiseAbs().maxCoeff() <= 1e-12);
  CHECK_THROWS_AS(fem::ProxyGeodesicSolver(ice::intrinsic_mesh(coarse.F, coarse_lengths), fem::SparseMatrix(0.5 * P)), std::invalid_argument);

  // A row whose columns are not joined by an edge (as QEM's rows can be after intrinsic Delaunay
  // flips): the point (−1, 0), halfway between the vertices at (−2, 0) and (0, 0). As a source it
  // is marched from both and combined, exact here; as a target it is interpolated linearly.
  const auto vertex_at = [&](double x, double y) {
    Eigen::Index found = -1;
    for (Eigen::Index v = 0; v < coarse.V.rows(); ++v)
      if ((coarse.V.row(v) - Eigen::RowVector3d(x, y, 0)).norm() < 1e-12) found = v;
    REQUIRE(found >= 0);
    return static_cast<int>(found);
  };
  const int left = vertex_at(-2, 0), right = vertex_at(0, 0);
  const auto nc = static_cast<Eigen::Index>(coarse.V.rows());
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index v = 0; v < nc; ++v) triplets.emplace_back(v, v, 1.0);
  triplets.emplace_back(nc, left, 0.5);
  triplets.emplace_back(nc, right, 0.5);
  fem::SparseMatrix unlaid(nc + 1, nc);
  unlaid.setFromTriplets(triplets.begin(), triplets.end());
  const fem::ProxyGeodesicSolver across(ice::intrinsic_mesh(coarse.F, coarse_lengths), unlaid);
  fem::SparseMatrix negative = unlaid;  // rows summing to 1, one with a negative weight: refused
  negative.coeffRef(nc, left) = 1.5;
  negative.coeffRef(nc, right) = -0.5;
  CHECK_THROWS_AS(fem::ProxyGeodesicSolver(ice::intrinsic_mesh(coarse.F, coarse_lengths), negative), std::invalid_argument);
  const Eigen::VectorXd from_point = across.distance({static_cast<int>(nc)});
  const Eigen::VectorXd to_point = (coarse.V.rowwise() - Eigen::RowVector3d(-1, 0, 0)).rowwise().norm();
  CHECK(from_point(nc) == 0.0);
  // (float layouts, and the square root of a rounding error where the point meets a vertex: 1.2e-4)
  CHECK((from_point.head(nc) - to_point).cwiseAbs().maxCoeff() <= 1e-4 * to_point.maxCoeff());
  const Eigen::VectorXd from_vertex = across.distance({0});
  CHECK(from_vertex(nc) == Approx(0.5 * (from_vertex(left) + from_vertex(right))).epsilon(1e-12));
  // Both kinds of source at once: the nearer one's distance at every coarse vertex.
  const Eigen::VectorXd mixed = across.distance({static_cast<int>(nc), 0});
  CHECK((mixed.head(nc) - from_point.head(nc).cwiseMin(from_vertex.head(nc))).cwiseAbs().maxCoeff() <= 1e-4 * to_point.maxCoeff());
  CHECK_THROWS_AS(marching.distance({}), std::invalid_argument);
  CHECK_THROWS_AS(marching.distance({static_cast<int>(fine.V.rows())}), std::invalid_argument);
}

TEST_CASE("coarse marching on the subdivided coarse mesh: the same metric, nearer its geodesics", "[fem][coarse_proxy]") {
  // Flat and acute (the equilateral hexagon): exact with or without subdivision.
  {
    const ice::TriangleMesh coarse = equilateral_hexagon(6);
    const auto [fine, P] = midpoint_split(coarse);
    const ice::FaceLengths lengths = ice::face_lengths_from_positions(coarse.V, coarse.F);
    for (int subdivisions = 0; subdivisions < 3; ++subdivisions) {
      const fem::ProxyGeodesicSolver solver(ice::intrinsic_mesh(coarse.F, lengths), P, subdivisions);
      for (int source : {0, 17, static_cast<int>(coarse.V.rows()) + 5}) {
        const Eigen::VectorXd exact = (fine.V.rowwise() - fine.V.row(source)).rowwise().norm();
        const Eigen::VectorXd d = solver.distance({source});
        CHECK(d(source) == 0.0);
        CHECK(fem::max_abs_error(d, exact) <= 1e-6 * exact.maxCoeff());  // float layouts
      }
    }
    CHECK_THROWS_AS(fem::ProxyGeodesicSolver(ice::intrinsic_mesh(coarse.F, lengths), P, -1), std::invalid_argument);
  }
  // Curved (a coarse icosphere's polyhedral metric, its curvature at the vertices): the marching's
  // planar updates miss the polyhedron's geodesics; on its 1:4 subdivisions (the same metric, flat
  // pieces) they converge to them: the distances approach those of the finest subdivision
  // (measured mean gaps 2.6 %, 0.31 %, 0.14 %, ... of the largest distance).
  {
    const ice::TriangleMesh coarse = ice::make_icosphere(1);
    const auto [fine, P] = midpoint_split(coarse);
    const ice::FaceLengths lengths = ice::face_lengths_from_positions(coarse.V, coarse.F);
    const std::vector<int> sources{0, static_cast<int>(coarse.V.rows()) + 7};
    std::vector<Eigen::VectorXd> distances;
    for (int subdivisions = 0; subdivisions <= 4; ++subdivisions) {
      const fem::ProxyGeodesicSolver solver(ice::intrinsic_mesh(coarse.F, lengths), P, subdivisions);
      Eigen::VectorXd d(2 * fine.V.rows());
      d << solver.distance({sources[0]}), solver.distance({sources[1]});
      distances.push_back(d);
    }
    const Eigen::VectorXd& finest = distances.back();
    std::array<double, 4> gap{};
    for (std::size_t k = 0; k < 4; ++k) gap[k] = (distances[k] - finest).cwiseAbs().mean() / finest.maxCoeff();
    INFO("mean gap to the 1:256 subdivision: " << gap[0] << ", " << gap[1] << ", " << gap[2] << ", " << gap[3]);
    CHECK(gap[0] > 1e-3);
    CHECK(gap[1] < gap[0]);
    CHECK(gap[2] < gap[1]);
    CHECK(gap[3] < gap[2]);
  }
}

TEST_CASE("coarse marching from a point off-centre on an edge or in a face is the straight-line distance",
          "[fem][coarse_proxy]") {
  // A source between coarse vertices seeds its corners at their planar distances. The near corner's
  // turn comes first; the far one's seed must already count for the faces across the source's edge,
  // or the vertices beyond it, reached along edges only, take their turn too early with distances
  // too long, and so does everything behind them (CGAL's holes at 100 coarse vertices, from a
  // source on a coarse edge: 2.6x the distance oracle's error). With subdivisions the kite's obtuse
  // pieces need the marching's reopening too. A flat kite: the long side ab (4) between the corners
  // c (the face above) and w (below), near it.
  ice::TriangleMesh coarse;
  coarse.V.resize(4, 3);
  coarse.V << 0, 0, 0,   // a
      4, 0, 0,           // b
      2, 1.5, 0,         // c
      1, -0.5, 0;        // w
  coarse.F.resize(2, 3);
  coarse.F << 0, 1, 2, 1, 0, 3;
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(coarse.V, coarse.F);
  // Fine points: the coarse vertices, then on ab at 0.85 / 0.15 and 0.3 / 0.7, inside abc at
  // (0.75, 0.2, 0.05) and inside baw at (0.1, 0.6, 0.3).
  const std::vector<std::pair<int, std::array<double, 3>>> points{
      {0, {0.85, 0.15, 0.0}}, {0, {0.3, 0.7, 0.0}}, {0, {0.75, 0.2, 0.05}}, {1, {0.1, 0.6, 0.3}}};
  std::vector<Eigen::Triplet<double>> triplets;
  for (int v = 0; v < 4; ++v) triplets.emplace_back(v, v, 1.0);
  Eigen::MatrixXd where(4 + static_cast<Eigen::Index>(points.size()), 3);
  where.topRows(4) = coarse.V;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto row = 4 + static_cast<Eigen::Index>(k);
    const auto& [face, w] = points[k];
    where.row(row).setZero();
    for (int corner = 0; corner < 3; ++corner) {
      const double weight = w[static_cast<std::size_t>(corner)];
      where.row(row) += weight * coarse.V.row(coarse.F(face, corner));
      if (weight > 0) triplets.emplace_back(row, coarse.F(face, corner), weight);
    }
  }
  fem::SparseMatrix P(where.rows(), 4);
  P.setFromTriplets(triplets.begin(), triplets.end());
  for (int subdivisions = 0; subdivisions <= 2; ++subdivisions) {
    const fem::ProxyGeodesicSolver solver(ice::intrinsic_mesh(coarse.F, lengths), P, subdivisions);
    for (Eigen::Index source = 4; source < where.rows(); ++source) {
      INFO("subdivisions " << subdivisions << ", source " << source - 4);
      const Eigen::VectorXd exact = (where.rowwise() - where.row(source)).rowwise().norm();
      const Eigen::VectorXd d = solver.distance({static_cast<int>(source)});
      INFO("distances " << d.transpose() << "\nexact " << exact.transpose());
      CHECK(fem::max_abs_error(d, exact) <= 1e-5 * exact.maxCoeff());  // float layouts
    }
  }
}

TEST_CASE("smoothed prolongation: one damped Jacobi step of P, a better Galerkin coarse space", "[fem][coarse_proxy]") {
  const auto [coarse, fine, coarse_lengths, fine_lengths, P] = nested_spheres(2);
  const fem::SparseMatrix L = fem::cotan_laplacian(ice::intrinsic_mesh(fine.F, fine_lengths));
  const fem::SparseMatrix M = fem::mass_matrix(ice::intrinsic_mesh(fine.F, fine_lengths));

  // The definition, entry by entry against dense arithmetic, and rows still summing to 1.
  const fem::SparseMatrix S = fem::smoothed_prolongation(P, L);
  const Eigen::MatrixXd dense_L(L), dense_P(P);
  const Eigen::MatrixXd expected =
      dense_P - fem::kProlongationSmoothingWeight * dense_L.diagonal().cwiseInverse().asDiagonal() * dense_L * dense_P;
  CHECK((Eigen::MatrixXd(S) - expected).cwiseAbs().maxCoeff() < 1e-12);
  CHECK((S * Eigen::VectorXd::Ones(S.cols()) - Eigen::VectorXd::Ones(S.rows())).cwiseAbs().maxCoeff() < 1e-12);
  CHECK(S.nonZeros() > P.nonZeros());  // each row reaches the coarse vertices of its neighbours
  CHECK_THROWS_AS(fem::smoothed_prolongation(P, fem::cotan_laplacian(ice::intrinsic_mesh(coarse.F, coarse_lengths))), std::invalid_argument);

  const fem::CoarseProxy plain(ice::intrinsic_mesh(fine.F, fine_lengths), ice::intrinsic_mesh(coarse.F, coarse_lengths), P, {fem::CoarseOperatorKind::galerkin});
  const fem::CoarseProxy smoothed(ice::intrinsic_mesh(fine.F, fine_lengths), ice::intrinsic_mesh(coarse.F, coarse_lengths), P, {fem::CoarseOperatorKind::galerkin, fem::MassKind::lumped, fem::ProlongationKind::smoothed});
  CHECK(smoothed.prolongation_kind() == fem::ProlongationKind::smoothed);
  CHECK((Eigen::MatrixXd(smoothed.prolongation()) - Eigen::MatrixXd(S)).cwiseAbs().maxCoeff() == 0.0);
  CHECK((Eigen::MatrixXd(smoothed.barycentric_prolongation()) - dense_P).cwiseAbs().maxCoeff() == 0.0);
  CHECK(smoothed.coarse_vertex_of(0) == plain.coarse_vertex_of(0));  // read off the barycentric P

  // Poisson and heat: Galerkin orthogonality in the smoothed space, and smaller errors than the
  // barycentric space's on smooth data (z + xy).
  const Eigen::ArrayXd x = fine.V.col(0), y = fine.V.col(1), z = fine.V.col(2);
  const Eigen::VectorXd f = (z + x * y).matrix();
  const Eigen::VectorXd poisson = fem::PoissonSolver::zero_mean(L, M).solve(f);
  const Eigen::VectorXd u_plain = fem::ProxyPoissonSolver(plain).solve(f);
  const Eigen::VectorXd u_smoothed = fem::ProxyPoissonSolver(smoothed).solve(f);
  const Eigen::VectorXd residual = S.transpose() * (L * (poisson - u_smoothed));
  CHECK(residual.norm() < 1e-10 * (S.transpose() * (L * poisson)).norm());
  const double plain_error = fem::relative_l2_error(u_plain, poisson, M);
  const double smoothed_error = fem::relative_l2_error(u_smoothed, poisson, M);
  UNSCOPED_INFO("Poisson relative L2 error: barycentric " << plain_error << ", smoothed " << smoothed_error);
  CHECK(smoothed_error < 0.7 * plain_error);
  const Eigen::VectorXd heat = fem::HeatSolver(L, M, 0.01).integrate(f, 10);
  const double heat_plain = fem::relative_l2_error(
      fem::ProxyHeatSolver(plain, 0.01, fem::RestrictionKind::l2_projection).integrate(f, 10), heat, M);
  const double heat_smoothed = fem::relative_l2_error(
      fem::ProxyHeatSolver(smoothed, 0.01, fem::RestrictionKind::l2_projection).integrate(f, 10), heat, M);
  UNSCOPED_INFO("heat relative L2 error: barycentric " << heat_plain << ", smoothed " << heat_smoothed);
  CHECK(heat_smoothed < heat_plain);

  // Coarse marching interpolates with the barycentric P either way: the same distances.
  Eigen::Index source = 0;
  fine.V.col(2).maxCoeff(&source);
  const std::vector<int> sources{static_cast<int>(source)};
  CHECK(fem::max_abs_error(fem::ProxyGeodesicSolver(smoothed).distance(sources),
                           fem::ProxyGeodesicSolver(plain).distance(sources)) == 0.0);

  // What a smoothed P cannot do: intrinsic coarse operators, Dirichlet vertices.
  CHECK_THROWS_AS(fem::CoarseProxy(ice::intrinsic_mesh(fine.F, fine_lengths), ice::intrinsic_mesh(coarse.F, coarse_lengths), P, {fem::CoarseOperatorKind::intrinsic, fem::MassKind::lumped, fem::ProlongationKind::smoothed}),
                  std::invalid_argument);
  const int fixed = static_cast<int>(source);
  REQUIRE(plain.coarse_vertex_of(fixed) >= 0);
  CHECK_NOTHROW(fem::ProxyPoissonSolver(plain, {fixed}));
  CHECK_THROWS_AS(fem::ProxyPoissonSolver(smoothed, {fixed}), std::invalid_argument);
}

TEST_CASE("the coarse heat method refuses a smoothed prolongation", "[fem][coarse_proxy]") {
  // Its sources' weights would be negative, and its distances through the smoothed space were 6x
  // less accurate (2.4 % against 0.37 % mean error here); marching reads the barycentric P.
  const NestedSpheres s = nested_spheres(2);
  const fem::CoarseProxy proxy(ice::intrinsic_mesh(s.fine.F, s.fine_lengths), ice::intrinsic_mesh(s.coarse.F, s.coarse_lengths), s.P, {fem::CoarseOperatorKind::galerkin, fem::MassKind::lumped, fem::ProlongationKind::smoothed});
  fem::ProxyGeodesicOptions heat_method;
  heat_method.method = fem::CoarseDistanceMethod::heat_method;
  CHECK_THROWS_AS(fem::ProxyGeodesicSolver(proxy, heat_method), std::invalid_argument);
  CHECK_THROWS_AS(fem::ProxyGeodesicSolver(proxy, proxy.coarse_heat_method_operators()), std::invalid_argument);
  CHECK_NOTHROW(fem::ProxyGeodesicSolver(proxy));
}

TEST_CASE("the marching's subdivision keeps each edge's midpoint apart, loop edges and parallel edges too",
          "[fem][coarse_proxy]") {
  // A flat 1 x 0.7 torus of one vertex and two faces (three loop edges). One subdivision turns each
  // loop into two parallel edges of one length (vertex -> midpoint); pairing sides by length alone
  // would give the next subdivision one midpoint for both, joining two places of the torus. The
  // gluing carried from level to level keeps χ = 0 and every vertex flat.
  ice::Faces F(2, 3);
  F << 0, 0, 0, 0, 0, 0;
  const double diagonal = std::sqrt(1.0 + 0.49);
  ice::FaceLengths L(2, 3);
  L << 1.0, 0.7, diagonal, diagonal, 1.0, 0.7;  // (0,0)->(1,0)->(1,.7) and (0,0)->(1,.7)->(0,.7)
  fem::detail::SubdividedMesh mesh{{F, L, {}, 1}, {}};
  for (int level = 1; level <= 3; ++level) {
    mesh = fem::detail::subdivide_midpoints(mesh.F, mesh.L, mesh.vertex_count, mesh.twin);
    const Eigen::Index faces = mesh.F.rows(), edges = 3 * faces / 2;
    CHECK(mesh.vertex_count - edges + faces == 0);  // χ of the torus
    const Eigen::MatrixXd angles = fem::corner_angles(mesh.L);
    Eigen::VectorXd angle_sum = Eigen::VectorXd::Zero(mesh.vertex_count);
    for (Eigen::Index f = 0; f < faces; ++f)
      for (int k = 0; k < 3; ++k) angle_sum[mesh.F(f, k)] += angles(f, k);
    CHECK((angle_sum.array() - 2 * M_PI).abs().maxCoeff() < 1e-12);
    REQUIRE(mesh.twin.size() == static_cast<std::size_t>(3 * faces));
    for (std::size_t side = 0; side < mesh.twin.size(); ++side) {  // a closed surface: every side glued, both ways
      const ice::Index other = mesh.twin[side];
      REQUIRE(other >= 0);
      CHECK(mesh.twin[static_cast<std::size_t>(other)] == static_cast<ice::Index>(side));
      const auto f = static_cast<Eigen::Index>(side / 3), g = static_cast<Eigen::Index>(other / 3);
      const int k = static_cast<int>(side % 3), j = static_cast<int>(other % 3);
      CHECK(mesh.L(f, k) == mesh.L(g, j));
      CHECK(mesh.F(f, k) == mesh.F(g, (j + 1) % 3));  // opposite directions
      CHECK(mesh.F(f, (k + 1) % 3) == mesh.F(g, j));
    }
  }
}

TEST_CASE("curvature-corrected coarse lengths: unchanged where flat, exp(K l^2/divisor) where curved", "[fem][coarse_proxy]") {
  // Flat (a planar disk): no interior vertex carries curvature, boundary vertices count none.
  {
    const ice::TriangleMesh disk = equilateral_hexagon(6);
    const auto [fine, P] = midpoint_split(disk);
    const ice::FaceLengths coarse_lengths = ice::face_lengths_from_positions(disk.V, disk.F);
    const ice::FaceLengths corrected = fem::curvature_corrected_lengths(ice::intrinsic_mesh(fine), ice::intrinsic_mesh(disk.F, coarse_lengths), P);
    CHECK((corrected - coarse_lengths).cwiseAbs().maxCoeff() < 1e-12);
    CHECK(fem::angle_defects(ice::intrinsic_mesh(fine)).cwiseAbs().maxCoeff() < 1e-12);
  }
  // A closed convex surface with P = identity: every edge lengthened by exp(K l²/divisor), K the two
  // ends' angle defects over their areas (the divisor the proxy's marching takes by default, or the
  // oracle's); Gauss–Bonnet holds for the defects.
  {
    const ice::TriangleMesh sphere = ice::make_icosphere(2);
    const ice::FaceLengths L = ice::face_lengths_from_positions(sphere.V, sphere.F);
    const Eigen::VectorXd defect = fem::angle_defects(ice::intrinsic_mesh(sphere.F, L, sphere.V.rows()));
    CHECK(defect.sum() == Approx(4 * 3.141592653589793).epsilon(1e-12));
    const Eigen::VectorXd area = fem::lumped_vertex_areas(ice::intrinsic_mesh(sphere.F, L));
    const ice::FaceLengths by_default = fem::curvature_corrected_lengths(ice::intrinsic_mesh(sphere.F, L), ice::intrinsic_mesh(sphere.F, L), identity(sphere.V.rows()));
    const ice::FaceLengths for_oracle =
        fem::curvature_corrected_lengths(ice::intrinsic_mesh(sphere.F, L), ice::intrinsic_mesh(sphere.F, L), identity(sphere.V.rows()), fem::kOracleCorrectionDivisor);
    for (Eigen::Index f = 0; f < sphere.F.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int u = sphere.F(f, k), w = sphere.F(f, (k + 1) % 3);
        const double density = (defect(u) + defect(w)) / (area(u) + area(w));
        CHECK(by_default(f, k) == Approx(L(f, k) * std::exp(density * L(f, k) * L(f, k) / 48)).epsilon(1e-12));
        CHECK(for_oracle(f, k) == Approx(L(f, k) * std::exp(density * L(f, k) * L(f, k) / 24)).epsilon(1e-12));
        CHECK(by_default(f, k) > L(f, k));
      }
    CHECK_THROWS_AS(fem::curvature_corrected_lengths(ice::intrinsic_mesh(sphere.F, L), ice::intrinsic_mesh(sphere.F, L), identity(sphere.V.rows()), 0.0),
                    std::invalid_argument);
  }
  CHECK_THROWS_AS(fem::curvature_corrected_lengths(ice::intrinsic_mesh(ice::Faces(0, 3), ice::FaceLengths(0, 3)), ice::intrinsic_mesh(ice::Faces::Constant(1, 3, 5), ice::FaceLengths::Ones(1, 3)), fem::SparseMatrix(3, 3)),
                  std::invalid_argument);
}

TEST_CASE("curvature-corrected lengths bring coarse marching nearer the sphere's geodesics", "[fem][coarse_proxy]") {
  // Coarse faces are flat: with the great-circle lengths of their edges they shorten the paths that
  // cross them (a spherical triangle's medians are (1 + K s²/24) times its flat twin's). Corrected,
  // the distances from the fine vertices' points approach the great-circle distances.
  const NestedSpheres lower = nested_spheres(1), upper = nested_spheres(2);
  const fem::SparseMatrix P = upper.P * lower.P;  // icosphere(3) → icosphere(1): rows in one coarse face
  ice::FaceLengths arcs = lower.coarse_lengths;
  for (Eigen::Index f = 0; f < arcs.rows(); ++f)
    for (int k = 0; k < 3; ++k) arcs(f, k) = 2 * std::asin(arcs(f, k) / 2);  // unit sphere: chord → arc
  const ice::TriangleMesh& fine = upper.fine;
  const ice::FaceLengths corrected = fem::curvature_corrected_lengths(ice::intrinsic_mesh(fine.F, upper.fine_lengths), ice::intrinsic_mesh(lower.coarse.F, arcs), P);
  double error_plain = 0, error_corrected = 0;
  for (int source : {0, 5, 200}) {
    Eigen::VectorXd exact(fine.V.rows());
    for (Eigen::Index v = 0; v < fine.V.rows(); ++v)
      exact(v) = std::acos(std::clamp(fine.V.row(v).normalized().dot(fine.V.row(source).normalized()), -1.0, 1.0));
    error_plain += fem::distance_errors(fem::ProxyGeodesicSolver(ice::intrinsic_mesh(lower.coarse.F, arcs), P, 2).distance({source}), exact).mean_relative;
    error_corrected += fem::distance_errors(fem::ProxyGeodesicSolver(ice::intrinsic_mesh(lower.coarse.F, corrected), P, 2).distance({source}), exact).mean_relative;
  }
  INFO("mean error, plain " << error_plain / 3 << ", corrected " << error_corrected / 3);
  CHECK(error_corrected < 0.75 * error_plain);
}

namespace {

// A cone of total angle `angle` around its apex (vertex 0), as a polar grid of `rings` rings of
// `spokes` vertices at radii 1, 2, …: the lengths are those of the cone's development (each face
// spans angle / spokes < π), so every vertex but the apex is flat.
struct Cone {
  ice::Faces F;
  ice::FaceLengths L;
  std::vector<double> radius, polar;  // per vertex: distance from the apex, angle in the development
};

Cone polar_cone(double angle, int rings, int spokes) {
  Cone cone;
  cone.radius.push_back(0);
  cone.polar.push_back(0);
  for (int ring = 1; ring <= rings; ++ring)
    for (int spoke = 0; spoke < spokes; ++spoke) {
      cone.radius.push_back(ring);
      cone.polar.push_back(angle * spoke / spokes);
    }
  const auto vertex = [&](int ring, int spoke) { return ring == 0 ? 0 : 1 + (ring - 1) * spokes + spoke % spokes; };
  std::vector<std::array<int, 3>> faces;
  for (int spoke = 0; spoke < spokes; ++spoke) {
    faces.push_back({0, vertex(1, spoke), vertex(1, spoke + 1)});
    for (int ring = 1; ring < rings; ++ring) {
      faces.push_back({vertex(ring, spoke), vertex(ring + 1, spoke), vertex(ring + 1, spoke + 1)});
      faces.push_back({vertex(ring, spoke), vertex(ring + 1, spoke + 1), vertex(ring, spoke + 1)});
    }
  }
  cone.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  cone.L.resize(static_cast<Eigen::Index>(faces.size()), 3);
  const double step = angle / spokes;
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::size_t>(faces[f][static_cast<std::size_t>(k)]);
      const auto b = static_cast<std::size_t>(faces[f][static_cast<std::size_t>((k + 1) % 3)]);
      cone.F(static_cast<Eigen::Index>(f), k) = static_cast<int>(a);
      // Neighbours differ in angle by 0 or one step (the seam's by angle − step: the same step).
      const double turn = std::abs(cone.polar[a] - cone.polar[b]) > step * 1.5 ? step : std::abs(cone.polar[a] - cone.polar[b]);
      cone.L(static_cast<Eigen::Index>(f), k) =
          std::sqrt(cone.radius[a] * cone.radius[a] + cone.radius[b] * cone.radius[b] - 2 * cone.radius[a] * cone.radius[b] * std::cos(turn));
    }
  return cone;
}

// The geodesic distance on the cone between two of its points: straight in the development where
// they are less than a half turn apart around the apex (the short way), else through the apex.
double cone_distance(double angle, double r, double phi, double s, double psi) {
  double apart = std::fmod(std::abs(phi - psi), angle);
  apart = std::min(apart, angle - apart);
  return apart < 3.141592653589793 ? std::sqrt(r * r + s * s - 2 * r * s * std::cos(apart)) : r + s;
}

}  // namespace

TEST_CASE("coarse marching with tracked sources: exact on cones, convex and saddle", "[fem][coarse_proxy]") {
  // Every vertex but the apex is flat: straight lines carried across many faces (7 spokes: wide,
  // obtuse faces) are exact, and only paths around the apex bend — behind a saddle apex (angle >
  // 2π) every path to its shadow runs through it, and the lines that pass it on the wrong side are
  // not paths (taken, they would be too short). The plain marching is exact here too (one cone:
  // its planar updates' corners are consistent); where it is not, on coarse meshes whose every
  // vertex is a cone, the accuracy protocol measures the difference (docs/measurements.md, "Tracked
  // virtual sources; the planar check").
  for (const double angle : {1.5 * 3.141592653589793, 2.6 * 3.141592653589793}) {
    const Cone cone = polar_cone(angle, 10, 7);
    const auto n = static_cast<Eigen::Index>(cone.radius.size());
    const fem::detail::MarchingMesh mesh(cone.F, cone.L, n);
    fem::detail::CoarseMarcher tracked(mesh, /*reopen=*/true, /*track_sources=*/true), plain(mesh, /*reopen=*/true);
    for (const int source : {5, 1 + 6 * 7 + 3}) {
      INFO("angle " << angle << ", source " << source);
      std::vector<double> with_tracking, without;
      tracked.run(source, with_tracking);
      plain.run(source, without);
      double tracked_error = 0, plain_error = 0, largest = 0;
      for (Eigen::Index v = 0; v < n; ++v) {
        const auto i = static_cast<std::size_t>(v), s = static_cast<std::size_t>(source);
        const double exact = cone_distance(angle, cone.radius[i], cone.polar[i], cone.radius[s], cone.polar[s]);
        largest = std::max(largest, exact);
        tracked_error = std::max(tracked_error, std::abs(with_tracking[i] - exact));
        plain_error = std::max(plain_error, std::abs(without[i] - exact));
      }
      INFO("largest error, tracked " << tracked_error / largest << ", plain " << plain_error / largest);
      CHECK(tracked_error < 1e-5 * largest);  // (the faces' layouts are floats)
      CHECK(plain_error < 1e-5 * largest);
    }
  }
}
