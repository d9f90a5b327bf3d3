#pragma once
/// \file heat.h
/// Backward-Euler heat flow on a triangle mesh through a coarse proxy: heat_flow in one call, or a
/// HeatSolver set up once (one factorisation for a time step) and integrated from many initial
/// fields. What Python's ice.heat_flow computes, with the same defaults.
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "ice/proxy/setup.h"

namespace ice::proxy {

struct HeatOptions {
  /// As PoissonOptions::coarsening.
  CoarseSpaceOptions coarsening = default_coarsening(ProxyUse::poisson_heat);
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::galerkin;
  FineGeometry fine = FineGeometry::intrinsic_delaunay;
  Prolongation prolongation = Prolongation::automatic;
  /// How the initial values reach the coarse mesh.
  fem::RestrictionKind restriction = fem::RestrictionKind::l2_projection;
  fem::PolishOptions polish;
  /// Where the set-up proxy is looked up and saved (store.h); off by default in the library (the
  /// tools and the Python package use default_store_options()). A given coarse space bypasses it.
  StoreOptions store;
};

class HeatSolver {
 public:
  /// Coarsens `mesh` (or uses `coarse`, a coarse space of it) and factors M_c + τ L_c for the time
  /// step τ > 0. Throws std::invalid_argument on bad options or τ.
  HeatSolver(const TriangleMesh& mesh, double time_step, HeatOptions options = {}, std::optional<CoarseSpace> coarse = {});

  /// The field after `steps` backward-Euler steps from u0 (one value per vertex); fem::ProxyHeatSolver's
  /// contract: steps >= 1 with L2 projection, >= 0 with injection (std::invalid_argument otherwise).
  Eigen::VectorXd integrate(const Eigen::Ref<const Eigen::VectorXd>& u0, int steps = 1,
                            fem::ProxyPhaseTimes* times = nullptr, fem::PolishReport* polish_report = nullptr) const;

  /// The field after every `every`-th step up to `steps` (and after `steps`), one column each,
  /// their step counts in `output_steps`: restricted once, stepped on the coarse mesh, only those
  /// states prolonged (fem::ProxyHeatSolver::trajectory; column j equals integrate(u0,
  /// output_steps[j]) to the last bit). Not with polishing (std::invalid_argument).
  Eigen::MatrixXd steps(const Eigen::Ref<const Eigen::VectorXd>& u0, int steps, int every = 1,
                        std::vector<int>* output_steps = nullptr, fem::ProxyPhaseTimes* times = nullptr) const;

  double time_step() const { return time_step_; }
  const CoarseSpace& coarse_space() const { return setup_.coarse; }
  const FineMesh& fine_mesh() const { return setup_.fine; }
  const fem::CoarseProxy& proxy() const { return *setup_.proxy; }
  /// Where the setup came from (the store's status and times).
  const CacheReport& cache() const { return setup_.cache; }

 private:
  double time_step_;
  ProxySetup setup_;
  std::unique_ptr<fem::ProxyHeatSolver> solver_;
};

/// HeatSolver(mesh, time_step, options).integrate(u0, steps).
Eigen::VectorXd heat_flow(const TriangleMesh& mesh, const Eigen::Ref<const Eigen::VectorXd>& u0, double time_step,
                          int steps = 1, const HeatOptions& options = {});

}  // namespace ice::proxy
