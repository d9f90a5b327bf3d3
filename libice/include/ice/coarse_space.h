#pragma once
/// \file coarse_space.h
/// The coarse space a user of ICE comes for, in one call: a fine mesh in; a small intrinsic mesh,
/// the prolongation P (fine vertices × coarse vertices) and a summary out, made by ICE or by the QEM
/// baseline. Tools, reports and bindings call this instead of driving ice::coarsen / ice::qem_coarsen
/// themselves. Also the fine mesh's discretisation that the PDE solvers pair with it.
///
///   ice::CoarseSpaceOptions options;
///   options.coarsen.target_ratio = 0.05;                  // or target_vertices, max_error
///   const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
///   // space.mesh (faces, lengths, to_input/from_input, gluing), space.P, space.summary
///   const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
///
/// Postconditions: P has mesh.V.rows() rows and space.mesh.to_input.size() columns, every row sums
/// to 1 (barycentric coordinates of the fine vertex in a coarse face; a surviving vertex's row is
/// e_j); locked vertices survive (both methods).
#include <array>
#include <optional>
#include <vector>
#include <string>

#include <Eigen/SparseCore>

#include "ice/coarsen.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh.h"
#include "ice/qem.h"
#include "ice/refinement.h"
#include "ice/tufted_cover.h"

namespace ice {

struct FineMesh;

/// How the coarse mesh is made.
enum class CoarseningMethod {
  ice,  ///< intrinsic vertex removals ordered by the ICE error metric (ice::coarsen)
  qem,  ///< the extrinsic QEM baseline with a closest-point map (ice::qem_coarsen)
};
/// Where a QEM coarse mesh's edge lengths come from. Both keep the QEM vertices, so P is the same.
enum class QemGeometry {
  extrinsic,           ///< the QEM mesh's own positions
  intrinsic_delaunay,  ///< its intrinsic Delaunay triangulation (edges flipped until every cotan weight ≥ 0)
};
const char* to_string(CoarseningMethod method);
const char* to_string(QemGeometry geometry);

/// What a coarse space will serve; picks the ICE metric's defaults for it (recommended_coarsen_options).
enum class ProxyUse { poisson_heat, geodesic };
const char* to_string(ProxyUse use);

/// CoarsenOptions (defaults everywhere) with the ICE metric settings — area_weight,
/// normalize_curvature — that were the most accurate for `use` in the accuracy runs of ice-report,
/// as a PDE proxy with Galerkin coarse operators (the tools' default), against QEM with intrinsic
/// Delaunay operators (the strongest baseline: better than QEM with extrinsic or Galerkin
/// operators), over area weights from 0 to 1 with and without normalisation (docs/measurements.md,
/// "ICE metric defaults"):
///  - poisson_heat: area weight 0.5 of normalised masses. Normalisation makes the weight mean the
///    same on every mesh (the total absolute curvature varies widely between meshes).
///  - geodesic: area weight 0.9, curvature not normalised (geodesics want more curvature than
///    Poisson: with normalisation the best weight is small and still loses to QEM). Chosen with
///    the geodesic pipeline of the tools (coarse fast marching on traced, curvature-corrected
///    lengths, tracked sources, 1 subdivision) against exact polyhedral geodesics; 0.9 was the best
///    weight on the default meshes and on CGAL's alike.
/// Curvature only (area weight 0, the ICE paper's metric and CoarsenOptions' own default) was never
/// best for any of the three problems (same section).
CoarsenOptions recommended_coarsen_options(ProxyUse use = ProxyUse::poisson_heat);

struct CoarseSpaceOptions {
  CoarseningMethod method = CoarseningMethod::ice;
  /// Target (target_vertices / target_ratio), max_error, area_weight, locked_vertices, remove_boundary,
  /// threads and progress of ICE. QEM uses the target, locked_vertices and remove_boundary; it has no
  /// error bound of ICE's kind (a finite max_error with QEM throws std::invalid_argument).
  /// Defaults: recommended_coarsen_options() (the metric chosen for Poisson and heat).
  CoarsenOptions coarsen = recommended_coarsen_options();
  /// With QEM only.
  QemGeometry qem_geometry = QemGeometry::extrinsic;
  /// A mesh that needs the tufted cover (needs_tufted_cover): refused, or coarsened through its
  /// cover (build_coarse_space of a TuftedCover: ICE only). An oriented manifold is coarsened as it
  /// is either way, to the same bits.
  NonmanifoldInput nonmanifold = NonmanifoldInput::refuse;
  /// Keep the method's own result in CoarseSpace (the coarsened triangulation with every input
  /// vertex's location, or the QEM result with its mesh and closest-point map): for the map file,
  /// validation, refinement. Off by default: the PDE tools free it before the fine solves.
  bool keep_method_state = false;
  /// ICE with keep_method_state: the triangulation also records its history of local operations
  /// (IntrinsicTriangulation::record_history), so that trace_coarse_mesh draws every coarse edge
  /// exactly (ice/coarse_tracing.h). Costs memory in proportion to the removals
  /// (docs/measurements.md, "Coarse tracing: the exact pull-back").
  bool record_history = false;
  /// ICE: coarsen in a copy of the mesh renumbered for memory locality (vertices in the Z-order of
  /// their positions, faces by their first vertex) and give the result back in the mesh's
  /// numbering. Same method, other tie-breaks and thread regions, so not bit-identical to a run
  /// without it; on large meshes the triangulation builds and the coarsening runs markedly faster
  /// (docs/measurements.md, "Locality numbering"). Off: the coarsener works in the input's numbering.
  bool locality_numbering = true;
  /// ICE only: intrinsic Delaunay refinement of the coarse mesh after coarsening (ice/refinement.h),
  /// inserted vertices becoming coarse vertices of their own (P gains their columns; their places on
  /// the input surface are CoarseSpace::inserted). Absent: none. With QEM: std::invalid_argument.
  std::optional<RefinementOptions> refinement;
};

/// What QEM did (ice/qem.h, QemResult).
struct QemOutcome {
  Index collapses = 0;
  bool guard_relaxed = false;                  ///< the normal-flip guard was dropped to reach the target
  double max_distance = 0, mean_distance = 0;  ///< closest-point distances of collapsed vertices (absolute)
  double decimate_seconds = 0, map_seconds = 0;
  QemGeometry geometry = QemGeometry::extrinsic;
  Index intrinsic_delaunay_flips = 0;          ///< with QemGeometry::intrinsic_delaunay
};

/// One summary for both methods; the method's own details are in exactly one of `ice` / `qem`.
struct CoarseSpaceSummary {
  CoarseningMethod method = CoarseningMethod::ice;
  Index input_vertices = 0, coarse_vertices = 0, coarse_faces = 0;
  /// The vertex target was met (for ICE: stop_reason == TargetReached; a --max-error-only run reports
  /// ErrorThreshold here as false).
  bool target_reached = false;
  double seconds = 0;                ///< the whole call: coarsening, map, coarse mesh and P
  /// Coarsened through the input's tufted cover (build_coarse_space of a TuftedCover).
  bool tufted_cover = false;
  /// ICE: where `seconds` went besides coarsen() (whose phases are in `ice`): numbering the mesh for
  /// locality and building its intrinsic triangulation, then the compact coarse mesh and P.
  double triangulation_seconds = 0, prolongation_seconds = 0;
  /// When the call made the fine intrinsic Delaunay mesh too (build_coarse_space's `fine_delaunay`):
  /// its time, which `seconds` leaves out (not stored with a coarse space: 0 once restored).
  double fine_mesh_seconds = 0;
  std::optional<CoarsenResult> ice;  ///< method == ice: removals, stop reason, costs
  std::optional<QemOutcome> qem;     ///< method == qem
  std::optional<RefinementResult> refinement;  ///< when refinement was asked for
  double refinement_seconds = 0;
  /// Removals (ICE) or collapses (QEM).
  Index removed() const;
  /// ICE's stop reason; for QEM TargetReached or NothingRemovable (no further collapse was legal).
  StopReason stop_reason() const;
};

struct CoarseSpace {
  /// The coarse intrinsic mesh (faces, lengths, gluing, vertex maps). Vertices inserted by refinement
  /// come last, with to_input kInvalid.
  CompactMesh mesh;
  /// Where each inserted vertex lies on the input surface (a face of the input mesh and barycentric
  /// coordinates), in the order of those last coarse vertices. Empty without refinement. With
  /// record_history, each pulled back through the history (exact); else located by laying out the
  /// input triangles around it by the map (ice::locate_inserted_vertices: approximate where the map
  /// bends input triangles; docs/measurements.md, "Locating inserted vertices without the history").
  std::vector<InputSurfacePoint> inserted;
  Eigen::SparseMatrix<double> P;   ///< fine (input) vertices × coarse vertices
  CoarseSpaceSummary summary;
  /// With keep_method_state and ICE: the coarsened triangulation. Its input vertex t is the mesh's
  /// vertex triangulation_order[t] (empty: t itself); `mesh` is its compact() with the vertex
  /// numbers translated to the mesh's and the coarse vertices listed in increasing input order.
  std::optional<IntrinsicTriangulation> triangulation;
  std::vector<Index> triangulation_order;
  /// With record_history: the mesh's face of each face slot the triangulation was built with (same
  /// corner order; empty: slot f is face f).
  std::vector<Index> triangulation_face_order;
  /// With keep_method_state through a tufted cover: per input vertex, the triangulation's input
  /// vertex (one of its copies on the cover) whose location fine_to_coarse_map reads — a surviving
  /// copy when there is one (the vertex's coarse vertex), else the copy of largest area.
  std::vector<Index> mapped_copy;
  /// With keep_method_state and QEM: its result (the QEM mesh, the map; its P is moved into P above).
  std::optional<QemResult> qem_result;

  CoarseSpace() = default;
  CoarseSpace(const CoarseSpace&) = default;
  CoarseSpace& operator=(const CoarseSpace&) = default;
  /// Moves hand P over: Eigen 3.4's SparseMatrix has no move operations (std::move would copy it).
  CoarseSpace(CoarseSpace&& other) noexcept;
  CoarseSpace& operator=(CoarseSpace&& other) noexcept;
};

/// Coarsens `mesh` (clean, oriented, manifold: e.g. from ice::load_mesh; any clean_but_for_sheets()
/// mesh with options.nonmanifold = tufted_cover) by options.method.
/// Throws std::invalid_argument on bad options (those of ice::coarsen / ice::qem_coarsen) and
/// std::runtime_error when a QEM mesh with QemGeometry::intrinsic_delaunay has a degenerate face.
///
/// With `fine_delaunay`, also fills it with fine_mesh(mesh, FineGeometry::intrinsic_delaunay) (the
/// same arrays to the last bit): ICE flips a copy of the triangulation it starts from instead of
/// building that triangulation again.
CoarseSpace build_coarse_space(const TriangleMesh& mesh, const CoarseSpaceOptions& options,
                               FineMesh* fine_delaunay = nullptr);

/// What build_coarse_space does with a QEM decimation already made (ice::qem_coarsen): the coarse
/// space of `geometry`, for callers that compare both geometries of one decimation (ice-report).
/// summary.seconds covers this call only (the decimation's times are in summary.qem).
CoarseSpace coarse_space_from_qem(QemResult qem, QemGeometry geometry, bool keep_method_state = false);

/// The fine-to-coarse map: one CoarsePoint (ice/mesh.h) per input vertex, faces in space.mesh's numbering (for
/// ICE the points the coarsened triangulation tracked, for QEM its closest-point map). Its rows
/// agree with P (P(i, ·) is point i's barycentric coordinates summed over repeated corners), except
/// through a tufted cover: there a vertex's point is that of one copy (CoarseSpace::mapped_copy)
/// while P's row averages all its copies' (the point's corners are among the row's columns).
/// Preconditions: the space was built with keep_method_state; a QEM space has extrinsic geometry
/// (with QemGeometry::intrinsic_delaunay the points lie in the QEM mesh's faces, not in
/// space.mesh's: see space.qem_result->map). Throws std::invalid_argument otherwise.
std::vector<CoarsePoint> fine_to_coarse_map(const CoarseSpace& space);

/// Positions of the coarse vertices on the input surface (for drawing): a survivor's input position,
/// an inserted vertex's point of its input face. Preconditions: `space` was built from `mesh`.
Positions coarse_vertex_positions(const TriangleMesh& mesh, const CoarseSpace& space);

/// The fine mesh's discretisation for the PDE solvers (and the Galerkin coarse operators).
enum class FineGeometry {
  input,               ///< the input triangles with their extrinsic edge lengths
  intrinsic_delaunay,  ///< the input's intrinsic Delaunay triangulation: same vertices, every cotan weight ≥ 0
};
const char* to_string(FineGeometry geometry);

/// The fine intrinsic mesh, in the input's vertex numbering (vertex_count: the input's). A mesh that
/// needs the tufted cover: fine_mesh(tufted_cover(mesh), geometry) when `nonmanifold` says so. With
/// FineGeometry::input the input's faces, glued by vertex pairs (`twin` empty); with
/// intrinsic_delaunay faces in an order of their own (the triangulation is built and flipped in the
/// locality numbering of build_coarse_space, for speed: docs/measurements.md, "Locality numbering")
/// and their gluing (flips can join two vertices by two edges, which vertex pairs cannot tell apart).
struct FineMesh : IntrinsicMesh {
  FineGeometry geometry = FineGeometry::intrinsic_delaunay;
  Index flips = 0;  ///< intrinsic Delaunay flips made
};
FineMesh fine_mesh(const TriangleMesh& mesh, FineGeometry geometry, NonmanifoldInput nonmanifold = NonmanifoldInput::refuse);

// ---- meshes that are not oriented manifolds: through their tufted cover (ice/tufted_cover.h) ----

/// The coarse space of a mesh through its tufted cover `cover` (tufted_cover(mesh)), on the mesh's
/// own vertices: ICE coarsens the cover (a closed, oriented Δ-complex); the surviving copies of one
/// input vertex are then one coarse vertex (as the fine mesh's copies are one fine vertex: the coarse
/// mesh's faces are named by it and keep the cover's gluing), and P = W·P_cover·S with
/// W = cover_to_input(cover, cover_vertex_areas(cover)) (an input vertex's value is the area-weighted
/// mean of its copies') and S summing the columns of a coarse vertex's copies. Rows of P sum to 1;
/// a locked input vertex (all its copies locked) has a unit row. mesh.to_input and mesh.from_input
/// map coarse and input vertices both ways.
/// The method's state (keep_method_state) is that of the cover (its vertices are copies, in the
/// numbering of distinct_sheets(cover)), with mapped_copy for fine_to_coarse_map.
/// With `fine_delaunay`: the fine mesh of fine_mesh(cover, FineGeometry::intrinsic_delaunay).
/// Throws std::invalid_argument for QEM (it decimates an extrinsic surface; the cover's sheets
/// coincide in space) and for refinement, and on bad options as build_coarse_space.
CoarseSpace build_coarse_space(const TuftedCover& cover, const CoarseSpaceOptions& options, FineMesh* fine_delaunay = nullptr);

/// The fine discretisation of a mesh through its cover, on the mesh's own vertices: the cover's
/// triangles (FineGeometry::input) or their intrinsic Delaunay triangulation, each corner named by
/// its input vertex, with the cover's gluing (a vertex then has one fan per copy). Its cotan
/// Laplacian and lumped mass are twice the mesh's own on an oriented manifold; on any other mesh,
/// with intrinsic_delaunay, (twice) the robust Laplacian of Sharp & Crane.
FineMesh fine_mesh(const TuftedCover& cover, FineGeometry geometry);

/// The same fine mesh with the copies left apart (vertex_count: the cover's vertices): an oriented
/// Δ-complex, where tangent vectors live (one tangent plane per copy, ice::proxy's vector fields).
FineMesh fine_mesh_on_copies(const TuftedCover& cover, FineGeometry geometry);

/// The coarse space of the cover's copies, left apart as build_coarse_space(cover) makes it before
/// the copies of one input vertex become one coarse vertex: P is copies × coarse copies, mesh.to_input
/// names copies, and with keep_method_state fine_to_coarse_map gives one point per copy (the space
/// is that of `cover` as an oriented Δ-complex, with a boundary where it was made without boundary
/// tufts: summary.tufted_cover is false). Pass distinct_sheets' result (a mirror sheet would be
/// coarsened twice otherwise). Target and preconditions as build_coarse_space(cover); locked input
/// vertices lock every copy, and nothing else is locked (the copies join nothing to keep joined).
CoarseSpace build_coarse_space_on_copies(const TuftedCover& cover, const CoarseSpaceOptions& options);

}  // namespace ice
