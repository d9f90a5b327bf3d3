// vector-accuracy: parallel transport by the vector heat method against exact parallel transport
// along exact polyhedral geodesics (CGAL's Surface_mesh_shortest_path), per mesh:
//
//   vector-accuracy [--ratio R] [--time-factor F] [--repair] [--max-vertices N] mesh...
//
// Meshes of more than N vertices (default 100,000) are skipped with a message: the exact geodesics'
// memory grows faster than the mesh (dragon_vrip_bin, 437,645 vertices: killed at 24 GB after 5 min).
//
// Sources: vertices 0, n/3 and 2n/3 (vector-coarse's sweeps), each with the vector of angle 0 in its
// frame. The exact transport of z from s to v keeps its angle with the geodesic: z times the path's
// direction at v over its direction at s, both read in the vertices' frames (fem::ambient_to_tangent
// of the path's first segment at s and, reversed, of its last segment at v); a path that runs
// through mesh vertices carries it across each in the frames' convention (arriving is half a turn
// from leaving back, as at any vertex of the discrete connection) — a convention, so the reference is
// uncertain by up to the angle excess of the saddles crossed (stderr: per source, how many paths
// cross none, and the fine method's error on those). Prints one Markdown row per mesh: median angle
// errors (degrees; median over vertices, then over the sources) of the fine method and of the proxy
// at R of the vertices (vector-coarse's pipelines: coarse diffusion, --vector-solver diffusion, and the
// sweep, the default), each with the fine operators of the input triangles and of their intrinsic
// Delaunay triangulation, against exact transport and the proxies against their own fine method
// (what vector-coarse reports). A benchmark tool: CGAL is not a dependency of the
// libraries.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "app_common.h"
#include "exact_geodesics.h"
#include "fem/vector_fields.h"
#include "ice/coarse_space.h"
#include "ice/mesh_io.h"

namespace {

double median(std::vector<double> values) {
  if (values.empty()) return std::nan("");
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  double ratio = 0.05, time_factor = fem::kVectorProxyTimeFactor;
  long long max_vertices = ice_bench::kDefaultExactMaxVertices;
  ice::LoadOptions load;
  std::vector<std::string> meshes;
  bool help = false, bad_option = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--ratio" && i + 1 < argc) ratio = std::atof(argv[++i]);
    else if (arg == "--time-factor" && i + 1 < argc) time_factor = std::atof(argv[++i]);
    else if (arg == "--repair") load.repair = true;  // the safe repairs (ice-info --repair)
    else if (arg == "--max-vertices" && i + 1 < argc) max_vertices = std::atoll(argv[++i]);
    else if (arg.rfind('-', 0) == 0) {  // --help, or an option it does not know (not a mesh path)
      help = arg == "--help" || arg == "-h";
      bad_option = !help;
      break;
    } else meshes.push_back(arg);
  }
  if (help || bad_option || meshes.empty() || !(ratio > 0 && ratio <= 1) || !(time_factor > 0) || max_vertices < 1) {
    std::fprintf(help ? stdout : stderr,
                 "usage: vector-accuracy [--ratio R] [--time-factor F] [--repair] [--max-vertices N] mesh...\n");
    return help ? 0 : 4;
  }
  std::printf("| mesh | vertices | coarse | fine vs exact: input / iDT | diffusion vs exact: input / iDT | diffusion vs its fine: "
              "input / iDT | sweep vs exact: input / iDT | sweep vs its fine: input / iDT | vertices compared |\n"
              "|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& path : meshes) {
    ice::TriangleMesh mesh;
    try {
      mesh = ice::load_mesh(path, load);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "vector-accuracy: skipping %s: %s\n", path.c_str(), e.what());
      continue;
    }
    const auto n = static_cast<ice::Index>(mesh.V.rows());
    if (ice_bench::skip_for_exact_geodesics("vector-accuracy", path, n, max_vertices)) continue;
    ice::CoarseSpaceOptions options;
    options.coarsen.target_ratio = ratio;
    options.keep_method_state = true;
    const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
    const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(space);
    // vector-coarse's pipeline with the fine operators of the input triangles, then of their
    // intrinsic Delaunay triangulation (both in the input triangles' frames).
    struct Discretisation {
      ice::proxy::TangentMesh fine;
      fem::VectorHeatSolver solver;
      fem::VectorHeatProxy proxy;
      fem::VectorSweepProxy sweep;
      std::vector<double> fine_errors, proxy_errors, proxy_vs_fine, sweep_errors, sweep_vs_fine;  // per source
    };
    std::vector<std::unique_ptr<Discretisation>> runs;
    for (const ice::FineGeometry geometry : {ice::FineGeometry::input, ice::FineGeometry::intrinsic_delaunay}) {
      ice::proxy::TangentMesh fine = ice::proxy::tangent_mesh(mesh, geometry, true);
      fem::VectorHeatSolver solver(*fine.operators);
      fem::VectorHeatProxy proxy = ice::proxy::make_vector_proxy(fine, space, map, fem::VectorOperatorKind::galerkin, time_factor);
      fem::VectorSweepProxy sweep = ice::proxy::make_vector_sweep(mesh, fine, space, map);
      runs.push_back(std::make_unique<Discretisation>(
          Discretisation{std::move(fine), std::move(solver), std::move(proxy), std::move(sweep), {}, {}, {}, {}, {}}));
    }
    const ice::IntrinsicMesh& input = runs.front()->fine.mesh;  // the same triangles and frames in both
    const fem::TangentFrames& frames = runs.front()->fine.frames;
    const auto unit_tangent = [&](ice::Index v, const Eigen::Vector3d& direction) {
      const fem::Complex t = fem::ambient_to_tangent(input, frames, mesh.V, v, direction);
      return t / std::abs(t);
    };
    long long compared = 0;
    for (const ice::Index source : {ice::Index{0}, static_cast<ice::Index>(n / 3), static_cast<ice::Index>(2 * n / 3)}) {
      const fem::Complex z(1, 0);
      std::vector<Eigen::VectorXcd> fine_fields, proxy_fields, sweep_fields;
      for (const auto& run : runs) {
        fine_fields.push_back(run->solver.interpolate({source}, {z}));
        proxy_fields.push_back(run->proxy.interpolate({source}, {z}));
        sweep_fields.push_back(run->sweep.interpolate({source}, {z}));
      }
      std::vector<std::vector<double>> fine_here(runs.size()), proxy_here(runs.size()), between_here(runs.size()),
          sweep_here(runs.size()), sweep_between_here(runs.size());
      std::vector<double> direct_here;  // the Delaunay fine method on paths that cross no vertex
      ice_bench::for_each_exact_path(mesh, source, [&](ice::Index v, const ice_bench::ExactPath& path) {
        // The vector's angle with the path, carried from the source: kept along each straight piece;
        // at a vertex the path runs through, arriving along it is half a turn from leaving back
        // along it in the vertex's frame (the frames' convention at cones and saddles).
        fem::Complex relative = z / unit_tangent(source, path.departure);
        for (const ice_bench::ExactPath::Through& through : path.through)
          relative = -unit_tangent(through.vertex, through.back) * relative / unit_tangent(through.vertex, through.ahead);
        const fem::Complex exact = -unit_tangent(v, path.back) * relative;
        if (!std::isfinite(std::abs(exact))) return;
        for (std::size_t r = 0; r < runs.size(); ++r) {
          fine_here[r].push_back(fem::angle_between_degrees(fine_fields[r](v), exact));
          proxy_here[r].push_back(fem::angle_between_degrees(proxy_fields[r](v), exact));
          between_here[r].push_back(fem::angle_between_degrees(proxy_fields[r](v), fine_fields[r](v)));
          sweep_here[r].push_back(fem::angle_between_degrees(sweep_fields[r](v), exact));
          sweep_between_here[r].push_back(fem::angle_between_degrees(sweep_fields[r](v), fine_fields[r](v)));
        }
        if (path.through.empty()) direct_here.push_back(fine_here.back().back());
      });
      compared += static_cast<long long>(fine_here.front().size());
      for (std::size_t r = 0; r < runs.size(); ++r) {
        runs[r]->fine_errors.push_back(median(fine_here[r]));
        runs[r]->proxy_errors.push_back(median(proxy_here[r]));
        runs[r]->proxy_vs_fine.push_back(median(between_here[r]));
        runs[r]->sweep_errors.push_back(median(sweep_here[r]));
        runs[r]->sweep_vs_fine.push_back(median(sweep_between_here[r]));
      }
      std::fprintf(stderr, "%s, source %lld: %zu of %zu paths cross no vertex; fine method (Delaunay) vs exact on them %.2f\n",
                   path.c_str(), static_cast<long long>(source), direct_here.size(), fine_here.back().size(), median(direct_here));
    }
    const std::string name = path.substr(path.find_last_of('/') + 1);
    const Discretisation &on_input = *runs.front(), &on_delaunay = *runs.back();
    std::printf("| %s | %lld | %lld | %.2f / %.2f | %.2f / %.2f | %.2f / %.2f | %.2f / %.2f | %.2f / %.2f | %lld |\n",
                name.c_str(), static_cast<long long>(n), static_cast<long long>(space.mesh.num_vertices()),
                median(on_input.fine_errors), median(on_delaunay.fine_errors), median(on_input.proxy_errors),
                median(on_delaunay.proxy_errors), median(on_input.proxy_vs_fine), median(on_delaunay.proxy_vs_fine),
                median(on_input.sweep_errors), median(on_delaunay.sweep_errors), median(on_input.sweep_vs_fine),
                median(on_delaunay.sweep_vs_fine), compared);
    std::fflush(stdout);
  }
  return 0;
}
