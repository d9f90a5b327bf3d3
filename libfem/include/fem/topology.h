#pragma once
/// \file topology.h
/// Connectivity queries on a triangle list that the PDE solvers need (boundary detection).
#include <vector>

#include "fem/geometry.h"

namespace fem {

/// Sorted, unique vertices that lie on a boundary edge (an edge used by exactly one face).
/// Runs in O(m log m). Edges with more than two faces are treated as interior.
std::vector<Index> boundary_vertices(const ice::Faces& F);

}  // namespace fem
