#pragma once
/// Helpers shared by the test files.
#include <catch2/catch.hpp>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>
#include <vector>

#include <unistd.h>

#include "ice/intrinsic_mesh_io.h"
#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "mesh_sets.h"
#include "test_skip.h"

namespace ice_test {

/// The failed conditions of a sweep over many elements, counted, the first few described: one
/// assertion per sweep (ICE_SWEEP_REPORT) instead of one per element, whose cost dominates large
/// sweeps in the sanitizer build. The description is made only on failure.
class SweepChecks {
 public:
  template <class Describe>
  void check(bool ok, const char* expression, Describe&& context) {
    if (ok) return;
    if (failures_++ < 5) text_ += std::string(expression) + " failed: " + context() + "\n";
  }
  long long failures() const { return failures_; }
  const std::string& text() const { return text_; }

 private:
  long long failures_ = 0;
  std::string text_;
};
/// Checks `expression` within a sweep, `context` a callable returning what the element is.
#define ICE_SWEEP_CHECK(sweep, expression, context) (sweep).check(static_cast<bool>(expression), #expression, context)
/// The sweep's one assertion: no condition failed (the first failures' descriptions as the message).
#define ICE_SWEEP_REPORT(sweep)    \
  do {                             \
    INFO((sweep).text());          \
    CHECK((sweep).failures() == 0); \
  } while (false)

/// A fresh, empty directory for one test case's store (TMP/ice-store-test-NAME-PID, emptied if it
/// exists); NAME must be unique across the suite, whose cases run in parallel processes.
inline std::filesystem::path fresh_store(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("ice-store-test-" + name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir;
}

/// A file's bytes, and a file written with given bytes (replaced): for damaging store entries.
inline std::vector<char> read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), {});
}
inline void write_bytes(const std::filesystem::path& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}


/// ‖result − reference‖ / ‖reference‖ (Frobenius for matrices, sparse ones too).
template <class Result, class Reference>
double relative_difference(const Result& result, const Reference& reference) {
  return (result - reference).eval().norm() / reference.norm();
}

/// The unit icosphere of 2,562 vertices (ice::make_icosphere(4)), made once per process.
inline const ice::TriangleMesh& unit_sphere() {
  static const ice::TriangleMesh mesh = ice::make_icosphere(4);
  return mesh;
}

/// Path of a mesh of the project set (data/default/, made by scripts/setup.sh). Every clone has it,
/// so a missing file fails the test (it does not skip), saying how to make it.
inline std::string project_mesh(const std::string& name) {
  const std::string path = ice_mesh_sets::project_dir() + "/" + name;
  if (!std::filesystem::is_regular_file(path))
    FAIL("project mesh missing: " << path << " (scripts/setup.sh makes data/default/; see data/README.md)");
  return path;
}

/// True, after saying so, when the extended mesh set is absent: the calling test then returns early and
/// ctest counts it as skipped (see ICE_SKIP_WITHOUT_EXTENDED_SET).
inline bool skip_without_extended_set() {
  if (ice_mesh_sets::extended_present()) return false;
  WARN("SKIPPED: this test needs the extended mesh set, which is absent: " << ice_mesh_sets::extended_dir()
       << " (set ICE_EXTENDED_MESHES to the folder of the meshes listed in data/README.md)");
  skipped() = true;
  return true;
}

/// Path of a mesh of the extended set, once the caller has checked the set is present; a file missing
/// from a present set fails the test.
inline std::string extended_mesh(const std::string& name) {
  const std::string path = ice_mesh_sets::extended_dir() + "/" + name;
  if (!std::filesystem::is_regular_file(path)) FAIL("extended-set mesh missing: " << path);
  return path;
}

/// Paths for a sweep over real meshes: every project-set name (a missing file fails), then the
/// extended-set names when that set is present (breadth; a bare clone runs the project part only).
inline std::vector<std::string> mesh_sweep(std::initializer_list<const char*> project_names,
                                           std::initializer_list<const char*> extended_names = {}) {
  std::vector<std::string> paths;
  for (const char* name : project_names) paths.push_back(project_mesh(name));
  if (ice_mesh_sets::extended_present())
    for (const char* name : extended_names) paths.push_back(extended_mesh(name));
  return paths;
}

/// Writes T.compact() as .ilm to `path`, reads it back and checks the round trip is exact: the same
/// faces, lengths (bit for bit), gluing and vertex map, and a valid triangulation with the same Euler
/// characteristic, boundary vertices and total curvature. Returns the mesh written.
inline ice::CompactMesh check_ilm_round_trip(const ice::IntrinsicTriangulation& T, const std::string& path) {
  const ice::CompactMesh written = T.compact();
  ice::write_intrinsic_mesh(path, written, T.num_input_vertices());
  const ice::IntrinsicMeshFile file = ice::read_intrinsic_mesh(path);
  CHECK(file.version == 2);
  CHECK(file.F == written.F);
  CHECK(file.L == written.L);
  CHECK(file.twin == written.twin);
  CHECK(file.to_input == written.to_input);
  const ice::IntrinsicTriangulation back = ice::triangulation_of(file, path);
  CHECK(back.validate() == "");
  CHECK(back.euler_characteristic() == T.euler_characteristic());
  CHECK(std::abs(back.total_curvature() - T.total_curvature()) < 1e-9 * std::max<double>(1, T.num_vertices()));
  const ice::CompactMesh again = back.compact();
  CHECK(again.F == written.F);
  CHECK(again.L == written.L);
  CHECK(again.twin == written.twin);
  int boundary_before = 0, boundary_after = 0;
  for (ice::Index v = 0; v < T.num_input_vertices(); ++v)
    if (T.vertex_alive(v)) boundary_before += T.is_boundary_vertex(v);
  for (ice::Index v = 0; v < back.num_input_vertices(); ++v) boundary_after += back.is_boundary_vertex(v);
  CHECK(boundary_after == boundary_before);
  return written;
}

/// Expect a MeshError of the given kind whose message names the file and contains `needle`.
template <class F>
inline void require_mesh_error(F&& call, ice::MeshError::Kind kind, const std::string& path, const std::string& needle) {
  try {
    call();
    FAIL("expected ice::MeshError containing '" << needle << "'");
  } catch (const ice::MeshError& e) {
    INFO(e.what());
    CHECK(e.kind() == kind);
    CHECK(std::string(e.what()).find(path) != std::string::npos);
    CHECK(std::string(e.what()).find(needle) != std::string::npos);
  }
}

/// A fresh directory under the system temp dir, removed (with its contents) when the test ends.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("ice_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  /// Writes `content` (binary) to a file in the directory and returns its path.
  std::string write(const std::string& name, const std::string& content) const {
    std::ofstream(file(name), std::ios::binary) << content;
    return file(name);
  }

 private:
  std::filesystem::path path_;
};

}  // namespace ice_test

/// First statement of a test case that needs the extended mesh set: without it the case ends here and
/// ctest reports it as skipped (never as passed).
#define ICE_SKIP_WITHOUT_EXTENDED_SET()                   \
  do {                                                    \
    if (::ice_test::skip_without_extended_set()) return;  \
  } while (false)
