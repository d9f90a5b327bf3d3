#pragma once
// The tufted cover's copies of input vertices as the recipes use them: merged into one unknown per
// input vertex (the coarse space's P and the hierarchy's levels), locked together, weighted by area.
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "disjoint_sets.h"
#include "ice/mesh.h"

namespace ice {
struct TuftedCover;
}

namespace ice::detail {

/// Copies merged into one unknown per input vertex, the unknowns numbered by their first copy.
struct MergedCopies {
  std::vector<Index> unknown;     ///< per copy: its unknown
  std::vector<Index> to_input;    ///< per unknown: its input vertex
  std::vector<Index> from_input;  ///< per input vertex: its unknown, or kInvalid without a copy
  /// copies × unknowns: each copy takes its unknown's value.
  Eigen::SparseMatrix<double> spread() const;
};
/// input_of_copy[c] in [0, input_vertices) for every copy c (not checked).
MergedCopies merge_copies(const std::vector<Index>& input_of_copy, Index input_vertices);

/// The copies c whose input vertex is one of `vertices` (those out of [0, input_vertices) ignored).
std::vector<Index> copies_of(const std::vector<Index>& input_of_copy, Index input_vertices, const std::vector<Index>& vertices);

/// The cover's faces in sets of faces joined across glued sides (its connected components); open
/// sides (kInvalid, a cover without boundary tufts) join nothing. distinct_sheets checks the gluing.
DisjointSets glued_faces(const TuftedCover& cover);

/// The input vertices where separate sheets of `cover` meet at the vertex alone: copies in two or more
/// of its connected components (glued faces). Call it on distinct_sheets' cover, where a closed
/// sheet's mirror is gone (else every vertex of a closed sheet would count). Increasing order.
std::vector<Index> sheet_junctions(const TuftedCover& cover);

/// Per vertex of (F, L) with `vertex_count` vertices: a third of the area of every face at its corners.
Eigen::VectorXd lumped_vertex_areas(const Faces& F, const FaceLengths& L, Index vertex_count);

}  // namespace ice::detail
