#include "ice/prolongation.h"

#include "run_tasks.h"

#include <array>
#include <cstdint>
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
  // Each row's (at most three) entries, repeated corners summed in corner order, on several threads
  // for large meshes; then the rows assembled (row-major) and transposed into P's column-major
  // storage, which lists each column's rows in increasing order, as setFromTriplets did.
  std::vector<std::array<Index, 3>> row_columns(static_cast<std::size_t>(rows));
  std::vector<std::array<double, 3>> row_values(static_cast<std::size_t>(rows));
  std::vector<std::uint8_t> row_size(static_cast<std::size_t>(rows), 0);
  detail::run_ranges(detail::threads_for(static_cast<std::size_t>(rows), 100000), rows, [&](Index begin, Index end) {
    for (Index p = begin; p < end; ++p) {
      const SurfacePoint s = T.location(p);
      const auto row = static_cast<std::size_t>(row_of.empty() ? p : row_of[static_cast<std::size_t>(p)]);
      std::uint8_t size = 0;
      const auto add = [&](Index c, double value) {
        for (std::uint8_t i = 0; i < size; ++i)
          if (row_columns[row][i] == c) {
            row_values[row][i] += value;
            return;
          }
        row_columns[row][size] = c;
        row_values[row][size++] = value;
      };
      if (s.is_vertex()) {
        add(column(p), 1.0);
      } else {
        Index h = T.halfedge(s.face);
        for (int k = 0; k < 3; ++k, h = T.next(h))
          if (s.bary[k] != 0.0) add(column(T.tail(h)), s.bary[k]);
      }
      row_size[row] = size;
    }
  });
  std::vector<int> outer(static_cast<std::size_t>(rows) + 1, 0);
  for (Index r = 0; r < rows; ++r) outer[static_cast<std::size_t>(r) + 1] = outer[static_cast<std::size_t>(r)] + row_size[static_cast<std::size_t>(r)];
  std::vector<int> inner(static_cast<std::size_t>(outer.back()));
  std::vector<double> values(inner.size());
  for (Index r = 0; r < rows; ++r) {
    const auto row = static_cast<std::size_t>(r);
    for (std::uint8_t i = 0; i < row_size[row]; ++i) {
      inner[static_cast<std::size_t>(outer[row]) + i] = row_columns[row][i];
      values[static_cast<std::size_t>(outer[row]) + i] = row_values[row][i];
    }
  }
  const Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor, int>> by_row(rows, cols, outer.back(), outer.data(),
                                                                                   inner.data(), values.data());
  Eigen::SparseMatrix<double> P = by_row;  // the transpose into column-major storage
  return P;
}

}  // namespace ice
