// geodesic-coarse: geodesic distance on a mesh by the heat method, solved on an ICE coarse proxy and
// prolonged to the input vertices; optionally compared with the same solve on the fine mesh.
//
// Pipeline (every phase timed apart): load → coarsen (ice::build_coarse_space: ICE from the input's
// intrinsic triangulation, or QEM; includes the coarse mesh and the prolongation P) → fine mesh
// (ice::fine_mesh: the reference's discretisation, intrinsic Delaunay by default) → assemble
// (fem::CoarseProxy and the coarse heat-method operators) → factor (fem::ProxyGeodesicSolver) → solve
// (heat method on the coarse mesh from the restricted sources Pᵀ e_s) → prolong (P φ_c, shifted to
// vanish on average at the sources), the last two timed by the solver. The heat step uses the lumped
// (row-sum) coarse mass, which matters for Galerkin operators: see
// fem::CoarseProxy::coarse_heat_method_operators. Then the reference: fem::HeatGeodesicSolver on the
// fine mesh (assemble, factor, solve) and the errors of the prolonged distance against it.
//
// Exit codes: see app_common.h (0 ok, 1 unreadable, 2 defective/unsuitable mesh, 3 output not written,
// 4 bad command line, 5 computation failed).
#include <iostream>

#include "app_common.h"
#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "fem/problems.h"
#include "ice/scalar_field_io.h"

namespace {

const std::string kTool = "geodesic-coarse";

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{
      "geodesic-coarse: geodesic distance from source vertices by the heat method, solved on a small ICE "
      "coarse proxy of the mesh and carried back to every input vertex; by default also solved on the "
      "fine mesh to report the error and the speed-up.\n\n"
      "Examples:\n  geodesic-coarse spot.obj --source 0 --ratio 0.05\n"
      "  geodesic-coarse bunny.off --source 10,250 --vertices 1000 --operators galerkin -o dist.ply --report r.json\n\n"
      "Exit status: 0 ok, 1 unreadable input, 2 defective or disconnected mesh, 3 output not written, "
      "4 bad command line (e.g. source out of range), 5 computation failed."};
  app::PdeOptions opt;
  std::string sources_text;
  cli.add_option("--source,-s", sources_text,
                 "Source vertex or vertices, 0-based indices in the input file, comma separated (e.g. 0,1500); "
                 "the distance is to the nearest of them")
      ->required();
  opt.target.use_defaults_for(ice::ProxyUse::geodesic);  // the metric measured best for geodesics
  opt.add_to(cli, "'distance' (prolonged), 'reference' and 'error' (= distance - reference)");
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&] {
    opt.check_outputs();
    const std::vector<long long> file_sources = app::parse_index_list(sources_text, "--source");
    app::PdeRun run = app::PdeRun::start(kTool, opt, opt.operators == fem::CoarseOperatorKind::galerkin);

    // ---- load
    app::Stopwatch clock;
    const ice::LoadResult loaded = app::load_input_mesh(opt.mesh, opt.repair);
    const ice::TriangleMesh& mesh = loaded.mesh;
    const long long n = mesh.V.rows();
    std::vector<int> sources;
    for (long long s : file_sources) sources.push_back(app::mesh_vertex_of_file_vertex(loaded, s, "--source: vertex"));
    ice::CoarsenOptions coarsen_options;
    opt.target.apply(coarsen_options, n);
    app::require_connected(loaded, opt.mesh, kTool);
    run.fine_vertices = n;
    run.fine_faces = mesh.F.rows();
    run.load = clock.lap();

    // ---- coarsen, fine discretisation, then the proxy (fem::ProxyGeodesicSolver): assemble, factor,
    // restrict + solve and prolong, the last two timed by the solver
    const app::PdeProxy pde = app::build_pde_proxy(mesh, coarsen_options, opt, run, clock);
    const ice::FineMesh& fine = pde.fine;
    const fem::CoarseProxy& proxy = *pde.proxy;
    fem::HeatMethodOperators coarse_ops = proxy.coarse_heat_method_operators();  // lumped mass for Galerkin
    run.assemble = clock.lap();
    const fem::ProxyGeodesicSolver proxy_solver(proxy, std::move(coarse_ops));
    run.factor = clock.lap();
    fem::ProxyPhaseTimes phases;
    const Eigen::VectorXd distance = proxy_solver.distance(sources, &phases);
    run.solve = phases.restriction + phases.coarse_solve;
    run.prolong = phases.prolongation;
    clock.lap();

    // ---- reference
    nlohmann::json error_json;
    Eigen::VectorXd reference;
    if (run.has_reference) {
      fem::HeatMethodOperators fine_ops = fem::heat_method_operators(fine.F, fine.L, fem::MassKind::lumped, 1.0, n);
      run.ref_assemble = clock.lap();
      const fem::HeatGeodesicSolver fine_solver(std::move(fine_ops));
      run.ref_factor = clock.lap();
      reference = fine_solver.distance(sources);
      run.ref_solve = clock.lap();
      const fem::DistanceErrors d = fem::distance_errors(distance, reference);
      error_json = {{"rel_l2", fem::relative_l2_error(distance, reference, fine_solver.operators().mass)},
                    {"max_abs", fem::max_abs_error(distance, reference)},
                    {"mean_rel", d.mean_relative},
                    {"max_rel", d.max_relative},
                    {"max_reference_distance", reference.maxCoeff()}};
      clock.lap();
    }

    // ---- outputs
    app::write_result_ply(opt, mesh, "distance", distance, reference);
    run.write = clock.lap();
    nlohmann::json report = run.report();
    report["sources"] = file_sources;
    report["max_distance"] = distance.maxCoeff();
    if (run.has_reference) report["error"] = error_json;
    if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

    run.print_summary(std::cout);
    std::cout << "  sources: " << sources_text << "; prolonged max distance " << distance.maxCoeff() << '\n';
    if (run.has_reference)
      std::cout << "  error vs fine: mean " << app::percent(error_json["mean_rel"]) << ", max "
                << app::percent(error_json["max_rel"]) << " of the max distance "
                << static_cast<double>(error_json["max_reference_distance"]) << "; relative L2 "
                << app::percent(error_json["rel_l2"]) << ", max abs " << static_cast<double>(error_json["max_abs"]) << '\n';
    if (!opt.output.empty()) std::cout << "  wrote " << opt.output << '\n';
    if (!opt.report.empty()) std::cout << "  wrote " << opt.report << '\n';
    return app::kOk;
  });
}
