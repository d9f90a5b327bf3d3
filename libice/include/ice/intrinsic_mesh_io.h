#pragma once
/// \file intrinsic_mesh_io.h
/// The `.ilm` file format ("ICE intrinsic mesh", plain text, version 2): a coarse intrinsic mesh
/// (faces, per-face edge lengths and how the faces are glued) and, for each of its vertices, the
/// input-mesh vertex it is.
///
///     ICE-ILM 2                         header line (format name and version)
///     # ...                             comment lines ('#' first) may appear anywhere after it
///     vertices <n>                      number of vertices
///     faces <m>                         number of faces
///     input_vertices <N>                number of vertices of the mesh it was made from
///     f <i> <j> <k> <lij> <ljk> <lki> <tij> <tjk> <tki>
///                                       m lines: corners (0-based vertex ids, counter-clockwise), the
///                                       lengths of the edges i→j, j→k, k→i (ice/mesh.h FaceLengths
///                                       convention: column c runs from corner c to c+1), and for each
///                                       of those sides its twin: 3g + d for side d of face g (the
///                                       same edge run the other way), or -1 on the boundary
///     v <input vertex id>               n lines: vertex c (the c-th v line, 0-based) is this 0-based
///                                       vertex of the input mesh, or -1 for a vertex inserted by
///                                       Delaunay refinement (no input vertex)
///
/// The gluing makes the file say exactly which triangulation it is, Δ-complexes included (a face
/// repeating a vertex, two edges between the same two vertices: the normal state of a coarse
/// intrinsic mesh), and lengths are written in the shortest form that reads back to the same double,
/// so write → read is an exact round trip of connectivity, lengths and the vertex map.
///
/// Version 1 files (the same without the three twins) are still read: their faces are glued by vertex
/// pairs, which is right for meshes without self- or multi-edges; a version-1 file of a Δ-complex is
/// refused when building its triangulation (it cannot say how its faces were glued). A version-1 mesh
/// with two faces sharing more than one edge may have been glued otherwise when written: write it
/// again with this version.
#include <string>
#include <vector>

#include "ice/intrinsic_triangulation.h"
#include "ice/mesh.h"

namespace ice {

/// The content of an .ilm file: its intrinsic mesh (`twin` empty for version 1; vertex_count ==
/// to_input.size()) and its map to the input.
struct IntrinsicMeshFile : IntrinsicMesh {
  int version = 2;            ///< the file's format version (1 or 2)
  std::vector<Index> to_input;  ///< vertex -> input-mesh vertex (kInvalid: inserted by refinement)
  Index input_vertices = 0;   ///< vertex count of the input mesh
};

/// Reads an .ilm file (version 1 or 2). Throws MeshError (ice/mesh_io.h) naming the file, the line
/// and the defect: Unreadable for a missing file, a wrong header, a malformed or missing line or
/// count; Defective for contents that are well-formed but invalid (a vertex id out of range, a
/// non-positive or non-finite length, a face violating the triangle inequality, a twin out of range,
/// not symmetric, joining sides with other ends or other lengths, an input vertex id out of range or
/// repeated, a vertex used by no face).
IntrinsicMeshFile read_intrinsic_mesh(const std::string& path);

/// The triangulation a file describes: IntrinsicTriangulation::from_glued_faces with its gluing, or for
/// version 1 from_lengths (gluing by vertex pairs). Throws MeshError(Defective) naming the file when
/// the faces do not form a valid triangulation (e.g. a version-1 Δ-complex, a vertex whose corners form
/// several fans).
IntrinsicTriangulation triangulation_of(const IntrinsicMeshFile& file, const std::string& path);

/// Writes `mesh` (e.g. IntrinsicTriangulation::compact() of a coarsened triangulation) as .ilm version 2
/// (an empty mesh.twin is taken as gluing by vertex pairs: glue_by_vertex_pairs), with
/// `comment` as a comment line when not empty. `input_vertices` is the input mesh's vertex count.
/// Throws MeshError(Unwritable) when the file cannot be written. Overwrites `path`: callers decide
/// whether that is allowed.
void write_intrinsic_mesh(const std::string& path, const CompactMesh& mesh, Index input_vertices,
                          const std::string& comment = "");

}  // namespace ice
