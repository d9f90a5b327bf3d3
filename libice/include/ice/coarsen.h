#pragma once
/// \file coarsen.h
/// ICE coarsening (Liu et al., "Surface Simplification using Intrinsic Error Metrics", SIGGRAPH
/// 2023): greedy removal of vertices of an intrinsic triangulation, cheapest first, where the cost
/// of removing a vertex measures how far its Gaussian curvature (and optionally its area) must be
/// transported to the neighbours that absorb it.
///
/// Error metric. Every vertex carries three channels c ∈ {K⁺, K⁻, area}: a mass m ≥ 0 and a tangent
/// vector x (in the vertex's angular-coordinate frame) from the vertex to the centre of the mass it
/// has absorbed. Initially m(K⁺) = (1−w)·max(K,0), m(K⁻) = (1−w)·max(−K,0), m(area) = w·A_v/A_total
/// (A_v: one third of the incident face areas), x = 0; w is `area_weight` (0 = curvature only).
/// Removing v splits its masses among its neighbours j with weights proportional to how much
/// flattening v changes their curvature (|ΔK_j|; uniform when all are zero), transports x_v into
/// j's frame (rotation ρ = A(j→v) − A(v→j) + π), offsets it by the edge vector from j to v, and
/// merges the centres of mass. The cost is Σ_j Σ_c m_j'·|x_j'| after the merge.
///
/// Removal itself (IntrinsicTriangulation::remove_vertex) flattens v, flips it down to degree 3 (2
/// on the boundary), replaces its star by one triangle, and the driver restores the intrinsic
/// Delaunay property around it. Every input vertex stays tracked (the fine-to-coarse map).
#include <array>
#include <complex>
#include <functional>
#include <limits>
#include <vector>

#include "ice/intrinsic_triangulation.h"
#include "ice/vertex_star.h"

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
  /// Vertices never removed.
  std::vector<Index> locked_vertices;
  /// Whether boundary vertices may be removed (boundary loops always keep at least two edges).
  bool remove_boundary = true;
  /// Called every `progress_interval` removals; return false to cancel. Always called on the
  /// calling thread.
  std::function<bool(const CoarsenProgress&)> progress;
  Index progress_interval = 1000;
  /// Threads (1: serial, the exact greedy order; 0: one per hardware thread). With k > 1 and at
  /// least `parallel_min_vertices` live vertices, the mesh is first cut into 4k compact regions
  /// (ranges of a breadth-first order) and the threads run the greedy order inside the regions,
  /// never removing a vertex with a neighbour in another region nor flipping an edge across two,
  /// in rounds with a common cost threshold (growing 1.4x per round, so the regions advance in
  /// nearly the global cost order), down to an intermediate size that leaves max(target, 1/32 of
  /// the removals) to a final serial greedy pass over the whole mesh (which first restores the
  /// Delaunay property along the region seams). In that phase `progress` is called once per round.
  /// The result is deterministic for a given thread count, but differs from the serial one.
  int threads = 1;
  Index parallel_min_vertices = 20000;
};

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
  double seconds = 0;          ///< wall time of coarsen()
  /// Adds the counts of a part run (removals, failures by status) and keeps the larger max_cost:
  /// how runs in stages (parallel regions, hierarchy passes) sum up.
  void add_counts(const CoarsenResult& part);
};

/// Coarsens T in place. Preconditions: T was built from a mesh (all input vertices alive or
/// tracked); locked vertex indices are in range. Deterministic: the same input and options give
/// bit-identical output.
CoarsenResult coarsen(IntrinsicTriangulation& T, const CoarsenOptions& options);

/// The intrinsic curvature error state (masses and centres per vertex and channel) and the cost of
/// removing a vertex. coarsen() keeps one; it is exposed for tests and tools. Threads may call it
/// concurrently for vertices whose stars and neighbours' records are disjoint. The prepared removal
/// is kept per thread (not per object): apply it on the thread that prepared it, before that thread
/// prepares another one with any metric.
class IntrinsicErrorMetric {
 public:
  static constexpr int kChannels = 3;  // K+, K-, area
  /// Initial state of every vertex of T (see the file comment).
  IntrinsicErrorMetric(const IntrinsicTriangulation& T, double area_weight);
  /// Cost of removing v (a dry run that changes nothing); +inf when v cannot be flattened. The
  /// flattening scale it found is written to *log_scale (NaN when none).
  double removal_cost(const IntrinsicTriangulation& T, Index v, double* log_scale = nullptr) const;
  /// Computes the neighbours' records after v's removal and keeps them pending; returns false when v
  /// cannot be flattened. Call before T.remove_vertex(v), while v's star still exists. `log_scale`
  /// may pass the flattening scale of an earlier removal_cost on the same star (NaN: compute it).
  bool prepare_removal(const IntrinsicTriangulation& T, Index v,
                       double log_scale = std::numeric_limits<double>::quiet_NaN());
  /// Writes the pending records (call once T.remove_vertex(v) succeeded).
  void apply_prepared_removal();
  double mass(Index v, int channel) const { return records_[v].mass[channel]; }
  /// Requests v's record from memory (see IntrinsicTriangulation::prefetch_two_ring).
  void prefetch(Index v) const {
    __builtin_prefetch(&records_[v]);
    __builtin_prefetch(reinterpret_cast<const char*>(&records_[v]) + sizeof(Record) - 1);
  }
  std::complex<double> centre(Index v, int channel) const { return records_[v].centre[channel]; }
  /// Σ of each channel's masses over live vertices (conserved by removals).
  std::array<double, kChannels> total_mass(const IntrinsicTriangulation& T) const;

 private:
  struct Neighbour {
    Index vertex;
    Index halfedge;  // v -> vertex
    double weight;
  };
  struct PendingRecord {
    Index vertex;
    std::array<double, kChannels> mass;
    std::array<std::complex<double>, kChannels> moment;  // merged mass × merged centre
  };
  // Neighbours of v with their split weights; false when v cannot be flattened.
  bool split_weights(const IntrinsicTriangulation& T, Index v, std::vector<Neighbour>& out, double* log_scale) const;
  // Neighbour n's record after absorbing its share of v: calls sink(channel, mass, moment re, im)
  // for each of the first `Channels` channels (an empty channel reports zeros; the area channel,
  // the last, is skipped when the area weight is 0: it is empty everywhere, forever).
  template <int Channels, class Sink>
  void merge_channels(const IntrinsicTriangulation& T, Index v, const Neighbour& n, Sink&& sink) const;
  // One record per vertex (all channels together: a cost evaluation reads them all).
  struct Record {
    std::array<double, kChannels> mass{};
    std::array<std::complex<double>, kChannels> centre{};
  };
  LargeArray<Record> records_;  // huge pages: read in removal order (ice/large_array.h)
  bool area_channel_ = false;   // area weight > 0
  // Scratch space and the prepared removal, one per thread: coarsen's parallel mode runs threads
  // on disjoint parts of the mesh, which read and write disjoint records.
  struct Workspace {
    std::vector<Neighbour> neighbours;
    VertexStar star;
    std::vector<PendingRecord> pending;
    Index pending_vertex = kInvalid;
  };
  static Workspace& workspace();
};

}  // namespace ice
