#include "ice/scalar_field_io.h"

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "ice/mesh_io.h"

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

}  // namespace

void write_ply_with_fields(const std::string& path, const TriangleMesh& mesh, const std::vector<ScalarField>& fields,
                           const ScalarFieldWriteOptions& options) {
  const auto fail = [&](const std::string& message) { throw MeshError(MeshError::Kind::Unwritable, path, message); };
  const Eigen::Index nv = mesh.V.rows(), nf = mesh.F.rows();
  if (mesh.V.cols() != 3 || mesh.F.cols() != 3 || (nf > 0 && (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= nv)))
    fail("invalid mesh (needs n×3 positions and in-range n×3 faces)");
  std::set<std::string> names{"x", "y", "z"};
  for (const ScalarField& field : fields) {
    if (!valid_property_name(field.name))
      fail("invalid PLY property name '" + field.name + "' (letters, digits and '_', not starting with a digit)");
    if (!names.insert(field.name).second) fail("property name '" + field.name + "' is used twice (or is x, y or z)");
    if (field.values.size() != nv) {
      std::ostringstream message;
      message << "field '" << field.name << "' has " << field.values.size() << " values for " << nv << " vertices";
      fail(message.str());
    }
  }
  require_writable(path, options.overwrite);
  std::error_code ec;

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
  out.flush();
  if (!out) {
    out.close();
    fs::remove(path, ec);
    fail("write failed (disk full?)");
  }
}

// ---- dense matrices --------------------------------------------------------------------------------

NpyMatrixWriter::NpyMatrixWriter(const std::string& path, Eigen::Index rows, Eigen::Index cols, bool overwrite)
    : path_(path), rows_(rows), cols_(cols) {
  if (rows < 0 || cols < 0) throw MeshError(MeshError::Kind::Unwritable, path, "negative matrix size");
  require_writable(path, overwrite);
  out_.open(path, std::ios::binary);
  if (!out_) throw MeshError(MeshError::Kind::Unwritable, path, "cannot create the file");
  // Magic, version 1.0, header length (little-endian uint16), then the header dictionary padded
  // with spaces and a newline so that the data starts on a multiple of 64 bytes.
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(rows) + ", " +
                       std::to_string(cols) + "), }";
  const std::size_t unpadded = 10 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header.push_back('\n');
  const auto length = static_cast<std::uint16_t>(header.size());
  out_.write("\x93NUMPY\x01\x00", 8);
  const char length_bytes[2] = {static_cast<char>(length & 0xff), static_cast<char>(length >> 8)};
  out_.write(length_bytes, 2);
  out_.write(header.data(), static_cast<std::streamsize>(header.size()));
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
  out.flush();
  if (!out) {
    out.close();
    std::error_code ec;
    fs::remove(path, ec);
    throw MeshError(MeshError::Kind::Unwritable, path, "write failed (disk full?)");
  }
}

}  // namespace ice
