// The test runner: Catch2's session, plus ctest's skip status. ctest runs one test case per process
// (catch_discover_tests) or, under the sanitizers, the cases of one file per process (tests/CMakeLists.txt).
// A run whose every case skipped itself (ICE_SKIP_WITHOUT_EXTENDED_SET) and failed nothing exits with
// kSkipExitCode, which tests/CMakeLists.txt declares as SKIP_RETURN_CODE; a run where some cases skipped
// and the rest passed passes. A failed assertion exits non-zero as usual, whether or not a case skipped.
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include "test_skip.h"

namespace {

int cases_run = 0;
int cases_skipped = 0;

// Counts the cases that ran and those that skipped themselves (the flag is per case).
struct SkipCounter : Catch::TestEventListenerBase {
  using TestEventListenerBase::TestEventListenerBase;
  void testCaseStarting(const Catch::TestCaseInfo& info) override {
    ice_test::skipped() = false;
    TestEventListenerBase::testCaseStarting(info);
  }
  void testCaseEnded(const Catch::TestCaseStats& stats) override {
    ++cases_run;
    if (ice_test::skipped()) ++cases_skipped;
    TestEventListenerBase::testCaseEnded(stats);
  }
};

}  // namespace

CATCH_REGISTER_LISTENER(SkipCounter)

int main(int argc, char* argv[]) {
  const int failures = Catch::Session().run(argc, argv);
  if (failures == 0 && cases_run > 0 && cases_skipped == cases_run) return ice_test::kSkipExitCode;
  // Never let a run with exactly 77 failed assertions read as a skip.
  return failures == ice_test::kSkipExitCode ? failures + 1 : failures;
}
