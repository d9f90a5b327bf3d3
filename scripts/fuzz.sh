#!/usr/bin/env bash
# scripts/fuzz.sh — fuzz every input reader with libFuzzer. Not part of the test command; the inputs it
# finds become regression tests (tests/fuzz/regressions/<kind>/, replayed by test_fuzz_regressions).
#
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET] [KIND ...]     (default 600 s; kinds: obj off ply stl ilm numbers)
#
# 1. builds build/fuzz with clang (ICE_FUZZ=ON: coverage, ASan, UBSan everywhere);
# 2. seeds build/fuzz/corpus/<kind>/ from tests/fuzz/regressions/<kind>/ and small meshes of the
#    project set (data/default/, made by scripts/setup.sh), converted to each format by ice-info;
# 3. runs each target for SECONDS_PER_TARGET (2 jobs at once on 2 cores: libFuzzer's -fork mode), with
#    inputs up to 8 KiB, a 10 s timeout per input and 2 GiB of memory. Findings (crash-*, timeout-*,
#    oom-*) land in build/fuzz/findings/<kind>/; the script lists them and exits 1 if there are any.
#
# To keep a finding: fix the defect, then copy the file into tests/fuzz/regressions/<kind>/.
# Needs Debian's clang-14 and libclang-rt-14-dev (libFuzzer); install them with apt if missing.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
SECONDS_PER_TARGET="${1:-600}"
shift || true
KINDS=("$@")
[[ ${#KINDS[@]} -gt 0 ]] || KINDS=(obj off ply stl ilm numbers)
BUILD="$ROOT/build/fuzz"
JOBS="${ICE_JOBS:-2}"

command -v clang++-14 >/dev/null || { echo "fuzz.sh: clang++-14 missing (apt-get install clang-14 libclang-rt-14-dev)" >&2; exit 2; }
[[ -d data/default ]] || bash scripts/setup.sh
mkdir -p "$BUILD"

cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_COMPILER=clang++-14 -DICE_FUZZ=ON \
  -DICE_BUILD_TESTS=OFF -DICE_BUILD_BENCH=OFF -DICE_BUILD_APPS=ON >"$BUILD.configure.log" 2>&1 ||
  { cat "$BUILD.configure.log" >&2; exit 2; }
targets=()
for kind in "${KINDS[@]}"; do targets+=("fuzz_$kind"); done
cmake --build "$BUILD" --parallel "$JOBS" --target ice-info ice-coarsen "${targets[@]}"

# Seeds: the regression inputs and small real meshes in every mesh format.
small=(hourglass_ico.obj triple_vierbein.obj cat_head.obj eight.off boxpart.obj degtri_sliding.off)
for kind in "${KINDS[@]}"; do
  corpus="$BUILD/corpus/$kind"
  mkdir -p "$corpus" "$BUILD/findings/$kind"
  cp -f tests/fuzz/regressions/"$kind"/* "$corpus"/ 2>/dev/null || true
  case "$kind" in
    obj|off|ply|stl)
      for mesh in "${small[@]}"; do
        "$BUILD/apps/ice-info" "data/default/$mesh" --repair -o "$corpus/${mesh%.*}.$kind" --force >/dev/null 2>&1 || true
      done ;;
    ilm)
      for mesh in cat_head.obj eight.off; do
        "$BUILD/apps/ice-coarsen" "data/default/$mesh" --ratio 0.1 -o "$BUILD/ilm_seed" --force -q >/dev/null 2>&1 &&
          cp "$BUILD/ilm_seed/coarse.ilm" "$corpus/${mesh%.*}.ilm"
      done ;;
  esac
done

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
for kind in "${KINDS[@]}"; do
  echo "fuzz.sh: fuzz_$kind for ${SECONDS_PER_TARGET}s"
  "$BUILD/tests/fuzz/fuzz_$kind" "$BUILD/corpus/$kind" -max_total_time="$SECONDS_PER_TARGET" -max_len=8192 \
    -timeout=10 -rss_limit_mb=2048 -fork="$JOBS" -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
    -artifact_prefix="$BUILD/findings/$kind/" >"$BUILD/fuzz_$kind.log" 2>&1 || true
  grep -E "^#[0-9]+: cov|DONE|INFO: exiting" "$BUILD/fuzz_$kind.log" | tail -n 2 || true
done

findings=$(find "$BUILD/findings" -type f | sort)
if [[ -n "$findings" ]]; then
  echo "fuzz.sh: findings (reproduce: build/fuzz/tests/fuzz/fuzz_KIND FILE):"
  echo "$findings"
  exit 1
fi
echo "fuzz.sh: no findings in ${#KINDS[@]} targets x ${SECONDS_PER_TARGET}s"
