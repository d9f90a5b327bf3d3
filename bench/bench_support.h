#pragma once
/// Helpers shared by the benchmark files.
#include <chrono>
#include <map>

#include <benchmark/benchmark.h>
#include <string>
#include <utility>

#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"
#include "mesh_sets.h"

namespace ice_bench {

/// Seconds since `mark`, and moves `mark` to now (a lap timer for the phases inside one iteration).
inline double seconds_since(std::chrono::steady_clock::time_point& mark) {
  const auto now = std::chrono::steady_clock::now();
  const double s = std::chrono::duration<double>(now - mark).count();
  mark = now;
  return s;
}

/// Path of a mesh of the project set (or the extended set); the project set's path when in neither, so
/// that the load error names where the mesh was expected.
inline std::string mesh_path(const std::string& name) {
  const std::string path = ice_mesh_sets::find(name);
  return path.empty() ? ice_mesh_sets::project_dir() + "/" + name : path;
}

/// True when `name` is in the project or the extended set. Otherwise the benchmark is skipped with a
/// message naming the mesh and both folders (benchmarks on extended-set meshes keep their published
/// inputs; they do not fall back to another mesh).
inline bool has_mesh(benchmark::State& state, const std::string& name) {
  if (!ice_mesh_sets::find(name).empty()) return true;
  state.SkipWithError((name + " is in neither the project set (" + ice_mesh_sets::project_dir() +
                       ") nor the extended set (" + ice_mesh_sets::extended_dir() + ", $ICE_EXTENDED_MESHES)")
                          .c_str());
  return false;
}

/// A mesh Loop-subdivided `levels` times, loaded and subdivided once per process.
inline const ice::TriangleMesh& subdivided_mesh(const std::string& name, int levels = 0) {
  static std::map<std::pair<std::string, int>, ice::TriangleMesh> cache;
  const auto key = std::make_pair(name, levels);
  auto it = cache.find(key);
  if (it == cache.end()) {
    ice::TriangleMesh m = ice::load_mesh(mesh_path(name));
    if (levels > 0) m = ice::loop_subdivide(m, levels);
    it = cache.emplace(key, std::move(m)).first;
  }
  return it->second;
}

}  // namespace ice_bench
