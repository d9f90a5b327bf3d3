// Tests of ICE coarsening, the fine-to-coarse map and the prolongation matrix.
#include <catch2/catch.hpp>

#include <cmath>

#include "ice/triangle_geometry.h"
#include "ice/coarsen.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/prolongation.h"
#include "test_support.h"

using namespace ice;

namespace {

using ice::kPi;

// The clean real meshes, small to large: the project set (boundaries, three components, genus 1-9, CAD
// parts, a surface with four holes), then the extended set's when present.
std::vector<std::string> clean_meshes() {
  return ice_test::mesh_sweep({"cat_head.obj", "eight.off", "boxpart.obj", "blobby_3cc.off", "couplingdown.off",
                               "elephant.off", "spot.obj", "bob_tri.obj", "mech-holes-shark.off", "fandisk.off",
                               "blub_triangulated.obj", "lion-head.off", "capsule.obj", "bs_rest.obj",
                               "spot_subdiv.obj", "armadillo.off"},
                              {"spot_offset1e6.obj", "fertility.off", "fandisk.obj", "camelhead.off", "dragon_fat.obj",
                               "face_scan.obj", "bunny_closed.off", "armadillo_43k.obj"});
}

void check_map(const IntrinsicTriangulation& T) {
  const CompactMesh coarse = T.compact();
  const Eigen::SparseMatrix<double> P = prolongation(T, coarse);
  REQUIRE(P.rows() == T.num_input_vertices());
  REQUIRE(P.cols() == T.num_vertices());
  const Eigen::VectorXd row_sums = P * Eigen::VectorXd::Ones(P.cols());
  CHECK((row_sums.array() - 1.0).abs().maxCoeff() < 1e-14);
  Eigen::SparseMatrix<double, Eigen::RowMajor> rows = P;
  int bad = 0;
  for (Eigen::Index r = 0; r < rows.rows(); ++r) {
    int nonzeros = 0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(rows, r); it; ++it) {
      ++nonzeros;
      bad += !(it.value() >= 0 && it.value() <= 1 + 1e-15);
    }
    bad += nonzeros < 1 || nonzeros > 3;
  }
  CHECK(bad == 0);
  // The same matrix as the plain definition: one entry per corner of the point's face (repeated
  // corners of a Δ-complex face summed), a vertex's own column with weight 1.
  std::vector<Eigen::Triplet<double>> entries;
  ice_test::SweepChecks points;  // one assertion for all input points
  for (Index p = 0; p < T.num_input_vertices(); ++p) {
    const SurfacePoint s = T.location(p);
    if (s.is_vertex()) {
      entries.emplace_back(p, coarse.from_input[static_cast<std::size_t>(p)], 1.0);
      continue;
    }
    const auto which = [&] { return "input vertex " + std::to_string(p) + " in face " + std::to_string(s.face); };
    ICE_SWEEP_CHECK(points, T.face_alive(s.face), which);
    if (!T.face_alive(s.face)) continue;
    ICE_SWEEP_CHECK(points, (s.bary[0] >= 0 && s.bary[1] >= 0 && s.bary[2] >= 0), which);
    Index h = T.halfedge(s.face);
    for (int k = 0; k < 3; ++k, h = T.next(h))
      if (s.bary[k] != 0) entries.emplace_back(p, coarse.from_input[static_cast<std::size_t>(T.tail(h))], s.bary[k]);
  }
  ICE_SWEEP_REPORT(points);
  Eigen::SparseMatrix<double> reference(P.rows(), P.cols());
  reference.setFromTriplets(entries.begin(), entries.end());
  CHECK(P.nonZeros() == reference.nonZeros());
  CHECK((P - reference).norm() == 0);
}

// A run with options.max_error = bound stopped there: nothing removed above it, the next above it.
void check_threshold_stop(const IntrinsicTriangulation& T, const CoarsenResult& result, double bound) {
  CHECK(result.stop_reason == StopReason::ErrorThreshold);
  CHECK(result.removed > 0);
  CHECK(result.max_cost <= bound);
  CHECK(result.next_cost > bound);
  CHECK(T.validate() == "");
}

int count_non_delaunay(const IntrinsicTriangulation& T) {
  int bad = 0;
  for (Index h = 0; h < T.num_halfedge_slots(); h += 2)
    if (T.halfedge_alive(h)) bad += !T.is_delaunay(h);
  return bad;
}

}  // namespace

TEST_CASE("coarsening every clean real mesh keeps validity, χ and Gauss-Bonnet down to the minimum", "[coarsen][meshes]") {
  std::vector<std::string> paths = clean_meshes();
  // Huge coordinates: spot translated by 1e6 in each coordinate, written and read back as OBJ.
  const ice_test::TempDir dir;
  TriangleMesh offset = load_mesh(ice_test::project_mesh("spot.obj"));
  offset.V.array() += 1e6;
  write_mesh(dir.file("spot_offset1e6.obj"), offset);
  paths.push_back(dir.file("spot_offset1e6.obj"));
  for (const std::string& path : paths) {
    INFO(path);
    const TriangleMesh mesh = load_mesh(path);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    const int chi = T.euler_characteristic();
    const Index n = T.num_vertices();
    // Validate when crossing 50 %, 10 % and 1 % of the vertices, then run to the minimum.
    std::vector<double> checkpoints = {0.5, 0.1, 0.01};
    int validated = 0;
    CoarsenOptions options;
    options.progress_interval = 1;
    options.progress = [&](const CoarsenProgress& p) {
      if (!checkpoints.empty() && p.vertices <= checkpoints.front() * n) {
        checkpoints.erase(checkpoints.begin());
        INFO("at " << p.vertices << " vertices");
        CHECK(T.validate() == "");
        CHECK(T.euler_characteristic() == chi);
        ++validated;
      }
      return true;
    };
    const CoarsenResult result = coarsen(T, options);
    INFO("stopped at " << result.output_vertices << " vertices; failures by status: "
         << result.failures_by_status[2] << " flatten, " << result.failures_by_status[3] << " face at vertex, "
         << result.failures_by_status[4] << " no flip, " << result.failures_by_status[5] << " small loop, "
         << result.failures_by_status[6] << " topology");
    CHECK(validated == 3 - static_cast<int>(checkpoints.size()));
    for (double fraction : checkpoints) CHECK(fraction * n < result.output_vertices);  // unreachable ones only
    // Either the topology's minimum was reached (a torus can keep 1 vertex) or nothing is removable.
    CHECK(result.stop_reason != StopReason::Cancelled);
    CHECK(T.validate() == "");
    CHECK(T.euler_characteristic() == chi);
    CHECK(std::abs(T.total_curvature() - 2 * kPi * chi) < 1e-8);
    CHECK(count_non_delaunay(T) == 0);
    CHECK(result.output_vertices < std::max<Index>(60, n / 100));
    check_map(T);
    ice_test::check_ilm_round_trip(T, dir.file("coarse.ilm"));  // the file says exactly this triangulation
  }
}

TEST_CASE("coarsening to a target: map, prolongation, Delaunay, determinism", "[coarsen][meshes]") {
  const TriangleMesh mesh = load_mesh(ice_test::project_mesh("lion-head.off"));
  CoarsenOptions options;
  options.target_vertices = 500;
  auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  const CoarsenResult result = coarsen(T, options);
  CHECK(result.stop_reason == StopReason::TargetReached);
  CHECK(T.num_vertices() == 500);
  CHECK(result.removed == mesh.V.rows() - 500);
  CHECK(T.validate() == "");
  CHECK(count_non_delaunay(T) == 0);
  check_map(T);

  auto again = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  coarsen(again, options);
  const CompactMesh a = T.compact(), b = again.compact();
  CHECK(a.F == b.F);
  CHECK(a.L == b.L);  // bit-identical
  CHECK(a.to_input == b.to_input);
}

TEST_CASE("the error metric conserves each channel's total mass", "[coarsen]") {
  const TriangleMesh mesh = make_torus(30, 14, 2.0, 0.8);
  auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  IntrinsicErrorMetric metric(T, 0.3);
  const auto before = metric.total_mass(T);
  CHECK(before[2] == Approx(0.3).epsilon(1e-12));
  int removed = 0;
  IntrinsicErrorMetric::RemovalPlan plan;
  for (Index v = 0; v < T.num_input_vertices() && removed < 200; v += 2) {
    if (!metric.prepare_removal(T, v, plan)) continue;
    CHECK(plan.vertex() == v);
    std::vector<Index> changed;
    const bool ok = T.remove_vertex(v, &changed) == RemovalStatus::Removed;
    T.flip_to_delaunay_around(changed);
    if (!ok) continue;
    metric.apply_removal(plan);
    CHECK(plan.vertex() == kInvalid);
    ++removed;
  }
  CHECK(removed == 200);
  const auto after = metric.total_mass(T);
  for (int c = 0; c < 3; ++c) CHECK(after[c] == Approx(before[c]).epsilon(1e-12));
}

TEST_CASE("on a flat disk the coarse mesh stays flat and the map is exact", "[coarsen]") {
  const TriangleMesh mesh = make_flat_disk(20, 1.0, 0.3, 4);
  auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  CoarsenOptions options;
  options.target_ratio = 0.1;
  options.remove_boundary = false;  // flattening a boundary vertex to π would bend the disk
  const CoarsenResult result = coarsen(T, options);
  CHECK(result.stop_reason == StopReason::TargetReached);
  CHECK(T.validate() == "");
  for (Index v = 0; v < T.num_input_vertices(); ++v)
    if (T.vertex_alive(v) && !T.is_boundary_vertex(v)) CHECK(std::abs(T.curvature(v)) < 1e-10);
  const CompactMesh coarse = T.compact();
  const Eigen::SparseMatrix<double> P = prolongation(T, coarse);
  Eigen::MatrixXd coarse_xy(coarse.to_input.size(), 2);
  for (std::size_t c = 0; c < coarse.to_input.size(); ++c) coarse_xy.row(c) = mesh.V.row(coarse.to_input[c]).head<2>();
  const Eigen::MatrixXd prolonged = P * coarse_xy;
  CHECK((prolonged - mesh.V.leftCols<2>()).cwiseAbs().maxCoeff() < 1e-9);
}

TEST_CASE("locked vertices survive and a threshold stop stops where it says", "[coarsen]") {
  const TriangleMesh mesh = make_icosphere(4);
  SECTION("locked") {
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    CoarsenOptions options;
    options.target_vertices = 50;
    for (Index v = 0; v < T.num_input_vertices(); v += 137) options.locked_vertices.push_back(v);
    coarsen(T, options);
    CHECK(T.num_vertices() == 50);
    for (Index v : options.locked_vertices) CHECK(T.vertex_alive(v));
  }
  SECTION("threshold") {
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    CoarsenOptions options;
    options.max_error = 0.05;
    check_threshold_stop(T, coarsen(T, options), 0.05);
  }
  SECTION("cancel") {
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    CoarsenOptions options;
    options.progress_interval = 100;
    options.progress = [](const CoarsenProgress& p) { return p.removed < 300; };
    const CoarsenResult result = coarsen(T, options);
    CHECK(result.stop_reason == StopReason::Cancelled);
    CHECK(result.removed == 300);
    CHECK(T.validate() == "");
  }
}

TEST_CASE("a compacted coarse triangulation is a valid input for further coarsening", "[coarsen]") {
  const TriangleMesh mesh = make_torus(40, 16, 2.0, 0.6);
  auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  CoarsenOptions options;
  options.target_vertices = 80;
  coarsen(T, options);
  CompactMesh maps;
  IntrinsicTriangulation level = T.compacted(&maps);
  CHECK(level.validate() == "");
  CHECK(level.num_vertices() == 80);
  CHECK(level.num_input_vertices() == 80);
  CHECK(level.euler_characteristic() == 0);
  CHECK(level.total_area() == Approx(T.total_area()).epsilon(1e-13));
  // Same faces and lengths as the arrays export.
  const CompactMesh again = level.compact();
  CHECK(again.F == maps.F);
  CHECK(again.L == maps.L);
  // Angular coordinates and angle sums carried over: curvature per vertex unchanged.
  for (Index c = 0; c < level.num_vertices(); ++c) CHECK(level.curvature(c) == T.curvature(maps.to_input[c]));
  // Coarsen the level down to the minimum (a torus can reach 1 vertex: a Δ-complex with self-edges).
  options.target_vertices = 1;
  const CoarsenResult result = coarsen(level, options);
  CHECK(level.validate() == "");
  CHECK(level.euler_characteristic() == 0);
  CHECK(result.output_vertices <= 3);
  CHECK(level.compacted().validate() == "");
}

TEST_CASE("the parallel mode keeps every invariant, is deterministic and stays close to the serial order", "[coarsen][meshes]") {
  // A boundary loop (lion-head), genus 3 (elephant, once Loop-subdivided: 11k vertices), three
  // components (blobby_3cc), a large closed surface (spot_subdiv); two and three threads (eight and
  // twelve regions).
  struct Case {
    const char* name;
    int subdivisions;
    int threads;
  };
  for (const Case& c : {Case{"lion-head.off", 0, 2}, Case{"elephant.off", 1, 2}, Case{"blobby_3cc.off", 0, 2},
                        Case{"spot_subdiv.obj", 0, 3}}) {
    INFO(c.name << " (" << c.subdivisions << " subdivisions), " << c.threads << " threads");
    const TriangleMesh mesh = loop_subdivide(load_mesh(ice_test::project_mesh(c.name)), c.subdivisions);
    CoarsenOptions options;
    options.target_ratio = 0.02;
    options.threads = c.threads;
    options.regions = 4 * c.threads;
    options.parallel_min_vertices = 1000;
    for (Index v = 0; v < mesh.V.rows(); v += 997) options.locked_vertices.push_back(v);
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    const int chi = T.euler_characteristic();
    const CoarsenResult result = coarsen(T, options);
    CHECK(result.stop_reason == StopReason::TargetReached);
    CHECK(result.parallel_removed > result.removed / 2);  // most removals ran in the regions
    // The stages after the regions coarsen the seams: the serial pass makes the last
    // max(target, removals / 32) removals and the few the regions could not (boundary, locked
    // and the last stage's seam vertices). Measured on these small meshes of 8-12 regions: 7-19 %
    // of the vertices with the stages, 31-44 % without (the first regions' seams kept the input's
    // density).
    const Index n = mesh.V.rows(), target = static_cast<Index>(std::ceil(0.02 * static_cast<double>(n)));
    const Index last_removals = std::max(target, (n - target) / 32);
    INFO("serial pass: " << result.removed - result.parallel_removed << " removals of " << n << " vertices; "
         << last_removals << " are its share");
    CHECK(result.removed - result.parallel_removed < last_removals + n / 5);
    CHECK(result.removed == mesh.V.rows() - T.num_vertices());
    CHECK(T.validate() == "");
    CHECK(T.euler_characteristic() == chi);
    CHECK(std::abs(T.total_curvature() - 2 * kPi * chi) < 1e-8);
    CHECK(count_non_delaunay(T) == 0);  // the seams were restored too
    for (Index v : options.locked_vertices) CHECK(T.vertex_alive(v));
    check_map(T);

    auto again = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    coarsen(again, options);
    const CompactMesh a = T.compact(), b = again.compact();
    CHECK(a.F == b.F);
    CHECK(a.L == b.L);  // bit-identical for a given thread count
    CHECK(a.to_input == b.to_input);
    CHECK(a.twin == b.twin);
    const ice_test::TempDir dir;
    ice_test::check_ilm_round_trip(T, dir.file("parallel.ilm"));

    // The same problem serially: the largest removal cost is of the same size (the regions only
    // reorder the early, cheap removals; the serial pass orders the last ones globally).
    auto serial = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    options.regions = 1;
    const CoarsenResult serial_result = coarsen(serial, options);
    CHECK(serial_result.parallel_removed == 0);
    // The phase times: a parallel phase only with regions, and the phases within the whole call.
    CHECK(result.parallel_seconds > 0);
    CHECK(serial_result.parallel_seconds == 0);
    for (const CoarsenResult* r : {&result, &serial_result}) {
      CHECK(r->serial_seconds > 0);
      CHECK(r->setup_seconds + r->parallel_seconds + r->serial_seconds <= r->seconds);
      // Every vertex's first cost, then the neighbours' after each removal: several per removal.
      CHECK(r->cost_evaluations > r->input_vertices);
      CHECK(r->cost_evaluations > 3 * r->removed);
    }
    CHECK(result.max_cost < 1.5 * serial_result.max_cost);
    CHECK(result.max_cost > serial_result.max_cost / 1.5);
  }
}

TEST_CASE("with a fixed region count the result does not depend on the thread count", "[coarsen][meshes]") {
  // Two components and a boundary (blobby_3cc), a closed surface once subdivided (spot: 11.7k).
  for (const auto& [name, subdivisions] : {std::pair{"blobby_3cc.off", 0}, std::pair{"spot.obj", 1}}) {
    INFO(name);
    const TriangleMesh mesh = loop_subdivide(load_mesh(ice_test::project_mesh(name)), subdivisions);
    const auto coarsened = [&](int threads, int regions, CoarsenResult* result = nullptr) {
      CoarsenOptions options;
      options.target_ratio = 0.03;
      options.threads = threads;
      options.regions = regions;
      options.parallel_min_vertices = 1000;
      auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
      const CoarsenResult r = coarsen(T, options);
      if (result) *result = r;
      CHECK(T.validate() == "");
      return T.compact();
    };
    // Eigen compares only matrices of one size (an assertion otherwise): sizes first.
    const auto same = [](const auto& x, const auto& y) { return x.rows() == y.rows() && x.cols() == y.cols() && x == y; };
    const auto check_equal = [&](const CompactMesh& a, const CompactMesh& b) {
      CHECK(same(a.F, b.F));
      CHECK(same(a.L, b.L));  // bit-identical
      CHECK(a.to_input == b.to_input);
      CHECK(a.twin == b.twin);
    };
    CoarsenResult one_thread, serial;
    const CompactMesh reference = coarsened(1, 8, &one_thread);
    CHECK(one_thread.parallel_removed > one_thread.removed / 2);  // the regions ran, on one thread
    check_equal(coarsened(2, 8), reference);
    check_equal(coarsened(3, 8), reference);
    // 0: the default count, on any number of threads (0: this machine's).
    const CompactMesh by_default = coarsened(1, kDefaultCoarseningRegions);
    check_equal(coarsened(1, 0), by_default);
    check_equal(coarsened(2, 0), by_default);
    check_equal(coarsened(0, 0), by_default);
    // An odd region count (its stages pair the regions unevenly) is as independent of the threads.
    check_equal(coarsened(2, 5), coarsened(1, 5));
    // One region is the serial greedy order, which differs.
    const CompactMesh exact = coarsened(1, 1, &serial);
    CHECK(serial.parallel_removed == 0);
    check_equal(coarsened(4, 1), exact);
    CHECK(!same(exact.L, reference.L));
  }
  auto T = IntrinsicTriangulation::from_mesh(make_icosphere(2).V, make_icosphere(2).F);
  CoarsenOptions options;
  options.target_ratio = 0.5;
  for (int regions : {-1, 255}) {
    options.regions = regions;
    CHECK_THROWS_AS(coarsen(T, options), std::invalid_argument);
  }
}

TEST_CASE("the parallel mode honours thresholds and cancellation", "[coarsen]") {
  const TriangleMesh mesh = make_icosphere(5);  // 10,242 vertices
  CoarsenOptions options;
  options.threads = 2;
  options.parallel_min_vertices = 1000;
  SECTION("threshold") {
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    options.max_error = 0.02;
    const CoarsenResult result = coarsen(T, options);
    CHECK(result.parallel_removed > 0);
    check_threshold_stop(T, result, 0.02);
  }
  SECTION("cancel") {
    auto T = IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
    options.target_vertices = 100;
    options.progress_interval = 100;
    options.progress = [](const CoarsenProgress& p) { return p.removed < 1000; };
    const CoarsenResult result = coarsen(T, options);
    CHECK(result.stop_reason == StopReason::Cancelled);
    CHECK(result.removed >= 1000);
    CHECK(result.removed < 9000);
    CHECK(T.validate() == "");
  }
}
