#!/usr/bin/env bash
# scripts/test.sh — THE test command (CI runs it through .ci/run).
#
#   1. scripts/setup.sh                         packages, BLAS check, the project's mesh set (data/default/)
#   2. Release build in build/release           cmake + build (-j2) + ctest
#   3. ASan+UBSan build in build/asan           Debug, ICE_SANITIZE=ON, no benchmarks, clang if present;
#                                               cmake + build + ctest
#
# Every phase runs even if an earlier test phase failed (a failed build skips its own ctest); the
# script exits non-zero if anything failed. ctest is strict: --no-tests=error, --output-on-failure.
#
# Environment:
#   ICE_JOBS=N            parallel build/test jobs (default 2: the reference machine has 2 cores)
#   ICE_TEST_ONLY=release|asan   run only one of the two configurations
#   ICE_CTEST_ARGS="..."  extra ctest arguments (e.g. "-R mesh")
#   ICE_EXTENDED_MESHES=DIR   the extended mesh set (default: ../shared/data/meshes beside the
#                         repository); without it the tests that need it are skipped, and counted so
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

JOBS="${ICE_JOBS:-2}"
ONLY="${ICE_TEST_ONLY:-}"
read -r -a EXTRA_CTEST <<<"${ICE_CTEST_ARGS:-}"

# Tests run two at a time on two cores: keep OpenBLAS and OpenMP (multigrid) from starting their
# own threads on top (tests that exercise threads ask for them explicitly).
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
# Idle OpenMP threads sleep instead of spinning: two test processes share the two cores, and clang's
# OpenMP (the sanitizer build's) spins 200 ms after every parallel region by default, taking the core
# the other test needs (docs/measurements.md, "The test command's time").
export OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-passive}"
# Sanitizers: stop at the first error, with a stack trace; leak checking on.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:halt_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"

PHASES=()        # "name seconds status"
FAILED=0
TOTAL_PASSED=0
TOTAL_FAILED=0
TOTAL_SKIPPED=0
T_START=$SECONDS

# phase NAME CMD...: run, time and record one step.
phase() {
  local name="$1"; shift
  local t0=$SECONDS rc=0
  printf '\n===== test.sh: %s =====\n' "$name"
  "$@" || rc=$?
  local dt=$((SECONDS - t0))
  if [[ $rc -eq 0 ]]; then
    PHASES+=("$name:${dt}s:ok")
  else
    PHASES+=("$name:${dt}s:FAILED($rc)")
    FAILED=1
  fi
  return $rc
}

# run_ctest DIR: ctest with a copy of the output kept to count results.
run_ctest() {
  local dir="$1" log="$1/ctest-output.log" rc=0
  ctest --test-dir "$dir" --output-on-failure --no-tests=error -j "$JOBS" "${EXTRA_CTEST[@]}" 2>&1 |
    tee "$log" || rc=$?
  # "100% tests passed, 0 tests failed out of 57"; ctest counts skipped tests among the passed ones
  # and lists them as "  12 - name (Skipped)" under "The following tests did not run:".
  local line total failed skipped
  line="$(grep -E '[0-9]+% tests passed, [0-9]+ tests? failed out of [0-9]+' "$log" | tail -n1 || true)"
  if [[ -n "$line" ]]; then
    failed="$(sed -E 's/.* ([0-9]+) tests? failed out of.*/\1/' <<<"$line")"
    total="$(sed -E 's/.*out of ([0-9]+).*/\1/' <<<"$line")"
    skipped="$(grep -cE '^[[:space:]]*[0-9]+ - .*\(Skipped\)[[:space:]]*$' "$log" || true)"
    TOTAL_PASSED=$((TOTAL_PASSED + total - failed - skipped))
    TOTAL_FAILED=$((TOTAL_FAILED + failed))
    TOTAL_SKIPPED=$((TOTAL_SKIPPED + skipped))
  elif [[ $rc -ne 0 ]]; then
    TOTAL_FAILED=$((TOTAL_FAILED + 1))   # ctest itself failed (no tests found, crash...)
  fi
  return $rc
}

# A fresh build folder is configured for Ninja when it is installed (a folder configured before keeps
# its generator: CMake cannot switch one).
generator_for() {
  [[ ! -f "$1/CMakeCache.txt" ]] && command -v ninja >/dev/null 2>&1 && echo "-GNinja"
  return 0
}

# config NAME DIR CMAKE-ARGS...: configure, build, test one configuration.
config() {
  local name="$1" dir="$2"; shift 2
  local generator
  generator="$(generator_for "$dir")"
  phase "$name configure" cmake -S . -B "$dir" ${generator:+"$generator"} -DICE_BUILD_TESTS=ON "$@" || return 0
  phase "$name build" cmake --build "$dir" --parallel "$JOBS" || return 0
  phase "$name ctest" run_ctest "$dir" || true
}

phase "setup" bash scripts/setup.sh || {
  echo "test.sh: setup failed; not building" >&2
  printf '\ntest.sh summary: %s\n' "${PHASES[*]}"
  echo "test.sh: 0 passed, 1 failed, 0 skipped"
  exit 1
}

if [[ -z "$ONLY" || "$ONLY" == release ]]; then
  config "release" build/release -DCMAKE_BUILD_TYPE=Release -DICE_SANITIZE=OFF -DICE_BUILD_APPS=ON -DICE_BUILD_BENCH=ON
fi
if [[ -z "$ONLY" || "$ONLY" == asan ]]; then
  # Debug keeps assertions (no NDEBUG) and Eigen's bounds checks; -O1 instead of -O0 because
  # Eigen-heavy code under ASan at -O0 is several times slower and the CI budget is 90 minutes.
  # -g1: line tables only, all a sanitizer's stack trace reads (file:line per frame); full debug
  # information of the template-heavy code was a third of this build's time (docs/measurements.md,
  # "The test command's time"). Build with -g yourself to debug in gdb.
  # clang when present (scripts/setup.sh installs it): the same sanitizers, ~40 % less compile time than
  # GCC's and a third of the start-up time per test process (docs/measurements.md, "The test command's
  # time"); the release build stays GCC's, the compiler the product's figures are measured with.
  # lld when present: it links the sanitized binaries (line tables, instrumented code) several times
  # faster than GNU ld (docs/measurements.md, "The test command's time").
  SANITIZER_COMPILERS=()
  SANITIZER_CXX=c++
  if command -v clang++ >/dev/null 2>&1 && command -v clang >/dev/null 2>&1; then
    SANITIZER_COMPILERS=(-DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++)
    SANITIZER_CXX=clang++
    if command -v ld.lld >/dev/null 2>&1; then
      SANITIZER_COMPILERS+=(-DCMAKE_EXE_LINKER_FLAGS=-fuse-ld=lld -DCMAKE_SHARED_LINKER_FLAGS=-fuse-ld=lld
                            -DCMAKE_MODULE_LINKER_FLAGS=-fuse-ld=lld)
    fi
  fi
  # A folder configured with the other compiler is made afresh: CMake would drop its cache on the
  # switch and could lose the options given with it.
  if [[ -f build/asan/CMakeCache.txt ]]; then
    cached_cxx="$(sed -n 's/^CMAKE_CXX_COMPILER:[A-Z]*=//p' build/asan/CMakeCache.txt)"
    cached_is_clang=0; wanted_is_clang=0
    [[ "$(basename "$cached_cxx")" == clang* ]] && cached_is_clang=1
    [[ "$SANITIZER_CXX" == clang* ]] && wanted_is_clang=1
    if [[ $cached_is_clang -ne $wanted_is_clang ]]; then
      echo "test.sh: build/asan was configured with $cached_cxx: making it afresh with $SANITIZER_CXX"
      rm -rf build/asan
    fi
  fi
  config "asan" build/asan "${SANITIZER_COMPILERS[@]}" -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-g1 -O1" \
    -DICE_SANITIZE=ON -DICE_BUILD_APPS=ON -DICE_BUILD_BENCH=OFF -DICE_BUILD_ACCURACY_TOOLS=OFF -DICE_BUILD_DOCS=OFF
fi

TOTAL=$((SECONDS - T_START))
printf '\n===== test.sh summary =====\n'
for p in "${PHASES[@]}"; do
  IFS=: read -r n t s <<<"$p"
  printf '  %-20s %6s  %s\n' "$n" "$t" "$s"
done
printf '  %-20s %6s\n' "total" "${TOTAL}s"
if [[ $FAILED -eq 0 ]]; then
  echo "test.sh: ALL PASSED (${ONLY:-release + asan}) in ${TOTAL}s"
else
  echo "test.sh: FAILED (see the phases above) after ${TOTAL}s"
  [[ $TOTAL_FAILED -gt 0 ]] || TOTAL_FAILED=1
fi
echo "test.sh: ${TOTAL_PASSED} passed, ${TOTAL_FAILED} failed, ${TOTAL_SKIPPED} skipped"
exit $FAILED
