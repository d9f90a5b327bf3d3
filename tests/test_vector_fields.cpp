// Tangent vector fields: frames, the connection Laplacian, the vector heat method on the fine mesh
// and through the coarse proxy, and the vector prolongation.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "fem/vector_fields.h"
#include "ice/coarse_space.h"
#include "ice/intrinsic_triangulation.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/triangle_geometry.h"
#include "test_support.h"

namespace {

using ice::Index;
using ice::kPi;

ice::IntrinsicMesh glued(const ice::TriangleMesh& mesh) {
  ice::IntrinsicMesh out = ice::intrinsic_mesh(mesh);
  out.twin = ice::glue_by_vertex_pairs(mesh.F);
  return out;
}

double wrap_angle(double a) { return std::remainder(a, 2 * kPi); }

// Largest modulus among the stored entries (sparse: the matrices here are too large to densify).
double largest_entry(const fem::ComplexSparseMatrix& A) {
  double largest = 0;
  for (Eigen::Index k = 0; k < A.outerSize(); ++k)
    for (fem::ComplexSparseMatrix::InnerIterator it(A, k); it; ++it) largest = std::max(largest, std::abs(it.value()));
  return largest;
}

double median(std::vector<double> values) {
  REQUIRE(!values.empty());
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

std::vector<double> angle_errors(const Eigen::VectorXcd& a, const Eigen::VectorXcd& b) {
  std::vector<double> errors;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    const double e = fem::angle_between_degrees(a(i), b(i));
    if (!std::isnan(e)) errors.push_back(e);
  }
  return errors;
}

// Error (degrees) of a field on the unit icosphere against the exact transport of `start` from
// `source` along great circles, over the vertices at most 150° from the source: median and max.
std::pair<double, double> sphere_field_error(const ice::TriangleMesh& mesh, const ice::IntrinsicMesh& fine,
                                             const fem::TangentFrames& frames, Index source, const Eigen::Vector3d& start,
                                             const Eigen::VectorXcd& field) {
  const Eigen::Vector3d p = mesh.V.row(source).transpose().normalized();
  const Eigen::MatrixXd ambient = fem::tangent_to_ambient(fine, frames, mesh.V, field);
  std::vector<double> errors;
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i) {
    const Eigen::Vector3d x = mesh.V.row(i).transpose().normalized();
    const double distance = std::acos(std::clamp(p.dot(x), -1.0, 1.0));
    if (distance < 1e-9 || distance > 150 * kPi / 180) continue;
    const Eigen::Vector3d expected = Eigen::AngleAxisd(distance, p.cross(x).normalized()) * start;
    Eigen::Vector3d got = ambient.row(i).transpose();
    got = (got - got.dot(x) * x).normalized();
    errors.push_back(std::acos(std::clamp(got.dot(expected), -1.0, 1.0)) * 180 / kPi);
  }
  return {median(errors), *std::max_element(errors.begin(), errors.end())};
}

// A unit tangent vector at `source` of the unit icosphere `mesh`: in 3D and in the source's frame.
std::pair<Eigen::Vector3d, fem::Complex> sphere_start(const ice::TriangleMesh& mesh, const ice::IntrinsicMesh& fine,
                                                      const fem::TangentFrames& frames, Index source) {
  const Eigen::Vector3d p = mesh.V.row(source).transpose().normalized();
  Eigen::Vector3d start(1, 0.3, 0.2);
  start = (start - start.dot(p) * p).normalized();
  // The projection into a face plane shortens a unit tangent vector by the face's tilt only (0.3 %
  // on the 642-vertex sphere, 0.02 % on the 10,242-vertex one).
  const fem::Complex z0 = fem::ambient_to_tangent(fine, frames, mesh.V, source, start);
  CHECK(std::abs(z0) == Approx(1).epsilon(1e-2));
  return {start, z0 / std::abs(z0)};
}

// Parallel transport of a unit vector from the vertex nearest the north pole of an icosphere by the
// vector heat method, compared with the exact transport (sphere_field_error).
std::pair<double, double> sphere_transport_error(int subdivisions) {
  const ice::TriangleMesh mesh = ice::make_icosphere(subdivisions);
  const ice::IntrinsicMesh fine = glued(mesh);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const Index source = 0;
  const auto [start, z0] = sphere_start(mesh, fine, frames, source);
  const fem::VectorHeatSolver solver(fem::vector_heat_operators(fine, frames, 3.0));
  const Eigen::VectorXcd field = solver.interpolate({source}, {z0});
  CHECK((field.cwiseAbs().array() - 1.0).abs().maxCoeff() < 1e-6);  // one source: the magnitude is the source's
  return sphere_field_error(mesh, fine, frames, source, start, field);
}

// The rotation a vector picks up going once around a closed loop of vertices, each step carried by
// the connection Laplacian's own transport (the phase of −A(next, current)).
double loop_holonomy(const fem::ComplexSparseMatrix& A, const std::vector<Index>& loop) {
  double total = 0;
  for (std::size_t k = 0; k < loop.size(); ++k) {
    const Index from = loop[k], to = loop[(k + 1) % loop.size()];
    const fem::Complex entry = A.coeff(to, from);
    REQUIRE(std::abs(entry) > 0);
    total += std::arg(-entry);
  }
  return wrap_angle(total);
}

// The boundary loop (counter-clockwise around the cap) of the faces of an icosphere whose three
// vertices have z > height, and the angle defect enclosed by it.
struct Cap {
  std::vector<Index> loop;
  double inner_defect = 0;    ///< Σ (2π − Θ) over vertices strictly inside
  double boundary_defect = 0;  ///< Σ |2π − Θ| over the loop's vertices
};
Cap sphere_cap(const ice::TriangleMesh& mesh, const fem::TangentFrames& frames, double height) {
  std::map<Index, Index> next;  // boundary side of the cap: tail -> head
  std::vector<char> in_cap_face(static_cast<std::size_t>(mesh.F.rows()), 0);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    in_cap_face[static_cast<std::size_t>(f)] =
        mesh.V(mesh.F(f, 0), 2) > height && mesh.V(mesh.F(f, 1), 2) > height && mesh.V(mesh.F(f, 2), 2) > height;
  const std::vector<Index> twin = ice::glue_by_vertex_pairs(mesh.F);
  std::vector<char> on_loop(static_cast<std::size_t>(mesh.V.rows()), 0), touched(static_cast<std::size_t>(mesh.V.rows()), 0);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    if (!in_cap_face[static_cast<std::size_t>(f)]) continue;
    for (int k = 0; k < 3; ++k) {
      touched[static_cast<std::size_t>(mesh.F(f, k))] = 1;
      const Index across = twin[static_cast<std::size_t>(3 * f + k)];
      if (!in_cap_face[static_cast<std::size_t>(across / 3)]) {
        next[mesh.F(f, k)] = mesh.F(f, (k + 1) % 3);
        on_loop[static_cast<std::size_t>(mesh.F(f, k))] = 1;
      }
    }
  }
  Cap cap;
  REQUIRE(!next.empty());
  Index v = next.begin()->first;
  do {
    cap.loop.push_back(v);
    v = next.at(v);
  } while (v != cap.loop.front() && cap.loop.size() <= next.size());
  REQUIRE(cap.loop.size() == next.size());  // one simple loop
  for (Eigen::Index u = 0; u < mesh.V.rows(); ++u) {
    const double defect = 2 * kPi - frames.angle_sum(u);
    if (on_loop[static_cast<std::size_t>(u)]) cap.boundary_defect += std::abs(defect);
    else if (touched[static_cast<std::size_t>(u)]) cap.inner_defect += defect;
  }
  return cap;
}

}  // namespace

TEST_CASE("tangent frames: coordinates start at 0 and span the circle", "[fem][vectors]") {
  const ice::TriangleMesh disk = ice::make_flat_disk(6, 1.0, 0.2);
  const ice::TriangleMesh sphere = ice::make_icosphere(2);
  for (const ice::TriangleMesh* mesh : {&disk, &sphere}) {
    const ice::IntrinsicMesh m = glued(*mesh);
    const fem::TangentFrames frames = fem::tangent_frames(m);
    const Eigen::MatrixXd angles = fem::corner_angles(m.L);
    for (Eigen::Index v = 0; v < mesh->V.rows(); ++v) {
      const Index reference = frames.reference_corner[static_cast<std::size_t>(v)];
      REQUIRE(reference != ice::kInvalid);
      CHECK(frames.side_coordinate(reference / 3, reference % 3) == 0.0);
    }
    // Per vertex, the coordinates plus the scaled corner angles add up to 2π inside and Θ on the boundary.
    Eigen::VectorXd span = Eigen::VectorXd::Zero(mesh->V.rows());
    for (Eigen::Index f = 0; f < m.F.rows(); ++f)
      for (int k = 0; k < 3; ++k) span(m.F(f, k)) += frames.angle_scale(m.F(f, k)) * angles(f, k);
    for (Eigen::Index v = 0; v < mesh->V.rows(); ++v)
      CHECK(span(v) == Approx(frames.boundary[static_cast<std::size_t>(v)] ? frames.angle_sum(v) : 2 * kPi).epsilon(1e-12));
  }
}

TEST_CASE("tangent frames refuse a mesh without its gluing", "[fem][vectors]") {
  ice::IntrinsicMesh m = glued(ice::make_icosphere(1));
  m.twin.clear();
  CHECK_THROWS_AS(fem::tangent_frames(m), std::invalid_argument);
  m = glued(ice::make_icosphere(1));
  m.twin[0] = m.twin[1];  // no longer an involution
  CHECK_THROWS_AS(fem::tangent_frames(m), std::invalid_argument);
}

TEST_CASE("connection Laplacian of a flat disk is the scalar Laplacian of each component", "[fem][vectors]") {
  // Written in the plane's own frame (z_v = e^{−iθ_v} w_v, θ_v the direction of v's reference side),
  // the connection Laplacian must be the real cotan Laplacian: D A Dᴴ = L.
  const ice::TriangleMesh disk = ice::make_flat_disk(8, 1.0, 0.25);
  const ice::IntrinsicMesh m = glued(disk);
  const fem::TangentFrames frames = fem::tangent_frames(m);
  const fem::ComplexSparseMatrix A = fem::connection_laplacian(m, frames);
  const fem::SparseMatrix L = fem::cotan_laplacian(m);
  const Eigen::Index n = disk.V.rows();
  Eigen::VectorXcd D(n);
  for (Eigen::Index v = 0; v < n; ++v) {
    const Index c = frames.reference_corner[static_cast<std::size_t>(v)];
    const Eigen::RowVector3d side = disk.V.row(m.F(c / 3, (c % 3 + 1) % 3)) - disk.V.row(v);
    D(v) = std::polar(1.0, std::atan2(side(1), side(0)));
  }
  const Eigen::MatrixXcd conjugated = D.asDiagonal() * Eigen::MatrixXcd(A) * D.conjugate().asDiagonal();
  const Eigen::MatrixXcd scalar = Eigen::MatrixXd(L).cast<fem::Complex>();
  CHECK((conjugated - scalar).cwiseAbs().maxCoeff() < 1e-12 * scalar.cwiseAbs().maxCoeff());
}

TEST_CASE("connection Laplacian is Hermitian positive semidefinite on a coarse Δ-complex", "[fem][vectors]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  ice::CoarseSpaceOptions options;
  options.coarsen.target_vertices = 60;
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const fem::TangentFrames frames = fem::tangent_frames(space.mesh);
  const Eigen::MatrixXcd A = Eigen::MatrixXcd(fem::connection_laplacian(space.mesh, frames));
  CHECK((A - A.adjoint()).cwiseAbs().maxCoeff() < 1e-13 * A.cwiseAbs().maxCoeff());
  const Eigen::VectorXd eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(A).eigenvalues();
  CHECK(eigenvalues.minCoeff() > -1e-10 * eigenvalues.maxCoeff());
  // A closed curved surface has no parallel field: the connection Laplacian is definite.
  CHECK(eigenvalues.minCoeff() > 1e-8 * eigenvalues.maxCoeff());
}

TEST_CASE("holonomy around a cap of a sphere equals the enclosed curvature", "[fem][vectors]") {
  // Carried around the cap's boundary, a vector turns by the curvature inside (discrete Gauss–Bonnet:
  // the angle defects of the cap's vertices); the loop's own vertices share theirs with the outside,
  // so the difference is bounded by their defects and shrinks under refinement.
  double previous_gap = INFINITY, previous_smooth_gap = INFINITY;
  for (int subdivisions : {3, 4, 5}) {
    const ice::TriangleMesh mesh = ice::make_icosphere(subdivisions);
    const ice::IntrinsicMesh m = glued(mesh);
    const fem::TangentFrames frames = fem::tangent_frames(m);
    const Cap cap = sphere_cap(mesh, frames, 0.3);
    const double holonomy = loop_holonomy(fem::connection_laplacian(m, frames), cap.loop);
    const double gap = std::abs(wrap_angle(holonomy - cap.inner_defect));
    INFO("subdivisions " << subdivisions << ": holonomy " << holonomy << ", inner defect " << cap.inner_defect
                         << ", loop vertices' defects " << cap.boundary_defect);
    CHECK(gap <= cap.boundary_defect);
    // The smooth cap's curvature 2π(1 − 0.3) is approached too, as the jagged loop nears the circle
    // z = 0.3 (measured 0.45, 0.18, 0.11).
    const double smooth_gap = std::abs(wrap_angle(holonomy - 2 * kPi * 0.7));
    CHECK(smooth_gap < 0.5);
    CHECK(smooth_gap < previous_smooth_gap);
    CHECK(gap < previous_gap);
    previous_gap = gap;
    previous_smooth_gap = smooth_gap;
  }
}

TEST_CASE("vector heat method: parallel transport on a sphere converges to the exact transport", "[fem][vectors]") {
  const auto [coarse_median, coarse_max] = sphere_transport_error(4);
  const auto [fine_median, fine_max] = sphere_transport_error(5);
  INFO("median / max error: " << coarse_median << " / " << coarse_max << " deg at 2,562 vertices, " << fine_median
                              << " / " << fine_max << " deg at 10,242");
  CHECK(fine_median < 0.05);
  CHECK(fine_max < 0.2);
  CHECK(fine_median < 0.5 * coarse_median);  // second order: ~4x per halving of h
}

TEST_CASE("vector heat method interpolates prescribed vectors", "[fem][vectors]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(4);
  const ice::IntrinsicMesh m = glued(mesh);
  const fem::TangentFrames frames = fem::tangent_frames(m);
  const fem::VectorHeatSolver solver(fem::vector_heat_operators(m, frames));
  const std::vector<Index> sources = {0, 5, 9};
  const std::vector<fem::Complex> vectors = {std::polar(1.0, 0.3), std::polar(2.0, 2.0), std::polar(3.0, -1.0)};
  const Eigen::VectorXcd field = solver.interpolate(sources, vectors);
  for (std::size_t s = 0; s < sources.size(); ++s) {
    CHECK(fem::angle_between_degrees(field(sources[s]), vectors[s]) < 2.0);
    CHECK(std::abs(field(sources[s])) == Approx(std::abs(vectors[s])).epsilon(0.05));
  }
  for (Eigen::Index v = 0; v < field.size(); ++v) {  // magnitudes interpolate: within the given range
    CHECK(std::abs(field(v)) >= 1 - 1e-9);
    CHECK(std::abs(field(v)) <= 3 + 1e-9);
  }
  CHECK_THROWS_AS(solver.interpolate({0, 1}, {fem::Complex(1)}), std::invalid_argument);
  CHECK_THROWS_AS(solver.interpolate({}, {}), std::invalid_argument);
  CHECK_THROWS_AS(solver.interpolate({static_cast<Index>(mesh.V.rows())}, {fem::Complex(1)}), std::invalid_argument);
}

TEST_CASE("vector prolongation without coarsening is a change of frames", "[fem][vectors]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  const ice::IntrinsicMesh fine = glued(mesh);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const Eigen::Index n = mesh.V.rows();
  SECTION("the same mesh on both sides: the identity") {
    std::vector<ice::CoarsePoint> map(static_cast<std::size_t>(n));
    for (Eigen::Index f = 0; f < fine.F.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        ice::CoarsePoint& p = map[static_cast<std::size_t>(fine.F(f, k))];
        p.coarse_vertex = fine.F(f, k);
        p.face = static_cast<Index>(f);
        p.bary = {0, 0, 0};
        p.bary[static_cast<std::size_t>(k)] = 1;
      }
    const fem::ComplexSparseMatrix P = fem::vector_prolongation(fine, frames, fine, frames, map);
    fem::ComplexSparseMatrix identity(n, n);
    identity.setIdentity();
    CHECK(largest_entry(fem::ComplexSparseMatrix(P - identity)) < 1e-12);
  }
  SECTION("ICE with no removal: diagonal, unitary, and carries one connection Laplacian to the other") {
    ice::CoarseSpaceOptions options;
    options.coarsen.target_vertices = static_cast<Index>(n);
    options.keep_method_state = true;
    const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
    REQUIRE(space.mesh.num_vertices() == n);
    const fem::TangentFrames coarse_frames = fem::tangent_frames(space.mesh);
    const fem::ComplexSparseMatrix P =
        fem::vector_prolongation(fine, frames, space.mesh, coarse_frames, ice::fine_to_coarse_map(space));
    CHECK(P.nonZeros() == n);
    for (Eigen::Index v = 0; v < n; ++v) CHECK(std::abs(std::abs(P.coeff(v, v)) - 1) < 1e-12);
    const fem::ComplexSparseMatrix galerkin =
        fem::ComplexSparseMatrix(P.adjoint()) * (fem::connection_laplacian(fine, frames) * P);
    const fem::ComplexSparseMatrix coarse = fem::connection_laplacian(space.mesh, coarse_frames);
    CHECK(largest_entry(fem::ComplexSparseMatrix(galerkin - coarse)) < 1e-9 * largest_entry(coarse));
  }
}

TEST_CASE("vector heat method through the coarse proxy approaches the fine field", "[fem][vectors]") {
  // A sphere coarsened to 5 %: the proxy's transport against the fine mesh's, both operator kinds.
  const ice::TriangleMesh mesh = ice::make_icosphere(5);
  const ice::IntrinsicMesh fine = glued(mesh);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.keep_method_state = true;
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const fem::TangentFrames coarse_frames = fem::tangent_frames(space.mesh);
  const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(space);
  const fem::VectorHeatSolver solver(fem::vector_heat_operators(fine, frames));
  const Eigen::VectorXcd reference = solver.interpolate({17}, {fem::Complex(0, 1)});
  for (const fem::VectorOperatorKind kind : {fem::VectorOperatorKind::intrinsic, fem::VectorOperatorKind::galerkin}) {
    const fem::VectorHeatProxy proxy(fine, frames, space.mesh, coarse_frames, map, space.P, kind);
    CHECK(proxy.prolongation_stats().unmatched == 0);
    // Rows: moduli are the barycentric coordinates of P.
    const fem::ComplexSparseMatrix& P_vec = proxy.vector_prolongation();
    CHECK(P_vec.nonZeros() == space.P.nonZeros());
    double gap = 0;
    for (Eigen::Index k = 0; k < P_vec.outerSize(); ++k)
      for (fem::ComplexSparseMatrix::InnerIterator it(P_vec, k); it; ++it)
        gap = std::max(gap, std::abs(std::abs(it.value()) - space.P.coeff(it.row(), it.col())));
    CHECK(gap < 1e-12);
    const Eigen::VectorXcd field = proxy.interpolate({17}, {fem::Complex(0, 1)});
    const std::vector<double> errors = angle_errors(field, reference);
    INFO("kind " << static_cast<int>(kind) << ": median angle error " << median(errors) << " deg");
    CHECK(median(errors) < 2.0);
  }
}

TEST_CASE("vector prolongation finds each neighbour's image along the faces its edge crosses", "[fem][vectors]") {
  // dino's thin limbs leave coarse faces that the unfolding around a coarse face reaches by two
  // routes (around a cone vertex), laid out at different places. Taking a neighbour's image from
  // the first copy reached made the fits fail (2 % of the frames a guess at 20 %, 4 % at 10 %) and
  // the transport from vertex 0 came out reversed (median 168° at 20 %); the copy whose route the
  // segment from the vertex follows gives 0.15 % / 0.3 % poor fits and 8.6°.
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("dino.off"));
  const ice::IntrinsicMesh fine = glued(mesh);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const fem::VectorHeatSolver solver(fem::vector_heat_operators(fine, frames));
  const Eigen::VectorXcd reference = solver.interpolate({0}, {fem::Complex(1, 0)});
  for (const double ratio : {0.1, 0.2}) {
    ice::CoarseSpaceOptions options;
    options.coarsen.target_ratio = ratio;
    options.keep_method_state = true;
    const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
    const fem::TangentFrames coarse_frames = fem::tangent_frames(space.mesh);
    const fem::VectorHeatProxy proxy(fine, frames, space.mesh, coarse_frames, ice::fine_to_coarse_map(space), space.P,
                                     fem::VectorOperatorKind::galerkin);
    const fem::VectorProlongationStats& stats = proxy.prolongation_stats();
    INFO("ratio " << ratio << ": " << stats.poor_fits << " poor fits of " << stats.fitted);
    CHECK(stats.unmatched == 0);
    CHECK(stats.poor_fits < 0.01 * static_cast<double>(stats.fitted));
    if (ratio == 0.2) {
      const double error = median(angle_errors(proxy.interpolate({0}, {fem::Complex(1, 0)}), reference));
      INFO("median angle error " << error << " deg");
      CHECK(error < 20.0);
    }
  }
}

TEST_CASE("vector heat method: every vertex reached gets a vector, of the sources' magnitudes, on a non-Delaunay mesh", "[fem][vectors]") {
  // lion-head's input triangles have negative cotan weights: far from a source the diffused
  // magnitude u and indicator φ both turn negative on 52 vertices. u/φ is still the sources'
  // weighted mean magnitude there; taking it only where φ > 0 left those vertices without a vector.
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("lion-head.off"));
  const ice::IntrinsicMesh fine = glued(mesh);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const fem::VectorHeatSolver solver(fem::vector_heat_operators(fine, frames));
  const fem::VectorSources one = fem::vector_sources(mesh.V.rows(), {0}, {fem::Complex(0, 1)});
  const fem::VectorHeatParts parts = solver.diffuse(one.vectors, one.magnitudes, one.indicator);
  CHECK(parts.indicator.minCoeff() < 0);  // the case this test is about
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.keep_method_state = true;
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const fem::VectorHeatProxy proxy(fine, frames, space.mesh, fem::tangent_frames(space.mesh), ice::fine_to_coarse_map(space),
                                   space.P, fem::VectorOperatorKind::galerkin);
  for (const bool through_proxy : {false, true}) {
    INFO((through_proxy ? "proxy" : "fine"));
    const auto field = [&](const std::vector<Index>& sources, const std::vector<fem::Complex>& vectors) {
      return through_proxy ? proxy.interpolate(sources, vectors) : solver.interpolate(sources, vectors);
    };
    const Eigen::VectorXcd transported = field({0}, {fem::Complex(0, 1)});
    CHECK((transported.cwiseAbs().array() - 1.0).abs().maxCoeff() < 1e-12);
    const Eigen::VectorXcd two = field({0, 4000}, {fem::Complex(1, 0), fem::Complex(0, 2)});
    CHECK(two.cwiseAbs().minCoeff() >= 1.0 - 1e-12);
    CHECK(two.cwiseAbs().maxCoeff() <= 2.0 + 1e-12);
    CHECK(std::abs(std::abs(two(4000)) - 2.0) < 0.05);
  }
}

TEST_CASE("vector heat operators on a second triangulation: the same operators in the input's frames", "[fem][vectors]") {
  SECTION("a Delaunay input: no flip, the input's own operators") {
    const ice::TriangleMesh mesh = ice::make_icosphere(2);
    const ice::IntrinsicMesh fine = glued(mesh);
    const fem::TangentFrames frames = fem::tangent_frames(fine);
    ice::IntrinsicTriangulation delaunay = ice::IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    REQUIRE(delaunay.flip_to_delaunay() == 0);
    const fem::VectorHeatOperators own = fem::vector_heat_operators(fine, frames, 2.0);
    const fem::VectorHeatOperators other = fem::vector_heat_operators(fine, frames, delaunay.compact(), 2.0);
    CHECK(other.time_step == own.time_step);
    CHECK(largest_entry(other.connection - own.connection) < 1e-12 * largest_entry(own.connection));
    CHECK((Eigen::MatrixXd(other.laplacian - own.laplacian)).cwiseAbs().maxCoeff() < 1e-12);
    CHECK((Eigen::MatrixXd(other.mass - own.mass)).cwiseAbs().maxCoeff() < 1e-15);
  }
  SECTION("a flat disk with obtuse triangles: the parallel field is in the null space") {
    // In the plane a field of one direction is parallel: e^{−iθ_v} in v's frame, θ_v the direction of
    // v's reference side. Any flat triangulation's connection Laplacian annihilates it, so the input's
    // frames must have been matched with the Delaunay triangulation's exactly.
    const ice::TriangleMesh disk = ice::make_flat_disk(10, 1.0, 0.3, 7);
    const ice::IntrinsicMesh fine = glued(disk);
    const fem::TangentFrames frames = fem::tangent_frames(fine);
    ice::IntrinsicTriangulation delaunay = ice::IntrinsicTriangulation::from_mesh(disk.V, disk.F);
    REQUIRE(delaunay.flip_to_delaunay() > 0);  // the input triangles are not Delaunay
    const fem::VectorHeatOperators ops = fem::vector_heat_operators(fine, frames, delaunay.compact());
    const Eigen::Index n = disk.V.rows();
    Eigen::VectorXcd parallel(n);
    for (Eigen::Index v = 0; v < n; ++v) {
      const Index c = frames.reference_corner[static_cast<std::size_t>(v)];
      const Eigen::RowVector3d side = disk.V.row(fine.F(c / 3, (c % 3 + 1) % 3)) - disk.V.row(v);
      parallel(v) = std::polar(1.0, -std::atan2(side(1), side(0)));
    }
    CHECK((ops.connection * parallel).cwiseAbs().maxCoeff() < 1e-10 * largest_entry(ops.connection));
    CHECK(largest_entry(ops.connection - fem::ComplexSparseMatrix(ops.connection.adjoint())) == 0);
    // Every cotan weight of the Delaunay triangulation is >= 0 inside, so the heat kernel stays
    // positive and transport from any vertex is exactly the parallel field.
    const fem::VectorHeatSolver solver(ops);
    const Eigen::VectorXcd field = solver.interpolate({0}, {parallel(0)});
    const std::vector<double> errors = angle_errors(field, parallel);
    CHECK(*std::max_element(errors.begin(), errors.end()) < 1e-6);
  }
  SECTION("another vertex count is refused") {
    const ice::TriangleMesh mesh = ice::make_icosphere(1);
    const ice::IntrinsicMesh fine = glued(mesh);
    const fem::TangentFrames frames = fem::tangent_frames(fine);
    ice::CompactMesh bigger = ice::IntrinsicTriangulation::from_mesh(mesh.V, mesh.F).compact();
    bigger.F(0, 0) = static_cast<Index>(mesh.V.rows());
    CHECK_THROWS_AS(fem::vector_heat_operators(fine, frames, bigger), std::invalid_argument);
  }
}

TEST_CASE("vector field from a distance: a flat disk's field is parallel, two lengths stay in their range", "[fem][vectors]") {
  const ice::TriangleMesh disk = ice::make_flat_disk(10, 1.0, 0.2, 3);
  const ice::IntrinsicMesh fine = glued(disk);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const fem::VectorHeatOperators operators = fem::vector_heat_operators(fine, frames);
  const Index source = 0, other = static_cast<Index>(disk.V.rows() / 2);
  Eigen::VectorXd distance(disk.V.rows());
  for (Eigen::Index i = 0; i < distance.size(); ++i) distance(i) = (disk.V.row(i) - disk.V.row(source)).norm();
  const fem::Complex start = std::polar(1.0, 0.7);
  fem::DistanceSweepStats stats;
  const Eigen::VectorXcd field = fem::vector_field_from_distance(operators, distance, {source}, {start}, {}, &stats);
  CHECK(stats.passes >= 1);
  const Eigen::MatrixXd ambient = fem::tangent_to_ambient(fine, frames, disk.V, field);
  const Eigen::Vector3d expected = ambient.row(source).transpose();
  REQUIRE(expected.norm() == Approx(1).epsilon(1e-12));
  for (Eigen::Index i = 0; i < ambient.rows(); ++i) CHECK((ambient.row(i).transpose() - expected).norm() < 1e-9);

  SECTION("two sources with the same ambient vector and different lengths: parallel, lengths in their range") {
    const fem::Complex there = 3.0 * fem::ambient_to_tangent(fine, frames, disk.V, other, expected);
    Eigen::VectorXd nearest = distance;
    for (Eigen::Index i = 0; i < nearest.size(); ++i) nearest(i) = std::min(nearest(i), (disk.V.row(i) - disk.V.row(other)).norm());
    const Eigen::VectorXcd two = fem::vector_field_from_distance(operators, nearest, {source, other}, {start, there});
    const Eigen::MatrixXd drawn = fem::tangent_to_ambient(fine, frames, disk.V, two);
    for (Eigen::Index i = 0; i < drawn.rows(); ++i) {
      CHECK((drawn.row(i).transpose().normalized() - expected).norm() < 1e-9);
      CHECK(drawn.row(i).norm() >= 1 - 1e-9);
      CHECK(drawn.row(i).norm() <= 3 + 1e-9);
    }
    CHECK(std::abs(two(source)) < std::abs(two(other)));  // each source's own length dominates there
  }
  SECTION("unreached vertices get no vector; bad arguments are refused") {
    Eigen::VectorXd part = distance;
    part(other) = std::numeric_limits<double>::infinity();
    const Eigen::VectorXcd cut = fem::vector_field_from_distance(operators, part, {source}, {start});
    CHECK(cut(other) == fem::Complex(0));
    CHECK(std::abs(cut(1)) == Approx(1));
    CHECK_THROWS_AS(fem::vector_field_from_distance(operators, distance.head(3), {source}, {start}), std::invalid_argument);
    CHECK_THROWS_AS(fem::vector_field_from_distance(operators, distance, {source, other}, {start}), std::invalid_argument);
    CHECK_THROWS_AS(fem::vector_field_from_distance(operators, distance, {static_cast<Index>(disk.V.rows())}, {start}),
                    std::invalid_argument);
    CHECK_THROWS_AS(fem::vector_field_from_distance(operators, part, {other}, {start}), std::invalid_argument);  // unreached source
    fem::DistanceSweepOptions bad;
    bad.max_passes = -1;
    CHECK_THROWS_AS(fem::vector_field_from_distance(operators, distance, {source}, {start}, bad), std::invalid_argument);
    fem::DistanceSweepOptions negative_size;
    negative_size.supernodal_from = -1;
    CHECK_THROWS_AS(fem::vector_field_from_distance(operators, distance, {source}, {start}, negative_size), std::invalid_argument);
  }
}

TEST_CASE("vector field from a distance: the passes converge to the fine method's field, whatever the distance", "[fem][vectors]") {
  // A curved surface, two sources of different lengths (so the scalar diffusions are swept too), and
  // a distance that is only roughly the geodesic one (straight-line, through the torus's hole, with
  // dips): the passes are Gauss–Seidel on the fine method's own systems, so they converge to its
  // field; the distance only orders and scales them.
  const ice::TriangleMesh torus = ice::make_torus(48, 16, 1.0, 0.35);
  const ice::IntrinsicMesh fine = glued(torus);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const fem::VectorHeatOperators operators = fem::vector_heat_operators(fine, frames);
  const std::vector<Index> sources = {0, static_cast<Index>(torus.V.rows() / 2 + 5)};
  const std::vector<fem::Complex> vectors = {std::polar(1.0, 0.3), std::polar(2.0, -1.1)};
  Eigen::VectorXd distance(torus.V.rows());
  for (Eigen::Index i = 0; i < distance.size(); ++i)
    distance(i) = std::min((torus.V.row(i) - torus.V.row(sources[0])).norm(), (torus.V.row(i) - torus.V.row(sources[1])).norm());
  // And local minima, as a distance prolonged from a coarse mesh has on noisy scans: vertices with
  // no nearer neighbour, which the first pass cannot scale.
  for (const Eigen::Index dip : {101, 333, 517}) distance(dip) *= 0.5;
  const Eigen::VectorXcd reference = fem::VectorHeatSolver(operators).interpolate(sources, vectors);
  std::vector<double> medians;
  for (const int passes : {0, 5, 40}) {
    fem::DistanceSweepOptions options;
    options.max_passes = passes;
    options.tolerance = 0;
    medians.push_back(median(angle_errors(fem::vector_field_from_distance(operators, distance, sources, vectors, options), reference)));
  }
  INFO("median angle error after 0 / 5 / 40 passes: " << medians[0] << " / " << medians[1] << " / " << medians[2] << " deg");
  CHECK(medians[1] < 0.5 * medians[0]);
  CHECK(medians[2] < 0.5 * medians[1]);
  fem::DistanceSweepOptions converged;
  converged.tolerance = 1e-12;
  converged.max_passes = 5000;
  fem::DistanceSweepStats stats;
  const Eigen::VectorXcd field = fem::vector_field_from_distance(operators, distance, sources, vectors, converged, &stats);
  INFO(stats.passes << " passes, last change " << stats.last_change);
  CHECK(stats.last_change <= 1e-12);
  CHECK(stats.settled);
  CHECK((field - reference).cwiseAbs().maxCoeff() < 1e-8 * reference.cwiseAbs().maxCoeff());
  for (Eigen::Index i = 0; i < field.size(); ++i) CHECK(std::abs(std::abs(field(i)) - std::abs(reference(i))) < 1e-8);
}

TEST_CASE("vector field from a distance: a coarse-grid correction converges where the passes stall", "[fem][vectors]") {
  // A long time step against the edges (t = (4h)²): the rows are dominated by their neighbours, and a
  // relative error spread over a region leaves them satisfied but for its rim, so the passes carry
  // it out a vertex at a time. The Galerkin correction on a coarse space's relative errors removes
  // it. Two sources of different lengths, so that the scalar systems are corrected too.
  const ice::TriangleMesh torus = ice::make_torus(64, 24, 1.0, 0.35);
  const ice::IntrinsicMesh fine = glued(torus);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const fem::VectorHeatOperators operators = fem::vector_heat_operators(fine, frames, 4.0);
  const std::vector<Index> sources = {0, static_cast<Index>(torus.V.rows() / 2 + 7)};
  const std::vector<fem::Complex> vectors = {std::polar(1.0, 0.3), std::polar(2.0, -1.1)};
  Eigen::VectorXd distance(torus.V.rows());
  for (Eigen::Index i = 0; i < distance.size(); ++i)
    distance(i) = std::min((torus.V.row(i) - torus.V.row(sources[0])).norm(), (torus.V.row(i) - torus.V.row(sources[1])).norm());
  const Eigen::VectorXcd reference = fem::VectorHeatSolver(operators).interpolate(sources, vectors);
  ice::CoarseSpaceOptions coarse_options;
  coarse_options.coarsen.target_ratio = 0.05;
  const fem::SweepCoarseSpace coarse_space(ice::build_coarse_space(torus, coarse_options).P);
  const auto sweep = [&](int passes, int interval, const fem::SweepCoarseSpace* space, fem::DistanceSweepStats* stats = nullptr) {
    fem::DistanceSweepOptions options;
    options.max_passes = passes;
    options.tolerance = 0;
    options.coarse_correction_interval = interval;
    return fem::vector_field_from_distance(operators, distance, sources, vectors, options, stats, space);
  };
  const auto magnitude_error = [&](const Eigen::VectorXcd& field) {
    return (field.cwiseAbs() - reference.cwiseAbs()).cwiseAbs().maxCoeff();
  };
  const Eigen::VectorXcd plain = sweep(20, 0, nullptr);
  fem::DistanceSweepStats stats;
  const Eigen::VectorXcd corrected = sweep(20, 1, &coarse_space, &stats);
  CHECK(stats.coarse_corrections == 20);
  CHECK_FALSE(stats.coarse_supernodal);  // far below the default supernodal size
  const double plain_error = median(angle_errors(plain, reference)), corrected_error = median(angle_errors(corrected, reference));
  INFO("median angle error after 20 passes: " << plain_error << " deg plain, " << corrected_error << " deg with corrections");
  INFO("largest magnitude error: " << magnitude_error(plain) << " plain, " << magnitude_error(corrected) << " with corrections");
  CHECK(corrected_error < 0.1 * plain_error);
  CHECK(magnitude_error(corrected) < 0.1 * magnitude_error(plain));
  // Without a coarse space, or with the interval 0, the passes are as before.
  CHECK(sweep(20, 0, &coarse_space) == plain);
  CHECK(sweep(20, 1, nullptr) == plain);
  // With every vertex its own coarse vertex the basis spans everything: a correction is the direct
  // solve up to the 1e-8 its diagonal is lifted by (and rows the first pass left zero), and a second
  // one, iterative refinement, reaches round-off.
  fem::SweepCoarseSpace identity(torus.V.rows(), torus.V.rows());
  identity.setIdentity();
  const Eigen::VectorXcd once = sweep(1, 1, &identity), twice = sweep(2, 1, &identity);
  CHECK((once - reference).cwiseAbs().maxCoeff() < 1e-3 * reference.cwiseAbs().maxCoeff());
  CHECK((twice - reference).cwiseAbs().maxCoeff() < 1e-9 * reference.cwiseAbs().maxCoeff());
  CHECK(magnitude_error(twice) < 1e-9);
  fem::DistanceSweepOptions negative;
  negative.coarse_correction_interval = -1;
  CHECK_THROWS_AS(fem::vector_field_from_distance(operators, distance, sources, vectors, negative, nullptr, &coarse_space),
                  std::invalid_argument);
  const fem::SweepCoarseSpace wrong(torus.V.rows() - 1, 4);
  CHECK_THROWS_AS(fem::vector_field_from_distance(operators, distance, sources, vectors, {}, nullptr, &wrong), std::invalid_argument);
}

TEST_CASE("vector field from a distance: a large coarse system goes to the supernodal factorisation", "[fem][vectors]") {
  // 3,200 vertices, each its own coarse vertex, with the supernodal size lowered below it: CHOLMOD
  // factorises the coarse system instead of Eigen's simplicial LDLᵀ; two corrections are the direct
  // solve again.
  const ice::TriangleMesh torus = ice::make_torus(80, 40, 1.0, 0.35);
  const ice::IntrinsicMesh fine = glued(torus);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const fem::VectorHeatOperators operators = fem::vector_heat_operators(fine, frames);
  Eigen::VectorXd distance(torus.V.rows());
  for (Eigen::Index i = 0; i < distance.size(); ++i) distance(i) = (torus.V.row(i) - torus.V.row(0)).norm();
  const Eigen::VectorXcd reference = fem::VectorHeatSolver(operators).interpolate({0}, {fem::Complex(0, 1)});
  fem::SweepCoarseSpace identity(torus.V.rows(), torus.V.rows());
  identity.setIdentity();
  fem::DistanceSweepOptions options;
  options.max_passes = 2;
  options.tolerance = 0;
  options.coarse_correction_interval = 1;
  options.supernodal_from = torus.V.rows() / 2;
  fem::DistanceSweepStats stats;
  const Eigen::VectorXcd field =
      fem::vector_field_from_distance(operators, distance, {0}, {fem::Complex(0, 1)}, options, &stats, &identity);
  CHECK(stats.coarse_corrections == 2);
  CHECK(stats.coarse_supernodal);
  const std::vector<double> errors = angle_errors(field, reference);
  INFO("largest angle error " << *std::max_element(errors.begin(), errors.end()) << " deg");
  CHECK(*std::max_element(errors.begin(), errors.end()) < 1e-6);
}

TEST_CASE("vector field from a distance: a field where the fine solve's kernel underflows", "[fem][vectors]") {
  // A flat strip 1,500 unit squares long: the kernel of M + tL (t = h²) falls by ~e per edge, below
  // the smallest double long before the far end, where the fine method's field is then zero. Scaled
  // by the distance's decay, the sweep's values stay of order one along the whole strip.
  const int cells = 1500;
  ice::TriangleMesh strip;
  strip.V.resize(2 * (cells + 1), 3);
  strip.F.resize(2 * cells, 3);
  for (int i = 0; i <= cells; ++i) {
    strip.V.row(2 * i) = Eigen::RowVector3d(i, 0, 0);
    strip.V.row(2 * i + 1) = Eigen::RowVector3d(i, 1, 0);
  }
  for (int i = 0; i < cells; ++i) {
    strip.F.row(2 * i) = Eigen::RowVector3i(2 * i, 2 * i + 2, 2 * i + 3);
    strip.F.row(2 * i + 1) = Eigen::RowVector3i(2 * i, 2 * i + 3, 2 * i + 1);
  }
  const ice::IntrinsicMesh fine = glued(strip);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  const fem::VectorHeatOperators operators = fem::vector_heat_operators(fine, frames);
  Eigen::VectorXd distance(strip.V.rows());
  for (Eigen::Index i = 0; i < distance.size(); ++i) distance(i) = strip.V.row(i).norm();
  const fem::Complex start = std::polar(1.0, 0.4);
  const Eigen::VectorXcd field = fem::vector_field_from_distance(operators, distance, {0}, {start});
  const Eigen::MatrixXd ambient = fem::tangent_to_ambient(fine, frames, strip.V, field);
  for (Eigen::Index i = 0; i < ambient.rows(); ++i) CHECK((ambient.row(i) - ambient.row(0)).norm() < 1e-9);
  // The first pass alone reaches the far end too (its scale e passes 709 there, where exp(e)
  // overflows: it must never be formed).
  fem::DistanceSweepOptions first_only;
  first_only.max_passes = 0;
  const Eigen::MatrixXd first = fem::tangent_to_ambient(fine, frames, strip.V,
                                                        fem::vector_field_from_distance(operators, distance, {0}, {start}, first_only));
  for (Eigen::Index i = 0; i < first.rows(); ++i) CHECK((first.row(i) - ambient.row(0)).norm() < 1e-9);
  // A coarse correction (every vertex its own coarse vertex) leaves the rows beyond exp(−600) of the
  // source's scale to the passes instead of forming their underflowing residuals.
  fem::SweepCoarseSpace identity(strip.V.rows(), strip.V.rows());
  identity.setIdentity();
  const Eigen::MatrixXd corrected = fem::tangent_to_ambient(
      fine, frames, strip.V, fem::vector_field_from_distance(operators, distance, {0}, {start}, {}, nullptr, &identity));
  for (Eigen::Index i = 0; i < corrected.rows(); ++i) CHECK((corrected.row(i) - ambient.row(0)).norm() < 1e-9);
  const Eigen::VectorXcd direct = fem::VectorHeatSolver(operators).interpolate({0}, {start});
  Index lost = 0;
  for (Eigen::Index i = 0; i < direct.size(); ++i) lost += direct(i) == fem::Complex(0);
  INFO(lost << " of " << direct.size() << " vertices without a field from the fine solve");
  CHECK(lost > 0);  // the regime is real: the far end underflows there
  for (Eigen::Index i = 0; i < direct.size(); ++i) CHECK(std::isfinite(std::abs(direct(i))));
}

TEST_CASE("vector heat field: a subnormal direction keeps its angle, a vanished one gives zero", "[fem][vectors]") {
  fem::VectorHeatParts parts{Eigen::VectorXcd(3), Eigen::VectorXd::Constant(3, 2.0), Eigen::VectorXd::Constant(3, 1.0)};
  parts.directions << fem::Complex(3e-320, 4e-320), fem::Complex(0.6, 0.8), fem::Complex(0);
  const Eigen::VectorXcd field = fem::vector_heat_field(parts, 2.0, 2.0);
  CHECK(std::abs(field(0) - fem::Complex(1.2, 1.6)) < 1e-3);  // 3:4 survives in subnormals to ~1e-4
  CHECK(std::abs(field(1) - fem::Complex(1.2, 1.6)) < 1e-15);
  CHECK(field(2) == fem::Complex(0));
}

TEST_CASE("vector sweep through the coarse proxy approaches the fine field", "[fem][vectors]") {
  const ice::TriangleMesh mesh = ice::make_icosphere(5);
  const ice::IntrinsicMesh fine = glued(mesh);
  const fem::TangentFrames frames = fem::tangent_frames(fine);
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const fem::VectorHeatOperators operators = fem::vector_heat_operators(fine, frames);
  const Eigen::VectorXcd reference = fem::VectorHeatSolver(operators).interpolate({17}, {fem::Complex(0, 1)});
  const fem::VectorSweepProxy sweep(operators, fem::ProxyGeodesicSolver(ice::intrinsic_mesh(space.mesh.F, space.mesh.L), space.P));
  fem::DistanceSweepStats stats;
  const Eigen::VectorXcd field = sweep.interpolate({17}, {fem::Complex(0, 1)}, &stats);
  const std::vector<double> errors = angle_errors(field, reference);
  INFO("median angle error " << median(errors) << " deg after " << stats.passes << " passes");
  CHECK(median(errors) < 0.05);  // 3e-8° after 12 passes with the coarse corrections, 0.0006° after 50 without (coarse diffusion: 0.8°)
  CHECK((field.cwiseAbs().array() - 1.0).abs().maxCoeff() < 1e-12);  // one source: its magnitude
  CHECK_THROWS_AS(fem::VectorSweepProxy(fem::vector_heat_operators(glued(ice::make_icosphere(1)), fem::tangent_frames(glued(ice::make_icosphere(1)))),
                                        fem::ProxyGeodesicSolver(ice::intrinsic_mesh(space.mesh.F, space.mesh.L), space.P)),
                  std::invalid_argument);
}
