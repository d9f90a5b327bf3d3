#include "ice/coarsen.h"

#include "ice/vertex_star.h"
#include "removal_queue.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <memory>
#include <optional>
#include <thread>
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
  // Rotate by the quarter turns with a table, not a switch: the quadrant is unpredictable.
  static constexpr double kQuarterCos[4] = {1, 0, -1, 0}, kQuarterSin[4] = {0, 1, 0, -1};
  const int quadrant = static_cast<int>(static_cast<long long>(quarter_turns) & 3);
  const double c = kQuarterCos[quadrant], s = kQuarterSin[quadrant];
  return {c * cosine - s * sine, c * sine + s * cosine};
}
}

void CoarsenResult::add_counts(const CoarsenResult& part) {
  removed += part.removed;
  failed_removals += part.failed_removals;
  for (std::size_t k = 0; k < part.failures_by_status.size(); ++k) failures_by_status[k] += part.failures_by_status[k];
  max_cost = std::max(max_cost, part.max_cost);
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

IntrinsicErrorMetric::IntrinsicErrorMetric(const IntrinsicTriangulation& T, double area_weight)
    : area_channel_(area_weight != 0) {
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

IntrinsicErrorMetric::Workspace& IntrinsicErrorMetric::workspace() {
  thread_local Workspace work;
  return work;
}

bool IntrinsicErrorMetric::split_weights(const IntrinsicTriangulation& T, Index v, std::vector<Neighbour>& out,
                                         double* log_scale) const {
  out.clear();
  // One walk reads the star; Newton and the curvature changes below work on that snapshot. The
  // split weights only rank and share masses: a 1e-7 relative angle-sum tolerance is plenty (the
  // weights move by about as much; the committed flattening itself is exact to 1e-13). A scale
  // already computed for the same star (*log_scale finite on entry) is reused.
  VertexStar& star = workspace().star;
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
  const std::vector<StarCorner>& corners = star.corners;
  const int count = static_cast<int>(corners.size());
  // With distinct neighbours (no multi- or self-edges at v: nearly always) neighbour k is corner k's
  // out_vertex and the weights go straight to their slots, where the general path searches the list
  // per corner (mispredicted branches). Same order and sums, so the same result.
  const int extra = star.boundary ? 1 : 0;
  const bool simple = has_distinct_neighbours(star);
  if (simple) {
    out.resize(static_cast<std::size_t>(count + extra));
    for (int k = 0; k < count; ++k) out[k] = {corners[k].out_vertex, corners[k].halfedge, 0.0};
    if (extra) out[count] = {corners[count - 1].in_vertex, corners[count - 1].in_halfedge ^ 1, 0.0};
    for (int k = 0; k < count; ++k) {
      // Curvature is 2π − Θ, so a corner shrinking by δ raises its vertex's curvature by δ.
      const CornerAngleChange change = corner_angle_change(corners[k], half_scale);
      out[k].weight += change.at_out;
      out[k + 1 < count ? k + 1 : (extra ? count : 0)].weight += change.at_in;
    }
  } else {
    const auto add = [&](Index vertex, Index halfedge, double delta_K) {
      if (vertex == v) return;  // a self-edge: v absorbs nothing from itself
      for (Neighbour& n : out)
        if (n.vertex == vertex) {
          n.weight += delta_K;
          return;
        }
      out.push_back({vertex, halfedge, delta_K});
    };
    for (const StarCorner& corner : corners) {
      const CornerAngleChange change = corner_angle_change(corner, half_scale);
      add(corner.out_vertex, corner.halfedge, change.at_out);
      add(corner.in_vertex, corner.in_halfedge ^ 1, change.at_in);
    }
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

template <int Channels, class Sink>
void IntrinsicErrorMetric::merge_channels(const IntrinsicTriangulation& T, Index v, const Neighbour& n, Sink&& sink) const {
  // Complex arithmetic is written out: std::complex's operator* guards against NaN/inf operands,
  // which cannot occur here, at several times the cost.
  const Record& from = records_[v];
  const Record& to = records_[n.vertex];
  const Index h = n.halfedge;  // v -> j
  // Transport from v's frame to j's: the vector from j to v in j's frame (needed whenever mass
  // moves) and the rotation of v's centre (needed only when that centre is not v itself, i.e. v
  // has absorbed mass; most vertices have not, early on).
  // Branch-free per channel (which channels hold mass varies from neighbour to neighbour, and
  // mispredicted branches cost more than the arithmetic they skip): an empty channel adds zeros.
  // What depends only on v (whether it moves mass, whether its centres are off v) is decided once.
  double rotation_re = 1, rotation_im = 0, edge_re = 0, edge_im = 0;
  const bool moves = n.weight != 0 && (from.mass[0] != 0 || from.mass[1] != 0 || from.mass[2] != 0);
  if (moves) {
    const std::complex<double> direction = unit_complex(T.angular_coordinate(h ^ 1));
    edge_re = T.length(h) * direction.real(), edge_im = T.length(h) * direction.imag();
    bool off_centre = false;
    for (int c = 0; c < kChannels; ++c) off_centre |= (from.centre[c].real() != 0) | (from.centre[c].imag() != 0);
    if (off_centre) {
      const std::complex<double> rotation = unit_complex(T.angular_coordinate(h ^ 1) - T.angular_coordinate(h) + kPi);
      rotation_re = rotation.real(), rotation_im = rotation.imag();
    }
  }
  for (int c = 0; c < Channels; ++c) {
    const double share = n.weight * from.mass[c];
    const double m_j = to.mass[c];
    const double x = rotation_re * from.centre[c].real() - rotation_im * from.centre[c].imag();
    const double y = rotation_re * from.centre[c].imag() + rotation_im * from.centre[c].real();
    const double re = m_j * to.centre[c].real() + share * (x + edge_re);
    const double im = m_j * to.centre[c].imag() + share * (y + edge_im);
    sink(c, m_j + share, re, im);
  }
}

double IntrinsicErrorMetric::removal_cost(const IntrinsicTriangulation& T, Index v, double* log_scale) const {
  if (log_scale) *log_scale = std::numeric_limits<double>::quiet_NaN();
  std::vector<Neighbour>& neighbours = workspace().neighbours;
  if (!split_weights(T, v, neighbours, log_scale)) return std::numeric_limits<double>::infinity();
  // The neighbours' records are usually not cached on large meshes: request them all at once.
  for (const Neighbour& n : neighbours) __builtin_prefetch(&records_[n.vertex]);
  double cost = 0;
  const auto add_cost = [&](int, double, double re, double im) { cost += std::sqrt(re * re + im * im); };  // m'·|x'| = |m'·x'|
  for (const Neighbour& n : neighbours) {
    if (area_channel_) merge_channels<kChannels>(T, v, n, add_cost);
    else merge_channels<kChannels - 1>(T, v, n, add_cost);
  }
  return cost;
}

bool IntrinsicErrorMetric::prepare_removal(const IntrinsicTriangulation& T, Index v, double log_scale) {
  Workspace& work = workspace();
  work.pending.clear();
  work.pending_vertex = kInvalid;
  if (!split_weights(T, v, work.neighbours, &log_scale)) return false;
  for (const Neighbour& n : work.neighbours) {
    PendingRecord record{n.vertex, {}, {}};
    const auto keep = [&](int c, double mass, double re, double im) {
      record.mass[c] = mass;
      record.moment[c] = {re, im};
    };
    if (area_channel_) merge_channels<kChannels>(T, v, n, keep);
    else merge_channels<kChannels - 1>(T, v, n, keep);
    work.pending.push_back(record);
  }
  work.pending_vertex = v;
  return true;
}

void IntrinsicErrorMetric::apply_prepared_removal() {
  Workspace& work = workspace();
  for (const PendingRecord& r : work.pending) {
    Record& record = records_[r.vertex];
    record.mass = r.mass;
    for (int c = 0; c < kChannels; ++c)
      record.centre[c] = r.mass[c] > 0 ? r.moment[c] / r.mass[c] : std::complex<double>(0, 0);
  }
  if (work.pending_vertex != kInvalid) records_[work.pending_vertex] = Record{};
  work.pending.clear();
  work.pending_vertex = kInvalid;
}

// ------------------------------------------------------------------------------------------------
// Greedy driver

namespace {

using detail::RemovalQueue;
using detail::VertexState;

constexpr std::uint8_t kMaxFailures = 3;

// What the greedy loops of one coarsen() call share.
struct GreedyContext {
  IntrinsicTriangulation& T;
  IntrinsicErrorMetric& metric;
  LargeArray<VertexState>& state;
  const CoarsenOptions& options;
  Index final_target;                 // for progress reports
  Index vertices_at_start;            // for progress reports
  std::atomic<Index> removed{0};      // by all loops so far
  std::atomic<bool> cancelled{false};
};

// Where one greedy loop works: the whole mesh, or (parallel phase) one region. A region's loop
// only removes interior, non-frontier vertices of its region (their stars and their neighbours'
// stars lie in it) and only flips edges inside it, so loops of different regions read and write
// disjoint data.
struct GreedyScope {
  const IntrinsicTriangulation::WriteRegion* region = nullptr;
  std::uint8_t* frontier = nullptr;  // with a region: 1 where a neighbour lies outside it (set by the loop)
  Index vertices = 0;                // live vertices in scope (decremented per removal)
  Index target = 0;                  // never go below
};

// Why GreedyLoop::run returned.
enum class RunStop { Target, Threshold, Quota, Empty, Cancelled };

// The greedy removal loop of one scope, resumable: run() removes the cheapest vertex while its
// cost is at most a threshold, up to a quota of removals, and can be called again with another.
class GreedyLoop {
 public:
  GreedyLoop(GreedyContext& context, const GreedyScope& scope)
      : context_(context),
        scope_(scope),
        T_(context.T),
        state_(context.state),
        queue_(context.state) {
    const Index n = T_.num_input_vertices();
    const IntrinsicTriangulation::WriteRegion* region = scope_.region;
    for (Index v = 0; v < n; ++v) {
      if (!in_scope(v)) continue;
      if (region) {  // each loop marks its own vertices: faces at them are never changed by other loops
        scope_.frontier[v] = 0;
        T_.for_each_outgoing(v, [&](Index h) {
          if (!region->contains(T_.head(h))) scope_.frontier[v] = 1;
        });
      }
      state_[v].position = kInvalid;  // a slot of an earlier loop's queue
      state_[v].seen = 0;
      schedule(v);
      blocked_ += T_.vertex_alive(v) && !eligible(v);
    }
  }

  RunStop run(double threshold, Index quota) {
    const CoarsenOptions& options = context_.options;
    for (Index removed_here = 0;; ) {
      if (scope_.vertices <= scope_.target) return RunStop::Target;
      if (removed_here >= quota) return RunStop::Quota;
      if (context_.cancelled.load(std::memory_order_relaxed)) return RunStop::Cancelled;
      if (queue_.empty()) return RunStop::Empty;
      const RemovalQueue::Entry top = queue_.top();  // a copy: erase() moves the heap's entries
      if (top.cost > threshold) return RunStop::Threshold;
      const Index v = top.vertex;
      // v's two-ring, from memory: walked during the previous removal when that guessed v (the
      // usual case), else now.
      if (ahead_.vertex() != v) ahead_.start(T_, v);
      while (advance_ahead()) {
      }
      queue_.erase(v);
      // The next removal's vertex is most likely the cheapest one now (its exact cost is known:
      // the removal below changes only the costs around v, which mostly rise): its two-ring walk
      // runs in rounds between the steps of this removal, so that its memory latencies overlap
      // this removal's work.
      if (!queue_.empty()) ahead_.start(T_, queue_.top().vertex);
      // The one-ring (its costs change), collected while the star exists.
      affected_.clear();
      // (tail(prev(h)) is the next half-edge's head, except past the last one at a boundary vertex.)
      Index last = kInvalid;
      T_.for_each_outgoing(v, [&](Index h) {
        affected_.push_back(T_.head(h));
        last = h;
      });
      if (T_.is_boundary_vertex(v)) affected_.push_back(T_.tail(T_.prev(last)));
      if (!context_.metric.prepare_removal(T_, v, state_[v].log_scale)) continue;
      advance_ahead();
      changed_faces_.clear();
      const RemovalStatus status = T_.remove_vertex(v, &changed_faces_, &affected_, state_[v].log_scale);
      if (status == RemovalStatus::Removed) {
        context_.metric.apply_prepared_removal();
        ++result_.removed, ++removed_here;
        --scope_.vertices;
        result_.last_cost = top.cost;
        result_.max_cost = std::max(result_.max_cost, top.cost);
        context_.removed.fetch_add(1, std::memory_order_relaxed);
      } else {
        ++result_.failed_removals;
        ++result_.failures_by_status[static_cast<int>(status)];
        ++state_[v].failures;
        affected_.push_back(v);
      }
      advance_ahead();
      T_.flip_to_delaunay_around(changed_faces_, &affected_, scope_.region);
      advance_ahead();
      if (++epoch_ == 0) {  // the 16-bit epoch wrapped: forget every mark in scope
        for (Index u = 0; u < T_.num_input_vertices(); ++u)
          if (in_scope(u)) state_[u].seen = 0;
        epoch_ = 1;
      }
      for (Index u : affected_) {
        if (!in_scope(u) || state_[u].seen == epoch_) continue;
        state_[u].seen = epoch_;
        schedule(u);
        advance_ahead();
      }
      // The serial loop reports per removal; the regions' progress is reported between rounds.
      if (!scope_.region && options.progress && status == RemovalStatus::Removed &&
          result_.removed % options.progress_interval == 0) {
        const Index removed = context_.removed.load(std::memory_order_relaxed);
        const CoarsenProgress progress{context_.vertices_at_start - removed, context_.final_target, removed,
                                       result_.last_cost};
        if (!options.progress(progress)) {
          context_.cancelled.store(true, std::memory_order_relaxed);
          return RunStop::Cancelled;
        }
      }
    }
  }

  /// The cost of the cheapest candidate (+inf if none).
  double next_cost() { return queue_.empty() ? std::numeric_limits<double>::infinity() : queue_.top().cost; }
  const CoarsenResult& result() const { return result_; }
  Index vertices() const { return scope_.vertices; }
  /// Live vertices in scope that were never candidates (frontier, boundary, locked, failed).
  Index blocked() const { return blocked_; }

 private:
  // Nothing outside the region is read or written: its state belongs to another thread.
  bool in_scope(Index v) const { return !scope_.region || scope_.region->contains(v); }
  bool eligible(Index v) const {
    if (scope_.region && (!scope_.region->contains(v) || scope_.frontier[v] || T_.is_boundary_vertex(v))) return false;
    return T_.vertex_alive(v) && !state_[v].locked && state_[v].failures < kMaxFailures &&
           (context_.options.remove_boundary || !T_.is_boundary_vertex(v));
  }
  void schedule(Index v) {
    const double cost = eligible(v) ? context_.metric.removal_cost(T_, v, &state_[v].log_scale)
                                    : std::numeric_limits<double>::infinity();
    if (std::isfinite(cost)) queue_.set(v, cost);
    else queue_.erase(v);
  }

  // One round of the walk over the next removal's two-ring (see run()). Re-evaluating a
  // neighbour reads its state and the metric records of its own neighbours.
  bool advance_ahead() {
    return ahead_.advance(
        [&](Index w) {
          __builtin_prefetch(&state_[w]);
          context_.metric.prefetch(w);
        },
        [&](Index w) { context_.metric.prefetch(w); });
  }

  GreedyContext& context_;
  GreedyScope scope_;
  IntrinsicTriangulation& T_;
  LargeArray<VertexState>& state_;
  RemovalQueue queue_;
  Index blocked_ = 0;
  std::uint16_t epoch_ = 0;
  TwoRingPrefetch ahead_;
  std::vector<Index> affected_, changed_faces_;
  CoarsenResult result_;
};

// Runs f(task) for task = 0..tasks−1 on `threads` threads (the calling one included), each thread
// taking the next task when it finishes one (a task's result must not depend on which thread runs
// it); rethrows the first exception.
template <class F>
void run_tasks(int threads, int tasks, F&& f) {
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(tasks));
  std::atomic<int> next{0};
  const auto work = [&] {
    for (int task; (task = next.fetch_add(1)) < tasks;) {
      try {
        f(task);
      } catch (...) {
        errors[task] = std::current_exception();
      }
    }
  };
  std::vector<std::thread> workers;
  for (int t = 1; t < std::min(threads, tasks); ++t) workers.emplace_back(work);
  work();
  for (std::thread& worker : workers) worker.join();
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
}

// Labels the live vertices with `parts` regions: contiguous ranges of a breadth-first order of
// each component (first vertex first), i.e. a ball and the shells around it, each compact on the
// surface with a short frontier. Dead vertices get kNoRegion. Returns each region's live vertex
// count.
constexpr std::uint8_t kNoRegion = 255;
std::vector<Index> partition_vertices(const IntrinsicTriangulation& T, int parts, std::vector<std::uint8_t>& label) {
  const Index n = T.num_input_vertices();
  const Index live = T.num_vertices();
  label.assign(static_cast<std::size_t>(n), kNoRegion);
  std::vector<Index> sizes(static_cast<std::size_t>(parts), 0);
  std::vector<Index> queue;
  queue.reserve(static_cast<std::size_t>(live));
  Index rank = 0;
  for (Index root = 0; root < n; ++root) {
    if (label[root] != kNoRegion || !T.vertex_alive(root)) continue;
    queue.clear();
    queue.push_back(root);
    label[root] = 0;  // visited (the final label is set when dequeued)
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const Index v = queue[head];
      const int part = static_cast<int>(static_cast<std::int64_t>(rank++) * parts / live);
      label[v] = static_cast<std::uint8_t>(part);
      ++sizes[part];
      T.for_each_outgoing(v, [&](Index h) {
        const Index w = T.head(h);
        if (label[w] == kNoRegion) label[w] = 0, queue.push_back(w);
      });
    }
  }
  return sizes;
}

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

  // Parallel phase: the threads coarsen regions of the mesh (see GreedyScope) down to an
  // intermediate size that leaves max(target, 1/32 of the removals) to the serial phase, which
  // restores the Delaunay property along the seams and then continues the global greedy order from
  // exact costs over all vertices (so the last, most visible removals are ordered as in the serial
  // algorithm, and the vertices along the seams are removed too).
  const int threads = std::min(options.threads > 0 ? options.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency())), 64);
  const Index live = T.num_vertices();
  const Index intermediate = target + std::max<Index>(target, (live - target) / 32);
  const bool parallel = threads > 1 && live >= options.parallel_min_vertices && intermediate < live / 2;
  // More regions than threads: a thread that finishes its region early in a round takes another.
  const int parts = std::min(4 * threads, 254);
  // The partition (a breadth-first pass) runs on a second thread while the metric is set up.
  std::vector<std::uint8_t> label, frontier;
  std::vector<Index> sizes;
  std::optional<IntrinsicErrorMetric> metric_storage;
  run_tasks(parallel ? 2 : 1, parallel ? 2 : 1, [&](int task) {
    if (task == 0) {
      metric_storage.emplace(T, options.area_weight);
    } else {
      sizes = partition_vertices(T, parts, label);
      frontier.resize(label.size());
    }
  });
  IntrinsicErrorMetric& metric = *metric_storage;
  LargeArray<VertexState> state(static_cast<std::size_t>(n));
  for (Index v : options.locked_vertices)
    if (v >= 0 && v < n) state[v].locked = 1;
  GreedyContext context{T, metric, state, options, target, T.num_vertices()};

  if (parallel) {
    // The regions advance in rounds with a common cost threshold that grows by kGrowth per round,
    // so they remove vertices in nearly the global cost order (a region whose vertices are all
    // expensive waits instead of being forced to its share of the removals); within a round, a
    // quota per region (its share of the removals still wanted) keeps the total from overshooting
    // the intermediate size. Region outcomes depend only on the thresholds and quotas, which are
    // computed between rounds from the regions' counts: deterministic.
    constexpr double kGrowth = 1.4;
    constexpr int kMaxRounds = 1000;
    std::vector<IntrinsicTriangulation::WriteRegion> regions(parts);
    std::vector<std::unique_ptr<GreedyLoop>> loops(parts);
    run_tasks(threads, parts, [&](int r) {
      regions[r] = {label.data(), static_cast<std::uint8_t>(r)};
      GreedyScope scope;
      scope.region = &regions[r];
      scope.frontier = frontier.data();
      scope.vertices = sizes[r];
      scope.target = 0;
      loops[r] = std::make_unique<GreedyLoop>(context, scope);
    });
    double threshold = std::numeric_limits<double>::infinity();
    for (auto& loop : loops) threshold = std::min(threshold, loop->next_cost());
    // The vertices the regions cannot remove stay on top of the intermediate size: the regions
    // must not make up for them with removals the serial order would not make yet.
    Index blocked = 0;
    for (auto& loop : loops) blocked += loop->blocked();
    const Index parallel_target = std::min(live, intermediate + blocked);
    Index vertices = live;
    std::vector<RunStop> stops(parts);
    int rounds = 0;
    for (; rounds < kMaxRounds && vertices > parallel_target && std::isfinite(threshold) && !context.cancelled.load(); ++rounds) {
      const double round_threshold = std::min(threshold, options.max_error);
      const Index wanted = vertices - parallel_target;
      run_tasks(threads, parts, [&](int r) {
        const Index quota = std::max<Index>(1, static_cast<Index>(std::ceil(static_cast<double>(wanted) * loops[r]->vertices() / vertices)));
        stops[r] = loops[r]->run(round_threshold, quota);
      });
      vertices = 0;
      bool quota_hit = false, any_left = false;
      for (int r = 0; r < parts; ++r) {
        vertices += loops[r]->vertices();
        quota_hit = quota_hit || stops[r] == RunStop::Quota;
        any_left = any_left || stops[r] == RunStop::Threshold || stops[r] == RunStop::Quota;
      }
      if (!any_left) break;  // every region is out of candidates
      if (options.progress) {
        const Index removed = context.removed.load();
        if (!options.progress(CoarsenProgress{live - removed, target, removed, threshold})) context.cancelled.store(true);
      }
      if (!quota_hit) {
        if (threshold >= options.max_error) break;  // the error bound stops every region
        threshold *= kGrowth;
      }
    }
    for (auto& loop : loops) {
      result.add_counts(loop->result());
      result.last_cost = std::max(result.last_cost, loop->result().last_cost);
    }
    result.parallel_removed = result.removed;
    loops.clear();
    T.flip_to_delaunay();  // the seams: edges with a corner in two regions were never flipped
  }

  if (!context.cancelled.load()) {
    GreedyScope whole;
    whole.vertices = T.num_vertices();
    whole.target = target;
    GreedyLoop loop(context, whole);
    const RunStop stop = loop.run(options.max_error, std::numeric_limits<Index>::max());
    result.add_counts(loop.result());
    if (loop.result().removed > 0) result.last_cost = loop.result().last_cost;
    result.stop_reason = stop == RunStop::Target      ? StopReason::TargetReached
                         : stop == RunStop::Threshold ? StopReason::ErrorThreshold
                         : stop == RunStop::Cancelled ? StopReason::Cancelled
                                                      : StopReason::NothingRemovable;
    result.next_cost = loop.next_cost();
  } else {
    result.stop_reason = StopReason::Cancelled;
    result.next_cost = std::numeric_limits<double>::quiet_NaN();
  }
  result.output_vertices = T.num_vertices();
  result.output_faces = T.num_faces();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace ice
