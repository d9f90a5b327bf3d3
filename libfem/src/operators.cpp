#include "fem/operators.h"

#include "parallel_kernels.h"
#include "sparse_columns.h"

#include <algorithm>
#include <optional>
#include <utility>
#include <stdexcept>
#include <vector>

namespace fem {
namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

}  // namespace

Eigen::Index checked_vertex_count(const ice::IntrinsicMesh& mesh) {
  const Faces& F = mesh.F;
  if (F.cols() != 3 || mesh.L.cols() != 3 || F.rows() != mesh.L.rows())
    throw std::invalid_argument("fem: F and L must both be m×3 with the same m");
  if (F.size() > 0 && F.minCoeff() < 0) throw std::invalid_argument("fem: negative vertex index in F");
  const Eigen::Index needed = F.size() == 0 ? 0 : Eigen::Index(F.maxCoeff()) + 1;
  if (mesh.vertex_count < needed) throw std::invalid_argument("fem: vertex_count smaller than max index + 1");
  return mesh.vertex_count;
}

namespace {

SparseMatrix from_triplets(Eigen::Index rows, Eigen::Index cols, const Triplets& triplets) {
  SparseMatrix matrix(rows, cols);
  matrix.setFromTriplets(triplets.begin(), triplets.end());  // sums duplicates
  return matrix;
}

// The triplet assembly below, for faces whose corners are three distinct vertices (every input
// mesh; coarse Δ-complexes may repeat a vertex), without the triplets: each face's off-diagonal
// entries are scattered straight into their columns in face order (a counting sort; threads take
// ranges of faces and each writes its own slots of every column), then each column is sorted by row
// and its duplicates summed. Duplicates are summed in face order and each diagonal is the sum of
// its column's weights in face order, as setFromTriplets sums them: the same matrix to the last
// bit, with a quarter of the memory traffic, on all threads.
SparseMatrix cotan_laplacian_distinct(const Faces& F, const Eigen::MatrixXd& cot, Eigen::Index n) {
  const Eigen::Index m = F.rows();
  const int parts = detail::active_threads(m, detail::default_threads());
  const auto first_face = [&](int part) { return static_cast<Eigen::Index>(static_cast<long long>(m) * part / parts); };
  // slots[p][v]: entries that faces of part p put into column v (two per incident face), then
  // where part p's first such entry goes.
  std::vector<std::vector<Index>> slots(static_cast<std::size_t>(parts), std::vector<Index>(static_cast<std::size_t>(n), 0));
#pragma omp parallel for schedule(static, 1) num_threads(parts)
  for (int p = 0; p < parts; ++p) {
    std::vector<Index>& count = slots[static_cast<std::size_t>(p)];
    for (Eigen::Index f = first_face(p); f < first_face(p + 1); ++f)
      for (int k = 0; k < 3; ++k) count[static_cast<std::size_t>(F(f, k))] += 2;
  }
  std::vector<Index> start(static_cast<std::size_t>(n) + 1, 0);
  for (Eigen::Index v = 0; v < n; ++v) {
    Index at = start[static_cast<std::size_t>(v)];
    for (std::vector<Index>& count : slots) {
      const Index c = count[static_cast<std::size_t>(v)];
      count[static_cast<std::size_t>(v)] = at;
      at += c;
    }
    start[static_cast<std::size_t>(v) + 1] = at;
  }
  const std::size_t scattered = static_cast<std::size_t>(start.back());
  std::vector<Index> rows(scattered);
  std::vector<double> values(scattered);
#pragma omp parallel for schedule(static, 1) num_threads(parts)
  for (int p = 0; p < parts; ++p) {
    std::vector<Index>& next = slots[static_cast<std::size_t>(p)];
    for (Eigen::Index f = first_face(p); f < first_face(p + 1); ++f)
      for (int k = 0; k < 3; ++k) {
        const Index i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3);
        const double w = 0.5 * cot(f, k);
        const Index in_j = next[static_cast<std::size_t>(j)]++, in_i = next[static_cast<std::size_t>(i)]++;
        rows[static_cast<std::size_t>(in_j)] = i, values[static_cast<std::size_t>(in_j)] = -w;
        rows[static_cast<std::size_t>(in_i)] = j, values[static_cast<std::size_t>(in_i)] = -w;
      }
  }
  slots.clear();
  slots.shrink_to_fit();
  // Per column: the diagonal (before sorting: in face order), a stable sort by row, the distinct rows.
  std::vector<double> diagonal(static_cast<std::size_t>(n));
  std::vector<Index> kept(static_cast<std::size_t>(n) + 1, 0);
  const int column_threads = detail::active_threads(n, detail::default_threads());
#pragma omp parallel num_threads(column_threads)
  {
    std::vector<std::pair<Index, double>> column;
#pragma omp for schedule(static, 4096)
    for (Eigen::Index v = 0; v < n; ++v) {
      const std::size_t begin = static_cast<std::size_t>(start[static_cast<std::size_t>(v)]);
      const std::size_t end = static_cast<std::size_t>(start[static_cast<std::size_t>(v) + 1]);
      if (begin == end) continue;  // no face: no diagonal either
      double sum = 0;
      for (std::size_t e = begin; e < end; ++e) sum += -values[e];
      diagonal[static_cast<std::size_t>(v)] = sum;
      column.clear();
      for (std::size_t e = begin; e < end; ++e) column.emplace_back(rows[e], values[e]);
      const auto by_row = [](const auto& a, const auto& b) { return a.first < b.first; };
      if (column.size() > 32) {
        std::stable_sort(column.begin(), column.end(), by_row);
      } else {  // insertion sort (stable): a column holds about twelve entries
        for (std::size_t a = 1; a < column.size(); ++a)
          for (std::size_t b = a; b > 0 && by_row(column[b], column[b - 1]); --b) std::swap(column[b], column[b - 1]);
      }
      std::size_t out = begin;
      for (std::size_t e = 0; e < column.size(); ++e) {
        if (e > 0 && column[e].first == column[e - 1].first) {
          values[out - 1] += column[e].second;
          continue;
        }
        rows[out] = column[e].first, values[out] = column[e].second;
        ++out;
      }
      kept[static_cast<std::size_t>(v) + 1] = static_cast<Index>(out - begin) + 1;  // and the diagonal
    }
  }
  for (Eigen::Index v = 0; v < n; ++v) kept[static_cast<std::size_t>(v) + 1] += kept[static_cast<std::size_t>(v)];
  SparseMatrix laplacian(n, n);
  laplacian.resizeNonZeros(kept.back());
  std::copy(kept.begin(), kept.end(), laplacian.outerIndexPtr());
  Index* inner = laplacian.innerIndexPtr();
  double* value = laplacian.valuePtr();
#pragma omp parallel for schedule(static, 4096) num_threads(column_threads)
  for (Eigen::Index v = 0; v < n; ++v) {
    Index at = kept[static_cast<std::size_t>(v)];
    if (at == kept[static_cast<std::size_t>(v) + 1]) continue;
    const Index begin = start[static_cast<std::size_t>(v)];
    const Index end = begin + (kept[static_cast<std::size_t>(v) + 1] - at) - 1;
    bool diagonal_written = false;
    for (Index e = begin; e < end; ++e) {
      if (!diagonal_written && rows[static_cast<std::size_t>(e)] > v) {
        inner[at] = static_cast<Index>(v), value[at++] = diagonal[static_cast<std::size_t>(v)];
        diagonal_written = true;
      }
      inner[at] = rows[static_cast<std::size_t>(e)], value[at++] = values[static_cast<std::size_t>(e)];
    }
    if (!diagonal_written) inner[at] = static_cast<Index>(v), value[at] = diagonal[static_cast<std::size_t>(v)];
  }
  return laplacian;
}

}  // namespace

SparseMatrix cotan_laplacian(const ice::IntrinsicMesh& mesh) {
  const Eigen::Index n = checked_vertex_count(mesh);
  const Faces& F = mesh.F;
  const FaceLengths& L = mesh.L;
  const Eigen::MatrixXd cot = corner_cotangents(L);
  bool distinct = true;
  for (Eigen::Index f = 0; f < F.rows() && distinct; ++f)
    distinct = F(f, 0) != F(f, 1) && F(f, 1) != F(f, 2) && F(f, 2) != F(f, 0);
  if (distinct) return cotan_laplacian_distinct(F, cot, n);
  Triplets triplets;
  triplets.reserve(static_cast<std::size_t>(12 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      // Corner k is opposite edge (k+1)%3, which joins corners k+1 and k+2.
      const int i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3);
      const double w = 0.5 * cot(f, k);
      triplets.emplace_back(i, j, -w);
      triplets.emplace_back(j, i, -w);
      triplets.emplace_back(i, i, w);
      triplets.emplace_back(j, j, w);
    }
  return from_triplets(n, n, triplets);
}

Eigen::VectorXd lumped_vertex_areas(const ice::IntrinsicMesh& mesh) {
  const Eigen::Index n = checked_vertex_count(mesh);
  const Faces& F = mesh.F;
  const FaceLengths& L = mesh.L;
  const Eigen::VectorXd areas = face_areas(L);
  Eigen::VectorXd vertex_areas = Eigen::VectorXd::Zero(n);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) vertex_areas(F(f, k)) += areas(f) / 3.0;
  return vertex_areas;
}

SparseMatrix mass_matrix(const ice::IntrinsicMesh& mesh, MassKind kind) {
  const Eigen::Index n = checked_vertex_count(mesh);
  const Faces& F = mesh.F;
  const FaceLengths& L = mesh.L;
  if (kind == MassKind::lumped) {
    const Eigen::VectorXd vertex_areas = lumped_vertex_areas(mesh);
    SparseMatrix mass(n, n);
    mass.reserve(Eigen::VectorXi::Ones(n));
    for (Eigen::Index v = 0; v < n; ++v) mass.insert(v, v) = vertex_areas(v);
    mass.makeCompressed();
    return mass;
  }
  const Eigen::VectorXd areas = face_areas(L);
  Triplets triplets;
  triplets.reserve(static_cast<std::size_t>(9 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) triplets.emplace_back(F(f, a), F(f, b), areas(f) / (a == b ? 6.0 : 12.0));
  return from_triplets(n, n, triplets);
}

SparseMatrix gradient(const ice::IntrinsicMesh& mesh) {
  const Eigen::Index n = checked_vertex_count(mesh);
  const Faces& F = mesh.F;
  const FaceLengths& L = mesh.L;
  validate_lengths(L);
  Triplets triplets;
  triplets.reserve(static_cast<std::size_t>(6 * F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Matrix<double, 3, 2> p = layout_triangle(L(f, 0), L(f, 1), L(f, 2));
    const double twice_area = L(f, 0) * p(2, 1);  // base l0 times height of corner 2
    if (!(twice_area > 0)) throw InvalidTriangle(f, "zero area: gradient undefined");
    for (int k = 0; k < 3; ++k) {
      // ∇φ_k is the opposite edge (counter-clockwise) rotated by +90°, divided by 2A.
      const Eigen::RowVector2d edge = p.row((k + 2) % 3) - p.row((k + 1) % 3);
      triplets.emplace_back(2 * f, F(f, k), -edge(1) / twice_area);
      triplets.emplace_back(2 * f + 1, F(f, k), edge(0) / twice_area);
    }
  }
  return from_triplets(2 * F.rows(), n, triplets);
}

SparseMatrix divergence(const ice::IntrinsicMesh& mesh) {
  const SparseMatrix G = gradient(mesh);
  const Eigen::VectorXd areas = face_areas(mesh.L);
  Eigen::VectorXd weights(2 * areas.size());
  for (Eigen::Index f = 0; f < areas.size(); ++f) weights(2 * f) = weights(2 * f + 1) = areas(f);
  return SparseMatrix(-(G.transpose() * weights.asDiagonal()));
}

namespace {

// The lower triangle of a Galerkin product, column by column, for a range of coarse columns.
struct LowerColumns {
  std::vector<Index> count;  // entries per column of the range
  std::vector<Index> rows;
  std::vector<double> values;
};

// A dense accumulator over the coarse unknowns with the list of those touched (Gustavson).
struct Accumulator {
  std::vector<double> value;
  std::vector<char> is_touched;
  std::vector<Index> touched;
  explicit Accumulator(Eigen::Index n) : value(static_cast<std::size_t>(n), 0.0), is_touched(static_cast<std::size_t>(n), 0) {}
  void add(Index I, double v) {
    if (!is_touched[static_cast<std::size_t>(I)]) {
      is_touched[static_cast<std::size_t>(I)] = 1;
      touched.push_back(I);
    }
    value[static_cast<std::size_t>(I)] += v;
  }
  // Appends the column (rows in increasing order) and clears.
  void flush(LowerColumns& out) {
    std::sort(touched.begin(), touched.end());
    for (Index I : touched) {
      out.rows.push_back(I);
      out.values.push_back(value[static_cast<std::size_t>(I)]);
      value[static_cast<std::size_t>(I)] = 0;
      is_touched[static_cast<std::size_t>(I)] = 0;
    }
    out.count.push_back(static_cast<Index>(touched.size()));
    touched.clear();
  }
};

// Both triangles from the lower ones of consecutive column ranges: column c holds the mirrored
// entries (rows < c, in increasing order as the columns are visited in order) followed by its own
// lower-triangle entries (rows ≥ c).
SparseMatrix mirror_lower(const std::vector<LowerColumns>& parts, Eigen::Index nc) {
  std::vector<Index> mirrored(static_cast<std::size_t>(nc), 0), own(static_cast<std::size_t>(nc), 0);
  {
    Eigen::Index J = 0;
    for (const LowerColumns& pt : parts) {
      std::size_t k = 0;
      for (Index c : pt.count) {
        own[static_cast<std::size_t>(J)] = c;
        for (Index e = 0; e < c; ++e, ++k)
          if (pt.rows[k] != J) ++mirrored[static_cast<std::size_t>(pt.rows[k])];
        ++J;
      }
    }
  }
  SparseMatrix result(nc, nc);
  Eigen::Index total = 0;
  for (Eigen::Index c = 0; c < nc; ++c) total += mirrored[static_cast<std::size_t>(c)] + own[static_cast<std::size_t>(c)];
  result.resizeNonZeros(total);
  auto* start = result.outerIndexPtr();
  start[0] = 0;
  for (Eigen::Index c = 0; c < nc; ++c)
    start[c + 1] = start[c] + mirrored[static_cast<std::size_t>(c)] + own[static_cast<std::size_t>(c)];
  std::vector<Index> mirror_fill(start, start + nc);
  Eigen::Index J = 0;
  for (const LowerColumns& pt : parts) {
    std::size_t k = 0;
    for (Index c : pt.count) {
      Index own_fill = start[J] + mirrored[static_cast<std::size_t>(J)];
      for (Index e = 0; e < c; ++e, ++k) {
        const Index I = pt.rows[k];
        const double value = pt.values[k];
        result.innerIndexPtr()[own_fill] = I;
        result.valuePtr()[own_fill++] = value;
        if (I != J) {
          const Index at = mirror_fill[static_cast<std::size_t>(I)]++;
          result.innerIndexPtr()[at] = static_cast<Index>(J);
          result.valuePtr()[at] = value;
        }
      }
      ++J;
    }
  }
  return result;
}

// Pᵀ A P, and Pᵀ D P for a diagonal D when `diagonal` is given, in one pass over P and A.
// Column J of Pᵀ A P is Σ_j P_jJ Σ_i A_ij (row i of P): one pass per coarse column with a dense
// accumulator, for the rows I ≥ J only; the upper triangle is the mirror image, so the result is
// exactly symmetric. Column J of Pᵀ D P is Σ_j P_jJ d_j (row j of P), summed in the same order as
// Pᵀ A P's with A = D: the same bits as two separate products. The columns split among threads.
std::pair<SparseMatrix, SparseMatrix> galerkin_products(const SparseMatrix& P, const SparseMatrix& A,
                                                        const SparseMatrix* diagonal, int threads) {
  if (A.rows() != A.cols() || A.cols() != P.rows())
    throw std::invalid_argument("galerkin: need square A with as many rows as P");
  SparseMatrix P_copy, A_copy;
  const SparseMatrix& Pc = detail::compressed(P, P_copy);
  const SparseMatrix& Ac = detail::compressed(A, A_copy);
  std::vector<double> d;
  std::vector<char> stored;  // d_j is a stored entry (an absent one adds nothing, as in galerkin(P, D))
  if (diagonal) {
    if (diagonal->rows() != P.rows() || diagonal->cols() != P.rows())
      throw std::invalid_argument("galerkin: the diagonal operator must have as many rows as P");
    d.assign(static_cast<std::size_t>(P.rows()), 0.0);
    stored.assign(static_cast<std::size_t>(P.rows()), 0);
    for (Eigen::Index j = 0; j < diagonal->outerSize(); ++j)
      for (SparseMatrix::InnerIterator it(*diagonal, j); it; ++it) {
        if (it.row() != j || stored[static_cast<std::size_t>(j)])
          throw std::invalid_argument("galerkin: the second operator is not a compressed diagonal matrix");
        d[static_cast<std::size_t>(j)] = it.value();
        stored[static_cast<std::size_t>(j)] = 1;
      }
  }
  const detail::RowMajorSparse P_rows = Pc;
  const Eigen::Index nc = Pc.cols();
  const int parts = detail::active_threads(Pc.rows(), threads > 0 ? threads : detail::default_threads());
  std::vector<LowerColumns> lower(static_cast<std::size_t>(parts)), lower_d(diagonal ? static_cast<std::size_t>(parts) : 0);
  const auto* p_start = Pc.outerIndexPtr();
  const auto* p_row = Pc.innerIndexPtr();
  const double* p_value = Pc.valuePtr();
  const auto* a_start = Ac.outerIndexPtr();
  const auto* a_row = Ac.innerIndexPtr();
  const double* a_value = Ac.valuePtr();
  const auto* r_start = P_rows.outerIndexPtr();
  const auto* r_column = P_rows.innerIndexPtr();
  const double* r_value = P_rows.valuePtr();
#pragma omp parallel for schedule(static, 1) num_threads(parts)
  for (int t = 0; t < parts; ++t) {
    const Eigen::Index first = nc * t / parts, last = nc * (t + 1) / parts;
    Accumulator a(nc);
    std::optional<Accumulator> m;
    if (diagonal) m.emplace(nc);
    for (Eigen::Index J = first; J < last; ++J) {
      for (auto p = p_start[J]; p < p_start[J + 1]; ++p) {
        const Index j = p_row[p];
        const double w = p_value[p];
        for (auto q = a_start[j]; q < a_start[j + 1]; ++q) {
          const Index i = a_row[q];
          const double wa = w * a_value[q];
          for (auto r = r_start[i]; r < r_start[i + 1]; ++r)
            if (r_column[r] >= J) a.add(r_column[r], wa * r_value[r]);
        }
        if (m && stored[static_cast<std::size_t>(j)]) {
          const double wd = w * d[static_cast<std::size_t>(j)];
          for (auto r = r_start[j]; r < r_start[j + 1]; ++r)
            if (r_column[r] >= J) m->add(r_column[r], wd * r_value[r]);
        }
      }
      a.flush(lower[static_cast<std::size_t>(t)]);
      if (m) m->flush(lower_d[static_cast<std::size_t>(t)]);
    }
  }
  std::pair<SparseMatrix, SparseMatrix> result;
  result.first = mirror_lower(lower, nc);
  detail::stabilise_weak_coarse_unknowns(Pc, result.first);
  if (diagonal) {
    result.second = mirror_lower(lower_d, nc);
    detail::stabilise_weak_coarse_unknowns(Pc, result.second);
  }
  return result;
}

}  // namespace

SparseMatrix galerkin(const SparseMatrix& P, const SparseMatrix& A, int threads) {
  return galerkin_products(P, A, nullptr, threads).first;
}

std::pair<SparseMatrix, SparseMatrix> galerkin(const SparseMatrix& P, const SparseMatrix& A, const SparseMatrix& D,
                                               int threads) {
  return galerkin_products(P, A, &D, threads);
}

}  // namespace fem
