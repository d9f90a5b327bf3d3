#include "ice/prolongation.h"

#include <vector>

namespace ice {

Eigen::SparseMatrix<double> prolongation(const IntrinsicTriangulation& T, const CompactMesh& coarse) {
  const Index rows = T.num_input_vertices();
  const Index cols = static_cast<Index>(coarse.to_input.size());
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(3 * static_cast<std::size_t>(rows));
  for (Index p = 0; p < rows; ++p) {
    const SurfacePoint s = T.location(p);
    if (s.is_vertex()) {
      entries.emplace_back(p, coarse.from_input[p], 1.0);
      continue;
    }
    Index h = T.halfedge(s.face);
    for (int k = 0; k < 3; ++k, h = T.next(h))
      if (s.bary[k] != 0.0) entries.emplace_back(p, coarse.from_input[T.tail(h)], s.bary[k]);
  }
  Eigen::SparseMatrix<double> P(rows, cols);
  P.setFromTriplets(entries.begin(), entries.end());  // sums the entries of repeated corners
  return P;
}

}  // namespace ice
