#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "entry_checks.h"
#include "fem/curvature_correction.h"
#include "ice/mesh_io.h"
#include "ice/proxy/setup.h"
#include "ice/wall_time.h"
#include "stored_space.h"

namespace ice::proxy {

namespace {

using detail::require;

constexpr const char* kSpaceKind = "space";
constexpr const char* kTracedKind = "traced";
constexpr const char* kCurvatureKind = "curvature";

// A mapped space's entry: the coarse space's arrays and the map's, two int32 and three doubles a point.
struct SpaceEntry {
  EntryWriter writer;
  detail::CoarseSpaceArrays coarse_arrays;
  std::vector<std::int32_t> vertex_face;
  std::vector<double> bary;
  SpaceEntry(const CoarseSpace& coarse, const std::vector<CoarsePoint>& map) : coarse_arrays(writer, coarse) {
    vertex_face.reserve(2 * map.size());
    bary.reserve(3 * map.size());
    for (const CoarsePoint& p : map) {
      vertex_face.push_back(p.coarse_vertex);
      vertex_face.push_back(p.face);
      bary.insert(bary.end(), p.bary.begin(), p.bary.end());
    }
    writer.put("map.vertex_face", vertex_face.data(), vertex_face.size());
    writer.put("map.bary", bary.data(), bary.size());
  }
};

// The map an entry holds, checked against its coarse space (whose vertex maps are checked already):
// points in a face, survivors where from_input says, and every entry of P the point's barycentric coordinates summed over its face's
// corners (a consumer walks the map and prolongs with P: the two must be one map). Through a tufted
// cover a point is one copy's and P's row the mean of all copies' (ice::fine_to_coarse_map): there
// every corner the point weighs lies in the row's columns, with a positive entry.
std::vector<CoarsePoint> map_from_entry(const EntryReader& entry, const std::string& path, const CoarseSpace& c, bool covered) {
  require(c.summary.tufted_cover == covered, path,
          covered ? "the space is not a tufted cover's, which the mesh needs" : "the space is a tufted cover's, which the mesh does not need");
  const std::vector<std::int32_t> vertex_face = entry.ints("map.vertex_face");
  const std::vector<double> bary = entry.doubles("map.bary");
  const auto n = static_cast<std::size_t>(c.P.rows());
  require(vertex_face.size() == 2 * n && bary.size() == 3 * n, path, "the fine-to-coarse map has the wrong size");
  const auto faces = static_cast<std::int32_t>(c.mesh.F.rows());
  std::vector<CoarsePoint> map(n);
  for (std::size_t i = 0; i < n; ++i) {
    CoarsePoint& p = map[i];
    p.coarse_vertex = vertex_face[2 * i];
    p.face = vertex_face[2 * i + 1];
    require(p.coarse_vertex == c.mesh.from_input[i], path, "the map and the input vertex map disagree");
    require(p.face >= 0 && p.face < faces, path, "a map point lies in no coarse face");
    double sum = 0;
    bool at_its_vertex = false;
    for (std::size_t k = 0; k < 3; ++k) {
      p.bary[k] = bary[3 * i + k];
      require(std::isfinite(p.bary[k]) && p.bary[k] >= -1e-9, path, "a map point's coordinates are not finite and non-negative");
      sum += p.bary[k];
      at_its_vertex |= p.bary[k] == 1 && c.mesh.F(p.face, static_cast<Eigen::Index>(k)) == p.coarse_vertex;
    }
    require(std::abs(sum - 1) <= 1e-9, path, "a map point's coordinates do not sum to 1");
    // Through a cover P is checked loosely below: a survivor's point must then be its coarse vertex.
    if (covered && p.coarse_vertex != kInvalid) require(at_its_vertex, path, "a surviving vertex's map point is not its coarse vertex");
  }
  constexpr double kTolerance = 1e-12;  // P's entries are the map's coordinates summed over repeated corners
  std::vector<double> row_sum(n, 0.0);
  std::vector<int> corners_seen(n, 0);  // covered: the point's weighted corners met among the row's columns
  for (Eigen::Index j = 0; j < c.P.outerSize(); ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(c.P, j); it; ++it) {
      const auto i = static_cast<std::size_t>(it.row());
      const CoarsePoint& p = map[i];
      double expected = 0;
      for (int k = 0; k < 3; ++k)
        if (c.mesh.F(p.face, k) == j) {
          expected += p.bary[static_cast<std::size_t>(k)];
          if (p.bary[static_cast<std::size_t>(k)] > 0 && it.value() > 0) ++corners_seen[i];
        }
      if (!covered) require(std::abs(it.value() - expected) <= kTolerance, path, "P and the fine-to-coarse map disagree");
      row_sum[i] += it.value();
    }
  for (double s : row_sum) require(std::abs(s - 1) <= 1e-9, path, "a row of P does not sum to 1");
  if (covered)
    for (std::size_t i = 0; i < n; ++i) {
      int weighted = 0;
      for (double b : map[i].bary) weighted += b > 0 ? 1 : 0;
      require(corners_seen[i] == weighted, path, "a map point weighs a coarse vertex its row of P does not");
    }
  return map;
}

// A value of `mesh` stored beside a mapped space, under a key of `kind` made from the space's
// (`space_key`; null, or a store that is off: made and not stored) and the mesh's arrays (a coarse
// space may be handed another mesh of the same faces and count: the value is that mesh's): loaded when
// there and whole (`parse`), else made (`make`) and saved (`put` writes its arrays). Its use is added
// to `cache` when given: its key and times, and a damaged entry (status rebuilt, the damage appended).
template <class T, class Parse, class Make, class Put>
T stored_beside(const TriangleMesh& mesh, const Store& store, const char* kind, const StoreKey* space_key, CacheReport* cache,
                Parse&& parse, Make&& make, Put&& put) {
  std::optional<StoreKey> key;
  if (store.enabled() && space_key) {
    KeyHasher h(kind);
    key = h.add(*space_key).add_matrix(mesh.V).add_matrix(mesh.F).finish();
    CacheReport attempt;
    std::optional<detail::Stored<T>> hit = detail::load_entry<detail::Stored<T>>(
        store, kind, *key, attempt, [&](const EntryReader& entry, const std::string& path) { return detail::Stored<T>{parse(entry, path), {}}; });
    if (hit) {
      if (cache) {
        cache->keys.push_back(key->hex());
        cache->load_seconds += hit->cache.load_seconds;
      }
      return std::move(hit->value);
    }
    if (cache) {
      cache->load_seconds += attempt.load_seconds;
      if (attempt.status == CacheStatus::rebuilt) {
        cache->status = CacheStatus::rebuilt;
        cache->damage += (cache->damage.empty() ? "" : "; ") + attempt.damage;
      }
    }
  }
  T value = make();
  if (key) {
    const auto start = std::chrono::steady_clock::now();
    EntryWriter writer;
    put(writer, value);
    CacheReport saved;
    detail::save_entry(store, kind, *key, writer, saved, start);
    if (cache) {
      cache->keys.push_back(key->hex());
      cache->save_seconds += saved.save_seconds;
      if (!saved.save_error.empty()) cache->save_error = saved.save_error;
    }
  }
  return value;
}

}  // namespace

StoreKey mapped_space_key(const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening) {
  KeyHasher h(kSpaceKind);
  detail::add_mesh_and_coarsening(h, mesh, coarsening);
  return h.finish();
}

MappedSpace build_mapped_space(const TriangleMesh& mesh, const MappedSpaceOptions& options, FineMesh* fine_delaunay) {
  const CoarseSpaceOptions& coarsening = options.coarsening;
  // QEM's intrinsic Delaunay geometry: its closest-point map lies in the QEM mesh's faces, not in the
  // coarse mesh's: no map, and so not stored (what needs only the coarse mesh and P still works).
  const bool has_map = !(coarsening.method == CoarseningMethod::qem && coarsening.qem_geometry == QemGeometry::intrinsic_delaunay);
  const bool covered = solved_on_tufted_cover(mesh, coarsening.nonmanifold);
  MappedSpace result;
  const bool stored = has_map && options.store.enabled() && !coarsening.keep_method_state && !coarsening.record_history;
  if (stored) {
    result.key = mapped_space_key(mesh, coarsening);
    std::optional<MappedSpace> hit = detail::load_entry<MappedSpace>(
        options.store, kSpaceKind, *result.key, result.cache, [&](const EntryReader& entry, const std::string& path) {
          MappedSpace space;
          space.coarse = detail::coarse_space_from_entry(entry, path, mesh);
          space.map = map_from_entry(entry, path, space.coarse, covered);
          return space;
        });
    if (hit) {
      hit->key = result.key;
      return std::move(*hit);
    }
  }
  CoarseSpaceOptions build = coarsening;
  build.keep_method_state = has_map;  // the map is read from it
  build.nonmanifold = covered ? NonmanifoldInput::tufted_cover : NonmanifoldInput::refuse;  // decided above
  result.coarse = options.builder ? options.builder(mesh, build, fine_delaunay) : build_coarse_space(mesh, build, fine_delaunay);
  if (has_map) result.map = fine_to_coarse_map(result.coarse);
  if (!coarsening.keep_method_state) {
    result.coarse.triangulation.reset();
    result.coarse.triangulation_order = {};
    result.coarse.triangulation_face_order = {};
    result.coarse.mapped_copy = {};
    result.coarse.qem_result.reset();
  }
  // A coarsening cancelled by its progress callback is not the space its key names: never stored,
  // and nothing is stored beside it.
  if (result.coarse.summary.stop_reason() == StopReason::Cancelled) result.key.reset();
  if (stored && result.key) {
    const auto start = std::chrono::steady_clock::now();
    const SpaceEntry entry(result.coarse, result.map);
    detail::save_entry(options.store, kSpaceKind, *result.key, entry.writer, result.cache, start);
  }
  return result;
}

void save_mapped_space_file(const std::filesystem::path& path, const TriangleMesh& mesh, const CoarseSpace& coarse,
                            const std::vector<CoarsePoint>& map, bool overwrite) {
  if (coarse.P.rows() != mesh.V.rows() || map.size() != static_cast<std::size_t>(mesh.V.rows()))
    throw std::invalid_argument("save_mapped_space_file: the coarse space and map are not of this mesh of " +
                                std::to_string(mesh.V.rows()) + " vertices");
  require_writable(path.string(), overwrite);
  const SpaceEntry entry(coarse, map);
  write_entry_file(path, kSpaceKind, detail::file_key(kSpaceKind, mesh), entry.writer);
}

MappedSpace load_mapped_space_file(const std::filesystem::path& path, const TriangleMesh& mesh) {
  const auto start = std::chrono::steady_clock::now();
  const EntryReader entry = detail::read_file_for(path, kSpaceKind, mesh);
  MappedSpace space;
  space.coarse = detail::coarse_space_from_entry(entry, path.string(), mesh);
  // A mesh that needs the cover can only have been coarsened through it (and one that does not, not).
  space.map = map_from_entry(entry, path.string(), space.coarse, needs_tufted_cover(mesh));
  space.cache.load_seconds = seconds_since(start);
  return space;
}

SurfaceEdgeLengths traced_edge_lengths(const TriangleMesh& mesh, const MappedSpace& space, const Store& store,
                                       CacheReport* cache) {
  return traced_edge_lengths(mesh, space.coarse, space.map, space.key ? &*space.key : nullptr, store, cache);
}

SurfaceEdgeLengths traced_edge_lengths(const TriangleMesh& mesh, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                       const StoreKey* space_key, const Store& store, CacheReport* cache) {
  const Eigen::Index faces = coarse.mesh.F.rows();
  return stored_beside<SurfaceEdgeLengths>(
      mesh, store, kTracedKind, space_key, cache,
      [&](const EntryReader& entry, const std::string& path) {
        SurfaceEdgeLengths stored;
        stored.lengths = entry.double_matrix("lengths");
        require(stored.lengths.rows() == faces && stored.lengths.cols() == 3, path, "traced lengths of the wrong shape");
        require((stored.lengths.array() > 0).all() && stored.lengths.allFinite(), path, "a traced length is not positive and finite");
        const std::int64_t edges = entry.integer("edges"), traced = entry.integer("traced");
        require(edges >= 0 && edges <= 3 * faces && traced >= 0 && traced <= edges, path, "traced edge counts out of range");
        stored.edges = static_cast<Index>(edges);
        stored.traced = static_cast<Index>(traced);
        return stored;
      },
      [&] { return surface_edge_lengths(mesh, coarse.mesh, map, coarse.inserted); },
      [](EntryWriter& writer, const SurfaceEdgeLengths& lengths) {
        writer.put_matrix("lengths", lengths.lengths);
        writer.put_int("edges", lengths.edges);
        writer.put_int("traced", lengths.traced);
      });
}

fem::CoarseCurvature gathered_curvature(const TriangleMesh& mesh, const CoarseSpace& coarse, const StoreKey* space_key,
                                        const Store& store, CacheReport* cache) {
  const Eigen::Index vertices = coarse.P.cols();
  return stored_beside<fem::CoarseCurvature>(
      mesh, store, kCurvatureKind, space_key, cache,
      [&](const EntryReader& entry, const std::string& path) {
        const std::vector<double> curvature = entry.doubles("curvature"), area = entry.doubles("area");
        require(static_cast<Eigen::Index>(curvature.size()) == vertices && static_cast<Eigen::Index>(area.size()) == vertices,
                path, "gathered curvature of the wrong size");
        for (std::size_t v = 0; v < area.size(); ++v)
          require(std::isfinite(curvature[v]) && std::isfinite(area[v]) && area[v] >= 0, path,
                  "a gathered curvature or area is not finite (or an area negative)");
        fem::CoarseCurvature stored;
        stored.curvature = Eigen::Map<const Eigen::VectorXd>(curvature.data(), vertices);
        stored.area = Eigen::Map<const Eigen::VectorXd>(area.data(), vertices);
        return stored;
      },
      [&] { return fem::coarse_curvature(intrinsic_mesh(mesh), coarse.P); },
      [](EntryWriter& writer, const fem::CoarseCurvature& gathered) {
        writer.put("curvature", gathered.curvature.data(), static_cast<std::size_t>(gathered.curvature.size()));
        writer.put("area", gathered.area.data(), static_cast<std::size_t>(gathered.area.size()));
      });
}

SurfaceEdgeLengths stored_marching_lengths(const TriangleMesh& mesh, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                           const StoreKey* space_key, const Store& store, bool traced,
                                           CurvatureCorrection correction, double divisor, CacheReport* cache) {
  SurfaceEdgeLengths lengths =
      traced ? traced_edge_lengths(mesh, coarse, map, space_key, store, cache) : SurfaceEdgeLengths{coarse.mesh.L, 0, 0};
  if (corrects_curvature(correction, coarse.summary.method, coarse.summary.tufted_cover))
    lengths.lengths = fem::curvature_corrected_lengths(with_lengths(coarse.mesh, lengths.lengths),
                                                       gathered_curvature(mesh, coarse, space_key, store, cache), divisor);
  return lengths;
}

SurfaceEdgeLengths stored_marching_lengths(const TriangleMesh& mesh, const MappedSpace& space, const Store& store, bool traced,
                                           CurvatureCorrection correction, double divisor, CacheReport* cache) {
  return stored_marching_lengths(mesh, space.coarse, space.map, space.key ? &*space.key : nullptr, store, traced, correction,
                                 divisor, cache);
}

}  // namespace ice::proxy
