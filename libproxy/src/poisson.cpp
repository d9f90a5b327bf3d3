#include "ice/proxy/poisson.h"

#include <stdexcept>
#include <string>
#include <utility>

namespace ice::proxy {

PoissonSolver::PoissonSolver(const TriangleMesh& mesh, PoissonOptions options, std::optional<CoarseSpace> coarse)
    : options_(std::move(options)) {
  const auto n = static_cast<Index>(mesh.V.rows());
  for (Index v : options_.fixed_vertices)
    if (v < 0 || v >= n)
      throw std::invalid_argument("fixed vertex " + std::to_string(v) + " is out of range: the mesh has " +
                                  std::to_string(n) + " vertices");
  ProxySetupOptions setup;
  setup.coarsening = options_.coarsening;
  setup.locked = options_.fixed_vertices;
  setup.fine = options_.fine;
  setup.operators = options_.operators;
  setup.prolongation = options_.prolongation;
  setup.dirichlet = !options_.fixed_vertices.empty();
  setup.fine_operators = options_.polish.enabled();
  setup.store = Store(options_.store);
  setup_ = build_proxy_setup(mesh, setup, std::move(coarse));
  solver_ = std::make_unique<fem::ProxyPoissonSolver>(*setup_.proxy, options_.fixed_vertices, options_.polish);
}

Eigen::VectorXd PoissonSolver::solve(const Eigen::Ref<const Eigen::VectorXd>& f, const Eigen::VectorXd& fixed_values,
                                     fem::ProxyPhaseTimes* times, fem::PolishReport* polish_report) const {
  return solver_->solve(f, fixed_values, times, polish_report);
}

Eigen::MatrixXd PoissonSolver::solve_block(const Eigen::Ref<const Eigen::MatrixXd>& F, const Eigen::MatrixXd& fixed_values,
                                           fem::ProxyPhaseTimes* times) const {
  return solver_->solve_block(F, fixed_values, times);
}

Eigen::VectorXd solve_poisson(const TriangleMesh& mesh, const Eigen::Ref<const Eigen::VectorXd>& f,
                              const PoissonOptions& options, const Eigen::VectorXd& fixed_values) {
  return PoissonSolver(mesh, options).solve(f, fixed_values);
}

}  // namespace ice::proxy
