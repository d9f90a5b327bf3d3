#pragma once
/// \file error_metric.h
/// The intrinsic curvature error of ICE (Liu et al. 2023, §4): the cost of removing a vertex of an
/// intrinsic triangulation, and the bookkeeping of where removed curvature went.
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
/// A removal is prepared into a RemovalPlan that the caller owns (one per thread), while the vertex's
/// star still exists, and written once IntrinsicTriangulation::remove_vertex succeeded: the metric
/// itself holds no per-thread or pending state, so an exception between the two leaves nothing
/// behind but a plan the next prepare_removal overwrites.
#include <array>
#include <complex>
#include <limits>
#include <vector>

#include "ice/intrinsic_triangulation.h"
#include "ice/large_array.h"
#include "ice/vertex_star.h"

namespace ice {

/// The error state (masses and centres per vertex and channel) and the cost of removing a vertex.
/// ice::coarsen keeps one. Threads may use it concurrently for vertices whose stars and neighbours'
/// records are disjoint, each with its own RemovalPlan.
class IntrinsicErrorMetric {
 public:
  static constexpr int kChannels = 3;  // K+, K-, area

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

 public:
  /// A prepared removal (the neighbours' records after it) and the scratch space of cost
  /// evaluations. Owned by the caller, one per thread; reusing one keeps its allocations.
  class RemovalPlan {
   public:
    /// The vertex whose removal is prepared, or kInvalid.
    Index vertex() const { return vertex_; }

   private:
    friend class IntrinsicErrorMetric;
    std::vector<Neighbour> neighbours_;
    VertexStar star_;
    std::vector<PendingRecord> pending_;
    Index vertex_ = kInvalid;
  };

  /// Initial state of every vertex of T (see the file comment). With `normalize_curvature` the
  /// curvature masses are divided by the total absolute curvature Σ|K| (when positive), so that
  /// both channels sum to fractions of 1 and w is the area channel's share of the total mass on any
  /// mesh (without it, Σ|K| — from under 4π to over 100·4π on real meshes — sets the balance).
  /// Precondition: T.frames_maintained() (the transports read the angular coordinates); throws
  /// std::invalid_argument otherwise. T (and any triangulation passed to the methods below) must keep
  /// its frames for as long as the metric is used: only the constructor checks.
  IntrinsicErrorMetric(const IntrinsicTriangulation& T, double area_weight, bool normalize_curvature = false);
  /// Cost of removing v (a dry run that changes nothing but `scratch`); +inf when v cannot be
  /// flattened. The flattening scale it found is written to *log_scale (NaN when none).
  double removal_cost(const IntrinsicTriangulation& T, Index v, RemovalPlan& scratch, double* log_scale = nullptr) const;
  /// The same with scratch space of its own (allocates: for occasional queries).
  double removal_cost(const IntrinsicTriangulation& T, Index v, double* log_scale = nullptr) const;
  /// Computes the neighbours' records after v's removal into `plan`; false when v cannot be flattened
  /// (the plan is then empty). Call before T.remove_vertex(v), while v's star still exists.
  /// `log_scale` may pass the flattening scale of an earlier removal_cost on the same star (NaN:
  /// compute it).
  bool prepare_removal(const IntrinsicTriangulation& T, Index v, RemovalPlan& plan,
                       double log_scale = std::numeric_limits<double>::quiet_NaN()) const;
  /// Writes a prepared plan's records (call once T.remove_vertex(plan.vertex()) succeeded) and
  /// empties the plan. An empty plan changes nothing.
  void apply_removal(RemovalPlan& plan);
  double mass(Index v, int channel) const { return records_[v].mass[channel]; }
  /// Requests v's record from memory (the coarsener calls it during its two-ring prefetch walk).
  void prefetch(Index v) const {
    __builtin_prefetch(&records_[v]);
    __builtin_prefetch(reinterpret_cast<const char*>(&records_[v]) + sizeof(Record) - 1);
  }
  std::complex<double> centre(Index v, int channel) const { return records_[v].centre[channel]; }
  /// Σ of each channel's masses over live vertices (conserved by removals).
  std::array<double, kChannels> total_mass(const IntrinsicTriangulation& T) const;

 private:
  // Neighbours of v with their split weights; false when v cannot be flattened.
  bool split_weights(const IntrinsicTriangulation& T, Index v, RemovalPlan& scratch, double* log_scale) const;
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
};

}  // namespace ice
