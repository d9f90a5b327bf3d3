#include "app_common.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <map>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <new>
#include <sstream>

#include "fem/blas_info.h"
#include "ice/prolongation.h"

namespace app {

namespace {

// The command-line names of the method choices; CLI11 parses them straight into the enums.
const std::map<std::string, ice::CoarseningMethod> kMethodNames{{"ice", ice::CoarseningMethod::ice},
                                                                {"qem", ice::CoarseningMethod::qem}};
const std::map<std::string, ice::QemGeometry> kQemGeometryNames{{"extrinsic", ice::QemGeometry::extrinsic},
                                                                {"idt", ice::QemGeometry::intrinsic_delaunay}};
const std::map<std::string, fem::CoarseOperatorKind> kOperatorNames{{"intrinsic", fem::CoarseOperatorKind::intrinsic},
                                                                    {"galerkin", fem::CoarseOperatorKind::galerkin}};

template <class Enum>
std::string name_of(const std::map<std::string, Enum>& names, Enum value) {
  for (const auto& [name, entry] : names)
    if (entry == value) return name;
  return "?";
}

}  // namespace

namespace fs = std::filesystem;

// ---- exit codes and errors ------------------------------------------------------------------------

int parse_command_line(CLI::App& cli, int argc, char** argv) {
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

// ---- time, memory, progress -------------------------------------------------------------------------

double peak_rss_mb() {
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

bool stderr_is_terminal() { return isatty(fileno(stderr)) != 0; }

void ProgressBar::update(double fraction, const std::string& detail) {
  if (!enabled_) return;
  if (drawn_ && since_draw_.seconds() < 0.1) return;
  since_draw_.lap();
  fraction = std::min(1.0, std::max(0.0, fraction));
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(std::lround(fraction * kWidth));
  std::string bar(static_cast<std::size_t>(filled), '#');
  bar.resize(kWidth, '.');
  std::cerr << '\r' << label_ << " [" << bar << "] " << std::setw(3) << std::lround(100 * fraction) << "% " << detail
            << "\x1b[K" << std::flush;  // erase the rest of the line
  drawn_ = true;
}

void ProgressBar::finish() {
  if (!drawn_) return;
  std::cerr << "\r\x1b[K" << std::flush;
  drawn_ = false;
}

// ---- formatting -------------------------------------------------------------------------------------

std::string thousands(long long value) {
  std::string digits = std::to_string(value < 0 ? -value : value);
  std::string out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return value < 0 ? "-" + out : out;
}

std::string fixed(double value, int digits) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << value;
  return s.str();
}

std::string percent(double fraction) {
  const double p = 100 * fraction;
  return fixed(p, std::abs(p) < 10 ? 2 : 1) + "%";
}

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

std::string percent(const nlohmann::json& fraction) {
  return fraction.is_number() ? percent(static_cast<double>(fraction)) : "undefined";
}

// ---- input ------------------------------------------------------------------------------------------

ice::LoadResult load_input_mesh(const std::string& path, bool repair) {
  ice::LoadOptions options;
  options.repair = repair;
  return ice::load_mesh_with_report(path, options);
}

int mesh_vertex_of_file_vertex(const ice::LoadResult& loaded, long long file_vertex, const std::string& what) {
  const long long n_file = static_cast<long long>(loaded.file.soup.V.rows());
  if (file_vertex < 0 || file_vertex >= n_file)
    throw AppError(kUsage, what + " " + std::to_string(file_vertex) + " is out of range: the mesh has " +
                               thousands(n_file) + " vertices (valid: 0.." + std::to_string(n_file - 1) + ")");
  // Identity unless the repairs dropped or welded vertices.
  const auto& source = loaded.source_vertex;
  if (static_cast<long long>(source.size()) == n_file && source[static_cast<std::size_t>(file_vertex)] == file_vertex)
    return static_cast<int>(file_vertex);
  for (std::size_t i = 0; i < source.size(); ++i)
    if (source[i] == file_vertex) return static_cast<int>(i);
  throw AppError(kUsage, what + " " + std::to_string(file_vertex) + " was removed by --repair (unreferenced or welded)");
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

std::vector<double> read_number_file(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw AppError(kUnreadable, path + ": no such file");
  std::ifstream in(path);
  if (!in) throw AppError(kUnreadable, path + ": cannot be opened");
  std::vector<double> values;
  std::string line;
  long long line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    for (char& c : line)
      if (c == ',' || c == ';' || c == '\t' || c == '\r') c = ' ';
    std::istringstream tokens(line);
    std::string token;
    while (tokens >> token) {
      std::size_t used = 0;
      double value = 0;
      try {
        value = std::stod(token, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != token.size() || !std::isfinite(value))
        throw AppError(kUnreadable, path + ":" + std::to_string(line_number) + ": '" + token + "' is not a finite number");
      values.push_back(value);
    }
  }
  if (in.bad()) throw AppError(kUnreadable, path + ": read error");
  return values;
}

void require_connected(const ice::LoadResult& loaded, const std::string& path, const std::string& tool) {
  const std::size_t components = loaded.report.components.size();
  if (components > 1)
    throw AppError(kDefective, path + ": the mesh has " + std::to_string(components) + " connected components; " + tool +
                                   " needs a connected mesh (its solvers pin one vertex): split it first");
}

// ---- coarsening -------------------------------------------------------------------------------------

void TargetOptions::add_to(CLI::App& cli, bool with_max_error) {
  vertices_option = cli.add_option("--vertices,-n", vertices, "Coarsen down to N vertices (1 <= N <= input vertices)")
                       ->check(integer_between(1, std::numeric_limits<int>::max()));
  ratio_option = cli.add_option("--ratio,-r", ratio, "Coarsen down to ceil(R * input vertices), 0 < R <= 1 (e.g. 0.05)")
                     ->check(CLI::Validator(
                         [](std::string& text) -> std::string {
                           double value = 0;
                           if (!parse_number(text, value)) return "'" + text + "' is not a number";
                           return value > 0 && value <= 1 ? "" : text + " is out of range: it must be in (0, 1], e.g. 0.05 for 5%";
                         },
                         "in (0, 1]"));
  cli.add_option("--min-vertices", min_vertices,
                 "With --ratio: keep at least M vertices (at most all of them), e.g. --ratio 0.05 --min-vertices 1000");
  if (with_max_error)
    cli.add_option("--max-error,-e", max_error,
                   "Remove vertices while the cheapest removal costs at most E (ICE error metric); "
                   "alone it coarsens as far as possible under E, with --vertices/--ratio it stops at whichever comes first");
  cli.add_option("--area-weight,-w", area_weight,
                 "Weight w in [0,1] of the area term of the ICE error metric (0: curvature only; "
                 "more weight spreads vertices more evenly)")
      ->check(number_between(0, 1))
      ->capture_default_str();
  cli.add_option("--method", method,
                 "Coarsening method: 'ice' (intrinsic coarsening) or 'qem' (the extrinsic QEM baseline: OpenMesh "
                 "Decimater with quadrics, input vertices mapped by closest-point projection)")
      ->transform(CLI::CheckedTransformer(kMethodNames))
      ->default_str("ice");
  cli.add_option("--coarsen-threads", threads,
                 "ICE coarsening threads: 1 = the exact serial greedy order; k > 1 = k regions coarsened in parallel, "
                 "then a serial pass over the whole mesh (meshes of 20,000+ vertices; deterministic for a given k, "
                 "not identical to the serial result); 0 = one per hardware thread")
      ->check(integer_between(0, 64))
      ->capture_default_str();
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
  options.target_vertices = has_vertices ? static_cast<ice::Index>(vertices) : 0;
  options.target_ratio = has_ratio ? ratio : 0;
  if (has_ratio && min_vertices > 0) {  // the same rounding as ice::coarsen, then the floor
    const long long by_ratio = static_cast<long long>(std::ceil(ratio * static_cast<double>(n)));
    options.target_vertices = static_cast<ice::Index>(std::min(n, std::max(by_ratio, min_vertices)));
  }
  options.max_error = max_error;
  options.area_weight = area_weight;
  options.threads = threads;
}

std::unique_ptr<ProgressBar> attach_progress_bar(ice::CoarsenOptions& options, ice::Index start_vertices,
                                                 bool show_progress) {
  auto bar = std::make_unique<ProgressBar>("coarsening", show_progress && stderr_is_terminal());
  options.progress_interval = 250;
  options.progress = [bar = bar.get(), clock = Stopwatch(), start_vertices](const ice::CoarsenProgress& p) {
    const double total = std::max<double>(1, start_vertices - p.target);
    const double rate = p.removed / std::max(1e-9, clock.seconds());
    bar->update(p.removed / total, thousands(p.vertices) + " -> " + thousands(p.target) + " vertices, " +
                                       thousands(static_cast<long long>(rate)) + " removals/s");
    return true;
  };
  return bar;
}

ice::CoarsenResult coarsen_with_progress(ice::IntrinsicTriangulation& T, ice::CoarsenOptions options,
                                         bool show_progress) {
  const std::unique_ptr<ProgressBar> bar = attach_progress_bar(options, T.num_vertices(), show_progress);
  ice::CoarsenResult result = ice::coarsen(T, options);
  bar->finish();
  return result;
}

void warn_if_target_missed(const std::string& tool, const ice::CoarseSpaceSummary& summary,
                           const ice::CoarsenOptions& options) {
  if (summary.qem) {
    if (!summary.target_reached)
      warn(tool, "QEM stopped at " + thousands(summary.coarse_vertices) + " vertices: no further collapse is legal");
    return;
  }
  const ice::CoarsenResult& result = *summary.ice;
  if (result.stop_reason == ice::StopReason::NothingRemovable)
    warn(tool, "stopped at " + thousands(result.output_vertices) +
                   " vertices: no further vertex could be removed (locked, boundary kept, or topology)");
  else if (result.stop_reason == ice::StopReason::ErrorThreshold && (options.target_vertices > 0 || options.target_ratio > 0))
    warn(tool, "stopped at " + thousands(result.output_vertices) + " vertices: the next removal would cost " +
                   std::to_string(result.next_cost) + " > --max-error");
}

nlohmann::json coarsen_json(const ice::CoarsenResult& result, const ice::CompactMesh& coarse) {
  nlohmann::json failures;
  for (int s = 0; s < static_cast<int>(result.failures_by_status.size()); ++s)
    if (result.failures_by_status[s] > 0) {
      std::string key = ice::to_string(static_cast<ice::RemovalStatus>(s));
      std::replace(key.begin(), key.end(), ' ', '_');
      failures[key] = result.failures_by_status[s];
    }
  const auto finite_or_null = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
  return {{"vertices", coarse.to_input.size()},
          {"faces", coarse.F.rows()},
          {"stop_reason", ice::to_string(result.stop_reason)},
          {"removed", result.removed},
          {"failed_removals", result.failed_removals},
          {"failures_by_status", failures.is_null() ? nlohmann::json::object() : failures},
          {"last_cost", result.last_cost},
          {"max_cost", result.max_cost},
          {"next_cost", finite_or_null(result.next_cost)},
          {"parallel_removed", result.parallel_removed}};
}

nlohmann::json coarsen_json(const ice::CoarseSpaceSummary& summary) {
  if (summary.ice) {
    nlohmann::json j = coarsen_json(*summary.ice, ice::CompactMesh{});
    j["vertices"] = summary.coarse_vertices;
    j["faces"] = summary.coarse_faces;
    return j;
  }
  return {{"vertices", summary.coarse_vertices},
          {"faces", summary.coarse_faces},
          {"stop_reason", ice::to_string(summary.target_reached ? ice::StopReason::TargetReached
                                                                : ice::StopReason::NothingRemovable)},
          {"removed", summary.removed()}};
}

nlohmann::json qem_json(const ice::QemOutcome& qem, bool target_reached) {
  return {{"mapping", "closest point on the coarse mesh (AABB tree), survivors exact"},
          {"collapses", qem.collapses},
          {"target_reached", target_reached},
          {"normal_guard_relaxed", qem.guard_relaxed},
          {"max_distance", qem.max_distance},
          {"mean_distance", qem.mean_distance},
          {"decimate_s", qem.decimate_seconds},
          {"map_s", qem.map_seconds},
          {"operators", cli_name(qem.geometry)},
          {"idt_flips", qem.intrinsic_delaunay_flips}};
}

std::string cli_name(ice::CoarseningMethod method) { return name_of(kMethodNames, method); }
std::string cli_name(ice::QemGeometry geometry) { return name_of(kQemGeometryNames, geometry); }
std::string cli_name(fem::CoarseOperatorKind kind) { return name_of(kOperatorNames, kind); }

// ---- output -----------------------------------------------------------------------------------------

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

void write_json_file(const std::string& path, const nlohmann::json& report, bool overwrite) {
  check_output(path, overwrite, "--report");
  std::ofstream out(path);
  out << report.dump(2) << '\n';
  out.flush();
  if (!out) throw AppError(kNotWritten, path + ": cannot be written");
}

nlohmann::json report_header(const std::string& tool, const std::string& mesh_path) {
  return {{"tool", tool}, {"mesh", mesh_path}};
}

// ---- the coarse proxy ----------------------------------------------------------------------------------

void add_operators_option(CLI::App& cli, fem::CoarseOperatorKind& operators) {
  cli.add_option("--operators", operators,
                 "Coarse operators: 'intrinsic' (cotan Laplacian and mass from the coarse edge lengths) or "
                 "'galerkin' (P^T L P and P^T M P from the fine operators)")
      ->transform(CLI::CheckedTransformer(kOperatorNames))
      ->default_str("intrinsic");
}

fem::CoarseProxy make_proxy(const ice::FineMesh& fine, const ice::CoarseSpace& coarse, fem::CoarseOperatorKind kind) {
  return fem::CoarseProxy(fine.F, fine.L, coarse.mesh.F, coarse.mesh.L, coarse.P, kind, fem::MassKind::lumped);
}

// ---- the coarse-proxy PDE tools ----------------------------------------------------------------------

ice::CoarseSpace coarsen_for_pde(const ice::TriangleMesh& mesh, const ice::CoarsenOptions& options, const PdeOptions& opt,
                                 PdeRun& run) {
  ice::CoarseSpaceOptions space_options;
  space_options.method = opt.target.method;
  space_options.qem_geometry = opt.qem_geometry;
  space_options.coarsen = options;
  std::unique_ptr<ProgressBar> bar;
  if (opt.target.method == ice::CoarseningMethod::ice)
    bar = attach_progress_bar(space_options.coarsen, static_cast<ice::Index>(mesh.V.rows()), !opt.quiet);
  ice::CoarseSpace space;
  try {
    space = ice::build_coarse_space(mesh, space_options);
  } catch (const std::runtime_error& e) {
    if (opt.qem_geometry == ice::QemGeometry::intrinsic_delaunay && opt.target.method == ice::CoarseningMethod::qem)
      throw AppError(kFailed, std::string("--qem-operators idt: ") + e.what());
    throw;
  }
  if (bar) bar->finish();
  warn_if_target_missed(run.tool, space.summary, options);
  run.coarsening = space.summary;
  return space;
}

void PdeOptions::add_to(CLI::App& cli, const std::string& field_names) {
  cli.add_option("mesh", mesh, "Input mesh (.obj, .off, .ply, .stl); must be connected")->required();
  target.add_to(cli, false);
  add_operators_option(cli, operators);
  cli.add_option("--qem-operators", qem_geometry,
                 "With --method qem: coarse geometry from the QEM mesh's positions ('extrinsic') or from its "
                 "intrinsic Delaunay triangulation ('idt', same vertices, so the same P)")
      ->transform(CLI::CheckedTransformer(kQemGeometryNames))
      ->default_str("extrinsic");
  cli.add_flag("--fine-idt,!--no-fine-idt", fine_idt,
               "Fine reference (and fine operators of the proxy) on the intrinsic Delaunay triangulation of the "
               "input (default), or on the input triangles as they are (--no-fine-idt)")
      ->capture_default_str();
  cli.add_option("--output,-o", output, "Write the input mesh with the per-vertex fields " + field_names + " as PLY");
  cli.add_flag("--ascii", ascii, "With --output: ASCII PLY instead of binary little endian");
  cli.add_flag("--no-reference", no_reference, "Skip the fine reference solve (no errors, no speed-up)");
  cli.add_option("--report", report, "Write a JSON report (sizes, timings per phase, errors, memory, BLAS)");
  cli.add_flag("--quiet,-q", quiet, "No progress bar");
  cli.add_flag("--force", force, "Overwrite existing output files");
  cli.add_flag("--repair", repair, "Apply the safe mesh repairs first (see ice-info --repair)");
}

void PdeOptions::check_outputs() const {
  if (!output.empty()) check_output(output, force, "--output");
  if (!report.empty()) check_output(report, force, "--report");
  if (!output.empty() && !report.empty() && fs::path(output) == fs::path(report))
    throw AppError(kUsage, "--output and --report name the same file");
}

ice::FineGeometry PdeOptions::fine_geometry() const {
  return fine_idt ? ice::FineGeometry::intrinsic_delaunay : ice::FineGeometry::input;
}

double PdeRun::proxy_total() const {
  return coarsen + assemble + factor + solve + prolong;
}

double PdeRun::reference_total() const { return ref_assemble + ref_factor + ref_solve; }

nlohmann::json PdeRun::report() const {
  nlohmann::json r = report_header(tool, mesh_path);
  r["method"] = cli_name(coarsening.method);
  r["operators"] = cli_name(operators);
  if (coarsening.qem) r["qem"] = qem_json(*coarsening.qem, coarsening.target_reached);
  r["input"] = {{"vertices", fine_vertices}, {"faces", fine_faces}};
  r["coarse"] = coarsen_json(coarsening);
  r["fine_mesh"] = {{"kind", fine_idt ? "intrinsic Delaunay" : "input"},
                    {"flips", idt_flips},
                    {"used_by_proxy", proxy_uses_fine_mesh}};
  nlohmann::json t = {{"load", load},       {"coarsen", coarsen}, {"fine_mesh", fine_mesh}, {"assemble", assemble},
                      {"factor", factor},   {"solve", solve},     {"prolong", prolong},     {"proxy_total", proxy_total()},
                      {"per_solve", solve + prolong}, {"write", write}};
  if (has_reference) {
    t["reference"] = reference_total();
    t["reference_phases"] = {{"assemble", ref_assemble}, {"factor", ref_factor}, {"solve", ref_solve}};
    r["speedup"] = {{"total", reference_total() / std::max(proxy_total(), 1e-12)},
                    {"per_solve", ref_solve / std::max(solve + prolong, 1e-12)}};
  }
  r["timings_s"] = t;
  r["removals_per_second"] = coarsening.removed() / std::max(coarsen, 1e-9);
  r["peak_rss_mb"] = peak_rss_mb();
  r["blas"] = fem::blas_library();
  return r;
}

void PdeRun::print_summary(std::ostream& out) const {
  const long long coarse_vertices = coarsening.coarse_vertices;
  const bool qem = coarsening.qem.has_value();
  out << tool << ": " << mesh_path << ": " << thousands(fine_vertices) << " vertices -> " << thousands(coarse_vertices)
      << " coarse vertices (" << percent(double(coarse_vertices) / double(std::max(1LL, fine_vertices))) << "), "
      << (qem ? "QEM (" + cli_name(coarsening.qem->geometry) + " mesh)" : std::string("ICE")) << ", " << cli_name(operators)
      << " coarse operators\n";
  const auto row = [&](const std::string& name, double seconds, const std::string& note = "") {
    out << "  " << std::left << std::setw(16) << name << std::right << std::setw(10) << fixed(seconds, 4) << " s"
        << (note.empty() ? "" : "   " + note) << '\n';
  };
  row("load", load);
  row("coarsen", coarsen, thousands(coarsening.removed()) + (qem ? " collapses, " : " removals, ") +
                              thousands(static_cast<long long>(coarsening.removed() / std::max(coarsen, 1e-9))) + "/s");
  row("fine mesh", fine_mesh,
      (fine_idt ? "intrinsic Delaunay, " + thousands(idt_flips) + " flips" : std::string("input triangles")) +
          (proxy_uses_fine_mesh ? " (used by the proxy too; counted in neither total)" : " (for the reference; counted in neither total)"));
  row("assemble", assemble);
  row("factor", factor);
  row("solve", solve);
  row("prolong", prolong);
  row("proxy total", proxy_total(), "coarsen+assemble+factor+solve+prolong; per solve " + fixed(solve + prolong, 4) + " s");
  if (has_reference) {
    row("fine reference", reference_total(),
        "assemble " + fixed(ref_assemble, 4) + " + factor " + fixed(ref_factor, 4) + " + solve " + fixed(ref_solve, 4));
    out << "  speed-up: " << fixed(reference_total() / std::max(proxy_total(), 1e-12), 2) << "x end to end, "
        << fixed(ref_solve / std::max(solve + prolong, 1e-12), 1) << "x per solve (fine solve "
        << fixed(ref_solve, 4) << " s vs coarse solve+prolong " << fixed(solve + prolong, 4) << " s)\n";
  }
}

Eigen::VectorXd demo_poisson_rhs(const ice::TriangleMesh& mesh) {
  const Eigen::Index n = mesh.V.rows();
  const double sigma = 0.1 * (mesh.V.colwise().maxCoeff() - mesh.V.colwise().minCoeff()).norm();
  const double weights[3] = {1.0, -1.0, 1.0};
  Eigen::VectorXd f = Eigen::VectorXd::Zero(n);
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::Index centre = 0;
    mesh.V.col(axis).maxCoeff(&centre);
    const Eigen::RowVector3d c = mesh.V.row(centre);
    for (Eigen::Index i = 0; i < n; ++i)
      f(i) += weights[axis] * std::exp(-(mesh.V.row(i) - c).squaredNorm() / (2 * sigma * sigma));
  }
  return f;
}

Eigen::VectorXd remove_mean(const Eigen::VectorXd& f, const Eigen::SparseMatrix<double>& mass) {
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(f.size());
  const Eigen::VectorXd m1 = mass * ones;
  // The same reduction on both sides: a constant f has a mean of exactly that constant, and becomes 0.
  return f.array() - m1.dot(f) / m1.dot(ones);
}


}  // namespace app
