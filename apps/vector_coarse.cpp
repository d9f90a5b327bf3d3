// vector-coarse: tangent vector fields by the vector heat method (Sharp, Soliman, Crane 2019) through
// an ICE coarse proxy; optionally compared with the same method solved directly on the fine mesh.
//
// One source: parallel transport of its vector along shortest geodesics; several: the smooth field
// that interpolates them (directions by the connection Laplacian, magnitudes by scalar diffusion).
//
// Pipeline (every phase timed apart): load → coarsen (ice::build_coarse_space with the fine-to-coarse
// map) → fine mesh (app::tangent_mesh: the input triangles and their tangent frames, in which the
// fields are given, and the fine operators in those frames, on the input's intrinsic Delaunay
// triangulation unless --no-fine-idt) → factor → solve. The default proxy (--vector-solver sweep,
// app::make_vector_sweep): factor prepares coarse marching (traced, curvature-corrected lengths);
// solve marches the distance from the sources on the coarse mesh and solves the fine method's systems
// by Gauss–Seidel in order of that distance, scaled by the kernel's decay along it (converging to the
// fine method's field; --sweep-passes). The other (--vector-solver diffusion, app::make_vector_proxy):
// factor fits the vector prolongation P_vec from the map and factors the coarse operators (Galerkin
// P_vecᴴ L∇ P_vec or intrinsic); solve restricts the sources, solves three coarse systems and prolongs
// them with P_vec and P. Then the reference: fem::VectorHeatSolver with the fine operators, and the
// angle and magnitude errors against it.
//
// Vectors are given in each source's tangent frame (fem/vector_fields.h): an angle in degrees,
// counter-clockwise from the vertex's reference edge (the first edge of its first face in the file;
// on the boundary the boundary edge it starts along), or a 3D direction projected into the surface.
// The fine discretisation is the input triangles, on which the fields are drawn (--output writes
// them as 3D vectors per vertex).
//
// Exit codes: see app_common.h (0 ok, 1 unreadable, 2 defective/unsuitable mesh, 3 output not written,
// 4 bad command line, 5 computation failed).
#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>

#include <Eigen/Geometry>

#include "tool_main.h"
#include "app_common.h"
#include "fem/vector_fields.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/large_array.h"
#include "ice/scalar_field_io.h"

namespace vector_coarse_tool {

const std::string kTool = "vector-coarse";
constexpr double kPi = 3.141592653589793238462643383279502884;

nlohmann::json angle_error_json(const std::vector<double>& errors, Eigen::Index vertices) {
  double sum = 0;
  for (double e : errors) sum += e;
  return {{"vertices_compared", errors.size()},
          {"vertices_without_field", static_cast<long long>(vertices) - static_cast<long long>(errors.size())},
          {"median_deg", app::quantile(errors, 0.5)},
          {"mean_deg", errors.empty() ? std::nan("") : sum / static_cast<double>(errors.size())},
          {"p95_deg", app::quantile(errors, 0.95)},
          {"max_deg", errors.empty() ? std::nan("") : *std::max_element(errors.begin(), errors.end())}};
}

/// Fine frames whose fit to the coarse mesh is poor beyond this share make the tool warn. Measured
/// (source 0, 5 %, 148 CGAL-archive and shared meshes): 28 of the 37 meshes above 5 % had median
/// angle errors above 10° (cheese 18 % poor fits: 96°, elephant-with-holes 47 %: 65°, boxpart 19 %:
/// 87°), and the poor fits rise as the coarse mesh gets too coarse for the surface's topology, holes
/// or thin parts.
constexpr double kPoorFitShareWarning = 0.05;

void warn_if_frames_fit_poorly(const fem::VectorProlongationStats& stats) {
  if (stats.fitted == 0 || static_cast<double>(stats.poor_fits) <= kPoorFitShareWarning * static_cast<double>(stats.fitted)) return;
  app::warn(kTool, app::thousands(stats.poor_fits) + " of " + app::thousands(stats.fitted) + " fine frames (" +
                       app::percent(static_cast<double>(stats.poor_fits) / static_cast<double>(stats.fitted)) +
                       ") fit the coarse mesh poorly (the fine-to-coarse map distorts or folds their one-rings: too few "
                       "coarse vertices for the surface's holes, handles or thin parts); angle errors are likely large. "
                       "Coarsen less (--ratio, --vertices)");
}

}  // namespace vector_coarse_tool

int vector_coarse_tool::main(int argc, char** argv) {
  ice::keep_freed_memory_for_reuse();  // one job per process: reuse freed arrays instead of re-faulting them
  CLI::App cli{
      "vector-coarse: tangent vector fields by the vector heat method (parallel transport from a source, or the "
      "smooth field\nthrough several vectors) through an ICE coarse mesh, compared with the fine solution.\n\n"
      "Examples:\n"
      "  vector-coarse data/default/bear.off --source 0 --vector 30 -o field.ply\n"
      "  vector-coarse bunny.off --source 10,250 --direction 1,0,0,0,1,0 --ratio 0.02 --report r.json\n\n"
      "Exit status: 0 ok, 1 unreadable input, 2 defective or disconnected mesh, 3 output not written,\n"
      "4 bad command line (e.g. source out of range), 5 computation failed."};
  app::PdeOptions opt;
  std::string sources_text, angles_text, directions_text, magnitudes_text;
  double time_factor = fem::kVectorProxyTimeFactor;
  ice::proxy::VectorSolver solver = ice::proxy::VectorSolver::sweep;
  fem::DistanceSweepOptions sweep_options;
  cli.add_option("--source,-s", sources_text, "Source vertices, 0-based, comma separated")
      ->required();
  cli.add_option("--vector", angles_text,
                 "One angle per source, degrees counter-clockwise from its reference edge (its first face's outgoing "
                 "edge)");
  cli.add_option("--direction", directions_text,
                 "Instead of --vector: one x,y,z direction per source, projected into the surface");
  cli.add_option("--magnitude", magnitudes_text, "One length per source (default 1 each)");
  app::add_choice(cli, "--vector-solver", solver, {{"sweep", ice::proxy::VectorSolver::sweep}, {"diffusion", ice::proxy::VectorSolver::diffusion}},
                  "'sweep': Gauss-Seidel on the fine systems in coarse-marching distance order; 'diffusion': coarse "
                  "diffusion");
  cli.add_option("--sweep-passes", sweep_options.max_passes,
                 "sweep: at most N Gauss-Seidel passes after the first (stops when no value moves by 1e-3 of its "
                 "terms)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cli.add_option("--sweep-coarse-interval", sweep_options.coarse_correction_interval,
                 "sweep: a Galerkin coarse-grid correction before every N-th pass (0: passes only)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cli.add_option("--time-factor", time_factor,
                 "diffusion: coarse time t = (F h_c)^2, h_c the coarse mean edge length (default measured best)")
      ->check(app::positive_number())
      ->capture_default_str();
  opt.add_to(cli, "vector_*, reference_*, angle_error, magnitude_error");
  opt.add_cache_options(cli);
  opt.add_nonmanifold_option(cli);
  if (const int status = app::parse_command_line(cli, argc, argv); status >= 0) return status;

  return app::run_tool(kTool, [&]() -> int {
    using app::AppError;
    if (angles_text.empty() == directions_text.empty())
      throw AppError(app::kUsage, "give the vectors by exactly one of --vector (angles) and --direction (3D)");
    if (opt.target.method == ice::CoarseningMethod::qem && opt.qem_geometry == ice::QemGeometry::intrinsic_delaunay)
      throw AppError(app::kUsage, "--qem-operators idt has no fine-to-coarse map onto its coarse mesh; use extrinsic");
    // The field is written as PLY vertex properties; no page draws vector fields yet: refuse rather
    // than write nothing (--html) or a PLY under a .glb name.
    if (!opt.html.empty()) throw AppError(app::kUsage, "--html: vector-coarse draws no page; write the field with -o FILE.ply");
    if (opt.output_is_gltf()) throw AppError(app::kUsage, "--output " + opt.output + ": vector-coarse writes PLY; use a .ply name");
    opt.check_outputs();
    const std::vector<long long> file_sources = app::parse_index_list(sources_text, "--source");
    const std::size_t count = file_sources.size();
    const std::vector<double> angles = angles_text.empty() ? std::vector<double>() : app::parse_number_list(angles_text, "--vector");
    const std::vector<double> directions =
        directions_text.empty() ? std::vector<double>() : app::parse_number_list(directions_text, "--direction");
    std::vector<double> magnitudes = magnitudes_text.empty() ? std::vector<double>(count, 1.0)
                                                             : app::parse_number_list(magnitudes_text, "--magnitude");
    if (!angles.empty() && angles.size() != count)
      throw AppError(app::kUsage, "--vector: " + std::to_string(angles.size()) + " angles for " + std::to_string(count) + " sources");
    if (!directions.empty() && directions.size() != 3 * count)
      throw AppError(app::kUsage, "--direction: " + std::to_string(directions.size()) + " numbers for " +
                                      std::to_string(count) + " sources (3 per source)");
    if (magnitudes.size() != count)
      throw AppError(app::kUsage, "--magnitude: " + std::to_string(magnitudes.size()) + " lengths for " + std::to_string(count) + " sources");
    for (double m : magnitudes)
      if (!(m > 0)) throw AppError(app::kUsage, "--magnitude: lengths must be positive");

    const fem::VectorOperatorKind kind = opt.operators == fem::CoarseOperatorKind::galerkin ? fem::VectorOperatorKind::galerkin
                                                                                            : fem::VectorOperatorKind::intrinsic;
    const bool sweep = solver == ice::proxy::VectorSolver::sweep;
    const bool galerkin = !sweep && kind == fem::VectorOperatorKind::galerkin;
    app::PdeRun run = app::PdeRun::start(kTool, opt, galerkin);
    if (sweep) run.coarse_solver = "fine Gauss-Seidel ordered and scaled by the coarse marching distance";

    // ---- load
    app::Stopwatch clock;
    const ice::LoadResult loaded = app::load_input_mesh(opt.mesh, opt.load_options());
    const ice::TriangleMesh& mesh = loaded.mesh;
    const Eigen::Index n = mesh.V.rows();
    // On a tufted cover (--nonmanifold tufted, a mesh that needs it) the field lives on the copies of
    // its sheets, each with a tangent plane of its own: sources are given in space (--direction), on
    // every copy of the vertex, and each vertex's vector is the mean of its copies' in space.
    const bool covered = ice::solved_on_tufted_cover(mesh, opt.nonmanifold);
    if (covered && !angles.empty())
      throw AppError(app::kUsage, opt.mesh + ": --vector: on the tufted cover a vertex has a tangent plane per sheet around it "
                                             "(no one reference edge); give --direction");
    std::optional<ice::TuftedCover> cover;
    if (covered) cover = ice::distinct_sheets(ice::tufted_cover(mesh, /*tuft_boundary=*/false));  // open sheets keep their boundary
    const app::FileVertexMap vertices(loaded);
    std::vector<ice::Index> sources;
    for (long long s : file_sources) sources.push_back(vertices.mesh_vertex(s, "--source: vertex"));
    run.fine_vertices = n;
    run.fine_faces = mesh.F.rows();
    ice::CoarsenOptions coarsen_options;
    opt.target.apply(coarsen_options, n);
    run.load = clock.lap();

    // ---- coarsen (with the map P_vec is fitted from), or the coarse space and map from the store
    // (on a cover: its copies' coarse space, made here)
    const ice::proxy::Store store = opt.store();
    ice::proxy::MappedSpace space;
    if (covered) {
      space.coarse = app::coarsen_copies_for_pde(*cover, coarsen_options, opt, run);
      space.map = ice::fine_to_coarse_map(space.coarse);
      space.coarse.triangulation.reset();  // the map made: free the method's state
      run.coarsen = clock.seconds();
    } else {
      space = app::mapped_space_for_pde(mesh, coarsen_options, opt, run, store, /*need_map=*/true);
    }
    const ice::CoarseSpace& coarse = space.coarse;
    const std::vector<ice::CoarsePoint>& map = space.map;
    clock.lap();  // run.coarsen, and the cache's load and save

    // ---- the input triangles' frames (the fields' and the sources'), the fine operators in them
    const bool fine_operators = sweep || galerkin || run.has_reference;
    const ice::proxy::TangentMesh fine = covered ? ice::proxy::tangent_mesh(*cover, opt.fine_geometry(), fine_operators)
                                                 : ice::proxy::tangent_mesh(mesh, opt.fine_geometry(), fine_operators);
    const fem::TangentFrames& fine_frames = fine.frames;
    run.fine_built = fine.operators.has_value();
    run.idt_flips = fine.flips;
    run.proxy_uses_fine_mesh = sweep || galerkin;
    run.fine_mesh = clock.lap();
    // The sources' vectors in the fine frames (on a cover: on every copy of each source).
    std::vector<ice::Index> field_sources = sources;
    std::vector<fem::Complex> vectors;
    try {
      if (covered) {
        Eigen::MatrixXd scaled(static_cast<Eigen::Index>(count), 3);
        for (std::size_t s = 0; s < count; ++s) {
          const Eigen::Vector3d d(directions[3 * s], directions[3 * s + 1], directions[3 * s + 2]);
          scaled.row(static_cast<Eigen::Index>(s)) = magnitudes[s] * d.normalized().transpose();
        }
        ice::proxy::CopySources on_copies = ice::proxy::sources_on_copies(*cover, fine, sources, scaled, file_sources);
        field_sources = std::move(on_copies.copies);
        vectors = std::move(on_copies.vectors);
      } else {
        for (std::size_t s = 0; s < count; ++s) {
          const Eigen::Vector3d d(directions.empty() ? Eigen::Vector3d::Zero()
                                                     : Eigen::Vector3d(directions[3 * s], directions[3 * s + 1], directions[3 * s + 2]));
          const fem::Complex z = !angles.empty() ? std::polar(1.0, angles[s] * kPi / 180)
                                                 : ice::proxy::tangent_direction(fine, mesh.V, sources[s], d.normalized(),
                                                                                 "source " + std::to_string(file_sources[s]));
          vectors.push_back(magnitudes[s] * z);
        }
      }
    } catch (const std::invalid_argument& e) {  // a direction normal to the surface, a source on a cover's fold
      throw AppError(app::kUsage, opt.mesh + ": " + e.what());
    }
    run.assemble = clock.lap();
    // One of the two proxies: the sweep's marching distance, or the diffusion's vector prolongation
    // and coarse factorisations.
    std::optional<fem::VectorSweepProxy> sweep_proxy;
    std::optional<fem::VectorHeatProxy> diffusion_proxy;
    if (sweep) {
      // The sweep marches on the coarse edges' traced, curvature-corrected lengths (ICE): through the store too.
      // On a cover on the coarse mesh's own (its edges lie on the sheets, not on the input's triangles).
      const ice::SurfaceEdgeLengths lengths =
          covered ? ice::SurfaceEdgeLengths{coarse.mesh.L, 0, 0}
                  : app::stored_marching_lengths(run, clock, mesh, space, store, ice::proxy::vector_sweep_traces(coarse),
                                                 ice::proxy::CurvatureCorrection::automatic,
                                                 ice::proxy::curvature_divisor(ice::proxy::MarchingUse::single_source));
      sweep_proxy.emplace(ice::proxy::make_vector_sweep(mesh, fine, coarse, map, sweep_options, &lengths));
    } else {
      diffusion_proxy.emplace(ice::proxy::make_vector_proxy(fine, coarse, map, kind, time_factor));
    }
    run.factor = clock.lap();
    if (diffusion_proxy) warn_if_frames_fit_poorly(diffusion_proxy->prolongation_stats());
    fem::DistanceSweepStats sweep_stats;
    const Eigen::VectorXcd field =
        sweep ? sweep_proxy->interpolate(field_sources, vectors, &sweep_stats) : diffusion_proxy->interpolate(field_sources, vectors);
    run.solve = clock.lap();  // the distance or the coarse solves, and the fine combination, in one call

    // ---- reference
    nlohmann::json error_json;
    Eigen::VectorXcd reference;
    std::vector<double> angle_errors;
    Eigen::VectorXd angle_error_field, magnitude_error_field;
    if (run.has_reference) {
      run.ref_assemble = clock.lap();  // the fine operators: built with the fine mesh above
      const fem::VectorHeatSolver fine_solver(*fine.operators);
      run.ref_factor = clock.lap();
      reference = fine_solver.interpolate(field_sources, vectors);
      run.ref_solve = clock.lap();
      angle_error_field = Eigen::VectorXd::Constant(n, std::nan(""));
      magnitude_error_field = Eigen::VectorXd::Constant(n, std::nan(""));
      std::vector<double> magnitude_errors;
      // Per input vertex: in its frame, or on a cover between the 3D vectors written (the copies' means).
      const Eigen::MatrixXd field_3d = covered ? ice::proxy::ambient_on_input(*cover, fine, field) : Eigen::MatrixXd();
      const Eigen::MatrixXd reference_3d = covered ? ice::proxy::ambient_on_input(*cover, fine, reference) : Eigen::MatrixXd();
      for (Eigen::Index v = 0; v < n; ++v) {
        double e, size, reference_size;
        if (covered) {
          const Eigen::Vector3d a = field_3d.row(v).transpose(), b = reference_3d.row(v).transpose();
          size = a.norm();
          reference_size = b.norm();
          e = size > 0 && reference_size > 0 ? std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / kPi : std::nan("");
        } else {
          e = fem::angle_between_degrees(field(v), reference(v));
          size = std::abs(field(v));
          reference_size = std::abs(reference(v));
        }
        if (std::isnan(e)) continue;
        angle_errors.push_back(e);
        angle_error_field(v) = e;
        magnitude_error_field(v) = (size - reference_size) / reference_size;
        magnitude_errors.push_back(std::abs(magnitude_error_field(v)));
      }
      error_json = {{"angle", angle_error_json(angle_errors, n)},
                    {"magnitude_rel", {{"median", app::quantile(magnitude_errors, 0.5)}, {"max", app::quantile(magnitude_errors, 1.0)}}}};
      clock.lap();
    }

    // ---- outputs
    if (!opt.output.empty()) {
      std::vector<ice::ScalarField> fields;
      const auto add_vectors = [&](const std::string& name, const Eigen::VectorXcd& values) {
        const Eigen::MatrixXd ambient = covered ? ice::proxy::ambient_on_input(*cover, fine, values)
                                                : fem::tangent_to_ambient(fine.mesh, fine_frames, mesh.V, values);
        for (int axis = 0; axis < 3; ++axis) fields.push_back({name + "_" + "xyz"[axis], ambient.col(axis)});
      };
      add_vectors("vector", field);
      if (run.has_reference) {
        add_vectors("reference", reference);
        fields.push_back({"angle_error", angle_error_field});
        fields.push_back({"magnitude_error", magnitude_error_field});
      }
      ice::write_ply_with_fields(opt.output, mesh, fields, {opt.force, !opt.ascii});
    }
    run.write = clock.lap();
    nlohmann::json report = run.report();
    report["sources"] = file_sources;
    report["vector_solver"] = sweep ? "sweep" : "diffusion";
    if (sweep) {
      report["sweep"] = {{"passes", sweep_stats.passes},
                         {"last_change", sweep_stats.last_change},
                         {"settled", sweep_stats.settled},
                         {"coarse_interval", sweep_options.coarse_correction_interval},
                         {"coarse_corrections", sweep_stats.coarse_corrections}};
    } else {
      const fem::VectorProlongationStats& stats = diffusion_proxy->prolongation_stats();
      report["time_factor"] = time_factor;
      report["vector_prolongation"] = {{"fitted", stats.fitted},
                                       {"from_corner_chart", stats.from_corner},
                                       {"unmatched", stats.unmatched},
                                       {"median_fit_residual", stats.median_fit_residual},
                                       {"poor_fits", stats.poor_fits}};
    }
    if (run.has_reference) report["error"] = error_json;
    if (!opt.report.empty()) app::write_json_file(opt.report, report, opt.force);

    run.print_summary(std::cout);
    if (sweep) {
      std::cout << "  sources: " << sources_text << "; fine Gauss-Seidel along the coarse marching distance: " << sweep_stats.passes
                << " passes after the first (" << sweep_stats.coarse_corrections << " coarse corrections), last change "
                << sweep_stats.last_change << (sweep_stats.settled ? " (settled)" : " (stopped at the pass limit, --sweep-passes)") << "\n";
    } else {
      const fem::VectorProlongationStats& stats = diffusion_proxy->prolongation_stats();
      std::cout << "  sources: " << sources_text << "; vector prolongation: " << stats.fitted << " frames fitted, "
                << stats.from_corner << " from a corner's chart, " << stats.unmatched << " unmatched, " << stats.poor_fits
                << " poor fits\n";
    }
    if (run.has_reference)
      std::cout << "  angle error vs fine: median " << app::fixed(error_json["angle"]["median_deg"], 2) << " deg, mean "
                << app::fixed(error_json["angle"]["mean_deg"], 2) << ", p95 " << app::fixed(error_json["angle"]["p95_deg"], 2)
                << ", max " << app::fixed(error_json["angle"]["max_deg"], 1) << "; magnitude error median "
                << app::percent(error_json["magnitude_rel"]["median"]) << '\n';
    if (!opt.output.empty()) std::cout << "  wrote " << opt.output << '\n';
    if (!opt.report.empty()) std::cout << "  wrote " << opt.report << '\n';
    return app::kOk;
  });
}
