#include "ice/hierarchy.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <stdexcept>

#include "ice/graph_ordering.h"
#include "ice/prolongation.h"
#include "cover_copies.h"
#include "locality_numbering.h"
#include "run_tasks.h"

namespace ice {

double Hierarchy::grid_complexity() const {
  if (levels.empty() || levels[0].num_vertices() == 0) return 0;
  double total = 0;
  for (const HierarchyLevel& level : levels) total += level.num_vertices();
  return total / levels[0].num_vertices();
}

Eigen::SparseMatrix<double> Hierarchy::prolongation_to_fine(int k) const {
  if (k < 0 || k >= num_levels()) throw std::out_of_range("Hierarchy::prolongation_to_fine: no such level");
  const Index n0 = levels[0].num_vertices();
  Eigen::SparseMatrix<double> P(n0, n0);
  P.setIdentity();
  for (int j = 0; j < k; ++j) P = Eigen::SparseMatrix<double>(P * prolongations[static_cast<std::size_t>(j)]);
  return P;
}

namespace {

// The neighbour carrying at least `share` of v's summed non-negative cotan weights, or kInvalid.
Index strongest_neighbour(const IntrinsicTriangulation& T, Index v, double share) {
  double total = 0, strongest = 0;
  Index neighbour = kInvalid;
  T.for_each_outgoing(v, [&](Index h) {
    const double w = std::max(0.0, T.cotan_weight(h));
    total += w;
    if (w > strongest && T.head(h) != v) strongest = w, neighbour = T.head(h);
  });
  return neighbour != kInvalid && strongest >= share * total ? neighbour : kInvalid;
}

// The neighbours of up to kSize interior vertices, their fans walked in lockstep: one fan walk
// waits for each half-edge record in turn (a cache miss per step once a level outgrows the caches),
// interleaved walks overlap their misses. Measured at 1.66M vertices: the independent-set selection
// 0.70 s → 0.44 s over the hierarchy's 29 passes (level 0: 0.48 → 0.33 s), the same sets (the
// walks only gather).
struct FanBatch {
  static constexpr int kSize = 16;
  int count = 0;
  Index vertex[kSize];
  std::vector<Index> neighbours[kSize];
  void gather(const IntrinsicTriangulation& T) {
    Index cursor[kSize], start[kSize];
    int active = count;
    for (int i = 0; i < count; ++i) {
      cursor[i] = start[i] = T.vertex_halfedge(vertex[i]);
      neighbours[i].clear();
    }
    while (active > 0)
      for (int i = 0; i < count; ++i) {
        if (cursor[i] == kInvalid) continue;
        neighbours[i].push_back(T.head(cursor[i]));
        const Index next = T.rotate_ccw(cursor[i]);
        cursor[i] = next == start[i] ? kInvalid : next;
        active -= cursor[i] == kInvalid;
      }
  }
};

// Coarsens T to co.target_vertices in passes. Each pass removes (at most) an independent set of
// the current triangulation, picked greedily in the SetOrder (vertex index, |curvature| or exact ICE
// removal cost): a vertex is taken, its neighbours are excluded, and so on;
// everything else is locked for that pass. The set is then removed either directly (remove_vertex
// + Delaunay repair around it, flattest first) or by ice::coarsen with the rest locked (use_metric:
// ICE-metric order, same result up to order, ~1.4x slower). This
// keeps each level's vertex density uniform (every removed vertex keeps all its neighbours within a
// pass), which is what multigrid needs, while the ICE metric still decides which vertices go.
//
// Boundary vertices are chosen apart, along each boundary loop, at the rate of a curve: when the
// level keeps a fraction r of the vertices, the spacing of the surface's vertices grows by 1/√r, so
// a boundary loop keeps √r of its vertices (half of them at r = 1/4), spread evenly along the loop.
// An independent set on a 1D loop takes every other vertex, so without this rule every pass halved
// the boundary: at r = 1/4 (about six passes) the boundary kept 1/64 of its vertices and P's
// boundary rows reached 8–14 edges away (lion-head), the slowest V-cycle mode sat within four
// edges of the boundary (99 % of its energy, 3 % of the vertices) and PCG converged at 0.29–0.32
// per iteration on scans with holes against 0.07 on closed meshes.
//
// Large levels in a locality numbering are removed range by range on threads: the vertex slots are
// cut into kRegions index ranges (breadth-first layers of the numbering, so each range is a band of
// the surface), and a pass first removes, range by range in parallel, the set's vertices whose
// neighbours all lie in their own range, then the rest serially, then restores Delaunay across
// the ranges' seams. The ranges do not depend on the thread count, so neither does the hierarchy.
constexpr Index kRegionalFrom = 50000;  // live vertices of a pass, at least
constexpr int kRegions = 16;

CoarsenResult coarsen_by_independent_sets(IntrinsicTriangulation& T, const CoarsenOptions& base, double area_weight,
                                          SetOrder set_order, bool use_metric, double anchor_share,
                                          bool locality_numbered, int threads) {
  const bool exact_costs = set_order == SetOrder::exact_cost;
  const auto start = std::chrono::steady_clock::now();
  CoarsenResult total;
  total.input_vertices = T.num_vertices();
  const Index slots = T.num_input_vertices();
  // The ranges, and the same shifted by half a range (first and last shorter and longer), whose
  // interiors hold the first ranges' seams.
  std::vector<std::uint8_t> region_label, shifted_label;  // empty: no ranges on this level
  const auto region_start = [&](int r) { return static_cast<Index>(static_cast<long long>(slots) * r / kRegions); };
  const auto shifted_start = [&](int r) {
    return r == 0 ? 0 : r == kRegions ? slots : static_cast<Index>(static_cast<long long>(slots) * (2 * r - 1) / (2 * kRegions));
  };
  if (locality_numbered && set_order == SetOrder::vertex_index && !use_metric && T.num_vertices() >= kRegionalFrom) {
    region_label.resize(static_cast<std::size_t>(slots));
    shifted_label.resize(static_cast<std::size_t>(slots));
    for (int r = 0; r < kRegions; ++r) {
      std::fill(region_label.begin() + region_start(r), region_label.begin() + region_start(r + 1), static_cast<std::uint8_t>(r));
      std::fill(shifted_label.begin() + shifted_start(r), shifted_label.begin() + shifted_start(r + 1), static_cast<std::uint8_t>(r));
    }
  }
  std::vector<std::uint8_t> user_locked(static_cast<std::size_t>(slots), 0), blocked(static_cast<std::size_t>(slots));
  for (Index v : base.locked_vertices) user_locked[static_cast<std::size_t>(v)] = 1;
  // A removed boundary vertex is interpolated along its loop's new edge, so one whose strong link
  // leaves the loop (to an interior vertex, or across a sliver to another hole: scan_test1_vcg)
  // stays: removing it drops the link from the coarse space as surely as removing both ends would.
  // scan_test1_vcg's PCG factor: 0.31 -> 0.15; over 67 meshes the median 0.106 -> 0.094.
  auto tied_off_loop = [&](Index v) {
    const Index anchor = strongest_neighbour(T, v, anchor_share);
    if (anchor == kInvalid) return false;
    const Index first = T.vertex_halfedge(v);
    Index last = first;
    T.for_each_outgoing(v, [&](Index h) { last = h; });
    return anchor != T.head(first) && anchor != T.tail(T.prev(last));
  };
  // The boundary vertices the walk may remove, flagged afresh each pass (the walk reads the flags).
  // Tied ones stay, so they count neither toward a loop's size nor toward its goal: otherwise the goal
  // is met by stripping the untied stretches between them (lion-head: 25 of 36 loop vertices tied, the
  // rest gone, P's boundary rows 6 edges long).
  std::vector<std::uint8_t> removable_boundary(static_cast<std::size_t>(slots));
  auto count_boundary = [&] {
    Index count = 0;
    for (Index v = 0; v < slots; ++v) {
      const bool removable = T.vertex_alive(v) && T.is_boundary_vertex(v) && !(anchor_share > 0 && tied_off_loop(v));
      removable_boundary[static_cast<std::size_t>(v)] = removable;
      count += removable;
    }
    return count;
  };
  const Index boundary_start = count_boundary();
  const double boundary_keep =
      std::sqrt(std::min(1.0, static_cast<double>(base.target_vertices) / static_cast<double>(std::max<Index>(T.num_vertices(), 1))));
  const auto boundary_goal = static_cast<Index>(std::ceil(boundary_keep * static_cast<double>(boundary_start)));
  std::vector<std::pair<double, Index>> order;
  std::vector<std::uint8_t> on_walked_loop(static_cast<std::size_t>(slots));
  FanBatch batch;
  std::vector<Index> boundary_ring;
  for (int pass = 0; pass < 64 && T.num_vertices() > base.target_vertices; ++pass) {
    order.clear();
    if (exact_costs) {
      const IntrinsicErrorMetric metric(T, area_weight);
      IntrinsicErrorMetric::RemovalPlan scratch;
      for (Index v = 0; v < slots; ++v)
        if (T.vertex_alive(v) && !user_locked[static_cast<std::size_t>(v)]) {
          const double cost = metric.removal_cost(T, v, scratch);
          if (std::isfinite(cost)) order.emplace_back(cost, v);
        }
    } else {
      for (Index v = 0; v < slots; ++v)
        if (T.vertex_alive(v) && !user_locked[static_cast<std::size_t>(v)]) order.emplace_back(std::abs(T.curvature(v)), v);
    }
    if (set_order != SetOrder::vertex_index) std::sort(order.begin(), order.end());  // else: vertex order already
    Index selected = 0;
    // v joins the set; its neighbours (with repeats) may not.
    auto take = [&](Index v, const std::vector<Index>& neighbours) {
      ++selected;
      blocked[static_cast<std::size_t>(v)] = 2;  // selected
      for (const Index w : neighbours) blocked[static_cast<std::size_t>(w)] |= 1;
    };
    // A boundary vertex's neighbours: the heads of its outgoing half-edges and, across the incoming
    // boundary edge, the tail of a prev(). (An interior vertex's are the heads alone: FanBatch.)
    auto take_boundary = [&](Index v) {
      boundary_ring.clear();
      T.for_each_outgoing(v, [&](Index h) {
        boundary_ring.push_back(T.head(h));
        boundary_ring.push_back(T.tail(T.prev(h)));
      });
      take(v, boundary_ring);
    };
    // Boundary first: a fraction `remove` of each loop's vertices, evenly along it (at most every
    // other one, as an independent set allows), until the loops are down to √r of their vertices.
    // When nothing else can go (a strip that is all boundary), the boundary goes at the full rate.
    auto choose = [&](double remove) {
      std::fill(blocked.begin(), blocked.end(), 0);
      selected = 0;
      if (remove > 0) {
        std::fill(on_walked_loop.begin(), on_walked_loop.end(), 0);
        for (Index start = 0; start < slots; ++start) {
          if (!T.vertex_alive(start) || !T.is_boundary_vertex(start) || on_walked_loop[static_cast<std::size_t>(start)])
            continue;
          double carry = 0;  // Bresenham: select when the accumulated fraction passes 1
          for (Index v = start; !on_walked_loop[static_cast<std::size_t>(v)]; v = T.head(T.vertex_halfedge(v))) {
            on_walked_loop[static_cast<std::size_t>(v)] = 1;
            if (!removable_boundary[static_cast<std::size_t>(v)]) continue;  // tied: stays, not counted
            carry += remove;
            if (carry < 1) continue;
            if (blocked[static_cast<std::size_t>(v)] || user_locked[static_cast<std::size_t>(v)]) continue;
            carry -= 1;
            take_boundary(v);
          }
        }
      }
      // Interior vertices in `order`, each taken unless a neighbour was, in batches whose fans are
      // gathered together first (a vertex blocked when its batch forms stays blocked).
      for (std::size_t next = 0; next < order.size();) {
        batch.count = 0;
        for (; next < order.size() && batch.count < FanBatch::kSize; ++next) {
          const Index v = order[next].second;
          if (!blocked[static_cast<std::size_t>(v)] && !T.is_boundary_vertex(v)) batch.vertex[batch.count++] = v;
        }
        batch.gather(T);
        for (int i = 0; i < batch.count; ++i)
          if (!blocked[static_cast<std::size_t>(batch.vertex[i])]) take(batch.vertex[i], batch.neighbours[i]);
      }
    };
    const Index boundary_now = count_boundary();
    choose(base.remove_boundary && boundary_now > boundary_goal
               ? std::min(0.5, static_cast<double>(boundary_now - boundary_goal) / static_cast<double>(boundary_now))
               : 0.0);
    if (selected == 0 && base.remove_boundary && boundary_now > 0) choose(0.5);
    if (selected == 0) break;
    CoarsenResult r;
    if (!use_metric) {
      // Remove the set directly in `order`, restoring Delaunay around each removal. On a large level
      // the vertices inside the index ranges of the locality numbering go first, range by range on
      // the threads, then those inside the shifted ranges, and the rest (on the boundary, or next to
      // seams of both) after them in `order` (see kRegionalFrom).
      const auto remove_one = [&](Index v, const IntrinsicTriangulation::WriteRegion* region, std::vector<Index>& changed,
                                  CoarsenResult& counts) {
        if (anchor_share > 0) {
          // The neighbour carrying most of v's cotan weight stays for the rest of this level, so that
          // v is interpolated from the vertex it is tied to (HierarchyOptions::strong_neighbour_share).
          const Index anchor = strongest_neighbour(T, v, anchor_share);
          if (anchor != kInvalid) user_locked[static_cast<std::size_t>(anchor)] = 1;
        }
        changed.clear();
        const RemovalStatus status = T.remove_vertex(v, &changed);
        if (status == RemovalStatus::Removed) {
          ++counts.removed;
        } else {
          ++counts.failed_removals;
          ++counts.failures_by_status[static_cast<int>(status)];
        }
        T.flip_to_delaunay_around(changed, nullptr, region);
      };
      std::vector<Index> changed;
      std::vector<Index> seam_edges;  // half-edges the threads left unflipped (diamonds across a seam)
      // The set in `order`. With ranges, only its first vertices, about as many as the serial loop
      // would remove before reaching the target (it stops there by itself).
      std::vector<Index> rest;
      Index allowed = region_label.empty() ? std::numeric_limits<Index>::max() : std::max<Index>(0, T.num_vertices() - base.target_vertices);
      for (const auto& entry : order)
        if (blocked[static_cast<std::size_t>(entry.second)] == 2 && allowed > 0) {
          rest.push_back(entry.second);
          --allowed;
        }
      // Delaunay across the seams, from the faces on both sides of the edges the threads could not
      // flip (before the next removals read cotan weights).
      const auto restore_seams = [&] {
        if (seam_edges.empty()) return;
        changed.clear();
        for (const Index h : seam_edges)
          for (const Index side : {h, h ^ 1})
            if (T.halfedge_alive(side) && !T.is_exterior(side)) changed.push_back(T.face(side));
        T.flip_to_delaunay_around(changed);
        seam_edges.clear();
      };
      // One round over `candidates` (by increasing index) in the ranges [start(k), start(k + 1))
      // that `label` names: the vertices whose neighbours all lie in their own range are removed,
      // range by range on the threads (their stars and the flips around them stay inside, where no
      // other thread writes, as in coarsen()'s parallel phase); the others are returned in order.
      const auto remove_in_ranges = [&](const std::vector<Index>& candidates, const std::vector<std::uint8_t>& label,
                                        const auto& start) {
        std::vector<CoarsenResult> counts(kRegions);
        std::vector<std::vector<Index>> left(kRegions), skipped(kRegions);
        const auto first_in = [&](int k) { return std::lower_bound(candidates.begin(), candidates.end(), start(k)) - candidates.begin(); };
        detail::run_tasks(threads, kRegions, [&](int k) {
          const IntrinsicTriangulation::WriteRegion region{label.data(), static_cast<std::uint8_t>(k), &skipped[static_cast<std::size_t>(k)]};
          std::vector<Index> changed_here;
          for (auto i = first_in(k), end = first_in(k + 1); i < end; ++i) {
            const Index v = candidates[static_cast<std::size_t>(i)];
            bool inside = !T.is_boundary_vertex(v);
            if (inside) T.for_each_outgoing(v, [&](Index h) { inside = inside && region.contains(T.head(h)); });
            if (inside) remove_one(v, &region, changed_here, counts[static_cast<std::size_t>(k)]);
            else left[static_cast<std::size_t>(k)].push_back(v);
          }
        });
        std::vector<Index> others;
        for (int k = 0; k < kRegions; ++k) {
          r.add_counts(counts[static_cast<std::size_t>(k)]);
          others.insert(others.end(), left[static_cast<std::size_t>(k)].begin(), left[static_cast<std::size_t>(k)].end());
          seam_edges.insert(seam_edges.end(), skipped[static_cast<std::size_t>(k)].begin(), skipped[static_cast<std::size_t>(k)].end());
        }
        return others;
      };
      if (!region_label.empty() && T.num_vertices() >= kRegionalFrom) {
        // The ranges, then the shifted ranges for the vertices next to the first ranges' seams: what
        // is left for the serial loop is the boundary and the few vertices next to both seams.
        rest = remove_in_ranges(rest, region_label, region_start);
        restore_seams();
        rest = remove_in_ranges(rest, shifted_label, shifted_start);
      }
      for (const Index v : rest) {
        if (T.num_vertices() <= base.target_vertices) break;
        remove_one(v, nullptr, changed, r);
      }
      restore_seams();
      r.stop_reason = T.num_vertices() <= base.target_vertices ? StopReason::TargetReached : StopReason::NothingRemovable;
    } else {
      // Everything but the set locked for this pass.
      CoarsenOptions co = base;
      co.locked_vertices.clear();
      for (Index v = 0; v < slots; ++v)
        if (T.vertex_alive(v) && blocked[static_cast<std::size_t>(v)] != 2) co.locked_vertices.push_back(v);
      co.target_vertices = std::max(base.target_vertices, T.num_vertices() - selected);
      co.target_ratio = 0;
      r = coarsen(T, co);
    }
    total.add_counts(r);
    total.last_cost = r.last_cost;
    total.next_cost = r.next_cost;
    total.stop_reason = r.stop_reason;
    if (r.removed == 0) break;
  }
  if (T.num_vertices() <= base.target_vertices) total.stop_reason = StopReason::TargetReached;
  total.output_vertices = T.num_vertices();
  total.output_faces = T.num_faces();
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

// F and L renumbered breadth first (ice::reverse_cuthill_mckee on the vertex graph of F; order[new]
// = old) with the faces sorted by their smallest new vertex (detail::renumber_faces): a removal's
// faces then lie together in memory as its vertices do. Vertices that no face uses keep a place
// (isolated vertices of the graph).
// A gluing `twin` (sides 3f + k) is renumbered with the faces into twin_out (corners keep their order).
void breadth_first_numbering(const Faces& F, const FaceLengths& L, const std::vector<Index>& twin, std::vector<Index>& order,
                             Faces& F_out, FaceLengths& L_out, std::vector<Index>& twin_out) {
  // What IntrinsicTriangulation::from_lengths would refuse, refused before the arrays are indexed.
  if (F.cols() != 3 || L.cols() != 3 || F.rows() != L.rows())
    throw std::invalid_argument("build_hierarchy: F and L must both be m x 3");
  if (F.rows() > 0 && F.minCoeff() < 0) throw std::invalid_argument("build_hierarchy: negative vertex index");
  const Index n = F.rows() == 0 ? 0 : F.maxCoeff() + 1;
  std::vector<Index> offsets(static_cast<std::size_t>(n) + 1, 0), adjacency(static_cast<std::size_t>(6 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) offsets[static_cast<std::size_t>(F(f, k)) + 1] += 2;
  for (Index v = 0; v < n; ++v) offsets[static_cast<std::size_t>(v) + 1] += offsets[static_cast<std::size_t>(v)];
  std::vector<Index> fill(offsets.begin(), offsets.end() - 1);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Index v = F(f, k);
      adjacency[static_cast<std::size_t>(fill[static_cast<std::size_t>(v)]++)] = F(f, (k + 1) % 3);
      adjacency[static_cast<std::size_t>(fill[static_cast<std::size_t>(v)]++)] = F(f, (k + 2) % 3);
    }
  const std::vector<int> rcm = reverse_cuthill_mckee(static_cast<int>(n), offsets.data(), adjacency.data());
  order.assign(rcm.begin(), rcm.end());
  std::vector<Index> new_index(static_cast<std::size_t>(n));
  for (Index i = 0; i < n; ++i) new_index[static_cast<std::size_t>(order[static_cast<std::size_t>(i)])] = i;
  detail::RenumberedFaces faces = detail::renumber_faces(F, new_index);
  F_out = std::move(faces.F);
  L_out.resize(L.rows(), 3);
  for (Eigen::Index row = 0; row < L.rows(); ++row) L_out.row(row) = L.row(faces.face_order[static_cast<std::size_t>(row)]);
  twin_out.clear();
  if (twin.empty()) return;
  if (twin.size() != static_cast<std::size_t>(3 * F.rows()))
    throw std::invalid_argument("build_hierarchy: twin must have 3 entries per face");
  std::vector<Index> new_face(static_cast<std::size_t>(F.rows()));
  for (std::size_t row = 0; row < faces.face_order.size(); ++row)
    new_face[static_cast<std::size_t>(faces.face_order[row])] = static_cast<Index>(row);
  twin_out.resize(twin.size());
  for (std::size_t row = 0; row < faces.face_order.size(); ++row)
    for (std::size_t k = 0; k < 3; ++k) {
      const Index side = twin[3 * static_cast<std::size_t>(faces.face_order[row]) + k];
      if (side == kInvalid) {  // a boundary side
        twin_out[3 * row + k] = kInvalid;
        continue;
      }
      if (side < 0 || side >= static_cast<Index>(twin.size()))
        throw std::invalid_argument("build_hierarchy: twin entry out of range");
      twin_out[3 * row + k] = 3 * new_face[static_cast<std::size_t>(side / 3)] + side % 3;
    }
}

Hierarchy hierarchy_of(const Faces& F, const FaceLengths& L, const std::vector<Index>& twin, const HierarchyOptions& options);

}  // namespace

Hierarchy build_hierarchy(const TriangleMesh& mesh, const HierarchyOptions& options) {
  if (solved_on_tufted_cover(mesh, options.nonmanifold)) return build_hierarchy(tufted_cover(mesh), options);
  return hierarchy_of(mesh.F, face_lengths_from_positions(mesh.V, mesh.F), {}, options);
}

Hierarchy build_hierarchy(const IntrinsicMesh& mesh, const HierarchyOptions& options) {
  if (mesh.vertex_count != (mesh.F.size() == 0 ? 0 : mesh.F.maxCoeff() + 1))
    throw std::invalid_argument("build_hierarchy: every vertex must be used by a face (vertex_count = max index + 1)");
  return hierarchy_of(mesh.F, mesh.L, mesh.twin, options);
}

Hierarchy build_hierarchy(const TuftedCover& full_cover, const HierarchyOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  // Coarsened once per distinct sheet: a mirror sheet's copies would give every coarse basis
  // function twice (singular coarse operators), as in build_coarse_space.
  const TuftedCover cover = distinct_sheets(full_cover);
  const Index n = cover.input_vertex_count;
  const auto copies = static_cast<Index>(cover.to_input.size());
  HierarchyOptions cover_options = options;
  for (Index v : options.locked_vertices)
    if (v < 0 || v >= n) throw std::invalid_argument("build_hierarchy: locked vertex out of range");
  cover_options.locked_vertices = detail::copies_of(cover.to_input, n, options.locked_vertices);
  // The coarsest size counts input vertices; a cover level has about copies / n times as many.
  if (options.coarsest_vertices < 1) throw std::invalid_argument("build_hierarchy: coarsest_vertices must be >= 1");
  if (n > 0) {
    const double scaled = static_cast<double>(options.coarsest_vertices) * static_cast<double>(copies) / static_cast<double>(n);
    cover_options.coarsest_vertices = static_cast<Index>(std::min(std::round(scaled), double(std::numeric_limits<Index>::max())));
  }
  const IntrinsicMesh intrinsic = cover.intrinsic_mesh();
  Hierarchy H = hierarchy_of(intrinsic.F, intrinsic.L, intrinsic.twin, cover_options);

  // Per level, the copies merged into one unknown per input vertex (level 0: the input numbering,
  // since the cover numbers copies in increasing input order and every input vertex has one).
  std::vector<detail::MergedCopies> merged(H.levels.size());
  for (std::size_t k = 0; k < H.levels.size(); ++k) {
    std::vector<Index> input_of_copy(H.levels[k].to_fine.size());
    for (std::size_t c = 0; c < input_of_copy.size(); ++c)
      input_of_copy[c] = cover.to_input[static_cast<std::size_t>(H.levels[k].to_fine[c])];
    merged[k] = detail::merge_copies(input_of_copy, n);
  }
  for (std::size_t k = 0; k + 1 < H.levels.size(); ++k) {
    const HierarchyLevel& level = H.levels[k];
    const Eigen::SparseMatrix<double> W =
        copies_to_vertices(merged[k].unknown, static_cast<Index>(merged[k].to_input.size()),
                           detail::lumped_vertex_areas(level.F, level.L, level.vertex_count));
    Eigen::SparseMatrix<double> P = W * H.prolongations[k] * merged[k + 1].spread();
    P.makeCompressed();
    H.prolongations[k] = std::move(P);
  }
  // The levels on the unknowns: each copy named by its vertex, the gluing kept; level 0 the whole
  // cover's (the fine operators' mesh).
  for (std::size_t k = 0; k < H.levels.size(); ++k) {
    HierarchyLevel& level = H.levels[k];
    if (k == 0) static_cast<IntrinsicMesh&>(level) = full_cover.intrinsic_mesh();
    const std::vector<Index>& name = k == 0 ? full_cover.to_input : merged[k].unknown;
    for (Eigen::Index f = 0; f < level.F.rows(); ++f)
      for (int c = 0; c < 3; ++c) level.F(f, c) = name[static_cast<std::size_t>(level.F(f, c))];
    level.vertex_count = static_cast<Index>(merged[k].to_input.size());
    level.to_fine = std::move(merged[k].to_input);
  }
  if (!H.fine_order.empty()) {
    std::vector<Index> copy_order(H.fine_order.size());
    for (std::size_t i = 0; i < copy_order.size(); ++i) copy_order[i] = cover.to_input[static_cast<std::size_t>(H.fine_order[i])];
    H.fine_order = detail::merge_copies(copy_order, n).to_input;  // each vertex at its first copy
  }
  H.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return H;
}

namespace {

// The hierarchy of the intrinsic mesh (F, L) (the two public forms' common part).
Hierarchy hierarchy_of(const Faces& F, const FaceLengths& L, const std::vector<Index>& twin, const HierarchyOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (!(options.ratio > 0 && options.ratio < 1))
    throw std::invalid_argument("build_hierarchy: ratio must be in (0, 1)");
  if (options.coarsest_vertices < 1) throw std::invalid_argument("build_hierarchy: coarsest_vertices must be >= 1");
  if (options.max_levels < 1) throw std::invalid_argument("build_hierarchy: max_levels must be >= 1");
  if (options.threads < 0) throw std::invalid_argument("build_hierarchy: threads must be >= 0");
  const int threads = detail::requested_threads(options.threads);
  if (!(options.strong_neighbour_share >= 0 && options.strong_neighbour_share <= 1))
    throw std::invalid_argument("build_hierarchy: strong_neighbour_share must be in [0, 1]");

  // T is the triangulation being coarsened; its input vertices are the current level's vertices
  // (IntrinsicTriangulation::compacted restarts tracking), t_to_fine maps them to level-0 vertices.
  // With options.reorder, T's level-0 vertex i is input vertex fine_order[i].
  std::vector<Index> fine_order;
  const bool glued = !twin.empty();
  IntrinsicTriangulation T = [&] {
    if (!options.reorder)
      return glued ? IntrinsicTriangulation::from_glued_faces(F, L, twin) : IntrinsicTriangulation::from_lengths(F, L);
    Faces renumbered;
    FaceLengths lengths;
    std::vector<Index> renumbered_twin;
    breadth_first_numbering(F, L, twin, fine_order, renumbered, lengths, renumbered_twin);
    return glued ? IntrinsicTriangulation::from_glued_faces(renumbered, lengths, renumbered_twin)
                 : IntrinsicTriangulation::from_lengths(renumbered, std::move(lengths));
  }();
  // The independent-set passes read no angular coordinate (only ice::coarsen's metric does), so
  // their levels skip maintaining them (IntrinsicTriangulation::maintain_frames).
  const bool frameless = options.coarsening == LevelCoarsening::independent_sets && options.set_order != SetOrder::exact_cost;
  T.maintain_frames(!frameless);
  const Index n0 = T.num_input_vertices();
  for (Index v : options.locked_vertices)
    if (v < 0 || v >= n0) throw std::invalid_argument("build_hierarchy: locked vertex out of range");

  Hierarchy H;
  HierarchyLevel input;
  input.F = F;
  input.L = L;
  input.twin = twin;
  input.vertex_count = n0;
  input.to_fine.resize(static_cast<std::size_t>(n0));
  std::iota(input.to_fine.begin(), input.to_fine.end(), 0);
  H.levels.push_back(std::move(input));
  std::vector<Index> t_to_fine = options.reorder ? fine_order : H.levels[0].to_fine;

  H.stop_reason = "max_levels reached";
  while (H.num_levels() < options.max_levels) {
    const Index n = H.levels.back().num_vertices();
    if (n <= options.coarsest_vertices) {
      H.stop_reason = "coarsest size reached";
      break;
    }
    CoarsenOptions co;
    co.target_vertices = std::max<Index>(static_cast<Index>(std::ceil(options.ratio * n)), options.coarsest_vertices);
    co.area_weight = options.area_weight;
    co.remove_boundary = options.remove_boundary;
    co.threads = options.threads;  // the caller's (a greedy level below a quarter runs the parallel phase)
    if (!options.locked_vertices.empty()) {
      std::vector<Index> fine_to_t(static_cast<std::size_t>(n0), kInvalid);
      for (std::size_t i = 0; i < t_to_fine.size(); ++i) fine_to_t[static_cast<std::size_t>(t_to_fine[i])] = static_cast<Index>(i);
      for (Index v : options.locked_vertices)
        if (fine_to_t[static_cast<std::size_t>(v)] != kInvalid) co.locked_vertices.push_back(fine_to_t[static_cast<std::size_t>(v)]);
    }
    const CoarsenResult result =
        options.coarsening == LevelCoarsening::greedy
            ? coarsen(T, co)
            : coarsen_by_independent_sets(T, co, options.area_weight, options.set_order,
                                          options.coarsening == LevelCoarsening::independent_sets_by_metric,
                                          options.strong_neighbour_share, options.reorder, threads);
    // Every coarse level intrinsic Delaunay (non-negative cotan weights, which the strong-neighbour
    // rule and the next level's removals read): the removals restore Delaunay only around
    // themselves, so non-Delaunay edges of the input (an extrinsic mesh) that no removal reached
    // would stay.
    T.flip_to_delaunay();
    H.coarsen_seconds += result.seconds;
    if (T.num_vertices() > n - std::max<Index>(1, n / 10)) {
      H.stop_reason = "coarsening stalled (" + std::string(to_string(result.stop_reason)) + ")";
      break;
    }
    // The next level: a compact copy of T whose vertices are the surviving ones (tracking restarts,
    // so its own coarsening tracks exactly this level's vertices). Not needed after the last level.
    const bool last = T.num_vertices() <= options.coarsest_vertices || H.num_levels() + 1 >= options.max_levels;
    CompactMesh C;
    std::optional<IntrinsicTriangulation> next;
    if (last)
      C = T.compact();
    else
      next.emplace(T.compacted(&C));
    // This level's vertices × the next level's; level 0's rows back in the input's numbering (T's
    // input vertex i is input vertex fine_order[i]), set as P is built (a permutation product after
    // it took 0.2 s at 1.66M).
    const std::vector<Index> same_rows;
    Eigen::SparseMatrix<double> P = prolongation(T, C, options.reorder && H.num_levels() == 1 ? fine_order : same_rows);
    P.makeCompressed();
    HierarchyLevel level;
    level.to_fine.resize(C.to_input.size());
    for (std::size_t i = 0; i < C.to_input.size(); ++i)
      level.to_fine[i] = t_to_fine[static_cast<std::size_t>(C.to_input[i])];
    level.F = std::move(C.F);
    level.L = std::move(C.L);
    if (glued) level.twin = std::move(C.twin);  // a Δ-complex's levels keep their gluing
    level.vertex_count = C.vertex_count;
    H.prolongations.push_back(std::move(P));
    H.coarsening.push_back(result);
    H.levels.push_back(std::move(level));
    if (last) continue;
    T = std::move(*next);  // compacted() carried the frames setting
    t_to_fine = H.levels.back().to_fine;
  }
  H.fine_order = std::move(fine_order);
  H.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return H;
}

}  // namespace

}  // namespace ice
