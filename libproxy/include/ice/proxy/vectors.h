#pragma once
/// \file vectors.h
/// Tangent vector fields carried from sources to every vertex through a coarse proxy (the vector
/// heat method): transport_vectors in one call, or a VectorTransportSolver set up once. What
/// vector-coarse and Python's ice.transport_vectors compute, with the same defaults. One source
/// gives its vector parallel-transported along shortest geodesics; several give the smooth field
/// through them.
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "ice/proxy/setup.h"

namespace ice::proxy {

struct VectorTransportOptions {
  /// As PoissonOptions::coarsening.
  CoarseSpaceOptions coarsening = default_coarsening(ProxyUse::poisson_heat);
  VectorSolver solver = VectorSolver::sweep;
  /// The fine operators' discretisation (the sweep's, and the Galerkin products of diffusion).
  FineGeometry fine = FineGeometry::intrinsic_delaunay;
  /// The sweep's passes and coarse-grid corrections.
  fem::DistanceSweepOptions sweep;
  /// Diffusion only: its coarse operators and t = (time_factor · h_c)².
  fem::VectorOperatorKind operators = fem::VectorOperatorKind::galerkin;
  double time_factor = fem::kVectorProxyTimeFactor;
};

class VectorTransportSolver {
 public:
  /// Coarsens `mesh` (or uses `coarse`, a coarse space of it, with its fine-to-coarse `map` or built
  /// with keep_method_state) and prepares the solver. Throws std::invalid_argument on bad options.
  explicit VectorTransportSolver(const TriangleMesh& mesh, VectorTransportOptions options = {},
                                 std::optional<CoarseSpace> coarse = {}, const std::vector<CoarsePoint>* map = nullptr);

  /// The field (one complex number per vertex, in the tangent frames of tangent_mesh()) through
  /// `vectors` at `sources` (input vertices, each vector in its source's frame). `stats`: the sweep's.
  Eigen::VectorXcd transport(const std::vector<Index>& sources, const std::vector<fem::Complex>& vectors,
                             fem::DistanceSweepStats* stats = nullptr) const;

  const VectorTransportOptions& options() const { return options_; }
  const CoarseSpace& coarse_space() const { return coarse_; }
  /// The input triangles' frames and the fine operators.
  const TangentMesh& tangent_mesh() const { return fine_; }
  /// One of the two is set, as options().solver says.
  const fem::VectorSweepProxy* sweep() const { return sweep_.get(); }
  const fem::VectorHeatProxy* diffusion() const { return diffusion_.get(); }

 private:
  VectorTransportOptions options_;
  CoarseSpace coarse_;
  TangentMesh fine_;
  std::unique_ptr<fem::VectorSweepProxy> sweep_;
  std::unique_ptr<fem::VectorHeatProxy> diffusion_;
};

/// VectorTransportSolver(mesh, options).transport(sources, vectors).
Eigen::VectorXcd transport_vectors(const TriangleMesh& mesh, const std::vector<Index>& sources,
                                   const std::vector<fem::Complex>& vectors, const VectorTransportOptions& options = {});

}  // namespace ice::proxy
