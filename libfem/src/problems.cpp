#include "fem/problems.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "fem/topology.h"

namespace fem {
namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

void require_square(const SparseMatrix& A, Eigen::Index n, const char* what) {
  if (A.rows() != n || A.cols() != n) throw std::invalid_argument(std::string(what) + ": size mismatch");
}

}  // namespace

// ---- ConstrainedSolver ------------------------------------------------------------------------------

ConstrainedSolver::ConstrainedSolver(const SparseMatrix& A, std::vector<Index> constrained, CholeskyOrdering ordering)
    : size_(A.rows()), constrained_(std::move(constrained)) {
  factor_.set_ordering(ordering);
  if (A.rows() != A.cols()) throw std::invalid_argument("ConstrainedSolver: matrix must be square");
  // Index maps: free_[i] is i's position among the free unknowns, or -(c+1) for constrained index c
  // in the caller's order (values come in that order).
  free_.assign(static_cast<std::size_t>(size_), 0);
  for (std::size_t c = 0; c < constrained_.size(); ++c) {
    const Index i = constrained_[c];
    if (i < 0 || i >= size_)
      throw std::invalid_argument("ConstrainedSolver: constrained index " + std::to_string(i) + " out of range");
    if (free_[static_cast<std::size_t>(i)] != 0)
      throw std::invalid_argument("ConstrainedSolver: constrained index " + std::to_string(i) + " given twice");
    free_[static_cast<std::size_t>(i)] = -static_cast<int>(c) - 1;
  }
  int free_count = 0;
  for (int& index : free_)
    if (index == 0) index = free_count++;

  Triplets free_block, coupling;
  for (Eigen::Index j = 0; j < A.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(A, j); it; ++it) {
      const int row = free_[static_cast<std::size_t>(it.row())], col = free_[static_cast<std::size_t>(it.col())];
      if (row < 0) continue;  // constrained rows are replaced by x_C = values
      if (col >= 0) free_block.emplace_back(row, col, it.value());
      else coupling.emplace_back(row, -col - 1, it.value());
    }
  SparseMatrix A_FF(free_count, free_count);
  A_FF.setFromTriplets(free_block.begin(), free_block.end());
  free_constrained_coupling_.resize(free_count, static_cast<Eigen::Index>(constrained_.size()));
  free_constrained_coupling_.setFromTriplets(coupling.begin(), coupling.end());
  if (free_count > 0) factor_.compute(A_FF);
}

namespace {

// The rows of `full` at free indices, in free order (free[i] >= 0: the free index of i).
template <class Dense>
Dense free_rows(const Dense& full, const std::vector<Index>& free, Eigen::Index free_count) {
  Dense out(free_count, full.cols());
  for (Eigen::Index i = 0; i < full.rows(); ++i)
    if (free[static_cast<std::size_t>(i)] >= 0) out.row(free[static_cast<std::size_t>(i)]) = full.row(i);
  return out;
}

// The full-length solution: free rows from `free_solution`, constrained index i from row
// -free[i] - 1 of `values`.
template <class Dense>
Dense full_rows(const Dense& free_solution, const Dense& values, const std::vector<Index>& free) {
  Dense x(static_cast<Eigen::Index>(free.size()), free_solution.cols());
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const int index = free[static_cast<std::size_t>(i)];
    x.row(i) = index >= 0 ? free_solution.row(index) : values.row(-index - 1);
  }
  return x;
}

}  // namespace

Eigen::VectorXd ConstrainedSolver::solve(const Eigen::VectorXd& b, const Eigen::VectorXd& constrained_values) const {
  if (b.size() != size_) throw std::invalid_argument("ConstrainedSolver::solve: rhs has the wrong size");
  const auto constrained_count = static_cast<Eigen::Index>(constrained_.size());
  const Eigen::VectorXd values =
      constrained_values.size() == 0 ? Eigen::VectorXd::Zero(constrained_count) : constrained_values;
  if (values.size() != constrained_count)
    throw std::invalid_argument("ConstrainedSolver::solve: one value per constrained index expected");

  Eigen::VectorXd free_rhs = free_rows(b, free_, factor_.rows());
  if (constrained_count > 0) free_rhs -= free_constrained_coupling_ * values;
  const Eigen::VectorXd free_solution = free_rhs.size() > 0 ? factor_.solve(free_rhs) : free_rhs;
  return full_rows(free_solution, values, free_);
}

Eigen::MatrixXd ConstrainedSolver::solve_multiple(const Eigen::MatrixXd& B, const Eigen::MatrixXd& constrained_values) const {
  if (B.rows() != size_) throw std::invalid_argument("ConstrainedSolver::solve_multiple: rhs has the wrong size");
  const auto constrained_count = static_cast<Eigen::Index>(constrained_.size());
  const Eigen::MatrixXd values = constrained_values.size() == 0 ? Eigen::MatrixXd::Zero(constrained_count, B.cols()).eval()
                                                                : constrained_values;
  if (values.rows() != constrained_count || values.cols() != B.cols())
    throw std::invalid_argument("ConstrainedSolver::solve_multiple: one row of values per constrained index, one column per rhs expected");
  Eigen::MatrixXd free_rhs = free_rows(B, free_, factor_.rows());
  if (constrained_count > 0) free_rhs -= free_constrained_coupling_ * values;
  const Eigen::MatrixXd free_solution = free_rhs.rows() > 0 ? factor_.solve_multiple(free_rhs) : free_rhs;
  return full_rows(free_solution, values, free_);
}

// ---- PoissonSolver ----------------------------------------------------------------------------------

PoissonSolver::PoissonSolver(const SparseMatrix& laplacian, const SparseMatrix& mass,
                             std::vector<Index> constrained, ComponentLabels components, bool zero_mean,
                             std::optional<PoissonMultigrid> multigrid, CholeskyOrdering ordering)
    : mass_(mass), mass_of_one_(mass * Eigen::VectorXd::Ones(mass.cols())), zero_mean_(zero_mean),
      components_(std::move(components)) {
  require_square(mass, laplacian.rows(), "PoissonSolver: mass and Laplacian");
  if (multigrid) {
    multigrid_ = std::make_unique<MultigridSolver>(std::move(multigrid->prolongations), multigrid->options);
    multigrid_->set_locality_order(std::move(multigrid->locality_order));
    multigrid_->setup(laplacian, std::move(constrained));
    // In the mass norm, the norm the errors are reported in (after re-centring in zero-mean mode).
    if (multigrid->estimate_error) multigrid_->set_error_norm(mass_of_one_, zero_mean);
  } else {
    direct_ = std::make_unique<ConstrainedSolver>(laplacian, std::move(constrained), ordering);
  }
}

PoissonSolver PoissonSolver::dirichlet(const SparseMatrix& laplacian, const SparseMatrix& mass,
                                       std::vector<Index> dirichlet_vertices, std::optional<PoissonMultigrid> multigrid,
                                       CholeskyOrdering ordering) {
  if (dirichlet_vertices.empty())
    throw std::invalid_argument("PoissonSolver::dirichlet: no Dirichlet vertices (use zero_mean)");
  const ComponentLabels components = component_labels(laplacian);
  if (components.count() > 1) {  // each component needs a prescribed value, or it floats
    const std::vector<char> held = components_holding(components, dirichlet_vertices);
    for (std::size_t c = 0; c < held.size(); ++c)
      if (!held[c])
        throw std::invalid_argument("PoissonSolver::dirichlet: the mesh has " + std::to_string(components.count()) +
                                    " connected components and the one of vertex " + std::to_string(components.first[c]) +
                                    " has no Dirichlet vertex (fix a value in each component)");
  }
  return PoissonSolver(laplacian, mass, std::move(dirichlet_vertices), {}, false, std::move(multigrid), ordering);
}

PoissonSolver PoissonSolver::zero_mean(const SparseMatrix& laplacian, const SparseMatrix& mass,
                                       std::optional<PoissonMultigrid> multigrid, CholeskyOrdering ordering) {
  if (laplacian.rows() == 0) throw std::invalid_argument("PoissonSolver::zero_mean: empty system");
  ComponentLabels components = component_labels(laplacian);
  std::vector<Index> pinned = components.first;  // any vertex of each component can be pinned; use its first
  return PoissonSolver(laplacian, mass, std::move(pinned), std::move(components), true, std::move(multigrid), ordering);
}

Eigen::VectorXd PoissonSolver::solve(const Eigen::VectorXd& f, const Eigen::VectorXd& dirichlet_values) const {
  return solve_weighted(mass_ * f, dirichlet_values);
}

Eigen::VectorXd PoissonSolver::solve_constrained(const Eigen::VectorXd& b, const Eigen::VectorXd& values,
                                                 const Eigen::VectorXd& initial_guess) const {
  if (direct_) return direct_->solve(b, values);
  if (b.size() != multigrid_->size()) throw std::invalid_argument("PoissonSolver::solve: rhs has the wrong size");
  return multigrid_->solve(b, values, initial_guess);
}

Eigen::VectorXd PoissonSolver::solve_weighted(const Eigen::VectorXd& b, const Eigen::VectorXd& dirichlet_values) const {
  return solve_weighted(b, dirichlet_values, Eigen::VectorXd());
}

Eigen::VectorXd PoissonSolver::solve_weighted(const Eigen::VectorXd& b, const Eigen::VectorXd& dirichlet_values,
                                              const Eigen::VectorXd& initial_guess) const {
  if (initial_guess.size() != 0 && initial_guess.size() != b.size())
    throw std::invalid_argument("PoissonSolver::solve: initial guess has the wrong size");
  if (!zero_mean_) return solve_constrained(b, dirichlet_values, initial_guess);
  Eigen::VectorXd compatible = b;
  make_compatible(components_, mass_of_one_, compatible);
  // The pinned unknowns (each component's first vertex) are 0: shift the guess to agree there
  // (solutions differ by a constant per component).
  Eigen::VectorXd guess;
  if (initial_guess.size() != 0) {
    guess = initial_guess;
    for (Eigen::Index i = 0; i < guess.size(); ++i)
      guess[i] -= initial_guess(components_.first[static_cast<std::size_t>(components_.label[static_cast<std::size_t>(i)])]);
  }
  Eigen::VectorXd u = solve_constrained(compatible, Eigen::VectorXd(), guess);
  remove_component_means(components_, mass_of_one_, u);
  return u;
}

Eigen::MatrixXd PoissonSolver::solve_multiple_weighted(const Eigen::MatrixXd& B, const Eigen::MatrixXd& dirichlet_values) const {
  const auto solve_block = [&](const Eigen::MatrixXd& rhs, const Eigen::MatrixXd& values) {
    if (direct_) return direct_->solve_multiple(rhs, values);
    if (rhs.rows() != multigrid_->size()) throw std::invalid_argument("PoissonSolver::solve_multiple: rhs has the wrong size");
    return multigrid_->solve_multiple(rhs, values);  // block V-cycles: the levels streamed once for all columns
  };
  if (!zero_mean_) return solve_block(B, dirichlet_values);
  Eigen::MatrixXd compatible(B.rows(), B.cols());
  for (Eigen::Index j = 0; j < B.cols(); ++j) {  // column by column, as solve_weighted does
    Eigen::VectorXd b = B.col(j);
    make_compatible(components_, mass_of_one_, b);
    compatible.col(j) = b;
  }
  Eigen::MatrixXd X = solve_block(compatible, Eigen::MatrixXd());
  for (Eigen::Index j = 0; j < X.cols(); ++j) {
    Eigen::VectorXd u = X.col(j);
    remove_component_means(components_, mass_of_one_, u);
    X.col(j) = u;
  }
  return X;
}

// ---- HeatSolver -------------------------------------------------------------------------------------

std::vector<int> output_steps(int steps, int every) {
  if (steps < 1 || every < 1) throw std::invalid_argument("output_steps: steps and every must be >= 1");
  std::vector<int> listed;
  for (long long k = every; k <= steps; k += every) listed.push_back(static_cast<int>(k));
  if (listed.empty() || listed.back() != steps) listed.push_back(steps);
  return listed;
}

namespace {

// M + τL after checking the sizes and τ (both HeatSolver constructors).
SparseMatrix heat_matrix(const SparseMatrix& laplacian, const SparseMatrix& mass, double time_step) {
  require_square(mass, laplacian.rows(), "HeatSolver: mass and Laplacian");
  if (!(time_step > 0)) throw std::invalid_argument("HeatSolver: time step must be positive");
  return SparseMatrix(mass + time_step * laplacian);
}

}  // namespace

HeatSolver::HeatSolver(const SparseMatrix& laplacian, const SparseMatrix& mass, double time_step, CholeskyOrdering ordering)
    : mass_(mass), time_step_(time_step) {
  const SparseMatrix A = heat_matrix(laplacian, mass, time_step);
  factor_.set_ordering(ordering);
  factor_.compute(A);
}

HeatSolver::HeatSolver(const SparseMatrix& laplacian, const SparseMatrix& mass, double time_step, PoissonMultigrid multigrid)
    : mass_(mass), time_step_(time_step) {
  const SparseMatrix A = heat_matrix(laplacian, mass, time_step);
  multigrid_ = std::make_unique<MultigridSolver>(std::move(multigrid.prolongations), multigrid.options);
  multigrid_->set_locality_order(std::move(multigrid.locality_order));
  multigrid_->setup(A);
}

Eigen::VectorXd HeatSolver::solve_weighted(const Eigen::VectorXd& b) const {
  return multigrid_ ? multigrid_->solve(b) : factor_.solve(b);
}

Eigen::MatrixXd HeatSolver::solve_multiple_weighted(const Eigen::MatrixXd& B) const {
  return multigrid_ ? multigrid_->solve_multiple(B) : factor_.solve_multiple(B);
}

Eigen::VectorXd HeatSolver::step(const Eigen::VectorXd& u) const {
  const Eigen::VectorXd b = mass_ * u;
  // The previous state is within O(τ) of the next one: a far better start than 0.
  return multigrid_ ? multigrid_->solve(b, Eigen::VectorXd(), u) : factor_.solve(b);
}

Eigen::VectorXd HeatSolver::integrate(const Eigen::VectorXd& u0, int steps) const {
  if (steps < 0) throw std::invalid_argument("HeatSolver::integrate: negative number of steps");
  Eigen::VectorXd u = u0;
  for (int k = 0; k < steps; ++k) u = step(u);
  return u;
}

Eigen::MatrixXd HeatSolver::trajectory(const Eigen::VectorXd& u0, int steps, int every, std::vector<int>* steps_written,
                                       std::vector<MultigridReport>* step_reports) const {
  const std::vector<int> listed = output_steps(steps, every);
  if (u0.size() != mass_.rows()) throw std::invalid_argument("HeatSolver::trajectory: initial state of the wrong size");
  Eigen::MatrixXd out(u0.size(), static_cast<Eigen::Index>(listed.size()));
  if (step_reports) step_reports->clear();
  Eigen::VectorXd u = u0;
  int done = 0;
  for (std::size_t j = 0; j < listed.size(); ++j) {
    for (; done < listed[j]; ++done) {
      u = step(u);
      if (step_reports && multigrid_) step_reports->push_back(multigrid_->report());
    }
    out.col(static_cast<Eigen::Index>(j)) = u;
  }
  if (steps_written) *steps_written = listed;
  return out;
}

// ---- Heat method ------------------------------------------------------------------------------------

HeatMethodOperators heat_method_operators(const ice::IntrinsicMesh& mesh, MassKind mass_kind, double time_factor) {
  if (!(time_factor > 0)) throw std::invalid_argument("heat_method_operators: time_factor must be positive");
  HeatMethodOperators ops;
  ops.laplacian = cotan_laplacian(mesh);
  ops.mass = mass_matrix(mesh, mass_kind);
  ops.gradient = gradient(mesh);
  ops.face_areas = face_areas(mesh.L);
  ops.boundary_vertices = boundary_vertices(mesh.F);
  const double h = mean_edge_length(mesh.L);
  ops.time_step = time_factor * time_factor * h * h;
  return ops;
}

namespace {

HeatMethodOperators checked(HeatMethodOperators ops) {
  const Eigen::Index n = ops.laplacian.rows();
  require_square(ops.laplacian, n, "HeatGeodesicSolver: laplacian");
  require_square(ops.mass, n, "HeatGeodesicSolver: mass");
  if (ops.gradient.cols() != n || ops.gradient.rows() != 2 * ops.face_areas.size())
    throw std::invalid_argument("HeatGeodesicSolver: gradient must be 2k×n with k face areas");
  return ops;
}

}  // namespace

HeatGeodesicSolver::HeatGeodesicSolver(HeatMethodOperators operators)
    : operators_(checked(std::move(operators))),
      components_(component_labels(operators_.laplacian)),
      neumann_heat_(operators_.laplacian, operators_.mass, operators_.time_step),
      pinned_poisson_(operators_.laplacian, components_.first) {
  if (!operators_.boundary_vertices.empty())
    dirichlet_heat_ = std::make_unique<ConstrainedSolver>(
        SparseMatrix(operators_.mass + operators_.time_step * operators_.laplacian), operators_.boundary_vertices);
}

Eigen::VectorXd HeatGeodesicSolver::distance(const std::vector<Index>& sources) const {
  if (sources.empty()) throw std::invalid_argument("HeatGeodesicSolver::distance: no sources");
  Eigen::VectorXd weights = Eigen::VectorXd::Zero(operators_.laplacian.rows());
  for (int s : sources) {
    if (s < 0 || s >= weights.size()) throw std::invalid_argument("HeatGeodesicSolver::distance: bad source");
    weights(s) = 1.0;
  }
  return distance_from_weights(weights);
}

// −∇u/|∇u| per face (0 where ∇u vanishes exactly), weighted by the face area for the divergence;
// g holds the per-face gradients of one or more functions (one per column). The gradient is scaled
// by its largest component before normalising: far from the sources u is subnormal (at t = h² on
// a 1.6M-vertex mesh it falls to 1e-320), and area / |∇u| then overflowed to ∞ and ∞ · 0 made the
// whole distance NaN.
Eigen::MatrixXd HeatGeodesicSolver::normalized_field(const Eigen::MatrixXd& g) const {
  Eigen::MatrixXd weighted_field(g.rows(), g.cols());
  for (Eigen::Index c = 0; c < g.cols(); ++c)
    for (Eigen::Index f = 0; f < operators_.face_areas.size(); ++f) {
      if (std::isnan(g(2 * f, c)) || std::isnan(g(2 * f + 1, c))) {  // propagate, do not hide
        weighted_field(2 * f, c) = weighted_field(2 * f + 1, c) = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      const double largest = std::max(std::abs(g(2 * f, c)), std::abs(g(2 * f + 1, c)));
      if (!(largest > 0)) {
        weighted_field(2 * f, c) = weighted_field(2 * f + 1, c) = 0.0;
        continue;
      }
      const double x = g(2 * f, c) / largest, y = g(2 * f + 1, c) / largest;
      const double scale = -operators_.face_areas(f) / std::hypot(x, y);
      weighted_field(2 * f, c) = scale * x;
      weighted_field(2 * f + 1, c) = scale * y;
    }
  return weighted_field;
}

Eigen::MatrixXd HeatGeodesicSolver::distances_from_each(const std::vector<Index>& sources) const {
  const Eigen::Index n = operators_.laplacian.rows();
  Eigen::MatrixXd deltas = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(sources.size()));
  for (std::size_t j = 0; j < sources.size(); ++j) {
    if (sources[j] < 0 || sources[j] >= n) throw std::invalid_argument("HeatGeodesicSolver::distances_from_each: bad source");
    deltas(sources[j], static_cast<Eigen::Index>(j)) = 1.0;
  }
  if (sources.empty()) return deltas;
  Eigen::MatrixXd u = neumann_heat_.solve_multiple_weighted(deltas);
  if (dirichlet_heat_) u = 0.5 * (u + dirichlet_heat_->solve_multiple(deltas));
  const Eigen::MatrixXd rhs = operators_.gradient.transpose() * normalized_field(operators_.gradient * u);
  Eigen::MatrixXd phi = pinned_poisson_.solve_multiple(rhs);
  for (std::size_t j = 0; j < sources.size(); ++j) {
    const auto column = static_cast<Eigen::Index>(j);
    const Index component = components_.label[static_cast<std::size_t>(sources[j])];
    const double at_source = phi(sources[j], column);
    for (Eigen::Index i = 0; i < n; ++i)
      phi(i, column) = components_.label[static_cast<std::size_t>(i)] == component
                           ? phi(i, column) - at_source
                           : std::numeric_limits<double>::infinity();
  }
  return phi;
}

Eigen::VectorXd HeatGeodesicSolver::distance_from_weights(const Eigen::VectorXd& source_weights) const {
  if (source_weights.size() != operators_.laplacian.rows() || !(source_weights.minCoeff() >= 0) ||
      !(source_weights.sum() > 0))
    throw std::invalid_argument("HeatGeodesicSolver: source weights must be non-negative, not all zero");

  Eigen::VectorXd u = neumann_heat_.solve_weighted(source_weights);
  if (dirichlet_heat_) u = 0.5 * (u + dirichlet_heat_->solve(source_weights));

  const Eigen::VectorXd rhs = operators_.gradient.transpose() * normalized_field(operators_.gradient * u);
  Eigen::VectorXd phi = pinned_poisson_.solve(rhs);
  // Per component: shifted by its sources' weighted mean; +∞ where it has no source.
  remove_component_means(components_, source_weights, phi);
  std::vector<char> reached(static_cast<std::size_t>(components_.count()), 0);
  for (Eigen::Index i = 0; i < phi.size(); ++i)
    if (source_weights[i] > 0) reached[static_cast<std::size_t>(components_.label[static_cast<std::size_t>(i)])] = 1;
  for (Eigen::Index i = 0; i < phi.size(); ++i)
    if (!reached[static_cast<std::size_t>(components_.label[static_cast<std::size_t>(i)])])
      phi[i] = std::numeric_limits<double>::infinity();
  return phi;
}

}  // namespace fem
