#include "ice/point_cloud.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>
#include <nanoflann.hpp>

#include "run_tasks.h"
#include "vertex_buckets.h"
#include "ice/mesh_validation.h"
#include "ice/triangle_geometry.h"

namespace ice {

namespace {

// The points one after the other (a Positions matrix stores each coordinate apart: three cache
// misses per point for the k-d tree and the fans).
using PointList = std::vector<Eigen::Vector3d>;

// nanoflann's view of the points.
struct PointCloudRows {
  const PointList& points;
  std::size_t kdtree_get_point_count() const { return points.size(); }
  double kdtree_get_pt(std::size_t i, std::size_t d) const { return points[i][static_cast<Eigen::Index>(d)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const { return false; }
};
using PointCloudTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointCloudRows>, PointCloudRows, 3, Index>;

// A point's tangent plane: its least-squares plane's two axes.
struct TangentFrame {
  Eigen::Vector3d e1 = Eigen::Vector3d::Zero(), e2 = Eigen::Vector3d::Zero();
};

struct InvertedNeighbour {
  Eigen::Vector2d q;  // the neighbour's position in the tangent plane, inverted in the unit circle
  Index point;
};

double cross_2d(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

// The convex hull of the inverted positions, counter-clockwise without collinear points (Andrew's
// monotone chain), as indices into `q`.
void convex_hull(std::vector<InvertedNeighbour>& q, std::vector<Index>& hull) {
  std::sort(q.begin(), q.end(), [](const InvertedNeighbour& a, const InvertedNeighbour& b) {
    return a.q.x() < b.q.x() || (a.q.x() == b.q.x() && a.q.y() < b.q.y());
  });
  hull.clear();
  const Index n = static_cast<Index>(q.size());
  if (n < 2) return;
  hull.resize(static_cast<std::size_t>(2 * n));
  Index k = 0;
  const auto turns_left = [&](Index a, Index b, Index c) {
    return cross_2d(q[b].q - q[a].q, q[c].q - q[a].q) > 0;
  };
  for (Index i = 0; i < n; ++i) {  // lower chain
    while (k >= 2 && !turns_left(hull[k - 2], hull[k - 1], i)) --k;
    hull[k++] = i;
  }
  for (Index i = n - 2, lower = k + 1; i >= 0; --i) {  // upper chain
    while (k >= lower && !turns_left(hull[k - 2], hull[k - 1], i)) --k;
    hull[k++] = i;
  }
  hull.resize(static_cast<std::size_t>(k - 1));  // the first point closes the chain
}

// Point i's fan, appended to `out` as (i, a, b) counter-clockwise in i's tangent plane.
//
// Why the hull: the Delaunay neighbours of the origin among points x_j are those whose bisector
// half-plane {y : y·x_j ≤ |x_j|²/2} bounds the origin's Voronoi cell. Written y·q_j ≤ 1/2 with
// q_j = x_j/|x_j|², these are the vertices of the convex hull of the q_j (polar duality), in angular
// order; consecutive hull vertices a, b meet at a Voronoi vertex (the circumcentre of 0, x_a, x_b)
// exactly when the origin lies to the left of the hull edge a → b, i.e. q_a × q_b > 0. Otherwise the
// cell is unbounded there: the point is on the boundary of its neighbourhood.
//
// With separate_thin_parts, why the plane is the nearest third's (10 of 30 neighbours): where the
// surface is thin at the neighbourhood's scale (a limb a few points around) all of the neighbours
// span it across, and their least-squares plane can be anything (on a tube sampled 6 points around,
// 345 of 360 points' planes were more than 30° off with all 30, 12 with the nearest 10); the nearest
// ones still lie on the point's side. The Delaunay fan is still taken of all the neighbours.
//
// With separate_thin_parts, why steep neighbours are left out (those farther from the plane than
// along it, 45° or more off it): where the surface is locally a sphere through i tangent to the
// plane, a point on it at 45° from the plane is on the sphere's equator, where its projection onto
// the plane turns back; beyond it projected points fall among nearer ones in the wrong order. Such
// neighbours are on another sheet (across a thin part a few points around: a limb, a fin) or where
// the surface bends at the neighbourhood's scale; their triangles joined the two sides of a thin
// part, and the cloud's Laplacian then differed from its surface's (docs/measurements.md, "Clouds:
// thin parts kept apart").
//
// Why `reach` (the farthest neighbour's distance): a triangle whose circumcentre (a vertex of the
// origin's Voronoi cell) lies beyond it owes its place to the neighbourhood's edge: points not among
// the neighbours may lie in its circumcircle. Along the hull of a scan, a gap or a random sample such
// triangles are slivers (angles up to ~180°: cotan weights of ~1e5 on an open sheet's boundary, where
// intrinsic flips cannot mend them); they are left out unless the whole fan is of them (a point must
// keep a triangle).
void local_fan(const Positions& P, const PointList& X, Index i, const Index* neighbour, std::size_t count, double diagonal,
               double reach, bool separate_thin_parts, std::vector<InvertedNeighbour>& q, std::vector<Index>& hull,
               std::vector<std::array<Index, 3>>& out, TangentFrame& frame) {
  const Eigen::Vector3d& p = X[static_cast<std::size_t>(i)];
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  const auto fit_plane = [&](std::size_t used) {  // the least-squares plane of i and its `used` nearest
    Eigen::Vector3d mean = p;
    for (std::size_t j = 0; j < used; ++j) mean += X[static_cast<std::size_t>(neighbour[j])];
    mean /= static_cast<double>(used + 1);
    Eigen::Matrix3d covariance = (p - mean) * (p - mean).transpose();
    for (std::size_t j = 0; j < used; ++j) {
      const Eigen::Vector3d d = X[static_cast<std::size_t>(neighbour[j])] - mean;
      covariance += d * d.transpose();
    }
    solver.computeDirect(covariance);
  };
  const std::size_t third = std::min(count, std::max<std::size_t>(2, count / 3));
  fit_plane(separate_thin_parts ? third : count);
  // The nearest third nearly on a line (their spread across under a tenth of their spread along, as
  // on a scan line) determine no plane: then all of them.
  if (separate_thin_parts && third < count && !(solver.eigenvalues()(1) > 1e-2 * solver.eigenvalues()(2))) fit_plane(count);
  const Eigen::Vector3d e1 = solver.eigenvectors().col(2), e2 = solver.eigenvectors().col(1);  // the two largest
  const Eigen::Vector3d normal = solver.eigenvectors().col(0);
  frame = {e1, e2};
  const std::size_t first = out.size();
  // The fan of the neighbours, those 45° or more off the plane left out when asked; returns how many were.
  const auto add_fan = [&](bool leave_out_steep) {
    q.clear();
    std::size_t steep = 0;
    for (std::size_t j = 0; j < count; ++j) {
      const Eigen::Vector3d d = X[static_cast<std::size_t>(neighbour[j])] - p;
      const Eigen::Vector2d x(d.dot(e1), d.dot(e2));
      const double r2 = x.squaredNorm();
      if (!(r2 > 0)) continue;  // right above or below i in its plane: no place in the fan
      const double height = d.dot(normal);
      if (leave_out_steep && height * height >= r2) {
        ++steep;
        continue;
      }
      q.push_back({x / r2, neighbour[j]});
    }
    convex_hull(q, hull);
    const std::size_t h = hull.size();
    if (h < 2) return steep;
    std::size_t beyond = 0;
    for (std::size_t k = 0; k < h; ++k) {  // h = 2: both ways round, at most one with the origin on its left
      const InvertedNeighbour& a = q[static_cast<std::size_t>(hull[k])];
      const InvertedNeighbour& b = q[static_cast<std::size_t>(hull[(k + 1) % h])];
      const double det = cross_2d(a.q, b.q);
      if (!(det > 0)) continue;
      if (is_degenerate_triangle(P, i, a.point, b.point, diagonal)) continue;
      // The Voronoi vertex c (c·q_a = c·q_b = 1/2), the triangle's circumcentre.
      const Eigen::Vector2d c = Eigen::Vector2d(b.q.y() - a.q.y(), a.q.x() - b.q.x()) / (2 * det);
      const bool inside = c.squaredNorm() <= reach * reach;
      if (!inside) ++beyond;
      out.push_back({inside ? i : -1 - i, a.point, b.point});  // marked: left out below unless all are
    }
    const bool keep_beyond = beyond == out.size() - first;
    std::size_t w = first;
    for (std::size_t r = first; r < out.size(); ++r) {
      if (out[r][0] < 0) {
        if (!keep_beyond) continue;
        out[r][0] = -1 - out[r][0];
      }
      out[w++] = out[r];
    }
    out.resize(w);
    return steep;
  };
  // A fan left empty by the steep neighbours (an outlier off its neighbours' plane): one of all.
  if (add_fan(separate_thin_parts) > 0 && out.size() == first) add_fan(false);
}

// The directions a triangle at corner v covers in v's tangent plane: from `start`, counter-clockwise
// over `length` (at most π: the shorter way round between its two other corners' directions).
struct CornerArc {
  double start = 0, length = 0;
};

CornerArc corner_arc(const PointList& X, const TangentFrame& frame, Index v, Index x, Index y) {
  const auto angle = [&](Index w) {
    const Eigen::Vector3d d = X[static_cast<std::size_t>(w)] - X[static_cast<std::size_t>(v)];
    return std::atan2(d.dot(frame.e2), d.dot(frame.e1));
  };
  const double tau = 2 * kPi, ax = angle(x), ay = angle(y);
  const double turn = std::fmod(ay - ax + 2 * tau, tau);
  return turn <= kPi ? CornerArc{ax, turn} : CornerArc{ay, tau - turn};
}

// Whether two arcs share interior directions (arcs that only touch at an end do not).
bool arcs_overlap(const CornerArc& a, const CornerArc& b) {
  const double tau = 2 * kPi, slack = 1e-9;
  return std::fmod(b.start - a.start + 2 * tau, tau) < a.length - slack ||
         std::fmod(a.start - b.start + 2 * tau, tau) < b.length - slack;
}

}  // namespace

Faces point_cloud_triangles(const Positions& points, const PointCloudOptions& options) {
  if (points.cols() != 3) throw std::invalid_argument("point_cloud_triangles: the points must have 3 columns");
  if (points.rows() > std::numeric_limits<Index>::max() / 8)  // 3·(faces) stays an Index
    throw std::invalid_argument("point_cloud_triangles: " + std::to_string(points.rows()) + " points are too many");
  const Index n = static_cast<Index>(points.rows());
  if (n < 3) throw std::invalid_argument("point_cloud_triangles: a point cloud needs at least 3 points, not " + std::to_string(n));
  if (options.neighbours < 2)
    throw std::invalid_argument("point_cloud_triangles: neighbours must be at least 2, not " + std::to_string(options.neighbours));
  for (Index i = 0; i < n; ++i)
    if (!points.row(i).allFinite())
      throw std::invalid_argument("point_cloud_triangles: point " + std::to_string(i) + " has a coordinate that is not finite");

  // Translated and scaled into a box of side 1 to 2: squared distances, covariances and circumradii
  // of coordinates near the ends of the double range would underflow or overflow. The scale is a power
  // of two (exact: the same triangles at any power-of-two scale) from half the extent (no overflow near
  // the largest doubles).
  const Eigen::RowVector3d low = points.colwise().minCoeff();
  const double half_extent = (0.5 * points.colwise().maxCoeff() - 0.5 * low).maxCoeff();
  if (!(half_extent > 0)) throw std::invalid_argument("point_cloud_triangles: points 0 and 1 are at the same position (all are)");
  int exponent = 0;
  std::frexp(half_extent, &exponent);
  const double scale = std::ldexp(1.0, -exponent);  // half_extent · scale in [0.5, 1)
  const Positions unit = (points.rowwise() - low) * scale;  // for the zero-area test (relative) as well
  const double diagonal = (unit.colwise().maxCoeff() - unit.colwise().minCoeff()).norm();
  PointList X(static_cast<std::size_t>(n));
  for (Index i = 0; i < n; ++i) X[static_cast<std::size_t>(i)] = unit.row(i).transpose();
  const PointCloudRows rows{X};
  const PointCloudTree tree(3, rows, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  const std::size_t wanted = static_cast<std::size_t>(std::min<Index>(options.neighbours, n - 1)) + 1;  // the point itself

  // Per range of points, in point order: the fans' triangles.
  const int threads = detail::requested_threads(options.threads);
  const int ranges = detail::range_count(threads, n);
  std::vector<std::vector<std::array<Index, 3>>> fans(static_cast<std::size_t>(ranges));
  std::vector<TangentFrame> frames(static_cast<std::size_t>(n));
  detail::run_numbered_ranges(threads, n, [&](int range, Index begin, Index end) {
    std::vector<Index> found(wanted), neighbour(wanted);
    std::vector<double> distance(wanted);
    std::vector<InvertedNeighbour> q;
    std::vector<Index> hull;
    auto& out = fans[static_cast<std::size_t>(range)];
    for (Index i = begin; i < end; ++i) {
      const std::size_t got = tree.knnSearch(X[static_cast<std::size_t>(i)].data(), wanted, found.data(), distance.data());
      std::size_t count = 0;
      for (std::size_t j = 0; j < got; ++j) {
        if (found[j] == i) continue;
        if (!(distance[j] > 0))
          throw std::invalid_argument("point_cloud_triangles: points " + std::to_string(std::min(i, found[j])) + " and " +
                                      std::to_string(std::max(i, found[j])) + " are at the same position");
        if (count + 1 < wanted) neighbour[count++] = found[j];
      }
      const double reach = got > 0 ? std::sqrt(distance[got - 1]) : 0.0;
      local_fan(unit, X, i, neighbour.data(), count, diagonal, reach, options.separate_thin_parts, q, hull, out,
                frames[static_cast<std::size_t>(i)]);
    }
  });

  // Every distinct triangle once (in the orientation of the lowest point's fan), with the fans that
  // have it (1 to 3): pairs (vertex set, the triangle as its fan has it) in increasing order (the
  // project's counting sort on the lowest point, its buckets ordered on the threads); a fan's
  // triangles start at its own point, so the lowest point's comes first in a group of equal vertex sets.
  using Keyed = std::pair<std::array<Index, 3>, std::array<Index, 3>>;
  std::vector<Keyed> all;
  {
    std::size_t total = 0;
    for (const auto& part : fans) total += part.size();
    all.reserve(total);
  }
  for (auto& part : fans) {
    for (const auto& t : part) {
      std::array<Index, 3> k = t;
      std::sort(k.begin(), k.end());
      all.emplace_back(k, t);
    }
    std::vector<std::array<Index, 3>>().swap(part);
  }
  detail::sort_by_vertex(
      all, n, [](const Keyed& r) { return r.first[0]; },
      [](const Keyed& a, const Keyed& b) { return a.first != b.first ? a.first < b.first : a.second[0] < b.second[0]; }, threads);
  struct Candidate {
    std::array<Index, 3> face;
    int votes;
    double circumradius;
    std::array<bool, 3> in_fan_of;  // corner k's own fan has it
  };
  // Per range of lowest vertices (a group of equal vertex sets never spans two), in order.
  const auto first_of = [&all](Index v) {
    return static_cast<std::size_t>(std::partition_point(all.begin(), all.end(), [v](const Keyed& r) { return r.first[0] < v; }) -
                                    all.begin());
  };
  std::vector<std::vector<Candidate>> candidate_parts(static_cast<std::size_t>(ranges));
  detail::run_numbered_ranges(threads, n, [&](int range, Index begin, Index end) {
    const std::size_t from = first_of(begin), to = first_of(end);
    auto& out = candidate_parts[static_cast<std::size_t>(range)];
    for (std::size_t first = from, last; first < to; first = last) {
      for (last = first + 1; last < to && all[last].first == all[first].first;) ++last;
      const auto& t = all[first].second;
      std::array<bool, 3> in_fan_of{false, false, false};
      for (std::size_t j = first; j < last; ++j)
        for (int k = 0; k < 3; ++k) in_fan_of[static_cast<std::size_t>(k)] |= all[j].second[0] == t[static_cast<std::size_t>(k)];
      const Eigen::Vector3d &x = X[static_cast<std::size_t>(t[0])], &y = X[static_cast<std::size_t>(t[1])], &z = X[static_cast<std::size_t>(t[2])];
      const double a = (y - x).norm(), b = (z - y).norm(), c = (x - z).norm();
      out.push_back({t, static_cast<int>(last - first), a * b * c / (4 * triangle_area(a, b, c)), in_fan_of});
    }
  });
  decltype(all)().swap(all);
  std::vector<Candidate> candidates;
  {
    std::size_t count = 0;
    for (const auto& part : candidate_parts) count += part.size();
    candidates.reserve(count);
    for (auto& part : candidate_parts) {
      candidates.insert(candidates.end(), part.begin(), part.end());
      std::vector<Candidate>().swap(part);
    }
  }
  // The fans of a triangle's corners can disagree (near-cocircular neighbours seen in different
  // tangent planes take different diagonals): their union would cover such places twice, which the
  // cover keeps as folded sheets that no vertex removal can flatten. One consistent choice: the
  // triangles most fans agree on first, then the smaller circumradius (the Delaunay choice of a
  // quad's diagonal), each kept unless it covers, at one of its corners, directions in that corner's
  // tangent plane that a kept triangle covers already.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    if (a.votes != b.votes) return a.votes > b.votes;
    if (a.circumradius != b.circumradius) return a.circumradius < b.circumradius;
    return a.face < b.face;
  });
  // The kept triangles' arcs at each point: at most one per candidate at the point (slots start[v] ..).
  std::vector<std::size_t> start(static_cast<std::size_t>(n) + 1, 0);
  for (const Candidate& candidate : candidates)
    for (Index v : candidate.face) ++start[static_cast<std::size_t>(v) + 1];
  for (std::size_t v = 0; v < static_cast<std::size_t>(n); ++v) start[v + 1] += start[v];
  // Each candidate's arcs at its corners, on the threads (they depend on the candidate alone): the
  // choice below, which must follow the order, then only compares arcs.
  std::vector<std::array<CornerArc, 3>> arcs(candidates.size());
  detail::run_ranges(threads, candidates.size(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t c = begin; c < end; ++c) {
      const auto& t = candidates[c].face;
      for (std::size_t k = 0; k < 3; ++k)
        arcs[c][k] = corner_arc(X, frames[static_cast<std::size_t>(t[k])], t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
    }
  });
  std::vector<CornerArc> covered(start.back());
  std::vector<std::size_t> covered_count(static_cast<std::size_t>(n), 0);
  std::vector<std::array<Index, 3>> kept;
  kept.reserve(candidates.size());
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    const auto& t = candidates[c].face;
    bool free = true;
    for (std::size_t k = 0; k < 3 && free; ++k) {
      const auto v = static_cast<std::size_t>(t[k]);
      for (std::size_t j = start[v]; j < start[v] + covered_count[v] && free; ++j)
        if (arcs_overlap(arcs[c][k], covered[j])) free = false;
    }
    if (!free) continue;
    for (std::size_t k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(t[k]);
      covered[start[v] + covered_count[v]++] = arcs[c][k];
    }
    kept.push_back(t);
  }
  decltype(covered)().swap(covered);
  decltype(arcs)().swap(arcs);
  // A point whose every triangle lost to its neighbours' (a point squeezed between close ones) keeps
  // its own: a point on no triangle would have no value.
  std::vector<char> on_face(static_cast<std::size_t>(n), 0);
  for (const auto& t : kept)
    for (Index v : t) on_face[static_cast<std::size_t>(v)] = 1;
  // (A point whose own fan is empty keeps every candidate through it.)
  std::vector<char> has_fan(static_cast<std::size_t>(n), 0);
  for (const Candidate& candidate : candidates)
    for (int k = 0; k < 3; ++k)
      if (candidate.in_fan_of[static_cast<std::size_t>(k)]) has_fan[static_cast<std::size_t>(candidate.face[static_cast<std::size_t>(k)])] = 1;
  for (const Candidate& candidate : candidates) {
    const auto& t = candidate.face;
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(t[static_cast<std::size_t>(k)]);
      if (!on_face[v] && (candidate.in_fan_of[static_cast<std::size_t>(k)] || !has_fan[v])) {
        kept.push_back(t);
        break;
      }
    }
  }
  std::sort(kept.begin(), kept.end());

  for (const auto& t : kept)
    for (Index v : t) on_face[static_cast<std::size_t>(v)] = 1;
  for (Index i = 0; i < n; ++i)
    if (!on_face[static_cast<std::size_t>(i)])
      throw std::invalid_argument("point_cloud_triangles: point " + std::to_string(i) +
                                  " lies on no triangle (it and its nearest neighbours lie on one line)");
  Faces F(static_cast<Eigen::Index>(kept.size()), 3);
  for (std::size_t f = 0; f < kept.size(); ++f)
    for (int k = 0; k < 3; ++k) F(static_cast<Eigen::Index>(f), k) = kept[f][static_cast<std::size_t>(k)];
  return F;
}

}  // namespace ice
