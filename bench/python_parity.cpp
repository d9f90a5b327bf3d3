// python-parity: the C++ side of the Python package's overhead benchmark (bench/python_overhead.py).
// Runs, with the library alone, exactly the calls the package makes for
//   coarse = ice.coarsen(V, F, ratio=R); proxy = ice.Proxy(V, F, coarse)
//   solver = ice.ProxyPoissonSolver(proxy); solver.solve(f)
//   geodesic = ice.ProxyGeodesicSolver(proxy); geodesic.distance([0])
// and prints the seconds of each as one JSON object per round. The input is MESH, Loop-subdivided
// --subdivide times (untimed). The two solves are timed as the median of 9 (python_overhead.py does
// the same). The Python side times the same operations through the package, so
// the ratio of the two is what calling through Python adds (argument checks, conversions, the GIL).
//
//   python-parity MESH [--subdivide L] [--ratio R] [--rounds K]
#include <algorithm>
#include <chrono>
#include <vector>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>

#include <Eigen/Core>

#include "fem/coarse_proxy.h"
#include "ice/coarse_space.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"

namespace {
double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}
// Solves take milliseconds, where one measurement is mostly noise: the median of kSolveRepeats.
constexpr int kSolveRepeats = 9;
template <class Call>
double median_seconds(Call call) {
  std::vector<double> samples;
  for (int i = 0; i < kSolveRepeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    call();
    samples.push_back(seconds_since(start));
  }
  std::nth_element(samples.begin(), samples.begin() + kSolveRepeats / 2, samples.end());
  return samples[kSolveRepeats / 2];
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "usage: python-parity MESH [--subdivide L] [--ratio R] [--rounds K]\n";
    return 4;
  }
  std::string path = argv[1];
  int subdivide = 0, rounds = 1;
  double ratio = 0.05;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string option = argv[i];
    if (option == "--subdivide") subdivide = std::atoi(argv[i + 1]);
    else if (option == "--ratio") ratio = std::atof(argv[i + 1]);
    else if (option == "--rounds") rounds = std::atoi(argv[i + 1]);
    else {
      std::cerr << "python-parity: unknown option " << option << "\n";
      return 4;
    }
  }
  try {
    ice::TriangleMesh mesh = ice::loop_subdivide(ice::load_mesh(path), subdivide);
    // The same right-hand side as the Python side: sin(3x) + y.
    const Eigen::VectorXd f = (3 * mesh.V.col(0)).array().sin().matrix() + mesh.V.col(1);
    for (int round = 0; round < rounds; ++round) {
      auto start = std::chrono::steady_clock::now();
      ice::CoarseSpaceOptions options;
      options.coarsen.target_ratio = ratio;
      options.keep_method_state = true;  // ice.coarsen keeps the map by default
      ice::CoarseSpace coarse = ice::build_coarse_space(mesh, options);
      const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(coarse);
      coarse.triangulation.reset();
      const ice::Positions positions = ice::coarse_vertex_positions(mesh, coarse);
      const double coarsen = seconds_since(start);

      start = std::chrono::steady_clock::now();
      const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
      const fem::CoarseProxy proxy(fine, coarse.mesh, coarse.P, {fem::CoarseOperatorKind::galerkin, fem::MassKind::lumped});
      const double proxy_seconds = seconds_since(start);

      start = std::chrono::steady_clock::now();
      const fem::ProxyPoissonSolver poisson(proxy);
      const double poisson_setup = seconds_since(start);
      Eigen::VectorXd u;
      const double poisson_solve = median_seconds([&] { u = poisson.solve(f); });

      start = std::chrono::steady_clock::now();
      const fem::ProxyGeodesicSolver geodesic(proxy);
      const double geodesic_setup = seconds_since(start);
      Eigen::VectorXd distance;
      const double geodesic_solve = median_seconds([&] { distance = geodesic.distance({0}); });

      std::cout.precision(9);
      std::cout << "{\"vertices\": " << mesh.V.rows() << ", \"coarse_vertices\": " << coarse.mesh.num_vertices()
                << ", \"coarsen\": " << coarsen << ", \"proxy\": " << proxy_seconds
                << ", \"poisson_setup\": " << poisson_setup << ", \"poisson_solve\": " << poisson_solve
                << ", \"geodesic_setup\": " << geodesic_setup << ", \"geodesic_solve\": " << geodesic_solve
                << ", \"check\": " << u.norm() + distance.norm() + static_cast<double>(map.size() + positions.rows())
                << "}" << std::endl;
    }
  } catch (const std::exception& e) {
    std::cerr << "python-parity: " << e.what() << "\n";
    return 5;
  }
  return 0;
}
