// poisson-coarse: the Poisson equation −Δu = f on a mesh, solved on an ICE coarse proxy and prolonged
// to the input vertices; optionally compared with the same solve on the fine mesh.
//
// Discretisation (fem::PoissonSolver): L u = M f with the cotan Laplacian L and the lumped mass M.
//  - Boundary conditions: with --fix V=value, Dirichlet values at those vertices (they are locked
//    during coarsening, so they are coarse vertices too and the prolonged solution takes the values
//    exactly); the rest of the boundary, if any, is natural (zero Neumann). Without --fix: zero-mean
//    Neumann — f is made compatible by removing its area-weighted mean, and u is the solution with
//    zero area-weighted mean. This is the natural choice on closed surfaces and, on surfaces with a
//    boundary, means zero normal derivative on the whole boundary.
//  - Right-hand side: --rhs FILE (one value per vertex of the input file), or the demo source: three
//    Gaussian bumps exp(−|x − c|²/(2σ²)) with weights +1, −1, +1 centred at the vertices with the
//    largest x, y and z coordinate, σ = 0.1 × the bounding-box diagonal, minus the area-weighted mean.
//  - Proxy: ice::build_coarse_space, then fem::ProxyPoissonSolver: b_c = Pᵀ M f (restriction of the
//    integrated source), L_c u_c = b_c on the coarse mesh (intrinsic or Galerkin L_c, M_c), u = P u_c
//    (re-centred to zero fine mean in zero-mean mode); the solver times each stage.
//
// Exit codes: see app_common.h.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>

#include "tool_main.h"
#include "app_common.h"
#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "fem/multigrid.h"
#include "fem/problems.h"
#include "ice/hierarchy.h"
#include "ice/large_array.h"
#include "ice/scalar_field_io.h"

namespace poisson_coarse_tool {

/// The report's "error" object: relative L2 error in the mass norm, max abs error, and max abs error
/// relative to max |reference|. A zero reference leaves the relative errors undefined (null): that is
/// a constant --rhs in zero-mean mode, which is zero once its mean is removed, and so is u.
nlohmann::json solution_error_json(const Eigen::VectorXd& solution, const Eigen::VectorXd& reference,
                                   const fem::SparseMatrix& M) {
  const double max_abs = fem::max_abs_error(solution, reference);
  const double scale = reference.cwiseAbs().maxCoeff();
  const bool zero_reference = !(reference.dot(M * reference) > 0);
  return {{"rel_l2", zero_reference ? nlohmann::json() : nlohmann::json(fem::relative_l2_error(solution, reference, M))},
          {"max_abs", max_abs},
          {"max_rel", scale > 0 ? nlohmann::json(max_abs / scale) : nlohmann::json()},
          {"max_abs_reference", scale}};
}

/// The "error" object of several sources: that of the column of largest relative L2 error (its
/// index in "worst_column"), and the number of columns.
nlohmann::json block_error_json(const Eigen::MatrixXd& solutions, const Eigen::MatrixXd& references, const fem::SparseMatrix& M) {
  nlohmann::json worst;
  double worst_error = -1;
  for (Eigen::Index j = 0; j < solutions.cols(); ++j) {
    nlohmann::json e = solution_error_json(solutions.col(j), references.col(j), M);
    const double error = e["rel_l2"].is_number() ? e["rel_l2"].get<double>() : 0.0;
    if (error > worst_error) {
      worst_error = error;
      worst = e;
      worst["worst_column"] = j;
    }
  }
  worst["columns"] = solutions.cols();
  return worst;
}

const std::string kTool = "poisson-coarse";

const std::map<std::string, fem::CholeskyOrdering> kOrderingNames{
    {"automatic", fem::CholeskyOrdering::automatic},
    {"amd", fem::CholeskyOrdering::amd},
    {"metis", fem::CholeskyOrdering::metis},
    {"nested_dissection", fem::CholeskyOrdering::nested_dissection}};

// The fine Poisson solver: Dirichlet at the fixed vertices, or zero-mean without any.
fem::PoissonSolver fine_poisson_solver(const fem::SparseMatrix& L, const fem::SparseMatrix& M,
                                       const std::vector<int>& fixed_vertices,
                                       std::optional<fem::PoissonMultigrid> multigrid, fem::CholeskyOrdering ordering) {
  return fixed_vertices.empty() ? fem::PoissonSolver::zero_mean(L, M, std::move(multigrid), ordering)
                                : fem::PoissonSolver::dirichlet(L, M, fixed_vertices, std::move(multigrid), ordering);
}

// --solver multigrid|direct: the fine problem solved exactly (to --mg-tolerance for multigrid) on
// the fine mesh by fem::PoissonSolver (CHOLMOD, or multigrid on an ICE hierarchy); writes the
// outputs and the report itself.
app::ExitCode solve_on_fine_mesh(const std::string& solver, const app::MultigridCli& mg, const app::PdeOptions& opt,
                       const ice::TriangleMesh& mesh, Eigen::VectorXd f, std::string rhs_name,
                       const std::vector<int>& fixed_vertices, const Eigen::VectorXd& fixed_values, double load_seconds,
                       fem::CholeskyOrdering ordering, const Eigen::MatrixXd& block) {
  const long long n = mesh.V.rows();
  const bool dirichlet = !fixed_vertices.empty();
  app::Stopwatch clock;
  const ice::FineMesh fine = ice::fine_mesh(mesh, opt.fine_geometry(), opt.nonmanifold);
  const double fine_mesh_seconds = clock.lap();
  const fem::SparseMatrix L = fem::cotan_laplacian(fine);
  const fem::SparseMatrix M = fem::mass_matrix(fine, fem::MassKind::lumped);
  if (f.size() == 0) f = app::remove_mean(app::demo_poisson_rhs(mesh), M);
  const double assemble_seconds = clock.lap();
  nlohmann::json solver_json = {{"kind", solver}};
  nlohmann::json timings;
  nlohmann::json cache = {{"status", "off"}};  // the multigrid hierarchy's store
  Eigen::VectorXd u;
  // Several sources (--rhs FILE.npy): one block solve (CHOLMOD: one call; multigrid: block V-cycles),
  // the Dirichlet values of --fix for each.
  const Eigen::Index sources = std::max<Eigen::Index>(1, block.cols());
  const Eigen::MatrixXd weighted_block = block.cols() > 1 ? (M * block).eval() : Eigen::MatrixXd();
  const Eigen::MatrixXd fixed_block =
      block.cols() > 1 && dirichlet ? fixed_values.replicate(1, block.cols()).eval() : Eigen::MatrixXd();
  Eigen::MatrixXd U;
  clock.lap();  // weighting the sources is the problem's, neither route's setup
  const auto solve_all = [&](const fem::PoissonSolver& poisson) {
    if (block.cols() > 1)
      U = poisson.solve_multiple_weighted(weighted_block, fixed_block);
    else
      u = poisson.solve(f, fixed_values);
  };
  double setup_seconds = 0, solve_seconds = 0;
  const auto make_solver = [&](std::optional<fem::PoissonMultigrid> multigrid) {
    return fine_poisson_solver(L, M, fixed_vertices, std::move(multigrid), ordering);
  };
  if (solver == "direct") {
    const fem::PoissonSolver direct = make_solver(std::nullopt);
    setup_seconds = clock.lap();
    solve_all(direct);
    solve_seconds = clock.lap();
    solver_json["method"] = "CHOLMOD supernodal Cholesky (analyse + factor in setup)";
    solver_json["ordering"] = fem::to_string(ordering);
    timings = {{"setup", setup_seconds}, {"solve", solve_seconds}};
  } else {
    const ice::proxy::Store store = opt.store();
    const ice::proxy::MultigridHierarchy hierarchy = app::stored_hierarchy(kTool, mesh, mg, opt, store);
    const double hierarchy_seconds = clock.lap();
    const fem::PoissonSolver poisson = make_solver(hierarchy.poisson_multigrid(mg.options));
    const double numeric_setup = clock.lap();
    setup_seconds = hierarchy_seconds + numeric_setup;
    solve_all(poisson);
    solve_seconds = clock.lap();
    const fem::MultigridSolver& multigrid = *poisson.multigrid();
    const fem::MultigridReport& r = multigrid.report();
    if (!r.converged)
      app::warn(kTool, "multigrid stopped after " + std::to_string(r.iterations) + " iterations at relative residual " +
                           std::to_string(r.relative_residual) + " (tolerance " + std::to_string(mg.options.tolerance) + ")");
    solver_json.update(ice::proxy::multigrid_json(multigrid));
    solver_json["hierarchy"] = ice::proxy::hierarchy_json(hierarchy, mg.hierarchy);
    cache = ice::proxy::cache_json(hierarchy.cache, store);
    timings = {{"setup", setup_seconds}, {"hierarchy", hierarchy_seconds}, {"galerkin_and_coarse_factor", numeric_setup},
               {"solve", solve_seconds}, {"cache_load", hierarchy.cache.load_seconds},
               {"cache_save", hierarchy.cache.save_seconds}};
  }
  timings["load"] = load_seconds;
  timings["fine_mesh"] = fine_mesh_seconds;
  timings["assemble"] = assemble_seconds;
  timings["total"] = assemble_seconds + setup_seconds + solve_seconds;

  nlohmann::json error_json;
  Eigen::VectorXd reference;
  const bool has_reference = !opt.no_reference && solver != "direct";
  if (has_reference) {
    const fem::PoissonSolver direct = make_solver(std::nullopt);
    timings["reference_setup"] = clock.lap();
    if (block.cols() > 1) {
      const Eigen::MatrixXd references = direct.solve_multiple_weighted(weighted_block, fixed_block);
      timings["reference_solve"] = clock.lap();
      error_json = block_error_json(U, references, M);
    } else {
      reference = direct.solve(f, fixed_values);
      timings["reference_solve"] = clock.lap();
      error_json = solution_error_json(u, reference, M);
    }
  }
  if (!opt.solutions.empty()) ice::write_npy_matrix(opt.solutions, block.cols() > 1 ? U : Eigen::MatrixXd(u), opt.force);
  app::write_result_fields(opt, mesh, "solution", u, reference, {{"rhs", f}});
  nlohmann::json report = app::report_header(kTool, opt.mesh);
  report["solver"] = solver_json;
  report["input"] = {{"vertices", n}, {"faces", mesh.F.rows()}};
  report["fine_mesh"] = {{"kind", opt.fine_idt ? "intrinsic Delaunay" : "input"},
                         {"flips", fine.flips},
                         {"tufted_cover", ice::solved_on_tufted_cover(mesh, opt.nonmanifold)}};
  report["timings_s"] = timings;
  report["cache"] = cache;
  report["rhs"] = rhs_name;
  report["sources"] = sources;
  report["boundary_conditions"] = dirichlet ? "dirichlet" : "zero-mean neumann";
  report["fixed_vertices"] = fixed_vertices.size();
  if (has_reference) report["error"] = error_json;
  report["peak_rss_mb"] = app::peak_rss_mb();
  if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

  std::cout << kTool << ": " << opt.mesh << ": " << app::thousands(n) << " vertices, --solver " << solver << '\n';
  std::cout << "  setup " << app::fixed(setup_seconds, 4) << " s, solve " << app::fixed(solve_seconds, 4) << " s";
  if (solver == "multigrid")
    std::cout << ", " << solver_json["iterations"] << " iterations, convergence factor "
              << app::fixed(solver_json["convergence_factor"], 3) << ", relative residual "
              << static_cast<double>(solver_json["relative_residual"]);
  std::cout << '\n';
  if (has_reference)
    std::cout << "  vs CHOLMOD: relative L2 " << app::relative_error(error_json["rel_l2"]) << ", max abs "
              << static_cast<double>(error_json["max_abs"]) << " (CHOLMOD setup "
              << app::fixed(timings["reference_setup"], 4) << " s, solve " << app::fixed(timings["reference_solve"], 4)
              << " s)\n";
  app::print_written(std::cout, opt, nullptr);
  return app::kOk;
}

}  // namespace poisson_coarse_tool

int poisson_coarse_tool::main(int argc, char** argv) {
  ice::keep_freed_memory_for_reuse();  // one job per process: reuse freed arrays instead of re-faulting them
  CLI::App cli{
      "poisson-coarse: solve -Laplace(u) = f through a small ICE coarse proxy and (by default) compare with the fine\n"
      "solve. Without --rhs: a demo source; without --fix: zero-mean Neumann.\n\n"
      "Examples:\n  poisson-coarse spot.obj --ratio 0.05\n"
      "  poisson-coarse lion-head.off --vertices 800 --fix 0=1 --fix 4000=0 -o u.ply\n\n"
      "Exit status: 0 ok, 1 unreadable input, 2 defective or disconnected mesh, 3 output not written, 4 bad command "
      "line,\n5 computation failed."};
  app::PdeOptions opt;
  std::string rhs_path, solver = "proxy";
  std::vector<std::string> fixes;
  cli.add_option("--rhs", rhs_path,
                 "Source f: one value per vertex (text), or .npy (n x k: k sources)");
  cli.add_option("--solutions", opt.solutions, "Write the solutions as .npy (float64, n x k: one column per source)");
  cli.add_option("--fix", fixes,
                 "Dirichlet condition V=value at vertex V (0-based); repeat or comma-separate")
      ->delimiter(',')
      ->allow_extra_args(false);
  app::MultigridCli mg;
  cli.add_option("--solver", solver,
                 "proxy (coarse solve), or exact: multigrid or direct (CHOLMOD)")
      ->check(CLI::IsMember({"proxy", "multigrid", "direct"}))
      ->capture_default_str();
  mg.add_to(cli);
  fem::CholeskyOrdering cholmod_ordering = ice::proxy::kFineReferenceOrdering;
  app::add_choice(cli, "--cholmod-ordering", cholmod_ordering, kOrderingNames,
                  "CHOLMOD ordering of exact fine solves");
  opt.add_to(cli, "'solution', 'reference', 'error'");
  opt.add_polish_options(cli);
  opt.add_cache_options(cli);
  opt.add_nonmanifold_option(cli);
  ice::proxy::Prolongation prolongation = ice::proxy::Prolongation::automatic;
  app::add_prolongation_option(cli, prolongation);
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&] {
    opt.has_coarse_space = solver == "proxy";
    opt.check_outputs();
    const bool rhs_npy = !rhs_path.empty() && app::lower_extension(rhs_path) == ".npy";
    if (solver != "proxy" && opt.polish.enabled())
      throw app::AppError(app::kUsage, "--polish and --tolerance polish the proxy's solution: use them with --solver proxy");
    if (opt.polish.tolerance > 0 && opt.target.method == ice::CoarseningMethod::qem)
      app::warn(kTool, "--tolerance with --method qem: the error estimate is validated on ICE coarse spaces; on QEM's "
                       "it can underestimate (measured up to 60x on 2 of 40 meshes)");
    // A smoothed P does not take the fixed values at the fixed vertices.
    opt.prolongation = app::resolve_prolongation(prolongation, opt.operators, fixes.empty() ? "" : "--fix");
    // "V=value" pairs, checked for syntax before loading anything.
    std::vector<std::pair<long long, double>> file_fixes;
    for (const std::string& fix : fixes) {
      const auto eq = fix.find('=');
      std::size_t used_v = 0, used_x = 0;
      long long v = -1;
      double x = 0;
      try {
        if (eq == std::string::npos) throw std::invalid_argument("no '='");
        v = std::stoll(fix.substr(0, eq), &used_v);
        x = std::stod(fix.substr(eq + 1), &used_x);
      } catch (const std::exception&) {
        used_v = used_x = std::string::npos;
      }
      if (eq == std::string::npos || used_v != eq || used_x != fix.size() - eq - 1 || !std::isfinite(x))
        throw app::AppError(app::kUsage, "--fix '" + fix + "': expected VERTEX=VALUE, e.g. --fix 12=0.5");
      file_fixes.emplace_back(v, x);
    }

    app::PdeRun run = app::PdeRun::start(kTool, opt, /*proxy_uses_fine_mesh=*/true);  // for M f (and Galerkin)

    // ---- load
    app::Stopwatch clock;
    const ice::LoadResult loaded = app::load_input_mesh(opt.mesh, opt.load_options());
    const ice::TriangleMesh& mesh = loaded.mesh;
    const long long n = mesh.V.rows();
    std::vector<int> fixed_vertices;
    Eigen::VectorXd fixed_values(static_cast<Eigen::Index>(file_fixes.size()));
    std::map<int, double> seen;
    const app::FileVertexMap vertices(loaded);
    for (const auto& [file_vertex, value] : file_fixes) {
      const int v = vertices.mesh_vertex(file_vertex, "--fix: vertex");
      if (!seen.emplace(v, value).second)
        throw app::AppError(app::kUsage, "--fix: vertex " + std::to_string(file_vertex) + " is fixed twice");
      fixed_values(static_cast<Eigen::Index>(fixed_vertices.size())) = value;
      fixed_vertices.push_back(v);
    }
    ice::CoarsenOptions coarsen_options;
    if (solver == "proxy") opt.target.apply(coarsen_options, n);  // multigrid/direct need no coarse target
    if (coarsen_options.target_vertices > 0 && coarsen_options.target_vertices < static_cast<ice::Index>(fixed_vertices.size()))
      throw app::AppError(app::kUsage, "--vertices is smaller than the number of --fix vertices (they all stay)");
    coarsen_options.locked_vertices.assign(fixed_vertices.begin(), fixed_vertices.end());
    app::require_fixed_in_every_component(loaded, fixed_vertices, opt.mesh);
    Eigen::VectorXd f;
    std::string rhs_name = "demo (three Gaussian bumps, zero mean)";
    Eigen::MatrixXd block;  // --rhs FILE.npy with several columns: one source per column
    if (rhs_npy) {
      const Eigen::MatrixXd values = ice::read_npy_matrix(rhs_path);
      const auto expected = static_cast<Eigen::Index>(loaded.input_report.n_vertices);
      if (values.rows() != expected || values.cols() < 1)
        throw app::AppError(app::kUnreadable, rhs_path + ": has " + std::to_string(values.rows()) + " rows and " +
                                                  std::to_string(values.cols()) + " columns, the mesh has " +
                                                  std::to_string(expected) + " vertices (one row per vertex of the input file expected)");
      block.resize(n, values.cols());
      for (Eigen::Index i = 0; i < n; ++i) block.row(i) = values.row(loaded.source_vertex[i]);
      if (block.cols() == 1) {  // one source: the single solve
        f = block.col(0);
        block.resize(0, 0);
      }
      rhs_name = rhs_path;
      if (block.cols() > 1) {
        rhs_name += " (" + std::to_string(values.cols()) + " columns)";
        if (!opt.output.empty() || !opt.html.empty())
          throw app::AppError(app::kUsage, "--output and --html draw one solution: with several sources write them with --solutions");
        if (opt.polish.enabled())
          throw app::AppError(app::kUsage, "--polish and --tolerance polish one solution at a time: give one source per run");
      }
    } else if (!rhs_path.empty()) {
      const std::vector<double> values = app::read_number_file(rhs_path);
      const std::size_t expected = loaded.input_report.n_vertices;
      if (values.size() != expected)
        throw app::AppError(app::kUnreadable, rhs_path + ": has " + std::to_string(values.size()) +
                                                  " values, the mesh has " + std::to_string(expected) +
                                                  " vertices (one value per vertex of the input file expected)");
      f.resize(n);
      for (Eigen::Index i = 0; i < n; ++i) f(i) = values[static_cast<std::size_t>(loaded.source_vertex[i])];
      rhs_name = rhs_path;
    }
    run.fine_vertices = n;
    run.fine_faces = mesh.F.rows();
    run.load = clock.lap();
    if (solver != "proxy")
      return solve_on_fine_mesh(solver, mg, opt, mesh, f, rhs_name, fixed_vertices, fixed_values, run.load,
                                cholmod_ordering, block);

    // ---- coarsen, fine discretisation, then the proxy (fem::ProxyPoissonSolver: restrict, coarse
    // solve, prolong, each timed)
    const ice::proxy::ProxySetup pde = app::build_pde_proxy(mesh, coarsen_options, opt, run, clock, true, run.has_reference, false,
                                                   opt.store());
    const ice::FineMesh& fine = pde.fine;
    const fem::CoarseProxy& proxy = *pde.proxy;
    const bool dirichlet = !fixed_vertices.empty();
    if (f.size() == 0) {  // the demo source has zero mean in both modes (zero-mean: the solver removes it)
      f = app::demo_poisson_rhs(mesh);
      if (dirichlet) f = app::remove_mean(f, proxy.fine_mass());
    }
    run.assemble = clock.lap();
    const fem::ProxyPoissonSolver proxy_solver(proxy, fixed_vertices, opt.polish);
    run.polish_options = opt.polish;
    run.polish_setup = proxy_solver.polish_setup_seconds();
    run.factor = clock.lap() - run.polish_setup;
    fem::ProxyPhaseTimes phases;
    Eigen::VectorXd solution;
    Eigen::MatrixXd solutions;  // several sources: one column each
    // The Dirichlet values of --fix hold for every source.
    const Eigen::MatrixXd fixed_block = block.cols() > 1 && dirichlet ? fixed_values.replicate(1, block.cols()).eval() : Eigen::MatrixXd();
    if (block.cols() > 1) {
      solutions = proxy_solver.solve_block(block, fixed_block, &phases);
      run.solves = block.cols();
    } else {
      solution = proxy_solver.solve(f, fixed_values, &phases, &run.polish_report);
    }
    run.solve = phases.restriction + phases.coarse_solve;
    run.prolong = phases.prolongation;
    run.polish = run.polish_report.seconds;
    // Zero-mean Neumann solves -Laplace(u) = f - mean(f) (the solver made f compatible the same
    // way): the reference, the error and the written rhs use that f.
    if (!dirichlet) {
      if (block.cols() > 1)
        for (Eigen::Index j = 0; j < block.cols(); ++j) block.col(j) = app::remove_mean(block.col(j), proxy.fine_mass());
      else
        f = app::remove_mean(f, proxy.fine_mass());
    }
    clock.lap();

    // ---- reference (several sources: CHOLMOD's block solve, one call for all columns)
    nlohmann::json error_json;
    Eigen::VectorXd reference;
    if (run.has_reference) {
      const fem::SparseMatrix L = fem::cotan_laplacian(fine);
      const fem::SparseMatrix M = fem::mass_matrix(fine, fem::MassKind::lumped);
      run.ref_assemble = clock.lap();
      const fem::PoissonSolver fine_solver = fine_poisson_solver(L, M, fixed_vertices, std::nullopt, cholmod_ordering);
      run.ref_factor = clock.lap();
      if (block.cols() > 1) {
        const Eigen::MatrixXd references = fine_solver.solve_multiple_weighted(M * block, fixed_block);
        run.ref_solve = clock.lap();
        error_json = block_error_json(solutions, references, M);
      } else {
        reference = fine_solver.solve(f, fixed_values);
        run.ref_solve = clock.lap();
        error_json = solution_error_json(solution, reference, M);
      }
      clock.lap();
    }
    if (!opt.solutions.empty())
      ice::write_npy_matrix(opt.solutions, block.cols() > 1 ? solutions : Eigen::MatrixXd(solution), opt.force);

    // ---- outputs
    const std::optional<ice::CoarseTracing> tracing = app::trace_for_outputs(opt, mesh, pde.coarse);
    const ice::CoarseTracing* traced = tracing ? &*tracing : nullptr;
    app::write_result_fields(opt, mesh, "solution", solution, reference, {{"rhs", f}}, traced);
    app::write_result_page(opt, mesh, "poisson-coarse: " + std::filesystem::path(opt.mesh).filename().string(), "poisson", "solution",
                           solution, reference, pde.coarse, traced, error_json, loaded.point_cloud);
    run.write = clock.lap();
    nlohmann::json report = run.report();
    if (traced) report["trace"] = {{"edges", traced->edges.size()}, {"traced", traced->traced}};
    report["solver"] = {{"kind", solver}};
    if (run.has_reference) report["reference_ordering"] = fem::to_string(cholmod_ordering);
    report["timings_s"]["setup"] = run.coarsen + run.assemble + run.factor + run.polish_setup;
    report["timings_s"]["solve"] = run.per_solve();
    report["rhs"] = rhs_name;
    report["sources"] = run.solves;
    report["boundary_conditions"] = dirichlet ? "dirichlet" : "zero-mean neumann";
    report["fixed_vertices"] = fixed_vertices.size();
    if (run.has_reference) report["error"] = error_json;
    if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

    run.print_summary(std::cout);
    std::cout << "  problem: -Laplace(u) = f, f = " << rhs_name << ", "
              << (dirichlet ? std::to_string(fixed_vertices.size()) + " Dirichlet vertices" : std::string("zero-mean Neumann"))
              << '\n';
    if (run.has_reference)
      std::cout << "  error vs fine" << (run.solves > 1 ? " (worst of " + std::to_string(run.solves) + " sources)" : std::string())
                << ": relative L2 " << app::relative_error(error_json["rel_l2"]) << ", max abs "
                << static_cast<double>(error_json["max_abs"]) << " (" << app::percent(error_json["max_rel"])
                << " of max |u| " << static_cast<double>(error_json["max_abs_reference"]) << ")\n";
    if (!opt.solutions.empty()) std::cout << "  wrote " << opt.solutions << " (" << app::thousands(n) << " x " << run.solves << ")\n";
    if (run.has_reference && error_json["rel_l2"].is_null())
      std::cout << "  note: the fine solution is zero (a constant f is zero once its mean is removed), so relative "
                   "errors are undefined\n";
    app::print_written(std::cout, opt, traced);
    return app::kOk;
  });
}
