// ice-report: ICE against the QEM baseline, side by side, on the same meshes, budgets and problems.
//
// For every mesh (default: the clean meshes of the project and extended sets present), coarse budget (default 1, 2, 5, 10 % of
// the vertices, at least --min-vertices) and method:
//   ice        ICE, curvature only (area weight 0)
//   ice_area   ICE with the pipeline's default metric (ice::recommended_coarsen_options: area weight 0.5 of
//              normalised masses), or --area-weight / --no-normalize-curvature
//   qem_ext    QEM (OpenMesh Decimater + quadrics, closest-point map), operators from its positions
//   qem_idt    the same QEM mesh and P, operators from its intrinsic Delaunay triangulation
// it solves three problems through the coarse proxy (fem::CoarseProxy; ICE with --operators galerkin by
// default, QEM always with the operators of its own geometry, its most accurate configuration)
// and on the fine mesh (its intrinsic Delaunay triangulation, as the tools do by default):
//   poisson    zero-mean Poisson L u = M f, f = the demo source of poisson-coarse (three Gaussian bumps,
//              zero mean); error: relative L2 in the fine mass norm
//   heat       one backward-Euler step of length t = 0.1 × surface area (long time, smooth answer) from
//              u0 = the same zero-mean field: (M + tL) u = M u0, restricted as Pᵀ M u0; error: relative L2
//   geodesic   distance from each of 3 sources (vertex 0, then twice the vertex farthest in R³ from those
//              chosen): through the proxy by coarse fast marching (--coarse-distances heat: the coarse heat
//              method), on the fine mesh by the heat method; error: mean |d − d_ref| / max d_ref, averaged
//              over the sources, d_ref the fine heat method's distances or (--geodesic-reference exact, when
//              built with CGAL) exact polyhedral geodesics, against which the fine heat method's own error
//              is reported too
// and writes results.csv, results.json, summary.md and (with gnuplot) SVG plots into the output dir.
// Progress goes to stderr. --quick: 2 small meshes, 2 budgets (the CTest test report_quick).
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "app_common.h"
#include "exact_geodesics.h"  // (its functions are built only with CGAL: ICE_REPORT_EXACT_GEODESICS)
#include "fem/blas_info.h"
#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "fem/eigen.h"
#include "fem/problems.h"
#include "ice/large_array.h"
#include "ice/proxy/eigen.h"
#include "ice/qem.h"
#include "mesh_sets.h"
#include "view_page.h"

namespace fs = std::filesystem;

namespace {

const std::string kTool = "ice-report";
const std::vector<std::string> kProblems = {"poisson", "heat", "geodesic"};
// Names are looked up in the project set, then the extended set (tests/mesh_sets.h), unless --meshes-dir
// is given; the default list takes the ones present (the extended set's are absent from a bare clone).
const std::vector<std::string> kDefaultMeshes = {
    "spot.obj",      "fertility.off",    "bob_tri.obj",       "fandisk.obj",  "blub_triangulated.obj",
    "capsule.obj",   "camelhead.off",    "dragon_fat.obj",    "bs_rest.obj",  "spot_subdiv.obj",
    "face_scan.obj", "bunny_closed.off", "armadillo_43k.obj", "elephant.off", "lion-head.off",
    "bear.off"};
// The project set only: a bare clone runs it.
const std::vector<std::string> kQuickMeshes = {"spot.obj", "elephant.off"};

struct Row {
  std::string mesh, method, problem;
  long long n = 0, target = 0, coarse_n = 0, coarse_faces = 0;
  double budget = 0;
  double coarsen = 0, assemble = 0, factor = 0, solve = 0, prolong = 0;
  double fine_assemble = 0, fine_factor = 0, fine_solve = 0;
  double error = 0, error_max = 0, error_l2 = 0;
  double qem_max_distance = -1;  // QEM only: largest projection distance / bounding-box diagonal
  bool target_reached = true;
  std::string note;
  double proxy_total() const { return coarsen + assemble + factor + solve + prolong; }
  double fine_total() const { return fine_assemble + fine_factor + fine_solve; }
  double speedup_total() const { return fine_total() / std::max(proxy_total(), 1e-12); }
  double speedup_solve() const { return fine_solve / std::max(solve + prolong, 1e-12); }
};

// One polished solve (--tolerances): Poisson or heat through the proxy, then polished on the fine
// system to an estimated relative error (fem::PolishOptions).
struct PolishRow {
  std::string mesh, method, problem;
  long long n = 0, coarse_n = 0;
  double budget = 0, tolerance = 0;
  int iterations = 0;
  bool reached = false;
  double plain_error = 0, error = 0, estimated_error = 0;
  double setup = 0, polish = 0, proxy_solve = 0;  ///< polish setup; polish iterations; coarse solve + prolong
  double fine_factor = 0, fine_solve = 0;
  double per_solve() const { return proxy_solve + polish; }
};

// The first K eigenpairs through one proxy (--eigen-pairs) against the fine mesh's.
struct EigenRow {
  std::string mesh, method;
  long long n = 0, coarse_n = 0;
  double budget = 0;
  int pairs = 0, zero_modes = 0;
  double relative_median = std::numeric_limits<double>::quiet_NaN(), relative_max = relative_median;
  double angle_median_deg = relative_median, angle_max_deg = relative_median;
  double seconds = 0, fine_seconds = 0;  ///< the proxy's eigensolve + prolongation; the fine eigensolve
  std::string note;
};

// The demo source of poisson-coarse: three Gaussian bumps (+1, −1, +1) at the vertices with the
// largest x, y, z, σ = 0.1 × bounding-box diagonal, minus its mass-weighted mean.
std::vector<int> spread_sources(const ice::Positions& V, int count) {
  std::vector<int> s{0};
  Eigen::VectorXd d = (V.rowwise() - V.row(0)).rowwise().norm();
  while (static_cast<int>(s.size()) < count) {
    Eigen::Index far = 0;
    d.maxCoeff(&far);
    s.push_back(static_cast<int>(far));
    d = d.cwiseMin((V.rowwise() - V.row(far)).rowwise().norm());
  }
  return s;
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const std::size_t k = v.size() / 2;
  return v.size() % 2 ? v[k] : 0.5 * (v[k - 1] + v[k]);
}

std::string num(double x, int digits = 4) {
  if (!std::isfinite(x)) return "n/a";
  std::ostringstream s;
  s << std::setprecision(digits) << x;
  return s.str();
}
std::string pct(double x) { return std::isfinite(x) ? app::percent(x) : "n/a"; }

// ---- fine reference of one mesh ---------------------------------------------------------------------

struct Fine {
  ice::TriangleMesh mesh;
  ice::FineMesh disc;
  fem::SparseMatrix M;
  Eigen::VectorXd demo;  // the demo source as made (the proxy solver removes its mean itself)
  Eigen::VectorXd f;     // zero-mean demo field (Poisson source, heat initial values)
  double heat_time = 0;
  std::vector<int> sources;
  Eigen::VectorXd poisson, heat;
  std::vector<Eigen::VectorXd> distances;  // the geodesic reference, per source
  /// With the exact reference: the fine heat method's error against it (mean |d - d_ref| / max d_ref,
  /// averaged over the sources); NaN otherwise.
  double heat_method_error = std::numeric_limits<double>::quiet_NaN();
  double t_assemble[3] = {0, 0, 0}, t_factor[3] = {0, 0, 0}, t_solve[3] = {0, 0, 0};
  /// The first --eigen-pairs eigenpairs of (L, M) (none when off or the mesh is too small), and their time.
  std::optional<fem::Eigenpairs> eigen;
  double t_eigen = 0;
};

Fine fine_reference(const ice::TriangleMesh& mesh, bool exact_geodesics, int eigen_pairs) {
  Fine r;
  r.mesh = mesh;
  r.disc = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  app::Stopwatch clock;
  const fem::SparseMatrix L = fem::cotan_laplacian(r.disc);
  r.M = fem::mass_matrix(r.disc, fem::MassKind::lumped);
  r.t_assemble[0] = r.t_assemble[1] = clock.lap();  // the same L and M for Poisson and heat
  r.demo = app::demo_poisson_rhs(mesh);
  r.f = app::remove_mean(r.demo, r.M);
  r.heat_time = 0.1 * r.M.sum();
  r.sources = spread_sources(mesh.V, 3);
  clock.lap();
  const fem::PoissonSolver poisson = fem::PoissonSolver::zero_mean(L, r.M);
  r.t_factor[0] = clock.lap();
  r.poisson = poisson.solve(r.f);
  r.t_solve[0] = clock.lap();
  const fem::HeatSolver heat(L, r.M, r.heat_time);
  r.t_factor[1] = clock.lap();
  r.heat = heat.step(r.f);
  r.t_solve[1] = clock.lap();
  fem::HeatMethodOperators ops = fem::heat_method_operators(r.disc, fem::MassKind::lumped, 1.0);
  r.t_assemble[2] = clock.lap();
  const fem::HeatGeodesicSolver geodesic(std::move(ops));
  r.t_factor[2] = clock.lap();
  for (int s : r.sources) r.distances.push_back(geodesic.distance({s}));
  r.t_solve[2] = clock.lap();
#ifdef ICE_REPORT_EXACT_GEODESICS
  if (exact_geodesics) {
    const Eigen::MatrixXd exact =
        ice_bench::exact_geodesic_distances(mesh, std::vector<ice::Index>(r.sources.begin(), r.sources.end()));
    r.heat_method_error = 0;
    for (std::size_t k = 0; k < r.sources.size(); ++k) {
      r.heat_method_error += fem::distance_errors(r.distances[k], exact.col(static_cast<Eigen::Index>(k))).mean_relative /
                             static_cast<double>(r.sources.size());
      r.distances[k] = exact.col(static_cast<Eigen::Index>(k));
    }
  }
#else
  if (exact_geodesics) throw std::logic_error("exact geodesics: not built with CGAL");
#endif
  if (eigen_pairs > 0 && eigen_pairs < L.rows()) {
    clock.lap();
    r.eigen = fem::smallest_eigenpairs(L, r.M, eigen_pairs);
    r.t_eigen = clock.lap();
  }
  return r;
}

// ---- one coarse proxy, three problems ---------------------------------------------------------------

// A method that failed on this input: one row per problem with NaN errors and the reason in the note.
void record_failure(Row r, const std::string& what, std::vector<Row>& rows) {
  r.note += std::string(r.note.empty() ? "" : "; ") + "failed: " + what;
  for (const auto& p : kProblems) {
    r.problem = p;
    r.error = r.error_max = r.error_l2 = std::numeric_limits<double>::quiet_NaN();
    rows.push_back(r);
  }
}

// The proxy's solutions, kept for the 3D page: Poisson, heat, and the distance from the first source.
struct ProxySolutions {
  Eigen::VectorXd poisson, heat, geodesic;
};

// The three problems through the library's proxy solvers (fem/coarse_proxy.h), each phase timed.
void solve_on_proxy(const Fine& fine, const ice::CoarseSpace& coarse, fem::CoarseOperatorKind kind,
                    fem::ProlongationKind prolongation, Row base, std::vector<Row>& rows,
                    const std::vector<double>& tolerances, std::vector<PolishRow>& polished,
                    const fem::ProxyGeodesicOptions& geodesic, ProxySolutions* kept = nullptr,
                    const ice::FaceLengths* marching_lengths = nullptr, std::vector<EigenRow>* eigen_rows = nullptr) {
  app::Stopwatch clock;
  const fem::CoarseProxy proxy = ice::proxy::make_proxy(fine.disc, coarse, kind, prolongation);
  const double t_proxy = clock.lap();  // counted in the assembly of every problem (each needs it)
  if (eigen_rows && fine.eigen) {  // the eigenbasis of the Galerkin pencil (PᵀLP, PᵀMP), prolonged
    EigenRow e;
    e.mesh = base.mesh, e.method = base.method, e.n = base.n, e.budget = base.budget, e.coarse_n = base.coarse_n;
    e.pairs = static_cast<int>(fine.eigen->values.size());
    e.fine_seconds = fine.t_eigen;
    if (kind != fem::CoarseOperatorKind::galerkin) {
      e.note = "needs Galerkin operators";
    } else if (e.pairs >= proxy.coarse_size()) {
      e.note = "the coarse space has " + std::to_string(proxy.coarse_size()) + " vertices";
    } else {
      const ice::proxy::Eigenbasis basis = ice::proxy::proxy_eigenbasis(proxy, e.pairs);
      const ice::proxy::EigenbasisErrors errors = ice::proxy::eigenbasis_errors(basis.values, basis.vectors, *fine.eigen, fine.M);
      e.zero_modes = errors.zero_modes;
      e.relative_median = errors.relative_median, e.relative_max = errors.relative_max;
      e.angle_median_deg = errors.angle_median * 180 / M_PI, e.angle_max_deg = errors.angle_max * 180 / M_PI;
      e.seconds = basis.eigensolve_seconds + basis.prolong_seconds;
    }
    eigen_rows->push_back(e);
    clock.lap();
  }
  const auto record = [&](Row& r, int index, const fem::ProxyPhaseTimes& phases) {
    r.solve = phases.restriction + phases.coarse_solve;
    r.prolong = phases.prolongation;
    r.fine_assemble = fine.t_assemble[index], r.fine_factor = fine.t_factor[index], r.fine_solve = fine.t_solve[index];
  };
  {  // Poisson, zero mean: the solver makes the demo source compatible and re-centres the answer
    Row r = base;
    r.problem = "poisson";
    r.assemble = t_proxy;
    clock.lap();
    const fem::ProxyPoissonSolver solver(proxy);
    r.factor = clock.lap();
    fem::ProxyPhaseTimes phases;
    const Eigen::VectorXd u = solver.solve(fine.demo, {}, &phases);
    if (kept) kept->poisson = u;
    record(r, 0, phases);
    r.error = r.error_l2 = fem::relative_l2_error(u, fine.poisson, fine.M);
    r.error_max = fem::max_abs_error(u, fine.poisson) / fine.poisson.cwiseAbs().maxCoeff();
    rows.push_back(r);
  }
  {  // heat: one backward-Euler step from the L2 projection of the field (right-hand side Pᵀ M u0)
    Row r = base;
    r.problem = "heat";
    r.assemble = t_proxy;
    clock.lap();
    const fem::ProxyHeatSolver solver(proxy, fine.heat_time, fem::RestrictionKind::l2_projection);
    r.factor = clock.lap();
    fem::ProxyPhaseTimes phases;
    const Eigen::VectorXd u = solver.integrate(fine.f, 1, &phases);
    if (kept) kept->heat = u;
    record(r, 1, phases);
    r.error = r.error_l2 = fem::relative_l2_error(u, fine.heat, fine.M);
    r.error_max = fem::max_abs_error(u, fine.heat) / fine.heat.cwiseAbs().maxCoeff();
    rows.push_back(r);
  }
  // Polished Poisson and heat, to each tolerance (the plain rows above are the starting points).
  const Row& plain_poisson = rows[rows.size() - 2];
  const Row& plain_heat = rows.back();
  for (double tolerance : tolerances) {
    fem::PolishOptions options;
    options.tolerance = tolerance;
    for (const Row* plain : {&plain_poisson, &plain_heat}) {
      const bool poisson = plain->problem == "poisson";
      PolishRow p;
      p.mesh = base.mesh, p.method = base.method, p.problem = plain->problem, p.n = base.n, p.coarse_n = base.coarse_n;
      p.budget = base.budget, p.tolerance = tolerance, p.plain_error = plain->error;
      p.fine_factor = plain->fine_factor, p.fine_solve = plain->fine_solve;
      fem::PolishReport report;
      fem::ProxyPhaseTimes phases;
      Eigen::VectorXd u;
      if (poisson) {
        const fem::ProxyPoissonSolver solver(proxy, {}, options);
        p.setup = solver.polish_setup_seconds();
        u = solver.solve(fine.demo, {}, &phases, &report);
        p.error = fem::relative_l2_error(u, fine.poisson, fine.M);
      } else {
        const fem::ProxyHeatSolver solver(proxy, fine.heat_time, fem::RestrictionKind::l2_projection, options);
        p.setup = solver.polish_setup_seconds();
        u = solver.integrate(fine.f, 1, &phases, &report);
        p.error = fem::relative_l2_error(u, fine.heat, fine.M);
      }
      p.iterations = report.iterations, p.reached = report.reached_tolerance, p.estimated_error = report.estimated_error;
      p.polish = report.seconds;
      p.proxy_solve = phases.restriction + phases.coarse_solve + phases.prolongation;
      polished.push_back(p);
    }
  }
  {  // geodesics from each source
    Row r = base;
    r.problem = "geodesic";
    clock.lap();
    r.assemble = t_proxy;
    // The heat method's assembly counts as its factorisation; marching on other lengths than the
    // coarse mesh's own (--geodesic-lengths traced) takes the mesh and the barycentric P directly.
    const fem::ProxyGeodesicSolver solver = marching_lengths
                                                ? fem::ProxyGeodesicSolver(ice::with_lengths(coarse.mesh, *marching_lengths), coarse.P, geodesic.subdivisions)
                                                : fem::ProxyGeodesicSolver(proxy, geodesic);
    r.factor = clock.lap();
    fem::ProxyPhaseTimes total;
    double mean = 0, max = 0, l2 = 0;
    const double count = static_cast<double>(fine.sources.size());
    for (std::size_t k = 0; k < fine.sources.size(); ++k) {
      fem::ProxyPhaseTimes phases;
      const Eigen::VectorXd d = solver.distance({fine.sources[k]}, &phases);
      if (kept && k == 0) kept->geodesic = d;
      total.restriction += phases.restriction, total.coarse_solve += phases.coarse_solve, total.prolongation += phases.prolongation;
      const fem::DistanceErrors e = fem::distance_errors(d, fine.distances[k]);
      mean += e.mean_relative / count;
      max += e.max_relative / count;
      l2 += fem::relative_l2_error(d, fine.distances[k], fine.M) / count;
    }
    record(r, 2, total);
    r.error = mean, r.error_max = max, r.error_l2 = l2;
    rows.push_back(r);
  }
}

// ---- outputs ----------------------------------------------------------------------------------------

nlohmann::json row_json(const Row& r) {
  return {{"mesh", r.mesh},
          {"n", r.n},
          {"budget", r.budget},
          {"target", r.target},
          {"method", r.method},
          {"problem", r.problem},
          {"coarse_n", r.coarse_n},
          {"coarse_faces", r.coarse_faces},
          {"target_reached", r.target_reached},
          {"time_s",
           {{"coarsen", r.coarsen},
            {"assemble", r.assemble},
            {"factor", r.factor},
            {"solve", r.solve},
            {"prolong", r.prolong},
            {"proxy_total", r.proxy_total()},
            {"fine_assemble", r.fine_assemble},
            {"fine_factor", r.fine_factor},
            {"fine_solve", r.fine_solve},
            {"fine_total", r.fine_total()}}},
          {"speedup", {{"total", r.speedup_total()}, {"per_solve", r.speedup_solve()}}},
          {"error", {{"primary", r.error}, {"max_rel", r.error_max}, {"rel_l2", r.error_l2}}},
          {"qem_max_distance_rel", r.qem_max_distance >= 0 ? nlohmann::json(r.qem_max_distance) : nlohmann::json(nullptr)},
          {"note", r.note}};
}

// A CSV file: the header line, then one line per row written by write_row (9 significant digits).
template <class Item, class WriteRow>
void write_table(const std::string& path, const char* header, const std::vector<Item>& rows, WriteRow&& write_row) {
  std::ofstream out(path);
  out << header << '\n' << std::setprecision(9);
  for (const Item& r : rows) {
    write_row(out, r);
    out << '\n';
  }
  if (!out) throw app::AppError(app::kNotWritten, path + ": cannot be written");
}

void write_csv(const std::string& path, const std::vector<Row>& rows) {
  write_table(path,
              "mesh,n,budget,target,method,problem,coarse_n,coarse_faces,target_reached,coarsen_s,assemble_s,factor_s,"
              "solve_s,prolong_s,proxy_total_s,fine_assemble_s,fine_factor_s,fine_solve_s,fine_total_s,speedup_total,"
              "speedup_per_solve,error,error_max_rel,error_rel_l2,qem_max_distance_rel,note",
              rows, [](std::ostream& out, const Row& r) {
    out << r.mesh << ',' << r.n << ',' << r.budget << ',' << r.target << ',' << r.method << ',' << r.problem << ','
        << r.coarse_n << ',' << r.coarse_faces << ',' << (r.target_reached ? 1 : 0) << ',' << r.coarsen << ','
        << r.assemble << ',' << r.factor << ',' << r.solve << ',' << r.prolong << ',' << r.proxy_total() << ','
        << r.fine_assemble << ',' << r.fine_factor << ',' << r.fine_solve << ',' << r.fine_total() << ','
        << r.speedup_total() << ',' << r.speedup_solve() << ',' << r.error << ',' << r.error_max << ',' << r.error_l2
        << ',' << (r.qem_max_distance >= 0 ? num(r.qem_max_distance, 6) : "") << ',' << r.note;
  });
}

void write_eigen_csv(const std::string& path, const std::vector<EigenRow>& rows) {
  write_table(path,
              "mesh,n,budget,method,coarse_n,pairs,zero_modes,eigenvalue_rel_median,eigenvalue_rel_max,angle_deg_median,"
              "angle_deg_max,proxy_s,fine_s,note",
              rows, [](std::ostream& out, const EigenRow& r) {
    out << r.mesh << ',' << r.n << ',' << r.budget << ',' << r.method << ',' << r.coarse_n << ',' << r.pairs << ','
        << r.zero_modes << ',' << r.relative_median << ',' << r.relative_max << ',' << r.angle_median_deg << ','
        << r.angle_max_deg << ',' << r.seconds << ',' << r.fine_seconds << ',' << r.note;
  });
}

nlohmann::json eigen_json(const EigenRow& r) {
  const auto value = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
  return {{"mesh", r.mesh}, {"n", r.n}, {"budget", r.budget}, {"method", r.method}, {"coarse_n", r.coarse_n},
          {"pairs", r.pairs}, {"zero_modes", r.zero_modes},
          {"error", {{"eigenvalue_rel_median", value(r.relative_median)}, {"eigenvalue_rel_max", value(r.relative_max)},
                     {"angle_deg_median", value(r.angle_median_deg)}, {"angle_deg_max", value(r.angle_max_deg)}}},
          {"time_s", {{"proxy", r.seconds}, {"fine", r.fine_seconds}}}, {"note", r.note}};
}

// The eigenbasis per method: medians over meshes and budgets, and per mesh and budget each method's
// median eigenvalue error (median angle), with each ICE method's over QEM's (qem_ext) where both ran.
void write_eigen_summary(std::ostream& out, const std::vector<EigenRow>& rows, const std::vector<std::string>& methods) {
  if (rows.empty()) return;
  out << "\n## Eigenbasis (--eigen-pairs): the first " << rows.front().pairs
      << " eigenpairs through the Galerkin proxies against the fine mesh's\n\n"
         "Relative eigenvalue error (zero modes left out) and angle to the fine eigenspace, medians over the pairs; "
         "per mesh and budget, then the medians of those over meshes and budgets.\n\n| mesh | budget |";
  for (const auto& m : methods) out << ' ' << m << " |";
  const auto has = [&](const std::string& m) { return std::find(methods.begin(), methods.end(), m) != methods.end(); };
  std::vector<std::string> over_qem;  // ICE methods given a ratio column
  for (const std::string m : {"ice", "ice_area"})
    if (has(m) && has("qem_ext")) over_qem.push_back(m);
  for (const auto& m : over_qem) out << ' ' << m << " / qem_ext |";
  out << "\n|---|---:|";
  for (std::size_t i = 0; i < methods.size() + over_qem.size(); ++i) out << "---:|";
  out << '\n';
  std::map<std::pair<std::string, double>, std::map<std::string, const EigenRow*>> by_key;
  for (const EigenRow& r : rows) by_key[{r.mesh, r.budget}][r.method] = &r;
  std::map<std::string, std::vector<double>> errors, angles, ratios;
  for (const auto& [key, by_method] : by_key) {
    out << "| " << key.first << " | " << num(100 * key.second, 3) << "% |";
    for (const auto& m : methods) {
      const auto it = by_method.find(m);
      if (it == by_method.end() || !std::isfinite(it->second->relative_median)) {
        out << " " << (it == by_method.end() ? "–" : it->second->note) << " |";
        continue;
      }
      out << ' ' << pct(it->second->relative_median) << " (" << num(it->second->angle_median_deg, 3) << "°) |";
      errors[m].push_back(it->second->relative_median);
      angles[m].push_back(it->second->angle_median_deg);
    }
    for (const auto& m : over_qem) {
      const auto ice = by_method.find(m), qem = by_method.find("qem_ext");
      double x = std::numeric_limits<double>::quiet_NaN();
      if (ice != by_method.end() && qem != by_method.end() && qem->second->relative_median > 0)
        x = ice->second->relative_median / qem->second->relative_median;
      if (std::isfinite(x)) ratios[m].push_back(x);
      out << ' ' << num(x, 3) << " |";
    }
    out << '\n';
  }
  out << "| **median** | |";
  for (const auto& m : methods) out << ' ' << pct(median(errors[m])) << " (" << num(median(angles[m]), 3) << "°) |";
  for (const auto& m : over_qem) out << ' ' << num(median(ratios[m]), 3) << " |";
  out << '\n';
}

void write_polish_csv(const std::string& path, const std::vector<PolishRow>& rows) {
  write_table(path,
              "mesh,n,budget,method,problem,coarse_n,tolerance,iterations,reached,plain_error,error,estimated_error,"
              "polish_setup_s,polish_s,proxy_solve_s,per_solve_s,fine_factor_s,fine_solve_s",
              rows, [](std::ostream& out, const PolishRow& r) {
    out << r.mesh << ',' << r.n << ',' << r.budget << ',' << r.method << ',' << r.problem << ',' << r.coarse_n << ','
        << r.tolerance << ',' << r.iterations << ',' << (r.reached ? 1 : 0) << ',' << r.plain_error << ',' << r.error
        << ',' << r.estimated_error << ',' << r.setup << ',' << r.polish << ',' << r.proxy_solve << ',' << r.per_solve()
        << ',' << r.fine_factor << ',' << r.fine_solve;
  });
}

// Polishing per problem, method and tolerance: is the tolerance met (true error <= T), how many
// iterations, and what a polished solve costs against the fine factor + solve.
void write_polish_summary(std::ostream& out, const std::vector<PolishRow>& rows, const std::vector<std::string>& methods) {
  if (rows.empty()) return;
  out << "\n## Polished proxy (--tolerances): true error against the fine solution\n\n"
         "Per problem, method and tolerance T over meshes and budgets: how often the true error is at most T, the "
         "largest true error / T, the estimate's range (true / estimated), median iterations, and the median cost "
         "of a polished solve (coarse solve + prolong + polish) over the fine factor + solve.\n\n"
         "| problem | method | T | true <= T | max true / T | true / estimate min–max | median iterations | median "
         "plain error | median per solve / fine factor+solve |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
  std::set<double> tolerances;
  for (const PolishRow& r : rows) tolerances.insert(r.tolerance);
  for (const std::string problem : {"poisson", "heat"})
    for (const auto& m : methods)
      for (double t : tolerances) {
        int met = 0, count = 0;
        double worst = 0, low = std::numeric_limits<double>::infinity(), high = 0;
        std::vector<double> iterations, plain, cost;
        for (const PolishRow& r : rows) {
          if (r.problem != problem || r.method != m || r.tolerance != t) continue;
          ++count;
          met += r.error <= t;
          worst = std::max(worst, r.error / t);
          if (r.estimated_error > 0) {
            low = std::min(low, r.error / r.estimated_error);
            high = std::max(high, r.error / r.estimated_error);
          }
          iterations.push_back(r.iterations);
          plain.push_back(r.plain_error);
          cost.push_back(r.per_solve() / std::max(r.fine_factor + r.fine_solve, 1e-12));
        }
        if (count == 0) continue;
        out << "| " << problem << " | " << m << " | " << num(t, 3) << " | " << met << "/" << count << " | " << num(worst, 3)
            << " | " << num(low, 3) << "–" << num(high, 3) << " | " << num(median(iterations), 3) << " | "
            << pct(median(plain)) << " | " << num(median(cost), 3) << " |\n";
      }
}

struct Key {
  std::string mesh, problem;
  double budget;
  bool operator<(const Key& o) const { return std::tie(mesh, problem, budget) < std::tie(o.mesh, o.problem, o.budget); }
};

void write_summary(const std::string& path, const std::vector<Row>& rows, const std::vector<std::string>& methods,
                   const std::vector<double>& budgets, const std::vector<std::string>& meshes, const std::string& command,
                   double total_seconds, const std::string& operators, double area_weight, bool normalize_curvature,
                   const std::vector<PolishRow>& polished, const nlohmann::json& skipped,
                   const std::map<std::string, double>& fine_heat_method_errors, const std::vector<EigenRow>& eigen) {
  std::map<Key, std::map<std::string, const Row*>> by_key;
  for (const Row& r : rows) by_key[{r.mesh, r.problem, r.budget}][r.method] = &r;
  const auto has = [&](const std::string& m) { return std::find(methods.begin(), methods.end(), m) != methods.end(); };
  std::vector<std::pair<std::string, std::string>> ratios;  // (numerator, denominator)
  for (const std::string ice : {"ice", "ice_area"})
    for (const std::string qem : {"qem_ext", "qem_idt"})
      if (has(ice) && has(qem)) ratios.emplace_back(ice, qem);

  std::ofstream out(path);
  out << "# ICE vs QEM report\n\n"
      << "Command: `" << command << "`  \n"
      << "Meshes (" << meshes.size() << "): " << [&] {
           std::string s;
           for (const auto& m : meshes) s += (s.empty() ? "" : ", ") + m;
           return s;
         }() << "  \n";
  for (const auto& entry : skipped)
    out << "Skipped " << entry["mesh"].get<std::string>() << ": " << entry["reason"].get<std::string>() << "  \n";
  out << "Coarse operators of ICE: " << operators << " (QEM: from its own geometry); ICE area weight for `ice_area`: " << area_weight
      << (normalize_curvature ? " (normalised curvature)" : " (curvature not normalised)")
      << "; fine reference on the intrinsic Delaunay triangulation of the input; BLAS: " << fem::blas_library()
      << "  \nTotal run time " << num(total_seconds, 3) << " s.\n\n"
      << "Methods: `ice` ICE curvature only (the paper's metric); `ice_area` ICE with area weight; `qem_ext` QEM (OpenMesh quadric "
         "decimation, closest-point map) with operators from its positions; `qem_idt` the same QEM mesh and P with "
         "operators from its intrinsic Delaunay triangulation.  \n"
         "Errors: Poisson and heat relative L2 (fine mass norm); geodesic mean |d - d_ref| / max d_ref over 3 "
         "sources, d_ref "
      << (fine_heat_method_errors.empty() ? "the fine heat method's distances" : "exact polyhedral geodesics (CGAL)")
      << ". Ratios < 1 mean ICE is more accurate.\n\n";
  if (!fine_heat_method_errors.empty()) {
    std::vector<double> errors;
    for (const auto& [mesh, error] : fine_heat_method_errors) errors.push_back(error);
    out << "The fine heat method against exact geodesics (same error measure): median " << pct(median(errors))
        << " over " << errors.size() << " meshes.\n\n";
  }

  for (const std::string& problem : kProblems) {
    out << "## " << problem << ": median error per method, median ICE/QEM error ratio\n\n| budget | median coarse n |";
    for (const auto& m : methods) out << ' ' << m << " |";
    for (const auto& [a, b] : ratios) out << ' ' << a << "/" << b << " |";
    out << " ice beats qem_idt |\n|---|---:|";
    for (std::size_t i = 0; i < methods.size() + ratios.size(); ++i) out << "---:|";
    out << "---:|\n";
    for (double budget : budgets) {
      std::map<std::string, std::vector<double>> errors, ratio_values;
      std::vector<double> sizes;
      int wins = 0, count = 0;
      for (const auto& [key, row_of] : by_key) {
        if (key.problem != problem || key.budget != budget) continue;
        for (const auto& [m, r] : row_of) {
          errors[m].push_back(r->error);
          if (m == methods.front()) sizes.push_back(static_cast<double>(r->coarse_n));
        }
        for (const auto& [a, b] : ratios)
          if (row_of.count(a) && row_of.count(b))
            ratio_values[a + "/" + b].push_back(row_of.at(a)->error / row_of.at(b)->error);
        if (row_of.count("ice") && row_of.count("qem_idt")) {
          ++count;
          wins += row_of.at("ice")->error < row_of.at("qem_idt")->error;
        }
      }
      out << "| " << num(100 * budget, 3) << "% | " << num(median(sizes), 5) << " |";
      for (const auto& m : methods) out << ' ' << pct(median(errors[m])) << " |";
      for (const auto& [a, b] : ratios) out << ' ' << num(median(ratio_values[a + "/" + b]), 3) << " |";
      out << ' ' << wins << "/" << count << " |\n";
    }
    out << '\n';
  }

  // Coarsening time on the same inputs (the same for every problem: take the Poisson rows).
  out << "## Coarsening time, ICE vs QEM (seconds, same inputs; QEM = decimation + closest-point map; qem_idt "
         "adds the intrinsic Delaunay flips)\n\n| mesh | n | budget | coarse n |";
  for (const auto& m : methods) out << ' ' << m << " |";
  out << " ice/qem_ext |\n|---|---:|---:|---:|";
  for (std::size_t i = 0; i <= methods.size(); ++i) out << "---:|";
  out << '\n';
  std::vector<double> time_ratios;
  std::map<std::string, double> total_time;
  for (const auto& [key, row_of] : by_key) {
    if (key.problem != "poisson") continue;
    const Row* first = row_of.begin()->second;
    out << "| " << key.mesh << " | " << first->n << " | " << num(100 * key.budget, 3) << "% | " << first->coarse_n << " |";
    for (const auto& m : methods) {
      const auto it = row_of.find(m);
      out << ' ' << (it == row_of.end() ? "n/a" : num(it->second->coarsen, 3)) << " |";
      if (it != row_of.end()) total_time[m] += it->second->coarsen;
    }
    double ratio = std::numeric_limits<double>::quiet_NaN();
    if (row_of.count("ice") && row_of.count("qem_ext")) ratio = row_of.at("ice")->coarsen / row_of.at("qem_ext")->coarsen;
    time_ratios.push_back(ratio);
    out << ' ' << num(ratio, 3) << " |\n";
  }
  out << "\nTotal coarsening time per method:";
  for (const auto& m : methods) out << ' ' << m << ' ' << num(total_time[m], 4) << " s;";
  out << " median ICE/QEM time ratio " << num(median(time_ratios), 3) << ".\n\n";

  // Speed-up vs the fine solve.
  out << "## Speed-up vs the fine solve (median over meshes; end to end = fine assemble+factor+solve / proxy "
         "coarsen+assemble+factor+solve+prolong; per solve = fine solve / (coarse solve + prolong))\n\n"
         "| problem | budget |";
  for (const auto& m : methods) out << ' ' << m << " end to end | " << m << " per solve |";
  out << "\n|---|---:|";
  for (std::size_t i = 0; i < 2 * methods.size(); ++i) out << "---:|";
  out << '\n';
  for (const std::string& problem : kProblems)
    for (double budget : budgets) {
      out << "| " << problem << " | " << num(100 * budget, 3) << "% |";
      for (const auto& m : methods) {
        std::vector<double> total, solve;
        for (const Row& r : rows)
          if (r.problem == problem && r.budget == budget && r.method == m) {
            total.push_back(r.speedup_total());
            solve.push_back(r.speedup_solve());
          }
        out << ' ' << num(median(total), 3) << "x | " << num(median(solve), 3) << "x |";
      }
      out << '\n';
    }

  // Where ICE does not win, per ICE method.
  for (const std::string ice_method : {"ice", "ice_area"}) {
    if (!has(ice_method)) continue;
    out << "\n## Where " << ice_method << " is less accurate than QEM\n\n";
    int losses = 0, cases = 0;
    std::ostringstream list;
    for (const auto& [key, row_of] : by_key) {
      if (!row_of.count(ice_method)) continue;
      const Row* ice = row_of.at(ice_method);
      for (const std::string q : {"qem_ext", "qem_idt"}) {
        if (!row_of.count(q)) continue;
        ++cases;
        if (ice->error > row_of.at(q)->error) {
          ++losses;
          list << "- " << key.mesh << ", " << num(100 * key.budget, 3) << "%, " << key.problem << ": " << ice_method << ' '
               << pct(ice->error) << " vs " << q << ' ' << pct(row_of.at(q)->error) << '\n';
        }
      }
    }
    out << losses << " of " << cases << " comparisons (mesh × budget × problem × QEM variant):\n\n" << list.str();
  }
  write_polish_summary(out, polished, methods);
  write_eigen_summary(out, eigen, methods);
  std::vector<std::string> notes;
  for (const Row& r : rows)
    if (!r.note.empty() && r.problem == "poisson") notes.push_back(r.mesh + " " + num(100 * r.budget, 3) + "% " + r.method + ": " + r.note);
  if (!notes.empty()) {
    out << "\n## Notes\n\n";
    for (const auto& n : notes) out << "- " << n << '\n';
  }
  if (!out) throw app::AppError(app::kNotWritten, path + ": cannot be written");
}

// Data files for plot_report.gp (blocks separated by two blank lines, one per method or problem).
void write_plot_data(const std::string& dir, const std::vector<Row>& rows, const std::vector<std::string>& methods,
                     const std::vector<double>& budgets) {
  for (const std::string& problem : kProblems) {
    std::ofstream out(dir + "/plot_error_" + problem + ".dat");
    for (const auto& m : methods) {
      out << "# " << m << ": coarse_n error\n";
      for (const Row& r : rows)
        if (r.problem == problem && r.method == m && std::isfinite(r.error)) out << r.coarse_n << ' ' << r.error << '\n';
      out << "\n\n";
    }
    std::ofstream med(dir + "/plot_median_" + problem + ".dat");
    for (const auto& m : methods) {
      med << "# " << m << ": budget_percent median_error\n";
      for (double b : budgets) {
        std::vector<double> e;
        for (const Row& r : rows)
          if (r.problem == problem && r.method == m && r.budget == b) e.push_back(r.error);
        med << 100 * b << ' ' << median(e) << '\n';
      }
      med << "\n\n";
    }
  }
  // Mean time per phase (over meshes and budgets), per method, summed over the three problems; and fine.
  std::ofstream ph(dir + "/plot_phases.dat");
  ph << "# method coarsen assemble factor solve prolong\n";
  std::set<std::tuple<std::string, double>> instances;
  for (const Row& r : rows) instances.insert({r.mesh, r.budget});
  const double count = std::max<double>(1, static_cast<double>(instances.size()));
  for (const auto& m : methods) {
    double c = 0, a = 0, f = 0, s = 0, p = 0;
    for (const Row& r : rows)
      if (r.method == m) {
        if (r.problem == "poisson") c += r.coarsen;
        a += r.assemble, f += r.factor, s += r.solve, p += r.prolong;
      }
    ph << m << ' ' << c / count << ' ' << a / count << ' ' << f / count << ' ' << s / count << ' ' << p / count << '\n';
  }
  double a = 0, f = 0, s = 0;
  for (const Row& r : rows)
    if (r.method == methods.front()) a += r.fine_assemble, f += r.fine_factor, s += r.fine_solve;
  ph << "fine 0 " << a / count << ' ' << f / count << ' ' << s / count << " 0\n";
  // Median speed-ups of the first method vs budget, per problem.
  std::ofstream sp(dir + "/plot_speedup.dat");
  for (const std::string& problem : kProblems) {
    sp << "# " << problem << ": budget_percent end_to_end per_solve (" << methods.front() << ")\n";
    for (double b : budgets) {
      std::vector<double> t, s2;
      for (const Row& r : rows)
        if (r.problem == problem && r.method == methods.front() && r.budget == b) {
          t.push_back(r.speedup_total());
          s2.push_back(r.speedup_solve());
        }
      sp << 100 * b << ' ' << median(t) << ' ' << median(s2) << '\n';
    }
    sp << "\n\n";
  }
}

std::vector<double> parse_doubles(const std::string& text, const std::string& what) {
  std::vector<double> values;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      values.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw app::AppError(app::kUsage, what + ": '" + item + "' is not a number");
    }
  }
  return values;
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) items.push_back(item);
  return items;
}

}  // namespace

// ---- the 3D page ------------------------------------------------------------------------------------

// The fine solutions every method is compared with (common fields of the mesh's view).
void add_fine_fields(app::ViewMesh& view, const Fine& fine) {
  view.fields.push_back(app::view_field(view, "poisson: fine solution", "poisson", "solution", "", fine.poisson));
  view.fields.push_back(app::view_field(view, "heat: fine solution", "heat", "solution", "", fine.heat));
  view.fields.push_back(app::view_field(view, "geodesic: fine distance", "geodesic", "solution", "", fine.distances.front()));
}

// One method of the view: its coarse edges, its relative L2 errors at the page's budget (geodesics:
// the mean over the sources) and |u - u_fine| per problem (geodesics: from the first source).
void add_view_method(app::ViewMesh& view, const std::string& method, const ice::TriangleMesh& mesh,
                     const ice::CoarseSpace& coarse, const Fine& fine, const ProxySolutions& solved,
                     const std::vector<Row>& rows) {
  std::optional<ice::CoarseTracing> tracing;
  if (coarse.triangulation) tracing = ice::trace_coarse_mesh(mesh, coarse);  // ICE: its edges on the surface
  app::ViewMethod drawn = app::view_method(method, mesh, coarse, tracing ? &*tracing : nullptr);
  for (auto it = rows.rbegin(); it != rows.rbegin() + std::min<std::ptrdiff_t>(3, static_cast<std::ptrdiff_t>(rows.size())); ++it)
    if (it->method == method && std::isfinite(it->error_l2)) drawn.errors[it->problem] = it->error_l2;  // as the tools' pages
  view.methods.push_back(std::move(drawn));
  view.fields.push_back(app::view_field(view, "poisson |error| " + method, "poisson", "error", method,
                                        (solved.poisson - fine.poisson).cwiseAbs()));
  view.fields.push_back(app::view_field(view, "heat |error| " + method, "heat", "error", method,
                                        (solved.heat - fine.heat).cwiseAbs()));
  view.fields.push_back(app::view_field(view, "geodesic |error| " + method, "geodesic", "error", method,
                                        (solved.geodesic - fine.distances.front()).cwiseAbs()));
  if (tracing) view.fields.push_back(app::view_field(view, "patch " + method, "", "label", method, app::patch_values(*tracing)));
}

// A method that failed on the mesh: shown as such on the page, with the reason.
void add_failed_method(app::ViewMesh& view, const std::string& method, const std::string& reason) {
  app::ViewMethod failed;
  failed.name = method;
  failed.ok = false;
  failed.message = reason;
  view.methods.push_back(std::move(failed));
}

int main(int argc, char** argv) {
  ice::keep_freed_memory_for_reuse();  // one job per process: reuse freed arrays instead of re-faulting them
  CLI::App cli{
      "ice-report: ICE against the QEM baseline on the same meshes, budgets and problems (Poisson, heat, geodesics); "
      "writes\nresults.csv, results.json, summary.md and SVG plots into the output directory.\n\n"
      "Examples:\n  ice-report -o report\n  ice-report --quick -o /tmp/r\n"
      "  ice-report --meshes spot.obj,/data/my.off --budgets 0.02,0.05 --methods ice,qem_idt -o r"};
  std::string outdir = "ice-report", meshes_text, budgets_text = "0.01,0.02,0.05,0.1", methods_text = "ice,ice_area,qem_ext,qem_idt";
  // The sources' script when run from the build tree, the installed one otherwise.
  std::string meshes_dir, operators = "galerkin",
                          plot_script = fs::exists(ICE_REPORT_PLOT_SCRIPT_SOURCE) ? ICE_REPORT_PLOT_SCRIPT_SOURCE
                                                                                  : ICE_REPORT_PLOT_SCRIPT;
  long long min_vertices = 100;
  double area_weight = ice::recommended_coarsen_options().area_weight;  // the pipeline's default metric
  bool quick = false, no_plots = false;
  cli.add_option("--output,-o", outdir, "Output directory (created; report files in it are replaced)")
      ->capture_default_str();
  cli.add_option("--meshes", meshes_text,
                 "Comma-separated mesh names or paths (default: the clean meshes of both sets)");
  cli.add_option("--meshes-dir", meshes_dir, "Where mesh names are looked up (default: data/default/, then the extended set)");
  cli.add_option("--budgets", budgets_text, "Comma-separated coarse budgets (fractions of the vertices)")->capture_default_str();
  cli.add_option("--min-vertices", min_vertices, "Floor of every coarse size (at most the input size)")->capture_default_str();
  cli.add_option("--methods", methods_text, "Comma-separated subset of the methods")->capture_default_str();
  cli.add_option("--area-weight", area_weight, "ICE area weight of the ice_area method")->capture_default_str();
  cli.add_option("--operators", operators,
                 "Coarse operators of the ICE methods: galerkin or intrinsic (QEM's: see --qem-prolongation)")
      ->check(CLI::IsMember({"intrinsic", "galerkin"}))
      ->capture_default_str();
  ice::proxy::Prolongation prolongation_choice = ice::proxy::Prolongation::automatic;
  app::add_prolongation_option(cli, prolongation_choice);
  ice::proxy::Prolongation qem_choice = ice::proxy::Prolongation::automatic;
  app::add_prolongation_option(
      cli, qem_choice, "--qem-prolongation",
      "QEM's proxy: 'smoothed'/'smoothed_twice' (Galerkin), 'barycentric' (its own operators) or 'auto'");
  bool normalize_curvature = ice::recommended_coarsen_options().normalize_curvature;
  cli.add_flag("--normalize-curvature,!--no-normalize-curvature", normalize_curvature,
               "ice_area: curvature masses divided by the total absolute curvature")
      ->capture_default_str();
  fem::ProxyGeodesicOptions geodesic;
  app::add_choice(cli, "--coarse-distances", geodesic.method,
                  {{"marching", fem::CoarseDistanceMethod::marching}, {"heat", fem::CoarseDistanceMethod::heat_method}},
                  "Geodesics through the proxy: coarse fast marching or the coarse heat method");
  cli.add_option("--time-factor", geodesic.time_factor,
                 "With --coarse-distances heat: t = (F x coarse mean edge length)^2")
      ->check(app::positive_number())
      ->capture_default_str();
  cli.add_option("--marching-subdivisions", geodesic.subdivisions,
                 "Coarse marching on the coarse mesh split 1:4 this many times")
      ->check(CLI::Range(0, fem::kMaxMarchingSubdivisions))
      ->capture_default_str();
  bool exact_geodesics = false;
  app::add_choice(cli, "--geodesic-reference", exact_geodesics, {{"heat", false}, {"exact", true}},
                  "Geodesic errors against the fine heat method or exact geodesics (CGAL builds)");
  bool equal_sizes = true;
  cli.add_flag("--equal-sizes,!--no-equal-sizes", equal_sizes,
               "Compare methods at equal vertex counts where one stops above the target (default on)");
  long long exact_max_vertices = ice_bench::kDefaultExactMaxVertices;
  cli.add_option("--exact-max-vertices", exact_max_vertices,
                 "With --geodesic-reference exact: skip meshes of more vertices")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  ice::proxy::CoarseLengths lengths_choice = ice::proxy::CoarseLengths::automatic;
  app::add_coarse_lengths_option(cli, "--geodesic-lengths", lengths_choice);  // (the tracing counts in the
                                                                              // geodesic row's factor time)
  ice::proxy::CurvatureCorrection curvature_correction = ice::proxy::CurvatureCorrection::automatic;
  app::add_curvature_correction_option(cli, curvature_correction);
  cli.add_option("--curvature-divisor", geodesic.curvature_divisor,
                 "Divisor d of the curvature correction exp(K l^2/d) (default: measured best)")
      ->check(app::positive_number())
      ->capture_default_str();
  int coarsen_threads = 0, coarsen_regions = 0;  // ICE coarsening's parallel phase (ice::CoarsenOptions' defaults)
  app::add_coarsen_parallel_options(cli, coarsen_threads, coarsen_regions);
  std::string tolerances_text;
  cli.add_option("--tolerances", tolerances_text,
                 "Also polish the Poisson and heat proxies to these tolerances, e.g. 1e-2,1e-3 (polish.csv)");
  int eigen_pairs = 20;
  cli.add_option("--eigen-pairs", eigen_pairs,
                 "Also compare the first K Laplace-Beltrami eigenpairs through the Galerkin proxies (eigen.csv; 0: off)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  bool repair = false;
  cli.add_flag("--repair", repair,
               "Apply the safe mesh repairs (else defective meshes are skipped)");
  cli.add_flag("--quick", quick, "Small subset for CI: spot and elephant, budgets 5% and 10%");
  cli.add_flag("--no-plots", no_plots, "Do not run gnuplot");
  bool no_html = false, force = false;
  double view_budget = 0;
  cli.add_flag("--no-html", no_html, "Do not write report.html (the 3D page)");
  cli.add_option("--view-budget", view_budget,
                 "The budget the 3D page shows (default: nearest 5%)");
  cli.add_flag("--force", force, "Replace an existing report.html");
  cli.add_option("--plot-script", plot_script, "The gnuplot script that draws the plots")->capture_default_str();
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&] {
    app::Stopwatch total_clock;
    std::string command;
    for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);
    std::vector<std::string> mesh_names = meshes_text.empty() ? (quick ? kQuickMeshes : kDefaultMeshes) : split(meshes_text);
    std::vector<double> budgets = parse_doubles(budgets_text, "--budgets");
    if (quick && cli.count("--budgets") == 0) budgets = {0.05, 0.1};
    for (double b : budgets)
      if (!(b > 0 && b <= 1)) throw app::AppError(app::kUsage, "--budgets: every budget must be in (0, 1]");
    const std::vector<std::string> methods = split(methods_text);
    for (const auto& m : methods)
      if (m != "ice" && m != "ice_area" && m != "qem_ext" && m != "qem_idt")
        throw app::AppError(app::kUsage, "--methods: unknown method '" + m + "'");
    if (methods.empty()) throw app::AppError(app::kUsage, "--methods: none given");
    const std::vector<double> tolerances =
        tolerances_text.empty() ? std::vector<double>{} : parse_doubles(tolerances_text, "--tolerances");
    for (double t : tolerances)
      if (!(t > 0 && t < 1)) throw app::AppError(app::kUsage, "--tolerances: every tolerance must be in (0, 1)");
    if (!(area_weight >= 0 && area_weight <= 1)) throw app::AppError(app::kUsage, "--area-weight must be in [0, 1]");
    const fem::CoarseOperatorKind kind =
        operators == "galerkin" ? fem::CoarseOperatorKind::galerkin : fem::CoarseOperatorKind::intrinsic;
    // The coarse heat method needs the barycentric P (fem::ProxyGeodesicSolver), and one proxy serves
    // the three problems.
    const std::string heat_geodesics =
        geodesic.method == fem::CoarseDistanceMethod::heat_method ? "--coarse-distances heat" : "";
#ifndef ICE_REPORT_EXACT_GEODESICS
    if (exact_geodesics)
      throw app::AppError(app::kUsage, "--geodesic-reference exact: this ice-report was built without CGAL (libcgal-dev)");
#endif
    if (lengths_choice == ice::proxy::CoarseLengths::traced && !heat_geodesics.empty())
      throw app::AppError(app::kUsage, "--geodesic-lengths traced: the lengths are for coarse marching, not with --coarse-distances heat");
    // ICE's geodesics march on traced lengths unless asked otherwise (QEM's keep their own).
    const bool traced_lengths = ice::proxy::traces_lengths(lengths_choice, ice::CoarseningMethod::ice, heat_geodesics.empty());
    const fem::ProlongationKind prolongation = app::resolve_prolongation(prolongation_choice, kind, heat_geodesics);
    // QEM: Galerkin operators of its smoothed P, or the operators of its own geometry with its P as given.
    const fem::ProlongationKind qem_prolongation =
        app::resolve_prolongation(qem_choice, fem::CoarseOperatorKind::galerkin, heat_geodesics, "--qem-prolongation");
    const fem::CoarseOperatorKind qem_kind =
        fem::is_smoothed(qem_prolongation) ? fem::CoarseOperatorKind::galerkin : fem::CoarseOperatorKind::intrinsic;
    if (cli.count("--view-budget") == 0) {
      view_budget = budgets.front();
      for (double b : budgets)
        if (std::abs(b - 0.05) < std::abs(view_budget - 0.05)) view_budget = b;
    } else if (std::find(budgets.begin(), budgets.end(), view_budget) == budgets.end()) {
      throw app::AppError(app::kUsage, "--view-budget must be one of --budgets");
    }
    std::error_code ec;
    fs::create_directories(outdir, ec);
    if (ec) throw app::AppError(app::kNotWritten, "--output " + outdir + ": " + ec.message());
    const std::string page = outdir + "/report.html";
    if (!no_html) app::check_view_page(page, force, "the page");  // before the runs: an existing page, missing viewer files

    // Resolve the meshes; the default list skips missing files (with a note), an explicit one fails.
    const std::string where = !meshes_dir.empty() ? meshes_dir
                                                  : ice_mesh_sets::project_dir() + " or " + ice_mesh_sets::extended_dir();
    std::vector<std::pair<std::string, std::string>> inputs;  // (name, path)
    for (const auto& name : mesh_names) {
      const std::string path = fs::exists(name)         ? name
                               : !meshes_dir.empty()     ? meshes_dir + "/" + name
                                                         : ice_mesh_sets::find(name);
      if (path.empty() || !fs::exists(path)) {
        if (!meshes_text.empty()) throw app::AppError(app::kUnreadable, name + ": no such mesh in " + where);
        app::warn(kTool, "skipping " + name + ": not in " + where);
        continue;
      }
      inputs.emplace_back(fs::path(name).stem().string(), path);
    }
    if (inputs.empty()) throw app::AppError(app::kUnreadable, "no meshes found (looked in " + where + ")");

    std::vector<Row> rows;
    std::vector<PolishRow> polished;
    std::vector<EigenRow> eigen_rows;  // --eigen-pairs: one per mesh, budget and method
    std::vector<app::ViewMesh> views;  // the 3D page: one per mesh
    std::vector<std::string> used_meshes;
    std::map<std::string, double> fine_heat_method_errors;  // --geodesic-reference exact: mesh -> error
    nlohmann::json skipped = nlohmann::json::array();  // {mesh, reason} of the inputs not used
    const std::size_t steps = inputs.size() * budgets.size();
    std::size_t step = 0;
    for (const auto& [name, path] : inputs) {
      app::Stopwatch mesh_clock;
      // A mesh that cannot be used is skipped with its reason (in results.json too), not the report.
      const auto skip = [&, &name = name](const std::string& reason) {
        app::warn(kTool, "skipping " + name + ": " + reason);
        skipped.push_back({{"mesh", name}, {"reason", reason}});
      };
      std::optional<ice::LoadResult> loaded_or;
      try {
        loaded_or.emplace(app::load_input_mesh(path, repair));
      } catch (const ice::MeshError& e) {
        const bool repairable = e.kind() == ice::MeshError::Kind::Defective && !repair;
        skip(std::string(e.what()) + (repairable ? " (--repair applies the safe repairs)" : ""));
        continue;
      }
      const ice::LoadResult& loaded = *loaded_or;
      if (loaded.report.components.size() != 1) {
        skip("not connected (" + std::to_string(loaded.report.components.size()) + " components)");
        continue;
      }
      const ice::TriangleMesh& mesh = loaded.mesh;
      const long long n = mesh.V.rows();
      if (exact_geodesics && n > exact_max_vertices) {
        skip(app::thousands(n) + " vertices, above --exact-max-vertices " + app::thousands(exact_max_vertices) +
             " (the exact geodesics' memory grows faster than the mesh)");
        continue;
      }
      used_meshes.push_back(name);
      const double diagonal = (mesh.V.colwise().maxCoeff() - mesh.V.colwise().minCoeff()).norm();
      const Fine fine = fine_reference(mesh, exact_geodesics, eigen_pairs);
      if (exact_geodesics) fine_heat_method_errors[name] = fine.heat_method_error;
      std::cerr << kTool << ": " << name << " (" << app::thousands(n) << " vertices): fine reference "
                << app::fixed(mesh_clock.seconds(), 2) << " s\n";
      std::optional<app::ViewMesh> view;
      if (!no_html) {
        view = app::view_mesh(name, mesh, app::kDisplayVertices);
        add_fine_fields(*view, fine);
      }
      for (double budget : budgets) {
        ++step;
        const bool viewed = view && budget == view_budget;
        const long long target = ice::proxy::target_vertices(static_cast<ice::Index>(n), budget,
                                                             static_cast<ice::Index>(std::min(min_vertices, n)));
        Row base;
        base.mesh = name, base.n = n, base.budget = budget, base.target = target;
        std::ostringstream progress;
        progress << kTool << ": [" << step << "/" << steps << "] " << name << ' ' << num(100 * budget, 3) << "% -> "
                 << target << ':';
        // Coarse sizes first: where a method stops above the target (it cannot go lower without
        // changing the topology: many holes or handles), the others are coarsened to the size it
        // reached (--equal-sizes), so that every comparison is at equal vertex counts.
        const auto build_ice = [&](const std::string& m, long long size) {
          ice::CoarseSpaceOptions options;
          options.coarsen.target_vertices = static_cast<ice::Index>(size);
          options.coarsen.area_weight = m == "ice" ? 0.0 : area_weight;
          options.coarsen.normalize_curvature = m == "ice" ? false : normalize_curvature;
          options.coarsen.threads = coarsen_threads;
          options.coarsen.regions = coarsen_regions;
          options.keep_method_state = viewed || traced_lengths;  // the page and traced lengths trace the coarse edges:
          options.record_history = viewed;                       // the page exactly, the lengths by the walk
          return ice::build_coarse_space(mesh, options);
        };
        const auto decimate = [&](long long size) {
          ice::QemOptions options;
          options.target_vertices = static_cast<ice::Index>(size);
          return ice::qem_coarsen(mesh, options);
        };
        const auto wanted = [&](const std::string& m) { return std::find(methods.begin(), methods.end(), m) != methods.end(); };
        std::map<std::string, ice::CoarseSpace> ice_spaces;  // (in the order ice, ice_area)
        for (const std::string m : {"ice", "ice_area"})
          if (wanted(m)) ice_spaces.emplace(m, build_ice(m, target));
        std::optional<ice::QemResult> decimated;
        if (wanted("qem_ext") || wanted("qem_idt")) decimated = decimate(target);
        long long equal_size = target;
        if (equal_sizes) {  // (a method that reached the target is not run again)
          for (const auto& [m, space] : ice_spaces) equal_size = std::max<long long>(equal_size, space.summary.coarse_vertices);
          if (decimated) equal_size = std::max<long long>(equal_size, static_cast<long long>(decimated->to_input.size()));
          if (equal_size > target) {
            for (auto& [m, space] : ice_spaces)
              if (space.summary.coarse_vertices < equal_size) space = build_ice(m, equal_size);
            if (decimated && static_cast<long long>(decimated->to_input.size()) < equal_size) decimated = decimate(equal_size);
          }
        }
        const std::string equal_note =
            equal_size > target ? "size raised to " + std::to_string(equal_size) + " (--equal-sizes)" : std::string();
        const auto add_note = [](Row& r, const std::string& note) {
          if (!note.empty()) r.note += (r.note.empty() ? "" : "; ") + note;
        };
        // ICE variants.
        for (const auto& [m, coarse] : ice_spaces) {
          std::optional<ice::FaceLengths> marching_lengths;
          app::Stopwatch trace_clock;
          if (traced_lengths)
            marching_lengths = ice::proxy::marching_lengths(mesh, coarse, true, curvature_correction, nullptr, geodesic.curvature_divisor).lengths;
          const double trace_seconds = trace_clock.lap();
          Row r = base;
          r.method = m;
          r.coarsen = coarse.summary.seconds;
          r.coarse_n = coarse.summary.coarse_vertices;
          r.coarse_faces = coarse.summary.coarse_faces;
          r.target_reached = coarse.summary.target_reached;
          if (!r.target_reached) r.note = std::string("stopped: ") + ice::to_string(coarse.summary.stop_reason());
          add_note(r, equal_note);
          ProxySolutions solved;
          fem::ProxyGeodesicOptions ice_geodesic = geodesic;
          ice_geodesic.curvature_correction = ice::proxy::corrects_curvature(curvature_correction, coarse.summary.method);
          solve_on_proxy(fine, coarse, kind, prolongation, r, rows, tolerances, polished, ice_geodesic,
                         viewed ? &solved : nullptr, marching_lengths ? &*marching_lengths : nullptr, &eigen_rows);
          rows.back().factor += trace_seconds;  // the geodesic row: its marching needs the tracing
          if (viewed) add_view_method(*view, m, mesh, coarse, fine, solved, rows);
          progress << ' ' << m << ' ' << app::fixed(r.coarsen, 2) << " s (" << pct(rows[rows.size() - 3].error) << ' '
                   << pct(rows[rows.size() - 2].error) << ' ' << pct(rows.back().error) << ')';
        }
        // QEM: one decimation, its two coarse geometries.
        for (const std::string m : {"qem_ext", "qem_idt"}) {
          if (!wanted(m)) continue;
          Row r = base;
          r.method = m;
          ice::CoarseSpace coarse;
          try {
            coarse = ice::coarse_space_from_qem(
                *decimated, m == "qem_idt" ? ice::QemGeometry::intrinsic_delaunay : ice::QemGeometry::extrinsic);
          } catch (const std::runtime_error& e) {  // the QEM mesh has a face no intrinsic triangulation takes
            record_failure(r, e.what(), rows);
            if (viewed) add_failed_method(*view, m, e.what());
            continue;
          }
          const ice::QemOutcome& qem = *coarse.summary.qem;
          r.target_reached = coarse.summary.target_reached;
          r.qem_max_distance = qem.max_distance / diagonal;
          if (!r.target_reached) r.note = "QEM stopped early";
          add_note(r, equal_note);
          if (qem.guard_relaxed) add_note(r, "normal guard relaxed");
          r.coarsen = qem.decimate_seconds + qem.map_seconds + coarse.summary.seconds;
          r.coarse_n = coarse.summary.coarse_vertices;
          r.coarse_faces = coarse.summary.coarse_faces;
          try {
            // QEM with Galerkin operators of its smoothed P, or with the operators of its own geometry
            // (positions, or their intrinsic Delaunay triangulation; Galerkin operators with its
            // barycentric P make QEM less accurate).
            ProxySolutions solved;
            fem::ProxyGeodesicOptions qem_geodesic = geodesic;
            qem_geodesic.curvature_correction = ice::proxy::corrects_curvature(curvature_correction, coarse.summary.method);
            solve_on_proxy(fine, coarse, qem_kind, qem_prolongation, r, rows, tolerances, polished, qem_geodesic,
                           viewed ? &solved : nullptr, nullptr, &eigen_rows);
            if (viewed) add_view_method(*view, m, mesh, coarse, fine, solved, rows);
          } catch (const std::exception& e) {  // e.g. a degenerate QEM face breaks the cotan assembly
            record_failure(r, e.what(), rows);
            if (viewed) add_failed_method(*view, m, e.what());
            continue;
          }
          progress << ' ' << m << ' ' << app::fixed(r.coarsen, 2) << " s (" << pct(rows[rows.size() - 3].error) << ' '
                   << pct(rows[rows.size() - 2].error) << ' ' << pct(rows.back().error) << ')';
        }
        std::cerr << progress.str() << "  [" << app::fixed(total_clock.seconds(), 0) << " s]\n";
      }
      if (view) views.push_back(std::move(*view));
    }

    if (used_meshes.empty()) throw app::AppError(app::kDefective, "no mesh could be used (see the warnings above)");

    // ---- outputs
    const double total_seconds = total_clock.seconds();
    write_csv(outdir + "/results.csv", rows);
    if (!tolerances.empty()) write_polish_csv(outdir + "/polish.csv", polished);
    if (eigen_pairs > 0) write_eigen_csv(outdir + "/eigen.csv", eigen_rows);
    nlohmann::json results = {{"tool", kTool},
                              {"command", command},
                              {"meshes", used_meshes},
                              {"skipped_meshes", skipped},
                              {"repair", repair},
                              {"budgets", budgets},
                              {"min_vertices", min_vertices},
                              {"equal_sizes", equal_sizes},
                              {"methods", methods},
                              {"area_weight", area_weight},
                              {"normalize_curvature", normalize_curvature},
                              {"operators", operators},
                              {"prolongation", ice::proxy::spelling(prolongation)},
                              {"qem_operators", fem::is_smoothed(qem_prolongation)
                                                    ? "galerkin, " + ice::proxy::spelling(qem_prolongation) + " prolongation"
                                                    : std::string("its own geometry's")},
                              {"heat_time", "0.1 x surface area, one backward Euler step"},
                              {"geodesic_sources", "vertex 0 and two farthest-point picks (R^3)"},
                              {"geodesic_coarse_distances", fem::to_string(geodesic.method)},
                              {"geodesic_lengths", traced_lengths ? "traced" : "intrinsic"},
                              {"curvature_correction", curvature_correction == ice::proxy::CurvatureCorrection::automatic ? "auto"
                                                       : curvature_correction == ice::proxy::CurvatureCorrection::on ? "on" : "off"},
                              {"curvature_divisor", geodesic.curvature_divisor},
                              {"fine_reference", "intrinsic Delaunay triangulation of the input"},
                              {"geodesic_reference", exact_geodesics ? "exact polyhedral geodesics (CGAL)" : "fine heat method"},
                              {"fine_heat_method_geodesic_errors", fine_heat_method_errors},
                              {"eigen_pairs", eigen_pairs},
                              {"eigen_reference", "shift-invert Lanczos (Spectra) on a CHOLMOD factorisation, fine L and lumped M"},
                              {"eigen", nlohmann::json::array()},
                              {"blas", fem::blas_library()},
                              {"total_seconds", total_seconds},
                              {"rows", nlohmann::json::array()}};
    for (const Row& r : rows) results["rows"].push_back(row_json(r));
    for (const EigenRow& e : eigen_rows) results["eigen"].push_back(eigen_json(e));
    {
      std::ofstream out(outdir + "/results.json");
      out << results.dump(1) << '\n';
      if (!out) throw app::AppError(app::kNotWritten, outdir + "/results.json: cannot be written");
    }
    write_summary(outdir + "/summary.md", rows, methods, budgets, used_meshes, command, total_seconds, operators,
                  area_weight, normalize_curvature, polished, skipped, fine_heat_method_errors, eigen_rows);
    write_plot_data(outdir, rows, methods, budgets);
    std::string plots = "no plots (--no-plots)";
    if (!no_plots) {
      if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
        app::warn(kTool, "gnuplot not found: no plots (scripts/setup.sh installs gnuplot-nox)");
        plots = "no plots (gnuplot missing)";
      } else if (!fs::exists(plot_script)) {
        app::warn(kTool, "plot script " + plot_script + " not found: no plots");
        plots = "no plots (script missing)";
      } else {
        std::string methods_words;
        for (const auto& m : methods) methods_words += (methods_words.empty() ? "" : " ") + m;
        const std::string cmd = "gnuplot -e \"dir='" + outdir + "'; methods='" + methods_words + "'\" '" + plot_script + "'";
        if (std::system(cmd.c_str()) != 0) throw app::AppError(app::kFailed, "gnuplot failed: " + cmd);
        plots = "errors.svg, errors_median.svg, phases.svg, speedup.svg";
      }
    }
    if (!no_html) {
      // The plots (SVG files beside the page) and the summary, above the 3D views.
      std::string plots_html = "<p>Coarse budget shown in 3D: " + num(100 * view_budget, 3) +
                               " %. Tables: <a href=\"summary.md\">summary.md</a>, <a href=\"results.csv\">results.csv</a>.</p>\n";
      if (plots.rfind("no plots", 0) != 0)
        for (const char* svg : {"errors.svg", "errors_median.svg", "phases.svg", "speedup.svg"})
          plots_html += std::string("<figure><img src=\"") + svg + "\" alt=\"" + svg + "\"><figcaption>" + svg +
                        "</figcaption></figure>\n";
      app::write_view_page(page, "ice-report: ICE and QEM on " + std::to_string(views.size()) + " meshes", views,
                           plots_html, force);
      plots += ", report.html";
    }
    std::cerr << kTool << ": " << rows.size() << " figures in " << app::fixed(total_seconds, 1) << " s\n";
    std::cout << kTool << ": wrote " << outdir << "/{results.csv, results.json, summary.md}, " << plots << '\n';
    return app::kOk;
  });
}
