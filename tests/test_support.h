#pragma once
/// Helpers shared by the test files.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace ice_test {

/// The folder of shared real meshes: $ICE_SHARED_MESHES, else ../shared/data/meshes beside the
/// source tree. Tests that need it FAIL (not skip) when it is missing, saying so.
inline std::string shared_meshes_dir() {
  const char* env = std::getenv("ICE_SHARED_MESHES");
  const std::string dir = env ? env : ICE_SHARED_MESHES_DIR;
  if (!std::filesystem::is_directory(dir))
    FAIL("this test needs the shared meshes folder, which is missing: " << dir
         << " (set ICE_SHARED_MESHES to its location)");
  return dir;
}

/// Path of one shared mesh; fails the test when the file is missing.
inline std::string shared_mesh(const std::string& name) {
  const std::string path = shared_meshes_dir() + "/" + name;
  if (!std::filesystem::exists(path)) FAIL("shared mesh missing: " << path);
  return path;
}

}  // namespace ice_test
