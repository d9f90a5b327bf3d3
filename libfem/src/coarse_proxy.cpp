#include "fem/coarse_proxy.h"

#include "parallel_kernels.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "fem/topology.h"

namespace fem {

namespace {

// diag(row sums of mass): the lumped version of a (Galerkin) mass matrix.
SparseMatrix lumped(const SparseMatrix& mass) {
  const Eigen::VectorXd row_sums = mass * Eigen::VectorXd::Ones(mass.cols());
  SparseMatrix diagonal(mass.rows(), mass.cols());
  diagonal.reserve(Eigen::VectorXi::Constant(mass.cols(), 1));
  for (Eigen::Index i = 0; i < row_sums.size(); ++i) diagonal.insert(i, i) = row_sums(i);
  diagonal.makeCompressed();
  return diagonal;
}

}  // namespace

CoarseProxy::CoarseProxy(const Faces& F, const FaceLengths& L, const Faces& Fc, const FaceLengths& Lc, SparseMatrix P,
                         CoarseOperatorKind kind, MassKind mass_kind, Eigen::Index fine_vertex_count,
                         Eigen::Index coarse_vertex_count)
    : kind_(kind), mass_kind_(mass_kind), P_(std::move(P)), coarse_faces_(Fc), coarse_lengths_(Lc) {
  const Eigen::Index n_fine =
      fine_vertex_count >= 0 ? fine_vertex_count : (F.size() == 0 ? 0 : Eigen::Index(F.maxCoeff()) + 1);
  fine_mass_ = mass_matrix(F, L, mass_kind, n_fine);
  lazy_ = std::make_unique<LazyFineOperators>();
  lazy_->F = F;
  lazy_->L = L;
  lazy_->n = n_fine;
  const Eigen::Index n_coarse =
      coarse_vertex_count >= 0 ? coarse_vertex_count : (Fc.size() == 0 ? 0 : Eigen::Index(Fc.maxCoeff()) + 1);
  if (P_.rows() != n_fine || P_.cols() != n_coarse)
    throw std::invalid_argument("CoarseProxy: P must be n_fine × n_coarse");
  const Eigen::VectorXd row_sums = P_ * Eigen::VectorXd::Ones(n_coarse);
  if (n_fine > 0 && (row_sums.array() - 1.0).abs().maxCoeff() > 1e-10)
    throw std::invalid_argument("CoarseProxy: every row of P must sum to 1");

  if (kind == CoarseOperatorKind::intrinsic) {
    coarse_laplacian_ = cotan_laplacian(Fc, Lc, n_coarse);
    coarse_mass_ = mass_matrix(Fc, Lc, mass_kind, n_coarse);
  } else {
    coarse_laplacian_ = galerkin(P_, fine_laplacian());
    coarse_mass_ = galerkin(P_, fine_mass_);
  }
  coarse_mass_factor_.compute(coarse_mass_);

  // A coarse vertex sitting on a fine vertex shows up as a row of P equal to e_j.
  SparseMatrix P_columns = P_;
  P_columns.makeCompressed();
  coarse_to_fine_.assign(static_cast<std::size_t>(n_coarse), -1);
  for (Eigen::Index j = 0; j < P_columns.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(P_columns, j); it; ++it)
      if (std::abs(it.value() - 1.0) < 1e-12) coarse_to_fine_[static_cast<std::size_t>(j)] = static_cast<int>(it.row());
}

const CoarseProxy::LazyFineOperators& CoarseProxy::fine_operators() const {
  LazyFineOperators& lazy = *lazy_;
  std::call_once(lazy.once, [&lazy] {
    lazy.laplacian = cotan_laplacian(lazy.F, lazy.L, lazy.n);
    lazy.gradient = gradient(lazy.F, lazy.L, lazy.n);
    lazy.face_areas = face_areas(lazy.L);
  });
  return lazy;
}

const SparseMatrix& CoarseProxy::fine_laplacian() const { return fine_operators().laplacian; }

Eigen::VectorXd CoarseProxy::restrict_weighted(const Eigen::VectorXd& b) const {
  if (b.size() != fine_size()) throw std::invalid_argument("CoarseProxy::restrict_weighted: wrong size");
  return P_.transpose() * b;
}

Eigen::VectorXd CoarseProxy::restrict_values(const Eigen::VectorXd& u, RestrictionKind kind) const {
  if (u.size() != fine_size()) throw std::invalid_argument("CoarseProxy::restrict_values: wrong size");
  if (kind == RestrictionKind::l2_projection)
    return coarse_mass_factor_.solve(Eigen::VectorXd(P_.transpose() * (fine_mass_ * u)));
  Eigen::VectorXd coarse(coarse_size());
  for (Eigen::Index j = 0; j < coarse_size(); ++j) {
    const int fine = coarse_to_fine_[static_cast<std::size_t>(j)];
    if (fine < 0) throw std::logic_error("CoarseProxy: coarse vertex " + std::to_string(j) + " has no fine vertex in P");
    coarse(j) = u(fine);
  }
  return coarse;
}

Eigen::VectorXd CoarseProxy::prolong(const Eigen::VectorXd& coarse_values) const {
  if (coarse_values.size() != coarse_size()) throw std::invalid_argument("CoarseProxy::prolong: wrong size");
  return P_ * coarse_values;
}

HeatMethodOperators CoarseProxy::coarse_heat_method_operators(double time_factor) const {
  if (kind_ == CoarseOperatorKind::intrinsic)
    return heat_method_operators(coarse_faces_, coarse_lengths_, mass_kind_, time_factor, coarse_size());
  if (!(time_factor > 0)) throw std::invalid_argument("coarse_heat_method_operators: time_factor must be positive");
  HeatMethodOperators ops;
  const LazyFineOperators& fine = fine_operators();
  ops.laplacian = coarse_laplacian_;
  ops.mass = lumped(coarse_mass_);  // see the header: the heat step needs a diagonal mass
  ops.gradient = fine.gradient * P_;  // gradients of prolonged coarse functions, on the fine faces
  ops.face_areas = fine.face_areas;
  ops.boundary_vertices = boundary_vertices(coarse_faces_);
  const double h = mean_edge_length(coarse_lengths_);
  ops.time_step = time_factor * time_factor * h * h;
  return ops;
}

// ---- proxy solvers ----------------------------------------------------------------------------------

ProxyPoissonSolver::ProxyPoissonSolver(const CoarseProxy& proxy)
    : P_(proxy.prolongation()),
      fine_mass_(proxy.fine_mass()),
      P_rows_(P_),
      fine_mass_of_one_(fine_mass_ * Eigen::VectorXd::Ones(P_.rows())),
      total_mass_(fine_mass_of_one_.sum()),
      coarse_(PoissonSolver::zero_mean(proxy.coarse_laplacian(), proxy.coarse_mass())) {
  P_.makeCompressed();
  fine_mass_.makeCompressed();
  P_rows_.makeCompressed();
}

Eigen::VectorXd ProxyPoissonSolver::solve(const Eigen::VectorXd& f) const {
  using namespace detail;
  if (f.size() != P_.rows()) throw std::invalid_argument("ProxyPoissonSolver::solve: wrong size");
  const Eigen::Index n = P_.rows();
  const int threads = default_threads();
  // Fine-size passes as gathers (M is symmetric, so its columns are its rows): M f, Pᵀ (M f), P u_c.
  Eigen::VectorXd weighted(n), coarse_rhs(P_.cols()), u(n);
  gather_product(fine_mass_, f.data(), weighted.data(), false, threads, n);
  gather_product(P_, weighted.data(), coarse_rhs.data(), false, threads, n);
  const Eigen::VectorXd coarse_u = coarse_.solve_weighted(coarse_rhs);
  gather_product(P_rows_, coarse_u.data(), u.data(), false, threads, n);
  add_constant(-dot(fine_mass_of_one_, u, threads) / total_mass_, u, threads);
  return u;
}

ProxyHeatSolver::ProxyHeatSolver(const CoarseProxy& proxy, double time_step, RestrictionKind restriction)
    : proxy_(&proxy), restriction_(restriction), coarse_(proxy.coarse_laplacian(), proxy.coarse_mass(), time_step) {}

Eigen::VectorXd ProxyHeatSolver::integrate(const Eigen::VectorXd& fine_u0, int steps) const {
  return proxy_->prolong(coarse_.integrate(proxy_->restrict_values(fine_u0, restriction_), steps));
}

ProxyGeodesicSolver::ProxyGeodesicSolver(const CoarseProxy& proxy, double time_factor)
    : P_rows_(proxy.prolongation()), coarse_(proxy.coarse_heat_method_operators(time_factor)) {
  P_rows_.makeCompressed();
}

Eigen::VectorXd ProxyGeodesicSolver::distance(const std::vector<int>& fine_sources) const {
  if (fine_sources.empty()) throw std::invalid_argument("ProxyGeodesicSolver::distance: no sources");
  // The sources' weights restricted directly from P's rows (Pᵀ of a sparse indicator), without a
  // fine-size pass; a repeated source counts once.
  const Eigen::Index n = P_rows_.rows();
  std::vector<int> sources = fine_sources;
  std::sort(sources.begin(), sources.end());
  sources.erase(std::unique(sources.begin(), sources.end()), sources.end());
  if (sources.front() < 0 || sources.back() >= n) throw std::invalid_argument("ProxyGeodesicSolver::distance: bad source");
  Eigen::VectorXd coarse_weights = Eigen::VectorXd::Zero(P_rows_.cols());
  for (int s : sources)
    for (decltype(P_rows_)::InnerIterator it(P_rows_, s); it; ++it) coarse_weights(it.col()) += it.value();
  const Eigen::VectorXd coarse_phi = coarse_.distance_from_weights(coarse_weights);
  Eigen::VectorXd phi(n);
  detail::gather_product(P_rows_, coarse_phi.data(), phi.data(), false, detail::default_threads(), n);
  // Shift so that the sources' mean distance is zero.
  double sum = 0;
  for (int s : sources) sum += phi(s);
  detail::add_constant(-sum / static_cast<double>(sources.size()), phi, detail::default_threads());
  return phi;
}

}  // namespace fem
