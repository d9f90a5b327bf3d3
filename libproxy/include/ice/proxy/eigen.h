#pragma once
/// \file eigen.h
/// The Laplace–Beltrami eigenbasis of a triangle mesh through a coarse proxy: the k smallest
/// eigenpairs of L φ = λ M φ (cotan L, lumped M, Neumann boundary), approximated by the coarse
/// Galerkin problem (PᵀLP) ψ = λ (PᵀMP) ψ and prolonged, φ = P ψ. eigenbasis in one call, or an
/// EigenSolver set up once (the proxy, from the store when it holds it) and asked for any k.
///
/// Why the prolonged vectors are a basis: with Galerkin operators, φᵢᵀ M φⱼ = ψᵢᵀ (PᵀMP) ψⱼ = δᵢⱼ and
/// φᵢᵀ L φⱼ = λᵢ δᵢⱼ exactly, so the φ are M-orthonormal on the input mesh and each λ is the Rayleigh
/// quotient of its φ: an upper bound of the fine eigenvalue of the same index (Courant–Fischer).
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "fem/eigen.h"
#include "ice/proxy/setup.h"

namespace ice::proxy {

/// The boundary condition of the eigenproblem on meshes with a boundary.
enum class EigenBoundary {
  neumann,    ///< natural (zero normal derivative): the default; constants are eigenfunctions
  dirichlet,  ///< φ = 0 on the boundary: the boundary vertices are kept by the coarsening
};

struct EigenbasisOptions {
  /// How the coarse space is made when none is given (as PoissonOptions::coarsening).
  CoarseSpaceOptions coarsening = default_coarsening(ProxyUse::poisson_heat);
  FineGeometry fine = FineGeometry::intrinsic_delaunay;
  Prolongation prolongation = Prolongation::automatic;
  EigenBoundary boundary = EigenBoundary::neumann;
  /// The coarse eigensolve's (fem::smallest_eigenpairs).
  fem::EigenOptions eigen;
  /// Where the set-up proxy is looked up and saved (store.h); off by default in the library.
  StoreOptions store;
};

/// Eigenvalues (increasing) and eigenvectors (one column per eigenvalue, one row per input vertex,
/// M-orthonormal with the input mesh's lumped mass).
struct Eigenbasis {
  Eigen::VectorXd values;
  Eigen::MatrixXd vectors;
  int restarts = 0;              ///< of the coarse Lanczos iteration
  double eigensolve_seconds = 0; ///< the coarse eigensolve (factorisation included)
  double prolong_seconds = 0;
};

class EigenSolver {
 public:
  /// Coarsens `mesh` (clean, oriented, manifold: e.g. from ice::load_mesh) by options.coarsening
  /// (with the boundary vertices locked under EigenBoundary::dirichlet), or uses `coarse` (a coarse
  /// space of `mesh`; under Dirichlet conditions every boundary vertex must be one of its vertices,
  /// else compute() throws std::invalid_argument), and sets up the Galerkin proxy. Throws
  /// std::invalid_argument on bad options.
  explicit EigenSolver(const TriangleMesh& mesh, EigenbasisOptions options = {}, std::optional<CoarseSpace> coarse = {});
  /// The k smallest eigenpairs through the proxy. Throws std::invalid_argument unless
  /// 1 <= k < the coarse vertex count (the message names both).
  Eigenbasis compute(int k) const;

  const EigenbasisOptions& options() const { return options_; }
  const CoarseSpace& coarse_space() const { return setup_.coarse; }
  const fem::CoarseProxy& proxy() const { return *setup_.proxy; }
  /// Where the setup came from (the store's status and times).
  const CacheReport& cache() const { return setup_.cache; }
  /// The Dirichlet vertices (the mesh's boundary with EigenBoundary::dirichlet), else empty.
  const std::vector<Index>& dirichlet_vertices() const { return dirichlet_; }

 private:
  EigenbasisOptions options_;
  std::vector<Index> dirichlet_;
  ProxySetup setup_;
};

/// The k smallest eigenpairs through a set-up Galerkin proxy (what EigenSolver::compute runs): the
/// coarse pencil's by fem::smallest_eigenpairs, prolonged by the proxy's P. With
/// `dirichlet_vertices` (input vertices, each a coarse vertex: locked by the coarsening, and the
/// proxy's P barycentric) the coarse pencil is restricted to the other coarse vertices, so the
/// prolonged vectors vanish there. Throws std::invalid_argument unless the proxy's operators are
/// Galerkin and 1 <= k < its free coarse size, or when a Dirichlet vertex is not a coarse vertex.
Eigenbasis proxy_eigenbasis(const fem::CoarseProxy& proxy, int k, const fem::EigenOptions& options = {},
                            const std::vector<Index>& dirichlet_vertices = {});

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
