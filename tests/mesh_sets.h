#pragma once
/// Where the tests, the benchmarks and ice-report find real meshes. Two sets:
///
///  - the **project set**: data/default/, made by scripts/setup.sh from the meshes committed in
///    data/meshes/ and from CGAL's data archive (Debian's libcgal-demo). Every clone has it once setup
///    has run; data/README.md lists each mesh with its source and licence.
///  - the **extended set**: meshes the project may not redistribute (Stanford scans, files without a
///    licence), in $ICE_EXTENDED_MESHES, else ../shared/data/meshes beside the repository. Optional:
///    what needs it is skipped, saying so, when it is absent.
///
/// ICE_PROJECT_MESHES_DIR and ICE_EXTENDED_MESHES_DIR are compile definitions (target ice_mesh_sets).
#include <cstdlib>
#include <filesystem>
#include <string>

namespace ice_mesh_sets {

/// The project set's folder: $ICE_PROJECT_MESHES if set (a relocated build), else data/default/.
inline std::string project_dir() {
  const char* env = std::getenv("ICE_PROJECT_MESHES");
  return env && *env ? env : ICE_PROJECT_MESHES_DIR;
}

/// The extended set's folder ($ICE_EXTENDED_MESHES, else the configured default), whether or not it exists.
inline std::string extended_dir() {
  const char* env = std::getenv("ICE_EXTENDED_MESHES");
  return env && *env ? env : ICE_EXTENDED_MESHES_DIR;
}

inline bool extended_present() { return std::filesystem::is_directory(extended_dir()); }

/// Path of a mesh by file name: the project set first, then the extended set; "" if in neither.
inline std::string find(const std::string& name) {
  for (const std::string& dir : {project_dir(), extended_dir()}) {
    const std::filesystem::path path = std::filesystem::path(dir) / name;
    if (std::filesystem::is_regular_file(path)) return path.string();
  }
  return {};
}

}  // namespace ice_mesh_sets
