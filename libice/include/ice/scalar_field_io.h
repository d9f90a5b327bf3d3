#pragma once
/// \file scalar_field_io.h
/// Writing a triangle mesh together with named per-vertex scalar fields (solutions, references,
/// errors, ...) as a PLY file that viewers (MeshLab, ParaView, Blender, polyscope) and numpy/plyfile
/// read directly, or as binary glTF coloured by one field, with polylines drawn over the surface.
///
/// PLY layout: `element vertex n` with `property double x`, `y`, `z`, then one `property double <name>`
/// per field in the given order; `element face m` with `property list uchar int vertex_indices`.
/// Binary little endian by default (exact doubles, compact); ASCII on request (17 significant digits,
/// so doubles still round-trip). The writer never replaces an existing file unless asked to.
#include <array>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ice/mesh.h"

namespace ice {

/// One named per-vertex field.
struct ScalarField {
  std::string name;        ///< PLY property name: [A-Za-z_][A-Za-z0-9_]*, not x, y or z, unique
  Eigen::VectorXd values;  ///< one value per vertex of the mesh
};

struct ScalarFieldWriteOptions {
  bool overwrite = false;  ///< replace an existing file (otherwise MeshError, kind Unwritable)
  bool binary = true;      ///< binary_little_endian (default) or ascii
};

/// Writes `mesh` and `fields` to `path` (any extension; `.ply` recommended). Throws MeshError
/// (kind Unwritable, message starting with the path) if the file exists and !options.overwrite, a
/// field name is invalid or repeated, a field does not have one value per vertex, the faces are out
/// of range, or the file cannot be written (a partially written file is removed).
void write_ply_with_fields(const std::string& path, const TriangleMesh& mesh, const std::vector<ScalarField>& fields,
                           const ScalarFieldWriteOptions& options = {});

/// Writes polylines (e.g. the traced coarse edges: ice::traced_polyline) as a PLY file of points and
/// edges that MeshLab and ParaView draw as lines: `element vertex` (double x, y, z: every polyline's
/// points, in order) and `element edge` (int vertex1, vertex2, and int polyline: the index of the
/// polyline in `polylines`). Binary little endian unless options.binary is false. Throws MeshError
/// (Unwritable, naming the path) if the file exists and !options.overwrite, a polyline is not n×3, or
/// the write fails (a partial file is removed).
void write_ply_polylines(const std::string& path, const std::vector<Positions>& polylines,
                         const ScalarFieldWriteOptions& options = {});

// ---- binary glTF: the same mesh and fields for Blender, three.js and web viewers -------------------

/// matplotlib's viridis (a perceptually uniform sequential colour map), sRGB in [0, 1], at t in
/// [0, 1] (clamped): linear interpolation between 17 evenly spaced samples of the map, within 6/255
/// of it. The colours of the glTF files below and of the HTML view.
std::array<double, 3> viridis(double t);

/// The 17 samples of viridis (sRGB, 0–255), t = 0, 1/16, ..., 1.
const std::array<std::array<unsigned char, 3>, 17>& viridis_samples();

struct GltfWriteOptions {
  bool overwrite = false;       ///< replace an existing file (otherwise MeshError, kind Unwritable)
  /// The field drawn as the vertex colours (COLOR_0, viridis over its finite range; non-finite values
  /// grey). Empty: the first field; no fields: no colours.
  std::string colour_field;
  std::array<double, 3> line_colour{1.0, 0.125, 0.125};  ///< sRGB of the polylines
};

/// Writes `mesh`, `fields` and `polylines` (e.g. the traced coarse edges: ice::traced_polyline) as one
/// binary glTF 2.0 file (.glb) through tinygltf. Layout:
///  - node "mesh": triangles with POSITION (float32), NORMAL (area-weighted vertex normals; (0, 0, 1)
///    where undefined), COLOR_0 (the colour field through viridis, linear RGB as glTF requires) and
///    one float32 application attribute per field, named "_" + the field name in upper case (glTF's
///    rule for application-specific attributes), so a viewer can recolour without the PLY;
///  - node "lines" (only with polylines): a LINES primitive of every polyline's segments, material
///    "lines" in `line_colour`;
///  - the mesh's `extras`: {"colour_field", "colour_map": "viridis", "range": [min, max], "fields":
///    [{"name", "attribute", "min", "max"}]} — ranges over the finite values (a legend needs them).
/// Field names as for write_ply_with_fields. Positions are float32 (glTF has no doubles): the PLY is
/// the exact record. Throws MeshError (Unwritable, naming the path) as write_ply_with_fields does,
/// and for an unknown colour_field; a partially written file is removed.
void write_gltf_with_fields(const std::string& path, const TriangleMesh& mesh, const std::vector<ScalarField>& fields,
                            const std::vector<Positions>& polylines = {}, const GltfWriteOptions& options = {});

// ---- dense matrices (distance matrices of fem::DistanceOracle) ---------------------------------------

/// Writes a float32 matrix row by row as a NumPy `.npy` file (format 1.0, '<f4', C order; numpy.load
/// reads it, also memory-mapped), so that matrices larger than memory can be written in blocks.
/// Never replaces an existing file unless asked; a file left incomplete (close() not reached, or a
/// write failed) is removed.
class NpyMatrixWriter {
 public:
  /// Throws MeshError (Unwritable, naming the path) if the file exists and !overwrite, or cannot be
  /// created.
  NpyMatrixWriter(const std::string& path, Eigen::Index rows, Eigen::Index cols, bool overwrite);
  ~NpyMatrixWriter();
  NpyMatrixWriter(const NpyMatrixWriter&) = delete;
  NpyMatrixWriter& operator=(const NpyMatrixWriter&) = delete;
  /// Appends the rows of `block` (block.cols() == cols). Throws MeshError past the declared rows or
  /// on a failed write.
  void write_rows(const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& block);
  /// Checks every declared row was written and closes the file (throws MeshError otherwise).
  void close();

 private:
  std::string path_;
  Eigen::Index rows_, cols_, written_ = 0;
  std::ofstream out_;
  bool closed_ = false;
};

/// Reads a NumPy `.npy` file of float64 or float32 values ('<f8' or '<f4'; C or Fortran order;
/// format 1.0 to 3.0), 1-D (one column) or 2-D, into a double matrix of its shape. Throws MeshError
/// (Unreadable) naming the file and what is wrong: not an .npy file, another type (integers,
/// big-endian, objects), more than two dimensions, a truncated payload, a value that is not finite.
Eigen::MatrixXd read_npy_matrix(const std::string& path);

/// Writes `matrix` as a float64 NumPy `.npy` file (format 1.0, '<f8', C order: numpy.load gives the
/// matrix's rows × cols). Never replaces an existing file unless `overwrite`; a failed write leaves
/// no file. Throws MeshError (Unwritable).
void write_npy_matrix(const std::string& path, const Eigen::MatrixXd& matrix, bool overwrite);

/// Writes `matrix` by the extension of `path`: `.npy` (float32, NpyMatrixWriter) or `.mtx` (Matrix
/// Market "array real general", column-major as the format prescribes, 9 significant digits: float
/// precision round-trips). Throws MeshError (Unwritable) on another extension, an existing file
/// without overwrite, or a failed write.
void write_dense_matrix(const std::string& path, const Eigen::MatrixXf& matrix, bool overwrite);

}  // namespace ice
