// The mesh writers of ice/mesh_io.h (write_mesh, and the overwrite policy every writer of ICE
// follows), apart from the readers in mesh_io.cpp.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>

#include <Eigen/Geometry>

#include "file_extension.h"
#include "ice/mesh_io.h"
#include "ice/scalar_field_io.h"

namespace ice {

namespace fs = std::filesystem;

namespace {

template <class T>
void put_binary(std::ostream& out, T value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof value);  // host is little endian (x86/ARM)
}

}  // namespace

WriteCheck check_writable(const std::string& path, bool overwrite) {
  std::error_code ec;
  if (!overwrite && fs::exists(path, ec)) return WriteCheck::exists;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !fs::is_directory(parent, ec)) return WriteCheck::no_directory;
  return WriteCheck::ok;
}

void require_writable(const std::string& path, bool overwrite) {
  switch (check_writable(path, overwrite)) {
    case WriteCheck::ok: return;
    case WriteCheck::exists:
      throw MeshError(MeshError::Kind::Unwritable, path, "exists already (allow overwriting to replace it)");
    case WriteCheck::no_directory:
      throw MeshError(MeshError::Kind::Unwritable, path,
                      "directory " + fs::path(path).parent_path().string() + " does not exist");
  }
}

void write_mesh(const std::string& path, const TriangleMesh& mesh, const WriteOptions& options) {
  const std::string ext = lower_extension(path);
  if (ext != "obj" && ext != "off" && ext != "ply" && ext != "stl")
    throw MeshError(MeshError::Kind::Unwritable, path, "unsupported output format '." + ext + "'");
  require_writable(path, options.overwrite);
  const Eigen::Index nv = mesh.V.rows(), nf = mesh.F.rows();
  if (mesh.V.cols() != 3 || mesh.F.cols() != 3 || (nf > 0 && (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= nv)))
    throw MeshError(MeshError::Kind::Unwritable, path, "invalid mesh (needs n×3 positions and in-range n×3 faces)");

  if (ext == "ply") {  // the one PLY writer (ice/scalar_field_io.h), here without fields
    write_ply_with_fields(path, mesh, {}, {true, options.binary});
    return;
  }
  const bool binary = options.binary && ext == "stl";
  std::ofstream out(path, binary ? std::ios::binary : std::ios::out);
  if (!out) throw MeshError(MeshError::Kind::Unwritable, path, "cannot be opened for writing");
  out.precision(std::numeric_limits<double>::max_digits10);  // exact round trip of doubles

  if (ext == "obj") {
    for (Eigen::Index i = 0; i < nv; ++i) out << "v " << mesh.V(i, 0) << ' ' << mesh.V(i, 1) << ' ' << mesh.V(i, 2) << '\n';
    for (Eigen::Index f = 0; f < nf; ++f)
      out << "f " << mesh.F(f, 0) + 1 << ' ' << mesh.F(f, 1) + 1 << ' ' << mesh.F(f, 2) + 1 << '\n';
  } else if (ext == "off") {
    out << "OFF\n" << nv << ' ' << nf << " 0\n";
    for (Eigen::Index i = 0; i < nv; ++i) out << mesh.V(i, 0) << ' ' << mesh.V(i, 1) << ' ' << mesh.V(i, 2) << '\n';
    for (Eigen::Index f = 0; f < nf; ++f) out << "3 " << mesh.F(f, 0) << ' ' << mesh.F(f, 1) << ' ' << mesh.F(f, 2) << '\n';
  } else {  // stl
    auto normal = [&](Eigen::Index f) {
      const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
      return (b - a).cross(c - a).normalized().eval();
    };
    if (binary) {
      char header[80] = "ICE binary STL";
      out.write(header, sizeof header);
      put_binary(out, static_cast<std::uint32_t>(nf));
      for (Eigen::Index f = 0; f < nf; ++f) {
        const Eigen::Vector3d n = normal(f);
        for (int k = 0; k < 3; ++k) put_binary(out, static_cast<float>(n[k]));
        for (int c = 0; c < 3; ++c)
          for (int k = 0; k < 3; ++k) put_binary(out, static_cast<float>(mesh.V(mesh.F(f, c), k)));
        put_binary(out, static_cast<std::uint16_t>(0));
      }
    } else {
      out << "solid ice\n";
      for (Eigen::Index f = 0; f < nf; ++f) {
        const Eigen::Vector3d n = normal(f);
        out << "facet normal " << n[0] << ' ' << n[1] << ' ' << n[2] << "\nouter loop\n";
        for (int c = 0; c < 3; ++c)
          out << "vertex " << mesh.V(mesh.F(f, c), 0) << ' ' << mesh.V(mesh.F(f, c), 1) << ' ' << mesh.V(mesh.F(f, c), 2)
              << '\n';
        out << "endloop\nendfacet\n";
      }
      out << "endsolid ice\n";
    }
  }
  out.flush();
  if (!out) throw MeshError(MeshError::Kind::Unwritable, path, "write error");
}

}  // namespace ice
