#include "ice/proxy/vectors.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace ice::proxy {

VectorTransportSolver::VectorTransportSolver(const TriangleMesh& mesh, VectorTransportOptions options,
                                             std::optional<CoarseSpace> coarse, const std::vector<CoarsePoint>* map)
    : options_(std::move(options)) {
  if (coarse && coarse->summary.tufted_cover)
    throw std::invalid_argument("VectorTransportSolver: a tufted cover's coarse space with the copies of a vertex merged has "
                                "a fan per sheet at its coarse vertices (no tangent plane): give build_coarse_space_on_copies' "
                                "space, or none");
  const bool sweep = options_.solver == VectorSolver::sweep;
  const bool galerkin = options_.operators == fem::VectorOperatorKind::galerkin;
  CoarseSpaceOptions coarsening = options_.coarsening;
  coarsening.keep_method_state = true;  // P_vec and the sweep's traced lengths read the fine-to-coarse map
  if (solved_on_tufted_cover(mesh, options_.coarsening.nonmanifold)) {
    // The copies of the cover, where every vertex has one tangent plane (one fan of one sheet).
    cover_ = distinct_sheets(tufted_cover(mesh, /*tuft_boundary=*/false));
    if (coarse && coarse->P.rows() != static_cast<Eigen::Index>(cover_->to_input.size()))
      throw std::invalid_argument("VectorTransportSolver: the given coarse space has " + std::to_string(coarse->P.rows()) +
                                  " fine vertices, not the cover's " + std::to_string(cover_->to_input.size()) +
                                  " copies (build_coarse_space_on_copies)");
    coarse_ = coarse ? std::move(*coarse) : build_coarse_space_on_copies(*cover_, coarsening);
    fine_ = proxy::tangent_mesh(*cover_, options_.fine, sweep || galerkin);
    positions_ = cover_->mesh.V;
  } else {
    coarse_ = coarse ? std::move(*coarse) : build_coarse_space(mesh, coarsening);
    fine_ = proxy::tangent_mesh(mesh, options_.fine, sweep || galerkin);
    positions_ = mesh.V;
  }
  std::vector<CoarsePoint> own_map;
  if (!map) {
    own_map = fine_to_coarse_map(coarse_);
    map = &own_map;
  }
  if (sweep) {
    // On a cover: the coarse mesh's own lengths (its edges lie on the sheets, not on the input's triangles).
    const SurfaceEdgeLengths own{coarse_.mesh.L, 0, 0};
    sweep_ = std::make_unique<fem::VectorSweepProxy>(make_vector_sweep(mesh, fine_, coarse_, *map, options_.sweep, cover_ ? &own : nullptr));
  } else {
    diffusion_ = std::make_unique<fem::VectorHeatProxy>(make_vector_proxy(fine_, coarse_, *map, options_.operators,
                                                                          options_.time_factor));
  }
}

Eigen::VectorXcd VectorTransportSolver::transport(const std::vector<Index>& sources, const std::vector<fem::Complex>& vectors,
                                                  fem::DistanceSweepStats* stats) const {
  return sweep_ ? sweep_->interpolate(sources, vectors, stats) : diffusion_->interpolate(sources, vectors);
}

Eigen::MatrixXd VectorTransportSolver::transport_directions(const std::vector<Index>& sources, const Eigen::MatrixXd& directions,
                                                            fem::DistanceSweepStats* stats) const {
  if (cover_) {
    const CopySources on_copies = sources_on_copies(*cover_, fine_, sources, directions);
    return ambient_on_input(*cover_, fine_, transport(on_copies.copies, on_copies.vectors, stats));
  }
  if (directions.rows() != static_cast<Eigen::Index>(sources.size()) || directions.cols() != 3)
    throw std::invalid_argument("transport_directions: one 3D direction per source");
  std::vector<fem::Complex> vectors;
  for (std::size_t s = 0; s < sources.size(); ++s) {
    const Eigen::Vector3d d = directions.row(static_cast<Eigen::Index>(s)).transpose();
    if (sources[s] < 0 || sources[s] >= fine_.mesh.vertex_count)
      throw std::invalid_argument("transport_directions: source " + std::to_string(sources[s]) + " is not a vertex of the mesh");
    vectors.push_back(tangent_direction(fine_, positions_, sources[s], d, "source " + std::to_string(sources[s])));
  }
  return fem::tangent_to_ambient(fine_.mesh, fine_.frames, positions_, transport(sources, vectors, stats));
}

Eigen::VectorXcd transport_vectors(const TriangleMesh& mesh, const std::vector<Index>& sources,
                                   const std::vector<fem::Complex>& vectors, const VectorTransportOptions& options) {
  if (solved_on_tufted_cover(mesh, options.coarsening.nonmanifold))
    throw std::invalid_argument("transport_vectors: on a tufted cover a vertex has a tangent frame per copy; give the sources' "
                                "vectors in space (transport_directions)");
  return VectorTransportSolver(mesh, options).transport(sources, vectors);
}

Eigen::MatrixXd transport_directions(const TriangleMesh& mesh, const std::vector<Index>& sources, const Eigen::MatrixXd& directions,
                                     const VectorTransportOptions& options) {
  return VectorTransportSolver(mesh, options).transport_directions(sources, directions);
}

}  // namespace ice::proxy
