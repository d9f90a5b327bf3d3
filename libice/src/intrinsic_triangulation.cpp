#include "ice/triangle_geometry.h"
#include "ice/intrinsic_triangulation.h"

#include "run_tasks.h"
#include "vertex_buckets.h"


#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace ice {
namespace {

constexpr double kTwoPi = 2 * kPi;

// The gluing of a mesh named by vertex pairs, and the corners in vertex-pair order (the edge order of
// from_mesh and from_lengths, kept so that their triangulations are laid out as before).
struct VertexPairGluing {
  std::vector<Index> twin, order;
};
VertexPairGluing pair_sides_by_vertices(const Faces& F);

// Per-face lengths (FaceLengths convention) as one length per corner's side, 3f + k: build()'s input.
std::vector<double> lengths_by_corner(const FaceLengths& L) {
  std::vector<double> lengths(static_cast<std::size_t>(3 * L.rows()));
  for (Eigen::Index f = 0; f < L.rows(); ++f)
    for (int k = 0; k < 3; ++k) lengths[static_cast<std::size_t>(3 * f + k)] = L(f, k);
  return lengths;
}

// flip() and the removal of a degree-4 vertex refuse to make a triangle whose smallest angle has a
// sine below this (see flip()).
constexpr double kFlipMinSine = 1e-7;
// The stored angle sums and angular coordinates of a vertex that has been a corner of such thin
// triangles keep their round-off, ε/θ ≈ 2.2e-9 at the limit above (a later update that replaces one
// corner of a pair by a value recomputed from lengths makes it permanent). validate() therefore
// accepts stored-vs-recomputed gaps up to this bound. Measured over full coarsenings of 25 real
// meshes: at most 2e-11 on 23 of them, 1.8e-9 and 3.2e-9 on two CAD meshes with flat regular grids
// (fandisk.off, fandisk.obj); a missed update shows as a gap of a whole corner change.
constexpr double kThinTriangleAngleRoundoff = 16 * 2.220446049250313e-16 / kFlipMinSine;
// The same bound for the triangles present now: 8ε/sin θ per angle of a face with smallest angle θ.
// Input meshes may hold thinner triangles than flips make (the loader accepts 2·area/longest² down to
// 1e-10: round-off ~2e-6 rad); validate() allows their round-off in the angle-sum and Gauss-Bonnet
// checks (a fuzzed input with a vertex at -1e10 failed Gauss-Bonnet by that much).
constexpr double kAngleRoundoffPerSine = 8 * 2.220446049250313e-16;

double wrap_angle(double a) {
  // Arguments are almost always within one turn of [0, 2π): avoid fmod's cost then.
  if (a >= 0 && a < kTwoPi) return a;
  if (a >= kTwoPi && a < 2 * kTwoPi) return a - kTwoPi;
  if (a < 0 && a >= -kTwoPi) return a + kTwoPi;
  a = std::fmod(a, kTwoPi);
  return a < 0 ? a + kTwoPi : a;
}

// Positions of the tails of a handful of half-edges in a local planar layout (a diamond or a star);
// linear lookup is fastest for the <= 9 entries a local operation needs.
class LocalLayout {
 public:
  void clear() { size_ = 0; }
  void set(Index h, Vec2 p) {
    halfedge_[size_] = h;
    position_[size_++] = p;
  }
  Vec2 at(Index h) const {
    for (int i = 0; i < size_; ++i)
      if (halfedge_[i] == h) return position_[i];
    throw std::logic_error("LocalLayout: half-edge not laid out");
  }

 private:
  std::array<Index, 12> halfedge_{};
  std::array<Vec2, 12> position_{};
  int size_ = 0;
};

// The history shard of this thread (IntrinsicTriangulation::HistoryShard), if one is alive.
thread_local TriangulationHistory* t_history_shard = nullptr;

// Writes one record of a history (nothing without one): the faces replaced, then the faces that
// replace them, each by its corners' positions in one layout (equal positions share a point), or
// the faces of a flattened star.
class RecordWriter {
 public:
  explicit RecordWriter(TriangulationHistory* history, bool flattening = false, double weight = 1) {
    if (!history) return;
    history_ = history;
    chunk_ = &history->writable();
    first_point_ = chunk_->points.size();
    TriangulationHistory::Record record;
    record.flattening = flattening;
    chunk_->records.push_back(record);
    if (flattening) point(Vec2{weight, 0});
  }
  bool active() const { return chunk_ != nullptr; }
  // A face by its corners' positions, in its corner order.
  void face(Index slot, Vec2 p0, Vec2 p1, Vec2 p2, bool replacement) {
    if (!chunk_) return;
    TriangulationHistory::Face face;
    face.slot = slot;
    const Vec2 corner[3] = {p0, p1, p2};
    for (int k = 0; k < 3; ++k) face.corner[k] = point(corner[k]);
    add(face, replacement);
  }
  // A face about to be replaced, its corners (tails of its half-edges from halfedge(f)) in `layout`.
  void old_face(const IntrinsicTriangulation& T, Index f, const LocalLayout& layout) {
    if (!chunk_) return;
    const Index h0 = T.halfedge(f), h1 = T.next(h0), h2 = T.next(h1);
    face(f, layout.at(h0), layout.at(h1), layout.at(h2), false);
  }
  // A face of a flattened star: which of its corners are at the vertex.
  void star_face(Index slot, const bool at_vertex[3]) {
    if (!chunk_) return;
    TriangulationHistory::Face face;
    face.slot = slot;
    for (int k = 0; k < 3; ++k) face.corner[k] = at_vertex[k] ? 1 : 0;
    add(face, false);
  }

 private:
  void add(const TriangulationHistory::Face& face, bool replacement) {
    chunk_->faces.push_back(face);
    TriangulationHistory::Record& record = chunk_->records.back();
    ++(replacement ? record.new_faces : record.old_faces);
    history_->face_slots = std::max(history_->face_slots, face.slot + 1);
  }
  std::uint8_t point(Vec2 p) {
    std::vector<Vec2>& points = chunk_->points;
    for (std::size_t i = first_point_; i < points.size(); ++i)
      if (points[i].x == p.x && points[i].y == p.y) return static_cast<std::uint8_t>(i - first_point_);
    points.push_back(p);
    return chunk_->records.back().num_points++;
  }
  TriangulationHistory* history_ = nullptr;
  TriangulationHistory::Chunk* chunk_ = nullptr;
  std::size_t first_point_ = 0;
};

}  // namespace

const char* to_string(RemovalStatus status) {
  switch (status) {
    case RemovalStatus::Removed: return "removed";
    case RemovalStatus::NotAVertex: return "not a vertex";
    case RemovalStatus::FlattenFailed: return "flattening failed";
    case RemovalStatus::FaceOnlyAtVertex: return "a face has all corners at the vertex";
    case RemovalStatus::NoConvexFlip: return "no convex flip to reduce the degree";
    case RemovalStatus::BoundaryLoopTooSmall: return "boundary loop too small";
    case RemovalStatus::TopologyChange: return "removal would change the topology";
  }
  return "unknown";
}

// ------------------------------------------------------------------------------------------------
// Construction

IntrinsicTriangulation IntrinsicTriangulation::from_mesh(const Positions& V, const Faces& F) {
  if (V.cols() != 3) throw std::invalid_argument("IntrinsicTriangulation: V must be n x 3");
  if (F.cols() != 3) throw std::invalid_argument("IntrinsicTriangulation: F must be m x 3");
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (F(f, k) < 0 || F(f, k) >= V.rows())
        throw std::invalid_argument("IntrinsicTriangulation: face " + std::to_string(f) +
                                    " has an out-of-range vertex index");
  const std::vector<double> lengths = lengths_by_corner(face_lengths_from_positions(V, F));
  if (F.size() > 0 && F.maxCoeff() + 1 != V.rows())
    throw std::invalid_argument("IntrinsicTriangulation: unreferenced vertices (the last vertex is unused)");
  return from_corner_lengths(F, lengths);
}

IntrinsicTriangulation IntrinsicTriangulation::from_lengths(const Faces& F, const FaceLengths& L) {
  if (F.cols() != 3 || L.cols() != 3 || F.rows() != L.rows())
    throw std::invalid_argument("IntrinsicTriangulation: F and L must both be m x 3");
  return from_corner_lengths(F, lengths_by_corner(L));
}

IntrinsicTriangulation IntrinsicTriangulation::from_lengths(const Faces& F, FaceLengths&& L) {
  if (F.cols() != 3 || L.cols() != 3 || F.rows() != L.rows())
    throw std::invalid_argument("IntrinsicTriangulation: F and L must both be m x 3");
  std::vector<double> lengths = lengths_by_corner(L);
  L = FaceLengths();
  return from_corner_lengths(F, lengths);
}

IntrinsicTriangulation IntrinsicTriangulation::from_corner_lengths(const Faces& F, const std::vector<double>& lengths) {
  IntrinsicTriangulation T;
  const VertexPairGluing gluing = pair_sides_by_vertices(F);
  T.build(F, lengths, gluing.twin, gluing.order);
  return T;
}

IntrinsicTriangulation IntrinsicTriangulation::from_glued_faces(const Faces& F, const FaceLengths& L,
                                                                const std::vector<Index>& twin) {
  if (F.cols() != 3 || L.cols() != 3 || F.rows() != L.rows())
    throw std::invalid_argument("IntrinsicTriangulation: F and L must both be m x 3");
  if (twin.size() != static_cast<std::size_t>(3 * F.rows()))
    throw std::invalid_argument("IntrinsicTriangulation: the gluing must have 3 entries per face");
  const std::vector<double> lengths = lengths_by_corner(L);
  std::vector<Index> order(twin.size());
  for (std::size_t c = 0; c < order.size(); ++c) order[c] = static_cast<Index>(c);
  IntrinsicTriangulation T;
  T.build(F, lengths, twin, order);
  return T;
}

std::vector<Index> glue_by_vertex_pairs(const Faces& F) { return pair_sides_by_vertices(F).twin; }

namespace {
// Triangulations of at least this many vertices are built on several threads: the first touch of
// the records (the kernel zeroing their pages), the corner passes and the vertex frames. Every
// element is written by one thread with what a serial pass writes: the result does not depend on
// the thread count.
constexpr std::size_t kParallelBuildVertices = 100000;

// Numbers the i in [0, count) for which alive(i) holds 0, 1, ... in increasing order (kInvalid for
// the others) into `id`, and returns how many there are: a count per range on the threads, then
// each range numbered from its offset.
template <class Alive>
Index number_alive(Index count, const Alive& alive, int threads, std::vector<Index>& id) {
  id.resize(static_cast<std::size_t>(count));
  const int ranges = detail::range_count(threads, count);
  std::vector<Index> offset(static_cast<std::size_t>(ranges) + 1, 0);
  detail::run_numbered_ranges(threads, count, [&](int range, Index begin, Index end) {
    Index live = 0;
    for (Index i = begin; i < end; ++i) live += alive(i) ? 1 : 0;
    offset[static_cast<std::size_t>(range) + 1] = live;
  });
  for (int range = 0; range < ranges; ++range) offset[static_cast<std::size_t>(range) + 1] += offset[static_cast<std::size_t>(range)];
  detail::run_numbered_ranges(threads, count, [&](int range, Index begin, Index end) {
    Index next = offset[static_cast<std::size_t>(range)];
    for (Index i = begin; i < end; ++i) id[static_cast<std::size_t>(i)] = alive(i) ? next++ : kInvalid;
  });
  return offset.back();
}

VertexPairGluing pair_sides_by_vertices(const Faces& F) {
  const Index num_faces = static_cast<Index>(F.rows());
  if (num_faces == 0) throw std::invalid_argument("IntrinsicTriangulation: no faces");
  const Index num_vertices = F.minCoeff() < 0 ? -1 : F.maxCoeff() + 1;
  if (num_vertices <= 0) throw std::invalid_argument("IntrinsicTriangulation: negative vertex index");
  const Index num_corners = 3 * num_faces;
  const int threads = detail::threads_for(static_cast<std::size_t>(num_vertices), kParallelBuildVertices);

  // Pair corners (directed edges) into undirected edges by sorting on the vertex pair (lower
  // vertex, higher vertex, corner) with a counting sort on the lower vertex (detail::order_by_vertex).
  std::vector<std::uint64_t> key(num_corners);
  detail::run_ranges(threads, num_corners, [&](Index begin, Index end) {
    for (Index c = begin; c < end; ++c) {
      const std::uint64_t a = F(c / 3, c % 3), b = F(c / 3, (c % 3 + 1) % 3);
      if (a == b)
        throw std::invalid_argument("IntrinsicTriangulation: face " + std::to_string(c / 3) + " repeats a vertex");
      key[c] = (std::min(a, b) << 32) | std::max(a, b);
    }
  });
  std::vector<Index> order = detail::order_by_vertex(
      static_cast<std::size_t>(num_corners), num_vertices, [&](Index c) { return static_cast<Index>(key[c] >> 32); },
      [&](Index x, Index y) { return key[x] < key[y]; }, threads);

  // Runs of equal keys are one edge's sides. Ranges of the sorted corners are paired on the threads,
  // each from the first run that starts in it (the first error in sorted order is the one thrown).
  VertexPairGluing gluing;
  gluing.twin.assign(num_corners, kInvalid);
  const auto run_start = [&](Index i) {
    while (i > 0 && i < num_corners && key[order[i]] == key[order[i - 1]]) ++i;
    return i;
  };
  detail::run_ranges(threads, num_corners, [&](Index begin, Index end) {
    for (Index i = run_start(begin), stop = run_start(end); i < stop;) {
      Index j = i + 1;
      while (j < num_corners && key[order[j]] == key[order[i]]) ++j;
      const Index c0 = order[i];
      const auto edge_name = [&] {
        return "edge (" + std::to_string(F(c0 / 3, c0 % 3)) + ", " + std::to_string(F(c0 / 3, (c0 % 3 + 1) % 3)) + ")";
      };
      if (j - i > 2)
        throw std::invalid_argument("IntrinsicTriangulation: non-manifold " + edge_name() + " has " +
                                    std::to_string(j - i) + " faces");
      if (j - i == 2) {
        const Index c1 = order[i + 1];
        if (F(c0 / 3, c0 % 3) == F(c1 / 3, c1 % 3))
          throw std::invalid_argument("IntrinsicTriangulation: inconsistent orientation at " + edge_name());
        gluing.twin[c0] = c1;
        gluing.twin[c1] = c0;
      }
      i = j;
    }
  });
  gluing.order = std::move(order);
  return gluing;
}

// The gluing of the corners' sides (twin: an involution without fixed points joining sides with the
// same ends, run opposite ways, of the same length; kInvalid on the boundary), checked, with the
// edges numbered in `order` (the vertex-pair order for from_mesh): side c becomes half-edge
// corner_halfedge[c] (2e and 2e + 1 for the two sides of edge e). Throws std::invalid_argument naming
// the first edge that breaks a rule.
std::vector<Index> number_glued_sides(const Faces& F, const std::vector<double>& corner_length,
                                      const std::vector<Index>& twin, const std::vector<Index>& order,
                                      Index& num_edges, int threads) {
  const Index num_corners = static_cast<Index>(3 * F.rows());
  const auto tail_of = [&](Index c) { return F(c / 3, c % 3); };
  const auto head_of = [&](Index c) { return F(c / 3, (c % 3 + 1) % 3); };
  // An edge is numbered at the first of its sides in `order`: a side is first unless its twin, a
  // proper one, comes earlier. Edge numbers are counts of first sides (per range, then offsets).
  std::vector<Index> position(static_cast<std::size_t>(num_corners));
  detail::run_ranges(threads, num_corners, [&](Index begin, Index end) {
    for (Index i = begin; i < end; ++i) position[static_cast<std::size_t>(order[i])] = i;
  });
  const auto is_first = [&](Index i) {
    const Index c = order[i], t = twin[c];
    return t == kInvalid || t < 0 || t >= num_corners || t == c || twin[t] != c || position[static_cast<std::size_t>(t)] > i;
  };
  std::vector<Index> edge_at;  // the edge numbered at each position of `order` (kInvalid: a second side)
  num_edges = number_alive(num_corners, is_first, threads, edge_at);
  std::vector<Index> corner_halfedge(num_corners, kInvalid);
  // The checks, at each first side (the first failure in `order` is the one thrown).
  detail::run_ranges(threads, num_corners, [&](Index begin, Index end) {
    for (Index i = begin; i < end; ++i) {
      const Index edge = edge_at[static_cast<std::size_t>(i)];
      if (edge == kInvalid) continue;
      const Index c = order[i], t = twin[c];
      corner_halfedge[c] = 2 * edge;
      if (t == kInvalid) continue;
      const auto edge_name = [&] {
        return "edge (" + std::to_string(tail_of(c)) + ", " + std::to_string(head_of(c)) + ") of face " + std::to_string(c / 3);
      };
      if (t < 0 || t >= num_corners || t == c || twin[t] != c)
        throw std::invalid_argument("IntrinsicTriangulation: the gluing of " + edge_name() + " is not symmetric");
      if (tail_of(t) != head_of(c) || head_of(t) != tail_of(c))
        throw std::invalid_argument("IntrinsicTriangulation: " + edge_name() + " is glued to a side with other ends");
      const double l0 = corner_length[c], l1 = corner_length[t];
      if (std::abs(l0 - l1) > 1e-12 * std::max(l0, l1))
        throw std::invalid_argument("IntrinsicTriangulation: the two faces of " + edge_name() + " disagree on its length");
      corner_halfedge[t] = 2 * edge + 1;
    }
  });
  for (Index c = 0; c < num_corners; ++c)
    if (corner_halfedge[c] == kInvalid) throw std::invalid_argument("IntrinsicTriangulation: the edge order misses a side");
  return corner_halfedge;
}

}  // namespace

namespace {
// Sets `records` to `count` copies of `value`, each range first touched by the thread that fills it.
template <class Record>
void fill_records(LargeArray<Record>& records, Index count, const Record& value, int threads) {
  records.clear();
  records.resize(static_cast<std::size_t>(count));  // default-initialised: no page touched yet
  detail::run_ranges(threads, count, [&](Index begin, Index end) {
    std::fill(records.begin() + begin, records.begin() + end, value);
  });
}
}  // namespace

void IntrinsicTriangulation::build(const Faces& F, const std::vector<double>& corner_length,
                                   const std::vector<Index>& twin, const std::vector<Index>& order) {
  const Index num_faces = static_cast<Index>(F.rows());
  if (num_faces == 0) throw std::invalid_argument("IntrinsicTriangulation: no faces");
  const Index num_vertices = F.minCoeff() < 0 ? -1 : F.maxCoeff() + 1;
  if (num_vertices <= 0) throw std::invalid_argument("IntrinsicTriangulation: negative vertex index");
  const int threads = detail::threads_for(static_cast<std::size_t>(num_vertices), kParallelBuildVertices);
  // The gluing, checked, numbers the edges: corner c's side is half-edge corner_halfedge[c].
  Index num_edges = 0;
  const std::vector<Index> corner_halfedge = number_glued_sides(F, corner_length, twin, order, num_edges, threads);

  fill_records(edges_, num_edges,
               EdgeRecord{{kInvalid, kInvalid}, {kInvalid, kInvalid}, {kInvalid, kInvalid}, {kInvalid, kInvalid}, {0.0, 0.0}, 0.0},
               threads);
  fill_records(faces_, num_faces, FaceRecord{kInvalid, kInvalid}, threads);
  fill_records(vertices_, num_vertices, VertexRecord{kInvalid, 0, 0.0}, threads);
  num_vertices_ = num_vertices;
  num_edges_ = num_edges;
  num_faces_ = num_faces;
  link_vertices(link_halfedges(F, corner_length, twin, corner_halfedge, threads));
  // The first face that breaks the triangle inequality, as a serial scan finds it (run_tasks
  // rethrows the lowest range's error).
  detail::run_ranges(threads, num_faces, [&](Index begin, Index end) {
    for (Index f = begin; f < end; ++f) {
      const Index h = fhalfedge(f);
      if (!triangle_inequality_holds(length(h), length(next(h)), length(prev(h))))
        throw std::invalid_argument("IntrinsicTriangulation: face " + std::to_string(f) +
                                    " is degenerate or violates the triangle inequality");
    }
  });
  // Each vertex's frame is its own (its angle sum and its outgoing half-edges' coordinates).
  detail::run_ranges(threads, num_vertices, [this](Index begin, Index end) {
    for (Index v = begin; v < end; ++v) recompute_vertex_frame(v);
  });
  fill_records(points_, num_vertices, TrackedPoint{kInvalid, kInvalid, {0, 0, 0}}, threads);
}

std::vector<Index> IntrinsicTriangulation::link_halfedges(const Faces& F, const std::vector<double>& corner_length,
                                                          const std::vector<Index>& twin,
                                                          const std::vector<Index>& corner_halfedge, int threads) {
  const Index num_corners = static_cast<Index>(corner_halfedge.size());
  // Every corner writes its own half-edge; an edge's length is its later corner's (as a serial
  // pass over the corners left it: the two sides agree to 1e-12, not always to the bit).
  detail::run_ranges(threads, num_corners, [&](Index begin, Index end) {
    for (Index c = begin; c < end; ++c) {
      const Index h = corner_halfedge[c];
      const Index f = c / 3;
      hnext(h) = corner_halfedge[3 * f + (c % 3 + 1) % 3];
      htail(h) = F(f, c % 3);
      hface(h) = f;
      if (twin[c] == kInvalid || twin[c] < c) elength(h >> 1) = corner_length[c];
      if (c % 3 == 0) fhalfedge(f) = h;
    }
  });
  detail::run_ranges(threads, num_corners, [&](Index begin, Index end) {
    for (Index c = begin; c < end; ++c) hprev(hnext(corner_halfedge[c])) = corner_halfedge[c];
  });
  // Exterior half-edges: tail is the head of their interior twin.
  detail::run_ranges(threads, 2 * num_edges_, [&](Index begin, Index end) {
    for (Index h = begin; h < end; ++h)
      if (htail(h) == kInvalid) htail(h) = htail(hnext(h ^ 1));
  });
  std::vector<Index> corners_at_vertex(static_cast<std::size_t>(num_vertices_), 0);
  for (Index c = 0; c < num_corners; ++c) ++corners_at_vertex[F(c / 3, c % 3)];
  return corners_at_vertex;
}

void IntrinsicTriangulation::link_vertices(const std::vector<Index>& corners_at_vertex) {
  for (Index v = 0; v < num_vertices_; ++v)
    if (corners_at_vertex[v] == 0)
      throw std::invalid_argument("IntrinsicTriangulation: vertex " + std::to_string(v) + " is not referenced by any face");
  // Vertex half-edges: any outgoing interior one, then the boundary one where it exists.
  for (Index h = 0; h < 2 * num_edges_; ++h) {
    if (hface(h) == kInvalid) continue;
    const Index v = htail(h);
    if (vhalfedge(v) == kInvalid || hface(h ^ 1) == kInvalid) {
      if (vhalfedge(v) != kInvalid && hface(vhalfedge(v) ^ 1) == kInvalid)
        throw std::invalid_argument("IntrinsicTriangulation: non-manifold vertex " + std::to_string(v) +
                                    " (several boundary fans)");
      vhalfedge(v) = h;
    }
  }
  for (Index v = 0; v < num_vertices_; ++v)
    vertices_[v].boundary = vhalfedge(v) != kInvalid && is_exterior(vhalfedge(v) ^ 1);
  // One fan per vertex: the rotation from vertex_halfedge must visit every corner.
  for (Index v = 0; v < num_vertices_; ++v) {
    if (degree(v) != corners_at_vertex[v])
      throw std::invalid_argument("IntrinsicTriangulation: non-manifold vertex " + std::to_string(v) +
                                  " (its faces form several fans)");
  }
}

// ------------------------------------------------------------------------------------------------
// Geometry

int IntrinsicTriangulation::degree(Index v) const {
  int count = 0;
  for_each_outgoing(v, [&](Index) { ++count; });
  return count;
}

double IntrinsicTriangulation::face_area(Index f) const {
  const Index h = fhalfedge(f);
  return triangle_area(length(h), length(next(h)), length(prev(h)));
}

double IntrinsicTriangulation::total_area() const {
  double sum = 0;
  for (Index f = 0; f < num_face_slots(); ++f)
    if (face_alive(f)) sum += face_area(f);
  return sum;
}

double IntrinsicTriangulation::compute_angle_sum(Index v) const {
  double sum = 0;
  for_each_outgoing(v, [&](Index h) { sum += corner_angle(h); });
  return sum;
}

double IntrinsicTriangulation::curvature(Index v) const {
  return (is_boundary_vertex(v) ? kPi : kTwoPi) - vsum(v);
}

double IntrinsicTriangulation::total_curvature() const {
  double sum = 0;
  for (Index v = 0; v < num_vertex_slots(); ++v)
    if (vertex_alive(v)) sum += curvature(v);
  return sum;
}

void IntrinsicTriangulation::recompute_vertex_frame(Index v) {
  if (frames_maintained_)
    refresh_vertex_frame(v, kInvalid, nullptr, 0);
  else
    vsum(v) = compute_angle_sum(v);
}

void IntrinsicTriangulation::record_history(bool on) {
  recording_ = on;
  history_ = TriangulationHistory{};
  history_.initial_faces = num_face_slots();
}

TriangulationHistory* IntrinsicTriangulation::history_sink() {
  if (!recording_) return nullptr;
  return t_history_shard ? t_history_shard : &history_;
}

IntrinsicTriangulation::HistoryShard::HistoryShard(TriangulationHistory& shard) : previous_(t_history_shard) {
  t_history_shard = &shard;
}

IntrinsicTriangulation::HistoryShard::~HistoryShard() { t_history_shard = previous_; }

void IntrinsicTriangulation::maintain_frames(bool on) {
  const bool resume = on && !frames_maintained_;
  frames_maintained_ = on;
  if (!resume) return;
  const int threads = detail::threads_for(static_cast<std::size_t>(num_vertex_slots()), kParallelBuildVertices);
  detail::run_ranges(threads, num_vertex_slots(), [this](Index begin, Index end) {
    for (Index v = begin; v < end; ++v)
      if (vertex_alive(v)) recompute_vertex_frame(v);
  });
}

void IntrinsicTriangulation::refresh_vertex_frame(Index v, Index changed_near, const CornerChange* changes,
                                                  int change_count) {
  // Corner angles of v's fan, counter-clockwise from vhalfedge(v). With `changes` (after the
  // neighbour `changed_near` was flattened), the corners of faces touching it take their listed new
  // values and every other corner is read back from the stored coordinates,
  // A(following) − A(h) = scale·corner. Without, or for fans of one or two corners (a corner may
  // then span the whole turn), every corner is recomputed from the lengths. One walk records each outgoing half-edge
  // and the one after it, so the coordinates are written without walking the fan again.
  struct FanCorner {
    Index halfedge, following;  // following = prev(halfedge)^1, the next outgoing one (or exterior)
    double corner;
  };
  constexpr int kSmall = 64;
  FanCorner fan_small[kSmall];
  std::vector<FanCorner> fan_large;
  FanCorner* fan = fan_small;
  const double old_scale = angle_scale(v);
  int count = 0;
  const auto collect = [&](bool reuse) {
    count = 0;
    fan_large.clear();
    fan = fan_small;
    for_each_outgoing(v, [&](Index h) {
      const Index in = prev(h);
      const Index following = in ^ 1;
      double corner;
      if (!reuse) {
        corner = corner_angle(h);
      } else if (changed_near == kInvalid) {
        corner = wrap_angle(hangle(following) - hangle(h)) / old_scale;
        for (int i = 0; i < change_count; ++i) corner = changes[i].halfedge == h ? changes[i].corner : corner;
      } else if (head(h) == changed_near || tail(in) == changed_near) {
        corner = -1;
        for (int i = 0; i < change_count; ++i)
          if (changes[i].halfedge == h) {
            corner = changes[i].corner;
            break;
          }
        if (corner < 0) corner = corner_angle(h);  // not listed: recompute (never expected)
      } else {
        corner = wrap_angle(hangle(following) - hangle(h)) / old_scale;
      }
      if (count == kSmall && fan == fan_small) fan_large.assign(fan_small, fan_small + kSmall);
      if (count >= kSmall) {
        fan_large.push_back({h, following, corner});
        fan = fan_large.data();
      } else {
        fan_small[count] = {h, following, corner};
      }
      ++count;
    });
  };
  collect(changes != nullptr);
  if (changes != nullptr && count <= 2) collect(false);
  double theta = 0;
  for (int c = 0; c < count; ++c) theta += fan[c].corner;
  vsum(v) = theta;
  const double scale = angle_scale(v);
  double angle = is_boundary_vertex(v) ? 0.0 : hangle(fan[0].halfedge);
  for (int c = 0; c < count; ++c) {
    hangle(fan[c].halfedge) = wrap_angle(angle);
    angle += scale * fan[c].corner;
  }
  // Boundary: the exterior outgoing half-edge closes the fan.
  if (is_exterior(fan[count - 1].following)) hangle(fan[count - 1].following) = wrap_angle(angle);
}

// ------------------------------------------------------------------------------------------------
// Tracked points

void IntrinsicTriangulation::add_point_to_face(Index p, Index f, const std::array<double, 3>& bary) {
  static_assert(sizeof(TrackedPoint) == 32, "a point record never straddles a cache line");
  points_[p] = TrackedPoint{f, ffirst(f), clamp_barycentric(bary)};
  ffirst(f) = p;
}

SurfacePoint IntrinsicTriangulation::location(Index p) const {
  SurfacePoint s;
  if (vertex_alive(p)) {
    s.vertex = p;
  } else {
    s.face = points_[p].face;
    s.bary = points_[p].bary;
  }
  return s;
}

std::vector<IntrinsicTriangulation::PlacedPoint>& IntrinsicTriangulation::scratch_points() {
  thread_local std::vector<PlacedPoint> points;
  return points;
}

std::vector<Index>& IntrinsicTriangulation::scratch_faces() {
  thread_local std::vector<Index> faces;
  return faces;
}

// Appends every point of face f to `out`, with its position in `layout`, and unlinks it.
template <class Layout>
void IntrinsicTriangulation::collect_points(Index f, const Layout& layout, std::vector<PlacedPoint>& out) {
  const Index h0 = fhalfedge(f), h1 = next(h0), h2 = next(h1);
  const Vec2 p0 = layout.at(h0), p1 = layout.at(h1), p2 = layout.at(h2);
  Index p = ffirst(f);
  while (p != kInvalid) {
    TrackedPoint& point = points_[p];
    const auto& b = point.bary;
    out.push_back({p, p0 * b[0] + p1 * b[1] + p2 * b[2]});
    p = point.next;
    point.face = point.next = kInvalid;
  }
  ffirst(f) = kInvalid;
}

// ------------------------------------------------------------------------------------------------
// Flips

bool IntrinsicTriangulation::flip(Index h) {
  if (is_boundary_edge(h)) return false;
  const Index t = h ^ 1;
  const Index f0 = face(h), f1 = face(t);
  if (f0 == f1) return false;
  const Index a = next(h), b = next(a), c = next(t), d = next(c);
  const Index k = tail(b), l = tail(d);

  // Lay the diamond out: i at the origin, j on the x axis, k above, l below.
  const double l_ij = length(h), l_a = length(a), l_b = length(b), l_c = length(c), l_d = length(d);
  const double inv_ij = 1.0 / l_ij;
  const Vec2 pi{0, 0}, pj{l_ij, 0};
  const Vec2 pk{0.5 * ((l_ij - l_a) * (l_ij + l_a) + l_b * l_b) * inv_ij, 2.0 * triangle_area(l_ij, l_b, l_a) * inv_ij};
  const Vec2 pl{0.5 * ((l_ij - l_d) * (l_ij + l_d) + l_c * l_c) * inv_ij, -2.0 * triangle_area(l_ij, l_d, l_c) * inv_ij};
  // Strictly convex, with a margin: the diamond's angles at i and j must stay below π − θ_min and
  // the new triangles' angles above θ_min (sine tests). Angles of a triangle whose smallest angle is
  // θ carry round-off of about ε/θ, so flips into near-degenerate triangles are refused. Twice the
  // new triangles' areas are the cross products at i and at j.
  const double twice_area0 = cross(pl - pi, pk - pi), twice_area1 = cross(pk - pj, pl - pj);
  if (!(twice_area0 > kFlipMinSine * l_c * l_b && twice_area1 > kFlipMinSine * l_a * l_d)) return false;
  const Vec2 kl = pk - pl;
  const double l_kl = std::sqrt(kl.x * kl.x + kl.y * kl.y);
  // Smallest angle sine of a triangle = 2·area / (product of its two longest sides).
  const auto two_longest = [](double x, double y, double z) {
    return x * y * z / std::min({x, y, z});
  };
  if (!(twice_area0 > kFlipMinSine * two_longest(l_kl, l_b, l_c) && twice_area1 > kFlipMinSine * two_longest(l_kl, l_d, l_a)))
    return false;

  // The diamond's layout, for the tracked points of both faces and the history's record.
  const bool has_points = ffirst(f0) != kInvalid || ffirst(f1) != kInvalid;
  RecordWriter record(history_sink());
  LocalLayout layout;
  if (has_points || record.active()) {
    layout.set(h, pi);
    layout.set(a, pj);
    layout.set(b, pk);
    layout.set(t, pj);
    layout.set(c, pi);
    layout.set(d, pl);
  }
  record.old_face(*this, f0, layout);
  record.old_face(*this, f1, layout);
  record.face(f0, pl, pk, pi, true);  // the faces as rewired below: f0 = (l, k, i), f1 = (k, l, j)
  record.face(f1, pk, pl, pj, true);
  std::vector<PlacedPoint>& points = scratch_points();
  points.clear();
  if (has_points) {
    collect_points(f0, layout, points);
    collect_points(f1, layout, points);
  }

  // Rewire: f0 = (h: l->k, b: k->i, c: i->l), f1 = (t: k->l, d: l->j, a: j->k).
  const Index i = tail(h), j = tail(t);
  link_face(h, b, c);
  link_face(t, d, a);
  hface(c) = f0, hface(a) = f1;
  htail(h) = l, htail(t) = k;
  fhalfedge(f0) = h, fhalfedge(f1) = t;
  if (vhalfedge(i) == h) vhalfedge(i) = c;
  if (vhalfedge(j) == t) vhalfedge(j) = a;
  elength(h >> 1) = l_kl;
  // New angular coordinates from the layout: at l the corner from d (l->j) to h (l->k), at k the
  // corner from b (k->i) to t (k->l).
  if (frames_maintained_) {
    const Vec2 lj = pj - pl, lk = pk - pl, ki = pi - pk, kl_dir = pl - pk;
    const double corner_l = std::atan2(cross(lj, lk), lj.x * lk.x + lj.y * lk.y);
    const double corner_k = std::atan2(cross(ki, kl_dir), ki.x * kl_dir.x + ki.y * kl_dir.y);
    hangle(h) = wrap_angle(hangle(d) + angle_scale(l) * corner_l);
    hangle(t) = wrap_angle(hangle(b) + angle_scale(k) * corner_k);
  }

  for (const auto& q : points) {
    if (orient2d(pk, pl, q.position) > 0)
      add_point_to_face(q.point, f1, barycentric(q.position, pk, pl, pj));
    else
      add_point_to_face(q.point, f0, barycentric(q.position, pl, pk, pi));
  }
  return true;
}

int IntrinsicTriangulation::flip_to_delaunay() {
  // The edges that need a flip are found on all threads (on a mesh that is nearly Delaunay, as a
  // coarsened level or an input's intrinsic Delaunay triangulation after a few flips, that pass is
  // most of the work); the flips, which spread, start from their faces on this thread.
  const Index edge_slots = static_cast<Index>(edges_.size());
  constexpr std::size_t kParallelScanEdges = 300000;  // as the builds' 100,000 vertices
  const int threads = detail::threads_for(static_cast<std::size_t>(edge_slots), kParallelScanEdges);
  std::vector<std::vector<Index>> found(static_cast<std::size_t>(detail::range_count(threads, edge_slots)));
  detail::run_numbered_ranges(threads, edge_slots, [&](int range, Index begin, Index end) {
    for (Index e = begin; e < end; ++e) {
      const Index h = 2 * e;
      if (halfedge_alive(h) && !is_delaunay(h)) found[static_cast<std::size_t>(range)].push_back(hface(h));  // interior
    }
  });
  std::vector<Index> faces;
  for (const std::vector<Index>& part : found) faces.insert(faces.end(), part.begin(), part.end());
  return flip_to_delaunay_around(faces);
}

int IntrinsicTriangulation::flip_to_delaunay_around(const std::vector<Index>& faces, std::vector<Index>* touched,
                                                    const WriteRegion* region) {
  // A stack of edges with an in-stack flag per edge slot, kept between calls (per thread), so local
  // calls cost only what they touch (the flags are all back to 0 when the stack empties). Outside
  // the region an edge is not even flagged: another thread may own it.
  thread_local std::vector<Index> stack;
  thread_local std::vector<std::uint8_t> queued;
  stack.clear();
  if (queued.size() < edges_.size()) queued.resize(edges_.size(), 0);
  const auto push = [&](Index h) {
    const Index e = h >> 1;
    if (queued[e] || is_boundary_edge(h)) return;
    if (region && !(region->contains(tail(h)) && region->contains(head(h)) && region->contains(tail(prev(h))) &&
                    region->contains(tail(prev(h ^ 1))))) {
      if (region->skipped) region->skipped->push_back(h);
      return;
    }
    queued[e] = 1;
    stack.push_back(e);
  };
  for (Index f : faces) {
    if (!face_alive(f)) continue;
    const Index h = fhalfedge(f);
    push(h), push(next(h)), push(prev(h));
  }
  int flips = 0;
  while (!stack.empty()) {
    const Index e = stack.back();
    stack.pop_back();
    queued[e] = 0;
    const Index h = 2 * e;
    if (!halfedge_alive(h) || is_delaunay(h)) continue;
    const Index i = tail(h), j = head(h);
    if (!flip(h)) continue;
    ++flips;
    if (touched) touched->insert(touched->end(), {i, j, tail(h), head(h)});
    push(next(h)), push(prev(h)), push(next(h ^ 1)), push(prev(h ^ 1));
  }
  return flips;
}

// ------------------------------------------------------------------------------------------------
// Flattening

void IntrinsicTriangulation::read_star(Index v, VertexStar& star) const {
  star.centre = v;
  star.boundary = is_boundary_vertex(v);
  star.angle_sum = angle_sum(v);
  star.corners.clear();
  for_each_outgoing(v, [&](Index h) {
    const Index opposite = next(h), in = prev(h);
    StarCorner c;
    c.halfedge = h;
    c.in_halfedge = in;
    c.out_vertex = head(h);
    c.in_vertex = tail(in);
    c.l_out = length(h);
    c.l_in = length(in);
    c.l_opposite = length(opposite);
    c.m_out = static_cast<std::uint8_t>(1 + (c.out_vertex == v));
    c.m_in = static_cast<std::uint8_t>(1 + (c.in_vertex == v));
    c.m_opposite = static_cast<std::uint8_t>((c.in_vertex == v) + (c.out_vertex == v));
    star.corners.push_back(c);
  });
}

FlattenResult IntrinsicTriangulation::compute_flattening(Index v, double tolerance, double initial_log_scale) const {
  thread_local VertexStar star;  // re-used storage: no allocation per call
  read_star(v, star);
  return flatten_star(star, tolerance, initial_log_scale);
}

FlattenResult IntrinsicTriangulation::flatten_vertex(Index v, double initial_log_scale) {
  return flatten_vertex(v, initial_log_scale, true);
}

FlattenResult IntrinsicTriangulation::flatten_vertex(Index v, double initial_log_scale, bool update_own_frame) {
  thread_local VertexStar star;  // re-used storage: no allocation per call
  read_star(v, star);
  const FlattenResult result = flatten_star(star, 1e-13, initial_log_scale);
  if (!result.success || result.log_scale == 0.0) return result;
  const double u = result.log_scale;
  const double half_scale = std::exp(0.5 * u);
  // The new corners of the star's faces away from v, from the flattened areas Newton left in the
  // star (no second Heron). Each is computed afresh from its lengths rather than as a change of the
  // old corner worked out from the two areas: such a change carries the relative error of two
  // areas, which on thin faces reaches 1e-11 rad and would accumulate over the many flattenings a
  // vertex's neighbours go through. (The frameless increments below are differences of two corners
  // each computed afresh: they add only summation round-off.)
  // (With distinct neighbours, corner k's two entries are changes[2k] at its out_vertex and
  // changes[2k+1] at its in_vertex, and every listed corner is a different one.)
  const bool simple = has_distinct_neighbours(star);
  thread_local std::vector<CornerChange> changes;
  changes.clear();
  // Without frames, a simple star's neighbours take their angle sums' increments instead
  // (new − old corner, both by corner_angle's expression: round-off only), not a walk of each fan;
  // `old_corners` holds the old corners in `changes`' order.
  const bool increments = !frames_maintained_ && simple;
  thread_local std::vector<double> old_corners;
  old_corners.clear();
  const double scale[3] = {1.0, half_scale, half_scale * half_scale};
  for (const StarCorner& c : star.corners) {
    const double a = c.l_out * scale[c.m_out], b = c.l_in * scale[c.m_in], o = c.l_opposite * scale[c.m_opposite];
    // Exactly corner_angle's expression for these half-edges (next(h): sides o, a, opposite b;
    // prev(h): sides b, o, opposite a), so stored and recomputed angle sums agree to round-off.
    if (c.out_vertex != v) changes.push_back({next(c.halfedge), std::atan2(c.four_area_flat, (o - b) * (o + b) + a * a)});
    if (c.in_vertex != v) changes.push_back({c.in_halfedge, std::atan2(c.four_area_flat, (b - a) * (b + a) + o * o)});
    if (increments) {
      const double a0 = c.l_out, b0 = c.l_in, o0 = c.l_opposite;
      old_corners.push_back(std::atan2(c.four_area, (o0 - b0) * (o0 + b0) + a0 * a0));
      old_corners.push_back(std::atan2(c.four_area, (b0 - a0) * (b0 + a0) + o0 * o0));
    }
  }
  // Every outgoing half-edge (interior and, at the boundary, the exterior one) scales its edge by
  // e^{u/2}; a self-edge is outgoing twice and so scales by e^u.
  thread_local std::vector<Index> neighbours;
  neighbours.clear();
  for_each_outgoing(v, [&](Index h) {
    elength(h >> 1) *= half_scale;
    neighbours.push_back(head(h));
  });
  if (is_boundary_vertex(v)) {
    Index last = vhalfedge(v);
    while (rotate_ccw(last) != kInvalid) last = rotate_ccw(last);
    const Index exterior_out = prev(last) ^ 1;
    elength(exterior_out >> 1) *= half_scale;
    neighbours.push_back(head(exterior_out));
  }
  // Tracked points in the star: the coordinate of each corner at v is multiplied by e^u (the
  // reference implementation's choice) and the coordinates renormalised. Visit each face once.
  const double weight = std::exp(u);
  std::vector<Index>& star_faces = scratch_faces();
  star_faces.clear();
  for_each_outgoing(v, [&](Index h) { star_faces.push_back(face(h)); });
  if (!simple) {
    std::sort(star_faces.begin(), star_faces.end());
    star_faces.erase(std::unique(star_faces.begin(), star_faces.end()), star_faces.end());
  }
  RecordWriter record(history_sink(), true, weight);
  for (Index f : star_faces) {
    const Index h0 = fhalfedge(f);
    const bool at_v[3] = {tail(h0) == v, tail(next(h0)) == v, tail(prev(h0)) == v};
    record.star_face(f, at_v);
    for_each_point_in_face(f, [&](Index p) {
      std::array<double, 3>& b = points_[p].bary;
      for (int k = 0; k < 3; ++k)
        if (at_v[k]) b[k] *= weight;
      b = clamp_barycentric(b);
    });
  }
  if (update_own_frame) recompute_vertex_frame(v);
  if (simple) {
    // Neighbour k changes at two corners: in face k (changes[2k]) and in face k−1 (changes[2k−1]);
    // at a boundary vertex the first neighbour only in face 0 and the extra last one only in the
    // last face. The frames of distinct vertices are independent: any order gives the same result.
    // Without frames each neighbour's angle sum takes its corners' increments instead.
    const int count = static_cast<int>(star.corners.size());
    const auto update = [&](Index w, int first, int second, int listed) {
      if (increments) {
        const auto increment = [&](int i) { return changes[static_cast<std::size_t>(i)].corner - old_corners[static_cast<std::size_t>(i)]; };
        vsum(w) += increment(first) + (listed == 2 ? increment(second) : 0.0);
      } else {
        const CornerChange pair[2] = {changes[static_cast<std::size_t>(first)], changes[static_cast<std::size_t>(second)]};
        refresh_vertex_frame(w, kInvalid, pair, listed);
      }
    };
    for (int k = 0; k < count; ++k)
      update(star.corners[k].out_vertex, 2 * k, k > 0 ? 2 * k - 1 : 2 * count - 1, star.boundary && k == 0 ? 1 : 2);
    if (star.boundary) update(star.corners[count - 1].in_vertex, 2 * count - 1, 2 * count - 1, 1);
    return result;
  }
  std::sort(neighbours.begin(), neighbours.end());
  neighbours.erase(std::unique(neighbours.begin(), neighbours.end()), neighbours.end());
  for (Index w : neighbours)
    if (w != v) {
      if (frames_maintained_)
        refresh_vertex_frame(w, v, changes.data(), static_cast<int>(changes.size()));
      else
        vsum(w) = compute_angle_sum(w);
    }
  return result;
}

// ------------------------------------------------------------------------------------------------
// Vertex removal

void IntrinsicTriangulation::kill_face(Index f) {
  fhalfedge(f) = kInvalid;
  ffirst(f) = kInvalid;
  decrement(num_faces_);
}

void IntrinsicTriangulation::kill_edge(Index e) {
  for (Index h : {2 * e, 2 * e + 1}) hnext(h) = hprev(h) = htail(h) = hface(h) = kInvalid;
  elength(e) = 0;
  decrement(num_edges_);
}

RemovalStatus IntrinsicTriangulation::remove_vertex(Index v, std::vector<Index>* changed_faces,
                                                    std::vector<Index>* touched, double flattening_hint) {
  // An inserted vertex has no tracked point to become: only input vertices are removed.
  if (v < 0 || v >= num_input_vertices() || !vertex_alive(v)) return RemovalStatus::NotAVertex;
  bool face_only_at_v = false;
  for_each_outgoing(v, [&](Index h) {
    if (head(h) == v && tail(prev(h)) == v) face_only_at_v = true;
  });
  if (face_only_at_v) return RemovalStatus::FaceOnlyAtVertex;
  const RemovalStatus status = is_boundary_vertex(v) ? remove_boundary_vertex(v, changed_faces, touched, flattening_hint)
                                                     : remove_interior_vertex(v, changed_faces, touched, flattening_hint);
  if (status != RemovalStatus::Removed && changed_faces && vertex_alive(v))
    for_each_outgoing(v, [&](Index h) { changed_faces->push_back(face(h)); });
  return status;
}

namespace {
// Flips outgoing edges ("spokes") of v until v has at most `target` corners, and reports its final
// corner count in *degree. Order: self-edges first, then the smallest cotan weight (the most
// non-Delaunay spoke); when a diamond is not convex the next spoke is tried. Returns false when no
// spoke can be flipped. A flip changes a face on one side of each of the two spokes beside the
// flipped one and nothing else at v, so only their priorities are recomputed (all of them when v
// has a self-edge, which appears as two spokes).
template <class Tri>
bool reduce_degree(Tri& T, Index v, int target, int* degree, std::vector<Index>* changed_faces,
                   std::vector<Index>* touched) {
  struct Spoke {
    Index h;
    double priority;
    bool candidate;  // boundary edges cannot be flipped
  };
  thread_local std::vector<Spoke> spokes;
  thread_local std::vector<int> order;
  const auto priority = [&](Index h) { return (T.head(h) == v ? 1e300 : 0.0) - T.cotan_weight(h); };
  bool self_edge = false;
  const auto collect = [&] {
    spokes.clear();
    self_edge = false;
    T.for_each_outgoing(v, [&](Index h) {
      const bool candidate = !T.is_boundary_edge(h);
      spokes.push_back({h, candidate ? priority(h) : 0.0, candidate});
      self_edge = self_edge || T.head(h) == v;
    });
  };
  const auto refresh = [&](int i) {
    if (spokes[i].candidate) spokes[i].priority = priority(spokes[i].h);
  };
  const bool cyclic = !T.is_boundary_vertex(v);  // on the boundary the fan is a sequence
  collect();
  // Without self-edges every flip takes a spoke away; a flip at a self-edge need not (it can make
  // another), and stars of many self-edges (a tufted cover's folds) could flip for ever: give up
  // after more flips than a star's spokes could ever need.
  int flips_left = 4 * static_cast<int>(spokes.size()) + 8;
  while (static_cast<int>(spokes.size()) > target) {
    if (--flips_left < 0) {
      *degree = static_cast<int>(spokes.size());
      return false;
    }
    order.clear();
    for (int i = 0; i < static_cast<int>(spokes.size()); ++i)
      if (spokes[i].candidate) order.push_back(i);
    std::sort(order.begin(), order.end(), [&](int x, int y) {
      return spokes[x].priority > spokes[y].priority || (spokes[x].priority == spokes[y].priority && x < y);
    });
    int flipped = -1;
    for (int i : order) {
      const Index h = spokes[i].h;
      const Index a = T.tail(h), b = T.head(h);
      if (T.flip(h)) {
        if (touched) touched->insert(touched->end(), {a, b, T.tail(h), T.head(h)});
        if (changed_faces) changed_faces->insert(changed_faces->end(), {T.face(h), T.face(h ^ 1)});
        flipped = i;
        break;
      }
    }
    if (flipped < 0) {
      *degree = static_cast<int>(spokes.size());
      return false;
    }
    if (self_edge) {
      collect();
      continue;
    }
    spokes.erase(spokes.begin() + flipped);
    const int n = static_cast<int>(spokes.size());
    if (n == 0) break;
    if (flipped > 0 || cyclic) refresh((flipped - 1 + n) % n);
    if (flipped < n || cyclic) refresh(flipped % n);
  }
  *degree = static_cast<int>(spokes.size());
  return true;
}
}  // namespace

RemovalStatus IntrinsicTriangulation::remove_interior_vertex(Index v, std::vector<Index>* changed_faces,
                                                             std::vector<Index>* touched, double flattening_hint) {
  // v's own frame (angle sum, coordinates) is read again only if v survives or through a
  // self-edge at v (flips of its spokes assign coordinates at the opposite corners, never at v), so
  // without self-edges it is brought up to date only on the failure paths.
  bool self_edge = false;
  for_each_outgoing(v, [&](Index h) { self_edge = self_edge || head(h) == v; });
  if (!flatten_vertex(v, flattening_hint, self_edge).success) return RemovalStatus::FlattenFailed;
  const auto fail = [&](RemovalStatus status) {
    if (!self_edge) recompute_vertex_frame(v);
    return status;
  };
  int deg = 0;
  if (!reduce_degree(*this, v, 3, &deg, changed_faces, touched)) {
    if (deg == 4 && merge_star_along_diagonal(v, changed_faces)) return RemovalStatus::Removed;
    return fail(RemovalStatus::NoConvexFlip);
  }
  if (deg < 3) return fail(RemovalStatus::TopologyChange);
  std::vector<Index>& star = scratch_faces();
  star.clear();
  for_each_outgoing(v, [&](Index h) { star.push_back(h); });
  // The merge needs three distinct faces with one corner at v each.
  for (Index h : star)
    if (head(h) == v) return fail(RemovalStatus::NoConvexFlip);
  if (face(star[0]) == face(star[1]) || face(star[1]) == face(star[2]) || face(star[0]) == face(star[2]))
    return fail(RemovalStatus::TopologyChange);
  merge_star_into_face(v, star, changed_faces);
  return RemovalStatus::Removed;
}

void IntrinsicTriangulation::merge_star_into_face(Index v, const std::vector<Index>& star,
                                                  std::vector<Index>* changed_faces) {
  const Index h0 = star[0], h1 = star[1], h2 = star[2];
  const Index o0 = next(h0), o1 = next(h1), o2 = next(h2);
  // Flat star layout: v at the origin, its neighbours around it.
  const Vec2 pv{0, 0}, p0{length(h0), 0};
  const Vec2 p1 = layout_third_point(pv, p0, length(h0), length(h1), length(o0));
  const Vec2 p2 = layout_third_point(pv, p1, length(h1), length(h2), length(o1));
  LocalLayout layout;
  layout.set(h0, pv), layout.set(o0, p0), layout.set(prev(h0), p1);
  layout.set(h1, pv), layout.set(o1, p1), layout.set(prev(h1), p2);
  layout.set(h2, pv), layout.set(o2, p2), layout.set(prev(h2), p0);
  if (RecordWriter record(history_sink()); record.active()) {
    for (Index h : star) record.old_face(*this, face(h), layout);
    record.face(face(h0), p0, p1, p2, true);
  }
  std::vector<PlacedPoint>& points = scratch_points();
  points.clear();
  for (Index h : star) collect_points(face(h), layout, points);
  points.push_back({v, pv});

  const Index f = face(h0);
  const Index f1 = face(h1), f2 = face(h2);
  link_face(o0, o1, o2);
  hface(o0) = hface(o1) = hface(o2) = f;
  fhalfedge(f) = o0;
  kill_face(f1);
  kill_face(f2);
  const Index x[3] = {tail(o0), tail(o1), tail(o2)};
  for (Index h : star) kill_edge(h >> 1);
  for (int k = 0; k < 3; ++k)
    if (!halfedge_alive(vhalfedge(x[k])) || tail(vhalfedge(x[k])) != x[k])
      vhalfedge(x[k]) = k == 0 ? o0 : (k == 1 ? o1 : o2);
  vhalfedge(v) = kInvalid;
  vsum(v) = 0;
  decrement(num_vertices_);
  // The neighbours' frames stay as they are: the star was flat, so each merged corner is exactly
  // the sum of the corners it replaces and no angle sum or angular coordinate changes.
  for (const auto& q : points) add_point_to_face(q.point, f, barycentric(q.position, p0, p1, p2));
  if (changed_faces) changed_faces->push_back(f);
}

bool IntrinsicTriangulation::merge_star_along_diagonal(Index v, std::vector<Index>* changed_faces) {
  Index spokes[4];
  int count = 0;
  for_each_outgoing(v, [&](Index h) { spokes[count++] = h; });
  for (Index h : spokes)
    if (head(h) == v) return false;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b)
      if (face(spokes[a]) == face(spokes[b])) return false;
  // Choose the diagonal through v: the one whose two corners at v sum closest to π.
  const double c0 = corner_angle(spokes[0]) + corner_angle(spokes[1]);
  const double c1 = corner_angle(spokes[1]) + corner_angle(spokes[2]);
  const int first = std::abs(c0 - kPi) <= std::abs(c1 - kPi) ? 0 : 1;
  if (std::abs((first == 0 ? c0 : c1) - kPi) > 1e-6) return false;
  Index s[4], o[4], x[4];
  for (int k = 0; k < 4; ++k) {
    s[k] = spokes[(first + k) % 4];
    o[k] = next(s[k]);
    x[k] = head(s[k]);
  }
  // Flat layout around v.
  const Vec2 pv{0, 0};
  Vec2 p[4];
  p[0] = {length(s[0]), 0};
  for (int k = 1; k < 4; ++k) p[k] = layout_third_point(pv, p[k - 1], length(s[k - 1]), length(s[k]), length(o[k - 1]));
  const double diagonal = (p[2] - p[0]).norm();
  // The two new triangles obey the flips' bound on thinness.
  if (!(smallest_angle_sine(length(o[0]), length(o[1]), diagonal) > kFlipMinSine &&
        smallest_angle_sine(length(o[2]), length(o[3]), diagonal) > kFlipMinSine))
    return false;
  LocalLayout layout;
  for (int k = 0; k < 4; ++k) layout.set(s[k], pv), layout.set(o[k], p[k]), layout.set(prev(s[k]), p[(k + 1) % 4]);
  if (RecordWriter record(history_sink()); record.active()) {
    for (int k = 0; k < 4; ++k) record.old_face(*this, face(s[k]), layout);
    record.face(face(s[0]), p[0], p[1], p[2], true);  // A and B below
    record.face(face(s[2]), p[2], p[3], p[0], true);
  }
  std::vector<PlacedPoint>& points = scratch_points();
  points.clear();
  for (int k = 0; k < 4; ++k) collect_points(face(s[k]), layout, points);
  points.push_back({v, pv});

  // Faces A = (x0, x1, x2) and B = (x2, x3, x0); s0's edge becomes the diagonal x2 <-> x0.
  const Index fa = face(s[0]), fb = face(s[2]);
  const Index dead1 = face(s[1]), dead3 = face(s[3]);
  const Index d = s[0], d_twin = s[0] ^ 1;
  htail(d) = x[2], htail(d_twin) = x[0];
  link_face(o[0], o[1], d);
  link_face(o[2], o[3], d_twin);
  hface(o[0]) = hface(o[1]) = hface(d) = fa;
  hface(o[2]) = hface(o[3]) = hface(d_twin) = fb;
  fhalfedge(fa) = o[0], fhalfedge(fb) = o[2];
  elength(d >> 1) = diagonal;
  kill_face(dead1);
  kill_face(dead3);
  for (int k = 1; k < 4; ++k) kill_edge(s[k] >> 1);
  for (int k = 0; k < 4; ++k)
    if (!halfedge_alive(vhalfedge(x[k])) || tail(vhalfedge(x[k])) != x[k]) vhalfedge(x[k]) = o[k];
  vhalfedge(v) = kInvalid;
  vsum(v) = 0;
  decrement(num_vertices_);
  for (int k = 0; k < 4; ++k) {
    bool repeated = false;
    for (int earlier = 0; earlier < k; ++earlier) repeated = repeated || x[earlier] == x[k];
    if (!repeated) recompute_vertex_frame(x[k]);
  }
  for (const auto& q : points) {
    if (orient2d(p[0], p[2], q.position) <= 0)
      add_point_to_face(q.point, fa, barycentric(q.position, p[0], p[1], p[2]));
    else
      add_point_to_face(q.point, fb, barycentric(q.position, p[2], p[3], p[0]));
  }
  if (changed_faces) changed_faces->insert(changed_faces->end(), {fa, fb});
  return true;
}

RemovalStatus IntrinsicTriangulation::remove_boundary_vertex(Index v, std::vector<Index>* changed_faces,
                                                             std::vector<Index>* touched, double flattening_hint) {
  Index hb = vhalfedge(v);  // v -> k, twin exterior
  Index last = hb;
  while (rotate_ccw(last) != kInvalid) last = rotate_ccw(last);
  const Index k = head(hb), j = tail(prev(last));
  if (j == v || k == v || j == k) return RemovalStatus::BoundaryLoopTooSmall;
  if (degree(v) == 1) {
    // An ear: flip the opposite edge first, so that flattening does not degenerate the face.
    const Index opposite = next(hb);
    if (is_boundary_edge(opposite)) return RemovalStatus::TopologyChange;
    const Index a = tail(opposite), b = head(opposite);
    if (!flip(opposite)) return RemovalStatus::NoConvexFlip;
    if (touched) touched->insert(touched->end(), {a, b, tail(opposite), head(opposite)});
    if (changed_faces) changed_faces->insert(changed_faces->end(), {face(opposite), face(opposite ^ 1)});
    flattening_hint = 0;  // the hint was for the star before this flip
  }
  if (!flatten_vertex(v, flattening_hint).success) return RemovalStatus::FlattenFailed;
  int deg = 0;
  if (!reduce_degree(*this, v, 2, &deg, changed_faces, touched)) return RemovalStatus::NoConvexFlip;
  hb = vhalfedge(v);
  const Index h2 = rotate_ccw(hb);  // v -> m
  if (h2 == kInvalid) return RemovalStatus::TopologyChange;
  const Index o1 = next(hb), o2 = next(h2), in = prev(h2);  // k -> m, m -> j, j -> v
  const Index m = head(h2);
  if (m == v || face(hb) == face(h2)) return RemovalStatus::TopologyChange;

  // Layout of the flat half-star: v at the origin, k on the x axis, j on the negative x axis.
  const Vec2 pv{0, 0}, pk{length(hb), 0};
  const Vec2 pm = layout_third_point(pv, pk, length(hb), length(h2), length(o1));
  const Vec2 pj = layout_third_point(pv, pm, length(h2), length(in), length(o2));
  LocalLayout layout;
  layout.set(hb, pv), layout.set(o1, pk), layout.set(prev(hb), pm);
  layout.set(h2, pv), layout.set(o2, pm), layout.set(in, pj);
  if (RecordWriter record(history_sink()); record.active()) {
    record.old_face(*this, face(hb), layout);
    record.old_face(*this, face(h2), layout);
    record.face(face(hb), pk, pm, pj, true);
  }
  std::vector<PlacedPoint>& points = scratch_points();
  points.clear();
  collect_points(face(hb), layout, points);
  collect_points(face(h2), layout, points);
  points.push_back({v, pv});

  const double new_length = length(hb) + length(in);
  const Index f = face(hb), f2 = face(h2);
  // Re-use hb's edge as the new boundary edge j -> k (twin k -> j stays exterior).
  htail(hb) = j, htail(hb ^ 1) = k;
  link_face(o1, o2, hb);
  hface(o2) = f;
  fhalfedge(f) = o1;
  elength(hb >> 1) = new_length;
  kill_face(f2);
  kill_edge(h2 >> 1);
  kill_edge(in >> 1);
  vhalfedge(j) = hb;
  if (!halfedge_alive(vhalfedge(m)) || tail(vhalfedge(m)) != m) vhalfedge(m) = o2;
  vhalfedge(v) = kInvalid;
  vsum(v) = 0;
  decrement(num_vertices_);
  recompute_vertex_frame(j);
  recompute_vertex_frame(k);
  if (m != j && m != k) recompute_vertex_frame(m);
  for (const auto& q : points) add_point_to_face(q.point, f, barycentric(q.position, pk, pm, pj));
  if (changed_faces) changed_faces->push_back(f);
  return RemovalStatus::Removed;
}

// ------------------------------------------------------------------------------------------------
// Insertions (Delaunay refinement)

Index IntrinsicTriangulation::new_vertex(bool boundary, double angle_sum) {
  vertices_.push_back(VertexRecord{kInvalid, boundary ? 1 : 0, angle_sum});
  ++num_vertices_;
  return static_cast<Index>(vertices_.size()) - 1;
}

Index IntrinsicTriangulation::new_edge(double length) {
  EdgeRecord record{};
  for (int side = 0; side < 2; ++side)
    record.next[side] = record.prev[side] = record.tail[side] = record.face[side] = kInvalid, record.angle[side] = 0;
  record.length = length;
  edges_.push_back(record);
  ++num_edges_;
  return static_cast<Index>(edges_.size()) - 1;
}

Index IntrinsicTriangulation::new_face() {
  faces_.push_back(FaceRecord{kInvalid, kInvalid});
  ++num_faces_;
  return static_cast<Index>(faces_.size()) - 1;
}

namespace {
// Counter-clockwise angle from direction a to direction b, in [0, 2π).
double angle_between(Vec2 a, Vec2 b) {
  const double angle = std::atan2(cross(a, b), a.x * b.x + a.y * b.y);
  return angle < 0 ? angle + kTwoPi : angle;
}
}  // namespace

Index IntrinsicTriangulation::insert_vertex(Index f, const std::array<double, 3>& bary, std::vector<Index>* new_faces) {
  if (f < 0 || f >= num_face_slots() || !face_alive(f))
    throw std::invalid_argument("insert_vertex: face " + std::to_string(f) + " is not a live face");
  if (!(bary[0] > 0 && bary[1] > 0 && bary[2] > 0) || std::abs(bary[0] + bary[1] + bary[2] - 1) > 1e-9)
    throw std::invalid_argument("insert_vertex: barycentric coordinates must be positive and sum to 1");
  const Index h0 = fhalfedge(f), h1 = next(h0), h2 = next(h1);
  const Index c0 = tail(h0), c1 = tail(h1), c2 = tail(h2);
  const Vec2 p0{0, 0}, p1{length(h0), 0};
  const Vec2 p2 = layout_third_point(p0, p1, length(h0), length(h2), length(h1));
  const Vec2 q = p0 * bary[0] + p1 * bary[1] + p2 * bary[2];
  // As flip(): no triangle thinner than kFlipMinSine (its angles would be mostly round-off).
  const double d0 = (q - p0).norm(), d1 = (q - p1).norm(), d2 = (q - p2).norm();
  if (!(smallest_angle_sine(length(h0), d1, d0) > kFlipMinSine && smallest_angle_sine(length(h1), d2, d1) > kFlipMinSine &&
        smallest_angle_sine(length(h2), d0, d2) > kFlipMinSine))
    return kInvalid;

  std::vector<PlacedPoint>& points = scratch_points();
  points.clear();
  LocalLayout layout;
  layout.set(h0, p0);
  layout.set(h1, p1);
  layout.set(h2, p2);
  collect_points(f, layout, points);
  RecordWriter record(history_sink());
  record.old_face(*this, f, layout);

  // Spokes c_k <-> v: half-edge 2e goes c_k -> v, 2e + 1 goes v -> c_k.
  const Index v = new_vertex(false, kTwoPi);
  const Index e0 = new_edge(d0), e1 = new_edge(d1), e2 = new_edge(d2);
  const Index f1 = new_face(), f2 = new_face();
  const Index to0 = 2 * e0, from0 = 2 * e0 + 1, to1 = 2 * e1, from1 = 2 * e1 + 1, to2 = 2 * e2, from2 = 2 * e2 + 1;
  htail(to0) = c0, htail(from0) = v, htail(to1) = c1, htail(from1) = v, htail(to2) = c2, htail(from2) = v;
  // f = (c0 -> c1 -> v), f1 = (c1 -> c2 -> v), f2 = (c2 -> c0 -> v).
  link_face(h0, to1, from0);
  link_face(h1, to2, from1);
  link_face(h2, to0, from2);
  hface(h0) = hface(to1) = hface(from0) = f;
  hface(h1) = hface(to2) = hface(from1) = f1;
  hface(h2) = hface(to0) = hface(from2) = f2;
  fhalfedge(f) = h0, fhalfedge(f1) = h1, fhalfedge(f2) = h2;
  vhalfedge(v) = from0;
  // The corners keep their angle sums; each new spoke sits inside its corner.
  hangle(to0) = wrap_angle(hangle(h0) + angle_scale(c0) * angle_between(p1 - p0, q - p0));
  hangle(to1) = wrap_angle(hangle(h1) + angle_scale(c1) * angle_between(p2 - p1, q - p1));
  hangle(to2) = wrap_angle(hangle(h2) + angle_scale(c2) * angle_between(p0 - p2, q - p2));
  hangle(from0) = 0;
  recompute_vertex_frame(v);
  record.face(f, p0, p1, q, true);
  record.face(f1, p1, p2, q, true);
  record.face(f2, p2, p0, q, true);

  // Every point lies in f: the two spokes that bound a sub-face decide.
  for (const auto& point : points) {
    const Vec2 x = point.position;
    if (orient2d(p1, q, x) >= 0 && orient2d(q, p0, x) >= 0)
      add_point_to_face(point.point, f, barycentric(x, p0, p1, q));
    else if (orient2d(p2, q, x) >= 0 && orient2d(q, p1, x) >= 0)
      add_point_to_face(point.point, f1, barycentric(x, p1, p2, q));
    else
      add_point_to_face(point.point, f2, barycentric(x, p2, p0, q));
  }
  if (new_faces) new_faces->insert(new_faces->end(), {f, f1, f2});
  return v;
}

Index IntrinsicTriangulation::split_edge(Index h, double t, std::vector<Index>* new_faces) {
  if (h < 0 || h >= num_halfedge_slots() || !halfedge_alive(h))
    throw std::invalid_argument("split_edge: half-edge " + std::to_string(h) + " is not alive");
  if (!(t > 0 && t < 1)) throw std::invalid_argument("split_edge: the fraction must lie in (0, 1)");
  if (is_exterior(h)) {  // split from the interior side
    h ^= 1;
    t = 1 - t;
  }
  const Index tw = h ^ 1;
  const bool boundary = is_exterior(tw);
  if (!boundary && face(h) == face(tw)) return kInvalid;
  const Index j = tail(tw);
  const double l_ij = length(h);
  // Face A (h: i -> j, a: j -> k, b: k -> i) laid out with i at the origin and j on +x; face B
  // (tw: j -> i, c: i -> l, d: l -> j) below the axis.
  const Index fa = face(h), a = next(h), b = next(a), k = tail(b);
  const Vec2 pi{0, 0}, pj{l_ij, 0};
  const Vec2 pk = layout_third_point(pi, pj, l_ij, length(b), length(a));
  const Vec2 pm{t * l_ij, 0};
  const auto too_thin = [](Vec2 x, Vec2 y, Vec2 z) {
    return !(smallest_angle_sine((y - x).norm(), (z - y).norm(), (x - z).norm()) > kFlipMinSine);
  };
  Index fb = kInvalid, c = kInvalid, d = kInvalid, l = kInvalid;
  Vec2 pl;
  if (!boundary) {
    fb = face(tw), c = next(tw), d = next(c), l = tail(d);
    pl = layout_third_point(pj, pi, l_ij, length(d), length(c));
  }
  if (too_thin(pi, pm, pk) || too_thin(pm, pj, pk) || (!boundary && (too_thin(pj, pm, pl) || too_thin(pm, pi, pl))))
    return kInvalid;
  std::vector<PlacedPoint>& points = scratch_points();
  points.clear();
  LocalLayout layout;
  layout.set(h, pi);
  layout.set(a, pj);
  layout.set(b, pk);
  collect_points(fa, layout, points);
  RecordWriter record(history_sink());
  record.old_face(*this, fa, layout);
  if (!boundary) {
    LocalLayout below;
    below.set(tw, pj);
    below.set(c, pi);
    below.set(d, pl);
    collect_points(fb, below, points);
    record.old_face(*this, fb, below);
  }
  const double old_angle_tw = hangle(tw);
  const bool j_started_at_tw = vhalfedge(j) == tw;

  // Edge of h becomes i—m; g is m—j; spokes m—k and m—l.
  const Index m = new_vertex(boundary, boundary ? kPi : kTwoPi);
  const Index g = new_edge((1 - t) * l_ij);
  const Index spoke_k = new_edge((pk - pm).norm());
  elength(h >> 1) = t * l_ij;
  const Index m_to_j = 2 * g, j_to_m = 2 * g + 1, m_to_k = 2 * spoke_k, k_to_m = 2 * spoke_k + 1;
  const Index m_to_i = tw;  // the old twin now runs m -> i
  htail(m_to_i) = m, htail(m_to_j) = m, htail(j_to_m) = j, htail(m_to_k) = m, htail(k_to_m) = k;
  const Index fa2 = new_face();
  Index fb2 = kInvalid;
  // A = (h: i -> m, m -> k, b: k -> i), A2 = (m -> j, a: j -> k, k -> m).
  link_face(h, m_to_k, b);
  link_face(m_to_j, a, k_to_m);
  hface(h) = hface(m_to_k) = hface(b) = fa;
  hface(m_to_j) = hface(a) = hface(k_to_m) = fa2;
  fhalfedge(fa) = h, fhalfedge(fa2) = m_to_j;
  hangle(k_to_m) = wrap_angle(hangle(b) + angle_scale(k) * angle_between(pi - pk, pm - pk));
  hangle(j_to_m) = old_angle_tw;
  if (boundary) {
    hnext(m_to_i) = hprev(m_to_i) = kInvalid;
    hface(m_to_i) = kInvalid;
    hnext(j_to_m) = hprev(j_to_m) = kInvalid;
    hface(j_to_m) = kInvalid;
    vhalfedge(m) = m_to_j;  // the first outgoing half-edge counter-clockwise: its twin is exterior
  } else {
    const Index spoke_l = new_edge((pl - pm).norm());
    const Index m_to_l = 2 * spoke_l, l_to_m = 2 * spoke_l + 1;
    htail(m_to_l) = m, htail(l_to_m) = l;
    fb2 = new_face();
    // B = (j -> m, m -> l, d: l -> j), B2 = (m -> i, c: i -> l, l -> m).
    link_face(j_to_m, m_to_l, d);
    link_face(m_to_i, c, l_to_m);
    hface(j_to_m) = hface(m_to_l) = hface(d) = fb;
    hface(m_to_i) = hface(c) = hface(l_to_m) = fb2;
    fhalfedge(fb) = j_to_m, fhalfedge(fb2) = m_to_i;
    hangle(l_to_m) = wrap_angle(hangle(d) + angle_scale(l) * angle_between(pj - pl, pm - pl));
    vhalfedge(m) = m_to_k;
    hangle(m_to_k) = 0;
    if (new_faces) new_faces->insert(new_faces->end(), {fb, fb2});
  }
  if (j_started_at_tw) vhalfedge(j) = j_to_m;
  recompute_vertex_frame(m);
  record.face(fa, pi, pm, pk, true);
  record.face(fa2, pm, pj, pk, true);
  if (!boundary) {
    record.face(fb, pj, pm, pl, true);
    record.face(fb2, pm, pi, pl, true);
  }

  for (const auto& point : points) {
    const Vec2 x = point.position;
    if (x.y >= 0 || boundary) {
      if (orient2d(pm, pk, x) >= 0)
        add_point_to_face(point.point, fa, barycentric(x, pi, pm, pk));
      else
        add_point_to_face(point.point, fa2, barycentric(x, pm, pj, pk));
    } else {
      if (orient2d(pl, pm, x) <= 0)
        add_point_to_face(point.point, fb, barycentric(x, pj, pm, pl));
      else
        add_point_to_face(point.point, fb2, barycentric(x, pm, pi, pl));
    }
  }
  if (new_faces) new_faces->insert(new_faces->end(), {fa, fa2});
  return m;
}

// ------------------------------------------------------------------------------------------------
// Export and checks

namespace {
// Threads for the passes of compact() and compacted() over a mesh of `slots` vertex slots.
int compact_threads(Index slots) { return detail::threads_for(static_cast<std::size_t>(slots), kParallelBuildVertices); }
}  // namespace

IntrinsicTriangulation::CompactNumbers IntrinsicTriangulation::compact_numbers(int threads) const {
  CompactNumbers numbers;
  numbers.vertices = number_alive(num_vertex_slots(), [this](Index v) { return vertex_alive(v); }, threads, numbers.vertex);
  numbers.faces = number_alive(num_face_slots(), [this](Index f) { return face_alive(f); }, threads, numbers.face);
  return numbers;
}

IntrinsicTriangulation IntrinsicTriangulation::compacted(CompactMesh* maps) const {
  const int threads = compact_threads(num_vertex_slots());
  const CompactNumbers numbers = compact_numbers(threads);
  CompactMesh arrays = compact(numbers, threads);
  const std::vector<Index>& vertex_id = numbers.vertex;
  const std::vector<Index>& face_id = numbers.face;
  std::vector<Index> edge_id;
  const Index edges = number_alive(static_cast<Index>(edges_.size()), [this](Index e) { return halfedge_alive(2 * e); }, threads, edge_id);
  const auto halfedge_id = [&](Index h) { return h == kInvalid ? kInvalid : 2 * edge_id[h >> 1] + (h & 1); };

  IntrinsicTriangulation T;
  T.edges_.resize(edges);
  detail::run_ranges(threads, static_cast<Index>(edges_.size()), [&](Index begin, Index end) {
    for (Index e = begin; e < end; ++e) {
      if (edge_id[e] == kInvalid) continue;
      const EdgeRecord& old_record = edges_[e];
      EdgeRecord& record = T.edges_[edge_id[e]];
      for (int side = 0; side < 2; ++side) {
        record.next[side] = halfedge_id(old_record.next[side]);
        record.prev[side] = halfedge_id(old_record.prev[side]);
        record.tail[side] = vertex_id[old_record.tail[side]];
        record.face[side] = old_record.face[side] == kInvalid ? kInvalid : face_id[old_record.face[side]];
        record.angle[side] = old_record.angle[side];
      }
      record.length = old_record.length;
    }
  });
  T.faces_.resize(numbers.faces);
  detail::run_ranges(threads, num_face_slots(), [&](Index begin, Index end) {
    for (Index f = begin; f < end; ++f)
      if (face_id[f] != kInvalid) T.faces_[face_id[f]] = FaceRecord{halfedge_id(fhalfedge(f)), kInvalid};
  });
  T.vertices_.resize(numbers.vertices);
  detail::run_ranges(threads, num_vertex_slots(), [&](Index begin, Index end) {
    for (Index v = begin; v < end; ++v)
      if (vertex_id[v] != kInvalid) {
        const VertexRecord& old_record = vertices_[v];
        T.vertices_[vertex_id[v]] = VertexRecord{halfedge_id(old_record.halfedge), old_record.boundary, old_record.angle_sum};
      }
  });
  T.points_.assign(numbers.vertices, TrackedPoint{kInvalid, kInvalid, {0, 0, 0}});
  T.num_vertices_ = numbers.vertices, T.num_edges_ = edges, T.num_faces_ = numbers.faces;
  T.frames_maintained_ = frames_maintained_;  // the coordinates copied are current only if they were
  if (maps) *maps = std::move(arrays);
  return T;
}

CompactMesh IntrinsicTriangulation::compact() const {
  const int threads = compact_threads(num_vertex_slots());
  return compact(compact_numbers(threads), threads);
}

CompactMesh IntrinsicTriangulation::compact(const CompactNumbers& numbers, int threads) const {
  CompactMesh out;
  // Live input vertices first (in input order), then live inserted vertices (to_input kInvalid).
  const std::vector<Index>& compact_of = numbers.vertex;
  out.from_input.assign(compact_of.begin(), compact_of.begin() + num_input_vertices());
  out.to_input.resize(static_cast<std::size_t>(numbers.vertices));
  out.vertex_count = numbers.vertices;
  detail::run_ranges(threads, num_vertex_slots(), [&](Index begin, Index end) {
    for (Index v = begin; v < end; ++v)
      if (compact_of[v] != kInvalid) out.to_input[static_cast<std::size_t>(compact_of[v])] = v < num_input_vertices() ? v : kInvalid;
  });
  out.F.resize(numbers.faces, 3);
  out.L.resize(numbers.faces, 3);
  // Each live half-edge's side (3·row + k), then the gluing through the twin half-edges.
  std::vector<Index> side_of(static_cast<std::size_t>(num_halfedge_slots()), kInvalid);
  detail::run_ranges(threads, num_face_slots(), [&](Index begin, Index end) {
    for (Index f = begin; f < end; ++f) {
      const Index row = numbers.face[f];
      if (row == kInvalid) continue;
      Index h = fhalfedge(f);
      for (int k = 0; k < 3; ++k, h = next(h)) {
        out.F(row, k) = compact_of[tail(h)];
        out.L(row, k) = length(h);
        side_of[h] = 3 * row + k;
      }
    }
  });
  out.twin.assign(static_cast<std::size_t>(3 * numbers.faces), kInvalid);
  detail::run_ranges(threads, num_halfedge_slots(), [&](Index begin, Index end) {
    for (Index h = begin; h < end; ++h)
      if (side_of[h] != kInvalid) out.twin[side_of[h]] = side_of[h ^ 1];  // kInvalid: exterior twin
  });
  return out;
}

std::string IntrinsicTriangulation::validate(double tolerance) const {
  std::ostringstream problems;
  int count = 0;
  const auto fail = [&](const std::string& what) {
    if (count++ < 10) problems << what << "\n";
  };
  const Index H = num_halfedge_slots();
  Index live_edges = 0, live_faces = 0, live_vertices = 0;
  double face_roundoff_sum = 0;  // Σ over faces of the angle round-off their shape allows
  std::vector<double> vertex_roundoff(static_cast<std::size_t>(num_vertex_slots()), 0.0);
  for (Index h = 0; h < H; h += 2) {
    const bool alive0 = halfedge_alive(h), alive1 = halfedge_alive(h + 1);
    if (alive0 != alive1) fail("half-edge " + std::to_string(h) + " alive without its twin");
    if (!alive0) continue;
    ++live_edges;
    if (is_exterior(h) && is_exterior(h + 1)) fail("edge " + std::to_string(h / 2) + " has no face");
    const double l = elength(h / 2);
    if (!(l > 0) || !std::isfinite(l)) fail("edge " + std::to_string(h / 2) + " has a non-positive length");
  }
  for (Index h = 0; h < H; ++h) {
    if (!halfedge_alive(h)) continue;
    const Index v = tail(h);
    if (v < 0 || v >= num_vertex_slots() || !vertex_alive(v))
      fail("half-edge " + std::to_string(h) + " starts at a dead vertex");
    if (is_exterior(h)) continue;
    const Index n = next(h);
    if (n == kInvalid || !halfedge_alive(n) || face(n) != face(h) || next(next(n)) != h)
      fail("half-edge " + std::to_string(h) + " is not in a 3-cycle of its face");
    else if (hprev(n) != h || hprev(h) != next(n))
      fail("half-edge " + std::to_string(h) + ": stored prev disagrees with next");
    else if (head(h) != tail(n))
      fail("half-edge " + std::to_string(h) + ": head differs from the tail of next");
  }
  for (Index f = 0; f < num_face_slots(); ++f) {
    if (!face_alive(f)) {
      if (ffirst(f) != kInvalid) fail("dead face " + std::to_string(f) + " holds points");
      continue;
    }
    ++live_faces;
    const Index h = fhalfedge(f);
    if (!halfedge_alive(h) || face(h) != f) {
      fail("face " + std::to_string(f) + " has a bad half-edge");
      continue;
    }
    const double a = length(h), b = length(next(h)), c = length(prev(h));
    if (!triangle_inequality_holds(a, b, c)) {
      fail("face " + std::to_string(f) + " violates the triangle inequality");
      continue;
    }
    // Angles of a face whose smallest angle is θ carry round-off of about ε/θ (sin θ = 2·area over
    // the product of the two longest sides); the checks of stored against recomputed angles allow it.
    const double smallest_sine = 2 * triangle_area(a, b, c) * std::min({a, b, c}) / (a * b * c);
    const double roundoff = kAngleRoundoffPerSine / smallest_sine;
    face_roundoff_sum += 3 * roundoff;
    for (Index k = 0, g = h; k < 3; ++k, g = next(g))
      if (tail(g) >= 0 && tail(g) < num_vertex_slots()) vertex_roundoff[tail(g)] += roundoff;
  }
  if (live_edges != num_edges_ || live_faces != num_faces_)
    fail("element counts out of date");
  if (count > 0) return problems.str();  // connectivity is broken: stop before walking it

  double curvature_sum = 0;
  for (Index v = 0; v < num_vertex_slots(); ++v) {
    if (!vertex_alive(v)) continue;
    ++live_vertices;
    const Index start = vhalfedge(v);
    if (!halfedge_alive(start) || tail(start) != v || is_exterior(start)) {
      fail("vertex " + std::to_string(v) + " has a bad half-edge");
      continue;
    }
    // Walk the fan with a step bound (a broken rotation must not hang validate()).
    double theta = 0;
    Index h = start;
    Index steps = 0;
    const double scale = angle_scale(v);
    bool broken = false;
    while (true) {
      if (++steps > H) {
        fail("vertex " + std::to_string(v) + ": rotation does not close");
        broken = true;
        break;
      }
      const double corner = corner_angle(h);
      theta += corner;
      const Index t = prev(h) ^ 1;
      const double expected = hangle(h) + scale * corner;
      const double got = hangle(t);
      double gap = std::fmod(std::abs(expected - got), kTwoPi);
      gap = std::min(gap, kTwoPi - gap);
      if (gap > 1e-7 && frames_maintained_) fail("vertex " + std::to_string(v) + ": angular coordinates inconsistent");
      if (is_exterior(t) || t == start) break;
      h = t;
    }
    if (broken) continue;
    if (std::abs(theta - vsum(v)) > std::max(tolerance, kThinTriangleAngleRoundoff) + vertex_roundoff[v])
      fail("vertex " + std::to_string(v) + ": stale angle sum");
    curvature_sum += curvature(v);
  }
  if (live_vertices != num_vertices_) fail("vertex count out of date");
  const double gauss_bonnet = kTwoPi * euler_characteristic();
  if (std::abs(curvature_sum - gauss_bonnet) > tolerance * std::max<double>(1.0, num_vertices_) + face_roundoff_sum)
    fail("Gauss-Bonnet violated: total curvature " + std::to_string(curvature_sum) + " vs 2*pi*chi " +
         std::to_string(gauss_bonnet));

  // Tracked points.
  Index listed = 0;
  for (Index f = 0; f < num_face_slots(); ++f) {
    if (!face_alive(f)) continue;
    for (Index p = ffirst(f); p != kInvalid; p = points_[p].next) {
      if (++listed > num_input_vertices()) {
        fail("point list of face " + std::to_string(f) + " does not end");
        return problems.str();
      }
      if (points_[p].face != f) fail("point " + std::to_string(p) + " listed in the wrong face");
    }
  }
  Index located = 0;
  for (Index p = 0; p < num_input_vertices(); ++p) {
    if (vertex_alive(p)) {
      if (points_[p].face != kInvalid) fail("point " + std::to_string(p) + " is a vertex and in a face");
      continue;
    }
    ++located;
    const Index f = points_[p].face;
    if (f == kInvalid || !face_alive(f)) {
      fail("removed vertex " + std::to_string(p) + " is in no live face");
      continue;
    }
    const auto& b = points_[p].bary;
    if (b[0] < -tolerance || b[1] < -tolerance || b[2] < -tolerance ||
        std::abs(b[0] + b[1] + b[2] - 1) > tolerance)
      fail("point " + std::to_string(p) + " has barycentric coordinates outside its face");
  }
  if (located != listed) fail("point lists and point faces disagree");
  return problems.str();
}

std::size_t IntrinsicTriangulation::memory_bytes() const {
  const auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  return bytes(edges_) + bytes(vertices_) + bytes(faces_) + bytes(points_) + history_.memory_bytes();
}

}  // namespace ice
