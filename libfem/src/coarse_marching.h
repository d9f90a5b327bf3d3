#pragma once
/// \file coarse_marching.h
/// Fast marching with exact planar updates on an intrinsic mesh (private to libfem): the coarse
/// distances of the distance oracle and of the geodesic proxy (see fem/distance_oracle.h for the
/// update). A MarchingMesh is what the marching reads around each vertex, laid out once,
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

class MarchingMesh {
 public:
  /// Faces and lengths of a valid intrinsic mesh (a Δ-complex: repeated corners allowed) on
  /// vertex_count vertices.
  MarchingMesh(const Faces& F, const FaceLengths& L, Eigen::Index vertex_count) : vertex_count_(vertex_count) {
    // Around each vertex u: its neighbours w (multi-edges merged: the shortest length counts), and
    // for each, the faces (u, w, x) through which w can be updated from u and x.
    struct Relation {
      Index u, w, x;
      double to_w, to_x, across;  // |u w|, |u x|, |w x|
    };
    std::vector<Relation> relations;
    relations.reserve(static_cast<std::size_t>(6 * F.rows()));
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        // Corner k at u; "first" is corner k+1, "second" corner k+2.
        const Index u = F(f, k), first = F(f, (k + 1) % 3), second = F(f, (k + 2) % 3);
        const double to_first = L(f, k), across = L(f, (k + 1) % 3), to_second = L(f, (k + 2) % 3);
        relations.push_back({u, first, second, to_first, to_second, across});
        relations.push_back({u, second, first, to_second, to_first, across});
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
        if (r.x != r.u)
          faces_.push_back({r.x, layout(r.to_w, r.to_x, r.across)});
      }
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

  Eigen::Index vertex_count_;
  std::vector<Index> neighbour_start_;  ///< CSR of neighbours_ by vertex
  std::vector<Neighbour> neighbours_;    ///< (plus a sentinel closing the last face range)
  std::vector<FaceEntry> faces_;
  std::vector<char> repeated_corner_;  ///< the vertex is two corners of one face
};

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
  explicit CoarseMarcher(const MarchingMesh& mesh, bool reopen = false) : mesh_(mesh), reopen_(reopen) {}

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
    const auto n = static_cast<std::size_t>(mesh_.vertex_count_);
    distance.assign(n, kInfinity);
    source.assign(n, -1);
    accepted_.assign(n, 0);
    position_.assign(n, -1);
    front_.assign(n + 2, kSentinel);
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
      accepted_[static_cast<std::size_t>(u)] = kAccepted;
      // Each neighbour w once: along the edge, and through every face (u, w, x) whose x is accepted
      // too (the face's turn for w comes when the second of u and x is accepted); with reopen_, a
      // done w through those faces only.
      const Index end = mesh_.neighbour_start_[static_cast<std::size_t>(u) + 1];
      for (Index i = mesh_.neighbour_start_[static_cast<std::size_t>(u)]; i < end; ++i) {
        const MarchingMesh::Neighbour& neighbour = neighbours[static_cast<std::size_t>(i)];
        const bool closed = accepted_[static_cast<std::size_t>(neighbour.w)] == kAccepted;
        if (closed && !reopen_) continue;
        double through = kInfinity;
        const Index faces_end = neighbours[static_cast<std::size_t>(i) + 1].faces_begin;
        for (Index k = neighbour.faces_begin; k < faces_end; ++k) {
          const MarchingMesh::FaceEntry& face = faces[static_cast<std::size_t>(k)];
          if (accepted_[static_cast<std::size_t>(face.x)] != kOpen && source[static_cast<std::size_t>(face.x)] == from)
            through = std::min(through, value_through(value, distance[static_cast<std::size_t>(face.x)], face.layout));
        }
        const double along = value + neighbour.length;
        const double current = distance[static_cast<std::size_t>(neighbour.w)];
        if (closed ? through < current * (1 - kReopenGain) : std::min(along, through) < current) {
          distance[static_cast<std::size_t>(neighbour.w)] = std::min(along, through);
          source[static_cast<std::size_t>(neighbour.w)] = from;
          accepted_[static_cast<std::size_t>(neighbour.w)] = kOpen;  // a seed beaten, or a done vertex reopened
          lower(neighbour.w, distance);
        }
      }
    }
  }

 private:
  static constexpr double kInfinity = std::numeric_limits<double>::infinity();
  /// How far below 0 the squared height of the virtual source may fall and still be read as 0:
  /// the layout's floats carry relative errors of ~1e-7 into sx² and da².
  static constexpr double kOnLineTolerance = 1e-5;
  /// How much nearer a face must find a done vertex to reopen it: above the floats' round-off, so
  /// that equal values reached through two faces do not reopen each other.
  static constexpr double kReopenGain = 1e-6;
  // The value of v through the interior of its face from corners a, b at distances da, db: the
  // distance from their virtual source, or +∞ where the straight line from it does not cross ab
  // (v is then reached along edges, by the corners' own edge relaxations).
  static double value_through(double da, double db, const MarchingMesh::Layout& layout) {
    if (!(da < kInfinity && db < kInfinity) || !(layout.vy > 0)) return kInfinity;
    const double base = layout.base, vx = layout.vx, vy = layout.vy;
    // The virtual source s below ab with |s a| = da, |s b| = db (two circles); the straight line
    // from s to v must cross ab between a and b: 0 <= sx + (−sy)(vx − sx)/(vy − sy) <= base.
    const double sx = (da * da - db * db + base * base) * layout.half_inverse_base;
    double sy2 = da * da - sx * sx;
    if (sy2 < 0) {
      // da, db not consistent with one source (|da − db| > base) — or a source on the line ab (a
      // seed pair on the edge a source lies on, da + db = base), which rounding in the float
      // layout leaves on either side of 0.
      if (sy2 < -kOnLineTolerance * (da * da + db * db)) return kInfinity;
      sy2 = 0;
    }
    const double sy = -std::sqrt(sy2);
    const double rise = vy - sy;  // > 0
    const double crossing_times_rise = sx * rise - sy * (vx - sx);
    if (crossing_times_rise < 0 || crossing_times_rise > base * rise) return kInfinity;
    const double dx = vx - sx;
    return std::sqrt(dx * dx + rise * rise);
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
  bool reopen_;
  std::vector<Index> source_;  ///< the single-source run's (all 0)
  /// Per vertex: kOpen, kSeeded (its seed value, not yet its turn) or kAccepted.
  static constexpr char kOpen = 0, kSeeded = 1, kAccepted = 2;
  std::vector<char> accepted_;
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
constexpr Index kUnknownTwin = -2;

struct SubdividedMesh {
  Faces F;
  FaceLengths L;
  Eigen::Index vertex_count = 0;
  std::vector<Index> side_midpoint;  ///< per side 3f + k of the input mesh
  std::vector<Index> twin;           ///< per side of F: the side glued to it, −1 on the boundary, or kUnknownTwin
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
  struct Side {
    Index low, high;
    double length;
    Index side;  // 3f + k
  };
  std::vector<Side> unknown;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (twin[static_cast<std::size_t>(3 * f + k)] == kUnknownTwin) {
        const Index u = F(f, k), w = F(f, (k + 1) % 3);
        unknown.push_back({std::min(u, w), std::max(u, w), L(f, k), static_cast<Index>(3 * f + k)});
      }
  const auto key_less = [](const Side& p, const Side& q) {
    return p.low != q.low ? p.low < q.low : p.high != q.high ? p.high < q.high : p.length < q.length;
  };
  std::sort(unknown.begin(), unknown.end(), key_less);
  for (std::size_t i = 0; i < unknown.size();) {
    std::size_t j = i + 1;
    while (j < unknown.size() && !key_less(unknown[i], unknown[j])) ++j;
    const auto midpoint = static_cast<Index>(out.vertex_count++);
    for (std::size_t g = i; g < j; ++g) out.side_midpoint[static_cast<std::size_t>(unknown[g].side)] = midpoint;
    if (j - i == 1) twin[static_cast<std::size_t>(unknown[i].side)] = -1;
    if (j - i == 2) {
      twin[static_cast<std::size_t>(unknown[i].side)] = unknown[i + 1].side;
      twin[static_cast<std::size_t>(unknown[i + 1].side)] = unknown[i].side;
    }
    i = j;
  }
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
