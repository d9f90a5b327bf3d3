#pragma once
/// \file reports.h
/// What the ICE tools report and how: timers, peak memory, the progress bar, number formatting, the
/// JSON report objects and the PDE tools' run record (phase table, speed-ups).
#include <chrono>
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "command_line.h"
#include "fem/coarse_proxy.h"
#include "fem/multigrid.h"
#include "ice/coarse_space.h"
#include "ice/mesh_validation.h"
#include "ice/proxy/report.h"

namespace app {

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
  /// Moves the start back by `seconds`: the next lap() counts them too.
  void rewind(double seconds) {
    start_ -= std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(seconds));
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

/// The q-quantile (0 ≤ q ≤ 1) of `values` by the nearest lower rank; NaN for an empty list.
double quantile(std::vector<double> values, double q);

/// 1234567 → "1,234,567".
std::string thousands(long long value);
/// Fixed-point with `digits` decimals.
std::string fixed(double value, int digits);
/// A percentage with 2 significant decimals for small values: 0.01234 → "1.23%".
std::string percent(double fraction);
/// A relative error: as a percentage from 0.1 %, in scientific notation below (1e-6 is not "0.00%").
std::string relative_error(double fraction);
/// The same for a report value; null (undefined) prints as "undefined".
std::string relative_error(const nlohmann::json& fraction);
/// The same for a report value; null (an undefined relative error) prints as "undefined".
std::string percent(const nlohmann::json& fraction);

// ---- JSON reports ---------------------------------------------------------------------------------

/// One line on the refinement of a coarse space ("+132 vertices (114 boundary midpoints) in 0.005 s,
/// smallest angle 0.69° -> 3.75°, ..."), or "" without refinement.
std::string refinement_line(const ice::CoarseSpaceSummary& summary);

/// Writes `report` (pretty-printed) to `path`. Throws AppError(kNotWritten) on failure or when it
/// exists and !overwrite.
void write_json_file(const std::string& path, const nlohmann::json& report, bool overwrite);

/// The fields every report shares: tool, mesh, peak_rss_mb (at call time).
nlohmann::json report_header(const std::string& tool, const std::string& mesh_path);

/// Timings, sizes and outcome of one coarse-proxy run, with the parts of the report and of the human
/// summary that both PDE tools share.
struct PdeRun {
  std::string tool, mesh_path;
  fem::CoarseOperatorKind operators = fem::CoarseOperatorKind::galerkin;
  fem::ProlongationKind prolongation = fem::ProlongationKind::barycentric;
  /// Printed instead of "<operators> coarse operators" by a solve that uses none (coarse marching).
  std::string coarse_solver;
  double area_weight = 0;            ///< the ICE metric used (ignored by QEM)
  bool normalize_curvature = false;
  long long fine_vertices = 0, fine_faces = 0;
  ice::CoarseSpaceSummary coarsening;  ///< method, sizes, outcome (ICE or QEM details)
  bool fine_idt = true;
  bool fine_built = true;  ///< false: no fine mesh was needed (a marching proxy without reference)
  long long idt_flips = 0;
  /// Solved on the input's tufted cover (--nonmanifold tufted on a mesh that needs it): the fine
  /// mesh and the coarse mesh are the cover's (its copies' values averaged onto the input vertices).
  bool tufted_cover = false;
  bool proxy_uses_fine_mesh = false;  ///< the proxy needed the fine discretisation (Galerkin, M f)
  bool has_reference = false;
  /// Solves made (sources of a block): solve, prolong, polish and ref_solve are their totals.
  long long solves = 1;
  std::string unit = "solve";  ///< what one of them is called in the summary ("step" for heat flow)
  double load = 0, coarsen = 0, fine_mesh = 0, assemble = 0, factor = 0, solve = 0, prolong = 0, write = 0;
  double ref_assemble = 0, ref_factor = 0, ref_solve = 0;
  /// Polishing (fem::PolishOptions), when asked for: its setup (fine Laplacian, two-level cycle) and
  /// its iterations, both counted in the proxy total (the iterations also per solve).
  fem::PolishOptions polish_options;
  fem::PolishReport polish_report;
  double polish_setup = 0, polish = 0;
  /// The store of set-up proxies: where the setup came from, and the store's directory (report only).
  ice::proxy::CacheReport cache;
  nlohmann::json cache_json;
  /// What a hit loaded, for the summary.
  std::string stored_setup = "coarse space and proxy from the store (nothing coarsened or assembled)";
  /// Records where the setup came from (`cache`, through `store`).
  void record_cache(const ice::proxy::CacheReport& report, const ice::proxy::Store& store);

  /// A run of `tool` with the shared PDE options (mesh, operators, fine mesh, reference).
  static PdeRun start(const std::string& tool, const PdeOptions& opt, bool proxy_uses_fine_mesh);
  /// cache load and save + coarsen + assemble + factor + solve + prolong (+ polish setup and
  /// iterations). The fine mesh (intrinsic Delaunay or input
  /// lengths) is a choice of fine discretisation shared by both sides: timed apart, in neither total.
  double proxy_total() const;
  /// reference assemble + factor + solve.
  double reference_total() const;
  /// The number of solves after which this run's route (its setup, then per_solve() a solve) has
  /// cost less than the reference's (assemble and factor, then its solve a solve): 1 when the
  /// setup already costs less, -1 when never (a proxy solve no faster than the fine one).
  long long break_even_solves() const;
  /// (solve + prolong (+ the polishing iterations)) / solves.
  double per_solve() const;
  /// ref_solve / solves.
  double reference_per_solve() const { return ref_solve / static_cast<double>(solves); }
  /// tool, mesh, method, operators, input, coarse, fine_mesh, timings_s (incl. reference and
  /// proxy_total), speedup (when there is a reference), peak_rss_mb, blas.
  nlohmann::json report() const;
  /// Sizes, the phase table and the speed-ups.
  void print_summary(std::ostream& out) const;
};

}  // namespace app
