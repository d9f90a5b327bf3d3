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
  // Columns of inserted vertices (refinement): the coarse vertices without an input vertex, taken in
  // order, are the live inserted slots in slot order (compact() lists them so, after the input ones).
  std::vector<Index> inserted_column(static_cast<std::size_t>(T.num_vertex_slots() - rows), kInvalid);
  {
    std::size_t next = 0;
    for (Index c = 0; c < cols; ++c) {
      if (coarse.to_input[static_cast<std::size_t>(c)] != kInvalid) continue;
      while (next < inserted_column.size() && !T.vertex_alive(rows + static_cast<Index>(next))) ++next;
      if (next == inserted_column.size()) throw std::invalid_argument("prolongation: more inserted coarse vertices than T has");
      inserted_column[next++] = c;
    }
  }
  const auto column = [&](Index slot) {
    return slot < rows ? coarse.from_input[static_cast<std::size_t>(slot)] : inserted_column[static_cast<std::size_t>(slot - rows)];
  };
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(3 * static_cast<std::size_t>(rows));
  for (Index p = 0; p < rows; ++p) {
    const SurfacePoint s = T.location(p);
    const Index row = row_of.empty() ? p : row_of[static_cast<std::size_t>(p)];
    if (s.is_vertex()) {
      entries.emplace_back(row, column(p), 1.0);
      continue;
    }
    Index h = T.halfedge(s.face);
    for (int k = 0; k < 3; ++k, h = T.next(h))
      if (s.bary[k] != 0.0) entries.emplace_back(row, column(T.tail(h)), s.bary[k]);
  }
  Eigen::SparseMatrix<double> P(rows, cols);
  P.setFromTriplets(entries.begin(), entries.end());  // sums the entries of repeated corners
  return P;
}

}  // namespace ice
