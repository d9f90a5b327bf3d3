#pragma once
/// \file coarsen.h
/// ICE coarsening (Liu et al., "Surface Simplification using Intrinsic Error Metrics", SIGGRAPH
/// 2023): greedy removal of vertices of an intrinsic triangulation, cheapest first, where the cost
/// of removing a vertex measures how far its Gaussian curvature (and optionally its area) must be
/// transported to the neighbours that absorb it.
///
/// The cost of a removal is the intrinsic curvature error of ice/error_metric.h.
///
/// Removal itself (IntrinsicTriangulation::remove_vertex) flattens v, flips it down to degree 3 (2
/// on the boundary), replaces its star by one triangle, and the driver restores the intrinsic
/// Delaunay property around it. Every input vertex stays tracked (the fine-to-coarse map).
#include <array>
#include <complex>
#include <functional>
#include <limits>
#include <vector>

#include "ice/error_metric.h"
#include "ice/intrinsic_triangulation.h"

namespace ice {

/// Progress report passed to the callback.
struct CoarsenProgress {
  Index vertices = 0;       ///< current vertex count
  Index target = 0;         ///< target vertex count
  Index removed = 0;        ///< removals so far
  double last_cost = 0;     ///< cost of the latest removal
};

struct CoarsenOptions {
  /// Stop when this many vertices remain (0: use target_ratio; both 0: as few as possible).
  Index target_vertices = 0;
  /// Stop at this fraction of the input vertices (used when target_vertices == 0).
  double target_ratio = 0;
  /// Stop when the cheapest removal would cost more than this.
  double max_error = std::numeric_limits<double>::infinity();
  /// Mixture weight w ∈ [0,1] of the area channel (0: curvature only).
  double area_weight = 0;
  /// Divide the curvature masses by the mesh's total absolute curvature, making w the area
  /// channel's share of the total mass on every mesh (IntrinsicErrorMetric).
  bool normalize_curvature = false;
  /// Vertices never removed.
  std::vector<Index> locked_vertices;
  /// Whether boundary vertices may be removed (boundary loops always keep at least two edges).
  bool remove_boundary = true;
  /// Called every `progress_interval` removals; return false to cancel. Always called on the
  /// calling thread.
  std::function<bool(const CoarsenProgress&)> progress;
  Index progress_interval = 1000;
  /// Regions of the parallel phase, in [0, 254] (std::invalid_argument otherwise). 0 (the default):
  /// kDefaultCoarseningRegions. 1: no parallel phase, the exact serial greedy order. R ≥ 2: on a
  /// mesh of at least `parallel_min_vertices` live vertices, the mesh is first cut into R compact
  /// regions (ranges of a breadth-first order) and the threads run the greedy order inside the
  /// regions, never removing a vertex with a neighbour in another region nor flipping an edge across
  /// two, in rounds with a common cost threshold (growing 1.4x per round, so the regions advance in
  /// nearly the global cost order), down to an intermediate size that leaves max(target, 1/32 of
  /// the removals), plus the vertices the regions cannot remove (boundary, locked, along the last
  /// seams), to a final serial greedy pass over the whole mesh (which first restores the Delaunay
  /// property along the region seams). With 4+ regions that phase runs in three stages: the
  /// regions, then pairs of neighbouring regions across every other seam, then across the others,
  /// so the seams' vertices (which a region never removes) are coarsened in parallel too. In that
  /// phase `progress` is called once per round.
  /// The result depends on the region count and the mesh, never on `threads` (bit-identical for 1,
  /// 2, … threads, so on any machine), and differs from the serial order's within its noise
  /// (docs/measurements.md, "The parallel phase by default").
  int regions = 0;
  /// Threads of the parallel phase (0, the default: one per hardware thread the process may run on,
  /// at most OMP_NUM_THREADS when that is set; k ≥ 1: at most k). They change how long coarsening
  /// takes, never its result.
  int threads = 0;
  Index parallel_min_vertices = 20000;
};

/// The region count `regions = 0` stands for. Fixed, so that a result does not depend on the machine
/// that made it; 16 keeps four regions per thread (a thread that finishes early takes another) on up
/// to four threads. Give more regions for more threads.
inline constexpr int kDefaultCoarseningRegions = 16;

enum class StopReason { TargetReached, ErrorThreshold, NothingRemovable, Cancelled };
const char* to_string(StopReason reason);

struct CoarsenResult {
  StopReason stop_reason = StopReason::NothingRemovable;
  Index input_vertices = 0;
  Index output_vertices = 0;
  Index output_faces = 0;
  Index removed = 0;
  Index failed_removals = 0;   ///< attempts where the vertex turned out not removable
  /// Failed attempts by RemovalStatus (index = static_cast<int>(status)).
  std::array<Index, 7> failures_by_status{};
  double last_cost = 0;        ///< cost of the last removal
  double max_cost = 0;         ///< largest cost among the removals made
  double next_cost = 0;        ///< cost of the cheapest remaining removal (inf if none, NaN if cancelled in the parallel phase)
  Index parallel_removed = 0;  ///< removals made by the parallel phase (0 when serial)
  Index cost_evaluations = 0;  ///< removal costs computed (every vertex's first cost included)
  double seconds = 0;          ///< wall time of coarsen()
  /// Where that time went: the error metric's per-vertex records (with threads, beside the partition
  /// into regions), the parallel phase (each region's first costs and removals, the seams' Delaunay
  /// flips; 0 when serial) and the serial greedy phase (with its own first costs of the vertices
  /// left). The setup and the serial phase are what more threads cannot shorten.
  double setup_seconds = 0, parallel_seconds = 0, serial_seconds = 0;
  /// Adds the counts of a part run (removals, failures by status) and keeps the larger max_cost:
  /// how runs in stages (parallel regions, hierarchy passes) sum up.
  void add_counts(const CoarsenResult& part);
};

/// Coarsens T in place. Preconditions: T was built from a mesh (all input vertices alive or
/// tracked) and has no vertex inserted by refinement (std::invalid_argument otherwise: coarsen its
/// compacted() copy); locked vertex indices are in range. Resumes T's frames if they were stopped
/// (IntrinsicTriangulation::maintain_frames). Deterministic: the same input and options give
/// bit-identical output.
CoarsenResult coarsen(IntrinsicTriangulation& T, const CoarsenOptions& options);

/// The regions coarsen() cuts a mesh of at least `options.parallel_min_vertices` live vertices into
/// for its parallel phase (`regions`, or kDefaultCoarseningRegions for 0; 1: serial). Its result
/// depends on this count, never on the thread count.
int coarsening_regions(const CoarsenOptions& options);


}  // namespace ice
