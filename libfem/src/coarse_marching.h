#pragma once
/// \file coarse_marching.h
/// Fast marching with exact planar updates on an intrinsic mesh (private to libfem): the coarse
/// distances of the distance oracle and of the geodesic proxy (see fem/distance_oracle.h for the
/// update), the proxy's also with tracked virtual sources (CoarseMarcher's track_sources). A
/// MarchingMesh is what the marching reads around each vertex, with each vertex's chart, laid out once,
/// contiguously, in the order it is read, and shared (read-only) by any number of CoarseMarchers,
/// which hold the per-run front and values (one per thread).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "fem/operators.h"
#include "ice/triangle_geometry.h"

namespace fem::detail {

/// Throws std::invalid_argument (message prefixed by `who`) unless F and L are m × 3 with m > 0,
/// non-negative vertex indices and positive finite lengths.
inline void check_marching_mesh(const Faces& F, const FaceLengths& L, const std::string& who) {
  if (F.rows() == 0 || F.cols() != 3 || L.rows() != F.rows() || L.cols() != 3)
    throw std::invalid_argument(who + ": the coarse mesh needs faces (m x 3) and lengths of the same shape");
  if (F.minCoeff() < 0) throw std::invalid_argument(who + ": negative coarse vertex index");
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (!(L.row(f).minCoeff() > 0) || !std::isfinite(L.row(f).sum()))
      throw std::invalid_argument(who + ": coarse face " + std::to_string(f) + " has a non-positive or non-finite length");
}

/// A side whose gluing is not known (in a `twin` vector: per side 3f + k, the side glued to it,
/// −1 on the boundary).
constexpr Index kUnknownTwin = -2;

/// Sides of unknown gluing (twin[side] == kUnknownTwin; every side when `twin` is empty), grouped
/// by their end vertices and length: the sides of one group are taken as one edge (two: an interior
/// edge, one: a boundary side, more: parallel edges of one length, whose gluing stays unknown).
/// Groups in the order of their keys; sides as 3f + k.
inline std::vector<std::vector<Index>> group_unknown_sides(const Faces& F, const FaceLengths& L, const std::vector<Index>& twin) {
  struct Side {
    Index low, high;
    double length;
    Index side;
  };
  std::vector<Side> unknown;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (twin.empty() || twin[static_cast<std::size_t>(3 * f + k)] == kUnknownTwin) {
        const Index u = F(f, k), w = F(f, (k + 1) % 3);
        unknown.push_back({std::min(u, w), std::max(u, w), L(f, k), static_cast<Index>(3 * f + k)});
      }
  const auto key_less = [](const Side& p, const Side& q) {
    return p.low != q.low ? p.low < q.low : p.high != q.high ? p.high < q.high : p.length < q.length;
  };
  std::sort(unknown.begin(), unknown.end(), key_less);
  std::vector<std::vector<Index>> groups;
  for (std::size_t i = 0; i < unknown.size();) {
    std::size_t j = i + 1;
    while (j < unknown.size() && !key_less(unknown[i], unknown[j])) ++j;
    groups.emplace_back();
    for (std::size_t g = i; g < j; ++g) groups.back().push_back(unknown[g].side);
    i = j;
  }
  return groups;
}

/// `twin` (empty: all unknown) with its unknown sides glued by group_unknown_sides: pairs glued,
/// single sides on the boundary (−1), larger groups left unknown.
inline std::vector<Index> complete_gluing(const Faces& F, const FaceLengths& L, std::vector<Index> twin) {
  const std::vector<std::vector<Index>> groups = group_unknown_sides(F, L, twin);
  if (twin.empty()) twin.assign(static_cast<std::size_t>(3 * F.rows()), kUnknownTwin);
  for (const std::vector<Index>& group : groups) {
    if (group.size() == 1) twin[static_cast<std::size_t>(group[0])] = -1;
    if (group.size() == 2) {
      twin[static_cast<std::size_t>(group[0])] = group[1];
      twin[static_cast<std::size_t>(group[1])] = group[0];
    }
  }
  return twin;
}

class MarchingMesh {
 public:
  /// Faces and lengths of a valid intrinsic mesh (a Δ-complex: repeated corners allowed) on
  /// vertex_count vertices, and its sides' gluing (per side 3f + k: the side glued to it, −1 on the
  /// boundary, kUnknownTwin where unknown; empty: matched by complete_gluing). The gluing gives each
  /// vertex its chart (the angle at which each of its edges leaves it), which the marching uses to
  /// carry virtual sources from vertex to vertex; a vertex whose corners are not one fan (parallel
  /// edges of unknown gluing, a non-manifold vertex) has none.
  MarchingMesh(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count, const std::vector<Index>& twin = {})
      : vertex_count_(vertex_count) {
    // Per corner 3f + k: its angle (between its sides k and k + 2; the lengths as given, a face off
    // the triangle inequality by round-off is flat), and the chart angle of its first edge.
    std::vector<double> angle(static_cast<std::size_t>(3 * F.rows()));
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        angle[static_cast<std::size_t>(3 * f + k)] = ice::angle_opposite(L(f, k), L(f, (k + 2) % 3), L(f, (k + 1) % 3));
    const std::vector<double> chart = corner_charts(F, angle, complete_gluing(F, L, twin));
    // The chart angle of the edge from corner k of face f to its next (first) or previous (second)
    // corner: a corner spans [chart, chart + angle] from its first edge to its second.
    const auto to_first = [&](Eigen::Index f, int k) { return chart[static_cast<std::size_t>(3 * f + k)]; };
    const auto to_second = [&](Eigen::Index f, int k) { return to_first(f, k) + angle[static_cast<std::size_t>(3 * f + k)]; };
    // Each charted vertex's spokes (its edges, by chart angle): the first edge of each corner, and on
    // the boundary the last corner's second edge.
    {
      const auto spoke = [](double direction, double length) {
        return Spoke{static_cast<float>(direction), static_cast<float>(length), static_cast<float>(std::cos(direction)),
                     static_cast<float>(std::sin(direction))};
      };
      std::vector<std::pair<Index, Spoke>> spokes;
      for (Eigen::Index f = 0; f < F.rows(); ++f)
        for (int k = 0; k < 3; ++k) {
          if (std::isnan(to_first(f, k))) continue;
          const auto v = static_cast<std::size_t>(F(f, k));
          spokes.push_back({F(f, k), spoke(to_first(f, k), L(f, k))});
          if (boundary_[v] && std::abs(to_second(f, k) - angle_sum_[v]) < 1e-9 * (1 + angle_sum_[v]))
            spokes.push_back({F(f, k), spoke(angle_sum_[v], L(f, (k + 2) % 3))});
        }
      std::sort(spokes.begin(), spokes.end(), [](const auto& p, const auto& q) {
        return p.first != q.first ? p.first < q.first : p.second.angle < q.second.angle;
      });
      spoke_start_.assign(static_cast<std::size_t>(vertex_count) + 1, 0);
      for (const auto& spoke : spokes) {
        ++spoke_start_[static_cast<std::size_t>(spoke.first) + 1];
        spokes_.push_back(spoke.second);
      }
      for (std::size_t v = 0; v < static_cast<std::size_t>(vertex_count); ++v) spoke_start_[v + 1] += spoke_start_[v];
    }
    const auto charts = [](double u_to_x, double x_to_u, double w_to_u, int u_sense, int x_sense, int w_sense) {
      return Charts{static_cast<float>(u_to_x), static_cast<float>(x_to_u), static_cast<float>(w_to_u),
                    static_cast<signed char>(u_sense), static_cast<signed char>(x_sense), static_cast<signed char>(w_sense),
                    static_cast<float>(std::cos(u_to_x)), static_cast<float>(std::sin(u_to_x)),
                    static_cast<float>(std::cos(x_to_u)), static_cast<float>(std::sin(x_to_u))};
    };
    sum_cos_.resize(static_cast<std::size_t>(vertex_count));
    sum_sin_.resize(static_cast<std::size_t>(vertex_count));
    for (std::size_t v = 0; v < static_cast<std::size_t>(vertex_count); ++v) {
      sum_cos_[v] = std::cos(angle_sum_[v]);
      sum_sin_[v] = std::sin(angle_sum_[v]);
    }
    // Around each vertex u: its neighbours w (multi-edges merged: the shortest length counts), and
    // for each, the faces (u, w, x) through which w can be updated from u and x.
    struct Relation {
      Index u, w, x;
      double to_w, to_x, across;  // |u w|, |u x|, |w x|
      Charts charts;
    };
    std::vector<Relation> relations;
    relations.reserve(static_cast<std::size_t>(6 * F.rows()));
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        // Corner k at u; "first" is corner k+1, "second" corner k+2.
        const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
        const Index u = F(f, k), first = F(f, k1), second = F(f, k2);
        const double to_first_length = L(f, k), across = L(f, k1), to_second_length = L(f, k2);
        // w = first, x = second: at u the base edge (to x) is u's second edge and w lies back from
        // it; at x (corner k2, whose first edge goes to u) w lies onward; at w (corner k1, whose
        // second edge goes to u) x lies back.
        relations.push_back({u, first, second, to_first_length, to_second_length, across,
                             charts(to_second(f, k), to_first(f, k2), to_second(f, k1), -1, 1, -1)});
        relations.push_back({u, second, first, to_second_length, to_first_length, across,
                             charts(to_first(f, k), to_second(f, k1), to_first(f, k2), 1, -1, 1)});
      }
    std::sort(relations.begin(), relations.end(), [](const Relation& p, const Relation& q) {
      return p.u != q.u ? p.u < q.u : p.w < q.w;
    });
    neighbour_start_.assign(static_cast<std::size_t>(vertex_count) + 1, 0);
    repeated_corner_.assign(static_cast<std::size_t>(vertex_count), 0);
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        if (F(f, k) == F(f, (k + 1) % 3)) repeated_corner_[static_cast<std::size_t>(F(f, k))] = 1;
    for (std::size_t i = 0; i < relations.size();) {
      std::size_t j = i;
      Neighbour neighbour{relations[i].w, static_cast<float>(relations[i].to_w), static_cast<Index>(faces_.size())};
      for (; j < relations.size() && relations[j].u == relations[i].u && relations[j].w == relations[i].w; ++j) {
        const Relation& r = relations[j];
        // One edge is seen from at most two faces, with one length; more, or another length, are
        // parallel edges: which one a point's coordinates refer to is unknown.
        if (j - i >= 2 || static_cast<float>(r.to_w) != neighbour.length) neighbour.parallel = true;
        neighbour.length = std::min(neighbour.length, static_cast<float>(r.to_w));
        // A face whose other corner is u again (a self-folded face, around a loop edge) offers no
        // source consistent with both copies of u: only its edge counts.
        if (r.x != r.u) {
          faces_.push_back({r.x, layout(r.to_w, r.to_x, r.across)});
          face_charts_.push_back(r.charts);
        }
      }
      neighbour_back_.push_back(neighbour.parallel ? kNoDirection : relations[i].charts.w_to_u);
      neighbours_.push_back(neighbour);
      ++neighbour_start_[static_cast<std::size_t>(relations[i].u) + 1];
      i = j;
    }
    for (std::size_t v = 0; v < static_cast<std::size_t>(vertex_count); ++v) neighbour_start_[v + 1] += neighbour_start_[v];
    neighbours_.push_back({0, 0, static_cast<Index>(faces_.size()), false});  // sentinel: the end of the last face range
  }

  Eigen::Index vertex_count() const { return vertex_count_; }
  /// The length of the one edge between u and w; NaN if they are not neighbours, are joined by
  /// parallel edges, or one of them is a repeated corner of some face (a loop edge): then
  /// barycentric weights over {u, w} do not say which flat layout they refer to.
  double edge_length(Index u, Index w) const {
    constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
    if (repeated_corner_[static_cast<std::size_t>(u)] || repeated_corner_[static_cast<std::size_t>(w)]) return kUnknown;
    const Index end = neighbour_start_[static_cast<std::size_t>(u) + 1];
    for (Index i = neighbour_start_[static_cast<std::size_t>(u)]; i < end; ++i) {
      const Neighbour& neighbour = neighbours_[static_cast<std::size_t>(i)];
      if (neighbour.w == w) return neighbour.parallel ? kUnknown : neighbour.length;
    }
    return kUnknown;
  }

 private:
  friend class CoarseMarcher;
  static constexpr float kNoDirection = std::numeric_limits<float>::quiet_NaN();
  /// A face flattened for the update of its vertex v from its other corners a, b: a = (0, 0),
  /// b = (base, 0), v = (vx, vy), vy > 0 unless the face is degenerate. Floats: the geometry is
  /// read for every update and the values stay double.
  struct Layout {
    float base, half_inverse_base, vx, vy;
  };
  static Layout layout(double to_a, double base, double to_b) {
    const double vx = (to_a * to_a - to_b * to_b + base * base) / (2 * base);
    return {static_cast<float>(base), static_cast<float>(0.5 / base), static_cast<float>(vx),
            static_cast<float>(std::sqrt(std::max(0.0, to_a * to_a - vx * vx)))};
  }
  /// Where a face (u, w, x) lies in its corners' charts: the chart angles of the edges u → x, x → u
  /// and w → u, and on which side of that edge (+1: onward in the chart, −1: back) the face's third
  /// corner (w at u and x, x at w) lies. NaN angles where a corner's vertex has no chart.
  struct Charts {
    float u_to_x, x_to_u, w_to_u;
    signed char u_sense, x_sense, w_sense;
    float u_cos, u_sin, x_cos, x_sin;  ///< of u_to_x and x_to_u (the marching's turns by angle sums)
  };
  /// A neighbour w of u: the edge length and where its faces start in faces_ (they end where the
  /// next neighbour's start).
  struct Neighbour {
    Index w;
    float length;
    Index faces_begin;
    bool parallel = false;  ///< several edges join u and w (length is the shortest)
  };
  /// A face (u, w, x) for updating w from u and x: the face flattened with u at the origin and x
  /// on the axis (along its edges, w is updated from u and from x by their own edge relaxations).
  struct FaceEntry {
    Index x;
    Layout layout;
  };
  /// A face entry's charts (kept apart: the plain marching does not read them).
  const Charts& charts_of(const FaceEntry& face) const { return face_charts_[static_cast<std::size_t>(&face - faces_.data())]; }
  /// Per corner 3f + k: the chart angle of its first edge (to corner k + 1), walking each vertex's
  /// fan from its first corner (on the boundary, the one whose first edge is a boundary side);
  /// NaN for the corners of a vertex that is not one fan (`angle`: per corner). Fills angle_sum_ and
  /// boundary_.
  std::vector<double> corner_charts(const Faces& F, const std::vector<double>& angle, const std::vector<Index>& twin);

  Eigen::Index vertex_count_;
  std::vector<Index> neighbour_start_;  ///< CSR of neighbours_ by vertex
  std::vector<Neighbour> neighbours_;    ///< (plus a sentinel closing the last face range)
  std::vector<FaceEntry> faces_;
  std::vector<Charts> face_charts_;  ///< per entry of faces_
  std::vector<float> neighbour_back_;  ///< per entry of neighbours_: the chart angle at w of its edge to u (NaN: none)
  std::vector<char> repeated_corner_;  ///< the vertex is two corners of one face
  std::vector<double> angle_sum_;      ///< per vertex: its chart's full turn (NaN: no chart)
  std::vector<char> boundary_;         ///< per vertex: its fan is open (its chart does not wrap)
  std::vector<double> sum_cos_, sum_sin_;  ///< per vertex: cos and sin of its angle sum
  /// An edge leaving a charted vertex: its chart angle and length.
  struct Spoke {
    float angle, length, cos, sin;  ///< (cos and sin of angle)
  };
  std::vector<Index> spoke_start_;  ///< CSR of spokes_ by vertex
  std::vector<Spoke> spokes_;
};

inline std::vector<double> MarchingMesh::corner_charts(const Faces& F, const std::vector<double>& angle,
                                                      const std::vector<Index>& twin) {
  const auto n = static_cast<std::size_t>(vertex_count_);
  const std::size_t sides = static_cast<std::size_t>(3 * F.rows());
  std::vector<double> chart(sides, std::numeric_limits<double>::quiet_NaN());
  angle_sum_.assign(n, std::numeric_limits<double>::quiet_NaN());
  boundary_.assign(n, 0);
  constexpr Index kNone = -1, kUnknown = kUnknownTwin;
  // The corners around a vertex, onward: corner k of f is followed by the corner of the same vertex
  // across f's side k + 2 (from its second corner to it); back: across its side k.
  const auto onward = [&](Index corner) -> Index {
    const Index f = corner / 3, k = corner % 3, t = twin[static_cast<std::size_t>(3 * f + (k + 2) % 3)];
    if (t < 0) return t == -1 ? kNone : kUnknown;
    return F(t / 3, t % 3) == F(f, k) ? t : kUnknown;  // that side runs from the vertex
  };
  const auto back = [&](Index corner) -> Index {
    const Index f = corner / 3, k = corner % 3, t = twin[static_cast<std::size_t>(3 * f + k)];
    if (t < 0) return t == -1 ? kNone : kUnknown;
    const Index next = 3 * (t / 3) + (t % 3 + 1) % 3;  // that side runs to the vertex
    return F(next / 3, next % 3) == F(f, k) ? next : kUnknown;
  };
  std::vector<Index> corner_count(n, 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ++corner_count[static_cast<std::size_t>(F(f, k))];
  for (std::size_t c0 = 0; c0 < sides; ++c0) {
    const auto v = static_cast<std::size_t>(F(static_cast<Eigen::Index>(c0 / 3), static_cast<int>(c0 % 3)));
    if (!std::isnan(angle_sum_[v]) || corner_count[v] < 0) continue;  // its fan done (or found not one)
    // Back to the fan's first corner (or round to c0), then onward, summing the corner angles.
    Index first = static_cast<Index>(c0);
    bool known = true, open = false;
    for (Index step = 0, c = first; step <= corner_count[v]; ++step) {
      const Index previous = back(c);
      if (previous == kUnknown) known = false;
      if (previous < 0) {
        open = previous == kNone;
        first = c;
        break;
      }
      if (previous == static_cast<Index>(c0)) break;
      c = previous;
    }
    Index visited_count = 0;
    double sum = 0;
    for (Index c = first; known && visited_count <= corner_count[v];) {
      chart[static_cast<std::size_t>(c)] = sum;
      sum += angle[static_cast<std::size_t>(c)];
      ++visited_count;
      const Index next = onward(c);
      if (next == kUnknown) known = false;
      if (next < 0 || next == first) break;
      c = next;
    }
    if (known && visited_count == corner_count[v]) {
      angle_sum_[v] = sum;
      boundary_[v] = open ? 1 : 0;
    } else {
      corner_count[v] = -1;  // not one fan: no chart
    }
  }
  for (std::size_t c = 0; c < sides; ++c)
    if (std::isnan(angle_sum_[static_cast<std::size_t>(F(static_cast<Eigen::Index>(c / 3), static_cast<int>(c % 3)))]))
      chart[c] = std::numeric_limits<double>::quiet_NaN();
  return chart;
}

/// One marching run at a time over a MarchingMesh (which must outlive it).
class CoarseMarcher {
 public:
  /// A vertex where the front starts, at a given distance (a point source inside a face starts at
  /// its corners, at their planar distances from it), and the source it belongs to.
  struct Seed {
    Index vertex;
    double value;
    Index source = 0;
  };
  /// With `reopen`, a vertex whose turn has come is reopened when a face through two later corners
  /// finds it nearer (by more than kReopenGain): the updates are exact in the plane only when both
  /// corners were done first, which an obtuse face's far corner is not — the vertex behind it was
  /// reached along an edge or through another face, too far. Measured: a proxy geodesic from a
  /// fine source (3 sources, two of them inside coarse faces), 3 subdivisions, traced lengths,
  /// CGAL's holes at 100 coarse vertices: mean error against exact geodesics 1.53 % → 0.66 % (the
  /// known seeds alone: 2.70 → 1.01 % without subdivisions, nothing with 3); over the 40 meshes ×
  /// 4 budgets of the accuracy protocol 0.455 → 0.389 % (geometric mean, both changes). The price:
  /// every done neighbour's faces are looked at again, 1.57× the time of a run; the distance
  /// oracle, whose runs start at coarse vertices and whose distances are symmetrised, gains 1-4 %
  /// on some meshes and loses as much on others (`oracle-accuracy --coarse 200`), so it does
  /// without.
  ///
  /// With `track_sources`, each done vertex also carries where its value comes from (a virtual
  /// source and the wedge of straight lines from it known to be paths, in its chart), and a face
  /// updates its third corner from the source of either other corner alone when the straight line
  /// stays in that wedge and passes no vertex around the corner on the wrong side: exact lines over
  /// many faces instead of one planar update per face, whose errors add up along the front —
  /// towards too long on the coarse meshes of curved surfaces, whose every vertex is a cone (the
  /// planar update from two corners reached around a cone from two sides is not a distance from
  /// one source). Measured: a proxy geodesic of ICE coarse meshes (traced lengths, 1 subdivision,
  /// with the curvature correction's divisor measured for it, fem::kProxyCorrectionDivisor) against
  /// exact geodesics, 40 meshes × 1–10 %: 0.546 % → 0.458 % (geometric mean), at 5 % and 10 % 0.532
  /// → 0.451 % and 0.321 → 0.221 % (medians); marching on armadillo_43k's own mesh 0.345 % → 0.045 %.
  /// A planar update from two done corners counts only where the point it places agrees with the
  /// direction of either corner's virtual source (kPlanarCheck): behind a saddle it would otherwise
  /// be a shortcut (docs/measurements.md, "Tracked virtual sources; the planar check": 40 meshes,
  /// 2026-11-29).
  /// It costs 2–3× a run (1.58M vertices at 1 %: 89 ms a solve); the oracle's all-pairs marching
  /// (`oracle-accuracy --coarse 200`, 6 meshes: 0–22 % less error) would take 3.9× as long and does
  /// without.
  CoarseMarcher(const MarchingMesh& mesh, bool reopen = false, bool track_sources = false)
      : mesh_(mesh), reopen_(reopen), track_(track_sources) {}

  /// Distances from `source` to every vertex into `distance` (+∞ where unreachable).
  void run(Index source, std::vector<double>& distance) { run(std::vector<Seed>{{source, 0.0}}, distance, source_); }

  /// Distances from the seeds (the least seed value + path length over the seeds; a vertex seeded
  /// twice keeps the smaller value) into `distance` (+∞ where unreachable), and into `source` the
  /// source of the seed each vertex's value comes from (-1 where unreachable). A face updates a
  /// vertex through its interior only from two corners of one source (corners of two sources are
  /// not consistent with one virtual source). A seed's value counts as known for those face updates
  /// before its turn in the front: a source on an edge (or inside a face) seeds a near and a far
  /// corner, and the far one's turn comes after the near one's neighbours across that edge were
  /// reached along edges only — which made every distance from such a source too long.
  void run(const std::vector<Seed>& seeds, std::vector<double>& distance, std::vector<Index>& source) {
    if (track_) march<true>(seeds, distance, source);
    else march<false>(seeds, distance, source);
  }

 private:
  template <bool kTrack>
  void march(const std::vector<Seed>& seeds, std::vector<double>& distance, std::vector<Index>& source) {
    const auto n = static_cast<std::size_t>(mesh_.vertex_count_);
    distance.assign(n, kInfinity);
    source.assign(n, -1);
    accepted_.assign(n, 0);
    position_.assign(n, -1);
    front_.assign(n + 2, kSentinel);
    if constexpr (kTrack) {
      pending_.assign(n, Candidate{});
      virtual_.assign(n, VirtualSource{});
    }
    front_size_ = 0;
    for (const Seed& seed : seeds)
      if (seed.value < distance[static_cast<std::size_t>(seed.vertex)]) {
        distance[static_cast<std::size_t>(seed.vertex)] = seed.value;
        source[static_cast<std::size_t>(seed.vertex)] = seed.source;
        accepted_[static_cast<std::size_t>(seed.vertex)] = kSeeded;
        lower(seed.vertex, distance);
      }
    const auto& neighbours = mesh_.neighbours_;
    const auto& faces = mesh_.faces_;
    while (front_size_ > 0) {
      const Index u = pop();
      const double value = distance[static_cast<std::size_t>(u)];
      const Index from = source[static_cast<std::size_t>(u)];
      const VirtualSource* from_u = nullptr;
      if constexpr (kTrack) {
        virtual_[static_cast<std::size_t>(u)] = resolve(u, pending_[static_cast<std::size_t>(u)]);
        from_u = &virtual_[static_cast<std::size_t>(u)];
      }
      accepted_[static_cast<std::size_t>(u)] = kAccepted;
      // Each neighbour w once: along the edge, and through every face (u, w, x) — from u's virtual
      // source, and with x done too from x's and from the source that u's and x's values place
      // (the face's turn for w comes when the second of u and x is accepted); with reopen_, a done
      // w through those faces only.
      const Index end = mesh_.neighbour_start_[static_cast<std::size_t>(u) + 1];
      for (Index i = mesh_.neighbour_start_[static_cast<std::size_t>(u)]; i < end; ++i) {
        const MarchingMesh::Neighbour& neighbour = neighbours[static_cast<std::size_t>(i)];
        const auto w = static_cast<std::size_t>(neighbour.w);
        const bool closed = accepted_[w] == kAccepted;
        if (closed && !reopen_) continue;
        // What a face's candidate must beat to matter: w's value (less the reopening margin for a
        // done w) and, for an open one, the path along the edge.
        const double along = value + neighbour.length;
        const double limit = closed ? distance[w] * (1 - kReopenGain) : std::min(distance[w], along);
        Candidate through;
        const Index faces_end = neighbours[static_cast<std::size_t>(i) + 1].faces_begin;
        for (Index k = neighbour.faces_begin; k < faces_end; ++k) {
          const MarchingMesh::FaceEntry& face = faces[static_cast<std::size_t>(k)];
          const auto x = static_cast<std::size_t>(face.x);
          if constexpr (kTrack) {
            consider(through, from_tracked(*from_u, u, false, face, std::min(through.value, limit)));
            if (accepted_[x] == kAccepted && source[x] == from)
              consider(through, from_tracked(virtual_[x], face.x, true, face, std::min(through.value, limit)));
          }
          if (accepted_[x] != kOpen && source[x] == from) {
            Point placed;
            double planar = from_values(value, distance[x], face.layout, placed);
            if constexpr (kTrack)
              if (planar < through.value && accepted_[x] == kAccepted &&
                  !agrees(*from_u, u, false, face, placed) && !agrees(virtual_[x], face.x, true, face, placed))
                planar = kInfinity;
            if (planar < through.value) {
              through.value = planar;
              if constexpr (kTrack) through = Candidate{planar, 0, placed, {Point{0, 0}, Point{face.layout.base, 0}}, &face, nullptr};
            }
          }
        }
        if (through.value < limit || (!closed && along < distance[w])) {
          distance[w] = std::min(through.value, along);
          if constexpr (kTrack)  // through the face, or from u itself along the edge
            pending_[w] = through.value <= along ? through : Candidate{along, value, {}, {}, nullptr, &neighbour};
          source[w] = from;
          accepted_[w] = kOpen;  // a seed beaten, or a done vertex reopened
          lower(neighbour.w, distance);
        }
      }
    }
  }

  static constexpr double kInfinity = std::numeric_limits<double>::infinity();
  /// Angles of the charts and layouts are floats: directions this close (radians) are taken as one.
  static constexpr double kAngleTolerance = 1e-6;
  /// How far below 0 the squared height of the virtual source may fall and still be read as 0:
  /// the layout's floats carry relative errors of ~1e-7 into sx² and da².
  static constexpr double kOnLineTolerance = 1e-5;
  // With tracked sources, a planar update from two done corners counts only if the point it places
  // lies, within this angle (radians) seen from u or from x, in the direction of that corner's own
  // virtual source: values that came around a saddle from its two sides place a point that is no
  // source, and the line from it passes through the saddle's excess angle — a shortcut (CGAL's
  // mannequin-devil at 130 coarse vertices: 23 % of the largest distance too short with 2
  // subdivisions). On a flat mesh both corners' sources are the point itself. Measured there
  // (against marching on the fine mesh, 0 / 1 / 2 / 3 subdivisions, mean error): without the check
  // 1.63 / 2.36 / 4.99 / 0.81 %, with 0.2 rad 1.53 / 1.05 / 0.86 / 0.80 %, 0.05 rad 1.47 / 0.87 /
  // 0.86 / 0.81 %, 0.01 rad 1.52 / 0.94 / 0.94 / 0.87 %; over the accuracy protocol's 40 meshes see
  // docs/measurements.md, "Tracked virtual sources; the planar check".
  static constexpr double kPlanarCheck = 0.05;
  /// How much nearer a face must find a done vertex to reopen it: above the floats' round-off, so
  /// that equal values reached through two faces do not reopen each other.
  static constexpr double kReopenGain = 1e-6;
  /// A direction's cosine and sine.
  struct Turn {
    double cos = 1, sin = 0;
  };
  static Turn rotate(Turn a, Turn b) { return {a.cos * b.cos - a.sin * b.sin, a.sin * b.cos + a.cos * b.sin}; }
  /// Where a done vertex's value comes from, in its chart: a (virtual) source `offset` from the true
  /// one (0 for a straight line from it; a vertex's own value where paths turn at that vertex), at
  /// `radius` in the direction `angle` (radius 0: none — a seed), and the wedge of straight lines from
  /// it known to be paths (between the lines through the two bound points, at bound_radius in the
  /// directions bound_turn from the source's, the short way round; it holds the line to the vertex):
  /// a window of exact geodesics (Mitchell, Mount and Papadimitriou) kept per vertex, which says which
  /// lines onward from the vertex are paths too. The turns' cosines and sines are kept with them.
  struct VirtualSource {
    double offset = 0, radius = 0, angle = 0;
    Turn direction;
    double bound_radius[2] = {0, 0};
    Turn bound_turn[2];
  };
  using Point = ice::Vec2;
  static double cross(Point o, Point p, Point q) { return ice::orient2d(o, p, q); }
  static double dot(Point o, Point p, Point q) { return (p.x - o.x) * (q.x - o.x) + (p.y - o.y) * (q.y - o.y); }
  /// A value of w through one face (the virtual source and its wedge's bound points in the face's
  /// layout: u at the origin, x at (base, 0), w above), or along an edge (`edge`, from the vertex at
  /// `offset`); converted into w's chart when w's turn comes.
  struct Candidate {
    double value = kInfinity;
    double offset = 0;
    Point source, bound[2];
    const MarchingMesh::FaceEntry* face = nullptr;
    const MarchingMesh::Neighbour* edge = nullptr;
  };
  static void consider(Candidate& best, const Candidate& candidate) {
    if (candidate.value < best.value) best = candidate;
  }
  // Where the straight line from s, s.y <= 0, to w = (vx, vy) crosses the base's line (y = 0),
  // times vy − sy (> 0): sx (vy − sy) + (−sy)(vx − sx). (Scaled: no division in the hot loop.)
  static double crossing_times_rise(Point s, const MarchingMesh::Layout& layout) {
    return s.x * (layout.vy - s.y) - s.y * (layout.vx - s.x);
  }
  // The length of that line where it crosses the base between u and x, else +∞.
  static double through_base(Point s, const MarchingMesh::Layout& layout) {
    const double at = crossing_times_rise(s, layout), rise = layout.vy - s.y;
    if (at < 0 || at > layout.base * rise) return kInfinity;
    const double dx = layout.vx - s.x;
    return std::sqrt(dx * dx + rise * rise);
  }
  // The turn sense·(base − angle) at vertex c, reduced to [0, its angle sum) (no wrap on the
  // boundary), and its cosine and sine from those of base and angle (both in [0, angle sum]).
  double away(std::size_t c, int sense, double base, Turn base_turn, double angle, Turn angle_turn, Turn& out) const {
    double turn = sense * (base - angle);
    out = {base_turn.cos * angle_turn.cos + base_turn.sin * angle_turn.sin,
           sense * (base_turn.sin * angle_turn.cos - base_turn.cos * angle_turn.sin)};
    if (mesh_.boundary_[c]) return turn;
    const Turn full{mesh_.sum_cos_[c], mesh_.sum_sin_[c]};
    if (turn < 0) {
      turn += mesh_.angle_sum_[c];
      out = rotate(out, full);
    } else if (turn >= mesh_.angle_sum_[c]) {
      turn -= mesh_.angle_sum_[c];
      out = rotate(out, Turn{full.cos, -full.sin});
    }
    return turn;
  }
  // A corner's chart read along its face's base edge (u's towards x, or x's towards u when `at_x`):
  // the edge's chart angle (NaN where the corner has no chart), the sense in which turns away from
  // w count, and the angle's cos and sin.
  struct BaseFrame {
    double angle;
    int sense;
    Turn turn;
  };
  BaseFrame base_frame(const MarchingMesh::FaceEntry& face, bool at_x) const {
    const MarchingMesh::Charts& charts = mesh_.charts_of(face);
    return at_x ? BaseFrame{charts.x_to_u, charts.x_sense, Turn{charts.x_cos, charts.x_sin}}
                : BaseFrame{charts.u_to_x, charts.u_sense, Turn{charts.u_cos, charts.u_sin}};
  }
  // Whether the direction from a corner (u, or x when `at_x`) to the point `placed` of the face's
  // layout is that of the corner's own virtual source (within kPlanarCheck radians); true where the
  // corner has no chart or source to compare with.
  bool agrees(const VirtualSource& known, Index corner, bool at_x, const MarchingMesh::FaceEntry& face, Point placed) const {
    const BaseFrame base = base_frame(face, at_x);
    if (!(known.radius > 0) || std::isnan(base.angle)) return true;
    Turn to_source;
    const double turn = away(static_cast<std::size_t>(corner), base.sense, base.angle, base.turn, known.angle, known.direction, to_source);
    // The placed point's turn away from w from the base edge, seen from the corner.
    const double dx = at_x ? face.layout.base - placed.x : placed.x, dy = -placed.y;
    const double placed_turn = std::atan2(dy, dx);
    return std::abs(placed_turn - turn) <= kPlanarCheck;
  }
  // w's value from the virtual source of one corner of its face (u, or x when `at_x`): the source
  // laid out in the face through the corner's chart — it must lie on the far side of the base
  // (within a half turn of the base edge, away from w), the line from it to w cross the base and
  // lie in the source's wedge, and no vertex around the corner lie between that line and the line
  // to the corner (which is known to be a path; a saddle vertex between would make the line to w
  // a shortcut). Candidates no nearer than `limit` are not checked.
  Candidate from_tracked(const VirtualSource& known, Index corner, bool at_x, const MarchingMesh::FaceEntry& face,
                         double limit) const {
    Candidate out;
    const auto [base_angle, sense, base_turn] = base_frame(face, at_x);
    if (!(known.radius > 0) || std::isnan(base_angle) || !(face.layout.vy > 0)) return out;
    const auto c = static_cast<std::size_t>(corner);
    Turn to_source;
    const double turn = away(c, sense, base_angle, base_turn, known.angle, known.direction, to_source);
    if (!(turn > 0 && turn < ice::kPi)) return out;
    const Point here{at_x ? face.layout.base : 0.0, 0.0}, other{at_x ? 0.0 : face.layout.base, 0.0};
    // A point at `radius` from the corner, turned by `t` (cos, sin) away from w from the base edge.
    const auto lay = [&](double radius, Turn t) {
      return Point{at_x ? here.x - radius * t.cos : radius * t.cos, -radius * t.sin};
    };
    out.source = lay(known.radius, to_source);
    const Point s = out.source, w{face.layout.vx, face.layout.vy};
    // The line to w must cross the base, or pass beyond its other end (then it bends there, below);
    // one passing beyond the corner is the corner's path along its edge.
    const double crossing_at = crossing_times_rise(s, face.layout) / (w.y - s.y);
    if (at_x ? crossing_at > face.layout.base : crossing_at < 0) return out;
    const double length = std::sqrt(dot(s, w, w));
    if (!(known.offset + length < limit)) return out;  // (no better than what w has: not worth checking)
    // In the wedge: w not on the far side of either bound line (the side away from the other bound).
    Point bounds[2];
    for (int j = 0; j < 2; ++j)
      bounds[j] = known.bound_radius[j] > 0
                      ? lay(known.bound_radius[j], rotate(to_source, Turn{known.bound_turn[j].cos, -sense * known.bound_turn[j].sin}))
                      : here;
    // A line that leaves the wedge, or passes a vertex around the corner on the wrong side, is not
    // a path; the shortest path that is bends at the outermost such point (a string pulled taut
    // around it) — the continuation of the straight value across the line through that point,
    // where a plain rejection would make the result jump between two candidates.
    bool bent = false;
    Point bend;
    const double wedge = cross(s, bounds[0], bounds[1]);
    const double slack = kAngleTolerance * (dot(s, w, w) + dot(s, bounds[0], bounds[0]) + dot(s, bounds[1], bounds[1]));
    const double orientation = wedge >= 0 ? 1.0 : -1.0;
    if (orientation * cross(s, bounds[0], w) < -slack) bent = true, bend = bounds[0];
    else if (orientation * cross(s, w, bounds[1]) < -slack) bent = true, bend = bounds[1];
    if (at_x ? crossing_at < 0 : crossing_at > face.layout.base) {
      if (!bent || cross(s, bend, other) * cross(s, w, other) > 0) bend = other;  // (the outer of the two)
      bent = true;
    }
    // The new wedge: from the corner to the nearest bound on the other side of the line to w — of
    // the old wedge's, the base's other end, and the spokes inside the turn (all of which must lie
    // on that side).
    const double other_side = -cross(s, w, here);  // the side away from the corner
    const auto nearer = [&](Point p, Point q) { return cross(s, p, q) * other_side > 0; };
    Point tightest = other;
    for (const Point& b : bounds)
      if (cross(s, w, b) * other_side > 0 && nearer(b, tightest)) tightest = b;
    const Index spokes_end = mesh_.spoke_start_[c + 1];
    for (Index i = mesh_.spoke_start_[c]; i < spokes_end; ++i) {
      const MarchingMesh::Spoke& spoke = mesh_.spokes_[static_cast<std::size_t>(i)];
      Turn to_end;
      const double spoke_turn = away(c, sense, base_angle, base_turn, spoke.angle, Turn{spoke.cos, spoke.sin}, to_end);
      // (A spoke along the line to the source — a subdivision's straight coarse edge — is on that
      // path, not beside it: within the floats' round-off of the chart, it does not count.)
      if (!(spoke_turn > kAngleTolerance && spoke_turn < turn - kAngleTolerance)) continue;
      const Point end = lay(spoke.length, to_end);
      if (cross(s, w, end) * other_side >= 0) {
        if (nearer(end, tightest)) tightest = end;
      } else if (!bent || cross(s, bend, end) * other_side < 0) {  // wrong side, and outermost so far
        bent = true;
        bend = end;
      }
    }
    if (bent) {
      const double to_bend = std::sqrt(dot(s, bend, bend));
      const double onward = through_base(bend, face.layout);
      if (!(known.offset + to_bend + onward < limit)) return out;
      out.value = known.offset + to_bend + onward;
      out.offset = known.offset + to_bend;
      out.source = bend;
      out.bound[0] = Point{0, 0};
      out.bound[1] = Point{face.layout.base, 0};
      out.face = &face;
      return out;
    }
    out.value = known.offset + length;
    out.offset = known.offset;
    out.bound[0] = here;
    out.bound[1] = tightest;
    out.face = &face;
    return out;
  }
  // w's value through its face from the values du, dx of u and x alone: the distance from the
  // point they place (two circles; into `placed`), or +∞ where the straight line from it does not
  // cross the base. (Its wedge is the base's.)
  static double from_values(double du, double dx, const MarchingMesh::Layout& layout, Point& placed) {
    if (!(du < kInfinity && dx < kInfinity) || !(layout.vy > 0)) return kInfinity;
    const double sx = (du * du - dx * dx + layout.base * layout.base) * layout.half_inverse_base;
    double sy2 = du * du - sx * sx;
    if (sy2 < 0) {
      // du, dx not consistent with one source (|du − dx| > base) — or a source on the line ux (a
      // seed pair on the edge a source lies on, du + dx = base), which rounding in the float
      // layout leaves on either side of 0.
      if (sy2 < -kOnLineTolerance * (du * du + dx * dx)) return kInfinity;
      sy2 = 0;
    }
    placed = Point{sx, -std::sqrt(sy2)};
    return through_base(placed, layout);
  }
  // The chart angle at w (the third corner of `face`) of the direction to point p of the face's
  // layout (NaN where w has no chart).
  double chart_angle(std::size_t w, const MarchingMesh::FaceEntry& face, Point p) const {
    const Point at{face.layout.vx, face.layout.vy}, u{0, 0};
    const double turn = std::atan2(cross(at, u, p), dot(at, u, p));  // towards x: positive
    const MarchingMesh::Charts& charts = mesh_.charts_of(face);
    double angle = static_cast<double>(charts.w_to_u) + charts.w_sense * turn;
    if (!mesh_.boundary_[w] && !std::isnan(angle)) {
      while (angle < 0) angle += mesh_.angle_sum_[w];
      while (angle >= mesh_.angle_sum_[w]) angle -= mesh_.angle_sum_[w];
    }
    return angle;
  }
  // A done vertex's candidate in its chart (NaN angles: no chart, radius 0: no source).
  VirtualSource resolve(Index vertex, const Candidate& candidate) const {
    const auto v = static_cast<std::size_t>(vertex);
    VirtualSource out;
    out.offset = candidate.offset;
    double bound_angle[2] = {0, 0};
    if (candidate.face) {
      const MarchingMesh::FaceEntry& face = *candidate.face;
      const Point at{face.layout.vx, face.layout.vy};
      out.radius = candidate.value - candidate.offset;
      out.angle = chart_angle(v, face, candidate.source);
      for (int j = 0; j < 2; ++j) {
        out.bound_radius[j] = std::sqrt(dot(at, candidate.bound[j], candidate.bound[j]));
        bound_angle[j] = chart_angle(v, face, candidate.bound[j]);
      }
    } else if (candidate.edge) {
      // Reached along the edge from u: u is the source, with the wedge of the faces on both sides of
      // the edge (one face: the edge itself bounds it).
      const MarchingMesh::Neighbour& edge = *candidate.edge;
      out.radius = edge.length;
      out.angle = mesh_.neighbour_back_[static_cast<std::size_t>(&edge - mesh_.neighbours_.data())];
      const Index faces_end = (&edge + 1)->faces_begin;
      int count = 0;
      for (Index k = edge.faces_begin; k < faces_end && count < 2; ++k, ++count) {
        const MarchingMesh::FaceEntry& face = mesh_.faces_[static_cast<std::size_t>(k)];
        const Point at{face.layout.vx, face.layout.vy}, x{face.layout.base, 0};
        out.bound_radius[count] = std::sqrt(dot(at, x, x));
        bound_angle[count] = chart_angle(v, face, x);
      }
      if (count == 0) out.radius = 0;
    }
    if (!(out.radius > 0) || std::isnan(out.angle) || std::isnan(bound_angle[0]) || std::isnan(bound_angle[1])) {
      out.radius = 0;  // no usable source
      return out;
    }
    out.direction = Turn{std::cos(out.angle), std::sin(out.angle)};
    for (int j = 0; j < 2; ++j) {
      double delta = bound_angle[j] - out.angle;
      if (!mesh_.boundary_[v]) {  // the short way round
        if (delta > 0.5 * mesh_.angle_sum_[v]) delta -= mesh_.angle_sum_[v];
        if (delta < -0.5 * mesh_.angle_sum_[v]) delta += mesh_.angle_sum_[v];
      }
      out.bound_turn[j] = Turn{std::cos(delta), std::sin(delta)};
    }
    return out;
  }
  // The front: a binary min-heap of (distance, vertex) in front_[0, front_size_), each vertex at
  // most once (position_ = its slot, or -1), so a lowered value moves it up instead of adding an
  // entry. The slots past the end hold +∞, so that picking the smaller child needs no bounds test.
  struct Entry {
    double key;
    Index vertex;
  };
  static constexpr Entry kSentinel{std::numeric_limits<double>::infinity(), -1};
  void place(std::size_t slot, Entry entry) {
    front_[slot] = entry;
    position_[static_cast<std::size_t>(entry.vertex)] = static_cast<Index>(slot);
  }
  void lower(Index v, const std::vector<double>& distance) {
    std::size_t slot = position_[static_cast<std::size_t>(v)] < 0
                           ? front_size_++
                           : static_cast<std::size_t>(position_[static_cast<std::size_t>(v)]);
    const Entry entry{distance[static_cast<std::size_t>(v)], v};
    while (slot > 0) {
      const std::size_t parent = (slot - 1) / 2;
      if (!(entry.key < front_[parent].key)) break;
      place(slot, front_[parent]);
      slot = parent;
    }
    place(slot, entry);
  }
  Index pop() {
    const Index top = front_[0].vertex;
    position_[static_cast<std::size_t>(top)] = -1;
    const Entry last = front_[--front_size_];
    front_[front_size_] = kSentinel;
    if (front_size_ == 0) return top;
    std::size_t slot = 0;
    for (;;) {
      std::size_t child = 2 * slot + 1;
      if (child >= front_size_) break;
      child += front_[child + 1].key < front_[child].key ? 1 : 0;
      if (!(front_[child].key < last.key)) break;
      place(slot, front_[child]);
      slot = child;
    }
    place(slot, last);
    return top;
  }

  const MarchingMesh& mesh_;
  bool reopen_, track_;
  std::vector<Index> source_;  ///< the single-source run's (all 0)
  /// Per vertex: kOpen, kSeeded (its seed value, not yet its turn) or kAccepted.
  static constexpr char kOpen = 0, kSeeded = 1, kAccepted = 2;
  std::vector<char> accepted_;
  std::vector<Candidate> pending_;      ///< per vertex: where its value comes from (layout form)
  std::vector<VirtualSource> virtual_;  ///< per done vertex: the same in its chart
  std::vector<Entry> front_;
  std::size_t front_size_ = 0;
  std::vector<Index> position_;
};

/// One 1:4 midpoint subdivision of an intrinsic mesh for marching: each face (a, b, c) becomes
/// (a, m_ab, m_ca), (m_ab, b, m_bc), (m_ca, m_bc, c) and (m_ab, m_bc, m_ca), flat and similar to it
/// with half its lengths (faces 4f .. 4f + 3). Old vertices keep their numbers; the midpoints follow.
/// Which sides are one edge (and share its midpoint): `twin` (per side 3f + k: the side glued to
/// it, −1 on the boundary, kUnknownTwin where not known), as every subdivision returns it for the
/// next; a mesh given by faces and lengths alone (empty `twin`) has its sides with the same end
/// vertices and the same length taken as one edge: exact unless parallel edges have one length
/// (none among 130,043 vertex pairs of 50 coarse meshes at 5 %; such sides share one midpoint, and
/// their halves stay of unknown gluing). Without the carried gluing, the two halves of a loop edge
/// (two parallel edges of one length after one subdivision) would share one midpoint at the next:
/// a vertex of angle sum 4π joining two places of the surface.
/// The subdivided mesh (its `twin`: per side of F the side glued to it, −1 on the boundary, or
/// kUnknownTwin) and where each side of the mesh it came from got its midpoint.
struct SubdividedMesh : ice::IntrinsicMesh {
  std::vector<Index> side_midpoint;  ///< per side 3f + k of the input mesh
};

inline SubdividedMesh subdivide_midpoints(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count,
                                          const std::vector<Index>& given_twin = {}) {
  const auto side_count = static_cast<std::size_t>(3 * F.rows());
  std::vector<Index> twin = given_twin.empty() ? std::vector<Index>(side_count, kUnknownTwin) : given_twin;
  SubdividedMesh out;
  out.vertex_count = vertex_count;
  out.side_midpoint.assign(side_count, -1);
  // Sides of unknown gluing: those with the same ends and length share a midpoint, numbered in the
  // order of their keys; a pair of them is an edge, one alone a boundary side.
  for (const std::vector<Index>& group : group_unknown_sides(F, L, twin)) {
    const auto midpoint = static_cast<Index>(out.vertex_count++);
    for (Index side : group) out.side_midpoint[static_cast<std::size_t>(side)] = midpoint;
  }
  twin = complete_gluing(F, L, std::move(twin));
  // Sides of known gluing: one midpoint per edge.
  for (std::size_t side = 0; side < side_count; ++side) {
    if (out.side_midpoint[side] >= 0) continue;
    out.side_midpoint[side] = static_cast<Index>(out.vertex_count++);
    if (twin[side] >= 0) out.side_midpoint[static_cast<std::size_t>(twin[side])] = out.side_midpoint[side];
  }
  out.F.resize(4 * F.rows(), 3);
  out.L.resize(4 * F.rows(), 3);
  out.twin.assign(4 * side_count, -1);
  // The halves of side k of face f (x → y): x → m is side k of sub-face 4f + k, m → y side k of
  // sub-face 4f + (k + 1) mod 3. A twin side runs y → x, so halves pair crosswise.
  const auto first_half = [](Index side) { return 3 * (4 * (side / 3) + side % 3) + side % 3; };
  const auto second_half = [](Index side) { return 3 * (4 * (side / 3) + (side % 3 + 1) % 3) + side % 3; };
  const auto glue = [&](Index p, Index q) {
    out.twin[static_cast<std::size_t>(p)] = q;
    out.twin[static_cast<std::size_t>(q)] = p;
  };
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Index a = F(f, 0), b = F(f, 1), c = F(f, 2);
    const double ab = L(f, 0), bc = L(f, 1), ca = L(f, 2);
    const Index m_ab = out.side_midpoint[static_cast<std::size_t>(3 * f)],
                m_bc = out.side_midpoint[static_cast<std::size_t>(3 * f + 1)],
                m_ca = out.side_midpoint[static_cast<std::size_t>(3 * f + 2)];
    out.F.row(4 * f) << a, m_ab, m_ca;
    out.L.row(4 * f) << ab / 2, bc / 2, ca / 2;
    out.F.row(4 * f + 1) << m_ab, b, m_bc;
    out.L.row(4 * f + 1) << ab / 2, bc / 2, ca / 2;
    out.F.row(4 * f + 2) << m_ca, m_bc, c;
    out.L.row(4 * f + 2) << ab / 2, bc / 2, ca / 2;
    out.F.row(4 * f + 3) << m_ab, m_bc, m_ca;
    out.L.row(4 * f + 3) << ca / 2, ab / 2, bc / 2;
    const auto face = static_cast<Index>(f);
    glue(3 * (4 * face + 3) + 0, 3 * (4 * face + 1) + 2);  // the inner triangle against the corners'
    glue(3 * (4 * face + 3) + 1, 3 * (4 * face + 2) + 0);
    glue(3 * (4 * face + 3) + 2, 3 * (4 * face + 0) + 1);
    for (int k = 0; k < 3; ++k) {
      const Index side = 3 * face + k, other = twin[static_cast<std::size_t>(side)];
      if (other >= 0) {
        out.twin[static_cast<std::size_t>(first_half(side))] = second_half(other);
        out.twin[static_cast<std::size_t>(second_half(side))] = first_half(other);
      } else if (other == kUnknownTwin) {
        out.twin[static_cast<std::size_t>(first_half(side))] = out.twin[static_cast<std::size_t>(second_half(side))] = kUnknownTwin;
      }
    }
  }
  return out;
}

}  // namespace fem::detail
