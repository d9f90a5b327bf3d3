#include "ice/proxy/eigen.h"

#include "entry_checks.h"
#include "fem/multigrid.h"
#include "fem/ordering.h"
#include "fem/topology.h"
#include "ice/wall_time.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace ice::proxy {

namespace {

using Clock = std::chrono::steady_clock;

// Column by column, in place. `forward`: row i of the result is row order[i] of X (to the numbering
// `order`); otherwise the inverse (back to the original numbering).
void permute_rows_in_place(Eigen::MatrixXd& X, const std::vector<Index>& order, bool forward) {
  Eigen::VectorXd column(X.rows());
  for (Eigen::Index c = 0; c < X.cols(); ++c) {
    column = X.col(c);
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      const Index old = order[static_cast<std::size_t>(i)];
      if (forward)
        X(i, c) = column(old);
      else
        X(old, c) = column(i);
    }
  }
}

// The proxy's coarse vertices off the Dirichlet ones (`coarse_fixed`: those, as coarse vertices),
// and the check that k pairs fit in them.
Eigen::Index free_coarse_vertices(const fem::CoarseProxy& proxy, const std::vector<Index>& dirichlet_vertices,
                                  std::vector<Index>& coarse_fixed) {
  coarse_fixed = fem::coarse_dirichlet_vertices(proxy, dirichlet_vertices);
  return proxy.coarse_laplacian().rows() - static_cast<Eigen::Index>(coarse_fixed.size());
}

void require_pair_count(int k, Eigen::Index coarse, bool dirichlet) {
  if (k < 1 || k >= coarse)
    throw std::invalid_argument("eigenbasis: asked for " + std::to_string(k) + " eigenpairs, the coarse space has " +
                                std::to_string(coarse) + (dirichlet ? " free" : "") +
                                " vertices (1 <= k < coarse vertices: ask for more coarse vertices)");
}

constexpr const char* kEigenpairsKind = "eigenpairs";

// How the coarse pairs are computed: all of them by the Lanczos eigensolver (fem::EigenOptions), or,
// with `subspace`, by subspace iteration until the first `accurate` are converged (the refined
// route's start and coarse directions: the rest only span the low spectrum).
struct CoarsePairsMethod {
  fem::EigenOptions lanczos;
  const fem::SubspaceIterationOptions* subspace = nullptr;
  int accurate = 0;
  // The pairs whose residuals the eigensolver bounds, and its tolerance.
  int bounded(int count) const { return subspace ? accurate : count; }
  double tolerance() const { return subspace ? subspace->tolerance : lanczos.tolerance; }
};

// What is wrong with `pairs` as the smallest pairs of the pencil (L, M) with φ = 0 at `fixed`, or ""
// when nothing is: finite, values in order, vectors zero at the Dirichlet vertices, M-orthonormal to
// 1e-8, and the residuals (fem::eigen_residuals, all returned in `residuals`) of the pairs the
// eigensolver converged within the square root of its tolerance — a bound any converged pair meets
// with room to spare.
std::string eigenpairs_defect(const fem::SparseMatrix& L, const fem::SparseMatrix& M, const std::vector<Index>& fixed,
                              const fem::Eigenpairs& p, const CoarsePairsMethod& method, Eigen::VectorXd& residuals) {
  const Eigen::Index k = p.values.size();
  if (p.vectors.rows() != L.rows() || p.vectors.cols() != k) return "eigenpairs of the wrong shape";
  if (!p.values.allFinite() || !p.vectors.allFinite()) return "an eigenpair is not finite";
  for (Eigen::Index j = 1; j < k; ++j)
    if (p.values(j) < p.values(j - 1)) return "eigenvalues out of order";
  for (Index v : fixed)
    if (!p.vectors.row(v).isZero(0)) return "an eigenvector is not zero at a Dirichlet vertex";
  residuals = fem::eigen_residuals(L, M, p.values, p.vectors, fixed);
  const Eigen::Index bounded = std::min<Eigen::Index>(k, method.bounded(static_cast<int>(k)));
  if (!(residuals.head(bounded).maxCoeff() <= std::sqrt(method.tolerance()))) return "an eigenpair's residual is too large";
  const Eigen::MatrixXd gram = p.vectors.transpose() * (M * p.vectors);
  if (!((gram - Eigen::MatrixXd::Identity(k, k)).cwiseAbs().maxCoeff() <= 1e-8)) return "the eigenvectors are not M-orthonormal";
  return "";
}

// The pairs by the method asked; subspace iteration that does not converge (or loses rank) falls
// back to the Lanczos eigensolver for all k pairs, which meets the same checks.
fem::Eigenpairs solve_coarse_pairs(const fem::SparseMatrix& L, const fem::SparseMatrix& M, const std::vector<Index>& fixed,
                                   int k, const CoarsePairsMethod& method) {
  if (method.subspace) {
    try {
      return fem::subspace_eigenpairs_dirichlet(L, M, fixed, k, method.accurate, *method.subspace);
    } catch (const std::runtime_error&) {
    }
  }
  return fem::smallest_eigenpairs_dirichlet(L, M, fixed, k, method.lanczos);
}

// The coarse pencil's k smallest pairs (CoarsePairsMethod), through the store when it is on. The key
// is the pencil itself (the coarse operators' arrays), the Dirichlet coarse vertices (as a set), k
// and the method with its options: whatever proxy or setup made the pencil, the pairs are the same.
// A stored entry is used only when its pairs pass eigenpairs_defect and their residuals, recomputed,
// match those stored with them (to 1e-6 relative: another build may sum in another order); else it
// is rebuilt. Fresh pairs that fail the same checks are returned but not stored.
fem::Eigenpairs coarse_eigenpairs(const fem::SparseMatrix& L, const fem::SparseMatrix& M, const std::vector<Index>& fixed,
                                  int k, const CoarsePairsMethod& method, const Store& store, CacheReport& cache) {
  if (!store.enabled()) return solve_coarse_pairs(L, M, fixed, k, method);
  std::vector<Index> fixed_set = fixed;
  std::sort(fixed_set.begin(), fixed_set.end());
  fixed_set.erase(std::unique(fixed_set.begin(), fixed_set.end()), fixed_set.end());
  KeyHasher h(kEigenpairsKind);
  h.add_sparse(L).add_sparse(M);
  h.add(static_cast<std::int64_t>(fixed_set.size())).add_bytes(fixed_set.data(), sizeof(Index) * fixed_set.size());
  h.add(k);
  if (method.subspace) {
    const fem::SubspaceIterationOptions& o = *method.subspace;
    h.add(std::string("subspace")).add(method.accurate).add(o.tolerance).add(o.max_iterations).add(static_cast<int>(o.ordering));
  } else {
    const fem::EigenOptions& o = method.lanczos;
    h.add(o.tolerance).add(o.max_restarts).add(static_cast<std::int64_t>(o.basis_size)).add(static_cast<int>(o.ordering));
  }
  const StoreKey key = h.finish();
  std::optional<detail::Stored<fem::Eigenpairs>> hit = detail::load_entry<detail::Stored<fem::Eigenpairs>>(
      store, kEigenpairsKind, key, cache, [&](const EntryReader& entry, const std::string& path) {
        detail::Stored<fem::Eigenpairs> stored;
        fem::Eigenpairs& p = stored.value;
        const std::vector<double> values = entry.doubles("values"), residuals = entry.doubles("residuals");
        detail::require(static_cast<int>(values.size()) == k && static_cast<int>(residuals.size()) == k, path,
                        "eigenpairs of the wrong shape");
        p.values = Eigen::Map<const Eigen::VectorXd>(values.data(), k);
        p.vectors = entry.double_matrix("vectors");
        Eigen::VectorXd recomputed;
        const std::string defect = eigenpairs_defect(L, M, fixed_set, p, method, recomputed);
        if (!defect.empty()) detail::fail(path, defect);
        for (int j = 0; j < k; ++j) {
          const double r = residuals[static_cast<std::size_t>(j)];
          detail::require(std::abs(recomputed(j) - r) <= 1e-6 * r + 1e-13, path,
                          "the eigenpairs are not this pencil's (their residuals differ from those stored)");
        }
        p.restarts = static_cast<int>(entry.integer("restarts"));
        const std::vector<double> shift = entry.doubles("shift");
        detail::require(shift.size() == 1, path, "the eigenpairs' shift is missing");
        p.shift = shift[0];
        return stored;
      });
  if (hit) {
    cache = std::move(hit->cache);
    return std::move(hit->value);
  }
  fem::Eigenpairs pairs = solve_coarse_pairs(L, M, fixed, k, method);
  const auto start = Clock::now();
  Eigen::VectorXd residuals;
  const std::string defect = eigenpairs_defect(L, M, fixed_set, pairs, method, residuals);
  if (!defect.empty()) {  // an entry that every load would reject: not written
    cache.save_error = "eigenpairs not stored: " + defect;
    return pairs;
  }
  EntryWriter writer;
  writer.put("values", pairs.values.data(), static_cast<std::size_t>(pairs.values.size()));
  writer.put("residuals", residuals.data(), static_cast<std::size_t>(residuals.size()));
  writer.put_matrix("vectors", pairs.vectors);
  writer.put_int("restarts", pairs.restarts);
  writer.put("shift", &pairs.shift, 1);
  detail::save_entry(store, kEigenpairsKind, key, writer, cache, start);
  return pairs;
}

// proxy_eigenbasis's work for `count` coarse pairs of which the first `prolonged` are prolonged and
// returned; the coarse vectors of all `count` go to `coarse_vectors` when given.
Eigenbasis coarse_basis(const fem::CoarseProxy& proxy, int count, int prolonged, const CoarsePairsMethod& method,
                        const std::vector<Index>& dirichlet_vertices, const Store& store, Eigen::MatrixXd* coarse_vectors) {
  if (proxy.kind() != fem::CoarseOperatorKind::galerkin)
    throw std::invalid_argument("eigenbasis: the proxy's coarse operators must be Galerkin (PᵀLP, PᵀMP)");
  std::vector<Index> coarse_fixed;
  require_pair_count(count, free_coarse_vertices(proxy, dirichlet_vertices, coarse_fixed), !coarse_fixed.empty());
  auto start = Clock::now();
  Eigenbasis basis;
  fem::Eigenpairs pairs =
      coarse_eigenpairs(proxy.coarse_laplacian(), proxy.coarse_mass(), coarse_fixed, count, method, store, basis.cache);
  basis.eigensolve_seconds = seconds_since(start) - basis.cache.save_seconds;
  start = Clock::now();
  basis.values = pairs.values.head(prolonged);
  basis.vectors = proxy.prolong_block(pairs.vectors.leftCols(prolonged));
  basis.prolong_seconds = seconds_since(start);
  basis.restarts = pairs.restarts;
  if (coarse_vectors) *coarse_vectors = std::move(pairs.vectors);
  return basis;
}

// The shift σ of the refinement's preconditioner (L + σM)⁻¹: the smallest positive eigenvalue of
// `values` that is not a zero mode (the scale of the modes sought), else the inverse area.
double preconditioner_shift(const Eigen::VectorXd& values, const fem::SparseMatrix& L, const fem::SparseMatrix& M) {
  const double largest = fem::zero_mode_scale(values.size() ? values.cwiseAbs().maxCoeff() : 0.0, L, M);
  for (Eigen::Index j = 0; j < values.size(); ++j)
    if (values(j) > 0 && !fem::is_zero_mode(values(j), largest)) return values(j);
  return 1.0 / M.sum();
}

// L + σM with the rows and columns of `fixed` replaced by the identity's: its inverse is the free
// block's, which is what the Dirichlet pencil's preconditioner must apply.
fem::SparseMatrix shifted_free_block(const fem::SparseMatrix& L, const fem::SparseMatrix& M, double sigma,
                                     const std::vector<Index>& fixed) {
  fem::SparseMatrix A = L + sigma * M;
  if (fixed.empty()) return A;
  std::vector<char> is_fixed(static_cast<std::size_t>(A.rows()), 0);
  for (Index i : fixed) is_fixed[static_cast<std::size_t>(i)] = 1;
  A.prune([&](Index row, Index col, double) {
    return !is_fixed[static_cast<std::size_t>(row)] && !is_fixed[static_cast<std::size_t>(col)];
  });
  std::vector<Eigen::Triplet<double>> ones;
  for (Index i : fixed) ones.emplace_back(i, i, 1.0);
  fem::SparseMatrix identity(A.rows(), A.cols());
  identity.setFromTriplets(ones.begin(), ones.end(), [](double a, double) { return a; });  // repeats: one 1
  return A + identity;
}

// A refinement's report into the basis (the refinement's time is the caller's: its set-up included).
void record_refinement(Eigenbasis& basis, const fem::EigenRefineReport& report) {
  basis.converged = report.converged;
  basis.refine_iterations = report.iterations;
  basis.residuals = report.residuals;
  basis.residual_history = report.history;
  basis.precondition_seconds = report.precondition_seconds;
  basis.refine_sparse_seconds = report.sparse_seconds;
  basis.refine_dense_seconds = report.dense_seconds;
  basis.refine_coarse_seconds = report.coarse_seconds;
}

// The refined route on a proxy as large as its mesh: the fine pencil's k + guard pairs by the fine
// eigensolver, the first k returned. Its residuals level off near 1e-10 whatever its own tolerance
// (Spectra's test is on the shifted-inverted problem), so a tighter tolerance is reached by
// fem::refine_eigenpairs (LOBPCG) preconditioned by the exact (L + σM)⁻¹, affordable at these sizes.
Eigenbasis fine_pencil_eigenbasis(const fem::SparseMatrix& L, const fem::SparseMatrix& M, int k,
                                  const EigenRefinement& refinement, const fem::EigenOptions& options,
                                  const std::vector<Index>& fixed, Eigen::Index free_vertices) {
  const auto start = Clock::now();
  const int guard = refinement_guard(k, refinement, free_vertices);
  fem::Eigenpairs pairs = fem::smallest_eigenpairs_dirichlet(L, M, fixed, k + guard, options);
  Eigenbasis basis;
  basis.eigensolve_seconds = seconds_since(start);
  basis.restarts = pairs.restarts;
  basis.refined = true;
  basis.fine_eigensolve = true;
  basis.guard = guard;
  // Zero modes judged against all k + guard pairs, as refine_eigenpairs judges them.
  basis.residuals = fem::eigen_residuals(L, M, pairs.values, pairs.vectors, fixed).head(k);
  basis.residual_history = {basis.residuals.maxCoeff()};
  if (basis.residuals.maxCoeff() > refinement.tolerance) {
    const auto refine_start = Clock::now();
    fem::CholeskySolver inverse;
    inverse.compute(shifted_free_block(L, M, preconditioner_shift(pairs.values, L, M), fixed));
    const fem::BlockPreconditioner exact = [&inverse](const Eigen::MatrixXd& R) { return inverse.solve_multiple(R); };
    fem::EigenRefineOptions refine;
    refine.tolerance = refinement.tolerance;
    refine.max_iterations = refinement.max_iterations;
    record_refinement(basis, fem::refine_eigenpairs(L, M, pairs.values, pairs.vectors, k, exact, fixed, refine));
    basis.refine_seconds = seconds_since(refine_start);
  }
  basis.converged = basis.residuals.maxCoeff() <= refinement.tolerance;
  basis.values = pairs.values.head(k);
  pairs.vectors.conservativeResize(Eigen::NoChange, k);
  basis.vectors = std::move(pairs.vectors);
  return basis;
}

}  // namespace

EigenSolver::EigenSolver(const TriangleMesh& mesh, EigenbasisOptions options, std::optional<CoarseSpace> coarse)
    : options_(std::move(options)) {
  // Galerkin operators: the prolonged vectors are then M-orthonormal with Rayleigh quotients λ (eigen.h).
  // Dirichlet: the boundary vertices stay coarse vertices (locked), so the coarse functions that
  // vanish there vanish on the whole fine boundary.
  const bool dirichlet = options_.boundary == EigenBoundary::dirichlet;
  if (dirichlet) dirichlet_ = fem::boundary_vertices(mesh.F);
  ProxySetupOptions setup;
  setup.coarsening = options_.coarsening;
  setup.locked = dirichlet_;
  setup.fine = options_.fine;
  setup.operators = fem::CoarseOperatorKind::galerkin;
  setup.prolongation = options_.prolongation;
  setup.prolongation_use = ProlongationUse::eigenpairs;
  setup.dirichlet = !dirichlet_.empty();
  setup.store = Store(options_.store);
  const EigenRefinement& refine = options_.refine;
  if (refine.tolerance < 0 || !std::isfinite(refine.tolerance) || refine.max_iterations < 1 ||
      !(refine.coarse_tolerance > 0) || !std::isfinite(refine.coarse_tolerance))
    throw std::invalid_argument(
        "eigenbasis: the refinement needs tolerance >= 0 (0: none), max_iterations >= 1 and coarse_tolerance > 0");
  const bool refining = refine.tolerance > 0;
  setup.fine_operators = refining;  // a restored proxy makes its fine Laplacian from a copy of the mesh
  setup_ = build_proxy_setup(mesh, setup, std::move(coarse));
  if (refining && refinement_needs_hierarchy(*setup_.proxy)) {
    setup_.proxy->fine_laplacian();  // made now, while `mesh` is at hand
    HierarchyOptions hierarchy = refine.hierarchy;
    hierarchy.nonmanifold = options_.coarsening.nonmanifold;  // the proxy's choice, made once
    hierarchy_ = multigrid_hierarchy(mesh, hierarchy, Store(options_.store));
  }
}

Eigenbasis EigenSolver::compute(int k) const {
  const Store store(options_.store);
  if (options_.refine.tolerance > 0)
    return refined_eigenbasis(*setup_.proxy, hierarchy_, k, options_.refine, options_.eigen, dirichlet_, store);
  return proxy_eigenbasis(*setup_.proxy, k, options_.eigen, dirichlet_, store);
}

int refinement_guard(int k, const EigenRefinement& refinement, Eigen::Index coarse_free_vertices) {
  const long long wanted = refinement.guard >= 0 ? refinement.guard : std::max(4LL, (static_cast<long long>(k) + 3) / 4);
  return static_cast<int>(std::max<long long>(0, std::min<long long>(wanted, coarse_free_vertices - 1 - k)));
}

Index refined_coarse_vertices(int k, const EigenRefinement& refinement, Index dirichlet_vertices) {
  if (k < 1 || refinement.coarse_vertices_per_pair < 1 || dirichlet_vertices < 0)
    throw std::invalid_argument(
        "refined_coarse_vertices: k >= 1, coarse_vertices_per_pair >= 1 and dirichlet_vertices >= 0 are needed");
  // The guard's and the directions' own rules, with a coarse space too large to cap them.
  constexpr Eigen::Index unbounded = std::numeric_limits<Index>::max() / 4;
  const int guard = refinement_guard(k, refinement, unbounded);
  const long long pairs = static_cast<long long>(k) + guard + refinement_coarse_directions(k, guard, refinement, unbounded);
  return static_cast<Index>(std::min<long long>(pairs * refinement.coarse_vertices_per_pair + dirichlet_vertices,
                                                std::numeric_limits<Index>::max()));
}

int refinement_coarse_directions(int k, int guard, const EigenRefinement& refinement, Eigen::Index coarse_free_vertices) {
  const long long wanted = refinement.coarse_directions >= 0 ? refinement.coarse_directions : 2LL * (k + guard);
  return static_cast<int>(std::max<long long>(0, std::min<long long>(wanted, coarse_free_vertices - 1 - k - guard)));
}

Eigenbasis refined_eigenbasis(const fem::CoarseProxy& proxy, const MultigridHierarchy& hierarchy, int k,
                              const EigenRefinement& refinement, const fem::EigenOptions& options,
                              const std::vector<Index>& dirichlet_vertices, const Store& store) {
  if (!(refinement.tolerance > 0) || !std::isfinite(refinement.tolerance))
    throw std::invalid_argument("refined_eigenbasis: the tolerance must be > 0");
  if (!(refinement.coarse_tolerance > 0) || !std::isfinite(refinement.coarse_tolerance))
    throw std::invalid_argument("refined_eigenbasis: the coarse tolerance must be > 0");
  std::vector<Index> coarse_fixed;
  const Eigen::Index coarse_free = free_coarse_vertices(proxy, dirichlet_vertices, coarse_fixed);
  require_pair_count(k, coarse_free, !coarse_fixed.empty());  // before the coarse eigensolve of k + guard + directions pairs
  const fem::SparseMatrix& input_L = proxy.fine_laplacian();
  if (!refinement_needs_hierarchy(proxy))
    return fine_pencil_eigenbasis(input_L, proxy.fine_mass(), k, refinement, options, dirichlet_vertices, coarse_free);
  if (hierarchy.fine_vertices != input_L.rows())
    throw std::invalid_argument("refined_eigenbasis: the hierarchy has " + std::to_string(hierarchy.fine_vertices) +
                                " fine vertices, the proxy " + std::to_string(input_L.rows()));
  const int guard = refinement_guard(k, refinement, coarse_free);
  const int directions = refinement_coarse_directions(k, guard, refinement, coarse_free);
  // One coarse eigensolve for the start (k + guard pairs, prolonged) and the coarse directions: by
  // subspace iteration, which converges the start pairs only as far as the refinement can use and
  // leaves the directions as approximate pairs (the Lanczos eigensolver took ~4 times as long for
  // all of them to its tolerance: docs/measurements.md, "The refined route's coarse eigensolve").
  // Its start pairs converge at about λ_(k+guard) / λ_count per iteration: at most ~1/2 (eigenvalues
  // about linear in their index) when the directions are at least as many as the start pairs; with
  // fewer (a small coarse space, or LOBPCG's none) the Lanczos eigensolver, which needs no such gap.
  Eigen::MatrixXd coarse_vectors;
  CoarsePairsMethod method;
  method.lanczos = options;
  fem::SubspaceIterationOptions subspace;
  subspace.tolerance = refinement.coarse_tolerance;
  subspace.ordering = options.ordering;
  if (directions >= k + guard) {
    method.subspace = &subspace;
    method.accurate = k + guard;
  }
  Eigenbasis basis = coarse_basis(proxy, k + guard + directions, k + guard, method, dirichlet_vertices, store, &coarse_vectors);
  const auto start = Clock::now();
  // The refinement runs in the hierarchy's breadth-first numbering of the fine vertices (its
  // fine_order): there a vertex's neighbours sit close in memory, so the products with L and P and
  // the V-cycles' gathers stream instead of jumping over the mesh (an input numbering such as Loop
  // subdivision's scatters them). The vectors are turned back to the input's numbering at the end.
  const std::vector<Index>& order = hierarchy.fine_order;  // order[new] = old; empty: as it is
  const bool renumbered = !order.empty();
  fem::SparseMatrix renumbered_L, renumbered_M, renumbered_P;
  std::vector<Index> fixed = dirichlet_vertices;
  std::vector<fem::SparseMatrix> prolongations;
  prolongations.reserve(hierarchy.prolongations.size());
  for (std::size_t level = 0; level < hierarchy.prolongations.size(); ++level)
    prolongations.push_back(renumbered && level == 0
                                ? fem::permute_rows(hierarchy.prolongations[0], order)
                                : hierarchy.prolongations[level]);
  if (renumbered) {
    renumbered_L = fem::permute_symmetric(input_L, order);
    renumbered_M = fem::permute_symmetric(proxy.fine_mass(), order);
    renumbered_P = fem::permute_rows(proxy.prolongation(), order);
    std::vector<Index> new_index(order.size());
    for (std::size_t i = 0; i < order.size(); ++i) new_index[static_cast<std::size_t>(order[i])] = static_cast<Index>(i);
    for (Index& v : fixed) v = new_index[static_cast<std::size_t>(v)];
  }
  const fem::SparseMatrix& L = renumbered ? renumbered_L : input_L;
  const fem::SparseMatrix& M = renumbered ? renumbered_M : proxy.fine_mass();
  fem::EigenCoarseDirections coarse;
  if (directions > 0) {
    coarse.prolongation = renumbered ? &renumbered_P : &proxy.prolongation();
    coarse.coarse_vectors = coarse_vectors.rightCols(directions);
    coarse.laplacian_gram = coarse.coarse_vectors.transpose() * (proxy.coarse_laplacian() * coarse.coarse_vectors);
    coarse.mass_gram = coarse.coarse_vectors.transpose() * (proxy.coarse_mass() * coarse.coarse_vectors);
  }
  coarse_vectors.resize(0, 0);
  // The preconditioner: one V-cycle of L + σM (symmetric positive definite for any σ > 0). σ is
  // the scale of the modes sought, the smallest positive coarse eigenvalue (an upper bound of the
  // fine one); with zero modes only, the inverse area (λ·area is of order 10 for the lowest modes
  // of compact surfaces).
  const double sigma = preconditioner_shift(basis.values, L, M);
  fem::MultigridOptions cycle;
  cycle.mode = fem::MultigridMode::vcycle;  // the finest level smoothed in double precision
  fem::MultigridSolver multigrid(std::move(prolongations), cycle);
  if (renumbered) {  // already in the locality order
    std::vector<Index> identity(order.size());
    std::iota(identity.begin(), identity.end(), 0);
    multigrid.set_locality_order(std::move(identity));
  }
  multigrid.setup(fem::SparseMatrix(L + sigma * M), fixed);
  // In place: no copy of the residuals' columns and no block of V-cycle results beside X and R.
  const fem::InPlacePreconditioner precondition = [&multigrid](const Eigen::MatrixXd& R,
                                                               const std::vector<Eigen::Index>& columns, Eigen::MatrixXd& X) {
    multigrid.subtract_vcycle_columns(R, columns, X);
  };
  fem::EigenRefineOptions refine;
  refine.tolerance = refinement.tolerance;
  refine.max_iterations = refinement.max_iterations;
  Eigen::VectorXd values = std::move(basis.values);
  Eigen::MatrixXd vectors = std::move(basis.vectors);
  if (renumbered) permute_rows_in_place(vectors, order, true);
  const fem::EigenRefineReport report =
      fem::refine_eigenpairs(L, M, values, vectors, k, precondition, fixed, refine, directions > 0 ? &coarse : nullptr);
  basis.values = values.head(k);
  vectors.conservativeResize(Eigen::NoChange, k);
  if (renumbered) permute_rows_in_place(vectors, order, false);
  basis.vectors = std::move(vectors);
  basis.refined = true;
  record_refinement(basis, report);
  basis.guard = guard;
  basis.coarse_directions = directions;
  basis.refine_seconds = seconds_since(start);
  return basis;
}

Eigenbasis proxy_eigenbasis(const fem::CoarseProxy& proxy, int k, const fem::EigenOptions& options,
                            const std::vector<Index>& dirichlet_vertices, const Store& store) {
  CoarsePairsMethod method;
  method.lanczos = options;
  return coarse_basis(proxy, k, k, method, dirichlet_vertices, store, nullptr);
}

Eigenbasis eigenbasis(const TriangleMesh& mesh, int k, const EigenbasisOptions& options) {
  return EigenSolver(mesh, options).compute(k);
}

Eigen::MatrixXd heat_kernel_signature(const Eigenbasis& basis, const Eigen::VectorXd& times) {
  const Eigen::MatrixXd squares = basis.vectors.array().square();
  Eigen::MatrixXd weights(basis.values.size(), times.size());
  for (Eigen::Index t = 0; t < times.size(); ++t) {
    if (!(times(t) > 0)) throw std::invalid_argument("heat_kernel_signature: times must be > 0");
    weights.col(t) = (-times(t) * basis.values.cwiseMax(0.0).array()).exp().matrix();
  }
  return squares * weights;
}

Eigen::MatrixXd wave_kernel_signature(const Eigenbasis& basis, const Eigen::VectorXd& energies, double wks_sigma) {
  if (!(wks_sigma > 0)) throw std::invalid_argument("wave_kernel_signature: sigma must be > 0");
  const double largest = basis.values.size() > 0 ? basis.values.cwiseAbs().maxCoeff() : 0.0;
  const Eigen::MatrixXd squares = basis.vectors.array().square();
  Eigen::MatrixXd weights = Eigen::MatrixXd::Zero(basis.values.size(), energies.size());
  for (Eigen::Index e = 0; e < energies.size(); ++e) {
    double total = 0;
    for (Eigen::Index i = 0; i < basis.values.size(); ++i) {
      if (!(basis.values(i) > 0) || fem::is_zero_mode(basis.values(i), largest)) continue;  // zero modes carry no energy
      const double d = energies(e) - std::log(basis.values(i));
      weights(i, e) = std::exp(-d * d / (2 * wks_sigma * wks_sigma));
      total += weights(i, e);
    }
    if (total > 0) weights.col(e) /= total;
  }
  return squares * weights;
}

double median(Eigen::VectorXd v) {
  if (v.size() == 0) return 0;
  std::sort(v.data(), v.data() + v.size());
  const Eigen::Index m = v.size() / 2;
  return v.size() % 2 ? v(m) : 0.5 * (v(m - 1) + v(m));
}

EigenbasisErrors eigenbasis_errors(const Eigen::VectorXd& values, const Eigen::MatrixXd& vectors,
                                   const fem::Eigenpairs& reference, const fem::SparseMatrix& M) {
  const Eigen::Index k = values.size();
  if (vectors.cols() != k || reference.values.size() < k || reference.vectors.cols() != reference.values.size() ||
      reference.vectors.rows() != vectors.rows() || M.rows() != vectors.rows() || M.cols() != vectors.rows())
    throw std::invalid_argument("eigenbasis_errors: " + std::to_string(k) + " values, " + std::to_string(vectors.cols()) +
                                " vectors of " + std::to_string(vectors.rows()) + " rows against " +
                                std::to_string(reference.values.size()) + " reference pairs of " +
                                std::to_string(reference.vectors.rows()) + " rows");
  EigenbasisErrors errors;
  errors.angles = fem::eigenspace_angles(vectors, reference.vectors, reference.values, M);
  errors.relative = Eigen::VectorXd::Zero(k);
  const double largest = reference.values.head(k).cwiseAbs().maxCoeff();
  std::vector<double> relative;
  for (Eigen::Index j = 0; j < k; ++j) {
    if (fem::is_zero_mode(reference.values(j), largest)) {
      ++errors.zero_modes;
      continue;
    }
    errors.relative(j) = std::abs(values(j) - reference.values(j)) / reference.values(j);
    relative.push_back(errors.relative(j));
  }
  const Eigen::VectorXd nonzero = Eigen::Map<const Eigen::VectorXd>(relative.data(), static_cast<Eigen::Index>(relative.size()));
  errors.relative_median = median(nonzero);
  errors.relative_max = nonzero.size() ? nonzero.maxCoeff() : 0.0;
  errors.angle_median = median(errors.angles);
  errors.angle_max = k ? errors.angles.maxCoeff() : 0.0;
  return errors;
}

double reconstruction_error(const Eigenbasis& basis, const Eigen::VectorXd& mass, const Eigen::VectorXd& f) {
  if (mass.size() != basis.vectors.rows() || f.size() != basis.vectors.rows())
    throw std::invalid_argument("reconstruction_error: the mass and f need one entry per vertex");
  const Eigen::VectorXd Mf = mass.cwiseProduct(f);
  const double norm2 = f.dot(Mf);
  if (!(norm2 > 0)) return 0;
  const Eigen::VectorXd residual = f - basis.vectors * (basis.vectors.transpose() * Mf);
  return std::sqrt(residual.dot(mass.cwiseProduct(residual)) / norm2);
}

}  // namespace ice::proxy
