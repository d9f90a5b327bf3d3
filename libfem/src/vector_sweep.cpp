// The vector heat method's field from a distance (vector_field_from_distance) and the proxy that
// takes the distance from coarse marching (VectorSweepProxy). See fem/vector_fields.h.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "fem/vector_fields.h"

namespace fem {

Eigen::VectorXcd vector_field_from_distance(const VectorHeatOperators& operators, const Eigen::VectorXd& distance,
                                            const std::vector<Index>& vertices, const std::vector<Complex>& vectors,
                                            const DistanceSweepOptions& options, DistanceSweepStats* stats) {
  const ComplexSparseMatrix& C = operators.connection;
  const SparseMatrix& L = operators.laplacian;
  const Eigen::Index n = C.rows();
  if (C.cols() != n || L.rows() != n || L.cols() != n || distance.size() != n)
    throw std::invalid_argument("vector_field_from_distance: L∇ is " + std::to_string(C.rows()) + " x " + std::to_string(C.cols()) +
                                ", L " + std::to_string(L.rows()) + " x " + std::to_string(L.cols()) + ", the distance has " +
                                std::to_string(distance.size()) + " values");
  if (!(operators.time_step > 0) || !(options.time_factor > 0) || !(options.tolerance >= 0) || options.max_passes < 0)
    throw std::invalid_argument("vector_field_from_distance: the time step, time factor and tolerance must be positive");
  if (!C.isCompressed() || !L.isCompressed())
    throw std::invalid_argument("vector_field_from_distance: the operators must be compressed sparse matrices");
  const VectorSources sources = vector_sources(n, vertices, vectors);
  const double tau = options.time_factor * std::sqrt(operators.time_step);

  // Column i of L∇ lists i's neighbours j with L∇(j, i) = conj(L∇(i, j)) = −w_ij conj(r_ij).
  const Index* outer = C.outerIndexPtr();
  const Index* inner = C.innerIndexPtr();
  const Complex* value = C.valuePtr();
  const auto reached = [&](Index v) { return std::isfinite(distance(v)); };
  // r_ij Z_j: the transport carries j's vector into i's frame (|L∇(j, i)| = w_ij).
  const auto transported = [&](Index k, const Complex& z) { return -std::conj(value[k]) / std::abs(value[k]) * z; };
  // The weights of i's mean, per nonzero of its column: w_ij exp(−(d_j − d_min)/τ) (d_min over its
  // neighbours, so the largest is w_ij); 0 on the diagonal, for negative or zero w and for unreached
  // neighbours.
  // w_ij = −L(j, i) is read by walking column i of L beside column i of L∇ (both sorted by row).
  std::vector<double> weight;
  const auto weigh = [&](Index i) {
    weight.assign(static_cast<std::size_t>(outer[i + 1] - outer[i]), 0.0);
    double nearest = std::numeric_limits<double>::infinity();
    for (Index k = outer[i]; k < outer[i + 1]; ++k)
      if (inner[k] != i && reached(inner[k])) nearest = std::min(nearest, distance(inner[k]));
    Index l = L.outerIndexPtr()[i];
    const Index l_end = L.outerIndexPtr()[i + 1];
    for (Index k = outer[i]; k < outer[i + 1]; ++k) {
      const Index j = inner[k];
      while (l < l_end && L.innerIndexPtr()[l] < j) ++l;
      if (j == i || !reached(j) || l == l_end || L.innerIndexPtr()[l] != j) continue;
      const double w = -L.valuePtr()[l];
      if (w > 0 && value[k] != Complex(0)) weight[static_cast<std::size_t>(k - outer[i])] = w * std::exp(-(distance(j) - nearest) / tau);
    }
  };

  // The unknowns: the reached vertices that are not sources, numbered in order of distance, so that
  // a row's entries left of the diagonal are its neighbours nearer the sources.
  std::vector<Index> order;
  order.reserve(static_cast<std::size_t>(n));
  std::vector<char> fixed(static_cast<std::size_t>(n), 0);
  for (Index v = 0; v < n; ++v) {
    if (sources.indicator(v) != 0) fixed[static_cast<std::size_t>(v)] = 1;
    else if (reached(v)) order.push_back(v);
  }
  std::sort(order.begin(), order.end(), [&](Index a, Index b) { return distance(a) < distance(b) || (distance(a) == distance(b) && a < b); });
  std::vector<Index> position(static_cast<std::size_t>(n), -1);
  for (std::size_t p = 0; p < order.size(); ++p) position[static_cast<std::size_t>(order[p])] = static_cast<Index>(p);

  Eigen::VectorXcd source_direction = Eigen::VectorXcd::Zero(n);
  Eigen::VectorXd source_magnitude = Eigen::VectorXd::Zero(n);
  for (Index v = 0; v < n; ++v) {
    if (!fixed[static_cast<std::size_t>(v)]) continue;
    const double length = std::abs(sources.vectors(v));
    source_direction(v) = length > 0 ? sources.vectors(v) / length : Complex(0);  // opposite vectors at one vertex cancel
    source_magnitude(v) = sources.magnitudes(v) / sources.indicator(v);
  }
  // Row p of the means, Z_p = b_p + Σ_q a_pq Z_q over unknown neighbours q (a_pq = w_pq r_pq, the
  // weights of a row summing to 1 with its sources'), stored by rows in distance order, and the same
  // for m with the weights alone when the sources' magnitudes differ (else m is their magnitude).
  const bool one_magnitude = sources.min_magnitude == sources.max_magnitude;
  const std::size_t unknowns = order.size();
  std::vector<std::size_t> row_start(unknowns + 1, 0);
  std::vector<Index> column;
  std::vector<Complex> coefficient;
  std::vector<double> row_weight;  // per entry, for m and for the first sweep's partial sums
  std::vector<double> source_weight(unknowns, 0.0);  // the sources' share of each row
  Eigen::VectorXcd rhs = Eigen::VectorXcd::Zero(static_cast<Eigen::Index>(unknowns));
  Eigen::VectorXd magnitude_rhs = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(unknowns));
  column.reserve(static_cast<std::size_t>(C.nonZeros()));
  coefficient.reserve(static_cast<std::size_t>(C.nonZeros()));
  row_weight.reserve(static_cast<std::size_t>(C.nonZeros()));
  for (std::size_t p = 0; p < unknowns; ++p) {
    const Index i = order[p];
    weigh(i);
    double total = 0;
    for (const double w : weight) total += w;
    for (Index k = outer[i]; k < outer[i + 1] && total > 0; ++k) {
      const double w = weight[static_cast<std::size_t>(k - outer[i])] / total;
      if (w == 0) continue;
      const Index j = inner[k];
      if (fixed[static_cast<std::size_t>(j)]) {
        rhs(static_cast<Eigen::Index>(p)) += w * transported(k, source_direction(j));
        magnitude_rhs(static_cast<Eigen::Index>(p)) += w * source_magnitude(j);
        source_weight[p] += w;
      } else {
        column.push_back(position[static_cast<std::size_t>(j)]);
        coefficient.push_back(w * transported(k, Complex(1)));
        row_weight.push_back(w);
      }
    }
    row_start[p + 1] = column.size();
  }

  Eigen::VectorXcd direction = Eigen::VectorXcd::Zero(static_cast<Eigen::Index>(unknowns));
  Eigen::VectorXd magnitude = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(unknowns), sources.max_magnitude);
  // Row p's mean, into direction(p) and magnitude(p); returns how far they moved. `upwind_only`: over
  // its sources and its neighbours nearer them (q < p) alone, renormalised over those — the first
  // sweep, the means' heavy terms, so that the passes start near the solution.
  const auto update = [&](std::size_t p, auto upwind_only) {
    Complex sum = rhs(static_cast<Eigen::Index>(p));
    double sum_magnitude = magnitude_rhs(static_cast<Eigen::Index>(p)), total = source_weight[p];
    for (std::size_t e = row_start[p]; e < row_start[p + 1]; ++e) {
      const Index q = column[e];
      if constexpr (decltype(upwind_only)::value)
        if (static_cast<std::size_t>(q) >= p) continue;
      sum += coefficient[e] * direction(q);
      if (!one_magnitude) sum_magnitude += row_weight[e] * magnitude(q);
      if constexpr (decltype(upwind_only)::value) total += row_weight[e];
    }
    if constexpr (decltype(upwind_only)::value) {
      if (total == 0) return 0.0;
      sum /= total;
      sum_magnitude /= total;
    }
    double change = std::abs(sum - direction(static_cast<Eigen::Index>(p)));
    direction(static_cast<Eigen::Index>(p)) = sum;
    if (!one_magnitude) {
      change = std::max(change, std::abs(sum_magnitude - magnitude(static_cast<Eigen::Index>(p))) / sources.max_magnitude);
      magnitude(static_cast<Eigen::Index>(p)) = sum_magnitude;
    }
    return change;
  };
  for (std::size_t p = 0; p < unknowns; ++p) update(p, std::true_type{});
  // Gauss–Seidel passes in the same order.
  DistanceSweepStats done;
  while (done.passes < options.max_passes) {
    double change = 0;
    for (std::size_t p = 0; p < unknowns; ++p) change = std::max(change, update(p, std::false_type{}));
    ++done.passes;
    done.last_change = change;
    if (change <= options.tolerance) break;
  }
  if (stats) *stats = done;

  Eigen::VectorXcd field = Eigen::VectorXcd::Zero(n);
  for (Index v = 0; v < n; ++v) {
    if (fixed[static_cast<std::size_t>(v)]) {
      field(v) = source_direction(v) * source_magnitude(v);
      continue;
    }
    const Index p = position[static_cast<std::size_t>(v)];
    if (p < 0) continue;
    const double length = std::abs(direction(p));
    if (length > 0) field(v) = direction(p) * (magnitude(p) / length);
  }
  return field;
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
  return vector_field_from_distance(operators_, distances_.distance(vertices), vertices, vectors, options_, stats);
}

}  // namespace fem
