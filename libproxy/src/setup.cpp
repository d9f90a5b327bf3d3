#include "ice/proxy/setup.h"

#include <stdexcept>
#include <utility>

#include "fem/curvature_correction.h"
#include "ice/prolongation.h"

namespace ice::proxy {

fem::CoarseProxy make_proxy(const FineMesh& fine, const CoarseSpace& coarse, fem::CoarseOperatorKind kind,
                            fem::ProlongationKind prolongation) {
  return fem::CoarseProxy(fine.F, fine.L, coarse.mesh.F, coarse.mesh.L, coarse.P, kind, fem::MassKind::lumped, prolongation);
}

ProxySetup build_proxy_setup(const TriangleMesh& mesh, std::optional<CoarseSpace> coarse, CoarseSpaceOptions coarsening,
                             const std::vector<Index>& locked, FineGeometry geometry, fem::CoarseOperatorKind kind,
                             Prolongation prolongation, bool dirichlet, const Store& store, const CoarseSpaceBuilder& builder,
                             bool fine_operators) {
  const fem::ProlongationKind resolved = resolve_prolongation(prolongation, kind, dirichlet);  // before any work
  ProxySetup setup;
  bool geometry_made = false;  // setup.fine
  std::optional<StoreKey> key;
  if (coarse) {
    setup.coarse = std::move(*coarse);
  } else {
    std::vector<Index>& kept = coarsening.coarsen.locked_vertices;
    kept.insert(kept.end(), locked.begin(), locked.end());
    if (store.enabled() && !coarsening.keep_method_state && !coarsening.record_history) {
      key = proxy_setup_key(mesh, coarsening, geometry, kind, resolved);
      if (std::optional<ProxySetup> stored = load_proxy_setup(store, *key, mesh, setup.cache,
                                                              fine_operators ? fine_mesh_source(mesh, geometry) : nullptr))
        return std::move(*stored);
    }
    if (builder) {
      setup.coarse = builder(mesh, coarsening);
    } else {
      // The fine intrinsic Delaunay mesh from the triangulation the coarsening starts with.
      const bool shared = geometry == FineGeometry::intrinsic_delaunay;
      setup.coarse = build_coarse_space(mesh, coarsening, shared ? &setup.fine : nullptr);
      if (shared) geometry_made = true;
    }
  }
  if (!geometry_made) setup.fine = fine_mesh(mesh, geometry);
  setup.proxy = std::make_unique<fem::CoarseProxy>(make_proxy(setup.fine, setup.coarse, kind, resolved));
  if (key) save_proxy_setup(store, *key, setup);
  return setup;
}

FaceLengths curvature_corrected_lengths(const TriangleMesh& mesh, const CoarseSpace& space, const FaceLengths& lengths,
                                        double divisor) {
  return fem::curvature_corrected_lengths(mesh.F, face_lengths_from_positions(mesh.V, mesh.F), space.mesh.F, lengths,
                                          space.P, divisor);
}

SurfaceEdgeLengths marching_lengths(const TriangleMesh& mesh, const CoarseSpace& space, bool traced,
                                    CurvatureCorrection correction, const std::vector<CoarsePoint>* map, double divisor) {
  SurfaceEdgeLengths result;
  if (traced && map)  // (not `map ? *map : fine_to_coarse_map(space)`: that copies the given map)
    result = surface_edge_lengths(mesh, space.mesh, *map, space.inserted);
  else if (traced)
    result = surface_edge_lengths(mesh, space.mesh, fine_to_coarse_map(space), space.inserted);
  else
    result.lengths = space.mesh.L;
  if (corrects_curvature(correction, space.summary.method))
    result.lengths = curvature_corrected_lengths(mesh, space, result.lengths, divisor);
  return result;
}

TangentMesh tangent_mesh(const TriangleMesh& mesh, FineGeometry geometry, bool with_operators, double time_factor) {
  TangentMesh out;
  out.mesh.F = mesh.F;
  out.mesh.L = face_lengths_from_positions(mesh.V, mesh.F);
  out.mesh.twin = glue_by_vertex_pairs(mesh.F);
  out.frames = fem::tangent_frames(out.mesh);
  if (!with_operators) return out;
  if (geometry == FineGeometry::input) {
    out.operators = fem::vector_heat_operators(out.mesh, out.frames, time_factor);
  } else {
    FineMesh delaunay = fine_mesh(mesh, geometry);
    out.flips = delaunay.flips;
    out.operators = fem::vector_heat_operators(
        out.mesh, out.frames, CompactMesh{std::move(delaunay.F), std::move(delaunay.L), std::move(delaunay.twin), {}, {}},
        time_factor);
  }
  return out;
}

fem::VectorHeatProxy make_vector_proxy(const TangentMesh& fine, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                       fem::VectorOperatorKind kind, double time_factor) {
  const fem::TangentFrames coarse_frames = fem::tangent_frames(coarse.mesh);
  if (fine.operators)
    return fem::VectorHeatProxy(fine.mesh, fine.frames, *fine.operators, coarse.mesh, coarse_frames, map, coarse.P, kind,
                                time_factor);
  if (kind == fem::VectorOperatorKind::galerkin)
    throw std::logic_error("make_vector_proxy: Galerkin operators need the fine operators (tangent_mesh with_operators)");
  return fem::VectorHeatProxy(fine.mesh, fine.frames, coarse.mesh, coarse_frames, map, coarse.P, kind, time_factor);
}

fem::VectorSweepProxy make_vector_sweep(const TriangleMesh& mesh, const TangentMesh& fine, const CoarseSpace& coarse,
                                        const std::vector<CoarsePoint>& map, const fem::DistanceSweepOptions& options) {
  if (!fine.operators) throw std::logic_error("make_vector_sweep: the sweep needs the fine operators (tangent_mesh with_operators)");
  const bool traced = traces_lengths(CoarseLengths::automatic, coarse.summary.method, true);
  const SurfaceEdgeLengths lengths = marching_lengths(mesh, coarse, traced, CurvatureCorrection::automatic, &map);
  return fem::VectorSweepProxy(*fine.operators, fem::ProxyGeodesicSolver(coarse.mesh.F, lengths.lengths, coarse.P), options);
}

}  // namespace ice::proxy
