#include "ice/coarse_tracing.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "ice/intrinsic_triangulation.h"  // glue_by_vertex_pairs
#include "ice/triangle_geometry.h"
#include "run_tasks.h"

namespace ice {

const char* to_string(TraceStatus status) {
  switch (status) {
    case TraceStatus::traced: return "traced";
    case TraceStatus::left_surface: return "left_surface";
    case TraceStatus::lost: return "lost";
    case TraceStatus::step_limit: return "step_limit";
    case TraceStatus::crossed: return "crossed";
  }
  return "unknown";
}

namespace {

// A coarse face laid out in the plane of a trace.
struct FaceCopy {
  Index face = kInvalid;
  std::array<Vec2, 3> corner{};
};

// Unfolding limits of a placement: the coarse faces between an input vertex's image and the images
// of its neighbours are few (coarse faces are much larger than input faces); these bounds only stop
// a search on a broken map.
constexpr int kMaxDepth = 12;
constexpr std::size_t kMaxCopies = 512;
// An end vertex counts as reached when its image is this close (relative to the edge length) to the
// segment's end: placements differ from exact by round-off only.
constexpr double kEndTolerance = 1e-6;
// Fraction of a coarse side left off at each end when testing whether an unfolding crosses it
// inside an image (unfolds_through).
constexpr double kSideShrink = 1e-9;

// Where on the side p → q the x axis crosses it, as a fraction from p (p and q on opposite sides).
double axis_fraction(Vec2 p, Vec2 q) { return p.y / (p.y - q.y); }

// Closed-set intersection of the segment (a, b) with the convex hull of 1–3 points, with a
// tolerance of round-off size: touching counts.
bool segment_meets_hull(Vec2 a, Vec2 b, const std::vector<Vec2>& hull) {
  double scale = (b - a).norm();
  for (const Vec2& p : hull) scale = std::max(scale, (p - a).norm());
  const double eps = 1e-12 * scale * scale;
  const auto segments_meet = [eps](Vec2 p, Vec2 q, Vec2 r, Vec2 s) {
    const double d1 = orient2d(p, q, r), d2 = orient2d(p, q, s), d3 = orient2d(r, s, p), d4 = orient2d(r, s, q);
    if (((d1 > eps && d2 > eps) || (d1 < -eps && d2 < -eps)) || ((d3 > eps && d4 > eps) || (d3 < -eps && d4 < -eps)))
      return false;
    // Collinear within tolerance: overlap of the projections.
    if (std::abs(d1) <= eps && std::abs(d2) <= eps) {
      const Vec2 u = q - p;
      const double t0 = (r.x - p.x) * u.x + (r.y - p.y) * u.y, t1 = (s.x - p.x) * u.x + (s.y - p.y) * u.y;
      const double length2 = u.x * u.x + u.y * u.y;
      return std::max(t0, t1) >= -eps && std::min(t0, t1) <= length2 + eps;
    }
    return true;
  };
  if (hull.size() == 1) return segments_meet(a, b, hull[0], hull[0]);
  if (hull.size() == 2) return segments_meet(a, b, hull[0], hull[1]);
  const Vec2 p = hull[0], q = hull[1], r = hull[2];
  const double area = orient2d(p, q, r);
  if (std::abs(area) > eps) {  // an endpoint inside the triangle
    const double sign = area > 0 ? 1 : -1;
    for (const Vec2& x : {a, b})
      if (sign * orient2d(p, q, x) >= -eps && sign * orient2d(q, r, x) >= -eps && sign * orient2d(r, p, x) >= -eps)
        return true;
  }
  return segments_meet(a, b, p, q) || segments_meet(a, b, q, r) || segments_meet(a, b, r, p);
}

// The shape of an input triangle (p, q, c) whose side p → q is laid out at (p_image, q_image): how
// far an image x of c is from that shape, by its distances to the side's ends relative to the side
// (0 for an image similar to the input triangle).
struct TriangleShape {
  Vec2 p_image, q_image;
  double image_side = 0, to_p = 0, to_q = 0;  // |p_image q_image|; |pc| and |qc| over |pq| on the input
  double error(Vec2 x) const {
    return std::abs(std::log((x - p_image).norm() / image_side / to_p)) +
           std::abs(std::log((x - q_image).norm() / image_side / to_q));
  }
};

class Tracer {
 public:
  Tracer(const Faces& F, const CompactMesh& coarse, const std::vector<CoarsePoint>& map,
         const std::vector<InputSurfacePoint>& inserted, const Positions& V)
      : F_(F), coarse_(coarse), map_(map), inserted_(inserted), V_(V) {
    coarse_twin_ = coarse.twin.empty() ? glue_by_vertex_pairs(coarse.F) : coarse.twin;
    fine_twin_ = glue_by_vertex_pairs(F);
    // Input vertex -> its faces (compressed rows), for the first step out of a vertex.
    const Index n = static_cast<Index>(map.size());
    face_start_.assign(static_cast<std::size_t>(n) + 1, 0);
    for (Index t = 0; t < F.rows(); ++t)
      for (int k = 0; k < 3; ++k) ++face_start_[F(t, k) + 1];
    for (Index v = 0; v < n; ++v) face_start_[v + 1] += face_start_[v];
    vertex_faces_.resize(static_cast<std::size_t>(3 * F.rows()));
    std::vector<Index> fill(face_start_.begin(), face_start_.end() - 1);
    for (Index t = 0; t < F.rows(); ++t)
      for (int k = 0; k < 3; ++k) vertex_faces_[fill[F(t, k)]++] = t;
    for (Index c = 0; c < coarse.num_vertices(); ++c)
      if (coarse.to_input[c] != kInvalid) ++first_inserted_;
    angle_sum_.assign(static_cast<std::size_t>(coarse.num_vertices()), 0.0);
    boundary_vertex_.assign(static_cast<std::size_t>(coarse.num_vertices()), 0);
    for (Index g = 0; g < coarse.F.rows(); ++g)
      for (int k = 0; k < 3; ++k) {
        angle_sum_[coarse.F(g, k)] += corner_angle(g, k);
        if (coarse_twin_[static_cast<std::size_t>(3 * g + k)] == kInvalid)
          boundary_vertex_[coarse.F(g, k)] = boundary_vertex_[coarse.F(g, (k + 1) % 3)] = 1;
      }
  }

  const std::vector<Index>& coarse_twin() const { return coarse_twin_; }
  const std::vector<Index>& fine_twin() const { return fine_twin_; }

  TracedEdge trace(Index side) const;
  Index face_patch(Index t) const;

 private:
  struct Placement {
    Vec2 position;
    FaceCopy copy;
  };
  using Cache = std::unordered_map<Index, Placement>;

  double coarse_length(Index f, int k) const { return coarse_.L(f, k); }
  double corner_angle(Index f, int k) const {
    return angle_opposite(coarse_length(f, k), coarse_length(f, (k + 2) % 3), coarse_length(f, (k + 1) % 3));
  }

  // A face of the star of an end vertex of the traced edge, laid out about it: the vertex is corner
  // `centre`, and the face spans the angles [start, start + corner angle] about it, counted
  // counter-clockwise from the direction of the traced edge (tail) or of its reverse (head).
  struct StarCopy {
    FaceCopy copy;
    int centre = 0;
    double start = 0;
  };

  // The star of `vertex` unfolded both ways from copy0 (vertex at corner `centre`, spanning from
  // angle `start`) until each way passes half the vertex's angle sum (the cut is opposite the
  // edge, away from where the walk goes); a boundary vertex's whole star.
  void add_star(const FaceCopy& copy0, int centre, double start, std::vector<StarCopy>& star) const {
    const Index vertex = coarse_.F(copy0.face, centre);
    const bool open = boundary_vertex_[vertex] != 0;
    const double half = 0.5 * angle_sum_[vertex];
    const std::size_t limit = star.size() + 4 * static_cast<std::size_t>(coarse_.F.rows()) + 8;
    star.push_back({copy0, centre, start});
    // Counter-clockwise: across the side into the centre.
    for (StarCopy cur = star.back(); star.size() < limit;) {
      const double end = cur.start + corner_angle(cur.copy.face, cur.centre);
      if (!open && end >= half) break;
      const int side = (cur.centre + 2) % 3;
      const FaceCopy next = across(cur.copy, side);
      if (next.face == kInvalid) break;
      const int d = static_cast<int>(coarse_twin_[static_cast<std::size_t>(3 * cur.copy.face + side)] % 3);
      cur = {next, d, end};
      star.push_back(cur);
    }
    // Clockwise: across the side out of the centre.
    StarCopy cur{copy0, centre, start};
    while (star.size() < limit && (open || cur.start > -half)) {
      const FaceCopy next = across(cur.copy, cur.centre);
      if (next.face == kInvalid) break;
      const int d = static_cast<int>(coarse_twin_[static_cast<std::size_t>(3 * cur.copy.face + cur.centre)] % 3);
      const int centre_next = (d + 1) % 3;
      cur = {next, centre_next, cur.start - corner_angle(next.face, centre_next)};
      star.push_back(cur);
    }
  }

  // Places input vertex v in the stars of the edge's ends (cached per trace): its images in the
  // star copies within the cut (a coarse vertex: each corner that is it), the one nearest `near`.
  // The stars hold every coarse face an input triangle crossed by the edge reaches, unless input
  // triangles are large against coarse faces: then place() searches further.
  // How a candidate image ranks (smaller first): by `shape` when given, else by its distance to `near`.
  static double closeness(Vec2 position, Vec2 near, const TriangleShape* shape) {
    return shape ? shape->error(position) : (position - near).norm();
  }

  const Placement* place_in_star(Index v, const std::vector<StarCopy>& star, Vec2 near, Cache& cache,
                                 const TriangleShape* shape = nullptr, const std::array<Vec2, 2>* left_of = nullptr) const {
    const auto hit = cache.find(v);
    if (hit != cache.end()) return &hit->second;
    const CoarsePoint& point = map_[static_cast<std::size_t>(v)];
    bool have = false;
    double best = 0;
    Placement chosen;
    for (const StarCopy& member : star) {
      const Index vertex = coarse_.F(member.copy.face, member.centre);
      const double half = boundary_vertex_[vertex] ? 1e300 : 0.5 * angle_sum_[vertex] + 1e-9;
      const Vec2 centre = member.copy.corner[member.centre];
      const Vec2 first = member.copy.corner[(member.centre + 1) % 3] - centre;
      images_in(point, member.copy, [&](Vec2 position) {
        const Vec2 w = position - centre;
        const double within = w.norm() == 0 ? 0 : std::atan2(cross(first, w), first.x * w.x + first.y * w.y);
        const double angle = member.start + within;
        if (angle < -half || angle > half) return;
        // With `left_of` (see place()), only images on its left.
        if (left_of && orient2d((*left_of)[0], (*left_of)[1], position) <= 0) return;
        const double distance = closeness(position, near, shape);
        if (!have || distance < best) {
          have = true;
          best = distance;
          chosen = {position, member.copy};
        }
      });
    }
    if (!have) return nullptr;
    return &cache.emplace(v, chosen).first->second;
  }

  // Face f with corner k at the origin and corner k + 1 on the positive x axis.
  FaceCopy along_side(Index f, int k) const {
    FaceCopy copy;
    copy.face = f;
    const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
    const double base = coarse_length(f, k);
    copy.corner[k] = {0, 0};
    copy.corner[k1] = {base, 0};
    copy.corner[k2] = layout_third_point(copy.corner[k], copy.corner[k1], base, coarse_length(f, k2), coarse_length(f, k1));
    return copy;
  }

  // The face across side k of `copy`, laid out against it (face kInvalid on the boundary). Shared
  // corners are copied, not recomputed, so points on a coarse edge get the same image from both sides.
  FaceCopy across(const FaceCopy& copy, int k) const {
    FaceCopy next;
    const Index s = coarse_twin_[static_cast<std::size_t>(3 * copy.face + k)];
    if (s == kInvalid) return next;
    const Index g = s / 3;
    const int d = static_cast<int>(s % 3), d1 = (d + 1) % 3, d2 = (d + 2) % 3;
    next.face = g;
    next.corner[d] = copy.corner[(k + 1) % 3];
    next.corner[d1] = copy.corner[k];
    next.corner[d2] = layout_third_point(next.corner[d], next.corner[d1], coarse_length(g, d), coarse_length(g, d2),
                                         coarse_length(g, d1));
    return next;
  }

  // Images of a map point in a copy: a removed vertex's point when the copy is its face, a coarse
  // vertex at each corner of the copy that is that vertex. Calls take(position).
  template <class Take>
  void images_in(const CoarsePoint& point, const FaceCopy& copy, Take&& take) const {
    if (point.coarse_vertex != kInvalid) {
      for (int k = 0; k < 3; ++k)
        if (coarse_.F(copy.face, k) == point.coarse_vertex) take(copy.corner[k]);
    } else if (copy.face == point.face) {
      take(copy.corner[0] * point.bary[0] + copy.corner[1] * point.bary[1] + copy.corner[2] * point.bary[2]);
    }
  }

  // A copy reached by unfolding: its parent in the search and the parent's side it was unfolded across.
  struct Unfolded {
    FaceCopy copy;
    int parent = -1;
    int side = -1;   ///< the parent's side crossed
    int entry = -1;  ///< the same side, as this copy's
  };

  // Breadth-first unfolding from the seeds: calls visit(copies, c) for each copy, depth by depth,
  // until `extra_depth` depths after the first at which visit returned true (found), or the limits
  // are reached (returns whether anything was found).
  template <class Visit>
  bool unfold_from(const std::vector<FaceCopy>& seeds, int extra_depth, Visit&& visit) const {
    std::vector<Unfolded> copies;
    for (const FaceCopy& seed : seeds)
      if (seed.face != kInvalid) copies.push_back({seed, -1, -1, -1});
    std::size_t level_begin = 0;
    int found_at = -1;
    for (int depth = 0; depth <= kMaxDepth && level_begin < copies.size(); ++depth) {
      const std::size_t level_end = copies.size();
      bool found = false;
      for (std::size_t c = level_begin; c < level_end; ++c) found = visit(copies, static_cast<int>(c)) || found;
      if (found && found_at < 0) found_at = depth;
      if (found_at >= 0 && depth >= found_at + extra_depth) return true;
      for (std::size_t c = level_begin; c < level_end && copies.size() < kMaxCopies; ++c) {
        // Not back across the side just crossed; otherwise every way is kept, also to a copy reached
        // before at the same place (around a flat vertex both ways arrive, one of them outside the
        // image: unfolds_through tells them apart).
        for (int k = 0; k < 3; ++k) {
          if (k == copies[c].entry) continue;
          const FaceCopy next = across(copies[c].copy, k);
          if (next.face == kInvalid) continue;
          const int entry = static_cast<int>(coarse_twin_[static_cast<std::size_t>(3 * copies[c].copy.face + k)] % 3);
          copies.push_back({next, static_cast<int>(c), k, entry});
        }
      }
      level_begin = level_end;
    }
    return found_at >= 0;
  }

  // True when every side crossed on the way from a seed to copies[c] meets the convex hull of the
  // points `hull` (one to three) away from its ends: the unfolding follows the image it lays out (an
  // input triangle's image crosses exactly the coarse faces between its corners), not a way around
  // a coarse vertex.
  static bool unfolds_through(const std::vector<Unfolded>& copies, int c, const std::vector<Vec2>& hull, double shrink) {
    // An image holds no coarse vertex inside (the map embeds the input): an unfolding that puts a
    // corner of its copies strictly inside a triangle image went the wrong way round that vertex.
    if (hull.size() == 3) {
      const double area = orient2d(hull[0], hull[1], hull[2]);
      const double sign = area >= 0 ? 1 : -1, eps = 1e-12 * std::abs(area);
      for (int d = c; d >= 0; d = copies[d].parent)
        for (const Vec2& corner : copies[d].copy.corner)
          if (sign * orient2d(hull[0], hull[1], corner) > eps && sign * orient2d(hull[1], hull[2], corner) > eps &&
              sign * orient2d(hull[2], hull[0], corner) > eps)
            return false;
    }
    // Nor does the image of a point lie inside another face crossed on the way to its own (the
    // unfolding wrapped round a vertex onto faces laid out already).
    const Vec2 point = hull.back();
    for (int d = copies[c].parent; d >= 0; d = copies[d].parent) {
      const std::array<Vec2, 3>& q = copies[d].copy.corner;
      const double eps = 1e-9 * orient2d(q[0], q[1], q[2]);
      if (orient2d(q[0], q[1], point) > eps && orient2d(q[1], q[2], point) > eps && orient2d(q[2], q[0], point) > eps)
        return false;
    }
    for (; copies[c].parent >= 0; c = copies[c].parent) {
      const FaceCopy& parent = copies[copies[c].parent].copy;
      const int k = copies[c].side;
      // The side without its ends: a side out of a corner of the image only touches it there when
      // it runs outside the image's angle at that corner (the way around a cone vertex).
      const Vec2 a = parent.corner[k], b = parent.corner[(k + 1) % 3];
      if (!segment_meets_hull(a + (b - a) * shrink, b + (a - b) * shrink, hull)) return false;
    }
    return true;
  }

  // Places input vertex v in the layout around `seeds` (cached per trace: one image per vertex).
  // `anchors` are points of the image being laid out (an input triangle's placed corners, a point of
  // it inside a seed). Images reached through the image itself come first (unfolds_through, sides
  // shortened by `shrink` at each end; 0 where the image is only a segment out of a vertex and the
  // unfolding must turn about it), then the one nearest `near`.
  const Placement* place(Index v, const std::vector<FaceCopy>& seeds, const std::vector<Vec2>& anchors, Vec2 near,
                         Cache& cache, double shrink, const std::array<Vec2, 2>* left_of = nullptr,
                         const TriangleShape* shape = nullptr) const {
    const auto hit = cache.find(v);
    if (hit != cache.end()) return &hit->second;
    const CoarsePoint& point = map_[static_cast<std::size_t>(v)];
    bool have = false;
    int best_rank = 0;
    double best = 0;
    Placement chosen;
    std::vector<Vec2> hull;
    // Two depths beyond the first image reached through the image: a point near a corner of a face
    // whose other corners are the same coarse vertex (a Δ-complex), or near a cone, has images
    // around the other corners too.
    unfold_from(seeds, 2, [&](const std::vector<Unfolded>& copies, int c) {
      bool valid_any = false;
      images_in(point, copies[c].copy, [&](Vec2 position) {
        hull = anchors;
        hull.push_back(position);
        const bool valid = unfolds_through(copies, c, hull, shrink);
        // With `left_of`: the new corner of a triangle entered through that side lies on its left
        // (the map does not fold input triangles: the test "ICE's map lays input triangles out...").
        const bool left = !left_of || orient2d((*left_of)[0], (*left_of)[1], position) > 0;
        const int rank = (valid ? 0 : 2) + (left ? 0 : 1);
        const double distance = closeness(position, near, shape);
        // Ties (images rotated about `near`'s vertex, e.g. around a cone at the segment's start) go
        // to the shallower unfolding.
        if (!have || rank < best_rank || (rank == best_rank && distance < best * (1 - 1e-9))) {
          have = true;
          best_rank = rank;
          best = distance;
          chosen = {position, copies[c].copy};
        }
        valid_any = valid_any || valid;
      });
      return valid_any;
    });
    if (!have) return nullptr;
    return &cache.emplace(v, chosen).first->second;
  }

  const Faces& F_;
  const CompactMesh& coarse_;
  const std::vector<CoarsePoint>& map_;
  const std::vector<InputSurfacePoint>& inserted_;
  const Positions& V_;
  std::vector<Index> coarse_twin_, fine_twin_;
  std::vector<Index> face_start_, vertex_faces_;
  Index first_inserted_ = 0;
  std::vector<double> angle_sum_;      // per coarse vertex
  std::vector<char> boundary_vertex_;  // per coarse vertex
};

// The walk: the coarse edge is the segment (0, 0) → (l, 0) of the layout of its face. Input vertices
// are classed by the side of the x axis their images lie on (y ≥ 0 "above"; for a boundary edge y > 0,
// so input vertices on the edge count as outside and the walk stays in the surface); an input triangle
// is crossed where its corners' classes differ. Classes are computed once per vertex (cached
// images), so the walk is consistent even where the segment passes exactly through an image.
TracedEdge Tracer::trace(Index side) const {
  const Index f = side / 3;
  const int k = static_cast<int>(side % 3);
  TracedEdge edge;
  edge.side = side;
  edge.tail = coarse_.F(f, k);
  edge.head = coarse_.F(f, (k + 1) % 3);
  edge.length = coarse_length(f, k);
  const double l = edge.length;
  const FaceCopy frame = along_side(f, k);
  const FaceCopy beyond = across(frame, k);
  const bool boundary = beyond.face == kInvalid;
  const std::vector<FaceCopy> frame_seeds{frame, beyond};
  // The stars of both ends, cut opposite the edge: every input vertex near the edge gets one image.
  std::vector<StarCopy> star;
  add_star(frame, k, 0, star);
  add_star(frame, (k + 1) % 3, -corner_angle(f, (k + 1) % 3), star);
  // Near the edge: in the stars; a vertex of a large input triangle beyond them: by unfolding.
  const auto locate = [&](Index v, const std::vector<Vec2>& anchors, Vec2 near, Cache& in, double shrink,
                          const std::array<Vec2, 2>* left_of = nullptr, const TriangleShape* shape = nullptr) {
    const Placement* placed = place_in_star(v, star, near, in, shape, left_of);
    return placed ? placed : place(v, frame_seeds, anchors, near, in, shrink, left_of, shape);
  };
  const auto above = [boundary](Vec2 p) { return boundary ? p.y > 0 : p.y >= 0; };
  const Vec2 origin{0, 0}, end{l, 0};
  Cache cache;

  Index t = kInvalid;                 // the input face being crossed
  std::array<const Placement*, 3> corners{};
  std::array<double, 3> from{0, 0, 0};
  double from_param = 0;
  int exit_side = -1;                 // the side (corner e to e + 1) the segment leaves t through
  int start_corner = -1;              // the tail's corner in the first face, when the tail is an input vertex

  const auto fail = [&](TraceStatus status) {
    edge.status = status;
    return edge;
  };
  // The side of t (corner e to e + 1) whose corners' classes differ and where the segment is furthest along.
  const auto furthest_exit = [&]() {
    int best_side = -1;
    double best_x = -1;
    for (int e = 0; e < 3; ++e) {
      const Vec2 p = corners[e]->position, q = corners[(e + 1) % 3]->position;
      if (above(p) == above(q)) continue;
      const double x = p.x + (q.x - p.x) * axis_fraction(p, q);
      if (x > best_x) best_x = x, best_side = e;
    }
    return best_side;
  };

  const Index tail_input = coarse_.to_input[static_cast<std::size_t>(edge.tail)];
  const Index head_input = coarse_.to_input[static_cast<std::size_t>(edge.head)];
  if (boundary && tail_input != kInvalid && head_input != kInvalid) {
    // A boundary edge between input vertices: the map keeps the boundary on the boundary, so the
    // trace is the chain of input boundary sides from the tail to the head (the face on their left,
    // as on the coarse side's), each a segment of its face; positions along the edge from the images
    // of the chain's vertices.
    Index v = tail_input;
    double param = 0;
    for (Index step = 0; step <= F_.rows(); ++step) {
      Index out = kInvalid;  // the boundary side out of v
      for (Index i = face_start_[v]; i < face_start_[v + 1] && out == kInvalid; ++i) {
        const Index g = vertex_faces_[i];
        for (int c = 0; c < 3; ++c)
          if (F_(g, c) == v && fine_twin_[static_cast<std::size_t>(3 * g + c)] == kInvalid) out = 3 * g + c;
      }
      if (out == kInvalid) return fail(TraceStatus::lost);
      t = out / 3;
      const int c = static_cast<int>(out % 3);
      const Index w = F_(t, (c + 1) % 3);
      std::array<double, 3> a{0, 0, 0}, b{0, 0, 0};
      a[c] = 1;
      b[(c + 1) % 3] = 1;
      if (w == head_input) {
        edge.segments.push_back({t, a, b, param, l});
        edge.status = TraceStatus::traced;
        return edge;
      }
      // Another coarse vertex before the head: the boundary does not correspond.
      if (coarse_.from_input[static_cast<std::size_t>(w)] != kInvalid) return fail(TraceStatus::lost);
      const Placement* placed = locate(w, {Vec2{param, 0}}, Vec2{param, 0}, cache, 0);
      if (!placed) return fail(TraceStatus::lost);
      // Along the edge, and not past its head.
      if (placed->position.x < param - 1e-9 * l || placed->position.x > l * (1 + 1e-9)) return fail(TraceStatus::lost);
      edge.segments.push_back({t, a, b, param, placed->position.x});
      param = placed->position.x;
      v = w;
    }
    return fail(TraceStatus::step_limit);
  }
  if (tail_input != kInvalid) {
    // Out of the tail: the input face around it whose image the segment enters.
    cache.emplace(tail_input, Placement{origin, frame});
    // The fan is searched in a cache of its own: only the two corners of the face chosen are kept
    // (a neighbour laid out for another face of the fan need not be where the walk will meet it).
    Cache fan = cache;
    double best_x = 0;
    Placement chosen_a, chosen_b;
    // A point of the segment just after its start is in the image of the face it starts into:
    // unfolding through (tail, that point, corner) turns about the tail the way the image does.
    const std::vector<Vec2> start{origin, Vec2{1e-6 * l, 0}};
    for (Index i = face_start_[tail_input]; i < face_start_[tail_input + 1]; ++i) {
      const Index g = vertex_faces_[i];
      int m = 0;
      while (F_(g, m) != tail_input) ++m;
      const Placement* a = locate(F_(g, (m + 1) % 3), start, origin, fan, kSideShrink);
      const Placement* b = locate(F_(g, (m + 2) % 3), start, origin, fan, kSideShrink);
      if (!a || !b || above(a->position) || !above(b->position)) continue;
      const Vec2 p = a->position, q = b->position;
      const double x = p.x + (q.x - p.x) * axis_fraction(p, q);
      if (x > 0 && (t == kInvalid || x < best_x)) {
        t = g, best_x = x, start_corner = m, exit_side = (m + 1) % 3;
        chosen_a = *a;
        chosen_b = *b;
      }
    }
    if (t != kInvalid) {
      corners[start_corner] = &cache.at(tail_input);
      corners[(start_corner + 1) % 3] = &cache.emplace(F_(t, (start_corner + 1) % 3), chosen_a).first->second;
      corners[(start_corner + 2) % 3] = &cache.emplace(F_(t, (start_corner + 2) % 3), chosen_b).first->second;
    }
    if (t == kInvalid) return fail(TraceStatus::lost);
    from[start_corner] = 1;
  } else {
    // Out of an inserted vertex: its point inside an input face.
    const InputSurfacePoint& point = inserted_[static_cast<std::size_t>(edge.tail - first_inserted_)];
    t = point.face;
    for (int c = 0; c < 3; ++c) {
      corners[c] = locate(F_(t, c), {origin}, origin, cache, 0);
      if (!corners[c]) return fail(TraceStatus::lost);
    }
    from = point.bary;
    // The tail's image in this layout must be the segment's start (else the corners went to other copies).
    Vec2 tail_image{0, 0};
    for (int c = 0; c < 3; ++c) tail_image = tail_image + corners[c]->position * point.bary[c];
    if (tail_image.norm() > kEndTolerance * l) return fail(TraceStatus::lost);
    exit_side = furthest_exit();
    if (exit_side < 0) return fail(TraceStatus::lost);
  }

  const InputSurfacePoint* head_point =
      head_input == kInvalid ? &inserted_[static_cast<std::size_t>(edge.head - first_inserted_)] : nullptr;
  const auto finish = [&](const std::array<double, 3>& to) {
    if (from_param > l * (1 + 1e-9)) return fail(TraceStatus::lost);  // walked past the head
    edge.segments.push_back({t, from, to, from_param, l});
    edge.status = TraceStatus::traced;
    return edge;
  };

  for (Index step = 0;; ++step) {
    if (step > F_.rows()) return fail(TraceStatus::step_limit);
    // The head reached inside t: the segment's end is at its image (see the file comment: once the
    // walk is in the head's star, the straight way to the head stays in the face it entered).
    if (head_point) {
      if (t == head_point->face) {
        // Entering the head's face in another copy (a Δ-complex wraps round) is not reaching it.
        Vec2 head_image{0, 0};
        for (int c = 0; c < 3; ++c) head_image = head_image + corners[c]->position * head_point->bary[c];
        if ((head_image - end).norm() <= kEndTolerance * l) return finish(head_point->bary);
      }
    } else {
      for (int c = 0; c < 3; ++c) {
        if (c == start_corner || F_(t, c) != head_input) continue;
        const Placement* head = corners[c];
        if ((head->position - end).norm() <= kEndTolerance * l) {
          std::array<double, 3> to{0, 0, 0};
          to[c] = 1;
          return finish(to);
        }
      }
    }
    const int p = exit_side, q = (exit_side + 1) % 3;
    const Vec2 pp = corners[p]->position, qp = corners[q]->position;
    const double lambda = axis_fraction(pp, qp);
    const double x = pp.x + (qp.x - pp.x) * lambda;
    // The map embeds the input, so the segment only moves on through the images; a step back means
    // an input vertex was laid out in the wrong copy (an unresolved unfolding): no trace rather than
    // a wrong one.
    if (x < from_param - 1e-9 * l) return fail(TraceStatus::lost);
    if (head_point && x >= l) {  // past an inserted head lying on t's boundary: end at the segment's end
      const std::array<double, 3> to = barycentric(end, corners[0]->position, corners[1]->position, corners[2]->position);
      // The end must be in t (up to round-off), else the walk is not where the head is.
      if (std::min({to[0], to[1], to[2]}) < -kEndTolerance) return fail(TraceStatus::lost);
      return finish(clamp_barycentric(to));
    }
    std::array<double, 3> to{0, 0, 0};
    to[p] = 1 - lambda;
    to[q] = lambda;
    edge.segments.push_back({t, from, to, from_param, x});
    // A self-edge ends where it began: its end vertex is placed afresh near the end of the walk.
    if (start_corner >= 0 && head_input == tail_input) cache.erase(tail_input);
    start_corner = -1;

    // Into the neighbouring input face across side p → q.
    const Index s = fine_twin_[static_cast<std::size_t>(3 * t + p)];
    if (s == kInvalid) return fail(TraceStatus::left_surface);
    const Index g = s / 3;
    const int d = static_cast<int>(s % 3), d1 = (d + 1) % 3, d2 = (d + 2) % 3;
    std::array<const Placement*, 3> next{};
    next[d] = corners[q];
    next[d1] = corners[p];
    // The new corner is laid out from the coarse edge's two faces, through the triangle's image from
    // the entry point on the edge, which lies in them.
    const Vec2 entry{x, 0};
    const std::array<Vec2, 2> entry_side{qp, pp};
    // The image being laid out is the triangle (pp, qp, new corner): the entry point lies on its side
    // pp → qp, so the anchors are that side's ends (unfolds_through tests the whole triangle).
    // With positions: the image whose distances to the entry side's ends, relative to that side,
    // are nearest the input triangle's (ICE's map is nearly conformal on a small triangle; an image
    // in a wrong copy is turned by a cone's angle defect about some coarse vertex).
    TriangleShape shape;
    if (V_.rows() > 0) {  // corner d is at qp, d1 at pp
      const Eigen::RowVector3d A = V_.row(F_(g, d)), B = V_.row(F_(g, d1)), C = V_.row(F_(g, d2));
      const double side = (B - A).norm();
      shape = {qp, pp, (pp - qp).norm(), (C - A).norm() / side, (C - B).norm() / side};
    }
    next[d2] = locate(F_(g, d2), {pp, qp}, entry, cache, 0, &entry_side, V_.rows() > 0 ? &shape : nullptr);
    if (!next[d2]) return fail(TraceStatus::lost);
    // Input triangles keep their orientation in the layout (the map does not fold them): a new corner
    // on the wrong side of the entry side was laid out in the wrong copy.
    if (orient2d(qp, pp, next[d2]->position) <= 0) return fail(TraceStatus::lost);
    from = {0, 0, 0};
    from[d] = lambda;
    from[d1] = 1 - lambda;
    from_param = x;
    t = g;
    corners = next;
    exit_side = above(corners[d2]->position) == above(corners[d]->position) ? d1 : d2;
  }
}

// The coarse face containing the image of input face t's barycentre (the face of its first corner's
// map point when the image cannot be laid out).
Index Tracer::face_patch(Index t) const {
  const CoarsePoint& first = map_[static_cast<std::size_t>(F_(t, 0))];
  // Corners inside one coarse face (not at its corners, which several faces share): that face.
  bool inside_one = true;
  for (int c = 0; c < 3; ++c) {
    const CoarsePoint& p = map_[static_cast<std::size_t>(F_(t, c))];
    inside_one = inside_one && p.coarse_vertex == kInvalid && p.face == first.face;
  }
  if (inside_one) return first.face;
  // The layout starts from the corner deepest inside its coarse face: a corner at a coarse vertex
  // (a cone) has its neighbours' images in several copies around it, one inside a face has one.
  int seed_corner = 0;
  double deepest = -1;
  for (int c = 0; c < 3; ++c) {
    const std::array<double, 3>& b = map_[static_cast<std::size_t>(F_(t, c))].bary;
    const double depth = std::min({b[0], b[1], b[2]});
    if (depth > deepest) deepest = depth, seed_corner = c;
  }
  const std::vector<FaceCopy> seeds{along_side(map_[static_cast<std::size_t>(F_(t, seed_corner))].face, 0)};
  Cache cache;
  Vec2 centre{0, 0};
  const Placement* corner0 = place(F_(t, seed_corner), seeds, {}, Vec2{0, 0}, cache, 0);
  if (!corner0) return first.face;
  for (int c = 0; c < 3; ++c) {
    const Placement* corner = place(F_(t, c), seeds, {corner0->position}, corner0->position, cache, 0);
    if (!corner) return first.face;
    centre = centre + corner->position * (1.0 / 3);
  }
  Index found = first.face;
  double best = -1;
  unfold_from(seeds, 0, [&](const std::vector<Unfolded>& copies, int c) {
    const FaceCopy& copy = copies[c].copy;
    const std::array<double, 3> b = barycentric(centre, copy.corner[0], copy.corner[1], copy.corner[2]);
    const double smallest = std::min({b[0], b[1], b[2]});
    if (smallest > best) best = smallest, found = copy.face;
    return smallest >= -1e-12;
  });
  return found;
}

// Two traced edges cross inside an input face only where a walk laid a vertex out in the wrong copy
// and still reached its head: both edges are marked `crossed` (no trace rather than a wrong one).
// Segments are compared in the face's barycentric plane (an affine image: crossings are kept).
void mark_crossing_edges(std::vector<TracedEdge>& edges, const CompactMesh& coarse, const Faces& F,
                         const std::vector<InputSurfacePoint>& inserted) {
  struct Piece {
    Index face, edge;
    std::array<double, 3> from, to;
  };
  std::vector<Piece> pieces;
  for (std::size_t e = 0; e < edges.size(); ++e)
    if (edges[e].status == TraceStatus::traced)
      for (const TracedSegment& s : edges[e].segments) pieces.push_back({s.face, static_cast<Index>(e), s.from, s.to});
  std::sort(pieces.begin(), pieces.end(), [](const Piece& a, const Piece& b) { return a.face < b.face; });
  const auto is_coarse_corner = [&](Index face, const std::array<double, 3>& b) {
    for (int c = 0; c < 3; ++c)
      if (b[c] == 1) return coarse.from_input[static_cast<std::size_t>(F(face, c))] != kInvalid;
    for (const InputSurfacePoint& p : inserted)  // a vertex inserted by refinement (few)
      if (p.face == face && std::abs(p.bary[0] - b[0]) + std::abs(p.bary[1] - b[1]) + std::abs(p.bary[2] - b[2]) < 1e-12)
        return true;
    return false;
  };
  std::vector<char> crossed(edges.size(), 0);
  for (std::size_t begin = 0, end; begin < pieces.size(); begin = end) {
    for (end = begin + 1; end < pieces.size() && pieces[end].face == pieces[begin].face;) ++end;
    for (std::size_t a = begin; a < end; ++a) {
      for (std::size_t b = a + 1; b < end; ++b) {
        const Piece& p = pieces[a];
        const Piece& q = pieces[b];
        if (p.edge == q.edge) continue;
        const Vec2 p0{p.from[1], p.from[2]}, p1{p.to[1], p.to[2]}, q0{q.from[1], q.from[2]}, q1{q.to[1], q.to[2]};
        const Vec2 r = p1 - p0, u = q1 - q0, w = q0 - p0;
        const double denominator = cross(r, u);
        bool meet = false;
        if (std::abs(denominator) > 1e-14) {
          const double along_p = cross(w, u) / denominator, along_q = cross(w, r) / denominator;
          meet = along_p > 1e-9 && along_p < 1 - 1e-9 && along_q > 1e-9 && along_q < 1 - 1e-9;
        }
        for (const auto& x : {p.from, p.to})
          for (const auto& y : {q.from, q.to})
            meet = meet || (std::abs(x[0] - y[0]) + std::abs(x[1] - y[1]) + std::abs(x[2] - y[2]) < 1e-12 &&
                            !is_coarse_corner(p.face, x));
        if (meet) crossed[p.edge] = crossed[q.edge] = 1;
      }
    }
  }
  for (std::size_t e = 0; e < edges.size(); ++e)
    if (crossed[e]) edges[e].status = TraceStatus::crossed;
}

double distance_3d(const Positions& V, Index a, Index b) { return (V.row(a) - V.row(b)).norm(); }

// Length of the shortest path between the first and last of `portals` (the path's start and end
// as degenerate portals, between them the (left, right) ends of the edges it crosses, in order)
// through the planar channel they bound: the funnel algorithm (Lee & Preparata 1984), which keeps
// the apex of the current shortest path and the two rays through the portals' tightest ends, and
// turns a corner wherever one ray crosses the other. NaN if it has not finished after a generous
// number of steps (it restarts from a turned corner; a channel folded on itself could cycle).
double funnel_length(const std::vector<std::pair<Vec2, Vec2>>& portals) {
  const auto same = [](Vec2 a, Vec2 b) { return a.x == b.x && a.y == b.y; };
  Vec2 apex = portals.front().first, left = apex, right = apex;
  std::size_t left_index = 0, right_index = 0;
  double length = 0;
  std::size_t steps = 0;
  const std::size_t step_limit = 4 * portals.size() * portals.size() + 16;
  for (std::size_t i = 1; i < portals.size(); ++i) {
    if (++steps > step_limit) return std::numeric_limits<double>::quiet_NaN();
    const Vec2 next_left = portals[i].first, next_right = portals[i].second;
    if (orient2d(apex, right, next_right) >= 0) {  // the right ray tightens
      if (same(apex, right) || orient2d(apex, left, next_right) < 0) {
        right = next_right, right_index = i;
      } else {  // past the left ray: the path turns at the left end
        length += (left - apex).norm();
        apex = right = left, right_index = i = left_index;
        continue;
      }
    }
    if (orient2d(apex, left, next_left) <= 0) {  // the left ray tightens
      if (same(apex, left) || orient2d(apex, right, next_left) > 0) {
        left = next_left, left_index = i;
      } else {  // past the right ray: the path turns at the right end
        length += (right - apex).norm();
        apex = left = right, left_index = i = right_index;
        continue;
      }
    }
  }
  return length + (portals.back().first - apex).norm();
}

// The shortest path from a traced edge's tail to its head within the input faces it crosses,
// unfolded into the plane (the traced polyline is one path among those; this is the shortest, so
// never longer). Where the trace passes from one face to the next through a vertex rather than a
// shared side, that point stays on the path and the two runs are shortened apart.
double shortest_length_in_strip(const Positions& V, const Faces& F, const std::vector<Index>& fine_twin,
                                const TracedEdge& edge) {
  const std::vector<TracedSegment>& segments = edge.segments;
  double total = 0;
  std::vector<std::pair<Vec2, Vec2>> portals;
  std::size_t begin = 0;
  while (begin < segments.size()) {
    // Lay out the first face of the run, then unfold each next face across the side it shares.
    Index face = segments[begin].face;
    std::array<Vec2, 3> corner;
    corner[0] = {0, 0};
    corner[1] = {distance_3d(V, F(face, 0), F(face, 1)), 0};
    corner[2] = layout_third_point(corner[0], corner[1], corner[1].x, distance_3d(V, F(face, 0), F(face, 2)),
                                   distance_3d(V, F(face, 1), F(face, 2)));
    const auto at = [&](const std::array<double, 3>& b) {
      return corner[0] * b[0] + corner[1] * b[1] + corner[2] * b[2];
    };
    portals.clear();
    const Vec2 start = at(segments[begin].from);
    portals.emplace_back(start, start);
    std::size_t last = begin;
    for (; last + 1 < segments.size(); ++last) {
      const Index next = segments[last + 1].face;
      if (next == face) continue;  // a bend inside the face (an exact trace's): the same run
      int shared = -1;
      for (int k = 0; k < 3; ++k) {
        const Index twin = fine_twin[static_cast<std::size_t>(3 * face + k)];
        if (twin != kInvalid && twin / 3 == next) shared = k;
      }
      if (shared < 0) break;  // through a vertex: the run ends here
      // Leaving a face through side (a, b) with the face's interior on the left of a → b, b is on
      // the left of the path and a on its right (the layout, not F's orientation, decides).
      const Index a = F(face, shared), b = F(face, (shared + 1) % 3);
      const Vec2 pa = corner[shared], pb = corner[(shared + 1) % 3];
      if (orient2d(pa, pb, corner[(shared + 2) % 3]) > 0) portals.emplace_back(pb, pa);
      else portals.emplace_back(pa, pb);
      std::array<Vec2, 3> next_corner;
      for (int k = 0; k < 3; ++k) {
        const Index v = F(next, k);
        if (v == a && v != b) next_corner[k] = pa;
        else if (v == b && v != a) next_corner[k] = pb;
        else
          next_corner[k] = layout_third_point(pb, pa, (pa - pb).norm(), distance_3d(V, b, v), distance_3d(V, a, v));
      }
      corner = next_corner;
      face = next;
    }
    const Vec2 end = at(segments[last].to);
    portals.emplace_back(end, end);
    const double length = funnel_length(portals);
    if (!std::isfinite(length)) return traced_length(V, F, edge);
    total += length;
    begin = last + 1;
  }
  return std::min(total, traced_length(V, F, edge));
}

void complete_tracing(CoarseTracing& result, const Faces& F, const CompactMesh& coarse, const std::vector<CoarsePoint>& map,
                      const std::vector<InputSurfacePoint>& inserted, const Positions& V,
                      const std::vector<Index>& fine_twin, int threads);

// The coarse sides traced, one per coarse edge (CoarseTracing::edges' order): interior edges from
// the side with the smaller index, boundary edges from their face; `twin` is the coarse gluing.
std::vector<Index> traced_sides(const std::vector<Index>& twin) {
  std::vector<Index> sides;
  for (Index s = 0; s < static_cast<Index>(twin.size()); ++s)
    if (twin[s] == kInvalid || s < twin[s]) sides.push_back(s);
  return sides;
}

}  // namespace

CoarseTracing trace_coarse_mesh(const Faces& F, const CompactMesh& coarse, const std::vector<CoarsePoint>& map,
                                const std::vector<InputSurfacePoint>& inserted, const Positions& V, int threads) {
  const Index n = static_cast<Index>(map.size());
  if (F.size() > 0 && F.minCoeff() < 0)
    throw std::invalid_argument("trace_coarse_mesh: an input face has a negative vertex index (" +
                                std::to_string(F.minCoeff()) + ")");
  if (F.size() > 0 && F.maxCoeff() >= n)
    throw std::invalid_argument("trace_coarse_mesh: the map has " + std::to_string(n) +
                                " points, fewer than the input faces' vertices (" + std::to_string(F.maxCoeff() + 1) + ")");
  if (V.rows() != 0 && V.rows() != n)
    throw std::invalid_argument("trace_coarse_mesh: " + std::to_string(V.rows()) + " positions for " +
                                std::to_string(n) + " input vertices");
  if (static_cast<Index>(coarse.from_input.size()) != n)
    throw std::invalid_argument("trace_coarse_mesh: the coarse mesh's from_input has " +
                                std::to_string(coarse.from_input.size()) + " entries for " + std::to_string(n) +
                                " input vertices");
  // Coarse vertices: input vertices first (to_input names one), then the inserted ones (kInvalid).
  bool inserted_seen = false;
  for (Index c = 0; c < coarse.num_vertices(); ++c) {
    const Index input = coarse.to_input[static_cast<std::size_t>(c)];
    if (input == kInvalid) {
      inserted_seen = true;
      continue;
    }
    if (inserted_seen)
      throw std::invalid_argument("trace_coarse_mesh: coarse vertex " + std::to_string(c) +
                                  " is an input vertex after an inserted one (inserted vertices come last)");
    if (input < 0 || input >= n || coarse.from_input[static_cast<std::size_t>(input)] != c)
      throw std::invalid_argument("trace_coarse_mesh: coarse vertex " + std::to_string(c) + " names input vertex " +
                                  std::to_string(input) + ", which does not name it back");
  }
  for (Index v = 0; v < n; ++v) {
    const CoarsePoint& p = map[static_cast<std::size_t>(v)];
    if (p.face < 0 || p.face >= coarse.F.rows())
      throw std::invalid_argument("trace_coarse_mesh: map point " + std::to_string(v) + " names coarse face " +
                                  std::to_string(p.face) + " of " + std::to_string(coarse.F.rows()));
  }
  Index inserted_vertices = 0;
  for (const Index input : coarse.to_input) inserted_vertices += input == kInvalid;
  if (static_cast<std::size_t>(inserted_vertices) != inserted.size())
    throw std::invalid_argument("trace_coarse_mesh: " + std::to_string(inserted.size()) + " inserted points for " +
                                std::to_string(inserted_vertices) + " inserted coarse vertices");
  for (const InputSurfacePoint& p : inserted)
    if (p.face < 0 || p.face >= F.rows()) throw std::invalid_argument("trace_coarse_mesh: an inserted point names no input face");

  const Tracer tracer(F, coarse, map, inserted, V);
  CoarseTracing result;
  const std::vector<Index> sides = traced_sides(tracer.coarse_twin());
  result.edges.resize(sides.size());
  result.face_patch.assign(static_cast<std::size_t>(F.rows()), kInvalid);
  threads = detail::requested_threads(threads);
  constexpr Index kChunk = 256;
  const Index edge_chunks = (static_cast<Index>(sides.size()) + kChunk - 1) / kChunk;
  const Index face_chunks = (static_cast<Index>(F.rows()) + kChunk - 1) / kChunk;
  detail::run_tasks(threads, static_cast<int>(edge_chunks + face_chunks), [&](int task) {
    if (task < edge_chunks) {
      const Index begin = task * kChunk, stop = std::min<Index>(begin + kChunk, static_cast<Index>(sides.size()));
      for (Index e = begin; e < stop; ++e) result.edges[e] = tracer.trace(sides[e]);
    } else {
      const Index begin = (task - edge_chunks) * kChunk, stop = std::min<Index>(begin + kChunk, F.rows());
      for (Index t = begin; t < stop; ++t) result.face_patch[t] = tracer.face_patch(t);
    }
  });
  complete_tracing(result, F, coarse, map, inserted, V, tracer.fine_twin(), threads);
  return result;
}

namespace {
// What both ways of tracing finish with: edges that cross marked, the surface lengths (with the
// gluing `fine_twin` of F), the vertices' labels, the counts and length ratios.
void complete_tracing(CoarseTracing& result, const Faces& F, const CompactMesh& coarse, const std::vector<CoarsePoint>& map,
                      const std::vector<InputSurfacePoint>& inserted, const Positions& V,
                      const std::vector<Index>& fine_twin, int threads) {
  mark_crossing_edges(result.edges, coarse, F, inserted);
  constexpr Index kChunk = 256;
  const Index edges = static_cast<Index>(result.edges.size());
  if (V.rows() != 0)  // each traced edge's shortest path through its strip
    detail::run_tasks(threads, static_cast<int>((edges + kChunk - 1) / kChunk), [&](int task) {
      const Index begin = task * kChunk, stop = std::min<Index>(begin + kChunk, edges);
      for (Index e = begin; e < stop; ++e)
        if (TracedEdge& edge = result.edges[e]; edge.status == TraceStatus::traced)
          edge.surface_length = shortest_length_in_strip(V, F, fine_twin, edge);
    });
  result.vertex_patch.resize(map.size());
  for (std::size_t v = 0; v < map.size(); ++v) result.vertex_patch[v] = map[v].face;
  result.traced = result.failed = 0;
  bool first_ratio = true;
  for (const TracedEdge& edge : result.edges) {
    if (edge.status != TraceStatus::traced) {
      ++result.failed;
      continue;
    }
    ++result.traced;
    if (V.rows() == 0) continue;
    const double ratio = traced_length(V, F, edge) / edge.length;
    result.length_ratio_min = first_ratio ? ratio : std::min(result.length_ratio_min, ratio);
    result.length_ratio_max = first_ratio ? ratio : std::max(result.length_ratio_max, ratio);
    first_ratio = false;
  }
}

// The point b of input face `from` in the coordinates of face `to`, when it lies on their common
// side or corner (its weight off the corners they share is round-off), else nothing.
std::optional<std::array<double, 3>> express_in(const Faces& F, Index from, const std::array<double, 3>& b, Index to,
                                                bool renormalise = true) {
  // Round-off of many records on slivers: ~2e-9 on most scans, 1.6e-7 at a vertex of
  // dragon_vrip_bin (to 1 %, 16 regions). Welding moves a point by at most this share of its face.
  constexpr double kOnSide = 1e-6;
  if (from == to) return b;
  std::array<double, 3> out{0, 0, 0};
  double off = 0, on = 0;
  for (int c = 0; c < 3; ++c) {
    int corner = -1;
    for (int k = 0; k < 3; ++k)
      if (F(from, c) == F(to, k)) corner = k;
    if (corner < 0) {
      off += b[c];
    } else {
      on += b[c];
      out[static_cast<std::size_t>(corner)] = b[c];
    }
  }
  if (off > kOnSide || on <= 0) return std::nullopt;
  if (renormalise)
    for (double& x : out) x /= on;
  return out;
}

// Makes the ends of consecutive segments of a trace the same point to the bit (pulled back
// separately through many records, they agree to round-off only): the same coordinates in one
// face; in faces that share a side or a corner, the point there by the same weights.
void weld_joints(const Faces& F, std::vector<TracedSegment>& segments) {
  for (std::size_t i = 0; i + 1 < segments.size(); ++i) {
    TracedSegment& s = segments[i];
    TracedSegment& n = segments[i + 1];
    const std::optional<std::array<double, 3>> there = express_in(F, s.face, s.to, n.face);
    if (!there) continue;
    if (s.face != n.face)  // s's own end: the same weights at the same corners (the same sums to the bit)
      if (const std::optional<std::array<double, 3>> back = express_in(F, n.face, *there, s.face, false)) s.to = *back;
    n.from = *there;
  }
}

// The exact tracing: every coarse edge pulled back through the triangulation's recorded history
// (ice/triangulation_history.h) onto the faces it was built from, i.e. the input's; every input
// face's barycentre pushed forward to label it.
CoarseTracing trace_from_history(const TriangleMesh& mesh, const CoarseSpace& space, int threads) {
  threads = detail::requested_threads(threads);
  const IntrinsicTriangulation& T = *space.triangulation;
  const CompactMesh& coarse = space.mesh;
  const std::vector<Index>& face_order = space.triangulation_face_order;
  const auto input_face = [&](Index slot) { return face_order.empty() ? slot : face_order[static_cast<std::size_t>(slot)]; };
  std::vector<Index> slot_of, compact_of(static_cast<std::size_t>(T.num_face_slots()), kInvalid);
  for (Index f = 0; f < T.num_face_slots(); ++f)
    if (T.face_alive(f)) {
      compact_of[static_cast<std::size_t>(f)] = static_cast<Index>(slot_of.size());
      slot_of.push_back(f);
    }
  const std::vector<Index> sides = traced_sides(coarse.twin.empty() ? glue_by_vertex_pairs(coarse.F) : coarse.twin);
  std::vector<std::vector<FaceSegment>> curves(sides.size());
  for (std::size_t e = 0; e < sides.size(); ++e) {
    const Index f = sides[e] / 3;
    const int k = static_cast<int>(sides[e] % 3);
    FaceSegment side;
    side.face = slot_of[static_cast<std::size_t>(f)];
    side.from[k] = 1;
    side.to[(k + 1) % 3] = 1;
    side.to_param = coarse.L(f, k);
    curves[e].push_back(side);
  }
  // The edges pulled back and the faces' barycentres pushed forward, side by side.
  std::vector<FacePoint> centres(static_cast<std::size_t>(T.history().initial_faces));
  for (Index slot = 0; slot < T.history().initial_faces; ++slot)
    centres[static_cast<std::size_t>(slot)] = {slot, {1.0 / 3, 1.0 / 3, 1.0 / 3}};
  detail::run_tasks(std::min(threads, 2), 2, [&](int task) {
    if (task == 0)
      curves = pull_back(T.history(), std::move(curves));
    else
      centres = push_forward(T.history(), std::move(centres));
  });
  Index first_inserted = 0;
  for (const Index input : coarse.to_input) first_inserted += input != kInvalid;
  CoarseTracing result;
  result.edges.resize(sides.size());
  for (std::size_t e = 0; e < sides.size(); ++e) {
    TracedEdge& edge = result.edges[e];
    const Index f = sides[e] / 3;
    const int k = static_cast<int>(sides[e] % 3);
    edge.side = sides[e];
    edge.tail = coarse.F(f, k);
    edge.head = coarse.F(f, (k + 1) % 3);
    edge.length = coarse.L(f, k);
    edge.segments.reserve(curves[e].size());
    for (const FaceSegment& piece : curves[e])
      edge.segments.push_back({input_face(piece.face), piece.from, piece.to, piece.from_param, piece.to_param});
    weld_joints(mesh.F, edge.segments);
    // Ends at inserted vertices: their points as the coarse space gives them (pulled back the same
    // way, equal up to round-off), so that edges meeting there meet at one point.
    for (int end = 0; end < 2 && !edge.segments.empty(); ++end) {
      const Index vertex = end == 0 ? edge.tail : edge.head;
      if (coarse.to_input[static_cast<std::size_t>(vertex)] != kInvalid) continue;
      const InputSurfacePoint& point = space.inserted[static_cast<std::size_t>(vertex - first_inserted)];
      TracedSegment& segment = end == 0 ? edge.segments.front() : edge.segments.back();
      if (const std::optional<std::array<double, 3>> b = express_in(mesh.F, point.face, point.bary, segment.face))
        (end == 0 ? segment.from : segment.to) = *b;
    }
  }
  result.face_patch.assign(static_cast<std::size_t>(mesh.F.rows()), kInvalid);
  for (Index slot = 0; slot < static_cast<Index>(centres.size()); ++slot)
    result.face_patch[static_cast<std::size_t>(input_face(slot))] = compact_of[static_cast<std::size_t>(centres[slot].face)];
  complete_tracing(result, mesh.F, coarse, fine_to_coarse_map(space), space.inserted, mesh.V, glue_by_vertex_pairs(mesh.F),
                   threads);
  return result;
}
}  // namespace

CoarseTracing trace_coarse_mesh(const TriangleMesh& mesh, const CoarseSpace& space, int threads) {
  if (!space.triangulation)
    throw std::invalid_argument("trace_coarse_mesh: the coarse space has no triangulation (ICE with keep_method_state)");
  if (space.summary.tufted_cover)
    throw std::invalid_argument("trace_coarse_mesh: the space was coarsened through a tufted cover (its triangulation "
                                "is the cover's, not the mesh's)");
  if (space.triangulation->records_history()) return trace_from_history(mesh, space, threads);
  return trace_coarse_mesh(mesh.F, space.mesh, fine_to_coarse_map(space), space.inserted, mesh.V, threads);
}

namespace {
// The point of input face `face` with barycentric coordinates b.
Eigen::RowVector3d surface_point(const Positions& V, const Faces& F, Index face, const std::array<double, 3>& b) {
  return V.row(F(face, 0)) * b[0] + V.row(F(face, 1)) * b[1] + V.row(F(face, 2)) * b[2];
}
}  // namespace

Positions traced_polyline(const Positions& V, const Faces& F, const TracedEdge& edge) {
  Positions points(edge.segments.empty() ? 0 : static_cast<Index>(edge.segments.size()) + 1, 3);
  for (std::size_t i = 0; i < edge.segments.size(); ++i)
    points.row(static_cast<Index>(i)) = surface_point(V, F, edge.segments[i].face, edge.segments[i].from);
  if (!edge.segments.empty())
    points.row(points.rows() - 1) = surface_point(V, F, edge.segments.back().face, edge.segments.back().to);
  return points;
}

double traced_length(const Positions& V, const Faces& F, const TracedEdge& edge) {
  double length = 0;
  for (const TracedSegment& s : edge.segments)
    length += (surface_point(V, F, s.face, s.to) - surface_point(V, F, s.face, s.from)).norm();
  return length;
}

double shortest_traced_length(const Positions& V, const Faces& F, const TracedEdge& edge) {
  return shortest_length_in_strip(V, F, glue_by_vertex_pairs(F), edge);
}

FaceLengths traced_edge_lengths(const Positions& V, const Faces& F, const CompactMesh& coarse, const CoarseTracing& tracing,
                                TracedLengthMeasure measure) {
  const std::size_t sides = static_cast<std::size_t>(3 * coarse.F.rows());
  if (coarse.twin.size() != sides || (tracing.edges.empty() && sides > 0))
    throw std::invalid_argument("traced_edge_lengths: the tracing is not of this coarse mesh (no edges, or no gluing)");
  FaceLengths L = coarse.L;
  std::vector<Index> fine_twin;  // glued only for edges traced without positions
  const auto twin_of = [&](Index side) { return coarse.twin[static_cast<std::size_t>(side)]; };
  for (const TracedEdge& edge : tracing.edges) {
    if (edge.side < 0 || static_cast<std::size_t>(edge.side) >= sides)
      throw std::invalid_argument("traced_edge_lengths: a traced edge names side " + std::to_string(edge.side) +
                                  " beyond the coarse mesh");
    if (edge.status != TraceStatus::traced) continue;
    double length = 0;
    if (measure == TracedLengthMeasure::polyline) {
      length = traced_length(V, F, edge);
    } else if (edge.surface_length >= 0) {
      length = edge.surface_length;
    } else {
      if (fine_twin.empty()) fine_twin = glue_by_vertex_pairs(F);
      length = shortest_length_in_strip(V, F, fine_twin, edge);
    }
    L(edge.side / 3, edge.side % 3) = length;
    if (const Index twin = twin_of(edge.side); twin != kInvalid) L(twin / 3, twin % 3) = length;
  }
  // Faces whose traced lengths break the triangle inequality take their intrinsic lengths back, on
  // both sides of each edge; that can break a neighbour, so repeat until none does (each round
  // restores at least one face for good: the intrinsic lengths are valid).
  for (bool changed = true; changed;) {
    changed = false;
    for (Eigen::Index f = 0; f < L.rows(); ++f) {
      if (triangle_inequality_holds(L(f, 0), L(f, 1), L(f, 2))) continue;
      for (int k = 0; k < 3; ++k) {
        const Index side = static_cast<Index>(3 * f + k);
        L(f, k) = coarse.L(f, k);
        if (const Index twin = twin_of(side); twin != kInvalid) L(twin / 3, twin % 3) = coarse.L(twin / 3, twin % 3);
      }
      changed = true;
    }
  }
  return L;
}

SurfaceEdgeLengths surface_edge_lengths(const TriangleMesh& mesh, const CompactMesh& coarse, const std::vector<CoarsePoint>& map,
                                        const std::vector<InputSurfacePoint>& inserted, int threads) {
  if (mesh.V.rows() != static_cast<Index>(map.size()))
    throw std::invalid_argument("surface_edge_lengths: " + std::to_string(mesh.V.rows()) + " input positions for a map of " +
                                std::to_string(map.size()) + " points");
  const CoarseTracing tracing = trace_coarse_mesh(mesh.F, coarse, map, inserted, mesh.V, threads);
  return {traced_edge_lengths(mesh.V, mesh.F, coarse, tracing), static_cast<Index>(tracing.edges.size()), tracing.traced};
}

}  // namespace ice
