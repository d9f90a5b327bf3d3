// heat-coarse: heat flow ∂u/∂t = Δu on a mesh by backward Euler, stepped on an ICE coarse proxy:
// the initial field restricted once, every step taken on the coarse system, only the states asked
// for (--output-every) prolonged to the input vertices; optionally compared, state by state, with
// the same steps on the fine mesh (CHOLMOD: M + τL factored once, one solve per step).
//
// Discretisation: (M + τL) u_{k+1} = M u_k with the cotan Laplacian L and the lumped mass M; the
// proxy's coarse system is (M_c + τL_c), u₀ reaches it by L² projection (fem::ProxyHeatSolver).
// --solver multigrid takes the exact route instead: every step on the fine mesh by Galerkin
// multigrid on an ICE hierarchy (from the store when it holds it), iterated from the last state.
//
// Exit codes: see app_common.h.
#include <algorithm>
#include <filesystem>
#include <iostream>

#include "tool_main.h"
#include "app_common.h"
#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "fem/geometry.h"
#include "fem/problems.h"
#include "ice/proxy/report.h"
#include "ice/scalar_field_io.h"

namespace heat_coarse_tool {

const std::string kTool = "heat-coarse";

// The errors of the written states against the fine ones (relative L2 in the mass norm, max abs):
// the worst, where, and each.
nlohmann::json state_errors(const Eigen::MatrixXd& states, const Eigen::MatrixXd& fine_states, const fem::SparseMatrix& M,
                            const std::vector<int>& output_steps) {
  double worst = 0, worst_max_abs = 0;
  int worst_step = output_steps.front();
  nlohmann::json per_output = nlohmann::json::array();
  for (Eigen::Index j = 0; j < states.cols(); ++j) {
    const Eigen::VectorXd state = states.col(j), fine_state = fine_states.col(j);
    const double rel = fem::relative_l2_error(state, fine_state, M);
    const double max_abs = fem::max_abs_error(state, fine_state);
    const int step = output_steps[static_cast<std::size_t>(j)];
    per_output.push_back({{"step", step}, {"rel_l2", rel}, {"max_abs", max_abs}});
    if (rel >= worst) {
      worst = rel;
      worst_step = step;
    }
    worst_max_abs = std::max(worst_max_abs, max_abs);
  }
  return {{"rel_l2", worst}, {"worst_step", worst_step}, {"max_abs", worst_max_abs}, {"outputs", per_output}};
}

struct HeatProblem {
  Eigen::VectorXd u0;
  std::string u0_name;
  double time_step = 0;
  int steps = 0, every = 0;
  nlohmann::json json() const {
    return {{"time_step", time_step}, {"steps", steps}, {"output_every", every}, {"initial_field", u0_name}};
  }
};

// --solver multigrid: the steps on the fine mesh by multigrid, compared with CHOLMOD's; writes the
// outputs and the report itself.
app::ExitCode step_on_fine_mesh(const app::MultigridCli& mg, const app::PdeOptions& opt, const ice::TriangleMesh& mesh,
                                const HeatProblem& heat, double load_seconds) {
  const long long n = mesh.V.rows();
  app::Stopwatch clock;
  const ice::FineMesh fine = ice::fine_mesh(mesh, opt.fine_geometry(), opt.nonmanifold);
  const double fine_mesh_seconds = clock.lap();
  const fem::SparseMatrix L = fem::cotan_laplacian(fine);
  const fem::SparseMatrix M = fem::mass_matrix(fine, fem::MassKind::lumped);
  const double assemble_seconds = clock.lap();
  const ice::proxy::Store store = opt.store();
  const ice::proxy::MultigridHierarchy hierarchy = app::stored_hierarchy(kTool, mesh, mg, opt, store);
  const double hierarchy_seconds = clock.lap();
  const fem::HeatSolver solver(L, M, heat.time_step, hierarchy.poisson_multigrid(mg.options));
  const double numeric_setup = clock.lap();
  std::vector<int> output_steps;
  std::vector<fem::MultigridReport> step_reports;
  const Eigen::MatrixXd states = solver.trajectory(heat.u0, heat.steps, heat.every, &output_steps, &step_reports);
  const double steps_seconds = clock.lap();
  const fem::MultigridSolver& multigrid = *solver.multigrid();
  int most = 0, unconverged = 0;
  double sum = 0, worst_residual = 0;
  for (const fem::MultigridReport& r : step_reports) {
    most = std::max(most, r.iterations);
    sum += r.iterations;
    unconverged += !r.converged;
    worst_residual = std::max(worst_residual, r.relative_residual);
  }
  if (unconverged > 0)
    app::warn(kTool, std::to_string(unconverged) + " of " + std::to_string(heat.steps) +
                         " steps stopped before the tolerance (worst relative residual " + std::to_string(worst_residual) + ")");
  const double setup_seconds = hierarchy_seconds + numeric_setup;
  nlohmann::json timings = {{"load", load_seconds}, {"fine_mesh", fine_mesh_seconds}, {"assemble", assemble_seconds},
                            {"hierarchy", hierarchy_seconds}, {"galerkin_and_coarse_factor", numeric_setup},
                            {"setup", setup_seconds}, {"steps", steps_seconds}, {"per_step", steps_seconds / heat.steps},
                            {"total", assemble_seconds + setup_seconds + steps_seconds},
                            {"cache_load", hierarchy.cache.load_seconds}, {"cache_save", hierarchy.cache.save_seconds}};
  nlohmann::json solver_json = {{"kind", "multigrid"}};
  solver_json.update(ice::proxy::multigrid_json(multigrid));
  // multigrid_json describes the last step; the steps' own figures:
  solver_json["iterations_per_step"] = {{"mean", sum / static_cast<double>(step_reports.size())}, {"max", most}};
  solver_json["steps_converged"] = unconverged == 0;
  solver_json["worst_relative_residual"] = worst_residual;
  solver_json["hierarchy"] = ice::proxy::hierarchy_json(hierarchy, mg.hierarchy);

  nlohmann::json error_json;
  Eigen::VectorXd reference;
  if (!opt.no_reference) {
    const fem::HeatSolver direct(L, M, heat.time_step, ice::proxy::kFineReferenceOrdering);
    timings["reference_setup"] = clock.lap();
    const Eigen::MatrixXd fine_states = direct.trajectory(heat.u0, heat.steps, heat.every);
    timings["reference_steps"] = clock.lap();
    error_json = state_errors(states, fine_states, M, output_steps);
    reference = fine_states.col(fine_states.cols() - 1);
  }
  if (!opt.solutions.empty()) ice::write_npy_matrix(opt.solutions, states, opt.force);
  const Eigen::VectorXd last = states.col(states.cols() - 1);
  app::write_result_fields(opt, mesh, "solution", last, reference, {{"u0", heat.u0}});
  nlohmann::json report = app::report_header(kTool, opt.mesh);
  report["solver"] = solver_json;
  report["input"] = {{"vertices", n}, {"faces", mesh.F.rows()}};
  report["fine_mesh"] = {{"kind", opt.fine_idt ? "intrinsic Delaunay" : "input"},
                         {"flips", fine.flips},
                         {"tufted_cover", ice::solved_on_tufted_cover(mesh, opt.nonmanifold)}};
  report["heat"] = heat.json();
  report["heat"]["output_steps"] = output_steps;
  report["timings_s"] = timings;
  report["cache"] = ice::proxy::cache_json(hierarchy.cache, store);
  if (!opt.no_reference) {
    report["error"] = error_json;
    report["reference_ordering"] = fem::to_string(ice::proxy::kFineReferenceOrdering);
  }
  report["peak_rss_mb"] = app::peak_rss_mb();
  if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

  std::cout << kTool << ": " << opt.mesh << ": " << app::thousands(n) << " vertices, --solver multigrid ("
            << hierarchy.num_levels() << " levels, hierarchy " << ice::proxy::spelling(hierarchy.cache.status) << ")\n";
  std::cout << "  setup " << app::fixed(setup_seconds, 4) << " s, " << heat.steps << " steps " << app::fixed(steps_seconds, 4)
            << " s (" << app::fixed(sum / static_cast<double>(step_reports.size()), 2) << " iterations a step, at most " << most
            << ")\n";
  if (!opt.no_reference)
    std::cout << "  vs CHOLMOD steps: relative L2 " << app::relative_error(error_json["rel_l2"]) << " at worst, max abs "
              << static_cast<double>(error_json["max_abs"]) << " (CHOLMOD setup " << app::fixed(timings["reference_setup"], 4)
              << " s, steps " << app::fixed(timings["reference_steps"], 4) << " s)\n";
  if (!opt.solutions.empty())
    std::cout << "  wrote " << opt.solutions << " (" << app::thousands(n) << " x " << states.cols() << ")\n";
  app::print_written(std::cout, opt, nullptr);
  return app::kOk;
}

}  // namespace heat_coarse_tool

int heat_coarse_tool::main(int argc, char** argv) {
  ice::keep_freed_memory_for_reuse();  // one job per process: reuse freed arrays instead of re-faulting them
  CLI::App cli{
      "heat-coarse: backward-Euler heat flow stepped on a small ICE coarse proxy (restricted once, prolonged only\n"
      "at the steps written out) and, by default, compared with the same steps on the fine mesh.\n"
      "Without --u0 or --source: a demo field (three Gaussian bumps).\n\n"
      "Examples:\n  heat-coarse spot.obj --ratio 0.05 --steps 100 --output-every 10 --solutions u.npy\n"
      "  heat-coarse bunny.off --ratio 0.02 --source 0 --time-step 1e-4 --steps 1000 -o last.ply\n\n"
      "Exit status: 0 ok, 1 unreadable input, 2 defective or disconnected mesh, 3 output not written, 4 bad command "
      "line,\n5 computation failed."};
  app::PdeOptions opt;
  std::string u0_path;
  std::vector<long long> sources;
  double time_step = 0;
  int steps = 100, every = 0;
  cli.add_option("--u0", u0_path, "Initial field: text file of one number per input vertex, or .npy (one column)");
  cli.add_option("--source", sources, "Initial field 1 at these vertices (0-based), 0 elsewhere")->delimiter(',');
  cli.add_option("--time-step", time_step, "Time step tau (default: the squared mean edge length)")->check(app::positive_number());
  cli.add_option("--steps", steps, "Backward-Euler steps")->check(app::integer_between(1, 100000000))->capture_default_str();
  cli.add_option("--output-every", every, "Prolong and compare every M-th step (default: the last step only)")
      ->check(app::integer_between(1, 100000000));
  cli.add_option("--solutions", opt.solutions, "Write the states as .npy (float64, n x outputs)");
  opt.add_to(cli, "'solution' (the last state), 'reference', 'error'");
  std::string solver = "proxy";
  cli.add_option("--solver", solver, "proxy (steps on the coarse level), or exact: multigrid (fine steps)")
      ->check(CLI::IsMember({"proxy", "multigrid"}))
      ->capture_default_str();
  app::MultigridCli mg;
  mg.add_to(cli);
  opt.add_cache_options(cli);
  opt.add_nonmanifold_option(cli);
  ice::proxy::Prolongation prolongation = ice::proxy::Prolongation::automatic;
  app::add_prolongation_option(cli, prolongation);
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&] {
    opt.has_coarse_space = solver == "proxy";  // --html draws the coarse mesh: not with --solver multigrid
    opt.check_outputs();
    if (!u0_path.empty() && !sources.empty()) throw app::AppError(app::kUsage, "give --u0 or --source, not both");
    if (every == 0) every = steps;
    opt.prolongation = app::resolve_prolongation(prolongation, opt.operators, "");
    app::PdeRun run = app::PdeRun::start(kTool, opt, /*proxy_uses_fine_mesh=*/true);

    // ---- load
    app::Stopwatch clock;
    const ice::LoadResult loaded = app::load_input_mesh(opt.mesh, opt.load_options());
    const ice::TriangleMesh& mesh = loaded.mesh;
    const long long n = mesh.V.rows();
    Eigen::VectorXd u0;
    std::string u0_name = "demo (three Gaussian bumps)";
    const app::FileVertexMap vertices(loaded);
    if (!u0_path.empty()) {
      std::vector<double> values;
      if (app::lower_extension(u0_path) == ".npy") {
        const Eigen::MatrixXd m = ice::read_npy_matrix(u0_path);
        if (m.cols() != 1) throw app::AppError(app::kUnreadable, u0_path + ": has " + std::to_string(m.cols()) + " columns, one expected");
        values.assign(m.data(), m.data() + m.size());
      } else {
        values = app::read_number_file(u0_path);
      }
      if (values.size() != loaded.input_report.n_vertices)
        throw app::AppError(app::kUnreadable, u0_path + ": has " + std::to_string(values.size()) + " values, the mesh has " +
                                                  std::to_string(loaded.input_report.n_vertices) + " vertices");
      u0.resize(n);
      for (Eigen::Index i = 0; i < n; ++i) u0(i) = values[static_cast<std::size_t>(loaded.source_vertex[i])];
      u0_name = u0_path;
    } else if (!sources.empty()) {
      u0 = Eigen::VectorXd::Zero(n);
      for (long long s : sources) u0(vertices.mesh_vertex(s, "--source: vertex")) = 1;
      u0_name = std::to_string(sources.size()) + " source vertices";
    } else {
      u0 = app::demo_poisson_rhs(mesh);
    }
    if (time_step == 0) {
      const double h = fem::mean_edge_length(ice::face_lengths_from_positions(mesh.V, mesh.F));
      time_step = h * h;
    }
    if (solver == "multigrid")
      return step_on_fine_mesh(mg, opt, mesh, HeatProblem{u0, u0_name, time_step, steps, every}, clock.lap());
    ice::CoarsenOptions coarsen_options;
    opt.target.apply(coarsen_options, n);
    run.fine_vertices = n;
    run.fine_faces = mesh.F.rows();
    run.load = clock.lap();

    // ---- the proxy (from the store when it holds this setup), its factorisation, the steps
    const ice::proxy::ProxySetup pde = app::build_pde_proxy(mesh, coarsen_options, opt, run, clock, true, run.has_reference, false,
                                                   opt.store());
    const fem::CoarseProxy& proxy = *pde.proxy;
    run.assemble = clock.lap();
    const fem::ProxyHeatSolver heat(proxy, time_step, fem::RestrictionKind::l2_projection);
    run.factor = clock.lap();
    fem::ProxyPhaseTimes phases;
    std::vector<int> output_steps;
    const Eigen::MatrixXd states = heat.trajectory(u0, steps, every, &output_steps, &phases);
    run.solves = steps;
    run.unit = "step";
    run.solve = phases.restriction + phases.coarse_solve;
    run.prolong = phases.prolongation;
    clock.lap();

    // ---- reference: the same steps on the fine mesh, compared at every output step
    nlohmann::json error_json;
    Eigen::VectorXd reference;
    if (run.has_reference) {
      const ice::FineMesh& fine = pde.fine;
      const fem::SparseMatrix L = fem::cotan_laplacian(fine);
      const fem::SparseMatrix M = fem::mass_matrix(fine, fem::MassKind::lumped);
      run.ref_assemble = clock.lap();
      const fem::HeatSolver fine_heat(L, M, time_step, ice::proxy::kFineReferenceOrdering);
      run.ref_factor = clock.lap();
      const Eigen::MatrixXd fine_states = fine_heat.trajectory(u0, steps, every);
      run.ref_solve = clock.lap();
      error_json = state_errors(states, fine_states, M, output_steps);
      reference = fine_states.col(fine_states.cols() - 1);
      clock.lap();
    }
    if (!opt.solutions.empty()) ice::write_npy_matrix(opt.solutions, states, opt.force);
    const Eigen::VectorXd last = states.col(states.cols() - 1);
    const std::optional<ice::CoarseTracing> tracing = app::trace_for_outputs(opt, mesh, pde.coarse);
    const ice::CoarseTracing* traced = tracing ? &*tracing : nullptr;
    app::write_result_fields(opt, mesh, "solution", last, reference, {{"u0", u0}}, traced);
    app::write_result_page(opt, mesh, "heat-coarse: " + std::filesystem::path(opt.mesh).filename().string(), "heat",
                           "solution", last, reference, pde.coarse, traced, error_json, loaded.point_cloud);
    run.write = clock.lap();

    nlohmann::json report = run.report();
    report["heat"] = HeatProblem{u0, u0_name, time_step, steps, every}.json();
    report["heat"]["output_steps"] = output_steps;
    report["heat"]["restriction"] = "l2_projection";
    report["timings_s"]["per_step"] = run.per_solve();
    if (run.has_reference) {
      report["error"] = error_json;
      report["reference_ordering"] = fem::to_string(ice::proxy::kFineReferenceOrdering);
    }
    if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

    run.print_summary(std::cout);
    std::cout << "  problem: " << steps << " backward-Euler steps of " << time_step << " from " << u0_name << ", "
              << output_steps.size() << " states prolonged\n";
    if (run.has_reference)
      std::cout << "  error vs fine steps: relative L2 " << app::relative_error(error_json["rel_l2"]) << " at worst (step "
                << error_json["worst_step"].get<int>() << "), max abs " << static_cast<double>(error_json["max_abs"]) << '\n';
    if (!opt.solutions.empty())
      std::cout << "  wrote " << opt.solutions << " (" << app::thousands(n) << " x " << states.cols() << ")\n";
    app::print_written(std::cout, opt, traced);
    return app::kOk;
  });
}
