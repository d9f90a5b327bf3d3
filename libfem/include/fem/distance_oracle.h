#pragma once
/// \file distance_oracle.h
/// Geodesic distance between any two points of a fine mesh, answered through a small coarse mesh.
///
///   fem::DistanceOracle oracle(coarse.F, coarse.L, ice::fine_to_coarse_map(space));
///   double d = oracle.distance(u, v);                        // two fine vertices
///   Eigen::MatrixXf D = oracle.distance_matrix(rows, cols);  // a dense block
///
/// Precompute: the distances between all pairs of coarse vertices, D(a, b), symmetrised and kept as
/// float (4 n_c² bytes), plus per fine vertex its coarse face and barycentric coordinates (16 bytes,
/// half the 32 of the CoarsePoint it came from).
///
/// Query: a fine point x = Σ λ_i p_i in coarse face (p_0, p_1, p_2), y = Σ μ_j q_j in face (q_0, q_1, q_2):
///     d(x, y)² = Σ_ij λ_i μ_j D(p_i, q_j)² − V(x) − V(y),   V(x) = Σ_{i<k} λ_i λ_k |p_i p_k|²
/// (clamped at 0). This interpolates the *squared* distance with the one quadratic whose Hessian is
/// that of |x − s|², so it is exact whenever the distance from every corner involved is, inside the
/// flattened face, the distance from a point source s (a virtual source in the unfolding) — true
/// away from cut loci in the coarse mesh's flat-cone metric. Linear interpolation of D instead
/// overestimates near the diagonal (d(x, x) would be positive). Near pairs:
///  - same coarse face: the distance inside the flattened face, from the face's own edge lengths
///    (the formula with D replaced by them), not from D;
///  - neighbouring faces: the formula with the corners' D, which for adjacent corners is the
///    unfolded planar distance computed by the marching below (an edge, or the straight line across
///    the diamond of two faces).
///
/// Coarse distances (DistanceOracleOptions::method):
///  - marching (default): fast marching on the coarse intrinsic mesh with exact planar updates —
///    a vertex's value through a face is the distance from the virtual source consistent with its
///    two accepted corners (the two-circle construction in the flattened face), when the straight
///    line from it crosses the opposite edge; otherwise along an edge. In a flat-cone metric that is
///    exact wherever one source image reaches the edge. Nearer the fine heat-method distances than
///    the heat method on the coarse mesh, for coarse vertices and fine pairs alike
///    (docs/measurements.md, "Distance oracle").
///  - heat_method: the heat method on the coarse mesh (cotan operators from its lengths), all
///    sources in blocks of multi-right-hand-side solves (HeatGeodesicSolver::distances_from_each).
///
/// Preconditions: the coarse faces and lengths are a valid intrinsic mesh (positive lengths,
/// triangle inequalities; a Δ-complex: repeated corners allowed); every point names a face in range
/// with non-negative barycentric coordinates summing to 1 (within 1e-6). Distances between coarse
/// components that are not connected are +∞ with marching (farthest-point sampling then visits
/// every component); the heat method needs a connected coarse mesh (it throws NotPositiveDefinite).
/// Queries are const and thread-safe.
#include <array>
#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "fem/operators.h"
#include "ice/mesh.h"

namespace fem {

enum class CoarseDistanceMethod { marching, heat_method };
const char* to_string(CoarseDistanceMethod method);

/// Most 1:4 subdivisions of the coarse mesh the marching takes (DistanceOracleOptions, and
/// fem::ProxyGeodesicOptions): each multiplies the faces by 4 for a shrinking gain
/// (docs/measurements.md, "Marching subdivisions").
constexpr int kMaxMarchingSubdivisions = 4;

struct DistanceOracleOptions {
  CoarseDistanceMethod method = CoarseDistanceMethod::marching;
  /// heat_method only: t = (time_factor · mean coarse edge)², and sources per block of solves.
  double heat_time_factor = 1.0;
  int heat_block_size = 256;
  /// Threads of the precompute and of the many-query calls (0: OpenMP's default, all cores).
  int threads = 0;
  /// marching only: the coarse mesh split 1:4 this many times for the marching between coarse
  /// vertices (as fem::ProxyGeodesicOptions::subdivisions; the queries are unchanged). The default 1
  /// was more accurate than 0 against exact geodesics on every mesh measured, at a moderate cost in
  /// precompute time (docs/measurements.md, "Marching subdivisions").
  int subdivisions = 1;
};

/// Seconds of the precompute.
struct DistanceOracleTimes {
  double coarse_distances = 0;  ///< all coarse pairs (marching or heat method), symmetrised
  double fine_points = 0;       ///< the per-fine-vertex records
};

class DistanceOracle {
 public:
  /// Precomputes the coarse distances (see the file comment). `fine_points`: where each fine vertex
  /// lies on the coarse mesh (ice::fine_to_coarse_map). Throws std::invalid_argument on a face out
  /// of range, bad barycentric coordinates, a non-positive length, a mesh failing
  /// fem::checked_vertex_count, or bad options.
  /// Level 0 of the marching pairs sides by their ends and lengths: `coarse.twin` is not read.
  DistanceOracle(const ice::IntrinsicMesh& coarse, const std::vector<ice::CoarsePoint>& fine_points,
                 const DistanceOracleOptions& options = {});

  Eigen::Index fine_size() const { return static_cast<Eigen::Index>(points_.size()); }
  Eigen::Index coarse_size() const { return coarse_size_; }

  /// Distance between fine vertices u and v (0 when u == v). Preconditions: both in range (unchecked
  /// here; the many-query calls check).
  double distance(Index u, Index v) const;
  /// Distance between two surface points of the coarse mesh (face + barycentric coordinates).
  /// Throws std::invalid_argument on a bad point.
  double distance(const ice::CoarsePoint& x, const ice::CoarsePoint& y) const;
  /// distance(pairs[i][0], pairs[i][1]) for every pair, threaded. Throws std::invalid_argument on an
  /// index out of range.
  Eigen::VectorXd distances(const std::vector<std::array<Index, 2>>& pairs) const;
  /// Distances from one fine vertex to every fine vertex.
  Eigen::VectorXd distances_from(Index source) const;
  /// The dense |rows| × |cols| block between two sets of fine vertices, threaded over rows.
  Eigen::MatrixXf distance_matrix(const std::vector<Index>& rows, const std::vector<Index>& cols) const;
  /// `count` fine vertices by farthest-point sampling in the oracle's distance, starting at `first`:
  /// each next sample is the vertex farthest from those chosen (ties: the smallest index).
  /// Throws std::invalid_argument if count is not in [1, fine_size()] or first is out of range.
  std::vector<Index> farthest_point_samples(Index count, Index first = 0) const;

  /// Whether the coarse faces of u and v share a corner vertex (the pairs reported as "near").
  bool is_near(Index u, Index v) const;
  /// Coarse distance between coarse vertices a and b (symmetrised).
  double coarse_distance(Index a, Index b) const;
  /// Bytes held: the coarse distances, the per-vertex records and the coarse faces and lengths.
  std::size_t memory_bytes() const;
  const DistanceOracleTimes& times() const { return times_; }

 private:
  /// What a query needs of one fine vertex: its coarse face, two barycentric weights (the third is
  /// 1 minus their sum) and the spread V = Σ_{i<k} λ_i λ_k |p_i p_k|². 16 bytes: four to a cache
  /// line, none straddling two, which is what random pair queries on large meshes wait for.
  struct FinePoint {
    Index face;
    float weight0, weight1;
    float spread;
    std::array<double, 3> weights() const {
      return {weight0, weight1, 1.0 - static_cast<double>(weight0) - static_cast<double>(weight1)};
    }
  };
  FinePoint make_point(const ice::CoarsePoint& point) const;
  double squared_distance(const FinePoint& x, const FinePoint& y) const;
  /// Σ_i λ_i D(p_i, b)² − V(x) for every coarse vertex b: the squared distances from x to the coarse
  /// vertices, from which the distance to any fine vertex is one 3-term sum.
  void squared_distances_to_coarse(const FinePoint& x, std::vector<double>& out) const;
  double squared_distance_from_row(const std::vector<double>& row, const FinePoint& x, const FinePoint& y) const;
  int threads() const;

  Eigen::Index coarse_size_ = 0;
  Eigen::Matrix<Index, Eigen::Dynamic, 3, Eigen::RowMajor> faces_;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> squared_lengths_;
  std::vector<float> squared_distances_;  ///< n_c × n_c, row-major, symmetric: D(a, b)²
  std::vector<FinePoint> points_;
  DistanceOracleOptions options_;
  DistanceOracleTimes times_;
};

/// Per-pair relative errors |d − d_ref| / d_ref of the oracle against reference distances from
/// `sources` (column j of `reference`: from sources[j] to every fine vertex), split into far and
/// near pairs (DistanceOracle::is_near); the sources themselves, pairs with d_ref <= 0 and pairs
/// both put at +∞ (in different components) are left out. What the tools and benchmarks report. Throws std::invalid_argument on a reference of the
/// wrong shape.
struct PairErrors {
  std::vector<double> far, near;
  std::vector<double> all() const;  ///< far then near
};
PairErrors relative_pair_errors(const DistanceOracle& oracle, const std::vector<Index>& sources,
                                const Eigen::MatrixXd& reference);

}  // namespace fem
