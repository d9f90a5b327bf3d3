#pragma once
/// \file ordering.h
/// Orderings of the unknowns of a sparse symmetric matrix for memory locality.
///
/// Iterative kernels on mesh matrices (Gauss–Seidel sweeps, products with many right-hand sides)
/// read x at the neighbours of every row. When neighbours have nearby indices those reads hit the
/// caches; in the order a mesh file or Loop subdivision produces they are scattered over the whole
/// vector. A Cuthill–McKee ordering numbers the unknowns breadth first, so every neighbour of row i
/// lies within the band of the breadth-first levels around i (for a surface mesh of n vertices,
/// typically a few √n rows), and contiguous index ranges are contiguous regions of the mesh (a split
/// into ranges cuts few couplings, which is what parallel Gauss–Seidel needs).
#include <vector>

#include "fem/operators.h"

namespace fem {

/// Reverse Cuthill–McKee ordering of the graph of A's off-diagonal pattern (A square with a
/// symmetric pattern; values are ignored): ice::reverse_cuthill_mckee (ice/graph_ordering.h) on
/// A's columns. Returns `order` with order[new] = old, a permutation of 0..n−1, each connected
/// component contiguous; deterministic. Throws std::invalid_argument if A is not square.
std::vector<Index> reverse_cuthill_mckee(const SparseMatrix& A);

/// Largest |i − j| over the stored entries of A (its bandwidth; 0 for a diagonal or empty matrix).
Eigen::Index bandwidth(const SparseMatrix& A);

/// P A Pᵀ for the ordering `order` (order[new] = old): entry (i, j) of the result is
/// A(order[i], order[j]). Inner indices sorted. Throws std::invalid_argument on a size mismatch.
SparseMatrix permute_symmetric(const SparseMatrix& A, const std::vector<Index>& order);

/// P's rows in the ordering `order` (order[new] = old), its columns as they are: row i of the result
/// is row order[i] of P (e.g. a prolongation whose fine vertices are renumbered). Inner indices
/// sorted. Throws std::invalid_argument unless `order` is a permutation of P's rows.
SparseMatrix permute_rows(const SparseMatrix& P, const std::vector<Index>& order);

}  // namespace fem
