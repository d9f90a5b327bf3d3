#pragma once
/// Helpers shared by the benchmark files.
#include <cstdlib>
#include <map>
#include <string>
#include <utility>

#include "ice/mesh_generators.h"
#include "ice/mesh_io.h"

namespace ice_bench {

/// Path of a shared mesh: $ICE_SHARED_MESHES, else ../shared/data/meshes beside the sources.
inline std::string shared_mesh_path(const std::string& name) {
  const char* env = std::getenv("ICE_SHARED_MESHES");
  return std::string(env ? env : ICE_SHARED_MESHES_DIR) + "/" + name;
}

/// A shared mesh Loop-subdivided `levels` times, loaded and subdivided once per process.
inline const ice::TriangleMesh& subdivided_shared_mesh(const std::string& name, int levels = 0) {
  static std::map<std::pair<std::string, int>, ice::TriangleMesh> cache;
  const auto key = std::make_pair(name, levels);
  auto it = cache.find(key);
  if (it == cache.end()) {
    ice::TriangleMesh m = ice::load_mesh(shared_mesh_path(name));
    if (levels > 0) m = ice::loop_subdivide(m, levels);
    it = cache.emplace(key, std::move(m)).first;
  }
  return it->second;
}

}  // namespace ice_bench
