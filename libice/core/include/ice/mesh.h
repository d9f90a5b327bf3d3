#pragma once
/// \file mesh.h
/// Plain array meshes shared by every part of ICE: the core target (ICE::core, header-only) that both
/// libice and libfem use; libfem sees nothing else of libice.
///
/// Conventions used throughout the project:
///  - `V` is n×3 (double), one row per vertex; `F` is m×3 (int), 0-based vertex indices, one row per
///    triangle, counter-clockwise seen from outside.
///  - Per-face edge lengths (`FaceLengths`, m×3): column k holds the length of the edge that goes from
///    corner k to corner (k+1)%3 of the face, i.e. from F(f,k) to F(f,(k+1)%3). The corner angle at
///    corner k is therefore opposite the edge stored in column (k+1)%3.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace ice {

/// Vertex, face and half-edge indices of ICE (int32: meshes up to 2^31 elements, half the memory of
/// 64-bit indices in every connectivity array).
using Index = std::int32_t;
/// "No such element" (a removed input vertex, a boundary side without a twin, ...).
constexpr Index kInvalid = -1;

/// Vertex positions, n×3.
using Positions = Eigen::MatrixXd;
/// Triangles, m×3, 0-based indices.
using Faces = Eigen::MatrixXi;
/// Per-face edge lengths, m×3; column k is the edge from corner k to corner (k+1)%3.
using FaceLengths = Eigen::MatrixXd;

/// An extrinsic triangle mesh: positions and triangles.
struct TriangleMesh {
  Positions V;
  Faces F;
};

/// Length of the edge from vertex a to vertex b of V: the one formula behind
/// face_lengths_from_positions and the validator's degenerate-face test, so they agree to the bit.
inline double edge_length(const Positions& V, int a, int b) { return (V.row(b) - V.row(a)).norm(); }

/// Per-face edge lengths of an extrinsic mesh, in the `FaceLengths` convention.
inline FaceLengths face_lengths_from_positions(const Positions& V, const Faces& F) {
  FaceLengths lengths(F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) lengths(f, k) = edge_length(V, F(f, k), F(f, (k + 1) % 3));
  return lengths;
}

/// An intrinsic triangle mesh as a value: ICE's one vocabulary for it. Faces, per-face edge lengths
/// (the `FaceLengths` convention), how the faces are glued, and the vertex count. What libfem's
/// operators take; CompactMesh, FineMesh, HierarchyLevel and IntrinsicMeshFile are one, with their
/// maps beside it.
/// Invariants (code that takes one checks those it relies on: std::invalid_argument): L has F's
/// rows; every index of F lies in [0, vertex_count); `twin` is empty or has 3·F.rows() entries.
struct IntrinsicMesh {
  Faces F;        ///< faces (ice/mesh.h convention)
  FaceLengths L;  ///< per-face edge lengths
  /// How the faces are glued: twin[3f + k] is the side 3g + d that runs along face f's side k (from
  /// corner k to k+1) the other way, or kInvalid on the boundary. Vertex pairs cannot say this in a
  /// Δ-complex (self-edges, two edges between one pair of vertices). Empty: glue by vertex pairs.
  std::vector<Index> twin;
  /// Vertices 0 .. vertex_count − 1, also those no face uses (which F alone cannot count).
  Index vertex_count = 0;

  Index num_vertices() const { return vertex_count; }
};

/// The intrinsic mesh of an extrinsic one: its faces, their edge lengths from the positions, glued by
/// vertex pairs, one vertex per row of V.
inline IntrinsicMesh intrinsic_mesh(const TriangleMesh& mesh) {
  return IntrinsicMesh{mesh.F, face_lengths_from_positions(mesh.V, mesh.F), {}, static_cast<Index>(mesh.V.rows())};
}

/// The intrinsic mesh of faces F and lengths L (of F's shape), glued by vertex pairs, with
/// `vertex_count` vertices, or (−1) the vertices F names: max index + 1.
inline IntrinsicMesh intrinsic_mesh(Faces F, FaceLengths L, Index vertex_count = -1) {
  if (vertex_count < 0) vertex_count = F.size() == 0 ? 0 : F.maxCoeff() + 1;
  return IntrinsicMesh{std::move(F), std::move(L), {}, vertex_count};
}

/// What is wrong with a side's gluing (first_gluing_defect).
enum class GluingDefect { none, out_of_range, not_glued_back, other_ends, other_length };
struct GluingCheck {
  GluingDefect defect = GluingDefect::none;
  Index side = -1, other = -1;  ///< the side (3f + k) and the side `twin` glues it to
};
/// The first side, in increasing order, that `twin` (3·F.rows() entries: the IntrinsicMesh
/// convention, −1 on the boundary) does not glue to a side glued back to it, running between the
/// same two vertices the other way, of the same length to `relative_tolerance` (0: bit for bit).
/// Precondition: twin.size() == 3·F.rows(), L of F's shape.
inline GluingCheck first_gluing_defect(const Faces& F, const FaceLengths& L, const std::vector<Index>& twin,
                                       double relative_tolerance = 0) {
  const auto sides = static_cast<Index>(3 * F.rows());
  for (Index side = 0; side < sides; ++side) {
    const Index other = twin[static_cast<std::size_t>(side)];
    if (other == -1) continue;
    GluingCheck found{GluingDefect::none, side, other};
    const Index f = side / 3, g = other / 3;
    const int c = static_cast<int>(side % 3), d = static_cast<int>(other % 3);
    if (other < 0 || other >= sides || other == side)
      found.defect = GluingDefect::out_of_range;
    else if (twin[static_cast<std::size_t>(other)] != side)
      found.defect = GluingDefect::not_glued_back;
    else if (F(f, c) != F(g, (d + 1) % 3) || F(f, (c + 1) % 3) != F(g, d))
      found.defect = GluingDefect::other_ends;
    else if (std::abs(L(f, c) - L(g, d)) > relative_tolerance * std::max(L(f, c), L(g, d)))
      found.defect = GluingDefect::other_length;
    if (found.defect != GluingDefect::none) return found;
  }
  return {};
}

/// The same faces, gluing and vertices with other lengths (e.g. traced or curvature-corrected ones).
inline IntrinsicMesh with_lengths(const IntrinsicMesh& mesh, FaceLengths lengths) {
  return IntrinsicMesh{mesh.F, std::move(lengths), mesh.twin, mesh.vertex_count};
}

/// An intrinsic mesh exported from a (possibly heavily modified) triangulation
/// (`IntrinsicTriangulation::compact`), written as `.ilm`, with its map to the input's vertices
/// (vertex_count == to_input.size()).
struct CompactMesh : IntrinsicMesh {
  /// compact vertex -> input vertex, or kInvalid for a vertex inserted by refinement (not an input
  /// vertex; such vertices follow the input ones)
  std::vector<Index> to_input;
  std::vector<Index> from_input;    ///< input vertex -> compact vertex, or kInvalid if removed
};

/// Where one input vertex lies on a coarse mesh (ice/coarse_space.h, fine_to_coarse_map): the coarse
/// vertex it became (kInvalid if it was removed) and a face of the coarse mesh containing it with
/// barycentric coordinates with respect to that face's corners (a survivor: weight 1 at its own
/// corner). What fem::DistanceOracle answers queries with.
struct CoarsePoint {
  Index coarse_vertex = kInvalid;
  Index face = kInvalid;
  std::array<double, 3> bary{0, 0, 0};
};

}  // namespace ice
