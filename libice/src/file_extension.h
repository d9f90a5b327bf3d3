#pragma once
// Internal to libice: a path's extension in lower case, without the dot ("Mesh.PLY" -> "ply"); how
// the readers and writers choose a format.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

namespace ice {

inline std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty() && ext[0] == '.') ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace ice
