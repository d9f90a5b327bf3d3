#pragma once
/// Helpers shared by the test files.
#include <catch2/catch.hpp>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

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
