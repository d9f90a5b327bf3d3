#include "ice/prolongation.h"

#include "run_tasks.h"

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
  // Each row's (at most three) entries in three slots, repeated corners summed in corner order, on
  // several threads for large meshes; the slots seen as a row-major matrix (uncompressed: a row's
  // count of used slots) and transposed into P's column-major storage, which lists each column's
  // rows in increasing order, as setFromTriplets did.
  std::vector<int> slot_start(static_cast<std::size_t>(rows) + 1), columns(3 * static_cast<std::size_t>(rows)),
      used(static_cast<std::size_t>(rows), 0);
  std::vector<double> values(columns.size());
  for (std::size_t r = 0; r < slot_start.size(); ++r) slot_start[r] = static_cast<int>(3 * r);
  detail::run_ranges(detail::threads_for(static_cast<std::size_t>(rows), 100000), rows, [&](Index begin, Index end) {
    for (Index p = begin; p < end; ++p) {
      const SurfacePoint s = T.location(p);
      const auto row = static_cast<std::size_t>(row_of.empty() ? p : row_of[static_cast<std::size_t>(p)]);
      int* const row_columns = &columns[3 * row];
      double* const row_values = &values[3 * row];
      int& size = used[row];
      const auto add = [&](Index c, double value) {
        for (int i = 0; i < size; ++i)
          if (row_columns[i] == c) {
            row_values[i] += value;
            return;
          }
        row_columns[size] = c;
        row_values[size++] = value;
      };
      if (s.is_vertex()) {
        add(column(p), 1.0);
      } else {
        Index h = T.halfedge(s.face);
        for (int k = 0; k < 3; ++k, h = T.next(h))
          if (s.bary[k] != 0.0) add(column(T.tail(h)), s.bary[k]);
      }
    }
  });
  const Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor, int>> by_row(
      rows, cols, static_cast<Eigen::Index>(columns.size()), slot_start.data(), columns.data(), values.data(), used.data());
  Eigen::SparseMatrix<double> P = by_row;  // the transpose into column-major storage
  return P;
}

}  // namespace ice
