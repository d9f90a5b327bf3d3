#pragma once
// Internal to libice (not installed): the coarsener's memory prefetching over a vertex's two-ring.
// It reads IntrinsicTriangulation's private arrays (a friend), so it stays beside the code that uses
// it instead of in the triangulation's public header.
#include <cstdint>

#include "ice/intrinsic_triangulation.h"

namespace ice {

/// A walk over the star of a vertex v and over its neighbours' stars that requests their records
/// from memory, in rounds: each round reads only records requested by earlier rounds, so a round
/// run a while after the previous one never waits for memory. Run back to back (prefetch_two_ring below)
/// it still overlaps its misses: every fan is walked both ways at once and the neighbours' fans in
/// lockstep, about seven memory latencies in a row instead of one per half-edge. Spread out over
/// other work it costs no waiting at all: the coarsener walks the next removal's two-ring during
/// the current removal.
/// The triangulation may change between rounds (removals, flips): the walk then requests useless
/// records, but never reads outside the arrays. Reads only; no result depends on it.
class TwoRingPrefetch {
 public:
  /// Starts a walk around v (a live vertex) and requests v's record.
  void start(const IntrinsicTriangulation& T, Index v) {
    T_ = &T;
    vertex_ = v;
    spokes_ = 0;
    step_ = 0;
    phase_ = Phase::Vertex;
    __builtin_prefetch(&T.vertices_[v]);
  }
  /// The vertex of the latest walk (finished or not; kInvalid before the first).
  Index vertex() const { return vertex_; }
  /// One round; false once the walk is complete. neighbour(w) / second(w) as in prefetch_two_ring.
  template <class Neighbour, class Second>
  bool advance(Neighbour&& neighbour, Second&& second) {
    const IntrinsicTriangulation& T = *T_;
    switch (phase_) {
      case Phase::Vertex: {
        const Index h = T.vhalfedge(vertex_);
        if (h < 0) return finish();
        forward_ = backward_ = h;
        request_edge(h);
        phase_ = Phase::FirstSpoke;
        return true;
      }
      case Phase::FirstSpoke:
        add_spoke(forward_, neighbour);
        next_forward_ = next_ccw(forward_), next_backward_ = next_cw(backward_);
        request_edge(next_forward_), request_edge(next_backward_);
        phase_ = Phase::Fan;
        return true;
      case Phase::Fan: {
        // v's fan, both ways from vertex_halfedge until the two walks meet (or reach the boundary).
        const Index a = next_forward_, b = next_backward_;
        const bool a_new = a != forward_ && a != backward_ && T.hface(a) != kInvalid;
        if (a_new) add_spoke(forward_ = a, neighbour);
        const bool b_new = b != backward_ && b != forward_ && T.hface(b) != kInvalid;
        if (b_new) add_spoke(backward_ = b, neighbour);
        if ((!a_new && !b_new) || ++step_ > 32) {
          phase_ = Phase::Neighbours;
          step_ = 0;
        } else {
          next_forward_ = next_ccw(forward_), next_backward_ = next_cw(backward_);
          request_edge(next_forward_), request_edge(next_backward_);
        }
        return true;
      }
      case Phase::Neighbours:
        // Each neighbour's fan, both ways from its edge to v: a cursor's record was requested in
        // the previous round; it is read (the edge across requested, the head visited) and the
        // cursor moves on. Three moves each way cover a neighbour of degree up to 7 (the first is
        // an edge of v's star).
        for (int k = 0; k < spokes_; ++k) {
          second(touch(ccw_[k]));
          second(touch(cw_[k]));
          if (step_ < 3) {
            request_edge(ccw_[k] = next_ccw(ccw_[k]));
            request_edge(cw_[k] = next_cw(cw_[k]));
          }
        }
        if (++step_ > 3) return finish();
        return true;
      case Phase::Done:
        return false;
    }
    return false;
  }

 private:
  enum class Phase : std::uint8_t { Vertex, FirstSpoke, Fan, Neighbours, Done };
  static constexpr int kMaxSpokes = 16;
  bool finish() {
    phase_ = Phase::Done;
    return false;
  }
  // The outgoing half-edge after h counter-clockwise is prev(h)^1, clockwise next(h^1); an
  // exterior or dead half-edge (a fan's end at the boundary, or a stale cursor) has neither, and
  // the walk stays put.
  Index next_ccw(Index h) const { return T_->hface(h) != kInvalid ? T_->hprev(h) ^ 1 : h; }
  Index next_cw(Index h) const { return T_->hface(h ^ 1) != kInvalid ? T_->hnext(h ^ 1) : h; }
  void request_edge(Index h) const {  // a record may straddle two cache lines
    const char* record = reinterpret_cast<const char*>(&T_->edges_[h >> 1]);
    __builtin_prefetch(record);
    __builtin_prefetch(record + sizeof(IntrinsicTriangulation::EdgeRecord) - 1);
  }
  // h's record has been requested: request the edge across its face and return its head.
  Index touch(Index h) const {
    const bool interior = T_->hface(h) != kInvalid;
    request_edge(interior ? T_->hnext(h) : h);
    const Index w = T_->htail(h ^ 1);
#if defined(__GNUC__)
    // The walk's loads feed nothing but prefetches, which the optimiser may drop as dead code.
    __asm__ volatile("" : : "r"(w));
#endif
    return w < 0 ? 0 : w;  // (a dead edge has no ends)
  }
  template <class Neighbour>
  void add_spoke(Index h, Neighbour& neighbour) {  // h: v -> a neighbour; two walks start at h^1
    const Index w = touch(h);
    const Index f = T_->hface(h);
    __builtin_prefetch(&T_->faces_[f < 0 ? 0 : f]);  // the faces of v's star
    __builtin_prefetch(&T_->vertices_[w]);
    neighbour(w);
    ccw_[spokes_] = cw_[spokes_] = h ^ 1;
    spokes_ += spokes_ < kMaxSpokes - 1;
  }
  const IntrinsicTriangulation* T_ = nullptr;
  Index vertex_ = kInvalid;
  Phase phase_ = Phase::Done;
  int spokes_ = 0, step_ = 0;
  Index forward_ = kInvalid, backward_ = kInvalid, next_forward_ = kInvalid, next_backward_ = kInvalid;
  Index ccw_[kMaxSpokes], cw_[kMaxSpokes];
};

/// Requests the records of v's star and of its neighbours' stars from memory ahead of a local
/// operation there (a removal reads and writes all of them): runs a TwoRingPrefetch to the end.
/// Calls neighbour(w) for every neighbour of v and second(w) for every vertex met around them
/// (with repeats), for the caller's own per-vertex data. Reads only: no result depends on it.
template <class Neighbour, class Second>
void prefetch_two_ring(const IntrinsicTriangulation& T, Index v, Neighbour&& neighbour, Second&& second) {
  TwoRingPrefetch walk;
  walk.start(T, v);
  while (walk.advance(neighbour, second)) {
  }
}

}  // namespace ice
