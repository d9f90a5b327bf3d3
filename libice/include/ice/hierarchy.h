#pragma once
/// \file hierarchy.h
/// A multilevel hierarchy of intrinsic meshes by repeated ICE coarsening, with the prolongation
/// between consecutive levels (the geometric part of a Galerkin multigrid solver, fem/multigrid.h).
///
/// Level 0 is the input mesh. Level k+1 is made from level k alone: the triangulation of level k
/// (IntrinsicTriangulation::compacted of the previous coarsening, which restarts tracking, so its
/// input vertices are exactly level k's vertices; any Δ-complex carries over) is coarsened to
/// ⌈ratio·n_k⌉ vertices (at least `coarsest_vertices`) by intrinsic vertex removals (flatten, flip
/// to degree 3, merge, re-locate tracked points, restore Delaunay), in independent-set passes by
/// default (see HierarchyOptions::independent_sets: plain greedy ICE coarsening makes levels whose
/// density follows curvature, which multigrid converges badly on). ice::prolongation of the
/// coarsened triangulation is then exactly P_k (n_k × n_{k+1}, rows sum to 1, at most three
/// non-zeros per row). Building stops when a level has at most `coarsest_vertices` vertices,
/// when `max_levels` is reached, or when a level cannot be coarsened usefully (the coarsening
/// removed fewer than 10 % of the vertices). The hierarchy depends only on the mesh, not on the
/// PDE: one hierarchy serves every operator on the fine vertices (Laplacian, mass, M + tL, Dirichlet
/// systems) and every right-hand side.
#include <string>
#include <vector>

#include <Eigen/SparseCore>

#include "ice/coarsen.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh.h"
#include "ice/tufted_cover.h"

namespace ice {

/// How a hierarchy level is coarsened.
enum class LevelCoarsening {
  /// Default: in passes; a pass picks a maximal independent set of the current triangulation greedily
  /// (every other vertex stays for that pass) and removes it directly (IntrinsicTriangulation::
  /// remove_vertex + Delaunay repair). Levels stay uniform in density, which multigrid needs. No
  /// angular coordinate is read (except with SetOrder::exact_cost, whose costs come from the ICE
  /// metric), so the levels are coarsened without maintaining them
  /// (IntrinsicTriangulation::maintain_frames(false): faster hierarchies with the same PCG iteration
  /// counts; docs/measurements.md, "Multigrid hierarchy: level coarsening").
  independent_sets,
  /// The same sets, removed through ice::coarsen in ICE-metric order (every other vertex locked): the
  /// same removals up to order, measured slower (same section); no anchors.
  independent_sets_by_metric,
  /// Plain greedy ICE coarsening: adaptive levels (flat regions get very coarse), on which the
  /// V-cycle converges much more slowly (same section).
  greedy,
};

/// Which vertex an independent-set pass takes first.
enum class SetOrder {
  /// Default: vertex order (memory-local; faster hierarchies than flattest_first with about the same
  /// PCG iterations; docs/measurements.md, "Multigrid hierarchy: level coarsening").
  vertex_index,
  flattest_first,  ///< smallest |curvature| first
  exact_cost,      ///< smallest exact ICE removal cost first (slower still, no better; same section)
};

struct HierarchyOptions {
  /// Vertex fraction kept per level (0 < ratio < 1).
  double ratio = 0.25;
  /// The coarsest level has about this many vertices (the last level stops here; 0 < value).
  Index coarsest_vertices = 500;
  /// Upper bound on the number of levels, the fine one included (>= 1).
  int max_levels = 20;
  /// Area weight of the ICE error metric (coarsen.h).
  double area_weight = 0;
  /// How each level is coarsened (see LevelCoarsening).
  LevelCoarsening coarsening = LevelCoarsening::independent_sets;
  /// Which vertex an independent-set pass takes first (ignored by LevelCoarsening::greedy).
  SetOrder set_order = SetOrder::vertex_index;
  /// With LevelCoarsening::independent_sets (direct removals): when a removed vertex's strongest link (largest non-negative cotan weight
  /// of the current triangulation) carries at least this share of its summed weights, that neighbour
  /// stays for the rest of the level, so the removed vertex is interpolated from the vertex it is tied
  /// to. Slivers and anisotropic sampling (scan rows, CAD strips) otherwise lose both ends of a
  /// strong link within one level, and the V-cycle cannot represent the error mode along it (smooth
  /// across the link, invisible to the smoother). The default 0.5 was measured against 0 with
  /// poisson-coarse --solver multigrid: better PCG factors and fewer iterations on most meshes
  /// (docs/measurements.md, "Multigrid hierarchy: strong-neighbour share").
  /// 0 disables it; isotropic vertices (six comparable links) never trigger it.
  /// The same share decides which boundary vertices the boundary walk may remove: one whose strongest
  /// link leaves its loop stays (its removal would interpolate it along the loop, not from the vertex
  /// it is tied to), and does not count toward the loop's √r goal (measured in the same section).
  double strong_neighbour_share = 0.5;
  /// Whether boundary vertices may be removed.
  bool remove_boundary = true;
  /// Coarsen in a breadth-first (reverse Cuthill–McKee, ice/graph_ordering.h) numbering of the
  /// fine vertices instead of the input's: each removal's two-ring then sits close in memory (a
  /// Loop-subdivided mesh's own numbering scatters it), and the coarse levels inherit the order.
  /// Internal only: level 0, prolongations[0]'s rows and every to_fine are in the input's numbering.
  /// Which vertices each level keeps depends on the numbering (vertex-order independent sets).
  bool reorder = true;
  /// Threads of the independent-set passes on levels of 50,000+ vertices (0: one per hardware
  /// thread). With `reorder`, such a level is cut into 16 index ranges whatever the thread count, so
  /// the hierarchy is the same for every thread count.
  int threads = 0;
  /// Fine (level-0) vertices that stay on every level (e.g. to keep sources as coarse vertices).
  /// Not needed for Dirichlet conditions: fem::MultigridSolver handles those algebraically.
  std::vector<Index> locked_vertices;
  /// A mesh that is not an oriented manifold: refused (as IntrinsicTriangulation::from_mesh), or its
  /// levels made by coarsening its tufted cover (build_hierarchy(const TuftedCover&, ...)). Read by
  /// build_hierarchy(const TriangleMesh&, ...) only; an oriented manifold is coarsened as it is either way.
  NonmanifoldInput nonmanifold = NonmanifoldInput::refuse;
};

/// One level: an intrinsic mesh (glued by vertex pairs: `twin` empty; a tufted cover's levels keep
/// their gluing, with each vertex's copies named by the vertex) and where its vertices come from
/// (vertex_count == to_fine.size()).
struct HierarchyLevel : IntrinsicMesh {
  std::vector<Index> to_fine; ///< level vertex -> level-0 vertex (the same surface point)
};

struct Hierarchy {
  /// levels[0] is the input; levels.back() the coarsest.
  std::vector<HierarchyLevel> levels;
  /// prolongations[k] is P_k, n_k × n_{k+1}: level k+1 values -> level k values.
  std::vector<Eigen::SparseMatrix<double>> prolongations;
  /// The coarsening of level k into level k+1.
  std::vector<CoarsenResult> coarsening;
  /// Why the building stopped (human readable).
  std::string stop_reason;
  /// With HierarchyOptions::reorder, level 0's vertices in the breadth-first (reverse
  /// Cuthill–McKee) order the levels were coarsened in (fine_order[new] = level-0 vertex), else
  /// empty. A multigrid solver on these levels can number its unknowns by it instead of ordering
  /// the matrix's graph again (fem::MultigridSolver::set_locality_order).
  std::vector<Index> fine_order;
  /// Wall time of build_hierarchy, and the part spent inside ice::coarsen.
  double seconds = 0, coarsen_seconds = 0;

  int num_levels() const { return static_cast<int>(levels.size()); }
  /// Σ n_k / n_0.
  double grid_complexity() const;
  /// P_0·P_1·…·P_{k-1} (n_0 × n_k), for tests and tools; identity for k = 0.
  Eigen::SparseMatrix<double> prolongation_to_fine(int k) const;
};

/// Builds the hierarchy of an intrinsic mesh, glued by vertex pairs (`twin` empty) or by `twin` (any
/// Δ-complex; its levels keep their gluing), whose every vertex is used (vertex_count =
/// F.maxCoeff() + 1). Preconditions as for IntrinsicTriangulation::from_lengths (or
/// from_glued_faces), and that one (std::invalid_argument otherwise); options checked
/// (std::invalid_argument; options.nonmanifold is not read).
Hierarchy build_hierarchy(const IntrinsicMesh& mesh, const HierarchyOptions& options = {});

/// Same for an extrinsic mesh (lengths from positions). With options.nonmanifold = tufted_cover, a
/// mesh that needs the cover (ice::needs_tufted_cover) is coarsened through it, as below.
Hierarchy build_hierarchy(const TriangleMesh& mesh, const HierarchyOptions& options = {});

/// The hierarchy of a mesh that is not an oriented manifold, on its own vertices: the levels are
/// coarsened on the cover's distinct sheets (ice::distinct_sheets) and, on every level, the copies of
/// one input vertex are one unknown (as ice::build_coarse_space does for the proxy). Level 0 is the
/// input's vertices in their numbering; P_k = W_k · Pᶜ_k · S_{k+1}, where Pᶜ_k is the cover level's
/// prolongation, S_{k+1} gives each copy of level k+1 its vertex's value and W_k averages the copies
/// of each level-k vertex by their lumped areas (ice::copies_to_vertices): rows sum to 1, and a
/// field equal on all copies keeps its values. coarsest_vertices and locked_vertices count input
/// vertices (every copy of a locked vertex stays). fine_order is the cover's breadth-first order
/// of its copies, each vertex at its first copy. `coarsening` holds the cover levels' results.
/// Preconditions as for ice::tufted_cover's result (std::invalid_argument otherwise).
Hierarchy build_hierarchy(const TuftedCover& cover, const HierarchyOptions& options = {});

}  // namespace ice
