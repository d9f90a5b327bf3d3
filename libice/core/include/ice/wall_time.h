#pragma once
/// \file wall_time.h
/// The wall time the libraries report their steps in (summaries, phase times).
#include <chrono>

namespace ice {

/// Seconds of std::chrono::steady_clock since `start`.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace ice
