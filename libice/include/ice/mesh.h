#pragma once
/// \file mesh.h
/// Plain array meshes shared by every part of ICE.
///
/// Conventions used throughout the project:
///  - `V` is n×3 (double), one row per vertex; `F` is m×3 (int), 0-based vertex indices, one row per
///    triangle, counter-clockwise seen from outside.
///  - Per-face edge lengths (`FaceLengths`, m×3): column k holds the length of the edge that goes from
///    corner k to corner (k+1)%3 of the face, i.e. from F(f,k) to F(f,(k+1)%3). The corner angle at
///    corner k is therefore opposite the edge stored in column (k+1)%3.
#include <Eigen/Core>

namespace ice {

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
FaceLengths face_lengths_from_positions(const Positions& V, const Faces& F);

}  // namespace ice
