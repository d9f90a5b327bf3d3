#pragma once
/// \file app_common.h
/// What the ICE tools (ice-info, ice-coarsen, geodesic-coarse, poisson-coarse) and ice-report share
/// beyond the command line (command_line.h) and the reports (reports.h), both included here: loading
/// the input and its side files, the coarsening with a progress bar, the outputs, the demo source. The
/// recipes themselves (coarse proxy, marching lengths, vector proxies) are ICE::proxy's (ice/proxy/setup.h).
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
#include "ice/proxy/multigrid.h"
#include "ice/proxy/setup.h"
#include "reports.h"

namespace app {

// ---- input ------------------------------------------------------------------------------------------

/// Loads and validates a mesh (ice::load_mesh_with_report) and drops the raw soup (`file.soup` is
/// empty; `input_report.n_vertices` is the file's vertex count); throws the MeshError of the loader.
ice::LoadResult load_input_mesh(const std::string& path, bool repair);
ice::LoadResult load_input_mesh(const std::string& path, const ice::LoadOptions& options);

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
                                                 bool show_progress, ice::FineMesh* fine_delaunay = nullptr);

/// Prints a warning when the coarsening stopped before its vertex target (either method).
void warn_if_target_missed(const std::string& tool, const ice::CoarseSpaceSummary& summary,
                           const ice::CoarsenOptions& options);

// ---- the coarse proxy of the PDE tools ----------------------------------------------------------------

/// ice::build_coarse_space with the method, QEM geometry and progress bar of `opt`; warns if the
/// target was missed and records the summary in `run`. `keep_method_state`: keep what
/// ice::fine_to_coarse_map needs (CoarseSpaceOptions::keep_method_state); `record_history`: and
/// what ice::trace_coarse_mesh draws the coarse edges exactly from (CoarseSpaceOptions::record_history).
ice::CoarseSpace coarsen_for_pde(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                 PdeRun& run, bool keep_method_state = false, bool record_history = false);
/// The same for the copies of a tufted cover (ice::build_coarse_space_on_copies, with the method state
/// for the map): what vector fields on a cover are solved through (not through the store). Records the
/// summary (coarse vertices counted per input vertex) and the cover in `run`.
/// AppError(kUsage) naming the file for what a cover does not take (QEM, refinement).
ice::CoarseSpace coarsen_copies_for_pde(const ice::TuftedCover& cover, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                        PdeRun& run);

/// The multigrid hierarchy of `mesh` for the --mg-* options through `store` (ice::proxy::
/// multigrid_hierarchy; through the tufted cover where --nonmanifold tufted asks for it and the mesh
/// needs it), warning as `tool` when a damaged stored entry had to be rebuilt.
ice::proxy::MultigridHierarchy stored_hierarchy(const std::string& tool, const ice::TriangleMesh& mesh, const MultigridCli& mg,
                                                const PdeOptions& opt, const ice::proxy::Store& store);

/// What a PDE tool solves through — the coarse space, the fine discretisation and the coarse proxy —
/// by ice::proxy::build_proxy_setup with the method, QEM geometry, fine mesh, operators and prolongation
/// of `opt`, a progress bar, and a warning when the target was missed or a stored entry was damaged.
/// The method's state is kept with its history for outputs that draw the coarse mesh, the state
/// alone when `keep_method_state` asks (both bypass the store). Without `assemble_proxy` the proxy
/// stays null; `need_fine`: the fine mesh is made also when the proxy does not need it (a reference).
/// Records run.coarsening, coarsen, fine_mesh, fine_built, idt_flips and the cache; the proxy's
/// assembly is left running on `clock`, for the caller's assemble phase.
ice::proxy::ProxySetup build_pde_proxy(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                       PdeRun& run, Stopwatch& clock, bool assemble_proxy = true, bool need_fine = true,
                                       bool keep_method_state = false, const ice::proxy::Store& store = {});

/// The coarse space with its fine-to-coarse map (ice::proxy::build_mapped_space), for the tools that
/// march on the coarse mesh or fit vectors to the map, with the method, QEM geometry and progress bar
/// of `opt`, through `store`; `record_history` keeps what draws the coarse mesh on the surface (and
/// bypasses the store). Warns when the target was missed or a stored entry was damaged; records
/// run.coarsening, run.coarsen and the cache. AppError(kUsage) for bad options, and when
/// `need_map` for QEM with intrinsic Delaunay geometry (no map).
/// `fine_delaunay`: as ice::proxy::build_mapped_space's (filled on a build, not on a hit).
ice::proxy::MappedSpace mapped_space_for_pde(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options,
                                             const PdeOptions& opt, PdeRun& run, const ice::proxy::Store& store, bool need_map,
                                             bool record_history = false, ice::FineMesh* fine_delaunay = nullptr);

/// The marching lengths of `space` through `store` (ice::proxy::stored_marching_lengths), warning
/// when a stored entry was damaged; records space.cache in `run` (and what a hit loaded), and leaves
/// the entries' load and save out of the phase running on `clock`.
ice::SurfaceEdgeLengths stored_marching_lengths(PdeRun& run, Stopwatch& clock, const ice::TriangleMesh& mesh,
                                               ice::proxy::MappedSpace& space, const ice::proxy::Store& store, bool traced,
                                               ice::proxy::CurvatureCorrection correction, double divisor);

/// Whether the outputs of `opt` draw the coarse mesh on the surface (--output or --html of an ICE
/// space; not through a tufted cover, whose coarse mesh is the cover's).
bool outputs_draw_coarse_mesh(const PdeOptions& opt, bool tufted_cover = false);

/// --curvature-correction auto|on|off, for the tools that march on the coarse mesh.
void add_curvature_correction_option(CLI::App& cli, ice::proxy::CurvatureCorrection& correction);

/// The coarse-lengths option (`name`: --coarse-lengths, ice-report's --geodesic-lengths) auto|intrinsic|traced.
void add_coarse_lengths_option(CLI::App& cli, const std::string& name, ice::proxy::CoarseLengths& choice);

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
/// ("poisson", "geodesic"), `error_json` the run's errors (its rel_l2 is shown; null or empty: none);
/// `points`: the input is a point cloud (ice::LoadResult::point_cloud), drawn as points.
void write_result_page(const PdeOptions& opt, const ice::TriangleMesh& mesh, const std::string& title,
                       const std::string& problem, const std::string& name, const Eigen::VectorXd& result,
                       const Eigen::VectorXd& reference, const ice::CoarseSpace& space,
                       const ice::CoarseTracing* tracing, const nlohmann::json& error_json, bool points = false);

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
