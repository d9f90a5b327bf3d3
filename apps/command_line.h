#pragma once
/// \file command_line.h
/// The command line of the ICE tools: exit codes and the error handling that produces them, option
/// checks in the tools' own words, the coarsening-target and PDE options, and the names of the
/// method enums. Reports and formatting: reports.h; what the tools share beyond that: app_common.h.
#include <functional>
#include <limits>
#include <map>
#include <stdexcept>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "fem/coarse_proxy.h"
#include "fem/multigrid.h"
#include "ice/hierarchy.h"
#include "ice/coarse_space.h"
#include "ice/mesh_io.h"
#include "ice/coarsen.h"
#include "ice/proxy/policies.h"
#include "ice/proxy/store.h"

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

// ---- option checks and lists ----------------------------------------------------------------------

/// CLI11 checks that say in the tools' own words what an option allows (CLI11 prefixes the option
/// name): a number > 0, an integer >= 0, a number in [low, high], an integer in [low, high].
CLI::Validator positive_number();
CLI::Validator non_negative_integer();
CLI::Validator number_between(double low, double high);
CLI::Validator integer_between(long long low, long long high);
/// Parses "3,17,42" (commas and/or spaces). Throws AppError(kUsage) naming `what` on junk.
std::vector<long long> parse_index_list(const std::string& text, const std::string& what);
/// Parses "30,-12.5,1e-3" (commas): finite numbers. Throws AppError(kUsage) naming `what` on an empty
/// or non-numeric entry.
std::vector<double> parse_number_list(const std::string& text, const std::string& what);

/// The stopping rule chosen on the command line: exactly one of --vertices, --ratio, --max-error.
struct TargetOptions {
  long long vertices = 0;
  double ratio = 0;
  long long min_vertices = 0;
  double max_error = std::numeric_limits<double>::infinity();
  /// ICE metric: the measured defaults for Poisson and heat (ice::recommended_coarsen_options);
  /// use_defaults_for picks another use's before add_to.
  double area_weight = ice::recommended_coarsen_options().area_weight;
  bool normalize_curvature = ice::recommended_coarsen_options().normalize_curvature;
  ice::CoarseningMethod method = ice::CoarseningMethod::ice;  ///< --method ice|qem
  int threads = 0;             ///< ICE coarsening threads (ice::CoarsenOptions::threads)
  int regions = 0;             ///< regions of the parallel phase (ice::CoarsenOptions::regions)
  /// --refine-angle DEG (0: no refinement) and --refine-budget R: intrinsic Delaunay refinement of
  /// the ICE coarse mesh (ice::RefinementOptions).
  double refine_angle = 0;
  double refine_budget = ice::RefinementOptions().max_vertex_ratio;
  /// The refinement asked for, if any (checked by apply()).
  std::optional<ice::RefinementOptions> refinement() const;
  /// The options as added by add_to: whether a target was given at all (a given 0 is out of range,
  /// not "no target").
  const CLI::Option* vertices_option = nullptr;
  const CLI::Option* ratio_option = nullptr;
  /// The metric defaults measured for `use` (call before add_to, so --help shows them).
  void use_defaults_for(ice::ProxyUse use);
  /// Adds --vertices, --ratio, --min-vertices (and --max-error if asked), --area-weight,
  /// --normalize-curvature/--no-normalize-curvature, --method, --coarsen-threads, --coarsen-regions,
  /// --refine-angle and --refine-budget.
  void add_to(CLI::App& cli, bool with_max_error);
  /// Checks the values against an input of n vertices and fills `options` (target, error, area
  /// weight, threads, regions). Throws AppError(kUsage) with a clear message on a bad combination or
  /// value.
  void apply(ice::CoarsenOptions& options, long long n) const;
};

/// Adds --coarsen-threads and --coarsen-regions (ice::CoarsenOptions::threads and ::regions).
void add_coarsen_parallel_options(CLI::App& cli, int& threads, int& regions);

/// Adds an option whose value is one of `names` (the spellings, listed in --help as {a,b}=default),
/// stored as the matching enum value; any other value is a usage error naming the choices.
template <class Enum>
CLI::Option* add_choice(CLI::App& cli, const std::string& name, Enum& value, const std::map<std::string, Enum>& names,
                        const std::string& description) {
  std::vector<std::string> spellings;
  std::string default_name;
  for (const auto& [spelling, entry] : names) {
    spellings.push_back(spelling);
    if (entry == value) default_name = spelling;
  }
  return cli
      .add_option_function<std::string>(
          name, [&value, names](const std::string& text) { value = names.at(text); }, description)
      ->check(CLI::IsMember(spellings))
      ->default_str(default_name);
}

/// The choices of an enum as the options parse them: its spellings and aliases (ice::proxy::spellings).
template <class Enum>
std::map<std::string, Enum> choice_names() {
  const auto& table = ice::proxy::spellings<Enum>();
  return std::map<std::string, Enum>(table.begin(), table.end());
}

/// Throws AppError(kNotWritten) if `path` exists and !overwrite (the tools call it for every output
/// before doing any work), or if its directory does not exist (ice::check_writable's policy).
void check_output(const std::string& path, bool overwrite, const std::string& option);
/// The store of set-up proxies in `directory`, or the default one (ice::proxy::default_store_options:
/// $ICE_CACHE, the XDG cache folder) when it is empty; throws AppError(kUsage) on a malformed
/// $ICE_CACHE_MAX_MB.
ice::proxy::Store store_at(const std::string& directory);
/// The store of set-ups (ice/proxy/store.h) a tool uses: --cache DIR, or the default
/// (ice::proxy::default_store_options: $ICE_CACHE, the XDG cache folder); off with --no-cache.
struct CacheOptions {
  std::string directory;
  bool off = false;
  void add_to(CLI::App& cli);
  /// The store these options name; throws AppError(kUsage) on a malformed $ICE_CACHE_MAX_MB.
  ice::proxy::Store store() const { return off ? ice::proxy::Store() : store_at(directory); }
};
/// The extension of `path` in lower case, with its dot (".npy").
std::string lower_extension(const std::string& path);
/// Whether two paths name one file (also when written differently: ./a and a).
bool same_file(const std::string& a, const std::string& b);

/// Adds --operators intrinsic|galerkin.
void add_operators_option(CLI::App& cli, fem::CoarseOperatorKind& operators);
/// Adds the option `name` (auto|barycentric|smoothed|smoothed_twice; empty `description`: --prolongation's help).
void add_prolongation_option(CLI::App& cli, ice::proxy::Prolongation& choice, const std::string& name = "--prolongation",
                             const std::string& description = "");
/// ice::proxy::resolve_prolongation for a problem where `needs_barycentric` names what rules out a
/// smoothed P (e.g. "--fix"; empty: nothing), for `use`. Throws AppError(kUsage), naming `option`,
/// for an explicit smoothed choice that cannot be honoured.
fem::ProlongationKind resolve_prolongation(ice::proxy::Prolongation choice, fem::CoarseOperatorKind operators,
                                           const std::string& needs_barycentric = "",
                                           const std::string& option = "--prolongation",
                                           ice::proxy::ProlongationUse use = ice::proxy::ProlongationUse::solves);

// ---- the command line both PDE tools share (geodesic-coarse, poisson-coarse) ---------------------------

/// The exact route's options (--mg-*): the hierarchy's and the solver's, straight into
/// ice::HierarchyOptions and fem::MultigridOptions.
struct MultigridCli {
  ice::HierarchyOptions hierarchy;
  fem::MultigridOptions options;
  void add_to(CLI::App& cli);
};

/// The command-line options the PDE tools share.
struct PdeOptions {
  std::string mesh;
  TargetOptions target;
  /// Galerkin by default: more accurate than intrinsic for ICE on every problem and area weight
  /// measured (docs/measurements.md, "ICE metric defaults"), e.g. 0.89x the intrinsic error
  /// (geometric mean) at the defaults.
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::galerkin;
  /// The prolongation the proxy solves with (fem::ProlongationKind): resolved by poisson-coarse from
  /// its --prolongation (resolve_prolongation); the other tools keep the barycentric P (geodesics by
  /// marching read it, and gain nothing from smoothing).
  fem::ProlongationKind prolongation = fem::ProlongationKind::barycentric;
  ice::QemGeometry qem_geometry = ice::QemGeometry::extrinsic;  ///< --qem-operators extrinsic|idt
  /// --nonmanifold refuse|tufted and --separate-thin-parts (add_nonmanifold_option), for the tools
  /// that solve on the cover.
  ice::NonmanifoldInput nonmanifold = ice::NonmanifoldInput::refuse;
  bool separate_thin_parts = false;
  void add_nonmanifold_option(CLI::App& cli);
  /// The load options of the input: --repair, non-manifold parts kept with --nonmanifold tufted, and
  /// point clouds' fans with --separate-thin-parts.
  ice::LoadOptions load_options() const;
  bool fine_idt = true;
  std::string output;  ///< PLY or binary glTF (.glb)
  std::string html;    ///< the interactive 3D page (app/view_page.h)
  /// --solutions FILE.npy of the tools that write several solutions or states (added by each tool).
  std::string solutions;
  /// False when the run has no coarse space (poisson-coarse --solver direct|multigrid): no coarse
  /// edges or page to draw.
  bool has_coarse_space = true;
  bool no_reference = false;
  std::string report;  ///< JSON
  bool quiet = false, force = false, repair = false, ascii = false;
  /// Adds every shared option (the mesh positional, the target, --operators, --method, --area-weight,
  /// --fine-idt/--no-fine-idt, --output, --ascii, --html, --no-reference, --report, -q, --force, --repair).
  void add_to(CLI::App& cli, const std::string& field_names);
  /// Polishing of the proxy solution (fem::PolishOptions): set by add_polish_options.
  fem::PolishOptions polish;
  /// --polish N, --tolerance T and --polish-sweeps K, for the tools that polish.
  void add_polish_options(CLI::App& cli);
  /// Refuses existing outputs (without --force), bad extensions and outputs naming one file before
  /// any work.
  void check_outputs() const;
  /// Where a PLY --output's companion file of ICE's traced coarse edges goes (NAME_coarse_edges.ply
  /// beside NAME.ply); empty when there is none (no output, glTF output, or QEM).
  std::string coarse_edges_output() const;
  /// Whether --output names a binary glTF file (.glb, any case), else PLY.
  bool output_is_gltf() const;
  /// The fine discretisation chosen by --fine-idt / --no-fine-idt.
  ice::FineGeometry fine_geometry() const;
  /// --cache and --no-cache (CacheOptions), for the tools that set up through the store.
  CacheOptions cache;
  void add_cache_options(CLI::App& cli) { cache.add_to(cli); }
  ice::proxy::Store store() const { return cache.store(); }
};

}  // namespace app
