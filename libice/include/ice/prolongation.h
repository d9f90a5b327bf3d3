#pragma once
/// \file prolongation.h
/// The fine-to-coarse map of a coarsened intrinsic triangulation as a sparse prolongation matrix.
///
/// P is |V_input| × |V_coarse|. A surviving input vertex's row holds a single 1 in its coarse
/// column; a removed vertex's row holds its barycentric coordinates in the columns of the corners of
/// the coarse face that contains it (entries of repeated corners of a Δ-complex face are summed).
/// Rows sum to 1, at most three non-zeros per row. Restriction is Pᵀ. Vertices inserted by refinement
/// (ice/refinement.h) are coarse vertices too: their columns hold the weights of the input vertices
/// in their faces (they have no row).
#include <vector>

#include <Eigen/SparseCore>

#include "ice/intrinsic_triangulation.h"

namespace ice {

/// P for the current state of T; `coarse` must be T.compact() of that same state, its coarse
/// vertices possibly renumbered (P's columns follow coarse.from_input; inserted vertices, whose
/// to_input is kInvalid, must keep their relative order). With `row_of`, T's input
/// vertex t is row row_of[t] (a permutation: T works in another numbering than the caller's).
Eigen::SparseMatrix<double> prolongation(const IntrinsicTriangulation& T, const CompactMesh& coarse,
                                         const std::vector<Index>& row_of = {});

}  // namespace ice
