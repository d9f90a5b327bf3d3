// oracle-accuracy: the geodesic distance oracle (fem/distance_oracle.h) against exact polyhedral
// geodesics (CGAL's Surface_mesh_shortest_path, Debian's libcgal-dev) and against the fine heat
// method, per mesh:
//
//   oracle-accuracy [--coarse N] [--sources K] [--subdivisions S] [--max-vertices N] mesh...
//
// Meshes of more than N vertices (default 100,000, ice_bench::kDefaultExactMaxVertices) are skipped
// with a message: the exact geodesics' memory grows faster than the mesh.
//
// For K random source vertices: exact distances to every vertex (CGAL), fine heat-method distances
// (one factorisation, blocked solve), and the oracle's at N coarse vertices (ICE, geodesic
// defaults) with marching (on the coarse lengths and on the curvature-corrected ones,
// fem/curvature_correction.h) and with heat-method coarse distances. Prints one Markdown row per mesh
// and oracle: mean and 95th-percentile of |d − d_ref| / d_ref over all pairs, far pairs and near
// pairs (sharing a coarse vertex), against exact and against the fine heat method; and the fine
// heat method's own error against exact. A benchmark tool: CGAL is not a dependency of the library.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "fem/curvature_correction.h"
#include "fem/distance_oracle.h"
#include "fem/problems.h"
#include "ice/coarse_space.h"
#include "exact_geodesics.h"
#include "ice/mesh_io.h"

namespace {

std::string summary(std::vector<double> e) {
  if (e.empty()) return "- / -";
  double sum = 0;
  for (double x : e) sum += x;
  std::sort(e.begin(), e.end());
  char text[64];
  std::snprintf(text, sizeof text, "%.2f%% / %.2f%%", 100 * sum / static_cast<double>(e.size()),
                100 * e[(e.size() - 1) * 95 / 100]);
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  int coarse = 1000, source_count = 4, subdivisions = 0;
  long long max_vertices = ice_bench::kDefaultExactMaxVertices;
  std::vector<std::string> meshes;
  bool help = false, bad_option = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--coarse" && i + 1 < argc) coarse = std::atoi(argv[++i]);
    else if (arg == "--subdivisions" && i + 1 < argc) subdivisions = std::atoi(argv[++i]);
    else if (arg == "--sources" && i + 1 < argc) source_count = std::atoi(argv[++i]);
    else if (arg == "--max-vertices" && i + 1 < argc) max_vertices = std::atoll(argv[++i]);
    else if (arg.rfind('-', 0) == 0) {  // --help, or an option it does not know (not a mesh path)
      help = arg == "--help" || arg == "-h";
      bad_option = !help;
      break;
    } else meshes.push_back(arg);
  }
  if (help || bad_option || meshes.empty() || coarse < 10 || source_count < 1 || subdivisions < 0 || max_vertices < 1) {
    std::fprintf(help ? stdout : stderr,
                 "usage: oracle-accuracy [--coarse N] [--sources K] [--subdivisions S] [--max-vertices N] mesh...\n");
    return help ? 0 : 4;
  }
  std::printf("| mesh | vertices | coarse | oracle | vs exact: all (mean / p95) | far | near | vs fine heat: all | far | near "
              "| fine heat vs exact | coarse pairs |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& path : meshes) {
    ice::TriangleMesh mesh;
    try {
      mesh = ice::load_mesh(path);
    } catch (const std::exception& e) {  // (as vector-accuracy: the other meshes still count)
      std::fprintf(stderr, "oracle-accuracy: skipping %s: %s\n", path.c_str(), e.what());
      continue;
    }
    const auto n = static_cast<ice::Index>(mesh.V.rows());
    if (ice_bench::skip_for_exact_geodesics("oracle-accuracy", path, n, max_vertices)) continue;
    ice::CoarseSpaceOptions options;
    options.coarsen = ice::recommended_coarsen_options(ice::ProxyUse::geodesic);
    options.coarsen.target_vertices = std::min<ice::Index>(coarse, n / 5);
    options.keep_method_state = true;
    const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
    const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(space);

    std::mt19937 rng(1);
    std::uniform_int_distribution<ice::Index> vertex(0, n - 1);
    std::vector<ice::Index> sources;
    for (int s = 0; s < source_count; ++s) sources.push_back(vertex(rng));

    const Eigen::MatrixXd exact = ice_bench::exact_geodesic_distances(mesh, sources);
    const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
    const fem::HeatGeodesicSolver fine_solver(fem::heat_method_operators(fine, fem::MassKind::lumped, 1.0));
    const Eigen::MatrixXd heat = fine_solver.distances_from_each(sources);
    std::vector<double> heat_vs_exact;
    for (int s = 0; s < source_count; ++s)
      for (ice::Index v = 0; v < n; ++v)
        if (v != sources[s] && exact(v, s) > 0) heat_vs_exact.push_back(std::abs(heat(v, s) - exact(v, s)) / exact(v, s));

    // Marching on the coarse mesh's own lengths and on the curvature-corrected ones (geodesic-coarse's
    // default for ICE), and the heat method.
    const ice::FaceLengths corrected =
        fem::curvature_corrected_lengths(ice::intrinsic_mesh(mesh), space.mesh, space.P, fem::kOracleCorrectionDivisor);
    for (const int variant : {0, 1, 2}) {
      const fem::CoarseDistanceMethod method = variant < 2 ? fem::CoarseDistanceMethod::marching : fem::CoarseDistanceMethod::heat_method;
      fem::DistanceOracleOptions oracle_options;
      oracle_options.method = method;
      oracle_options.subdivisions = method == fem::CoarseDistanceMethod::marching ? subdivisions : 0;
      const fem::DistanceOracle oracle(ice::with_lengths(space.mesh, variant == 1 ? corrected : space.mesh.L), map, oracle_options);
      const fem::PairErrors vs_exact = fem::relative_pair_errors(oracle, sources, exact);
      const fem::PairErrors vs_heat = fem::relative_pair_errors(oracle, sources, heat);
      const std::string name = path.substr(path.find_last_of('/') + 1);
      std::printf("| %s | %d | %ld | %s | %s | %s | %s | %s | %s | %s | %s | %.3f s |\n", name.c_str(), n,
                  static_cast<long>(oracle.coarse_size()), variant == 1 ? "marching, curvature-corrected" : fem::to_string(method),
                  summary(vs_exact.all()).c_str(),
                  summary(vs_exact.far).c_str(), summary(vs_exact.near).c_str(), summary(vs_heat.all()).c_str(),
                  summary(vs_heat.far).c_str(), summary(vs_heat.near).c_str(), summary(heat_vs_exact).c_str(),
                  oracle.times().coarse_distances);
      std::fflush(stdout);
    }
  }
  return 0;
}
