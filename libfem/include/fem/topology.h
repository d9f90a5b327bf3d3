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

/// The same components, labelled: label[i] in [0, count()), components numbered in the order of
/// their smallest row, which first[] holds (the unknown a zero-mean solver pins in each).
struct ComponentLabels {
  std::vector<Index> label;
  std::vector<Index> first;
  Index count() const { return static_cast<Index>(first.size()); }
};
ComponentLabels component_labels(const SparseMatrix& A);
/// The components of a face list's vertices (0 .. vertex_count − 1; faces join their corners, a
/// vertex no face uses is a component of its own), labelled as above. O(m α(n)).
ComponentLabels vertex_components(const ice::Faces& F, Index vertex_count);

/// Per component: whether it holds one of `vertices` (those out of range are ignored).
std::vector<char> components_holding(const ComponentLabels& components, const std::vector<Index>& vertices);

/// Per component c of x's entries: x_i −= (Σ_{j∈c} w_j x_j) / (Σ_{j∈c} w_j), i.e. zero w-weighted
/// mean on each (a component of zero total weight is left as it is). One component: x −= w·x / Σw.
void remove_component_means(const ComponentLabels& components, const Eigen::VectorXd& weights, Eigen::VectorXd& x);

/// Per component c: b_i −= w_i (Σ_{j∈c} b_j) / (Σ_{j∈c} w_j), so that b sums to zero on each: a
/// mass-weighted right-hand side b made compatible with a Laplacian whose null space is the
/// components' constants (w = M·1). One component: b −= w (Σb / Σw).
void make_compatible(const ComponentLabels& components, const Eigen::VectorXd& weights, Eigen::VectorXd& b);

/// Throws std::invalid_argument naming `what` unless A's graph is connected: the solvers that pin
/// one unknown (zero-mean Poisson, the heat method's Poisson step) are singular otherwise, which
/// CHOLMOD would report only as a tiny pivot.
void require_connected(const SparseMatrix& A, const char* what);

}  // namespace fem
