#include "locality_numbering.h"

#include "run_tasks.h"

#include <algorithm>
#include <cstdint>
#include <utility>

namespace ice::detail {
namespace {

// The low 21 bits of x spread out to every third bit (bit i to bit 3i).
std::uint64_t spread_bits(std::uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

// Meshes of at least this many faces get their lengths on several threads.
constexpr std::size_t kParallelFaces = 200000;

}  // namespace

std::vector<Index> morton_order(const Positions& V) {
  const Index n = static_cast<Index>(V.rows());
  std::vector<Index> order(static_cast<std::size_t>(n));
  if (n == 0) return order;
  constexpr double kCells = (1 << 21) - 1;
  const Eigen::RowVector3d low = V.colwise().minCoeff(), high = V.colwise().maxCoeff();
  const double extent = (high - low).maxCoeff();
  const double scale = extent > 0 ? kCells / extent : 0;
  std::vector<std::pair<std::uint64_t, Index>> keys(static_cast<std::size_t>(n));
  for (Index v = 0; v < n; ++v) {
    std::uint64_t key = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double cell = (V(v, axis) - low[axis]) * scale;
      // Written so that a NaN (never in a validated mesh) lands in cell 0 instead of overflowing.
      const double clamped = cell >= 0 ? std::min(cell, kCells) : 0.0;
      key |= spread_bits(static_cast<std::uint64_t>(clamped)) << axis;
    }
    keys[static_cast<std::size_t>(v)] = {key, v};
  }
  std::sort(keys.begin(), keys.end());
  for (Index i = 0; i < n; ++i) order[static_cast<std::size_t>(i)] = keys[static_cast<std::size_t>(i)].second;
  return order;
}

LocalityNumbering locality_numbering(const TriangleMesh& mesh) {
  LocalityNumbering out;
  const Index n = static_cast<Index>(mesh.V.rows());
  const Eigen::Index m = mesh.F.rows();
  if (mesh.V.cols() != 3 || mesh.F.cols() != 3) return out;
  std::vector<std::uint8_t> used(static_cast<std::size_t>(n), 0);
  for (Eigen::Index f = 0; f < m; ++f)
    for (int k = 0; k < 3; ++k) {
      const Index v = mesh.F(f, k);
      if (v < 0 || v >= n) return out;
      used[static_cast<std::size_t>(v)] = 1;
    }
  if (std::find(used.begin(), used.end(), 0) != used.end()) return out;
  out.order = morton_order(mesh.V);
  std::vector<Index> new_index(static_cast<std::size_t>(n));
  for (Index i = 0; i < n; ++i) new_index[static_cast<std::size_t>(out.order[static_cast<std::size_t>(i)])] = i;
  RenumberedFaces faces = renumber_faces(mesh.F, new_index);
  out.F = std::move(faces.F);
  out.face_order = std::move(faces.face_order);
  return out;
}

RenumberedFaces renumber_faces(const Faces& F, const std::vector<Index>& new_index) {
  const Eigen::Index m = F.rows();
  const auto n = static_cast<Index>(new_index.size());
  // Faces by their smallest new vertex: a counting sort, stable (ties keep the input's order).
  std::vector<Index> first_vertex(static_cast<std::size_t>(m));
  std::vector<Index> start(static_cast<std::size_t>(n) + 1, 0);
  for (Eigen::Index f = 0; f < m; ++f) {
    Index smallest = n;
    for (int k = 0; k < 3; ++k) smallest = std::min(smallest, new_index[static_cast<std::size_t>(F(f, k))]);
    first_vertex[static_cast<std::size_t>(f)] = smallest;
    ++start[static_cast<std::size_t>(smallest) + 1];
  }
  for (Index v = 0; v < n; ++v) start[static_cast<std::size_t>(v) + 1] += start[static_cast<std::size_t>(v)];
  RenumberedFaces out;
  out.F.resize(m, 3);
  out.face_order.resize(static_cast<std::size_t>(m));
  for (Eigen::Index f = 0; f < m; ++f) {
    const Index row = start[static_cast<std::size_t>(first_vertex[static_cast<std::size_t>(f)])]++;
    out.face_order[static_cast<std::size_t>(row)] = static_cast<Index>(f);
    for (int k = 0; k < 3; ++k) out.F(row, k) = new_index[static_cast<std::size_t>(F(f, k))];
  }
  return out;
}

FaceLengths LocalityNumbering::face_lengths(const Positions& V) const {
  FaceLengths lengths(F.rows(), 3);
  run_ranges(threads_for(static_cast<std::size_t>(F.rows()), kParallelFaces), F.rows(), [&](Eigen::Index begin, Eigen::Index end) {
    for (Eigen::Index f = begin; f < end; ++f)
      for (int k = 0; k < 3; ++k)
        lengths(f, k) = edge_length(V, order[static_cast<std::size_t>(F(f, k))], order[static_cast<std::size_t>(F(f, (k + 1) % 3))]);
  });
  return lengths;
}

}  // namespace ice::detail
