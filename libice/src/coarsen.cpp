#include "ice/coarsen.h"

#include "ice/vertex_star.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace ice {
namespace {
constexpr double kPi = 3.14159265358979323846;

// e^{iθ} for the transport of the error metric, by quadrant reduction and Taylor polynomials on
// [−π/4, π/4] (truncation below 1e-11, far below what the metric's flattening tolerance of 1e-7
// resolves): several times cheaper than sincos, and deterministic.
inline std::complex<double> unit_complex(double theta) {
  // Round to the nearest quarter turn by truncation (nearbyint is a library call without SSE4.1).
  const double turns = theta * (2 / kPi);
  const double quarter_turns = static_cast<double>(static_cast<long long>(turns + (turns >= 0 ? 0.5 : -0.5)));
  const double r = theta - quarter_turns * (kPi / 2);
  const double r2 = r * r;
  const double sine =
      r * (1 + r2 * (-1.0 / 6 + r2 * (1.0 / 120 + r2 * (-1.0 / 5040 + r2 * (1.0 / 362880 + r2 * (-1.0 / 39916800))))));
  const double cosine =
      1 + r2 * (-0.5 + r2 * (1.0 / 24 + r2 * (-1.0 / 720 + r2 * (1.0 / 40320 + r2 * (-1.0 / 3628800 + r2 * (1.0 / 479001600.0))))));
  switch (static_cast<long long>(quarter_turns) & 3) {
    case 0: return {cosine, sine};
    case 1: return {-sine, cosine};
    case 2: return {-cosine, -sine};
    default: return {sine, -cosine};
  }
}
}

const char* to_string(StopReason reason) {
  switch (reason) {
    case StopReason::TargetReached: return "target_reached";
    case StopReason::ErrorThreshold: return "error_threshold";
    case StopReason::NothingRemovable: return "nothing_removable";
    case StopReason::Cancelled: return "cancelled";
  }
  return "unknown";
}

// ------------------------------------------------------------------------------------------------
// Error metric

IntrinsicErrorMetric::IntrinsicErrorMetric(const IntrinsicTriangulation& T, double area_weight) {
  const Index n = T.num_input_vertices();
  records_.assign(n, Record{});
  std::vector<double> vertex_area(n, 0.0);
  double total_area = 0;
  for (Index f = 0; f < T.num_face_slots(); ++f) {
    if (!T.face_alive(f)) continue;
    const double third = T.face_area(f) / 3;
    Index h = T.halfedge(f);
    for (int k = 0; k < 3; ++k, h = T.next(h)) vertex_area[T.tail(h)] += third;
    total_area += 3 * third;
  }
  for (Index v = 0; v < n; ++v) {
    if (!T.vertex_alive(v)) continue;
    const double K = T.curvature(v);
    records_[v].mass = {(1 - area_weight) * std::max(K, 0.0), (1 - area_weight) * std::max(-K, 0.0),
                        area_weight * vertex_area[v] / total_area};
  }
}

std::array<double, IntrinsicErrorMetric::kChannels> IntrinsicErrorMetric::total_mass(
    const IntrinsicTriangulation& T) const {
  std::array<double, kChannels> total{0, 0, 0};
  for (Index v = 0; v < T.num_input_vertices(); ++v)
    if (T.vertex_alive(v))
      for (int c = 0; c < kChannels; ++c) total[c] += mass(v, c);
  return total;
}

bool IntrinsicErrorMetric::split_weights(const IntrinsicTriangulation& T, Index v, std::vector<Neighbour>& out,
                                         double* log_scale) const {
  out.clear();
  // One walk reads the star; Newton and the curvature changes below work on that snapshot. The
  // split weights only rank and share masses: a 1e-7 relative angle-sum tolerance is plenty (the
  // weights move by about as much; the committed flattening itself is exact to 1e-13). A scale
  // already computed for the same star (*log_scale finite on entry) is reused.
  VertexStar& star = star_;
  read_star(T, v, star);
  double u = log_scale ? *log_scale : std::numeric_limits<double>::quiet_NaN();
  if (std::isfinite(u)) {
    star_areas(star, u);
  } else {
    const FlattenResult flat = flatten_star(star, 1e-7);
    if (!flat.success) return false;
    u = flat.log_scale;
    if (log_scale) *log_scale = u;
  }
  const double half_scale = std::exp(0.5 * u);
  const auto add = [&](Index vertex, Index halfedge, double delta_K) {
    if (vertex == v) return;  // a self-edge: v absorbs nothing from itself
    for (Neighbour& n : out)
      if (n.vertex == vertex) {
        n.weight += delta_K;
        return;
      }
    out.push_back({vertex, halfedge, delta_K});
  };
  for (const StarCorner& corner : star.corners) {
    // Curvature is 2π − Θ, so a corner shrinking by δ raises its vertex's curvature by δ.
    const CornerAngleChange change = corner_angle_change(corner, half_scale);
    add(corner.out_vertex, corner.halfedge, change.at_out);
    add(corner.in_vertex, corner.in_halfedge ^ 1, change.at_in);
  }
  double total = 0;
  for (Neighbour& n : out) total += (n.weight = std::abs(n.weight));
  if (!(total > 0) || !std::isfinite(total)) {
    for (Neighbour& n : out) n.weight = 1.0 / out.size();
  } else {
    for (Neighbour& n : out) n.weight /= total;
  }
  return !out.empty();
}

template <class Sink>
void IntrinsicErrorMetric::merge_channels(const IntrinsicTriangulation& T, Index v, const Neighbour& n, Sink&& sink) const {
  // Complex arithmetic is written out: std::complex's operator* guards against NaN/inf operands,
  // which cannot occur here, at several times the cost.
  const Record& from = records_[v];
  const Record& to = records_[n.vertex];
  const Index h = n.halfedge;  // v -> j
  // Transport from v's frame to j's: the vector from j to v in j's frame (needed whenever mass
  // moves) and the rotation of v's centre (needed only when that centre is not v itself, i.e. v
  // has absorbed mass; most vertices have not, early on).
  double rotation_re = 0, rotation_im = 0, edge_re = 0, edge_im = 0;
  bool have_edge = false, have_rotation = false;
  for (int c = 0; c < kChannels; ++c) {
    const double share = n.weight * from.mass[c];
    const double m_j = to.mass[c];
    if (share == 0 && m_j == 0) continue;  // an empty channel (e.g. area with area_weight 0)
    double re = m_j * to.centre[c].real(), im = m_j * to.centre[c].imag();
    if (share != 0) {  // else nothing moves in this channel: j keeps its own moment
      if (!have_edge) {
        const std::complex<double> direction = unit_complex(T.angular_coordinate(h ^ 1));
        edge_re = T.length(h) * direction.real(), edge_im = T.length(h) * direction.imag();
        have_edge = true;
      }
      double x = 0, y = 0;
      if (from.centre[c].real() != 0 || from.centre[c].imag() != 0) {
        if (!have_rotation) {
          const std::complex<double> rotation =
              unit_complex(T.angular_coordinate(h ^ 1) - T.angular_coordinate(h) + kPi);
          rotation_re = rotation.real(), rotation_im = rotation.imag();
          have_rotation = true;
        }
        x = rotation_re * from.centre[c].real() - rotation_im * from.centre[c].imag();
        y = rotation_re * from.centre[c].imag() + rotation_im * from.centre[c].real();
      }
      re += share * (x + edge_re);
      im += share * (y + edge_im);
    }
    sink(c, m_j + share, re, im);
  }
}

double IntrinsicErrorMetric::removal_cost(const IntrinsicTriangulation& T, Index v, double* log_scale) const {
  if (log_scale) *log_scale = std::numeric_limits<double>::quiet_NaN();
  if (!split_weights(T, v, scratch_, log_scale)) return std::numeric_limits<double>::infinity();
  // The neighbours' records are usually not cached on large meshes: request them all at once.
  for (const Neighbour& n : scratch_) __builtin_prefetch(&records_[n.vertex]);
  double cost = 0;
  for (const Neighbour& n : scratch_)  // m'·|x'| = |m'·x'|
    merge_channels(T, v, n, [&](int, double, double re, double im) { cost += std::sqrt(re * re + im * im); });
  return cost;
}

bool IntrinsicErrorMetric::prepare_removal(const IntrinsicTriangulation& T, Index v, double log_scale) {
  pending_.clear();
  pending_vertex_ = kInvalid;
  if (!split_weights(T, v, scratch_, &log_scale)) return false;
  for (const Neighbour& n : scratch_) {
    PendingRecord record{n.vertex, {}, {}};
    merge_channels(T, v, n, [&](int c, double mass, double re, double im) {
      record.mass[c] = mass;
      record.moment[c] = {re, im};
    });
    pending_.push_back(record);
  }
  pending_vertex_ = v;
  return true;
}

void IntrinsicErrorMetric::apply_prepared_removal() {
  for (const PendingRecord& r : pending_) {
    Record& record = records_[r.vertex];
    record.mass = r.mass;
    for (int c = 0; c < kChannels; ++c)
      record.centre[c] = r.mass[c] > 0 ? r.moment[c] / r.mass[c] : std::complex<double>(0, 0);
  }
  if (pending_vertex_ != kInvalid) records_[pending_vertex_] = Record{};
  pending_.clear();
  pending_vertex_ = kInvalid;
}

// ------------------------------------------------------------------------------------------------
// Greedy driver

namespace {

// The removal candidates: an indexed 4-ary min-heap on (cost, vertex), at most one entry per vertex.
// A cost that rises is only recorded (in the vertex's slot, not in the heap): costs mostly rise as
// neighbours absorb mass, most such vertices are far from the top, and moving them would touch the
// heap at random places (cache misses once it outgrows the caches). The heap keys are therefore
// lower bounds; top() raises a stale top to its cost and sifts it down until the top's key is its
// cost, which is then the exact minimum, ties included. A cost that falls is moved up at once.
// Compared with a lazy heap of stale entries it stays at most n entries and pops once per removal;
// a 4-ary node's children share a cache line or two (half the depth of a binary heap).
class RemovalQueue {
 public:
  struct Entry {
    double cost;
    Index vertex;
  };
  explicit RemovalQueue(Index vertices) : slot_(static_cast<std::size_t>(vertices)) {}
  bool empty() const { return heap_.empty(); }
  /// The cheapest entry (ties: the lowest vertex index). Precondition: !empty().
  const Entry& top() {
    while (true) {
      Entry& front = heap_.front();
      const double cost = slot_[front.vertex].cost;
      if (cost == front.cost) return front;
      front.cost = cost;  // a risen cost: the key was a lower bound
      sift_down(0);
    }
  }
  /// Inserts v or changes its cost.
  void set(Index v, double cost) {
    Slot& slot = slot_[v];
    slot.cost = cost;
    if (slot.position == kInvalid) {
      heap_.push_back({cost, v});
      slot.position = static_cast<Index>(heap_.size() - 1);
      sift_up(heap_.size() - 1);
    } else if (cost < heap_[slot.position].cost) {
      heap_[slot.position].cost = cost;
      sift_up(slot.position);
    }
  }
  /// Removes v if present.
  void erase(Index v) {
    const Index i = slot_[v].position;
    if (i == kInvalid) return;
    slot_[v].position = kInvalid;
    const Entry last = heap_.back();
    heap_.pop_back();
    if (static_cast<std::size_t>(i) == heap_.size()) return;
    place(i, last);
    sift_up(i);
    sift_down(slot_[last.vertex].position);
  }

 private:
  struct Slot {
    double cost = 0;          // the vertex's current cost (≥ its heap key)
    Index position = kInvalid;  // its heap index, or kInvalid
  };
  static bool before(const Entry& a, const Entry& b) {
    return a.cost < b.cost || (a.cost == b.cost && a.vertex < b.vertex);
  }
  void place(std::size_t i, const Entry& e) {
    heap_[i] = e;
    slot_[e.vertex].position = static_cast<Index>(i);
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
      const std::size_t end = std::min(first + 4, size);
      for (std::size_t c = first + 1; c < end; ++c)
        if (before(heap_[c], heap_[best])) best = c;
      if (!before(heap_[best], e)) break;
      place(i, heap_[best]);
      i = best;
    }
    place(i, e);
  }
  LargeArray<Entry> heap_;
  LargeArray<Slot> slot_;
};

}  // namespace

CoarsenResult coarsen(IntrinsicTriangulation& T, const CoarsenOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const Index n = T.num_input_vertices();
  CoarsenResult result;
  result.input_vertices = T.num_vertices();
  Index target = options.target_vertices;
  if (target <= 0 && options.target_ratio > 0)
    target = static_cast<Index>(std::ceil(options.target_ratio * T.num_vertices()));
  target = std::max<Index>(target, 1);

  IntrinsicErrorMetric metric(T, options.area_weight);
  // Per-vertex driver state in one record (one cache line fetch per vertex touched, which is what
  // bounds the speed once the mesh outgrows the caches). log_scale is the flattening scale found by
  // the vertex's latest cost evaluation (its star has not changed since: every change re-evaluates
  // it), so the removal re-uses it instead of running Newton again; seen dedupes the vertices to
  // re-evaluate after one removal.
  struct VertexState {
    double log_scale = std::numeric_limits<double>::quiet_NaN();
    std::uint32_t seen = 0;
    std::uint8_t locked = 0, failures = 0;
  };
  LargeArray<VertexState> state(static_cast<std::size_t>(n));
  for (Index v : options.locked_vertices)
    if (v >= 0 && v < n) state[v].locked = 1;
  std::uint32_t epoch = 0;
  constexpr std::uint8_t kMaxFailures = 3;

  RemovalQueue queue(n);
  const auto eligible = [&](Index v) {
    return T.vertex_alive(v) && !state[v].locked && state[v].failures < kMaxFailures &&
           (options.remove_boundary || !T.is_boundary_vertex(v));
  };
  const auto schedule = [&](Index v) {
    const double cost = eligible(v) ? metric.removal_cost(T, v, &state[v].log_scale) : std::numeric_limits<double>::infinity();
    if (std::isfinite(cost)) queue.set(v, cost);
    else queue.erase(v);
  };
  for (Index v = 0; v < n; ++v) schedule(v);

  std::vector<Index> affected, changed_faces;
  result.stop_reason = StopReason::TargetReached;
  while (T.num_vertices() > target) {
    if (queue.empty()) {
      result.stop_reason = StopReason::NothingRemovable;
      break;
    }
    const RemovalQueue::Entry top = queue.top();  // a copy: erase() moves the heap's entries
    if (top.cost > options.max_error) {
      result.stop_reason = StopReason::ErrorThreshold;
      break;
    }
    const Index v = top.vertex;
    queue.erase(v);
    // The one-ring (its costs change), collected while the star exists.
    affected.clear();
    T.for_each_outgoing(v, [&](Index h) {
      affected.push_back(T.head(h));
      affected.push_back(T.tail(T.prev(h)));
    });
    if (!metric.prepare_removal(T, v, state[v].log_scale)) continue;
    changed_faces.clear();
    const RemovalStatus status = T.remove_vertex(v, &changed_faces, &affected, state[v].log_scale);
    if (status == RemovalStatus::Removed) {
      metric.apply_prepared_removal();
      ++result.removed;
      result.last_cost = top.cost;
      result.max_cost = std::max(result.max_cost, top.cost);
    } else {
      ++result.failed_removals;
      ++result.failures_by_status[static_cast<int>(status)];
      ++state[v].failures;
      affected.push_back(v);
    }
    T.flip_to_delaunay_around(changed_faces, &affected);
    ++epoch;
    for (Index u : affected) {
      if (state[u].seen == epoch) continue;
      state[u].seen = epoch;
      schedule(u);
    }
    if (options.progress && result.removed % options.progress_interval == 0 && status == RemovalStatus::Removed) {
      const CoarsenProgress progress{T.num_vertices(), target, result.removed, result.last_cost};
      if (!options.progress(progress)) {
        result.stop_reason = StopReason::Cancelled;
        break;
      }
    }
  }
  // The cost of the cheapest remaining removal (for reports and threshold stops).
  result.next_cost = queue.empty() ? std::numeric_limits<double>::infinity() : queue.top().cost;
  result.output_vertices = T.num_vertices();
  result.output_faces = T.num_faces();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace ice
