#pragma once
// What the readers of store entries share (stored_setup.cpp, multigrid.cpp).
#include <chrono>
#include <stdexcept>
#include <string>

namespace ice::proxy::detail {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Throws std::runtime_error "path: what" unless `ok`: the store then treats the entry as damaged.
inline void require(bool ok, const std::string& path, const std::string& what) {
  if (!ok) throw std::runtime_error(path + ": " + what);
}

}  // namespace ice::proxy::detail
