#include "ice/refinement.h"

#include <algorithm>
#include <cmath>
#include <queue>
#include <tuple>
#include <limits>
#include <stdexcept>
#include <string>

#include "ice/triangle_geometry.h"

namespace ice {
namespace {

constexpr double kDegree = kPi / 180;
// A vertex with a smaller angle sum is "sharp": refinement does not try to fix its corners.
constexpr double kSharpVertexAngle = 60 * kDegree;
// Barycentric coordinates below this put a traced point on an edge (split it) or a vertex (skip).
constexpr double kOnEdge = 1e-9;

// The corners of face f laid out in the plane: tail(halfedge(f)) at the origin, the next corner on +x.
std::array<Vec2, 3> layout_face(const IntrinsicTriangulation& T, Index f) {
  const Index h0 = T.halfedge(f), h1 = T.next(h0), h2 = T.next(h1);
  const Vec2 p0{0, 0}, p1{T.length(h0), 0};
  return {p0, p1, layout_third_point(p0, p1, T.length(h0), T.length(h2), T.length(h1))};
}

// Corner angles of face f, at tail(halfedge(f)), its next and its next·next.
std::array<double, 3> face_angles(const IntrinsicTriangulation& T, Index f) {
  const Index h0 = T.halfedge(f), h1 = T.next(h0), h2 = T.next(h1);
  return {T.corner_angle(h0), T.corner_angle(h1), T.corner_angle(h2)};
}

// The corners of the face of `across` (in its order: halfedge(face), next, next·next) laid out beyond
// the side that `across` runs along, from `from` to `to`: the unfolding step of tracing and locating.
std::array<Vec2, 3> unfold_across(const IntrinsicTriangulation& T, Index across, Vec2 from, Vec2 to) {
  const Index n1 = T.next(across), n2 = T.next(n1);
  const Vec2 third = layout_third_point(from, to, T.length(across), T.length(n2), T.length(n1));
  std::array<Vec2, 3> layout{};
  Index c = T.halfedge(T.face(across));
  for (int k = 0; k < 3; ++k, c = T.next(c)) layout[static_cast<std::size_t>(k)] = c == across ? from : (c == n1 ? to : third);
  return layout;
}

Vec2 circumcentre(Vec2 a, Vec2 b, Vec2 c) {
  const Vec2 ab = b - a, ac = c - a;
  const double d = 2 * cross(ab, ac);
  const double ab2 = ab.x * ab.x + ab.y * ab.y, ac2 = ac.x * ac.x + ac.y * ac.y;
  return a + Vec2{(ac.y * ab2 - ab.y * ac2) / d, (ab.x * ac2 - ac.x * ab2) / d};
}

// The end of a straight line traced across the intrinsic faces from a point of face f towards
// `target` (both in f's layout): the face and coordinates where it ends, or the boundary half-edge
// it runs into.
struct TraceEnd {
  Index face = kInvalid;
  std::array<double, 3> bary{0, 0, 0};
  Index boundary_halfedge = kInvalid;
  std::array<Vec2, 3> corners{};  ///< the end face laid out in the frame of the trace
};
TraceEnd trace_line(const IntrinsicTriangulation& T, Index f, Vec2 start, Vec2 target) {
  std::array<Index, 3> h{T.halfedge(f), 0, 0};
  h[1] = T.next(h[0]), h[2] = T.next(h[1]);
  std::array<Vec2, 3> q = layout_face(T, f);
  Vec2 x = start;
  Index face = f;
  const Index max_steps = 4 * T.num_faces() + 16;
  for (Index step = 0; step < max_steps; ++step) {
    const std::array<double, 3> b = barycentric(target, q[0], q[1], q[2]);
    if (b[0] >= -kOnEdge && b[1] >= -kOnEdge && b[2] >= -kOnEdge) return {face, clamp_barycentric(b), kInvalid, q};
    // Leave through the first side whose line the segment x -> target crosses outwards.
    int exit = -1;
    double exit_at = std::numeric_limits<double>::infinity();
    const Vec2 d = target - x;
    for (int k = 0; k < 3; ++k) {
      const Vec2 a = q[static_cast<std::size_t>(k)], e = q[static_cast<std::size_t>((k + 1) % 3)] - a;
      const double denominator = cross(e, d);
      if (!(denominator < 0)) continue;  // moving inwards or parallel: this side is not crossed outwards
      const double s = cross(a - x, e) / cross(d, e);
      if (s < exit_at) exit_at = s, exit = k;
    }
    if (exit < 0) return {face, clamp_barycentric(b), kInvalid, q};  // round-off at a corner: stay here
    const Index out = h[static_cast<std::size_t>(exit)];
    const Index across = out ^ 1;
    if (T.is_exterior(across)) return {kInvalid, {0, 0, 0}, out, q};
    // The next face, unfolded across the side: `across` runs from q[exit + 1] to q[exit].
    q = unfold_across(T, across, q[static_cast<std::size_t>((exit + 1) % 3)], q[static_cast<std::size_t>(exit)]);
    face = T.face(across);
    h[0] = T.halfedge(face), h[1] = T.next(h[0]), h[2] = T.next(h[1]);
    x = x + d * std::max(0.0, exit_at);
  }
  return {face, {1.0 / 3, 1.0 / 3, 1.0 / 3}, kInvalid, q};  // not reached on a valid triangulation
}

// A boundary edge of face f or of a face across one of its sides whose diametral circle holds x
// (positions in the frame where f's corners are `corners`), or kInvalid. Inserting x would make a
// thin triangle against that edge: Ruppert's rule splits the edge instead.
Index encroached_boundary_edge(const IntrinsicTriangulation& T, Index f, const std::array<Vec2, 3>& corners, Vec2 x) {
  const auto encroaches = [&](Vec2 a, Vec2 b) {
    const Vec2 middle = (a + b) * 0.5;
    return (x - middle).norm() < 0.5 * (b - a).norm() * (1 - 1e-12);
  };
  Index h = T.halfedge(f);
  for (int k = 0; k < 3; ++k, h = T.next(h)) {
    const Vec2 a = corners[static_cast<std::size_t>(k)], b = corners[static_cast<std::size_t>((k + 1) % 3)];
    const Index across = h ^ 1;
    if (T.is_exterior(across)) {
      if (encroaches(a, b)) return h;
      continue;
    }
    // The face across: its two other sides, laid out beyond a–b.
    const Index n1 = T.next(across), n2 = T.next(n1);
    const Vec2 third = layout_third_point(b, a, T.length(across), T.length(n2), T.length(n1));
    if (T.is_exterior(n1 ^ 1) && encroaches(a, third)) return n1;
    if (T.is_exterior(n2 ^ 1) && encroaches(third, b)) return n2;
  }
  return kInvalid;
}

}  // namespace

double min_corner_angle_degrees(const IntrinsicTriangulation& T) {
  double smallest = kPi;
  for (Index f = 0; f < T.num_face_slots(); ++f)
    if (T.face_alive(f))
      for (double a : face_angles(T, f)) smallest = std::min(smallest, a);
  return smallest / kDegree;
}

RefinementResult refine_delaunay(IntrinsicTriangulation& T, const RefinementOptions& options) {
  if (!(options.min_angle_degrees > 0 && options.min_angle_degrees <= 30))
    throw std::invalid_argument("refine_delaunay: the angle bound must lie in (0, 30] degrees, got " +
                                std::to_string(options.min_angle_degrees));
  if (!(options.max_vertex_ratio >= 1))
    throw std::invalid_argument("refine_delaunay: max_vertex_ratio must be at least 1");
  RefinementResult result;
  result.min_angle_before = min_corner_angle_degrees(T);
  result.flips = T.flip_to_delaunay();
  const double bound = options.min_angle_degrees * kDegree;
  const double budget = options.max_vertex_ratio * static_cast<double>(T.num_vertices());
  // Faces with a side shorter than this are left alone: near a sharp feature of a scan (a spike, a
  // component of a few slivers) Delaunay refinement would otherwise spend the whole budget on ever
  // smaller faces (measured on dragon_vrip_bin: 50,000 faces of edges ~1e-6 in one sliver component).
  double mean_side = 0;
  Index sides = 0;
  for (Index f = 0; f < T.num_face_slots(); ++f)
    if (T.face_alive(f)) {
      Index h = T.halfedge(f);
      for (int k = 0; k < 3; ++k, h = T.next(h)) mean_side += T.length(h), ++sides;
    }
  const double smallest_side = sides > 0 ? 1e-3 * mean_side / sides : 0;

  // A face needs work when its smallest angle is below the bound and not at a sharp vertex.
  enum class Quality { good, bad, sharp, tiny };
  struct Assessment {
    Quality quality;
    double smallest_angle;
  };
  const auto assess = [&](Index f) -> Assessment {
    const Index h0 = T.halfedge(f);
    const std::array<Index, 3> h{h0, T.next(h0), T.next(T.next(h0))};
    const std::array<double, 3> angles = face_angles(T, f);
    const int k = static_cast<int>(std::min_element(angles.begin(), angles.end()) - angles.begin());
    const double smallest = angles[static_cast<std::size_t>(k)];
    if (smallest >= bound) return {Quality::good, smallest};
    if (T.angle_sum(T.tail(h[static_cast<std::size_t>(k)])) < kSharpVertexAngle) return {Quality::sharp, smallest};
    const bool tiny = std::min({T.length(h[0]), T.length(h[1]), T.length(h[2])}) < smallest_side;
    return {tiny ? Quality::tiny : Quality::bad, smallest};
  };
  // Bad faces, smallest angle first (measured on four meshes: 1-6 % fewer insertions than first-in
  // first-out or largest circumradius first). Stale entries are skipped when popped.
  std::priority_queue<std::tuple<double, Index, Index>> queue;  // (−smallest angle, −stamp, face)
  Index stamp = 0;
  const auto push_if_bad = [&](Index f) {
    const Assessment a = assess(f);
    if (a.quality == Quality::bad) queue.emplace(-a.smallest_angle, -(stamp++), f);
  };
  for (Index f = 0; f < T.num_face_slots(); ++f)
    if (T.face_alive(f)) push_if_bad(f);

  std::vector<Index> changed, touched;
  // Faces whose new vertex could not be placed (a flat face, a point on an existing vertex, a face
  // thinner than a flip may make): left as they are.
  std::vector<char> unsplittable;
  const auto is_unsplittable = [&](Index f) {
    return static_cast<std::size_t>(f) < unsplittable.size() && unsplittable[static_cast<std::size_t>(f)];
  };
  const auto mark_unsplittable = [&](Index f) {
    if (static_cast<std::size_t>(f) >= unsplittable.size()) unsplittable.resize(static_cast<std::size_t>(f) + 1, 0);
    unsplittable[static_cast<std::size_t>(f)] = 1;
  };
  while (!queue.empty()) {
    if (static_cast<double>(T.num_vertices()) >= budget) {
      result.budget_exhausted = true;
      break;
    }
    const Index f = std::get<2>(queue.top());
    queue.pop();
    if (!T.face_alive(f) || is_unsplittable(f) || assess(f).quality != Quality::bad) continue;
    const std::array<Vec2, 3> p = layout_face(T, f);
    Vec2 centre = circumcentre(p[0], p[1], p[2]);
    {
      // Üngör's off-centre: on the shortest side's bisector, no farther than the apex of the isosceles
      // triangle with angle `bound` over that side (the new triangle is then just good enough). Fewer
      // insertions than circumcentres for the same bound.
      int shortest = 0;
      double shortest_length = INFINITY;
      for (int k = 0; k < 3; ++k) {
        const double length = (p[static_cast<std::size_t>((k + 1) % 3)] - p[static_cast<std::size_t>(k)]).norm();
        if (length < shortest_length) shortest_length = length, shortest = k;
      }
      const Vec2 middle = (p[static_cast<std::size_t>(shortest)] + p[static_cast<std::size_t>((shortest + 1) % 3)]) * 0.5;
      const double reach = 0.5 * shortest_length / std::tan(0.5 * bound);
      const double distance = (centre - middle).norm();
      if (distance > reach) centre = middle + (centre - middle) * (reach / distance);
    }
    if (!std::isfinite(centre.x) || !std::isfinite(centre.y)) {  // a numerically flat face
      mark_unsplittable(f);
      continue;
    }
    const TraceEnd end = trace_line(T, f, (p[0] + p[1] + p[2]) * (1.0 / 3), centre);
    changed.clear();
    touched.clear();
    Index inserted = kInvalid;
    if (end.boundary_halfedge != kInvalid) {
      inserted = T.split_edge(end.boundary_halfedge, 0.5, &changed);
      if (inserted != kInvalid) ++result.boundary_splits;
    } else if (const Index edge = encroached_boundary_edge(T, end.face, end.corners, centre); edge != kInvalid) {
      inserted = T.split_edge(edge, 0.5, &changed);
      if (inserted != kInvalid) ++result.boundary_splits;
    } else {
      const auto& b = end.bary;
      const int small = static_cast<int>((b[0] < kOnEdge) + (b[1] < kOnEdge) + (b[2] < kOnEdge));
      const bool finite = std::isfinite(b[0]) && std::isfinite(b[1]) && std::isfinite(b[2]);
      if (finite && small == 0) {
        inserted = T.insert_vertex(end.face, b, &changed);
      } else if (finite && small == 1) {  // on the side opposite the small coordinate's corner
        const int k = b[0] < kOnEdge ? 0 : (b[1] < kOnEdge ? 1 : 2);
        Index side = T.halfedge(end.face);
        for (int i = 0; i < (k + 1) % 3; ++i) side = T.next(side);
        const double from_tail = b[static_cast<std::size_t>((k + 2) % 3)] /
                                 (b[static_cast<std::size_t>((k + 1) % 3)] + b[static_cast<std::size_t>((k + 2) % 3)]);
        if (from_tail > kOnEdge && from_tail < 1 - kOnEdge) inserted = T.split_edge(side, from_tail, &changed);
        if (inserted != kInvalid && T.is_boundary_vertex(inserted)) ++result.boundary_splits;
      }
    }
    if (inserted == kInvalid) {
      mark_unsplittable(f);
      continue;
    }
    ++result.inserted;
    result.flips += T.flip_to_delaunay_around(changed, &touched);
    // Faces around the new vertex and around every vertex a flip touched.
    touched.push_back(inserted);
    for (Index v : touched) {
      if (!T.vertex_alive(v)) continue;
      T.for_each_outgoing(v, [&](Index h) { push_if_bad(T.face(h)); });
    }
  }
  result.min_angle_after = min_corner_angle_degrees(T);
  for (Index f = 0; f < T.num_face_slots(); ++f) {
    if (!T.face_alive(f)) continue;
    const Quality q = assess(f).quality;
    if (q == Quality::good) continue;
    ++result.faces_below_bound;
    if (q == Quality::sharp) ++result.sharp_vertex_faces;
    if (q == Quality::tiny) ++result.tiny_faces;
  }
  result.bound_reached = result.faces_below_bound == 0;
  return result;
}

std::vector<InputSurfacePoint> locate_inserted_vertices(const IntrinsicTriangulation& T, const Faces& F) {
  const Index n = T.num_input_vertices();
  // Input faces around each input vertex.
  std::vector<Index> start(static_cast<std::size_t>(n) + 1, 0), incident(static_cast<std::size_t>(3 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Index v = F(f, k);
      if (v < 0 || v >= n) throw std::invalid_argument("locate_inserted_vertices: face " + std::to_string(f) + " names vertex " + std::to_string(v) + " beyond the input");
      ++start[static_cast<std::size_t>(v) + 1];
    }
  for (std::size_t v = 0; v < static_cast<std::size_t>(n); ++v) start[v + 1] += start[v];
  {
    std::vector<Index> fill(start.begin(), start.end() - 1);
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k) incident[static_cast<std::size_t>(fill[static_cast<std::size_t>(F(f, k))]++)] = static_cast<Index>(f);
  }
  std::vector<Vec2> position(static_cast<std::size_t>(n));
  std::vector<Index> stamp(static_cast<std::size_t>(n), kInvalid);
  std::vector<Index> placed_stamp(static_cast<std::size_t>(T.num_face_slots()), kInvalid);
  std::vector<InputSurfacePoint> out;
  for (Index v = n; v < T.num_vertex_slots(); ++v) {
    if (!T.vertex_alive(v)) continue;
    // Unfold the intrinsic faces within three sides of one of v's faces, with v at its corner.
    const Index root_halfedge = T.vertex_halfedge(v);
    const Index root = T.face(root_halfedge);
    std::vector<std::pair<Index, std::array<Vec2, 3>>> placed;
    placed.emplace_back(root, layout_face(T, root));
    placed_stamp[root] = v;
    Vec2 target{0, 0};
    {
      Index g = T.halfedge(root);
      for (int k = 0; k < 3; ++k, g = T.next(g))
        if (g == root_halfedge) target = placed[0].second[static_cast<std::size_t>(k)];
    }
    // Grown ring by ring until an input triangle whose corners are all imaged contains the target
    // (fine triangles may span many small intrinsic faces after refinement); then the best found.
    // Input triangles become candidates when their last corner is imaged, so each attempt looks only
    // at the triangles around the input vertices imaged since the previous one.
    std::size_t begin = 0, imaged_faces = 0, candidates_from = 0;
    std::vector<Index> imaged;
    InputSurfacePoint best;
    double best_margin = -std::numeric_limits<double>::infinity();
    for (int level = 0; level < 64 && begin < placed.size() && best_margin < -1e-9; ++level) {
      const std::size_t end = placed.size();
      for (std::size_t i = begin; i < end && placed.size() < 65536; ++i) {
        const Index g = placed[i].first;
        const std::array<Vec2, 3> q = placed[i].second;
        Index side = T.halfedge(g);
        for (int k = 0; k < 3; ++k, side = T.next(side)) {
          const Index across = side ^ 1;
          if (T.is_exterior(across) || placed_stamp[T.face(across)] == v) continue;
          placed_stamp[T.face(across)] = v;
          placed.emplace_back(T.face(across), unfold_across(T, across, q[static_cast<std::size_t>((k + 1) % 3)],
                                                            q[static_cast<std::size_t>(k)]));
        }
      }
      begin = end;
      if (level < 2 && begin < placed.size()) continue;
      // Images of the input vertices in the faces laid out since the last attempt: tracked points
      // and surviving input vertices.
      for (; imaged_faces < placed.size(); ++imaged_faces) {
        const Index g = placed[imaged_faces].first;
        const std::array<Vec2, 3>& q = placed[imaged_faces].second;
        T.for_each_point_in_face(g, [&](Index p) {
          if (stamp[static_cast<std::size_t>(p)] == v) return;
          const SurfacePoint s = T.location(p);
          position[static_cast<std::size_t>(p)] = q[0] * s.bary[0] + q[1] * s.bary[1] + q[2] * s.bary[2];
          stamp[static_cast<std::size_t>(p)] = v;
          imaged.push_back(p);
        });
        Index c = T.halfedge(g);
        for (int k = 0; k < 3; ++k, c = T.next(c)) {
          const Index corner = T.tail(c);
          if (corner >= n || stamp[static_cast<std::size_t>(corner)] == v) continue;
          position[static_cast<std::size_t>(corner)] = q[static_cast<std::size_t>(k)];
          stamp[static_cast<std::size_t>(corner)] = v;
          imaged.push_back(corner);
        }
      }
      // Triangles whose image is folded over (a cone's cut in the unfolding) only when no other has
      // all its corners imaged.
      for (const bool allow_folded : {false, true}) {
        for (std::size_t j = candidates_from; j < imaged.size(); ++j)
          for (Index i = start[static_cast<std::size_t>(imaged[j])]; i < start[static_cast<std::size_t>(imaged[j]) + 1]; ++i) {
            const Index face = incident[static_cast<std::size_t>(i)];
            const Index a = F(face, 0), b = F(face, 1), c = F(face, 2);
            if (stamp[static_cast<std::size_t>(a)] != v || stamp[static_cast<std::size_t>(b)] != v ||
                stamp[static_cast<std::size_t>(c)] != v)
              continue;
            const Vec2 pa = position[static_cast<std::size_t>(a)], pb = position[static_cast<std::size_t>(b)],
                       pc = position[static_cast<std::size_t>(c)];
            const double orientation = orient2d(pa, pb, pc);
            if (orientation == 0 || (!allow_folded && orientation < 0)) continue;
            const std::array<double, 3> bary = barycentric(target, pa, pb, pc);
            const double margin = std::min({bary[0], bary[1], bary[2]});
            if (margin > best_margin) best_margin = margin, best = {face, bary};
          }
        if (best.face != kInvalid) break;
      }
      candidates_from = imaged.size();
    }
    if (best.face == kInvalid) {
      // No input triangle has a proper image here (a component of one or two numerically flat input
      // triangles): the nearest imaged input vertex stands for the point.
      Index nearest = kInvalid;
      double nearest_distance = std::numeric_limits<double>::infinity();
      for (Index p : imaged) {
        const double d = (position[static_cast<std::size_t>(p)] - target).norm();
        if (d < nearest_distance) nearest_distance = d, nearest = p;
      }
      if (nearest == kInvalid || start[static_cast<std::size_t>(nearest)] == start[static_cast<std::size_t>(nearest) + 1])
        throw std::runtime_error("locate_inserted_vertices: no input vertex around inserted vertex " + std::to_string(v) +
                                 " (" + std::to_string(placed.size()) + " intrinsic faces searched)");
      best.face = incident[static_cast<std::size_t>(start[static_cast<std::size_t>(nearest)])];
      for (int k = 0; k < 3; ++k) best.bary[static_cast<std::size_t>(k)] = F(best.face, k) == nearest ? 1.0 : 0.0;
    }
    best.bary = clamp_barycentric(best.bary);
    out.push_back(best);
  }
  return out;
}

}  // namespace ice
