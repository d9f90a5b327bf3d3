#include "ice/proxy/geodesics.h"

#include <stdexcept>
#include <string>
#include <utility>

namespace ice::proxy {

namespace {

/// Refuses, before any coarsening, lengths the coarse distances cannot use.
void require_marching_for_traced(CoarseLengths lengths, bool marching) {
  if (lengths == CoarseLengths::traced && !marching)
    throw std::invalid_argument("traced coarse lengths are for coarse marching, not the heat method");
}

/// Whether the recipe runs on a tufted cover: `coarse`'s, else the options' decision for `mesh`.
bool on_cover(const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening, const std::optional<CoarseSpace>& coarse) {
  return coarse ? coarse->summary.tufted_cover : solved_on_tufted_cover(mesh, coarsening.nonmanifold);
}

/// The coarse space of a marching recipe with its map, through `store` (which may be off).
MappedSpace mapped_space(const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening, const Store& store) {
  MappedSpaceOptions options;
  options.coarsening = coarsening;
  options.store = store;
  return build_mapped_space(mesh, options);
}

/// Whether to trace: as traces_lengths says, except that `automatic` falls back to the coarse mesh's
/// own lengths when there is nothing to trace with (a given space without map or method state, a
/// tufted cover's space).
bool trace(CoarseLengths choice, const CoarseSpace& space, const std::vector<CoarsePoint>* map, bool marching) {
  if (space.summary.tufted_cover) return false;  // (traced asked of a cover: refused by the callers before the work)
  const bool can_trace = map != nullptr || space.triangulation.has_value();
  if (choice == CoarseLengths::traced && space.summary.method != CoarseningMethod::ice)
    throw std::invalid_argument("traced coarse lengths need an ICE coarse space (QEM's edges are straight: nothing to trace)");
  return (choice != CoarseLengths::automatic || can_trace) && traces_lengths(choice, space.summary.method, marching);
}

}  // namespace

void refuse_tracing_on_cover(bool tufted_cover, const std::string& what) {
  if (tufted_cover)
    throw std::invalid_argument(what + ": traced lengths lay the coarse edges over the input's triangles, and a tufted "
                                "cover's coarse space (a mesh that is not an oriented manifold, or a point cloud) lies on "
                                "the cover's sheets: on a cover, coarse marching runs on the coarse mesh's own lengths "
                                "(lengths 'auto')");
}

GeodesicSolver::GeodesicSolver(const TriangleMesh& mesh, GeodesicOptions options, std::optional<CoarseSpace> coarse,
                               const std::vector<CoarsePoint>* map)
    : options_(std::move(options)) {
  const bool marching = options_.method == fem::CoarseDistanceMethod::marching;
  require_marching_for_traced(options_.lengths, marching);
  if (marching) {
    const double divisor = curvature_divisor(MarchingUse::single_source);
    // On a cover, the coarse mesh's own lengths (corrected only when asked: corrects_curvature); refused before the work.
    if (options_.lengths == CoarseLengths::traced)
      refuse_tracing_on_cover(on_cover(mesh, options_.coarsening, coarse), "traced coarse lengths for marching");
    if (!coarse) {  // coarsened with its map, the space and its marching lengths through the store
      const Store store(options_.store);
      MappedSpace space = mapped_space(mesh, options_.coarsening, store);
      traced_ = trace(options_.lengths, space.coarse, space.map.empty() ? nullptr : &space.map, true);
      lengths_ = stored_marching_lengths(mesh, space, store, traced_, options_.curvature_correction, divisor, &space.cache);
      setup_.coarse = std::move(space.coarse);
      cache_ = std::move(space.cache);
    } else {
      setup_.coarse = std::move(*coarse);
      traced_ = trace(options_.lengths, setup_.coarse, map, true);
      lengths_ = marching_lengths(mesh, setup_.coarse, traced_, options_.curvature_correction, map, divisor);
    }
    solver_ = std::make_unique<fem::ProxyGeodesicSolver>(with_lengths(setup_.coarse.mesh, lengths_.lengths), setup_.coarse.P,
                                                         options_.subdivisions);
  } else {
    ProxySetupOptions setup;
    setup.coarsening = options_.coarsening;
    setup.fine = options_.fine;
    setup.operators = options_.operators;
    setup.prolongation = Prolongation::barycentric;
    setup.store = Store(options_.store);
    setup.fine_operators = true;  // the Galerkin heat method's coarse operators are made from the fine ones
    setup_ = build_proxy_setup(mesh, setup, std::move(coarse));
    cache_ = setup_.cache;
    fem::ProxyGeodesicOptions heat;
    heat.method = fem::CoarseDistanceMethod::heat_method;
    heat.time_factor = options_.time_factor;
    solver_ = std::make_unique<fem::ProxyGeodesicSolver>(*setup_.proxy, heat);
  }
}

Eigen::VectorXd GeodesicSolver::distance(const std::vector<Index>& sources, fem::ProxyPhaseTimes* times) const {
  return solver_->distance(sources, times);
}

Eigen::VectorXd geodesic_distance(const TriangleMesh& mesh, const std::vector<Index>& sources, const GeodesicOptions& options) {
  return GeodesicSolver(mesh, options).distance(sources);
}

fem::DistanceOracle distance_oracle(const TriangleMesh& mesh, const OracleOptions& options, std::optional<CoarseSpace> coarse,
                                    const std::vector<CoarsePoint>* map, CacheReport* cache) {
  const bool marching = options.oracle.method == fem::CoarseDistanceMethod::marching;
  require_marching_for_traced(options.lengths, marching);
  if (options.lengths == CoarseLengths::traced) refuse_tracing_on_cover(on_cover(mesh, options.coarsening, coarse), "the distance oracle's traced lengths");
  const double divisor = curvature_divisor(MarchingUse::all_pairs);
  if (!coarse) {  // coarsened with its map, the space and its marching lengths through the store
    const Store store(options.store);
    MappedSpace space = mapped_space(mesh, options.coarsening, store);
    if (space.map.empty())
      throw std::invalid_argument("the distance oracle needs the fine-to-coarse map, which QEM's intrinsic Delaunay geometry "
                                  "does not have (its closest-point map lies in the QEM mesh's faces)");
    const bool traced = trace(options.lengths, space.coarse, &space.map, marching);
    const SurfaceEdgeLengths lengths =
        stored_marching_lengths(mesh, space, store, traced, options.curvature_correction, divisor, &space.cache);
    if (cache) *cache = space.cache;
    return fem::DistanceOracle(with_lengths(space.coarse.mesh, lengths.lengths), space.map, options.oracle);
  }
  const CoarseSpace& space = *coarse;
  std::vector<CoarsePoint> own_map;
  if (!map) {
    own_map = fine_to_coarse_map(space);
    map = &own_map;
  }
  const bool traced = trace(options.lengths, space, map, marching);
  return fem::DistanceOracle(with_lengths(space.mesh, marching_lengths(mesh, space, traced, options.curvature_correction,
                                                                      map, divisor)
                                                         .lengths),
                             *map, options.oracle);
}

}  // namespace ice::proxy
