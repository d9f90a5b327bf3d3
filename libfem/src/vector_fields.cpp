#include "fem/vector_fields.h"

#include "sparse_columns.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "fem/geometry.h"
#include "ice/triangle_geometry.h"

namespace fem {
namespace {

using ice::kPi;
constexpr double kTwoPi = 2 * kPi;

// Corners are numbered 3f + k; side 3f + k runs from corner k to corner k + 1 of face f.
Index corner_vertex(const Faces& F, Index corner) { return F(corner / 3, corner % 3); }
Index side_of(Index face, int k) { return 3 * face + ((k % 3) + 3) % 3; }

// The next corner counter-clockwise around the vertex of `corner` (across the side that enters it),
// or kInvalid at the last corner of a boundary fan.
Index next_ccw_corner(const std::vector<Index>& twin, Index corner) {
  // Side d of the face across starts at this vertex: it is corner d there.
  return twin[static_cast<std::size_t>(side_of(corner / 3, corner % 3 + 2))];
}
// Calls fn(corner) for the corners of one fan, counter-clockwise from `first` (a vertex whose
// corners tangent_frames has checked to form one fan).
template <class Fn>
void for_each_fan_corner(const std::vector<Index>& twin, Index first, Fn&& fn) {
  Index c = first;
  do {
    fn(c);
    c = next_ccw_corner(twin, c);
  } while (c != ice::kInvalid && c != first);
}
// The previous corner (clockwise), or kInvalid at the first corner of a boundary fan.
Index previous_cw_corner(const std::vector<Index>& twin, Index corner) {
  const Index across = twin[static_cast<std::size_t>(corner)];
  if (across == ice::kInvalid) return ice::kInvalid;
  return side_of(across / 3, across % 3 + 1);
}

void check_gluing(const ice::IntrinsicMesh& mesh) {
  const std::size_t sides = static_cast<std::size_t>(3 * mesh.F.rows());
  if (mesh.twin.size() != sides)
    throw std::invalid_argument("tangent frames: the mesh needs its gluing (twin of size 3 x faces; got " +
                                std::to_string(mesh.twin.size()) + " for " + std::to_string(sides) + " sides)");
  for (std::size_t s = 0; s < sides; ++s) {
    const Index t = mesh.twin[s];
    if (t == ice::kInvalid) continue;
    if (t < 0 || static_cast<std::size_t>(t) >= sides || mesh.twin[static_cast<std::size_t>(t)] != static_cast<Index>(s) ||
        t == static_cast<Index>(s))
      throw std::invalid_argument("tangent frames: twin is not an involution at side " + std::to_string(s));
  }
}

// Direction of side k of a face in its layout (fem::layout_triangle), from its corner angles.
// Angle at corner k of face f: fem::corner_angles' formula, for one corner.
double corner_angle(const FaceLengths& L, Index f, int k) {
  return ice::angle_opposite(L(f, (k + 2) % 3), L(f, k), L(f, (k + 1) % 3));
}

double side_direction(const Eigen::MatrixXd& angles, Index f, int k) {
  if (k == 0) return 0;
  if (k == 1) return kPi - angles(f, 1);
  return kPi + angles(f, 0);
}

using Point = Complex;  // a point or vector of a 2D chart

// Corners of face f laid out by fem::layout_triangle, as complex numbers.
std::array<Point, 3> face_layout(const FaceLengths& L, Index f) {
  const Eigen::Matrix<double, 3, 2> p = layout_triangle(L(f, 0), L(f, 1), L(f, 2));
  return {Point(p(0, 0), p(0, 1)), Point(p(1, 0), p(1, 1)), Point(p(2, 0), p(2, 1))};
}

// Corners of every vertex in counter-clockwise fan order (from the reference corner), CSR.
struct Fans {
  std::vector<Index> start, corners;
  template <class Fn>
  void for_each(Index v, Fn&& fn) const {
    for (Index c = start[static_cast<std::size_t>(v)]; c < start[static_cast<std::size_t>(v) + 1]; ++c)
      fn(corners[static_cast<std::size_t>(c)]);
  }
};
Fans vertex_fans(const ice::IntrinsicMesh& mesh, const TangentFrames& frames) {
  const std::size_t n = frames.reference_corner.size();
  Fans fans;
  fans.start.assign(n + 1, 0);
  fans.corners.reserve(static_cast<std::size_t>(3 * mesh.F.rows()));
  for (std::size_t v = 0; v < n; ++v) {
    fans.start[v] = static_cast<Index>(fans.corners.size());
    const Index first = frames.reference_corner[v];
    if (first != ice::kInvalid) for_each_fan_corner(mesh.twin, first, [&](Index c) { fans.corners.push_back(c); });
  }
  fans.start[n] = static_cast<Index>(fans.corners.size());
  return fans;
}

// An orthonormal basis of the plane of face f at corner k: along its outgoing side, and across it
// (towards the face's inside).
struct CornerBasis {
  Eigen::Vector3d along, across;
};
CornerBasis corner_basis(const Faces& F, const Eigen::MatrixXd& V, Index f, int k) {
  const Eigen::Vector3d origin = V.row(F(f, k)).transpose();
  const Eigen::Vector3d to_next = V.row(F(f, (k + 1) % 3)).transpose() - origin;
  const Eigen::Vector3d to_last = V.row(F(f, (k + 2) % 3)).transpose() - origin;
  CornerBasis basis;
  basis.along = to_next.normalized();
  basis.across = basis.along.cross(to_last).normalized().cross(basis.along);
  return basis;
}

}  // namespace

TangentFrames tangent_frames(const ice::IntrinsicMesh& mesh) {
  check_gluing(mesh);
  const Faces& F = mesh.F;
  const Eigen::Index m = F.rows();
  const Eigen::Index n = checked_vertex_count(mesh);
  const Eigen::MatrixXd angles = corner_angles(mesh.L);  // validates the lengths
  TangentFrames frames;
  frames.side_coordinate.resize(m, 3);
  frames.corner_rotation.resize(m, 3);
  frames.angle_sum = Eigen::VectorXd::Zero(n);
  frames.angle_scale = Eigen::VectorXd::Ones(n);
  frames.boundary.assign(static_cast<std::size_t>(n), 0);
  frames.reference_corner.assign(static_cast<std::size_t>(n), ice::kInvalid);
  std::vector<Index> corner_count(static_cast<std::size_t>(n), 0);
  for (Index c = 0; c < 3 * m; ++c) {
    const Index v = corner_vertex(F, c);
    if (v < 0 || v >= n) throw std::invalid_argument("tangent frames: face " + std::to_string(c / 3) + " names vertex " + std::to_string(v) + " beyond the mesh");
    ++corner_count[static_cast<std::size_t>(v)];
    Index& reference = frames.reference_corner[static_cast<std::size_t>(v)];
    if (previous_cw_corner(mesh.twin, c) == ice::kInvalid) {  // a boundary fan starts here
      if (frames.boundary[static_cast<std::size_t>(v)])
        throw std::invalid_argument("tangent frames: vertex " + std::to_string(v) + " has several boundary fans (not a manifold vertex)");
      frames.boundary[static_cast<std::size_t>(v)] = 1;
      reference = c;
    } else if (!frames.boundary[static_cast<std::size_t>(v)] && (reference == ice::kInvalid || c < reference)) {
      reference = c;
    }
  }
  for (Eigen::Index v = 0; v < n; ++v) {
    const Index first = frames.reference_corner[static_cast<std::size_t>(v)];
    if (first == ice::kInvalid) continue;
    // Θ first (the scale needs it), then the coordinates.
    double sum = 0;
    Index visited = 0;
    Index c = first;
    do {
      sum += angles(c / 3, c % 3);
      ++visited;
      c = next_ccw_corner(mesh.twin, c);
    } while (c != ice::kInvalid && c != first && visited <= corner_count[static_cast<std::size_t>(v)]);
    if (visited != corner_count[static_cast<std::size_t>(v)])
      throw std::invalid_argument("tangent frames: the corners of vertex " + std::to_string(v) + " do not form one fan");
    const bool boundary = frames.boundary[static_cast<std::size_t>(v)] != 0;
    const double scale = boundary ? 1.0 : kTwoPi / sum;
    frames.angle_sum(v) = sum;
    frames.angle_scale(v) = scale;
    double accumulated = 0;
    for_each_fan_corner(mesh.twin, first, [&](Index corner_index) {
      const Index f = corner_index / 3;
      const int k = corner_index % 3;
      const double corner = angles(f, k);
      const double coordinate = scale * accumulated;
      frames.side_coordinate(f, k) = coordinate;
      // The corner's bisector points the same way in the vertex frame and in the face.
      frames.corner_rotation(f, k) = (side_direction(angles, f, k) + 0.5 * corner) - (coordinate + 0.5 * scale * corner);
      accumulated += corner;
    });
  }
  return frames;
}

ComplexSparseMatrix connection_laplacian(const ice::IntrinsicMesh& mesh, const TangentFrames& frames) {
  const Eigen::MatrixXd cot = corner_cotangents(mesh.L);
  const Eigen::Index n = static_cast<Eigen::Index>(frames.reference_corner.size());
  std::vector<Eigen::Triplet<Complex, Index>> triplets;
  triplets.reserve(static_cast<std::size_t>(12 * mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int k1 = (k + 1) % 3;
      const Index i = mesh.F(f, k), j = mesh.F(f, k1);
      const double w = 0.5 * cot(f, (k + 2) % 3);
      // w |e^{iψ_i} z_i − e^{iψ_j} z_j|²: the side's term of the face's stiffness matrix.
      const Complex coupling = -w * std::polar(1.0, frames.corner_rotation(f, k1) - frames.corner_rotation(f, k));
      triplets.emplace_back(i, i, w);
      triplets.emplace_back(j, j, w);
      triplets.emplace_back(i, j, coupling);
      triplets.emplace_back(j, i, std::conj(coupling));
    }
  ComplexSparseMatrix A(n, n);
  A.setFromTriplets(triplets.begin(), triplets.end());
  A.makeCompressed();
  return A;
}

Eigen::MatrixXd tangent_to_ambient(const ice::IntrinsicMesh& mesh, const TangentFrames& frames, const Eigen::MatrixXd& V,
                                   const Eigen::VectorXcd& field) {
  const Eigen::Index n = static_cast<Eigen::Index>(frames.reference_corner.size());
  if (field.size() != n || V.rows() < n || V.cols() != 3)
    throw std::invalid_argument("tangent_to_ambient: " + std::to_string(field.size()) + " vectors and " +
                                std::to_string(V.rows()) + " positions for " + std::to_string(n) + " vertices");
  const Eigen::MatrixXd angles = corner_angles(mesh.L);
  const Fans fans = vertex_fans(mesh, frames);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n, 3);
  for (Eigen::Index v = 0; v < n; ++v) {
    const Complex z = field(v);
    if (z == Complex(0) || frames.reference_corner[static_cast<std::size_t>(v)] == ice::kInvalid) continue;
    double phase = std::arg(z);
    if (phase < 0) phase += kTwoPi;
    const double scale = frames.angle_scale(v);
    // The corner whose span of directions holds the phase (on the boundary, directions past the last
    // corner point outwards: the nearest end corner draws them).
    Index chosen = ice::kInvalid;
    double best_gap = INFINITY;
    fans.for_each(static_cast<Index>(v), [&](Index c) {
      const double low = frames.side_coordinate(c / 3, c % 3);
      const double high = low + scale * angles(c / 3, c % 3);
      const double gap = phase < low ? low - phase : (phase > high ? phase - high : 0.0);
      const double wrapped = std::min(gap, std::abs(phase - kTwoPi - high));
      if (wrapped < best_gap) best_gap = wrapped, chosen = c;
    });
    const Index f = chosen / 3;
    const int k = chosen % 3;
    const double within = (phase - frames.side_coordinate(f, k)) / scale;
    const CornerBasis basis = corner_basis(mesh.F, V, f, k);
    out.row(v) = (std::abs(z) * (std::cos(within) * basis.along + std::sin(within) * basis.across)).transpose();
  }
  return out;
}

Complex ambient_to_tangent(const ice::IntrinsicMesh& mesh, const TangentFrames& frames, const Eigen::MatrixXd& V, Index v,
                           const Eigen::Vector3d& direction) {
  if (v < 0 || static_cast<std::size_t>(v) >= frames.reference_corner.size() ||
      frames.reference_corner[static_cast<std::size_t>(v)] == ice::kInvalid)
    throw std::invalid_argument("ambient_to_tangent: vertex " + std::to_string(v) + " is not a vertex of a face");
  // Only v's fan: a source's vector must not cost a pass over the mesh.
  // A corner whose face is normal to the direction has no angle for it (atan2(0, 0)): skipped, so
  // that a direction in one face plane of a folded fan is not lost to another's. Ties go to the
  // longer projection.
  Complex best(0);
  double best_gap = INFINITY, best_length = 0;
  const double negligible = 1e-12 * direction.norm();
  for_each_fan_corner(mesh.twin, frames.reference_corner[static_cast<std::size_t>(v)], [&](Index c) {
    const Index f = c / 3;
    const int k = c % 3;
    const CornerBasis basis = corner_basis(mesh.F, V, f, k);
    const double x = direction.dot(basis.along), y = direction.dot(basis.across);
    const double length = std::hypot(x, y);
    if (!(length > negligible)) return;
    const double within = std::atan2(y, x);
    const double corner = corner_angle(mesh.L, f, k);
    const double gap = within < 0 ? -within : (within > corner ? within - corner : 0.0);
    if (gap < best_gap || (gap == best_gap && length > best_length)) {
      best_gap = gap;
      best_length = length;
      best = std::polar(length, frames.side_coordinate(f, k) + frames.angle_scale(v) * within);
    }
  });
  return best;
}

ComplexCholeskySolver::ComplexCholeskySolver(const ComplexSparseMatrix& A) : rows_(A.rows()) {
  if (A.rows() != A.cols()) throw std::invalid_argument("ComplexCholeskySolver: the matrix is not square");
  std::vector<Eigen::Triplet<double, Index>> triplets;
  triplets.reserve(static_cast<std::size_t>(4 * A.nonZeros()));
  for (Eigen::Index col = 0; col < A.outerSize(); ++col)
    for (ComplexSparseMatrix::InnerIterator it(A, col); it; ++it) {
      const Index p = static_cast<Index>(it.row()), q = static_cast<Index>(col);
      const double re = it.value().real(), im = it.value().imag();
      triplets.emplace_back(2 * p, 2 * q, re);
      triplets.emplace_back(2 * p + 1, 2 * q + 1, re);
      if (im != 0) {
        triplets.emplace_back(2 * p, 2 * q + 1, -im);
        triplets.emplace_back(2 * p + 1, 2 * q, im);
      }
    }
  SparseMatrix real(2 * rows_, 2 * rows_);
  real.setFromTriplets(triplets.begin(), triplets.end());
  factor_.compute(real);
}

Eigen::VectorXcd ComplexCholeskySolver::solve(const Eigen::VectorXcd& b) const {
  if (b.size() != rows_) throw std::invalid_argument("ComplexCholeskySolver::solve: wrong size");
  Eigen::VectorXd real(2 * rows_);
  for (Eigen::Index i = 0; i < rows_; ++i) real(2 * i) = b(i).real(), real(2 * i + 1) = b(i).imag();
  const Eigen::VectorXd x = factor_.solve(real);
  Eigen::VectorXcd out(rows_);
  for (Eigen::Index i = 0; i < rows_; ++i) out(i) = Complex(x(2 * i), x(2 * i + 1));
  return out;
}

VectorHeatOperators vector_heat_operators(const ice::IntrinsicMesh& mesh, const TangentFrames& frames, double time_factor) {
  if (!(time_factor > 0)) throw std::invalid_argument("vector_heat_operators: the time factor must be positive");
  const Eigen::Index n = static_cast<Eigen::Index>(frames.reference_corner.size());
  VectorHeatOperators ops;
  if (checked_vertex_count(mesh) != n) throw std::invalid_argument("vector_heat_operators: the frames are not the mesh's");
  ops.laplacian = cotan_laplacian(mesh);
  ops.mass = mass_matrix(mesh, MassKind::lumped);
  ops.connection = connection_laplacian(mesh, frames);
  const double h = time_factor * mean_edge_length(mesh.L);
  ops.time_step = h * h;
  return ops;
}

VectorHeatOperators vector_heat_operators(const ice::IntrinsicMesh& mesh, const TangentFrames& frames,
                                          const ice::IntrinsicMesh& delaunay, double time_factor) {
  if (!(time_factor > 0)) throw std::invalid_argument("vector_heat_operators: the time factor must be positive");
  const auto n = static_cast<Index>(frames.reference_corner.size());
  if (delaunay.F.rows() == 0 || delaunay.F.maxCoeff() >= n || delaunay.F.minCoeff() < 0)
    throw std::invalid_argument("vector_heat_operators: the second triangulation's vertices are not the mesh's");
  // Every vertex is its own coarse vertex, at one of its corners.
  ice::IntrinsicMesh same = delaunay;
  same.vertex_count = n;
  std::vector<ice::CoarsePoint> own(static_cast<std::size_t>(n));
  for (Eigen::Index f = 0; f < same.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      ice::CoarsePoint& point = own[static_cast<std::size_t>(same.F(f, k))];
      if (point.face != ice::kInvalid) continue;
      point = {same.F(f, k), static_cast<Index>(f), {0, 0, 0}};
      point.bary[static_cast<std::size_t>(k)] = 1;
    }
  for (Index v = 0; v < n; ++v)
    if (own[static_cast<std::size_t>(v)].face == ice::kInvalid && frames.reference_corner[static_cast<std::size_t>(v)] != ice::kInvalid)
      throw std::invalid_argument("vector_heat_operators: vertex " + std::to_string(v) + " is in no face of the second triangulation");
  const TangentFrames same_frames = tangent_frames(same);
  // Diagonal (each vertex is its own coarse vertex): the rotation from the vertex's frame in `same`
  // into its frame in `mesh`. L∇ becomes D L∇ Dᴴ, entry by entry (Hermitian as it was).
  const ComplexSparseMatrix turn = vector_prolongation(mesh, frames, same, same_frames, own);
  const Eigen::VectorXcd rotation = turn.diagonal();
  VectorHeatOperators ops = vector_heat_operators(same, same_frames, 1.0);
  for (Eigen::Index col = 0; col < ops.connection.outerSize(); ++col)
    for (ComplexSparseMatrix::InnerIterator it(ops.connection, col); it; ++it)
      it.valueRef() *= rotation(it.row()) * std::conj(rotation(col));
  const double h = time_factor * mean_edge_length(mesh.L);
  ops.time_step = h * h;
  return ops;
}

namespace {
ComplexSparseMatrix as_complex(const SparseMatrix& A) { return A.cast<Complex>(); }
}  // namespace

VectorHeatSolver::VectorHeatSolver(VectorHeatOperators operators)
    : operators_(std::move(operators)),
      vector_factor_(ComplexSparseMatrix(as_complex(operators_.mass) + operators_.time_step * operators_.connection)),
      scalar_factor_(SparseMatrix(operators_.mass + operators_.time_step * operators_.laplacian)) {}

VectorHeatParts VectorHeatSolver::diffuse(const Eigen::VectorXcd& vector_sources, const Eigen::VectorXd& magnitudes,
                                          const Eigen::VectorXd& indicator) const {
  const Eigen::Index n = operators_.mass.rows();
  if (vector_sources.size() != n || magnitudes.size() != n || indicator.size() != n)
    throw std::invalid_argument("VectorHeatSolver: right-hand sides of the wrong size");
  VectorHeatParts parts;
  parts.directions = vector_factor_.solve(vector_sources);
  Eigen::MatrixXd scalar(n, 2);
  scalar.col(0) = magnitudes;
  scalar.col(1) = indicator;
  const Eigen::MatrixXd diffused = scalar_factor_.solve_multiple(scalar);
  parts.magnitudes = diffused.col(0);
  parts.indicator = diffused.col(1);
  return parts;
}

Eigen::VectorXcd vector_heat_field(const VectorHeatParts& parts, double min_magnitude, double max_magnitude) {
  const Eigen::Index n = parts.directions.size();
  Eigen::VectorXcd field(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double length = std::abs(parts.directions(i));
    // u/φ is a mean of the sources' magnitudes weighted by the diffused indicator, so it lies in
    // their range; where cotan weights are negative (a non-Delaunay mesh) u and φ can both turn
    // negative far from the sources, and the ratio is kept, clamped to that range.
    // With one magnitude the clamp gives exactly it, wherever the sources reach.
    const double magnitude = parts.indicator(i) != 0
                                 ? std::clamp(parts.magnitudes(i) / parts.indicator(i), min_magnitude, max_magnitude)
                                 : 0.0;
    // Y/|Y| before the magnitude: far from the sources Y can be subnormal, and magnitude/|Y| would
    // overflow to ∞ (spot Loop ×3, 1.6M vertices: 7,639 infinite vectors).
    const Complex direction = length > 0 ? parts.directions(i) / length : Complex(0);
    field(i) = std::isfinite(direction.real()) && std::isfinite(direction.imag()) ? direction * magnitude : Complex(0);
  }
  return field;
}

VectorSources vector_sources(Eigen::Index n, const std::vector<Index>& vertices, const std::vector<Complex>& vectors) {
  if (vertices.empty() || vertices.size() != vectors.size())
    throw std::invalid_argument("vector heat method: " + std::to_string(vertices.size()) + " vertices and " +
                                std::to_string(vectors.size()) + " vectors (need the same, at least one)");
  VectorSources sources;
  sources.vectors = Eigen::VectorXcd::Zero(n);
  sources.magnitudes = Eigen::VectorXd::Zero(n);
  sources.indicator = Eigen::VectorXd::Zero(n);
  for (std::size_t s = 0; s < vertices.size(); ++s) {
    const Index v = vertices[s];
    if (v < 0 || v >= n) throw std::invalid_argument("vector heat method: source vertex " + std::to_string(v) + " out of range");
    sources.vectors(v) += vectors[s];
    sources.magnitudes(v) += std::abs(vectors[s]);
    sources.indicator(v) += 1;
    sources.min_magnitude = s == 0 ? std::abs(vectors[s]) : std::min(sources.min_magnitude, std::abs(vectors[s]));
    sources.max_magnitude = std::max(sources.max_magnitude, std::abs(vectors[s]));
  }
  return sources;
}

Eigen::VectorXcd VectorHeatSolver::interpolate(const std::vector<Index>& vertices, const std::vector<Complex>& vectors) const {
  const VectorSources sources = vector_sources(operators_.mass.rows(), vertices, vectors);
  return vector_heat_field(diffuse(sources.vectors, sources.magnitudes, sources.indicator), sources.min_magnitude,
                           sources.max_magnitude);
}

// ---- vector prolongation ----------------------------------------------------------------------

namespace {

// A patch of the coarse mesh unfolded into one plane: every route of at most `depth` side crossings
// from a root face that never crosses straight back. A face reached by several routes (around a cone
// vertex, or two faces of a Δ-complex glued along two sides) is laid out once per route, as the
// routes unfold it to different places. A point is looked up at the copy that the straight segment
// from where it is expected reaches through the copy's own route (the image of a short fine edge is
// a short path on the coarse surface, which unfolds along the faces it crosses); the nearest such
// copy, or the nearest copy if no segment follows its route.
class UnfoldedPatch {
 public:
  UnfoldedPatch(const ice::IntrinsicMesh& mesh, int depth) : mesh_(mesh), depth_(depth) {}
  void build(Index root) {
    for (const Placement& p : placements_) first_[static_cast<std::size_t>(p.face)] = -1;
    placements_.clear();
    if (first_.empty()) first_.assign(static_cast<std::size_t>(mesh_.F.rows()), -1);
    place({root, -1, -1, face_layout(mesh_.L, root), -1});
    std::size_t begin = 0;
    for (int level = 0; level < depth_; ++level) {
      const std::size_t end = placements_.size();
      for (std::size_t i = begin; i < end && placements_.size() < kMaxPlacements; ++i) {
        const Placement from = placements_[i];
        for (int k = 0; k < 3 && placements_.size() < kMaxPlacements; ++k) {
          if (k == from.entered_by) continue;
          const Index across = mesh_.twin[static_cast<std::size_t>(side_of(from.face, k))];
          if (across == ice::kInvalid) continue;
          const Index g = across / 3;
          const int d = across % 3;  // side d of g runs from corner k+1 of f to corner k of f
          const Point a = from.corners[static_cast<std::size_t>((k + 1) % 3)], b = from.corners[static_cast<std::size_t>(k)];
          const ice::Vec2 third = ice::layout_third_point({a.real(), a.imag()}, {b.real(), b.imag()}, mesh_.L(g, d),
                                                           mesh_.L(g, (d + 2) % 3), mesh_.L(g, (d + 1) % 3));
          std::array<Point, 3> layout;
          layout[static_cast<std::size_t>(d)] = a;
          layout[static_cast<std::size_t>((d + 1) % 3)] = b;
          layout[static_cast<std::size_t>((d + 2) % 3)] = Point(third.x, third.y);
          place({g, d, static_cast<Index>(i), layout, -1});
        }
      }
      begin = end;
    }
  }
  // Position of a point of the map in the patch as seen from `from` (see the class comment), if its
  // face (or, for a coarse vertex, a face at it) was laid out.
  bool position(const ice::CoarsePoint& point, Point from, Point& out) const {
    candidates_.clear();
    const auto add = [&](Index placement, Point candidate) {
      for (const auto& [other, place] : candidates_)
        if (std::abs(place - candidate) <= 1e-12 * std::abs(place - from)) return;  // the same place again
      candidates_.emplace_back(placement, candidate);
    };
    if (point.coarse_vertex == ice::kInvalid) {
      if (point.face < 0) return false;
      for (Index i = first_[static_cast<std::size_t>(point.face)]; i >= 0; i = placements_[static_cast<std::size_t>(i)].next_copy) {
        const std::array<Point, 3>& c = placements_[static_cast<std::size_t>(i)].corners;
        add(i, point.bary[0] * c[0] + point.bary[1] * c[1] + point.bary[2] * c[2]);
      }
    } else {
      for (std::size_t i = 0; i < placements_.size(); ++i)
        for (int k = 0; k < 3; ++k)
          if (mesh_.F(placements_[i].face, k) == point.coarse_vertex)
            add(static_cast<Index>(i), placements_[i].corners[static_cast<std::size_t>(k)]);
    }
    if (candidates_.empty()) return false;
    // Nearest first; the first whose segment follows its route, else the nearest.
    std::sort(candidates_.begin(), candidates_.end(),
              [&](const auto& x, const auto& y) { return std::abs(x.second - from) < std::abs(y.second - from); });
    out = candidates_.front().second;
    if (candidates_.size() > 1)
      for (const auto& [placement, candidate] : candidates_)
        if (follows_route(placement, from, candidate)) {
          out = candidate;
          break;
        }
    return true;
  }

 private:
  struct Placement {
    Index face;
    int entered_by;    // side of `face` crossed to reach it (-1: the root)
    Index parent;      // placement it was reached from (-1: the root)
    std::array<Point, 3> corners;
    Index next_copy;   // the face's previous placement, or -1
  };
  static constexpr std::size_t kMaxPlacements = 96;
  void place(Placement p) {
    p.next_copy = first_[static_cast<std::size_t>(p.face)];
    first_[static_cast<std::size_t>(p.face)] = static_cast<Index>(placements_.size());
    placements_.push_back(p);
  }
  // Whether the segment p→q crosses every side its placement's route crossed (up to round-off), i.e.
  // unfolds along that route.
  bool follows_route(Index placement, Point p, Point q) const {
    for (Index i = placement; i >= 0 && placements_[static_cast<std::size_t>(i)].parent >= 0;
         i = placements_[static_cast<std::size_t>(i)].parent) {
      const Placement& step = placements_[static_cast<std::size_t>(i)];
      const Point a = step.corners[static_cast<std::size_t>(step.entered_by)];
      const Point b = step.corners[static_cast<std::size_t>((step.entered_by + 1) % 3)];
      if (!segments_meet(p, q, a, b)) return false;
    }
    return true;
  }
  static double cross(Point u, Point v) { return u.real() * v.imag() - u.imag() * v.real(); }
  static bool segments_meet(Point p, Point q, Point a, Point b) {
    const double slack = 1e-9 * std::norm(std::abs(q - p) + std::abs(b - a));  // round-off of the cross products
    const double side_a = cross(q - p, a - p), side_b = cross(q - p, b - p);
    const double side_p = cross(b - a, p - a), side_q = cross(b - a, q - a);
    return std::min(side_a, side_b) <= slack && std::max(side_a, side_b) >= -slack && std::min(side_p, side_q) <= slack &&
           std::max(side_p, side_q) >= -slack;
  }
  const ice::IntrinsicMesh& mesh_;
  int depth_;
  std::vector<Index> first_;  // per face: its latest placement, or -1
  std::vector<Placement> placements_;
  mutable std::vector<std::pair<Index, Point>> candidates_;  // position()'s scratch
};

// The polar chart of a coarse vertex: a point in a face at the vertex becomes ρ·e^{i(coordinate)} in
// the vertex's own frame (angles scaled as its frame scales them).
class PolarChart {
 public:
  PolarChart(const ice::IntrinsicMesh& mesh, const TangentFrames& frames, const Eigen::MatrixXd& angles, const Fans& fans)
      : mesh_(mesh), frames_(frames), angles_(angles), fans_(fans) {}
  void build(Index vertex) {
    vertex_ = vertex;
    corners_.clear();
    fans_.for_each(vertex, [&](Index c) { corners_.push_back(c); });
  }
  bool position(const ice::CoarsePoint& point, Point near, Point& out) const {
    if (point.coarse_vertex == vertex_) {
      out = 0;
      return true;
    }
    // In a face of the fan: the corner at the vertex nearest to the point (a face may hold it twice).
    const Index* best = nullptr;
    for (const Index& c : corners_)
      if (c / 3 == point.face && (best == nullptr || point.bary[static_cast<std::size_t>(c % 3)] > point.bary[static_cast<std::size_t>(*best % 3)]))
        best = &c;
    if (best != nullptr) {
      const Index f = *best / 3;
      const int k = *best % 3;
      const std::array<Point, 3> c = face_layout(mesh_.L, f);
      const Point offset = point.bary[0] * c[0] + point.bary[1] * c[1] + point.bary[2] * c[2] - c[static_cast<std::size_t>(k)];
      double within = std::arg(offset * std::polar(1.0, -side_direction(angles_, f, k)));
      within = std::clamp(within, 0.0, angles_(f, k));
      out = std::polar(std::abs(offset), frames_.side_coordinate(f, k) + frames_.angle_scale(vertex_) * within);
      return true;
    }
    // A coarse vertex at the far end of one of the fan's sides (the nearest, with multi-edges).
    if (point.coarse_vertex == ice::kInvalid) return false;
    bool found = false;
    const auto consider = [&](Point candidate) {
      if (!found || std::abs(candidate - near) < std::abs(out - near)) out = candidate;
      found = true;
    };
    for (Index c : corners_) {
      const Index f = c / 3;
      const int k = c % 3;
      if (mesh_.F(f, (k + 1) % 3) == point.coarse_vertex) consider(std::polar(mesh_.L(f, k), frames_.side_coordinate(f, k)));
      if (mesh_.F(f, (k + 2) % 3) == point.coarse_vertex)
        consider(std::polar(mesh_.L(f, (k + 2) % 3), frames_.side_coordinate(f, k) + frames_.angle_scale(vertex_) * angles_(f, k)));
    }
    return found;
  }

 private:
  const ice::IntrinsicMesh& mesh_;
  const TangentFrames& frames_;
  const Eigen::MatrixXd& angles_;
  const Fans& fans_;
  Index vertex_ = ice::kInvalid;
  std::vector<Index> corners_;
};

// Least-squares similarity z_chart ≈ a·z_fine over the one-ring; returns false without a usable pair.
struct RotationFit {
  Complex rotation{1, 0};
  double residual = 0;
};
template <class Chart>
bool fit_rotation(const std::vector<std::pair<Index, Complex>>& ring, const std::vector<ice::CoarsePoint>& map,
                  const Chart& chart, Point origin, RotationFit& fit) {
  Complex cross(0);
  double fine_norm = 0, chart_norm = 0;
  for (const auto& [neighbour, fine_edge] : ring) {
    Point image;
    if (!chart.position(map[static_cast<std::size_t>(neighbour)], origin, image)) continue;
    const Complex chart_edge = image - origin;
    if (std::abs(chart_edge) == 0) continue;
    cross += std::conj(fine_edge) * chart_edge;
    fine_norm += std::norm(fine_edge);
    chart_norm += std::norm(chart_edge);
  }
  if (!(std::abs(cross) > 1e-300)) return false;
  fit.rotation = cross / std::abs(cross);
  // The best similarity a = cross / fine_norm leaves Σ|chart − a·fine|² = chart_norm − |cross|²/fine_norm.
  fit.residual = std::sqrt(std::max(0.0, 1 - std::norm(cross) / (fine_norm * chart_norm)));
  return true;
}

}  // namespace

ComplexSparseMatrix vector_prolongation(const ice::IntrinsicMesh& fine, const TangentFrames& fine_frames,
                                        const ice::IntrinsicMesh& coarse, const TangentFrames& coarse_frames,
                                        const std::vector<ice::CoarsePoint>& map, VectorProlongationStats* stats) {
  const Eigen::Index n_fine = static_cast<Eigen::Index>(fine_frames.reference_corner.size());
  const Eigen::Index n_coarse = static_cast<Eigen::Index>(coarse_frames.reference_corner.size());
  if (static_cast<Eigen::Index>(map.size()) != n_fine)
    throw std::invalid_argument("vector_prolongation: " + std::to_string(map.size()) + " map points for " +
                                std::to_string(n_fine) + " fine vertices");
  for (std::size_t i = 0; i < map.size(); ++i)
    if (map[i].face < 0 || map[i].face >= coarse.F.rows() || map[i].coarse_vertex >= n_coarse)
      throw std::invalid_argument("vector_prolongation: map point " + std::to_string(i) + " names a face or vertex beyond the coarse mesh");
  const Eigen::MatrixXd fine_angles = corner_angles(fine.L);
  const Eigen::MatrixXd coarse_angles = corner_angles(coarse.L);
  const Fans fine_fans = vertex_fans(fine, fine_frames);
  const Fans coarse_fans = vertex_fans(coarse, coarse_frames);

  // Fine vertices grouped by their coarse face (survivors by their coarse vertex), so that each chart
  // is built once.
  std::vector<Index> order(static_cast<std::size_t>(n_fine));
  for (Index i = 0; i < n_fine; ++i) order[static_cast<std::size_t>(i)] = i;
  auto key = [&](Index i) {
    const ice::CoarsePoint& p = map[static_cast<std::size_t>(i)];
    return p.coarse_vertex != ice::kInvalid ? std::pair<int, Index>(0, p.coarse_vertex) : std::pair<int, Index>(1, p.face);
  };
  std::sort(order.begin(), order.end(), [&](Index a, Index b) { return key(a) < key(b); });

  UnfoldedPatch patch(coarse, 3);
  PolarChart polar(coarse, coarse_frames, coarse_angles, coarse_fans);
  Index patch_root = ice::kInvalid, polar_root = ice::kInvalid;
  auto polar_at = [&](Index v) -> const PolarChart& {
    if (polar_root != v) polar.build(v), polar_root = v;
    return polar;
  };

  std::vector<Eigen::Triplet<Complex, Index>> triplets;
  triplets.reserve(static_cast<std::size_t>(3 * n_fine));
  std::vector<std::pair<Index, Complex>> ring;
  std::vector<double> residuals;
  VectorProlongationStats counts;
  const auto count_fit = [&](const RotationFit& fit) {
    ++counts.fitted;
    counts.poor_fits += fit.residual > kPoorFitResidual;
    residuals.push_back(fit.residual);
  };
  for (Index i : order) {
    const ice::CoarsePoint& point = map[static_cast<std::size_t>(i)];
    // The fine one-ring as edge vectors in i's frame: each corner's outgoing side, and at the last
    // corner of a boundary fan its incoming one too (inside a fan that is the next corner's side).
    ring.clear();
    const double scale = fine_frames.angle_scale(i);
    fine_fans.for_each(i, [&](Index c) {
      const Index f = c / 3;
      const int k = c % 3;
      const double coordinate = fine_frames.side_coordinate(f, k);
      const Index to = fine.F(f, (k + 1) % 3), back = fine.F(f, (k + 2) % 3);
      if (to != i) ring.emplace_back(to, std::polar(fine.L(f, k), coordinate));
      if (back != i && next_ccw_corner(fine.twin, c) == ice::kInvalid)
        ring.emplace_back(back, std::polar(fine.L(f, (k + 2) % 3), coordinate + scale * fine_angles(f, k)));
    });
    RotationFit fit;
    if (point.coarse_vertex != ice::kInvalid) {
      // A survivor: its fine frame against its coarse vertex's frame.
      if (fit_rotation(ring, map, polar_at(point.coarse_vertex), Point(0), fit)) {
        count_fit(fit);
      } else {
        ++counts.unmatched;
      }
      triplets.emplace_back(i, point.coarse_vertex, std::conj(fit.rotation));
      continue;
    }
    // A removed vertex: its fine frame against the layout of its coarse face.
    const Index f = point.face;
    if (patch_root != f) patch.build(f), patch_root = f;
    const std::array<Point, 3> corners = face_layout(coarse.L, f);
    const Point origin = point.bary[0] * corners[0] + point.bary[1] * corners[1] + point.bary[2] * corners[2];
    if (fit_rotation(ring, map, patch, origin, fit)) {
      count_fit(fit);
    } else {
      // Fall back on the polar chart of the nearest corner (the vertex frame, then into the face).
      const int k = static_cast<int>(std::max_element(point.bary.begin(), point.bary.end()) - point.bary.begin());
      const Index corner_vertex_index = coarse.F(f, k);
      const PolarChart& chart = polar_at(corner_vertex_index);
      Point own;
      if (chart.position(point, Point(0), own) && fit_rotation(ring, map, chart, own, fit)) {
        fit.rotation *= std::polar(1.0, coarse_frames.corner_rotation(f, k));
        ++counts.from_corner;
      } else {
        fit.rotation = Complex(1);
        ++counts.unmatched;
      }
    }
    for (int k = 0; k < 3; ++k)
      if (point.bary[static_cast<std::size_t>(k)] != 0)
        triplets.emplace_back(i, coarse.F(f, k),
                              point.bary[static_cast<std::size_t>(k)] * std::conj(fit.rotation) *
                                  std::polar(1.0, coarse_frames.corner_rotation(f, k)));
  }
  ComplexSparseMatrix P(n_fine, n_coarse);
  P.setFromTriplets(triplets.begin(), triplets.end());
  P.makeCompressed();
  if (stats != nullptr) {
    if (!residuals.empty()) {
      std::nth_element(residuals.begin(), residuals.begin() + static_cast<std::ptrdiff_t>(residuals.size() / 2), residuals.end());
      counts.median_fit_residual = residuals[residuals.size() / 2];
    }
    *stats = counts;
  }
  return P;
}

// The fine operators only serve the Galerkin products.
VectorHeatProxy::VectorHeatProxy(const ice::IntrinsicMesh& fine, const TangentFrames& fine_frames,
                                 const ice::IntrinsicMesh& coarse, const TangentFrames& coarse_frames,
                                 const std::vector<ice::CoarsePoint>& map, SparseMatrix P, VectorOperatorKind kind,
                                 double time_factor)
    : VectorHeatProxy(fine, fine_frames,
                      kind == VectorOperatorKind::galerkin ? vector_heat_operators(fine, fine_frames) : VectorHeatOperators{},
                      coarse, coarse_frames, map, std::move(P), kind, time_factor) {}

VectorHeatProxy::VectorHeatProxy(const ice::IntrinsicMesh& fine, const TangentFrames& fine_frames,
                                 const VectorHeatOperators& fine_operators, const ice::IntrinsicMesh& coarse,
                                 const TangentFrames& coarse_frames, const std::vector<ice::CoarsePoint>& map,
                                 SparseMatrix P, VectorOperatorKind kind, double time_factor)
    : P_(std::move(P)) {
  const Eigen::Index n_fine = static_cast<Eigen::Index>(fine_frames.reference_corner.size());
  const Eigen::Index n_coarse = static_cast<Eigen::Index>(coarse_frames.reference_corner.size());
  if (P_.rows() != n_fine || P_.cols() != n_coarse)
    throw std::invalid_argument("VectorHeatProxy: P is " + std::to_string(P_.rows()) + " x " + std::to_string(P_.cols()) +
                                ", the meshes have " + std::to_string(n_fine) + " and " + std::to_string(n_coarse) + " vertices");
  if (kind == VectorOperatorKind::galerkin && fine_operators.mass.rows() != n_fine)
    throw std::invalid_argument("VectorHeatProxy: the fine operators are not of the fine mesh's size");
  vector_prolongation_ = fem::vector_prolongation(fine, fine_frames, coarse, coarse_frames, map, &stats_);
  VectorHeatOperators coarse_ops;
  if (kind == VectorOperatorKind::intrinsic) {
    coarse_ops = vector_heat_operators(coarse, coarse_frames, time_factor);
  } else {
    coarse_ops.laplacian = galerkin(P_, fine_operators.laplacian);
    const Eigen::VectorXd coarse_areas = P_.transpose() * fine_operators.mass.diagonal();
    coarse_ops.mass = SparseMatrix(coarse_areas.asDiagonal());
    const ComplexSparseMatrix product = vector_prolongation_.adjoint() * (fine_operators.connection * vector_prolongation_);
    coarse_ops.connection = 0.5 * (product + ComplexSparseMatrix(product.adjoint()));
    detail::stabilise_weak_coarse_unknowns(vector_prolongation_, coarse_ops.connection);
    detail::stabilise_weak_coarse_unknowns(P_, coarse_ops.mass);  // Pᵀ·areas is zero there too
    const double h = time_factor * mean_edge_length(coarse.L);
    coarse_ops.time_step = h * h;
  }
  coarse_solver_ = std::make_unique<VectorHeatSolver>(std::move(coarse_ops));
}

Eigen::VectorXcd VectorHeatProxy::interpolate(const std::vector<Index>& vertices, const std::vector<Complex>& vectors) const {
  const VectorSources sources = vector_sources(P_.rows(), vertices, vectors);
  const Eigen::VectorXcd coarse_vectors = vector_prolongation_.adjoint() * sources.vectors;
  const Eigen::VectorXd coarse_magnitudes = P_.transpose() * sources.magnitudes;
  const Eigen::VectorXd coarse_indicator = P_.transpose() * sources.indicator;
  const VectorHeatParts coarse = coarse_solver_->diffuse(coarse_vectors, coarse_magnitudes, coarse_indicator);
  VectorHeatParts prolonged;
  prolonged.directions = vector_prolongation_ * coarse.directions;
  prolonged.magnitudes = P_ * coarse.magnitudes;
  prolonged.indicator = P_ * coarse.indicator;
  return vector_heat_field(prolonged, sources.min_magnitude, sources.max_magnitude);
}

double angle_between_degrees(Complex a, Complex b) {
  if (a == Complex(0) || b == Complex(0)) return std::nan("");
  return std::abs(std::arg(a * std::conj(b))) * 180.0 / kPi;
}

}  // namespace fem
