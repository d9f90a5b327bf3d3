#pragma once
/// \file mesh_io.h
/// Reading meshes from OBJ, OFF, PLY (ASCII/binary) and STL (ASCII/binary) files, and the loading
/// policy of ICE.
///
/// Reading. Files are read into a raw polygon soup (no half-edge structure, so non-manifold and
/// non-triangle faces, repeated and out-of-range indices all stay visible). OBJ, ASCII OFF and PLY
/// (ASCII and binary, either byte order, elements in any order, extra properties and elements read
/// past) are parsed by ICE's own strict readers, in double precision, with faces as written; a record
/// that cannot be parsed or a file that ends early is an error naming the line or element. OpenMesh's IO
/// layer reads only what they decline: STL (single precision by definition; its per-triangle vertices
/// are welded when they coincide exactly), binary or 4D OFF and PLY layouts such as list-valued vertex
/// properties, in single precision (a reader note says so). OpenMesh 9 parses coordinates as 32-bit
/// floats, drops repeated face corners and unparsable vertex lines, misreads OFF comment lines after the
/// counts and PLY files whose face element comes first: hence the own readers.
///
/// Loading policy (`load_mesh`):
///  - Refused (MeshError, kind Defective) unless repaired: non-triangle faces, out-of-range or repeated
///    indices in a face, non-finite coordinates, unreferenced vertices, duplicate faces, zero-area faces,
///    non-manifold edges or vertices, inconsistent orientation, non-orientable components.
///  - With `LoadOptions::repair`, the cheap safe repairs of mesh_repair.h are applied (triangulate
///    polygons, collapse repeated corners, drop zero-area and duplicate faces, drop unreferenced vertices,
///    re-orient orientable components, weld exactly coincident vertices if asked) and the result is
///    validated again. Still refused after repair: non-finite coordinates, out-of-range indices,
///    non-manifold or non-orientable surfaces (including non-manifoldness created by dropping faces).
///  - With `LoadOptions::keep_nonmanifold`, non-manifold edges and vertices, inconsistent orientation
///    and non-orientable components are kept (the tufted cover's input); the other defects as above.
///  - Accepted as they are: several connected components (ICE coarsens all components together, each
///    keeping its own topology), boundaries, any genus, coincident vertex positions (information only).
///  - Unreadable input (missing, unreadable, empty, unknown format, truncated or unparsable records):
///    MeshError, kind Unreadable. Every message starts with the file path.
#include <stdexcept>
#include <string>
#include <vector>

#include "ice/mesh.h"
#include "ice/mesh_repair.h"
#include "ice/mesh_validation.h"
#include "ice/point_cloud.h"

namespace ice {

/// Error raised for meshes that cannot be read or are refused by the loading policy.
class MeshError : public std::runtime_error {
 public:
  enum class Kind {
    Unreadable,  ///< Missing, unreadable, empty, unknown format or corrupt file.
    Defective,   ///< Read fine, but refused by the loading policy.
    Unwritable,  ///< An output file could not be written (or exists and overwriting was not allowed).
  };
  MeshError(Kind kind, const std::string& path, const std::string& message)
      : std::runtime_error(path + ": " + message), kind_(kind), path_(path) {}
  Kind kind() const { return kind_; }
  const std::string& path() const { return path_; }

 private:
  Kind kind_;
  std::string path_;
};

/// Whether an output may be written at `path`: the one overwrite policy of ICE's writers and of the
/// tools' checks before any work (an existing file is replaced only when `overwrite`; the directory
/// must exist).
enum class WriteCheck { ok, exists, no_directory };
WriteCheck check_writable(const std::string& path, bool overwrite);
/// Throws MeshError (Unwritable) naming the path unless check_writable(path, overwrite) is ok.
void require_writable(const std::string& path, bool overwrite);

/// A file's raw content.
struct MeshFile {
  PolygonSoup soup;
  std::string format;             ///< "obj", "off", "ply", "stl", or "xyz" / "pwn" (points only).
  bool exact_coordinates = false; ///< Read by ICE's own reader (OBJ, OFF, PLY); false for STL (OpenMesh's reader).
  std::vector<std::string> notes; ///< Remarks of the reader (none at present; kept for ice-info's report).
};

/// Read a mesh file into a raw polygon soup; no validation. The format is chosen by the extension
/// (case-insensitive): .obj, .off, .ply, .stl, or a point set as text (.xyz, .pwn: the first three
/// numbers of each line). Throws MeshError (Unreadable) naming the file if it is missing, not a
/// regular file, of unknown format, empty (no vertices), truncated or not parsable.
MeshFile read_mesh_file(const std::string& path);

/// Options of `load_mesh`.
struct LoadOptions {
  bool repair = false;                    ///< Apply the safe repairs of mesh_repair.h.
  bool weld_duplicate_positions = false;  ///< With repair: also weld exactly coincident vertices.
  /// Accept a mesh (after the repairs, when asked) whose only defects are non-manifold edges or
  /// vertices, inconsistent orientation or non-orientable components: what the tufted cover
  /// (ice/tufted_cover.h) solves on. LoadResult::report still lists them.
  /// A file of points only (.xyz, .pwn, or .obj/.off/.ply without faces) then becomes its points with the
  /// triangles of their local Delaunay fans (ice/point_cloud.h), coincident points refused or, with
  /// repair, merged into the first of them (weld_duplicate_positions is not needed for points). Without
  /// this option such a file is refused. Refusals name points by their number in the file.
  bool keep_nonmanifold = false;
  /// How a point cloud's fans are made (its neighbours below 2: load_mesh throws std::invalid_argument).
  PointCloudOptions point_cloud{};
};

/// Everything `load_mesh_with_report` learned about a file.
struct LoadResult {
  TriangleMesh mesh;               ///< The validated mesh.
  std::vector<Index> source_vertex;  ///< mesh vertex i is vertex source_vertex[i] of the file (0-based).
  std::vector<Index> source_face;    ///< mesh face f comes from face source_face[f] of the file (empty for a point cloud).
  bool point_cloud = false;          ///< The file had points only; the faces are their local Delaunay fans.
  MeshFile file;                   ///< Raw input (soup, format, reader notes).
  ValidationReport input_report;   ///< Validation of the raw input.
  RepairLog repairs;               ///< Empty unless options.repair.
  ValidationReport report;         ///< Validation of `mesh` (clean).
};

/// Read, validate and (optionally) repair a mesh according to the policy above.
/// Throws MeshError whose what() names the file and each defect with its count and first offenders.
LoadResult load_mesh_with_report(const std::string& path, const LoadOptions& options = {});

/// The loading policy for a mesh made in code (the Python package's arrays): validates it and throws
/// MeshError (Defective) naming `name` and each defect in the words load_mesh uses for files, or
/// returns the report of a clean mesh.
ValidationReport require_clean_mesh(const TriangleMesh& mesh, const std::string& name);

/// `load_mesh_with_report(path, options).mesh`.
TriangleMesh load_mesh(const std::string& path, const LoadOptions& options = {});

/// Options of `write_mesh`.
struct WriteOptions {
  bool overwrite = false;  ///< Replace an existing file (otherwise MeshError, kind Unwritable).
  bool binary = false;     ///< Binary PLY/STL (little endian); ignored for OBJ and OFF.
};

/// Write a triangle mesh as OBJ, OFF, PLY or STL, chosen by the extension. OBJ, OFF and PLY keep full
/// double precision (PLY stores `double` coordinates); STL stores float32 and one record per triangle.
/// Throws MeshError (Unwritable) naming the file on failure or if it exists and !options.overwrite.
void write_mesh(const std::string& path, const TriangleMesh& mesh, const WriteOptions& options = {});

}  // namespace ice
