#pragma once
/// \file topology.h
/// Connectivity queries that the PDE solvers need: boundary detection on a triangle list, connected
/// components of an operator's graph.
#include <vector>

#include "fem/geometry.h"
#include "fem/operators.h"

namespace fem {

/// Sorted, unique vertices that lie on a boundary edge (an edge used by exactly one face).
/// Runs in O(m log m). Edges with more than two faces are treated as interior.
std::vector<Index> boundary_vertices(const ice::Faces& F);

/// Connected components of the graph whose edges are the off-diagonal non-zeros of the square
/// matrix A (a Laplacian: the components of its mesh, Galerkin coarse operators included). O(nnz).
Index connected_components(const SparseMatrix& A);

/// Throws std::invalid_argument naming `what` unless A's graph is connected: the solvers that pin
/// one unknown (zero-mean Poisson, the heat method's Poisson step) are singular otherwise, which
/// CHOLMOD would report only as a tiny pivot.
void require_connected(const SparseMatrix& A, const char* what);

}  // namespace fem
