// Tests of the intrinsic triangulation: construction, geometry from lengths, flips, Delaunay
// flipping, flattening, removals, Δ-complex cases and exact point tracking on flat meshes.
#include <catch2/catch.hpp>

#include <cmath>
#include <numeric>
#include <random>
#include <set>

#include <Eigen/Geometry>

#include "ice/triangle_geometry.h"
#include "ice/coarsen.h"
#include "ice/error_metric.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/vertex_star.h"
#include "test_support.h"
#include "two_ring_prefetch.h"  // libice/src: the coarsener's prefetching walk

using namespace ice;

namespace {

using ice::kPi;

// Extrinsic cotangent weight of the edge (a, b) with opposite corner c: cot of the angle at c.
double extrinsic_cot(const Positions& V, int a, int b, int c) {
  const Eigen::Vector3d u = V.row(a) - V.row(c), w = V.row(b) - V.row(c);
  return u.dot(w) / u.cross(w).norm();
}

double extrinsic_area(const TriangleMesh& mesh) {
  double area = 0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  return area;
}

// Every half-edge's cotangent (of the angle opposite it) from lengths equals the one from positions.
// Lengths carry the positions' round-off, which a face with a near-zero angle amplifies by about
// 1/angle²; so the 1e-12 relative-norm check runs over faces whose angles all exceed 1e-3 rad (the
// test reports how many are left out), and every entry is checked to 1e-6 relative.
void check_cotangents_match_positions(const IntrinsicTriangulation& T, const TriangleMesh& mesh) {
  double worst = 0, difference_squared = 0, reference_squared = 0;
  int ill_conditioned = 0;
  for (Index h = 0; h < T.num_halfedge_slots(); ++h) {
    if (!T.halfedge_alive(h) || T.is_exterior(h)) continue;
    const double from_lengths = T.cotan_opposite(h);
    const double from_positions = extrinsic_cot(mesh.V, T.tail(h), T.head(h), T.tail(T.prev(h)));
    const double difference = from_lengths - from_positions;
    worst = std::max(worst, std::abs(difference) / std::max(1.0, std::abs(from_positions)));
    const double min_angle =
        std::min({T.corner_angle(h), T.corner_angle(T.next(h)), T.corner_angle(T.prev(h))});
    if (min_angle < 1e-3) {
      ++ill_conditioned;
      continue;
    }
    difference_squared += difference * difference;
    reference_squared += from_positions * from_positions;
  }
  INFO("half-edges in faces with an angle below 1e-3 rad: " << ill_conditioned);
  CHECK(ill_conditioned < T.num_faces() / 1000 + 3);
  CHECK(std::sqrt(difference_squared / reference_squared) < 1e-12);
  CHECK(worst < 1e-6);
}

// On a flat mesh every operation is an isometry of the plane: each tracked input vertex, mapped
// through its face's corners (live vertices keep their planar positions), lands where it was.
double planar_tracking_error(const IntrinsicTriangulation& T, const Positions& V) {
  double worst = 0;
  for (Index p = 0; p < T.num_input_vertices(); ++p) {
    const SurfacePoint s = T.location(p);
    if (s.is_vertex()) continue;
    Eigen::Vector2d q = Eigen::Vector2d::Zero();
    Index h = T.halfedge(s.face);
    for (int k = 0; k < 3; ++k, h = T.next(h)) q += s.bary[k] * V.row(T.tail(h)).head<2>().transpose();
    worst = std::max(worst, (q - V.row(p).head<2>().transpose()).norm());
  }
  return worst;
}

std::vector<Index> live_interior_edges(const IntrinsicTriangulation& T) {
  std::vector<Index> edges;
  for (Index h = 0; h < T.num_halfedge_slots(); h += 2)
    if (T.halfedge_alive(h) && !T.is_boundary_edge(h)) edges.push_back(h);
  return edges;
}

int random_flips(IntrinsicTriangulation& T, int attempts, std::mt19937& rng) {
  const std::vector<Index> edges = live_interior_edges(T);
  std::uniform_int_distribution<std::size_t> pick(0, edges.size() - 1);
  int flips = 0;
  for (int i = 0; i < attempts; ++i) flips += T.flip(edges[pick(rng)]);
  return flips;
}

// A square grid on [0,1]², n×n cells, triangulated along alternating diagonals: flat, with
// boundary vertices of angle π along the sides.
TriangleMesh make_square_grid(int n) {
  TriangleMesh mesh;
  mesh.V.resize((n + 1) * (n + 1), 3);
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) mesh.V.row(y * (n + 1) + x) << double(x) / n, double(y) / n, 0;
  mesh.F.resize(2 * n * n, 3);
  int f = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      if ((x + y) % 2) {
        mesh.F.row(f++) << a, b, d;
        mesh.F.row(f++) << a, d, c;
      } else {
        mesh.F.row(f++) << a, b, c;
        mesh.F.row(f++) << b, d, c;
      }
    }
  return mesh;
}

// The minimal torus: 7 vertices, 14 faces, 21 edges (every pair of vertices is an edge).
TriangleMesh make_seven_vertex_torus() {
  TriangleMesh mesh;
  mesh.V.resize(7, 3);
  // Positions only seed the lengths (a Császár-like embedding is not needed: lengths just have to
  // satisfy the triangle inequality); use points on a flat torus lifted to R^3.
  for (int i = 0; i < 7; ++i) {
    const double s = 2 * kPi * i / 7.0, t = 2 * kPi * 3 * i / 7.0;
    mesh.V.row(i) << (2 + std::cos(t)) * std::cos(s), (2 + std::cos(t)) * std::sin(s), std::sin(t);
  }
  mesh.F.resize(14, 3);
  for (int i = 0; i < 7; ++i) {
    mesh.F.row(2 * i) << i, (i + 1) % 7, (i + 3) % 7;
    mesh.F.row(2 * i + 1) << i, (i + 3) % 7, (i + 2) % 7;
  }
  return mesh;
}

bool has_self_or_multi_edge(const IntrinsicTriangulation& T) {
  std::set<std::pair<Index, Index>> seen;
  for (Index h = 0; h < T.num_halfedge_slots(); h += 2) {
    if (!T.halfedge_alive(h)) continue;
    const Index a = std::min(T.tail(h), T.head(h)), b = std::max(T.tail(h), T.head(h));
    if (a == b || !seen.insert({a, b}).second) return true;
  }
  return false;
}

}  // namespace

TEST_CASE("a triangulation built from a mesh is valid and its geometry matches the positions", "[intrinsic]") {
  const std::vector<std::pair<std::string, TriangleMesh>> meshes = {
      {"icosphere", make_icosphere(3)},
      {"torus", make_torus(24, 12, 2.0, 0.7)},
      {"disk", make_flat_disk(8, 1.0, 0.2)},
      {"genus2", make_genus2(2)},
  };
  for (const auto& [name, mesh] : meshes) {
    INFO(name);
    const auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    CHECK(T.validate() == "");
    CHECK(T.num_vertices() == mesh.V.rows());
    CHECK(T.num_faces() == mesh.F.rows());
    CHECK(T.total_area() == Approx(extrinsic_area(mesh)).epsilon(1e-12));
    CHECK(std::abs(T.total_curvature() - 2 * kPi * T.euler_characteristic()) < 1e-9);
    check_cotangents_match_positions(T, mesh);
  }
}

TEST_CASE("a large triangulation (built on several threads) is the serial build's", "[intrinsic][meshes]") {
  // spot Loop-subdivided 3 times: 187k vertices, above the size from which the build runs its
  // passes on the machine's cores. What the serial build gives, element by element: corner k of
  // face f is next^k(halfedge(f)) with tail F(f, k) and face f; an edge's length is the length of
  // its later corner (the corners in order, the last write wins); every invariant holds.
  const TriangleMesh mesh = loop_subdivide(load_mesh(ice_test::project_mesh("spot.obj")), 3);
  REQUIRE(mesh.V.rows() > 100000);
  const IntrinsicTriangulation T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  const FaceLengths L = face_lengths_from_positions(mesh.V, mesh.F);
  std::vector<double> expected(static_cast<std::size_t>(T.num_halfedge_slots() / 2), -1);
  Index wrong_corners = 0;
  for (Index f = 0; f < static_cast<Index>(mesh.F.rows()); ++f) {
    Index h = T.halfedge(f);
    for (int k = 0; k < 3; ++k, h = T.next(h)) {
      wrong_corners += T.tail(h) != mesh.F(f, k) || T.face(h) != f || T.prev(T.next(h)) != h;
      expected[static_cast<std::size_t>(h >> 1)] = L(f, k);
    }
  }
  CHECK(wrong_corners == 0);
  Index wrong_lengths = 0;
  for (std::size_t e = 0; e < expected.size(); ++e) wrong_lengths += T.length(static_cast<Index>(2 * e)) != expected[e];
  CHECK(wrong_lengths == 0);  // bit for bit
  CHECK(T.validate() == "");
}

TEST_CASE("the triangulation reproduces the extrinsic cotangents on real meshes", "[intrinsic][meshes]") {
  for (const std::string& path :
       ice_test::mesh_sweep({"spot.obj", "lion-head.off", "elephant.off", "blobby_3cc.off", "bear.off"},
                            {"camelhead.off", "fertility.off", "bunny_closed.off"})) {
    INFO(path);
    const TriangleMesh mesh = load_mesh(path);
    const auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    CHECK(T.validate() == "");
    CHECK(T.total_area() == Approx(extrinsic_area(mesh)).epsilon(1e-11));
    check_cotangents_match_positions(T, mesh);
  }
}

TEST_CASE("the constructor refuses what is not an oriented manifold", "[intrinsic]") {
  Positions V(5, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1;
  Faces three_on_an_edge(3, 3);
  three_on_an_edge << 0, 1, 2, 1, 0, 3, 0, 1, 4;
  CHECK_THROWS_WITH(IntrinsicTriangulation::from_mesh(V, three_on_an_edge), Catch::Contains("non-manifold"));
  Faces flipped(2, 3);
  flipped << 0, 1, 2, 0, 1, 3;
  CHECK_THROWS_WITH(IntrinsicTriangulation::from_mesh(V.topRows(4), flipped), Catch::Contains("orientation"));
  Faces degenerate(1, 3);
  degenerate << 0, 1, 1;
  CHECK_THROWS(IntrinsicTriangulation::from_mesh(V.topRows(2), degenerate));
}

TEST_CASE("random flips keep area, Gauss-Bonnet and every invariant", "[intrinsic][meshes]") {
  const TriangleMesh mesh = load_mesh(ice_test::project_mesh("spot.obj"));
  auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  const double area = T.total_area();
  std::mt19937 rng(7);
  const int flips = random_flips(T, 20000, rng);
  CHECK(flips > 10000);
  CHECK(T.validate() == "");
  CHECK(T.total_area() == Approx(area).epsilon(1e-10));
  CHECK(std::abs(T.total_curvature() - 2 * kPi * T.euler_characteristic()) < 1e-8);

  SECTION("flipping an edge twice restores its length") {
    double worst = 0;
    int checked = 0;
    for (Index h : live_interior_edges(T)) {
      const double before = T.length(h);
      const Index a = T.tail(h), b = T.head(h);
      if (!T.flip(h)) continue;
      REQUIRE(T.flip(h));
      CHECK(std::set<Index>{T.tail(h), T.head(h)} == std::set<Index>{a, b});
      worst = std::max(worst, std::abs(T.length(h) - before) / before);
      if (++checked == 2000) break;
    }
    CHECK(checked == 2000);
    CHECK(worst < 1e-10);
    CHECK(T.validate() == "");
  }
  SECTION("flipping to Delaunay leaves no non-Delaunay edge and no negative cotan weight") {
    T.flip_to_delaunay();
    CHECK(T.validate() == "");
    CHECK(T.total_area() == Approx(area).epsilon(1e-10));
    int bad = 0;
    double min_weight = 0;
    for (Index h = 0; h < T.num_halfedge_slots(); h += 2) {
      if (!T.halfedge_alive(h)) continue;
      bad += !T.is_delaunay(h);
      min_weight = std::min(min_weight, T.cotan_weight(h));
    }
    CHECK(bad == 0);
    CHECK(min_weight >= -1e-10);
  }
}

TEST_CASE("Δ-complexes: tiny closed meshes driven into self- and multi-edges stay valid", "[intrinsic]") {
  Positions tet_V(4, 3);
  tet_V << 1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1;
  Faces tet_F(4, 3);
  tet_F << 0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2;
  const TriangleMesh torus7 = make_seven_vertex_torus();
  const std::vector<std::pair<std::string, TriangleMesh>> meshes = {{"tetrahedron", {tet_V, tet_F}},
                                                                    {"7-vertex torus", torus7}};
  for (const auto& [name, mesh] : meshes) {
    INFO(name);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    REQUIRE(T.validate() == "");
    const double area = T.total_area();
    std::mt19937 rng(3);
    bool reached_delta_complex = false;
    int flips = 0;
    for (int round = 0; round < 2000; ++round) {
      flips += random_flips(T, 1, rng);
      // Unbounded random flips on these flat-cone metrics stretch edges without limit (lengths
      // ×1000 and angles of 1e-6 rad after ~900 flips on the tetrahedron, where round-off in areas
      // grows like ℓ³/area); whenever a face gets that thin, restore Delaunay to stay in a metric
      // where round-off is far below the tolerances checked.
      double thinnest = 1;
      for (Index f = 0; f < T.num_face_slots(); ++f) {
        const Index h = T.halfedge(f);
        thinnest = std::min(thinnest, smallest_angle_sine(T.length(h), T.length(T.next(h)), T.length(T.prev(h))));
      }
      if (thinnest < 0.01) T.flip_to_delaunay();
      reached_delta_complex = reached_delta_complex || has_self_or_multi_edge(T);
      INFO("round " << round);
      REQUIRE(T.validate() == "");
    }
    CHECK(flips > 100);
    CHECK(reached_delta_complex);
    CHECK(T.total_area() == Approx(area).epsilon(1e-9));
    T.flip_to_delaunay();
    CHECK(T.validate() == "");
  }
}

// The star's neighbours as has_distinct_neighbours defines them, checked by brute force.
bool neighbours_distinct_by_set(const VertexStar& star) {
  std::vector<Index> neighbours;
  for (const StarCorner& corner : star.corners) neighbours.push_back(corner.out_vertex);
  if (star.boundary) neighbours.push_back(star.corners.back().in_vertex);
  const std::set<Index> unique(neighbours.begin(), neighbours.end());
  return neighbours.size() <= 16 && unique.size() == neighbours.size() && unique.count(star.centre) == 0;
}

TEST_CASE("star snapshots: consecutive corners share a spoke; distinct neighbours are recognised", "[intrinsic]") {
  // The coarsener's fast paths (split weights, frame refreshes) rely on both properties; Δ-complex
  // stars (self- and multi-edges, from random flips of tiny meshes) must take the general paths.
  const TriangleMesh torus7 = make_seven_vertex_torus();
  TriangleMesh cap = make_flat_disk(4, 1.0, 0.2);
  for (Eigen::Index v = 0; v < cap.V.rows(); ++v) cap.V(v, 2) = 0.3 * cap.V(v, 0) * cap.V(v, 0);
  const std::vector<std::pair<std::string, TriangleMesh>> meshes = {
      {"7-vertex torus", torus7}, {"curved cap with boundary", cap}, {"icosphere", make_icosphere(1)}};
  for (const auto& [name, mesh] : meshes) {
    INFO(name);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    std::mt19937 rng(11);
    int simple = 0, not_simple = 0;
    VertexStar star;
    for (int round = 0; round < 300; ++round) {
      for (Index v = 0; v < T.num_input_vertices(); ++v) {
        if (!T.vertex_alive(v)) continue;
        T.read_star(v, star);
        const int count = static_cast<int>(star.corners.size());
        for (int k = 0; k + 1 < count; ++k) REQUIRE(star.corners[k].in_halfedge == (star.corners[k + 1].halfedge ^ 1));
        if (!star.boundary) REQUIRE(star.corners[count - 1].in_halfedge == (star.corners[0].halfedge ^ 1));
        const bool expected = neighbours_distinct_by_set(star);
        REQUIRE(has_distinct_neighbours(star) == expected);
        (expected ? simple : not_simple) += 1;
      }
      random_flips(T, 3, rng);
      // A flattening then exercises the frame refresh on whatever star the flips made.
      const Index v = std::uniform_int_distribution<Index>(0, T.num_input_vertices() - 1)(rng);
      T.flatten_vertex(v);
      if (round % 20 == 19) T.flip_to_delaunay();  // keeps the metric away from needle faces
      REQUIRE(T.validate() == "");
    }
    CHECK(simple > 0);
    if (name != "curved cap with boundary") CHECK(not_simple > 0);  // flips made self- or multi-edges
  }
}

TEST_CASE("a star of more than 16 neighbours is reported as not having distinct neighbours", "[intrinsic]") {
  // A flat fan of 18 triangles around vertex 0 (the contract: false beyond 16, the general paths).
  Positions V(19, 3);
  Faces F(18, 3);
  V.row(0) << 0, 0, 0;
  for (int k = 0; k < 18; ++k) {
    V.row(k + 1) << std::cos(2 * kPi * k / 18), std::sin(2 * kPi * k / 18), 0;
    F.row(k) << 0, k + 1, (k + 1) % 18 + 1;
  }
  auto T = IntrinsicTriangulation::from_mesh(V, F);
  VertexStar star;
  T.read_star(0, star);
  CHECK(star.corners.size() == 18);
  CHECK_FALSE(has_distinct_neighbours(star));
  T.read_star(1, star);  // a boundary vertex of the fan: one corner, three distinct neighbours
  CHECK(has_distinct_neighbours(star) == neighbours_distinct_by_set(star));
}

TEST_CASE("flattening makes the angle sum exactly the target and keeps the rest valid", "[intrinsic]") {
  SECTION("interior vertices of a sphere") {
    const TriangleMesh mesh = make_icosphere(2);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    for (Index v : {0, 5, 17, 100}) {
      const Index neighbour = T.head(T.vertex_halfedge(v));
      const double before = T.angle_sum(neighbour);
      const FlattenResult r = T.flatten_vertex(v);
      REQUIRE(r.success);
      CHECK(r.log_scale != 0.0);
      CHECK(std::abs(T.compute_angle_sum(v) - 2 * kPi) < 1e-12);
      CHECK(std::abs(T.angle_sum(neighbour) - before) > 1e-6);  // a neighbour's angle sum moved...
      CHECK(T.validate() == "");                                // ...and was kept current
    }
  }
  SECTION("boundary vertices of a curved cap") {
    TriangleMesh mesh = make_flat_disk(6, 1.0, 0.1);
    for (Eigen::Index v = 0; v < mesh.V.rows(); ++v)
      mesh.V(v, 2) = 0.5 * (mesh.V(v, 0) * mesh.V(v, 0) + mesh.V(v, 1) * mesh.V(v, 1));
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    int flattened = 0;
    for (Index v = 0; v < T.num_input_vertices(); ++v) {
      if (!T.is_boundary_vertex(v) || flattened == 5) continue;
      REQUIRE(T.flatten_vertex(v).success);
      CHECK(std::abs(T.compute_angle_sum(v) - kPi) < 1e-12);
      ++flattened;
    }
    CHECK(flattened == 5);
    CHECK(T.validate() == "");
  }
}

TEST_CASE("tracked points land on their planar positions after flips and removals", "[intrinsic]") {
  SECTION("jittered flat disk, interior removals") {
    const TriangleMesh mesh = make_flat_disk(12, 1.0, 0.3, 11);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    std::mt19937 rng(5);
    std::vector<Index> order(T.num_input_vertices());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    int removed = 0;
    for (Index v : order) {
      if (T.is_boundary_vertex(v)) continue;
      std::vector<Index> changed;
      if (T.remove_vertex(v, &changed) == RemovalStatus::Removed) ++removed;
      T.flip_to_delaunay_around(changed);
      if (removed % 25 == 0) random_flips(T, 50, rng);
    }
    CHECK(removed > T.num_input_vertices() / 2);
    CHECK(T.validate() == "");
    CHECK(planar_tracking_error(T, mesh.V) < 1e-10);
  }
  SECTION("square grid, boundary and interior removals") {
    const TriangleMesh mesh = make_square_grid(16);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    std::mt19937 rng(9);
    int removed_boundary = 0, removed = 0;
    for (int pass = 0; pass < 3; ++pass)
      for (Index v = 0; v < T.num_input_vertices(); ++v) {
        if (!T.vertex_alive(v)) continue;
        // Keep the four corners: their angle is π/2, and flattening them would bend the plane.
        const double x = mesh.V(v, 0), y = mesh.V(v, 1);
        if ((x == 0 || x == 1) && (y == 0 || y == 1)) continue;
        const bool boundary = T.is_boundary_vertex(v);
        std::vector<Index> changed;
        if (T.remove_vertex(v, &changed) == RemovalStatus::Removed) {
          ++removed;
          removed_boundary += boundary;
        }
        T.flip_to_delaunay_around(changed);
      }
    CHECK(removed_boundary > 30);
    CHECK(T.num_vertices() < 25);
    CHECK(T.validate() == "");
    CHECK(std::abs(T.total_area() - 1.0) < 1e-12);
    CHECK(planar_tracking_error(T, mesh.V) < 1e-10);
  }
}

TEST_CASE("removing vertices of closed and open surfaces keeps the topology", "[intrinsic]") {
  const std::vector<std::pair<std::string, TriangleMesh>> meshes = {
      {"icosphere", make_icosphere(2)}, {"torus", make_torus(16, 8, 2.0, 0.7)}, {"genus2", make_genus2(1)}};
  for (const auto& [name, mesh] : meshes) {
    INFO(name);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    const int chi = T.euler_characteristic();
    std::mt19937 rng(1);
    bool progress = true;
    int rounds = 0;
    while (progress && rounds++ < 50) {
      progress = false;
      std::vector<Index> order;
      for (Index v = 0; v < T.num_input_vertices(); ++v)
        if (T.vertex_alive(v)) order.push_back(v);
      std::shuffle(order.begin(), order.end(), rng);
      for (Index v : order) {
        std::vector<Index> changed;
        if (T.remove_vertex(v, &changed) == RemovalStatus::Removed) progress = true;
        T.flip_to_delaunay_around(changed);
      }
      REQUIRE(T.validate() == "");
    }
    CHECK(T.euler_characteristic() == chi);
    CHECK(T.num_vertices() <= (chi == 2 ? 4 : 12));
    CHECK(std::abs(T.total_curvature() - 2 * kPi * chi) < 1e-8);
    // Every removed vertex sits in a live face with coordinates in [0,1].
    for (Index p = 0; p < T.num_input_vertices(); ++p) {
      const SurfacePoint s = T.location(p);
      if (s.is_vertex()) continue;
      REQUIRE(T.face_alive(s.face));
      for (double b : s.bary) CHECK((b >= 0 && b <= 1));
    }
  }
}

TEST_CASE("without frames, removals and flips keep exact angle sums and tracked points", "[intrinsic]") {
  // Angle sums are then updated by increments (a flattening's changed corners) instead of being
  // re-accumulated: they must still match the lengths. The runs are not compared step by step with a
  // framed copy: round-off in the sums may break the exact ties of symmetric meshes differently.
  const TriangleMesh lion = load_mesh(ice_test::project_mesh("lion-head.off"));
  const TriangleMesh disk = make_flat_disk(12, 1.0, 0.3, 11);
  const std::vector<std::pair<std::string, TriangleMesh>> meshes = {
      {"icosphere", make_icosphere(3)}, {"lion-head (disk)", lion}, {"torus (Δ-complex at the end)", make_torus(12, 6, 2.0, 0.7)},
      {"flat disk", disk}};
  for (const auto& [name, mesh] : meshes) {
    INFO(name);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    const int chi = T.euler_characteristic();
    T.maintain_frames(false);
    CHECK(!T.frames_maintained());
    std::mt19937 rng(3);
    std::vector<Index> order(static_cast<std::size_t>(T.num_input_vertices()));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    int removed = 0;
    for (int round = 0; round < 3; ++round)
      for (Index v : order) {
        if (!T.vertex_alive(v) || (name == "flat disk" && T.is_boundary_vertex(v))) continue;
        std::vector<Index> changed;
        removed += T.remove_vertex(v, &changed) == RemovalStatus::Removed;
        T.flip_to_delaunay_around(changed);
        if (removed % 25 == 0) random_flips(T, 20, rng);
      }
    CHECK(removed > T.num_input_vertices() / 2);
    CHECK(T.euler_characteristic() == chi);
    CHECK(T.validate() == "");  // lengths, angle sums against the lengths, Gauss–Bonnet, tracked points
    double sum_gap = 0;
    for (Index v = 0; v < T.num_vertex_slots(); ++v)
      if (T.vertex_alive(v)) sum_gap = std::max(sum_gap, std::abs(T.angle_sum(v) - T.compute_angle_sum(v)));
    CHECK(sum_gap < 1e-11);
    if (name == "flat disk") CHECK(planar_tracking_error(T, mesh.V) < 1e-10);
    // The metric refuses a triangulation without frames, and a compacted copy too (its coordinates
    // are copies of stale ones); resuming them gives consistent ones, and coarsen() does so itself.
    CHECK_THROWS_AS(IntrinsicErrorMetric(T, 0.5), std::invalid_argument);
    IntrinsicTriangulation copy = T.compacted();
    CHECK(!copy.frames_maintained());
    CHECK(copy.validate() == "");
    CHECK_THROWS_AS(IntrinsicErrorMetric(copy, 0.5), std::invalid_argument);
    CoarsenOptions options;
    options.target_vertices = std::max<Index>(4, copy.num_vertices() / 2);
    coarsen(copy, options);
    CHECK(copy.frames_maintained());
    CHECK(copy.validate() == "");
    T.maintain_frames(true);
    CHECK(T.validate() == "");
    CHECK_NOTHROW(IntrinsicErrorMetric(T, 0.5));
  }
}

TEST_CASE("the two-ring prefetch walk meets every neighbour and second-ring vertex, and survives edits", "[intrinsic]") {
  // A closed surface, and an open one (fans that end at the boundary).
  const std::vector<std::pair<std::string, TriangleMesh>> meshes = {
      {"torus", make_torus(24, 12, 2.0, 0.7)}, {"disk", make_flat_disk(8, 1.0, 0.2)}};
  for (const auto& [name, mesh] : meshes) {
    INFO(name);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    const auto neighbours_of = [&](Index v) {
      std::set<Index> ring;
      T.for_each_outgoing(v, [&](Index h) { ring.insert(T.head(h)); });
      if (T.is_boundary_vertex(v)) {  // the last neighbour is only reached through the exterior edge
        Index last = T.vertex_halfedge(v);
        while (T.rotate_ccw(last) != kInvalid) last = T.rotate_ccw(last);
        ring.insert(T.tail(T.prev(last)));
      }
      return ring;
    };
    SECTION("coverage") {
      int checked = 0;
      for (Index v = 0; v < T.num_input_vertices(); ++v) {
        if (!T.vertex_alive(v)) continue;
        std::set<Index> first, second;
        prefetch_two_ring(T, v, [&](Index w) { first.insert(w); }, [&](Index w) { second.insert(w); });
        const std::set<Index> ring = neighbours_of(v);
        // Every interior spoke's head; at a boundary vertex the fan's last neighbour may come
        // second-hand (it is reached around the previous neighbour).
        for (Index w : ring) CHECK((first.count(w) + second.count(w)) > 0);
        std::set<Index> expected_second;
        bool small_degrees = true;
        for (Index u : ring) {
          small_degrees = small_degrees && T.degree(u) <= 7;
          for (Index w : neighbours_of(u)) expected_second.insert(w);
        }
        if (small_degrees)
          for (Index w : expected_second) CHECK((first.count(w) + second.count(w) + (w == v)) > 0);
        ++checked;
      }
      CHECK(checked == T.num_vertices());
    }
    SECTION("walks left half-way while vertices are removed and edges flipped stay inside the arrays") {
      std::mt19937 rng(3);
      std::vector<TwoRingPrefetch> walks(8);
      std::uniform_int_distribution<Index> pick(0, T.num_input_vertices() - 1);
      int visits = 0;
      const auto count = [&](Index w) {
        REQUIRE(w >= 0);
        REQUIRE(w < T.num_input_vertices());
        ++visits;
      };
      for (int round = 0; round < 4000; ++round) {
        TwoRingPrefetch& walk = walks[round % walks.size()];
        if (round % 3 == 0) {
          const Index v = pick(rng);
          if (T.vertex_alive(v)) walk.start(T, v);
        }
        if (walk.vertex() != kInvalid) walk.advance(count, count);
        const Index v = pick(rng);
        if (T.vertex_alive(v) && round % 2 == 0) {
          std::vector<Index> changed;
          T.remove_vertex(v, &changed);
          T.flip_to_delaunay_around(changed);
        }
      }
      CHECK(visits > 1000);
      CHECK(T.validate() == "");
    }
  }
}
