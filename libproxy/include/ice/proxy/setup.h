#pragma once
/// \file setup.h
/// The pieces every recipe is built from: the coarse proxy of a fine discretisation and a coarse
/// space, the lengths coarse marching runs on, and the tangent meshes and proxies of the vector
/// heat method. The one-call functions and solvers (poisson.h, heat.h, geodesics.h, vectors.h)
/// compose them under the measured defaults of policies.h; the tools and the Python package call
/// them directly when they time or report the steps one by one.
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "fem/coarse_proxy.h"
#include "fem/vector_fields.h"
#include "ice/coarse_space.h"
#include "ice/coarse_tracing.h"
#include "ice/proxy/policies.h"
#include "ice/proxy/store.h"

namespace ice::proxy {

/// The coarse proxy of the fine discretisation `fine` through `coarse` (a coarse space of the mesh
/// `fine` was made from): operators of `kind`, lumped mass, the prolongation `prolongation`.
fem::CoarseProxy make_proxy(const FineMesh& fine, const CoarseSpace& coarse, fem::CoarseOperatorKind kind,
                            fem::ProlongationKind prolongation = fem::ProlongationKind::barycentric);

/// A coarse space, the fine discretisation and the coarse proxy linking them: what the Poisson and
/// heat recipes solve through. Movable; the proxy keeps its address when moved.
struct ProxySetup {
  CoarseSpace coarse;
  /// Empty when the setup came from a store (`cache.status` hit): the proxy needs none of it, and
  /// proxy->fine_faces() / fine_lengths() make it on first use.
  FineMesh fine;
  std::unique_ptr<fem::CoarseProxy> proxy;
  CacheReport cache;  ///< where the setup came from (status off without a store)
};

/// How build_proxy_setup makes a coarse space when it has to (the tools pass one that draws progress).
using CoarseSpaceBuilder = std::function<CoarseSpace(const TriangleMesh&, const CoarseSpaceOptions&)>;
/// Coarsens `mesh` by `coarsening` (with `locked` vertices kept besides its own) unless a coarse
/// space is given, builds the fine discretisation of `geometry` and the proxy (operators `kind`,
/// prolongation `prolongation` resolved for `dirichlet`). Throws std::invalid_argument on bad
/// options (ice::build_coarse_space, resolve_prolongation, fem::CoarseProxy).
///
/// With an enabled `store` and no coarse space given, the setup is first looked up there under a key
/// of the mesh's arrays and every option that changes it (proxy_setup_key); on a hit nothing is
/// coarsened or assembled, and the results are those of the setup that was stored (the same arrays
/// to the last bit). Otherwise it is built and saved. A damaged entry is reported in
/// ProxySetup::cache (status rebuilt), removed and built again; an entry that cannot be written
/// leaves the run as it is (save_error). A restored proxy can make its fine operators (polishing)
/// only with `fine_operators` (it keeps a copy of the mesh for them). Options that keep the method's state (keep_method_state,
/// record_history) bypass the store: the triangulation is not stored.
ProxySetup build_proxy_setup(const TriangleMesh& mesh, std::optional<CoarseSpace> coarse, CoarseSpaceOptions coarsening,
                             const std::vector<Index>& locked, FineGeometry geometry, fem::CoarseOperatorKind kind,
                             Prolongation prolongation, bool dirichlet, const Store& store = {},
                             const CoarseSpaceBuilder& builder = {}, bool fine_operators = false);

/// The key build_proxy_setup stores a setup under: the mesh's positions and faces, the coarsening
/// options (with its locked vertices, and its thread count resolved to the regions the result
/// depends on), the fine geometry, the operators, the resolved prolongation and the format version.
StoreKey proxy_setup_key(const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening, FineGeometry geometry,
                         fem::CoarseOperatorKind kind, fem::ProlongationKind prolongation);

/// The setup stored under `key` (proxy_setup_key of `mesh`), checked, or std::nullopt: a miss, or a
/// damaged entry, which is removed and described in `cache` (status rebuilt). On a hit the setup's
/// cache says so and its fine mesh is empty (the proxy makes it of `geometry` if asked).
/// The restored proxy makes its fine mesh with `fine_mesh` if its fine operators are asked for
/// (polishing, the Galerkin heat method); null: std::logic_error then (the callers that never ask,
/// such as a Poisson or heat solver without polishing, keep no copy of the mesh).
std::optional<ProxySetup> load_proxy_setup(const Store& store, const StoreKey& key, const TriangleMesh& mesh,
                                           CacheReport& cache, fem::CoarseProxy::FineMeshSource fine_mesh = {});
/// A source of the fine mesh of `geometry` from a copy of `mesh`, for load_proxy_setup.
fem::CoarseProxy::FineMeshSource fine_mesh_source(const TriangleMesh& mesh, FineGeometry geometry);
/// Saves the coarse space and proxy of `setup` under `key` (its method state and fine mesh are not
/// stored); records the time and any error in setup.cache (status miss unless already rebuilt).
void save_proxy_setup(const Store& store, const StoreKey& key, ProxySetup& setup);

/// `lengths` (of space's coarse faces) curvature-corrected with the input `mesh`: its angle defects
/// and vertex areas gathered through space.P (fem::curvature_corrected_lengths) with divisor `divisor`.
FaceLengths curvature_corrected_lengths(const TriangleMesh& mesh, const CoarseSpace& space, const FaceLengths& lengths,
                                        double divisor);

/// The coarse edge lengths coarse marching runs on: the coarse mesh's own, or (`traced`) those of
/// its edges traced on the input surface by the walk over the fine-to-coarse map (`map`, or
/// ice::fine_to_coarse_map(space) when null: an ICE space built with keep_method_state); then
/// curvature-corrected as `correction` says for the marching `use`. The counts are the walk's (zero
/// for the coarse mesh's own lengths).
SurfaceEdgeLengths marching_lengths(const TriangleMesh& mesh, const CoarseSpace& space, bool traced,
                                    CurvatureCorrection correction, const std::vector<CoarsePoint>* map = nullptr,
                                    double divisor = curvature_divisor(MarchingUse::single_source));

/// The fine mesh of the vector heat method: the input triangles with their own edge lengths, glued
/// by vertex pairs, and their tangent frames, in which every field is given (one vector per input
/// vertex); and the method's fine operators in those frames, discretised on the input triangles or
/// (FineGeometry::intrinsic_delaunay) on their intrinsic Delaunay triangulation, with
/// t = (time_factor · the input's mean edge length)². The operators are built only when asked.
struct TangentMesh {
  CompactMesh mesh;
  fem::TangentFrames frames;
  std::optional<fem::VectorHeatOperators> operators;
  Index flips = 0;  ///< intrinsic Delaunay flips
};
TangentMesh tangent_mesh(const TriangleMesh& mesh, FineGeometry geometry, bool with_operators, double time_factor = 1.0);

/// The diffusion proxy of vector fields through `coarse` and its fine-to-coarse `map`: the coarse
/// frames, P_vec fitted from the map, coarse operators of `kind` (Galerkin ones need
/// fine.operators: std::logic_error otherwise).
fem::VectorHeatProxy make_vector_proxy(const TangentMesh& fine, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                       fem::VectorOperatorKind kind, double time_factor = fem::kVectorProxyTimeFactor);

/// The sweep proxy of vector fields through `coarse`: coarse marching with the measured defaults
/// (CoarseLengths::automatic, CurvatureCorrection::automatic, one subdivision) and fine.operators
/// (which must have been built: std::logic_error otherwise).
fem::VectorSweepProxy make_vector_sweep(const TriangleMesh& mesh, const TangentMesh& fine, const CoarseSpace& coarse,
                                        const std::vector<CoarsePoint>& map, const fem::DistanceSweepOptions& options = {});

}  // namespace ice::proxy
