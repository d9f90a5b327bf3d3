#include "command_line.h"

#include <cctype>

#include "view_page.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <new>
#include <sstream>

#include "ice/mesh_io.h"
#include "reports.h"

namespace app {

namespace fs = std::filesystem;

// ---- exit codes and errors ------------------------------------------------------------------------

int parse_command_line(CLI::App& cli, int argc, char** argv) {
  // The usage line names the tool, not the path it was run by (which --help's length would vary with).
  if (cli.get_name().empty() && argc > 0) cli.name(std::filesystem::path(argv[0]).filename().string());
  try {
    cli.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return cli.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return cli.exit(e);
  } catch (const CLI::ParseError& e) {
    cli.exit(e);
    return kUsage;
  }
  return -1;
}

int run_tool(const std::string& tool, const std::function<int()>& body) {
  try {
    return body();
  } catch (const AppError& e) {
    std::cerr << tool << ": " << e.what() << '\n';
    return e.code();
  } catch (const ice::MeshError& e) {
    std::cerr << tool << ": " << e.what() << '\n';
    switch (e.kind()) {
      case ice::MeshError::Kind::Unreadable: return kUnreadable;
      case ice::MeshError::Kind::Defective:
        std::cerr << tool << ": (--repair applies the safe repairs; `ice-info --repair` shows what they do)\n";
        return kDefective;
      case ice::MeshError::Kind::Unwritable: return kNotWritten;
    }
    return kFailed;
  } catch (const std::bad_alloc&) {
    std::cerr << tool << ": out of memory (peak resident set " << fixed(peak_rss_mb(), 0) << " MiB)\n";
    return kFailed;
  } catch (const std::exception& e) {
    std::cerr << tool << ": failed: " << e.what() << '\n';
    return kFailed;
  }
}

void warn(const std::string& tool, const std::string& message) { std::cerr << tool << ": warning: " << message << '\n'; }

// ---- option checks and lists ----------------------------------------------------------------------

namespace {
/// Whole-token parses for the option checks (no trailing junk, finite).
bool parse_number(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size() && std::isfinite(value);
}
/// A number as a person writes it: 0.01, 0.9, 1e-08.
std::string shortest(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}
bool parse_integer(const std::string& text, long long& value) {
  double number = 0;
  if (!parse_number(text, number) || number != std::floor(number) || std::abs(number) > 9e15) return false;
  value = static_cast<long long>(number);
  return true;
}
}  // namespace

CLI::Validator positive_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double value = 0;
        if (!parse_number(text, value)) return "'" + text + "' is not a number";
        return value > 0 ? "" : text + " is not allowed: give a number > 0";
      },
      "> 0");
}

CLI::Validator non_negative_integer() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        long long value = 0;
        if (!parse_integer(text, value)) return "'" + text + "' is not a whole number";
        return value >= 0 ? "" : text + " is not allowed: give a whole number >= 0";
      },
      ">= 0");
}

CLI::Validator number_between(double low, double high) {
  return CLI::Validator(
      [low, high](std::string& text) -> std::string {
        double value = 0;
        if (!parse_number(text, value)) return "'" + text + "' is not a number";
        return value >= low && value <= high ? ""
                                             : text + " is out of range: give a number from " + shortest(low) + " to " +
                                                   shortest(high);
      },
      "in [" + shortest(low) + ", " + shortest(high) + "]");
}

CLI::Validator integer_between(long long low, long long high) {
  return CLI::Validator(
      [low, high](std::string& text) -> std::string {
        long long value = 0;
        if (!parse_integer(text, value)) return "'" + text + "' is not a whole number";
        return value >= low && value <= high ? ""
                                             : text + " is out of range: give a whole number from " + std::to_string(low) +
                                                   " to " + std::to_string(high);
      },
      "in [" + std::to_string(low) + ", " + std::to_string(high) + "]");
}

std::vector<double> parse_number_list(const std::string& text, const std::string& what) {
  std::vector<double> numbers;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    const std::string token = text.substr(begin, end - begin);
    double value = 0;
    if (!parse_number(token, value)) throw AppError(kUsage, what + ": '" + token + "' is not a finite number");
    numbers.push_back(value);
    begin = end + 1;
  }
  return numbers;
}

std::vector<long long> parse_index_list(const std::string& text, const std::string& what) {
  std::vector<long long> out;
  std::string token;
  const auto flush = [&] {
    if (token.empty()) return;
    std::size_t used = 0;
    long long value = 0;
    try {
      value = std::stoll(token, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != token.size()) throw AppError(kUsage, what + ": '" + token + "' is not a vertex index");
    out.push_back(value);
    token.clear();
  };
  for (char c : text) {
    if (c == ',' || c == ' ' || c == '\t')
      flush();
    else
      token += c;
  }
  flush();
  if (out.empty()) throw AppError(kUsage, what + ": no vertex index given");
  return out;
}

// ---- options and names -----------------------------------------------------------------------------

void TargetOptions::use_defaults_for(ice::ProxyUse use) {
  const ice::CoarsenOptions recommended = ice::recommended_coarsen_options(use);
  area_weight = recommended.area_weight;
  normalize_curvature = recommended.normalize_curvature;
}

void add_coarsen_parallel_options(CLI::App& cli, int& threads, int& regions) {
  cli.add_option("--coarsen-threads", threads,
                 "Coarsening threads (0: all cores; same result)")
      ->check(integer_between(0, 64))
      ->capture_default_str();
  cli.add_option("--coarsen-regions", regions,
                 "Regions coarsened in parallel, large meshes (0: 16; 1: serial greedy order)")
      ->check(integer_between(0, 254))
      ->capture_default_str();
}

void TargetOptions::add_to(CLI::App& cli, bool with_max_error) {
  vertices_option = cli.add_option("--vertices,-n", vertices, "Coarsen down to N vertices")
                       ->check(integer_between(1, std::numeric_limits<int>::max()));
  ratio_option = cli.add_option("--ratio,-r", ratio, "Coarsen down to ceil(R * input vertices), e.g. 0.05")
                     ->check(CLI::Validator(
                         [](std::string& text) -> std::string {
                           double value = 0;
                           if (!parse_number(text, value)) return "'" + text + "' is not a number";
                           return value > 0 && value <= 1 ? "" : text + " is out of range: it must be in (0, 1], e.g. 0.05 for 5%";
                         },
                         "in (0, 1]"));
  cli.add_option("--min-vertices", min_vertices,
                 "With --ratio: keep at least M vertices");
  if (with_max_error)
    cli.add_option("--max-error,-e", max_error,
                   "Remove vertices while the cheapest costs at most E (ICE metric); with --vertices/--ratio: whichever "
                   "stops first");
  cli.add_option("--area-weight,-w", area_weight,
                 "Area term's weight in the ICE metric (0: curvature only)")
      ->check(number_between(0, 1))
      ->capture_default_str();
  cli.add_flag("--normalize-curvature,!--no-normalize-curvature", normalize_curvature,
               "Divide curvature masses by the total absolute curvature")
      ->capture_default_str();
  add_choice(cli, "--method", method, choice_names<ice::CoarseningMethod>(),
             "Coarsening method: 'ice', or 'qem' (the extrinsic QEM baseline)");
  add_coarsen_parallel_options(cli, threads, regions);
  cli.add_option("--refine-angle", refine_angle,
                 "Refine the coarse mesh to a smallest angle of DEG degrees (0: none)")
      ->check(number_between(0, 30))
      ->capture_default_str();
  cli.add_option("--refine-budget", refine_budget,
                 "With --refine-angle: at most R times the coarse vertices")
      ->check(number_between(1, 1e6))
      ->capture_default_str();
}

std::optional<ice::RefinementOptions> TargetOptions::refinement() const {
  if (!(refine_angle > 0)) return std::nullopt;
  ice::RefinementOptions options;
  options.min_angle_degrees = refine_angle;
  options.max_vertex_ratio = refine_budget;
  return options;
}

void TargetOptions::apply(ice::CoarsenOptions& options, long long n) const {
  const bool has_vertices = vertices_option ? vertices_option->count() > 0 : vertices != 0;
  const bool has_ratio = ratio_option ? ratio_option->count() > 0 : ratio != 0;
  const bool has_error = std::isfinite(max_error);
  if (has_vertices && has_ratio) throw AppError(kUsage, "give either --vertices or --ratio, not both");
  if (!has_vertices && !has_ratio && !has_error)
    throw AppError(kUsage, "say how far to coarsen: --vertices N or --ratio R (e.g. --ratio 0.05)");
  if (has_vertices && (vertices < 1 || vertices > n))
    throw AppError(kUsage, "--vertices " + std::to_string(vertices) + " is out of range: the mesh has " + thousands(n) +
                               " vertices (valid: 1.." + std::to_string(n) + ")");
  if (has_ratio && !(ratio > 0 && ratio <= 1))
    throw AppError(kUsage, "--ratio " + fixed(ratio, 6) + " is out of range: it must be in (0, 1], e.g. 0.05 for 5%");
  if (has_error && !(max_error >= 0)) throw AppError(kUsage, "--max-error must be >= 0");
  if (has_error && method == ice::CoarseningMethod::qem)
    throw AppError(kUsage, "--max-error is a bound on the ICE error metric; with --method qem give --vertices or --ratio");
  if (min_vertices != 0 && !has_ratio) throw AppError(kUsage, "--min-vertices goes with --ratio");
  if (min_vertices < 0) throw AppError(kUsage, "--min-vertices must be positive");
  if (!(area_weight >= 0 && area_weight <= 1)) throw AppError(kUsage, "--area-weight must be in [0, 1]");
  if (!(refine_angle >= 0 && refine_angle <= 30)) throw AppError(kUsage, "--refine-angle must be in (0, 30] degrees (0: none)");
  if (!(refine_budget >= 1)) throw AppError(kUsage, "--refine-budget must be at least 1");
  if (refine_angle > 0 && method == ice::CoarseningMethod::qem)
    throw AppError(kUsage, "--refine-angle refines ICE's intrinsic coarse mesh; it does not apply to --method qem");
  options.target_vertices = has_vertices ? static_cast<ice::Index>(vertices) : 0;
  options.target_ratio = has_ratio ? ratio : 0;
  if (has_ratio && min_vertices > 0)
    options.target_vertices = ice::proxy::target_vertices(static_cast<ice::Index>(n), ratio, static_cast<ice::Index>(min_vertices));
  options.max_error = max_error;
  options.area_weight = area_weight;
  options.normalize_curvature = normalize_curvature;
  options.threads = threads;
  options.regions = regions;
}


void check_output(const std::string& path, bool overwrite, const std::string& option) {
  switch (ice::check_writable(path, overwrite)) {
    case ice::WriteCheck::ok: return;
    case ice::WriteCheck::exists:
      throw AppError(kNotWritten, option + " " + path + ": exists already (--force overwrites)");
    case ice::WriteCheck::no_directory:
      throw AppError(kNotWritten,
                     option + " " + path + ": directory " + fs::path(path).parent_path().string() + " does not exist");
  }
}

void add_operators_option(CLI::App& cli, fem::CoarseOperatorKind& operators) {
  add_choice(cli, "--operators", operators, choice_names<fem::CoarseOperatorKind>(),
             "Coarse operators: 'intrinsic' (coarse lengths) or 'galerkin' (P^T L P, P^T M P)");
}

void add_prolongation_option(CLI::App& cli, ice::proxy::Prolongation& choice, const std::string& name,
                             const std::string& description) {
  add_choice(cli, name, choice, choice_names<ice::proxy::Prolongation>(),
             description.empty()
                 ? "'auto': the recipe's choice; smoothing needs Galerkin, no Dirichlet"
                 : description);
}

fem::ProlongationKind resolve_prolongation(ice::proxy::Prolongation choice, fem::CoarseOperatorKind operators,
                                           const std::string& needs_barycentric, const std::string& option,
                                           ice::proxy::ProlongationUse use) {
  try {
    return ice::proxy::resolve_prolongation(choice, operators, !needs_barycentric.empty(), use);
  } catch (const std::invalid_argument&) {  // the policy's refusal, in the command line's words
    if (operators != fem::CoarseOperatorKind::galerkin) throw AppError(kUsage, option + " smoothed needs --operators galerkin");
    throw AppError(kUsage, needs_barycentric + " needs " + option + " barycentric or auto (a smoothed prolongation "
                                               "does not serve it)");
  }
}

void PdeOptions::add_to(CLI::App& cli, const std::string& field_names) {
  cli.add_option("mesh", mesh, "Input mesh (.obj, .off, .ply, .stl)")->required();
  target.add_to(cli, false);
  add_operators_option(cli, operators);
  add_choice(cli, "--qem-operators", qem_geometry, choice_names<ice::QemGeometry>(),
             "QEM coarse geometry: 'extrinsic' (its positions) or 'idt' (intrinsic Delaunay)");
  cli.add_flag("--fine-idt,!--no-fine-idt", fine_idt,
               "Fine operators on the input's intrinsic Delaunay mesh (else its triangles)")
      ->capture_default_str();
  cli.add_option("--output,-o", output,
                 "Write the mesh with fields " + field_names + " (ICE: + 'patch'): PLY or glTF (.glb)");
  cli.add_flag("--ascii", ascii, "With --output: ASCII PLY instead of binary");
  cli.add_option("--html", html,
                 "Write a 3D page (PAGE.html + PAGE_files/) of the results");
  cli.add_flag("--no-reference", no_reference, "Skip the fine reference solve (no errors, no speed-up)");
  cli.add_option("--report", report, "Write a JSON report (sizes, timings, errors)");
  cli.add_flag("--quiet,-q", quiet, "No progress bar");
  cli.add_flag("--force", force, "Overwrite existing output files");
  cli.add_flag("--repair", repair, "Apply the safe mesh repairs first (see ice-info --repair)");
}

void CacheOptions::add_to(CLI::App& cli) {
  auto* dir = cli.add_option("--cache", directory, "Store of set-ups (default: $ICE_CACHE or ~/.cache/ice)");
  cli.add_flag("--no-cache", off, "Set up from scratch, store nothing")->excludes(dir);
}

ice::proxy::Store store_at(const std::string& directory) {
  try {
    return ice::proxy::Store(ice::proxy::default_store_options(directory));
  } catch (const std::invalid_argument& e) {
    throw AppError(kUsage, e.what());
  }
}


void PdeOptions::add_polish_options(CLI::App& cli) {
  cli.add_option("--polish", polish.iterations,
                 "At most N fine two-level PCG iterations (0: none)")
      ->check(non_negative_integer())
      ->capture_default_str();
  cli.add_option("--tolerance", polish.tolerance,
                 "Polish to an estimated relative error of at most T, e.g. 1e-3")
      ->check(positive_number());
  cli.add_option("--polish-sweeps", polish.cycle.smoothing_steps,
                 "Polishing: Gauss-Seidel sweeps around each coarse correction")
      ->check(integer_between(1, 100))
      ->capture_default_str();
}

std::string lower_extension(const std::string& path) {
  std::string extension = fs::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}
// Whether two paths name one file (also when written differently: ./a and a).
bool same_file(const std::string& a, const std::string& b) {
  std::error_code ec_a, ec_b;
  const fs::path x = fs::weakly_canonical(a, ec_a), y = fs::weakly_canonical(b, ec_b);
  return ec_a || ec_b ? fs::path(a) == fs::path(b) : x == y;
}

bool PdeOptions::output_is_gltf() const { return lower_extension(output) == ".glb"; }

std::string PdeOptions::coarse_edges_output() const {
  if (output.empty() || !has_coarse_space || target.method != ice::CoarseningMethod::ice || output_is_gltf()) return {};
  const fs::path path(output);
  return (path.parent_path() / (path.stem().string() + "_coarse_edges.ply")).string();
}

void PdeOptions::check_outputs() const {
  if (!output.empty()) check_output(output, force, "--output");
  if (const std::string edges = coarse_edges_output(); !edges.empty()) check_output(edges, force, "--output (its coarse edges)");
  if (ascii && output_is_gltf()) throw AppError(kUsage, "--ascii writes ASCII PLY; --output names a .glb file");
  if (!report.empty()) check_output(report, force, "--report");
  if (!output.empty() && !report.empty() && same_file(output, report))
    throw AppError(kUsage, "--output and --report name the same file");
  if (!solutions.empty()) {
    if (lower_extension(solutions) != ".npy") throw AppError(kUsage, "--solutions " + solutions + ": use a .npy file name");
    check_output(solutions, force, "--solutions");
    if ((!report.empty() && same_file(solutions, report)) || (!output.empty() && same_file(solutions, output)))
      throw AppError(kUsage, "--solutions names the same file as --output or --report");
  }
  if (!html.empty()) {
    if (!has_coarse_space) throw AppError(kUsage, "--html draws the coarse mesh: it needs --solver proxy");
    if (lower_extension(html) != ".html") throw AppError(kUsage, "--html " + html + ": the page's name must end in .html");
    if ((!output.empty() && same_file(html, output)) || (!report.empty() && same_file(html, report)))
      throw AppError(kUsage, "--html names the same file as --output or --report");
    check_view_page(html, force);  // the page, its folder of assets, the viewer's files: before any work
  }
}

void PdeOptions::add_nonmanifold_option(CLI::App& cli) {
  add_choice(cli, "--nonmanifold", nonmanifold, choice_names<ice::NonmanifoldInput>(),
             "Not an oriented manifold: refuse, or solve on the tufted cover");
  cli.add_flag("--separate-thin-parts", separate_thin_parts,
               "Clouds: keep thin parts' sides apart");
}

ice::LoadOptions PdeOptions::load_options() const {
  ice::LoadOptions options;
  options.repair = repair;
  options.keep_nonmanifold = nonmanifold == ice::NonmanifoldInput::tufted_cover;
  options.point_cloud.separate_thin_parts = separate_thin_parts;
  return options;
}

ice::FineGeometry PdeOptions::fine_geometry() const {
  return fine_idt ? ice::FineGeometry::intrinsic_delaunay : ice::FineGeometry::input;
}

}  // namespace app

namespace app {

void MultigridCli::add_to(CLI::App& cli) {
  static const std::map<std::string, fem::MultigridSmoother> smoothers{
      {"sgs", fem::MultigridSmoother::symmetric_gauss_seidel},
      {"gs", fem::MultigridSmoother::gauss_seidel},
      {"chebyshev", fem::MultigridSmoother::chebyshev}};
  static const std::map<std::string, fem::MultigridMode> cycles{{"pcg", fem::MultigridMode::pcg},
                                                                {"vcycle", fem::MultigridMode::vcycle}};
  cli.add_option("--mg-tolerance", options.tolerance, "multigrid: relative residual to reach")->check(positive_number())->capture_default_str();
  cli.add_option("--mg-ratio", hierarchy.ratio, "multigrid: vertex fraction kept per level")->check(number_between(0.01, 0.9))->capture_default_str();
  cli.add_option("--mg-coarsest", hierarchy.coarsest_vertices, "multigrid: vertices of the coarsest level (CHOLMOD)")
      ->check(integer_between(1, std::numeric_limits<int>::max()))
      ->capture_default_str();
  add_choice(cli, "--mg-smoother", options.smoother, smoothers, "multigrid smoother");
  add_choice(cli, "--mg-cycle", options.mode, cycles, "multigrid: V-cycle preconditioned CG, or plain V-cycles");
  cli.add_option("--mg-threads", options.threads, "multigrid: threads on levels of 50,000+ unknowns (0: all cores)")
      ->check(non_negative_integer())->capture_default_str();
}

}  // namespace app
