// Point clouds: the local Delaunay fans of ice/point_cloud.h, the loader's point sets, and solves on
// the tufted cover of the fans.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "fem/operators.h"
#include "fem/problems.h"
#include "ice/coarse_space.h"
#include "ice/mesh_io.h"
#include "ice/mesh_validation.h"
#include "ice/point_cloud.h"
#include "ice/proxy/geodesics.h"
#include "ice/proxy/poisson.h"
#include "ice/tufted_cover.h"
#include "test_support.h"

namespace {

using ice::Index;

// n points spread evenly over the unit sphere (a Fibonacci spiral).
ice::Positions sphere_points(int n) {
  ice::Positions P(n, 3);
  const double golden = ice::kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1.0 - z * z);
    P.row(i) << r * std::cos(golden * i), r * std::sin(golden * i), z;
  }
  return P;
}

double face_area(const ice::Positions& P, const ice::Faces& F, Eigen::Index f) {
  const Eigen::Vector3d a = P.row(F(f, 0)), b = P.row(F(f, 1)), c = P.row(F(f, 2));
  return 0.5 * (b - a).cross(c - a).norm();
}

}  // namespace

TEST_CASE("point cloud: a jittered grid in the plane gives its Delaunay triangulation", "[cloud]") {
  // Interior points jittered, the square's boundary points not: the fans of all points agree with the
  // Delaunay triangulation of the whole set, whose triangles tile the unit square.
  const int side = 15;
  std::mt19937 random(7);
  std::uniform_real_distribution<double> jitter(-0.3 / (side - 1), 0.3 / (side - 1));
  ice::Positions P(side * side, 3);
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) {
      const bool boundary = i == 0 || j == 0 || i + 1 == side || j + 1 == side;
      P.row(i * side + j) << double(i) / (side - 1) + (boundary ? 0.0 : jitter(random)),
          double(j) / (side - 1) + (boundary ? 0.0 : jitter(random)), 0.0;
    }
  const ice::Faces F = ice::point_cloud_triangles(P);
  double area = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) area += face_area(P, F, f);
  REQUIRE(area == Approx(1.0).epsilon(1e-12));
  REQUIRE(F.rows() == 2 * (side - 1) * (side - 1));  // Euler: 2n − 2 − (boundary points)
  std::map<std::pair<Index, Index>, int> faces_at_edge;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++faces_at_edge[std::minmax(F(f, k), F(f, (k + 1) % 3))];
  for (const auto& [edge, count] : faces_at_edge) REQUIRE(count <= 2);
  // Empty circumcircles.
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector2d a = P.row(F(f, 0)).head<2>(), b = P.row(F(f, 1)).head<2>(), c = P.row(F(f, 2)).head<2>();
    const double d = 2 * (a.x() * (b.y() - c.y()) + b.x() * (c.y() - a.y()) + c.x() * (a.y() - b.y()));
    const Eigen::Vector2d centre((a.squaredNorm() * (b.y() - c.y()) + b.squaredNorm() * (c.y() - a.y()) + c.squaredNorm() * (a.y() - b.y())) / d,
                                 (a.squaredNorm() * (c.x() - b.x()) + b.squaredNorm() * (a.x() - c.x()) + c.squaredNorm() * (b.x() - a.x())) / d);
    const double radius = (a - centre).norm();
    for (Eigen::Index i = 0; i < P.rows(); ++i) REQUIRE((P.row(i).head<2>().transpose() - centre).norm() >= radius * (1 - 1e-9));
  }
}

TEST_CASE("point cloud: no slivers along the hull of a random sample", "[cloud]") {
  // Uniform random points of the unit square: the Delaunay triangles along the hull of each point's
  // neighbourhood are slivers (angles up to ~180°) whose circumcentres lie far beyond the
  // neighbours; a fan keeps only triangles whose circumcentre lies within its farthest neighbour's
  // distance, so every triangle's circumradius is at most its corners' largest such distance.
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  ice::Positions P(2000, 3);
  for (Eigen::Index i = 0; i < P.rows(); ++i) P.row(i) << unit(random), unit(random), 0.0;
  const int neighbours = ice::PointCloudOptions{}.neighbours;
  std::vector<double> reach(static_cast<std::size_t>(P.rows()));
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    std::vector<double> distance;
    for (Eigen::Index j = 0; j < P.rows(); ++j)
      if (j != i) distance.push_back((P.row(j) - P.row(i)).norm());
    std::nth_element(distance.begin(), distance.begin() + (neighbours - 1), distance.end());
    reach[static_cast<std::size_t>(i)] = distance[static_cast<std::size_t>(neighbours - 1)];
  }
  const ice::Faces F = ice::point_cloud_triangles(P);
  double area = 0, largest_angle = 0;
  bool within_reach = true;  // one assertion, not one per face
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = P.row(F(f, 0)), b = P.row(F(f, 1)), c = P.row(F(f, 2));
    const double x = (b - c).norm(), y = (c - a).norm(), z = (a - b).norm();
    const double face = face_area(P, F, f), circumradius = x * y * z / (4 * face);
    area += face;
    const auto angle = [](const Eigen::Vector3d& u, const Eigen::Vector3d& v) {  // between u and v
      return std::atan2(u.cross(v).norm(), u.dot(v));
    };
    largest_angle = std::max({largest_angle, angle(b - a, c - a), angle(c - b, a - b), angle(a - c, b - c)});
    double corner_reach = 0;
    for (int k = 0; k < 3; ++k) corner_reach = std::max(corner_reach, reach[static_cast<std::size_t>(F(f, k))]);
    within_reach = within_reach && circumradius <= corner_reach * (1 + 1e-9);
  }
  INFO("area " << area << ", largest angle " << largest_angle * 180 / ice::kPi << " deg");
  REQUIRE(within_reach);
  REQUIRE(largest_angle < 175.0 / 180 * ice::kPi);
  REQUIRE(area > 0.95);  // only the hull's slivers are gone: the square stays covered
}

TEST_CASE("point cloud: with separate_thin_parts a tube sampled six points around is not joined across", "[cloud]") {
  // Rings of 6 jittered points (each turned half a step against the last) along a tube of radius 1,
  // as far apart as the points around: the 30 nearest neighbours reach across the tube, and by
  // default their least-squares plane and the Delaunay triangles of the projection join opposite
  // sides (edges through the axis), leaving half the surface uncovered. With the option, between the
  // rings away from the open ends the triangles are those of the tube: two per point, every edge
  // along the surface.
  constexpr int around = 6, rings = 60;
  const double step = 2 * ice::kPi / around;
  std::mt19937 random(5);
  std::uniform_real_distribution<double> jitter(-0.1, 0.1);
  ice::Positions P(around * rings, 3);
  for (int ring = 0; ring < rings; ++ring)
    for (int k = 0; k < around; ++k) {
      const double angle = (k + 0.5 * (ring % 2) + jitter(random)) * step, height = (ring + jitter(random)) * step;
      P.row(ring * around + k) << std::cos(angle), std::sin(angle), height;
    }
  const auto inner = [](Index v) { return v / around >= 2 && v / around < rings - 2; };
  // Faces between the inner rings, and the least distance of their edges' midpoints from the axis.
  const auto inner_faces = [&](const ice::Faces& F) {
    std::pair<Eigen::Index, double> result{0, std::numeric_limits<double>::infinity()};
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      if (!inner(F(f, 0)) || !inner(F(f, 1)) || !inner(F(f, 2))) continue;
      ++result.first;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d middle = 0.5 * (P.row(F(f, k)) + P.row(F(f, (k + 1) % 3))).transpose();
        result.second = std::min(result.second, middle.head<2>().norm());
      }
    }
    return result;
  };
  ice::PointCloudOptions apart;
  apart.separate_thin_parts = true;
  const auto [faces, nearest_to_axis] = inner_faces(ice::point_cloud_triangles(P, apart));
  INFO("faces between the inner rings " << faces << ", an edge's midpoint " << nearest_to_axis << " from the axis");
  CHECK(nearest_to_axis > 0.7);  // neighbours around a ring: cos(π/6 + jitter) ≥ 0.8; one skipped: 0.5
  CHECK(faces == 2 * around * (rings - 5));
  // By default the sides are joined (what the option is for).
  const auto [joined_faces, joined_nearest] = inner_faces(ice::point_cloud_triangles(P));
  INFO("by default: " << joined_faces << " faces, an edge's midpoint " << joined_nearest << " from the axis");
  CHECK(joined_nearest < 0.5);
}

TEST_CASE("point cloud: where the fans disagree, one consistent choice", "[cloud]") {
  // A square grid: every quad's corners are cocircular, each corner's fan takes its own diagonal;
  // the union would cover every quad twice. The choice keeps one triangulation of the square.
  const int side = 12;
  ice::Positions grid(side * side, 3);
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) grid.row(i * side + j) << double(i) / (side - 1), double(j) / (side - 1), 0.0;
  const ice::Faces G = ice::point_cloud_triangles(grid);
  double area = 0;
  for (Eigen::Index f = 0; f < G.rows(); ++f) area += face_area(grid, G, f);
  REQUIRE(area == Approx(1.0).epsilon(1e-12));
  REQUIRE(G.rows() == 2 * (side - 1) * (side - 1));
  // Random points on the unit sphere (clusters and near-cocircular quads in different tangent
  // planes): the triangles cover the sphere about once, almost every edge has two of them.
  std::mt19937 random(3);
  std::normal_distribution<double> normal;
  ice::Positions P(2000, 3);
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    const Eigen::Vector3d x(normal(random), normal(random), normal(random));
    P.row(i) = x.normalized().transpose();
  }
  const ice::Faces F = ice::point_cloud_triangles(P);
  double sphere_area = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) sphere_area += face_area(P, F, f);
  std::map<std::pair<Index, Index>, int> faces_at_edge;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++faces_at_edge[std::minmax(F(f, k), F(f, (k + 1) % 3))];
  std::size_t two = 0;
  for (const auto& [edge, count] : faces_at_edge) two += count == 2;
  INFO("area / 4π " << sphere_area / (4 * ice::kPi) << ", edges with two faces " << two << " of " << faces_at_edge.size());
  REQUIRE(sphere_area / (4 * ice::kPi) == Approx(1.0).epsilon(0.02));  // inscribed: a little below 1
  REQUIRE(double(two) >= 0.99 * double(faces_at_edge.size()));
  // The same faces on any thread count, and at any scale (powers of two: the same points, exactly,
  // once translated and scaled into the unit box), near the ends of the double range too.
  ice::PointCloudOptions one_thread, four_threads;
  one_thread.threads = 1;
  four_threads.threads = 4;
  REQUIRE(ice::point_cloud_triangles(P, one_thread) == F);
  REQUIRE(ice::point_cloud_triangles(P, four_threads) == F);
  REQUIRE(ice::point_cloud_triangles(P * std::ldexp(1.0, -560)) == F);
  REQUIRE(ice::point_cloud_triangles(P * std::ldexp(1.0, 500)) == F);
  REQUIRE(ice::point_cloud_triangles((P.array() + 1e6).matrix()).rows() == F.rows());
}

TEST_CASE("point cloud: a sphere's points give a robust Laplacian with the sphere's spectrum", "[cloud]") {
  const ice::TriangleMesh mesh{sphere_points(600), ice::point_cloud_triangles(sphere_points(600))};
  Eigen::Index degenerate = 0;  // counted: one assertion, not one per triangle
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    degenerate += ice::is_degenerate_triangle(mesh.V, mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2), 2.0);
  REQUIRE(degenerate == 0);
  const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay, ice::NonmanifoldInput::tufted_cover);
  REQUIRE(fine.vertex_count == 600);
  const Eigen::MatrixXd L(fem::cotan_laplacian(fine));
  const Eigen::VectorXd M = Eigen::MatrixXd(fem::mass_matrix(fine)).diagonal();
  REQUIRE((L - L.transpose()).norm() <= 1e-12 * L.norm());
  // Off-diagonal weights ≤ 0 (a maximum principle), one zero eigenvalue (the cloud is connected).
  double largest_off_diagonal = -std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < L.rows(); ++i)
    for (Eigen::Index j = 0; j < L.cols(); ++j)
      if (i != j) largest_off_diagonal = std::max(largest_off_diagonal, L(i, j));
  REQUIRE(largest_off_diagonal <= 1e-12 * L.diagonal().maxCoeff());
  // L u = λ M u: 0, then the sphere's 2 (three times) and 6 (five times), from the cover's twofold
  // operators (the ratio does not see the factor).
  const Eigen::VectorXd root = M.cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd A = root.asDiagonal() * L * root.asDiagonal();
  const Eigen::VectorXd values = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A, Eigen::EigenvaluesOnly).eigenvalues();
  REQUIRE(std::abs(values(0)) <= 1e-10 * values(values.size() - 1));
  REQUIRE(values(1) > 1e-3);
  for (int k = 1; k <= 3; ++k) REQUIRE(values(k) == Approx(2.0).epsilon(0.03));
  for (int k = 4; k <= 8; ++k) REQUIRE(values(k) == Approx(6.0).epsilon(0.03));
  // The cover's area, halved (it sees each triangle from both sides), is the sphere's to a few percent.
  REQUIRE(M.sum() / 2 == Approx(4 * ice::kPi).epsilon(0.05));
}

TEST_CASE("point cloud: Poisson through the proxy near the fine robust Laplacian's solution", "[cloud][proxy]") {
  const ice::TriangleMesh mesh{sphere_points(3000), ice::point_cloud_triangles(sphere_points(3000))};
  REQUIRE_THROWS_AS(ice::proxy::PoissonSolver(mesh), std::invalid_argument);  // needs the cover
  ice::proxy::PoissonOptions poisson;
  poisson.coarsening.coarsen.target_ratio = 0.1;
  poisson.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  const ice::proxy::PoissonSolver solver(mesh, poisson);
  Eigen::VectorXd f(mesh.V.rows());
  for (Eigen::Index i = 0; i < f.size(); ++i) f(i) = mesh.V(i, 0) * mesh.V(i, 1) + mesh.V(i, 2);  // degrees 1 and 2
  const Eigen::VectorXd u = solver.solve(f);
  const fem::SparseMatrix L = fem::cotan_laplacian(solver.fine_mesh());
  const fem::SparseMatrix M = fem::mass_matrix(solver.fine_mesh());
  const Eigen::VectorXd reference = fem::PoissonSolver::zero_mean(L, M).solve(f);
  const double error = std::sqrt((u - reference).dot(M * (u - reference)) / reference.dot(M * reference));
  INFO("relative L2 error against the fine robust Laplacian " << error);
  REQUIRE(error < 0.05);
  // And the fine solve against the sphere's: Δ⁻¹ of z is −z/2, of xy −xy/6.
  Eigen::VectorXd exact(f.size());
  for (Eigen::Index i = 0; i < f.size(); ++i) exact(i) = -(mesh.V(i, 0) * mesh.V(i, 1) / 6 + mesh.V(i, 2) / 2);
  const double sphere_error = std::sqrt((reference + exact).dot(M * (reference + exact)) / exact.dot(M * exact));
  INFO("fine against the smooth sphere " << sphere_error);
  REQUIRE(std::min((reference - exact).norm(), (reference + exact).norm()) / exact.norm() < 0.05);
}

TEST_CASE("point cloud: a large cloud is coarsened through the parallel phase, the same on any thread count",
          "[cloud][proxy]") {
  const ice::TriangleMesh mesh{sphere_points(24000), ice::point_cloud_triangles(sphere_points(24000))};
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  options.coarsen.threads = 1;
  const ice::CoarseSpace one = ice::build_coarse_space(mesh, options);
  options.coarsen.threads = 2;
  const ice::CoarseSpace two = ice::build_coarse_space(mesh, options);
  REQUIRE(one.summary.tufted_cover);
  REQUIRE(one.summary.ice);
  CHECK(one.summary.ice->parallel_removed > one.summary.ice->removed / 2);  // the default regions ran
  CHECK(one.mesh.F == two.mesh.F);
  CHECK(one.mesh.L == two.mesh.L);
  CHECK(ice_test::relative_difference(one.P, two.P) == 0.0);
  const Eigen::VectorXd row_sums = one.P * Eigen::VectorXd::Ones(one.P.cols());
  CHECK((row_sums.array() - 1).abs().maxCoeff() < 1e-12);
  CHECK(one.mesh.vertex_count < 24000 / 10);
}

TEST_CASE("point cloud: geodesics by marching and by the heat method through the proxy near the sphere's",
          "[cloud][proxy][geodesic]") {
  const ice::TriangleMesh mesh{sphere_points(3000), ice::point_cloud_triangles(sphere_points(3000))};
  ice::proxy::GeodesicOptions options;
  options.coarsening.coarsen.target_ratio = 0.1;
  options.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  // Traced lengths refuse the cover, naming it.
  options.lengths = ice::proxy::CoarseLengths::traced;
  REQUIRE_THROWS_WITH(ice::proxy::GeodesicSolver(mesh, options), Catch::Contains("tufted cover"));
  options.lengths = ice::proxy::CoarseLengths::automatic;
  // Coarse marching (the default) on the coarse mesh's own lengths, uncorrected.
  const ice::proxy::GeodesicSolver marching(mesh, options);
  REQUIRE(marching.coarse_space().summary.tufted_cover);
  REQUIRE_FALSE(marching.traced_lengths());
  REQUIRE(marching.lengths().lengths == marching.coarse_space().mesh.L);
  const Eigen::VectorXd marched = marching.distance({0});
  options.method = fem::CoarseDistanceMethod::heat_method;
  const ice::proxy::GeodesicSolver solver(mesh, options);
  REQUIRE(solver.coarse_space().summary.tufted_cover);
  const Eigen::VectorXd d = solver.distance({0});
  // The fine heat method on the cover's robust mesh (the same t rule on the fine edges), and the
  // sphere's great-circle distance from the source.
  const ice::IntrinsicMesh& fine = solver.proxy()->fine_mesh();
  const fem::HeatGeodesicSolver fine_solver(fem::heat_method_operators(fine, fem::MassKind::lumped, 1.0));
  const Eigen::VectorXd reference = fine_solver.distance({0});
  const fem::SparseMatrix& M = fine_solver.operators().mass;
  Eigen::VectorXd exact(d.size());
  for (Eigen::Index i = 0; i < d.size(); ++i)
    exact(i) = std::acos(std::clamp(mesh.V.row(0).dot(mesh.V.row(i)), -1.0, 1.0));
  const auto relative = [&M](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    return std::sqrt((a - b).dot(M * (a - b)) / b.dot(M * b));
  };
  INFO("proxy against the fine heat method " << relative(d, reference) << ", against the sphere " << relative(d, exact)
                                             << "; fine against the sphere " << relative(reference, exact));
  INFO("marching against the sphere " << relative(marched, exact));
  REQUIRE(d.allFinite());
  REQUIRE(d(0) == Approx(0.0).margin(1e-12));
  REQUIRE(relative(d, reference) < 0.05);
  REQUIRE(relative(d, exact) < 0.05);
  REQUIRE(relative(reference, exact) < 0.05);
  REQUIRE(marched.allFinite());
  REQUIRE(marched(0) == Approx(0.0).margin(1e-12));
  REQUIRE(relative(marched, exact) < relative(d, exact));  // marching: the sphere's distance, not a smoothed one
  // The distance oracle places each point by one copy on the cover: its distances from the source
  // are the sphere's as nearly as marching's.
  ice::proxy::OracleOptions oracle_options;
  oracle_options.coarsening = options.coarsening;
  const fem::DistanceOracle oracle = ice::proxy::distance_oracle(mesh, oracle_options);
  Eigen::VectorXd queried(d.size());
  for (Eigen::Index i = 0; i < d.size(); ++i) queried(i) = oracle.distance(0, static_cast<ice::Index>(i));
  INFO("oracle against the sphere " << relative(queried, exact));
  REQUIRE(relative(queried, exact) < 0.05);
}

TEST_CASE("point cloud: point files are read, refused without the option, merged with repair", "[cloud][io]") {
  using Kind = ice::MeshError::Kind;
  const ice_test::TempDir dir;
  const auto write_text = [&dir](const std::string& name, const std::string& text) { return dir.write(name, text); };
  std::string text = "# a point set\n600\n";  // a count line, as some writers put
  const ice::Positions P = sphere_points(600);
  for (Eigen::Index i = 0; i < P.rows(); ++i)
    text += std::to_string(P(i, 0)) + " " + std::to_string(P(i, 1)) + " " + std::to_string(P(i, 2)) + " 0 0 1\n";  // with normals
  const std::string xyz = write_text("cloud_sphere.xyz", text);
  const ice::MeshFile file = ice::read_mesh_file(xyz);
  REQUIRE(file.soup.V.rows() == 600);
  REQUIRE(file.soup.polygons.empty());
  REQUIRE(file.soup.V(7, 2) == Approx(P(7, 2)).margin(1e-6));

  ice_test::require_mesh_error([&] { ice::load_mesh(xyz); }, Kind::Defective, xyz, "point cloud of 600 points");
  ice_test::require_mesh_error([&] { ice::load_mesh(xyz); }, Kind::Defective, xyz, "--nonmanifold tufted");
  ice::LoadOptions options;
  options.keep_nonmanifold = true;
  const ice::LoadResult loaded = ice::load_mesh_with_report(xyz, options);
  REQUIRE(loaded.point_cloud);
  REQUIRE(loaded.mesh.V.rows() == 600);
  REQUIRE(loaded.mesh.F.rows() > 600);
  REQUIRE(loaded.report.clean_but_for_sheets());

  // A repeated point: refused naming it, merged into the first with repair.
  const std::string repeated = write_text("cloud_repeated.xyz", text + std::to_string(P(3, 0)) + " " + std::to_string(P(3, 1)) + " " +
                                                                    std::to_string(P(3, 2)) + "\n");
  ice_test::require_mesh_error([&] { ice::load_mesh(repeated, options); }, Kind::Defective, repeated, "point 600 at point 3's");
  options.repair = true;
  const ice::LoadResult merged = ice::load_mesh_with_report(repeated, options);
  REQUIRE(merged.mesh.V.rows() == 600);
  REQUIRE(merged.repairs.welded_vertices == 1);
  REQUIRE(merged.source_vertex.size() == 600);
  REQUIRE(merged.source_vertex.back() == 599);

  // Points on one line have no triangles; a short line is a read error naming it.
  const std::string line = write_text("cloud_line.xyz", "0 0 0\n1 0 0\n2 0 0\n3 0 0\n");
  ice_test::require_mesh_error([&] { ice::load_mesh(line, options); }, Kind::Defective, line, "lies on no triangle");
  const std::string short_line = write_text("cloud_short.xyz", "0 0 0\n1 0\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(short_line); }, Kind::Unreadable, short_line, "line 2");
  const std::string pwn = write_text("cloud_empty.pwn", "# nothing\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(pwn); }, Kind::Unreadable, pwn, "no vertices");
  REQUIRE_THROWS_AS(ice::point_cloud_triangles(P.topRows(2)), std::invalid_argument);
  ice::LoadOptions one_neighbour = options;
  one_neighbour.point_cloud.neighbours = 1;
  REQUIRE_THROWS_AS(ice::load_mesh(xyz, one_neighbour), std::invalid_argument);  // an option, not the file
}
