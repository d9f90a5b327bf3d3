#pragma once
/// \file vector_fields.h
/// Tangent vector fields on an intrinsic triangulation, and through a coarse proxy of it.
///
/// Tangent spaces. Every vertex v has a frame in which a tangent vector is one complex number. Angles
/// run counter-clockwise from v's *reference side* (at an interior vertex its lowest-numbered
/// corner's outgoing side, 3f + k; at a boundary vertex the boundary side it starts along) and, at an
/// interior vertex, scaled by 2π/Θ_v (Θ_v its angle sum), so that the full circle of directions around
/// a cone point is the full circle of complex phases (the convention of libice's angular coordinates).
/// Boundary vertices are not scaled: their half-disc of directions keeps its geometric angles, which
/// makes the frames of a flat domain those of the plane, whatever its boundary angles.
///
/// Transport. A vector enters a face from the corner's frame by one rotation, ψ(f, k) (see
/// TangentFrames): the bisector of the corner has the same direction in the vertex's frame and in the
/// face's layout (fem::layout_triangle). At a flat vertex (Θ = 2π, or any boundary vertex) that is the
/// exact planar transport; at a cone the angle defect is spread over the corners in proportion to
/// their angles. The connection Laplacian is the cotan stiffness matrix of the vectors carried into
/// each face, Σ_faces Σ_sides ½cot(opposite)·|e^{iψ_i} z_i − e^{iψ_j} z_j|²: Hermitian positive
/// semidefinite on any triangulation (per face it is a triangle's cotan matrix in a unitary change of
/// basis), and on a flat mesh unitarily similar to the scalar cotan Laplacian of each component.
///
/// Meshes are ice::IntrinsicMesh values with their gluing (`twin`, never empty here: a Δ-complex cannot
/// be glued by vertex pairs in general; ice::glue_by_vertex_pairs makes it for an ordinary mesh).
#include <complex>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "fem/cholesky.h"
#include "fem/coarse_proxy.h"
#include "fem/operators.h"
#include "ice/mesh.h"

namespace fem {

using Complex = std::complex<double>;
using ComplexSparseMatrix = Eigen::SparseMatrix<Complex, Eigen::ColMajor, Index>;

/// The frames of one mesh. Throws std::invalid_argument (from tangent_frames) for a mesh whose twin
/// is missing or is not an involution, or a vertex whose corners do not form one fan.
struct TangentFrames {
  /// m×3: angular coordinate of side k (from corner k to corner k+1) in the frame of corner k's vertex.
  Eigen::MatrixXd side_coordinate;
  /// m×3: rotation ψ(f, k) from corner k's vertex frame into face f's layout (fem::layout_triangle):
  /// a vector z at the vertex is e^{iψ} z in the face.
  Eigen::MatrixXd corner_rotation;
  Eigen::VectorXd angle_sum;      ///< Θ_v
  Eigen::VectorXd angle_scale;    ///< 2π/Θ_v inside, 1 on the boundary
  std::vector<char> boundary;     ///< 1 for a boundary vertex
  /// Corner 3f + k of each vertex's reference side (kInvalid for a vertex no face uses).
  std::vector<Index> reference_corner;
};

/// Frames of `mesh` (F, L, twin and its vertex count, checked as fem::checked_vertex_count does).
/// Throws InvalidTriangle for invalid lengths, std::invalid_argument as above.
TangentFrames tangent_frames(const ice::IntrinsicMesh& mesh);

/// The connection Laplacian (n×n, Hermitian positive semidefinite; see the file comment).
ComplexSparseMatrix connection_laplacian(const ice::IntrinsicMesh& mesh, const TangentFrames& frames);

/// Tangent vectors as 3D vectors on an extrinsic mesh with the same faces as `mesh` (positions V):
/// each vector is drawn in the plane of the face whose corner contains its direction.
Eigen::MatrixXd tangent_to_ambient(const ice::IntrinsicMesh& mesh, const TangentFrames& frames, const Eigen::MatrixXd& V,
                                   const Eigen::VectorXcd& field);
/// The tangent vector at v of a 3D direction (projected into the plane of the corner it points into;
/// the corner is the one whose face plane makes the projection's angle fall inside it, else the
/// closest; corners whose face is normal to the direction are passed over). Length: that of the
/// projection; 0 when every face at v is normal to the direction.
Complex ambient_to_tangent(const ice::IntrinsicMesh& mesh, const TangentFrames& frames, const Eigen::MatrixXd& V, Index v,
                           const Eigen::Vector3d& direction);

/// Solves A x = b for a Hermitian positive definite complex A through CHOLMOD, as the real symmetric
/// system [[Re A, −Im A], [Im A, Re A]] with each vertex's two unknowns interleaved (the vertex
/// graph's pattern in 2×2 blocks, so orderings and supernodes stay those of the scalar problem).
class ComplexCholeskySolver {
 public:
  explicit ComplexCholeskySolver(const ComplexSparseMatrix& A);
  Eigen::VectorXcd solve(const Eigen::VectorXcd& b) const;
  Eigen::Index rows() const { return rows_; }

 private:
  Eigen::Index rows_ = 0;
  CholeskySolver factor_;
};

/// Operators of the vector heat method on one discretisation (the fine mesh, an intrinsic coarse
/// mesh, or Galerkin products): scalar Laplacian and mass for the magnitudes, connection Laplacian
/// for the directions, and the time step.
struct VectorHeatOperators {
  SparseMatrix laplacian, mass;       ///< real, PSD; mass lumped (diagonal)
  ComplexSparseMatrix connection;     ///< Hermitian PSD
  double time_step = 0;
};
/// The operators of `mesh` with t = (time_factor·h)², h the mean edge length (the heat method's).
VectorHeatOperators vector_heat_operators(const ice::IntrinsicMesh& mesh, const TangentFrames& frames,
                                          double time_factor = 1.0);
/// The operators of `mesh` (an input's triangles, with `frames`) discretised on `delaunay`, another
/// triangulation of the same surface and vertices — its intrinsic Delaunay triangulation, faces in
/// the input's vertex numbering, with their gluing — and written in `mesh`'s frames: L and M are
/// `delaunay`'s, L∇ is `delaunay`'s with each vertex's frame turned into `mesh`'s (the rotation
/// between the two frames, fitted from the vertex's one-ring as vector_prolongation fits a vertex
/// that is its own coarse vertex: exact up to round-off, both describe one metric), and
/// t = (time_factor·h)² with h `mesh`'s mean edge length (so that only the discretisation changes).
/// Why: where an input triangle has an angle over 90° opposite an edge whose cotan weight is then
/// negative, the heat method's short-time solutions lose the maximum principle, and far from the
/// sources the vector heat method's directions can be anything; on the intrinsic Delaunay
/// triangulation they follow parallel transport again (docs/measurements.md, "Vector heat method on
/// the intrinsic Delaunay triangulation"). Throws
/// std::invalid_argument when `delaunay` has another vertex count or a vertex no face uses.
VectorHeatOperators vector_heat_operators(const ice::IntrinsicMesh& mesh, const TangentFrames& frames,
                                          const ice::IntrinsicMesh& delaunay, double time_factor = 1.0);

/// Right-hand sides of the vector heat method for vectors prescribed at vertices: Y₀ (the vectors),
/// u₀ (their lengths) and φ₀ (the sources' indicator), each summed where a vertex repeats.
struct VectorSources {
  Eigen::VectorXcd vectors;
  Eigen::VectorXd magnitudes, indicator;
  double min_magnitude = 0, max_magnitude = 0;  ///< over the given vectors
};
/// Throws std::invalid_argument for lists of different sizes, an empty list or a vertex out of [0, n).
VectorSources vector_sources(Eigen::Index n, const std::vector<Index>& vertices, const std::vector<Complex>& vectors);

/// The three diffused fields of the vector heat method, before they are combined.
struct VectorHeatParts {
  Eigen::VectorXcd directions;          ///< Y: (M + tL∇) Y = Y₀
  Eigen::VectorXd magnitudes, indicator;  ///< u and φ: (M + tL) u = u₀, (M + tL) φ = φ₀
};
/// The field Y/|Y|·u/φ, the magnitude u/φ clamped to the sources' magnitudes [min, max] (u/φ is
/// their mean weighted by the diffused indicator; with one magnitude it is that magnitude exactly).
/// Zero where Y or φ vanishes (a component no source reaches). Y is normalised before it is scaled:
/// far from the sources on a large mesh the direct solve's Y is subnormal, where |u/φ|/|Y| overflowed
/// (infinite vectors), and it keeps what precision is left instead (tested); a Y that is not finite
/// gives zero. The clamp matters where cotan weights are negative (a non-Delaunay mesh, such as the
/// input triangles): there u and φ can both turn negative far from the sources, where requiring
/// φ > 0 would leave zero vectors (observed cases: docs/measurements.md, "Vector heat field: underflow
/// and negative kernels").
Eigen::VectorXcd vector_heat_field(const VectorHeatParts& parts, double min_magnitude, double max_magnitude);

/// The vector heat method (Sharp, Soliman, Crane 2019): diffuse the vectors for time t with the
/// connection Laplacian, keep the directions Y/|Y|; diffuse the magnitudes and the sources'
/// indicator with the scalar Laplacian and take u/φ as the magnitude. One source: parallel transport
/// along shortest geodesics; several: a smooth field interpolating them. Both factorisations
/// (M + tL∇ and M + tL) happen in the constructor.
class VectorHeatSolver {
 public:
  explicit VectorHeatSolver(VectorHeatOperators operators);
  /// The three diffusions of given right-hand sides (for a caller that combines them elsewhere, as
  /// the coarse proxy does after prolongation). Throws std::invalid_argument for wrong sizes.
  VectorHeatParts diffuse(const Eigen::VectorXcd& vector_sources, const Eigen::VectorXd& magnitudes,
                          const Eigen::VectorXd& indicator) const;
  /// The field interpolating `vectors` prescribed at `vertices` (in their frames); one vertex:
  /// parallel transport of its vector. Throws as vector_sources.
  Eigen::VectorXcd interpolate(const std::vector<Index>& vertices, const std::vector<Complex>& vectors) const;
  const VectorHeatOperators& operators() const { return operators_; }

 private:
  VectorHeatOperators operators_;
  ComplexCholeskySolver vector_factor_;
  CholeskySolver scalar_factor_;
};

/// How well a fine vertex's tangent space was matched with the coarse mesh (vector_prolongation).
struct VectorProlongationStats {
  Index fitted = 0;          ///< rotation fitted to the images of the vertex's fine neighbours
  Index from_corner = 0;     ///< fitted in the polar chart of the nearest coarse corner instead
  Index unmatched = 0;       ///< no neighbour image found: frame carried through the face unrotated
  double median_fit_residual = 0;  ///< median over fitted vertices of the fit's relative residual
  /// Fitted vertices whose relative residual exceeds kPoorFitResidual: their one-ring's images are no
  /// rotation of the ring (the map folds there, or the images are far apart), so their frame is a guess.
  Index poor_fits = 0;
};

/// Relative residual above which a fit counts as poor (for images turned by a common angle from the
/// best rotation, the residual is about its sine: here ~30°).
inline constexpr double kPoorFitResidual = 0.5;

/// Vector prolongation P_vec (n_fine × n_coarse, complex): a coarse field Y_c becomes the fine field
/// P_vec Y_c. A fine vertex in coarse face f with barycentric coordinates b gets
/// Σ_k b_k e^{iψ(f,k)} Y_c(corner k) carried into its own frame; a vertex that survived gets its coarse
/// vertex's vector carried into its own frame. The frame relation is the rotation that best maps the
/// vertex's fine one-ring (edge vectors in its own frame) onto the images of its neighbours under the
/// fine-to-coarse map, laid out around the coarse face (unfolded across its sides and corners) or, for
/// a survivor, in its coarse vertex's polar chart: the rotation part of the map's differential, fitted
/// by least squares. Where the unfolding reaches a face or a coarse vertex by several routes (around a
/// cone vertex; two Δ-complex faces glued along two sides) it lays it out once per route, and each
/// neighbour's image is the nearest copy that the straight segment from the vertex reaches through
/// that copy's own route (the image of a short fine edge is a short path). Every row's moduli sum to 1
/// (they are the barycentric coordinates; less where a Δ-complex face repeats a corner and two entries
/// add); with no coarsening (every vertex survives, same frames) P_vec is the identity up to round-off.
/// `map` holds one CoarsePoint per fine vertex (ice::fine_to_coarse_map). Throws std::invalid_argument
/// on size mismatches or a map face out of range.
ComplexSparseMatrix vector_prolongation(const ice::IntrinsicMesh& fine, const TangentFrames& fine_frames,
                                        const ice::IntrinsicMesh& coarse, const TangentFrames& coarse_frames,
                                        const std::vector<ice::CoarsePoint>& map,
                                        VectorProlongationStats* stats = nullptr);

/// Which coarse operators the vector proxy solves with.
enum class VectorOperatorKind {
  intrinsic,  ///< from the coarse lengths: connection_laplacian of the coarse mesh, its cotan L and lumped M
  galerkin,   ///< P_vecᴴ L∇ P_vec, Pᵀ L P and the lumped Galerkin mass diag(Pᵀ M 1), from the fine operators
};

/// The coarse proxy's default time factor: t = (0.5·h_c)², the factor measured most accurate against
/// the fine solution at t = h², with Galerkin and intrinsic operators alike (docs/measurements.md,
/// "Vector proxy time factor"). A larger t biases the field (transport averaged over more paths: the
/// fine method itself moves noticeably from t = h² to t = h_c²); a smaller one resolves diffusion on
/// the coarse faces worse.
inline constexpr double kVectorProxyTimeFactor = 0.5;

/// The vector heat method through a coarse proxy: the sources are restricted (Y₀ by P_vecᴴ, u₀ and
/// φ₀ by Pᵀ, as the scalar geodesic proxy restricts its source), the three diffusions are solved on
/// the coarse mesh with t = (time_factor·h_c)² (h_c the coarse mean edge length), prolonged (Y by
/// P_vec, u and φ by P) and combined on the fine mesh. The fine operators are not needed for
/// intrinsic coarse operators.
class VectorHeatProxy {
 public:
  /// `P` is the scalar prolongation (fine × coarse, rows summing to 1), `map` the fine-to-coarse map it
  /// comes from. Throws std::invalid_argument on inconsistent sizes.
  VectorHeatProxy(const ice::IntrinsicMesh& fine, const TangentFrames& fine_frames, const ice::IntrinsicMesh& coarse,
                  const TangentFrames& coarse_frames, const std::vector<ice::CoarsePoint>& map, SparseMatrix P,
                  VectorOperatorKind kind, double time_factor = kVectorProxyTimeFactor);
  /// The same with the fine operators given, in `fine`'s frames, for the Galerkin coarse operators
  /// (e.g. vector_heat_operators(fine, fine_frames, delaunay): the input's intrinsic Delaunay
  /// discretisation) instead of those of `fine`'s own triangles.
  VectorHeatProxy(const ice::IntrinsicMesh& fine, const TangentFrames& fine_frames, const VectorHeatOperators& fine_operators,
                  const ice::IntrinsicMesh& coarse, const TangentFrames& coarse_frames,
                  const std::vector<ice::CoarsePoint>& map, SparseMatrix P, VectorOperatorKind kind,
                  double time_factor = kVectorProxyTimeFactor);
  /// The fine field interpolating `vectors` at fine `vertices` (in the fine frames).
  Eigen::VectorXcd interpolate(const std::vector<Index>& vertices, const std::vector<Complex>& vectors) const;
  const ComplexSparseMatrix& vector_prolongation() const { return vector_prolongation_; }
  const VectorProlongationStats& prolongation_stats() const { return stats_; }
  const VectorHeatSolver& coarse_solver() const { return *coarse_solver_; }

 private:
  SparseMatrix P_;
  ComplexSparseMatrix vector_prolongation_;
  VectorProlongationStats stats_;
  std::unique_ptr<VectorHeatSolver> coarse_solver_;
};

/// Options of vector_field_from_distance.
struct DistanceSweepOptions {
  /// Gauss–Seidel passes after the first stop when no vertex's value moves by more than this
  /// relative to the size of the terms its row sums (not to the value, which cancels where vectors
  /// from two sides meet), or after max_passes. The angle error against the fine method falls with
  /// the passes (docs/measurements.md, "Distance sweep: passes and coarse correction"); a pass is one
  /// visit of L∇'s nonzeros (L's too with sources of several magnitudes).
  double tolerance = 1e-3;
  int max_passes = 50;
  /// With a coarse space (VectorSweepProxy: the marching's P), a Galerkin coarse-grid correction of
  /// relative errors before every this many passes (0: none). A correction before every pass or
  /// every second pass removes the errors the passes alone leave on hard meshes; every second pass
  /// is nearly as accurate for less time, hence the default (a correction is a visit of the rows and
  /// one coarse solve; its matrix is factorised once per call). Docs/measurements.md, "Distance
  /// sweep: passes and coarse correction".
  int coarse_correction_interval = 2;
  /// Coarse systems of at least this many unknowns are factorised by CHOLMOD's supernodal
  /// Cholesky, smaller ones by a simplicial LDLᵀ (a small supernodal solve spends its time waiting
  /// on BLAS threads; measured in docs/measurements.md, "Distance sweep: passes and coarse
  /// correction").
  Index supernodal_from = 50'000;
};
/// What a sweep did.
struct DistanceSweepStats {
  int passes = 0;             ///< passes after the first
  double last_change = 0;     ///< the largest relative move in the last pass
  int coarse_corrections = 0; ///< coarse-grid corrections done
  bool coarse_supernodal = false; ///< the vector system's coarse matrix was factorised by CHOLMOD's supernodal Cholesky
  bool settled = false;       ///< the last pass moved no value by more than the tolerance (false: max_passes stopped it)
};
/// A coarse space for the sweep's coarse-grid correction: P (n_fine × n_coarse, rows of
/// barycentric weights), by rows.
using SweepCoarseSpace = Eigen::SparseMatrix<double, Eigen::RowMajor, Index>;

/// The vector heat method's field, solved on the fine mesh without a factorisation: Gauss–Seidel on
/// its systems (M + tL∇)Y = Y₀ and, for sources of several magnitudes, (M + tL)u = u₀ and
/// (M + tL)φ = φ₀, in order of `distance` to the sources (so that a vertex is updated after its
/// neighbours nearer them, the direction the kernel flows), combined as VectorHeatSolver does
/// (vector_heat_field). The passes converge to VectorHeatSolver::interpolate's field for any
/// distance (the systems are Hermitian positive definite); the distance makes them fast:
/// - each value is kept as exp(−e_i) times a value of order one, e_i the log of the kernel's decay,
///   found by the first pass (each vertex from its nearer neighbours, through the scalar kernel φ,
///   which unlike Y does not cancel): the far field stays in floating range where the direct
///   solve's underflows (tested on a long flat strip; docs/measurements.md, "Vector heat field:
///   underflow and negative kernels");
/// - the first pass counts each neighbour farther away (not reached yet) as the vertex itself times
///   the decay exp(−(d_j − d_i)/√t) the distance predicts (Varadhan: the backward-Euler kernel
///   decays as exp(−d/√t)), so that it starts near the solution instead of losing a factor at every
///   step away from the sources.
/// Alone, the passes converge slowly where a relative error spread over a region satisfies the rows
/// there (over-relaxation diverged on some meshes); given `coarse_space` (n × n_c, rows of
/// barycentric weights: VectorSweepProxy passes the marching's P), a Galerkin coarse-grid correction
/// of such relative errors before every options.coarse_correction_interval-th pass removes them
/// (docs/measurements.md, "Distance sweep: passes and coarse correction"). Rows whose scale is more
/// than e^600 below the sources' are left to the passes (their residuals would underflow). Throws
/// std::invalid_argument for a coarse space of the wrong size.
/// `operators` gives M (lumped), L, L∇ and t; `distance` is per vertex to the nearest source (+∞ or
/// NaN: not reached, the field is zero there; each source's must be finite). One magnitude and
/// direction per source as VectorHeatSolver::interpolate (a vertex given twice: its vectors add).
/// Throws std::invalid_argument on sizes, sources out of range or unreached (as vector_sources), a
/// non-positive diagonal of M + tL∇ or M + tL.
/// Through the coarse proxy's marching distance, with the coarse corrections, it was measured nearer
/// the fine method than coarse diffusion (VectorHeatProxy) and than the passes alone
/// (docs/measurements.md, "Distance sweep: passes and coarse correction").
Eigen::VectorXcd vector_field_from_distance(const VectorHeatOperators& operators, const Eigen::VectorXd& distance,
                                            const std::vector<Index>& vertices, const std::vector<Complex>& vectors,
                                            const DistanceSweepOptions& options = {}, DistanceSweepStats* stats = nullptr,
                                            const SweepCoarseSpace* coarse_space = nullptr);

/// The vector heat method through a coarse proxy's geodesic distance: the distance to the nearest
/// source by `distances` (fem::ProxyGeodesicSolver; marching on the coarse mesh), then
/// vector_field_from_distance on the fine operators, with the coarse-grid corrections on the
/// marching's coarse space (its P: the coarse mesh subdivided for marching). No fine factorisation
/// and no vector prolongation: per call a sort, the passes over L∇'s nonzeros and, with the
/// corrections, one factorisation of their Galerkin matrix (of the size of that coarse space).
class VectorSweepProxy {
 public:
  /// `fine_operators`: L, L∇ and t of the fine mesh (e.g. vector_heat_operators(fine, frames, delaunay)),
  /// of the size of `distances`' fine mesh (std::invalid_argument otherwise).
  VectorSweepProxy(VectorHeatOperators fine_operators, ProxyGeodesicSolver distances, DistanceSweepOptions options = {});
  /// The fine field interpolating `vectors` at fine `vertices` (in the fine frames); `stats`: the sweep's.
  Eigen::VectorXcd interpolate(const std::vector<Index>& vertices, const std::vector<Complex>& vectors,
                               DistanceSweepStats* stats = nullptr) const;
  const ProxyGeodesicSolver& distances() const { return distances_; }

 private:
  VectorHeatOperators operators_;
  ProxyGeodesicSolver distances_;
  DistanceSweepOptions options_;
};

/// Angle between two tangent vectors in degrees ([0, 180]; NaN if either is zero).
double angle_between_degrees(Complex a, Complex b);

}  // namespace fem
