#include "ice/prolongation.h"

#include <stdexcept>
#include <vector>

namespace ice {

Eigen::SparseMatrix<double> prolongation(const IntrinsicTriangulation& T, const CompactMesh& coarse,
                                         const std::vector<Index>& row_of) {
  const Index rows = T.num_input_vertices();
  const Index cols = static_cast<Index>(coarse.to_input.size());
  if (!row_of.empty() && row_of.size() != static_cast<std::size_t>(rows))
    throw std::invalid_argument("prolongation: row_of must have one entry per input vertex");
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(3 * static_cast<std::size_t>(rows));
  for (Index p = 0; p < rows; ++p) {
    const SurfacePoint s = T.location(p);
    const Index row = row_of.empty() ? p : row_of[static_cast<std::size_t>(p)];
    if (s.is_vertex()) {
      entries.emplace_back(row, coarse.from_input[p], 1.0);
      continue;
    }
    Index h = T.halfedge(s.face);
    for (int k = 0; k < 3; ++k, h = T.next(h))
      if (s.bary[k] != 0.0) entries.emplace_back(row, coarse.from_input[T.tail(h)], s.bary[k]);
  }
  Eigen::SparseMatrix<double> P(rows, cols);
  P.setFromTriplets(entries.begin(), entries.end());  // sums the entries of repeated corners
  return P;
}

}  // namespace ice
