#pragma once
/// \file setup.h
/// The pieces every recipe is built from: the coarse proxy of a fine discretisation and a coarse
/// space, the lengths coarse marching runs on, and the tangent meshes and proxies of the vector
/// heat method. The one-call functions and solvers (poisson.h, heat.h, geodesics.h, vectors.h)
/// compose them under the measured defaults of policies.h; the tools and the Python package call
/// them directly when they time or report the steps one by one.
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fem/coarse_proxy.h"
#include "fem/vector_fields.h"
#include "ice/coarse_space.h"
#include "ice/coarse_tracing.h"
#include "ice/proxy/policies.h"
#include "ice/proxy/store.h"

namespace ice::proxy {

/// Throws std::invalid_argument unless `kind` is Galerkin when the coarse space is (or will be) a tufted
/// cover's: the cover's own coarse Laplacian is not the input's robust Laplacian.
void require_galerkin_on_cover(bool tufted_cover, fem::CoarseOperatorKind kind);

/// The coarse proxy of the fine discretisation `fine` through `coarse` (a coarse space of the mesh
/// `fine` was made from): operators of `kind`, lumped mass, the prolongation `prolongation`.
/// Throws as require_galerkin_on_cover for a tufted cover's coarse space.
fem::CoarseProxy make_proxy(const FineMesh& fine, const CoarseSpace& coarse, fem::CoarseOperatorKind kind,
                            fem::ProlongationKind prolongation = fem::ProlongationKind::barycentric);

/// Wall times of build_proxy_setup's steps, in seconds (the store's load and save are in CacheReport).
struct ProxySetupTimes {
  double coarsen = 0;    ///< build_coarse_space, without the fine mesh it hands out
  double fine_mesh = 0;  ///< the fine discretisation (also when the coarsening handed it out)
  double assemble = 0;   ///< the coarse proxy's operators
};

/// A coarse space, the fine discretisation and the coarse proxy linking them: what the Poisson and
/// heat recipes solve through. Movable; the proxy keeps its address when moved.
struct ProxySetup {
  CoarseSpace coarse;
  /// Empty when the setup came from a store (`cache.status` hit) unless ProxySetupOptions::
  /// need_fine_mesh: the proxy needs none of it, and proxy->fine_faces() / fine_lengths() make it on
  /// first use.
  FineMesh fine;
  /// The fine discretisation the proxy was assembled on (what a restored proxy makes its fine
  /// operators from).
  FineGeometry fine_geometry = FineGeometry::intrinsic_delaunay;
  std::unique_ptr<fem::CoarseProxy> proxy;  ///< null without ProxySetupOptions::assemble
  CacheReport cache;  ///< where the setup came from (status off without a store)
  ProxySetupTimes times;
};

/// How build_proxy_setup makes a coarse space when it has to (the tools pass one that draws
/// progress): as ice::build_coarse_space(mesh, options, fine_delaunay).
using CoarseSpaceBuilder = std::function<CoarseSpace(const TriangleMesh&, const CoarseSpaceOptions&, FineMesh* fine_delaunay)>;

/// What build_proxy_setup makes and how.
struct ProxySetupOptions {
  CoarseSpaceOptions coarsening;  ///< how to coarsen when no coarse space is given
  std::vector<Index> locked;      ///< kept as coarse vertices besides coarsening's own locked vertices
  FineGeometry fine = FineGeometry::intrinsic_delaunay;
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::galerkin;
  Prolongation prolongation = Prolongation::automatic;
  ProlongationUse prolongation_use = ProlongationUse::solves;  ///< what `automatic` serves (resolve_prolongation)
  bool dirichlet = false;  ///< the problem has Dirichlet vertices (resolve_prolongation)
  /// Assemble the proxy. Without it the setup is the coarse space (and the fine mesh when
  /// need_fine_mesh) and the store is not used: it holds coarse spaces with their proxies.
  bool assemble = true;
  /// The caller needs ProxySetup::fine itself (a fine reference solve): it is made also on a store hit.
  bool need_fine_mesh = false;
  /// A proxy restored from the store can make its fine operators (polishing, the Galerkin heat
  /// method): from restored_fine_mesh when given (whose referents must outlive the proxy), else from
  /// a copy of the mesh kept by the proxy.
  bool fine_operators = false;
  fem::CoarseProxy::FineMeshSource restored_fine_mesh;
  Store store;                 ///< off by default
  CoarseSpaceBuilder builder;  ///< empty: ice::build_coarse_space
};

/// The coarse space of `mesh` (`coarse` when given, else coarsened by options.coarsening with
/// options.locked kept), the fine discretisation of options.fine and the proxy (options.operators,
/// prolongation resolved for options.dirichlet). Throws std::invalid_argument on bad options
/// (ice::build_coarse_space, resolve_prolongation, fem::CoarseProxy).
///
/// With an enabled store, an assembled proxy and no coarse space given, the setup is first looked
/// up there under a key of the mesh's arrays and every option that changes it (proxy_setup_key); on
/// a hit nothing is coarsened or assembled, and the results are those of the setup that was stored
/// (the same arrays to the last bit). Otherwise it is built and saved. A damaged entry is reported
/// in ProxySetup::cache (status rebuilt), removed and built again; an entry that cannot be written
/// leaves the run as it is (save_error). Options that keep the method's state (keep_method_state,
/// record_history) bypass the store: the triangulation is not stored; so does a mesh coarsened
/// through its tufted cover (options.coarsening.nonmanifold), whose fine mesh is then the cover's
/// (ice::fine_mesh of the cover, on the mesh's vertices).
ProxySetup build_proxy_setup(const TriangleMesh& mesh, const ProxySetupOptions& options,
                             std::optional<CoarseSpace> coarse = std::nullopt);

/// The key build_proxy_setup stores a setup under: the mesh's positions and faces, the coarsening
/// options (with its locked vertices and the region count the result depends on; never the thread
/// count), the fine geometry, the operators, the resolved prolongation and the format version.
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
/// A source of the fine mesh of `geometry` from a copy of `mesh` (its tufted cover's where `nonmanifold`
/// says so and the mesh needs one: ice::fine_mesh), for load_proxy_setup.
fem::CoarseProxy::FineMeshSource fine_mesh_source(const TriangleMesh& mesh, FineGeometry geometry,
                                                  NonmanifoldInput nonmanifold = NonmanifoldInput::refuse);
/// Saves the coarse space and proxy of `setup` under `key` (its method state and fine mesh are not
/// stored); records the time and any error in setup.cache (status miss unless already rebuilt).
void save_proxy_setup(const Store& store, const StoreKey& key, ProxySetup& setup);

/// Writes `setup` (its coarse space and assembled proxy, not its fine mesh) to the file `path` in
/// the store's entry format, keyed by `mesh`'s arrays: load_proxy_setup_file takes it back for that
/// mesh only. Atomic (a temporary file beside `path`, renamed). An existing file is replaced only
/// when `overwrite`. Throws std::invalid_argument when the setup has no proxy, was not made for a
/// mesh of `mesh`'s vertex count, ice::MeshError (unwritable) when `path` exists and `overwrite` is
/// false or its directory does not exist, std::runtime_error naming the file when it cannot be written.
void save_proxy_setup_file(const std::filesystem::path& path, const TriangleMesh& mesh, const ProxySetup& setup,
                           bool overwrite = false);
/// The same from its parts: a coarse space of `mesh`, the proxy assembled on it (its barycentric P
/// the coarse space's: std::invalid_argument otherwise) and the fine geometry it was assembled on.
void save_proxy_setup_file(const std::filesystem::path& path, const TriangleMesh& mesh, const CoarseSpace& coarse,
                           const fem::CoarseProxy& proxy, FineGeometry geometry, bool overwrite = false);
/// The setup saved at `path` for `mesh`, checked as a stored one is (header, checksum, every array's
/// structure, P's rows); cache.status off, cache.load_seconds its time. Its proxy makes its fine
/// operators when asked (polishing, the Galerkin heat method) from `fine_mesh`, else from a copy of
/// `mesh` in the saved fine geometry. Throws std::runtime_error naming the file and the defect: no
/// such file, not a setup, damaged, of another format version, or made for another mesh.
ProxySetup load_proxy_setup_file(const std::filesystem::path& path, const TriangleMesh& mesh,
                                 fem::CoarseProxy::FineMeshSource fine_mesh = {});

/// A coarse space with its fine-to-coarse map (ice::fine_to_coarse_map): what coarse marching, the
/// distance oracle, the vector heat method and ice-coarsen read. Movable.
struct MappedSpace {
  /// The method's state (triangulation, QEM result) only when built with keep_method_state or
  /// record_history, which bypass the store.
  CoarseSpace coarse;
  /// One point per input vertex, faces in coarse.mesh's numbering (through a tufted cover: one copy's
  /// point, ice::fine_to_coarse_map); empty for QEM with intrinsic Delaunay geometry (its
  /// closest-point map lies in the QEM mesh's faces).
  std::vector<CoarsePoint> map;
  CacheReport cache;             ///< the space's entry, then the traced lengths' (traced_edge_lengths)
  /// The key the space is stored under (none when it is not: store off, bypassed, no map, cancelled);
  /// the traced lengths and gathered curvature are stored under keys made from it and the mesh's arrays.
  std::optional<StoreKey> key;
};

struct MappedSpaceOptions {
  CoarseSpaceOptions coarsening;
  Store store;                 ///< off by default
  CoarseSpaceBuilder builder;  ///< empty: ice::build_coarse_space
};

/// The coarse space of `mesh` by options.coarsening and its fine-to-coarse map. With an enabled
/// store it is first looked up under mapped_space_key: on a hit nothing is coarsened, and the space
/// and map are those that were stored (the same arrays to the last bit), checked (every array's
/// structure, and every row of P against the map's point: equal, or through a tufted cover weighing
/// every corner the point weighs) before use. Otherwise it is built and
/// saved. A damaged entry is reported in `cache` (status rebuilt), removed and built again; an entry
/// that cannot be written leaves the run as it is (save_error). keep_method_state and
/// record_history bypass the store (the method's state is not stored), and so does QEM with intrinsic
/// Delaunay geometry, which has no map (`map` empty); a coarsening cancelled by its progress callback
/// is not stored (`key` empty). A mesh solved on its tufted cover (options.coarsening.nonmanifold) is
/// coarsened through it. Throws std::invalid_argument on bad options as build_coarse_space.
/// `fine_delaunay`, when given, is filled as build_coarse_space fills it if the space is built, and
/// left as it is on a hit.
MappedSpace build_mapped_space(const TriangleMesh& mesh, const MappedSpaceOptions& options, FineMesh* fine_delaunay = nullptr);

/// The key build_mapped_space stores a space under: the mesh's arrays, every coarsening option that
/// changes the result (as proxy_setup_key) and the format version.
StoreKey mapped_space_key(const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening);

/// The lengths coarse marching runs on, for a mapped space through `store`: its coarse edges traced
/// on the surface (traced_edge_lengths) when `traced`, else the coarse mesh's own, then corrected for
/// curvature as `correction` says for the space's method (corrects_curvature) with `divisor`, from the
/// fine curvature and areas gathered through P (fem::coarse_curvature), which are stored beside the
/// space too (`curvature-KEY.ice`, checked: one finite curvature and non-negative area per coarse
/// vertex). The same lengths to the last bit as marching_lengths; the entries' use is added to `cache`.
SurfaceEdgeLengths stored_marching_lengths(const TriangleMesh& mesh, const MappedSpace& space, const Store& store, bool traced,
                                           CurvatureCorrection correction, double divisor, CacheReport* cache = nullptr);
/// The same from a mapped space's parts (`space_key`: MappedSpace::key, null when it has none).
SurfaceEdgeLengths stored_marching_lengths(const TriangleMesh& mesh, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                           const StoreKey* space_key, const Store& store, bool traced,
                                           CurvatureCorrection correction, double divisor, CacheReport* cache = nullptr);

/// Writes a coarse space with its map (`map`: ice::fine_to_coarse_map of it) to the file `path` in
/// the store's entry format, keyed by `mesh`'s arrays: load_mapped_space_file takes it back for that
/// mesh only. Atomic (a temporary file beside `path`, renamed); an existing file is replaced only when
/// `overwrite`. Throws std::invalid_argument when the space or map is not one of `mesh` (P's rows, the
/// map's size), ice::MeshError (unwritable) when `path` exists and `overwrite`
/// is false or its directory does not exist, std::runtime_error naming the file when it cannot be written.
void save_mapped_space_file(const std::filesystem::path& path, const TriangleMesh& mesh, const CoarseSpace& coarse,
                            const std::vector<CoarsePoint>& map, bool overwrite = false);
/// The coarse space and map saved at `path` for `mesh`, checked as a stored one is (header, checksum,
/// every array, every entry of P against the map); cache.status off, cache.load_seconds its time.
/// Throws std::runtime_error naming the file and the defect: no such file, not a coarse space,
/// damaged, of another format version, or made for another mesh.
MappedSpace load_mapped_space_file(const std::filesystem::path& path, const TriangleMesh& mesh);

/// The coarse edges' lengths on the input surface (ice::surface_edge_lengths over space.map): from
/// `store` when the space has a key and its traced lengths were stored (checked: one positive, finite
/// length per coarse face side, the counts in range), else traced and saved there. The entry's use is
/// added to `cache` when given (its keys; status and times are left to the space's).
SurfaceEdgeLengths traced_edge_lengths(const TriangleMesh& mesh, const MappedSpace& space, const Store& store,
                                       CacheReport* cache = nullptr);
/// The same from a mapped space's parts (`space_key`: MappedSpace::key, null when it has none).
SurfaceEdgeLengths traced_edge_lengths(const TriangleMesh& mesh, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                       const StoreKey* space_key, const Store& store, CacheReport* cache = nullptr);

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
  IntrinsicMesh mesh;
  fem::TangentFrames frames;
  std::optional<fem::VectorHeatOperators> operators;
  Index flips = 0;  ///< intrinsic Delaunay flips
};
TangentMesh tangent_mesh(const TriangleMesh& mesh, FineGeometry geometry, bool with_operators, double time_factor = 1.0);
/// The same on a tufted cover's copies (pass distinct_sheets(tufted_cover(mesh, false)), the sheets the
/// coarse space of build_coarse_space_on_copies is made of): its triangles with the cover's gluing,
/// one tangent frame per copy, the operators on ice::fine_mesh_on_copies. A vertex of the input has
/// a tangent plane per copy (per sheet around it); the cover is oriented where the input may not be.
TangentMesh tangent_mesh(const TuftedCover& cover, FineGeometry geometry, bool with_operators, double time_factor = 1.0);

/// The 3D `direction` at vertex v of `fine` (positions V) as a tangent vector in v's frame: projected
/// into the surface (fem::ambient_to_tangent), of the direction's length. Throws std::invalid_argument
/// naming `name` when the direction is normal to the surface there (nothing left after projection).
fem::Complex tangent_direction(const TangentMesh& fine, const Positions& V, Index v, const Eigen::Vector3d& direction,
                               const std::string& name);

/// Sources of a field on a tufted cover's copies: every copy of each input vertex of `sources`, with
/// that source's 3D `direction` (a row of `directions`) projected into the copy's tangent plane, of the
/// direction's length — but a copy whose faces are all normal to the direction (it lies in another
/// sheet's plane), which takes none. Throws std::invalid_argument (naming the source by `labels[s]`
/// when given, e.g. the file's vertex numbers, else its index) when no copy of a source takes its
/// direction, for a source with a copy whose fan holds a face and its mirror image (where a cover
/// made with boundary tufts folds from a sheet's one side to the other, and the vector would reach
/// the other side mirrored), for a source out of range, or when the sizes disagree.
struct CopySources {
  std::vector<Index> copies;
  std::vector<fem::Complex> vectors;
};
CopySources sources_on_copies(const TuftedCover& cover, const TangentMesh& fine, const std::vector<Index>& sources,
                              const Eigen::MatrixXd& directions, const std::vector<long long>& labels = {});
/// A field on the copies (fine's frames) as 3D vectors on the input vertices: each vertex the mean of
/// the vectors of its copies that carry one (nonzero), weighted by their areas; zero where none does.
/// Where sheets meet at a vertex, the mean of theirs.
Eigen::MatrixXd ambient_on_input(const TuftedCover& cover, const TangentMesh& fine, const Eigen::VectorXcd& field);

/// The diffusion proxy of vector fields through `coarse` and its fine-to-coarse `map`: the coarse
/// frames, P_vec fitted from the map, coarse operators of `kind` (Galerkin ones need
/// fine.operators: std::logic_error otherwise).
fem::VectorHeatProxy make_vector_proxy(const TangentMesh& fine, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                       fem::VectorOperatorKind kind, double time_factor = fem::kVectorProxyTimeFactor);

/// The sweep proxy of vector fields through `coarse`: coarse marching with the measured defaults
/// (CoarseLengths::automatic, CurvatureCorrection::automatic, one subdivision) and fine.operators
/// (which must have been built: std::logic_error otherwise). `lengths`: the marching lengths of those
/// defaults when already made (stored_marching_lengths with vector_sweep_traces(coarse)), else they
/// are made here.
fem::VectorSweepProxy make_vector_sweep(const TriangleMesh& mesh, const TangentMesh& fine, const CoarseSpace& coarse,
                                        const std::vector<CoarsePoint>& map, const fem::DistanceSweepOptions& options = {},
                                        const SurfaceEdgeLengths* lengths = nullptr);
/// Whether the vector sweep's marching runs on traced lengths (CoarseLengths::automatic for `coarse`'s method).
bool vector_sweep_traces(const CoarseSpace& coarse);

}  // namespace ice::proxy
