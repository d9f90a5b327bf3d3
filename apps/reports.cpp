#include "reports.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <new>
#include <sstream>

#include "fem/blas_info.h"

namespace app {
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

std::string relative_error(double fraction) {
  if (fraction < 0) return "n/a";
  if (fraction >= 1e-3) return percent(fraction);
  std::ostringstream s;
  s << std::scientific << std::setprecision(2) << fraction;
  return s.str();
}

std::string relative_error(const nlohmann::json& fraction) {
  return fraction.is_number() ? relative_error(static_cast<double>(fraction)) : "undefined";
}

std::string percent(const nlohmann::json& fraction) {
  return fraction.is_number() ? percent(static_cast<double>(fraction)) : "undefined";
}

// ---- JSON reports ---------------------------------------------------------------------------------

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return std::nan("");
  const auto k = static_cast<std::size_t>(q * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

std::string refinement_line(const ice::CoarseSpaceSummary& summary) {
  if (!summary.refinement) return "";
  const ice::RefinementResult& r = *summary.refinement;
  std::string line = "+" + thousands(r.inserted) + " vertices (" + thousands(r.boundary_splits) + " boundary midpoints) in " +
                     fixed(summary.refinement_seconds, 3) + " s, smallest angle " + fixed(r.min_angle_before, 2) +
                     " -> " + fixed(r.min_angle_after, 2) + " deg";
  if (r.bound_reached) return line + ", bound reached";
  line += ", " + thousands(r.faces_below_bound) + " faces below the bound";
  if (r.sharp_vertex_faces + r.tiny_faces > 0)
    line += " (" + thousands(r.sharp_vertex_faces) + " at sharp vertices, " + thousands(r.tiny_faces) + " tiny)";
  if (r.budget_exhausted) line += "; vertex budget spent";
  return line;
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

PdeRun PdeRun::start(const std::string& tool, const PdeOptions& opt, bool proxy_uses_fine_mesh) {
  PdeRun run;
  run.tool = tool;
  run.mesh_path = opt.mesh;
  run.operators = opt.operators;
  run.prolongation = opt.prolongation;
  run.area_weight = opt.target.area_weight;
  run.normalize_curvature = opt.target.normalize_curvature;
  run.fine_idt = opt.fine_idt;
  run.has_reference = !opt.no_reference;
  run.proxy_uses_fine_mesh = proxy_uses_fine_mesh;
  return run;
}

void PdeRun::record_cache(const ice::proxy::CacheReport& report, const ice::proxy::Store& store) {
  cache = report;
  cache_json = cache.status == ice::proxy::CacheStatus::off ? nlohmann::json() : ice::proxy::cache_json(cache, store);
}

double PdeRun::proxy_total() const {
  return cache.load_seconds + cache.save_seconds + coarsen + assemble + factor + polish_setup + solve + prolong + polish;
}

long long PdeRun::break_even_solves() const {
  const double setup = proxy_total() - (solve + prolong + polish), reference_setup = ref_assemble + ref_factor;
  if (setup <= reference_setup) return 1;
  if (per_solve() >= reference_per_solve()) return -1;
  return static_cast<long long>(std::ceil((setup - reference_setup) / (reference_per_solve() - per_solve())));
}

double PdeRun::per_solve() const { return (solve + prolong + polish) / static_cast<double>(solves); }

double PdeRun::reference_total() const { return ref_assemble + ref_factor + ref_solve; }

nlohmann::json PdeRun::report() const {
  nlohmann::json r = report_header(tool, mesh_path);
  r["method"] = ice::proxy::spelling(coarsening.method);
  r["operators"] = ice::proxy::spelling(operators);
  r["prolongation"] = ice::proxy::spelling(prolongation);
  if (!coarsening.qem) r["metric"] = {{"area_weight", area_weight}, {"normalize_curvature", normalize_curvature}};
  if (coarsening.qem) r["qem"] = ice::proxy::qem_json(*coarsening.qem, coarsening.target_reached);
  r["input"] = {{"vertices", fine_vertices}, {"faces", fine_faces}};
  r["coarse"] = ice::proxy::coarsen_json(coarsening);
  r["fine_mesh"] = {{"kind", !fine_built ? "none (not needed)" : fine_idt ? "intrinsic Delaunay" : "input"},
                    {"flips", idt_flips},
                    {"used_by_proxy", proxy_uses_fine_mesh},
                    {"tufted_cover", tufted_cover}};
  nlohmann::json t = {{"load", load},       {"coarsen", coarsen}, {"fine_mesh", fine_mesh}, {"assemble", assemble},
                      {"factor", factor},   {"solve", solve},     {"prolong", prolong},     {"proxy_total", proxy_total()},
                      {"per_solve", per_solve()}, {"write", write},
                      {"cache_load", cache.load_seconds}, {"cache_save", cache.save_seconds}};
  r["cache"] = cache_json.is_null() ? nlohmann::json{{"status", "off"}} : cache_json;
  if (polish_options.enabled()) {
    t["polish_setup"] = polish_setup;
    t["polish"] = polish;
    r["polish"] = ice::proxy::polish_json(polish_options, polish_report);
  }
  if (has_reference) {
    t["reference"] = reference_total();
    t["reference_phases"] = {{"assemble", ref_assemble}, {"factor", ref_factor}, {"solve", ref_solve}};
    r["speedup"] = {{"total", reference_total() / std::max(proxy_total(), 1e-12)},
                    {"per_solve", reference_per_solve() / std::max(per_solve(), 1e-12)},
                    {"per_solve_vs_factor_and_solve", (ref_factor + reference_per_solve()) / std::max(per_solve(), 1e-12)},
                    {"break_even_solves", break_even_solves() > 0 ? nlohmann::json(break_even_solves()) : nlohmann::json()}};
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
      << (qem ? "QEM (" + ice::proxy::spelling(coarsening.qem->geometry) + " mesh)"
              : "ICE (area weight " + fixed(area_weight, 2) + (normalize_curvature ? ", normalised curvature)" : ")"))
      << ", " << (coarse_solver.empty() ? ice::proxy::spelling(operators) + " coarse operators" : coarse_solver) << '\n';
  const auto row = [&](const std::string& name, double seconds, const std::string& note = "") {
    out << "  " << std::left << std::setw(16) << name << std::right << std::setw(10) << fixed(seconds, 4) << " s"
        << (note.empty() ? "" : "   " + note) << '\n';
  };
  row("load", load);
  if (cache.status == ice::proxy::CacheStatus::hit)
    row("cache load", cache.load_seconds, stored_setup);
  if (cache.status == ice::proxy::CacheStatus::rebuilt)
    out << "  cache           damaged entry removed and rebuilt: " << cache.damage << '\n';
  if (cache.status != ice::proxy::CacheStatus::hit)
  row("coarsen", coarsen, thousands(coarsening.removed()) + (qem ? " collapses, " : " removals, ") +
                              thousands(static_cast<long long>(coarsening.removed() / std::max(coarsen, 1e-9))) + "/s");
  if (coarsening.refinement) out << "  refine          " << refinement_line(coarsening) << '\n';
  if (fine_built)
    row("fine mesh", fine_mesh,
        std::string(tufted_cover ? "tufted cover, " : "") +
            (fine_idt ? "intrinsic Delaunay, " + thousands(idt_flips) + " flips" : std::string("input triangles")) +
            (proxy_uses_fine_mesh ? " (used by the proxy too; counted in neither total)" : " (for the reference; counted in neither total)"));
  else
    row("fine mesh", 0, "not built (neither the proxy nor a reference needs it)");
  row("assemble", assemble);
  if (cache.status == ice::proxy::CacheStatus::miss || cache.status == ice::proxy::CacheStatus::rebuilt)
    row("cache save", cache.save_seconds, cache.save_error.empty() ? "stored for the next run" : "NOT stored: " + cache.save_error);
  row("factor", factor);
  row("solve", solve);
  row("prolong", prolong);
  if (polish_options.enabled()) {
    row("polish setup", polish_setup, "fine Laplacian, Galerkin P^T L P, smoother");
    const fem::PolishReport& p = polish_report;
    row("polish", polish,
        std::to_string(p.iterations) + " iterations, estimated error " + relative_error(p.initial_estimated_error) + " -> " +
            relative_error(p.estimated_error) +
            (polish_options.tolerance > 0 ? (p.reached_tolerance ? " (tolerance reached)" : " (tolerance NOT reached)") : ""));
  }
  row("proxy total", proxy_total(),
      std::string(cache.status == ice::proxy::CacheStatus::off ? "" : "cache+") +
          std::string(polish_options.enabled() ? "coarsen+assemble+factor+solve+prolong+polish" : "coarsen+assemble+factor+solve+prolong") +
          "; per " + unit + " " + fixed(per_solve(), 4) + " s");
  if (has_reference) {
    row("fine reference", reference_total(),
        "assemble " + fixed(ref_assemble, 4) + " + factor " + fixed(ref_factor, 4) + " + solve " + fixed(ref_solve, 4));
    out << "  speed-up: " << fixed(reference_total() / std::max(proxy_total(), 1e-12), 2) << "x end to end, "
        << fixed(reference_per_solve() / std::max(per_solve(), 1e-12), 1) << "x per " << unit << " (fine " << unit << " "
        << fixed(reference_per_solve(), 4) << " s vs " << (polish_options.enabled() ? "coarse solve+prolong+polish " : "coarse solve+prolong ")
        << fixed(per_solve(), 4) << " s)\n";
    const long long solves = break_even_solves();
    out << "  break-even: " << (solves > 0 ? "ICE is ahead from " + thousands(solves) + " " + unit + (solves == 1 ? "" : "s")
                                            : "never (a proxy " + unit + " is no faster than the fine one)")
        << (cache.status == ice::proxy::CacheStatus::hit ? " (setup from the store)" : cache.status == ice::proxy::CacheStatus::off ? "" : " (cold setup; a second run loads it from the store)") << '\n';
  }
}

}  // namespace app
