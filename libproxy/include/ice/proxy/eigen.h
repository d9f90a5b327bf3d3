#pragma once
/// \file eigen.h
/// The Laplace–Beltrami eigenbasis of a triangle mesh through a coarse proxy: the k smallest
/// eigenpairs of L φ = λ M φ (cotan L, lumped M, Neumann boundary), approximated by the coarse
/// Galerkin problem (PᵀLP) ψ = λ (PᵀMP) ψ and prolonged, φ = P ψ. eigenbasis in one call, or an
/// EigenSolver set up once (the proxy, from the store when it holds it) and asked for any k.
///
/// Two routes: the proxy route (the default) stops there; the refined route (EigenRefinement with a
/// tolerance) improves the prolonged pairs on the input mesh until each has a relative residual
/// below the tolerance (fem::refine_eigenpairs, preconditioned by a multigrid V-cycle on the mesh's
/// ICE hierarchy, multigrid.h): the fine eigenpairs, found from a start within a few per cent.
///
/// Why the prolonged vectors are a basis: with Galerkin operators, φᵢᵀ M φⱼ = ψᵢᵀ (PᵀMP) ψⱼ = δᵢⱼ and
/// φᵢᵀ L φⱼ = λᵢ δᵢⱼ exactly, so the φ are M-orthonormal on the input mesh and each λ is the Rayleigh
/// quotient of its φ: an upper bound of the fine eigenvalue of the same index (Courant–Fischer).
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "fem/eigen.h"
#include "ice/proxy/multigrid.h"
#include "ice/proxy/setup.h"

namespace ice::proxy {

/// The boundary condition of the eigenproblem on meshes with a boundary.
enum class EigenBoundary {
  neumann,    ///< natural (zero normal derivative): the default; constants are eigenfunctions
  dirichlet,  ///< φ = 0 on the boundary: the boundary vertices are kept by the coarsening
};

/// The refined route (fem::refine_eigenpairs on the input mesh's pencil).
struct EigenRefinement {
  /// Refine until every returned pair has a relative residual ‖Lφ − λMφ‖₂ / (|λ| ‖Mφ‖₂) at most this
  /// (fem::refine_eigenpairs; Eigenbasis::converged says whether it did); 0: no refinement (the
  /// proxy route).
  double tolerance = 0;
  /// Upper bound on refinement iterations (>= 1); reaching it is reported, not thrown.
  int max_iterations = 200;
  /// Pairs computed beyond k and refined along (not returned): with LOBPCG the k-th pair converges
  /// at a rate set by the gap λ_k / λ_{k+guard+1}; with coarse directions they keep a cluster of
  /// eigenvalues across λ_k from splitting between the refined vectors and the coarse ones. < 0:
  /// max(4, ⌈k/4⌉) (eigenvalues grow about linearly with their index on a surface, so a quarter
  /// more pairs keeps that ratio near 0.8 at any k), capped by the coarse space's size.
  int guard = -1;
  /// Coarse eigenvectors beyond the k + guard refined, prolonged, that every Rayleigh–Ritz step adds
  /// (fem::refine_eigenpairs's augmented subspace method; they come from the same coarse eigensolve,
  /// through the store). They hold the error components that a V-cycle step leaves, those of the
  /// eigenvalues just above the ones sought; the coarse space approximates the first few times k of
  /// them well. < 0: 2·(k + guard) (with eigenvalues about linear in their index, directions up to
  /// about three times λ_k), capped by the coarse space's size; 0: none, LOBPCG instead. The coarse
  /// eigensolve is asked for k + guard + coarse_directions pairs (a fem::EigenOptions::basis_size
  /// must exceed that), and the store keys its pairs by that count.
  int coarse_directions = -1;
  /// The coarse eigensolve of this route (fem::subspace_eigenpairs) stops when the k + guard start
  /// pairs have coarse relative residuals at most this (> 0); the coarse directions only span the
  /// low spectrum. The prolonged start pairs have fine residuals of order 1 (the coarse space's
  /// discretisation error), which the first refinement step reduces, so a coarse residual well
  /// below that changes nothing but the coarse eigensolve's time (docs/measurements.md, "The
  /// refined route's coarse eigensolve").
  double coarse_tolerance = 1e-3;
  /// The coarse space's size for this route when the caller names none (refined_coarse_vertices):
  /// this many coarse vertices per coarse pair the route computes (k + guard + coarse directions).
  /// By Weyl's law the j-th eigenvalue of a surface grows linearly in j, and a piecewise-linear space
  /// of N vertices resolves eigenvalue λ with a relative error of order λ h² ∝ λ / N: so the ratio
  /// N / pairs, not the mesh's size, sets how well the coarse space holds the pairs the iteration
  /// starts from and is augmented with. The refinement then corrects what the coarse space misses,
  /// while the coarse eigensolve's cost grows quickly with N.
  int coarse_vertices_per_pair = 20;
  /// The multigrid hierarchy whose V-cycle on L + σM preconditions the refinement (σ: the smallest
  /// positive coarse eigenvalue, a scale of the lowest modes); through the store when it is on.
  HierarchyOptions hierarchy;
};

struct EigenbasisOptions {
  /// How the coarse space is made when none is given (as PoissonOptions::coarsening).
  CoarseSpaceOptions coarsening = default_coarsening(ProxyUse::poisson_heat);
  FineGeometry fine = FineGeometry::intrinsic_delaunay;
  Prolongation prolongation = Prolongation::automatic;
  EigenBoundary boundary = EigenBoundary::neumann;
  /// The coarse eigensolve's (fem::smallest_eigenpairs).
  fem::EigenOptions eigen;
  /// Off by default (the proxy route).
  EigenRefinement refine;
  /// Where the set-up proxy, the coarse eigenpairs (proxy_eigenbasis) and the refinement's hierarchy
  /// are looked up and saved (store.h); off by default in the library.
  StoreOptions store;
};

/// Eigenvalues (increasing) and eigenvectors (one column per eigenvalue, one row per input vertex,
/// M-orthonormal with the input mesh's lumped mass).
struct Eigenbasis {
  Eigen::VectorXd values;
  Eigen::MatrixXd vectors;
  int restarts = 0;              ///< of the coarse Lanczos iteration (of all the coarse pairs when refined)
  /// The coarse eigensolve (factorisation included; k + guard + coarse-direction pairs when refined), or the load of
  /// its stored pairs with their checks (cache.status hit); a save is in cache.save_seconds.
  double eigensolve_seconds = 0;
  /// Where the coarse pairs came from: the store's "eigenpairs" entry (status off without a store).
  CacheReport cache;
  double prolong_seconds = 0;
  /// The refined route only: whether every pair reached the tolerance, the iterations, the pairs'
  /// relative residuals (fem::eigen_residuals) and the refinement's time (preconditioner set-up
  /// included; the hierarchy's build is the solver's set-up).
  bool refined = false;
  bool converged = false;
  /// The refined route on a coarse space as large as the mesh (not coarsened): nothing coarser to
  /// start from, so the fine pencil's k + guard pairs come from fem::smallest_eigenpairs directly (in
  /// eigensolve_seconds), refined (LOBPCG, the exact (L + σM)⁻¹ as preconditioner) only when the
  /// tolerance is below the residuals the eigensolver reached.
  bool fine_eigensolve = false;
  int refine_iterations = 0;
  int guard = 0;
  int coarse_directions = 0;  ///< of the refinement (0: LOBPCG)
  Eigen::VectorXd residuals;
  /// The largest relative residual of the k pairs before the first iteration and after each.
  std::vector<double> residual_history;
  double refine_seconds = 0;
  double precondition_seconds = 0;  ///< of refine_seconds: V-cycles
  /// Of refine_seconds: the products with L, the n-row dense products, the coarse directions'
  /// restrictions and prolongations (fem::EigenRefineReport).
  double refine_sparse_seconds = 0, refine_dense_seconds = 0, refine_coarse_seconds = 0;
};

class EigenSolver {
 public:
  /// Coarsens `mesh` (clean, oriented, manifold: e.g. from ice::load_mesh) by options.coarsening
  /// (with the boundary vertices locked under EigenBoundary::dirichlet), or uses `coarse` (a coarse
  /// space of `mesh`; under Dirichlet conditions every boundary vertex must be one of its vertices,
  /// else compute() throws std::invalid_argument), and sets up the Galerkin proxy; with
  /// options.refine.tolerance > 0 also the multigrid hierarchy of `mesh` (the refined route).
  /// Throws std::invalid_argument on bad options.
  explicit EigenSolver(const TriangleMesh& mesh, EigenbasisOptions options = {}, std::optional<CoarseSpace> coarse = {});
  /// The k smallest eigenpairs through the proxy, refined with options.refine.tolerance > 0
  /// (refined_eigenbasis). Throws std::invalid_argument unless 1 <= k < the coarse vertex count
  /// (the message names both).
  Eigenbasis compute(int k) const;

  const EigenbasisOptions& options() const { return options_; }
  const CoarseSpace& coarse_space() const { return setup_.coarse; }
  const fem::CoarseProxy& proxy() const { return *setup_.proxy; }
  /// Where the setup came from (the store's status and times).
  const CacheReport& cache() const { return setup_.cache; }
  /// The refined route's multigrid hierarchy (empty without a refinement tolerance, or when the
  /// coarse space is as large as the mesh).
  const MultigridHierarchy& hierarchy() const { return hierarchy_; }
  /// The Dirichlet vertices (the mesh's boundary with EigenBoundary::dirichlet), else empty.
  const std::vector<Index>& dirichlet_vertices() const { return dirichlet_; }

 private:
  EigenbasisOptions options_;
  std::vector<Index> dirichlet_;
  ProxySetup setup_;
  MultigridHierarchy hierarchy_;
};

/// The k smallest eigenpairs through a set-up Galerkin proxy (what EigenSolver::compute runs): the
/// coarse pencil's by fem::smallest_eigenpairs, prolonged by the proxy's P. With
/// `dirichlet_vertices` (input vertices, each a coarse vertex: locked by the coarsening, and the
/// proxy's P barycentric) the coarse pencil is restricted to the other coarse vertices, so the
/// prolonged vectors vanish there. Throws std::invalid_argument unless the proxy's operators are
/// Galerkin and 1 <= k < its free coarse size, or when a Dirichlet vertex is not a coarse vertex.
///
/// With `store` on, the coarse pairs are looked up in it and saved there ("eigenpairs" entries, keyed
/// by the coarse pencil's arrays, the Dirichlet coarse vertices, k and `options`; Eigenbasis::cache
/// says which): a second eigenbasis of the same proxy and k loads them instead of solving, the same
/// numbers to the last bit. A stored entry is used only if its pairs are this pencil's (residuals
/// recomputed and matched against those stored with them, M-orthonormality, order); else it is
/// rebuilt.
Eigenbasis proxy_eigenbasis(const fem::CoarseProxy& proxy, int k, const fem::EigenOptions& options = {},
                            const std::vector<Index>& dirichlet_vertices = {}, const Store& store = {});

/// The refined route on a set-up Galerkin proxy (what EigenSolver::compute runs with a tolerance):
/// the coarse pencil's k + guard + coarse-direction pairs (as proxy_eigenbasis), the first k + guard
/// prolonged, then fem::refine_eigenpairs on the proxy's fine pencil (its fine Laplacian and lumped
/// mass) with the others as its coarse directions, preconditioned by one V-cycle of L + σM over `hierarchy`
/// (a hierarchy of the proxy's fine mesh: its level 0 has the fine vertex count), with φ = 0 kept
/// at `dirichlet_vertices`. Returns the first k pairs. Throws as proxy_eigenbasis, and
/// std::invalid_argument when refinement.tolerance is not > 0 or the hierarchy's size differs.
/// The coarse pairs come through `store` as proxy_eigenbasis's. A proxy that is not coarser than its
/// mesh (as many coarse vertices as fine ones) gets the fine pencil's pairs from
/// fem::smallest_eigenpairs directly instead (Eigenbasis::fine_eigensolve; `hierarchy` and `store`
/// unused).
Eigenbasis refined_eigenbasis(const fem::CoarseProxy& proxy, const MultigridHierarchy& hierarchy, int k,
                              const EigenRefinement& refinement, const fem::EigenOptions& options = {},
                              const std::vector<Index>& dirichlet_vertices = {}, const Store& store = {});

/// Whether refined_eigenbasis on `proxy` refines through a multigrid hierarchy: only when the proxy is
/// coarser than its mesh (else it solves the fine pencil directly and needs none).
inline bool refinement_needs_hierarchy(const fem::CoarseProxy& proxy) { return proxy.coarse_size() < proxy.fine_size(); }

/// The guard pairs refined_eigenbasis adds to k (EigenRefinement::guard), given the coarse space's
/// free vertex count.
int refinement_guard(int k, const EigenRefinement& refinement, Eigen::Index coarse_free_vertices);
/// The coarse directions refined_eigenbasis adds to k + guard (EigenRefinement::coarse_directions),
/// given the coarse space's free vertex count.
int refinement_coarse_directions(int k, int guard, const EigenRefinement& refinement, Eigen::Index coarse_free_vertices);

/// The coarse vertex count for the refined route's k pairs when the caller names none:
/// refinement.coarse_vertices_per_pair × (k + guard + coarse directions), with the guard and the
/// directions as refinement asks for them, uncapped, plus `dirichlet_vertices` (the boundary
/// vertices EigenBoundary::dirichlet has the coarsening keep: they hold no free unknown). What
/// spectral-coarse (--tolerance without --ratio or --vertices) and Python's eigenbasis use, at most
/// the mesh. Throws std::invalid_argument unless k >= 1, coarse_vertices_per_pair >= 1 and
/// dirichlet_vertices >= 0.
Index refined_coarse_vertices(int k, const EigenRefinement& refinement, Index dirichlet_vertices = 0);

/// EigenSolver(mesh, options).compute(k).
Eigenbasis eigenbasis(const TriangleMesh& mesh, int k, const EigenbasisOptions& options = {});

/// How an eigenbasis compares with a reference one of the same pencil (e.g. the fine mesh's, by
/// fem::smallest_eigenpairs): what spectral-coarse and ice-report report.
struct EigenbasisErrors {
  /// |λ − λ_ref| / λ_ref per pair; 0 where the reference value is a zero mode (fem::is_zero_mode:
  /// a constant per component), which the statistics below leave out.
  Eigen::VectorXd relative;
  /// Per pair, the angle (radians, M inner product) to the reference eigenspace of its value
  /// (fem::eigenspace_angles, which widens it over nearly repeated values).
  Eigen::VectorXd angles;
  int zero_modes = 0;
  /// Over the pairs that are not zero modes (0 when there are none): median and largest relative
  /// error; over all pairs: median and largest angle. A median of an even count is the mean of the
  /// two middle values.
  double relative_median = 0, relative_max = 0, angle_median = 0, angle_max = 0;
};

/// `values` and `vectors` (k pairs, one column per value, M-orthonormal) against `reference` (at
/// least k pairs, increasing). Throws std::invalid_argument when the counts or row counts disagree
/// or M is not square of the vectors' row count.
EigenbasisErrors eigenbasis_errors(const Eigen::VectorXd& values, const Eigen::MatrixXd& vectors,
                                   const fem::Eigenpairs& reference, const fem::SparseMatrix& M);

/// The median of `v` (0 when empty; the mean of the two middle values of an even count).
double median(Eigen::VectorXd v);

/// Spectral descriptors of a basis (values λ, M-orthonormal vectors Φ), one row per vertex, one
/// column per time or energy:
/// - heat kernel signature HKS(x, t) = Σᵢ exp(−λᵢ t) φᵢ(x)²;
/// - wave kernel signature WKS(x, e) = Σᵢ exp(−(e − log λᵢ)² / (2σ²)) φᵢ(x)² / Σᵢ exp(−(e − log λᵢ)² / (2σ²)),
///   over the pairs with λ > 0, σ = `wks_sigma` (> 0); e are log-energies.
Eigen::MatrixXd heat_kernel_signature(const Eigenbasis& basis, const Eigen::VectorXd& times);
Eigen::MatrixXd wave_kernel_signature(const Eigenbasis& basis, const Eigen::VectorXd& energies, double wks_sigma);

/// The relative error, in the M norm, of f's projection onto the basis: ‖f − Φ Φᵀ M f‖_M / ‖f‖_M
/// (0 for f = 0). `mass` is the lumped mass the basis is orthonormal in (one entry per vertex).
double reconstruction_error(const Eigenbasis& basis, const Eigen::VectorXd& mass, const Eigen::VectorXd& f);

}  // namespace ice::proxy
