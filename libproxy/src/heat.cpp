#include "ice/proxy/heat.h"

#include <cmath>
#include <stdexcept>
#include <utility>

namespace ice::proxy {

HeatSolver::HeatSolver(const TriangleMesh& mesh, double time_step, HeatOptions options, std::optional<CoarseSpace> coarse)
    : time_step_(time_step) {
  if (!(time_step > 0) || !std::isfinite(time_step)) throw std::invalid_argument("the time step must be > 0 and finite");
  ProxySetupOptions setup;
  setup.coarsening = std::move(options.coarsening);
  setup.fine = options.fine;
  setup.operators = options.operators;
  setup.prolongation = options.prolongation;
  setup.fine_operators = options.polish.enabled();
  setup.store = Store(options.store);
  setup_ = build_proxy_setup(mesh, setup, std::move(coarse));
  solver_ = std::make_unique<fem::ProxyHeatSolver>(*setup_.proxy, time_step, options.restriction, options.polish);
}

Eigen::VectorXd HeatSolver::integrate(const Eigen::Ref<const Eigen::VectorXd>& u0, int steps, fem::ProxyPhaseTimes* times,
                                      fem::PolishReport* polish_report) const {
  return solver_->integrate(u0, steps, times, polish_report);
}

Eigen::MatrixXd HeatSolver::steps(const Eigen::Ref<const Eigen::VectorXd>& u0, int steps, int every,
                                  std::vector<int>* output_steps, fem::ProxyPhaseTimes* times) const {
  return solver_->trajectory(u0, steps, every, output_steps, times);
}

Eigen::VectorXd heat_flow(const TriangleMesh& mesh, const Eigen::Ref<const Eigen::VectorXd>& u0, double time_step, int steps,
                          const HeatOptions& options) {
  return HeatSolver(mesh, time_step, options).integrate(u0, steps);
}

}  // namespace ice::proxy
