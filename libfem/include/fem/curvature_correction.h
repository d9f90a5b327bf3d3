#pragma once
/// \file curvature_correction.h
/// Coarse edge lengths for geodesic distances that account for the curvature a coarse face flattens.
///
/// A coarse face is flat; the patch of surface it stands for is not. On a surface of constant
/// Gaussian curvature K, the geodesic triangle with sides s has medians (√3/2)·s·(1 + K s²/24 + …),
/// while a flat triangle with sides ℓ has (√3/2)·ℓ: with ℓ = s the flat face shortens every path that
/// crosses a positively curved patch (a bump) and lengthens every path across a negatively curved
/// one (a saddle: where limbs join a body, around handles and holes) — the coarse mesh's distances
/// are then biased, and no finer marching removes that. Lengthening each edge by exp(K s²/24), K the
/// curvature density around the edge, makes the flat medians match to second order.
///
/// Against exact polyhedral geodesics (coarse fast marching) the correction lowers the error of ICE
/// coarse meshes, with their intrinsic lengths and with traced lengths alike. QEM's coarse meshes are
/// not helped: their chords, short on curved parts, already offset the bias (docs/measurements.md,
/// "Curvature correction").
#include "fem/geometry.h"
#include "fem/operators.h"

namespace fem {

/// The angle defect of each fine vertex (2π minus its corner angles; 0 on boundary vertices, whose
/// curvature is geodesic curvature of the boundary, and on vertices no face uses): the Gaussian
/// curvature it carries. Throws InvalidTriangle as corner_angles.
Eigen::VectorXd angle_defects(const ice::IntrinsicMesh& mesh);

/// How strongly the lengths are corrected: each edge scaled by exp(K ℓ² / divisor). The expansion
/// for medians of constant curvature gives 24; the marching that reads the lengths has its own
/// bias, which the best divisor offsets, so each marching has the divisor measured best for it
/// against exact polyhedral geodesics (docs/measurements.md, "Curvature correction divisor"): 48
/// for the geodesic proxy's single-source marching, which tracks virtual sources and is nearly
/// exact on the coarse metric; 24 for the distance oracle's plain all-pairs marching, biased long.
inline constexpr double kProxyCorrectionDivisor = 48;
inline constexpr double kOracleCorrectionDivisor = 24;

/// `coarse`'s lengths with each edge (u, w) scaled by exp(K_uw ℓ² / divisor), K_uw = (κ_u + κ_w) / (A_u +
/// A_w), where κ = Pᵀ (fine angle defects) and A = Pᵀ (fine vertex areas, a third of each face's)
/// gather the fine curvature and area onto the coarse vertices through P. The curvature of fine
/// vertices that are coarse vertices counts too (so even P = I changes the lengths): leaving it out, as
/// the cone angles already hold it, was measured worse (docs/measurements.md, "Curvature
/// correction"). The expansion is of second order in Kℓ²; on inputs of a few vertices coarsened to 3
/// (CGAL's beam, pyramid, tetrahedron) each face spans too much curvature for it and the distances
/// get much worse (turn it off there), while large corrections on real meshes of high genus help
/// (same section). An edge
/// keeps one length on both its sides (sides are taken as one edge when they join the same vertices
/// with the same length, as the marching takes them); where the scaled lengths break a face's triangle
/// inequality, that face's edges keep their lengths (and so do their other sides), until every face is
/// valid, so the result is a valid intrinsic metric whenever `coarse`'s is. Preconditions
/// (std::invalid_argument): `fine` a valid mesh (checked_vertex_count) of P.rows() vertices; coarse
/// faces and lengths of one shape with vertices below P.cols(); P non-negative rows (a barycentric or
/// any interpolating prolongation), divisor > 0. The fine lengths must be valid (InvalidTriangle).
FaceLengths curvature_corrected_lengths(const ice::IntrinsicMesh& fine, const ice::IntrinsicMesh& coarse,
                                        const SparseMatrix& P, double divisor = kProxyCorrectionDivisor);

/// What the correction gathers from the fine mesh onto the coarse vertices: κ = Pᵀ (fine angle
/// defects) and A = Pᵀ (fine vertex areas), the fine mesh's whole part of it (what a store keeps).
struct CoarseCurvature {
  Eigen::VectorXd curvature, area;
};
/// κ and A of `fine` through P; preconditions on `fine` and P as curvature_corrected_lengths'.
CoarseCurvature coarse_curvature(const ice::IntrinsicMesh& fine, const SparseMatrix& P);
/// curvature_corrected_lengths from κ and A already gathered (`gathered`, of `coarse`'s vertex count:
/// std::invalid_argument otherwise): the same lengths to the last bit.
FaceLengths curvature_corrected_lengths(const ice::IntrinsicMesh& coarse, const CoarseCurvature& gathered,
                                        double divisor = kProxyCorrectionDivisor);

}  // namespace fem
