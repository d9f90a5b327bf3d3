#pragma once
/// \file app_common.h
/// What the ICE tools (ice-info, ice-coarsen, geodesic-coarse, poisson-coarse) and ice-report share
/// beyond the command line (command_line.h) and the reports (reports.h), both included here: loading
/// the input and its side files, the coarsening with a progress bar, the coarse proxy, the demo source.
#include <array>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/SparseCore>

#include "command_line.h"
#include "fem/coarse_proxy.h"
#include "fem/curvature_correction.h"
#include "fem/vector_fields.h"
#include "ice/coarse_space.h"
#include "ice/coarse_tracing.h"
#include "ice/scalar_field_io.h"
#include "ice/coarsen.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_io.h"
#include "reports.h"

namespace app {

// ---- input ------------------------------------------------------------------------------------------

/// Loads and validates a mesh (ice::load_mesh_with_report) and drops the raw soup (`file.soup` is
/// empty; `input_report.n_vertices` is the file's vertex count); throws the MeshError of the loader.
ice::LoadResult load_input_mesh(const std::string& path, bool repair);

/// 0-based vertex indices of the input *file* → the loaded mesh's indices (they differ only when
/// --repair dropped, welded or split vertices; a split file vertex maps to its first mesh vertex).
/// Built once (O(n)) for callers that map many indices (--pairs, --lock, --fix lists).
class FileVertexMap {
 public:
  explicit FileVertexMap(const ice::LoadResult& loaded);
  /// Throws AppError(kUsage) naming `what` when out of range or dropped.
  int mesh_vertex(long long file_vertex, const std::string& what) const;
  /// The same for an integral number read from a file, range-checked before the integer
  /// conversion (1e30 is no long long).
  int mesh_vertex(double file_vertex, const std::string& what) const;
  /// The mesh vertex, or -1 when out of range or dropped, without building a message: for long
  /// lists, which call mesh_vertex for the message only when this fails.
  int find(double file_vertex) const;

 private:
  std::vector<int> mesh_of_file_;  ///< -1: dropped by --repair
};

/// Reads whitespace- or comma-separated numbers from a text file; '#' starts a comment.
/// Throws AppError(kUnreadable) naming the file, line and token on anything else.
std::vector<double> read_number_file(const std::string& path);

/// With Dirichlet values (--fix), every connected component of the mesh needs one, or its solution
/// is undetermined: throws AppError(kUsage) naming a component (by a vertex of the file) without.
/// Nothing to check without fixed vertices (the zero-mean problem is solved on each component).
void require_fixed_in_every_component(const ice::LoadResult& loaded, const std::vector<int>& fixed_vertices,
                                      const std::string& path);

// ---- coarsening -------------------------------------------------------------------------------------

/// ice::build_coarse_space with a progress bar of the ICE removals on stderr (when `show_progress` and
/// stderr is a terminal), cleared before it returns. Any progress callback in `options` is replaced.
ice::CoarseSpace build_coarse_space_with_progress(const ice::TriangleMesh& mesh, ice::CoarseSpaceOptions options,
                                                 bool show_progress);

/// Prints a warning when the coarsening stopped before its vertex target (either method).
void warn_if_target_missed(const std::string& tool, const ice::CoarseSpaceSummary& summary,
                           const ice::CoarsenOptions& options);

// ---- the coarse proxy of the PDE tools ----------------------------------------------------------------

/// The coarse proxy of the PDE tools: the fine discretisation, the coarse space and its P (smoothed
/// or not), with coarse operators of `kind`, lumped mass.
fem::CoarseProxy make_proxy(const ice::FineMesh& fine, const ice::CoarseSpace& coarse, fem::CoarseOperatorKind kind,
                            fem::ProlongationKind prolongation = fem::ProlongationKind::barycentric);

/// The fine mesh of the vector heat method (vector-coarse, the Python package): the input triangles
/// with their own edge lengths, glued by vertex pairs, and their tangent frames, in which every field
/// is given (one vector per input vertex, drawn on the input triangles); and the method's fine
/// operators in those frames, discretised on the input triangles or (FineGeometry::intrinsic_delaunay,
/// the default) on their intrinsic Delaunay triangulation (fem::vector_heat_operators with a second
/// triangulation), with t = (time_factor · the input's mean edge length)². The operators are only
/// built when asked (`with_operators`): a fine reference or Galerkin coarse operators need them, an
/// intrinsic proxy alone does not.
struct TangentMesh {
  ice::CompactMesh mesh;
  fem::TangentFrames frames;
  std::optional<fem::VectorHeatOperators> operators;
  ice::Index flips = 0;  ///< intrinsic Delaunay flips
};
TangentMesh tangent_mesh(const ice::TriangleMesh& mesh, ice::FineGeometry geometry, bool with_operators,
                         double time_factor = 1.0);

/// The vector proxy through `coarse`, a coarse space of the mesh `fine` was made from, and its
/// fine-to-coarse map (ice::fine_to_coarse_map: ICE, or QEM with extrinsic geometry): the coarse
/// mesh's frames, P_vec fitted from the map, the coarse operators of `kind` (Galerkin ones from
/// fine.operators, which must then have been built: std::logic_error otherwise).
fem::VectorHeatProxy make_vector_proxy(const TangentMesh& fine, const ice::CoarseSpace& coarse,
                                       const std::vector<ice::CoarsePoint>& map, fem::VectorOperatorKind kind,
                                       double time_factor = fem::kVectorProxyTimeFactor);

/// How the vector tools find a field through the coarse mesh: `sweep` (the default) takes the coarse
/// marching distance and the fine connection (fem::VectorSweepProxy), `diffusion` diffuses vectors on
/// the coarse mesh (fem::VectorHeatProxy). Measured (README, Tangent vector fields; 27 shared and
/// project meshes at 5 %, median angle error against the fine method): 0.000° (with the sweep's
/// coarse-grid corrections; 25 meshes, largest 0.00°) against 4.48°.
enum class VectorSolver { sweep, diffusion };
/// The sweep proxy of `mesh` through `coarse`: coarse marching as geodesic-coarse's default (traced
/// lengths for ICE, curvature-corrected, 1 subdivision) and fine.operators (which must have been
/// built: std::logic_error otherwise).
fem::VectorSweepProxy make_vector_sweep(const ice::TriangleMesh& mesh, const TangentMesh& fine, const ice::CoarseSpace& coarse,
                                        const std::vector<ice::CoarsePoint>& map, const fem::DistanceSweepOptions& options = {});

/// ice::build_coarse_space with the method, QEM geometry and progress bar of `opt`; warns if the
/// target was missed and records the summary in `run`. `keep_method_state`: keep what
/// ice::fine_to_coarse_map needs (CoarseSpaceOptions::keep_method_state); `record_history`: and
/// what ice::trace_coarse_mesh draws the coarse edges exactly from (CoarseSpaceOptions::record_history).
ice::CoarseSpace coarsen_for_pde(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                 PdeRun& run, bool keep_method_state = false, bool record_history = false);

/// What a PDE tool solves through: the coarse space, the fine discretisation and the coarse proxy.
struct PdeProxy {
  ice::CoarseSpace coarse;
  ice::FineMesh fine;
  std::unique_ptr<fem::CoarseProxy> proxy;
};
/// Builds them in that order (coarsen_for_pde, keeping the method's state and its history for outputs
/// that draw the coarse mesh, the state alone when `keep_method_state` asks; ice::fine_mesh of
/// --fine-idt unless !need_fine, make_proxy of --operators unless !assemble_proxy: then proxy stays
/// null; assembling needs the fine mesh), with run.coarsen, run.fine_mesh, run.fine_built and
/// run.idt_flips recorded; the proxy's assembly is left running on `clock`, for the caller's assemble
/// phase.
PdeProxy build_pde_proxy(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                         PdeRun& run, Stopwatch& clock, bool assemble_proxy = true, bool need_fine = true,
                         bool keep_method_state = false);

/// Whether coarse marching runs on curvature-corrected lengths (fem/curvature_correction.h): `automatic`
/// for ICE coarse meshes and not for QEM's, as measured (README, Accuracy).
enum class CurvatureCorrection { automatic, on, off };

/// The coarse edge lengths coarse marching runs on: the coarse mesh's own, or (`traced`) those of its
/// edges traced on the input surface by the walk over the fine-to-coarse map (ice::surface_edge_lengths
/// of `map`, or of ice::fine_to_coarse_map(space) when null: an ICE space built with
/// keep_method_state; its history, if recorded for drawing, is not used, so the distances do not
/// depend on what else is written); then curvature-corrected (fem::curvature_corrected_lengths with
/// the input mesh and space.P) as `correction` says. The counts are the walk's (zero for the
/// intrinsic lengths). The tools and the Python bindings all take their marching lengths from here.
/// `divisor`: the correction's strength for the marching that reads them (fem::kProxyCorrectionDivisor
/// for fem::ProxyGeodesicSolver, fem::kOracleCorrectionDivisor for fem::DistanceOracle).
ice::SurfaceEdgeLengths marching_lengths(const ice::TriangleMesh& mesh, const ice::CoarseSpace& space, bool traced,
                                         CurvatureCorrection correction, const std::vector<ice::CoarsePoint>* map = nullptr,
                                         double divisor = fem::kProxyCorrectionDivisor);
/// Whether `correction` corrects marching on a coarse space made by `method` (automatic: ICE's).
bool corrects_curvature(CurvatureCorrection correction, ice::CoarseningMethod method);
/// `lengths` (of space's coarse faces) curvature-corrected with the input `mesh`: its angle defects and
/// vertex areas gathered through space.P (fem::curvature_corrected_lengths).
ice::FaceLengths curvature_corrected_lengths(const ice::TriangleMesh& mesh, const ice::CoarseSpace& space,
                                            const ice::FaceLengths& lengths, double divisor = fem::kProxyCorrectionDivisor);
/// --curvature-correction auto|on|off, for the tools that march on the coarse mesh.
void add_curvature_correction_option(CLI::App& cli, CurvatureCorrection& correction);

/// Which coarse edge lengths coarse marching runs on: `automatic` traces ICE's coarse edges on the
/// input surface (marching_lengths' `traced`) and keeps QEM's own lengths — the default since it
/// was measured (README, Accuracy: against exact geodesics over 40 meshes x 1-10 %, 0.81x the
/// error of the intrinsic lengths and ICE/QEM-iDT's median at 5 % 0.75 against 0.94, at 1.3x the
/// whole run's time); `intrinsic` and `traced` ask for one (traced: ICE only).
enum class CoarseLengths { automatic, intrinsic, traced };
/// Whether the coarse distances trace the coarse edges of a space made by `method` under `choice`:
/// never unless `marching` (the coarse heat method takes no lengths; asking for `traced` there is the
/// caller's usage error, in its own words).
bool traces_lengths(CoarseLengths choice, ice::CoarseningMethod method, bool marching);
/// The coarse-lengths option (`name`: --coarse-lengths, ice-report's --geodesic-lengths) auto|intrinsic|traced.
void add_coarse_lengths_option(CLI::App& cli, const std::string& name, CoarseLengths& choice);

/// The coarse mesh traced on the input (ice/coarse_tracing.h) when an output draws it: --output or
/// --html, and an ICE space built with keep_method_state (build_pde_proxy keeps it for them). Traced
/// once per run, for both.
std::optional<ice::CoarseTracing> trace_for_outputs(const PdeOptions& opt, const ice::TriangleMesh& mesh,
                                                    const ice::CoarseSpace& space);

/// Writes opt.output (nothing without -o), PLY or binary glTF by its extension (.glb: glTF): the
/// input mesh with the per-vertex field `name` (the tool's result), then, given a reference
/// (non-empty), 'reference' and 'error' (= result − reference), then `extra`; with a `tracing`,
/// also 'patch' (the coarse face of each vertex's map point, CoarseTracing::vertex_patch) and the
/// traced coarse edges as lines: in the glTF file, or beside a PLY in opt.coarse_edges_output().
/// glTF colours 'error' if present, else `name`.
void write_result_fields(const PdeOptions& opt, const ice::TriangleMesh& mesh, const std::string& name,
                         const Eigen::VectorXd& result, const Eigen::VectorXd& reference,
                         std::vector<ice::ScalarField> extra = {}, const ice::CoarseTracing* tracing = nullptr);

/// Writes opt.html (nothing without --html): the 3D page (view_page.h) of one run — the input mesh
/// (decimated for display above 200,000 vertices) coloured by `name` (the result), 'reference',
/// 'error' (|result − reference|) and, with a `tracing` of `space`, 'patch' and the traced coarse
/// edges (else the space's straight edges: QEM) — titled `title`; `problem` names the problem
/// ("poisson", "geodesic"), `error_json` the run's errors (its rel_l2 is shown; null or empty: none).
void write_result_page(const PdeOptions& opt, const ice::TriangleMesh& mesh, const std::string& title,
                       const std::string& problem, const std::string& name, const Eigen::VectorXd& result,
                       const Eigen::VectorXd& reference, const ice::CoarseSpace& space,
                       const ice::CoarseTracing* tracing, const nlohmann::json& error_json);

/// The summary's "wrote ..." lines of --output (with the counts of `tracing`, if any), --html and
/// --report.
void print_written(std::ostream& out, const PdeOptions& opt, const ice::CoarseTracing* tracing);


/// The demo right-hand side of poisson-coarse and ice-report: three Gaussian bumps
/// exp(−|x − c|²/(2σ²)) with weights +1, −1, +1 centred at the vertices of largest x, y and z,
/// σ = 0.1 × the bounding-box diagonal (its mean is not removed: see remove_mean).
Eigen::VectorXd demo_poisson_rhs(const ice::TriangleMesh& mesh);
/// f minus its mass-weighted mean (the compatible right-hand side of a zero-mean Neumann problem).
Eigen::VectorXd remove_mean(const Eigen::VectorXd& f, const Eigen::SparseMatrix<double>& mass);

}  // namespace app
