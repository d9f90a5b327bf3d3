#include "fem/coarse_proxy.h"

#include "ice/huge_pages.h"
#include "fem/curvature_correction.h"

#include "coarse_marching.h"
#include "parallel_kernels.h"
#include "sparse_columns.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <tuple>
#include <stdexcept>
#include <utility>

#include "fem/topology.h"

namespace fem {

namespace {

// diag(row sums of mass): the lumped version of a (Galerkin) mass matrix.
SparseMatrix lumped(const SparseMatrix& mass) {
  const Eigen::VectorXd row_sums = mass * Eigen::VectorXd::Ones(mass.cols());
  SparseMatrix diagonal(mass.rows(), mass.cols());
  diagonal.reserve(Eigen::VectorXi::Constant(mass.cols(), 1));
  for (Eigen::Index i = 0; i < row_sums.size(); ++i) diagonal.insert(i, i) = row_sums(i);
  diagonal.makeCompressed();
  return diagonal;
}

// P (n_fine × n_coarse) fits the coarse faces and its rows sum to 1: what a CoarseProxy and a
// ProxyGeodesicSolver made without one both require. Throws std::invalid_argument prefixed by `who`.
template <class Matrix>
void require_prolongation(const Matrix& P, const Faces& coarse_faces, const std::string& who) {
  if (coarse_faces.size() > 0 && coarse_faces.maxCoeff() >= P.cols())
    throw std::invalid_argument(who + ": P must be n_fine × n_coarse (the coarse faces name vertices beyond it)");
  const Eigen::VectorXd row_sums = P * Eigen::VectorXd::Ones(P.cols());
  for (Eigen::Index i = 0; i < row_sums.size(); ++i)
    if (!(std::abs(row_sums(i) - 1.0) <= 1e-10))
      throw std::invalid_argument(who + ": every row of P must sum to 1 (row " + std::to_string(i) + " does not)");
}

}  // namespace

const char* to_string(ProlongationKind kind) {
  return kind == ProlongationKind::smoothed_twice ? "smoothed_twice"
         : kind == ProlongationKind::smoothed    ? "smoothed"
                                                 : "barycentric";
}

SparseMatrix smoothed_prolongation(const SparseMatrix& P, const SparseMatrix& laplacian, double omega) {
  if (laplacian.rows() != laplacian.cols() || laplacian.rows() != P.rows())
    throw std::invalid_argument("smoothed_prolongation: L must be n × n and P n × m");
  const Eigen::VectorXd diagonal = laplacian.diagonal();
  Eigen::VectorXd scale(diagonal.size());
  for (Eigen::Index i = 0; i < diagonal.size(); ++i) scale(i) = diagonal(i) != 0 ? omega / diagonal(i) : 0.0;
  // P − diag(scale)·(L P) with its exact zeros dropped, row by row on the threads: row i of L P is
  // Σ_k L_ik P_k over L's column i (L is symmetric), k increasing, which is the order in which
  // Eigen's column-by-column sparse product sums each entry. So the result is that expression's in
  // Eigen to the last bit, but each row reads only its neighbours' rows of P, with a small
  // accumulator, where a column pass reads the whole fine mesh around each coarse vertex scattered
  // over memory into a fine-sized one (memory-latency bound: docs/measurements.md, "Cold setup").
  SparseMatrix P_copy, L_copy;
  const SparseMatrix& Pc = detail::compressed(P, P_copy);
  const SparseMatrix& Lc = detail::compressed(laplacian, L_copy);
  const detail::RowMajorSparse P_rows = Pc;
  const Eigen::Index n = Pc.rows(), nc = Pc.cols();
  const int parts = detail::active_threads(n, detail::default_threads());
  const auto first_row = [&](int part) { return static_cast<Eigen::Index>(static_cast<long long>(n) * part / parts); };
  struct Rows {
    std::vector<Index> count, columns;
    std::vector<double> values;
    std::vector<Index> per_column;  // entries of each coarse column in this part, then its first slot
  };
  std::vector<Rows> part(static_cast<std::size_t>(parts));
#pragma omp parallel for schedule(static, 1) num_threads(parts)
  for (int t = 0; t < parts; ++t) {
    Rows& out = part[static_cast<std::size_t>(t)];
    out.per_column.assign(static_cast<std::size_t>(nc), 0);
    std::vector<std::pair<Index, double>> row;  // (coarse column, (L P)_iJ), in order of first touch
    for (Eigen::Index i = first_row(t); i < first_row(t + 1); ++i) {
      row.clear();
      for (auto q = Lc.outerIndexPtr()[i]; q < Lc.outerIndexPtr()[i + 1]; ++q) {
        const Index k = Lc.innerIndexPtr()[q];
        const double x = Lc.valuePtr()[q];
        for (auto r = P_rows.outerIndexPtr()[k]; r < P_rows.outerIndexPtr()[k + 1]; ++r) {
          const Index J = P_rows.innerIndexPtr()[r];
          const double term = x * P_rows.valuePtr()[r];
          auto at = std::find_if(row.begin(), row.end(), [J](const auto& e) { return e.first == J; });
          if (at == row.end())
            row.emplace_back(J, term);
          else
            at->second += term;
        }
      }
      for (auto r = P_rows.outerIndexPtr()[i]; r < P_rows.outerIndexPtr()[i + 1]; ++r) {
        const Index J = P_rows.innerIndexPtr()[r];
        if (std::none_of(row.begin(), row.end(), [J](const auto& e) { return e.first == J; })) row.emplace_back(J, 0.0);
      }
      std::sort(row.begin(), row.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      Index kept = 0;
      auto own = P_rows.outerIndexPtr()[i];  // P's row i, columns increasing: merged with `row`
      for (const auto& [J, product] : row) {
        double p = 0;
        if (own < P_rows.outerIndexPtr()[i + 1] && P_rows.innerIndexPtr()[own] == J) p = P_rows.valuePtr()[own++];
        const double value = p - scale(i) * product;
        if (value != 0) {
          out.columns.push_back(J);
          out.values.push_back(value);
          ++out.per_column[static_cast<std::size_t>(J)];
          ++kept;
        }
      }
      out.count.push_back(kept);
    }
  }
  // Column-major: each part's entries of column J go after the earlier parts' (rows increasing).
  SparseMatrix smoothed(n, nc);
  Index* start = smoothed.outerIndexPtr();
  start[0] = 0;
  for (Eigen::Index J = 0; J < nc; ++J) {
    Index at = start[J];
    for (Rows& r : part) {
      const Index c = r.per_column[static_cast<std::size_t>(J)];
      r.per_column[static_cast<std::size_t>(J)] = at;
      at += c;
    }
    start[J + 1] = at;
  }
  smoothed.resizeNonZeros(start[nc]);
  Index* inner = smoothed.innerIndexPtr();
  double* value = smoothed.valuePtr();
#pragma omp parallel for schedule(static, 1) num_threads(parts)
  for (int t = 0; t < parts; ++t) {
    Rows& r = part[static_cast<std::size_t>(t)];
    std::size_t e = 0;
    Eigen::Index i = first_row(t);
    for (const Index count : r.count) {
      for (Index c = 0; c < count; ++c, ++e) {
        const Index slot = r.per_column[static_cast<std::size_t>(r.columns[e])]++;
        inner[slot] = static_cast<Index>(i);
        value[slot] = r.values[e];
      }
      ++i;
    }
  }
  return smoothed;
}

CoarseProxy::CoarseProxy(ice::IntrinsicMesh fine, ice::IntrinsicMesh coarse, SparseMatrix P, const CoarseProxyOptions& options)
    : kind_(options.kind), mass_kind_(options.mass_kind), prolongation_kind_(options.prolongation), coarse_(std::move(coarse)) {
  const CoarseOperatorKind kind = options.kind;
  const MassKind mass_kind = options.mass_kind;
  const ProlongationKind prolongation = options.prolongation;
  coarse_.twin.clear();
  P_.swap(P);  // Eigen 3.4's SparseMatrix has no move constructor (std::move copies)
  if (is_smoothed(prolongation) && kind != CoarseOperatorKind::galerkin)
    throw std::invalid_argument("CoarseProxy: a smoothed prolongation needs Galerkin coarse operators");
  P_.makeCompressed();  // the proxy solvers gather straight from its arrays
  if (checked_vertex_count(fine) != P_.rows() || checked_vertex_count(coarse_) != P_.cols())
    throw std::invalid_argument("CoarseProxy: P must be n_fine × n_coarse (" + std::to_string(fine.vertex_count) + " × " +
                                std::to_string(coarse_.vertex_count) + "), not " + std::to_string(P_.rows()) + " × " +
                                std::to_string(P_.cols()));
  require_prolongation(P_, coarse_.F, "CoarseProxy");
  fine_mass_ = mass_matrix(fine, mass_kind);
  fine_mass_.makeCompressed();
  lazy_ = std::make_unique<LazyFineOperators>();
  lazy_->mesh = std::move(fine);
  lazy_->mesh.twin = {};  // nothing here reads the gluing (fine_mesh()): not held for the proxy's life

  index_coinciding_vertices(P_);  // the given P (smoothed below)
  if (is_smoothed(prolongation)) {
    barycentric_ = std::move(P_);
    P_ = smoothed_prolongation(barycentric_, fine_laplacian());
    if (prolongation == ProlongationKind::smoothed_twice) P_ = smoothed_prolongation(P_, fine_laplacian());
  }

  if (kind == CoarseOperatorKind::intrinsic) {
    coarse_laplacian_ = cotan_laplacian(coarse_);
    coarse_mass_ = mass_matrix(coarse_, mass_kind);
  } else if (mass_kind == MassKind::lumped) {  // a diagonal mass: both products in one pass
    std::tie(coarse_laplacian_, coarse_mass_) = galerkin(P_, fine_laplacian(), fine_mass_);
  } else {
    coarse_laplacian_ = galerkin(P_, fine_laplacian());
    coarse_mass_ = galerkin(P_, fine_mass_);
  }
}

CoarseProxy::CoarseProxy(CoarseProxyArrays&& a, FineMeshSource fine_mesh)
    : kind_(a.kind), mass_kind_(a.mass_kind), prolongation_kind_(a.prolongation_kind), coarse_(std::move(a.coarse)) {
  // Eigen 3.4's SparseMatrix has no move constructor (std::move copies): swap the arrays in.
  P_.swap(a.P);
  barycentric_.swap(a.barycentric);
  fine_mass_.swap(a.fine_mass);
  coarse_laplacian_.swap(a.coarse_laplacian);
  coarse_mass_.swap(a.coarse_mass);
  const std::string who = "CoarseProxy (restored)";
  const bool smoothed = is_smoothed(prolongation_kind_);
  if (smoothed && kind_ != CoarseOperatorKind::galerkin)
    throw std::invalid_argument(who + ": a smoothed prolongation needs Galerkin coarse operators");
  if (!fine_mesh) throw std::invalid_argument(who + ": no source of the fine mesh");
  const Eigen::Index n_fine = P_.rows(), n_coarse = P_.cols();
  if (smoothed != (barycentric_.size() > 0) || (smoothed && (barycentric_.rows() != n_fine || barycentric_.cols() != n_coarse)))
    throw std::invalid_argument(who + ": the barycentric P must be given exactly when P is smoothed, of P's shape");
  if (fine_mass_.rows() != n_fine || fine_mass_.cols() != n_fine || coarse_laplacian_.rows() != n_coarse ||
      coarse_laplacian_.cols() != n_coarse || coarse_mass_.rows() != n_coarse || coarse_mass_.cols() != n_coarse)
    throw std::invalid_argument(who + ": operator shapes disagree with P (" + std::to_string(n_fine) + " x " +
                                std::to_string(n_coarse) + ")");
  coarse_.twin.clear();
  coarse_.vertex_count = static_cast<Index>(n_coarse);
  if (coarse_.F.cols() != 3 || coarse_.L.rows() != coarse_.F.rows() || coarse_.L.cols() != 3 ||
      (coarse_.F.size() > 0 && coarse_.F.minCoeff() < 0))
    throw std::invalid_argument(who + ": the coarse faces and lengths disagree");
  fine_mass_.makeCompressed();
  for (Eigen::Index i = 0; i < fine_mass_.outerSize(); ++i) {
    const auto begin = fine_mass_.outerIndexPtr()[i], end = fine_mass_.outerIndexPtr()[i + 1];
    if (end - begin != 1 || fine_mass_.innerIndexPtr()[begin] != i || !(fine_mass_.valuePtr()[begin] >= 0) ||
        !std::isfinite(fine_mass_.valuePtr()[begin]))
      throw std::invalid_argument(who + ": the fine mass is not a non-negative diagonal (column " + std::to_string(i) + ")");
  }
  P_.makeCompressed();
  require_prolongation(barycentric_prolongation(), coarse_.F, who);
  lazy_ = std::make_unique<LazyFineOperators>();
  lazy_->mesh.vertex_count = static_cast<Index>(n_fine);
  lazy_->source = std::move(fine_mesh);
  index_coinciding_vertices(barycentric_prolongation());
}

CoarseProxyArrays CoarseProxy::arrays() const {
  return {kind_, mass_kind_, prolongation_kind_, P_, barycentric_, fine_mass_, coarse_laplacian_, coarse_mass_,
          coarse_};
}

// A coarse vertex sitting on a fine vertex shows up as a row of the given P equal to e_j.
void CoarseProxy::index_coinciding_vertices(const SparseMatrix& P) {
  coarse_to_fine_.assign(static_cast<std::size_t>(P.cols()), -1);
  fine_to_coarse_.assign(static_cast<std::size_t>(P.rows()), -1);
  for (Eigen::Index j = 0; j < P.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(P, j); it; ++it)
      if (std::abs(it.value() - 1.0) < 1e-12) {
        coarse_to_fine_[static_cast<std::size_t>(j)] = static_cast<int>(it.row());
        fine_to_coarse_[static_cast<std::size_t>(it.row())] = static_cast<int>(j);
      }
}

int CoarseProxy::coarse_vertex_of(int fine_vertex) const {
  if (fine_vertex < 0 || fine_vertex >= static_cast<int>(fine_to_coarse_.size()))
    throw std::invalid_argument("CoarseProxy::coarse_vertex_of: fine vertex " + std::to_string(fine_vertex) + " out of range");
  return fine_to_coarse_[static_cast<std::size_t>(fine_vertex)];
}

CoarseProxy::LazyFineOperators& CoarseProxy::fine_mesh_of_lazy() const {
  LazyFineOperators& lazy = *lazy_;
  std::call_once(lazy.mesh_once, [&lazy] {
    if (!lazy.source) return;
    const Index n = lazy.mesh.vertex_count;  // P's rows
    lazy.source(lazy.mesh);
    lazy.mesh.twin = {};
    try {
      if (checked_vertex_count(lazy.mesh) == n) return;
    } catch (const std::invalid_argument&) {  // (reported as the mesh not fitting, below)
    }
    throw std::invalid_argument("CoarseProxy (restored): the fine mesh given does not fit P's rows");
  });
  return lazy;
}

// The Laplacian and the gradient apart: a Galerkin proxy needs the Laplacian at once, only the heat
// method the gradient.
const CoarseProxy::LazyFineOperators& CoarseProxy::fine_operators() const {
  LazyFineOperators& lazy = fine_mesh_of_lazy();
  std::call_once(lazy.gradient_once, [&lazy] {
    lazy.gradient = gradient(lazy.mesh);
    lazy.face_areas = face_areas(lazy.mesh.L);
  });
  return lazy;
}

const SparseMatrix& CoarseProxy::fine_laplacian() const {
  LazyFineOperators& lazy = fine_mesh_of_lazy();
  std::call_once(lazy.laplacian_once, [&lazy] { lazy.laplacian = cotan_laplacian(lazy.mesh); });
  return lazy.laplacian;
}

Eigen::VectorXd CoarseProxy::restrict_weighted(const Eigen::Ref<const Eigen::VectorXd>& b) const {
  if (b.size() != fine_size()) throw std::invalid_argument("CoarseProxy::restrict_weighted: wrong size");
  return P_.transpose() * b;
}

Eigen::VectorXd CoarseProxy::restrict_values(const Eigen::Ref<const Eigen::VectorXd>& u, RestrictionKind kind) const {
  if (u.size() != fine_size()) throw std::invalid_argument("CoarseProxy::restrict_values: wrong size");
  if (kind == RestrictionKind::l2_projection) {
    LazyFineOperators& lazy = *lazy_;  // the factor is made on first use: Poisson never needs it
    std::call_once(lazy.mass_factor_once, [&] { lazy.coarse_mass_factor.compute(coarse_mass_); });
    return lazy.coarse_mass_factor.solve(Eigen::VectorXd(P_.transpose() * (fine_mass_ * u)));
  }
  Eigen::VectorXd coarse(coarse_size());
  for (Eigen::Index j = 0; j < coarse_size(); ++j) {
    const int fine = coarse_to_fine_[static_cast<std::size_t>(j)];
    if (fine < 0) throw std::logic_error("CoarseProxy: coarse vertex " + std::to_string(j) + " has no fine vertex in P");
    coarse(j) = u(fine);
  }
  return coarse;
}

Eigen::VectorXd CoarseProxy::prolong(const Eigen::VectorXd& coarse_values) const {
  if (coarse_values.size() != coarse_size()) throw std::invalid_argument("CoarseProxy::prolong: wrong size");
  return P_ * coarse_values;
}

Eigen::MatrixXd CoarseProxy::prolong_block(const Eigen::MatrixXd& coarse_values) const {
  if (coarse_values.rows() != coarse_size()) throw std::invalid_argument("CoarseProxy::prolong_block: wrong number of rows");
  const Eigen::Index n = fine_size(), k = coarse_values.cols();
  Eigen::MatrixXd out(n, k);
  if (k == 0) return out;
  // A fresh n × k result (1.3 GB for 100 vectors at 1.6M vertices): huge pages spare most of the
  // page faults of its first touch.
  ice::advise_huge_pages(out.data(), sizeof(double) * static_cast<std::size_t>(out.size()));
  // P·X column by column streams P once per column and writes scattered rows; gathered per fine row
  // for a row-major chunk of columns it streams P once per chunk, a tile of rows at a time written out
  // into the columns (measured in docs/measurements.md, "The eigenbasis" and "Block Poisson").
  const Eigen::SparseMatrix<double, Eigen::RowMajor, int> P_rows = P_;
  detail::product_to_columns(P_rows, coarse_values, out, false, detail::default_threads());
  return out;
}

HeatMethodOperators CoarseProxy::coarse_heat_method_operators(double time_factor) const {
  if (kind_ == CoarseOperatorKind::intrinsic)
    return heat_method_operators(coarse_, mass_kind_, time_factor);
  if (!(time_factor > 0)) throw std::invalid_argument("coarse_heat_method_operators: time_factor must be positive");
  HeatMethodOperators ops;
  const LazyFineOperators& fine = fine_operators();
  ops.laplacian = coarse_laplacian_;
  ops.mass = lumped(coarse_mass_);  // see the header: the heat step needs a diagonal mass
  ops.gradient = fine.gradient * P_;  // gradients of prolonged coarse functions, on the fine faces
  ops.face_areas = fine.face_areas;
  ops.boundary_vertices = boundary_vertices(coarse_.F);
  const double h = mean_edge_length(coarse_.L);
  ops.time_step = time_factor * time_factor * h * h;
  return ops;
}

// ---- proxy solvers ----------------------------------------------------------------------------------

namespace {

using Clock = std::chrono::steady_clock;
// Seconds since `mark`, which moves to now (a lap of a stopwatch).
double lap_seconds(Clock::time_point& mark) {
  const Clock::time_point now = Clock::now();
  const double s = std::chrono::duration<double>(now - mark).count();
  mark = now;
  return s;
}

// One 1:4 midpoint subdivision of the coarse mesh for marching (detail::subdivide_midpoints), with
// P's rows carried into the sub-triangles: a row whose columns are one face's corners (the only face
// with them) or one edge's ends is re-expressed in the sub-triangle holding its point; other rows
// (interpolated linearly by the marching, see prepare_marching) keep their columns, which stay
// vertices.
/// The subdivided mesh (its gluing for the next subdivision: detail::SubdividedMesh) and P onto it.
struct SubdividedCoarseMesh : ice::IntrinsicMesh {
  Eigen::SparseMatrix<double, Eigen::RowMajor, int> P;
};

SubdividedCoarseMesh subdivide_for_marching(const Faces& Fc, const FaceLengths& Lc,
                                             const Eigen::SparseMatrix<double, Eigen::RowMajor, int>& P,
                                             const std::vector<Index>& twin) {
  detail::SubdividedMesh mesh = detail::subdivide_midpoints(Fc, Lc, P.cols(), twin);
  SubdividedCoarseMesh out;
  out.F = std::move(mesh.F);
  out.L = std::move(mesh.L);
  out.twin = std::move(mesh.twin);
  const Index count = static_cast<Index>(mesh.vertex_count);
  out.vertex_count = count;
  // Vertex pairs and the midpoint of their one edge, ice::kInvalid where sides with several midpoints
  // join the pair (parallel edges: which one a row's weights refer to is unknown).
  struct Edge {
    Index low, high, midpoint;
  };
  std::vector<Edge> edges;
  edges.reserve(static_cast<std::size_t>(3 * Fc.rows()));
  for (Eigen::Index f = 0; f < Fc.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Index u = Fc(f, k), w = Fc(f, (k + 1) % 3);
      edges.push_back({std::min(u, w), std::max(u, w), mesh.side_midpoint[static_cast<std::size_t>(3 * f + k)]});
    }
  const auto key = [](const Edge& e) { return std::tuple(e.low, e.high, e.midpoint); };
  std::sort(edges.begin(), edges.end(), [&](const Edge& p, const Edge& q) { return key(p) < key(q); });
  edges.erase(std::unique(edges.begin(), edges.end(), [&](const Edge& p, const Edge& q) { return key(p) == key(q); }),
              edges.end());
  std::vector<Edge> pairs;  // one per vertex pair
  for (const Edge& e : edges) {
    if (!pairs.empty() && pairs.back().low == e.low && pairs.back().high == e.high) pairs.back().midpoint = ice::kInvalid;
    else pairs.push_back(e);
  }
  edges = std::move(pairs);
  // Faces by their sorted corners (face −1: several faces have them).
  struct Corners {
    std::array<Index, 3> sorted;
    Eigen::Index face;
  };
  std::vector<Corners> faces;
  faces.reserve(static_cast<std::size_t>(Fc.rows()));
  for (Eigen::Index f = 0; f < Fc.rows(); ++f) {
    std::array<Index, 3> sorted{Fc(f, 0), Fc(f, 1), Fc(f, 2)};
    std::sort(sorted.begin(), sorted.end());
    faces.push_back({sorted, f});
  }
  std::sort(faces.begin(), faces.end(), [](const Corners& p, const Corners& q) { return p.sorted < q.sorted; });
  for (std::size_t i = 1; i < faces.size(); ++i)
    if (faces[i].sorted == faces[i - 1].sorted) faces[i].face = faces[i - 1].face = -1;
  const auto find_edge = [&](Index u, Index w) -> const Edge* {
    const Index low = std::min(u, w), high = std::max(u, w);
    const auto it = std::lower_bound(edges.begin(), edges.end(), std::pair{low, high}, [](const Edge& e, const std::pair<Index, Index>& k) {
      return e.low != k.first ? e.low < k.first : e.high < k.second;
    });
    return it != edges.end() && it->low == low && it->high == high && it->midpoint != ice::kInvalid ? &*it : nullptr;
  };
  const auto find_face = [&](std::array<Index, 3> sorted) -> Eigen::Index {
    const auto it = std::lower_bound(faces.begin(), faces.end(), sorted,
                                     [](const Corners& c, const std::array<Index, 3>& k) { return c.sorted < k; });
    return it != faces.end() && it->sorted == sorted ? it->face : -1;
  };

  // P's rows, re-expressed; at most three weights each, built in place (row-major).
  out.P.resize(P.rows(), count);
  out.P.reserve(P.nonZeros());
  std::vector<std::pair<Index, double>> row, placed;
  for (Eigen::Index y = 0; y < P.rows(); ++y) {
    row.clear();
    placed.clear();
    for (Eigen::SparseMatrix<double, Eigen::RowMajor, int>::InnerIterator it(P, y); it; ++it)
      row.emplace_back(static_cast<Index>(it.col()), it.value());
    if (row.size() == 2 && row[0].first != row[1].first) {
      auto [u, lu] = row[0];
      auto [w, lw] = row[1];
      if (const Edge* edge = find_edge(u, w)) {
        if (lu < lw) std::swap(u, w), std::swap(lu, lw);  // u holds at least half
        placed = {{u, 2 * lu - 1}, {edge->midpoint, 2 * lw}};
      }
    } else if (row.size() == 3) {
      std::array<Index, 3> sorted{row[0].first, row[1].first, row[2].first};
      std::sort(sorted.begin(), sorted.end());
      const Eigen::Index f = sorted[0] != sorted[1] && sorted[1] != sorted[2] ? find_face(sorted) : -1;
      if (f >= 0) {
        std::array<double, 3> weight{0, 0, 0};  // in the face's corner order
        for (const auto& [v, w] : row)
          for (int k = 0; k < 3; ++k)
            if (Fc(f, k) == v) weight[static_cast<std::size_t>(k)] = w;
        const auto sub = [&](int piece, int k) { return static_cast<Index>(out.F(4 * f + piece, k)); };
        const double la = weight[0], lb = weight[1], lc = weight[2];
        if (la >= 0.5) placed = {{sub(0, 0), 2 * la - 1}, {sub(0, 1), 2 * lb}, {sub(0, 2), 2 * lc}};
        else if (lb >= 0.5) placed = {{sub(1, 0), 2 * la}, {sub(1, 1), 2 * lb - 1}, {sub(1, 2), 2 * lc}};
        else if (lc >= 0.5) placed = {{sub(2, 0), 2 * la}, {sub(2, 1), 2 * lb}, {sub(2, 2), 2 * lc - 1}};
        else placed = {{sub(3, 0), 1 - 2 * lc}, {sub(3, 1), 1 - 2 * la}, {sub(3, 2), 1 - 2 * lb}};
      }
    }
    if (placed.empty()) placed = row;
    std::sort(placed.begin(), placed.end());
    out.P.startVec(y);
    for (const auto& [v, w] : placed)
      if (w > 0) out.P.insertBack(y, v) = w;
  }
  out.P.finalize();
  return out;
}

// The coarse heat method needs the barycentric P: a smoothed row has negative weights (no source
// weights), and through Galerkin operators of the smoothed P the distances came out 6x less accurate
// (nested icospheres, 162 -> 642 vertices: mean error 2.4 % against 0.37 %).
void require_barycentric(const CoarseProxy& proxy) {
  if (proxy.prolongation_kind() != ProlongationKind::barycentric)
    throw std::invalid_argument(
        "ProxyGeodesicSolver: the coarse heat method needs a proxy with the barycentric prolongation "
        "(coarse marching reads it from any proxy)");
}

}  // namespace

std::vector<Index> coarse_dirichlet_vertices(const CoarseProxy& proxy, const std::vector<Index>& fine_vertices) {
  if (!fine_vertices.empty() && is_smoothed(proxy.prolongation_kind()))
    throw std::invalid_argument(
        "Dirichlet vertices need the barycentric prolongation (a smoothed P does not take the prescribed "
        "values at them)");
  std::vector<Index> sorted = fine_vertices;
  std::sort(sorted.begin(), sorted.end());
  const auto repeat = std::adjacent_find(sorted.begin(), sorted.end());
  if (repeat != sorted.end())
    throw std::invalid_argument("Dirichlet vertex " + std::to_string(*repeat) + " given twice");
  std::vector<Index> coarse;
  for (int v : fine_vertices) {
    const int j = proxy.coarse_vertex_of(v);
    if (j < 0)
      throw std::invalid_argument("Dirichlet vertex " + std::to_string(v) + " is not a coarse vertex (lock it when coarsening)");
    coarse.push_back(j);
  }
  return coarse;
}

namespace {

// The two-level PCG of polishing (see PolishOptions): P as the one prolongation, the residual
// criterion out of the way (round-off), the iteration and error-estimate limits from the options.
PoissonMultigrid polishing_cycle(const CoarseProxy& proxy, const PolishOptions& polish) {
  if (polish.iterations < 0 || !(polish.tolerance >= 0) || polish.max_iterations < 1 || !(polish.estimate_safety >= 1))
    throw std::invalid_argument(
        "PolishOptions: iterations >= 0, tolerance >= 0, max_iterations >= 1 and estimate_safety >= 1 expected");
  PoissonMultigrid cycle{{proxy.prolongation()}, polish.cycle, /*estimate_error=*/true, /*locality_order=*/{}};
  cycle.options.mode = MultigridMode::pcg;
  cycle.options.tolerance = 1e-15;
  cycle.options.error_tolerance = polish.tolerance / polish.estimate_safety;
  cycle.options.max_iterations = polish.iterations > 0 ? polish.iterations : polish.max_iterations;
  return cycle;
}

void fill_polish_report(const MultigridReport& run, const PolishOptions& polish, PolishReport& report) {
  report.iterations = run.iterations;
  report.error_estimates = run.error_estimates;
  if (!run.error_estimates.empty()) {
    report.initial_estimated_error = run.error_estimates.front();
    report.estimated_error = run.error_estimates.back();
  }
  // The cycle's error_tolerance is the tolerance over the safety (and its steps, for heat).
  report.reached_tolerance = polish.tolerance > 0 && run.converged;
  report.seconds = run.seconds;
}

}  // namespace

ProxyPoissonSolver::ProxyPoissonSolver(const CoarseProxy& proxy, std::vector<Index> dirichlet_vertices,
                                       PolishOptions polish)
    : proxy_(&proxy),
      P_rows_(proxy.prolongation()),
      fine_mass_of_one_(proxy.fine_mass() * Eigen::VectorXd::Ones(proxy.fine_size())),
      total_mass_(fine_mass_of_one_.dot(Eigen::VectorXd::Ones(proxy.fine_size()))),
      dirichlet_vertices_(std::move(dirichlet_vertices)),
      coarse_(dirichlet_vertices_.empty()
                  ? PoissonSolver::zero_mean(proxy.coarse_laplacian(), proxy.coarse_mass())
                  : PoissonSolver::dirichlet(proxy.coarse_laplacian(), proxy.coarse_mass(),
                                             coarse_dirichlet_vertices(proxy, dirichlet_vertices_))),
      polish_(polish) {
  P_rows_.makeCompressed();
  if (is_zero_mean()) {
    // Several coarse components: each fine vertex belongs to the one its row of P lies in (P never
    // joins components: a row's columns are corners of one coarse face, or their neighbours).
    ComponentLabels coarse = component_labels(proxy.coarse_laplacian());
    if (coarse.count() > 1) {
      fine_components_.first.assign(static_cast<std::size_t>(coarse.count()), -1);
      fine_components_.label.assign(static_cast<std::size_t>(P_rows_.rows()), 0);
      for (Eigen::Index y = 0; y < P_rows_.rows(); ++y) {
        const int begin = P_rows_.outerIndexPtr()[y];
        if (begin == P_rows_.outerIndexPtr()[y + 1]) continue;
        const Index c = coarse.label[static_cast<std::size_t>(P_rows_.innerIndexPtr()[begin])];
        fine_components_.label[static_cast<std::size_t>(y)] = c;
        if (fine_components_.first[static_cast<std::size_t>(c)] < 0) fine_components_.first[static_cast<std::size_t>(c)] = static_cast<Index>(y);
      }
    }
  }
  if (polish_.enabled()) {
    Clock::time_point mark = Clock::now();
    PoissonMultigrid cycle = polishing_cycle(proxy, polish_);
    const SparseMatrix& laplacian = proxy.fine_laplacian();
    fine_ = std::make_unique<PoissonSolver>(
        is_zero_mean() ? PoissonSolver::zero_mean(laplacian, proxy.fine_mass(), std::move(cycle))
                       : PoissonSolver::dirichlet(laplacian, proxy.fine_mass(), dirichlet_vertices_, std::move(cycle)));
    polish_setup_seconds_ = lap_seconds(mark);
  }
}

Eigen::VectorXd ProxyPoissonSolver::solve(const Eigen::Ref<const Eigen::VectorXd>& f, const Eigen::VectorXd& dirichlet_values,
                                          ProxyPhaseTimes* times, PolishReport* polish_report) const {
  using namespace detail;
  const SparseMatrix& P = proxy_->prolongation();
  const SparseMatrix& fine_mass = proxy_->fine_mass();
  if (f.size() != P.rows()) throw std::invalid_argument("ProxyPoissonSolver::solve: wrong size");
  if (dirichlet_values.size() != 0 && dirichlet_values.size() != static_cast<Eigen::Index>(dirichlet_vertices_.size()))
    throw std::invalid_argument("ProxyPoissonSolver::solve: one Dirichlet value per Dirichlet vertex expected");
  Clock::time_point mark = Clock::now();
  const Eigen::Index n = P.rows();
  const int threads = default_threads();
  // Fine-size passes as gathers (M is symmetric, so its columns are its rows): M f, Pᵀ (M f), P u_c.
  // The mean reductions are Eigen's serial dot products: the same result on any thread count.
  Eigen::VectorXd compatible;
  if (is_zero_mean() && fine_components_.count() > 1) {
    compatible = f;
    remove_component_means(fine_components_, fine_mass_of_one_, compatible);
  } else if (is_zero_mean()) {
    compatible = f.array() - fine_mass_of_one_.dot(f) / total_mass_;
  }
  const double* source = is_zero_mean() ? compatible.data() : f.data();
  Eigen::VectorXd weighted(n), coarse_rhs(P.cols()), u(n);
  gather_product(fine_mass, source, weighted.data(), false, threads, n);
  gather_product(P, weighted.data(), coarse_rhs.data(), false, threads, n);
  if (times) times->restriction = lap_seconds(mark);
  const Eigen::VectorXd coarse_u = coarse_.solve_weighted(coarse_rhs, dirichlet_values);
  if (times) times->coarse_solve = lap_seconds(mark);
  gather_product(P_rows_, coarse_u.data(), u.data(), false, threads, n);
  if (is_zero_mean() && fine_components_.count() > 1)
    remove_component_means(fine_components_, fine_mass_of_one_, u);
  else if (is_zero_mean())
    add_constant(-fine_mass_of_one_.dot(u) / total_mass_, u, threads);
  if (times) times->prolongation = lap_seconds(mark);
  if (polish_report) *polish_report = PolishReport();
  if (!fine_) return u;
  // weighted = M·source is the fine right-hand side (already compatible in zero-mean mode).
  Eigen::VectorXd polished = fine_->solve_weighted(weighted, dirichlet_values, u);
  if (polish_report) fill_polish_report(fine_->multigrid()->report(), polish_, *polish_report);
  return polished;
}

Eigen::MatrixXd ProxyPoissonSolver::solve_block(const Eigen::Ref<const Eigen::MatrixXd>& F,
                                                const Eigen::MatrixXd& dirichlet_values, ProxyPhaseTimes* times) const {
  using namespace detail;
  using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const SparseMatrix& P = proxy_->prolongation();
  const Eigen::Index n = P.rows(), m = P.cols(), k = F.cols();
  if (F.rows() != n) throw std::invalid_argument("ProxyPoissonSolver::solve_block: wrong number of rows");
  if (dirichlet_values.size() != 0 &&
      (dirichlet_values.rows() != static_cast<Eigen::Index>(dirichlet_vertices_.size()) || dirichlet_values.cols() != k))
    throw std::invalid_argument("ProxyPoissonSolver::solve_block: one row of values per Dirichlet vertex, one column per source expected");
  Eigen::MatrixXd U(n, k);
  // Polishing iterates per column; the block kernels read the mass as a diagonal (lumped).
  if (fine_ || proxy_->mass_kind() != MassKind::lumped) {
    for (Eigen::Index j = 0; j < k; ++j)
      U.col(j) = solve(Eigen::VectorXd(F.col(j)),
                       dirichlet_values.size() == 0 ? Eigen::VectorXd() : Eigen::VectorXd(dirichlet_values.col(j)), nullptr, nullptr);
    return U;
  }
  if (times) *times = ProxyPhaseTimes();
  Clock::time_point mark = Clock::now();
  const int threads = default_threads();
  const Eigen::VectorXd& mass = fine_mass_of_one_;  // M is lumped: M f is mass ∘ f
  const bool components = is_zero_mean() && fine_components_.count() > 1;
  const std::size_t labels = static_cast<std::size_t>(std::max<Index>(fine_components_.count(), 1));
  const auto label_of = [&](Eigen::Index i) {
    return components ? static_cast<std::size_t>(fine_components_.label[static_cast<std::size_t>(i)]) : std::size_t{0};
  };
  // Columns go through the fine-size passes in chunks of at most 32: fine-size buffers of a chunk's
  // width, rows of the chunk's values contiguous (one pass over P reads or writes each fine row once).
  const Eigen::Index chunk = std::min<Eigen::Index>(std::max<Eigen::Index>(k, 1), 32);
  const auto stride = static_cast<std::size_t>(chunk);
  // The mass-weighted means the zero-mean problem removes (per component on several) of a chunk's
  // columns, means[label · chunk + c]: of F's columns in one pass over their rows, of the solutions
  // from the coarse values; the masses they divide by are the same for every chunk.
  std::vector<double> totals(labels, 0.0), means(labels * stride);
  for (Eigen::Index i = 0; i < n; ++i) totals[label_of(i)] += mass[i];
  const auto divide_means = [&] {
    for (std::size_t l = 0; l < labels; ++l)
      for (std::size_t c = 0; c < stride; ++c) means[l * stride + c] = totals[l] != 0 ? means[l * stride + c] / totals[l] : 0.0;
  };
  // The sums run over a fixed number of row blocks, in parallel, and add the blocks' sums in order:
  // the same result for any thread count (a fine-size serial pass per chunk cost as much as the
  // parallel ones around it). Fewer blocks when many components make each block's sums large.
  const std::size_t sums_size = labels * stride;
  const auto row_blocks = static_cast<Eigen::Index>(
      std::clamp<std::size_t>((std::size_t{1} << 22) / std::max<std::size_t>(sums_size, 1), 1, 64));
  std::vector<double> block_sums(static_cast<std::size_t>(row_blocks) * sums_size);
  const auto column_means = [&](Eigen::Index first, Eigen::Index width) {
    std::fill(block_sums.begin(), block_sums.end(), 0.0);
#pragma omp parallel for schedule(static) num_threads(active_threads(n, threads))
    for (Eigen::Index b = 0; b < row_blocks; ++b) {
      double* sums = block_sums.data() + static_cast<std::size_t>(b) * sums_size;
      for (Eigen::Index i = n * b / row_blocks; i < n * (b + 1) / row_blocks; ++i) {
        double* acc = sums + label_of(i) * stride;
        for (Eigen::Index c = 0; c < width; ++c) acc[c] += mass[i] * F(i, first + c);
      }
    }
    std::fill(means.begin(), means.end(), 0.0);
    for (Eigen::Index b = 0; b < row_blocks; ++b)
      for (std::size_t e = 0; e < sums_size; ++e) means[e] += block_sums[static_cast<std::size_t>(b) * sums_size + e];
    divide_means();
  };
  RowMatrix coarse_chunk(m, chunk), coarse_rhs(m, k);
  // The fresh n × k result (1.3 GB at 1.6M vertices and 100 sources): huge pages spare most of the
  // page faults of its first touch, which otherwise cost more than the passes.
  ice::advise_huge_pages(U.data(), sizeof(double) * static_cast<std::size_t>(U.size()));
  for (Eigen::Index first = 0; first < k; first += chunk) {
    const Eigen::Index width = std::min(chunk, k - first);
    if (is_zero_mean()) column_means(first, width);
    // Pᵀ M (f − its mean), each fine row weighted as the scatter reads it.
    scatter_transpose_tile_source(
        P_rows_,
        [&](Eigen::Index top, Eigen::Index rows, double* buffer) {
          for (Eigen::Index i = top; i < top + rows; ++i) {
            const double* mean = is_zero_mean() ? means.data() + label_of(i) * stride : nullptr;
            double* w = buffer + (i - top) * chunk;
            for (Eigen::Index c = 0; c < chunk; ++c) w[c] = c < width ? mass[i] * (F(i, first + c) - (mean ? mean[c] : 0.0)) : 0.0;
          }
          return static_cast<const double*>(buffer);
        },
        coarse_chunk.data(), chunk, threads);
    coarse_rhs.middleCols(first, width) = coarse_chunk.leftCols(width);
  }
  if (times) times->restriction = lap_seconds(mark);
  const RowMatrix coarse_u = coarse_.solve_multiple_weighted(Eigen::MatrixXd(coarse_rhs), dirichlet_values);
  if (times) times->coarse_solve = lap_seconds(mark);
  // The prolonged solutions' mass-weighted means, from the coarse values: Σ_i m_i (P u)_i = (Pᵀ m)·u,
  // with each coarse vertex in its fine rows' component (P does not couple components) — no fine-size
  // pass over the prolonged block.
  Eigen::VectorXd coarse_weight;
  std::vector<std::size_t> coarse_label(static_cast<std::size_t>(m), 0);
  if (is_zero_mean()) {
    coarse_weight.resize(m);
    scatter_transpose_rows(P_rows_, mass.data(), coarse_weight.data(), 1, threads);
    if (components)
      for (Eigen::Index i = 0; i < n; ++i)
        for (auto p = P_rows_.outerIndexPtr()[i]; p < P_rows_.outerIndexPtr()[i + 1]; ++p)
          coarse_label[static_cast<std::size_t>(P_rows_.innerIndexPtr()[p])] = label_of(i);
  }
  for (Eigen::Index first = 0; first < k; first += chunk) {
    const Eigen::Index width = std::min(chunk, k - first);
    coarse_chunk.leftCols(width) = coarse_u.middleCols(first, width);
    if (width < chunk) coarse_chunk.rightCols(chunk - width).setZero();
    if (is_zero_mean()) {
      std::fill(means.begin(), means.end(), 0.0);
      for (Eigen::Index j = 0; j < m; ++j)
        for (Eigen::Index c = 0; c < width; ++c)
          means[coarse_label[static_cast<std::size_t>(j)] * stride + static_cast<std::size_t>(c)] += coarse_weight(j) * coarse_chunk(j, c);
      divide_means();
    }
    gather_product_to_columns(P_rows_, coarse_chunk.data(), chunk, width, U, first, threads,
                              [&](Eigen::Index i, Eigen::Index c, double u) {
                                return u - (is_zero_mean() ? means[label_of(i) * stride + static_cast<std::size_t>(c)] : 0.0);
                              });
  }
  if (times) times->prolongation = lap_seconds(mark);
  return U;
}

ProxyHeatSolver::ProxyHeatSolver(const CoarseProxy& proxy, double time_step, RestrictionKind restriction,
                                 PolishOptions polish)
    : proxy_(&proxy),
      restriction_(restriction),
      coarse_(proxy.coarse_laplacian(), proxy.coarse_mass(), time_step),
      polish_(polish) {
  if (polish_.enabled()) {
    Clock::time_point mark = Clock::now();
    PoissonMultigrid cycle = polishing_cycle(proxy, polish_);
    fine_ = std::make_unique<MultigridSolver>(std::move(cycle.prolongations), cycle.options);
    fine_->setup(SparseMatrix(proxy.fine_mass() + time_step * proxy.fine_laplacian()));
    fine_->set_error_norm(proxy.fine_mass() * Eigen::VectorXd::Ones(proxy.fine_size()), false);
    polish_setup_seconds_ = lap_seconds(mark);
  }
}

ProxyHeatSolver::~ProxyHeatSolver() = default;

Eigen::MatrixXd ProxyHeatSolver::trajectory(const Eigen::Ref<const Eigen::VectorXd>& fine_u0, int steps, int every,
                                            std::vector<int>* output_steps, ProxyPhaseTimes* times) const {
  if (steps < 1 || every < 1) throw std::invalid_argument("ProxyHeatSolver::trajectory: steps and every must be >= 1");
  if (fine_) throw std::invalid_argument("ProxyHeatSolver::trajectory: polishing needs every fine step (use integrate)");
  if (fine_u0.size() != proxy_->fine_size()) throw std::invalid_argument("ProxyHeatSolver::trajectory: wrong size");
  const std::vector<int> listed = fem::output_steps(steps, every);
  if (times) *times = ProxyPhaseTimes();
  Clock::time_point mark = Clock::now();
  // The coarse states of the listed steps, stepped as integrate() steps them.
  std::vector<Eigen::VectorXd> states;
  Eigen::VectorXd u;
  int done = 0;
  if (restriction_ == RestrictionKind::l2_projection) {
    const Eigen::VectorXd rhs = proxy_->restrict_weighted(proxy_->fine_mass() * fine_u0);
    if (times) times->restriction = lap_seconds(mark);
    u = coarse_.solve_weighted(rhs);
    done = 1;
  } else {
    u = proxy_->restrict_values(fine_u0, RestrictionKind::injection);
    if (times) times->restriction = lap_seconds(mark);
  }
  for (const int target : listed) {
    for (; done < target; ++done) u = coarse_.step(u);
    states.push_back(u);
  }
  if (times) times->coarse_solve = lap_seconds(mark);
  Eigen::MatrixXd out(proxy_->fine_size(), static_cast<Eigen::Index>(states.size()));
  for (std::size_t j = 0; j < states.size(); ++j) out.col(static_cast<Eigen::Index>(j)) = proxy_->prolong(states[j]);
  if (times) times->prolongation = lap_seconds(mark);
  if (output_steps) *output_steps = listed;
  return out;
}

Eigen::VectorXd ProxyHeatSolver::integrate(const Eigen::Ref<const Eigen::VectorXd>& fine_u0, int steps, ProxyPhaseTimes* times,
                                           PolishReport* polish_report) const {
  if (steps < 0 || (steps == 0 && restriction_ == RestrictionKind::l2_projection))
    throw std::invalid_argument("ProxyHeatSolver::integrate: steps must be >= 1 with L2 projection, >= 0 with injection");
  if (fine_u0.size() != proxy_->fine_size()) throw std::invalid_argument("ProxyHeatSolver::integrate: wrong size");
  Clock::time_point mark = Clock::now();
  // The coarse trajectory: every state when polishing (each step's initial guess), else the last.
  std::vector<Eigen::VectorXd> coarse_states;
  Eigen::VectorXd u;
  if (restriction_ == RestrictionKind::l2_projection) {
    // Mc u_c0 = Pᵀ M u₀ defines the projection, and it is the first step's right-hand side.
    const Eigen::VectorXd rhs = proxy_->restrict_weighted(proxy_->fine_mass() * fine_u0);
    if (times) times->restriction = lap_seconds(mark);
    u = coarse_.solve_weighted(rhs);
    for (int k = 1; k < steps; ++k) {
      if (fine_) coarse_states.push_back(u);
      u = coarse_.step(u);
    }
  } else {
    u = proxy_->restrict_values(fine_u0, RestrictionKind::injection);
    if (times) times->restriction = lap_seconds(mark);
    for (int k = 0; k < steps; ++k) {
      u = coarse_.step(u);
      if (fine_ && k + 1 < steps) coarse_states.push_back(u);
    }
  }
  if (fine_) coarse_states.push_back(u);
  if (times) times->coarse_solve = lap_seconds(mark);
  Eigen::VectorXd fine_u = proxy_->prolong(u);
  if (times) times->prolongation = lap_seconds(mark);
  if (polish_report) *polish_report = PolishReport();
  if (!fine_ || steps == 0) return fine_u;

  // Polishing: the fine steps, each from the prolonged coarse state of the same step.
  MultigridOptions options = fine_->options();
  options.error_tolerance = polish_.tolerance / (polish_.estimate_safety * steps);
  fine_->set_options(options);
  PolishReport total;
  total.reached_tolerance = polish_.tolerance > 0;
  Eigen::VectorXd state = fine_u0;
  for (int k = 0; k < steps; ++k) {
    state = fine_->solve(Eigen::VectorXd(proxy_->fine_mass() * state), Eigen::VectorXd(),
                         proxy_->prolong(coarse_states[static_cast<std::size_t>(k)]));
    PolishReport step;
    fill_polish_report(fine_->report(), polish_, step);
    if (k == 0) total.initial_estimated_error = step.initial_estimated_error;
    total.iterations += step.iterations;
    total.seconds += step.seconds;
    total.error_estimates = step.error_estimates;
    total.estimated_error = step.estimated_error;
    total.reached_tolerance = total.reached_tolerance && step.reached_tolerance;
  }
  if (polish_report) *polish_report = total;
  return state;
}

ProxyGeodesicSolver::ProxyGeodesicSolver(const CoarseProxy& proxy, const ProxyGeodesicOptions& options)
    : P_rows_(proxy.barycentric_prolongation()) {  // the heat method requires it to be the proxy's P
  P_rows_.prune(0.0);  // (an explicit zero would join a row's corners, and 0 · ∞ spoil sums)
  P_rows_.makeCompressed();
  if (options.method == CoarseDistanceMethod::heat_method) {
    require_barycentric(proxy);
    heat_ = std::make_unique<HeatGeodesicSolver>(proxy.coarse_heat_method_operators(options.time_factor));
  } else {
    const ice::IntrinsicMesh& coarse = proxy.coarse_mesh();
    prepare_marching(coarse.F,
                     options.curvature_correction
                         ? curvature_corrected_lengths(proxy.fine_mesh(), coarse, proxy.barycentric_prolongation(),
                                                       options.curvature_divisor)
                         : coarse.L,
                     coarse.twin, options.subdivisions);
  }
}

ProxyGeodesicSolver::ProxyGeodesicSolver(const ice::IntrinsicMesh& coarse, SparseMatrix P, int subdivisions)
    : P_rows_(std::move(P)) {
  P_rows_.prune(0.0);
  P_rows_.makeCompressed();
  require_prolongation(P_rows_, coarse.F, "ProxyGeodesicSolver");
  if (checked_vertex_count(coarse) != P_rows_.cols())
    throw std::invalid_argument("ProxyGeodesicSolver: the coarse mesh's vertex count is not P's column count");
  for (Eigen::Index k = 0; k < P_rows_.nonZeros(); ++k)
    if (!(P_rows_.valuePtr()[k] > 0))
      throw std::invalid_argument("ProxyGeodesicSolver: P has a negative or non-finite weight (rows are barycentric coordinates)");
  prepare_marching(coarse.F, coarse.L, coarse.twin, subdivisions);
}

void ProxyGeodesicSolver::prepare_marching(const Faces& coarse_faces, const FaceLengths& coarse_lengths,
                                           const std::vector<Index>& coarse_twin, int subdivisions) {
  detail::check_marching_mesh(coarse_faces, coarse_lengths, "ProxyGeodesicSolver");
  if (subdivisions < 0 || subdivisions > kMaxMarchingSubdivisions)
    throw std::invalid_argument("ProxyGeodesicSolver: subdivisions must be in [0, " +
                                std::to_string(kMaxMarchingSubdivisions) + "]");
  // Sides are paired by their ends and lengths, which is the mesh's own gluing wherever it is
  // unambiguous; where three or more sides share ends and length (a tufted cover's sheets meet along
  // one pair of vertices several times) only the coarse mesh's twin can say which are one edge.
  const auto sides = static_cast<Index>(3 * coarse_faces.rows());
  bool ambiguous = false;
  if (!coarse_twin.empty())
    for (const std::vector<Index>& group : detail::group_unknown_sides(coarse_faces, coarse_lengths, {}))
      ambiguous = ambiguous || group.size() > 2;
  if (ambiguous) {
    // (Lengths to round-off: a caller may have computed them per face.)
    const bool glued = coarse_twin.size() == static_cast<std::size_t>(sides) &&
                       ice::first_gluing_defect(coarse_faces, coarse_lengths, coarse_twin, 1e-9).defect == ice::GluingDefect::none;
    if (!glued)
      throw std::invalid_argument("ProxyGeodesicSolver: the coarse mesh's gluing (twin) is not 3 entries per face, each "
                                  "side glued back by a side of the other direction and the same length, or on the boundary");
  }
  Faces Fc = coarse_faces;
  FaceLengths Lc = coarse_lengths;
  std::vector<Index> twin;  // each subdivision's gluing for the next
  if (ambiguous) twin = coarse_twin;
  for (int level = 0; level < subdivisions; ++level) {
    SubdividedCoarseMesh finer = subdivide_for_marching(Fc, Lc, P_rows_, twin);
    Fc = std::move(finer.F), Lc = std::move(finer.L), P_rows_ = std::move(finer.P), twin = std::move(finer.twin);
  }
  marching_ = std::make_unique<detail::MarchingMesh>(Fc, Lc, P_rows_.cols(), twin);
  const Eigen::Index n = P_rows_.rows();
  spread_.resize(static_cast<std::size_t>(n));
  const int* outer = P_rows_.outerIndexPtr();
  const int* column = P_rows_.innerIndexPtr();
  const double* weight = P_rows_.valuePtr();
#pragma omp parallel for schedule(static) num_threads(detail::active_threads(n, detail::default_threads()))
  for (Eigen::Index y = 0; y < n; ++y) {
    double spread = 0;
    for (int j = outer[y]; j < outer[y + 1]; ++j)
      for (int k = j + 1; k < outer[y + 1]; ++k) {
        const double length = marching_->edge_length(column[j], column[k]);
        spread += weight[j] * weight[k] * length * length;  // NaN when not an edge: linear
      }
    spread_[static_cast<std::size_t>(y)] = spread;
  }
}

ProxyGeodesicSolver::ProxyGeodesicSolver(const CoarseProxy& proxy, HeatMethodOperators coarse_operators)
    : P_rows_(proxy.barycentric_prolongation()), heat_(std::make_unique<HeatGeodesicSolver>(std::move(coarse_operators))) {
  if (heat_->operators().laplacian.rows() != proxy.coarse_size())
    throw std::invalid_argument("ProxyGeodesicSolver: coarse operators of the wrong size");
  P_rows_.makeCompressed();
  require_barycentric(proxy);
}

ProxyGeodesicSolver::ProxyGeodesicSolver(ProxyGeodesicSolver&&) = default;
ProxyGeodesicSolver::~ProxyGeodesicSolver() = default;

Eigen::VectorXd ProxyGeodesicSolver::distance(const std::vector<Index>& fine_sources, ProxyPhaseTimes* times) const {
  if (fine_sources.empty()) throw std::invalid_argument("ProxyGeodesicSolver::distance: no sources");
  std::vector<Index> sources = fine_sources;
  std::sort(sources.begin(), sources.end());
  sources.erase(std::unique(sources.begin(), sources.end()), sources.end());
  if (sources.front() < 0 || sources.back() >= P_rows_.rows())
    throw std::invalid_argument("ProxyGeodesicSolver::distance: bad source");
  return heat_ ? heat_distance(sources, times) : marching_distance(sources, times);
}

Eigen::VectorXd ProxyGeodesicSolver::heat_distance(const std::vector<Index>& sources, ProxyPhaseTimes* times) const {
  Clock::time_point mark = Clock::now();
  // The sources' weights restricted directly from P's rows (Pᵀ of a sparse indicator), without a
  // fine-size pass.
  const Eigen::Index n = P_rows_.rows();
  Eigen::VectorXd coarse_weights = Eigen::VectorXd::Zero(P_rows_.cols());
  for (int s : sources)
    for (decltype(P_rows_)::InnerIterator it(P_rows_, s); it; ++it) coarse_weights(it.col()) += it.value();
  if (times) times->restriction = lap_seconds(mark);
  const Eigen::VectorXd coarse_phi = heat_->distance_from_weights(coarse_weights);
  if (times) times->coarse_solve = lap_seconds(mark);
  Eigen::VectorXd phi(n);
  detail::gather_product(P_rows_, coarse_phi.data(), phi.data(), false, detail::default_threads(), n);
  // Shift so that the sources' mean distance is zero.
  double sum = 0;
  for (int s : sources) sum += phi(s);
  detail::add_constant(-sum / static_cast<double>(sources.size()), phi, detail::default_threads());
  if (times) times->prolongation = lap_seconds(mark);
  return phi;
}

Eigen::VectorXd ProxyGeodesicSolver::marching_distance(const std::vector<Index>& sources, ProxyPhaseTimes* times) const {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  Clock::time_point mark = Clock::now();
  const int* outer = P_rows_.outerIndexPtr();
  const int* column = P_rows_.innerIndexPtr();
  const double* weight = P_rows_.valuePtr();
  const auto nc = static_cast<std::size_t>(P_rows_.cols());
  // Each source x = Σ λ_i p_i seeds its corners at their planar distances,
  // |x p_i|² = Σ_k λ_k |p_k p_i|² − V(x). A source whose corners are not joined by edges has no
  // planar layout here: its squared distances come from a marching run from each corner instead,
  // combined as the distance oracle does (d(x, q)² = Σ_k λ_k d(p_k, q)² − V(x), with V(x) from
  // the corners' marched distances).
  std::vector<detail::CoarseMarcher::Seed> seeds;
  for (std::size_t number = 0; number < sources.size(); ++number) {
    const Index x = sources[number];
    const double spread = spread_[static_cast<std::size_t>(x)];
    if (std::isnan(spread)) continue;  // marched from its corners below
    for (int i = outer[x]; i < outer[x + 1]; ++i) {
      double squared = -spread;
      for (int k = outer[x]; k < outer[x + 1]; ++k)
        if (k != i) {
          const double length = marching_->edge_length(column[k], column[i]);
          squared += weight[k] * length * length;
        }
      seeds.push_back({column[i], std::sqrt(std::max(0.0, squared)), static_cast<Index>(number)});
    }
  }
  if (times) times->restriction = lap_seconds(mark);
  detail::CoarseMarcher marcher(*marching_, /*reopen=*/true, /*track_sources=*/true);  // (see there: one run, so worth it)
  std::vector<double> squared(nc, kInfinity);  // squared distance from the nearest source
  std::vector<Index> nearest(nc, -1);          // which source (its number in `sources`)
  if (!seeds.empty()) {
    marcher.run(seeds, squared, nearest);
    for (double& d : squared) d *= d;
  }
  std::vector<double> corner_rows, row;
  for (std::size_t number = 0; number < sources.size(); ++number) {
    const Index x = sources[number];
    if (!std::isnan(spread_[static_cast<std::size_t>(x)])) continue;
    const int begin = outer[x], count = outer[x + 1] - begin;
    corner_rows.resize(static_cast<std::size_t>(count) * nc);
    for (int k = 0; k < count; ++k) {
      marcher.run(column[begin + k], row);
      std::copy(row.begin(), row.end(), corner_rows.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(k) * nc));
    }
    double spread = 0;
    for (int j = 0; j < count; ++j)
      for (int k = j + 1; k < count; ++k) {
        const double d = corner_rows[static_cast<std::size_t>(j) * nc + static_cast<std::size_t>(column[begin + k])];
        spread += weight[begin + j] * weight[begin + k] * d * d;
      }
    for (std::size_t q = 0; q < nc; ++q) {
      double sum = -spread;
      for (int k = 0; k < count; ++k) {
        const double d = corner_rows[static_cast<std::size_t>(k) * nc + q];
        if (weight[begin + k] > 0) sum += weight[begin + k] * d * d;  // (0 · ∞ across components)
      }
      if (std::isnan(sum)) continue;  // unreachable from some corner
      if (std::max(0.0, sum) < squared[q]) {
        squared[q] = std::max(0.0, sum);
        nearest[q] = static_cast<Index>(number);
      }
    }
  }
  if (times) times->coarse_solve = lap_seconds(mark);
  // Fine values: the squared distance interpolated with V(y) subtracted — valid for the distance
  // from one source, so where y's coarse corners are nearest to different sources (near where two
  // sources' fronts meet), or V(y) is unknown, the distance is interpolated linearly. Zero weights
  // are skipped (0 · ∞ in a coarse component no source reaches).
  const Eigen::Index n = P_rows_.rows();
  Eigen::VectorXd phi(n);
#pragma omp parallel for schedule(static) num_threads(detail::active_threads(n, detail::default_threads()))
  for (Eigen::Index y = 0; y < n; ++y) {
    const double spread = spread_[static_cast<std::size_t>(y)];
    bool one_source = true;
    for (int j = outer[y] + 1; j < outer[y + 1]; ++j)
      one_source = one_source && nearest[static_cast<std::size_t>(column[j])] == nearest[static_cast<std::size_t>(column[outer[y]])];
    double sum = 0;
    if (std::isnan(spread) || !one_source) {
      for (int j = outer[y]; j < outer[y + 1]; ++j)
        if (weight[j] > 0) sum += weight[j] * std::sqrt(squared[static_cast<std::size_t>(column[j])]);
      phi(y) = sum;
    } else {
      for (int j = outer[y]; j < outer[y + 1]; ++j)
        if (weight[j] > 0) sum += weight[j] * squared[static_cast<std::size_t>(column[j])];
      phi(y) = std::sqrt(std::max(0.0, sum - spread));
    }
  }
  for (Index x : sources) phi(x) = 0;
  if (times) times->prolongation = lap_seconds(mark);
  return phi;
}

}  // namespace fem
