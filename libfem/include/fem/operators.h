#pragma once
/// \file operators.h
/// Piecewise-linear finite element operators on an intrinsic mesh (ice::IntrinsicMesh: faces F,
/// lengths L; its gluing is not needed here).
///
/// Conventions:
///  - the number of unknowns n is the mesh's vertex_count (vertices no face uses get empty rows);
///    F and L of different shapes, a negative index or a count below F.maxCoeff() + 1 throw
///    std::invalid_argument.
///  - The cotangent Laplacian is positive semidefinite: L_ij = −w_ij for an edge ij,
///    L_ii = Σ_j w_ij, with w_ij = ½ Σ cot of the angles opposite edge ij (one or two faces).
///    It is the stiffness matrix ∫∇φ_i·∇φ_j, so L = Gᵀ·diag(A)·G with G the gradient below.
///  - Per-face gradients live in each face's own 2D frame from fem::layout_triangle (corner 0 at the
///    origin, corner 1 on +x), so they need no embedding; rows 2f and 2f+1 are the x and y components.
/// All assembly is linear in the number of faces, and its result does not depend on the thread count.
#include <type_traits>
#include <utility>

#include <Eigen/SparseCore>

#include "fem/geometry.h"

namespace fem {

using SparseMatrix = Eigen::SparseMatrix<double>;
static_assert(std::is_same_v<SparseMatrix::StorageIndex, Index>, "vertex indices are the sparse storage index");

/// The mesh's vertex count, after checking the invariants above (std::invalid_argument).
Eigen::Index checked_vertex_count(const ice::IntrinsicMesh& mesh);

/// Lumped (diagonal) or consistent (Galerkin P1) mass matrix.
enum class MassKind { lumped, consistent };

/// Cotangent Laplacian (n×n, symmetric positive semidefinite, rows sum to zero), rows sorted, one
/// entry per vertex pair joined by an edge (multiple edges summed in face order) and a diagonal
/// entry for every vertex a face uses. On OpenMP's threads when faces name three distinct vertices.
/// Throws InvalidTriangle on invalid or zero-area faces.
SparseMatrix cotan_laplacian(const ice::IntrinsicMesh& mesh);

/// Lumped vertex areas (n): one third of the area of every incident face.
Eigen::VectorXd lumped_vertex_areas(const ice::IntrinsicMesh& mesh);

/// Mass matrix (n×n): diagonal of lumped_vertex_areas, or the consistent P1 mass with A_f/6 on the
/// diagonal and A_f/12 off the diagonal per face. Both have total sum equal to the surface area.
SparseMatrix mass_matrix(const ice::IntrinsicMesh& mesh, MassKind kind = MassKind::lumped);

/// Per-face gradient (2m×n): (G u)(2f, 2f+1) is the constant gradient of the linear interpolant of u
/// on face f, in that face's local frame. Throws InvalidTriangle on invalid or zero-area faces.
SparseMatrix gradient(const ice::IntrinsicMesh& mesh);

/// Integrated divergence (n×2m) of per-face vector fields given in the local frames of `gradient`:
/// D = −Gᵀ·diag(A_f, A_f), the negative adjoint of G in the face-area inner product, so that
/// D·G = −L (the integrated Laplace–Beltrami operator, negative semidefinite) and
/// (D X)_i = −∫ ∇φ_i · X.
SparseMatrix divergence(const ice::IntrinsicMesh& mesh);

/// Galerkin coarse operator Pᵀ·A·P for a prolongation P (n_fine×n_coarse) and a symmetric fine
/// operator A (n_fine×n_fine; precondition, not checked). The lower triangle is computed and
/// mirrored, so the result is exactly symmetric; inner indices sorted. One fused pass over the
/// coarse columns, split among `threads` (0: OpenMP's default; 1: serial) when P has at least
/// 50,000 rows; the result does not depend on the thread count. Coarse unknowns that P reaches
/// weakly (vertices inserted by refinement where the fine mesh is sparse: an empty column, or
/// weights summing to less than 1) would make the product singular; they are stabilised on the
/// diagonal (libfem/src/sparse_columns.h: an unreached one decoupled, a weak one shifted by 1e-8 of
/// the mean diagonal). A P whose columns all reach a fine vertex with weight 1 (every ICE or QEM
/// coarsening without refinement) is untouched.
SparseMatrix galerkin(const SparseMatrix& P, const SparseMatrix& A, int threads = 0);

/// Pᵀ·A·P and Pᵀ·D·P for a diagonal D (a lumped mass; only diagonal entries stored, else
/// std::invalid_argument) in one pass over P and A: each equal to galerkin() of it, bit for bit.
std::pair<SparseMatrix, SparseMatrix> galerkin(const SparseMatrix& P, const SparseMatrix& A, const SparseMatrix& D,
                                               int threads = 0);

}  // namespace fem
