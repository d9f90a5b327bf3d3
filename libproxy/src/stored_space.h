#pragma once
// A coarse space's arrays in a store entry or entry file, and the part of a key that says how it was
// coarsened: what the proxy setups (stored_setup.cpp) and the mapped spaces (mapped_space.cpp) share.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/SparseCore>

#include "ice/coarse_space.h"
#include "ice/proxy/store.h"

namespace ice::proxy::detail {

/// Writes a coarse space's arrays ("coarse.*", and "input_vertices") into an EntryWriter. The writer
/// points into the space and into this object, which must both outlive it.
class CoarseSpaceArrays {
 public:
  CoarseSpaceArrays(EntryWriter& writer, const CoarseSpace& coarse);
  CoarseSpaceArrays(const CoarseSpaceArrays&) = delete;
  CoarseSpaceArrays& operator=(const CoarseSpaceArrays&) = delete;

 private:
  std::vector<std::int32_t> inserted_faces_;
  std::vector<double> inserted_bary_, summary_;
  Eigen::SparseMatrix<double> compressed_P_;  // a copy only when the coarse space's P is not compressed
};

/// The coarse space an entry holds for `mesh`, every array checked (shapes, ranges, the gluing's and
/// vertex maps' symmetry, the triangle inequality, P's shape and sorted columns): throws
/// std::runtime_error naming `path` and the defect otherwise. Without the method's state.
CoarseSpace coarse_space_from_entry(const EntryReader& entry, const std::string& path, const TriangleMesh& mesh);

/// Adds the mesh's arrays and every coarsening option that changes the coarse space to a key (the
/// locked vertices as a set, the region count it runs with; never the thread count, the progress
/// callback or whether the method's state is kept).
void add_mesh_and_coarsening(KeyHasher& h, const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening);

}  // namespace ice::proxy::detail
