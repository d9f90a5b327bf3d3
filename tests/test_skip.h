#pragma once
/// The test runner's skip status (main.cpp), apart from test_support.h so that the runner compiles
/// without the libraries' headers.
#include <atomic>

namespace ice_test {

/// Exit status of a test binary whose only outcome was a skip (ctest's SKIP_RETURN_CODE; main.cpp).
constexpr int kSkipExitCode = 77;

/// Set when the running test case skipped itself; main.cpp counts the cases that did and turns a clean
/// run whose every case skipped into kSkipExitCode.
inline std::atomic<bool>& skipped() {
  static std::atomic<bool> flag{false};
  return flag;
}

}  // namespace ice_test
