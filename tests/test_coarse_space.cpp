// The pipeline a user comes for, as the tools run it: ice::build_coarse_space (ICE or QEM) and
// ice::fine_mesh, then the staged proxy solvers of fem/coarse_proxy.h. Checks the coarse space's
// postconditions, that it equals driving ice::coarsen / ice::qem_coarsen by hand, the solvers' Dirichlet,
// zero-mean and multi-source behaviour, and that their stages compose to the documented formulas.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "fem/coarse_proxy.h"
#include "fem/errors.h"
#include "fem/topology.h"
#include "ice/coarse_space.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/prolongation.h"
#include "ice/qem.h"
#include "locality_numbering.h"  // private to libice (the tests see libice/src)
#include "test_support.h"

namespace {

// Every row of P sums to 1, has 1..3 entries in [0, 1]; locked vertices are coarse vertices with row e_j.
void check_prolongation(const ice::CoarseSpace& space, Eigen::Index n, const std::vector<ice::Index>& locked) {
  REQUIRE(space.P.rows() == n);
  REQUIRE(space.P.cols() == static_cast<Eigen::Index>(space.mesh.to_input.size()));
  const Eigen::SparseMatrix<double, Eigen::RowMajor> rows = space.P;
  for (Eigen::Index i = 0; i < n; ++i) {
    double sum = 0;
    int entries = 0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(rows, i); it; ++it, ++entries) {
      sum += it.value();
      CHECK(it.value() >= 0);
      CHECK(it.value() <= 1 + 1e-12);
    }
    CHECK(std::abs(sum - 1) < 1e-12);
    CHECK(entries >= 1);
    CHECK(entries <= 3);
  }
  for (ice::Index v : locked) {
    const ice::Index j = space.mesh.from_input[static_cast<std::size_t>(v)];
    REQUIRE(j != ice::kInvalid);
    CHECK(rows.coeff(v, j) == 1.0);
  }
}

}  // namespace

TEST_CASE("build_coarse_space with ICE equals coarsening by hand, with a summary of what ICE did", "[coarse_space]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("lion-head.off"));
  const Eigen::Index n = mesh.V.rows();
  ice::CoarseSpaceOptions options;
  options.coarsen.target_vertices = 400;
  options.coarsen.area_weight = 0.25;
  options.coarsen.locked_vertices = {0, 17, 4000};
  options.locality_numbering = false;  // by hand in the input's numbering (see the next test)
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  check_prolongation(space, n, options.coarsen.locked_vertices);

  ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  const ice::CoarsenResult by_hand = ice::coarsen(T, options.coarsen);
  const ice::CompactMesh compact = T.compact();
  CHECK(space.mesh.F == compact.F);
  CHECK(space.mesh.L == compact.L);
  CHECK(space.mesh.twin == compact.twin);
  CHECK(space.mesh.to_input == compact.to_input);
  CHECK(fem::SparseMatrix(space.P - ice::prolongation(T, compact)).norm() == 0.0);

  const ice::CoarseSpaceSummary& s = space.summary;
  CHECK(s.method == ice::CoarseningMethod::ice);
  REQUIRE(s.ice.has_value());
  CHECK_FALSE(s.qem.has_value());
  CHECK(s.ice->removed == by_hand.removed);
  CHECK(s.removed() == by_hand.removed);
  CHECK(s.input_vertices == n);
  CHECK(s.coarse_vertices == 400);
  CHECK(s.coarse_faces == compact.F.rows());
  CHECK(s.target_reached);
  CHECK(s.seconds > 0);
  CHECK_FALSE(space.triangulation.has_value());  // only with keep_method_state

  options.keep_method_state = true;
  const ice::CoarseSpace kept = ice::build_coarse_space(mesh, options);
  REQUIRE(kept.triangulation.has_value());
  CHECK(kept.triangulation->num_vertices() == 400);
  CHECK(kept.triangulation->validate().empty());
}

// The coarse space of `mesh` must be that of `reference` with input vertex i of `reference` renamed
// order[i]: the same faces (in the same order, corners through the renaming), lengths, gluing and
// P entries, coarse vertices listed by increasing input vertex.
void check_same_space_renamed(const ice::CoarseSpace& space, const ice::CoarseSpace& reference,
                              const std::vector<ice::Index>& order) {
  const ice::CompactMesh &C = space.mesh, &R = reference.mesh;
  REQUIRE(C.F.rows() == R.F.rows());
  REQUIRE(C.num_vertices() == R.num_vertices());
  CHECK(std::is_sorted(C.to_input.begin(), C.to_input.end()));
  for (Eigen::Index f = 0; f < C.F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      CHECK(C.to_input[static_cast<std::size_t>(C.F(f, k))] == order[static_cast<std::size_t>(R.to_input[static_cast<std::size_t>(R.F(f, k))])]);
  CHECK(C.L == R.L);
  CHECK(C.twin == R.twin);
  for (std::size_t i = 0; i < order.size(); ++i) {
    const ice::Index r = R.from_input[i], c = C.from_input[static_cast<std::size_t>(order[i])];
    CHECK((r == ice::kInvalid) == (c == ice::kInvalid));
    if (r != ice::kInvalid) CHECK(C.to_input[static_cast<std::size_t>(c)] == order[i]);
  }
  // P: entry (i, j) of the reference is entry (order[i], the coarse vertex of j's input vertex renamed).
  Eigen::SparseMatrix<double, Eigen::RowMajor> P = space.P, Q = reference.P;
  REQUIRE(P.nonZeros() == Q.nonZeros());
  for (Eigen::Index i = 0; i < Q.rows(); ++i)
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(Q, i); it; ++it) {
      const ice::Index input = order[static_cast<std::size_t>(R.to_input[static_cast<std::size_t>(it.col())])];
      CHECK(P.coeff(order[static_cast<std::size_t>(i)], C.from_input[static_cast<std::size_t>(input)]) == it.value());
    }
}

TEST_CASE("build_coarse_space coarsens in a locality numbering and answers in the input's", "[coarse_space]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("lion-head.off"));
  const Eigen::Index n = mesh.V.rows();
  ice::CoarseSpaceOptions options;
  options.coarsen.target_vertices = 400;
  options.coarsen.locked_vertices = {0, 17, 4000};
  REQUIRE(options.locality_numbering);  // the default
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  check_prolongation(space, n, options.coarsen.locked_vertices);

  // By hand: the renumbered mesh coarsened with the locked vertices renamed, then renamed back.
  const ice::detail::LocalityNumbering local = ice::detail::locality_numbering(mesh);
  REQUIRE(local.order.size() == static_cast<std::size_t>(n));
  std::vector<ice::Index> new_index(local.order.size());
  for (std::size_t i = 0; i < local.order.size(); ++i) new_index[static_cast<std::size_t>(local.order[i])] = static_cast<ice::Index>(i);
  ice::CoarseSpaceOptions by_hand = options;
  by_hand.locality_numbering = false;
  for (ice::Index& v : by_hand.coarsen.locked_vertices) v = new_index[static_cast<std::size_t>(v)];
  ice::TriangleMesh renumbered;
  renumbered.F = local.F;
  renumbered.V.resize(n, 3);
  for (ice::Index i = 0; i < n; ++i) renumbered.V.row(i) = mesh.V.row(local.order[static_cast<std::size_t>(i)]);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)  // each new face is an input face, renamed
    for (int k = 0; k < 3; ++k)
      CHECK(local.order[static_cast<std::size_t>(local.F(f, k))] == mesh.F(local.face_order[static_cast<std::size_t>(f)], k));
  CHECK(local.face_lengths(mesh.V) == ice::face_lengths_from_positions(renumbered.V, renumbered.F));
  check_same_space_renamed(space, ice::build_coarse_space(renumbered, by_hand), local.order);

  // Users' vertex numbering no longer matters: shuffled input vertices give the same coarse space,
  // renamed (the Z-order depends on the positions only; the faces keep their order).
  std::vector<ice::Index> shuffle(static_cast<std::size_t>(n));
  for (ice::Index i = 0; i < n; ++i) shuffle[static_cast<std::size_t>(i)] = static_cast<ice::Index>((7919LL * i + 13) % n);
  REQUIRE(std::is_permutation(shuffle.begin(), shuffle.end(), new_index.begin()));  // a permutation of 0..n-1
  ice::TriangleMesh shuffled;
  shuffled.V.resize(n, 3);
  shuffled.F = mesh.F;
  for (ice::Index i = 0; i < n; ++i) shuffled.V.row(shuffle[static_cast<std::size_t>(i)]) = mesh.V.row(i);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) shuffled.F(f, k) = shuffle[static_cast<std::size_t>(mesh.F(f, k))];
  ice::CoarseSpaceOptions shuffled_options = options;
  for (ice::Index& v : shuffled_options.coarsen.locked_vertices) v = shuffle[static_cast<std::size_t>(v)];
  check_same_space_renamed(ice::build_coarse_space(shuffled, shuffled_options), space, shuffle);

  // Meshes the triangulation refuses keep their error (here an unused last vertex).
  ice::TriangleMesh unused = mesh;
  unused.V.conservativeResize(n + 1, 3);
  unused.V.row(n) = mesh.V.row(0);
  CHECK(ice::detail::locality_numbering(unused).order.empty());
  CHECK_THROWS_WITH(ice::build_coarse_space(unused, options), Catch::Contains("unreferenced vertices"));
}

TEST_CASE("build_coarse_space with QEM: both coarse geometries share the vertices and P", "[coarse_space][qem]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("spot.obj"));
  const Eigen::Index n = mesh.V.rows();
  ice::CoarseSpaceOptions options;
  options.method = ice::CoarseningMethod::qem;
  options.coarsen.target_ratio = 0.05;
  options.coarsen.locked_vertices = {3, 1500};
  const ice::CoarseSpace extrinsic = ice::build_coarse_space(mesh, options);
  options.qem_geometry = ice::QemGeometry::intrinsic_delaunay;
  options.keep_method_state = true;
  const ice::CoarseSpace idt = ice::build_coarse_space(mesh, options);
  check_prolongation(extrinsic, n, options.coarsen.locked_vertices);
  check_prolongation(idt, n, options.coarsen.locked_vertices);
  CHECK(extrinsic.summary.coarse_vertices == static_cast<ice::Index>(std::ceil(0.05 * static_cast<double>(n))));
  CHECK(extrinsic.mesh.to_input == idt.mesh.to_input);
  CHECK(fem::SparseMatrix(extrinsic.P - idt.P).norm() == 0.0);
  REQUIRE(idt.summary.qem.has_value());
  CHECK_FALSE(idt.summary.ice.has_value());
  CHECK(idt.summary.qem->geometry == ice::QemGeometry::intrinsic_delaunay);
  CHECK(idt.summary.qem->intrinsic_delaunay_flips > 0);
  CHECK(extrinsic.summary.qem->intrinsic_delaunay_flips == 0);
  CHECK(idt.summary.removed() == n - idt.summary.coarse_vertices);
  // The extrinsic geometry is the QEM mesh's own edge lengths.
  REQUIRE(idt.qem_result.has_value());
  const ice::CompactMesh own = ice::qem_extrinsic_mesh(*idt.qem_result);
  CHECK(extrinsic.mesh.F == own.F);
  CHECK(extrinsic.mesh.L == own.L);
  // An error bound belongs to ICE's metric.
  options.coarsen.max_error = 1e-3;
  CHECK_THROWS_AS(ice::build_coarse_space(mesh, options), std::invalid_argument);
}

TEST_CASE("fine_to_coarse_map: every input vertex in a coarse face, agreeing with P", "[coarse_space][map]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("elephant-with-holes.off"));  // with boundaries
  for (const ice::CoarseningMethod method : {ice::CoarseningMethod::ice, ice::CoarseningMethod::qem}) {
    INFO(ice::to_string(method));
    ice::CoarseSpaceOptions options;
    options.method = method;
    options.coarsen.target_ratio = 0.05;
    options.keep_method_state = true;
    const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
    const std::vector<ice::CoarsePoint> map = ice::fine_to_coarse_map(space);
    REQUIRE(map.size() == static_cast<std::size_t>(mesh.V.rows()));
    const Eigen::SparseMatrix<double, Eigen::RowMajor> rows = space.P;
    int survivors = 0;
    for (std::size_t i = 0; i < map.size(); ++i) {
      const ice::CoarsePoint& point = map[i];
      REQUIRE(point.face >= 0);
      REQUIRE(point.face < space.mesh.F.rows());
      CHECK(point.coarse_vertex == space.mesh.from_input[i]);
      CHECK(std::abs(point.bary[0] + point.bary[1] + point.bary[2] - 1) < 1e-12);
      // P's row i is the point's barycentric coordinates on its face's corners (summed over repeats).
      Eigen::SparseVector<double> expected(space.P.cols());
      for (int k = 0; k < 3; ++k) expected.coeffRef(space.mesh.F(point.face, k)) += point.bary[k];
      Eigen::VectorXd difference = Eigen::VectorXd(expected) - Eigen::VectorXd(rows.row(static_cast<Eigen::Index>(i)).transpose());
      CHECK(difference.cwiseAbs().maxCoeff() < 1e-9);
      if (point.coarse_vertex != ice::kInvalid) {
        ++survivors;
        int corner = -1;
        for (int k = 0; k < 3; ++k)
          if (space.mesh.F(point.face, k) == point.coarse_vertex) corner = k;
        REQUIRE(corner >= 0);
        CHECK(point.bary[corner] == 1.0);
      }
    }
    CHECK(survivors == static_cast<int>(space.mesh.to_input.size()));
  }
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.1;
  CHECK_THROWS_AS(ice::fine_to_coarse_map(ice::build_coarse_space(mesh, options)), std::invalid_argument);
  options.method = ice::CoarseningMethod::qem;
  options.qem_geometry = ice::QemGeometry::intrinsic_delaunay;
  options.keep_method_state = true;
  CHECK_THROWS_AS(ice::fine_to_coarse_map(ice::build_coarse_space(mesh, options)), std::invalid_argument);
}

TEST_CASE("fine_mesh: the input triangles or their intrinsic Delaunay triangulation", "[coarse_space]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("lion-head.off"));
  const ice::FineMesh input = ice::fine_mesh(mesh, ice::FineGeometry::input);
  CHECK(input.F == mesh.F);
  CHECK(input.L == ice::face_lengths_from_positions(mesh.V, mesh.F));
  CHECK(input.flips == 0);
  const ice::FineMesh idt = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  CHECK(idt.flips > 0);  // lion-head has needle triangles
  CHECK(idt.F.rows() == mesh.F.rows());
  // Intrinsic Delaunay: every interior edge's cotan weight is ≥ 0, i.e. the Laplacian's off-diagonal
  // entries are ≤ 0 away from the boundary (a boundary edge has one angle, which may be obtuse).
  std::vector<char> on_boundary(static_cast<std::size_t>(mesh.V.rows()), 0);
  for (int v : fem::boundary_vertices(mesh.F)) on_boundary[static_cast<std::size_t>(v)] = 1;
  auto most_positive_interior_weight = [&](const ice::FineMesh& m) {
    const fem::SparseMatrix L = fem::cotan_laplacian(m);
    double most = -1;
    for (Eigen::Index j = 0; j < L.outerSize(); ++j)
      for (fem::SparseMatrix::InnerIterator it(L, j); it; ++it)
        if (it.row() != it.col() && !(on_boundary[static_cast<std::size_t>(it.row())] && on_boundary[static_cast<std::size_t>(j)]))
          most = std::max(most, it.value());
    return most;
  };
  CHECK(most_positive_interior_weight(idt) <= 1e-12);
  CHECK(most_positive_interior_weight(input) > 0);  // the input itself is not Delaunay

  // fine_mesh flips in the locality numbering; flipped in the input's numbering by hand, the
  // triangulation may differ where four vertices are cocircular, but its Laplacian may not (the
  // intrinsic Delaunay Laplacian is unique: Bobenko & Springborn 2007).
  ice::IntrinsicTriangulation T = ice::IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  T.flip_to_delaunay();
  const ice::CompactMesh by_hand = T.compact();
  const fem::SparseMatrix L_fine = fem::cotan_laplacian(idt);
  const fem::SparseMatrix L_by_hand = fem::cotan_laplacian(by_hand);
  CHECK(fem::SparseMatrix(L_fine - L_by_hand).norm() <= 1e-9 * L_by_hand.norm());
  const fem::SparseMatrix M_fine = fem::mass_matrix(idt), M_by_hand = fem::mass_matrix(by_hand);
  CHECK(M_fine.sum() == Approx(M_by_hand.sum()).epsilon(1e-12));  // the same surface area
}

TEST_CASE("build_coarse_space hands out the fine intrinsic Delaunay mesh it starts from", "[coarse_space]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("elephant-with-holes.off"));
  const ice::FineMesh expected = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  REQUIRE(expected.flips > 0);  // a mesh the flips change
  const auto same_fine = [&](const ice::FineMesh& fine) {
    CHECK(fine.geometry == ice::FineGeometry::intrinsic_delaunay);
    CHECK(fine.flips == expected.flips);
    CHECK(fine.F == expected.F);
    CHECK(fine.L == expected.L);  // bit for bit
    CHECK(fine.twin == expected.twin);
  };
  // QEM's fine mesh is fine_mesh() itself: once, in the default numbering.
  for (const auto& [locality, method] : {std::pair{true, ice::CoarseningMethod::ice}, std::pair{false, ice::CoarseningMethod::ice},
                                         std::pair{true, ice::CoarseningMethod::qem}}) {
      INFO("locality numbering " << locality << ", method " << (method == ice::CoarseningMethod::ice ? "ice" : "qem"));
      ice::CoarseSpaceOptions options;
      options.method = method;
      options.locality_numbering = locality;
      options.coarsen.target_ratio = 0.05;
      ice::FineMesh fine;
      fine.flips = -1;
      const ice::CoarseSpace with = ice::build_coarse_space(mesh, options, &fine);
      same_fine(fine);
      CHECK(with.summary.fine_mesh_seconds > 0);
      const ice::CoarseSpace without = ice::build_coarse_space(mesh, options);
      CHECK(without.summary.fine_mesh_seconds == 0);
      CHECK(with.mesh.F == without.mesh.F);  // the coarsening itself is untouched
      CHECK(with.mesh.L == without.mesh.L);
      CHECK(fem::SparseMatrix(with.P - without.P).norm() == 0);
    }
  // With the method's state kept and its history recorded (the copy is taken before recording starts).
  ice::CoarseSpaceOptions options;
  options.coarsen.target_ratio = 0.05;
  options.keep_method_state = true;
  options.record_history = true;
  ice::FineMesh fine;
  const ice::CoarseSpace with = ice::build_coarse_space(mesh, options, &fine);
  same_fine(fine);
  const ice::CoarseSpace without = ice::build_coarse_space(mesh, options);
  CHECK(with.mesh.F == without.mesh.F);
  CHECK(fem::SparseMatrix(with.P - without.P).norm() == 0);
  REQUIRE(with.triangulation.has_value());
  CHECK(with.triangulation->history().num_records() > 0);  // the fine mesh's flips are not in it
  CHECK(with.triangulation->history().num_records() == without.triangulation->history().num_records());
}

TEST_CASE("staged proxy solvers: Dirichlet values, zero mean, several sources, phase times", "[coarse_space][fem]") {
  const ice::TriangleMesh mesh = ice::load_mesh(ice_test::project_mesh("lion-head.off"));
  const Eigen::Index n = mesh.V.rows();
  // Dirichlet on the whole boundary (one loop of 36 vertices), values from the height.
  const std::vector<int> fixed = fem::boundary_vertices(mesh.F);
  REQUIRE(fixed.size() > 30);
  Eigen::VectorXd values(static_cast<Eigen::Index>(fixed.size()));
  for (std::size_t i = 0; i < fixed.size(); ++i) values(static_cast<Eigen::Index>(i)) = mesh.V(fixed[i], 2);
  ice::CoarseSpaceOptions options;
  options.coarsen.target_vertices = 800;
  options.coarsen.locked_vertices.assign(fixed.begin(), fixed.end());
  const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
  const ice::FineMesh fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
  Eigen::VectorXd f(n);
  for (Eigen::Index i = 0; i < n; ++i) f(i) = std::sin(0.05 * mesh.V(i, 0)) + 0.5;  // not zero-mean

  for (fem::CoarseOperatorKind kind : {fem::CoarseOperatorKind::intrinsic, fem::CoarseOperatorKind::galerkin}) {
    INFO((kind == fem::CoarseOperatorKind::intrinsic ? "intrinsic" : "galerkin"));
    const fem::CoarseProxy proxy(ice::intrinsic_mesh(fine.F, fine.L), ice::intrinsic_mesh(space.mesh.F, space.mesh.L), space.P, {kind});
    const fem::SparseMatrix& M = proxy.fine_mass();
    const Eigen::VectorXd m1 = M * Eigen::VectorXd::Ones(n);
    const fem::SparseMatrix L = fem::cotan_laplacian(fine);

    // Dirichlet: the prolonged solution takes the prescribed values exactly and is close to the fine one.
    const fem::ProxyPoissonSolver dirichlet(proxy, fixed);
    CHECK_FALSE(dirichlet.is_zero_mean());
    fem::ProxyPhaseTimes times;
    const Eigen::VectorXd u = dirichlet.solve(f, values, &times);
    for (std::size_t i = 0; i < fixed.size(); ++i) CHECK(u(fixed[i]) == values(static_cast<Eigen::Index>(i)));
    CHECK(times.restriction >= 0);
    CHECK(times.coarse_solve > 0);
    CHECK(times.prolongation >= 0);
    const Eigen::VectorXd reference = fem::PoissonSolver::dirichlet(L, M, fixed).solve(f, values);
    CHECK(fem::relative_l2_error(u, reference, M) < 0.05);  // measured 0.79 % (intrinsic), 0.55 % (Galerkin)
    // The stages compose to P · (coarse Dirichlet solve of Pᵀ M f).
    std::vector<int> coarse_fixed;
    for (int v : fixed) coarse_fixed.push_back(proxy.coarse_vertex_of(v));
    const Eigen::VectorXd by_hand =
        proxy.prolong(fem::PoissonSolver::dirichlet(proxy.coarse_laplacian(), proxy.coarse_mass(), coarse_fixed)
                          .solve_weighted(proxy.restrict_weighted(M * f), values));
    CHECK((u - by_hand).cwiseAbs().maxCoeff() <= 1e-12 * by_hand.cwiseAbs().maxCoeff());

    // Zero mean: f is made compatible on the fine mesh first, so a constant gives 0 (up to round-off) …
    const fem::ProxyPoissonSolver zero_mean(proxy);
    CHECK(zero_mean.is_zero_mean());
    CHECK(zero_mean.solve(Eigen::VectorXd::Constant(n, 3.25)).cwiseAbs().maxCoeff() < 1e-12);
    // … and the answer has zero fine-mass mean and approximates the fine solution of f − mean(f).
    const Eigen::VectorXd w = zero_mean.solve(f);
    CHECK(std::abs(m1.dot(w)) <= 1e-12 * m1.sum() * w.cwiseAbs().maxCoeff());
    const Eigen::VectorXd fine_w = fem::PoissonSolver::zero_mean(L, M).solve(f);
    CHECK(fem::relative_l2_error(w, fine_w, M) < 0.05);  // measured 1.6 %, 1.2 %
    // A Dirichlet vertex that is no coarse vertex is refused, naming it.
    int removed = 0;
    while (space.mesh.from_input[static_cast<std::size_t>(removed)] != ice::kInvalid) ++removed;
    CHECK_THROWS_WITH(fem::ProxyPoissonSolver(proxy, {removed}), Catch::Contains(std::to_string(removed)));
    CHECK_THROWS_AS(dirichlet.solve(f, Eigen::VectorXd::Ones(3)), std::invalid_argument);

    // Heat: the L2-projection step solves (Mc + τLc) u1 = Pᵀ M u0, the projection's own equation.
    const double tau = 0.01 * M.sum();
    const fem::ProxyHeatSolver heat(proxy, tau, fem::RestrictionKind::l2_projection);
    const fem::HeatSolver coarse_heat(proxy.coarse_laplacian(), proxy.coarse_mass(), tau);
    const Eigen::VectorXd projected = proxy.restrict_values(f, fem::RestrictionKind::l2_projection);
    const Eigen::VectorXd two_steps = proxy.prolong(coarse_heat.integrate(projected, 2));
    CHECK((heat.integrate(f, 2) - two_steps).cwiseAbs().maxCoeff() <= 1e-10 * two_steps.cwiseAbs().maxCoeff());
    CHECK_THROWS_AS(heat.integrate(f, 0), std::invalid_argument);

    // Geodesics, by both coarse solvers: several sources give the distance to the nearest (about
    // the minimum of the single-source distances); the heat method with operators assembled by the
    // caller gives the same answer as with its options. Marching is 0 at every source, the heat
    // method 0 on average over them.
    fem::ProxyGeodesicOptions heat_options;
    heat_options.method = fem::CoarseDistanceMethod::heat_method;
    const fem::ProxyGeodesicSolver from_operators(proxy, proxy.coarse_heat_method_operators());
    const int a = fixed.front(), b = 4000;
    for (const fem::ProxyGeodesicOptions& options : {fem::ProxyGeodesicOptions{}, heat_options}) {
      const fem::ProxyGeodesicSolver geodesic(proxy, options);
      const bool heat = geodesic.method() == fem::CoarseDistanceMethod::heat_method;
      INFO((heat ? "heat method" : "marching"));
      const Eigen::VectorXd d01 = geodesic.distance({a, b, a});
      if (heat) {
        CHECK((d01 - from_operators.distance({b, a})).cwiseAbs().maxCoeff() == 0.0);
        CHECK(std::abs(d01(a) + d01(b)) <= 1e-12 * d01.maxCoeff());
      } else {
        CHECK(d01(a) == 0.0);
        CHECK(d01(b) == 0.0);
        CHECK(d01.minCoeff() >= 0.0);
      }
      const Eigen::VectorXd d0 = geodesic.distance({a}), d1 = geodesic.distance({b});
      CHECK(d0(a) == 0.0);
      const double scale = d0.maxCoeff();
      Eigen::Index worse = 0;  // not exactly a minimum of the two: a few % of the diameter
      for (Eigen::Index i = 0; i < n; ++i) worse += std::abs(d01(i) - std::min(d0(i), d1(i))) > 0.05 * scale;
      CHECK(worse <= n / 1000);
    }
  }
}
