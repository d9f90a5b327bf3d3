// Uses one trivial entry point of each installed library: if this links and runs, the package
// config, the exported targets and their transitive dependencies (Eigen, OpenMesh, CHOLMOD) work.
#include <fem/blas_info.h>
#include <ice/mesh.h>

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
  const std::string blas = fem::blas_library();
  std::printf("ICE package consumer OK: face lengths 3 4 5; BLAS %s%s\n",
              blas.empty() ? "(none loaded)" : blas.c_str(), fem::blas_is_openblas() ? " (OpenBLAS)" : "");
  return 0;
}
