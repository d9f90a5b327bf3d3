#pragma once
/// \file multigrid.h
/// The exact route's setup, made once: the ICE multigrid hierarchy of a mesh (ice/hierarchy.h),
/// looked up in and saved to the store (store.h) as the coarse proxies are. fem::PoissonSolver and
/// fem::MultigridSolver take what it holds; one hierarchy serves every operator on the mesh's
/// vertices (Poisson, heat steps M + τL, any time step).
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/SparseCore>

#include "fem/problems.h"
#include "ice/hierarchy.h"
#include "ice/proxy/store.h"

namespace ice::proxy {

/// What a multigrid solver needs of a hierarchy, and what reports say about it.
struct MultigridHierarchy {
  Index fine_vertices = 0;  ///< n_0, the mesh's vertex count
  /// P_k (n_k × n_{k+1}), as ice::Hierarchy::prolongations.
  std::vector<Eigen::SparseMatrix<double>> prolongations;
  /// ice::Hierarchy::fine_order (empty without HierarchyOptions::reorder).
  std::vector<Index> fine_order;
  std::string stop_reason;
  /// Of the build that made the hierarchy (also when it was loaded): wall time, and the part spent
  /// coarsening.
  double build_seconds = 0, coarsen_seconds = 0;
  CacheReport cache;  ///< where it came from (status off without a store)

  int num_levels() const { return static_cast<int>(prolongations.size()) + 1; }
  /// Vertices of level k (0 ≤ k < num_levels()).
  Index level_vertices(int k) const;
  /// Σ n_k / n_0, as ice::Hierarchy::grid_complexity.
  double grid_complexity() const;
  /// A fem::PoissonMultigrid on these levels with `options`, numbered by fine_order (copies the
  /// prolongations: the hierarchy stays usable for other operators).
  fem::PoissonMultigrid poisson_multigrid(const fem::MultigridOptions& options) const;
};

/// The multigrid hierarchy of `mesh` by `options` (ice::build_hierarchy). With an enabled `store`
/// it is first looked up under multigrid_hierarchy_key(mesh, options); a hit returns the stored
/// prolongations and order to the last bit, checked before use (shapes, sorted columns, finite
/// entries, every row of every P summing to 1, the order a permutation); a damaged entry is
/// reported in `cache` (status rebuilt), removed and built again. Otherwise the hierarchy is built
/// and saved. Throws as ice::build_hierarchy (std::invalid_argument on bad options or mesh).
MultigridHierarchy multigrid_hierarchy(const TriangleMesh& mesh, const HierarchyOptions& options = {},
                                       const Store& store = {});

/// Writes `hierarchy` (checked first as a loaded one is) to the file `path` in the store's entry
/// format, keyed by `mesh`'s arrays: load_multigrid_hierarchy_file takes it back for that mesh
/// only. Atomic (a temporary file beside `path`, renamed); an existing file is replaced only when
/// `overwrite`. Throws std::invalid_argument when the hierarchy is not one of `mesh` (its finest
/// level's size, its prolongations' shapes, weights and rows, the order), ice::MeshError
/// (unwritable) when `path` exists and `overwrite` is false or its directory does not exist,
/// std::runtime_error naming the file when it cannot be written.
void save_multigrid_hierarchy_file(const std::filesystem::path& path, const TriangleMesh& mesh,
                                   const MultigridHierarchy& hierarchy, bool overwrite = false);
/// The hierarchy saved at `path` for `mesh`, checked as a stored one is; cache.status off,
/// cache.load_seconds its time. Throws std::runtime_error naming the file and the defect: no such
/// file, not a hierarchy, damaged, of another format version, or made for another mesh.
MultigridHierarchy load_multigrid_hierarchy_file(const std::filesystem::path& path, const TriangleMesh& mesh);

/// The key of the hierarchy of `mesh` by `options`: the mesh's positions and faces, every option
/// (locked vertices as a set; the thread count and the non-manifold choice only where the result
/// depends on them) and the store's format version.
StoreKey multigrid_hierarchy_key(const TriangleMesh& mesh, const HierarchyOptions& options);

}  // namespace ice::proxy
