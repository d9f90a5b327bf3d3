#pragma once
/// \file app_common.h
/// Pieces shared by the ICE command-line tools (ice-coarsen, geodesic-coarse, poisson-coarse):
/// exit codes and error handling, timers, peak memory, a progress bar, mesh loading, the coarsening
/// target options, output-file checks, JSON reports and the fine/coarse discretisations of the
/// coarse-proxy solvers.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/SparseCore>
#include <nlohmann/json.hpp>

#include "fem/coarse_proxy.h"
#include "ice/coarse_space.h"
#include "ice/coarsen.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_io.h"
#include "ice/qem.h"

namespace app {

// ---- exit codes and errors ------------------------------------------------------------------------

/// Exit statuses of every tool (ice-info uses the first five with the same meaning).
enum ExitCode {
  kOk = 0,
  kUnreadable = 1,  ///< an input file (mesh, right-hand side, lock list) is missing or unreadable
  kDefective = 2,   ///< the mesh is refused by the loading policy or unsuitable for the tool
  kNotWritten = 3,  ///< an output exists (and no --force) or could not be written
  kUsage = 4,       ///< bad command line: unknown option, bad value, index out of range, ...
  kFailed = 5,      ///< the computation failed (solver breakdown, --validate found a problem, ...)
};

/// An error with the exit status it should produce; what() is printed after "<tool>: ".
class AppError : public std::runtime_error {
 public:
  AppError(ExitCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ExitCode code() const { return code_; }

 private:
  ExitCode code_;
};

/// Parses the command line. Returns -1 to go on, or the status to exit with (0 after --help,
/// kUsage after a parse error, whose message CLI11 has printed).
int parse_command_line(CLI::App& cli, int argc, char** argv);

/// Runs `body` and turns exceptions into "<tool>: message" on stderr and the matching exit status:
/// AppError → its code, ice::MeshError → kUnreadable / kDefective / kNotWritten by kind,
/// std::bad_alloc and any other std::exception → kFailed.
int run_tool(const std::string& tool, const std::function<int()>& body);

/// Prints "<tool>: warning: message" on stderr.
void warn(const std::string& tool, const std::string& message);

// ---- time, memory, progress -------------------------------------------------------------------------

/// Wall-clock stopwatch (steady clock).
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }
  /// Seconds since construction or the previous lap(), and restarts.
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - start_).count();
    start_ = now;
    return s;
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

/// Peak resident set size of this process so far, in MiB (getrusage ru_maxrss).
double peak_rss_mb();

/// True when stderr is a terminal.
bool stderr_is_terminal();

/// A one-line progress bar on stderr, redrawn at most 10 times per second. Draws nothing when
/// disabled (construct it with `enabled = !quiet && stderr_is_terminal()`).
class ProgressBar {
 public:
  ProgressBar(std::string label, bool enabled) : label_(std::move(label)), enabled_(enabled) {}
  ~ProgressBar() { finish(); }
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  /// fraction in [0, 1]; detail is printed after the percentage.
  void update(double fraction, const std::string& detail);
  /// Clears the line (idempotent).
  void finish();

 private:
  std::string label_;
  bool enabled_;
  bool drawn_ = false;
  Stopwatch since_draw_;
};

// ---- formatting -------------------------------------------------------------------------------------

/// 1234567 → "1,234,567".
std::string thousands(long long value);
/// Fixed-point with `digits` decimals.
std::string fixed(double value, int digits);
/// A percentage with 2 significant decimals for small values: 0.01234 → "1.23%".
std::string percent(double fraction);
/// CLI11 checks that say in the tools' own words what an option allows (CLI11 prefixes the option
/// name): a number > 0, an integer >= 0, a number in [low, high], an integer in [low, high].
CLI::Validator positive_number();
CLI::Validator non_negative_integer();
CLI::Validator number_between(double low, double high);
CLI::Validator integer_between(long long low, long long high);
/// The same for a report value; null (an undefined relative error) prints as "undefined".
std::string percent(const nlohmann::json& fraction);

// ---- input ------------------------------------------------------------------------------------------

/// Loads and validates a mesh (ice::load_mesh_with_report); throws the MeshError of the loader.
ice::LoadResult load_input_mesh(const std::string& path, bool repair);

/// Maps a 0-based vertex index of the input *file* to the loaded mesh's index (they differ only
/// when --repair dropped vertices). Throws AppError(kUsage) naming `what` when out of range or
/// dropped.
int mesh_vertex_of_file_vertex(const ice::LoadResult& loaded, long long file_vertex, const std::string& what);

/// Parses "3,17,42" (commas and/or spaces). Throws AppError(kUsage) naming `what` on junk.
std::vector<long long> parse_index_list(const std::string& text, const std::string& what);

/// Reads whitespace- or comma-separated numbers from a text file; '#' starts a comment.
/// Throws AppError(kUnreadable) naming the file, line and token on anything else.
std::vector<double> read_number_file(const std::string& path);

/// The fine mesh's connected components must be 1 for the PDE tools (heat method and zero-mean
/// Poisson pin one vertex). Throws AppError(kDefective) otherwise.
void require_connected(const ice::LoadResult& loaded, const std::string& path, const std::string& tool);

// ---- coarsening -------------------------------------------------------------------------------------

/// The stopping rule chosen on the command line: exactly one of --vertices, --ratio, --max-error.
struct TargetOptions {
  long long vertices = 0;
  double ratio = 0;
  long long min_vertices = 0;
  double max_error = std::numeric_limits<double>::infinity();
  double area_weight = 0;
  ice::CoarseningMethod method = ice::CoarseningMethod::ice;  ///< --method ice|qem
  int threads = 1;             ///< ICE coarsening threads (ice::CoarsenOptions::threads)
  /// The options as added by add_to: whether a target was given at all (a given 0 is out of range,
  /// not "no target").
  const CLI::Option* vertices_option = nullptr;
  const CLI::Option* ratio_option = nullptr;
  /// Adds --vertices, --ratio, --min-vertices (and --max-error if asked), --area-weight, --method
  /// and --coarsen-threads.
  void add_to(CLI::App& cli, bool with_max_error);
  /// Checks the values against an input of n vertices and fills `options` (target, error, area
  /// weight, threads). Throws AppError(kUsage) with a clear message on a bad combination or value.
  void apply(ice::CoarsenOptions& options, long long n) const;
};

/// The command-line spelling of each method choice (--method, --qem-operators, --operators); the
/// options parse these names straight into the enums.
std::string cli_name(ice::CoarseningMethod method);
std::string cli_name(ice::QemGeometry geometry);
std::string cli_name(fem::CoarseOperatorKind kind);

/// Sets options.progress to draw a progress bar on stderr (when `show_progress` and stderr is a
/// terminal); the bar lives in the returned object, which must outlive the coarsening.
std::unique_ptr<ProgressBar> attach_progress_bar(ice::CoarsenOptions& options, ice::Index start_vertices,
                                                 bool show_progress);

/// Runs ice::coarsen on T, with a progress bar on stderr when `show_progress` (and stderr is a
/// terminal). Any progress callback already in `options` is replaced.
ice::CoarsenResult coarsen_with_progress(ice::IntrinsicTriangulation& T, ice::CoarsenOptions options,
                                         bool show_progress);

/// Prints a warning when the coarsening stopped before its vertex target (either method).
void warn_if_target_missed(const std::string& tool, const ice::CoarseSpaceSummary& summary,
                           const ice::CoarsenOptions& options);

/// The "coarse" object of the JSON reports: vertices, faces, stop_reason, removed (ICE removals or
/// QEM collapses), and for ICE its removal details (failed removals by status, costs).
nlohmann::json coarsen_json(const ice::CoarsenResult& result, const ice::CompactMesh& coarse);
nlohmann::json coarsen_json(const ice::CoarseSpaceSummary& summary);

/// The "qem" object of the JSON reports (mapping, guard, distances, times, geometry of the coarse mesh).
nlohmann::json qem_json(const ice::QemOutcome& qem, bool target_reached);

// ---- output -----------------------------------------------------------------------------------------

/// Throws AppError(kNotWritten) if `path` exists and !overwrite (the tools call it for every output
/// before doing any work), or if its directory does not exist.
void check_output(const std::string& path, bool overwrite, const std::string& option);

/// Writes `report` (pretty-printed) to `path`. Throws AppError(kNotWritten) on failure or when it
/// exists and !overwrite.
void write_json_file(const std::string& path, const nlohmann::json& report, bool overwrite);

/// The fields every report shares: tool, mesh, peak_rss_mb (at call time).
nlohmann::json report_header(const std::string& tool, const std::string& mesh_path);

// ---- the coarse proxy of the PDE tools ----------------------------------------------------------------

/// Adds --operators intrinsic|galerkin.
void add_operators_option(CLI::App& cli, fem::CoarseOperatorKind& operators);

/// The coarse proxy of the PDE tools: the fine discretisation, the coarse space and its P, with coarse
/// operators of `kind`, lumped mass.
fem::CoarseProxy make_proxy(const ice::FineMesh& fine, const ice::CoarseSpace& coarse, fem::CoarseOperatorKind kind);

// ---- the coarse-proxy PDE tools (geodesic-coarse, poisson-coarse) ------------------------------------

/// The command-line options both PDE tools share.
struct PdeOptions {
  std::string mesh;
  TargetOptions target;
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::intrinsic;
  ice::QemGeometry qem_geometry = ice::QemGeometry::extrinsic;  ///< --qem-operators extrinsic|idt
  bool fine_idt = true;
  std::string output;  ///< PLY
  bool no_reference = false;
  std::string report;  ///< JSON
  bool quiet = false, force = false, repair = false, ascii = false;
  /// Adds every shared option (the mesh positional, the target, --operators, --method, --area-weight,
  /// --fine-idt/--no-fine-idt, --output, --ascii, --no-reference, --report, -q, --force, --repair).
  void add_to(CLI::App& cli, const std::string& field_names);
  /// Refuses existing outputs (without --force) and bad extensions before any work.
  void check_outputs() const;
  /// The fine discretisation chosen by --fine-idt / --no-fine-idt.
  ice::FineGeometry fine_geometry() const;
};

/// Timings, sizes and outcome of one coarse-proxy run, with the parts of the report and of the human
/// summary that both PDE tools share.
struct PdeRun {
  std::string tool, mesh_path;
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::intrinsic;
  long long fine_vertices = 0, fine_faces = 0;
  ice::CoarseSpaceSummary coarsening;  ///< method, sizes, outcome (ICE or QEM details)
  bool fine_idt = true;
  long long idt_flips = 0;
  bool proxy_uses_fine_mesh = false;  ///< the proxy needed the fine discretisation (Galerkin, M f)
  bool has_reference = false;
  double load = 0, coarsen = 0, fine_mesh = 0, assemble = 0, factor = 0, solve = 0, prolong = 0, write = 0;
  double ref_assemble = 0, ref_factor = 0, ref_solve = 0;

  /// coarsen + assemble + factor + solve + prolong. The fine mesh (intrinsic Delaunay or input
  /// lengths) is a choice of fine discretisation shared by both sides: timed apart, in neither total.
  double proxy_total() const;
  /// reference assemble + factor + solve.
  double reference_total() const;
  /// tool, mesh, method, operators, input, coarse, fine_mesh, timings_s (incl. reference and
  /// proxy_total), speedup (when there is a reference), peak_rss_mb, blas.
  nlohmann::json report() const;
  /// Sizes, the phase table and the speed-ups.
  void print_summary(std::ostream& out) const;
};

/// ice::build_coarse_space with the method, QEM geometry and progress bar of `opt`; warns if the
/// target was missed and records the summary in `run`.
ice::CoarseSpace coarsen_for_pde(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                 PdeRun& run);

/// The demo right-hand side of poisson-coarse and ice-report: three Gaussian bumps
/// exp(−|x − c|²/(2σ²)) with weights +1, −1, +1 centred at the vertices of largest x, y and z,
/// σ = 0.1 × the bounding-box diagonal (its mean is not removed: see remove_mean).
Eigen::VectorXd demo_poisson_rhs(const ice::TriangleMesh& mesh);
/// f minus its mass-weighted mean (the compatible right-hand side of a zero-mean Neumann problem).
Eigen::VectorXd remove_mean(const Eigen::VectorXd& f, const Eigen::SparseMatrix<double>& mass);

}  // namespace app
