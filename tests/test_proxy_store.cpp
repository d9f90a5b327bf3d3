// The store of set-up proxies (ice/proxy/store.h): a warm solver gives the cold one's results to the
// last bit; every kind of damage is detected, never used, and rebuilt to the same results; two
// writers of one entry both succeed; the size bound evicts the least recently used entry.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>
#include <vector>

#include "ice/mesh_generators.h"
#include "fem/coarse_proxy.h"
#include "ice/mesh_io.h"
#include "ice/coarse_tracing.h"
#include "ice/proxy/geodesics.h"
#include "ice/proxy/heat.h"
#include "ice/proxy/multigrid.h"
#include "ice/proxy/poisson.h"
#include "ice/proxy/store.h"
#include "test_support.h"

namespace fs = std::filesystem;
using ice::proxy::CacheStatus;
using ice_test::fresh_store;
using ice_test::read_bytes;
using ice_test::write_bytes;

namespace {

using ice_test::unit_sphere;

ice::proxy::PoissonOptions options_with(const fs::path& dir) {
  ice::proxy::PoissonOptions options;
  options.coarsening.coarsen.target_vertices = 300;
  options.store.directory = dir;
  return options;
}

Eigen::VectorXd source(const ice::TriangleMesh& mesh) {
  Eigen::VectorXd f(mesh.V.rows());
  for (Eigen::Index v = 0; v < f.size(); ++v) f(v) = mesh.V(v, 0) * mesh.V(v, 1) + mesh.V(v, 2);
  return f;
}

std::vector<fs::path> entries(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".ice") out.push_back(e.path());
  return out;
}

}  // namespace

TEST_CASE("store: a warm Poisson solver equals the cold one and the one without a store, bit for bit", "[proxy][store]") {
  const fs::path dir = fresh_store("warm");
  const ice::TriangleMesh& mesh = unit_sphere();
  const Eigen::VectorXd f = source(mesh);
  ice::proxy::PoissonOptions off = options_with({});
  const ice::proxy::PoissonSolver plain(mesh, off);
  CHECK(plain.cache().status == CacheStatus::off);
  const ice::proxy::PoissonSolver cold(mesh, options_with(dir));
  CHECK(cold.cache().status == CacheStatus::miss);
  CHECK(cold.cache().save_error.empty());
  REQUIRE(entries(dir).size() == 1);
  // An entry stays below 200 bytes per input vertex (the coarse space, the smoothed P, the masses).
  CHECK(fs::file_size(entries(dir)[0]) < 200 * static_cast<std::uintmax_t>(mesh.V.rows()));
  const ice::proxy::PoissonSolver warm(mesh, options_with(dir));
  CHECK(warm.cache().status == CacheStatus::hit);
  CHECK(warm.cache().keys == cold.cache().keys);
  const Eigen::VectorXd u = plain.solve(f);
  CHECK(cold.solve(f) == u);
  CHECK(warm.solve(f) == u);
  CHECK(warm.coarse_space().P.isApprox(cold.coarse_space().P, 0.0));
  CHECK(warm.coarse_space().mesh.F == cold.coarse_space().mesh.F);
  CHECK(warm.coarse_space().mesh.L == cold.coarse_space().mesh.L);
  CHECK(warm.coarse_space().summary.coarse_vertices == cold.coarse_space().summary.coarse_vertices);
  CHECK(warm.coarse_space().summary.ice->removed == cold.coarse_space().summary.ice->removed);

  SECTION("other options and another mesh of the same size miss") {
    ice::proxy::PoissonOptions other = options_with(dir);
    other.coarsening.coarsen.target_vertices = 301;
    CHECK(ice::proxy::PoissonSolver(mesh, other).cache().status == CacheStatus::miss);
    ice::TriangleMesh moved = mesh;
    moved.V(7, 0) += 1e-9;  // same counts, other positions
    CHECK(ice::proxy::PoissonSolver(moved, options_with(dir)).cache().status == CacheStatus::miss);
    CHECK(entries(dir).size() == 3);
  }
  SECTION("polishing from a warm proxy makes its fine operators and equals the cold polish") {
    ice::proxy::PoissonOptions polished = options_with(dir);
    polished.polish.iterations = 3;
    const ice::proxy::PoissonSolver warm_polished(mesh, polished);
    CHECK(warm_polished.cache().status == CacheStatus::hit);
    polished.store = {};
    CHECK(warm_polished.solve(f) == ice::proxy::PoissonSolver(mesh, polished).solve(f));
  }
  SECTION("a heat solver with the same setup options shares the entry and its results") {
    ice::proxy::HeatOptions heat;
    heat.coarsening.coarsen.target_vertices = 300;
    heat.store.directory = dir;
    const ice::proxy::HeatSolver warm_heat(mesh, 1e-3, heat);
    CHECK(warm_heat.cache().status == CacheStatus::hit);
    heat.store = {};
    CHECK(warm_heat.integrate(f, 3) == ice::proxy::HeatSolver(mesh, 1e-3, heat).integrate(f, 3));
  }
  fs::remove_all(dir);
}

TEST_CASE("store: damaged entries are reported, never used, and rebuilt to the same results", "[proxy][store]") {
  const fs::path dir = fresh_store("damage");
  const ice::TriangleMesh& mesh = unit_sphere();
  const Eigen::VectorXd f = source(mesh);
  const Eigen::VectorXd u = ice::proxy::PoissonSolver(mesh, options_with({})).solve(f);
  REQUIRE(ice::proxy::PoissonSolver(mesh, options_with(dir)).cache().status == CacheStatus::miss);
  const fs::path entry = entries(dir).at(0);
  const std::vector<char> good = read_bytes(entry);

  struct Damage {
    std::string name, expected;
    std::vector<char> bytes;
  };
  std::vector<Damage> damages;
  damages.push_back({"truncated", "truncated", std::vector<char>(good.begin(), good.begin() + good.size() / 2)});
  damages.push_back({"empty", "truncated", {}});
  std::vector<char> flipped = good;
  flipped[flipped.size() - 100] ^= 0x10;
  damages.push_back({"flipped payload byte", "checksum", flipped});
  std::vector<char> version = good;
  version[8] = static_cast<char>(version[8] + 1);  // the format version follows the 8-byte magic
  damages.push_back({"other format version", "format version", version});
  std::vector<char> key = good;
  key[40] ^= 0x01;  // a byte of the key: an entry made for another mesh or other options
  damages.push_back({"other key", "another key", key});
  std::vector<char> magic = good;
  magic[0] = 'X';
  damages.push_back({"not an entry", "not an ICE store entry", magic});

  for (const Damage& d : damages) {
    INFO(d.name);
    write_bytes(entry, d.bytes);
    const ice::proxy::PoissonSolver rebuilt(mesh, options_with(dir));
    CHECK(rebuilt.cache().status == CacheStatus::rebuilt);
    CHECK(rebuilt.cache().damage.find(d.expected) != std::string::npos);
    CHECK(rebuilt.solve(f) == u);
    // The rebuilt entry is whole again (of the same size: only the timings it records differ), and
    // the next run hits it.
    CHECK(read_bytes(entry).size() == good.size());
    CHECK(ice::proxy::PoissonSolver(mesh, options_with(dir)).cache().status == CacheStatus::hit);
  }

  SECTION("another mesh's entry under this key fails the content checks") {
    ice::TriangleMesh other = ice::make_icosphere(3);  // 642 vertices
    ice::proxy::PoissonOptions other_options = options_with(dir);
    other_options.coarsening.coarsen.target_vertices = 100;
    const ice::proxy::PoissonSolver made(other, other_options);
    const fs::path other_entry = dir / ("proxy-" + made.cache().keys.at(0) + ".ice");
    std::vector<char> moved = read_bytes(other_entry);
    std::copy(good.begin() + 32, good.begin() + 48, moved.begin() + 32);  // this mesh's key in its header...
    write_bytes(entry, moved);
    const ice::proxy::PoissonSolver rebuilt(mesh, options_with(dir));
    CHECK(rebuilt.cache().status == CacheStatus::rebuilt);  // ...but its arrays do not fit this mesh
    CHECK(rebuilt.solve(f) == u);
  }

  SECTION("verify finds a damaged entry and removes it on request") {
    write_bytes(entry, flipped);
    const ice::proxy::Store store({dir, ice::proxy::kDefaultStoreBytes});
    REQUIRE(store.list().size() == 1);
    const auto damaged = store.verify(false);
    REQUIRE(damaged.size() == 1);
    CHECK(damaged[0].second.find("checksum") != std::string::npos);
    CHECK(fs::exists(entry));
    CHECK(store.verify(true).size() == 1);
    CHECK(!fs::exists(entry));
    CHECK(store.verify(false).empty());
  }
  fs::remove_all(dir);
}

TEST_CASE("store: two writers of one entry both succeed with identical results", "[proxy][store]") {
  const fs::path dir = fresh_store("race");
  const ice::TriangleMesh& mesh = unit_sphere();
  const Eigen::VectorXd f = source(mesh);
  Eigen::VectorXd a, b;
  CacheStatus sa{}, sb{};
  std::thread first([&] {
    const ice::proxy::PoissonSolver s(mesh, options_with(dir));
    sa = s.cache().status;
    a = s.solve(f);
  });
  std::thread second([&] {
    const ice::proxy::PoissonSolver s(mesh, options_with(dir));
    sb = s.cache().status;
    b = s.solve(f);
  });
  first.join();
  second.join();
  CHECK(a == b);
  CHECK(sa != CacheStatus::rebuilt);
  CHECK(sb != CacheStatus::rebuilt);
  // One entry and no temporary file left; it is whole.
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file() ? 1 : 0;
  CHECK(files == 1);
  const ice::proxy::PoissonSolver warm(mesh, options_with(dir));
  CHECK(warm.cache().status == CacheStatus::hit);
  CHECK(warm.solve(f) == a);
  fs::remove_all(dir);
}

TEST_CASE("store: the size bound evicts the least recently used entries; clear empties it", "[proxy][store]") {
  const fs::path dir = fresh_store("evict");
  const ice::TriangleMesh& mesh = unit_sphere();
  ice::proxy::PoissonOptions options = options_with(dir);
  const ice::proxy::PoissonSolver first(mesh, options);
  const std::uintmax_t one = fs::file_size(entries(dir).at(0));
  options.store.max_bytes = one + one / 2;  // room for one entry, not two
  options.coarsening.coarsen.target_vertices = 310;
  const ice::proxy::PoissonSolver second(mesh, options);
  REQUIRE(entries(dir).size() == 1);
  CHECK(entries(dir)[0].filename().string().find(second.cache().keys.at(0)) != std::string::npos);
  // The key of the evicted entry misses now; the kept one hits.
  options.coarsening.coarsen.target_vertices = 300;
  options.store.max_bytes = ice::proxy::kDefaultStoreBytes;
  CHECK(ice::proxy::PoissonSolver(mesh, options).cache().status == CacheStatus::miss);
  const ice::proxy::Store store({dir, ice::proxy::kDefaultStoreBytes});
  CHECK(store.list().size() == 2);
  CHECK(store.clear() > 0);
  CHECK(store.list().empty());
  fs::remove_all(dir);
}

TEST_CASE("store: keys separate inputs and options; the default directory follows the environment", "[proxy][store]") {
  const auto key = [](const std::string& kind, auto... values) {
    ice::proxy::KeyHasher h(kind);
    (h.add(values), ...);
    return h.finish();
  };
  CHECK(key("proxy", std::string("ab"), std::string("c")).hex() != key("proxy", std::string("a"), std::string("bc")).hex());
  CHECK(key("proxy", 1.0).hex() != key("proxy", std::int64_t{1}).hex());
  CHECK(key("proxy", 0.0).hex() == key("proxy", -0.0).hex());
  CHECK(key("proxy", 1.0).hex() != key("other", 1.0).hex());
  CHECK(key("proxy", 1.0).hex().size() == 32);

  const std::string saved = std::getenv("ICE_CACHE") ? std::getenv("ICE_CACHE") : "";
  const bool had = std::getenv("ICE_CACHE") != nullptr;
  ::setenv("ICE_CACHE", "/some/where", 1);
  CHECK(ice::proxy::default_store_options().directory == fs::path("/some/where"));
  ::setenv("ICE_CACHE", "", 1);
  CHECK(ice::proxy::default_store_options().directory.empty());
  ::setenv("ICE_CACHE_MAX_MB", "12", 1);
  CHECK(ice::proxy::default_store_options().max_bytes == std::uint64_t{12} << 20);
  ::setenv("ICE_CACHE_MAX_MB", "lots", 1);
  CHECK_THROWS_AS(ice::proxy::default_store_options(), std::invalid_argument);
  ::unsetenv("ICE_CACHE_MAX_MB");
  if (had)
    ::setenv("ICE_CACHE", saved.c_str(), 1);
  else
    ::unsetenv("ICE_CACHE");
}

TEST_CASE("setup files: an explicit save loads back bit for bit, for its own mesh only, and damage is refused", "[proxy][store]") {
  const fs::path dir = fresh_store("setup-file");
  fs::create_directories(dir);
  const fs::path file = dir / "sphere-setup.ice";
  const ice::TriangleMesh& mesh = unit_sphere();
  ice::proxy::ProxySetupOptions options;
  options.coarsening.coarsen.target_vertices = 300;
  options.prolongation = ice::proxy::Prolongation::smoothed;  // the largest entry: the smoothed P is saved too
  const ice::proxy::ProxySetup made = ice::proxy::build_proxy_setup(mesh, options);
  ice::proxy::save_proxy_setup_file(file, mesh, made);
  CHECK(fs::file_size(file) < 200 * static_cast<std::uintmax_t>(mesh.V.rows()));
  CHECK_THROWS_AS(ice::proxy::save_proxy_setup_file(file, mesh, made), ice::MeshError);  // not overwritten unasked
  ice::proxy::save_proxy_setup_file(file, mesh, made, true);

  const ice::proxy::ProxySetup loaded = ice::proxy::load_proxy_setup_file(file, mesh);
  CHECK(loaded.cache.status == CacheStatus::off);
  CHECK(loaded.fine_geometry == made.fine_geometry);
  CHECK(loaded.coarse.P.isApprox(made.coarse.P, 0.0));
  CHECK(loaded.coarse.mesh.F == made.coarse.mesh.F);
  CHECK(loaded.coarse.mesh.L == made.coarse.mesh.L);
  CHECK(loaded.coarse.mesh.twin == made.coarse.mesh.twin);
  CHECK(loaded.proxy->prolongation_kind() == fem::ProlongationKind::smoothed);
  const Eigen::VectorXd f = source(mesh);
  const fem::ProxyPoissonSolver from_file(*loaded.proxy), original(*made.proxy);
  CHECK(from_file.solve(f) == original.solve(f));
  // Its fine operators come from the mesh in the saved geometry: the same fine Laplacian.
  CHECK(loaded.proxy->fine_laplacian().isApprox(made.proxy->fine_laplacian(), 0.0));

  SECTION("a store's entry is not a setup file") {
    ice::proxy::ProxySetupOptions stored = options;
    stored.store = ice::proxy::Store({dir / "store", ice::proxy::kDefaultStoreBytes});
    const ice::proxy::ProxySetup in_store = ice::proxy::build_proxy_setup(mesh, stored);
    REQUIRE(in_store.cache.keys.size() == 1);
    const fs::path entry = dir / "store" / ("proxy-" + in_store.cache.keys[0] + ".ice");
    CHECK_THROWS_WITH(ice::proxy::load_proxy_setup_file(entry, mesh), Catch::Contains("an entry of a store"));
  }
  SECTION("another mesh of the same size is refused") {
    ice::TriangleMesh moved = mesh;
    moved.V(0, 0) += 1e-9;
    CHECK_THROWS_WITH(ice::proxy::load_proxy_setup_file(file, moved), Catch::Contains("another mesh"));
  }
  SECTION("a damaged file, a hierarchy file and a missing file are refused, naming the file") {
    const std::vector<char> good = read_bytes(file);
    std::vector<char> flipped = good;
    flipped[flipped.size() / 2] ^= 0x10;
    write_bytes(file, flipped);
    CHECK_THROWS_WITH(ice::proxy::load_proxy_setup_file(file, mesh), Catch::Contains(file.string()) && Catch::Contains("checksum"));
    write_bytes(file, std::vector<char>(good.begin(), good.begin() + good.size() / 2));
    CHECK_THROWS_WITH(ice::proxy::load_proxy_setup_file(file, mesh), Catch::Contains("truncated"));
    const ice::proxy::MultigridHierarchy h = ice::proxy::multigrid_hierarchy(mesh);
    ice::proxy::save_multigrid_hierarchy_file(dir / "h.ice", mesh, h);
    CHECK_THROWS_WITH(ice::proxy::load_proxy_setup_file(dir / "h.ice", mesh), Catch::Contains("kind 'hierarchy'"));
    CHECK_THROWS_WITH(ice::proxy::load_proxy_setup_file(dir / "none.ice", mesh), Catch::Contains("no such file"));
  }
  fs::remove_all(dir);
}

namespace {

// A sphere small enough for the sanitizer build (642 vertices): the stored spaces' tests check
// identities, which hold at any size.
const ice::TriangleMesh& small_sphere() {
  static const ice::TriangleMesh mesh = ice::make_icosphere(3);
  return mesh;
}

ice::proxy::MappedSpaceOptions mapped_options(const fs::path& dir, ice::CoarseningMethod method = ice::CoarseningMethod::ice) {
  ice::proxy::MappedSpaceOptions options;
  options.coarsening.method = method;
  options.coarsening.coarsen.target_vertices = 150;
  options.store = ice::proxy::Store({dir, ice::proxy::kDefaultStoreBytes});
  return options;
}

void check_same_space(const ice::proxy::MappedSpace& a, const ice::proxy::MappedSpace& b) {
  CHECK(a.coarse.mesh.F == b.coarse.mesh.F);
  CHECK(a.coarse.mesh.L == b.coarse.mesh.L);
  CHECK(a.coarse.mesh.twin == b.coarse.mesh.twin);
  CHECK(a.coarse.mesh.to_input == b.coarse.mesh.to_input);
  CHECK(a.coarse.mesh.from_input == b.coarse.mesh.from_input);
  CHECK(a.coarse.P.isApprox(b.coarse.P, 0.0));
  CHECK(a.coarse.summary.removed() == b.coarse.summary.removed());
  REQUIRE(a.coarse.inserted.size() == b.coarse.inserted.size());
  for (std::size_t i = 0; i < a.coarse.inserted.size(); ++i) {
    CHECK(a.coarse.inserted[i].face == b.coarse.inserted[i].face);
    CHECK(a.coarse.inserted[i].bary == b.coarse.inserted[i].bary);
  }
  REQUIRE(a.map.size() == b.map.size());
  for (std::size_t i = 0; i < a.map.size(); ++i) {
    CHECK(a.map[i].coarse_vertex == b.map[i].coarse_vertex);
    CHECK(a.map[i].face == b.map[i].face);
    CHECK(a.map[i].bary == b.map[i].bary);
  }
}

}  // namespace

TEST_CASE("store: a coarse space with its map and traced lengths loads back bit for bit (ICE, refined, QEM)",
          "[proxy][store]") {
  const fs::path dir = fresh_store("mapped");
  const ice::TriangleMesh& mesh = small_sphere();
  const auto method = GENERATE(as<std::string>{}, "ice", "refined", "qem");
  INFO(method);
  ice::proxy::MappedSpaceOptions options = mapped_options(dir, method == "qem" ? ice::CoarseningMethod::qem : ice::CoarseningMethod::ice);
  if (method == "refined") options.coarsening.refinement = ice::RefinementOptions{};
  ice::proxy::MappedSpaceOptions off = options;
  off.store = {};

  const ice::proxy::MappedSpace plain = ice::proxy::build_mapped_space(mesh, off);
  CHECK(plain.cache.status == CacheStatus::off);
  CHECK(!plain.coarse.triangulation);  // the method's state is freed once the map is read
  if (method == "refined") CHECK(!plain.coarse.inserted.empty());
  const ice::proxy::MappedSpace cold = ice::proxy::build_mapped_space(mesh, options);
  CHECK(cold.cache.status == CacheStatus::miss);
  REQUIRE(entries(dir).size() == 1);
  // The map costs 40 bytes per input vertex: an entry stays below 200.
  CHECK(fs::file_size(entries(dir)[0]) < 200 * static_cast<std::uintmax_t>(mesh.V.rows()));
  const ice::proxy::MappedSpace warm = ice::proxy::build_mapped_space(mesh, options);
  CHECK(warm.cache.status == CacheStatus::hit);
  REQUIRE(warm.key);
  CHECK(warm.cache.keys == cold.cache.keys);
  check_same_space(plain, cold);
  check_same_space(plain, warm);

  // An explicit file of it reads back the same, for this mesh only.
  const fs::path file = dir / "space.ices";
  ice::proxy::save_mapped_space_file(file, mesh, plain.coarse, plain.map);
  check_same_space(plain, ice::proxy::load_mapped_space_file(file, mesh));
  CHECK_THROWS_AS(ice::proxy::save_mapped_space_file(file, mesh, plain.coarse, plain.map), ice::MeshError);
  ice::TriangleMesh moved = mesh;
  moved.V(0, 0) += 1e-3;
  CHECK_THROWS_WITH(ice::proxy::load_mapped_space_file(file, moved), Catch::Contains("another mesh"));
  fs::remove(file);

  // The map agrees with P: each row of P is its point's coordinates summed over the face's corners.
  const Eigen::SparseMatrix<double, Eigen::RowMajor> rows = warm.coarse.P;
  for (Eigen::Index i = 0; i < rows.rows(); ++i) {
    const ice::CoarsePoint& p = warm.map[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) {
      double expected = 0;
      for (int l = 0; l < 3; ++l)
        if (warm.coarse.mesh.F(p.face, l) == warm.coarse.mesh.F(p.face, k)) expected += p.bary[static_cast<std::size_t>(l)];
      CHECK(std::abs(rows.coeff(i, warm.coarse.mesh.F(p.face, k)) - expected) <= 1e-12);
    }
  }

  if (method != "qem") {  // QEM's edges are straight: nothing to trace
    const ice::SurfaceEdgeLengths traced = ice::surface_edge_lengths(mesh, plain.coarse.mesh, plain.map, plain.coarse.inserted);
    ice::proxy::CacheReport first = warm.cache, second = warm.cache;
    const ice::SurfaceEdgeLengths made = ice::proxy::traced_edge_lengths(mesh, warm, options.store, &first);
    CHECK(first.keys.size() == 2);
    CHECK(entries(dir).size() == 2);
    const ice::SurfaceEdgeLengths loaded = ice::proxy::traced_edge_lengths(mesh, warm, options.store, &second);
    CHECK(second.keys == first.keys);
    CHECK(second.status == CacheStatus::hit);
    CHECK(made.lengths == traced.lengths);
    CHECK(loaded.lengths == traced.lengths);
    CHECK(loaded.edges == traced.edges);
    CHECK(loaded.traced == traced.traced);
    CHECK(traced.traced > 0);

    // A damaged traced entry is reported, removed and traced again.
    const fs::path traced_entry = dir / ("traced-" + first.keys.at(1) + ".ice");
    std::vector<char> bytes = read_bytes(traced_entry);
    bytes[bytes.size() - 20] ^= 0x04;
    write_bytes(traced_entry, bytes);
    ice::proxy::CacheReport third = warm.cache;
    CHECK(ice::proxy::traced_edge_lengths(mesh, warm, options.store, &third).lengths == traced.lengths);
    CHECK(third.status == CacheStatus::rebuilt);
    CHECK(third.damage.find("checksum") != std::string::npos);

    // The marching lengths from the store (traced, then curvature-corrected from the gathered
    // curvature stored beside the space) equal those made from scratch, bit for bit.
    const double divisor = ice::proxy::curvature_divisor(ice::proxy::MarchingUse::single_source);
    const ice::SurfaceEdgeLengths own = ice::proxy::marching_lengths(mesh, plain.coarse, true, ice::proxy::CurvatureCorrection::on,
                                                                     &plain.map, divisor);
    for (int run = 0; run < 2; ++run) {
      ice::proxy::CacheReport report = warm.cache;
      CHECK(ice::proxy::stored_marching_lengths(mesh, warm, options.store, true, ice::proxy::CurvatureCorrection::on, divisor,
                                                &report)
                .lengths == own.lengths);
      CHECK(report.keys.size() == 3);
    }
  }
  fs::remove_all(dir);
}

TEST_CASE("store: a damaged coarse space entry is never used and is rebuilt to the same space and map", "[proxy][store]") {
  const fs::path dir = fresh_store("mapped-damage");
  const ice::TriangleMesh& mesh = small_sphere();
  const ice::proxy::MappedSpaceOptions options = mapped_options(dir);
  const ice::proxy::MappedSpace cold = ice::proxy::build_mapped_space(mesh, options);
  const fs::path entry = entries(dir).at(0);
  const std::vector<char> good = read_bytes(entry);
  std::vector<char> flipped = good;
  flipped[flipped.size() / 2] ^= 0x01;
  for (const std::vector<char>& bad : {std::vector<char>(good.begin(), good.begin() + good.size() / 3), flipped}) {
    write_bytes(entry, bad);
    const ice::proxy::MappedSpace rebuilt = ice::proxy::build_mapped_space(mesh, options);
    CHECK(rebuilt.cache.status == CacheStatus::rebuilt);
    CHECK(!rebuilt.cache.damage.empty());
    check_same_space(cold, rebuilt);
    CHECK(ice::proxy::build_mapped_space(mesh, options).cache.status == CacheStatus::hit);
  }
  // A coarsening its progress callback cancelled is not the space its key names: never stored.
  ice::proxy::MappedSpaceOptions cancelled = options;
  cancelled.coarsening.coarsen.target_vertices = 100;
  cancelled.coarsening.coarsen.progress_interval = 10;
  cancelled.coarsening.coarsen.progress = [](const ice::CoarsenProgress&) { return false; };
  const std::size_t before = entries(dir).size();
  const ice::proxy::MappedSpace stopped = ice::proxy::build_mapped_space(mesh, cancelled);
  CHECK(stopped.coarse.summary.stop_reason() == ice::StopReason::Cancelled);
  CHECK(!stopped.key);  // nor is anything stored beside it
  (void)ice::proxy::stored_marching_lengths(mesh, stopped, options.store, true, ice::proxy::CurvatureCorrection::on, 48);
  CHECK(entries(dir).size() == before);
  // What needs the method's state bypasses the store; so does nothing else.
  ice::proxy::MappedSpaceOptions kept = options;
  kept.coarsening.keep_method_state = true;
  const ice::proxy::MappedSpace with_state = ice::proxy::build_mapped_space(mesh, kept);
  CHECK(with_state.cache.status == CacheStatus::off);
  CHECK(with_state.coarse.triangulation);
  check_same_space(cold, with_state);
  // QEM's intrinsic Delaunay geometry has no map: made, not stored (marching on its own lengths works).
  ice::proxy::MappedSpaceOptions idt = options;
  idt.coarsening.method = ice::CoarseningMethod::qem;
  idt.coarsening.qem_geometry = ice::QemGeometry::intrinsic_delaunay;
  const ice::proxy::MappedSpace unmapped = ice::proxy::build_mapped_space(mesh, idt);
  CHECK(unmapped.map.empty());
  CHECK(!unmapped.key);
  CHECK(unmapped.cache.status == CacheStatus::off);
  CHECK(unmapped.coarse.P.rows() == mesh.V.rows());
  // A tufted cover's space is stored with its map (each vertex placed by one copy) and loads back
  // bit for bit.
  ice::TriangleMesh fin;  // three triangles on one edge: solved on its tufted cover
  fin.V.resize(5, 3);
  fin.V << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0, 0.5, 0, 1;
  fin.F.resize(3, 3);
  fin.F << 0, 1, 2, 1, 0, 3, 0, 1, 4;
  ice::proxy::MappedSpaceOptions covered = options;
  covered.coarsening.nonmanifold = ice::NonmanifoldInput::tufted_cover;
  covered.coarsening.coarsen.target_vertices = 4;
  const ice::proxy::MappedSpace covered_cold = ice::proxy::build_mapped_space(fin, covered);
  REQUIRE(covered_cold.coarse.summary.tufted_cover);
  REQUIRE(covered_cold.key);
  REQUIRE(covered_cold.map.size() == 5);
  const ice::proxy::MappedSpace covered_warm = ice::proxy::build_mapped_space(fin, covered);
  CHECK(covered_warm.cache.status == CacheStatus::hit);
  CHECK(covered_warm.coarse.summary.tufted_cover);
  CHECK(covered_warm.coarse.P.isApprox(covered_cold.coarse.P, 0.0));
  for (std::size_t i = 0; i < covered_cold.map.size(); ++i) {
    CHECK(covered_warm.map[i].face == covered_cold.map[i].face);
    CHECK(covered_warm.map[i].bary == covered_cold.map[i].bary);
  }
  fs::remove_all(dir);
}

TEST_CASE("store: geodesics from a stored space equal those set up from scratch, bit for bit", "[proxy][store][geodesic]") {
  const fs::path dir = fresh_store("geodesic");
  const ice::TriangleMesh& mesh = small_sphere();
  const std::vector<ice::Index> sources{0, 17};
  for (const fem::CoarseDistanceMethod method : {fem::CoarseDistanceMethod::marching, fem::CoarseDistanceMethod::heat_method}) {
    ice::proxy::GeodesicOptions options;
    options.method = method;
    options.coarsening.coarsen.target_vertices = 150;
    const Eigen::VectorXd plain = ice::proxy::GeodesicSolver(mesh, options).distance(sources);
    options.store.directory = dir;
    const ice::proxy::GeodesicSolver cold(mesh, options);
    CHECK(cold.cache().status == CacheStatus::miss);
    const ice::proxy::GeodesicSolver warm(mesh, options);
    CHECK(warm.cache().status == CacheStatus::hit);
    if (method == fem::CoarseDistanceMethod::marching) {
      CHECK(warm.traced_lengths());
      CHECK(warm.cache().keys.size() == 3);  // the space with its map, its traced lengths, its gathered curvature
    }
    CHECK(cold.distance(sources) == plain);
    CHECK(warm.distance(sources) == plain);
  }
  // The oracle reads the same space and traced lengths.
  ice::proxy::OracleOptions oracle;
  oracle.coarsening.coarsen.target_vertices = 150;
  const fem::DistanceOracle plain = ice::proxy::distance_oracle(mesh, oracle);
  oracle.store.directory = dir;
  ice::proxy::CacheReport cache;
  const fem::DistanceOracle warm = ice::proxy::distance_oracle(mesh, oracle, {}, nullptr, &cache);
  CHECK(cache.status == CacheStatus::hit);
  const std::vector<std::array<ice::Index, 2>> pairs{{0, 100}, {5, 400}, {17, 641}};
  CHECK(warm.distances(pairs) == plain.distances(pairs));

  // What is stored beside a space is keyed by the mesh too: the same space handed another mesh of its
  // faces (an animation's next frame) gets that mesh's lengths, never the first one's.
  ice::proxy::MappedSpaceOptions space_options;
  space_options.coarsening = ice::proxy::GeodesicOptions{}.coarsening;
  space_options.coarsening.coarsen.target_vertices = 150;
  space_options.store = ice::proxy::Store({dir, ice::proxy::kDefaultStoreBytes});
  const ice::proxy::MappedSpace space = ice::proxy::build_mapped_space(mesh, space_options);
  REQUIRE(space.cache.status == CacheStatus::hit);
  ice::TriangleMesh stretched = mesh;
  stretched.V.col(2) *= 1.5;
  const double divisor = ice::proxy::curvature_divisor(ice::proxy::MarchingUse::single_source);
  const ice::SurfaceEdgeLengths own = ice::proxy::marching_lengths(stretched, space.coarse, true, ice::proxy::CurvatureCorrection::on,
                                                                   &space.map, divisor);
  for (int run = 0; run < 2; ++run)
    CHECK(ice::proxy::stored_marching_lengths(stretched, space, space_options.store, true, ice::proxy::CurvatureCorrection::on,
                                              divisor)
              .lengths == own.lengths);

  // QEM's intrinsic Delaunay geometry (no map) marches on its own lengths through a store too.
  ice::proxy::GeodesicOptions idt;
  idt.coarsening.method = ice::CoarseningMethod::qem;
  idt.coarsening.qem_geometry = ice::QemGeometry::intrinsic_delaunay;
  idt.coarsening.coarsen.target_vertices = 150;
  const Eigen::VectorXd idt_plain = ice::proxy::GeodesicSolver(mesh, idt).distance(sources);
  idt.store.directory = dir;
  const ice::proxy::GeodesicSolver idt_stored(mesh, idt);
  CHECK(idt_stored.cache().status == CacheStatus::off);
  CHECK(idt_stored.distance(sources) == idt_plain);
  fs::remove_all(dir);
}
