// The project's own mesh set (data/default/, made by scripts/setup.sh from data/meshes/ and CGAL's data
// archive; data/README.md): their figures, the loading policy on each, and the defects no redistributable
// file shows, written by the tests themselves. Every clone runs these: together with the sweeps of the
// other files they check each property the extended set is used for (genus > 0, boundaries, several
// components, many holes, a CAD part with needles, a large binary PLY, defective files).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "ice/triangle_geometry.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "mesh_figures.h"
#include "test_support.h"

namespace fs = std::filesystem;

namespace {

using ice::kPi;

// file, nV, nF, loops, components, NM edges, NM vertices, genus, zero-area, dup positions, inconsistent,
// unreferenced, duplicate faces, orientable. The committed meshes' rows are those of the extended set's
// README (the same files); the CGAL meshes' rows were computed by a script independent of ICE (Euler
// characteristic, boundary-edge cycles, exact position and face comparisons) and agree with ice-info.
const std::vector<ice_test::Expected> kTable = {
    {"degtri_sliding.off", 8, 8, 1, 1, 0, 0, 0, 4, 0, 0, 0, 0, true},
    {"hourglass_ico.obj", 23, 40, 0, 1, 0, 1, -1, 0, 0, 0, 0, 0, true},
    {"triple_vierbein.obj", 75, 108, 1, 1, 20, 21, -1, 0, 0, 3, 0, 0, true},
    {"cat_head.obj", 131, 248, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"eight.off", 315, 634, 0, 1, 0, 0, 2, 0, 0, 0, 0, 0, true},
    {"boxpart.obj", 451, 930, 0, 1, 0, 0, 8, 0, 0, 0, 0, 0, true},
    {"blobby_3cc.off", 1820, 3417, 4, 3, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"couplingdown.off", 1841, 3714, 0, 1, 0, 0, 9, 0, 0, 0, 0, 0, true},
    {"blobby-shuffled.off", 2027, 4050, 0, 1, 0, 0, 0, 0, 0, 3069, 0, 0, true},
    {"elephant.off", 2775, 5558, 0, 1, 0, 0, 3, 0, 0, 0, 0, 0, true},
    {"elephant-with-holes.off", 2798, 4463, 106, 1, 0, 0, 3, 0, 65, 0, 0, 0, true},
    {"spot.obj", 2930, 5856, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"dino.off", 3916, 7828, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"mech-holes-shark.off", 5246, 10192, 4, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"bob_tri.obj", 5344, 10688, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, true},
    {"fandisk.off", 6475, 12946, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"blub_triangulated.obj", 7106, 14208, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"lion-head.off", 8356, 16674, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"capsule.obj", 10658, 21312, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"bear.off", 13826, 27648, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"bs_rest.obj", 19985, 39856, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"spot_subdiv.obj", 24755, 49506, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
    {"armadillo.off", 26002, 52000, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, true},
};

const ice_test::Expected& expected(const std::string& file) { return ice_test::table_row(kTable, file); }

using ice_test::refusal;

/// A Möbius strip of `segments` quads (two triangles each) across one twist: non-orientable, one
/// boundary loop. Written by the test because no redistributable file of one is at hand.
ice::TriangleMesh moebius_strip(int segments) {
  ice::TriangleMesh m;
  m.V.resize(2 * segments, 3);
  for (int i = 0; i < segments; ++i) {
    const double t = 2 * kPi * i / segments;
    for (int side = 0; side < 2; ++side) {
      const double w = side == 0 ? -0.3 : 0.3;
      m.V.row(2 * i + side) << (1 + w * std::cos(t / 2)) * std::cos(t), (1 + w * std::cos(t / 2)) * std::sin(t),
          w * std::sin(t / 2);
    }
  }
  m.F.resize(2 * segments, 3);
  for (int i = 0; i < segments; ++i) {
    const int a = 2 * i, b = 2 * i + 1;
    // Across the seam the strip comes back flipped: side 0 meets side 1.
    const bool seam = i + 1 == segments;
    const int c = seam ? 1 : 2 * (i + 1), d = seam ? 0 : 2 * (i + 1) + 1;
    m.F.row(2 * i) << a, c, b;
    m.F.row(2 * i + 1) << b, c, d;
  }
  return m;
}

/// Inserts an unreferenced vertex before every `stride`-th vertex (renumbering the faces), so that a
/// repair that drops them has a non-trivial map back to the file's vertex ids.
ice::TriangleMesh with_unreferenced_vertices(const ice::TriangleMesh& mesh, int stride, int* inserted) {
  std::vector<int> new_id(mesh.V.rows());
  std::vector<Eigen::RowVector3d> rows;
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) {
    if (v % stride == 0) rows.push_back(Eigen::RowVector3d(100.0 + v, -3.0, 7.0));  // far from the surface
    new_id[v] = static_cast<int>(rows.size());
    rows.push_back(mesh.V.row(v));
  }
  ice::TriangleMesh out;
  out.V.resize(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i) out.V.row(static_cast<Eigen::Index>(i)) = rows[i];
  out.F = mesh.F;
  for (Eigen::Index f = 0; f < out.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) out.F(f, k) = new_id[out.F(f, k)];
  *inserted = static_cast<int>(rows.size() - mesh.V.rows());
  return out;
}

/// Appends faces 0..count-1 again (duplicate faces, which also make their edges non-manifold).
ice::TriangleMesh with_duplicate_faces(const ice::TriangleMesh& mesh, int count) {
  ice::TriangleMesh out = mesh;
  out.F.conservativeResize(mesh.F.rows() + count, 3);
  out.F.bottomRows(count) = mesh.F.topRows(count);
  return out;
}

/// Appends `count` separate zero-area triangles (three collinear new vertices each) far from the mesh.
ice::TriangleMesh with_zero_area_triangles(const ice::TriangleMesh& mesh, int count) {
  ice::TriangleMesh out = mesh;
  const Eigen::Index nv = mesh.V.rows(), nf = mesh.F.rows();
  out.V.conservativeResize(nv + 3 * count, 3);
  out.F.conservativeResize(nf + count, 3);
  for (int i = 0; i < count; ++i) {
    for (int k = 0; k < 3; ++k) out.V.row(nv + 3 * i + k) << 50.0 + i, 1.0 + k, 2.0 + 2 * k;  // on one line
    out.F.row(nf + i) << static_cast<int>(nv + 3 * i), static_cast<int>(nv + 3 * i + 1), static_cast<int>(nv + 3 * i + 2);
  }
  return out;
}

}  // namespace

// Point sets of the project set (no faces): file and point count.
const std::vector<std::pair<std::string, Eigen::Index>> kPointSets = {{"kitten.xyz", 5210}};

TEST_CASE("project set: exactly the meshes of the table are present", "[project]") {
  const std::string dir = ice_mesh_sets::project_dir();
  for (const auto& e : kTable) {
    INFO(e.file);
    CHECK(fs::is_regular_file(fs::path(dir) / e.file));
  }
  for (const auto& [file, points] : kPointSets) {
    INFO(file);
    const ice::MeshFile read = ice::read_mesh_file(ice_test::project_mesh(file));
    CHECK(read.soup.V.rows() == points);
    CHECK(read.soup.polygons.empty());
  }
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.front() == '.') continue;  // setup's scratch files
    INFO("data/default/" << name << " is not in the table of test_project_meshes.cpp (update it with data/README.md)");
    CHECK((std::any_of(kTable.begin(), kTable.end(), [&](const ice_test::Expected& e) { return name == e.file; }) ||
           std::any_of(kPointSets.begin(), kPointSets.end(), [&](const auto& p) { return name == p.first; })));
  }
}

TEST_CASE("project set: figures match the table", "[project]") {
  for (const auto& e : kTable) {
    const ice::MeshFile file = ice::read_mesh_file(ice_test::project_mesh(e.file));
    INFO(e.file);
    CHECK(file.exact_coordinates);
    ice_test::check_figures(e, ice::validate_mesh(file.soup));
  }
}

TEST_CASE("project set: defective files are refused naming the file and the defect, clean ones load", "[project]") {
  const std::pair<const char*, const char*> refusals[] = {
      {"degtri_sliding.off", "4 zero-area faces"},
      {"hourglass_ico.obj", "1 non-manifold vertices"},
      {"triple_vierbein.obj", "20 non-manifold edges"},
      {"blobby-shuffled.off", "3069 inconsistently oriented edges"},
  };
  for (const auto& [file, defect] : refusals) {
    INFO(file);
    CHECK(ice_test::flagged(expected(file)));
    const std::string path = ice_test::project_mesh(file);
    CHECK_THAT(refusal(path), Catch::Contains(path) && Catch::Contains(defect));
  }
  // Boundaries, genus 2 to 9, three components, 106 holes (with 65 coincident positions, not a defect).
  for (const char* file : {"cat_head.obj", "eight.off", "boxpart.obj", "blobby_3cc.off", "couplingdown.off",
                           "elephant-with-holes.off"}) {
    INFO(file);
    const ice::LoadResult loaded = ice::load_mesh_with_report(ice_test::project_mesh(file));
    const ice_test::Expected& e = expected(file);
    CHECK(static_cast<std::size_t>(loaded.mesh.V.rows()) == e.vertices);
    CHECK(static_cast<std::size_t>(loaded.mesh.F.rows()) == e.faces);
    CHECK(loaded.report.components.size() == e.components);
    CHECK(loaded.report.genus == e.genus);
  }
}

TEST_CASE("project set: defects written by the test are refused, with the defect named", "[project]") {
  const ice_test::TempDir dir;
  SECTION("non-orientable: a Möbius strip (ASCII PLY)") {
    const std::string path = dir.file("moebius.ply");
    ice::write_mesh(path, moebius_strip(24));
    const ice::ValidationReport report = ice::validate_mesh(ice::read_mesh_file(path).soup);
    CHECK_FALSE(report.orientable());
    CHECK(report.manifold());
    CHECK(report.n_boundary_loops == 1);
    CHECK_THAT(refusal(path), Catch::Contains(path) && Catch::Contains("1 non-orientable components"));
    CHECK_THAT(refusal(path, {true, false}), Catch::Contains("after repair") && Catch::Contains("non-orientable"));
  }
  SECTION("a zero-area face joining two triangles at a vertex: dropping it leaves a pinch") {
    // Faces 0-1-2 and 0-3-4 meet only at vertex 0; face 0-2-3 (collinear) is what joined them.
    const std::string path = dir.write("pinch.off",
                                       "OFF\n5 3 0\n0 0 0\n1 -1 0\n1 0 0\n2 0 0\n2 1 0\n3 0 1 2\n3 0 2 3\n3 0 3 4\n");
    CHECK_THAT(refusal(path), Catch::Contains(path) && Catch::Contains("1 zero-area faces"));
    // Repair drops it, then gives the second fan at vertex 0 its own copy: two clean triangles.
    const ice::LoadResult repaired = ice::load_mesh_with_report(path, {true, false});
    CHECK(repaired.repairs.removed_zero_area_faces == 1);
    CHECK(repaired.repairs.split_non_manifold_vertices == 1);
    CHECK(repaired.report.clean());
    CHECK(repaired.report.components.size() == 2);
    REQUIRE(repaired.mesh.V.rows() == 6);
    CHECK(repaired.source_vertex[5] == 0);
    CHECK(repaired.mesh.V.row(5) == repaired.mesh.V.row(0));
  }
  SECTION("duplicate faces and unreferenced vertices are named, and repaired") {
    int inserted = 0;
    const ice::TriangleMesh sphere = ice::make_icosphere(2);
    const ice::TriangleMesh bad = with_duplicate_faces(with_unreferenced_vertices(sphere, 20, &inserted), 5);
    const std::string path = dir.file("duplicates.obj");
    ice::write_mesh(path, bad);
    const std::string message = refusal(path);
    CHECK_THAT(message, Catch::Contains(path) && Catch::Contains("5 duplicate faces") &&
                            Catch::Contains(std::to_string(inserted) + " unreferenced vertices"));
    const ice::LoadResult r = ice::load_mesh_with_report(path, {true, false});
    CHECK(r.repairs.removed_duplicate_faces == 5);
    CHECK(r.repairs.removed_unreferenced_vertices == static_cast<std::size_t>(inserted));
    CHECK(r.report.clean());
    CHECK(r.mesh.V == sphere.V);  // the surface as it was before the defects were added
    CHECK(r.mesh.F == sphere.F);
    REQUIRE(r.source_vertex.size() == static_cast<std::size_t>(r.mesh.V.rows()));
    for (Eigen::Index i = 0; i < r.mesh.V.rows(); ++i) CHECK(r.mesh.V.row(i) == r.file.soup.V.row(r.source_vertex[i]));
  }
  SECTION("two components sharing a position (not welded, not refused)") {
    const std::string path = dir.write("two.off", "OFF\n6 2 0\n0 0 0\n1 0 0\n0 1 0\n1 0 0\n2 0 0\n1 1 0\n3 0 1 2\n3 3 4 5\n");
    const ice::LoadResult r = ice::load_mesh_with_report(path);
    CHECK(r.report.components.size() == 2);
    CHECK(r.report.duplicate_positions.count == 1);
    CHECK(r.mesh.V.rows() == 6);
  }
  SECTION("huge coordinates: spot translated by 1e6 reads back exactly and keeps its figures") {
    ice::TriangleMesh offset = ice::load_mesh(ice_test::project_mesh("spot.obj"));
    offset.V.array() += 1e6;
    const std::string path = dir.file("spot_offset1e6.obj");
    ice::write_mesh(path, offset);
    const ice::MeshFile file = ice::read_mesh_file(path);
    CHECK(file.exact_coordinates);
    ice_test::Expected e = expected("spot.obj");
    ice_test::check_figures(e, ice::validate_mesh(file.soup));
    CHECK(ice::load_mesh(path).V == offset.V);
  }
}

TEST_CASE("project set: repair fixes what is safe and refuses the rest", "[project]") {
  const ice::LoadOptions repair{true, false};
  SECTION("re-orientation: blobby-shuffled becomes consistent, outward, same topology") {
    const ice::LoadResult r = ice::load_mesh_with_report(ice_test::project_mesh("blobby-shuffled.off"), repair);
    CHECK(r.repairs.reoriented_components == 1);
    CHECK(r.repairs.flipped_faces > 0);
    CHECK(r.report.inconsistent_edges.empty());
    CHECK(r.report.genus == 0);
    CHECK(r.mesh.F.rows() == 4050);
    CHECK(ice_test::signed_volume(r.mesh) > 0);
  }
  SECTION("zero-area faces: degtri_sliding repairs into two clean pieces") {
    const ice::LoadResult r = ice::load_mesh_with_report(ice_test::project_mesh("degtri_sliding.off"), repair);
    CHECK(r.repairs.removed_zero_area_faces == 4);
    CHECK(r.mesh.F.rows() == 4);
    CHECK(r.report.components.size() == 2);
  }
  SECTION("non-manifold vertex: hourglass_ico (two spheres touching at a vertex) splits into two spheres") {
    const ice::LoadResult r = ice::load_mesh_with_report(ice_test::project_mesh("hourglass_ico.obj"), repair);
    CHECK(r.repairs.split_non_manifold_vertices == 1);
    CHECK(r.report.clean());
    REQUIRE(r.report.components.size() == 2);
    for (const auto& component : r.report.components) CHECK(component.genus == 0);
    CHECK(r.mesh.V.rows() == 24);
    CHECK(r.mesh.F.rows() == 40);
    for (Eigen::Index i = 0; i < r.mesh.V.rows(); ++i) CHECK(r.mesh.V.row(i) == r.file.soup.V.row(r.source_vertex[i]));
  }
  SECTION("refused even after repair, with the remaining defect named") {
    CHECK_THAT(refusal(ice_test::project_mesh("triple_vierbein.obj"), repair),
               Catch::Contains("after repair") && Catch::Contains("non-manifold edges"));
  }
}

TEST_CASE("project set: a large binary PLY (blobby_3cc Loop x4, 3 components) reads back exactly and repairs",
          "[project][large]") {
  // ~437k vertices like the extended set's dragon scan: three components with four boundary loops, plus
  // 100 separate zero-area triangles and 50 duplicate faces, written as binary PLY by the test.
  const ice::TriangleMesh surface = ice::loop_subdivide(ice::load_mesh(ice_test::project_mesh("blobby_3cc.off")), 4);
  REQUIRE(surface.V.rows() > 400000);
  const ice::TriangleMesh with_defects = with_duplicate_faces(with_zero_area_triangles(surface, 100), 50);
  const ice_test::TempDir dir;
  const std::string path = dir.file("blobby_3cc_loop4.ply");
  ice::write_mesh(path, with_defects, {false, true});

  const ice::LoadResult r = ice::load_mesh_with_report(path, {true, false});
  CHECK(r.file.exact_coordinates);
  CHECK(r.file.soup.V == with_defects.V);  // binary doubles: bit-exact
  CHECK(r.input_report.n_vertices == static_cast<std::size_t>(with_defects.V.rows()));
  CHECK(r.input_report.n_faces == static_cast<std::size_t>(with_defects.F.rows()));
  CHECK(r.input_report.zero_area_faces.count == 100);
  CHECK(r.input_report.duplicate_faces.count == 50);
  std::string defects;
  for (const std::string& line : r.input_report.defects()) defects += line + "\n";
  CHECK_THAT(defects, Catch::Contains("100 zero-area faces") && Catch::Contains("50 duplicate faces"));

  CHECK(r.repairs.removed_zero_area_faces == 100);
  CHECK(r.repairs.removed_duplicate_faces == 50);
  CHECK(r.repairs.removed_unreferenced_vertices == 300);
  CHECK(r.report.clean());
  CHECK(r.report.components.size() == 3);
  CHECK(r.report.n_boundary_loops == 4);
  CHECK(r.report.genus == 0);
  CHECK(r.mesh.V == surface.V);
  CHECK(r.mesh.F == surface.F);
}
