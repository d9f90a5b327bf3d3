// The vector heat method's field from a distance (vector_field_from_distance) and the proxy that
// takes the distance from coarse marching (VectorSweepProxy). See fem/vector_fields.h.
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include <type_traits>

#include <Eigen/SparseCholesky>

#include "fem/cholesky.h"
#include "fem/vector_fields.h"

namespace fem {
namespace {

// Scaled values farther than this (in e) from the least are left to the passes by the coarse
// correction: its residuals and corrections are unscaled by exp(∓(e − least)), which must stay in
// floating range (exp(−708) is the least normal double).
constexpr double kCoarseWindow = 600;
// Scale ratios between neighbouring rows (and a coarse basis entry's within its patch) beyond
// e^±200 are clamped.
constexpr double kLargestExponent = 200;

// A Galerkin coarse-grid correction of one of the sweep's systems A x = b (A Hermitian positive
// definite, x kept scaled: x̂_p = exp(s_p) x_p, s_p = e_p − least). Why: a relative error that is
// the same over a region, x = (1 + ε) x*, leaves every row there satisfied but for the region's
// rim, so the passes remove it only by carrying it out of the region a vertex per pass (the dragon
// scan kept 12.7° after 50 passes). The basis is made of such relative errors: column c of the
// coarse space's P times the first pass's x̂⁰ (the solution's shape, its decay across a patch
// included) times exp(s̄_c − s_p), s̄_c the P-weighted mean of s over the column, so that every
// basis entry is of order one. The coarse matrix BᴴAB is Hermitian positive definite (a Galerkin
// product of A), so the correction never increases A's energy norm of the error, unlike the
// Petrov–Galerkin correction in the scaled variables that diverged on cow (docs/measurements.md,
// "Distance sweep: passes and coarse correction"); and its unknowns are relative, so that the far
// field is not lost in the near field's round-off, as it was with a basis that ignores the
// solution's decay.
template <class Scalar>
class CoarseCorrection {
 public:
  using Vector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  using Sparse = Eigen::SparseMatrix<Scalar, Eigen::ColMajor, Index>;

  // `A` unscaled, rows and columns in sweep order; `order[p]` the vertex of row p, its row of P
  // (by rows, n × n_c); `shape` the first pass's x̂; `shift` s per row.
  CoarseCorrection(const Sparse& A, const SweepCoarseSpace& P, const std::vector<Index>& order, const Vector& shape,
                   const Eigen::VectorXd& shift, Eigen::Index supernodal_from) {
    const Eigen::Index rows = A.rows(), coarse = P.cols();
    const auto used_row = [&](Eigen::Index p) { return shift(p) <= kCoarseWindow && shape(p) != Scalar(0); };
    std::vector<double> shift_sum(static_cast<std::size_t>(coarse), 0.0), weight(static_cast<std::size_t>(coarse), 0.0);
    for (Eigen::Index p = 0; p < rows; ++p)
      if (used_row(p))
        for (SweepCoarseSpace::InnerIterator it(P, order[static_cast<std::size_t>(p)]); it; ++it) {
          shift_sum[static_cast<std::size_t>(it.col())] += it.value() * shift(p);
          weight[static_cast<std::size_t>(it.col())] += it.value();
        }
    std::vector<Index> column(static_cast<std::size_t>(coarse), -1);
    Index columns = 0;
    for (std::size_t c = 0; c < column.size(); ++c)
      if (weight[c] > 0) column[c] = columns++;
    std::vector<Eigen::Triplet<Scalar, Index>> entries;
    for (Eigen::Index p = 0; p < rows; ++p)
      if (used_row(p))
        for (SweepCoarseSpace::InnerIterator it(P, order[static_cast<std::size_t>(p)]); it; ++it) {
          const std::size_t c = static_cast<std::size_t>(it.col());
          if (it.value() == 0) continue;
          const double exponent = std::clamp(shift_sum[c] / weight[c] - shift(p), -kLargestExponent, kLargestExponent);
          entries.emplace_back(static_cast<Index>(p), column[c], it.value() * std::exp(exponent) * shape(p));
        }
    unscale_ = Vector::Zero(rows);
    rescale_ = Vector::Zero(rows);
    for (Eigen::Index p = 0; p < rows; ++p)
      if (shift(p) <= kCoarseWindow) unscale_(p) = std::exp(-shift(p)), rescale_(p) = std::exp(shift(p));
    basis_.resize(rows, columns);
    basis_.setFromTriplets(entries.begin(), entries.end());
    Sparse coarse_matrix = Sparse(basis_.adjoint()) * Sparse(A * basis_);
    // Two columns of P can be (nearly) dependent on the rows the window keeps (a coarse vertex seen
    // by one fine vertex); a relative 1e-8 on the diagonal keeps the factorisation definite.
    for (Eigen::Index c = 0; c < coarse_matrix.outerSize(); ++c)
      for (typename Sparse::InnerIterator it(coarse_matrix, c); it; ++it)
        if (it.row() == c) it.valueRef() *= 1 + 1e-8;
    // Small coarse systems by Eigen's simplicial factorisation: a correction is one solve per pass,
    // where CHOLMOD's supernodal solve spent most of its time in the BLAS threads' waits (face_scan,
    // ~5,000 unknowns: 27 ms a correction against ~5 ms); large ones by CHOLMOD, whose supernodes
    // factorise them several times faster (spot Loop ×3 at 5 %, 316,000 unknowns: 42 s a solve
    // against 120 s; dragon_vrip_bin's 84,393 take as long either way, 9.5–9.8 s).
    if (coarse_matrix.rows() < supernodal_from) {
      simplicial_.emplace();
      simplicial_->compute(coarse_matrix);
      usable_ = simplicial_->info() == Eigen::Success;
    } else {
      try {
        supernodal_.emplace(coarse_matrix);
        usable_ = true;
      } catch (const std::runtime_error&) {  // NotPositiveDefinite, or CHOLMOD out of memory
        usable_ = false;
      }
    }
  }
  // False if the Galerkin matrix could not be factorised (not seen on the 63 meshes measured; the
  // passes then go on alone, and DistanceSweepStats::coarse_corrections says so).
  bool usable() const { return usable_; }
  bool supernodal() const { return supernodal_.has_value(); }

  // x̂ += the correction for the scaled residual r̂ = b̂ − Â x̂.
  void apply(const Vector& scaled_residual, Vector& x) const {
    const Vector coarse_residual = basis_.adjoint() * scaled_residual.cwiseProduct(unscale_);
    const Vector coarse_correction =
        simplicial_ ? Vector(simplicial_->solve(coarse_residual)) : Vector(supernodal_->solve(coarse_residual));
    x += (basis_ * coarse_correction).cwiseProduct(rescale_);
  }

 private:
  Sparse basis_;
  // exp(∓s_p) within the window, 0 beyond it (those rows are left to the passes).
  Vector unscale_, rescale_;
  std::optional<Eigen::SimplicialLDLT<Sparse, Eigen::Lower, Eigen::AMDOrdering<Index>>> simplicial_;
  std::optional<std::conditional_t<std::is_same_v<Scalar, Complex>, ComplexCholeskySolver, CholeskySolver>> supernodal_;
  bool usable_ = false;
};

}  // namespace

Eigen::VectorXcd vector_field_from_distance(const VectorHeatOperators& operators, const Eigen::VectorXd& distance,
                                            const std::vector<Index>& vertices, const std::vector<Complex>& vectors,
                                            const DistanceSweepOptions& options, DistanceSweepStats* stats,
                                            const SweepCoarseSpace* coarse_space) {
  const ComplexSparseMatrix& C = operators.connection;
  const SparseMatrix& L = operators.laplacian;
  const SparseMatrix& M = operators.mass;
  const Eigen::Index n = C.rows();
  if (C.cols() != n || L.rows() != n || L.cols() != n || M.rows() != n || M.cols() != n || distance.size() != n)
    throw std::invalid_argument("vector_field_from_distance: L∇ is " + std::to_string(C.rows()) + " x " + std::to_string(C.cols()) +
                                ", L " + std::to_string(L.rows()) + " x " + std::to_string(L.cols()) + ", M " +
                                std::to_string(M.rows()) + " x " + std::to_string(M.cols()) + ", the distance has " +
                                std::to_string(distance.size()) + " values");
  if (!(operators.time_step > 0) || !(options.tolerance >= 0) || options.max_passes < 0 || options.coarse_correction_interval < 0 ||
      options.supernodal_from < 0)
    throw std::invalid_argument(
        "vector_field_from_distance: the time step must be positive, the tolerance, passes, coarse-correction interval and supernodal size not negative");
  if (coarse_space && coarse_space->rows() != n)
    throw std::invalid_argument("vector_field_from_distance: the coarse space has " + std::to_string(coarse_space->rows()) +
                                " rows for " + std::to_string(n) + " vertices");
  if (!C.isCompressed() || !L.isCompressed())
    throw std::invalid_argument("vector_field_from_distance: the operators must be compressed sparse matrices");
  const VectorSources sources = vector_sources(n, vertices, vectors);
  const double t = operators.time_step;
  const double tau = std::sqrt(t);
  const auto reached = [&](Index v) { return std::isfinite(distance(v)); };
  double nearest_source = std::numeric_limits<double>::infinity();
  for (const Index v : vertices) {
    if (!reached(v))
      throw std::invalid_argument("vector_field_from_distance: source vertex " + std::to_string(v) + " has no finite distance");
    nearest_source = std::min(nearest_source, distance(v));
  }

  // The unknowns: the reached vertices in order of distance, sources included (their rows carry
  // the right-hand sides), so that a row's entries left of the diagonal are its neighbours nearer
  // the sources.
  std::vector<Index> order;
  order.reserve(static_cast<std::size_t>(n));
  for (Index v = 0; v < n; ++v)
    if (reached(v)) order.push_back(v);
  std::sort(order.begin(), order.end(), [&](Index a, Index b) { return distance(a) < distance(b) || (distance(a) == distance(b) && a < b); });
  std::vector<Index> position(static_cast<std::size_t>(n), -1);
  for (std::size_t p = 0; p < order.size(); ++p) position[static_cast<std::size_t>(order[p])] = static_cast<Index>(p);

  // Each vertex's value is kept as exp(−e_i) times a value of order one, e_i the log of the kernel's
  // decay, so that the far field stays in floating range (the direct solve's underflows: see the
  // header). The first pass finds e: each vertex from its neighbours nearer the sources, e_i from the
  // scalar kernel φ (positive, where Y can cancel), counting each neighbour farther away (not reached
  // yet) as the vertex itself times the decay the distance predicts, so that the first pass starts
  // near the solution instead of losing a factor at every step away from the sources.
  // Column i of L∇ lists i's neighbours j with L∇(j, i) = conj(L∇(i, j)); L's column is walked beside
  // it (both sorted by row). `visit(i, f)` calls f(j, L∇(i, j), L(i, j)) for each reached neighbour
  // and returns the diagonals of M + tL∇ and M + tL at i.
  const Index* outer = C.outerIndexPtr();
  const Index* inner = C.innerIndexPtr();
  const Complex* value = C.valuePtr();
  const Eigen::VectorXd lumped_mass = M.diagonal();
  const auto visit = [&](Index i, auto&& neighbour) {
    double vector_diagonal = 0, laplacian_diagonal = 0;
    Index l = L.outerIndexPtr()[i];
    const Index l_end = L.outerIndexPtr()[i + 1];
    for (Index k = outer[i]; k < outer[i + 1]; ++k) {
      const Index j = inner[k];
      while (l < l_end && L.innerIndexPtr()[l] < j) ++l;
      const double laplacian_entry = l < l_end && L.innerIndexPtr()[l] == j ? L.valuePtr()[l] : 0.0;
      if (j == i) {
        vector_diagonal = value[k].real();
        laplacian_diagonal = laplacian_entry;
      } else if (reached(j)) {
        neighbour(j, std::conj(value[k]), laplacian_entry);
      }
    }
    const double vector_row = lumped_mass(i) + t * vector_diagonal, scalar_row = lumped_mass(i) + t * laplacian_diagonal;
    if (!(vector_row > 0) || !(scalar_row > 0))
      throw std::invalid_argument("vector_field_from_distance: M + tL∇ or M + tL has a non-positive diagonal at vertex " + std::to_string(i));
    return std::pair<double, double>(vector_row, scalar_row);
  };
  const bool one_magnitude = sources.min_magnitude == sources.max_magnitude;
  const std::size_t unknowns = order.size();
  const Eigen::Index size = static_cast<Eigen::Index>(unknowns);
  Eigen::VectorXd log_scale(size);  // e per row
  Eigen::VectorXcd directions = Eigen::VectorXcd::Zero(size);
  Eigen::VectorXd magnitudes = Eigen::VectorXd::Zero(size), indicator = Eigen::VectorXd::Zero(size);
  const auto ratio = [&](double exponent) { return std::exp(std::clamp(exponent, -kLargestExponent, kLargestExponent)); };
  std::vector<std::size_t> unscaled;
  for (std::size_t p = 0; p < unknowns; ++p) {
    const Index i = order[p];
    const Eigen::Index row = static_cast<Eigen::Index>(p);
    // The terms factor exp(−least), least the smallest e among the nearer neighbours (and 0, the
    // sources' scale, on a source's row).
    double least = sources.indicator(i) != 0 ? 0.0 : std::numeric_limits<double>::infinity();
    visit(i, [&](Index j, Complex, double) {
      const Index q = position[static_cast<std::size_t>(j)];
      if (q < static_cast<Index>(p) && !std::isnan(log_scale(q))) least = std::min(least, log_scale(q));
    });
    Complex sum = 0;
    double sum_magnitude = 0, sum_indicator = 0, farther = 0, scalar_farther = 0;
    if (sources.indicator(i) != 0) {  // least ≤ 0 here; elsewhere exp(least) can overflow (e > 709)
      sum = sources.vectors(i) * std::exp(least);
      sum_magnitude = sources.magnitudes(i) * std::exp(least);
      sum_indicator = sources.indicator(i) * std::exp(least);
    }
    const auto [vector_row, scalar_row] = visit(i, [&](Index j, Complex connection, double laplacian) {
      const Index q = position[static_cast<std::size_t>(j)];
      if (q < static_cast<Index>(p)) {
        if (std::isnan(log_scale(q))) return;  // not scaled yet, and zero: the passes fill it
        const double decay = ratio(-(log_scale(q) - least));
        sum -= t * connection * decay * directions(q);
        sum_magnitude -= t * laplacian * decay * magnitudes(q);
        sum_indicator -= t * laplacian * decay * indicator(q);
      } else {
        const double decay = std::exp(-(distance(j) - distance(i)) / tau);  // ≤ 1: j is no nearer
        farther += t * std::abs(connection) * decay;
        scalar_farther += std::max(-t * laplacian * decay, 0.0);
      }
    });
    // With positive weights the first diagonals stay ≥ M_i; otherwise the passes' are kept.
    sum /= vector_row - farther > 0 ? vector_row - farther : vector_row;
    const double first_scalar = scalar_row - scalar_farther > 0 ? scalar_row - scalar_farther : scalar_row;
    sum_magnitude /= first_scalar;
    sum_indicator /= first_scalar;
    if (std::isfinite(least) && sum_indicator > 0 && std::isfinite(sum_indicator)) {
      log_scale(row) = least - std::log(sum_indicator);
      directions(row) = sum / sum_indicator;
      magnitudes(row) = sum_magnitude / sum_indicator;
      indicator(row) = 1;
    } else {  // no nearer neighbour, or a kernel not positive here: scaled below; the passes fill it
      log_scale(row) = std::numeric_limits<double>::quiet_NaN();
      unscaled.push_back(p);
    }
  }
  // A vertex the first pass could not scale (a local minimum of the distance among its neighbours,
  // as a distance prolonged from a coarse mesh has on noisy scans) takes its neighbours' level: its
  // kernel is of their order, while the distance's own decay can have drifted from the kernel's by
  // more than the ratios' clamp over a long mesh.
  for (const bool last_round : {false, true})
    for (const std::size_t p : unscaled) {
      const Eigen::Index row = static_cast<Eigen::Index>(p);
      if (!std::isnan(log_scale(row))) continue;
      double level = std::numeric_limits<double>::infinity();
      visit(order[p], [&](Index j, Complex, double) {
        const double e = log_scale(position[static_cast<std::size_t>(j)]);
        if (!std::isnan(e)) level = std::min(level, e);
      });
      if (std::isfinite(level)) log_scale(row) = level;
      else if (last_round) log_scale(row) = (distance(order[p]) - nearest_source) / tau;  // no scaled neighbour
    }

  // Row p of the scaled systems, Ŷ_i = exp(e_i) Y_i: Ŷ_i = (exp(e_i) Y₀_i − t Σ_j L∇(i, j) exp(e_i − e_j) Ŷ_j)
  // / (M_i + t L∇(i, i)), the same with L for the scalars. Stored by rows in distance order: per
  // entry the neighbour's row, −t L∇(i, j) exp(e_i − e_j) and −t L(i, j) exp(e_i − e_j).
  std::vector<std::size_t> row_start(unknowns + 1, 0);
  std::vector<Index> column;
  std::vector<Complex> coefficient;
  std::vector<double> scalar_coefficient;
  Eigen::VectorXd diagonal(size), scalar_diagonal(size);
  Eigen::VectorXcd rhs(size);
  Eigen::VectorXd magnitude_rhs(size), indicator_rhs(size);
  const bool corrected = coarse_space && options.coarse_correction_interval > 0 && options.max_passes > 0;
  std::vector<Eigen::Triplet<Complex, Index>> vector_entries;  // the unscaled systems, for the coarse correction
  std::vector<Eigen::Triplet<double, Index>> scalar_entries;
  if (corrected) vector_entries.reserve(static_cast<std::size_t>(C.nonZeros()));
  if (corrected && !one_magnitude) scalar_entries.reserve(static_cast<std::size_t>(C.nonZeros()));
  column.reserve(static_cast<std::size_t>(C.nonZeros()));
  coefficient.reserve(static_cast<std::size_t>(C.nonZeros()));
  scalar_coefficient.reserve(static_cast<std::size_t>(C.nonZeros()));
  for (std::size_t p = 0; p < unknowns; ++p) {
    const Index i = order[p];
    const Eigen::Index row = static_cast<Eigen::Index>(p);
    std::tie(diagonal(row), scalar_diagonal(row)) = visit(i, [&](Index j, Complex connection, double laplacian) {
      const Index q = position[static_cast<std::size_t>(j)];
      const double decay = ratio(log_scale(row) - log_scale(q));
      column.push_back(q);
      coefficient.push_back(-t * connection * decay);
      scalar_coefficient.push_back(-t * laplacian * decay);
      if (corrected) {
        vector_entries.emplace_back(static_cast<Index>(p), q, t * connection);
        if (!one_magnitude) scalar_entries.emplace_back(static_cast<Index>(p), q, t * laplacian);
      }
    });
    if (corrected) {
      vector_entries.emplace_back(static_cast<Index>(p), static_cast<Index>(p), diagonal(row));
      if (!one_magnitude) scalar_entries.emplace_back(static_cast<Index>(p), static_cast<Index>(p), scalar_diagonal(row));
    }
    row_start[p + 1] = column.size();
    const double source_scale = sources.indicator(i) != 0 ? ratio(log_scale(row)) : 0.0;
    rhs(row) = sources.vectors(i) * source_scale;
    magnitude_rhs(row) = sources.magnitudes(i) * source_scale;
    indicator_rhs(row) = sources.indicator(i) * source_scale;
  }

  Eigen::VectorXd direction_length = directions.cwiseAbs();
  // Row p's right-hand side minus its off-diagonal terms, in each system, and the size of the vector
  // row's terms (the passes' measure of change).
  struct RowSums {
    Complex vector;
    double size, magnitude, indicator;
  };
  const auto row_sums = [&](std::size_t p) {
    const Eigen::Index row = static_cast<Eigen::Index>(p);
    RowSums sums{rhs(row), std::abs(rhs(row)), magnitude_rhs(row), indicator_rhs(row)};
    for (std::size_t e = row_start[p]; e < row_start[p + 1]; ++e) {
      const Eigen::Index q = column[e];
      sums.vector += coefficient[e] * directions(q);
      // |L(i, j)| = |L∇(i, j)| (one cotan weight): the real coefficient's size, no square root here.
      sums.size += std::abs(scalar_coefficient[e]) * direction_length(q);
      if (!one_magnitude) {
        sums.magnitude += scalar_coefficient[e] * magnitudes(q);
        sums.indicator += scalar_coefficient[e] * indicator(q);
      }
    }
    return sums;
  };
  // Row p's update; returns how far it moved relative to the size of the terms it sums (not to the
  // result, which cancels to zero where vectors from two sides meet).
  const auto update = [&](std::size_t p) {
    const Eigen::Index row = static_cast<Eigen::Index>(p);
    auto [sum, size, sum_magnitude, sum_indicator] = row_sums(p);
    sum /= diagonal(row);
    size /= diagonal(row);
    double change = size > 0 ? std::abs(sum - directions(row)) / size : 0.0;
    directions(row) = sum;
    direction_length(row) = std::abs(sum);
    if (!one_magnitude) {
      sum_magnitude /= scalar_diagonal(row);
      sum_indicator /= scalar_diagonal(row);
      if (sum_indicator != 0) {
        change = std::max(change, std::abs(sum_indicator - indicator(row)) / std::abs(sum_indicator));
        if (sum_magnitude != 0) change = std::max(change, std::abs(sum_magnitude - magnitudes(row)) / std::abs(sum_magnitude));
      }
      magnitudes(row) = sum_magnitude;
      indicator(row) = sum_indicator;
    }
    return change;
  };
  // The coarse corrections (see CoarseCorrection), built from the first pass's values.
  std::optional<CoarseCorrection<Complex>> vector_correction;
  std::optional<CoarseCorrection<double>> magnitude_correction, indicator_correction;
  if (corrected) {
    const Eigen::VectorXd shift = log_scale.array() - log_scale.minCoeff();
    ComplexSparseMatrix vector_system(size, size);
    vector_system.setFromTriplets(vector_entries.begin(), vector_entries.end());
    vector_entries = {};
    vector_correction.emplace(vector_system, *coarse_space, order, directions, shift, options.supernodal_from);
    if (!one_magnitude) {
      SparseMatrix scalar_system(size, size);
      scalar_system.setFromTriplets(scalar_entries.begin(), scalar_entries.end());
      scalar_entries = {};
      magnitude_correction.emplace(scalar_system, *coarse_space, order, magnitudes, shift, options.supernodal_from);
      indicator_correction.emplace(scalar_system, *coarse_space, order, indicator, shift, options.supernodal_from);
    }
    if (!vector_correction->usable() || (!one_magnitude && (!magnitude_correction->usable() || !indicator_correction->usable())))
      vector_correction.reset();
  }
  DistanceSweepStats done;
  done.coarse_supernodal = vector_correction && vector_correction->supernodal();
  // One correction of each system from its scaled residual b̂ − Âx̂.
  const auto correct = [&]() {
    Eigen::VectorXcd vector_residual(size);
    Eigen::VectorXd magnitude_residual(one_magnitude ? 0 : size), indicator_residual(one_magnitude ? 0 : size);
    for (std::size_t p = 0; p < unknowns; ++p) {
      const Eigen::Index row = static_cast<Eigen::Index>(p);
      const RowSums sums = row_sums(p);
      vector_residual(row) = sums.vector - diagonal(row) * directions(row);
      if (!one_magnitude) {
        magnitude_residual(row) = sums.magnitude - scalar_diagonal(row) * magnitudes(row);
        indicator_residual(row) = sums.indicator - scalar_diagonal(row) * indicator(row);
      }
    }
    vector_correction->apply(vector_residual, directions);
    direction_length = directions.cwiseAbs();
    if (!one_magnitude) {
      magnitude_correction->apply(magnitude_residual, magnitudes);
      indicator_correction->apply(indicator_residual, indicator);
    }
    ++done.coarse_corrections;
  };
  // Gauss–Seidel passes in the same order, a coarse correction before every interval-th.
  while (done.passes < options.max_passes) {
    if (vector_correction && done.passes % options.coarse_correction_interval == 0) correct();
    double change = 0;
    for (std::size_t p = 0; p < unknowns; ++p) change = std::max(change, update(p));
    ++done.passes;
    done.last_change = change;
    if (change <= options.tolerance) {
      done.settled = true;
      break;
    }
  }
  if (stats) *stats = done;

  // The field as the fine method combines it (the common scale s cancels in Y/|Y| and u/φ).
  VectorHeatParts parts{Eigen::VectorXcd::Zero(n), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n)};
  for (std::size_t p = 0; p < unknowns; ++p) {
    const Index v = order[p];
    const Eigen::Index row = static_cast<Eigen::Index>(p);
    parts.directions(v) = directions(row);
    // One magnitude: u/φ is that magnitude wherever φ ≠ 0, so the scalars are not solved.
    parts.magnitudes(v) = one_magnitude ? sources.max_magnitude : magnitudes(row);
    parts.indicator(v) = one_magnitude ? 1.0 : indicator(row);
  }
  return vector_heat_field(parts, sources.min_magnitude, sources.max_magnitude);
}

VectorSweepProxy::VectorSweepProxy(VectorHeatOperators fine_operators, ProxyGeodesicSolver distances, DistanceSweepOptions options)
    : operators_(std::move(fine_operators)), distances_(std::move(distances)), options_(options) {
  if (operators_.connection.rows() != distances_.fine_size() || operators_.laplacian.rows() != distances_.fine_size())
    throw std::invalid_argument("VectorSweepProxy: the fine operators have " + std::to_string(operators_.connection.rows()) +
                                " rows, the distance solver's fine mesh " + std::to_string(distances_.fine_size()) + " vertices");
  operators_.connection.makeCompressed();
  operators_.laplacian.makeCompressed();
}

Eigen::VectorXcd VectorSweepProxy::interpolate(const std::vector<Index>& vertices, const std::vector<Complex>& vectors,
                                               DistanceSweepStats* stats) const {
  vector_sources(distances_.fine_size(), vertices, vectors);  // the same refusals before the distance
  return vector_field_from_distance(operators_, distances_.distance(vertices), vertices, vectors, options_, stats,
                                    &distances_.prolongation());
}

}  // namespace fem
