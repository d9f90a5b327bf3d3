// Tests of the .ilm format (ice/intrinsic_mesh_io.h): an exact write/read round trip of a coarsened
// real mesh, and a clear MeshError (file, line, defect) for every kind of bad file.
#include <catch2/catch.hpp>

#include <map>
#include <sstream>

#include "ice/coarsen.h"
#include "ice/intrinsic_mesh_io.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "test_support.h"

namespace {

// Expects read_intrinsic_mesh to refuse `content` with the given kind and a message naming the file
// and containing `expected`.
void expect_refused(const std::string& content, ice::MeshError::Kind kind, const std::string& expected) {
  ice_test::TempDir dir;
  const std::string path = dir.write("bad.ilm", content);
  INFO(content);
  try {
    ice::read_intrinsic_mesh(path);
    FAIL("accepted a bad file");
  } catch (const ice::MeshError& e) {
    CHECK(e.kind() == kind);
    CHECK(e.path() == path);
    CHECK_THAT(e.what(), Catch::Contains(path) && Catch::Contains(expected));
  }
}

const std::string kHeader = "ICE-ILM 1\nvertices 3\nfaces 1\ninput_vertices 5\n";

}  // namespace

TEST_CASE("an .ilm round trip reproduces the coarse mesh exactly", "[ilm][meshes]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  ice::CoarsenOptions options;
  options.target_vertices = 300;
  ice::coarsen(T, options);
  const ice::CompactMesh coarse = T.compact();

  ice_test::TempDir dir;
  const std::string path = dir.file("coarse.ilm");
  ice::write_intrinsic_mesh(path, coarse, static_cast<ice::Index>(mesh.V.rows()), "test");
  const ice::IntrinsicMeshFile file = ice::read_intrinsic_mesh(path);
  CHECK(file.input_vertices == mesh.V.rows());
  CHECK(file.to_input == coarse.to_input);
  REQUIRE(file.F.rows() == coarse.F.rows());
  CHECK(file.F == coarse.F);
  CHECK(file.L == coarse.L);  // bit-exact: lengths are printed in round-trip form
  // The read mesh is a valid intrinsic triangulation with the coarse mesh's area and curvature.
  const ice::IntrinsicTriangulation R = ice::IntrinsicTriangulation::from_lengths(file.F, file.L);
  CHECK(R.validate() == "");
  CHECK(R.total_area() == Approx(T.total_area()).epsilon(1e-12));
  CHECK(R.euler_characteristic() == T.euler_characteristic());
}

TEST_CASE("bad .ilm files are refused with the file, the line and the defect", "[ilm]") {
  using Kind = ice::MeshError::Kind;
  expect_refused("", Kind::Unreadable, "empty file");
  expect_refused("OFF\n3 1 0\n", Kind::Unreadable, "ICE-ILM 1");
  expect_refused("ICE-ILM 1\nvertices 3\n", Kind::Unreadable, "faces <count>");
  expect_refused("ICE-ILM 1\nvertices -3\nfaces 1\ninput_vertices 5\n", Kind::Unreadable, "line 2");
  expect_refused(kHeader, Kind::Unreadable, "file ends after 0 of 1 faces");
  // Corrupt counts are refused before anything is allocated for them.
  expect_refused("ICE-ILM 1\nvertices 2000000000\nfaces 2000000000\ninput_vertices 5\nf 0 1 2 1 1 1\n", Kind::Unreadable,
                 "exceed what a file of");
  expect_refused(kHeader + "f 0 1 2 1 1\n", Kind::Unreadable, "line 5");
  expect_refused(kHeader + "f 0 1 3 1 1 1\n", Kind::Defective, "vertex 3 out of range");
  expect_refused(kHeader + "f 0 1 2 1 nan 1\n", Kind::Defective, "not positive and finite");
  expect_refused(kHeader + "f 0 1 2 1 0 1\n", Kind::Defective, "not positive and finite");
  expect_refused(kHeader + "f 0 1 2 1 1 3\n", Kind::Defective, "triangle inequality");
  expect_refused(kHeader + "f 0 1 2 1 1 1\nv 0\nv 1\n", Kind::Unreadable, "file ends after 2 of 3 vertex lines");
  expect_refused(kHeader + "f 0 1 2 1 1 1\nv 0\nv 7\nv 2\n", Kind::Defective, "input vertex 7 out of range");
  expect_refused(kHeader + "f 0 1 2 1 1 1\nv 0\nv 0\nv 2\n", Kind::Defective, "listed twice");
  expect_refused(kHeader + "f 0 1 2 1 1 1\nv 0\nv 1\nv 2\nf 0 1 2 1 1 1\n", Kind::Unreadable, "after the last vertex line");
  expect_refused("ICE-ILM 1\nvertices 4\nfaces 1\ninput_vertices 5\nf 0 1 2 1 1 1\nv 0\nv 1\nv 2\nv 3\n", Kind::Defective,
                 "vertex 3 is used by no face");
  {
    ice_test::TempDir dir;
    CHECK_THROWS_AS(ice::read_intrinsic_mesh(dir.file("missing.ilm")), ice::MeshError);
  }
  // Comments, blank lines and CRLF line ends are fine.
  ice_test::TempDir dir;
  const std::string path =
      dir.write("ok.ilm", "ICE-ILM 1\r\n# made by hand\r\nvertices 3\r\n\r\nfaces 1\r\ninput_vertices 5\r\nf 0 1 2 3 4 5\r\n# the map\r\nv 4\r\nv 0\r\nv 2\r\n");
  const ice::IntrinsicMeshFile file = ice::read_intrinsic_mesh(path);
  CHECK(file.F.rows() == 1);
  CHECK(file.L(0, 2) == 5.0);
  CHECK(file.to_input == std::vector<ice::Index>{4, 0, 2});
}

namespace {

/// A unit cube without its top: ten triangles, a disk with a square boundary.
ice::TriangleMesh open_cube() {
  ice::TriangleMesh m;
  m.V.resize(8, 3);
  m.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1;
  m.F.resize(10, 3);
  m.F << 0, 2, 1, 0, 3, 2,  // bottom
      0, 1, 5, 0, 5, 4,     // front
      1, 2, 6, 1, 6, 5,     // right
      2, 3, 7, 2, 7, 6,     // back
      3, 0, 4, 3, 4, 7;     // left
  return m;
}

/// Counts of Δ-complex features of a compact mesh: faces repeating a vertex (self-edges) and vertex
/// pairs joined by more than one edge (multi-edges).
std::pair<int, int> delta_complex_features(const ice::CompactMesh& c) {
  int self = 0;
  std::map<std::pair<int, int>, int> sides;
  for (Eigen::Index f = 0; f < c.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = c.F(f, k), b = c.F(f, (k + 1) % 3);
      if (a == b) ++self;
      ++sides[{std::min(a, b), std::max(a, b)}];
    }
  int multi = 0;
  for (const auto& [pair, count] : sides) multi += count > 2;
  return {self, multi};
}

}  // namespace

TEST_CASE(".ilm version 2: write -> read is exact on Δ-complexes, boundaries and several components", "[ilm][io]") {
  ice_test::TempDir dir;
  struct Case {
    const char* name;
    ice::TriangleMesh mesh;
  };
  const std::vector<Case> cases = {
      {"torus", ice::make_torus(24, 12, 1.0, 0.4)},
      {"open cube", open_cube()},
      {"spot", ice::load_mesh(ice_test::project_mesh("spot.obj"))},
      {"eight (genus 2)", ice::load_mesh(ice_test::project_mesh("eight.off"))},
      {"blobby_3cc (3 components, 4 loops)", ice::load_mesh(ice_test::project_mesh("blobby_3cc.off"))},
      {"lion-head (disk)", ice::load_mesh(ice_test::project_mesh("lion-head.off"))},
  };
  int self_edges = 0, multi_edges = 0;
  for (const Case& c : cases) {
    auto T = ice::IntrinsicTriangulation::from_mesh(c.mesh.V, c.mesh.F);
    // Every level on the way down to the minimum: 50 %, 10 %, 1 %, as few as the topology allows.
    for (double fraction : {0.5, 0.1, 0.01, 0.0}) {
      INFO(c.name << " at " << fraction);
      ice::CoarsenOptions options;
      options.target_vertices = std::max<ice::Index>(1, static_cast<ice::Index>(fraction * c.mesh.V.rows()));
      ice::coarsen(T, options);
      const ice::CompactMesh written = ice_test::check_ilm_round_trip(T, dir.file("coarse.ilm"));
      const auto [self, multi] = delta_complex_features(written);
      self_edges += self;
      multi_edges += multi;
    }
  }
  // The cases above do reach Δ-complexes (measured: the torus and eight end with self-edges).
  CHECK(self_edges > 0);
  CHECK(multi_edges > 0);
}

TEST_CASE(".ilm: the open cube at 3 vertices keeps its boundary (version 1 read it back as a sphere)", "[ilm][io]") {
  ice_test::TempDir dir;
  const ice::TriangleMesh cube = open_cube();
  auto T = ice::IntrinsicTriangulation::from_mesh(cube.V, cube.F);
  ice::CoarsenOptions options;
  options.target_vertices = 3;
  ice::coarsen(T, options);
  REQUIRE(T.euler_characteristic() == 1);
  const ice::CompactMesh written = ice_test::check_ilm_round_trip(T, dir.file("cube.ilm"));
  // The same faces written as version 1: glued by vertex pairs, which either fails clearly or (for
  // this mesh, two faces on the same three vertices) glues them into another surface.
  std::ostringstream v1;
  v1 << "ICE-ILM 1\nvertices " << written.to_input.size() << "\nfaces " << written.F.rows() << "\ninput_vertices 8\n";
  v1.precision(17);
  for (Eigen::Index f = 0; f < written.F.rows(); ++f)
    v1 << "f " << written.F(f, 0) << ' ' << written.F(f, 1) << ' ' << written.F(f, 2) << ' ' << written.L(f, 0) << ' '
       << written.L(f, 1) << ' ' << written.L(f, 2) << '\n';
  for (ice::Index v : written.to_input) v1 << "v " << v << '\n';
  const std::string path = dir.write("cube_v1.ilm", v1.str());
  const ice::IntrinsicMeshFile file = ice::read_intrinsic_mesh(path);
  CHECK(file.version == 1);
  CHECK(file.twin.empty());
  try {
    const ice::IntrinsicTriangulation glued = ice::triangulation_of(file, path);
    CHECK(glued.euler_characteristic() != T.euler_characteristic());  // the ambiguity version 2 removes
  } catch (const ice::MeshError& e) {
    CHECK_THAT(e.what(), Catch::Contains(path) && Catch::Contains("version-1"));
  }
}

TEST_CASE(".ilm version 2: a bad gluing is refused naming the line, face and side", "[ilm][io]") {
  const std::string head = "ICE-ILM 2\nvertices 4\nfaces 2\ninput_vertices 4\n";
  const std::string tail = "v 0\nv 1\nv 2\nv 3\n";
  // Two triangles sharing edge 1-2: side 1 of face 0 (1->2) and side 1 of face 1 (2->1).
  const std::string good = head + "f 0 1 2 1 1 1 -1 4 -1\nf 3 2 1 1 1 1 -1 1 -1\n" + tail;
  ice_test::TempDir dir;
  const ice::IntrinsicMeshFile file = ice::read_intrinsic_mesh(dir.write("good.ilm", good));
  CHECK(file.twin == std::vector<ice::Index>{ice::kInvalid, 4, ice::kInvalid, ice::kInvalid, 1, ice::kInvalid});
  CHECK(ice::triangulation_of(file, "good.ilm").validate() == "");
  const std::pair<std::string, std::string> bad[] = {
      {head + "f 0 1 2 1 1 1 -1 4 -1\nf 3 2 1 1 1 1 -1 -1 -1\n" + tail, "line 5: face 0, side 1 is glued to side 4, which is not glued back"},
      {head + "f 0 1 2 1 1 1 -1 5 -1\nf 3 2 1 1 1 1 -1 -1 1\n" + tail, "line 5: face 0, side 1 is glued to side 5, whose end vertices differ"},
      {head + "f 0 1 2 1 1 1 -1 4 -1\nf 3 2 1 1 1.5 1 -1 1 -1\n" + tail, "face 0, side 1 is glued to side 4 of another length"},
      {head + "f 0 1 2 1 1 1 -1 6 -1\nf 3 2 1 1 1 1 -1 1 -1\n" + tail, "twin 6 of side 1 is out of range"},
      {head + "f 0 1 2 1 1 1 -1 1 -1\nf 3 2 1 1 1 1 -1 1 -1\n" + tail, "twin 1 of side 1 is out of range or the side itself"},
      {head + "f 0 1 2 1 1 1 -1 4\nf 3 2 1 1 1 1 -1 1 -1\n" + tail, "t_ij t_jk t_ki"},
  };
  for (const auto& [text, message] : bad) {
    INFO(message);
    const std::string path = dir.write("bad.ilm", text);
    try {
      ice::read_intrinsic_mesh(path);
      FAIL("accepted");
    } catch (const ice::MeshError& e) {
      CHECK_THAT(e.what(), Catch::Contains(path) && Catch::Contains(message));
    }
  }
}
