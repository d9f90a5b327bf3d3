#pragma once
/// \file removal_queue.h
/// The coarsener's removal candidates (private to libice; tests include it directly): per-vertex
/// driver state and a priority queue over it that always yields the exact cheapest candidate.

#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <vector>

#include "ice/intrinsic_triangulation.h"
#include "ice/large_array.h"

namespace ice::detail {

// Per-vertex driver state in one 32-byte record (one cache line fetch per vertex touched, which is
// what bounds the speed once the mesh outgrows the caches), the removal queue's slot included.
// log_scale is the flattening scale found by the vertex's latest cost evaluation (its star has not
// changed since: every change re-evaluates it), so the removal re-uses it instead of running
// Newton again.
struct alignas(32) VertexState {
  double cost = 0;      // current removal cost (>= key)
  double key = 0;       // the vertex's key in the queue's heap (a copy; valid while position >= 0)
  double log_scale = std::numeric_limits<double>::quiet_NaN();
  Index position = kInvalid;  // index in the queue's heap, RemovalQueue::kCold, or kInvalid (not queued)
  std::uint8_t locked = 0, failures = 0;
  std::uint16_t seen = 0;  // dedupes the vertices re-evaluated after one removal (GreedyLoop's epoch)
};
static_assert(sizeof(VertexState) == 32, "one record per half cache line");

// The removal candidates, in two tiers split at a cost threshold T: the "hot" candidates (cost < T)
// in an indexed 4-ary min-heap on (cost, vertex) with the slots in the vertices' VertexState
// records, the "cold" ones (cost >= T) unsorted in buckets by cost. Every candidate is in exactly
// one tier (a queue only ever holds the vertices of its own scope, so the queues of the parallel
// regions share one state array).
// Why two tiers: a heap over every vertex outgrows the caches, and every pop and every stale top
// then sifts through its deep levels at a cache miss each. The hot heap stays small (its deepest
// levels are where the risen costs sink, and those now leave it instead); the cold tier is touched
// once per vertex and bucket: appended to, and emptied into the heap when the heap runs dry (then T
// rises past the cheapest non-empty bucket).
// A cost that rises is only recorded (in the vertex's record, not in the heap): costs mostly rise as
// neighbours absorb mass, most such vertices are far from the top, and moving them would touch the
// heap at random places; the record's copy of the key tells without reading the heap. The heap keys
// are therefore lower bounds; top() raises a stale top to its cost and sifts it down (or moves it to
// the cold tier once it reaches T) until the top's key is its cost. That cost is then the exact
// minimum, ties included: below T, so below every cold cost. A cost that falls is moved up at once.
class RemovalQueue {
 public:
  struct Entry {
    double cost;
    Index vertex;
  };
  explicit RemovalQueue(LargeArray<VertexState>& state) : state_(state) {}
  bool empty() const { return heap_.empty() && cold_count_ == 0; }
  /// The cheapest entry (ties: the lowest vertex index). Precondition: !empty().
  const Entry& top() {
    while (true) {
      if (heap_.empty()) refill();
      Entry& front = heap_.front();
      VertexState& record = state_[front.vertex];
      if (record.cost == front.cost) return front;
      if (bucket(record.cost) >= hot_limit_) {  // risen out of the hot tier
        const Index v = front.vertex;
        remove_hot(0);
        make_cold(v);
      } else {
        front.cost = record.key = record.cost;  // a risen cost: the key was a lower bound
        sift_down(0);
      }
    }
  }
  /// Inserts v or changes its cost. Precondition: cost >= 0 and finite.
  void set(Index v, double cost) {
    VertexState& record = state_[v];
    const double old_cost = record.cost;
    record.cost = cost;
    const Index position = record.position;
    if (position >= 0) {
      if (cost < record.key) {
        record.key = heap_[position].cost = cost;
        sift_up(position);
      }
      return;
    }
    const int b = bucket(cost);
    if (position == kCold) {
      if (b < hot_limit_) {
        --cold_count_;
        push_hot(v, cost);
      } else if (b != bucket(old_cost)) {
        buckets_[b].push_back(v);  // the entry in the old bucket is now stale (see refill)
      }
    } else if (b < hot_limit_) {
      push_hot(v, cost);
    } else {
      make_cold(v);
    }
  }
  /// Removes v if present.
  void erase(Index v) {
    VertexState& record = state_[v];
    if (record.position == kCold) {
      record.position = kInvalid;
      --cold_count_;
    } else if (record.position != kInvalid) {
      remove_hot(record.position);
    }
  }

  static constexpr Index kCold = -2;  ///< VertexState::position of a cold candidate

 private:
  // Buckets of cost: the top 16 bits of a non-negative double (exponent and 4 mantissa bits), so
  // consecutive buckets differ by about 4 % in cost and bucket order is cost order.
  static int bucket(double cost) {
    std::uint64_t bits;
    std::memcpy(&bits, &cost, sizeof bits);
    return static_cast<int>(bits >> 48);
  }
  void make_cold(Index v) {
    VertexState& record = state_[v];
    record.position = kCold;
    ++cold_count_;
    buckets_[bucket(record.cost)].push_back(v);
  }
  void push_hot(Index v, double cost) {
    VertexState& record = state_[v];
    record.key = cost;
    heap_.push_back({cost, v});
    record.position = static_cast<Index>(heap_.size() - 1);
    sift_up(heap_.size() - 1);
  }
  void remove_hot(Index i) {
    state_[heap_[i].vertex].position = kInvalid;
    const Entry last = heap_.back();
    heap_.pop_back();
    if (static_cast<std::size_t>(i) == heap_.size()) return;
    place(i, last);
    sift_up(i);
    sift_down(state_[last.vertex].position);
  }
  // Moves the cheapest buckets into the (empty) heap, at least kRefill candidates unless fewer
  // are left, and raises T past them. A bucket's entries may be stale (the vertex left the cold
  // tier, or moved to another bucket while in it): only entries whose vertex is cold and in that
  // bucket now count. Each cold vertex has an entry in its current bucket, so none is missed.
  void refill() {
    constexpr std::size_t kRefill = 4096;
    while (heap_.size() < kRefill && cold_count_ > 0) {
      const auto cheapest = buckets_.begin();
      hot_limit_ = cheapest->first + 1;
      for (Index v : cheapest->second) {
        VertexState& record = state_[v];
        if (record.position != kCold || bucket(record.cost) != cheapest->first) continue;
        --cold_count_;
        record.key = record.cost;
        record.position = static_cast<Index>(heap_.size());
        heap_.push_back({record.cost, v});
      }
      buckets_.erase(cheapest);
    }
    if (heap_.size() > 1)  // Floyd's heap construction: sift down every parent, last first
      for (std::size_t i = (heap_.size() - 2) / 4 + 1; i-- > 0;) sift_down(i);
  }

  // Branch-free (bitwise, not short-circuit): heap comparisons are unpredictable.
  static bool before(const Entry& a, const Entry& b) {
    return (a.cost < b.cost) | ((a.cost == b.cost) & (a.vertex < b.vertex));
  }
  void place(std::size_t i, const Entry& e) {
    heap_[i] = e;
    state_[e.vertex].position = static_cast<Index>(i);
  }
  void sift_up(std::size_t i) {
    const Entry e = heap_[i];
    while (i > 0) {
      const std::size_t parent = (i - 1) / 4;
      if (!before(e, heap_[parent])) break;
      place(i, heap_[parent]);
      i = parent;
    }
    place(i, e);
  }
  void sift_down(std::size_t i) {
    const Entry e = heap_[i];
    const std::size_t size = heap_.size();
    while (true) {
      const std::size_t first = 4 * i + 1;
      if (first >= size) break;
      std::size_t best = first;
      if (first + 4 <= size) {  // a full node: a fixed tournament (conditional moves, no loop exit)
        const std::size_t left = before(heap_[first + 1], heap_[first]) ? first + 1 : first;
        const std::size_t right = before(heap_[first + 3], heap_[first + 2]) ? first + 3 : first + 2;
        best = before(heap_[right], heap_[left]) ? right : left;
      } else {
        for (std::size_t c = first + 1; c < size; ++c) best = before(heap_[c], heap_[best]) ? c : best;
      }
      if (!before(heap_[best], e)) break;
      place(i, heap_[best]);
      i = best;
    }
    place(i, e);
  }
  LargeArray<VertexState>& state_;
  LargeArray<Entry> heap_;                       // the hot tier
  std::map<int, std::vector<Index>> buckets_;    // the cold tier, by bucket (stale entries included)
  Index cold_count_ = 0;                         // vertices in the cold tier
  int hot_limit_ = 0;                            // T: costs of buckets below it are hot
};

}  // namespace ice::detail
