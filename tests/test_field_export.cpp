// Binary glTF with fields (ice/scalar_field_io.h): read back with tinygltf, the file holds the
// mesh (float32 positions, the faces, unit normals), one attribute per field with its values, the
// colours of the colour field through viridis (linear RGB) over the recorded range, and the
// polylines as LINES; bad input is refused before anything is written.
#include <catch2/catch.hpp>

#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/scalar_field_io.h"
#include "test_support.h"

namespace {

tinygltf::Model load_glb(const std::string& path) {
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string error, warning;
  const bool ok = loader.LoadBinaryFromFile(&model, &error, &warning, path);
  INFO(error << warning);
  REQUIRE(ok);
  return model;
}

// The elements of accessor `index` as doubles (float32 or uint32 components).
std::vector<double> accessor_values(const tinygltf::Model& model, int index) {
  const tinygltf::Accessor& accessor = model.accessors.at(static_cast<std::size_t>(index));
  const tinygltf::BufferView& view = model.bufferViews.at(static_cast<std::size_t>(accessor.bufferView));
  const std::vector<unsigned char>& data = model.buffers.at(static_cast<std::size_t>(view.buffer)).data;
  const std::size_t components = accessor.type == TINYGLTF_TYPE_VEC3 ? 3 : 1;
  const std::size_t count = accessor.count * components;
  REQUIRE(view.byteOffset + accessor.byteOffset + 4 * count <= data.size());
  const unsigned char* begin = data.data() + view.byteOffset + accessor.byteOffset;
  std::vector<double> values(count);
  for (std::size_t i = 0; i < count; ++i) {
    if (accessor.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
      float x;
      std::memcpy(&x, begin + 4 * i, 4);
      values[i] = x;
    } else {
      REQUIRE(accessor.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
      std::uint32_t x;
      std::memcpy(&x, begin + 4 * i, 4);
      values[i] = x;
    }
  }
  return values;
}

double srgb_to_linear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

}  // namespace

TEST_CASE("viridis: the samples at their points, continuous, lightness increasing", "[export]") {
  const auto& samples = ice::viridis_samples();
  double previous_lightness = -1;
  for (int k = 0; k <= 16; ++k) {
    const std::array<double, 3> colour = ice::viridis(k / 16.0);
    for (int c = 0; c < 3; ++c) CHECK(std::abs(colour[c] * 255 - samples[k][c]) < 1e-9);
    // Relative luminance rises along the map (what makes it readable in grey too).
    const double lightness = 0.2126 * srgb_to_linear(colour[0]) + 0.7152 * srgb_to_linear(colour[1]) +
                             0.0722 * srgb_to_linear(colour[2]);
    CHECK(lightness > previous_lightness);
    previous_lightness = lightness;
  }
  for (double t = 0; t < 1; t += 1.0 / 997) {
    const std::array<double, 3> a = ice::viridis(t), b = ice::viridis(t + 1e-6);
    for (int c = 0; c < 3; ++c) CHECK(std::abs(a[c] - b[c]) < 1e-4);
  }
  CHECK(ice::viridis(-3) == ice::viridis(0));
  CHECK(ice::viridis(7) == ice::viridis(1));
  CHECK(ice::viridis(std::numeric_limits<double>::quiet_NaN()) == ice::viridis(0));
}

TEST_CASE("glTF with fields and polylines reads back", "[export]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(2);
  const Eigen::Index n = mesh.V.rows();
  Eigen::VectorXd height = mesh.V.col(2), label(n);
  for (Eigen::Index i = 0; i < n; ++i) label(i) = static_cast<double>(i % 7);
  height(3) = std::numeric_limits<double>::quiet_NaN();  // no value: grey, left out of the range
  const std::vector<ice::ScalarField> fields{{"label", label}, {"height", height}};
  std::vector<ice::Positions> polylines(2);
  polylines[0] = mesh.V.topRows(4);
  polylines[1] = mesh.V.middleRows(10, 2);
  ice_test::TempDir dir;
  const std::string path = dir.file("fields.glb");
  ice::GltfWriteOptions options;
  options.colour_field = "height";
  ice::write_gltf_with_fields(path, mesh, fields, polylines, options);

  const tinygltf::Model model = load_glb(path);
  REQUIRE(model.meshes.size() == 2);
  REQUIRE(model.nodes.size() == 2);
  REQUIRE(model.scenes.size() == 1);
  CHECK(model.scenes[0].nodes.size() == 2);
  const tinygltf::Primitive& surface = model.meshes[0].primitives.at(0);
  CHECK(surface.mode == TINYGLTF_MODE_TRIANGLES);

  // Positions (float32 of the input), bounds recorded, faces exact, normals unit and outward.
  const std::vector<double> positions = accessor_values(model, surface.attributes.at("POSITION"));
  REQUIRE(positions.size() == static_cast<std::size_t>(3 * n));
  for (Eigen::Index i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) CHECK(positions[3 * i + k] == static_cast<float>(mesh.V(i, k)));
  const tinygltf::Accessor& position_accessor = model.accessors[surface.attributes.at("POSITION")];
  REQUIRE(position_accessor.minValues.size() == 3);
  for (int k = 0; k < 3; ++k) {
    CHECK(position_accessor.minValues[k] == static_cast<float>(mesh.V.col(k).minCoeff()));
    CHECK(position_accessor.maxValues[k] == static_cast<float>(mesh.V.col(k).maxCoeff()));
  }
  const std::vector<double> indices = accessor_values(model, surface.indices);
  REQUIRE(indices.size() == static_cast<std::size_t>(3 * mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) CHECK(indices[3 * f + k] == mesh.F(f, k));
  const std::vector<double> normals = accessor_values(model, surface.attributes.at("NORMAL"));
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d normal(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]);
    CHECK(std::abs(normal.norm() - 1) < 1e-6);
    CHECK(normal.dot(mesh.V.row(i).transpose().normalized()) > 0.9);  // a sphere's normal is its position
  }

  // Fields: attributes "_" + upper case, values as float32, ranges over finite values.
  const std::vector<double> labels = accessor_values(model, surface.attributes.at("_LABEL"));
  const std::vector<double> heights = accessor_values(model, surface.attributes.at("_HEIGHT"));
  for (Eigen::Index i = 0; i < n; ++i) {
    CHECK(labels[i] == label(i));
    if (i != 3) CHECK(heights[i] == static_cast<float>(height(i)));
  }
  CHECK(std::isnan(heights[3]));
  const tinygltf::Value& extras = model.meshes[0].extras;
  REQUIRE(extras.IsObject());
  CHECK(extras.Get("colour_field").Get<std::string>() == "height");
  CHECK(extras.Get("colour_map").Get<std::string>() == "viridis");
  Eigen::VectorXd finite_height = height;
  finite_height(3) = height(4);
  const double low = finite_height.minCoeff(), high = finite_height.maxCoeff();
  CHECK(extras.Get("range").Get(0).GetNumberAsDouble() == low);
  CHECK(extras.Get("range").Get(1).GetNumberAsDouble() == high);
  REQUIRE(extras.Get("fields").ArrayLen() == 2);
  CHECK(extras.Get("fields").Get(0).Get("name").Get<std::string>() == "label");
  CHECK(extras.Get("fields").Get(0).Get("attribute").Get<std::string>() == "_LABEL");
  CHECK(extras.Get("fields").Get(0).Get("max").GetNumberAsDouble() == 6);

  // Colours: viridis of the normalised value, in linear RGB; the value-less vertex grey.
  const std::vector<double> colours = accessor_values(model, surface.attributes.at("COLOR_0"));
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::array<double, 3> srgb = i == 3 ? std::array<double, 3>{0.5, 0.5, 0.5}
                                              : ice::viridis((height(i) - low) / (high - low));
    for (int k = 0; k < 3; ++k) CHECK(std::abs(colours[3 * i + k] - srgb_to_linear(srgb[k])) < 1e-6);
  }

  // Lines: each polyline's segments, joined end to end, in the line material.
  const tinygltf::Primitive& lines = model.meshes[1].primitives.at(0);
  CHECK(lines.mode == TINYGLTF_MODE_LINE);
  const std::vector<double> line_points = accessor_values(model, lines.attributes.at("POSITION"));
  const std::vector<double> line_indices = accessor_values(model, lines.indices);
  CHECK(line_points.size() == 3 * 6);
  REQUIRE(line_indices.size() == 2 * (3 + 1));
  const std::vector<double> expected{0, 1, 1, 2, 2, 3, 4, 5};
  CHECK(line_indices == expected);
  for (int k = 0; k < 3; ++k) CHECK(line_points[3 * 4 + k] == static_cast<float>(mesh.V(10, k)));
  REQUIRE(lines.material >= 0);
  CHECK(model.materials[lines.material].pbrMetallicRoughness.baseColorFactor[0] == 1.0);
}

TEST_CASE("glTF: no fields, no lines, no colours; bad input refused before writing", "[export]") {
  const ice::TriangleMesh mesh = ice::make_flat_disk(3);
  ice_test::TempDir dir;
  const std::string path = dir.file("plain.glb");
  ice::write_gltf_with_fields(path, mesh, {});
  const tinygltf::Model model = load_glb(path);
  CHECK(model.meshes.size() == 1);
  CHECK(model.meshes[0].primitives.at(0).attributes.count("COLOR_0") == 0);

  // Never replaced unless asked.
  CHECK_THROWS_AS(ice::write_gltf_with_fields(path, mesh, {}), ice::MeshError);
  ice::GltfWriteOptions overwrite;
  overwrite.overwrite = true;
  CHECK_NOTHROW(ice::write_gltf_with_fields(path, mesh, {}, {}, overwrite));

  const std::string other = dir.file("bad.glb");
  const Eigen::VectorXd short_field = Eigen::VectorXd::Zero(mesh.V.rows() - 1);
  CHECK_THROWS_WITH(ice::write_gltf_with_fields(other, mesh, {{"u", short_field}}),
                    Catch::Contains(other) && Catch::Contains("values for"));
  const Eigen::VectorXd values = Eigen::VectorXd::Zero(mesh.V.rows());
  CHECK_THROWS_WITH(ice::write_gltf_with_fields(other, mesh, {{"u", values}, {"U", values}}),
                    Catch::Contains("differ only in case"));
  ice::GltfWriteOptions unknown;
  unknown.colour_field = "v";
  CHECK_THROWS_WITH(ice::write_gltf_with_fields(other, mesh, {{"u", values}}, {}, unknown),
                    Catch::Contains("colour field 'v'"));
  CHECK(!std::filesystem::exists(other));
}

TEST_CASE("PLY polylines: points and edges, binary and ASCII, read back", "[export]") {
  std::vector<ice::Positions> polylines(3);
  polylines[0] = (ice::Positions(3, 3) << 0, 0, 0, 1, 0, 0, 1, 1, 0.1).finished();
  polylines[1] = ice::Positions(1, 3);  // a single point: no edge
  polylines[1] << 5, 5, 5;
  polylines[2] = (ice::Positions(2, 3) << 0.1, 0.2, 0.3, 1.0 / 3, 2.0 / 3, 1e-17).finished();
  ice_test::TempDir dir;
  // Expected: 6 points; edges (0,1,0), (1,2,0), (4,5,2).
  const std::vector<std::array<int, 3>> edges{{0, 1, 0}, {1, 2, 0}, {4, 5, 2}};
  std::vector<double> points;
  for (const ice::Positions& line : polylines)
    for (Eigen::Index i = 0; i < line.rows(); ++i)
      for (int k = 0; k < 3; ++k) points.push_back(line(i, k));

  SECTION("binary") {
    const std::string path = dir.file("lines.ply");
    ice::write_ply_polylines(path, polylines);
    std::ifstream in(path, std::ios::binary);
    std::string line, header;
    while (std::getline(in, line) && line != "end_header") header += line + "\n";
    CHECK(header.find("format binary_little_endian 1.0") != std::string::npos);
    CHECK(header.find("element vertex 6\n") != std::string::npos);
    CHECK(header.find("element edge 3\nproperty int vertex1\nproperty int vertex2\nproperty int polyline\n") !=
          std::string::npos);
    for (const double expected : points) {
      double x;
      in.read(reinterpret_cast<char*>(&x), sizeof x);
      CHECK(x == expected);  // exact doubles
    }
    for (const auto& edge : edges)
      for (const int expected : edge) {
        std::int32_t x;
        in.read(reinterpret_cast<char*>(&x), sizeof x);
        CHECK(x == expected);
      }
    CHECK(in.good());
    CHECK(in.peek() == std::char_traits<char>::eof());
    CHECK_THROWS_WITH(ice::write_ply_polylines(path, polylines), Catch::Contains(path));  // never replaced unasked
  }
  SECTION("ASCII") {
    const std::string path = dir.file("lines_ascii.ply");
    ice::ScalarFieldWriteOptions options;
    options.binary = false;
    ice::write_ply_polylines(path, polylines, options);
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line) && line != "end_header") {
    }
    for (std::size_t p = 0; p < 6; ++p) {
      double x, y, z;
      in >> x >> y >> z;
      CHECK(x == points[3 * p]);
      CHECK(y == points[3 * p + 1]);
      CHECK(z == points[3 * p + 2]);
    }
    for (const auto& edge : edges) {
      int a, b, c;
      in >> a >> b >> c;
      CHECK(std::array<int, 3>{a, b, c} == edge);
    }
  }
  SECTION("bad polylines refused before writing") {
    const std::string path = dir.file("bad.ply");
    CHECK_THROWS_AS(ice::write_ply_polylines(path, {ice::Positions(2, 2)}), ice::MeshError);
    CHECK(!std::filesystem::exists(path));
  }
}
