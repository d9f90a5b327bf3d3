#pragma once
/// Checks of mesh files shared by the tests: the figures of a real mesh as a mesh set's README states
/// them against a validation report, the loader's refusals, the orientation of a closed surface.
#include <catch2/catch.hpp>

#include <Eigen/Geometry>

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "ice/mesh_io.h"
#include "ice/mesh_validation.h"

namespace ice_test {

/// One row of a mesh set's table (data/README.md for the project set).
struct Expected {
  const char* file;
  std::size_t vertices, faces, boundary_loops, components;
  std::size_t non_manifold_edges, non_manifold_vertices;  // both 0: manifold
  int genus;                                              // -1: n/a
  // Flags of the README (0 if not listed).
  std::size_t zero_area_faces, duplicate_positions, inconsistent_edges, unreferenced_vertices, duplicate_faces;
  bool orientable;
};

/// Checks every figure of the row against a validation report of the file.
inline void check_figures(const Expected& e, const ice::ValidationReport& r) {
  INFO(e.file);
  CHECK(r.n_vertices == e.vertices);
  CHECK(r.n_faces == e.faces);
  CHECK(r.n_boundary_loops == e.boundary_loops);
  CHECK(r.components.size() == e.components);
  CHECK(r.non_manifold_edges.count == e.non_manifold_edges);
  CHECK(r.non_manifold_vertices.count == e.non_manifold_vertices);
  CHECK(r.manifold() == (e.non_manifold_edges == 0 && e.non_manifold_vertices == 0));
  CHECK(r.genus == e.genus);
  CHECK(r.zero_area_faces.count == e.zero_area_faces);
  CHECK(r.duplicate_positions.count == e.duplicate_positions);
  CHECK(r.inconsistent_edges.count == e.inconsistent_edges);
  CHECK(r.unreferenced_vertices.count == e.unreferenced_vertices);
  CHECK(r.duplicate_faces.count == e.duplicate_faces);
  CHECK(r.orientable() == e.orientable);
  // Nothing else is wrong with these files.
  CHECK(r.non_triangle_faces.empty());
  CHECK(r.out_of_range_faces.empty());
  CHECK(r.repeated_index_faces.empty());
  CHECK(r.non_finite_vertices.empty());
}

/// Whether the row lists a defect that makes the loader refuse the file.
inline bool flagged(const Expected& e) {
  return e.non_manifold_edges || e.non_manifold_vertices || e.zero_area_faces || e.inconsistent_edges ||
         e.unreferenced_vertices || e.duplicate_faces || !e.orientable;
}

/// The row of `file` in a table (a missing row is a bug of the test).
inline const Expected& table_row(const std::vector<Expected>& table, const std::string& file) {
  for (const Expected& e : table)
    if (file == e.file) return e;
  throw std::logic_error("not in the table: " + file);
}

/// Message of the MeshError thrown by load_mesh (fails the test if nothing is thrown).
inline std::string refusal(const std::string& path, const ice::LoadOptions& options = {}) {
  try {
    ice::load_mesh(path, options);
  } catch (const ice::MeshError& e) {
    CHECK(e.kind() == ice::MeshError::Kind::Defective);
    return e.what();
  }
  FAIL("load_mesh accepted " << path);
  return {};
}

/// Signed volume enclosed by a closed triangle mesh (positive for outward normals).
inline double signed_volume(const ice::TriangleMesh& m) {
  double v = 0;
  for (Eigen::Index f = 0; f < m.F.rows(); ++f)
    v += Eigen::Vector3d(m.V.row(m.F(f, 0))).dot(Eigen::Vector3d(m.V.row(m.F(f, 1))).cross(Eigen::Vector3d(m.V.row(m.F(f, 2)))));
  return v / 6;
}

}  // namespace ice_test
