// ice._ice: the Python bindings of libice and libfem. Every function converts and checks its
// arguments (arrays.h), releases the GIL, calls the library's pipeline (ice::build_coarse_space,
// ice::fine_mesh, fem::CoarseProxy and the proxy solvers, fem::MultigridSolver, fem::DistanceOracle)
// and converts the results back; reports are the tools' JSON objects (ice/proxy/report.h) as dicts, so a
// script and a tool report the same keys. The package's __init__.py re-exports everything with the
// documentation; nothing here computes anything the C++ tools do not.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/complex.h>
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "ice/proxy/policies.h"
#include "ice/proxy/report.h"
#include "ice/proxy/setup.h"
#include "arrays.h"
#include "fem/coarse_proxy.h"
#include "fem/distance_oracle.h"
#include "fem/multigrid.h"
#include "fem/operators.h"
#include "fem/problems.h"
#include "fem/vector_fields.h"
#include "ice/coarse_space.h"
#include "ice/coarse_tracing.h"
#include "ice/hierarchy.h"
#include "fem/topology.h"
#include "ice/proxy/eigen.h"
#include "ice/proxy/geodesics.h"
#include "ice/proxy/multigrid.h"
#include "ice/proxy/vectors.h"
#include "ice/intrinsic_mesh_io.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "ice/point_cloud.h"
#include "ice/refinement.h"

namespace py = pybind11;
using namespace ice_python;

namespace {

// ---- small conversions ---------------------------------------------------------------------------

py::object json_to_python(const nlohmann::json& value) {
  return py::module_::import("json").attr("loads")(value.dump());
}

template <class Enum>
Enum choice(const std::string& value, const char* name, std::initializer_list<std::pair<const char*, Enum>> choices) {
  std::string names;
  for (const auto& [spelling, entry] : choices) {
    if (value == spelling) return entry;
    names += (names.empty() ? "" : ", ") + std::string("'") + spelling + "'";
  }
  throw py::value_error(std::string(name) + " must be one of " + names + ", got '" + value + "'");
}
/// The same for an enum of the recipe floor, by its spellings (ice/proxy/policies.h).
template <class Enum>
Enum choice(const std::string& value, const char* name) {
  for (const auto& [spelling, entry] : ice::proxy::spellings<Enum>())
    if (value == spelling) return entry;
  throw py::value_error(std::string(name) + " must be one of " + ice::proxy::choices<Enum>() + ", got '" + value + "'");
}

/// "marching" or "heat": the coarse distances of ProxyGeodesicSolver and DistanceOracle.
fem::CoarseDistanceMethod coarse_distance_method(const std::string& method) {
  return choice<fem::CoarseDistanceMethod>(
      method, "method");
}

// Python numbers for keyword options, refused with the option's name when of another type (a
// float where a count is meant, a string where a number is meant).
long long integer_option(const py::handle& value, const char* name) {
  if (PyBool_Check(value.ptr()) || !PyIndex_Check(value.ptr()))
    throw py::type_error(std::string(name) + " must be an integer, got " + py::str(py::type::of(value)).cast<std::string>());
  const py::int_ number = py::reinterpret_steal<py::int_>(PyNumber_Index(value.ptr()));
  long long result = 0;
  try {
    result = number.cast<long long>();
  } catch (const py::cast_error&) {
    throw py::value_error(std::string(name) + " = " + py::str(py::handle(number)).cast<std::string>() + " is out of range");
  }
  return result;
}
double number_option(const py::handle& value, const char* name) {
  if (PyBool_Check(value.ptr()) || !(PyFloat_Check(value.ptr()) || PyIndex_Check(value.ptr()) ||
                                     py::isinstance(value, py::module_::import("numbers").attr("Real"))))
    throw py::type_error(std::string(name) + " must be a number, got " + py::str(py::type::of(value)).cast<std::string>());
  return value.cast<double>();
}
/// An integer option in [low, high], as the tools' integer_between.
int bounded_integer(const py::handle& value, const char* name, long long low, long long high) {
  const long long number = integer_option(value, name);
  if (number < low || number > high)
    throw py::value_error(std::string(name) + " = " + std::to_string(number) + " is out of range (valid " +
                          std::to_string(low) + ".." + std::to_string(high) + ")");
  return static_cast<int>(number);
}

ice::TriangleMesh mesh_argument(const py::handle& V, const py::handle& F) {
  ice::TriangleMesh mesh;
  mesh.V = positions_argument(V, "V");
  mesh.F = faces_argument(F, mesh.V.rows(), "F");
  return mesh;
}

// The fine discretisation of an operator call: (V, F), or (F, lengths) for an intrinsic mesh.
ice::IntrinsicMesh discretisation_argument(const py::object& V, const py::object& F, const py::object& lengths,
                                           const py::object& n) {
  ice::IntrinsicMesh d;
  if (!V.is_none() && !lengths.is_none()) throw py::value_error("give V or lengths, not both");
  if (V.is_none() && lengths.is_none()) throw py::value_error("give V (positions) or lengths (per-face edge lengths)");
  if (!V.is_none()) {
    const ice::TriangleMesh mesh = mesh_argument(V, F);
    d.F = mesh.F;
    d.L = ice::face_lengths_from_positions(mesh.V, mesh.F);
    d.vertex_count = static_cast<ice::Index>(mesh.V.rows());
    for (Eigen::Index f = 0; f < d.F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        if (!(d.L(f, k) < d.L(f, (k + 1) % 3) + d.L(f, (k + 2) % 3)))
          throw py::value_error("F[" + std::to_string(f) + "] is a degenerate (zero-area) triangle of V");
  } else {
    d.F = faces_argument(F, "F");
    d.L = lengths_argument(lengths, d.F.rows(), "lengths");
    d.vertex_count = d.F.maxCoeff() + 1;
  }
  if (!n.is_none()) {
    const auto count = integer_option(n, "n");
    if (count < d.vertex_count)
      throw py::value_error("n = " + std::to_string(count) + " is smaller than the vertex count F uses (" +
                            std::to_string(d.vertex_count) + ")");
    if (count > std::numeric_limits<ice::Index>::max()) throw py::value_error("n = " + std::to_string(count) + " is too large");
    d.vertex_count = static_cast<ice::Index>(count);
  }
  return d;
}

// ---- meshes --------------------------------------------------------------------------------------

// Validation of arrays, once per mesh content. Scripts pass the same (V, F) to coarsen, Proxy,
// hierarchy, ...; validating it each time cost 0.23 s per call at 104k vertices (18 % on top of
// coarsening and proxy setup, measured with bench/python_overhead.py), hashing it costs ~2 ms. The
// fingerprints of the last meshes found clean (or loaded from a file, which the loader validated)
// are kept; a mesh is validated again whenever its content differs in any byte (a collision of the
// 64-bit hash is the only way to skip a needed validation).
std::uint64_t hash_bytes(const void* data, std::size_t bytes, std::uint64_t hash) {
  const auto mix = [&hash](std::uint64_t word) {
    hash ^= word + 0x9e3779b97f4a7c15ull + (hash << 6) + (hash >> 2);
    hash *= 0xff51afd7ed558ccdull;
    hash ^= hash >> 33;
  };
  const auto* bytes_in = static_cast<const unsigned char*>(data);
  std::size_t i = 0;
  for (; i + 8 <= bytes; i += 8) {
    std::uint64_t word;
    std::memcpy(&word, bytes_in + i, 8);
    mix(word);
  }
  std::uint64_t tail = 0;
  std::memcpy(&tail, bytes_in + i, bytes - i);
  mix(tail ^ (static_cast<std::uint64_t>(bytes) << 56));
  return hash;
}
std::uint64_t faces_fingerprint(const ice::Faces& F) {
  return hash_bytes(F.data(), static_cast<std::size_t>(F.size()) * sizeof(int), 0x9e3779b97f4a7c15ull ^ static_cast<std::uint64_t>(F.rows()));
}
std::uint64_t mesh_fingerprint(const ice::TriangleMesh& mesh) {
  return hash_bytes(mesh.V.data(), static_cast<std::size_t>(mesh.V.size()) * sizeof(double),
                    faces_fingerprint(mesh.F) ^ (static_cast<std::uint64_t>(mesh.V.rows()) << 32));
}

class CleanMeshes {
 public:
  bool contains(std::uint64_t fingerprint) {
    const std::lock_guard<std::mutex> lock(mutex_);
    return std::find(recent_.begin(), recent_.end(), fingerprint) != recent_.end();
  }
  void add(std::uint64_t fingerprint) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (std::find(recent_.begin(), recent_.end(), fingerprint) != recent_.end()) return;
    if (recent_.size() == kKept) recent_.pop_front();
    recent_.push_back(fingerprint);
  }

 private:
  static constexpr std::size_t kKept = 32;
  std::mutex mutex_;
  std::deque<std::uint64_t> recent_;
};
CleanMeshes& clean_meshes() {
  static CleanMeshes meshes;
  return meshes;
}

/// ice::require_clean_mesh for arrays, skipped for a mesh already found clean. No GIL needed.
/// With `cover` (nonmanifold="tufted"): also a mesh whose only defects are the sheets the tufted cover
/// takes (non-manifold, inconsistently oriented, non-orientable).
void require_clean(const ice::TriangleMesh& mesh, ice::NonmanifoldInput cover = ice::NonmanifoldInput::refuse) {
  const std::uint64_t fingerprint = mesh_fingerprint(mesh);
  if (clean_meshes().contains(fingerprint)) return;
  if (cover == ice::NonmanifoldInput::tufted_cover) {
    const ice::ValidationReport report = ice::validate_mesh(mesh);
    if (report.clean_but_for_sheets()) return;
  }
  ice::require_clean_mesh(mesh, "(V, F)");
  clean_meshes().add(fingerprint);
}

py::dict load_mesh(const std::filesystem::path& file_path, bool repair, bool weld, const std::string& nonmanifold,
                   int neighbours, bool separate_thin_parts) {
  const std::string path = file_path.string();
  ice::LoadOptions options;
  options.repair = repair;
  options.weld_duplicate_positions = weld;
  options.keep_nonmanifold = choice<ice::NonmanifoldInput>(nonmanifold, "nonmanifold") == ice::NonmanifoldInput::tufted_cover;
  if (neighbours < 2) throw py::value_error("neighbours must be at least 2");
  options.point_cloud.neighbours = neighbours;
  options.point_cloud.separate_thin_parts = separate_thin_parts;
  if (weld && !repair) throw py::value_error("weld=True goes with repair=True");
  ice::LoadResult loaded;
  {
    py::gil_scoped_release release;
    loaded = ice::load_mesh_with_report(path, options);
    if (loaded.report.clean()) clean_meshes().add(mesh_fingerprint(loaded.mesh));  // the loader validated it
  }
  py::dict result;
  result["V"] = py::cast(std::move(loaded.mesh.V));
  result["F"] = py::cast(std::move(loaded.mesh.F));
  result["report"] = json_to_python(ice::proxy::validation_json(loaded.report));
  result["input_report"] = json_to_python(ice::proxy::validation_json(loaded.input_report));
  result["repairs"] = loaded.repairs.summary();
  result["source_vertex"] = to_numpy(std::move(loaded.source_vertex));
  result["source_face"] = to_numpy(std::move(loaded.source_face));
  result["format"] = loaded.file.format;
  result["point_cloud"] = loaded.point_cloud;
  return result;
}

py::object validate(const py::object& V, const py::object& F) {
  const ice::TriangleMesh mesh = mesh_argument(V, F);
  ice::ValidationReport report;
  {
    py::gil_scoped_release release;
    report = ice::validate_mesh(mesh);
    if (report.clean()) clean_meshes().add(mesh_fingerprint(mesh));
  }
  return json_to_python(ice::proxy::validation_json(report));
}

void save_mesh(const std::filesystem::path& path, const py::object& V, const py::object& F, bool overwrite, bool binary) {
  const ice::TriangleMesh mesh = mesh_argument(V, F);
  py::gil_scoped_release release;
  ice::write_mesh(path.string(), mesh, {overwrite, binary});
}

// ---- the coarse space ----------------------------------------------------------------------------

/// A coarse space as Python sees it: the library's CoarseSpace, the fine-to-coarse map (computed
/// while the method's state exists, which is then freed), and the coarse vertices' positions.
struct PyCoarseSpace {
  ice::CoarseSpace space;
  std::vector<ice::CoarsePoint> map;   ///< empty when loaded from a file or not kept
  /// With trace=True: the coarse edges traced exactly on the input surface, and their polylines.
  std::optional<ice::CoarseTracing> tracing;
  std::vector<ice::Positions> traced_polylines;
  ice::Positions positions;            ///< empty when loaded from a file
  ice::Index input_vertices = 0;
  bool has_space = false;              ///< built here (P, summary), not read from a file
  std::uint64_t faces_fingerprint = 0; ///< of the input's F, which a Proxy must be built on
  /// P row by row, made on first access of .P, viewed (read-only) by the scipy matrix it returns.
  std::optional<Eigen::SparseMatrix<double, Eigen::RowMajor, int>> P_rows;
  /// The store it went through (ice.coarsen's cache) and its key there, under which its traced lengths
  /// are stored too; where it came from (CoarseSpace.cache).
  ice::proxy::Store store;
  std::optional<ice::proxy::StoreKey> store_key;
  nlohmann::json cache = {{"status", "off"}};
};

// Calls a Python progress callback from the coarsener (on the calling thread, GIL released): with
// the GIL, as a dict; Ctrl-C or an exception in the callback cancels, and is raised afterwards.
struct ProgressBridge {
  py::object callback;
  std::exception_ptr error;  ///< raised by the caller once the coarsener has returned
  bool operator()(const ice::CoarsenProgress& progress) {
    py::gil_scoped_acquire acquire;
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (callback.is_none()) return true;
      py::dict state;
      state["vertices"] = progress.vertices;
      state["target"] = progress.target;
      state["removed"] = progress.removed;
      state["last_cost"] = progress.last_cost;
      const py::object answer = callback(state);
      if (answer.is_none()) return true;
      const int truth = PyObject_IsTrue(answer.ptr());  // Python's own truth (an array's may raise)
      if (truth < 0) throw py::error_already_set();
      return truth != 0;
    } catch (...) {  // nothing may cross the coarsener: stop it, raise afterwards
      error = std::current_exception();
      return false;
    }
  }
};

// The coarsening options of ice.coarsen's keyword arguments (checked) for `mesh`.
ice::CoarseSpaceOptions coarse_space_options(const ice::TriangleMesh& mesh, const py::object& n, const py::object& ratio,
                                             const py::object& min_vertices, const py::object& max_error,
                                             const std::string& method, const std::string& use, const py::object& area_weight,
                                             const py::object& normalize_curvature, const py::object& locked,
                                             bool remove_boundary, const py::object& threads, const py::object& regions,
                                             const std::string& qem_geometry, const py::object& refine_angle,
                                             double refine_budget, bool locality_numbering, const std::string& nonmanifold) {
  const auto vertex_count = static_cast<long long>(mesh.V.rows());
  ice::CoarseSpaceOptions options;
  options.nonmanifold = choice<ice::NonmanifoldInput>(nonmanifold, "nonmanifold");
  options.method = choice<ice::CoarseningMethod>(method, "method");
  options.coarsen = ice::recommended_coarsen_options(
      choice<ice::ProxyUse>(use, "use"));
  options.qem_geometry = choice<ice::QemGeometry>(
      qem_geometry, "qem_geometry");
  ice::CoarsenOptions& c = options.coarsen;
  if (!n.is_none() && !ratio.is_none()) throw py::value_error("give n or ratio, not both");
  if (n.is_none() && ratio.is_none() && max_error.is_none())
    throw py::value_error("say how far to coarsen: n=N vertices, ratio=R (e.g. 0.05) or max_error=E");
  if (!n.is_none()) {
    const auto target = integer_option(n, "n");
    if (target < 1 || target > vertex_count)
      throw py::value_error("n = " + std::to_string(target) + " is out of range: the mesh has " +
                            std::to_string(vertex_count) + " vertices (valid 1.." + std::to_string(vertex_count) + ")");
    c.target_vertices = static_cast<ice::Index>(target);
  }
  if (!ratio.is_none()) {
    c.target_ratio = number_option(ratio, "ratio");
    if (!(c.target_ratio > 0 && c.target_ratio <= 1))
      throw py::value_error("ratio = " + std::to_string(c.target_ratio) + " is out of range: it must be in (0, 1], e.g. 0.05");
  }
  if (!min_vertices.is_none()) {  // the tools' --min-vertices: the same rounding (ice::proxy::target_vertices)
    const auto floor = integer_option(min_vertices, "min_vertices");
    if (ratio.is_none()) throw py::value_error("min_vertices goes with ratio");
    if (floor < 1) throw py::value_error("min_vertices must be >= 1");
    c.target_vertices = ice::proxy::target_vertices(static_cast<ice::Index>(vertex_count), c.target_ratio,
                                                    static_cast<ice::Index>(std::min<long long>(floor, vertex_count)));
  }
  if (!max_error.is_none()) {
    c.max_error = number_option(max_error, "max_error");
    if (!(c.max_error >= 0)) throw py::value_error("max_error must be a number >= 0");
  }
  if (!area_weight.is_none()) {
    c.area_weight = number_option(area_weight, "area_weight");
    if (!(c.area_weight >= 0 && c.area_weight <= 1)) throw py::value_error("area_weight must be in [0, 1]");
  }
  if (!normalize_curvature.is_none()) c.normalize_curvature = normalize_curvature.cast<bool>();
  if (!locked.is_none()) c.locked_vertices = index_argument(locked, mesh.V.rows(), "locked");
  c.remove_boundary = remove_boundary;
  c.threads = bounded_integer(threads, "threads", 0, 64);  // the tools' --coarsen-threads range
  c.regions = bounded_integer(regions, "regions", 0, 254);  // --coarsen-regions
  // refine_angle: None or 0 = no refinement (as --refine-angle 0), else (0, 30] degrees.
  const double angle = refine_angle.is_none() ? 0.0 : number_option(refine_angle, "refine_angle");
  if (!(angle >= 0 && angle <= 30))
    throw py::value_error("refine_angle = " + std::to_string(angle) + " is out of range: degrees in (0, 30], or 0 for none");
  if (!(refine_budget >= 1 && refine_budget <= 1e6))
    throw py::value_error("refine_budget = " + std::to_string(refine_budget) + " is out of range: [1, 1e6]");
  if (angle > 0) {
    ice::RefinementOptions refinement;
    refinement.min_angle_degrees = angle;
    refinement.max_vertex_ratio = refine_budget;
    options.refinement = refinement;
  }
  options.locality_numbering = locality_numbering;
  return options;
}

ice::proxy::Store store_argument(const py::object& cache);

std::shared_ptr<PyCoarseSpace> coarsen(const py::object& V, const py::object& F, const py::object& n,
                                       const py::object& ratio, const py::object& min_vertices, const py::object& max_error, const std::string& method,
                                       const std::string& use, const py::object& area_weight,
                                       const py::object& normalize_curvature, const py::object& locked,
                                       bool remove_boundary, const py::object& threads, const py::object& regions,
                                       const std::string& qem_geometry,
                                       const py::object& refine_angle, double refine_budget, bool keep_map,
                                       bool locality_numbering, bool trace, const py::object& progress,
                                       const std::string& nonmanifold, const py::object& cache) {
  const ice::TriangleMesh mesh = mesh_argument(V, F);
  ice::CoarseSpaceOptions options =
      coarse_space_options(mesh, n, ratio, min_vertices, max_error, method, use, area_weight, normalize_curvature, locked,
                           remove_boundary, threads, regions, qem_geometry, refine_angle, refine_budget, locality_numbering,
                           nonmanifold);
  ice::CoarsenOptions& c = options.coarsen;
  if (trace && options.method != ice::CoarseningMethod::ice)
    throw py::value_error("trace=True draws ICE's intrinsic coarse edges on the surface; a QEM mesh has straight edges (method='ice')");
  // Through a cover: no tracing (the coarse edges lie on the cover's sheets, not on the input's
  // faces); decided here, before the work. Its map places each vertex by one of its copies.
  const bool covered = ice::solved_on_tufted_cover(mesh, options.nonmanifold);
  if (trace && covered) throw py::value_error("trace=True does not take a tufted cover (nonmanifold='tufted') yet");
  options.keep_method_state = keep_map || trace;
  options.record_history = trace;  // exact tracing (ice/coarse_tracing.h), made below before the history is freed
  ProgressBridge bridge{progress, nullptr};
  c.progress = [&bridge](const ice::CoarsenProgress& state) { return bridge(state); };
  const bool has_map = !(options.method == ice::CoarseningMethod::qem && options.qem_geometry == ice::QemGeometry::intrinsic_delaunay);
  // Through the store: a space with a map (not QEM's intrinsic Delaunay one), without the history of
  // trace=True, which is not stored.
  const ice::proxy::Store store = has_map && !trace ? store_argument(cache) : ice::proxy::Store();

  auto result = std::make_shared<PyCoarseSpace>();
  result->input_vertices = static_cast<ice::Index>(mesh.V.rows());
  std::optional<ice::proxy::MappedSpace> mapped;
  {
    py::gil_scoped_release release;
    require_clean(mesh, options.nonmanifold);
    if (store.enabled()) {
      ice::proxy::MappedSpaceOptions mapped_options;
      mapped_options.coarsening = options;
      mapped_options.coarsening.keep_method_state = false;  // the map comes with the space
      mapped_options.store = store;
      mapped.emplace(ice::proxy::build_mapped_space(mesh, mapped_options));
      result->space = std::move(mapped->coarse);
    } else {
      result->space = ice::build_coarse_space(mesh, options);
    }
  }
  if (bridge.error) std::rethrow_exception(bridge.error);
  if (mapped) {
    result->store = store;
    result->store_key = mapped->key;
    result->cache = ice::proxy::cache_json(mapped->cache, store);
    result->cache["load_seconds"] = mapped->cache.load_seconds;
    result->cache["save_seconds"] = mapped->cache.save_seconds;
    if (mapped->cache.status == ice::proxy::CacheStatus::rebuilt &&
        PyErr_WarnEx(PyExc_RuntimeWarning, ("ice.coarsen: the stored coarse space was damaged and is rebuilt: " + mapped->cache.damage).c_str(), 1) < 0)
      throw py::error_already_set();  // warnings turned into errors
  }
  {
    py::gil_scoped_release release;
    if (mapped && keep_map)
      result->map = std::move(mapped->map);
    else if (keep_map && has_map)
      result->map = ice::fine_to_coarse_map(result->space);
    if (trace) {
      result->tracing = ice::trace_coarse_mesh(mesh, result->space, c.threads);
      for (const ice::TracedEdge& edge : result->tracing->edges)
        result->traced_polylines.push_back(ice::traced_polyline(mesh.V, mesh.F, edge));
    }
    result->space.triangulation.reset();  // the map (and the tracing) made: free the method's state
    result->space.triangulation_order = {};
    result->space.mapped_copy = {};
    result->space.qem_result.reset();
    result->positions = ice::coarse_vertex_positions(mesh, result->space);
  }
  result->has_space = true;
  result->faces_fingerprint = faces_fingerprint(mesh.F);
  return result;
}

std::shared_ptr<PyCoarseSpace> load_coarse_mesh(const std::filesystem::path& file_path) {
  const std::string path = file_path.string();
  ice::IntrinsicMeshFile file;
  {
    py::gil_scoped_release release;
    file = ice::read_intrinsic_mesh(path);
    ice::triangulation_of(file, path);  // refuses files whose faces do not form a triangulation
  }
  auto result = std::make_shared<PyCoarseSpace>();
  ice::CompactMesh& mesh = result->space.mesh;
  mesh.F = std::move(file.F);
  mesh.L = std::move(file.L);
  mesh.twin = std::move(file.twin);
  mesh.to_input = std::move(file.to_input);
  mesh.vertex_count = file.vertex_count;
  mesh.from_input.assign(static_cast<std::size_t>(file.input_vertices), ice::kInvalid);
  for (std::size_t c = 0; c < mesh.to_input.size(); ++c)
    if (mesh.to_input[c] != ice::kInvalid) mesh.from_input[static_cast<std::size_t>(mesh.to_input[c])] = static_cast<ice::Index>(c);
  result->input_vertices = file.input_vertices;
  return result;
}

py::object coarse_map(const PyCoarseSpace& space) {
  if (space.map.empty()) return py::none();
  const auto n = static_cast<py::ssize_t>(space.map.size());
  py::array_t<ice::Index> coarse_vertex(n), face(n);
  py::array_t<double> bary({n, py::ssize_t{3}});
  auto cv = coarse_vertex.mutable_unchecked<1>();
  auto fc = face.mutable_unchecked<1>();
  auto b = bary.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const ice::CoarsePoint& p = space.map[static_cast<std::size_t>(i)];
    cv(i) = p.coarse_vertex;
    fc(i) = p.face;
    for (int k = 0; k < 3; ++k) b(i, k) = p.bary[static_cast<std::size_t>(k)];
  }
  return py::make_tuple(face, bary, coarse_vertex);
}

py::object coarse_summary(const PyCoarseSpace& space) {
  if (!space.has_space) return py::none();
  const ice::CoarseSpaceSummary& s = space.space.summary;
  nlohmann::json summary = ice::proxy::coarsen_json(s);
  summary["method"] = ice::to_string(s.method);
  summary["input_vertices"] = s.input_vertices;
  summary["target_reached"] = s.target_reached;
  summary["seconds"] = s.seconds;
  if (s.qem) summary["qem"] = ice::proxy::qem_json(*s.qem, s.target_reached);
  return json_to_python(summary);
}

py::object prolongation(const py::object& self) {
  PyCoarseSpace& space = self.cast<PyCoarseSpace&>();
  if (!space.has_space) return py::none();
  if (!space.P_rows) {
    space.P_rows.emplace(space.space.P);
    space.P_rows->makeCompressed();
  }
  return scipy_view(*space.P_rows, self);
}

/// What does not take a tufted cover's coarse space yet (its coarse vertices have one fan per sheet:
/// tangent spaces and the one-triangulation file need one).
void refuse_cover(bool tufted_cover, const std::string& what) {
  if (tufted_cover)
    throw py::value_error(what + " does not take a tufted cover's coarse space yet (nonmanifold='tufted': Poisson, "
                                 "heat, the eigenbasis, geodesics and the distance oracle do; vector fields on a cover: "
                                 "ice.transport_directions)");
}

void save_coarse_mesh(const PyCoarseSpace& space, const std::filesystem::path& file_path, bool overwrite, const std::string& comment) {
  // Its faces are named by input vertex with the cover's gluing: a vertex can have several fans,
  // which an intrinsic mesh file (one triangulation) cannot be read back as.
  refuse_cover(space.space.summary.tufted_cover, "CoarseSpace.save");
  const std::string path = file_path.string();
  py::gil_scoped_release release;
  ice::require_writable(path, overwrite);
  ice::write_intrinsic_mesh(path, space.space.mesh, space.input_vertices, comment);
}

// ---- the proxy and its solvers -------------------------------------------------------------------

struct PyProxy {
  ice::FineMesh fine;  ///< empty when the proxy came from the store (proxy->fine_mesh() makes it)
  ice::FineGeometry geometry = ice::FineGeometry::intrinsic_delaunay;  ///< of the fine mesh it was assembled on
  std::unique_ptr<fem::CoarseProxy> proxy;
  ice::CoarseningMethod method = ice::CoarseningMethod::ice;  ///< of its coarse space
  bool tufted_cover = false;                                  ///< its coarse space is a tufted cover's
  nlohmann::json cache = {{"status", "off"}};  ///< ice::proxy::cache_json of setup_proxy
};

/// curvature_correction=None|True|False of the geodesic solvers on a coarse space made by `method`:
/// None is geodesic-coarse's --curvature-correction auto (ICE's coarse spaces only, as measured).
ice::proxy::CurvatureCorrection curvature_correction_choice(const py::object& value) {
  if (!value.is_none() && !py::isinstance<py::bool_>(value))
    throw py::type_error("curvature_correction must be None, True or False");
  return value.is_none() ? ice::proxy::CurvatureCorrection::automatic
         : value.cast<bool>() ? ice::proxy::CurvatureCorrection::on
                              : ice::proxy::CurvatureCorrection::off;
}

bool curvature_correction_argument(const py::object& value, ice::CoarseningMethod method) {
  return ice::proxy::corrects_curvature(curvature_correction_choice(value), method);
}

/// The mesh (V, F), checked to be the one `coarse` was made from (vertex count and faces), with P.
ice::TriangleMesh require_coarse_space_of(const py::object& V, const py::object& F, const PyCoarseSpace& coarse,
                                          const std::string& what) {
  if (!coarse.has_space)
    throw py::value_error("this coarse space was read from a file and has no prolongation: coarsen the mesh to solve through it");
  ice::TriangleMesh mesh = mesh_argument(V, F);
  if (mesh.V.rows() != coarse.space.P.rows() || faces_fingerprint(mesh.F) != coarse.faces_fingerprint)
    throw py::value_error("the coarse space was made from another mesh (" + std::to_string(coarse.space.P.rows()) +
                          " vertices, other faces): build the " + what + " on the (V, F) that was coarsened");
  return mesh;
}

/// Coarse marching's lengths of `coarse` (made from `mesh`) as the tools take them
/// (ice::proxy::marching_lengths with the space's kept map): traced by the walk over the map or intrinsic,
/// then corrected as `correction` says for the space's method.
ice::FaceLengths marching_lengths_argument(const ice::TriangleMesh& mesh, const PyCoarseSpace& coarse, bool traced,
                                           ice::proxy::CurvatureCorrection correction, double divisor = fem::kProxyCorrectionDivisor) {
  if (traced) ice::proxy::refuse_tracing_on_cover(coarse.space.summary.tufted_cover, "lengths='traced'");
  if (traced && (coarse.map.empty() || coarse.space.summary.method != ice::CoarseningMethod::ice))
    throw py::value_error("lengths='traced' needs an ICE coarse space with its fine-to-coarse map (coarsen with keep_map=True)");
  py::gil_scoped_release release;
  // A space that came through the store has its traced lengths and gathered curvature stored beside it
  // (without a key, or with the store off, they are made here).
  return ice::proxy::stored_marching_lengths(mesh, coarse.space, coarse.map, coarse.store_key ? &*coarse.store_key : nullptr,
                                             coarse.store, traced, correction, divisor)
      .lengths;
}

/// lengths="auto"|"intrinsic"|"traced" of the marching entry points: whether to march on traced lengths
/// (auto, the tools' --coarse-lengths auto: an ICE coarse space that has its map; intrinsic otherwise).
/// `marching`: false for the coarse heat method, which takes neither (traced asked then: ValueError).
bool traced_lengths_argument(const std::string& lengths, const PyCoarseSpace& coarse, bool marching = true) {
  const auto asked = choice<ice::proxy::CoarseLengths>(lengths, "lengths");
  if (asked == ice::proxy::CoarseLengths::traced && !marching) throw py::value_error("lengths='traced' is for method='marching'");
  // auto needs the map to trace with (a space read from a file has none: its own lengths then), and
  // an input surface to trace on (a tufted cover's space: its own lengths).
  const bool can_trace = !coarse.map.empty() && !coarse.space.summary.tufted_cover;
  return (asked != ice::proxy::CoarseLengths::automatic || can_trace) &&
         ice::proxy::traces_lengths(asked, coarse.space.summary.method, marching);
}

/// The oracle and the vector proxy need the coarse space's fine-to-coarse map.
void require_map(const PyCoarseSpace& coarse) {
  if (coarse.map.empty())
    throw py::value_error("the coarse space has no fine-to-coarse map (coarsen with keep_map=True, ICE or "
                          "QEM with extrinsic geometry)");
}

/// The distance oracle of `coarse` on lengths L (both DistanceOracle entry points).
std::unique_ptr<fem::DistanceOracle> make_oracle(const PyCoarseSpace& coarse, const ice::FaceLengths& L,
                                                 fem::CoarseDistanceMethod method, double heat_time_factor, int threads,
                                                 int subdivisions) {
  fem::DistanceOracleOptions options;
  options.method = method;
  options.heat_time_factor = heat_time_factor;
  options.threads = threads;
  options.subdivisions = subdivisions;
  py::gil_scoped_release release;
  return std::make_unique<fem::DistanceOracle>(ice::with_lengths(coarse.space.mesh, L), coarse.map, options);
}

// The `fine=` argument of Proxy and VectorHeatSolver: the fine mesh's discretisation.
ice::FineGeometry fine_geometry_argument(const std::string& fine) {
  return choice<ice::FineGeometry>(
      fine, "fine");
}

std::shared_ptr<PyProxy> make_proxy(const py::object& V, const py::object& F, const PyCoarseSpace& coarse,
                                    const std::string& operators, const std::string& fine, const std::string& prolongation) {
  const ice::TriangleMesh mesh = require_coarse_space_of(V, F, coarse, "Proxy");
  const auto kind = choice<fem::CoarseOperatorKind>(
      operators, "operators");
  const ice::FineGeometry geometry = fine_geometry_argument(fine);
  const auto smoothing = choice<fem::ProlongationKind>(
      prolongation, "prolongation");
  if (fem::is_smoothed(smoothing) && kind != fem::CoarseOperatorKind::galerkin)
    throw py::value_error("prolongation='smoothed' needs operators='galerkin'");
  const ice::NonmanifoldInput cover =
      coarse.space.summary.tufted_cover ? ice::NonmanifoldInput::tufted_cover : ice::NonmanifoldInput::refuse;
  ice::proxy::require_galerkin_on_cover(coarse.space.summary.tufted_cover, kind);  // before the fine mesh is made
  auto result = std::make_shared<PyProxy>();
  result->method = coarse.space.summary.method;
  result->tufted_cover = coarse.space.summary.tufted_cover;
  result->geometry = geometry;
  py::gil_scoped_release release;
  require_clean(mesh, cover);
  result->fine = ice::fine_mesh(mesh, geometry, cover);
  // `new` initialised from the returned proxy itself: make_unique would move it, and a CoarseProxy's
  // move copies its sparse matrices (Eigen 3.4 has no sparse move).
  result->proxy.reset(new fem::CoarseProxy(ice::proxy::make_proxy(result->fine, coarse.space, kind, smoothing)));
  return result;
}

// The store of ice.setup_proxy's cache argument: None the default one ($ICE_CACHE, XDG), False none,
// a path that directory.
ice::proxy::Store store_argument(const py::object& cache) {
  if (py::isinstance<py::bool_>(cache)) {
    if (cache.cast<bool>()) throw py::value_error("cache must be None (the default store), False (none) or a directory");
    return {};
  }
  const std::string directory =
      cache.is_none() ? std::string() : py::str(py::module_::import("os").attr("fspath")(cache)).cast<std::string>();
  try {
    return ice::proxy::Store(ice::proxy::default_store_options(directory));
  } catch (const std::invalid_argument& e) {
    throw py::value_error(e.what());
  }
}

// The coarse space and proxy of `setup` (of `mesh`) moved into the Python objects setup_proxy and
// load_setup return (the proxy's cache report is the caller's).
void take_setup(const ice::TriangleMesh& mesh, ice::proxy::ProxySetup& setup, PyCoarseSpace& coarse, PyProxy& proxy) {
  coarse.space = std::move(setup.coarse);
  coarse.positions = ice::coarse_vertex_positions(mesh, coarse.space);
  coarse.input_vertices = static_cast<ice::Index>(mesh.V.rows());
  coarse.has_space = true;
  coarse.faces_fingerprint = faces_fingerprint(mesh.F);
  proxy.fine = std::move(setup.fine);
  proxy.geometry = setup.fine_geometry;
  proxy.proxy = std::move(setup.proxy);
  proxy.method = coarse.space.summary.method;
  proxy.tufted_cover = coarse.space.summary.tufted_cover;
}

py::tuple setup_proxy(const py::object& V, const py::object& F, const std::string& operators, const std::string& fine,
                      const std::string& prolongation, const py::object& fixed, const py::object& cache,
                      const py::object& n, const py::object& ratio, const py::object& min_vertices,
                      const py::object& max_error, const std::string& method, const std::string& use,
                      const py::object& area_weight, const py::object& normalize_curvature, const py::object& locked,
                      bool remove_boundary, const py::object& threads, const py::object& regions,
                      const std::string& qem_geometry, const py::object& refine_angle, double refine_budget,
                      bool locality_numbering, const std::string& nonmanifold) {
  const ice::TriangleMesh mesh = mesh_argument(V, F);
  ice::CoarseSpaceOptions options =
      coarse_space_options(mesh, n, ratio, min_vertices, max_error, method, use, area_weight, normalize_curvature, locked,
                           remove_boundary, threads, regions, qem_geometry, refine_angle, refine_budget, locality_numbering,
                           nonmanifold);
  const ice::NonmanifoldInput cover_choice = options.nonmanifold;
  std::vector<ice::Index> dirichlet;
  if (!fixed.is_none()) dirichlet = index_argument(fixed, mesh.V.rows(), "fixed");
  const auto kind = choice<fem::CoarseOperatorKind>(operators, "operators");
  const ice::FineGeometry geometry = fine_geometry_argument(fine);
  const auto choice_of_p = choice<ice::proxy::Prolongation>(prolongation, "prolongation");
  const ice::proxy::Store store = store_argument(cache);
  auto coarse = std::make_shared<PyCoarseSpace>();
  auto proxy = std::make_shared<PyProxy>();
  {
    py::gil_scoped_release release;
    require_clean(mesh, cover_choice);
    ice::proxy::ProxySetup setup;
    try {
      ice::proxy::ProxySetupOptions setup_options;
      setup_options.coarsening = std::move(options);
      setup_options.locked = dirichlet;
      setup_options.fine = geometry;
      setup_options.operators = kind;
      setup_options.prolongation = choice_of_p;
      setup_options.dirichlet = !dirichlet.empty();
      setup_options.fine_operators = true;
      setup_options.store = store;
      setup = ice::proxy::build_proxy_setup(mesh, setup_options);
    } catch (const std::invalid_argument& e) {
      py::gil_scoped_acquire acquire;
      throw py::value_error(e.what());
    }
    take_setup(mesh, setup, *coarse, *proxy);
    proxy->cache = ice::proxy::cache_json(setup.cache, store);
    proxy->cache["load_seconds"] = setup.cache.load_seconds;
    proxy->cache["save_seconds"] = setup.cache.save_seconds;
  }
  return py::make_tuple(coarse, proxy);
}

// ice.save_setup / ice.load_setup: a setup_proxy result in a file of the user's choosing.
void save_setup(const std::filesystem::path& path, const py::object& V, const py::object& F, const PyCoarseSpace& coarse,
                const PyProxy& proxy, bool overwrite) {
  const ice::TriangleMesh mesh = require_coarse_space_of(V, F, coarse, "setup");
  py::gil_scoped_release release;
  try {
    ice::proxy::save_proxy_setup_file(path, mesh, coarse.space, *proxy.proxy, proxy.geometry, overwrite);
  } catch (const std::invalid_argument& e) {
    py::gil_scoped_acquire acquire;
    throw py::value_error(e.what());
  }
}

// ice.save_coarse_space / ice.load_coarse_space: a coarse space with its map in a file of the user's choosing.
void save_coarse_space(const std::filesystem::path& path, const py::object& V, const py::object& F, const PyCoarseSpace& coarse,
                       bool overwrite) {
  const ice::TriangleMesh mesh = require_coarse_space_of(V, F, coarse, "save_coarse_space");
  if (coarse.map.empty())
    throw py::value_error("save_coarse_space: the coarse space has no fine-to-coarse map (coarsen with keep_map=True; not "
                          "QEM's intrinsic Delaunay space)");
  py::gil_scoped_release release;
  try {
    ice::proxy::save_mapped_space_file(path, mesh, coarse.space, coarse.map, overwrite);
  } catch (const std::invalid_argument& e) {
    py::gil_scoped_acquire acquire;
    throw py::value_error(e.what());
  }
}

std::shared_ptr<PyCoarseSpace> load_coarse_space(const std::filesystem::path& path, const py::object& V, const py::object& F) {
  const ice::TriangleMesh mesh = mesh_argument(V, F);
  auto result = std::make_shared<PyCoarseSpace>();
  py::gil_scoped_release release;
  ice::proxy::MappedSpace space = ice::proxy::load_mapped_space_file(path, mesh);
  result->space = std::move(space.coarse);
  result->map = std::move(space.map);
  result->positions = ice::coarse_vertex_positions(mesh, result->space);
  result->input_vertices = static_cast<ice::Index>(mesh.V.rows());
  result->has_space = true;
  result->faces_fingerprint = faces_fingerprint(mesh.F);
  result->cache = {{"status", "off"}, {"file", path.string()}, {"load_seconds", space.cache.load_seconds}};
  return result;
}

py::tuple load_setup(const std::filesystem::path& path, const py::object& V, const py::object& F) {
  const ice::TriangleMesh mesh = mesh_argument(V, F);
  auto coarse = std::make_shared<PyCoarseSpace>();
  auto proxy = std::make_shared<PyProxy>();
  {
    py::gil_scoped_release release;
    ice::proxy::ProxySetup setup = ice::proxy::load_proxy_setup_file(path, mesh);
    take_setup(mesh, setup, *coarse, *proxy);
    proxy->cache = {{"status", "off"}, {"file", path.string()}, {"load_seconds", setup.cache.load_seconds}};
  }
  return py::make_tuple(coarse, proxy);
}

// The prolongations (CSR, as ice.hierarchy returns them) and, with return_order, the order.
py::object hierarchy_to_python(ice::proxy::MultigridHierarchy& hierarchy, bool return_order) {
  py::list prolongations;
  for (auto& P : hierarchy.prolongations) {
    Eigen::SparseMatrix<double, Eigen::RowMajor, int> rows = P;
    prolongations.append(to_scipy(std::move(rows)));
  }
  if (!return_order) return std::move(prolongations);
  return py::make_tuple(prolongations, to_numpy(std::move(hierarchy.fine_order)));
}

// ---- tangent vector fields -------------------------------------------------------------------------

// The vector heat method on the input triangles (vector-coarse's fine mesh), alone or through a
// coarse space (by the sweep or by coarse diffusion): one of fine_solver / sweep / proxy is set.
struct PyVectorHeat {
  ice::Positions V;
  ice::proxy::TangentMesh fine;
  std::unique_ptr<fem::VectorHeatSolver> fine_solver;
  std::unique_ptr<fem::VectorSweepProxy> sweep;
  std::unique_ptr<fem::VectorHeatProxy> proxy;
  Eigen::Index size() const { return V.rows(); }
  Eigen::VectorXcd interpolate(const std::vector<ice::Index>& vertices, const std::vector<fem::Complex>& vectors) const {
    if (sweep) return sweep->interpolate(vertices, vectors);
    return proxy ? proxy->interpolate(vertices, vectors) : fine_solver->interpolate(vertices, vectors);
  }
};

// A 1-D array of `size` finite complex numbers (real numbers are taken as complex).
std::vector<fem::Complex> complex_argument(const py::handle& values, std::size_t size, const char* name) {
  const auto array = py::array_t<std::complex<double>, py::array::c_style | py::array::forcecast>::ensure(values);
  if (!array) throw py::type_error(std::string(name) + " must be complex numbers (an array or a sequence)");
  if (array.ndim() > 1) throw py::value_error(std::string(name) + " must be one-dimensional");
  if (static_cast<std::size_t>(array.size()) != size)
    throw py::value_error(std::string(name) + " has " + std::to_string(array.size()) + " entries, expected " + std::to_string(size));
  std::vector<fem::Complex> out(array.data(), array.data() + array.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    if (!std::isfinite(out[i].real()) || !std::isfinite(out[i].imag()))
      throw py::value_error(std::string(name) + "[" + std::to_string(i) + "] is not finite");
  return out;
}

std::unique_ptr<PyVectorHeat> make_vector_heat(const py::object& V, const py::object& F, const py::object& coarse_object,
                                               const std::string& operators, const py::object& time_factor_object,
                                               const std::string& fine, const std::string& solver_name, int sweep_passes,
                                               int sweep_coarse_interval) {
  auto result = std::make_unique<PyVectorHeat>();
  if (sweep_passes < 0) throw py::value_error("sweep_passes must be >= 0");
  if (sweep_coarse_interval < 0) throw py::value_error("sweep_coarse_interval must be >= 0");
  const PyCoarseSpace* coarse = coarse_object.is_none() ? nullptr : &coarse_object.cast<const PyCoarseSpace&>();
  const ice::TriangleMesh mesh = coarse ? require_coarse_space_of(V, F, *coarse, "VectorHeatSolver") : mesh_argument(V, F);
  if (coarse) refuse_cover(coarse->space.summary.tufted_cover, "VectorHeatSolver");
  if (coarse) require_map(*coarse);
  const auto kind = choice<fem::VectorOperatorKind>(
      operators, "operators");
  const double time_factor = time_factor_object.is_none() ? (coarse ? fem::kVectorProxyTimeFactor : 1.0)
                                                          : number_option(time_factor_object, "time_factor");
  if (!(time_factor > 0) || !std::isfinite(time_factor)) throw py::value_error("time_factor must be > 0");
  const auto solver = choice<ice::proxy::VectorSolver>(solver_name, "solver");
  const bool sweep = coarse && solver == ice::proxy::VectorSolver::sweep;
  const ice::FineGeometry geometry = fine_geometry_argument(fine);
  result->V = mesh.V;
  py::gil_scoped_release release;
  require_clean(mesh);
  // Through a coarse space the fine operators' time step is the sweep's (t = h²), unused by diffusion
  // (Galerkin products only).
  result->fine = ice::proxy::tangent_mesh(mesh, geometry, !coarse || sweep || kind == fem::VectorOperatorKind::galerkin,
                                   coarse ? 1.0 : time_factor);
  fem::DistanceSweepOptions sweep_options;
  sweep_options.max_passes = sweep_passes;
  sweep_options.coarse_correction_interval = sweep_coarse_interval;
  if (sweep) {
    // The sweep's marching lengths, from beside a space that came through the store.
    const ice::SurfaceEdgeLengths lengths = ice::proxy::stored_marching_lengths(
        mesh, coarse->space, coarse->map, coarse->store_key ? &*coarse->store_key : nullptr, coarse->store,
        ice::proxy::vector_sweep_traces(coarse->space), ice::proxy::CurvatureCorrection::automatic,
        ice::proxy::curvature_divisor(ice::proxy::MarchingUse::single_source));
    result->sweep = std::make_unique<fem::VectorSweepProxy>(
        ice::proxy::make_vector_sweep(mesh, result->fine, coarse->space, coarse->map, sweep_options, &lengths));
  }
  else if (coarse)
    result->proxy = std::make_unique<fem::VectorHeatProxy>(ice::proxy::make_vector_proxy(result->fine, coarse->space, coarse->map, kind, time_factor));
  else
    result->fine_solver = std::make_unique<fem::VectorHeatSolver>(*result->fine.operators);
  return result;
}

// ice.transport_directions: ice::proxy::VectorTransportSolver's transport_directions in one call, its
// coarsening arguments ice.coarsen's (a tufted cover when nonmanifold="tufted" and the mesh needs it).
Eigen::MatrixXd transport_directions(const py::object& V, const py::object& F, const py::object& sources,
                                     const py::object& directions, const std::string& solver_name, const std::string& operators,
                                     const py::object& time_factor_object, const std::string& fine, int sweep_passes,
                                     int sweep_coarse_interval, const py::object& n, const py::object& ratio,
                                     const py::object& min_vertices, const py::object& max_error, const std::string& method,
                                     const std::string& use, const py::object& area_weight,
                                     const py::object& normalize_curvature, const py::object& locked, bool remove_boundary,
                                     const py::object& threads, const py::object& regions, const std::string& qem_geometry,
                                     const py::object& refine_angle, double refine_budget, bool locality_numbering,
                                     const std::string& nonmanifold) {
  const ice::TriangleMesh mesh = mesh_argument(V, F);
  ice::proxy::VectorTransportOptions options;
  options.coarsening = coarse_space_options(mesh, n, ratio, min_vertices, max_error, method, use, area_weight, normalize_curvature,
                                            locked, remove_boundary, threads, regions, qem_geometry, refine_angle, refine_budget,
                                            locality_numbering, nonmanifold);
  options.solver = choice<ice::proxy::VectorSolver>(solver_name, "solver");
  options.operators = choice<fem::VectorOperatorKind>(operators, "operators");
  options.fine = fine_geometry_argument(fine);
  if (!time_factor_object.is_none()) options.time_factor = number_option(time_factor_object, "time_factor");
  if (!(options.time_factor > 0) || !std::isfinite(options.time_factor)) throw py::value_error("time_factor must be > 0");
  if (sweep_passes < 0) throw py::value_error("sweep_passes must be >= 0");
  if (sweep_coarse_interval < 0) throw py::value_error("sweep_coarse_interval must be >= 0");
  options.sweep.max_passes = sweep_passes;
  options.sweep.coarse_correction_interval = sweep_coarse_interval;
  const std::vector<ice::Index> vertices = index_argument(sources, mesh.V.rows(), "sources");
  if (vertices.empty()) throw py::value_error("sources is empty");
  const Eigen::MatrixXd D = matrix_argument(directions, static_cast<Eigen::Index>(vertices.size()), "directions");
  if (D.cols() != 3) throw py::value_error("directions must be one 3D direction per source (k x 3)");
  py::gil_scoped_release release;
  require_clean(mesh, options.coarsening.nonmanifold);
  return ice::proxy::transport_directions(mesh, vertices, D, options);  // std::invalid_argument: ValueError
}

// A matrix the proxy owns, as scipy viewing its arrays (read-only; a copy if not compressed).
py::object operator_view(const fem::SparseMatrix& matrix, const py::handle& owner) {
  if (matrix.isCompressed()) return scipy_view(matrix, owner);
  fem::SparseMatrix copy = matrix;
  return to_scipy(std::move(copy));
}

fem::PolishOptions polish_options(int iterations, double tolerance) {
  if (iterations < 0) throw py::value_error("polish must be >= 0 (iterations)");
  if (!(tolerance >= 0)) throw py::value_error("tolerance must be >= 0");
  fem::PolishOptions polish;
  polish.iterations = iterations;
  polish.tolerance = tolerance;
  return polish;
}

py::dict times_dict(const fem::ProxyPhaseTimes& times) {
  py::dict d;
  d["restriction"] = times.restriction;
  d["coarse_solve"] = times.coarse_solve;
  d["prolongation"] = times.prolongation;
  return d;
}

/// read() under `mutex`, waited for without the GIL (a solve holding the lock may need it to finish).
template <class Read>
auto locked(std::mutex& mutex, Read read) {
  py::gil_scoped_release release;
  const std::lock_guard<std::mutex> lock(mutex);
  return read();
}

struct PyPoissonSolver {
  std::shared_ptr<PyProxy> proxy;  // the solver keeps a reference to it
  Eigen::Index fixed_count = 0;
  std::unique_ptr<fem::ProxyPoissonSolver> solver;
  fem::PolishOptions polish;
  fem::PolishReport last_polish;
  fem::ProxyPhaseTimes last_times;
  std::mutex mutex;  // one solve at a time per object (they run without the GIL; polishing is not re-entrant)
};
struct PyHeatSolver {
  std::shared_ptr<PyProxy> proxy;
  std::unique_ptr<fem::ProxyHeatSolver> solver;
  fem::PolishOptions polish;
  fem::PolishReport last_polish;
  fem::ProxyPhaseTimes last_times;
  std::mutex mutex;
};
struct PyGeodesicSolver {  // (the solver copies what it needs of a Proxy: none is kept)
  std::unique_ptr<fem::ProxyGeodesicSolver> solver;
  fem::ProxyPhaseTimes last_times;
  std::mutex mutex;
};

// ---- multigrid -----------------------------------------------------------------------------------

/// The solver and the lock that makes one object safe to share between Python threads (its calls run
/// without the GIL; the library's solver is not re-entrant).
struct PyMultigrid {
  PyMultigrid(std::vector<fem::SparseMatrix> prolongations, const fem::MultigridOptions& options)
      : solver(std::move(prolongations), options) {}
  fem::MultigridSolver solver;
  std::mutex mutex;
};

fem::MultigridOptions multigrid_options(double tolerance, int max_iterations, const std::string& mode,
                                        const std::string& smoother, int smoothing_steps, int threads) {
  fem::MultigridOptions options;
  options.tolerance = tolerance;
  options.max_iterations = max_iterations;
  options.mode = choice<fem::MultigridMode>(mode, "mode", {{"pcg", fem::MultigridMode::pcg}, {"vcycle", fem::MultigridMode::vcycle}});
  options.smoother = choice<fem::MultigridSmoother>(smoother, "smoother",
                                                    {{"sgs", fem::MultigridSmoother::symmetric_gauss_seidel},
                                                     {"gs", fem::MultigridSmoother::gauss_seidel},
                                                     {"chebyshev", fem::MultigridSmoother::chebyshev}});
  options.smoothing_steps = smoothing_steps;
  options.threads = threads;
  return options;
}


}  // namespace

PYBIND11_MODULE(_ice, m) {
  m.doc() = "ICE: intrinsic coarsening and coarse-proxy PDE solvers (C++ core; see the ice package)";
  // What coarsen(regions=0) runs with (ice::kDefaultCoarseningRegions): ice-batch hashes it.
  m.attr("DEFAULT_COARSENING_REGIONS") = ice::kDefaultCoarseningRegions;

  // ice.MeshError: the library's MeshError, message as the tools print it, with .kind and .path.
  static py::handle mesh_error = py::exception<ice::MeshError>(m, "MeshError", PyExc_RuntimeError).release();
  py::register_exception_translator([](std::exception_ptr pointer) {
    try {
      if (pointer) std::rethrow_exception(pointer);
    } catch (const ice::MeshError& e) {
      const char* kind = e.kind() == ice::MeshError::Kind::Unreadable ? "unreadable"
                         : e.kind() == ice::MeshError::Kind::Defective ? "defective"
                                                                       : "unwritable";
      py::object error = py::reinterpret_borrow<py::object>(mesh_error)(e.what());
      error.attr("kind") = kind;
      error.attr("path") = e.path();
      PyErr_SetObject(mesh_error.ptr(), error.ptr());
    } catch (const fem::NotPositiveDefinite& e) {
      PyErr_SetString(PyExc_ArithmeticError, e.what());
    }
  });

  m.def(
      "_resolve_prolongation",
      [](const std::string& prolongation, const std::string& operators, bool dirichlet, bool eigenpairs) {
        try {
          return ice::proxy::spelling(ice::proxy::resolve_prolongation(
              choice<ice::proxy::Prolongation>(prolongation, "prolongation"),
              choice<fem::CoarseOperatorKind>(operators, "operators"), dirichlet,
              eigenpairs ? ice::proxy::ProlongationUse::eigenpairs : ice::proxy::ProlongationUse::solves));
        } catch (const std::invalid_argument& e) {
          throw py::value_error(e.what());
        }
      },
      py::arg("prolongation"), py::arg("operators"), py::arg("dirichlet"), py::arg("eigenpairs") = false,
      "The prolongation 'auto' means for these operators (ice::proxy::resolve_prolongation).");
  m.def("_load_mesh", &load_mesh, py::arg("path"), py::arg("repair") = false, py::arg("weld") = false,
        py::arg("nonmanifold") = "refuse", py::arg("neighbours") = 30, py::arg("separate_thin_parts") = false,
        "The dict behind ice.load_mesh (use that).");
  m.def(
      "point_cloud_triangles",
      [](const py::object& P, int neighbours, int threads, bool separate_thin_parts) {
        const ice::Positions points = positions_argument(P, "P");
        ice::PointCloudOptions options;
        options.neighbours = neighbours;
        options.separate_thin_parts = separate_thin_parts;
        options.threads = bounded_integer(py::int_(threads), "threads", 0, 64);
        ice::Faces F;
        {
          py::gil_scoped_release release;
          try {
            F = ice::point_cloud_triangles(points, options);
          } catch (const std::invalid_argument& error) {
            throw py::value_error(error.what());
          }
        }
        return py::cast(std::move(F));
      },
      py::arg("P"), py::kw_only(), py::arg("neighbours") = 30, py::arg("threads") = 0, py::arg("separate_thin_parts") = false,
      R"doc(Faces (m×3) for a point cloud P (n×3): the triangles of each point's local Delaunay fan (its `neighbours`
nearest points projected onto its least-squares tangent plane; Sharp & Crane 2020, §5.3), made consistent
where the fans disagree (no two overlapping at a corner). separate_thin_parts=True keeps apart the two
sides of parts sampled only a few points across (limbs, fins, tubes): the plane from the nearest third,
neighbours 45° or more off it left out (off by default: it also splits walls scanned on both sides).
A triangle soup (non-manifold, inconsistently oriented): pass (P, F) with nonmanifold="tufted" to ice.coarsen, ice.setup_proxy or the solve_* functions. Raises ValueError for fewer
than 3 points, non-finite or repeated positions, or a point whose neighbours and it lie on one line.)doc");
  m.def("validate", &validate, py::arg("V"), py::arg("F"),
        R"doc(Validation report of the mesh (V, F): sizes, components, boundary loops, genus, bounding box,
edge lengths and each defect ICE refuses (count and first offenders), as `ice-info --json` reports it.
report["clean"] says whether coarsen() and the solvers accept the mesh.)doc");
  m.def("save_mesh", &save_mesh, py::arg("path"), py::arg("V"), py::arg("F"), py::kw_only(), py::arg("overwrite") = false,
        py::arg("binary") = false,
        R"doc(Writes (V, F) as OBJ, OFF, PLY or STL (by the extension; PLY/OBJ/OFF in full double precision).
An existing file is replaced only with overwrite=True; raises ice.MeshError (kind "unwritable") otherwise.)doc");
  m.def(
      "face_lengths",
      [](const py::object& V, const py::object& F) {
        const ice::TriangleMesh mesh = mesh_argument(V, F);
        return ice::face_lengths_from_positions(mesh.V, mesh.F);
      },
      py::arg("V"), py::arg("F"),
      "Per-face edge lengths (m×3): column k is the length of the edge from corner k to corner (k+1)%3.");
  m.def(
      "intrinsic_delaunay",
      [](const py::object& V, const py::object& F) {
        const ice::TriangleMesh mesh = mesh_argument(V, F);
        ice::FineMesh fine;
        {
          py::gil_scoped_release release;
          require_clean(mesh);
          fine = ice::fine_mesh(mesh, ice::FineGeometry::intrinsic_delaunay);
        }
        return py::make_tuple(py::cast(std::move(fine.F)), py::cast(std::move(fine.L)), fine.flips);
      },
      py::arg("V"), py::arg("F"),
      R"doc(The intrinsic Delaunay triangulation of (V, F): (F_idt, lengths, flips). Same vertices, edges flipped
until every cotan weight is >= 0; the fine discretisation the solvers use by default.)doc");

  m.def(
      "loop_subdivide",
      [](const py::object& V, const py::object& F, int levels) {
        if (levels < 0) throw py::value_error("levels must be >= 0");
        const ice::TriangleMesh mesh = mesh_argument(V, F);
        ice::TriangleMesh fine;
        {
          py::gil_scoped_release release;
          require_clean(mesh);
          fine = ice::loop_subdivide(mesh, levels);
        }
        return py::make_tuple(py::cast(std::move(fine.V)), py::cast(std::move(fine.F)));
      },
      py::arg("V"), py::arg("F"), py::arg("levels") = 1,
      R"doc(Loop subdivision, `levels` times (about 4x the vertices each): (V, F) of the finer mesh, the input
vertices first. How the benchmarks make large inputs from real meshes.)doc");

  // ---- operators
  m.def(
      "cotan_laplacian",
      [](const py::object& V, const py::object& F, const py::object& lengths, const py::object& n) {
        const ice::IntrinsicMesh d = discretisation_argument(V, F, lengths, n);
        Eigen::SparseMatrix<double> L;
        {
          py::gil_scoped_release release;
          L = fem::cotan_laplacian(d);
        }
        return to_scipy(std::move(L));
      },
      py::arg("V") = py::none(), py::arg("F") = py::none(), py::kw_only(), py::arg("lengths") = py::none(),
      py::arg("n") = py::none(),
      R"doc(The cotan Laplacian as scipy.sparse.csc_matrix (n×n, symmetric positive semidefinite, rows sum to 0:
the weak form of -Δ). From positions, cotan_laplacian(V, F), or from an intrinsic mesh,
cotan_laplacian(F=F, lengths=L); n: vertex count when vertices beyond max(F) exist.)doc");
  m.def(
      "mass_matrix",
      [](const py::object& V, const py::object& F, const py::object& lengths, const py::object& n, const std::string& kind) {
        const ice::IntrinsicMesh d = discretisation_argument(V, F, lengths, n);
        const auto mass_kind =
            choice<fem::MassKind>(kind, "kind", {{"lumped", fem::MassKind::lumped}, {"consistent", fem::MassKind::consistent}});
        Eigen::SparseMatrix<double> M;
        {
          py::gil_scoped_release release;
          M = fem::mass_matrix(d, mass_kind);
        }
        return to_scipy(std::move(M));
      },
      py::arg("V") = py::none(), py::arg("F") = py::none(), py::kw_only(), py::arg("lengths") = py::none(),
      py::arg("n") = py::none(), py::arg("kind") = "lumped",
      R"doc(The mass matrix as scipy.sparse.csc_matrix: kind "lumped" (diagonal, a third of the incident
face areas) or "consistent" (P1). Arguments as for cotan_laplacian.)doc");

  // ---- coarse space
  py::class_<PyCoarseSpace, std::shared_ptr<PyCoarseSpace>>(m, "CoarseSpace", R"doc(A coarse intrinsic mesh of an input mesh and how the two are linked (ice.coarsen, ice.load_coarse_mesh).

The coarse mesh is intrinsic: faces with edge lengths and a gluing (self- and multi-edges allowed),
not positions. P maps coarse nodal values to the input vertices.)doc")
      .def_property_readonly("faces", [](const PyCoarseSpace& s) { return s.space.mesh.F; }, "Coarse faces (m×3 int32); a face may repeat a vertex (a Δ-complex).")
      .def_property_readonly("lengths", [](const PyCoarseSpace& s) { return s.space.mesh.L; }, "Per-face edge lengths (m×3): column k is the edge from corner k to corner (k+1)%3.")
      .def_property_readonly("twin", [](const PyCoarseSpace& s) {
        std::vector<ice::Index> twin = s.space.mesh.twin;
        return to_numpy(std::move(twin));
      }, "The gluing: twin[3f + k] is the side 3g + d along face f's side k, or -1 on the boundary.")
      .def_property_readonly("to_input", [](const PyCoarseSpace& s) {
        std::vector<ice::Index> to_input = s.space.mesh.to_input;
        return to_numpy(std::move(to_input));
      }, "Coarse vertex -> input vertex (-1: inserted by refinement).")
      .def_property_readonly("from_input", [](const PyCoarseSpace& s) {
        std::vector<ice::Index> from_input = s.space.mesh.from_input;
        return to_numpy(std::move(from_input));
      }, "Input vertex -> coarse vertex, or -1 if removed.")
      .def_property_readonly("n_vertices", [](const PyCoarseSpace& s) { return s.space.mesh.num_vertices(); }, "Coarse vertices.")
      .def_property_readonly("n_faces", [](const PyCoarseSpace& s) { return s.space.mesh.F.rows(); }, "Coarse faces.")
      .def_property_readonly("input_vertices", [](const PyCoarseSpace& s) { return s.input_vertices; }, "Vertices of the mesh it was made from.")
      .def_property_readonly("P", &prolongation, R"doc(The prolongation, scipy.sparse.csr_matrix (input vertices × coarse vertices): row i holds the
barycentric coordinates of input vertex i in a coarse face; every row sums to 1. None when read from a file.)doc")
      .def_property_readonly("map", &coarse_map, R"doc(The fine-to-coarse map as (face, bary, coarse_vertex): for each input vertex a coarse face containing
it, its barycentric coordinates (n×3) in that face's corners, and the coarse vertex it became (-1 if removed).
None when read from a file, with keep_map=False, or for QEM with intrinsic Delaunay geometry.)doc")
      .def_property_readonly("cache", [](const PyCoarseSpace& s) { return json_to_python(s.cache); },
                             "Where ice.coarsen's space came from: {'status': 'hit'|'miss'|'rebuilt'|'off', 'keys', 'directory', "
                             "'load_seconds', 'save_seconds'} ('off' without a store, and for spaces read from a file).")
      .def_property_readonly("summary", &coarse_summary, "What the coarsening did (the tools' report keys): sizes, stop reason, removals, costs, seconds.")
      .def_property_readonly("positions", [](const PyCoarseSpace& s) -> py::object {
        if (!s.has_space) return py::none();
        return py::cast(s.positions);
      }, "Positions of the coarse vertices on the input surface (for drawing; the coarse mesh is intrinsic).")
      .def_property_readonly("traced_edges", [](const PyCoarseSpace& s) -> py::object {
        if (!s.tracing) return py::none();
        py::list polylines;
        const auto m = static_cast<py::ssize_t>(s.tracing->edges.size());
        py::array_t<ice::Index> ends({m, py::ssize_t{2}});
        for (py::ssize_t e = 0; e < m; ++e) {
          const ice::TracedEdge& edge = s.tracing->edges[static_cast<std::size_t>(e)];
          ends.mutable_at(e, 0) = edge.tail;
          ends.mutable_at(e, 1) = edge.head;
          polylines.append(py::cast(s.traced_polylines[static_cast<std::size_t>(e)]));
        }
        return py::make_tuple(polylines, ends);
      }, R"doc((polylines, ends) with coarsen(..., trace=True), else None: each coarse edge's polyline on the input surface
(k×3 points, tail to head: the preimage of the edge under the fine-to-coarse map; ice-coarsen --trace draws the same)
and its (tail, head) coarse vertices (m×2).)doc")
      .def_property_readonly("inserted", [](const PyCoarseSpace& s) -> py::object {
        const auto k = static_cast<py::ssize_t>(s.space.inserted.size());
        py::array_t<ice::Index> face(k);
        py::array_t<double> bary({k, py::ssize_t{3}});
        for (py::ssize_t i = 0; i < k; ++i) {
          const ice::InputSurfacePoint& p = s.space.inserted[static_cast<std::size_t>(i)];
          face.mutable_at(i) = p.face;
          for (int c = 0; c < 3; ++c) bary.mutable_at(i, c) = p.bary[static_cast<std::size_t>(c)];
        }
        return py::make_tuple(face, bary);
      }, "(face, bary): where the vertices inserted by refinement lie on the input surface (the last coarse vertices).")
      .def("save", &save_coarse_mesh, py::arg("path"), py::kw_only(), py::arg("overwrite") = false, py::arg("comment") = "",
           R"doc(Writes the coarse intrinsic mesh as .ilm (faces, lengths, gluing, vertex map; exact round trip:
ice.load_coarse_mesh reads it back). An existing file is replaced only with overwrite=True.)doc")
      .def("__repr__", [](const PyCoarseSpace& s) {
        return "<ice.CoarseSpace " + std::to_string(s.space.mesh.num_vertices()) + " vertices, " +
               std::to_string(s.space.mesh.F.rows()) + " faces, from " + std::to_string(s.input_vertices) +
               " input vertices" + (s.has_space ? "" : ", read from a file") + ">";
      });

  m.def("coarsen", &coarsen, py::arg("V"), py::arg("F"), py::kw_only(), py::arg("n") = py::none(),
        py::arg("ratio") = py::none(), py::arg("min_vertices") = py::none(), py::arg("max_error") = py::none(), py::arg("method") = "ice",
        py::arg("use") = "poisson_heat", py::arg("area_weight") = py::none(), py::arg("normalize_curvature") = py::none(),
        py::arg("locked") = py::none(), py::arg("remove_boundary") = true, py::arg("threads") = 0,
        py::arg("regions") = 0, py::arg("qem_geometry") = "extrinsic", py::arg("refine_angle") = py::none(), py::arg("refine_budget") = 1.5,
        py::arg("keep_map") = true, py::arg("locality_numbering") = true, py::arg("trace") = false, py::arg("progress") = py::none(),
        py::arg("nonmanifold") = "refuse", py::arg("cache") = py::none(),
        R"doc(Coarsens the mesh (V, F) (clean, oriented, manifold; several components, boundaries and any genus
are fine) and returns its ice.CoarseSpace: the intrinsic coarse mesh, P, the fine-to-coarse map.
nonmanifold="tufted": a mesh that is not an oriented manifold (non-manifold edges or vertices,
inconsistent orientation, non-orientable; a point cloud with ice.point_cloud_triangles' faces) is
coarsened through its tufted cover instead of refused (Galerkin proxies only; its map places each vertex by
one copy, its P averages the copies; nothing traced on it).

Target: exactly one of n (vertices), ratio (of the input vertices, e.g. 0.05; with min_vertices, at
least that many, as the tools' --min-vertices), or max_error (the ICE error metric; may be combined
with n or ratio, whichever stops first).
method: "ice" (intrinsic vertex removals) or "qem" (the QEM baseline; qem_geometry "extrinsic" or
"intrinsic_delaunay"). use: "poisson_heat" or "geodesic" picks the measured metric defaults
(area_weight, normalize_curvature), which the two arguments override. locked: vertices never
removed (e.g. Dirichlet vertices). regions: meshes of 20,000+ vertices coarsened below a quarter of
their vertices are coarsened in R regions in parallel, then a serial pass (0: R = 16; 1: the exact serial greedy order); the result depends
on R, never on threads: coarsening threads (0: one per core), which only change the time.
refine_angle: intrinsic Delaunay refinement to this smallest angle (degrees), at most refine_budget
times the vertices. progress: called with a dict (vertices, target, removed, last_cost) every 1000
removals (once per round of the parallel phase); returning False stops early (summary["stop_reason"] == "cancelled"), an exception in it or
Ctrl-C stops and is raised. keep_map: keep the fine-to-coarse map (CoarseSpace.map, DistanceOracle). trace (ICE):
also trace every coarse edge on the input surface exactly (ice-coarsen --trace: the coarsening's history recorded
while it runs, ~1 KB per removal until this call returns): CoarseSpace.traced_edges, and the lengths of
ProxyGeodesicSolver.from_coarse(..., lengths='traced'). cache: None (the default store: $ICE_CACHE, else
~/.cache/ice), False (none) or a directory: a coarse space stored there with its map for the same mesh and
options is loaded instead of built (the same arrays to the last bit; no progress calls then), and the coarse
edges' traced lengths are stored beside it; CoarseSpace.cache says which ('hit', 'miss', 'rebuilt', 'off').
trace=True and QEM's intrinsic Delaunay geometry bypass it. Raises ice.MeshError naming
each defect of a refused mesh.)doc");
  m.def("_transport_directions", &transport_directions, py::arg("V"), py::arg("F"), py::arg("sources"), py::arg("directions"),
        py::kw_only(), py::arg("solver") = "sweep", py::arg("operators") = "galerkin", py::arg("time_factor") = py::none(),
        py::arg("fine") = "intrinsic_delaunay", py::arg("sweep_passes") = fem::DistanceSweepOptions{}.max_passes,
        py::arg("sweep_coarse_interval") = fem::DistanceSweepOptions{}.coarse_correction_interval, py::arg("n") = py::none(),
        py::arg("ratio") = py::none(), py::arg("min_vertices") = py::none(), py::arg("max_error") = py::none(),
        py::arg("method") = "ice", py::arg("use") = "poisson_heat", py::arg("area_weight") = py::none(),
        py::arg("normalize_curvature") = py::none(), py::arg("locked") = py::none(), py::arg("remove_boundary") = true,
        py::arg("threads") = 0, py::arg("regions") = 0, py::arg("qem_geometry") = "extrinsic",
        py::arg("refine_angle") = py::none(), py::arg("refine_budget") = 1.5, py::arg("locality_numbering") = true,
        py::arg("nonmanifold") = "refuse",
        "ice.transport_directions without its defaults (the coarsening target is required here).");
  m.def("setup_proxy", &setup_proxy, py::arg("V"), py::arg("F"), py::kw_only(), py::arg("operators") = "galerkin",
        py::arg("fine") = "intrinsic_delaunay", py::arg("prolongation") = "auto", py::arg("fixed") = py::none(),
        py::arg("cache") = py::none(), py::arg("n") = py::none(), py::arg("ratio") = py::none(),
        py::arg("min_vertices") = py::none(), py::arg("max_error") = py::none(), py::arg("method") = "ice",
        py::arg("use") = "poisson_heat", py::arg("area_weight") = py::none(), py::arg("normalize_curvature") = py::none(),
        py::arg("locked") = py::none(), py::arg("remove_boundary") = true, py::arg("threads") = 0, py::arg("regions") = 0,
        py::arg("qem_geometry") = "extrinsic", py::arg("refine_angle") = py::none(), py::arg("refine_budget") = 1.5,
        py::arg("locality_numbering") = true, py::arg("nonmanifold") = "refuse",
        R"doc(Coarsens (V, F) and builds its Proxy in one step, through the store of set-up proxies: (CoarseSpace, Proxy).

The coarsening arguments are ice.coarsen's (the coarse space keeps no fine-to-coarse map); operators, fine and
prolongation ("auto": smoothed with Galerkin operators and no fixed vertices) are Proxy's; fixed vertices are
locked. cache: None (the default store: $ICE_CACHE, else ~/.cache/ice), False (none) or a directory. A setup
stored there for the same mesh and options is loaded instead of built (the same arrays to the last bit);
Proxy.cache says which ('hit', 'miss', 'rebuilt' after a damaged entry, 'off').)doc");
  m.def("save_setup", &save_setup, py::arg("path"), py::arg("V"), py::arg("F"), py::arg("coarse"), py::arg("proxy"),
        py::kw_only(), py::arg("overwrite") = false,
        R"doc(Writes a setup_proxy result (coarse space and proxy) of (V, F) to a file that ice.load_setup takes back
for the same (V, F) only: binary, checksummed, written atomically, the store's format. An existing file is
replaced only with overwrite=True (ice.MeshError, kind "unwritable", otherwise); ValueError when the coarse
space and proxy are not one setup of (V, F).)doc");
  m.def("load_setup", &load_setup, py::arg("path"), py::arg("V"), py::arg("F"),
        R"doc((coarse, proxy) as ice.setup_proxy returned them when ice.save_setup wrote the file, checked (header,
checksum, every array's structure, P's rows) and bit for bit the same; nothing is coarsened or assembled.
Proxy.cache says {'status': 'off', 'file': path, 'load_seconds': ...}. Raises RuntimeError naming the file and
the defect: no such file, not a setup, damaged, another format version, or made for another mesh.)doc");
  m.def("save_coarse_space", &save_coarse_space, py::arg("path"), py::arg("V"), py::arg("F"), py::arg("coarse"), py::kw_only(),
        py::arg("overwrite") = false,
        R"doc(Writes a coarse space of (V, F) with its fine-to-coarse map (ice.coarsen, keep_map=True) to a file that
ice.load_coarse_space takes back for the same (V, F) only: binary, checksummed, written atomically, the store's
format, with P, the map and the summary (CoarseSpace.save writes the coarse mesh alone, as portable .ilm text).
An existing file is replaced only with overwrite=True (ice.MeshError, kind "unwritable", otherwise); ValueError
for a space without a map or of another mesh.)doc");
  m.def("load_coarse_space", &load_coarse_space, py::arg("path"), py::arg("V"), py::arg("F"),
        R"doc(The CoarseSpace ice.save_coarse_space wrote for (V, F), checked (header, checksum, every array, every entry
of P against the map) and bit for bit the same, P, map and summary included; nothing is coarsened. .cache says
{'status': 'off', 'file': path, 'load_seconds': ...}. Raises RuntimeError naming the file and the defect: no such
file, not a coarse space, damaged, another format version, or made for another mesh.)doc");
  m.def("load_coarse_mesh", &load_coarse_mesh, py::arg("path"),
        R"doc(Reads an .ilm coarse mesh (CoarseSpace.save, ice-coarsen): faces, lengths, gluing, vertex map; its
P, map and summary are None. Raises ice.MeshError naming the file, line and defect.)doc");

  // ---- proxy
  py::class_<PyProxy, std::shared_ptr<PyProxy>>(m, "Proxy", R"doc(The fine mesh and a coarse space linked by P, with the operators the proxy solvers use.

Proxy(V, F, coarse, operators="galerkin", fine="intrinsic_delaunay", prolongation="barycentric"): the fine
discretisation ("input" triangles or their "intrinsic_delaunay" triangulation), coarse operators
"galerkin" (PᵀLP, PᵀMP) or "intrinsic" (cotan operators of the coarse lengths); lumped masses; the
coarse space's P as given ("barycentric") or smoothed by one damped Jacobi step on the fine Laplacian
("smoothed": Galerkin operators only, no Dirichlet vertices, not for the coarse heat method; about
half the Poisson and heat error at 5 % of the vertices), or twice ("smoothed_twice": the same
conditions; a richer coarse space for eigenpairs, for a denser P). The operators and fine mesh default to the
tools'; the prolongation to the barycentric P, which serves every solver (solve_poisson, heat_flow
and poisson-coarse pick the smoothed one where it serves: prolongation="auto").)doc")
      .def(py::init(&make_proxy), py::arg("V"), py::arg("F"), py::arg("coarse"), py::kw_only(),
           py::arg("operators") = "galerkin", py::arg("fine") = "intrinsic_delaunay",
           py::arg("prolongation") = "barycentric")
      .def_property_readonly("prolongation", [](const py::object& self) {
        return operator_view(self.cast<PyProxy&>().proxy->prolongation(), self);
      }, "The P the proxy solves with (smoothed or as given; scipy.sparse, read-only view)")
      .def_property_readonly("fine_size", [](const PyProxy& p) { return p.proxy->fine_size(); }, "Fine vertices.")
      .def_property_readonly("coarse_size", [](const PyProxy& p) { return p.proxy->coarse_size(); }, "Coarse vertices.")
      .def_property_readonly("fine_faces", [](const PyProxy& p) { return p.proxy->fine_mesh().F; }, "Faces of the fine discretisation (the input's, or its intrinsic Delaunay triangulation's).")
      .def_property_readonly("fine_lengths", [](const PyProxy& p) { return p.proxy->fine_mesh().L; }, "Edge lengths of the fine discretisation.")
      .def_property_readonly("cache", [](const PyProxy& p) { return json_to_python(p.cache); },
                             "Where ice.setup_proxy got this proxy: status ('miss', 'hit', 'rebuilt', 'off'), keys, directory, seconds.")
      .def_property_readonly("fine_flips", [](const PyProxy& p) { return p.fine.flips; }, "Intrinsic Delaunay flips made on the fine mesh.")
      .def_property_readonly("fine_laplacian", [](const py::object& self) {
        return operator_view(self.cast<PyProxy&>().proxy->fine_laplacian(), self);
      }, "The fine cotan Laplacian (scipy.sparse, assembled on first use for intrinsic operators) (read-only view)")
      .def_property_readonly("fine_mass", [](const py::object& self) {
        return operator_view(self.cast<PyProxy&>().proxy->fine_mass(), self);
      }, "The fine lumped mass matrix (read-only view)")
      .def_property_readonly("coarse_laplacian", [](const py::object& self) {
        return operator_view(self.cast<PyProxy&>().proxy->coarse_laplacian(), self);
      }, "The coarse Laplacian (PᵀLP for Galerkin operators) (read-only view)")
      .def_property_readonly("coarse_mass", [](const py::object& self) {
        return operator_view(self.cast<PyProxy&>().proxy->coarse_mass(), self);
      }, "The coarse mass matrix (PᵀMP for Galerkin operators) (read-only view)")
      .def("prolong", [](const PyProxy& p, const py::object& values) {
        const Eigen::VectorXd coarse = vector_argument(values, p.proxy->coarse_size(), "values");
        return p.proxy->prolong(coarse);
      }, py::arg("values"), "P @ values: coarse nodal values to the fine vertices.")
      .def("restrict_weighted", [](const PyProxy& p, const py::object& values) {
        const auto fine = vector_values(values, p.proxy->fine_size(), "values");
        return p.proxy->restrict_weighted(view(fine));
      }, py::arg("values"), "Pᵀ @ values for an integrated (mass-weighted) fine vector.");

  py::class_<PyPoissonSolver>(m, "ProxyPoissonSolver", R"doc(Poisson L u = M f through the coarse proxy: u ≈ P u_c with (coarse L) u_c = Pᵀ M f.

ProxyPoissonSolver(proxy, fixed=None, polish=0, tolerance=0): without fixed vertices, zero-mean Neumann
(f made compatible, u with zero mass-weighted mean); with them, Dirichlet values there (they must be
coarse vertices: lock them when coarsening). polish/tolerance: conjugate gradients on the fine system
preconditioned by the two-level cycle, for at most `polish` iterations or to the estimated relative
error `tolerance` (poisson-coarse --polish/--tolerance). Factors once; solve() any number of times.)doc")
      .def(py::init([](std::shared_ptr<PyProxy> proxy, const py::object& fixed, int polish, double tolerance) {
             std::vector<ice::Index> dirichlet;
             if (!fixed.is_none()) dirichlet = index_argument(fixed, proxy->proxy->fine_size(), "fixed");
             const fem::PolishOptions options = polish_options(polish, tolerance);
             auto solver = std::make_unique<PyPoissonSolver>();
             solver->proxy = proxy;
             solver->fixed_count = static_cast<Eigen::Index>(dirichlet.size());
             solver->polish = options;
             py::gil_scoped_release release;
             solver->solver = std::make_unique<fem::ProxyPoissonSolver>(*proxy->proxy, std::move(dirichlet), options);
             return solver;
           }),
           py::arg("proxy"), py::kw_only(), py::arg("fixed") = py::none(), py::arg("polish") = 0,
           py::arg("tolerance") = 0.0)
      .def("solve", [](PyPoissonSolver& s, const py::object& f, const py::object& values) -> py::object {
             const Eigen::Index n = s.proxy->proxy->fine_size();
             if (py::array::ensure(f) && py::array::ensure(f).ndim() == 2) {  // (n, k): k sources as one block
               const Eigen::MatrixXd F = matrix_argument(f, n, "f");
               Eigen::MatrixXd fixed_values;
               if (!values.is_none()) {
                 if (s.solver->is_zero_mean()) throw py::value_error("values are given but the solver has no fixed vertices");
                 fixed_values = matrix_argument(values, s.fixed_count, "values");
                 if (fixed_values.cols() != F.cols()) throw py::value_error("values must have one column per column of f");
               }
               Eigen::MatrixXd U;
               {
                 py::gil_scoped_release release;
                 const std::lock_guard<std::mutex> lock(s.mutex);
                 U = s.solver->solve_block(F, fixed_values, &s.last_times);
               }
               return py::cast(std::move(U));
             }
             const auto rhs = vector_values(f, n, "f");  // read in place
             Eigen::VectorXd fixed_values;
             if (!values.is_none()) {
               if (s.solver->is_zero_mean()) throw py::value_error("values are given but the solver has no fixed vertices");
               fixed_values = vector_argument(values, s.fixed_count, "values");
             }
             Eigen::VectorXd u;
             {
               py::gil_scoped_release release;
               const std::lock_guard<std::mutex> lock(s.mutex);
               u = s.solver->solve(view(rhs), fixed_values, &s.last_times, &s.last_polish);
             }
             return py::cast(std::move(u));
           }, py::arg("f"), py::arg("values") = py::none(),
           "u for the nodal source f (n,); values: the Dirichlet values, aligned with `fixed` (default zeros).\n"
           "f of shape (n, k): k sources solved as one block (one pass over P, one coarse block solve; each column\n"
           "equal to its own solve within round-off), values then (len(fixed), k).")
      .def_property_readonly("polish_report", [](PyPoissonSolver& s) { return json_to_python(locked(s.mutex, [&] { return ice::proxy::polish_json(s.polish, s.last_polish); })); },
                             "What polishing did in the last solve (iterations, estimated errors, seconds).")
      .def_property_readonly("times", [](PyPoissonSolver& s) { return times_dict(locked(s.mutex, [&] { return s.last_times; })); },
                             "Seconds of the last solve's stages (restriction, coarse_solve, prolongation).")
      .def_property_readonly("is_zero_mean", [](const PyPoissonSolver& s) { return s.solver->is_zero_mean(); }, "True without fixed vertices (zero-mean Neumann).");

  py::class_<PyHeatSolver>(m, "ProxyHeatSolver", R"doc(Backward-Euler heat flow (M + τL) u_{k+1} = M u_k through the coarse proxy.

ProxyHeatSolver(proxy, time_step, restriction="l2", polish=0, tolerance=0): u0 restricted by L²
projection ("l2") or injection, stepped on the coarse mesh, prolonged with P; polishing as for
ProxyPoissonSolver, per step.)doc")
      .def(py::init([](std::shared_ptr<PyProxy> proxy, double time_step, const std::string& restriction, int polish,
                       double tolerance) {
             if (!(time_step > 0)) throw py::value_error("time_step must be > 0");
             const auto kind = choice<fem::RestrictionKind>(
                 restriction, "restriction",
                 {{"l2", fem::RestrictionKind::l2_projection}, {"injection", fem::RestrictionKind::injection}});
             const fem::PolishOptions options = polish_options(polish, tolerance);
             auto solver = std::make_unique<PyHeatSolver>();
             solver->proxy = proxy;
             solver->polish = options;
             py::gil_scoped_release release;
             solver->solver = std::make_unique<fem::ProxyHeatSolver>(*proxy->proxy, time_step, kind, options);
             return solver;
           }),
           py::arg("proxy"), py::arg("time_step"), py::kw_only(), py::arg("restriction") = "l2",
           py::arg("polish") = 0, py::arg("tolerance") = 0.0)
      .def("integrate", [](PyHeatSolver& s, const py::object& u0, int steps) {
             const auto initial = vector_values(u0, s.proxy->proxy->fine_size(), "u0");  // read in place
             if (steps < 1) throw py::value_error("steps must be >= 1");
             py::gil_scoped_release release;
             const std::lock_guard<std::mutex> lock(s.mutex);
             return s.solver->integrate(view(initial), steps, &s.last_times, &s.last_polish);
           }, py::arg("u0"), py::arg("steps") = 1, "The state after `steps` steps of time_step from nodal values u0.")
      .def("steps", [](PyHeatSolver& s, const py::object& u0, int steps, int every) {
             const auto initial = vector_values(u0, s.proxy->proxy->fine_size(), "u0");
             if (steps < 1 || every < 1) throw py::value_error("steps and every must be >= 1");
             if (s.solver->is_polishing()) throw py::value_error("steps() prolongs only some states; polishing needs every fine step (use integrate)");
             std::vector<int> listed;
             Eigen::MatrixXd states;
             {
               py::gil_scoped_release release;
               const std::lock_guard<std::mutex> lock(s.mutex);
               states = s.solver->trajectory(view(initial), steps, every, &listed, &s.last_times);
             }
             return py::make_tuple(std::move(states), listed);
           }, py::arg("u0"), py::arg("steps"), py::arg("every") = 1,
           "(states, step_counts): the states after every `every`-th step up to `steps` (and after `steps`), one column\n"
           "each, u0 restricted once and stepped on the coarse mesh, only those states prolonged; column j equals\n"
           "integrate(u0, step_counts[j]) to the last bit.")
      .def_property_readonly("polish_report", [](PyHeatSolver& s) { return json_to_python(locked(s.mutex, [&] { return ice::proxy::polish_json(s.polish, s.last_polish); })); },
                             "What polishing did in the last integrate().")
      .def_property_readonly("times", [](PyHeatSolver& s) { return times_dict(locked(s.mutex, [&] { return s.last_times; })); },
                             "Seconds of the last integrate()'s stages.");

  m.def("boundary_vertices", [](const py::object& F) {
        const ice::Faces faces = faces_argument(F);
        return to_numpy(fem::boundary_vertices(faces));
      },
      py::arg("F"), "The vertices on a boundary edge (an edge of one face), sorted (int32).");
  m.def("proxy_eigenbasis", [](std::shared_ptr<PyProxy> proxy, int k, double tolerance, const py::object& dirichlet,
                               const py::object& cache) {
        if (!(tolerance > 0)) throw py::value_error("tolerance must be > 0");
        fem::EigenOptions options;
        options.tolerance = tolerance;
        std::vector<ice::Index> fixed;
        if (!dirichlet.is_none()) fixed = index_argument(dirichlet, proxy->proxy->fine_size(), "dirichlet");
        const ice::proxy::Store store = store_argument(cache);
        ice::proxy::Eigenbasis basis;
        {
          py::gil_scoped_release release;
          basis = ice::proxy::proxy_eigenbasis(*proxy->proxy, k, options, fixed, store);
        }
        return py::make_tuple(std::move(basis.values), std::move(basis.vectors));
      },
      py::arg("proxy"), py::arg("k"), py::kw_only(), py::arg("tolerance") = 1e-10, py::arg("dirichlet") = py::none(),
      py::arg("cache") = false,
      R"doc((values, vectors): the k smallest eigenpairs of L φ = λ M φ through a Galerkin Proxy (spectral-coarse):
the coarse pencil's, prolonged; values increasing, vectors (n × k) M-orthonormal with the fine lumped mass.
dirichlet: input vertices where φ = 0 (each a coarse vertex: locked when coarsening; the proxy's P
barycentric). ValueError unless 1 <= k < the free coarse vertex count and the operators are Galerkin.
cache: the coarse pairs through the store (False, the default: none, as for anything else given a Proxy;
None the default store, or a directory): a second call with the same proxy, k and tolerance loads them,
the same numbers to the last bit.)doc");
  m.def("refined_coarse_vertices", [](int k, int coarse_directions, ice::Index dirichlet_vertices) {
        if (k < 1) throw py::value_error("k must be >= 1");
        if (coarse_directions < -1) throw py::value_error("coarse_directions must be >= -1 (-1: the default)");
        if (dirichlet_vertices < 0) throw py::value_error("dirichlet_vertices must be >= 0");
        ice::proxy::EigenRefinement refinement;
        refinement.coarse_directions = coarse_directions;
        return ice::proxy::refined_coarse_vertices(k, refinement, dirichlet_vertices);
      },
      py::arg("k"), py::kw_only(), py::arg("coarse_directions") = -1, py::arg("dirichlet_vertices") = 0,
      R"doc(The coarse vertex count the refined route (eigenbasis with refine_tolerance, spectral-coarse --tolerance) is
set up with when given no ratio or vertex count (at most the mesh's): a fixed number of coarse vertices per coarse
pair it computes (k + guard + coarse directions; coarse_directions -1: 2 (k + guard)), as by Weyl's law the accuracy
of the coarse pairs depends on that ratio, not on the mesh; plus the dirichlet_vertices the coarsening keeps.)doc");
  m.def("refined_eigenbasis", [](std::shared_ptr<PyProxy> proxy, const py::object& V, const py::object& F, int k,
                                 double refine_tolerance, int max_iterations, double tolerance, const py::object& dirichlet,
                                 const py::object& cache) {
        if (!(tolerance > 0)) throw py::value_error("tolerance must be > 0");
        if (!(refine_tolerance > 0) || !std::isfinite(refine_tolerance)) throw py::value_error("refine_tolerance must be > 0");
        if (max_iterations < 1) throw py::value_error("max_iterations must be >= 1");
        const ice::TriangleMesh mesh = mesh_argument(V, F);
        if (mesh.V.rows() != proxy->proxy->fine_size())
          throw py::value_error("(V, F) has " + std::to_string(mesh.V.rows()) + " vertices, the proxy's fine mesh " +
                                std::to_string(proxy->proxy->fine_size()));
        fem::EigenOptions options;
        options.tolerance = tolerance;
        ice::proxy::EigenRefinement refinement;
        refinement.tolerance = refine_tolerance;
        refinement.max_iterations = max_iterations;
        std::vector<ice::Index> fixed;
        if (!dirichlet.is_none()) fixed = index_argument(dirichlet, proxy->proxy->fine_size(), "dirichlet");
        const ice::proxy::Store store = store_argument(cache);
        ice::proxy::Eigenbasis basis;
        ice::proxy::MultigridHierarchy hierarchy;
        {
          py::gil_scoped_release release;
          // The hierarchy through the tufted cover when the proxy's space is one (the same choice).
          const ice::NonmanifoldInput nonmanifold =
              proxy->tufted_cover ? ice::NonmanifoldInput::tufted_cover : ice::NonmanifoldInput::refuse;
          require_clean(mesh, nonmanifold);
          ice::HierarchyOptions hierarchy_options = refinement.hierarchy;
          hierarchy_options.nonmanifold = nonmanifold;
          if (ice::proxy::refinement_needs_hierarchy(*proxy->proxy))
            hierarchy = ice::proxy::multigrid_hierarchy(mesh, hierarchy_options, store);
          basis = ice::proxy::refined_eigenbasis(*proxy->proxy, hierarchy, k, refinement, options, fixed, store);
        }
        py::dict info;
        info["converged"] = basis.converged;
        info["iterations"] = basis.refine_iterations;
        info["guard"] = basis.guard;
        info["coarse_directions"] = basis.coarse_directions;
        info["fine_eigensolve"] = basis.fine_eigensolve;
        info["residuals"] = basis.residuals;
        info["seconds"] = basis.refine_seconds;
        info["eigensolve_seconds"] = basis.eigensolve_seconds;
        info["hierarchy_seconds"] = hierarchy.build_seconds;
        info["hierarchy_cache"] = json_to_python(ice::proxy::cache_json(hierarchy.cache, store));
        info["eigenpairs_cache"] = json_to_python(ice::proxy::cache_json(basis.cache, store));
        return py::make_tuple(std::move(basis.values), std::move(basis.vectors), info);
      },
      py::arg("proxy"), py::arg("V"), py::arg("F"), py::arg("k"), py::kw_only(), py::arg("refine_tolerance") = 1e-6,
      py::arg("max_iterations") = 200, py::arg("tolerance") = 1e-10, py::arg("dirichlet") = py::none(),
      py::arg("cache") = py::none(),
      R"doc((values, vectors, info): the k smallest eigenpairs of L φ = λ M φ refined on the fine mesh (spectral-coarse
--tolerance): the Galerkin Proxy's pairs and a few more, improved by the augmented subspace method (each
Rayleigh-Ritz step also over the prolonged coarse eigenvectors beyond them) preconditioned with a multigrid
V-cycle on (V, F)'s ICE hierarchy (made or loaded through `cache` as by hierarchy(), as are the coarse pairs
it starts from) until each pair's
relative residual |Lφ − λMφ| / (λ|Mφ|) is at most refine_tolerance. (V, F) must be the proxy's input mesh
(only its vertex count is checked: another mesh's hierarchy would precondition worse, not wrongly).
A proxy with as many coarse vertices as its mesh (not coarsened) is solved by the fine eigensolver directly
(info fine_eigensolve True, no hierarchy, nothing stored; iterations only for a tolerance below its residuals).
info: converged, iterations, guard (pairs refined along), coarse_directions, fine_eigensolve, residuals (per pair), seconds
(the refinement's), eigensolve_seconds (the coarse, or fine, eigensolve's), hierarchy_seconds, hierarchy_cache,
eigenpairs_cache. A refinement that stops at max_iterations returns its pairs with
converged False.)doc");
  // A one-dimensional array of any length, or a two-dimensional one of any row count.
  const auto any_vector = [](const py::object& object, const char* name) {
    const py::array a = py::array::ensure(object);
    if (!a || a.ndim() != 1) throw py::value_error(std::string(name) + " must be a one-dimensional array");
    return vector_argument(object, a.shape(0), name);
  };
  const auto basis_argument = [any_vector](const py::object& values, const py::object& vectors) {
    ice::proxy::Eigenbasis basis;
    basis.values = any_vector(values, "values");
    const py::array a = py::array::ensure(vectors);
    if (!a || a.ndim() != 2) throw py::value_error("vectors must be a two-dimensional array (n, k)");
    basis.vectors = matrix_argument(vectors, a.shape(0), "vectors");
    if (basis.vectors.cols() != basis.values.size()) throw py::value_error("vectors need one column per value");
    return basis;
  };
  m.def("heat_kernel_signature", [basis_argument, any_vector](const py::object& values, const py::object& vectors, const py::object& times) {
        const ice::proxy::Eigenbasis basis = basis_argument(values, vectors);
        return ice::proxy::heat_kernel_signature(basis, any_vector(times, "times"));
      },
      py::arg("values"), py::arg("vectors"), py::arg("times"),
      "HKS(x, t) = sum_i exp(-lambda_i t) phi_i(x)^2: one row per vertex, one column per time (> 0).");
  m.def("wave_kernel_signature", [basis_argument, any_vector](const py::object& values, const py::object& vectors,
                                                               const py::object& energies, double sigma) {
        const ice::proxy::Eigenbasis basis = basis_argument(values, vectors);
        return ice::proxy::wave_kernel_signature(basis, any_vector(energies, "energies"), sigma);
      },
      py::arg("values"), py::arg("vectors"), py::arg("energies"), py::arg("sigma"),
      "WKS(x, e): the squared eigenfunctions weighted by exp(-(e - log lambda)^2 / (2 sigma^2)), normalised per e\n"
      "(zero modes left out); one row per vertex, one column per log-energy e.");

  m.def("reconstruction_error", [basis_argument, any_vector](const py::object& values, const py::object& vectors,
                                                              const py::object& mass, const py::object& f) {
        const ice::proxy::Eigenbasis basis = basis_argument(values, vectors);
        const Eigen::Index n = basis.vectors.rows();
        return ice::proxy::reconstruction_error(basis, vector_argument(mass, n, "mass"), vector_argument(f, n, "f"));
      },
      py::arg("values"), py::arg("vectors"), py::arg("mass"), py::arg("f"),
      "||f - Phi Phi^T M f||_M / ||f||_M: how much of f the M-orthonormal basis misses (mass: the lumped mass's\n"
      "diagonal, one entry per vertex; 0 for f = 0).");

  m.def("curvature_corrected_lengths", [](const py::object& V, const py::object& F, const PyCoarseSpace& coarse,
                                          const py::object& lengths, double divisor) {
          const ice::TriangleMesh mesh = require_coarse_space_of(V, F, coarse, "curvature_corrected_lengths");
          const ice::FaceLengths L =
              lengths.is_none() ? coarse.space.mesh.L : lengths_argument(lengths, coarse.space.mesh.F.rows(), "lengths");
          py::gil_scoped_release release;
          return ice::proxy::curvature_corrected_lengths(mesh, coarse.space, L, divisor);
        }, py::arg("V"), py::arg("F"), py::arg("coarse"), py::kw_only(), py::arg("lengths") = py::none(),
        py::arg("divisor") = fem::kProxyCorrectionDivisor,
        "The coarse edge lengths (m×3) scaled by exp(K l²/divisor) for the Gaussian curvature K each coarse face flattens, "
        "gathered from (V, F) through the coarse space's P (fem::curvature_corrected_lengths): what coarse marching "
        "runs on for ICE coarse spaces by default. lengths: the lengths to correct (default: the coarse mesh's own); "
        "divisor: 48 (the default) is what ProxyGeodesicSolver's marching takes, 24 what DistanceOracle's takes.");
  py::class_<PyGeodesicSolver>(m, "ProxyGeodesicSolver", R"doc(Geodesic distance through the coarse proxy (geodesic-coarse).

ProxyGeodesicSolver(proxy, method="marching", time_factor=1.0, subdivisions=1, curvature_correction=None): method "marching" (fast
marching with exact planar updates on the coarse mesh from the sources' points, the squared distance
interpolated to the fine vertices; the default, the more accurate) or "heat" (the heat method on the
coarse operators, heat time t = (time_factor · mean coarse edge length)²). On a mesh of several
components the distance is +inf on the components without a source.
subdivisions: marching on the coarse mesh split 1:4 that many times (the coarse metric unchanged; 0, 1 or
2 measured: 2 is the most accurate, at ~8x the cost per source of 0). For the most accurate distances
coarsen with use="geodesic". curvature_correction: march on edge lengths scaled by exp(K l²/48) for the
Gaussian curvature K each coarse face flattens (geodesic-coarse --curvature-correction); None = for ICE
coarse spaces (not a tufted cover's), not QEM's (measured: 0.79x ICE's error against exact geodesics over 40 meshes x 1-10 %, 1.19x
QEM's).)doc")
      .def(py::init([](std::shared_ptr<PyProxy> proxy, const std::string& method, double time_factor, int subdivisions,
                       const py::object& curvature_correction) {
             if (!(time_factor > 0)) throw py::value_error("time_factor must be > 0");
             fem::ProxyGeodesicOptions options;
             options.method = coarse_distance_method(method);
             // A CoarseProxy keeps no coarse gluing, which marching on a cover's coarse mesh needs where its
             // sheets' sides repeat (and its fine mesh's angle sums are several sheets'): from the coarse space.
             if (options.method == fem::CoarseDistanceMethod::marching && proxy->tufted_cover)
               throw py::value_error("ProxyGeodesicSolver(proxy, method='marching') does not take a tufted cover's Proxy: "
                                     "march from its coarse space (ProxyGeodesicSolver.from_coarse(V, F, coarse), "
                                     "geodesic_distance), or method='heat'");
             options.time_factor = time_factor;
             options.subdivisions = subdivisions;
             options.curvature_correction = curvature_correction_argument(curvature_correction, proxy->method);
             auto solver = std::make_unique<PyGeodesicSolver>();
             py::gil_scoped_release release;
             solver->solver = std::make_unique<fem::ProxyGeodesicSolver>(*proxy->proxy, options);
             return solver;
           }),
           py::arg("proxy"), py::kw_only(), py::arg("method") = "marching", py::arg("time_factor") = 1.0,
           py::arg("subdivisions") = fem::ProxyGeodesicOptions{}.subdivisions, py::arg("curvature_correction") = py::none())
      .def_static("from_coarse", [](const py::object& V, const py::object& F, const PyCoarseSpace& coarse, const std::string& lengths,
                                    int subdivisions, const py::object& curvature_correction) {
             const ice::TriangleMesh mesh = require_coarse_space_of(V, F, coarse, "ProxyGeodesicSolver.from_coarse");
             const bool traced = traced_lengths_argument(lengths, coarse);
             const ice::proxy::CurvatureCorrection correction = curvature_correction_choice(curvature_correction);
             auto solver = std::make_unique<PyGeodesicSolver>();
             ice::FaceLengths L = marching_lengths_argument(mesh, coarse, traced, correction);
             py::gil_scoped_release release;
             solver->solver = std::make_unique<fem::ProxyGeodesicSolver>(ice::with_lengths(coarse.space.mesh, L), coarse.space.P, subdivisions);
             return solver;
           }, py::arg("V"), py::arg("F"), py::arg("coarse"), py::kw_only(), py::arg("lengths") = "auto",
           py::arg("subdivisions") = fem::ProxyGeodesicOptions{}.subdivisions, py::arg("curvature_correction") = py::none(),
           "Coarse marching from a coarse space of (V, F) alone: no Proxy (no fine intrinsic Delaunay mesh, no operators), "
           "which the marching does not need; a tufted cover's coarse space too (its own lengths). The same distances as "
           "ProxyGeodesicSolver(Proxy(V, F, coarse)) on other spaces (with the "
           "curvature correction, up to the vertex areas of the fine triangulation: the input's here, its intrinsic "
           "Delaunay triangulation's there). "
           "lengths: 'traced' (ICE) marches on the coarse edges' lengths traced on the surface (more accurate on "
           "most meshes, at the cost of the tracing), 'intrinsic' on the coarse mesh's own; 'auto' (the default, as "
           "geodesic-coarse --coarse-lengths auto): traced for an ICE coarse space that has its fine-to-coarse map. "
           "subdivisions as for the constructor, and curvature_correction.")
      .def("distance", [](PyGeodesicSolver& s, const py::object& sources) {
             const std::vector<ice::Index> fine_sources = index_argument(sources, s.solver->fine_size(), "sources");
             if (fine_sources.empty()) throw py::value_error("sources is empty");
             py::gil_scoped_release release;
             const std::lock_guard<std::mutex> lock(s.mutex);
             return s.solver->distance(fine_sources, &s.last_times);
           }, py::arg("sources"), "Distance of every vertex to the nearest of `sources` (vertex indices).")
      .def_property_readonly("times", [](PyGeodesicSolver& s) { return times_dict(locked(s.mutex, [&] { return s.last_times; })); },
                             "Seconds of the last distance()'s stages.");

  // ---- tangent vector fields
  py::class_<PyVectorHeat>(m, "VectorHeatSolver", R"doc(The vector heat method (Sharp, Soliman, Crane 2019) on the input triangles, or through a coarse space (vector-coarse).

VectorHeatSolver(V, F, coarse=None, operators="galerkin", time_factor=None, fine="intrinsic_delaunay", solver="sweep",
sweep_passes=50, sweep_coarse_interval=2):
without `coarse`, on (V, F) itself with heat time t = (time_factor · mean edge length)², time_factor 1
by default, discretised on the intrinsic Delaunay triangulation of (V, F) (fine="input": on its
triangles as they are, whose obtuse angles can send far directions anywhere) — fields are given per
vertex in the frames of the input triangles either way; with a
coarse space of (V, F) (ice.coarsen, keep_map=True), through it, as vector-coarse's --vector-solver:
solver="sweep" (the default) takes the distance to the sources by coarse marching and solves the
fine method's systems by Gauss-Seidel passes in order of it, scaled by the kernel's decay along it
(fem::VectorSweepProxy; no fine factorisation; at most sweep_passes passes after the first, which
converge to the fine method's field, with a Galerkin coarse-grid correction of relative errors on the
marching's coarse space before every sweep_coarse_interval-th pass, 0 for none);
solver="diffusion" restricts the sources by the vector prolongation P_vec (complex,
fitted from the fine-to-coarse map) and by P, solves the three diffusions on the coarse mesh with
Galerkin ("galerkin", the default: from the fine operators of `fine`) or the coarse mesh's own
("intrinsic") operators, t = (time_factor · mean coarse edge length)² with time_factor 0.5 by default,
and prolongs them back (operators and time_factor are the diffusion's).

Tangent vectors are complex numbers in each vertex's frame: the angle counter-clockwise from the
vertex's reference edge (at an interior vertex scaled by 2π over its angle sum), the modulus the
length. to_ambient draws a field as 3D vectors; to_tangent turns 3D directions into such numbers.)doc")
      .def(py::init(&make_vector_heat), py::arg("V"), py::arg("F"), py::arg("coarse") = py::none(), py::kw_only(),
           py::arg("operators") = "galerkin", py::arg("time_factor") = py::none(), py::arg("fine") = "intrinsic_delaunay",
           py::arg("solver") = "sweep", py::arg("sweep_passes") = fem::DistanceSweepOptions{}.max_passes,
           py::arg("sweep_coarse_interval") = fem::DistanceSweepOptions{}.coarse_correction_interval)
      .def("interpolate", [](const PyVectorHeat& s, const py::object& sources, const py::object& vectors) {
             const std::vector<ice::Index> vertices = index_argument(sources, s.size(), "sources");
             if (vertices.empty()) throw py::value_error("sources is empty");
             const std::vector<fem::Complex> values = complex_argument(vectors, vertices.size(), "vectors");
             for (const fem::Complex& z : values)
               if (z == fem::Complex(0)) throw py::value_error("vectors must be nonzero (a zero vector has no direction)");
             py::gil_scoped_release release;
             return s.interpolate(vertices, values);
           }, py::arg("sources"), py::arg("vectors"),
           "The smooth field through `vectors` (complex, one per source vertex): one source transports its vector "
           "along shortest geodesics, several are interpolated (directions by the connection Laplacian, magnitudes "
           "by scalar diffusion). Complex array, one tangent vector per vertex.")
      .def("transport", [](const PyVectorHeat& s, long long source, std::complex<double> vector) {
             if (source < 0 || source >= s.size())
               throw py::value_error("source = " + std::to_string(source) + " is out of range (valid 0.." + std::to_string(s.size() - 1) + ")");
             if (!std::isfinite(vector.real()) || !std::isfinite(vector.imag()) || vector == fem::Complex(0))
               throw py::value_error("vector must be a finite nonzero complex number");
             const std::vector<ice::Index> vertices{static_cast<ice::Index>(source)};
             py::gil_scoped_release release;
             return s.interpolate(vertices, {vector});
           }, py::arg("source"), py::arg("vector") = std::complex<double>(1, 0),
           "Parallel transport of `vector` (complex, in the source's frame) from vertex `source` to every vertex.")
      .def("to_ambient", [](const PyVectorHeat& s, const py::object& field) {
             const std::vector<fem::Complex> values = complex_argument(field, static_cast<std::size_t>(s.size()), "field");
             const Eigen::VectorXcd vector = Eigen::Map<const Eigen::VectorXcd>(values.data(), s.size());
             py::gil_scoped_release release;
             return fem::tangent_to_ambient(s.fine.mesh, s.fine.frames, s.V, vector);
           }, py::arg("field"), "A field (complex, one per vertex) as n×3 vectors in the planes of the input triangles.")
      .def("to_tangent", [](const PyVectorHeat& s, const py::object& vertices, const py::object& directions) {
             const std::vector<ice::Index> at = index_argument(vertices, s.size(), "vertices");
             const Eigen::MatrixXd d = matrix_argument(directions, static_cast<Eigen::Index>(at.size()), "directions");
             if (d.cols() != 3) throw py::value_error("directions must have 3 columns");
             Eigen::VectorXcd out(static_cast<Eigen::Index>(at.size()));
             for (std::size_t i = 0; i < at.size(); ++i)
               out(static_cast<Eigen::Index>(i)) =
                   fem::ambient_to_tangent(s.fine.mesh, s.fine.frames, s.V, at[i], d.row(static_cast<Eigen::Index>(i)).transpose());
             return out;
           }, py::arg("vertices"), py::arg("directions"),
           "3D directions (k×3) at `vertices` as tangent vectors (complex): projected into the surface, the length the projection's.")
      .def_property_readonly("vector_prolongation", [](const PyVectorHeat& s) -> py::object {
             if (!s.proxy) return py::none();
             const fem::ComplexSparseMatrix& P = s.proxy->vector_prolongation();
             const py::module_ sparse = py::module_::import("scipy.sparse");
             std::vector<fem::Complex> data(P.valuePtr(), P.valuePtr() + P.nonZeros());
             std::vector<int> indices(P.innerIndexPtr(), P.innerIndexPtr() + P.nonZeros());
             std::vector<int> indptr(P.outerIndexPtr(), P.outerIndexPtr() + P.outerSize() + 1);
             return sparse.attr("csc_matrix")(py::make_tuple(py::array(py::cast(data)), py::array(py::cast(indices)), py::array(py::cast(indptr))),
                                              py::make_tuple(P.rows(), P.cols()));
           }, "P_vec (scipy.sparse.csc_matrix, complex, fine × coarse), None without a coarse space or with solver=\"sweep\".")
      .def_property_readonly("prolongation_stats", [](const PyVectorHeat& s) -> py::object {
             if (!s.proxy) return py::none();
             const fem::VectorProlongationStats& st = s.proxy->prolongation_stats();
             py::dict d;
             d["fitted"] = st.fitted;
             d["from_corner_chart"] = st.from_corner;
             d["unmatched"] = st.unmatched;
             d["median_fit_residual"] = st.median_fit_residual;
             d["poor_fits"] = st.poor_fits;
             return std::move(d);
           }, "How P_vec's frames were fitted (vector-coarse's report keys), None without a coarse space or with solver=\"sweep\".")
      .def_property_readonly("size", &PyVectorHeat::size, "Vertices of (V, F).");

  // ---- multigrid
  m.def(
      "hierarchy",
      [](const py::object& V, const py::object& F, double ratio, const py::object& coarsest, const py::object& max_levels,
         const py::object& threads, bool return_order, const std::string& nonmanifold, const py::object& cache) -> py::object {
        const ice::TriangleMesh mesh = mesh_argument(V, F);
        if (!(ratio > 0 && ratio < 1)) throw py::value_error("ratio must be in (0, 1)");
        ice::HierarchyOptions options;
        options.nonmanifold = choice<ice::NonmanifoldInput>(nonmanifold, "nonmanifold");
        options.ratio = ratio;
        options.coarsest_vertices = bounded_integer(coarsest, "coarsest", 1, std::numeric_limits<int>::max());
        options.max_levels = bounded_integer(max_levels, "max_levels", 1, 1000);
        options.threads = bounded_integer(threads, "threads", 0, 64);
        const ice::proxy::Store store = store_argument(cache);
        ice::proxy::MultigridHierarchy hierarchy;
        {
          py::gil_scoped_release release;
          require_clean(mesh, options.nonmanifold);
          hierarchy = ice::proxy::multigrid_hierarchy(mesh, options, store);
        }
        return hierarchy_to_python(hierarchy, return_order);
      },
      py::arg("V"), py::arg("F"), py::kw_only(), py::arg("ratio") = 0.25, py::arg("coarsest") = 500,
      py::arg("max_levels") = 20, py::arg("threads") = 0, py::arg("return_order") = false, py::arg("nonmanifold") = "refuse",
      py::arg("cache") = py::none(),
      R"doc(The prolongations of an ICE multigrid hierarchy of (V, F) (scipy.sparse.csr_matrix, n_k × n_{k+1}, rows
summing to 1): each level keeps about `ratio` of the previous one's vertices, down to about `coarsest`.
Pass them to MultigridSolver; one hierarchy serves every operator on the mesh's vertices.
cache: None (the default store: $ICE_CACHE, else ~/.cache/ice), False (none) or a directory: a hierarchy
made before with the same mesh and options is loaded from there (checked; the same arrays to the bit).
threads: for the large levels' removals (0: one per core; the result does not depend on it).
return_order=True returns (prolongations, order) instead: the breadth-first numbering the hierarchy
coarsened in (order[new] = old vertex), which MultigridSolver(..., locality_order=order) reuses
instead of ordering the matrix's graph again.
nonmanifold="tufted": a mesh that is not an oriented manifold is coarsened through its tufted cover, the
copies of each vertex one unknown on every level (for the robust Laplacian: the fine_laplacian of
ice.setup_proxy(V, F, nonmanifold="tufted", ...)); an oriented manifold gets the same hierarchy either way.)doc");

  m.def(
      "save_hierarchy",
      [](const std::filesystem::path& path, const py::object& V, const py::object& F, const py::sequence& prolongations,
         const py::object& order, bool overwrite) {
        const ice::TriangleMesh mesh = mesh_argument(V, F);
        ice::proxy::MultigridHierarchy hierarchy;
        hierarchy.fine_vertices = static_cast<ice::Index>(mesh.V.rows());
        hierarchy.prolongations.reserve(prolongations.size());
        for (std::size_t k = 0; k < prolongations.size(); ++k)
          sparse_argument(prolongations[k], "prolongations", false).swap(hierarchy.prolongations.emplace_back());
        if (!order.is_none()) hierarchy.fine_order = index_argument(order, mesh.V.rows(), "order");
        py::gil_scoped_release release;
        try {
          ice::proxy::save_multigrid_hierarchy_file(path, mesh, hierarchy, overwrite);
        } catch (const std::invalid_argument& e) {
          py::gil_scoped_acquire acquire;
          throw py::value_error(e.what());
        }
      },
      py::arg("path"), py::arg("V"), py::arg("F"), py::arg("prolongations"), py::kw_only(), py::arg("order") = py::none(),
      py::arg("overwrite") = false,
      R"doc(Writes a multigrid hierarchy of (V, F) (ice.hierarchy's prolongations, and its order when it was asked
for) to a file that ice.load_hierarchy takes back for the same (V, F) only: binary, checksummed, written
atomically. The hierarchy is checked first (shapes, non-negative weights, rows summing to 1, every coarse
vertex used, the order a permutation): ValueError otherwise. An existing file is replaced only with
overwrite=True (ice.MeshError, kind "unwritable", otherwise).)doc");
  m.def(
      "load_hierarchy",
      [](const std::filesystem::path& path, const py::object& V, const py::object& F, bool return_order) -> py::object {
        const ice::TriangleMesh mesh = mesh_argument(V, F);
        ice::proxy::MultigridHierarchy hierarchy;
        {
          py::gil_scoped_release release;
          hierarchy = ice::proxy::load_multigrid_hierarchy_file(path, mesh);
        }
        return hierarchy_to_python(hierarchy, return_order);
      },
      py::arg("path"), py::arg("V"), py::arg("F"), py::kw_only(), py::arg("return_order") = false,
      R"doc(The hierarchy ice.save_hierarchy wrote for (V, F), as ice.hierarchy returns it (with return_order, the
order too; an empty one if none was saved). Raises RuntimeError naming the file and the defect: no such
file, not a hierarchy, damaged (checksum, size, structure), another format version, or made for another mesh.)doc");

  py::class_<PyMultigrid>(m, "MultigridSolver", R"doc(Galerkin multigrid on given prolongations (ice.hierarchy) for symmetric positive definite systems.

MultigridSolver(prolongations, tolerance=1e-8, max_iterations=200, mode="pcg"|"vcycle",
smoother="sgs"|"gs"|"chebyshev", smoothing_steps=1, threads=0, locality_order=None), then setup(A)
and solve(b). locality_order: the fine unknowns' numbering for the threaded sweeps (the order of
ice.hierarchy(..., return_order=True)); None orders A's graph by reverse Cuthill–McKee. One object
serves one thread at a time (calls from several threads wait for each other).)doc")
      .def(py::init([](const py::list& prolongations, double tolerance, int max_iterations, const std::string& mode,
                       const std::string& smoother, int smoothing_steps, int threads, const py::object& locality_order) {
             std::vector<fem::SparseMatrix> matrices;
             for (std::size_t k = 0; k < prolongations.size(); ++k)
               matrices.push_back(sparse_argument(prolongations[k], ("prolongations[" + std::to_string(k) + "]").c_str(), false));
             std::vector<ice::Index> order;
             if (!locality_order.is_none()) {
               if (matrices.empty()) throw py::value_error("locality_order needs at least one prolongation");
               order = index_argument(locality_order, matrices.front().rows(), "locality_order");
               std::vector<char> listed(order.size(), 0);
               bool permutation = static_cast<Eigen::Index>(order.size()) == matrices.front().rows();
               for (std::size_t i = 0; permutation && i < order.size(); ++i)
                 permutation = !std::exchange(listed[static_cast<std::size_t>(order[i])], 1);
               if (!permutation)
                 throw py::value_error("locality_order must list each of the " + std::to_string(matrices.front().rows()) +
                                       " fine unknowns once");
             }
             auto solver = std::make_unique<PyMultigrid>(
                 std::move(matrices), multigrid_options(tolerance, max_iterations, mode, smoother, smoothing_steps, threads));
             solver->solver.set_locality_order(std::move(order));
             return solver;
           }),
           py::arg("prolongations"), py::kw_only(), py::arg("tolerance") = 1e-8, py::arg("max_iterations") = 200,
           py::arg("mode") = "pcg", py::arg("smoother") = "sgs", py::arg("smoothing_steps") = 1, py::arg("threads") = 0,
           py::arg("locality_order") = py::none())
      .def("setup", [](PyMultigrid& m, const py::object& A, const py::object& constrained) {
             fem::SparseMatrix matrix = sparse_argument(A, "A", true);
             std::vector<ice::Index> fixed;
             if (!constrained.is_none()) fixed = index_argument(constrained, matrix.rows(), "constrained");
             py::gil_scoped_release release;
             const std::lock_guard<std::mutex> lock(m.mutex);
             m.solver.setup(matrix, std::move(fixed));
           }, py::arg("A"), py::arg("constrained") = py::none(),
           R"doc(Galerkin level operators of A (scipy.sparse or dense, n×n, n = rows of the first prolongation) and
the coarsest factorisation; `constrained`: indices (each once) whose values solve() prescribes, in this order.)doc")
      .def("solve", [](PyMultigrid& m, const py::object& b, const py::object& constrained_values, const py::object& x0) {
             Eigen::Index size = 0, constrained = 0;
             {
               py::gil_scoped_release release;
               const std::lock_guard<std::mutex> lock(m.mutex);
               size = m.solver.size();
               constrained = static_cast<Eigen::Index>(m.solver.constrained().size());
             }
             if (size == 0) throw py::value_error("call setup(A) first");
             const Eigen::VectorXd rhs = vector_argument(b, size, "b");
             Eigen::VectorXd values, guess;
             if (!constrained_values.is_none()) values = vector_argument(constrained_values, constrained, "constrained_values");
             if (!x0.is_none()) guess = vector_argument(x0, size, "x0");
             py::gil_scoped_release release;
             const std::lock_guard<std::mutex> lock(m.mutex);
             if (m.solver.size() != size) throw std::invalid_argument("the solver was set up again with another size meanwhile");
             return x0.is_none() ? m.solver.solve(rhs, values) : m.solver.solve(rhs, values, guess);
           }, py::arg("b"), py::arg("constrained_values") = py::none(), py::arg("x0") = py::none(),
           "x with A x = b to the relative residual tolerance (report says how it went); x0: initial guess.")
      .def_property_readonly("report", [](PyMultigrid& m) {
             nlohmann::json report;
             {
               py::gil_scoped_release release;
               const std::lock_guard<std::mutex> lock(m.mutex);
               report = ice::proxy::multigrid_json(m.solver);
             }
             return json_to_python(report);
           }, "The last solve and the set-up, as poisson-coarse --solver multigrid reports them: converged, iterations, "
              "relative_residual, convergence_factor, residuals, seconds, options, levels, operator_complexity.")
      .def_property_readonly("size", [](PyMultigrid& m) {
             py::gil_scoped_release release;
             const std::lock_guard<std::mutex> lock(m.mutex);
             return m.solver.size();
           }, "Unknowns of the system set up (0 before setup()).");

  // ---- the distance oracle
  py::class_<fem::DistanceOracle>(m, "DistanceOracle", R"doc(All-pairs geodesic distances of the fine vertices from the coarse mesh (geodesic-coarse --pairs).

DistanceOracle(coarse, method="marching"|"heat", heat_time_factor=1.0, threads=0, subdivisions=1, lengths=None):
precomputes the coarse all-pairs distances (n_c² floats; marching on the coarse mesh split 1:4
`subdivisions` times); each query then costs a few operations. Needs the coarse
space's map (coarsen(..., keep_map=True), the default); coarsen with use="geodesic" for the metric
measured best for distances (what geodesic-coarse does). lengths: the coarse edge lengths to march on
(m×3, one row per coarse face; default: the coarse mesh's own), e.g.
ice.curvature_corrected_lengths(V, F, coarse). DistanceOracle.from_mesh(V, F, coarse) makes the oracle
of geodesic-coarse's oracle modes (curvature-corrected for ICE; traced lengths on request).)doc")
      .def(py::init([](const PyCoarseSpace& coarse, const std::string& method, double heat_time_factor, int threads,
                       int subdivisions, const py::object& lengths) {
             require_map(coarse);
             const ice::FaceLengths L =
                 lengths.is_none() ? coarse.space.mesh.L : lengths_argument(lengths, coarse.space.mesh.F.rows(), "lengths");
             return make_oracle(coarse, L, coarse_distance_method(method), heat_time_factor, threads, subdivisions);
           }),
           py::arg("coarse"), py::kw_only(), py::arg("method") = "marching", py::arg("heat_time_factor") = 1.0,
           py::arg("threads") = 0, py::arg("subdivisions") = fem::DistanceOracleOptions{}.subdivisions,
           py::arg("lengths") = py::none())
      .def_static("from_mesh", [](const py::object& V, const py::object& F, const PyCoarseSpace& coarse, const std::string& method,
                                  double heat_time_factor, int threads, int subdivisions, const std::string& lengths,
                                  const py::object& curvature_correction) {
             const ice::TriangleMesh mesh = require_coarse_space_of(V, F, coarse, "DistanceOracle.from_mesh");
             require_map(coarse);
             const fem::CoarseDistanceMethod distances = coarse_distance_method(method);
             const bool marching = distances == fem::CoarseDistanceMethod::marching;
             const bool traced = traced_lengths_argument(lengths, coarse, marching);
             const ice::proxy::CurvatureCorrection correction = curvature_correction_choice(curvature_correction);
             if (!marching && correction == ice::proxy::CurvatureCorrection::on)
               throw py::value_error("curvature_correction=True is for method='marching'");
             const ice::FaceLengths L =
                 marching ? marching_lengths_argument(mesh, coarse, traced, correction, fem::kOracleCorrectionDivisor)
                          : coarse.space.mesh.L;
             return make_oracle(coarse, L, distances, heat_time_factor, threads, subdivisions);
           },
           py::arg("V"), py::arg("F"), py::arg("coarse"), py::kw_only(), py::arg("method") = "marching",
           py::arg("heat_time_factor") = 1.0, py::arg("threads") = 0,
           py::arg("subdivisions") = fem::DistanceOracleOptions{}.subdivisions, py::arg("lengths") = "auto",
           py::arg("curvature_correction") = py::none(),
           "The oracle of geodesic-coarse's oracle modes (--pairs, --sample, --all-pairs) from the coarse space of "
           "(V, F): with marching, on the coarse lengths the tool marches on — curvature-corrected for ICE coarse "
           "spaces (curvature_correction=None, as --curvature-correction auto), and for them traced on the surface "
           "(lengths='auto', as --coarse-lengths auto; 'intrinsic' or 'traced' to choose). The constructor marches on "
           "the coarse mesh's own lengths (or those it is given).")
      .def("distance", [](const fem::DistanceOracle& o, long long u, long long v) {
             const Eigen::Index n = o.fine_size();
             if (u < 0 || u >= n || v < 0 || v >= n)
               throw py::value_error("vertex out of range (valid 0.." + std::to_string(n - 1) + ")");
             return o.distance(static_cast<ice::Index>(u), static_cast<ice::Index>(v));
           }, py::arg("u"), py::arg("v"), "Distance between fine vertices u and v.")
      .def("distances", [](const fem::DistanceOracle& o, const py::object& pairs) {
             const py::array array = py::array::ensure(pairs);
             if (!array || array.ndim() != 2 || array.shape(1) != 2)
               throw py::value_error("pairs must have shape (k, 2)");
             const std::vector<ice::Index> flat = index_argument(array.attr("reshape")(-1), o.fine_size(), "pairs");
             std::vector<std::array<ice::Index, 2>> list(flat.size() / 2);
             for (std::size_t i = 0; i < list.size(); ++i) list[i] = {flat[2 * i], flat[2 * i + 1]};
             py::gil_scoped_release release;
             return o.distances(list);
           }, py::arg("pairs"), "Distances of k pairs of fine vertices (k×2 integer array).")
      .def("distances_from", [](const fem::DistanceOracle& o, long long source) {
             if (source < 0 || source >= o.fine_size()) throw py::value_error("source out of range");
             py::gil_scoped_release release;
             return o.distances_from(static_cast<ice::Index>(source));
           }, py::arg("source"), "Distances from one fine vertex to all.")
      .def("distance_matrix", [](const fem::DistanceOracle& o, const py::object& rows, const py::object& cols) {
             const std::vector<ice::Index> r = index_argument(rows, o.fine_size(), "rows");
             const std::vector<ice::Index> c = cols.is_none() ? r : index_argument(cols, o.fine_size(), "cols");
             py::gil_scoped_release release;
             return o.distance_matrix(r, c);
           }, py::arg("rows"), py::arg("cols") = py::none(), "float32 matrix of distances between rows and cols (default rows).")
      .def("farthest_point_samples", [](const fem::DistanceOracle& o, long long count, long long first) {
             if (count < 1 || count > o.fine_size()) throw py::value_error("count must be in 1..number of vertices");
             if (first < 0 || first >= o.fine_size()) throw py::value_error("first out of range");
             std::vector<ice::Index> samples;
             {
               py::gil_scoped_release release;
               samples = o.farthest_point_samples(static_cast<ice::Index>(count), static_cast<ice::Index>(first));
             }
             return to_numpy(std::move(samples));
           }, py::arg("count"), py::arg("first") = 0, "Farthest-point sampling of `count` fine vertices from `first`.")
      .def_property_readonly("fine_size", &fem::DistanceOracle::fine_size, "Fine vertices the oracle answers for.")
      .def_property_readonly("coarse_size", &fem::DistanceOracle::coarse_size, "Coarse vertices (the precomputed table is this squared).")
      .def_property_readonly("memory_bytes", &fem::DistanceOracle::memory_bytes, "Bytes the oracle holds.");
}
