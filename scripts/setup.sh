#!/usr/bin/env bash
# scripts/setup.sh : bring a Debian 12 machine to the state ICE needs. Idempotent; quiet when
# everything is already there. Four steps:
#   1. install the missing Debian packages (apt only, --no-install-recommends);
#   2. report which BLAS/LAPACK CHOLMOD will load, and switch the reference BLAS to OpenBLAS;
#   3. make the project's own mesh set in data/default/: the members of CGAL's data archive listed in
#      data/cgal-meshes.txt (vertex counts checked) and the meshes committed compressed in data/meshes/
#      (decompressed, checksums of data/meshes/SHA256SUMS checked). Tests, the report's --quick run and
#      run.sh use only this set;
#   4. install the 3D page's front end (three.js, and playwright-core for its browser test) in
#      apps/viewer/node_modules with `npm ci` (the versions of apps/viewer/package-lock.json).
#
# Environment:
#   ICE_SETUP_SKIP_APT=1     skip step 1 (packages provided some other way)
#   ICE_SETUP_KEEP_BLAS=1    report the BLAS but never switch it
#   ICE_CGAL_DATA_ARCHIVE    path of the CGAL data archive (default: searched, see below)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: ERROR: %s\n' "$*" >&2; exit 1; }

# Run a command as root: directly when we are root, else through sudo.
as_root() {
  if [[ "$(id -u)" -eq 0 ]]; then
    "$@"
  elif command -v sudo >/dev/null 2>&1; then
    sudo "$@"
  else
    die "need root for: $* (not root, and sudo is not installed)"
  fi
}

# ---------------------------------------------------------------------------------------------
# 1. Debian packages
# ---------------------------------------------------------------------------------------------
# libopenblas0-pthread / libopenblas-pthread-dev pin the pthread flavour of OpenBLAS (libopenblas-dev
# alone would accept the openmp or serial one). libcgal-demo is only needed for its data archive;
# with --no-install-recommends it does not pull libcgal-qt5-dev (Qt): its Depends are libcgal-dev
# and, through it, Boost/GMP/MPFR headers. libhypre-dev (which pulls OpenMPI) is only for the
# BoomerAMG comparison in bench/bench_multigrid.cpp; the build works without it. The Python
# package (python/) is built with pybind11 against Debian's python3 and tested with its numpy,
# scipy, pytest and matplotlib (the example draws a picture); ice-batch runs on Dask distributed
# (python3-dask, python3-distributed; tqdm for its progress bar, psutil for its tests). libtinygltf-dev
# writes the binary glTF files of ice/scalar_field_io.h. chromium runs the browser test of the 3D page
# (--html; headless, software WebGL); Node.js and npm install the page's three.js and the test's
# playwright-core (step 4) and are installed from Debian only when the machine has none.
# doxygen builds the API reference of the public headers (docs/Doxyfile.in: target doc, test api_docs).
# clang, its sanitizer runtimes (libclang-rt-dev), OpenMP (libomp-dev) and its linker (lld) build the
# test command's sanitizer configuration (scripts/test.sh). libnanoflann-dev (header-only k-d tree) finds the
# k nearest neighbours of a point cloud's points (ice/point_cloud.h). ninja-build: scripts/test.sh and
# run.sh configure fresh build folders for Ninja, whose builds took ~7 % less time than Make's
# (docs/measurements.md, "The test command's time").
PACKAGES=(
  build-essential cmake pkg-config ninja-build
  libeigen3-dev libsuitesparse-dev libxxhash-dev libspectra-dev
  libopenblas-dev libopenblas0-pthread libopenblas-pthread-dev
  libopenmesh-dev catch2 libbenchmark-dev libcli11-dev nlohmann-json3-dev gnuplot-nox libtinygltf-dev
  libnanoflann-dev
  libcgal-demo libhypre-dev xz-utils chromium
  pybind11-dev python3-dev python3-numpy python3-scipy python3-pytest python3-matplotlib
  python3-dask python3-distributed python3-tqdm python3-psutil
  python3-pip python3-wheel python3-build python3-venv python3-meshio
  doxygen
  clang libclang-rt-dev libomp-dev lld
)

is_installed() {
  [[ "$(dpkg-query -W -f='${Status}' "$1" 2>/dev/null || true)" == "install ok installed" ]]
}

install_packages() {
  if [[ "${ICE_SETUP_SKIP_APT:-0}" == 1 ]]; then
    say "packages: skipped (ICE_SETUP_SKIP_APT=1)"
    return
  fi
  command -v dpkg-query >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1 ||
    die "this is not a Debian-like system (no dpkg-query/apt-get); install the packages listed in docs/design.md (Dependencies) by hand and rerun with ICE_SETUP_SKIP_APT=1"
  local missing=() p
  for p in "${PACKAGES[@]}"; do
    is_installed "$p" || missing+=("$p")
  done
  # Node.js and npm: any the machine has will do (a Node.js from another source often bundles npm,
  # and Debian's npm package would conflict with it).
  command -v node >/dev/null 2>&1 || missing+=(nodejs)
  command -v npm >/dev/null 2>&1 || missing+=(npm)
  if [[ ${#missing[@]} -eq 0 ]]; then
    say "packages: all ${#PACKAGES[@]} present"
    return
  fi
  say "packages: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  # The package lists may be empty (fresh container) or stale: refresh them once before installing.
  as_root apt-get update -qq
  as_root apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  for p in "${missing[@]}"; do
    is_installed "$p" || die "package $p is still not installed after apt-get install"
  done
  say "packages: installed ${#missing[@]}"
}

# ---------------------------------------------------------------------------------------------
# 2. BLAS / LAPACK behind CHOLMOD
# ---------------------------------------------------------------------------------------------
# Debian's libcholmod links libblas.so.3 and liblapack.so.3, which are update-alternatives symlinks.
# The reference (netlib) BLAS makes CHOLMOD's supernodal factorization crawl: a 1M-vertex Laplacian
# took ~129 s on it versus 6.5-11 s on OpenBLAS. So: say what is in use, and switch away from the
# reference implementation.
multiarch() {
  local ma=""
  ma="$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || true)"
  [[ -n "$ma" ]] || ma="$(gcc -print-multiarch 2>/dev/null || true)"
  [[ -n "$ma" ]] || ma="$(uname -m)-linux-gnu"
  printf '%s' "$ma"
}

# Human-readable name of a resolved BLAS/LAPACK shared object.
blas_kind() {
  case "$1" in
    */openblas-pthread/*) echo "OpenBLAS (pthread)" ;;
    */openblas-openmp/*)  echo "OpenBLAS (OpenMP)" ;;
    */openblas-serial/*)  echo "OpenBLAS (serial)" ;;
    *openblas*)           echo "OpenBLAS" ;;
    */blis*)              echo "BLIS" ;;
    */atlas/*)            echo "ATLAS" ;;
    *mkl*)                echo "Intel MKL" ;;
    */blas/libblas*|*/lapack/liblapack*) echo "reference (netlib)" ;;
    "")                   echo "not found" ;;
    *)                    echo "unknown" ;;
  esac
}

check_blas() {
  local ma libdir blas lapack blas_real lapack_real
  ma="$(multiarch)"
  libdir="/usr/lib/$ma"
  blas="$libdir/libblas.so.3"
  lapack="$libdir/liblapack.so.3"
  # What CHOLMOD itself resolves (normally exactly these two symlinks).
  local cholmod
  cholmod="$(ls "$libdir"/libcholmod.so.* 2>/dev/null | head -n1 || true)"
  if [[ -n "$cholmod" ]] && command -v ldd >/dev/null 2>&1; then
    local b l
    b="$(ldd "$cholmod" | awk '$1 == "libblas.so.3" {print $3}')"
    l="$(ldd "$cholmod" | awk '$1 == "liblapack.so.3" {print $3}')"
    [[ -n "$b" ]] && blas="$b"
    [[ -n "$l" ]] && lapack="$l"
  fi
  blas_real="$(readlink -f "$blas" 2>/dev/null || true)"
  lapack_real="$(readlink -f "$lapack" 2>/dev/null || true)"
  [[ -e "$blas_real" ]] || blas_real=""
  [[ -e "$lapack_real" ]] || lapack_real=""

  local blas_kind_s lapack_kind_s
  blas_kind_s="$(blas_kind "$blas_real")"
  lapack_kind_s="$(blas_kind "$lapack_real")"

  if [[ "$blas_kind_s" == "reference (netlib)" || "$lapack_kind_s" == "reference (netlib)" ]] &&
     [[ "${ICE_SETUP_KEEP_BLAS:-0}" != 1 ]]; then
    local ob="$libdir/openblas-pthread"
    [[ -e "$ob/libblas.so.3" && -e "$ob/liblapack.so.3" ]] ||
      die "CHOLMOD uses the reference BLAS/LAPACK and $ob has no OpenBLAS to switch to (install libopenblas0-pthread)"
    say "BLAS: CHOLMOD would use the reference BLAS ($blas_real) / LAPACK ($lapack_real);"
    say "      switching the alternatives to OpenBLAS pthread (reference BLAS: ~129 s vs 6.5-11 s"
    say "      for a 1M-vertex supernodal Cholesky)"
    as_root update-alternatives --quiet --set "libblas.so.3-$ma" "$ob/libblas.so.3"
    as_root update-alternatives --quiet --set "liblapack.so.3-$ma" "$ob/liblapack.so.3"
    blas_real="$(readlink -f "$libdir/libblas.so.3")"
    lapack_real="$(readlink -f "$libdir/liblapack.so.3")"
    blas_kind_s="$(blas_kind "$blas_real")"
    lapack_kind_s="$(blas_kind "$lapack_real")"
  fi
  say "BLAS:   $blas_kind_s : $blas_real"
  say "LAPACK: $lapack_kind_s : $lapack_real"
  if [[ "$blas_kind_s" == "reference (netlib)" ]]; then
    say "WARNING: CHOLMOD will run on the reference BLAS (ICE_SETUP_KEEP_BLAS=1): large solves will be slow"
  fi
}

# ---------------------------------------------------------------------------------------------
# 3. The project's mesh set
# ---------------------------------------------------------------------------------------------
MANIFEST="$ROOT/data/cgal-meshes.txt"
COMMITTED="$ROOT/data/meshes"
DEST="$ROOT/data/default"

find_archive() {
  local c
  for c in "${ICE_CGAL_DATA_ARCHIVE:-}" \
           /usr/share/doc/libcgal-demo/data.tar.gz \
           /usr/share/doc/libcgal-dev/data.tar.gz \
           /usr/share/doc/libcgal-demo/examples/data.tar.gz; do
    if [[ -n "$c" && -s "$c" ]]; then
      printf '%s' "$c"
      return 0
    fi
  done
  return 1
}

# Vertex count from an OFF header ("OFF" then "nv nf ne", possibly on the same line; comments allowed).
off_vertex_count() {
  awk '{ sub(/#.*/, "") } { for (i = 1; i <= NF; ++i) t[++n] = $i } n >= 2 { exit }
       END { if (t[1] ~ /OFF$/ && t[2] ~ /^[0-9]+$/) print t[2]; else print "" }' "$1"
}

extract_meshes() {
  [[ -f "$MANIFEST" ]] || die "missing manifest $MANIFEST"
  local members=() expected=() line member count
  while IFS= read -r line || [[ -n "$line" ]]; do
    line="${line%%#*}"
    read -r member count _ <<<"$line" || true
    [[ -n "${member:-}" ]] || continue
    members+=("$member")
    expected+=("${count:-}")
  done <"$MANIFEST"
  [[ ${#members[@]} -gt 0 ]] || die "manifest $MANIFEST lists no mesh"

  mkdir -p "$DEST"
  local missing=() m
  for m in "${members[@]}"; do
    [[ -s "$DEST/$(basename "$m")" ]] || missing+=("$m")
  done

  if [[ ${#missing[@]} -gt 0 ]]; then
    local archive
    archive="$(find_archive)" ||
      die "CGAL data archive not found (looked in /usr/share/doc/libcgal-demo/ and /usr/share/doc/libcgal-dev/; install libcgal-demo or set ICE_CGAL_DATA_ARCHIVE)"
    local tmp
    tmp="$(mktemp -d "$DEST/.extract.XXXXXX")"
    # Extract into a scratch directory first so a failed or partial extraction never leaves a
    # truncated file in data/default/ that a later run would take as present.
    if ! tar -xzf "$archive" -C "$tmp" "${missing[@]}" 2>"$tmp/tar.err"; then
      cat "$tmp/tar.err" >&2
      rm -rf "$tmp"
      die "could not extract ${missing[*]} from $archive"
    fi
    for m in "${missing[@]}"; do
      mv -f "$tmp/$m" "$DEST/$(basename "$m")"
    done
    rm -rf "$tmp"
    say "meshes: extracted ${#missing[@]} from $archive"
  fi

  local i f n bad=0
  for i in "${!members[@]}"; do
    f="$DEST/$(basename "${members[$i]}")"
    if [[ ! -s "$f" ]]; then
      printf 'setup: ERROR: %s is missing or empty\n' "$f" >&2
      bad=1
      continue
    fi
    if [[ -n "${expected[$i]}" ]]; then
      n="$(off_vertex_count "$f")"
      if [[ "$n" != "${expected[$i]}" ]]; then
        printf 'setup: ERROR: %s: OFF header says %s vertices, manifest expects %s\n' \
          "$f" "${n:-no valid header}" "${expected[$i]}" >&2
        bad=1
      fi
    fi
  done
  [[ $bad -eq 0 ]] || die "the meshes from CGAL's archive are incomplete (delete data/default/ and rerun)"
  say "meshes: ${#members[@]} from CGAL's archive in data/default/"
}

# The committed meshes: data/meshes/NAME.xz -> data/default/NAME, checked against data/meshes/SHA256SUMS
# (checksums of the decompressed files). A file that fails its checksum is decompressed again once.
decompress_committed() {
  local sums="$COMMITTED/SHA256SUMS" sum name made=0
  [[ -f "$sums" ]] || die "missing $sums"
  command -v xz >/dev/null 2>&1 || die "xz is not installed (Debian package xz-utils)"
  mkdir -p "$DEST"
  while read -r sum name; do
    [[ -n "${name:-}" ]] || continue
    [[ -f "$COMMITTED/$name.xz" ]] || die "$sums lists $name but $COMMITTED/$name.xz is missing"
    if [[ -s "$DEST/$name" ]] && sha256sum --quiet --check - <<<"$sum  $DEST/$name" >/dev/null 2>&1; then
      continue
    fi
    # Decompress beside the target and rename, so an interrupted run never leaves a truncated mesh.
    xz --decompress --stdout "$COMMITTED/$name.xz" >"$DEST/.$name.tmp" ||
      die "could not decompress $COMMITTED/$name.xz"
    sha256sum --quiet --check - <<<"$sum  $DEST/.$name.tmp" >/dev/null 2>&1 ||
      die "$COMMITTED/$name.xz does not decompress to the file of $sums (checksum mismatch)"
    mv -f "$DEST/.$name.tmp" "$DEST/$name"
    made=$((made + 1))
  done <"$sums"
  [[ $made -eq 0 ]] || say "meshes: decompressed $made from data/meshes/"
  say "meshes: $(wc -l <"$sums") committed meshes in data/default/"
}

# ---------------------------------------------------------------------------------------------
# 4. The 3D page's front end: apps/viewer/node_modules (three.js, copied beside every page, and
#    playwright-core for the browser test) from the npm registry, exactly as package-lock.json pins
#    them. Redone only when the lock file changed since the last install.
# ---------------------------------------------------------------------------------------------
install_viewer() {
  local dir="$ROOT/apps/viewer" stamp="$ROOT/apps/viewer/node_modules/.ice-lock.sha256" sum
  # Only the 3D pages (--html, ice-report's report.html) and their browser tests need these: without
  # them everything else works, and those say what is missing.
  if ! command -v npm >/dev/null 2>&1; then
    say "viewer: WARNING: npm is not installed (Debian package npm): no 3D pages, their tests fail"
    return
  fi
  sum="$(sha256sum "$dir/package-lock.json" | cut -d' ' -f1)"
  if [[ -f "$stamp" && "$(cat "$stamp")" == "$sum" && -f "$dir/node_modules/three/build/three.cjs" ]]; then
    say "viewer: three.js and playwright-core present"
    return
  fi
  if ! npm ci --prefix "$dir" --no-audit --no-fund --loglevel=error >/dev/null ||
     [[ ! -f "$dir/node_modules/three/build/three.cjs" ]]; then
    say "viewer: WARNING: npm ci in apps/viewer failed (is the npm registry reachable?): no 3D pages, their tests fail"
    return
  fi
  echo "$sum" >"$stamp"
  say "viewer: installed three.js and playwright-core (apps/viewer/node_modules)"
}

install_packages
check_blas
extract_meshes
decompress_committed
install_viewer
