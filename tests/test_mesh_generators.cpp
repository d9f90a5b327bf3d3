// Procedural meshes and Loop subdivision: topology (Euler characteristic, closedness, orientation),
// counts, and geometry (radius, volume, planarity, affine invariance).
#include <catch2/catch.hpp>

#include <cmath>
#include <map>
#include <set>
#include <utility>

#include <Eigen/Geometry>

#include "ice/triangle_geometry.h"
#include "ice/mesh_generators.h"
#include "mesh_figures.h"

namespace {

using ice::kPi;

/// Directed-edge census computed independently of the library's edge code.
struct Census {
  long vertices = 0, edges = 0, faces = 0;
  long boundary_edges = 0;
  bool edge_manifold = true;        ///< no edge with more than two faces
  bool consistently_oriented = true;  ///< no directed edge used twice
  long euler() const { return vertices - edges + faces; }
};

Census census(const ice::TriangleMesh& mesh) {
  Census c;
  c.vertices = mesh.V.rows();
  c.faces = mesh.F.rows();
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++directed[{mesh.F(f, k), mesh.F(f, (k + 1) % 3)}];
  std::map<std::pair<int, int>, int> undirected;
  for (const auto& [edge, count] : directed) {
    if (count > 1) c.consistently_oriented = false;
    undirected[{std::min(edge.first, edge.second), std::max(edge.first, edge.second)}] += count;
  }
  c.edges = static_cast<long>(undirected.size());
  for (const auto& [edge, count] : undirected) {
    if (count > 2) c.edge_manifold = false;
    if (count == 1) ++c.boundary_edges;
  }
  return c;
}

using ice_test::signed_volume;

/// Every vertex index is used by some face and lies in range.
bool all_vertices_referenced(const ice::TriangleMesh& mesh) {
  std::set<int> used;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      if (mesh.F(f, k) < 0 || mesh.F(f, k) >= mesh.V.rows()) return false;
      used.insert(mesh.F(f, k));
    }
  return static_cast<Eigen::Index>(used.size()) == mesh.V.rows();
}

void require_closed_oriented(const ice::TriangleMesh& mesh, long euler) {
  const Census c = census(mesh);
  REQUIRE(all_vertices_referenced(mesh));
  REQUIRE(c.edge_manifold);
  REQUIRE(c.consistently_oriented);
  REQUIRE(c.boundary_edges == 0);
  REQUIRE(c.euler() == euler);
  REQUIRE(signed_volume(mesh) > 0);
}

double min_corner_angle(const ice::TriangleMesh& mesh) {
  double smallest = kPi;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.V.row(mesh.F(f, k));
      const Eigen::Vector3d e1 = Eigen::Vector3d(mesh.V.row(mesh.F(f, (k + 1) % 3))) - p;
      const Eigen::Vector3d e2 = Eigen::Vector3d(mesh.V.row(mesh.F(f, (k + 2) % 3))) - p;
      smallest = std::min(smallest, std::atan2(e1.cross(e2).norm(), e1.dot(e2)));
    }
  return smallest;
}

}  // namespace

TEST_CASE("icosphere: counts, sphere of genus 0, vertices on the sphere", "[mesh_generators]") {
  for (int s = 0; s <= 3; ++s) {
    const double radius = 1.7;
    const ice::TriangleMesh mesh = ice::make_icosphere(s, radius);
    const long faces = 20L << (2 * s);
    REQUIRE(mesh.F.rows() == faces);
    REQUIRE(mesh.V.rows() == faces / 2 + 2);
    require_closed_oriented(mesh, 2);
    for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) REQUIRE(mesh.V.row(v).norm() == Approx(radius));
    // Inscribed polyhedron: volume below the ball's and approaching it.
    const double ball = 4.0 / 3.0 * kPi * radius * radius * radius;
    REQUIRE(signed_volume(mesh) < ball);
    if (s == 3) REQUIRE(signed_volume(mesh) > 0.97 * ball);
  }
  REQUIRE_THROWS_AS(ice::make_icosphere(-1), std::invalid_argument);
}

TEST_CASE("torus: genus 1, outward, volume close to 2π²Rr²", "[mesh_generators]") {
  const ice::TriangleMesh mesh = ice::make_torus(48, 24, 2.0, 0.5);
  REQUIRE(mesh.V.rows() == 48 * 24);
  REQUIRE(mesh.F.rows() == 2 * 48 * 24);
  require_closed_oriented(mesh, 0);
  const double exact = 2.0 * kPi * kPi * 2.0 * 0.5 * 0.5;
  REQUIRE(signed_volume(mesh) == Approx(exact).epsilon(0.02));
  REQUIRE_THROWS_AS(ice::make_torus(10, 10, 0.5, 1.0), std::invalid_argument);
}

TEST_CASE("flat disk: planar, counter-clockwise, one boundary circle, well shaped", "[mesh_generators]") {
  for (double jitter : {0.0, 0.25}) {
    const int rings = 8;
    const ice::TriangleMesh mesh = ice::make_flat_disk(rings, 2.0, jitter, 7);
    const Census c = census(mesh);
    REQUIRE(mesh.V.rows() == 1 + 3 * rings * (rings + 1));
    REQUIRE(mesh.F.rows() == 6 * rings * rings);
    REQUIRE(all_vertices_referenced(mesh));
    REQUIRE(c.edge_manifold);
    REQUIRE(c.consistently_oriented);
    REQUIRE(c.euler() == 1);
    REQUIRE(c.boundary_edges == 6 * rings);
    REQUIRE(mesh.V.col(2).cwiseAbs().maxCoeff() == 0.0);
    double area = 0;
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
      const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)),
                            d = mesh.V.row(mesh.F(f, 2));
      const double signed_area = 0.5 * (b - a).cross(d - a).z();
      REQUIRE(signed_area > 0);
      area += signed_area;
    }
    // Inscribed polygon of 6·rings sides, up to the jitter of interior vertices (which keeps area).
    REQUIRE(area == Approx(0.5 * 6 * rings * 4.0 * std::sin(2 * kPi / (6 * rings))));
    REQUIRE(min_corner_angle(mesh) > (jitter > 0 ? 0.3 : 0.5));  // ≥ 30° without jitter
  }
  // Jitter is reproducible from the seed and differs between seeds.
  const ice::TriangleMesh a = ice::make_flat_disk(5, 1.0, 0.2, 3), b = ice::make_flat_disk(5, 1.0, 0.2, 3);
  const ice::TriangleMesh c = ice::make_flat_disk(5, 1.0, 0.2, 4);
  REQUIRE(a.V == b.V);
  REQUIRE(a.V != c.V);
}

TEST_CASE("genus-2 voxel plate: genus 2, outward, volume 13", "[mesh_generators]") {
  for (int cells : {1, 2, 3}) {
    const ice::TriangleMesh mesh = ice::make_genus2(cells, 0.5);
    require_closed_oriented(mesh, -2);
    REQUIRE(signed_volume(mesh) == Approx(13.0 * 0.125));
  }
}

TEST_CASE("Loop subdivision: counts, topology, boundary and affine invariance", "[mesh_generators]") {
  SECTION("closed meshes keep topology; V' = V + E, F' = 4F") {
    for (const ice::TriangleMesh& coarse :
         {ice::make_icosphere(1), ice::make_torus(12, 8, 2.0, 0.7), ice::make_genus2(1)}) {
      const Census before = census(coarse);
      const ice::TriangleMesh fine = ice::loop_subdivide(coarse, 1);
      REQUIRE(fine.V.rows() == before.vertices + before.edges);
      REQUIRE(fine.F.rows() == 4 * before.faces);
      require_closed_oriented(fine, before.euler());
      const ice::TriangleMesh finer = ice::loop_subdivide(coarse, 2);
      REQUIRE(finer.F.rows() == 16 * before.faces);
      require_closed_oriented(finer, before.euler());
    }
  }
  SECTION("the limit surface of a convex polyhedron lies inside it") {
    const ice::TriangleMesh icosahedron = ice::make_icosphere(0);
    const ice::TriangleMesh fine = ice::loop_subdivide(icosahedron, 3);
    for (Eigen::Index v = 0; v < fine.V.rows(); ++v) REQUIRE(fine.V.row(v).norm() <= 1.0 + 1e-12);
    REQUIRE(signed_volume(fine) < signed_volume(icosahedron));
    REQUIRE(signed_volume(fine) > 0.5 * signed_volume(icosahedron));
  }
  SECTION("disk: stays planar, boundary refined as a curve, old vertices keep their indices") {
    const ice::TriangleMesh disk = ice::make_flat_disk(4, 1.0, 0.2, 11);
    const Census before = census(disk);
    const ice::TriangleMesh fine = ice::loop_subdivide(disk, 2);
    const Census after = census(fine);
    REQUIRE(after.euler() == 1);
    REQUIRE(after.consistently_oriented);
    REQUIRE(after.boundary_edges == 4 * before.boundary_edges);
    REQUIRE(fine.V.col(2).cwiseAbs().maxCoeff() == 0.0);
    // The centre vertex is interior and valence 6 with a symmetric ring before jitter; after jitter it
    // moves, but the boundary of a regular polygon shrinks only towards the circle's inside.
    for (Eigen::Index v = 0; v < fine.V.rows(); ++v) REQUIRE(fine.V.row(v).norm() <= 1.0 + 1e-12);
  }
  SECTION("commutes with affine maps") {
    const ice::TriangleMesh mesh = ice::make_genus2(1);
    Eigen::Matrix3d A;
    A << 1.0, 0.3, -0.2, 0.1, 0.8, 0.4, -0.5, 0.2, 1.3;
    const Eigen::RowVector3d shift(0.3, -1.0, 2.0);
    ice::TriangleMesh mapped = mesh;
    mapped.V = (mesh.V * A.transpose()).rowwise() + shift;
    const ice::TriangleMesh a = ice::loop_subdivide(mapped, 2);
    ice::TriangleMesh b = ice::loop_subdivide(mesh, 2);
    b.V = (b.V * A.transpose()).rowwise() + shift;
    REQUIRE(a.F == b.F);
    REQUIRE((a.V - b.V).cwiseAbs().maxCoeff() < 1e-12);
  }
  SECTION("rejects non-manifold edges") {
    ice::TriangleMesh fan;
    fan.V.setRandom(5, 3);
    fan.F.resize(3, 3);
    fan.F << 0, 1, 2, 1, 0, 3, 0, 1, 4;
    REQUIRE_THROWS_AS(ice::loop_subdivide(fan, 1), std::invalid_argument);
  }
}
