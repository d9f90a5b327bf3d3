#include "ice/proxy/vectors.h"

#include <utility>

namespace ice::proxy {

VectorTransportSolver::VectorTransportSolver(const TriangleMesh& mesh, VectorTransportOptions options,
                                             std::optional<CoarseSpace> coarse, const std::vector<CoarsePoint>* map)
    : options_(std::move(options)) {
  if (coarse) {
    coarse_ = std::move(*coarse);
  } else {
    CoarseSpaceOptions coarsening = options_.coarsening;
    coarsening.keep_method_state = true;  // P_vec and the sweep's traced lengths read the fine-to-coarse map
    coarse_ = build_coarse_space(mesh, coarsening);
  }
  const bool sweep = options_.solver == VectorSolver::sweep;
  const bool galerkin = options_.operators == fem::VectorOperatorKind::galerkin;
  fine_ = proxy::tangent_mesh(mesh, options_.fine, sweep || galerkin);
  std::vector<CoarsePoint> own_map;
  if (!map) {
    own_map = fine_to_coarse_map(coarse_);
    map = &own_map;
  }
  if (sweep)
    sweep_ = std::make_unique<fem::VectorSweepProxy>(make_vector_sweep(mesh, fine_, coarse_, *map, options_.sweep));
  else
    diffusion_ = std::make_unique<fem::VectorHeatProxy>(make_vector_proxy(fine_, coarse_, *map, options_.operators,
                                                                          options_.time_factor));
}

Eigen::VectorXcd VectorTransportSolver::transport(const std::vector<Index>& sources, const std::vector<fem::Complex>& vectors,
                                                  fem::DistanceSweepStats* stats) const {
  return sweep_ ? sweep_->interpolate(sources, vectors, stats) : diffusion_->interpolate(sources, vectors);
}

Eigen::VectorXcd transport_vectors(const TriangleMesh& mesh, const std::vector<Index>& sources,
                                   const std::vector<fem::Complex>& vectors, const VectorTransportOptions& options) {
  return VectorTransportSolver(mesh, options).transport(sources, vectors);
}

}  // namespace ice::proxy
