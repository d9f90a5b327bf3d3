// The test runner: Catch2's session, plus ctest's skip status. catch_discover_tests runs one test case
// per process; a case that skipped itself (ICE_SKIP_WITHOUT_EXTENDED_SET) and failed nothing exits with
// kSkipExitCode, which tests/CMakeLists.txt declares as SKIP_RETURN_CODE. A case that failed an
// assertion exits non-zero as usual, whether or not it also skipped.
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include "test_skip.h"

int main(int argc, char* argv[]) {
  const int failures = Catch::Session().run(argc, argv);
  if (failures == 0 && ice_test::skipped()) return ice_test::kSkipExitCode;
  // Never let a run with exactly 77 failed assertions read as a skip.
  return failures == ice_test::kSkipExitCode ? failures + 1 : failures;
}
