#pragma once
/// \file intrinsic_mesh_io.h
/// The `.ilm` file format ("ICE intrinsic mesh", plain text, version 1): a coarse intrinsic mesh
/// (faces + per-face edge lengths) and, for each of its vertices, the input-mesh vertex it is.
///
///     ICE-ILM 1                         header line (format name and version)
///     # ...                             comment lines ('#' first) may appear anywhere after it
///     vertices <n>                      number of vertices
///     faces <m>                         number of faces
///     input_vertices <N>                number of vertices of the mesh it was made from
///     f <i> <j> <k> <lij> <ljk> <lki>   m lines: corners (0-based vertex ids, counter-clockwise) and
///                                       the lengths of the edges i→j, j→k, k→i (ice/mesh.h
///                                       FaceLengths convention: column c runs from corner c to c+1)
///     v <input vertex id>               n lines: vertex c (the c-th v line, 0-based) is this 0-based
///                                       vertex of the input mesh
///
/// Lengths are written in the shortest form that reads back to the same double, so a write/read
/// round trip is exact. The mesh may be a Δ-complex (a face repeating a vertex, two faces sharing
/// more than one edge): the file does not record how such faces are glued, so take connectivity from
/// the face lines; IntrinsicTriangulation::from_lengths, which glues faces by vertex pairs, refuses
/// such meshes with a clear error rather than guessing.
#include <string>
#include <vector>

#include "ice/intrinsic_triangulation.h"
#include "ice/mesh.h"

namespace ice {

/// The content of an .ilm file.
struct IntrinsicMeshFile {
  Faces F;                    ///< faces in 0-based vertex ids
  FaceLengths L;              ///< per-face edge lengths
  std::vector<Index> to_input;  ///< vertex -> input-mesh vertex
  Index input_vertices = 0;   ///< vertex count of the input mesh
};

/// Reads an .ilm file. Throws MeshError (ice/mesh_io.h) naming the file, the line and the defect:
/// Unreadable for a missing file, a wrong header, a malformed or missing line or count; Defective
/// for contents that are well-formed but invalid (a vertex id out of range, a non-positive or
/// non-finite length, a face violating the triangle inequality, an input vertex id out of range or
/// repeated, a vertex used by no face).
IntrinsicMeshFile read_intrinsic_mesh(const std::string& path);

/// Writes `mesh` (e.g. IntrinsicTriangulation::compact() of a coarsened triangulation) as .ilm, with
/// `comment` as a comment line when not empty. `input_vertices` is the input mesh's vertex count.
/// Throws MeshError(Unwritable) when the file cannot be written. Overwrites `path`: callers decide
/// whether that is allowed.
void write_intrinsic_mesh(const std::string& path, const CompactMesh& mesh, Index input_vertices,
                          const std::string& comment = "");

}  // namespace ice
