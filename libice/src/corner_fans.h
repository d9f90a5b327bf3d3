#pragma once
// Internal to libice: the fans of faces around each vertex, as the validator finds them, for the
// repair that splits non-manifold vertices (one definition of a fan for both).
#include <cstddef>
#include <vector>

#include "ice/mesh_validation.h"

namespace ice::detail {

/// The fan of every corner of the soup's well-formed faces: two corners at one vertex are in one fan
/// when their faces share an edge (with exactly two faces) at that vertex. A fan is named by its
/// smallest corner; corners are numbered face by face over the well-formed faces (3f + k for a soup
/// of valid triangles).
std::vector<std::size_t> corner_fans(const PolygonSoup& soup);

}  // namespace ice::detail
