// Tests of the .ilm format (ice/intrinsic_mesh_io.h): an exact write/read round trip of a coarsened
// real mesh, and a clear MeshError (file, line, defect) for every kind of bad file.
#include <catch2/catch.hpp>

#include "ice/coarsen.h"
#include "ice/intrinsic_mesh_io.h"
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
