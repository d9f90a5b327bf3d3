// Validation report and repair on meshes built in code, and the loading policy on small hand-written files.
#include <catch2/catch.hpp>

#include <Eigen/Geometry>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include <unistd.h>

#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_generators.h"
#include "ice/triangle_geometry.h"
#include "mesh_figures.h"
#include "test_support.h"
#include "ice/mesh_io.h"
#include "ice/mesh_repair.h"
#include "ice/mesh_validation.h"

namespace fs = std::filesystem;

namespace {

using ice_test::refusal;
using ice_test::signed_volume;

ice::TriangleMesh two_disjoint_spheres() {
  const ice::TriangleMesh a = ice::make_icosphere(1);
  ice::TriangleMesh m;
  m.V.resize(2 * a.V.rows(), 3);
  m.V << a.V, (a.V.rowwise() + Eigen::RowVector3d(3, 0, 0));
  m.F.resize(2 * a.F.rows(), 3);
  m.F << a.F, (a.F.array() + static_cast<int>(a.V.rows())).matrix();
  return m;
}

}  // namespace

TEST_CASE("validation: topology of generated surfaces", "[validation]") {
  struct Case {
    const char* name;
    ice::TriangleMesh mesh;
    long chi;
    std::size_t loops;
    int genus;
  };
  const Case cases[] = {{"icosphere", ice::make_icosphere(2), 2, 0, 0},
                        {"torus", ice::make_torus(24, 12, 2.0, 0.5), 0, 0, 1},
                        {"genus-2", ice::make_genus2(2), -2, 0, 2},
                        {"disk", ice::make_flat_disk(5, 1.0, 0.2), 1, 1, 0},
                        {"subdivided torus", ice::loop_subdivide(ice::make_torus(12, 6, 2.0, 0.5), 1), 0, 0, 1}};
  for (const Case& c : cases) {
    INFO(c.name);
    const ice::ValidationReport r = ice::validate_mesh(c.mesh);
    CHECK(r.clean());
    CHECK(r.defects().empty());
    CHECK(r.components.size() == 1);
    CHECK(r.euler_characteristic == c.chi);
    CHECK(r.n_boundary_loops == c.loops);
    CHECK(r.genus == c.genus);
    CHECK(r.n_edges == static_cast<std::size_t>(c.mesh.V.rows() + c.mesh.F.rows() - c.chi));
  }
}

TEST_CASE("validation: several components are reported, not refused", "[validation]") {
  const ice::ValidationReport r = ice::validate_mesh(two_disjoint_spheres());
  CHECK(r.clean());
  CHECK(r.components.size() == 2);
  CHECK(r.euler_characteristic == 4);
  CHECK(r.genus == 0);
  for (const auto& c : r.components) CHECK(c.genus == 0);
}

TEST_CASE("validation: the zero-area test is scale and translation invariant", "[validation]") {
  ice::TriangleMesh tiny_far = ice::make_icosphere(2, 1e-3);
  tiny_far.V.array() += 1e6;
  CHECK(ice::validate_mesh(tiny_far).zero_area_faces.empty());

  ice::TriangleMesh huge = ice::make_icosphere(2, 1e8);
  CHECK(ice::validate_mesh(huge).zero_area_faces.empty());

  // A needle whose apex sits 1e-13 (relative) off the base line is degenerate at any scale.
  for (double scale : {1e-6, 1.0, 1e6}) {
    const Eigen::Vector3d a(0, 0, 0), b(scale, 0, 0), c(0.5 * scale, 1e-13 * scale, 0);
    CHECK(ice::is_zero_area_triangle(a, b, c, scale));
    CHECK_FALSE(ice::is_zero_area_triangle(a, b, Eigen::Vector3d(0.5 * scale, 1e-6 * scale, 0), scale));
  }
}

TEST_CASE("validation: each defect is counted and located", "[validation]") {
  const ice::TriangleMesh sphere = ice::make_icosphere(1);
  const int nv = static_cast<int>(sphere.V.rows());

  SECTION("flipped face: three inconsistent edges, repair flips it back") {
    ice::TriangleMesh m = sphere;
    std::swap(m.F(7, 1), m.F(7, 2));
    const ice::ValidationReport r = ice::validate_mesh(m);
    CHECK(r.inconsistent_edges.count == 3);
    CHECK(r.orientable());
    CHECK_FALSE(r.clean());
    const ice::RepairResult fixed = ice::repair_mesh(ice::to_polygon_soup(m));
    CHECK(fixed.report.clean());
    CHECK(fixed.log.flipped_faces == 1);
    CHECK(fixed.soup.polygons[7] == std::vector<int>{sphere.F(7, 1), sphere.F(7, 2), sphere.F(7, 0)});  // a rotation of the original
  }
  SECTION("inside-out inconsistent sphere is re-oriented outwards") {
    ice::TriangleMesh m = sphere;
    m.F.col(1).swap(m.F.col(2));  // all inward
    std::swap(m.F(3, 1), m.F(3, 2));  // one outward
    const ice::RepairResult fixed = ice::repair_mesh(ice::to_polygon_soup(m));
    REQUIRE(fixed.report.clean());
    ice::TriangleMesh out;
    out.V = fixed.soup.V;
    out.F.resize(static_cast<Eigen::Index>(fixed.soup.polygons.size()), 3);
    for (std::size_t f = 0; f < fixed.soup.polygons.size(); ++f)
      for (int k = 0; k < 3; ++k) out.F(f, k) = fixed.soup.polygons[f][k];
    CHECK(signed_volume(out) > 0);
    CHECK(fixed.log.flipped_faces == static_cast<std::size_t>(sphere.F.rows() - 1));
  }
  SECTION("duplicate face: also makes its edges non-manifold; repair removes it") {
    ice::PolygonSoup s = ice::to_polygon_soup(sphere);
    s.polygons.push_back({sphere.F(4, 1), sphere.F(4, 2), sphere.F(4, 0)});
    const ice::ValidationReport r = ice::validate_mesh(s);
    CHECK(r.duplicate_faces.count == 1);
    CHECK(r.duplicate_faces.first == std::vector<int>{static_cast<int>(sphere.F.rows())});
    CHECK(r.non_manifold_edges.count == 3);
    const ice::RepairResult fixed = ice::repair_mesh(s);
    CHECK(fixed.log.removed_duplicate_faces == 1);
    CHECK(fixed.report.clean());
  }
  SECTION("unreferenced vertices: exact count, first few, repair keeps an index map") {
    ice::PolygonSoup s = ice::to_polygon_soup(sphere);
    s.V.conservativeResize(nv + 10, 3);
    for (int i = 0; i < 10; ++i) s.V.row(nv + i) = Eigen::RowVector3d(5 + i, 0, 0);
    // Move the extra vertices to the front so that every face index shifts.
    ice::PolygonSoup shifted;
    shifted.V.resize(s.V.rows(), 3);
    shifted.V << s.V.bottomRows(10), s.V.topRows(nv);
    for (const auto corners : s.polygons) {
      std::vector<int> poly = corners.to_vector();
      for (int& v : poly) v += 10;
      shifted.polygons.push_back(poly);
    }
    const ice::ValidationReport r = ice::validate_mesh(shifted);
    CHECK(r.unreferenced_vertices.count == 10);
    CHECK(r.unreferenced_vertices.first.size() == ice::kMaxOffenders);
    CHECK(r.unreferenced_vertices.first[0] == 0);
    const ice::RepairResult fixed = ice::repair_mesh(shifted);
    REQUIRE(fixed.report.clean());
    CHECK(fixed.log.removed_unreferenced_vertices == 10);
    REQUIRE(fixed.source_vertex.size() == static_cast<std::size_t>(nv));
    for (int i = 0; i < nv; ++i) CHECK(fixed.soup.V.row(i) == shifted.V.row(fixed.source_vertex[i]));
  }
  SECTION("non-manifold edge and pinch vertex") {
    ice::PolygonSoup fin;  // three triangles on edge 0-1
    fin.V.resize(5, 3);
    fin.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1;
    fin.polygons = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
    const ice::ValidationReport r = ice::validate_mesh(fin);
    CHECK(r.non_manifold_edges.count == 1);
    CHECK(r.non_manifold_edges.first[0] == ice::VertexPair{0, 1});
    CHECK(r.non_manifold_vertices.count == 2);
    CHECK(r.genus == -1);

    ice::TriangleMesh spheres = two_disjoint_spheres();
    const int offset = nv;
    for (Eigen::Index f = 0; f < spheres.F.rows(); ++f)  // glue vertex 0 of sphere 2 onto vertex 0 of sphere 1
      for (int k = 0; k < 3; ++k)
        if (spheres.F(f, k) == offset) spheres.F(f, k) = 0;
    const ice::ValidationReport pinch = ice::validate_mesh(spheres);
    CHECK(pinch.non_manifold_edges.empty());
    CHECK(pinch.non_manifold_vertices.count == 1);
    CHECK(pinch.non_manifold_vertices.first[0] == 0);
    CHECK(pinch.components.size() == 1);
    CHECK(pinch.unreferenced_vertices.count == 1);
  }
  SECTION("Moebius strip: manifold, non-orientable, genus undefined; repair cannot fix it") {
    ice::PolygonSoup strip;
    const int n = 12;
    strip.V.resize(2 * n, 3);
    for (int i = 0; i < n; ++i) {
      const double t = 2 * M_PI * i / n, w = 0.3 * std::cos(t / 2), h = 0.3 * std::sin(t / 2);
      strip.V.row(2 * i) << (2 + w) * std::cos(t), (2 + w) * std::sin(t), h;
      strip.V.row(2 * i + 1) << (2 - w) * std::cos(t), (2 - w) * std::sin(t), -h;
    }
    for (int i = 0; i < n; ++i) {
      const int a = 2 * i, b = 2 * i + 1;
      const bool last = i == n - 1;
      const int c = last ? 1 : 2 * i + 2, d = last ? 0 : 2 * i + 3;  // the half twist swaps the sides
      strip.polygons.push_back({a, b, d});
      strip.polygons.push_back({a, d, c});
    }
    const ice::ValidationReport r = ice::validate_mesh(strip);
    CHECK(r.manifold());
    CHECK(r.non_orientable_components == 1);
    CHECK_FALSE(r.orientable());
    CHECK(r.n_boundary_loops == 1);
    CHECK(r.genus == -1);
    CHECK_FALSE(ice::repair_mesh(strip).report.clean());
  }
  SECTION("weld: a split seam is two components until welded") {
    ice::PolygonSoup s;
    s.V.resize(6, 3);
    s.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
    s.polygons = {{0, 1, 2}, {3, 4, 5}};
    const ice::ValidationReport r = ice::validate_mesh(s);
    CHECK(r.clean());
    CHECK(r.components.size() == 2);
    CHECK(r.duplicate_positions.count == 2);
    ice::RepairOptions weld;
    weld.weld_duplicate_positions = true;
    const ice::RepairResult fixed = ice::repair_mesh(s, weld);
    CHECK(fixed.log.welded_vertices == 2);
    CHECK(fixed.report.clean());
    CHECK(fixed.report.components.size() == 1);
    CHECK(fixed.soup.V.rows() == 4);
  }
  SECTION("garbage indices never crash validation") {
    ice::PolygonSoup s = ice::to_polygon_soup(sphere);
    s.polygons.push_back({});
    s.polygons.push_back({0, 1});
    s.polygons.push_back({-5, 1, 2});
    s.polygons.push_back({0, std::numeric_limits<int>::max(), 2});
    const ice::ValidationReport r = ice::validate_mesh(s);
    CHECK(r.non_triangle_faces.count == 2);
    CHECK(r.out_of_range_faces.count == 2);
    CHECK(r.genus == 0);  // broken faces stay out of the topology
    const ice::RepairResult fixed = ice::repair_mesh(s);
    CHECK_FALSE(fixed.report.clean());
  }
}

TEST_CASE("load policy on hand-written files", "[validation][io]") {
  ice_test::TempDir dir;
  const std::string quad_obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

  SECTION("quads: refused, triangulated with repair") {
    const std::string path = dir.write("quad.obj", quad_obj + "f 1 2 3 4\n");
    CHECK_THAT(refusal(path), Catch::Contains("1 non-triangle faces") && Catch::Contains(path));
    const ice::LoadResult loaded = ice::load_mesh_with_report(path, {true, false});
    CHECK(loaded.mesh.F.rows() == 2);
    CHECK(loaded.repairs.triangulated_polygons == 1);
    CHECK(loaded.source_face == std::vector<int>{0, 0});
    CHECK(loaded.report.n_boundary_loops == 1);
  }
  SECTION("NaN coordinate: refused even with repair") {
    const std::string path = dir.write("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n");
    CHECK_THAT(refusal(path), Catch::Contains("1 vertices with non-finite coordinates (first vertices: 1)"));
    CHECK_THAT(refusal(path, {true, false}), Catch::Contains("non-finite"));
    const std::string off = dir.write("inf.off", "OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n");
    CHECK_THAT(refusal(off), Catch::Contains("non-finite"));
    const std::string ply = dir.write("nan.ply",
                                      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
    CHECK_THAT(refusal(ply), Catch::Contains("non-finite"));
  }
  SECTION("out-of-range index: refused even with repair") {
    const std::string path = dir.write("range.obj", quad_obj + "f 1 2 3\nf 1 3 9\n");
    CHECK_THAT(refusal(path), Catch::Contains("1 faces with out-of-range vertex indices (first faces: 1)"));
    CHECK_THAT(refusal(path, {true, false}), Catch::Contains("out-of-range"));
    const std::string zero = dir.write("zero.obj", quad_obj + "f 0 1 2\n");
    CHECK_THAT(refusal(zero), Catch::Contains("out-of-range"));
  }
  SECTION("repeated index: refused; repair drops the degenerate face") {
    const std::string path = dir.write("rep.obj", quad_obj + "f 1 2 3\nf 1 3 4\nf 1 3 3\n");
    CHECK_THAT(refusal(path), Catch::Contains("faces with a repeated vertex index (first faces: 2)"));
    const ice::LoadResult loaded = ice::load_mesh_with_report(path, {true, false});
    CHECK(loaded.mesh.F.rows() == 2);
    CHECK(loaded.repairs.removed_degenerate_faces == 1);
  }
  SECTION("several components load fine") {
    const std::string path = dir.write("two.obj", quad_obj + "v 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\nf 5 6 7\n");
    const std::string message = refusal(path);  // vertex 4 is unreferenced
    CHECK_THAT(message, Catch::Contains("1 unreferenced vertices (first vertices: 3)"));
    const ice::LoadResult loaded = ice::load_mesh_with_report(path, {true, false});
    CHECK(loaded.report.components.size() == 2);
    CHECK(loaded.source_vertex == std::vector<int>{0, 1, 2, 4, 5, 6});
  }
}

TEST_CASE("validation and triangulation share one degenerate-face criterion", "[validation]") {
  // A tetrahedron whose face 0 is a sliver: apex 1e-9 of the base's length off the base. Its relative
  // area (2·area/longest² = 1e-9) passes the zero-area test, but its edge lengths add up exactly in
  // double precision, so no triangulation can be built from them. The report used to call the file
  // clean and every tool then failed inside the triangulation, naming neither file nor face.
  ice::TriangleMesh tetrahedron;
  tetrahedron.V.resize(4, 3);
  tetrahedron.V << 0, 0, 0, 1, 0, 0, 0.5, 1e-9, 0, 0.5, 0.3, 0.8;
  tetrahedron.F.resize(4, 3);
  tetrahedron.F << 0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3;
  const ice::FaceLengths lengths = ice::face_lengths_from_positions(tetrahedron.V, tetrahedron.F);
  REQUIRE_FALSE(ice::triangle_inequality_holds(lengths(0, 0), lengths(0, 1), lengths(0, 2)));
  CHECK_THROWS(ice::IntrinsicTriangulation::from_mesh(tetrahedron.V, tetrahedron.F));

  const ice::ValidationReport report = ice::validate_mesh(tetrahedron);
  CHECK(report.zero_area_faces.count == 1);
  CHECK(report.zero_area_faces.first == std::vector<int>{0});
  CHECK_FALSE(report.clean());

  ice_test::TempDir dir;
  const std::string path = dir.file("sliver.off");
  ice::write_mesh(path, tetrahedron);
  CHECK_THAT(refusal(path), Catch::Contains(path) && Catch::Contains("1 zero-area faces (first faces: 0)"));
  // The repair drops it: an open surface of three faces that triangulates.
  const ice::LoadResult repaired = ice::load_mesh_with_report(path, {true, false});
  CHECK(repaired.repairs.removed_zero_area_faces == 1);
  CHECK(repaired.report.clean());
  CHECK(repaired.mesh.F.rows() == 3);
  CHECK_NOTHROW(ice::IntrinsicTriangulation::from_mesh(repaired.mesh.V, repaired.mesh.F));

  // Any face the report calls clean triangulates: random thin triangles around the threshold.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> exponent(-12, -6), unit(0, 1);
  for (int trial = 0; trial < 2000; ++trial) {
    ice::TriangleMesh t;
    t.V.resize(3, 3);
    const double height = std::pow(10.0, exponent(rng));
    t.V << 0, 0, 0, 1 + unit(rng), 0, 0, unit(rng) * 2, height, 0;
    t.F.resize(1, 3);
    t.F << 0, 1, 2;
    const bool clean = ice::validate_mesh(t).zero_area_faces.count == 0;
    const ice::FaceLengths l = ice::face_lengths_from_positions(t.V, t.F);
    const bool triangulates = ice::triangle_inequality_holds(l(0, 0), l(0, 1), l(0, 2));
    if (clean) CHECK(triangulates);
  }
}
