// Reading and writing: formats, exactness, and clear errors for unreadable files.
#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

#include "ice/mesh_generators.h"
#include "test_support.h"
#include "ice/mesh_io.h"
#include "ice/scalar_field_io.h"

namespace fs = std::filesystem;

TEST_CASE("read_mesh_file: missing, empty, odd and corrupt files give clear errors", "[io]") {
  ice_test::TempDir dir;
  using Kind = ice::MeshError::Kind;
  const std::string missing = dir.file("nope.obj");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(missing); }, Kind::Unreadable, missing, "no such file");
  ice_test::require_mesh_error([&] { ice::load_mesh(missing); }, Kind::Unreadable, missing, "no such file");

  const std::string empty = dir.write("empty.off", "");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(empty); }, Kind::Unreadable, empty, "empty file");

  const std::string folder = dir.file("folder.obj");
  fs::create_directories(folder);
  ice_test::require_mesh_error([&] { ice::read_mesh_file(folder); }, Kind::Unreadable, folder, "not a regular file");

  const std::string unknown = dir.write("mesh.xyzw", "1 2 3\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(unknown); }, Kind::Unreadable, unknown, "unsupported format");

  const std::string no_faces = dir.write("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  REQUIRE(ice::read_mesh_file(no_faces).soup.V.rows() == 3);  // a point set: the loading policy decides
  ice_test::require_mesh_error([&] { ice::load_mesh(no_faces); }, Kind::Defective, no_faces, "contains no faces: a point cloud of 3 points");

  const std::string bad_vertex = dir.write("bad.obj", "v 0 0 0\nv 1 banana 0\nv 0 1 0\nf 1 2 3\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(bad_vertex); }, Kind::Unreadable, bad_vertex, "line 2");

  const std::string bad_corner = dir.write("badf.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(bad_corner); }, Kind::Unreadable, bad_corner, "line 4");

  const std::string truncated_off = dir.write("short.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n3 0 1 2\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(truncated_off); }, Kind::Unreadable, truncated_off, "ends early");

  const std::string huge_count = dir.write("huge.ply",
                                           "ply\nformat ascii 1.0\nelement vertex 999999999999\nproperty float x\n"
                                           "property float y\nproperty float z\nelement face 1\n"
                                           "property list uchar int vertex_indices\nend_header\n0 0 0\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(huge_count); }, Kind::Unreadable, huge_count, "impossible count");
}

TEST_CASE("OBJ: corner syntax, negative indices, repeated corners stay visible", "[io]") {
  ice_test::TempDir dir;
  const std::string path = dir.write("syntax.obj",
                                     "# comment\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\n"
                                     "f 1/1/1 2/1/1 3/1/1\nf -3//1 -1//1 -2//1\nf 1 2 2\n");
  const ice::MeshFile file = ice::read_mesh_file(path);
  REQUIRE(file.soup.V.rows() == 4);
  REQUIRE(file.soup.polygons.size() == 3);
  CHECK(file.soup.polygons[0] == std::vector<int>{0, 1, 2});
  CHECK(file.soup.polygons[1] == std::vector<int>{1, 3, 2});
  CHECK(file.soup.polygons[2] == std::vector<int>{0, 1, 1});  // OpenMesh alone would drop this face
  CHECK(file.exact_coordinates);
  const ice::ValidationReport report = ice::validate_mesh(file.soup);
  CHECK(report.repeated_index_faces.count == 1);
  CHECK(report.repeated_index_faces.first == std::vector<int>{2});
}

TEST_CASE("round trips keep double precision: OBJ, OFF, ASCII and binary PLY", "[io]") {
  ice_test::TempDir dir;
  ice::TriangleMesh mesh = ice::make_icosphere(2);
  mesh.V.array() += 1e6;  // float32 would move vertices by up to 0.03 here
  mesh.V.col(1).array() += 1.0 / 3.0;
  for (const auto& [name, binary] : std::vector<std::pair<std::string, bool>>{
           {"m.obj", false}, {"m.off", false}, {"ascii.ply", false}, {"binary.ply", true}}) {
    INFO(name);
    const std::string path = dir.file(name);
    ice::write_mesh(path, mesh, {false, binary});
    const ice::LoadResult loaded = ice::load_mesh_with_report(path);
    CHECK(loaded.file.exact_coordinates);
    REQUIRE(loaded.mesh.V.rows() == mesh.V.rows());
    REQUIRE(loaded.mesh.F.rows() == mesh.F.rows());
    CHECK(loaded.mesh.V == mesh.V);  // bit-exact
    CHECK(loaded.mesh.F == mesh.F);
    CHECK(loaded.report.zero_area_faces.empty());
    CHECK(loaded.report.genus == 0);
  }
}

TEST_CASE("STL (ASCII and binary): per-triangle vertices are welded back into a closed mesh", "[io]") {
  ice_test::TempDir dir;
  const ice::TriangleMesh mesh = ice::make_icosphere(1);
  for (bool binary : {false, true}) {
    INFO("binary " << binary);
    const std::string path = dir.file(binary ? "b.stl" : "a.stl");
    ice::write_mesh(path, mesh, {false, binary});
    const ice::LoadResult loaded = ice::load_mesh_with_report(path);
    CHECK(loaded.file.format == "stl");
    CHECK(loaded.mesh.V.rows() == mesh.V.rows());  // 3·F records welded to V vertices
    CHECK(loaded.mesh.F.rows() == mesh.F.rows());
    CHECK(loaded.report.n_boundary_loops == 0);
    CHECK(loaded.report.genus == 0);
    CHECK(loaded.report.inconsistent_edges.empty());
    // Every loaded triangle is one of the original triangles (float32 positions, same orientation).
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        CHECK((loaded.mesh.V.row(loaded.mesh.F(f, k)) - mesh.V.row(mesh.F(f, k))).norm() < 1e-6);
  }
}

TEST_CASE("truncated binary PLY is refused, never read as garbage", "[io]") {
  ice_test::TempDir dir;
  const ice::TriangleMesh mesh = ice::make_icosphere(1);
  const std::string path = dir.file("cut.ply");
  ice::write_mesh(path, mesh, {false, true});
  fs::resize_file(path, fs::file_size(path) / 2);
  ice_test::require_mesh_error([&] { ice::read_mesh_file(path); }, ice::MeshError::Kind::Unreadable, path, "ends early");
}

TEST_CASE("write_mesh never overwrites unless asked", "[io]") {
  ice_test::TempDir dir;
  const ice::TriangleMesh mesh = ice::make_icosphere(0);
  const std::string path = dir.file("out.obj");
  ice::write_mesh(path, mesh);
  ice_test::require_mesh_error([&] { ice::write_mesh(path, mesh); }, ice::MeshError::Kind::Unwritable, path, "exists");
  CHECK_NOTHROW(ice::write_mesh(path, mesh, {true, false}));
  const std::string bad = dir.file("out.vtk");
  ice_test::require_mesh_error([&] { ice::write_mesh(bad, mesh); }, ice::MeshError::Kind::Unwritable, bad, "unsupported");
}

namespace {

/// Appends `value` to `bytes` as `sizeof(T)` bytes in the given byte order.
template <class T>
void put(std::string& bytes, T value, bool big_endian) {
  char raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));
  if (big_endian) std::reverse(raw, raw + sizeof(T));
  bytes.append(raw, sizeof(T));
}

/// A valid PLY whose face element comes before its vertex element, with properties the reader must
/// read past (a per-face float, a per-vertex colour byte, a second list on the faces).
std::string faces_first_ply(const ice::TriangleMesh& m, const std::string& format) {
  const bool ascii = format == "ascii", big = format == "binary_big_endian";
  std::string text = "ply\nformat " + format + " 1.0\ncomment faces before vertices\n" +
                     "element face " + std::to_string(m.F.rows()) + "\nproperty float quality\n" +
                     "property list uchar int vertex_indices\nproperty list uchar float texcoord\n" +
                     "element vertex " + std::to_string(m.V.rows()) + "\nproperty double x\nproperty uchar red\n" +
                     "property double y\nproperty double z\nend_header\n";
  std::ostringstream out;
  out.precision(17);
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    if (ascii) {
      out << 0.5 << " 3 " << m.F(f, 0) << ' ' << m.F(f, 1) << ' ' << m.F(f, 2) << " 2 0.25 0.75\n";
    } else {
      put(text, 0.5f, big);
      put(text, static_cast<unsigned char>(3), big);
      for (int k = 0; k < 3; ++k) put(text, static_cast<std::int32_t>(m.F(f, k)), big);
      put(text, static_cast<unsigned char>(2), big);
      put(text, 0.25f, big);
      put(text, 0.75f, big);
    }
  }
  for (Eigen::Index v = 0; v < m.V.rows(); ++v) {
    if (ascii) {
      out << m.V(v, 0) << " 200 " << m.V(v, 1) << ' ' << m.V(v, 2) << '\n';
    } else {
      put(text, m.V(v, 0), big);
      put(text, static_cast<unsigned char>(200), big);
      put(text, m.V(v, 1), big);
      put(text, m.V(v, 2), big);
    }
  }
  return text + out.str();
}

}  // namespace

TEST_CASE("PLY: elements in any order, ASCII and both byte orders, extra properties read past", "[io]") {
  ice_test::TempDir dir;
  ice::TriangleMesh mesh = ice::make_icosphere(2);
  mesh.V.array() += 1e6;  // coordinates that float32 would round
  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    INFO(format);
    const std::string path = dir.write(format + ".ply", faces_first_ply(mesh, format));
    const ice::LoadResult loaded = ice::load_mesh_with_report(path);
    CHECK(loaded.file.exact_coordinates);
    CHECK(loaded.mesh.V == mesh.V);
    CHECK(loaded.mesh.F == mesh.F);
    CHECK(loaded.report.clean());
    // Repair has nothing to do on it (it once turned a misread file into a wrong "clean" mesh).
    const ice::LoadResult repaired = ice::load_mesh_with_report(path, {true, false});
    CHECK(repaired.repairs.empty());
    CHECK(repaired.mesh.F == mesh.F);
  }
  // Cut inside the vertex element (after the faces): refused, saying where.
  const std::string whole = faces_first_ply(mesh, "binary_little_endian");
  const std::string cut = dir.write("cut.ply", whole.substr(0, whole.size() - 100));
  ice_test::require_mesh_error([&] { ice::read_mesh_file(cut); }, ice::MeshError::Kind::Unreadable, cut,
                     "ends early in element 'vertex'");
}

TEST_CASE("OFF: comments anywhere, also between the counts and the records", "[io]") {
  // Each of these was refused ("exact re-read and OpenMesh disagree"): OpenMesh's OFF reader takes a
  // comment line after the counts for a vertex.
  const std::string records = "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n";
  const std::pair<const char*, std::string> variants[] = {
      {"after_counts.off", "OFF\n4 2 0\n# vertices follow\n" + records},
      {"indented.off", "OFF\n4 2 0\n   # indented comment\n" + records},
      {"numeric.off", "OFF\n4 2 0\n#1 2 3\n" + records},
      {"on_counts_line.off", "OFF\n4 2 0 # counts\n" + records},
      {"crlf.off", "OFF\r\n4 2 0\r\n# c\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n1 1 0\r\n3 0 1 2\r\n3 1 3 2\r\n"},
      {"everywhere.off", "# made by hand\nOFF\n# counts next\n4 2 0\n\n0 0 0 # trailing\n1 0 0\n0 1 0\n1 1 0\n"
                         "# faces follow\n3 0 1 2\n3 1 3 2\n"},
  };
  ice_test::TempDir dir;
  for (const auto& [name, text] : variants) {
    INFO(name);
    const std::string path = dir.write(name, text);
    const ice::MeshFile file = ice::read_mesh_file(path);
    CHECK(file.exact_coordinates);
    REQUIRE(file.soup.V.rows() == 4);
    CHECK(file.soup.V.row(1) == Eigen::RowVector3d(1, 0, 0));
    CHECK(file.soup.V.row(3) == Eigen::RowVector3d(1, 1, 0));
    CHECK(file.soup.polygons == ice::PolygonList{{0, 1, 2}, {1, 3, 2}});
    const ice::LoadResult loaded = ice::load_mesh_with_report(path);
    CHECK(loaded.report.clean());
    CHECK(loaded.report.n_boundary_loops == 1);
  }
}

namespace {

/// Binary OFF as Geomview (big endian) or OpenMesh (little endian) writes it, with `layout` extras per
/// vertex (normal: 3 floats, colour: 4) and one colour value per face.
std::string binary_off(const ice::TriangleMesh& mesh, bool big_endian, const std::string& keyword, int extra_floats) {
  std::string bytes = keyword + " BINARY\n";
  auto put = [&](std::uint32_t word) {
    for (int k = 0; k < 4; ++k) bytes += static_cast<char>(big_endian ? word >> (24 - 8 * k) : word >> (8 * k));
  };
  auto put_float = [&](float value) {
    std::uint32_t word;
    std::memcpy(&word, &value, sizeof word);
    put(word);
  };
  put(static_cast<std::uint32_t>(mesh.V.rows()));
  put(static_cast<std::uint32_t>(mesh.F.rows()));
  put(0);
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) {
    for (int k = 0; k < 3; ++k) put_float(static_cast<float>(mesh.V(v, k)));
    for (int k = 0; k < extra_floats; ++k) put_float(0.5f);
  }
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    put(3);
    for (int k = 0; k < 3; ++k) put(static_cast<std::uint32_t>(mesh.F(f, k)));
    put(1);
    put_float(0.25f);
  }
  return bytes;
}

}  // namespace

TEST_CASE("OFF: binary in either byte order; unknown keywords refused by name, never handed on", "[io]") {
  // OpenMesh's OFF reader used to get every file whose keyword ICE's reader declined; on some corrupt
  // keywords ("OFF\xff", found by fuzzing) it looped for minutes and took 5+ GB. Now every OFF file is
  // read here: binary OFF fully, anything else refused naming the keyword.
  const ice::TriangleMesh mesh = ice::make_icosphere(1);
  ice_test::TempDir dir;
  const std::pair<const char*, int> keywords[] = {{"OFF", 0}, {"NOFF", 3}, {"CNOFF", 7}};
  for (const bool big_endian : {true, false}) {
    for (const auto& [keyword, extra] : keywords) {
      INFO(keyword << (big_endian ? " big endian" : " little endian"));
      const std::string path = dir.write(std::string(keyword) + (big_endian ? "_be" : "_le") + ".off",
                                         binary_off(mesh, big_endian, keyword, extra));
      const ice::MeshFile file = ice::read_mesh_file(path);
      REQUIRE(file.soup.V.rows() == mesh.V.rows());
      REQUIRE(file.soup.polygons.size() == static_cast<std::size_t>(mesh.F.rows()));
      CHECK((file.soup.V - mesh.V.cast<float>().cast<double>()).cwiseAbs().maxCoeff() == 0.0);
      for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
        CHECK(file.soup.polygons[f] == std::vector<int>{mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)});
      CHECK(ice::load_mesh_with_report(path).report.clean());
    }
  }
  using Kind = ice::MeshError::Kind;
  const std::string whole = binary_off(mesh, true, "OFF", 0);
  const std::string cut = dir.write("cut_binary.off", whole.substr(0, whole.size() - 10));
  ice_test::require_mesh_error([&] { ice::read_mesh_file(cut); }, Kind::Unreadable, cut, "binary OFF data ends early");  // at a face
  std::string huge = whole;
  huge[11] = '\x7f';  // vertex count 0x7f0000.. in either byte order: more than the file holds
  huge[14] = '\x7f';
  const std::string impossible = dir.write("huge_binary.off", huge);
  ice_test::require_mesh_error([&] { ice::read_mesh_file(impossible); }, Kind::Unreadable, impossible, "vertex count 2130706559");

  const std::string garbage = dir.write("garbage.off", std::string("OFF\xff\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"));
  ice_test::require_mesh_error([&] { ice::read_mesh_file(garbage); }, Kind::Unreadable, garbage, "found 'OFF\\xff'");
  const std::string homogeneous = dir.write("h.off", "4OFF\n3 1 0\n0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 2\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(homogeneous); }, Kind::Unreadable, homogeneous, "not supported");
  const std::string no_extension = dir.write("mesh", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  ice_test::require_mesh_error([&] { ice::read_mesh_file(no_extension); }, Kind::Unreadable, no_extension, "no file extension");
}

TEST_CASE("dense matrices round-trip through .npy and .mtx; incomplete or existing files are not left",
          "[io][matrix]") {
  ice_test::TempDir dir;
  Eigen::MatrixXf m(3, 4);
  m << 0.0f, 1.5f, -2.25f, 1e-7f, 3.0f, 4.0f, 5.0f, 6.125f, 7.0f, 8.0f, 9.0f, 1e6f;

  const std::string npy = dir.file("m.npy");
  ice::write_dense_matrix(npy, m, false);
  std::ifstream in(npy, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  REQUIRE(bytes.size() >= 10);
  CHECK(bytes.compare(0, 8, std::string("\x93NUMPY\x01\x00", 8)) == 0);
  const std::size_t header_length = static_cast<unsigned char>(bytes[8]) + 256u * static_cast<unsigned char>(bytes[9]);
  CHECK((10 + header_length) % 64 == 0);  // data aligned, as the format asks
  const std::string header = bytes.substr(10, header_length);
  CHECK(header.find("'descr': '<f4'") != std::string::npos);
  CHECK(header.find("'fortran_order': False") != std::string::npos);
  CHECK(header.find("'shape': (3, 4)") != std::string::npos);
  REQUIRE(bytes.size() == 10 + header_length + 12 * sizeof(float));
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      float value;
      std::memcpy(&value, bytes.data() + 10 + header_length + sizeof(float) * static_cast<std::size_t>(4 * r + c), sizeof(float));
      CHECK(value == m(r, c));  // C order, exact
    }
  CHECK_THROWS_AS(ice::write_dense_matrix(npy, m, false), ice::MeshError);  // exists
  ice::write_dense_matrix(npy, m, true);

  const std::string mtx = dir.file("m.mtx");
  ice::write_dense_matrix(mtx, m, false);
  std::ifstream text(mtx);
  std::string banner;
  std::getline(text, banner);
  CHECK(banner == "%%MatrixMarket matrix array real general");
  long rows = 0, cols = 0;
  text >> rows >> cols;
  CHECK(rows == 3);
  CHECK(cols == 4);
  for (int c = 0; c < 4; ++c)  // column-major, as Matrix Market's array format prescribes
    for (int r = 0; r < 3; ++r) {
      double value = 0;
      text >> value;
      CHECK(static_cast<float>(value) == m(r, c));  // 9 significant digits round-trip a float
    }
  CHECK_THROWS_AS(ice::write_dense_matrix(dir.file("m.csv"), m, false), ice::MeshError);

  // A writer destroyed before all rows were written removes its file.
  const std::string partial = dir.file("partial.npy");
  {
    ice::NpyMatrixWriter writer(partial, 3, 4, false);
    writer.write_rows(m.topRows(1));
    CHECK_THROWS_AS(writer.close(), ice::MeshError);
  }
  CHECK_FALSE(std::filesystem::exists(partial));
}

TEST_CASE("large OFF, OBJ and ASCII PLY files are read in chunks on several threads: the same soup, the first defect named",
          "[io]") {
  // Above 4 MB the text readers cut the file into chunks of whole lines parsed on several threads;
  // nothing about the result may depend on where the cuts fall: records numbered across chunks,
  // comments and blank lines anywhere, polygons of any size, OBJ's relative indices, and of several
  // defects the first in the file reported with its line number.
  const ice::TriangleMesh mesh = ice::make_icosphere(6);  // 40,962 vertices: about 6 MB of text
  const auto nv = mesh.V.rows(), nf = mesh.F.rows();
  ice_test::TempDir dir;
  std::ostringstream off, obj;
  off.precision(17);
  obj.precision(17);
  off << "OFF\n# a comment before the counts\n" << nv << ' ' << nf + 1 << " 0\n";
  std::vector<std::size_t> off_line_of_vertex(static_cast<std::size_t>(nv));
  std::size_t off_line = 3;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (v % 997 == 0) off << "\n# vertex " << v << " next\n", off_line += 2;
    off << mesh.V(v, 0) << ' ' << mesh.V(v, 1) << ' ' << mesh.V(v, 2) << (v % 5 == 0 ? " 0.5 0.5 0.5 1\n" : "\n");
    off_line_of_vertex[v] = ++off_line;
    obj << "v " << mesh.V(v, 0) << ' ' << mesh.V(v, 1) << ' ' << mesh.V(v, 2) << '\n';
    if (v % 1009 == 0) obj << "vn 0 0 1\n# normal\n";
  }
  for (Eigen::Index f = 0; f < nf; ++f) {
    off << "3 " << mesh.F(f, 0) << ' ' << mesh.F(f, 1) << ' ' << mesh.F(f, 2) << (f % 7 == 0 ? " 255 0 0\n" : "\n");
    if (f % 2 == 0)
      obj << "f " << mesh.F(f, 0) + 1 << "//1 " << mesh.F(f, 1) + 1 << ' ' << mesh.F(f, 2) + 1 << '\n';
    else  // relative to the vertices read so far (all of them)
      obj << "f " << mesh.F(f, 0) - nv << ' ' << mesh.F(f, 1) - nv << ' ' << mesh.F(f, 2) - nv << '\n';
  }
  off << "4 0 1 2 3\n";  // a quad last
  obj << "f 1 2 3 4\n";
  REQUIRE(off.str().size() > (std::size_t(4) << 20));
  REQUIRE(obj.str().size() > (std::size_t(4) << 20));
  for (const auto& [name, text] : {std::pair<std::string, std::string>{"big.off", off.str()}, {"big.obj", obj.str()}}) {
    INFO(name);
    const ice::MeshFile file = ice::read_mesh_file(dir.write(name, text));
    REQUIRE(file.soup.V.rows() == nv);
    CHECK(file.soup.V == mesh.V);
    REQUIRE(file.soup.polygons.size() == static_cast<std::size_t>(nf) + 1);
    bool same_faces = true;
    for (Eigen::Index f = 0; f < nf; ++f)
      same_faces = same_faces && file.soup.polygons[f] == std::vector<int>{mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
    CHECK(same_faces);
    CHECK(file.soup.polygons[nf] == std::vector<int>{0, 1, 2, 3});
  }

  // ASCII PLY, one record per line (read in parallel), with an extra element before the faces and
  // extra properties; then the same records two to a line (not one record per line: read as the
  // token stream) and with a defect (named by the stream reader).
  std::ostringstream ply;
  ply.precision(17);
  ply << "ply\nformat ascii 1.0\nelement vertex " << nv
      << "\nproperty double x\nproperty float confidence\nproperty double y\nproperty double z\n"
         "element material 2\nproperty list uchar float rgb\nelement face "
      << nf << "\nproperty list uchar int vertex_indices\nproperty uchar flags\nend_header\n";
  const std::size_t data_begin = ply.str().size();
  for (Eigen::Index v = 0; v < nv; ++v) ply << mesh.V(v, 0) << " 0.5 " << mesh.V(v, 1) << ' ' << mesh.V(v, 2) << '\n';
  ply << "3 0.1 0.2 0.3\n0\n";
  for (Eigen::Index f = 0; f < nf; ++f) ply << "3 " << mesh.F(f, 0) << ' ' << mesh.F(f, 1) << ' ' << mesh.F(f, 2) << " 7\n";
  std::string paired = ply.str();
  for (std::size_t at = data_begin, line = 0; (at = paired.find('\n', at)) != std::string::npos; ++line)
    if (line % 2 == 0) paired[at] = ' ';  // two records per line
    else ++at;
  std::string bad = ply.str();
  bad.replace(bad.size() - 2, 1, "x");  // the last face's flags
  for (const auto& [name, text] : {std::pair<std::string, std::string>{"big.ply", ply.str()}, {"paired.ply", paired}}) {
    INFO(name);
    const ice::MeshFile file = ice::read_mesh_file(dir.write(name, text));
    CHECK(file.soup.V == mesh.V);
    REQUIRE(file.soup.polygons.size() == static_cast<std::size_t>(nf));
    bool same_faces = true;
    for (Eigen::Index f = 0; f < nf; ++f)
      same_faces = same_faces && file.soup.polygons[f] == std::vector<int>{mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
    CHECK(same_faces);
  }
  const std::string bad_ply = dir.write("bad.ply", bad);
  ice_test::require_mesh_error([&] { ice::read_mesh_file(bad_ply); }, ice::MeshError::Kind::Unreadable, bad_ply,
                     "element 'face' " + std::to_string(nf - 1) + " of " + std::to_string(nf) + ": bad number 'x'");

  // Two defects far apart (different chunks): the earlier one is named, by its line.
  using Kind = ice::MeshError::Kind;
  std::string defective = off.str();
  const auto replace_line = [&](std::size_t line_number, const std::string& with) {
    std::size_t at = 0;
    for (std::size_t line = 1; line < line_number; ++line) at = defective.find('\n', at) + 1;
    defective.replace(at, defective.find('\n', at) - at, with);
  };
  const std::size_t early = off_line_of_vertex[static_cast<std::size_t>(nv) * 3 / 4];
  const std::size_t late = off_line_of_vertex[static_cast<std::size_t>(nv) - 2];
  replace_line(late, "1 2");
  replace_line(early, "1 2 x");
  const std::string path = dir.write("two_defects.off", defective);
  ice_test::require_mesh_error([&] { ice::read_mesh_file(path); }, Kind::Unreadable, path,
                     "line " + std::to_string(early) + ": vertex needs three numbers");
  // One record short at the very end: the whole file is counted before any record is parsed.
  const std::string short_text = off.str().substr(0, off.str().size() - std::string("4 0 1 2 3\n").size());
  const std::string short_path = dir.write("short.off", short_text);
  ice_test::require_mesh_error([&] { ice::read_mesh_file(short_path); }, Kind::Unreadable, short_path, "file ends early");
}
