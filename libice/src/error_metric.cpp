#include "ice/triangle_geometry.h"
#include "ice/error_metric.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ice {
namespace {

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

IntrinsicErrorMetric::IntrinsicErrorMetric(const IntrinsicTriangulation& T, double area_weight, bool normalize_curvature)
    : area_channel_(area_weight != 0) {
  if (!T.frames_maintained())
    throw std::invalid_argument("IntrinsicErrorMetric: the triangulation does not maintain its frames (maintain_frames(true))");
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
  double curvature_scale = 1 - area_weight;
  if (normalize_curvature) {
    double total_curvature = 0;
    for (Index v = 0; v < n; ++v)
      if (T.vertex_alive(v)) total_curvature += std::abs(T.curvature(v));
    if (total_curvature > 0) curvature_scale /= total_curvature;
  }
  for (Index v = 0; v < n; ++v) {
    if (!T.vertex_alive(v)) continue;
    const double K = T.curvature(v);
    records_[v].mass = {curvature_scale * std::max(K, 0.0), curvature_scale * std::max(-K, 0.0),
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

bool IntrinsicErrorMetric::split_weights(const IntrinsicTriangulation& T, Index v, RemovalPlan& scratch,
                                         double* log_scale) const {
  std::vector<Neighbour>& out = scratch.neighbours_;
  out.clear();
  // One walk reads the star; Newton and the curvature changes below work on that snapshot. The
  // split weights only rank and share masses: a 1e-7 relative angle-sum tolerance is plenty (the
  // weights move by about as much; the committed flattening itself is exact to 1e-13). A scale
  // already computed for the same star (*log_scale finite on entry) is reused.
  VertexStar& star = scratch.star_;
  T.read_star(v, star);
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
    for (int c = 0; c < kChannels; ++c) off_centre = off_centre || from.centre[c] != std::complex<double>(0.0, 0.0);
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

double IntrinsicErrorMetric::removal_cost(const IntrinsicTriangulation& T, Index v, RemovalPlan& scratch,
                                          double* log_scale) const {
  if (log_scale) *log_scale = std::numeric_limits<double>::quiet_NaN();
  if (!split_weights(T, v, scratch, log_scale)) return std::numeric_limits<double>::infinity();
  const std::vector<Neighbour>& neighbours = scratch.neighbours_;
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

double IntrinsicErrorMetric::removal_cost(const IntrinsicTriangulation& T, Index v, double* log_scale) const {
  RemovalPlan scratch;
  return removal_cost(T, v, scratch, log_scale);
}

bool IntrinsicErrorMetric::prepare_removal(const IntrinsicTriangulation& T, Index v, RemovalPlan& plan,
                                           double log_scale) const {
  plan.pending_.clear();
  plan.vertex_ = kInvalid;
  if (!split_weights(T, v, plan, &log_scale)) return false;
  for (const Neighbour& n : plan.neighbours_) {
    PendingRecord record{n.vertex, {}, {}};
    const auto keep = [&](int c, double mass, double re, double im) {
      record.mass[c] = mass;
      record.moment[c] = {re, im};
    };
    if (area_channel_) merge_channels<kChannels>(T, v, n, keep);
    else merge_channels<kChannels - 1>(T, v, n, keep);
    plan.pending_.push_back(record);
  }
  plan.vertex_ = v;
  return true;
}

void IntrinsicErrorMetric::apply_removal(RemovalPlan& plan) {
  for (const PendingRecord& r : plan.pending_) {
    Record& record = records_[r.vertex];
    record.mass = r.mass;
    for (int c = 0; c < kChannels; ++c)
      record.centre[c] = r.mass[c] > 0 ? r.moment[c] / r.mass[c] : std::complex<double>(0, 0);
  }
  if (plan.vertex_ != kInvalid) records_[plan.vertex_] = Record{};
  plan.pending_.clear();
  plan.vertex_ = kInvalid;
}

}  // namespace ice
