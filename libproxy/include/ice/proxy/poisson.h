#pragma once
/// \file poisson.h
/// Poisson −Δu = f on a triangle mesh through a coarse proxy: solve_poisson in one call, or a
/// PoissonSolver set up once and solved for many right-hand sides. What poisson-coarse and Python's
/// ice.solve_poisson compute, with the same defaults.
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "ice/proxy/setup.h"

namespace ice::proxy {

struct PoissonOptions {
  /// How the coarse space is made when none is given: 5 % of the vertices by ICE, with the metric
  /// measured for Poisson and heat (default_coarsening). Dirichlet vertices are locked besides.
  CoarseSpaceOptions coarsening = default_coarsening(ProxyUse::poisson_heat);
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::galerkin;
  FineGeometry fine = FineGeometry::intrinsic_delaunay;
  Prolongation prolongation = Prolongation::automatic;
  /// Dirichlet vertices (input indices); none: the zero-mean Neumann problem, on each component.
  std::vector<Index> fixed_vertices;
  /// Polishing towards the fine solution (none by default).
  fem::PolishOptions polish;
  /// Where the set-up proxy is looked up and saved (store.h); off by default in the library (the
  /// tools and the Python package use default_store_options()). A given coarse space bypasses it.
  StoreOptions store;
};

/// A Poisson problem set up once: the coarse space, the fine discretisation, the proxy and its
/// factorisation. Solves are const and may run concurrently.
class PoissonSolver {
 public:
  /// Coarsens `mesh` (clean, oriented, manifold: e.g. from ice::load_mesh) by options.coarsening, or
  /// uses `coarse` (a coarse space of `mesh`; the fixed vertices should be among its vertices).
  /// Throws std::invalid_argument on bad options or a fixed vertex out of range.
  explicit PoissonSolver(const TriangleMesh& mesh, PoissonOptions options = {}, std::optional<CoarseSpace> coarse = {});

  /// u on every input vertex for the source f (one value per vertex). Without fixed vertices the
  /// zero-mean solution of −Δu = f − mean(f); with them, u = `fixed_values` there (default zeros).
  /// `times`, `polish_report`: where the solve's time went and what polishing did.
  Eigen::VectorXd solve(const Eigen::Ref<const Eigen::VectorXd>& f, const Eigen::VectorXd& fixed_values = {},
                        fem::ProxyPhaseTimes* times = nullptr, fem::PolishReport* polish_report = nullptr) const;

  /// solve() for every column of F (one row per vertex, one column per source) at once
  /// (fem::ProxyPoissonSolver::solve_block: one pass over the fine-size matrices per block of
  /// columns, one CHOLMOD call for the coarse solves); column j of `fixed_values` (one row per fixed
  /// vertex; empty: zeros) is column j's values. Each column agrees with its solve() within round-off.
  Eigen::MatrixXd solve_block(const Eigen::Ref<const Eigen::MatrixXd>& F, const Eigen::MatrixXd& fixed_values = {},
                              fem::ProxyPhaseTimes* times = nullptr) const;

  const PoissonOptions& options() const { return options_; }
  const CoarseSpace& coarse_space() const { return setup_.coarse; }
  const FineMesh& fine_mesh() const { return setup_.fine; }
  const fem::CoarseProxy& proxy() const { return *setup_.proxy; }
  /// Where the setup came from (the store's status and times).
  const CacheReport& cache() const { return setup_.cache; }
  const fem::ProxyPoissonSolver& proxy_solver() const { return *solver_; }

 private:
  PoissonOptions options_;
  ProxySetup setup_;
  std::unique_ptr<fem::ProxyPoissonSolver> solver_;
};

/// PoissonSolver(mesh, options).solve(f, fixed_values).
Eigen::VectorXd solve_poisson(const TriangleMesh& mesh, const Eigen::Ref<const Eigen::VectorXd>& f,
                              const PoissonOptions& options = {}, const Eigen::VectorXd& fixed_values = {});

}  // namespace ice::proxy
