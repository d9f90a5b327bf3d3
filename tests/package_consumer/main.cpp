// Uses one entry point of each installed library: if this links and runs, the package config, the
// exported targets and their transitive dependencies (Eigen, OpenMesh, CHOLMOD, nlohmann-json) work.
#include <fem/blas_info.h>
#include <ice/mesh.h>
#include <ice/mesh_generators.h>
#include <ice/proxy/geodesics.h>

#include <cmath>
#include <cstdio>

int main() {
  ice::Positions V(3, 3);
  V << 0, 0, 0,  //
      3, 0, 0,   //
      3, 4, 0;
  ice::Faces F(1, 3);
  F << 0, 1, 2;
  const ice::FaceLengths L = ice::face_lengths_from_positions(V, F);
  const double expected[3] = {3.0, 4.0, 5.0};
  for (int k = 0; k < 3; ++k) {
    if (std::abs(L(0, k) - expected[k]) > 1e-12) {
      std::fprintf(stderr, "face_lengths_from_positions: edge %d is %g, expected %g\n", k, L(0, k), expected[k]);
      return 1;
    }
  }
  // The recipe floor in one call: geodesic distances on a sphere through a 5 % coarse proxy.
  const ice::TriangleMesh sphere = ice::make_icosphere(3);
  const Eigen::VectorXd d = ice::proxy::geodesic_distance(sphere, {0});
  if (d(0) != 0 || !(d.maxCoeff() > 2.5 && d.maxCoeff() < 3.5)) {
    std::fprintf(stderr, "ice::proxy::geodesic_distance: %g at the source, %g at most (expected 0 and near pi)\n", d(0),
                 d.maxCoeff());
    return 1;
  }
  const std::string blas = fem::blas_library();
  std::printf("ICE package consumer OK: face lengths 3 4 5, geodesics on a sphere; BLAS %s%s\n",
              blas.empty() ? "(none loaded)" : blas.c_str(), fem::blas_is_openblas() ? " (OpenBLAS)" : "");
  return 0;
}
