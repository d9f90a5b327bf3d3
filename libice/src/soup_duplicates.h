#pragma once
// Internal to libice: exact duplicates in a polygon soup — vertices at the same position, faces on
// the same vertex set — found one way for the validator (which reports them) and the repair (which
// welds and drops them).
#include <cstddef>
#include <vector>

#include "ice/mesh.h"
#include "ice/mesh_validation.h"

namespace ice::detail {

/// For every vertex, the smallest vertex at exactly the same position (itself when none is
/// smaller). Vertices with a non-finite coordinate are never merged.
std::vector<int> first_coincident_vertex(const Positions& V);

/// The faces among those with include[f] whose vertex set (ignoring order and orientation) equals
/// that of an earlier included face, in increasing order. Every index of an included face must lie
/// in [0, vertices).
std::vector<int> later_duplicate_faces(const PolygonList& faces, const std::vector<char>& include, Index vertices);

}  // namespace ice::detail
