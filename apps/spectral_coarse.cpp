// spectral-coarse: the k smallest Laplace–Beltrami eigenpairs of a mesh (L φ = λ M φ, cotan L,
// lumped M, Neumann boundary or --boundary dirichlet) through an ICE coarse proxy: the coarse Galerkin pencil (PᵀLP, PᵀMP)
// solved by shift-invert Lanczos and its eigenvectors prolonged (ice::proxy::proxy_eigenbasis);
// by default compared with the same eigensolver on the fine mesh (eigenvalue errors, angles to the
// fine eigenspaces, residuals on the fine mesh).
//
// Exit codes: see app_common.h.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>

#include "tool_main.h"
#include "app_common.h"
#include "fem/eigen.h"
#include "fem/errors.h"
#include "fem/topology.h"
#include "ice/proxy/eigen.h"
#include "ice/proxy/report.h"
#include "ice/scalar_field_io.h"

namespace spectral_coarse_tool {

const std::string kTool = "spectral-coarse";

using ice::proxy::median;

}  // namespace spectral_coarse_tool

int spectral_coarse_tool::main(int argc, char** argv) {
  ice::keep_freed_memory_for_reuse();  // one job per process: reuse freed arrays instead of re-faulting them
  CLI::App cli{
      "spectral-coarse: the k smallest Laplace-Beltrami eigenpairs (cotan L, lumped M; Neumann or Dirichlet) through a\n"
      "small ICE coarse proxy, compared by default with the same eigensolver on the fine mesh.\n\n"
      "Examples:\n  spectral-coarse spot.obj -k 50 --ratio 0.05 --solutions eigs.npy --report r.json\n"
      "  spectral-coarse bunny.off -k 20 --vertices 2000 --show 3 --html page.html\n"
      "  spectral-coarse bunny.off -k 100 --ratio 0.05 --hks 0.001,0.01,0.1 --descriptors hks.npy\n\n"
      "Exit status: 0 ok, 1 unreadable input, 2 defective or disconnected mesh, 3 output not written, 4 bad command "
      "line,\n5 computation failed."};
  app::PdeOptions opt;
  int k = 0, show = -1, coarse_directions = -1;
  double tolerance = 0;
  std::string hks_text, descriptors, boundary = "neumann";
  cli.add_option("-k,--eigenpairs", k, "Number of eigenpairs (smallest eigenvalues first)")->required()->check(app::integer_between(1, 100000));
  cli.add_option("--boundary", boundary, "Boundary condition on meshes with a boundary: neumann, or dirichlet (phi = 0)")
      ->check(CLI::IsMember({"neumann", "dirichlet"}))
      ->capture_default_str();
  cli.add_option("--tolerance", tolerance,
                 "Refine the pairs on the input mesh to this relative residual |L phi - lambda M phi| / (lambda |M phi|);\n"
                 "0: the proxy's pairs as they are. Without --ratio/--vertices: " +
                     std::to_string(ice::proxy::EigenRefinement().coarse_vertices_per_pair) + " coarse vertices per coarse pair")
      ->check(CLI::Range(0.0, 0.1))
      ->capture_default_str();
  cli.add_option("--coarse-directions", coarse_directions,
                 "With --tolerance: coarse eigenvectors added to every Rayleigh-Ritz step (the augmented subspace method);\n"
                 "-1: 2 (k + guard); 0: none (LOBPCG)")
      ->check(CLI::Range(-1, 1000000))
      ->capture_default_str();
  cli.add_option("--solutions", opt.solutions, "Write the eigenvectors as .npy (float64, n x k, M-orthonormal)");
  cli.add_option("--show", show, "Eigenfunction drawn by -o/--html (0-based; default: the first non-constant)")
      ->check(app::non_negative_integer());
  cli.add_option("--hks", hks_text, "Heat kernel signature at these times (comma-separated), written by --descriptors");
  cli.add_option("--descriptors", descriptors, "Write the --hks descriptors as .npy (float64, n x times)");
  opt.add_to(cli, "'eigenfunction' (the --show one), 'reference', 'error'");
  opt.add_cache_options(cli);
  opt.add_nonmanifold_option(cli);
  ice::proxy::Prolongation prolongation = ice::proxy::Prolongation::automatic;
  app::add_prolongation_option(cli, prolongation);
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&] {
    opt.check_outputs();
    if (hks_text.empty() != descriptors.empty()) throw app::AppError(app::kUsage, "--hks and --descriptors go together");
    if (cli.count("--coarse-directions") > 0 && !(tolerance > 0))
      throw app::AppError(app::kUsage, "--coarse-directions applies to the refined route: give --tolerance too");
    if (!descriptors.empty()) app::check_output(descriptors, opt.force, "--descriptors");
    if (opt.operators != fem::CoarseOperatorKind::galerkin)
      throw app::AppError(app::kUsage, "the eigenbasis needs Galerkin coarse operators (--operators galerkin)");
    Eigen::VectorXd hks_times;
    if (!hks_text.empty()) {
      const std::vector<double> times = app::parse_number_list(hks_text, "--hks");
      hks_times = Eigen::Map<const Eigen::VectorXd>(times.data(), static_cast<Eigen::Index>(times.size()));
      if (hks_times.size() == 0 || !(hks_times.minCoeff() > 0)) throw app::AppError(app::kUsage, "--hks: times must be > 0");
    }
    const bool dirichlet = boundary == "dirichlet";
    if (show < 0) show = dirichlet ? 0 : std::min(1, k - 1);  // the first non-constant eigenfunction
    if (show >= k) throw app::AppError(app::kUsage, "--show " + std::to_string(show) + ": there are " + std::to_string(k) + " eigenfunctions");
    if (dirichlet && (prolongation == ice::proxy::Prolongation::smoothed || prolongation == ice::proxy::Prolongation::smoothed_twice))
      throw app::AppError(app::kUsage, "--boundary dirichlet needs --prolongation barycentric or auto (a smoothed "
                                       "prolongation does not vanish on the boundary)");
    app::PdeRun run = app::PdeRun::start(kTool, opt, /*proxy_uses_fine_mesh=*/true);

    // ---- load
    app::Stopwatch clock;
    const ice::LoadResult loaded = app::load_input_mesh(opt.mesh, opt.load_options());
    const ice::TriangleMesh& mesh = loaded.mesh;
    const long long n = mesh.V.rows();
    if (k >= n)
      throw app::AppError(app::kUsage, "-k " + std::to_string(k) + ": the mesh has " + std::to_string(n) + " vertices (k < vertices)");
    // Dirichlet: φ = 0 on the boundary, whose vertices the coarsening keeps (so coarse functions
    // vanishing there vanish on the whole fine boundary).
    // A point cloud has no boundary: its fans' one-sided edges are where candidates lost to overlaps.
    if (dirichlet && loaded.point_cloud)
      throw app::AppError(app::kUsage, "--boundary dirichlet: a point cloud has no boundary (its triangles' free edges are "
                                       "gaps between local fans, not a boundary of the surface)");
    const std::vector<ice::Index> fixed = dirichlet ? fem::boundary_vertices(mesh.F) : std::vector<ice::Index>();
    if (dirichlet && fixed.empty()) app::warn(kTool, "--boundary dirichlet: the mesh has no boundary (no vertex is fixed)");
    opt.prolongation = app::resolve_prolongation(prolongation, opt.operators, fixed.empty() ? "" : "--boundary dirichlet",
                                                 "--prolongation", ice::proxy::ProlongationUse::eigenpairs);
    run.prolongation = opt.prolongation;
    // The refined route (--tolerance): its coarse size below; the hierarchy whose V-cycle preconditions
    // it is set up with the proxy (through the store), the refinement is part of the solve.
    ice::proxy::EigenRefinement refinement;
    refinement.tolerance = tolerance;
    refinement.coarse_directions = coarse_directions;
    ice::CoarsenOptions coarsen_options;
    // The refined route without --ratio or --vertices: a coarse size for its pairs, not the mesh's
    // (ice::proxy::refined_coarse_vertices), at most the mesh (which the fine eigensolver then solves
    // directly: Eigenbasis::fine_eigensolve).
    app::TargetOptions target = opt.target;
    const bool target_given = cli.count("--ratio") + cli.count("--vertices") > 0;
    if (tolerance > 0 && !target_given) {
      target.vertices_option = nullptr;
      const long long wanted = ice::proxy::refined_coarse_vertices(k, refinement, static_cast<ice::Index>(fixed.size()));
      target.vertices = std::min(wanted, n);
    }
    target.apply(coarsen_options, n);
    coarsen_options.locked_vertices = fixed;
    if (coarsen_options.target_vertices > 0 && k >= coarsen_options.target_vertices)
      throw app::AppError(app::kUsage, "-k " + std::to_string(k) + ": the coarse target is " +
                                           std::to_string(coarsen_options.target_vertices) +
                                           " vertices (k < coarse vertices: raise --vertices or --ratio)");
    run.fine_vertices = n;
    run.fine_faces = mesh.F.rows();
    run.load = clock.lap();

    // ---- the proxy (from the store when it holds this setup), the coarse eigenproblem, prolongation
    const ice::proxy::Store store = opt.store();
    const ice::proxy::ProxySetup pde = app::build_pde_proxy(mesh, coarsen_options, opt, run, clock, true, run.has_reference, false,
                                                   store);
    const fem::CoarseProxy& proxy = *pde.proxy;
    run.assemble = clock.lap();
    const Eigen::Index coarse = proxy.coarse_laplacian().rows() - static_cast<Eigen::Index>(fixed.size());
    if (k >= coarse)
      throw app::AppError(app::kUsage, "-k " + std::to_string(k) + ": the coarse space has " + std::to_string(coarse) +
                                           (dirichlet ? " vertices off the boundary" : " vertices") +
                                           " (k < coarse vertices: raise --vertices or --ratio)");
    std::optional<ice::proxy::MultigridHierarchy> hierarchy;
    if (tolerance > 0 && ice::proxy::refinement_needs_hierarchy(proxy)) {
      hierarchy = app::stored_hierarchy(kTool, mesh, app::MultigridCli{refinement.hierarchy, {}}, opt, store);
      run.assemble += clock.lap();
    }
    static const ice::proxy::MultigridHierarchy no_hierarchy;  // not coarsened: refined_eigenbasis needs none
    const ice::proxy::Eigenbasis basis =
        tolerance > 0 ? ice::proxy::refined_eigenbasis(proxy, hierarchy ? *hierarchy : no_hierarchy, k, refinement, {}, fixed, store)
                      : ice::proxy::proxy_eigenbasis(proxy, k, {}, fixed, store);
    if (basis.refined && !basis.converged) {
      std::ostringstream message;
      if (basis.fine_eigensolve)
        message << "the fine eigensolver's largest residual is " << basis.residuals.maxCoeff() << " (--tolerance " << tolerance
                << ")";
      else
        message << "the refinement stopped after " << basis.refine_iterations << " iterations with a largest residual of "
                << basis.residuals.maxCoeff() << " (--tolerance " << tolerance << ")";
      app::warn(kTool, message.str());
    }
    // One eigenbasis is one "solve": the coarse factorisation and the Lanczos iteration (and the
    // refinement), as the reference's is its fine factorisation and iteration (both factor L − σM
    // for their own σ).
    run.solve = basis.eigensolve_seconds + basis.refine_seconds;
    run.prolong = basis.prolong_seconds;
    run.unit = "eigenbasis";
    clock.lap();

    // ---- reference: the same eigensolver on the fine mesh
    nlohmann::json error_json, residual_json, reference_json;
    Eigen::VectorXd reference_field;
    if (run.has_reference) {
      const ice::FineMesh& fine = pde.fine;
      const fem::SparseMatrix L = fem::cotan_laplacian(fine);
      const fem::SparseMatrix M = fem::mass_matrix(fine, fem::MassKind::lumped);
      run.ref_assemble = clock.lap();
      const fem::Eigenpairs ref = fem::smallest_eigenpairs_dirichlet(L, M, fixed, k);
      run.ref_solve = clock.lap();
      const ice::proxy::EigenbasisErrors errors = ice::proxy::eigenbasis_errors(basis.values, basis.vectors, ref, M);
      const Eigen::VectorXd residuals = fem::eigen_residuals(L, M, basis.values, basis.vectors, fixed);
      nlohmann::json per_pair = nlohmann::json::array();
      for (int j = 0; j < k; ++j)
        per_pair.push_back({{"value", basis.values(j)}, {"reference", ref.values(j)}, {"rel", errors.relative(j)},
                            {"angle_deg", errors.angles(j) * 180 / M_PI}, {"residual", residuals(j)}});
      const Eigen::VectorXd degrees = errors.angles * (180 / M_PI);
      error_json = {{"eigenvalue_rel_median", errors.relative_median},
                    {"eigenvalue_rel_max", errors.relative_max},
                    {"angle_deg_median", median(degrees)},
                    {"angle_deg_max", degrees.maxCoeff()},
                    {"zero_modes", errors.zero_modes},
                    {"pairs", per_pair}};
      residual_json = {{"max", residuals.maxCoeff()}, {"median", median(residuals)}};
      reference_json = {{"method", "shift-invert Lanczos (Spectra) on a CHOLMOD factorisation"},
                        {"ordering", fem::to_string(fem::EigenOptions{}.ordering)}, {"restarts", ref.restarts},
                        {"solves", ref.operations}, {"factor_seconds", ref.factor_seconds}};
      reference_field = ref.vectors.col(show);
      if (reference_field.dot(M * basis.vectors.col(show)) < 0) reference_field = -reference_field;  // eigenvectors' sign is free
      clock.lap();
    }
    const Eigen::VectorXd shown = basis.vectors.col(show);
    if (!opt.solutions.empty()) ice::write_npy_matrix(opt.solutions, basis.vectors, opt.force);
    if (!descriptors.empty()) ice::write_npy_matrix(descriptors, ice::proxy::heat_kernel_signature(basis, hks_times), opt.force);
    const std::optional<ice::CoarseTracing> tracing = app::trace_for_outputs(opt, mesh, pde.coarse);
    const ice::CoarseTracing* traced = tracing ? &*tracing : nullptr;
    app::write_result_fields(opt, mesh, "eigenfunction", shown, reference_field, {}, traced);
    app::write_result_page(opt, mesh, "spectral-coarse: " + std::filesystem::path(opt.mesh).filename().string(),
                           "eigenfunction " + std::to_string(show), "eigenfunction", shown, reference_field, pde.coarse,
                           traced, nlohmann::json(), loaded.point_cloud);
    run.write = clock.lap();

    nlohmann::json report = run.report();
    std::vector<double> values(basis.values.data(), basis.values.data() + k);
    report["eigen"] = {{"k", k}, {"values", values}, {"restarts", basis.restarts}, {"shown", show},
                       {"boundary", boundary}, {"dirichlet_vertices", fixed.size()},
                       {"cache", ice::proxy::cache_json(basis.cache, store)}};
    if (basis.refined)
      report["eigen"]["refine"] = {{"tolerance", tolerance},
                                   {"converged", basis.converged},
                                   {"iterations", basis.refine_iterations},
                                   {"guard", basis.guard},
                                   {"coarse_directions", basis.coarse_directions},
                                   {"method", basis.fine_eigensolve ? "fine_eigensolver"
                                              : basis.coarse_directions > 0 ? "augmented" : "lobpcg"},
                                   {"residual_max", basis.residuals.maxCoeff()},
                                   {"residual_history", basis.residual_history},
                                   {"seconds", basis.refine_seconds},
                                   {"precondition_seconds", basis.precondition_seconds},
                                   {"sparse_seconds", basis.refine_sparse_seconds},
                                   {"dense_seconds", basis.refine_dense_seconds},
                                   {"coarse_seconds", basis.refine_coarse_seconds},
                                   {"coarse_eigensolve_seconds", basis.eigensolve_seconds},
                                  };
    if (basis.refined && hierarchy) {
      report["eigen"]["refine"]["hierarchy"] = ice::proxy::hierarchy_json(*hierarchy, refinement.hierarchy);
      report["eigen"]["refine"]["hierarchy_cache"] = ice::proxy::cache_json(hierarchy->cache, store);
    }
    if (!hks_text.empty())
      report["eigen"]["hks_times"] = std::vector<double>(hks_times.data(), hks_times.data() + hks_times.size());
    if (run.has_reference) {
      report["error"] = error_json;
      report["residual"] = residual_json;
      report["reference"] = reference_json;
    }
    if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

    run.print_summary(std::cout);
    std::cout << "  problem: the " << k << " smallest eigenpairs; lambda_1.." << std::min(k, 4) << " =";
    for (int j = 0; j < std::min(k, 4); ++j) std::cout << ' ' << basis.values(j);
    std::cout << '\n';
    if (basis.fine_eigensolve)
      std::cout << "  not coarsened: the fine eigensolver on the input mesh, largest residual " << basis.residuals.maxCoeff()
                << (basis.converged ? "" : " (above --tolerance)") << '\n';
    else if (basis.refined)
      std::cout << "  refined on the input mesh: " << basis.refine_iterations << " iterations, largest residual "
                << basis.residuals.maxCoeff() << (basis.converged ? "" : " (not converged)") << '\n';
    if (run.has_reference)
      std::cout << "  vs fine eigenpairs: eigenvalue error median " << app::relative_error(error_json["eigenvalue_rel_median"])
                << ", max " << app::relative_error(error_json["eigenvalue_rel_max"]) << "; angle to the fine eigenspace median "
                << app::fixed(error_json["angle_deg_median"], 2) << " deg, max " << app::fixed(error_json["angle_deg_max"], 2)
                << " deg\n";
    if (!opt.solutions.empty())
      std::cout << "  wrote " << opt.solutions << " (" << app::thousands(n) << " x " << k << ")\n";
    if (!descriptors.empty())
      std::cout << "  wrote " << descriptors << " (" << app::thousands(n) << " x " << hks_times.size() << ")\n";
    app::print_written(std::cout, opt, traced);
    return app::kOk;
  });
}
