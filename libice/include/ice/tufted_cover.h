#pragma once
/// \file tufted_cover.h
/// The tufted cover of a triangle mesh that is not an oriented manifold (Sharp & Crane, "A Laplacian
/// for Nonmanifold Triangle Meshes", SGP 2020): every face doubled into a front and a back sheet, the
/// sheets around each edge glued in the order of their faces about the edge, so that the result is a
/// closed (with its boundary tufts: see tufted_cover), oriented, edge-manifold intrinsic triangulation
/// (a Δ-complex) on which ICE coarsens as on any other. Its cotan Laplacian, summed over each input vertex's copies, is twice the input's: the
/// cover sees every face from both sides.
#include <vector>

#include <Eigen/SparseCore>

#include "ice/mesh.h"

namespace ice {

/// The cover of an input mesh of n vertices and m faces.
struct TuftedCover {
  /// Cover vertices at their input vertex's position; faces f < m the input's (front sheets, same
  /// corner order), faces m + f their back sheets (corners 0, 2, 1 of face f).
  TriangleMesh mesh;
  /// How the sheets are glued (IntrinsicMesh::twin convention). Closed (no side kInvalid) unless made
  /// without boundary tufts. Two cover vertices can be joined by several edges, so vertex pairs
  /// cannot say this.
  std::vector<Index> twin;
  /// Cover vertex → input vertex. An input vertex has one copy per fan of sheets around it: one on an
  /// edge-manifold open sheet's boundary (front and back meet there; two without boundary tufts),
  /// two inside a sheet (its two sides), more where sheets only touch at the vertex. Copies of one input vertex
  /// are numbered consecutively, in increasing input order.
  std::vector<Index> to_input;
  Index input_vertex_count = 0;

  /// The cover as ICE's intrinsic mesh: its faces, their edge lengths from the positions, its gluing.
  IntrinsicMesh intrinsic_mesh() const;
};

/// Whether `mesh` needs the cover to be coarsened: it has a non-manifold edge (more than two faces),
/// an edge whose two faces run along it in the same direction (inconsistent orientation, which
/// includes every non-orientable surface) or a non-manifold vertex (several fans of faces).
/// Preconditions: indices in range.
bool needs_tufted_cover(const TriangleMesh& mesh);

/// What becomes of a mesh that is not an oriented manifold (ice::needs_tufted_cover).
enum class NonmanifoldInput {
  refuse,        ///< coarsening it throws std::invalid_argument (as IntrinsicTriangulation::from_mesh)
  tufted_cover,  ///< it is coarsened through its tufted cover (below), on its own vertices
};
const char* to_string(NonmanifoldInput choice);
/// Whether `mesh` is solved on its tufted cover under `choice`: asked for, and needed (needs_tufted_cover;
/// an oriented manifold is solved as it is). O(faces).
bool solved_on_tufted_cover(const TriangleMesh& mesh, NonmanifoldInput choice);

/// The tufted cover of `mesh`. Around an edge shared by d faces the sheets are glued in the order of
/// the faces' angle about the edge (ties by face index): the sheet of each face that looks into a
/// wedge between two consecutive faces is glued to the other face's sheet that looks into the same
/// wedge (a face alone on its edge: its front to its back). On an edge-manifold, consistently
/// oriented part this is two mirror copies of it joined along its boundary.
/// With `tuft_boundary` false a face alone on its edge is left open there (both sheets' sides
/// kInvalid): the sheets are then the input's oriented double cover with its boundary, where an
/// orientable open part is its two sides apart (distinct_sheets keeps one) — what tangent vector
/// fields need (at a tuft the sheet would fold onto its other side, mirroring every vector).
/// Preconditions (std::invalid_argument otherwise): every index in range, every vertex used, no face
/// repeating a vertex, every face non-degenerate (ice::is_degenerate_triangle false): what
/// load_mesh's safe repairs leave of a non-manifold file.
TuftedCover tufted_cover(const TriangleMesh& mesh, bool tuft_boundary = true);

/// The cover without redundant sheets: where a closed sheet and its mirror image are components of
/// the cover of their own (each side of a closed oriented surface that touches the rest of the mesh
/// at vertices only, or not at all), the mirror (the component without the lower front face) is
/// left out. The two carry the same geometry, so coarsening both would give the coarse space each
/// basis function twice (a singular Galerkin mass). Faces keep their order (a subset of the cover's,
/// so face f < m is no longer front face f); the gluing and copies are renumbered to match.
/// Preconditions (std::invalid_argument naming the defect otherwise): the shape of ice::tufted_cover's
/// result — an even face count, a gluing that is an involution of the 3·faces sides where it is
/// not kInvalid (open: made without boundary tufts), one input vertex in [0, input_vertex_count) per
/// cover vertex and a copy of every input vertex.
TuftedCover distinct_sheets(const TuftedCover& cover);

/// The n × (cover vertices) matrix that takes a field on the cover to the input vertices: each input
/// vertex gets the average of its copies' values weighted by `copy_mass` (their areas; all copies
/// without mass: the plain average). Rows sum to 1; a field equal on all copies maps to itself.
Eigen::SparseMatrix<double> cover_to_input(const TuftedCover& cover, const Eigen::VectorXd& copy_mass);

/// The same averaging for any copies: the vertex_count × copies matrix whose row i averages the
/// copies c with vertex_of_copy[c] == i, weighted by copy_mass (all of them without mass: the plain
/// average). Preconditions (std::invalid_argument otherwise): copy_mass has one entry per copy, every
/// vertex_of_copy in [0, vertex_count).
Eigen::SparseMatrix<double> copies_to_vertices(const std::vector<Index>& vertex_of_copy, Index vertex_count,
                                               const Eigen::VectorXd& copy_mass);

/// Per cover vertex: a third of the area of every cover face at its corners (lumped barycentric area).
Eigen::VectorXd cover_vertex_areas(const TuftedCover& cover);

}  // namespace ice
