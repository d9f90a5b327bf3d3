#!/usr/bin/env bash
# scripts/run.sh — THE main command.
#
#   bash scripts/run.sh [MESH] [EXTRA ARGS...]
#
# 1. scripts/setup.sh (packages, BLAS check, default meshes),
# 2. Release configure of build/release (the same build tree as scripts/test.sh),
# 3. the main job on MESH (default: the first mesh of data/cgal-meshes.txt), which builds the
#    tool it needs and runs it; EXTRA ARGS go to the tool.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="$ROOT/build/release"
JOBS="${ICE_JOBS:-2}"

# ---- THE MAIN JOB: what run.sh does. `app NAME ARGS...` builds the CMake target NAME in
# build/release and runs it. $MESH is the input mesh, "$@" the extra arguments (given to the tool).
# Today: heat flow, 1,000 backward-Euler steps with every 100th state written out, stepped on an ICE
# coarse proxy with 5% of the vertices (at least 1,000) and compared, state by state, with the same
# steps on the fine mesh (CHOLMOD with the fastest ordering measured, factored once). The proxy's
# setup is kept in the store of set-up proxies, so a second run loads it.
MAIN_REPORT=""
main_job() {
  local args=("$@") has_report=0
  for a in "${args[@]}"; do [[ "$a" == --report* ]] && has_report=1; done
  if [[ $has_report -eq 0 ]]; then
    MAIN_REPORT="$BUILD_DIR/main-job-report.json"  # run.sh's own file: replaced, never a user's
    rm -f "$MAIN_REPORT"
    args+=(--report "$MAIN_REPORT")
  fi
  app heat-coarse "$MESH" --ratio 0.05 --min-vertices 1000 --steps 1000 --output-every 100 "${args[@]}"
}
# -----------------------------------------------------------------------------------------------

say() { printf 'run.sh: %s\n' "$*"; }
die() { printf 'run.sh: ERROR: %s\n' "$*" >&2; exit 1; }

# Wall-clock time in milliseconds, and "1.234s" from a millisecond count.
now_ms() { local t="${EPOCHREALTIME/[.,]/}"; echo $((10#$t / 1000)); }
fmt_s() { printf '%d.%03ds' $(($1 / 1000)) $(($1 % 1000)); }
BUILD_MS=0
app() {
  local name="$1"; shift
  local t0
  t0=$(now_ms)
  say "building $name (Release)"
  cmake --build "$BUILD_DIR" --target "$name" --parallel "$JOBS" >"$BUILD_DIR/run-build.log" 2>&1 || {
    tail -n 40 "$BUILD_DIR/run-build.log" >&2
    die "build of target '$name' failed (full log: $BUILD_DIR/run-build.log)"
  }
  BUILD_MS=$(($(now_ms) - t0))
  local exe="$BUILD_DIR/apps/$name"
  [[ -x "$exe" ]] || exe="$(find "$BUILD_DIR" -path "$BUILD_DIR/CMakeFiles" -prune -o -type f -name "$name" -perm -u+x -print | head -n1)"
  [[ -n "$exe" ]] || die "target '$name' built but no executable named '$name' found under $BUILD_DIR"
  say "running: ${exe#"$ROOT"/} $*"
  echo "------------------------------------------------------------------------"
  (cd "$CALLER_DIR" && "$exe" "$@")
}

# The mesh: argument (relative to the caller's directory) or the first default mesh.
if [[ $# -gt 0 && "$1" != -* ]]; then
  [[ -e "$1" ]] || die "no such mesh file: $1"
  MESH="$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
  shift
else
  MESH=""
fi

# The tool runs in the caller's directory: output paths among ARGS (--html, -o, --report) are the caller's.
CALLER_DIR="$PWD"
cd "$ROOT"
T0=$(now_ms)
bash scripts/setup.sh
if [[ -z "$MESH" ]]; then
  first="$(sed -e 's/#.*//' data/cgal-meshes.txt | awk 'NF { print $1; exit }')"
  [[ -n "$first" ]] || die "data/cgal-meshes.txt lists no mesh"
  MESH="$ROOT/data/default/$(basename "$first")"
fi
[[ -s "$MESH" ]] || die "mesh file missing or empty: $MESH"

say "configuring build/release"
GENERATOR=()  # a fresh folder for Ninja when it is installed (one configured before keeps its generator)
[[ ! -f "$BUILD_DIR/CMakeCache.txt" ]] && command -v ninja >/dev/null 2>&1 && GENERATOR=(-G Ninja)
mkdir -p "$BUILD_DIR"
cmake -S . -B "$BUILD_DIR" "${GENERATOR[@]}" -DCMAKE_BUILD_TYPE=Release >"$BUILD_DIR/run-configure.log" 2>&1 || {
  cat "$BUILD_DIR/run-configure.log" >&2
  die "cmake configure failed"
}

say "mesh: ${MESH#"$ROOT"/} ($(du -h "$MESH" | cut -f1))"
t_job=$(now_ms)
rc=0
main_job "$@" || rc=$?
echo "------------------------------------------------------------------------"
t_end=$(now_ms)
job_ms=$((t_end - t_job - BUILD_MS))
if [[ $rc -eq 0 ]]; then
  if [[ -n "$MAIN_REPORT" && -s "$MAIN_REPORT" ]] && command -v python3 >/dev/null; then
    # Both routes' totals from the tool's report: ICE (its setup, from the store or not, and the steps)
    # against the fine route (assembly, factorisation, the steps).
    python3 - "$MAIN_REPORT" <<'PY' || true
import json, sys
r = json.load(open(sys.argv[1]))
t = r["timings_s"]
if "reference" in t:
    print(f"run.sh: ICE {t['proxy_total']:.3f} s (setup: {r['cache']['status']}) vs fine {t['reference']:.3f} s "
          f"({r.get('reference_ordering', '?')} ordering): {r['speedup']['total']:.2f}x end to end, "
          f"relative L2 error {100 * r['error']['rel_l2']:.2f}% at worst")
PY
  fi
  say "done: main job OK on ${MESH#"$ROOT"/} (build $(fmt_s "$BUILD_MS"), job $(fmt_s "$job_ms"), total $(fmt_s $((t_end - T0))))"
else
  say "FAILED: main job exited with status $rc on ${MESH#"$ROOT"/} (total $(fmt_s $((t_end - T0))))"
fi
exit $rc
