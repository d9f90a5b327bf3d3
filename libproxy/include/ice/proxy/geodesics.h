#pragma once
/// \file geodesics.h
/// Geodesic distances on a triangle mesh through a coarse proxy: geodesic_distance in one call, a
/// GeodesicSolver set up once for many source sets, and the distance oracle between any two
/// vertices. What geodesic-coarse and Python's ice.geodesic_distance / ice.DistanceOracle compute,
/// with the same defaults: coarse fast marching on the coarse edges traced on the surface,
/// curvature-corrected, the coarse mesh split once (policies.h).
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fem/distance_oracle.h"
#include "ice/proxy/setup.h"

namespace ice::proxy {

struct GeodesicOptions {
  /// How the coarse space is made when none is given: 5 % of the vertices by ICE, with the metric
  /// measured for geodesics (default_coarsening).
  CoarseSpaceOptions coarsening = default_coarsening(ProxyUse::geodesic);
  /// Coarse fast marching (the default) or the coarse heat method.
  fem::CoarseDistanceMethod method = fem::CoarseDistanceMethod::marching;
  /// Marching: the lengths it runs on, their curvature correction, the coarse mesh's 1:4 splits.
  CoarseLengths lengths = CoarseLengths::automatic;
  CurvatureCorrection curvature_correction = CurvatureCorrection::automatic;
  int subdivisions = 1;
  /// The heat method: t = (time_factor · h_c)², its coarse operators and fine discretisation.
  double time_factor = 1.0;
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::galerkin;
  FineGeometry fine = FineGeometry::intrinsic_delaunay;
  /// Where the setup is looked up and saved (store.h): marching's coarse space with its map and
  /// traced lengths (build_mapped_space, traced_edge_lengths), the heat method's proxy
  /// (build_proxy_setup). Off by default in the library; a given coarse space bypasses it.
  StoreOptions store;
};

class GeodesicSolver {
 public:
  /// Coarsens `mesh` (clean, oriented, manifold) by options.coarsening, or uses `coarse`, a coarse
  /// space of it; traced lengths need its fine-to-coarse map: `map`, or a space built with
  /// keep_method_state (with CoarseLengths::automatic and neither, the coarse mesh's own lengths are
  /// used). With options.coarsening.nonmanifold = tufted_cover a mesh that is not an oriented
  /// manifold (or a point cloud's faces, ice/point_cloud.h) is solved on its tufted cover: marching
  /// then runs on the coarse mesh's own lengths (nothing is traced on a cover: CoarseLengths::automatic
  /// means those).
  /// Throws std::invalid_argument on bad options (traced lengths without a way to trace, or on a
  /// tufted cover; options of the heat method with marching and conversely are simply unused).
  explicit GeodesicSolver(const TriangleMesh& mesh, GeodesicOptions options = {}, std::optional<CoarseSpace> coarse = {},
                          const std::vector<CoarsePoint>* map = nullptr);

  /// Distance from the nearest of `sources` (input vertices; non-empty, in range) to every vertex;
  /// +∞ on components no source reaches (marching).
  Eigen::VectorXd distance(const std::vector<Index>& sources, fem::ProxyPhaseTimes* times = nullptr) const;

  const GeodesicOptions& options() const { return options_; }
  const CoarseSpace& coarse_space() const { return setup_.coarse; }
  /// Whether marching runs on traced lengths, and the tracing's counts (edges, traced).
  bool traced_lengths() const { return traced_; }
  const SurfaceEdgeLengths& lengths() const { return lengths_; }
  /// The CoarseProxy of the heat method, or null with marching (which needs none).
  const fem::CoarseProxy* proxy() const { return setup_.proxy.get(); }
  const fem::ProxyGeodesicSolver& proxy_solver() const { return *solver_; }
  /// Where the setup came from (the store's status, times and keys).
  const CacheReport& cache() const { return cache_; }

 private:
  GeodesicOptions options_;
  ProxySetup setup_;  ///< with marching: the coarse space alone
  CacheReport cache_;
  bool traced_ = false;
  SurfaceEdgeLengths lengths_;
  std::unique_ptr<fem::ProxyGeodesicSolver> solver_;
};

/// GeodesicSolver(mesh, options).distance(sources).
Eigen::VectorXd geodesic_distance(const TriangleMesh& mesh, const std::vector<Index>& sources,
                                  const GeodesicOptions& options = {});

/// Throws std::invalid_argument naming `what` when `tufted_cover`: traced coarse lengths lay the coarse
/// edges over the input's triangles, and a tufted cover's coarse space is laid over its cover's
/// sheets, not the input's faces. Coarse marching on a cover (sources, the oracle) runs on the coarse
/// mesh's own lengths; its map (ice::fine_to_coarse_map) places each input vertex by one of its copies.
void refuse_tracing_on_cover(bool tufted_cover, const std::string& what);

struct OracleOptions {
  CoarseSpaceOptions coarsening = default_coarsening(ProxyUse::geodesic);
  CoarseLengths lengths = CoarseLengths::automatic;
  CurvatureCorrection curvature_correction = CurvatureCorrection::automatic;
  /// Coarse distances (marching or heat), subdivisions, threads.
  fem::DistanceOracleOptions oracle;
  /// Where the coarse space with its map and traced lengths is looked up and saved (as GeodesicOptions::store).
  StoreOptions store;
};

/// The distance oracle of `mesh` (fem::DistanceOracle: all coarse pairs precomputed, then any two
/// vertices in O(1)), with the lengths and correction divisor measured for all-pairs marching.
/// `coarse`/`map` as for GeodesicSolver, except that the oracle always needs the map: a given space
/// without `map` must have been built with keep_method_state (std::invalid_argument otherwise). A
/// mesh solved on its tufted cover places each input vertex by one of its copies (fine_to_coarse_map)
/// and marches on the coarse mesh's own lengths. `cache`, when given, says where the setup came from.
fem::DistanceOracle distance_oracle(const TriangleMesh& mesh, const OracleOptions& options = {},
                                    std::optional<CoarseSpace> coarse = {}, const std::vector<CoarsePoint>* map = nullptr,
                                    CacheReport* cache = nullptr);

}  // namespace ice::proxy
