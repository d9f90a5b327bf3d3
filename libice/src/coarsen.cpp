#include "ice/coarsen.h"

#include "ice/vertex_star.h"
#include "removal_queue.h"
#include "run_tasks.h"
#include "task_team.h"
#include "two_ring_prefetch.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <chrono>
#include <cmath>

namespace ice {

void CoarsenResult::add_counts(const CoarsenResult& part) {
  removed += part.removed;
  cost_evaluations += part.cost_evaluations;
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
  Index final_target;                 // the vertex target of the whole call
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
      if (!context_.metric.prepare_removal(T_, v, plan_, state_[v].log_scale)) continue;
      advance_ahead();
      changed_faces_.clear();
      const RemovalStatus status = T_.remove_vertex(v, &changed_faces_, &affected_, state_[v].log_scale);
      if (status == RemovalStatus::Removed) {
        context_.metric.apply_removal(plan_);
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
    double cost = std::numeric_limits<double>::infinity();
    if (eligible(v)) {
      cost = context_.metric.removal_cost(T_, v, plan_, &state_[v].log_scale);
      ++result_.cost_evaluations;
    }
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
  // This loop's prepared removal and cost scratch: costs re-evaluated between preparing and applying
  // a removal reuse its scratch part, never its prepared records.
  IntrinsicErrorMetric::RemovalPlan plan_;
  CoarsenResult result_;
};

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

// The live vertices labelled with `parts` regions (partition_vertices), each region's size, and
// the frontier flags the regions fill in as they go.
struct RegionPartition {
  int parts = 0;
  std::vector<std::uint8_t> label, frontier;
  std::vector<Index> sizes;
};

// Relabels the live vertices by pairs of the first partition's neighbouring regions (`first`,
// with `first_parts` regions): {0, 1}, {2, 3}, ... with shift 0, {0}, {1, 2}, {3, 4}, ... with
// shift 1, so that the seams between the members of a pair become interior and the two shifts
// between them cover every seam k | k + 1. Dead vertices get kNoRegion.
void pair_regions(const IntrinsicTriangulation& T, const std::vector<std::uint8_t>& first, int first_parts, int shift,
                  RegionPartition& partition) {
  partition.parts = (first_parts + shift) / 2 + (first_parts + shift) % 2;
  partition.sizes.assign(static_cast<std::size_t>(partition.parts), 0);
  for (std::size_t v = 0; v < first.size(); ++v) {
    if (!T.vertex_alive(static_cast<Index>(v))) {
      partition.label[v] = kNoRegion;
      continue;
    }
    const int pair = (first[v] + shift) / 2;
    partition.label[v] = static_cast<std::uint8_t>(pair);
    ++partition.sizes[pair];
  }
}

// The parallel phase of coarsen(): the regions of `partition`, coarsened by the threads of `team` down
// to about `intermediate` vertices. The regions advance in rounds with a common cost threshold that
// grows by kGrowth per round, so they remove vertices in nearly the global cost order (a region
// whose vertices are all expensive waits instead of being forced to its share of the removals);
// within a round, a quota per region (its share of the removals still wanted) keeps the total from
// overshooting the intermediate size. Region outcomes depend only on the thresholds and quotas,
// which are computed between rounds from the regions' counts: deterministic. Leaves the seams
// (edges with a corner in two regions, never flipped) Delaunay again.
CoarsenResult coarsen_regions(GreedyContext& context, RegionPartition& partition, detail::TaskTeam& team, Index intermediate) {
  constexpr double kGrowth = 1.4;
  constexpr int kMaxRounds = 1000;
  const CoarsenOptions& options = context.options;
  const int parts = partition.parts;
  const Index live = context.T.num_vertices();
  std::vector<IntrinsicTriangulation::WriteRegion> regions(parts);
  std::vector<std::unique_ptr<GreedyLoop>> loops(parts);
  // A recording triangulation's operations, region by region: each region's thread writes its own
  // shard, appended in region order after each pass over the regions (their faces are disjoint).
  const bool recording = context.T.records_history();
  std::vector<TriangulationHistory> shards(recording ? parts : 0);
  const auto append_shards = [&] {
    for (TriangulationHistory& shard : shards) context.T.append_history(std::move(shard));
  };
  team.run(parts, [&](int r) {
    std::optional<IntrinsicTriangulation::HistoryShard> shard;
    if (recording) shard.emplace(shards[r]);
    regions[r] = {partition.label.data(), static_cast<std::uint8_t>(r)};
    GreedyScope scope;
    scope.region = &regions[r];
    scope.frontier = partition.frontier.data();
    scope.vertices = partition.sizes[r];
    scope.target = 0;
    loops[r] = std::make_unique<GreedyLoop>(context, scope);
  });
  append_shards();
  double threshold = std::numeric_limits<double>::infinity();
  for (auto& loop : loops) threshold = std::min(threshold, loop->next_cost());
  // The vertices the regions cannot remove stay on top of the intermediate size: the regions
  // must not make up for them with removals the serial order would not make yet.
  Index blocked = 0;
  for (auto& loop : loops) blocked += loop->blocked();
  const Index parallel_target = std::min(live, intermediate + blocked);
  Index vertices = live;
  std::vector<RunStop> stops(parts);
  for (int round = 0; round < kMaxRounds && vertices > parallel_target && std::isfinite(threshold) &&
                      !context.cancelled.load();
       ++round) {
    const double round_threshold = std::min(threshold, options.max_error);
    const Index wanted = vertices - parallel_target;
    team.run(parts, [&](int r) {
      std::optional<IntrinsicTriangulation::HistoryShard> shard;
      if (recording) shard.emplace(shards[r]);
      const Index quota = std::max<Index>(1, static_cast<Index>(std::ceil(static_cast<double>(wanted) * loops[r]->vertices() / vertices)));
      stops[r] = loops[r]->run(round_threshold, quota);
    });
    append_shards();
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
      if (!options.progress(CoarsenProgress{context.vertices_at_start - removed, context.final_target, removed, threshold}))
        context.cancelled.store(true);
    }
    if (!quota_hit) {
      if (threshold >= options.max_error) break;  // the error bound stops every region
      threshold *= kGrowth;
    }
  }
  CoarsenResult result;
  for (auto& loop : loops) {
    result.add_counts(loop->result());
    result.last_cost = std::max(result.last_cost, loop->result().last_cost);
  }
  result.parallel_removed = result.removed;
  loops.clear();
  context.T.flip_to_delaunay();
  return result;
}

// The serial phase of coarsen(): the global greedy order over every vertex from exact costs, down
// to context.final_target or options.max_error. Adds its counts, stop reason and costs to `result`.
void coarsen_whole(GreedyContext& context, CoarsenResult& result) {
  GreedyScope whole;
  whole.vertices = context.T.num_vertices();
  whole.target = context.final_target;
  GreedyLoop loop(context, whole);
  const RunStop stop = loop.run(context.options.max_error, std::numeric_limits<Index>::max());
  result.add_counts(loop.result());
  if (loop.result().removed > 0) result.last_cost = loop.result().last_cost;
  result.stop_reason = stop == RunStop::Target      ? StopReason::TargetReached
                       : stop == RunStop::Threshold ? StopReason::ErrorThreshold
                       : stop == RunStop::Cancelled ? StopReason::Cancelled
                                                    : StopReason::NothingRemovable;
  result.next_cost = loop.next_cost();
}

}  // namespace

int coarsening_regions(const CoarsenOptions& options) {
  return options.regions > 0 ? options.regions : kDefaultCoarseningRegions;
}

CoarsenResult coarsen(IntrinsicTriangulation& T, const CoarsenOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (T.num_vertex_slots() != T.num_input_vertices())
    throw std::invalid_argument("coarsen: the triangulation has vertices inserted by refinement; coarsen its compacted() copy");
  T.maintain_frames(true);  // the metric's transports read them
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
  if (options.regions < 0 || options.regions > 254)
    throw std::invalid_argument("coarsen: regions = " + std::to_string(options.regions) + " is out of range [0, 254]");
  const int threads = detail::requested_threads(options.threads);
  const Index live = T.num_vertices();
  const Index intermediate = target + std::max<Index>(target, (live - target) / 32);
  RegionPartition partition;
  // More regions than threads: a thread that finishes its region early in a round takes another.
  partition.parts = coarsening_regions(options);
  const bool parallel = partition.parts > 1 && live >= options.parallel_min_vertices && intermediate < live / 2;
  // The partition (a breadth-first pass) runs on a second thread while the metric is set up.
  std::optional<IntrinsicErrorMetric> metric_storage;
  detail::run_tasks(parallel ? std::min(threads, 2) : 1, parallel ? 2 : 1, [&](int task) {
    if (task == 0) {
      metric_storage.emplace(T, options.area_weight, options.normalize_curvature);
    } else {
      partition.sizes = partition_vertices(T, partition.parts, partition.label);
      partition.frontier.resize(partition.label.size());
    }
  });
  IntrinsicErrorMetric& metric = *metric_storage;
  const auto since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  result.setup_seconds = since(start);
  LargeArray<VertexState> state(static_cast<std::size_t>(n));
  for (Index v : options.locked_vertices)
    if (v >= 0 && v < n) state[v].locked = 1;
  GreedyContext context{T, metric, state, options, target, T.num_vertices()};

  auto phase_start = std::chrono::steady_clock::now();
  if (parallel) {
    // Three stages. The seams of the first partition keep the input's density (their vertices are
    // never removed there): the second stage pairs neighbouring regions across every other seam
    // (ranges of one breadth-first order: region k borders k - 1 and k + 1), the third across the
    // others, so the seams are coarsened in parallel as well instead of by the serial phase.
    const int stages = partition.parts >= 4 ? 3 : 1;
    const std::vector<std::uint8_t> first = stages > 1 ? partition.label : std::vector<std::uint8_t>{};
    const int first_parts = partition.parts;
    detail::TaskTeam team(std::min(threads, partition.parts));  // for the stages' ~100 short rounds
    for (int stage = 0; stage < stages && !context.cancelled.load(); ++stage) {
      if (stage > 0) pair_regions(T, first, first_parts, stage == 1 ? 1 : 0, partition);
      const CoarsenResult regions = coarsen_regions(context, partition, team, intermediate);
      result.add_counts(regions);
      result.parallel_removed += regions.parallel_removed;
      result.last_cost = std::max(result.last_cost, regions.last_cost);
    }
    result.parallel_seconds = since(phase_start);
    phase_start = std::chrono::steady_clock::now();
  }
  if (!context.cancelled.load()) {
    coarsen_whole(context, result);
    result.serial_seconds = since(phase_start);
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
