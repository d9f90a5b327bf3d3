#pragma once
/// \file coarse_proxy.h
/// Solving a fine-mesh PDE through a small coarse proxy: restrict the data, solve on the coarse
/// mesh, prolong the solution with P.
///
/// Inputs: the fine intrinsic mesh (F, L), the coarse one (Fc, Lc) (ice::IntrinsicMesh values), and a prolongation P
/// (n_fine × n_coarse, every row sums to 1, typically the barycentric coordinates of each fine vertex
/// in a coarse face). Coarse operators come in two flavours:
///  - intrinsic: cotan Laplacian and mass assembled from the coarse lengths Lc;
///  - Galerkin: Lc = Pᵀ L P and Mc = Pᵀ M P from the fine operators (the variational restriction;
///    Fc and Lc are then only used for coarse boundary detection and the heat-method time step).
///
/// What is restricted, and how:
///  - Poisson (zero mean): the mass-weighted fine right-hand side, b_c = Pᵀ M f. Rows of P summing to
///    1 means 1ᵀ b_c = 1ᵀ M f, so compatibility (zero total source) carries over to the coarse mesh.
///    The prolonged solution P u_c is re-centred to zero fine-mass mean.
///  - Heat: the initial nodal values u₀, either by L² projection (solve M_c u_c = Pᵀ M u₀; exact
///    L² projection onto span P with Galerkin operators) or by injection (u_c(j) = u₀ at the fine
///    vertex that coincides with coarse vertex j, read off P as the row equal to e_j).
///  - Geodesic distance (ProxyGeodesicSolver), by one of two coarse solvers:
///    marching (the default): fast marching with exact planar updates on the coarse intrinsic mesh
///    from the sources' points (each source seeds the corners of its coarse face at their planar
///    distances from it; a vertex that a later face finds nearer, behind an obtuse face, is
///    reopened — which the distance oracle's all-pairs marching does not do), carried to the fine
///    vertices by interpolating the *squared* distance as the distance oracle does
///    (fem/distance_oracle.h): d(y)² = Σ_j μ_j d(q_j)² − Σ_{j<k} μ_j μ_k |q_j q_k|² over P's row of
///    y, exact inside the source's face and wherever one virtual source reaches y's face; heat_method: a fine source vertex becomes the coarse source weights Pᵀ e_s,
///    the coarse heat method solves, and the distance is prolonged with P and shifted so that it
///    vanishes (on average) at the fine sources.
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "fem/curvature_correction.h"
#include "fem/distance_oracle.h"
#include "fem/operators.h"
#include "fem/problems.h"
#include "fem/topology.h"

namespace fem {

namespace detail {
class MarchingMesh;
}

enum class CoarseOperatorKind { intrinsic, galerkin };
enum class RestrictionKind { l2_projection, injection };

/// Which prolongation a CoarseProxy solves with.
enum class ProlongationKind {
  /// P as given: each fine vertex interpolated from the corners of its coarse face (at most three
  /// weights per row).
  barycentric,
  /// P smoothed by one damped Jacobi step on the fine Laplacian (smoothed_prolongation; Galerkin
  /// operators only). The coarse space it spans holds smooth functions much better: Poisson and heat
  /// through ICE coarse spaces had a clearly smaller error than with the barycentric P in every
  /// measured case, at a few more weights per row (docs/measurements.md, "Smoothed prolongation").
  /// Dirichlet problems and the coarse heat method need the
  /// barycentric P (ProxyPoissonSolver and ProxyGeodesicSolver throw std::invalid_argument), and
  /// coarse fast marching reads the barycentric one whatever this is.
  smoothed,
  /// The smoothed P smoothed once more (two damped Jacobi steps; the same conditions). Its coarse
  /// space resolves more of the smooth spectrum at the same coarse size, for more weights per row of
  /// P and denser coarse operators (docs/measurements.md, "The eigenbasis through P smoothed twice").
  smoothed_twice,
};
/// Whether `kind` smooths the given P (smoothed or smoothed_twice).
inline bool is_smoothed(ProlongationKind kind) { return kind != ProlongationKind::barycentric; }
const char* to_string(ProlongationKind kind);

/// The damping ω of smoothed_prolongation: 4/(3ρ) for ρ(D⁻¹L) = 2, the bound of the spectral radius
/// when no cotan weight is negative (an intrinsic Delaunay mesh). Chosen because it gave the same
/// error as ω from each mesh's own spectral radius, and a lower one than ω from the row-sum bound
/// where weights are negative (docs/measurements.md, "Smoothed prolongation").
constexpr double kProlongationSmoothingWeight = 2.0 / 3.0;

/// P − ω D⁻¹ L P, D = diag(L): one damped Jacobi step of each column of P (the smoothing of
/// smoothed-aggregation multigrid). Rows of L that sum to 0 (a cotan Laplacian) keep the row sums of P;
/// rows with a zero diagonal (vertices no face uses) are left as they are. Preconditions:
/// L is n × n and P n × m (std::invalid_argument otherwise); L symmetric (not checked). Exact zeros
/// are not stored; the result does not depend on the thread count.
SparseMatrix smoothed_prolongation(const SparseMatrix& P, const SparseMatrix& laplacian,
                                   double omega = kProlongationSmoothingWeight);

/// What a CoarseProxy is made of once assembled: enough to build it back without the fine mesh or
/// any assembly (CoarseProxy::arrays, and the restoring constructor), which is how a proxy is
/// stored for reuse (ice/proxy/store.h).
struct CoarseProxyArrays {
  CoarseOperatorKind kind = CoarseOperatorKind::galerkin;
  MassKind mass_kind = MassKind::lumped;
  ProlongationKind prolongation_kind = ProlongationKind::barycentric;
  SparseMatrix P;            ///< the prolongation solved with (n_fine × n_coarse)
  SparseMatrix barycentric;  ///< P as given when P is its smoothing; empty otherwise
  SparseMatrix fine_mass, coarse_laplacian, coarse_mass;
  ice::IntrinsicMesh coarse;  ///< the coarse mesh (no gluing: CoarseProxy::coarse_mesh)
};

/// How a CoarseProxy is assembled.
struct CoarseProxyOptions {
  CoarseOperatorKind kind = CoarseOperatorKind::galerkin;
  MassKind mass_kind = MassKind::lumped;
  ProlongationKind prolongation = ProlongationKind::barycentric;
};

/// Fine and coarse operators linked by P. The constructor assembles the fine mass and the coarse
/// operators; the fine Laplacian is assembled there too for Galerkin operators, and only on first
/// use (fine_laplacian()) for intrinsic ones, which do not need it; the fine gradient only for the
/// Galerkin heat-method operators. The lazy assembly is thread-safe (std::call_once).
class CoarseProxy {
 public:
  /// The proxy of `fine` through `coarse` and P (n_fine × n_coarse: the meshes' vertex counts;
  /// vertices no face uses are fine). Throws std::invalid_argument if the vertex counts are not P's
  /// shape, a mesh breaks fem::checked_vertex_count's invariants, or a row of P does not sum to 1
  /// within 1e-10.
  /// With ProlongationKind::smoothed (Galerkin operators only: std::invalid_argument otherwise) the
  /// proxy restricts, prolongs and builds its coarse operators with smoothed_prolongation(P, fine
  /// Laplacian), with smoothed_twice with that smoothed once more; P itself stays available as
  /// barycentric_prolongation().
  CoarseProxy(ice::IntrinsicMesh fine, ice::IntrinsicMesh coarse, SparseMatrix P, const CoarseProxyOptions& options = {});

  /// Fills the fine mesh of a restored proxy (its vertex count: P's rows), on first use of the fine
  /// operators.
  using FineMeshSource = std::function<void(ice::IntrinsicMesh& fine)>;
  /// A proxy built back from the arrays of one (arrays()): no assembly; the fine Laplacian and
  /// gradient, which only polishing, fine_laplacian() and the Galerkin heat method use, are
  /// assembled on first use from the fine mesh `fine_mesh` gives then.
  /// Throws std::invalid_argument when the arrays are not those of a proxy: shapes that disagree, a
  /// coarse face naming a vertex beyond P's columns, a row of the barycentric P not summing to 1,
  /// a fine mass that is not diagonal with positive entries, or a smoothed P without Galerkin operators.
  /// The arrays are taken, not copied (`arrays` is left empty).
  CoarseProxy(CoarseProxyArrays&& arrays, FineMeshSource fine_mesh);
  /// A copy of the arrays this proxy is made of.
  CoarseProxyArrays arrays() const;

  CoarseOperatorKind kind() const { return kind_; }
  MassKind mass_kind() const { return mass_kind_; }
  ProlongationKind prolongation_kind() const { return prolongation_kind_; }
  /// The prolongation the proxy solves with (smoothed or as given).
  const SparseMatrix& prolongation() const { return P_; }
  /// P as given (barycentric coordinates in coarse faces): what coarse fast marching interpolates with.
  const SparseMatrix& barycentric_prolongation() const {
    return is_smoothed(prolongation_kind_) ? barycentric_ : P_;
  }
  /// Assembled on first call for intrinsic operators.
  const SparseMatrix& fine_laplacian() const;
  const SparseMatrix& fine_mass() const { return fine_mass_; }
  const SparseMatrix& coarse_laplacian() const { return coarse_laplacian_; }
  const SparseMatrix& coarse_mass() const { return coarse_mass_; }
  /// The fine mesh the proxy was built on (a restored proxy's: made by its source on first call),
  /// without its gluing (`twin` empty: nothing here reads it).
  const ice::IntrinsicMesh& fine_mesh() const { return fine_mesh_of_lazy().mesh; }
  /// The coarse mesh's faces and lengths as given; its gluing is not kept (nothing here reads it,
  /// and a stored proxy holds none): `twin` is empty.
  const ice::IntrinsicMesh& coarse_mesh() const { return coarse_; }
  Eigen::Index fine_size() const { return P_.rows(); }
  Eigen::Index coarse_size() const { return P_.cols(); }

  /// Pᵀ b for a mass-weighted (integrated) fine vector b.
  Eigen::VectorXd restrict_weighted(const Eigen::Ref<const Eigen::VectorXd>& b) const;
  /// Coarse nodal values from fine nodal values u (see the file comment for the two kinds).
  /// Injection throws std::logic_error if some coarse vertex has no coinciding fine vertex in P.
  Eigen::VectorXd restrict_values(const Eigen::Ref<const Eigen::VectorXd>& u, RestrictionKind kind) const;
  /// P u_c.
  Eigen::VectorXd prolong(const Eigen::VectorXd& coarse_values) const;
  /// P U_c for every column of U_c (coarse size × k) in passes over a row-major P, each for a chunk
  /// of columns; each column equals prolong() of it up to the order of its sums (round-off).
  Eigen::MatrixXd prolong_block(const Eigen::MatrixXd& coarse_values) const;
  /// The coarse vertex that fine vertex v is (P's row v equal to e_j), or -1.
  int coarse_vertex_of(int fine_vertex) const;

  /// Heat-method operators of the coarse space: intrinsic ones from (Fc, Lc), or Galerkin ones
  /// (Pᵀ L P, the *lumped* Galerkin mass diag(row sums of Pᵀ M P), gradient G_fine·P on the fine
  /// faces). Time step t = (time_factor·h_c)², h_c the coarse mean edge length, in both cases;
  /// boundary vertices from Fc.
  /// Why lumped: the heat method's mass only enters its heat step, and with the consistent Galerkin
  /// mass Pᵀ M P (not diagonal) the heat solution oscillates where it is small, so the normalised
  /// gradients there point the wrong way: without lumping the error was larger and erratic in the
  /// coarse size, with it smaller and decreasing with the size (docs/measurements.md, "Lumped
  /// Galerkin mass for the coarse heat method"). For intrinsic operators the mass is already of
  /// mass_kind (lumped by default).
  HeatMethodOperators coarse_heat_method_operators(double time_factor = 1.0) const;

 private:
  CoarseOperatorKind kind_;
  MassKind mass_kind_;
  ProlongationKind prolongation_kind_;
  SparseMatrix P_;
  SparseMatrix barycentric_;  ///< P as given, kept only when P_ is its smoothing
  SparseMatrix fine_mass_, coarse_laplacian_, coarse_mass_;
  // Fine Laplacian and gradient, assembled on first use (see the class comment), and the coarse
  // mass's factor (for restrict_values' L² projection).
  struct LazyFineOperators {
    ice::IntrinsicMesh mesh;
    FineMeshSource source;  ///< a restored proxy's: fills `mesh` on first use
    std::once_flag mesh_once, laplacian_once, gradient_once;
    std::once_flag mass_factor_once;
    CholeskySolver coarse_mass_factor;  ///< for the L² projection, on its first use
    SparseMatrix laplacian, gradient;
    Eigen::VectorXd face_areas;
  };
  std::unique_ptr<LazyFineOperators> lazy_;
  /// The lazy state with the gradient and face areas made (the Laplacian: fine_laplacian()).
  const LazyFineOperators& fine_operators() const;
  /// The lazy state with its mesh made (a restored proxy's from its source).
  LazyFineOperators& fine_mesh_of_lazy() const;
  void index_coinciding_vertices(const SparseMatrix& barycentric);
  ice::IntrinsicMesh coarse_;
  std::vector<Index> coarse_to_fine_;  ///< fine vertex coinciding with each coarse vertex, or -1
  std::vector<Index> fine_to_coarse_;  ///< coarse vertex each fine vertex coincides with, or -1
};

/// The coarse vertices of fine Dirichlet vertices, in their order. Throws std::invalid_argument when
/// one is not a coarse vertex (lock it when coarsening), is given twice, or when the proxy's P is
/// smoothed (which does not take prescribed values at them).
std::vector<Index> coarse_dirichlet_vertices(const CoarseProxy& proxy, const std::vector<Index>& fine_vertices);

/// Seconds spent in each stage of one proxy solve, for callers that report phases (the tools, the
/// report, benchmarks). Factorisations happen in the solvers' constructors; time those around them.
struct ProxyPhaseTimes {
  double restriction = 0;  ///< fine data → coarse right-hand side (fine-size passes)
  double coarse_solve = 0;  ///< the coarse solves (CHOLMOD)
  double prolongation = 0;  ///< P u_c and the fine-size post-processing (re-centring, shift)
};

/// Polishing: from the plain proxy to the exact fine solution, in steps.
/// The proxy's error is mostly the interpolation error inside coarse triangles, which the coarse
/// space cannot represent. Polishing runs conjugate gradients on the *fine* system, started from the
/// prolonged proxy solution and preconditioned by a two-level cycle: symmetric Gauss–Seidel sweeps on
/// the fine matrix and an exact solve of its Galerkin coarse operator PᵀAP (fem/multigrid.h with the
/// one prolongation P). No fine factorisation: each iteration costs a few fine matrix passes plus a
/// coarse solve. Iterations stop after `iterations`, or when the estimated relative error (the
/// mass norm of the preconditioned fine residual over that of the solution, corrected by the
/// cycle's weakest eigenvalue: MultigridSolver::set_error_norm) is at most tolerance / safety,
/// whichever comes first; with a tolerance at least cycle.error_min_iterations (3) run.
struct PolishOptions {
  /// Iterations at most (0 with tolerance 0: the plain proxy, no polishing).
  int iterations = 0;
  /// Estimated relative error to reach (0: run exactly `iterations`). With a tolerance and
  /// iterations = 0, at most `max_iterations`.
  double tolerance = 0;
  int max_iterations = 1000;
  /// Stop when safety × the estimate <= tolerance (after at least
  /// MultigridOptions::error_min_iterations, 3 by default). Why: the raw estimate (mass norm of the
  /// preconditioned residual) underestimates where the two-level cycle is weak (on ICE coarse spaces
  /// a little, on QEM's much more), so it is divided by the smallest Ritz value of BA
  /// (MultigridSolver::set_error_norm), and the safety factor covers what is left: with it every
  /// tolerance was met on ICE coarse spaces in the accuracy runs; on QEM's coarse spaces the cycle is
  /// much weaker on a few meshes and the estimate can be fooled there (docs/measurements.md,
  /// "Polishing: the error estimate").
  double estimate_safety = 2;
  /// The two-level cycle (smoother, sweeps, threads); its `tolerance`, `max_iterations`,
  /// `error_tolerance` and `mode` are set from the fields above (PCG).
  MultigridOptions cycle;
  bool enabled() const { return iterations > 0 || tolerance > 0; }
};

/// What polishing did, per solve.
struct PolishReport {
  int iterations = 0;
  /// Estimated relative error of the plain proxy solution and of the returned one (mass norm; -1
  /// without polishing).
  double initial_estimated_error = -1;
  double estimated_error = -1;
  /// Before the first and after every iteration (size iterations + 1).
  std::vector<double> error_estimates;
  /// The tolerance was asked for and safety × the estimate reached it.
  bool reached_tolerance = false;
  double seconds = 0;  ///< the polishing iterations (setup is in the solver's constructor)
};

/// Poisson L u = M f on the fine mesh, approximated through the proxy: u ≈ P u_c with
/// (coarse L) u_c = Pᵀ M f.
///  - Zero-mean Neumann (no Dirichlet vertices): f is first made compatible on the fine mesh
///    (f − its mass-weighted mean, so a constant f gives u = 0 exactly), and P u_c is re-centred to
///    zero fine-mass mean. On a mesh of several components both are done per coarse component (the
///    fine vertices grouped by the component their row of P lies in) and the coarse solve pins one
///    vertex in each (PoissonSolver::zero_mean).
///  - Dirichlet: `dirichlet_vertices` are fine vertices that must be coarse vertices too (lock them
///    when coarsening: their rows of P are e_j); the coarse solve prescribes the values there, so P u_c
///    takes them exactly. Elsewhere the boundary is natural. Not with a smoothed prolongation
///    (std::invalid_argument): its rows at coarse vertices are no longer e_j.
/// The fine-size passes (M f, Pᵀ, P) are gathers, threaded with OpenMP on meshes of 50,000+ vertices
/// (OMP_NUM_THREADS, default all cores); every output entry is one ordered sum and the two mean
/// reductions are serial, so the result does not depend on the thread count.
/// Keeps a reference to the proxy (its P and fine mass, not copies), which must outlive the solver.
class ProxyPoissonSolver {
 public:
  /// Factors the coarse system; with `polish` enabled also sets up the fine two-level cycle (the
  /// fine Laplacian, PᵀLP and its factorisation, smoother data; see PolishOptions). Throws
  /// std::invalid_argument if a Dirichlet vertex is out of range, repeated or not a coarse vertex.
  explicit ProxyPoissonSolver(const CoarseProxy& proxy, std::vector<Index> dirichlet_vertices = {},
                              PolishOptions polish = {});
  /// Fine nodal source f → fine solution. `dirichlet_values` align with the Dirichlet vertices (empty:
  /// zeros). `times`, when given, receives the seconds of each stage; `polish_report` what
  /// polishing did. Not to be called on two threads at once when polishing.
  /// `f` and `fine_u0` below are Eigen::Ref: any contiguous vector (a Map of a caller's buffer, such as
  /// a numpy array) is read in place.
  Eigen::VectorXd solve(const Eigen::Ref<const Eigen::VectorXd>& f, const Eigen::VectorXd& dirichlet_values = {},
                        ProxyPhaseTimes* times = nullptr, PolishReport* polish_report = nullptr) const;
  /// solve() for every column of F (n_fine × k) at once: the fine-size passes (M, Pᵀ, P) go over
  /// the matrices once for a block of up to 32 columns, reading and writing each fine row once (Pᵀ
  /// as a scatter into the small coarse block), and the k coarse solves are one CHOLMOD call. Column
  /// j of `dirichlet_values` (one row per Dirichlet vertex; empty: zeros) is column j's values.
  /// Each column agrees with its solve() within round-off (the block kernels order their sums
  /// their own way); the result does not depend on the thread count. Polishing is per column: with
  /// polishing, each column goes through solve().
  Eigen::MatrixXd solve_block(const Eigen::Ref<const Eigen::MatrixXd>& F, const Eigen::MatrixXd& dirichlet_values = {},
                              ProxyPhaseTimes* times = nullptr) const;
  bool is_zero_mean() const { return dirichlet_vertices_.empty(); }
  bool is_polishing() const { return fine_ != nullptr; }
  /// Seconds of the polishing setup in the constructor (0 without polishing).
  double polish_setup_seconds() const { return polish_setup_seconds_; }

 private:
  const CoarseProxy* proxy_;
  Eigen::SparseMatrix<double, Eigen::RowMajor, int> P_rows_;  ///< P row-major: prolongation as a gather per row
  Eigen::VectorXd fine_mass_of_one_;                           ///< M·1 (the re-centring weights)
  double total_mass_ = 0;
  ComponentLabels fine_components_;  ///< zero-mean mode on 2+ coarse components: each fine vertex's (its row's)
  std::vector<Index> dirichlet_vertices_;
  PoissonSolver coarse_;
  PolishOptions polish_;
  std::unique_ptr<PoissonSolver> fine_;  ///< two-level multigrid on the fine system, when polishing
  double polish_setup_seconds_ = 0;
};

/// Backward-Euler heat flow on the coarse mesh: u₀ restricted (RestrictionKind), `steps` steps of
/// (Mc + τ Lc) u_{k+1} = Mc u_k, prolonged with P. With L² projection the first step's right-hand side
/// Mc u_c0 is Pᵀ M u₀ itself (the projection's defining equation), so no coarse mass solve is made.
/// Keeps a reference to the proxy, which must outlive the solver.
///
/// Polishing (PolishOptions): each fine step (M + τL) u_{k+1} = M u_k is solved by the two-level
/// PCG from the prolonged coarse state of the same step, to tolerance / steps (backward Euler is a
/// contraction in the mass norm, so the per-step errors add up at most), or for `iterations` per
/// step. The result then approaches the fine backward-Euler trajectory from u₀.
class ProxyHeatSolver {
 public:
  ProxyHeatSolver(const CoarseProxy& proxy, double time_step, RestrictionKind restriction, PolishOptions polish = {});
  ~ProxyHeatSolver();
  /// `steps` >= 1 with L² projection, >= 0 with injection. Not to be called on two threads at once
  /// when polishing. `polish_report`: iterations summed over the steps, estimates of the last step.
  Eigen::VectorXd integrate(const Eigen::Ref<const Eigen::VectorXd>& fine_u0, int steps, ProxyPhaseTimes* times = nullptr,
                            PolishReport* polish_report = nullptr) const;
  /// The states after `every`, 2·every, … steps up to `steps` (and after `steps` itself when it is
  /// not a multiple), one column each, their step counts in `output_steps`: u₀ restricted once,
  /// every step taken on the coarse mesh, only those states prolonged. Column j equals
  /// integrate(u0, output_steps[j]) to the last bit. Preconditions: steps >= 1, every >= 1, no
  /// polishing (which needs every fine step: std::invalid_argument).
  Eigen::MatrixXd trajectory(const Eigen::Ref<const Eigen::VectorXd>& fine_u0, int steps, int every,
                             std::vector<int>* output_steps = nullptr, ProxyPhaseTimes* times = nullptr) const;
  bool is_polishing() const { return fine_ != nullptr; }
  double polish_setup_seconds() const { return polish_setup_seconds_; }

 private:
  const CoarseProxy* proxy_;
  RestrictionKind restriction_;
  HeatSolver coarse_;
  PolishOptions polish_;
  std::unique_ptr<MultigridSolver> fine_;  ///< two-level multigrid on M + τL, when polishing
  double polish_setup_seconds_ = 0;
};

/// Options of ProxyGeodesicSolver.
struct ProxyGeodesicOptions {
  /// The coarse solver (see the file comment). Marching is the default because it was measured the
  /// more accurate of the two for ICE and for QEM coarse meshes alike (docs/measurements.md, "Coarse
  /// geodesic solver: marching or heat method") and needs no factorisation.
  CoarseDistanceMethod method = CoarseDistanceMethod::marching;
  /// heat_method only: t = (time_factor · h_c)², h_c the coarse mean edge length.
  double time_factor = 1.0;
  /// marching only: the coarse mesh is split 1:4 this many times (flat midpoint subdivision, the
  /// coarse metric unchanged) before marching, and P's rows carried into the sub-triangles: the
  /// marching's planar updates then follow the coarse metric's geodesics more closely, and the
  /// distance is interpolated over smaller pieces. Each subdivision lowers the error against exact
  /// polyhedral geodesics and multiplies the marching's cost; 1 is the default as the balance of the
  /// two (docs/measurements.md, "Marching subdivisions").
  int subdivisions = 1;
  /// marching only: march on curvature_corrected_lengths (fem/curvature_correction.h) of the coarse
  /// lengths — each edge lengthened by exp(K ℓ²/48) (fem::kProxyCorrectionDivisor) for the Gaussian
  /// curvature K its faces flatten, gathered from the fine mesh through P. It lowers the error against
  /// exact polyhedral geodesics on ICE coarse meshes; QEM-iDT meshes are not helped (its chords'
  /// shortness already offsets the flat faces' bias), which is why the tools apply it to ICE coarse
  /// meshes only (docs/measurements.md, "Curvature correction").
  bool curvature_correction = true;
  /// marching only, with curvature_correction: the divisor d of exp(K ℓ²/d) (see
  /// fem::kProxyCorrectionDivisor for how it was chosen). Precondition: d > 0.
  double curvature_divisor = kProxyCorrectionDivisor;
};

/// Geodesic distance from fine source vertices through the coarse space (see the file comment).
/// Marching needs the coarse lengths to be a valid intrinsic mesh and P's rows to be barycentric
/// coordinates of a point in a coarse face; a row whose nonzero columns are not joined by coarse
/// edges (QEM with intrinsic Delaunay geometry: a QEM face the flips removed), or are joined by
/// parallel edges or include a vertex repeated in some face (Δ-complex cases: which layout the
/// weights refer to is unknown), is interpolated linearly instead, and a source on such a row is
/// reached by marching from each of its corners.
/// Vertices of coarse components no source reaches are +∞ with marching (the heat method needs a
/// connected coarse mesh: it throws NotPositiveDefinite).
/// The prolongation to the fine vertices is threaded on meshes of 50,000+ vertices.
class ProxyGeodesicSolver {
 public:
  /// Prepares the coarse solver: the marching's mesh, or the heat method's operators
  /// (proxy.coarse_heat_method_operators(options.time_factor)) and their factorisations.
  explicit ProxyGeodesicSolver(const CoarseProxy& proxy, const ProxyGeodesicOptions& options = {});
  /// Marching without a CoarseProxy: it needs only the coarse mesh and P (n_fine × n_coarse, rows of
  /// non-negative weights summing to 1), not the fine or coarse operators a CoarseProxy assembles
  /// (a sizeable part of a proxy's setup on large meshes; docs/measurements.md, "Coarse geodesic
  /// solver: marching or heat method"). Throws std::invalid_argument on a bad coarse mesh or P.
  /// The marching pairs sides by their ends and lengths, and follows `coarse.twin` where three or more
  /// sides share both (std::invalid_argument when that twin is not a gluing). A CoarseProxy keeps no
  /// coarse twin: march on a tufted cover's coarse mesh through this constructor.
  ProxyGeodesicSolver(const ice::IntrinsicMesh& coarse, SparseMatrix P,
                      int subdivisions = ProxyGeodesicOptions{}.subdivisions);
  /// The heat method with coarse operators assembled by the caller (to time assembly and
  /// factorisation apart).
  ProxyGeodesicSolver(const CoarseProxy& proxy, HeatMethodOperators coarse_operators);
  ProxyGeodesicSolver(ProxyGeodesicSolver&&);
  ~ProxyGeodesicSolver();
  CoarseDistanceMethod method() const { return heat_ ? CoarseDistanceMethod::heat_method : CoarseDistanceMethod::marching; }
  Eigen::Index fine_size() const { return P_rows_.rows(); }
  /// The P the distance is prolonged by (n_fine × n_coarse, by rows): with marching that of the
  /// coarse mesh subdivided `subdivisions` times, with the heat method the proxy's.
  const Eigen::SparseMatrix<double, Eigen::RowMajor, int>& prolongation() const { return P_rows_; }
  /// Distance to the nearest of `fine_sources` (non-empty, in range; repeats count once): with
  /// marching 0 at every source, with the heat method 0 on average over them.
  Eigen::VectorXd distance(const std::vector<Index>& fine_sources, ProxyPhaseTimes* times = nullptr) const;

 private:
  Eigen::VectorXd heat_distance(const std::vector<Index>& sources, ProxyPhaseTimes* times) const;
  Eigen::VectorXd marching_distance(const std::vector<Index>& sources, ProxyPhaseTimes* times) const;
  void prepare_marching(const Faces& coarse_faces, const FaceLengths& coarse_lengths, const std::vector<Index>& coarse_twin,
                        int subdivisions);
  Eigen::SparseMatrix<double, Eigen::RowMajor, int> P_rows_;  ///< P row-major (gathers per fine vertex)
  std::unique_ptr<HeatGeodesicSolver> heat_;                  ///< the heat method, or null
  std::unique_ptr<detail::MarchingMesh> marching_;            ///< marching, or null
  /// Marching: Σ_{j<k} μ_j μ_k |q_j q_k|² of each fine vertex's row of P, NaN where some pair of its
  /// columns is not a coarse edge (then interpolated linearly).
  std::vector<double> spread_;
};

}  // namespace fem
