#include "fem/distance_oracle.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "coarse_marching.h"
#include "fem/problems.h"
#include "parallel_kernels.h"
#include "ice/wall_time.h"

namespace fem {

const char* to_string(CoarseDistanceMethod method) {
  return method == CoarseDistanceMethod::marching ? "marching" : "heat_method";
}

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
using ice::seconds_since;

}  // namespace

DistanceOracle::DistanceOracle(const ice::IntrinsicMesh& coarse, const std::vector<ice::CoarsePoint>& fine_points,
                               const DistanceOracleOptions& options)
    : options_(options) {
  const Faces& coarse_faces = coarse.F;
  const FaceLengths& coarse_lengths = coarse.L;
  detail::check_marching_mesh(coarse_faces, coarse_lengths, "DistanceOracle");
  if (options.threads < 0 || options.heat_block_size < 1 || !(options.heat_time_factor > 0) || options.subdivisions < 0 ||
      options.subdivisions > kMaxMarchingSubdivisions)
    throw std::invalid_argument("DistanceOracle: threads must be >= 0, heat_block_size >= 1, heat_time_factor > 0, "
                                "subdivisions in [0, " + std::to_string(kMaxMarchingSubdivisions) + "]");
  coarse_size_ = checked_vertex_count(coarse);
  faces_ = coarse_faces;
  squared_lengths_ = coarse_lengths.array().square();
  const std::size_t nc = static_cast<std::size_t>(coarse_size_);

  // ---- the fine points first (cheap, and bad input is refused before the long part)
  auto start = std::chrono::steady_clock::now();
  points_.resize(fine_points.size());
  for (std::size_t i = 0; i < fine_points.size(); ++i) {
    try {
      points_[i] = make_point(fine_points[i]);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string(e.what()) + " (fine vertex " + std::to_string(i) + ")");
    }
  }
  times_.fine_points = seconds_since(start);

  // ---- all coarse pairs: row a = distances from coarse vertex a
  start = std::chrono::steady_clock::now();
  std::vector<float> distances(nc * nc);
  if (options.method == CoarseDistanceMethod::marching) {
    detail::SubdividedMesh finer{{coarse_faces, coarse_lengths, {}, static_cast<Index>(coarse_size_)}, {}};
    for (int level = 0; level < options.subdivisions; ++level)  // the gluing carried from level to level
      finer = detail::subdivide_midpoints(finer.F, finer.L, finer.vertex_count, finer.twin);
    const detail::MarchingMesh marching_mesh(finer.F, finer.L, finer.vertex_count, finer.twin);
#pragma omp parallel num_threads(threads())
    {
      detail::CoarseMarcher marcher(marching_mesh);
      std::vector<double> row;
#pragma omp for schedule(dynamic, 8)
      for (Eigen::Index a = 0; a < coarse_size_; ++a) {
        marcher.run(static_cast<Index>(a), row);
        std::copy(row.begin(), row.begin() + static_cast<std::ptrdiff_t>(nc),  // the coarse vertices come first
                  distances.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(a) * nc));
      }
    }
  } else {
    const HeatGeodesicSolver solver(
        heat_method_operators(coarse, MassKind::lumped, options.heat_time_factor));
    for (Eigen::Index first = 0; first < coarse_size_; first += options.heat_block_size) {
      const Eigen::Index count = std::min<Eigen::Index>(options.heat_block_size, coarse_size_ - first);
      std::vector<Index> sources(static_cast<std::size_t>(count));
      for (Eigen::Index j = 0; j < count; ++j) sources[static_cast<std::size_t>(j)] = static_cast<Index>(first + j);
      const Eigen::MatrixXd block = solver.distances_from_each(sources);
      for (Eigen::Index j = 0; j < count; ++j)
        for (Eigen::Index b = 0; b < coarse_size_; ++b)
          distances[static_cast<std::size_t>(first + j) * nc + static_cast<std::size_t>(b)] =
              static_cast<float>(std::max(0.0, block(b, j)));
    }
  }
  // Symmetrise (neither method is exactly symmetric) and square, in place, tile by tile so that the
  // transposed reads stay in cache on large coarse meshes (at 1,000 coarse vertices a plain
  // row-by-row pass measured the same).
  constexpr std::size_t kTile = 64;
  const auto tiles = static_cast<std::ptrdiff_t>((nc + kTile - 1) / kTile);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads())
  for (std::ptrdiff_t tile_row = 0; tile_row < tiles; ++tile_row) {
    const std::size_t row_begin = static_cast<std::size_t>(tile_row) * kTile, row_end = std::min(nc, row_begin + kTile);
    for (std::size_t col_begin = row_begin; col_begin < nc; col_begin += kTile) {
      const std::size_t col_end = std::min(nc, col_begin + kTile);
      for (std::size_t a = row_begin; a < row_end; ++a)
        for (std::size_t b = std::max(col_begin, a); b < col_end; ++b) {
          const double mean = a == b ? 0.0 : 0.5 * (static_cast<double>(distances[a * nc + b]) + distances[b * nc + a]);
          distances[a * nc + b] = distances[b * nc + a] = static_cast<float>(mean * mean);
        }
    }
  }
  squared_distances_ = std::move(distances);
  times_.coarse_distances = seconds_since(start);
}

int DistanceOracle::threads() const { return options_.threads > 0 ? options_.threads : detail::default_threads(); }

DistanceOracle::FinePoint DistanceOracle::make_point(const ice::CoarsePoint& point) const {
  if (point.face < 0 || point.face >= faces_.rows())
    throw std::invalid_argument("DistanceOracle: coarse face " + std::to_string(point.face) + " out of range");
  const auto& w = point.bary;
  if (!(w[0] >= 0 && w[1] >= 0 && w[2] >= 0) || !(std::abs(w[0] + w[1] + w[2] - 1) <= 1e-6))
    throw std::invalid_argument("DistanceOracle: barycentric coordinates must be non-negative and sum to 1");
  FinePoint p;
  p.face = point.face;
  const double sum = w[0] + w[1] + w[2];
  p.weight0 = static_cast<float>(w[0] / sum);
  p.weight1 = static_cast<float>(w[1] / sum);
  // Corners k and k+1 span edge k.
  double spread = 0;
  for (int k = 0; k < 3; ++k)
    spread += w[static_cast<std::size_t>(k)] * w[static_cast<std::size_t>((k + 1) % 3)] * squared_lengths_(point.face, k) / (sum * sum);
  p.spread = static_cast<float>(spread);
  return p;
}

double DistanceOracle::squared_distance(const FinePoint& x, const FinePoint& y) const {
  const std::array<double, 3> wx = x.weights(), wy = y.weights();
  double sum = 0;
  if (x.face == y.face) {
    // Inside one flattened face: its own squared edge lengths between corners (0 on the diagonal).
    const auto& l2 = squared_lengths_.row(x.face);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        if (i == j) continue;
        const int edge = (j == (i + 1) % 3) ? i : j;  // the edge from corner i to i+1 is column i
        sum += wx[static_cast<std::size_t>(i)] * wy[static_cast<std::size_t>(j)] * l2(edge);
      }
  } else {
    for (int i = 0; i < 3; ++i) {
      const float* row = squared_distances_.data() + static_cast<std::size_t>(faces_(x.face, i)) * static_cast<std::size_t>(coarse_size_);
      double inner = 0;
      for (int j = 0; j < 3; ++j) inner += wy[static_cast<std::size_t>(j)] * row[faces_(y.face, j)];
      sum += wx[static_cast<std::size_t>(i)] * inner;
    }
    // Between coarse components every D² is +∞ and a zero weight makes 0 · ∞ = NaN: then again
    // with the positive weights only (a test off the hot path, which branches per weight would slow
    // down by half).
    if (std::isnan(sum)) {
      sum = 0;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          if (wx[static_cast<std::size_t>(i)] > 0 && wy[static_cast<std::size_t>(j)] > 0) sum = kInfinity;
    }
  }
  return std::max(0.0, sum - x.spread - y.spread);
}

double DistanceOracle::distance(Index u, Index v) const {
  if (u == v) return 0;
  return std::sqrt(squared_distance(points_[static_cast<std::size_t>(u)], points_[static_cast<std::size_t>(v)]));
}

double DistanceOracle::distance(const ice::CoarsePoint& x, const ice::CoarsePoint& y) const {
  return std::sqrt(squared_distance(make_point(x), make_point(y)));
}

Eigen::VectorXd DistanceOracle::distances(const std::vector<std::array<Index, 2>>& pairs) const {
  const Index n = static_cast<Index>(points_.size());
  for (std::size_t i = 0; i < pairs.size(); ++i)
    if (pairs[i][0] < 0 || pairs[i][0] >= n || pairs[i][1] < 0 || pairs[i][1] >= n)
      throw std::invalid_argument("DistanceOracle::distances: pair " + std::to_string(i) + " names a vertex out of range");
  Eigen::VectorXd out(static_cast<Eigen::Index>(pairs.size()));
  const auto count = static_cast<Eigen::Index>(pairs.size());
  // Random pairs on a large mesh wait for memory: fetch the points of the pair `kAhead` on early.
  constexpr Eigen::Index kAhead = 16;
#pragma omp parallel for schedule(static) num_threads(count >= 10000 ? threads() : 1)
  for (Eigen::Index i = 0; i < count; ++i) {
    if (i + kAhead < count) {
      const auto& ahead = pairs[static_cast<std::size_t>(i + kAhead)];
      __builtin_prefetch(&points_[static_cast<std::size_t>(ahead[0])]);
      __builtin_prefetch(&points_[static_cast<std::size_t>(ahead[1])]);
    }
    out(i) = distance(pairs[static_cast<std::size_t>(i)][0], pairs[static_cast<std::size_t>(i)][1]);
  }
  return out;
}

void DistanceOracle::squared_distances_to_coarse(const FinePoint& x, std::vector<double>& out) const {
  const std::size_t nc = static_cast<std::size_t>(coarse_size_);
  out.assign(nc, -static_cast<double>(x.spread));
  for (int i = 0; i < 3; ++i) {
    const float* row = squared_distances_.data() + static_cast<std::size_t>(faces_(x.face, i)) * nc;
    const double w = x.weights()[static_cast<std::size_t>(i)];
    if (!(w > 0)) continue;  // (0 · ∞ across components; once per row, off the hot path)
    for (std::size_t b = 0; b < nc; ++b) out[b] += w * row[b];
  }
}

double DistanceOracle::squared_distance_from_row(const std::vector<double>& row, const FinePoint& x,
                                                 const FinePoint& y) const {
  if (x.face == y.face) return squared_distance(x, y);
  double sum = -static_cast<double>(y.spread);
  const std::array<double, 3> wy = y.weights();
  for (int j = 0; j < 3; ++j) sum += wy[static_cast<std::size_t>(j)] * row[static_cast<std::size_t>(faces_(y.face, j))];
  if (std::isnan(sum)) return kInfinity;  // 0 · ∞: y's face lies in another coarse component
  return std::max(0.0, sum);
}

Eigen::VectorXd DistanceOracle::distances_from(Index source) const {
  const Eigen::Index n = fine_size();
  if (source < 0 || source >= n) throw std::invalid_argument("DistanceOracle::distances_from: source out of range");
  std::vector<double> row;
  const FinePoint& x = points_[static_cast<std::size_t>(source)];
  squared_distances_to_coarse(x, row);
  Eigen::VectorXd out(n);
#pragma omp parallel for schedule(static) num_threads(detail::active_threads(n, threads()))
  for (Eigen::Index v = 0; v < n; ++v) out(v) = std::sqrt(squared_distance_from_row(row, x, points_[static_cast<std::size_t>(v)]));
  out(source) = 0;
  return out;
}

Eigen::MatrixXf DistanceOracle::distance_matrix(const std::vector<Index>& rows, const std::vector<Index>& cols) const {
  const Index n = static_cast<Index>(points_.size());
  for (const std::vector<Index>* set : {&rows, &cols})
    for (Index v : *set)
      if (v < 0 || v >= n) throw std::invalid_argument("DistanceOracle::distance_matrix: vertex " + std::to_string(v) + " out of range");
  Eigen::MatrixXf out(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(cols.size()));
  const auto row_count = static_cast<Eigen::Index>(rows.size());
#pragma omp parallel num_threads(row_count * static_cast<Eigen::Index>(cols.size()) >= 10000 ? threads() : 1)
  {
    std::vector<double> coarse_row;
#pragma omp for schedule(dynamic, 4)
    for (Eigen::Index r = 0; r < row_count; ++r) {
      const Index u = rows[static_cast<std::size_t>(r)];
      const FinePoint& x = points_[static_cast<std::size_t>(u)];
      squared_distances_to_coarse(x, coarse_row);
      for (std::size_t c = 0; c < cols.size(); ++c) {
        const Index v = cols[c];
        out(r, static_cast<Eigen::Index>(c)) =
            u == v ? 0.0f : static_cast<float>(std::sqrt(squared_distance_from_row(coarse_row, x, points_[static_cast<std::size_t>(v)])));
      }
    }
  }
  return out;
}

std::vector<Index> DistanceOracle::farthest_point_samples(Index count, Index first) const {
  const Eigen::Index n = fine_size();
  if (count < 1 || count > n) throw std::invalid_argument("DistanceOracle::farthest_point_samples: count must be in [1, vertices]");
  if (first < 0 || first >= n) throw std::invalid_argument("DistanceOracle::farthest_point_samples: first sample out of range");
  // The fine vertices of each coarse face (CSR, increasing indices), and per face the largest
  // squared distance of its vertices to the samples so far (the smallest index attaining it).
  const auto face_count = static_cast<std::size_t>(faces_.rows());
  std::vector<Index> start(face_count + 1, 0), members(static_cast<std::size_t>(n));
  for (const FinePoint& p : points_) ++start[static_cast<std::size_t>(p.face) + 1];
  for (std::size_t g = 0; g < face_count; ++g) start[g + 1] += start[g];
  {
    std::vector<Index> next(start.begin(), start.end() - 1);
    for (Eigen::Index v = 0; v < n; ++v)
      members[static_cast<std::size_t>(next[static_cast<std::size_t>(points_[static_cast<std::size_t>(v)].face)]++)] =
          static_cast<Index>(v);
  }
  // A face none of whose vertices can come closer to the new sample than they are to the old ones
  // is skipped. Why that is exact for the oracle's own distance: for y in face g (not the sample's
  // face), d² = Σ μ_j r(q_j) − V(y) >= min_j r(q_j) − max_l²/3, as Σ μ_j = 1 and V(y) <= max_l²/3
  // (max_l the longest side of g); late samples leave most faces untouched.
  std::vector<double> longest_squared(face_count);
  for (std::size_t g = 0; g < face_count; ++g) longest_squared[g] = squared_lengths_.row(static_cast<Eigen::Index>(g)).maxCoeff();
  std::vector<double> nearest(static_cast<std::size_t>(n), kInfinity);  // squared distance to the nearest sample
  std::vector<double> face_value(face_count, kInfinity);
  std::vector<Index> face_argmax(face_count);
  for (std::size_t g = 0; g < face_count; ++g) face_argmax[g] = start[g] < start[g + 1] ? members[static_cast<std::size_t>(start[g])] : -1;

  std::vector<Index> samples{first};
  std::vector<double> row;
  const int thread_count = detail::active_threads(n, threads());
  while (static_cast<Index>(samples.size()) < count) {
    const FinePoint& x = points_[static_cast<std::size_t>(samples.back())];
    squared_distances_to_coarse(x, row);
    nearest[static_cast<std::size_t>(samples.back())] = 0;
#pragma omp parallel for schedule(dynamic, 64) num_threads(thread_count)
    for (std::ptrdiff_t gi = 0; gi < static_cast<std::ptrdiff_t>(face_count); ++gi) {
      const auto g = static_cast<std::size_t>(gi);
      if (start[g] == start[g + 1]) continue;
      if (static_cast<Index>(g) != x.face) {
        double closest = kInfinity;
        for (int j = 0; j < 3; ++j) closest = std::min(closest, row[static_cast<std::size_t>(faces_(gi, j))]);
        const double bound = closest - longest_squared[g] / 3;
        if (bound - 1e-9 * std::abs(bound) >= face_value[g]) continue;  // (a margin for the float weights)
      }
      double value = -1;
      Index argmax = -1;
      for (Index k = start[g]; k < start[g + 1]; ++k) {
        const Index v = members[static_cast<std::size_t>(k)];
        double& d = nearest[static_cast<std::size_t>(v)];
        if (d > 0) d = std::min(d, squared_distance_from_row(row, x, points_[static_cast<std::size_t>(v)]));
        if (d > value) {
          value = d;
          argmax = v;
        }
      }
      face_value[g] = value;
      face_argmax[g] = argmax;
    }
    double best_value = -1;
    Index best = -1;
    for (std::size_t g = 0; g < face_count; ++g)
      if (face_argmax[g] >= 0 && (face_value[g] > best_value || (face_value[g] == best_value && face_argmax[g] < best))) {
        best_value = face_value[g];
        best = face_argmax[g];
      }
    if (!(best_value > 0)) break;  // every vertex coincides with a sample already
    samples.push_back(best);
  }
  return samples;
}

bool DistanceOracle::is_near(Index u, Index v) const {
  const Index f = points_[static_cast<std::size_t>(u)].face, g = points_[static_cast<std::size_t>(v)].face;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (faces_(f, i) == faces_(g, j)) return true;
  return false;
}

double DistanceOracle::coarse_distance(Index a, Index b) const {
  if (a < 0 || b < 0 || a >= coarse_size_ || b >= coarse_size_)
    throw std::invalid_argument("DistanceOracle::coarse_distance: coarse vertex out of range");
  return std::sqrt(static_cast<double>(squared_distances_[static_cast<std::size_t>(a) * static_cast<std::size_t>(coarse_size_) + static_cast<std::size_t>(b)]));
}

std::size_t DistanceOracle::memory_bytes() const {
  return squared_distances_.size() * sizeof(float) + points_.size() * sizeof(FinePoint) +
         static_cast<std::size_t>(faces_.size()) * sizeof(Index) + static_cast<std::size_t>(squared_lengths_.size()) * sizeof(double);
}

std::vector<double> PairErrors::all() const {
  std::vector<double> both = far;
  both.insert(both.end(), near.begin(), near.end());
  return both;
}

PairErrors relative_pair_errors(const DistanceOracle& oracle, const std::vector<Index>& sources,
                                const Eigen::MatrixXd& reference) {
  if (reference.rows() != oracle.fine_size() || reference.cols() != static_cast<Eigen::Index>(sources.size()))
    throw std::invalid_argument("relative_pair_errors: one reference column per source, one row per fine vertex");
  PairErrors errors;
  for (std::size_t s = 0; s < sources.size(); ++s) {
    const Eigen::VectorXd d = oracle.distances_from(sources[s]);
    for (Eigen::Index v = 0; v < d.size(); ++v) {
      const double r = reference(v, static_cast<Eigen::Index>(s));
      if (v == sources[s] || !(r > 0) || (std::isinf(r) && std::isinf(d(v)))) continue;
      (oracle.is_near(sources[s], static_cast<Index>(v)) ? errors.near : errors.far).push_back(std::abs(d(v) - r) / r);
    }
  }
  return errors;
}

}  // namespace fem
