// The recipe floor in a few calls: geodesic distances and a Poisson solve through a 5 % coarse
// proxy, with the tools' measured defaults. Usage: recipes MESH SOURCE RHS.txt (one number per
// vertex); prints the distances, then the solution, one value per line with 17 digits.
// The test suite builds it and checks it against geodesic-coarse, poisson-coarse and Python.
#include <cstdio>
#include <fstream>
#include <string>

#include <ice/mesh_io.h>
#include <ice/proxy/geodesics.h>
#include <ice/proxy/poisson.h>

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s MESH SOURCE RHS.txt\n", argv[0]);
    return 4;
  }
  const ice::TriangleMesh mesh = ice::load_mesh(argv[1]);
  Eigen::VectorXd f(mesh.V.rows());
  std::ifstream rhs(argv[3]);
  for (Eigen::Index i = 0; i < f.size(); ++i) rhs >> f(i);

  const Eigen::VectorXd d = ice::proxy::geodesic_distance(mesh, {std::stoi(argv[2])});
  const Eigen::VectorXd u = ice::proxy::solve_poisson(mesh, f);

  for (const Eigen::VectorXd* field : {&d, &u})
    for (Eigen::Index i = 0; i < field->size(); ++i) std::printf("%.17g\n", (*field)(i));
  return 0;
}
