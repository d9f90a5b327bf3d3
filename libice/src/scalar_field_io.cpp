#include "ice/scalar_field_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "ice/mesh_io.h"

#include <Eigen/Geometry>
#include <tiny_gltf.h>

namespace ice {
namespace {

namespace fs = std::filesystem;

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "write_ply_with_fields writes binary_little_endian by copying memory: little-endian hosts only"
#endif

bool valid_property_name(const std::string& name) {
  if (name.empty()) return false;
  const auto alpha = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; };
  if (!alpha(name[0])) return false;
  for (char c : name)
    if (!alpha(c) && !(c >= '0' && c <= '9')) return false;
  return true;
}

// Appends the bytes of a trivially copyable value to a buffer.
template <class T>
void append(std::vector<char>& buffer, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  buffer.insert(buffer.end(), bytes, bytes + sizeof(T));
}

// Flushes a written file; if any write failed, removes what was written (never leave a truncated
// file that looks complete) and throws MeshError naming the path.
void finish_output(std::ofstream& out, const std::string& path) {
  out.flush();
  if (out) return;
  out.close();
  std::error_code ec;
  fs::remove(path, ec);
  throw MeshError(MeshError::Kind::Unwritable, path, "write failed (disk full?)");
}

// The preconditions both writers share (MeshError naming the path).
void check_mesh_and_fields(const std::string& path, const TriangleMesh& mesh, const std::vector<ScalarField>& fields) {
  const auto fail = [&](const std::string& message) { throw MeshError(MeshError::Kind::Unwritable, path, message); };
  const Eigen::Index nv = mesh.V.rows(), nf = mesh.F.rows();
  if (mesh.V.cols() != 3 || mesh.F.cols() != 3 || (nf > 0 && (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= nv)))
    fail("invalid mesh (needs n×3 positions and in-range n×3 faces)");
  std::set<std::string> names{"x", "y", "z"};
  for (const ScalarField& field : fields) {
    if (!valid_property_name(field.name))
      fail("invalid field name '" + field.name + "' (letters, digits and '_', not starting with a digit)");
    if (!names.insert(field.name).second) fail("field name '" + field.name + "' is used twice (or is x, y or z)");
    if (field.values.size() != nv) {
      std::ostringstream message;
      message << "field '" << field.name << "' has " << field.values.size() << " values for " << nv << " vertices";
      fail(message.str());
    }
  }
}

}  // namespace

void write_ply_with_fields(const std::string& path, const TriangleMesh& mesh, const std::vector<ScalarField>& fields,
                           const ScalarFieldWriteOptions& options) {
  const auto fail = [&](const std::string& message) { throw MeshError(MeshError::Kind::Unwritable, path, message); };
  const Eigen::Index nv = mesh.V.rows(), nf = mesh.F.rows();
  check_mesh_and_fields(path, mesh, fields);
  require_writable(path, options.overwrite);

  std::ofstream out(path, options.binary ? std::ios::binary : std::ios::out);
  if (!out) fail("cannot be opened for writing");
  out << "ply\nformat " << (options.binary ? "binary_little_endian" : "ascii") << " 1.0\n"
      << "comment written by ICE (libice write_ply_with_fields)\n"
      << "element vertex " << nv << "\nproperty double x\nproperty double y\nproperty double z\n";
  for (const ScalarField& field : fields) out << "property double " << field.name << '\n';
  out << "element face " << nf << "\nproperty list uchar int vertex_indices\nend_header\n";

  if (options.binary) {
    std::vector<char> buffer;
    buffer.reserve(static_cast<std::size_t>(nv) * 8 * (3 + fields.size()) + static_cast<std::size_t>(nf) * 13);
    for (Eigen::Index i = 0; i < nv; ++i) {
      for (int k = 0; k < 3; ++k) append(buffer, mesh.V(i, k));
      for (const ScalarField& field : fields) append(buffer, field.values(i));
    }
    for (Eigen::Index f = 0; f < nf; ++f) {
      append(buffer, static_cast<std::uint8_t>(3));
      for (int k = 0; k < 3; ++k) append(buffer, static_cast<std::int32_t>(mesh.F(f, k)));
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  } else {
    out.precision(std::numeric_limits<double>::max_digits10);
    for (Eigen::Index i = 0; i < nv; ++i) {
      out << mesh.V(i, 0) << ' ' << mesh.V(i, 1) << ' ' << mesh.V(i, 2);
      for (const ScalarField& field : fields) out << ' ' << field.values(i);
      out << '\n';
    }
    for (Eigen::Index f = 0; f < nf; ++f) out << "3 " << mesh.F(f, 0) << ' ' << mesh.F(f, 1) << ' ' << mesh.F(f, 2) << '\n';
  }
  finish_output(out, path);
}

void write_ply_polylines(const std::string& path, const std::vector<Positions>& polylines,
                         const ScalarFieldWriteOptions& options) {
  const auto fail = [&](const std::string& message) { throw MeshError(MeshError::Kind::Unwritable, path, message); };
  std::size_t points = 0, edges = 0;
  for (const Positions& line : polylines) {
    if (line.rows() > 0 && line.cols() != 3) fail("a polyline's points are not 3D");
    points += static_cast<std::size_t>(line.rows());
    edges += line.rows() > 1 ? static_cast<std::size_t>(line.rows() - 1) : 0;
  }
  if (points > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) fail("too many points for int indices");
  require_writable(path, options.overwrite);
  std::ofstream out(path, options.binary ? std::ios::binary : std::ios::out);
  if (!out) fail("cannot be opened for writing");
  out << "ply\nformat " << (options.binary ? "binary_little_endian" : "ascii") << " 1.0\n"
      << "comment written by ICE (libice write_ply_polylines)\n"
      << "element vertex " << points << "\nproperty double x\nproperty double y\nproperty double z\n"
      << "element edge " << edges << "\nproperty int vertex1\nproperty int vertex2\nproperty int polyline\nend_header\n";
  if (!options.binary) out.precision(std::numeric_limits<double>::max_digits10);
  std::vector<char> buffer;
  for (const Positions& line : polylines)
    for (Eigen::Index i = 0; i < line.rows(); ++i) {
      if (options.binary)
        for (int k = 0; k < 3; ++k) append(buffer, line(i, k));
      else
        out << line(i, 0) << ' ' << line(i, 1) << ' ' << line(i, 2) << '\n';
    }
  std::int32_t first = 0;
  for (std::size_t p = 0; p < polylines.size(); ++p) {
    const auto count = static_cast<std::int32_t>(polylines[p].rows());
    for (std::int32_t i = 0; i + 1 < count; ++i) {
      const std::int32_t edge[3] = {first + i, first + i + 1, static_cast<std::int32_t>(p)};
      if (options.binary)
        for (const std::int32_t value : edge) append(buffer, value);
      else
        out << edge[0] << ' ' << edge[1] << ' ' << edge[2] << '\n';
    }
    first += count;
  }
  if (options.binary) out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  finish_output(out, path);
}

// ---- binary glTF --------------------------------------------------------------------------------------

const std::array<std::array<unsigned char, 3>, 17>& viridis_samples() {
  // matplotlib's viridis (public domain, CC0) at t = k/16.
  static const std::array<std::array<unsigned char, 3>, 17> samples{{
      {0x44, 0x01, 0x54}, {0x48, 0x18, 0x6a}, {0x47, 0x2d, 0x7b}, {0x42, 0x40, 0x86}, {0x3b, 0x52, 0x8b},
      {0x33, 0x63, 0x8d}, {0x2c, 0x72, 0x8e}, {0x26, 0x82, 0x8e}, {0x21, 0x91, 0x8c}, {0x1f, 0xa0, 0x88},
      {0x28, 0xae, 0x80}, {0x3f, 0xbc, 0x73}, {0x5e, 0xc9, 0x62}, {0x84, 0xd4, 0x4b}, {0xad, 0xdc, 0x30},
      {0xd8, 0xe2, 0x19}, {0xfd, 0xe7, 0x25}}};
  return samples;
}

std::array<double, 3> viridis(double t) {
  const auto& samples = viridis_samples();
  if (!(t > 0)) t = 0;  // NaN too
  if (t > 1) t = 1;
  const double scaled = t * 16;
  const int k = std::min(15, static_cast<int>(scaled));
  const double w = scaled - k;
  std::array<double, 3> colour{};
  for (int c = 0; c < 3; ++c) colour[c] = ((1 - w) * samples[k][c] + w * samples[k + 1][c]) / 255.0;
  return colour;
}

namespace {

// sRGB → linear (glTF's COLOR_0 and baseColorFactor are linear).
double srgb_to_linear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

// Builds a glTF model buffer by buffer view: each block of floats or indices becomes a view and an
// accessor of the one buffer.
class GltfBuilder {
 public:
  explicit GltfBuilder(tinygltf::Model& model) : model_(model) { model_.buffers.emplace_back(); }

  // float32 elements of `components` each (1 SCALAR, 3 VEC3); min/max recorded when asked (POSITION needs them).
  int add_floats(const std::vector<float>& data, int components, bool bounds, int target) {
    const int view = add_view(data.data(), data.size() * sizeof(float), target);
    tinygltf::Accessor accessor;
    accessor.bufferView = view;
    accessor.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    accessor.count = data.size() / static_cast<std::size_t>(components);
    accessor.type = components == 1 ? TINYGLTF_TYPE_SCALAR : TINYGLTF_TYPE_VEC3;
    if (bounds && accessor.count > 0) {
      accessor.minValues.assign(static_cast<std::size_t>(components), std::numeric_limits<double>::infinity());
      accessor.maxValues.assign(static_cast<std::size_t>(components), -std::numeric_limits<double>::infinity());
      for (std::size_t i = 0; i < data.size(); ++i) {
        const std::size_t c = i % static_cast<std::size_t>(components);
        accessor.minValues[c] = std::min<double>(accessor.minValues[c], data[i]);
        accessor.maxValues[c] = std::max<double>(accessor.maxValues[c], data[i]);
      }
    }
    model_.accessors.push_back(accessor);
    return static_cast<int>(model_.accessors.size()) - 1;
  }

  int add_indices(const std::vector<std::uint32_t>& data) {
    const int view = add_view(data.data(), data.size() * sizeof(std::uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    tinygltf::Accessor accessor;
    accessor.bufferView = view;
    accessor.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    accessor.count = data.size();
    accessor.type = TINYGLTF_TYPE_SCALAR;
    model_.accessors.push_back(accessor);
    return static_cast<int>(model_.accessors.size()) - 1;
  }

 private:
  int add_view(const void* data, std::size_t bytes, int target) {
    std::vector<unsigned char>& buffer = model_.buffers[0].data;
    buffer.resize((buffer.size() + 3) / 4 * 4);  // 4-byte alignment of every view (float32, uint32)
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = buffer.size();
    view.byteLength = bytes;
    view.target = target;
    const auto* begin = static_cast<const unsigned char*>(data);
    buffer.insert(buffer.end(), begin, begin + bytes);
    model_.bufferViews.push_back(view);
    return static_cast<int>(model_.bufferViews.size()) - 1;
  }

  tinygltf::Model& model_;
};

// Finite range of a field ({0, 0} when no value is finite).
std::array<double, 2> finite_range(const Eigen::VectorXd& values) {
  double low = std::numeric_limits<double>::infinity(), high = -low;
  for (Eigen::Index i = 0; i < values.size(); ++i)
    if (std::isfinite(values(i))) low = std::min(low, values(i)), high = std::max(high, values(i));
  if (low > high) return {0, 0};
  return {low, high};
}

std::string upper_case(std::string name) {
  for (char& c : name) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return name;
}

}  // namespace

void write_gltf_with_fields(const std::string& path, const TriangleMesh& mesh, const std::vector<ScalarField>& fields,
                            const std::vector<Positions>& polylines, const GltfWriteOptions& options) {
  const auto fail = [&](const std::string& message) { throw MeshError(MeshError::Kind::Unwritable, path, message); };
  check_mesh_and_fields(path, mesh, fields);
  std::set<std::string> attributes;
  for (const ScalarField& field : fields)
    if (!attributes.insert(upper_case(field.name)).second)
      fail("field names '" + field.name + "' and another differ only in case (glTF attribute names are upper case)");
  for (const Positions& line : polylines)
    if (line.rows() > 0 && line.cols() != 3) fail("a polyline's points are not 3D");
  int colour_index = fields.empty() ? -1 : 0;
  if (!options.colour_field.empty()) {
    colour_index = -1;
    for (std::size_t i = 0; i < fields.size(); ++i)
      if (fields[i].name == options.colour_field) colour_index = static_cast<int>(i);
    if (colour_index < 0) fail("the colour field '" + options.colour_field + "' is not among the fields");
  }
  require_writable(path, options.overwrite);

  const Eigen::Index nv = mesh.V.rows(), nf = mesh.F.rows();
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "ICE (libice write_gltf_with_fields)";
  GltfBuilder builder(model);

  std::vector<float> positions(static_cast<std::size_t>(3 * nv));
  for (Eigen::Index i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k) positions[static_cast<std::size_t>(3 * i + k)] = static_cast<float>(mesh.V(i, k));
  // Area-weighted vertex normals (the cross products' sum), unit length as glTF requires.
  Eigen::MatrixXd normal_sum = Eigen::MatrixXd::Zero(nv, 3);
  for (Eigen::Index f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const Eigen::RowVector3d n = (b - a).cross(c - a).transpose();
    for (int k = 0; k < 3; ++k) normal_sum.row(mesh.F(f, k)) += n;
  }
  std::vector<float> normals(static_cast<std::size_t>(3 * nv));
  for (Eigen::Index i = 0; i < nv; ++i) {
    const double length = normal_sum.row(i).norm();
    const Eigen::RowVector3d n = length > 0 && std::isfinite(length) ? Eigen::RowVector3d(normal_sum.row(i) / length)
                                                                      : Eigen::RowVector3d(0, 0, 1);
    for (int k = 0; k < 3; ++k) normals[static_cast<std::size_t>(3 * i + k)] = static_cast<float>(n(k));
  }
  std::vector<std::uint32_t> indices(static_cast<std::size_t>(3 * nf));
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) indices[static_cast<std::size_t>(3 * f + k)] = static_cast<std::uint32_t>(mesh.F(f, k));

  tinygltf::Primitive surface;
  surface.mode = TINYGLTF_MODE_TRIANGLES;
  surface.attributes["POSITION"] = builder.add_floats(positions, 3, true, TINYGLTF_TARGET_ARRAY_BUFFER);
  surface.attributes["NORMAL"] = builder.add_floats(normals, 3, false, TINYGLTF_TARGET_ARRAY_BUFFER);
  surface.indices = builder.add_indices(indices);
  surface.material = 0;

  tinygltf::Value::Array field_records;
  for (const ScalarField& field : fields) {
    std::vector<float> values(static_cast<std::size_t>(nv));
    for (Eigen::Index i = 0; i < nv; ++i) values[static_cast<std::size_t>(i)] = static_cast<float>(field.values(i));
    const std::string attribute = "_" + upper_case(field.name);
    surface.attributes[attribute] = builder.add_floats(values, 1, false, TINYGLTF_TARGET_ARRAY_BUFFER);
    const std::array<double, 2> range = finite_range(field.values);
    tinygltf::Value::Object record;
    record["name"] = tinygltf::Value(field.name);
    record["attribute"] = tinygltf::Value(attribute);
    record["min"] = tinygltf::Value(range[0]);
    record["max"] = tinygltf::Value(range[1]);
    field_records.emplace_back(record);
  }
  tinygltf::Value::Object extras;
  extras["fields"] = tinygltf::Value(field_records);
  if (colour_index >= 0) {
    const ScalarField& field = fields[static_cast<std::size_t>(colour_index)];
    const std::array<double, 2> range = finite_range(field.values);
    const double span = range[1] - range[0];
    std::vector<float> colours(static_cast<std::size_t>(3 * nv));
    for (Eigen::Index i = 0; i < nv; ++i) {
      const double value = field.values(i);
      std::array<double, 3> colour{0.5, 0.5, 0.5};  // no value (NaN, unreachable): grey
      if (std::isfinite(value)) colour = viridis(span > 0 ? (value - range[0]) / span : 0.5);
      for (int k = 0; k < 3; ++k) colours[static_cast<std::size_t>(3 * i + k)] = static_cast<float>(srgb_to_linear(colour[k]));
    }
    surface.attributes["COLOR_0"] = builder.add_floats(colours, 3, false, TINYGLTF_TARGET_ARRAY_BUFFER);
    extras["colour_field"] = tinygltf::Value(field.name);
    extras["colour_map"] = tinygltf::Value(std::string("viridis"));
    extras["range"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(range[0]), tinygltf::Value(range[1])});
  }

  // Materials: the surface (white base: the vertex colours show; matte), the lines.
  tinygltf::Material surface_material;
  surface_material.name = "surface";
  surface_material.doubleSided = true;
  surface_material.pbrMetallicRoughness.metallicFactor = 0;
  surface_material.pbrMetallicRoughness.roughnessFactor = 1;
  model.materials.push_back(surface_material);

  tinygltf::Mesh surface_mesh;
  surface_mesh.name = "mesh";
  surface_mesh.primitives.push_back(surface);
  surface_mesh.extras = tinygltf::Value(extras);
  model.meshes.push_back(surface_mesh);
  tinygltf::Node surface_node;
  surface_node.name = "mesh";
  surface_node.mesh = 0;
  model.nodes.push_back(surface_node);

  std::vector<float> line_points;
  std::vector<std::uint32_t> line_indices;
  for (const Positions& line : polylines) {
    const auto first = static_cast<std::uint32_t>(line_points.size() / 3);
    for (Eigen::Index i = 0; i < line.rows(); ++i)
      for (int k = 0; k < 3; ++k) line_points.push_back(static_cast<float>(line(i, k)));
    for (Eigen::Index i = 0; i + 1 < line.rows(); ++i) {
      line_indices.push_back(first + static_cast<std::uint32_t>(i));
      line_indices.push_back(first + static_cast<std::uint32_t>(i + 1));
    }
  }
  if (!line_indices.empty()) {
    tinygltf::Material line_material;
    line_material.name = "lines";
    line_material.pbrMetallicRoughness.baseColorFactor = {srgb_to_linear(options.line_colour[0]),
                                                          srgb_to_linear(options.line_colour[1]),
                                                          srgb_to_linear(options.line_colour[2]), 1.0};
    line_material.pbrMetallicRoughness.metallicFactor = 0;
    line_material.pbrMetallicRoughness.roughnessFactor = 1;
    model.materials.push_back(line_material);
    tinygltf::Primitive lines;
    lines.mode = TINYGLTF_MODE_LINE;
    lines.attributes["POSITION"] = builder.add_floats(line_points, 3, true, TINYGLTF_TARGET_ARRAY_BUFFER);
    lines.indices = builder.add_indices(line_indices);
    lines.material = 1;
    tinygltf::Mesh line_mesh;
    line_mesh.name = "lines";
    line_mesh.primitives.push_back(lines);
    model.meshes.push_back(line_mesh);
    tinygltf::Node line_node;
    line_node.name = "lines";
    line_node.mesh = 1;
    model.nodes.push_back(line_node);
  }
  tinygltf::Scene scene;
  for (int node = 0; node < static_cast<int>(model.nodes.size()); ++node) scene.nodes.push_back(node);
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  tinygltf::TinyGLTF writer;
  // embedImages, embedBuffers, prettyPrint, writeBinary
  if (!writer.WriteGltfSceneToFile(&model, path, true, true, false, true)) {
    std::error_code ec;
    fs::remove(path, ec);
    fail("write failed");
  }
}

// ---- dense matrices --------------------------------------------------------------------------------

namespace {
// A .npy header of a C-order rows × cols matrix of `descr` ('<f4', '<f8'): magic, version 1.0, header
// length (little-endian uint16), then the dictionary padded with spaces and a newline so that the
// data starts on a multiple of 64 bytes.
void write_npy_header(std::ostream& out, const char* descr, Eigen::Index rows, Eigen::Index cols) {
  std::string header = std::string("{'descr': '") + descr + "', 'fortran_order': False, 'shape': (" + std::to_string(rows) +
                       ", " + std::to_string(cols) + "), }";
  const std::size_t unpadded = 10 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header.push_back('\n');
  const auto length = static_cast<std::uint16_t>(header.size());
  out.write("\x93NUMPY\x01\x00", 8);
  const char length_bytes[2] = {static_cast<char>(length & 0xff), static_cast<char>(length >> 8)};
  out.write(length_bytes, 2);
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
}
}  // namespace

NpyMatrixWriter::NpyMatrixWriter(const std::string& path, Eigen::Index rows, Eigen::Index cols, bool overwrite)
    : path_(path), rows_(rows), cols_(cols) {
  if (rows < 0 || cols < 0) throw MeshError(MeshError::Kind::Unwritable, path, "negative matrix size");
  require_writable(path, overwrite);
  out_.open(path, std::ios::binary);
  if (!out_) throw MeshError(MeshError::Kind::Unwritable, path, "cannot create the file");
  write_npy_header(out_, "<f4", rows, cols);
}

NpyMatrixWriter::~NpyMatrixWriter() {
  if (!closed_) {
    out_.close();
    std::error_code ec;
    fs::remove(path_, ec);
  }
}

void NpyMatrixWriter::write_rows(const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& block) {
  if (block.cols() != cols_ || written_ + block.rows() > rows_)
    throw MeshError(MeshError::Kind::Unwritable, path_, "rows beyond the declared matrix shape");
  out_.write(reinterpret_cast<const char*>(block.data()), static_cast<std::streamsize>(block.size() * sizeof(float)));
  if (!out_) throw MeshError(MeshError::Kind::Unwritable, path_, "write failed (disk full?)");
  written_ += block.rows();
}

void NpyMatrixWriter::close() {
  if (written_ != rows_)
    throw MeshError(MeshError::Kind::Unwritable, path_,
                    std::to_string(written_) + " of " + std::to_string(rows_) + " rows written");
  out_.flush();
  if (!out_) throw MeshError(MeshError::Kind::Unwritable, path_, "write failed (disk full?)");
  out_.close();
  closed_ = true;
}

void write_dense_matrix(const std::string& path, const Eigen::MatrixXf& matrix, bool overwrite) {
  const std::string extension = fs::path(path).extension().string();
  if (extension == ".npy") {
    NpyMatrixWriter writer(path, matrix.rows(), matrix.cols(), overwrite);
    writer.write_rows(matrix);
    writer.close();
    return;
  }
  if (extension != ".mtx")
    throw MeshError(MeshError::Kind::Unwritable, path, "unknown matrix format (use .npy or .mtx)");
  require_writable(path, overwrite);
  std::ofstream out(path);
  if (!out) throw MeshError(MeshError::Kind::Unwritable, path, "cannot create the file");
  out << "%%MatrixMarket matrix array real general\n" << matrix.rows() << ' ' << matrix.cols() << '\n';
  out.precision(9);
  for (Eigen::Index c = 0; c < matrix.cols(); ++c)
    for (Eigen::Index r = 0; r < matrix.rows(); ++r) out << matrix(r, c) << '\n';
  finish_output(out, path);
}

// ---- float64 .npy ------------------------------------------------------------------------------------

Eigen::MatrixXd read_npy_matrix(const std::string& path) {
  const auto fail = [&](const std::string& message) { throw MeshError(MeshError::Kind::Unreadable, path, message); };
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("cannot be opened");
  char magic[8] = {};
  in.read(magic, 8);
  if (!in || std::memcmp(magic, "\x93NUMPY", 6) != 0) fail("not a NumPy .npy file (no \\x93NUMPY magic)");
  const int major = static_cast<unsigned char>(magic[6]);
  if (major < 1 || major > 3) fail("unknown .npy format version " + std::to_string(major));
  std::uint32_t header_length = 0;
  unsigned char length_bytes[4] = {};
  in.read(reinterpret_cast<char*>(length_bytes), major == 1 ? 2 : 4);
  if (!in) fail("truncated header");
  header_length = length_bytes[0] | (length_bytes[1] << 8) | (major == 1 ? 0u : (length_bytes[2] << 16) | (std::uint32_t(length_bytes[3]) << 24));
  if (header_length > (1u << 20)) fail("header too long");
  std::string header(header_length, '\0');
  in.read(header.data(), header_length);
  if (!in) fail("truncated header");
  // The header is a Python dict literal: 'descr', 'fortran_order', 'shape'.
  const auto value_of = [&](const std::string& key) {
    const std::size_t at = header.find("'" + key + "'");
    if (at == std::string::npos) fail("header without '" + key + "'");
    const std::size_t colon = header.find(':', at);
    if (colon == std::string::npos) fail("malformed header");
    return header.substr(colon + 1);
  };
  const std::string descr = value_of("descr");
  const bool f8 = descr.find("'<f8'") == 0 || descr.find(" '<f8'") == 0;
  const bool f4 = descr.find("'<f4'") == 0 || descr.find(" '<f4'") == 0;
  if (!f8 && !f4) fail("values of type " + descr.substr(0, descr.find(',')) + "; float64 or float32 ('<f8', '<f4') expected");
  const std::string order = value_of("fortran_order");
  const bool fortran = order.find("True") < order.find(',');
  const std::string shape_text = value_of("shape");
  const std::size_t open = shape_text.find('('), close = shape_text.find(')');
  if (open == std::string::npos || close == std::string::npos || close < open) fail("malformed shape");
  std::vector<long long> shape;
  std::string dims = shape_text.substr(open + 1, close - open - 1);
  for (std::size_t pos = 0; pos < dims.size();) {
    while (pos < dims.size() && (dims[pos] == ' ' || dims[pos] == ',')) ++pos;
    if (pos >= dims.size()) break;
    std::size_t used = 0;
    long long d = -1;
    try {
      d = std::stoll(dims.substr(pos), &used);
    } catch (const std::exception&) {
      fail("malformed shape");
    }
    if (d < 0) fail("negative dimension");
    shape.push_back(d);
    pos += used;
  }
  if (shape.empty() || shape.size() > 2) fail(std::to_string(shape.size()) + " dimensions; a vector or a matrix expected");
  const long long rows = shape[0], cols = shape.size() == 2 ? shape[1] : 1;
  if (rows > (1LL << 40) / std::max(1LL, cols)) fail("shape too large");
  const std::size_t count = static_cast<std::size_t>(rows * cols), width = f8 ? 8 : 4;
  // The declared size against the file's before allocating anything of it.
  const std::streamoff data_start = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff available = in.tellg() - data_start;
  in.seekg(data_start);
  if (!in || available < 0 || static_cast<std::uint64_t>(available) < count * width)
    fail("truncated data: " + std::to_string(rows) + " x " + std::to_string(cols) + " values declared");
  std::vector<char> raw(count * width);
  in.read(raw.data(), static_cast<std::streamsize>(raw.size()));
  if (!in) fail("truncated data: " + std::to_string(rows) + " x " + std::to_string(cols) + " values declared");
  Eigen::MatrixXd m(rows, cols);
  for (long long r = 0; r < rows; ++r)
    for (long long c = 0; c < cols; ++c) {
      const std::size_t k = static_cast<std::size_t>(fortran ? c * rows + r : r * cols + c);
      double v;
      if (f8) {
        std::memcpy(&v, raw.data() + 8 * k, 8);
      } else {
        float f;
        std::memcpy(&f, raw.data() + 4 * k, 4);
        v = f;
      }
      if (!std::isfinite(v)) fail("value at row " + std::to_string(r) + ", column " + std::to_string(c) + " is not finite");
      m(r, c) = v;
    }
  return m;
}

void write_npy_matrix(const std::string& path, const Eigen::MatrixXd& matrix, bool overwrite) {
  require_writable(path, overwrite);
  const auto fail = [&](const std::string& message) {
    std::error_code ec;
    fs::remove(path, ec);
    throw MeshError(MeshError::Kind::Unwritable, path, message);
  };
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw MeshError(MeshError::Kind::Unwritable, path, "cannot create the file");
  write_npy_header(out, "<f8", matrix.rows(), matrix.cols());
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rows = matrix;
  out.write(reinterpret_cast<const char*>(rows.data()), static_cast<std::streamsize>(rows.size() * sizeof(double)));
  out.close();
  if (!out) fail("write failed (disk full?)");
}

}  // namespace ice
