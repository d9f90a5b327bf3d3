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
  /// With options.coarsening.nonmanifold = tufted_cover a mesh that is not an oriented manifold (or a
  /// point cloud's faces) is solved on its tufted cover's copies: cover() is
  /// distinct_sheets(tufted_cover(mesh, false)) (no boundary tufts: an open sheet keeps its boundary,
  /// as on a manifold), tangent_mesh() its tangent_mesh(cover) (one frame per copy,
  /// per sheet around a vertex) and the coarse space build_coarse_space_on_copies' (a given `coarse`
  /// must be that, with P's rows the copies: std::invalid_argument otherwise). The sweep then
  /// marches on the coarse mesh's own lengths (nothing is traced on a cover).
  explicit VectorTransportSolver(const TriangleMesh& mesh, VectorTransportOptions options = {},
                                 std::optional<CoarseSpace> coarse = {}, const std::vector<CoarsePoint>* map = nullptr);

  /// The field (one complex number per vertex of tangent_mesh(), in its frames: on a cover, per copy)
  /// through `vectors` at `sources` (vertices of tangent_mesh(), each vector in its source's frame).
  /// `stats`: the sweep's. On a cover the sources are copies (cover()->to_input names their vertices).
  Eigen::VectorXcd transport(const std::vector<Index>& sources, const std::vector<fem::Complex>& vectors,
                             fem::DistanceSweepStats* stats = nullptr) const;
  /// The field as 3D vectors, one row per input vertex, through one 3D direction per source (a row of
  /// `directions`, projected into the tangent plane at the source, of its length) at `sources` (input
  /// vertices): transport() drawn in space (fem::tangent_to_ambient). On a cover every copy of a
  /// source is one, and a vertex's vector is the area-weighted mean of its copies' (ambient_on_input).
  /// Throws std::invalid_argument when a direction is normal to the surface at its source.
  Eigen::MatrixXd transport_directions(const std::vector<Index>& sources, const Eigen::MatrixXd& directions,
                                       fem::DistanceSweepStats* stats = nullptr) const;
  /// The sheets solved on when the mesh went through its tufted cover; null otherwise.
  const TuftedCover* cover() const { return cover_ ? &*cover_ : nullptr; }

  const VectorTransportOptions& options() const { return options_; }
  const CoarseSpace& coarse_space() const { return coarse_; }
  /// The input triangles' frames (on a cover, the copies') and the fine operators.
  const TangentMesh& tangent_mesh() const { return fine_; }
  /// One of the two is set, as options().solver says.
  const fem::VectorSweepProxy* sweep() const { return sweep_.get(); }
  const fem::VectorHeatProxy* diffusion() const { return diffusion_.get(); }

 private:
  VectorTransportOptions options_;
  std::optional<TuftedCover> cover_;
  Positions positions_;  ///< of tangent_mesh()'s vertices (transport_directions)
  CoarseSpace coarse_;
  TangentMesh fine_;
  std::unique_ptr<fem::VectorSweepProxy> sweep_;
  std::unique_ptr<fem::VectorHeatProxy> diffusion_;
};

/// VectorTransportSolver(mesh, options).transport(sources, vectors). A mesh solved on its tufted cover
/// is refused (std::invalid_argument: its vertices have a frame per copy; transport_directions takes it).
Eigen::VectorXcd transport_vectors(const TriangleMesh& mesh, const std::vector<Index>& sources,
                                   const std::vector<fem::Complex>& vectors, const VectorTransportOptions& options = {});
/// VectorTransportSolver(mesh, options).transport_directions(sources, directions): on any mesh, and on
/// a tufted cover.
Eigen::MatrixXd transport_directions(const TriangleMesh& mesh, const std::vector<Index>& sources, const Eigen::MatrixXd& directions,
                                     const VectorTransportOptions& options = {});

}  // namespace ice::proxy
