"""PEP 517 build backend of the ice Python package: drives the project's CMake build.

`pip install .` and `python3 -m build` call this module (pyproject.toml: build-backend, backend-path).
It needs nothing but the standard library, cmake and a C++ toolchain, so it builds offline, with or
without build isolation ([build-system] requires = []). A wheel is made in four steps:

  1. configure the project (Release; no tools, tests, benchmarks or docs) with this interpreter as
     Python_EXECUTABLE, in a temporary build directory, removed afterwards;
  2. build the target ice_python (the extension ice._ice and the libraries it links), 2 jobs;
  3. `cmake --install --component python` into a staging folder: the extension and the pure-Python
     files (python/CMakeLists.txt's install rules define the package's layout);
  4. zip that ice/ folder with a .dist-info (METADATA from pyproject.toml's [project] table, the
     version from CMakeLists.txt's project(ICE VERSION ...), WHEEL, entry_points.txt, RECORD).

Config settings (pip install . --config-settings KEY=VALUE; python3 -m build -C KEY=VALUE), each
also read from an environment variable:

  build-dir  ICE_WHEEL_BUILD_DIR   build there and keep it (a later build only recompiles what
                                   changed). An empty or absent folder is configured as in step 1;
                                   one this backend configured before is configured again with this
                                   interpreter; any other configured build tree (e.g. a developer's
                                   build/release) is used as it is, never reconfigured.
  no-build   ICE_WHEEL_NO_BUILD=1  with build-dir: skip step 2, pack what that tree has built.
  jobs       ICE_WHEEL_JOBS        parallel build jobs (default CMAKE_BUILD_PARALLEL_LEVEL, else 2).
  cmake-args ICE_WHEEL_CMAKE_ARGS  more configure arguments (shell words), e.g. "-DCMAKE_CXX_COMPILER=clang++".
"""
from __future__ import annotations

import base64
import contextlib
import hashlib
import io
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import tempfile
import time
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = "ice"  # the import package the wheel holds
MARKER = "ice-wheel-build-dir"  # left in the build directories this backend configured
# Zip entries get this time (1980-01-01, the earliest zip allows) unless SOURCE_DATE_EPOCH says otherwise.
ZIP_EPOCH = 315532800

__all__ = [
    "build_sdist", "build_wheel", "get_requires_for_build_sdist", "get_requires_for_build_wheel",
    "prepare_metadata_for_build_wheel",
]


def _say(message: str) -> None:
    print(f"ice build backend: {message}", file=sys.stderr, flush=True)


class BuildError(RuntimeError):
    pass


# ---- the project's metadata ----------------------------------------------------------------------

def _pyproject() -> dict:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        try:
            import tomli as tomllib
        except ModuleNotFoundError:
            raise BuildError("reading pyproject.toml needs Python >= 3.11 (tomllib) or the package tomli") from None
    with open(ROOT / "pyproject.toml", "rb") as file:
        return tomllib.load(file)["project"]


def _version() -> str:
    text = (ROOT / "CMakeLists.txt").read_text()
    match = re.search(r"project\s*\(\s*ICE\s+VERSION\s+([0-9][0-9A-Za-z.]*)", text)
    if not match:
        raise BuildError(f"no project(ICE VERSION ...) in {ROOT / 'CMakeLists.txt'}")
    return match.group(1)


def _normalized(name: str) -> str:
    """The distribution name as wheel and sdist file names spell it (PEP 427/625)."""
    return re.sub(r"[-_.]+", "_", name).lower()


def _with_extra(requirement: str, extra: str) -> str:
    requirement, _, marker = requirement.partition(";")
    marker = marker.strip()
    condition = f'extra == "{extra}"'
    return f"{requirement.strip()}; ({marker}) and {condition}" if marker else f"{requirement.strip()}; {condition}"


def _metadata() -> tuple[str, str, str]:
    """(name, version, METADATA text) from pyproject.toml's [project] and CMakeLists.txt."""
    project = _pyproject()
    name, version = project["name"], _version()
    lines = ["Metadata-Version: 2.1", f"Name: {name}", f"Version: {version}"]
    if "description" in project:
        lines.append(f"Summary: {project['description']}")
    if "requires-python" in project:
        lines.append(f"Requires-Python: {project['requires-python']}")
    for label, url in project.get("urls", {}).items():
        lines.append(f"Project-URL: {label}, {url}")
    for requirement in project.get("dependencies", []):
        lines.append(f"Requires-Dist: {requirement}")
    for extra, requirements in project.get("optional-dependencies", {}).items():
        lines.append(f"Provides-Extra: {extra}")
        lines += [f"Requires-Dist: {_with_extra(r, extra)}" for r in requirements]
    return name, version, "\n".join(lines) + "\n"


def _entry_points() -> str:
    project, text = _pyproject(), ""
    for group, key in (("console_scripts", "scripts"), ("gui_scripts", "gui-scripts")):
        if project.get(key):
            text += f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in project[key].items()) + "\n"
    return text


def _wheel_tag() -> str:
    """This interpreter's most specific tag: the extension is built for it alone (e.g. cp311-cp311-linux_x86_64)."""
    implementation = {"cpython": "cp", "pypy": "pp"}.get(sys.implementation.name, sys.implementation.name)
    python = f"{implementation}{sys.version_info.major}{sys.version_info.minor}"
    soabi = sysconfig.get_config_var("SOABI") or ""
    if implementation == "cp":
        abi = f"cp{sys.version_info.major}{sys.version_info.minor}" + (sys.abiflags if hasattr(sys, "abiflags") else "")
    else:
        abi = re.sub(r"[-.]", "_", soabi.rsplit("-", 2)[0]) if soabi else "none"
    platform = re.sub(r"[-.]", "_", sysconfig.get_platform())
    return f"{python}-{abi}-{platform}"


# ---- configuration -------------------------------------------------------------------------------

def _setting(config_settings: dict | None, key: str, variable: str) -> str | None:
    value = (config_settings or {}).get(key)
    if isinstance(value, list):  # pip gives a list when a key is repeated: the last wins
        value = value[-1] if value else None
    return value if value not in (None, "") else (os.environ.get(variable) or None)


def _true(value: str | None) -> bool:
    return (value or "").strip().lower() in ("1", "true", "yes", "on")


def _cache_entry(build_dir: pathlib.Path, name: str) -> str | None:
    try:
        text = (build_dir / "CMakeCache.txt").read_text(errors="replace")
    except OSError:
        return None
    match = re.search(rf"^{re.escape(name)}:[A-Z]+=(.*)$", text, re.MULTILINE)
    return match.group(1) if match else None


def _run(command: list[str]) -> None:
    _say(" ".join(shlex.quote(str(word)) for word in command))
    result = subprocess.run([str(word) for word in command], stdout=sys.stderr)
    if result.returncode != 0:
        raise BuildError(f"{command[0]} exited {result.returncode} (the output above says why)")


def _configure(build_dir: pathlib.Path, cmake: str, config_settings: dict | None) -> None:
    extra = shlex.split(_setting(config_settings, "cmake-args", "ICE_WHEEL_CMAKE_ARGS") or "")
    _run([cmake, "-S", ROOT, "-B", build_dir, "-DCMAKE_BUILD_TYPE=Release", "-DICE_BUILD_APPS=OFF",
          "-DICE_BUILD_TESTS=OFF", "-DICE_BUILD_BENCH=OFF", "-DICE_BUILD_DOCS=OFF", "-DICE_BUILD_PYTHON=ON",
          f"-DPython_EXECUTABLE={sys.executable}", *extra])
    (build_dir / MARKER).write_text("configured by python/pep517_backend/ice_build_backend.py; "
                                    "configured again with the building interpreter on every wheel build\n")


def _prepare(build_dir: pathlib.Path, cmake: str, config_settings: dict | None) -> None:
    """Configures build_dir unless it is someone else's configured tree (then it is used as it is)."""
    home = _cache_entry(build_dir, "CMAKE_HOME_DIRECTORY")
    if home and pathlib.Path(home).resolve() != ROOT:
        raise BuildError(f"{build_dir} is a build of {home}, not of {ROOT}: give another build-dir")
    if not (build_dir / "CMakeCache.txt").exists() or (build_dir / MARKER).exists():
        build_dir.mkdir(parents=True, exist_ok=True)
        _configure(build_dir, cmake, config_settings)
        return
    _say(f"using the configured build {build_dir} as it is (Python_EXECUTABLE="
         f"{_cache_entry(build_dir, 'Python_EXECUTABLE')}); not configured again")


def _stage(build_dir: pathlib.Path, stage: pathlib.Path, config_settings: dict | None) -> pathlib.Path:
    """Builds (unless no-build) and installs the python component into stage; returns the staged ice/ folder."""
    cmake = shutil.which("cmake")
    if not cmake:
        raise BuildError("cmake not found on PATH (Debian: apt-get install cmake build-essential)")
    no_build = _true(_setting(config_settings, "no-build", "ICE_WHEEL_NO_BUILD"))
    if no_build:
        if not (build_dir / "CMakeCache.txt").exists():
            raise BuildError(f"no-build: {build_dir} is not a configured build")
        _say(f"no-build: packing what {build_dir} has built")
    else:
        _prepare(build_dir, cmake, config_settings)
        jobs = _setting(config_settings, "jobs", "ICE_WHEEL_JOBS") or os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or "2"
        start = time.monotonic()
        _run([cmake, "--build", build_dir, "--config", "Release", "--target", "ice_python", "--parallel", jobs])
        _say(f"built ice_python in {time.monotonic() - start:.0f} s")
    # The python component: the extension and the pure-Python files (python/CMakeLists.txt).
    _run([cmake, "--install", build_dir, "--config", "Release", "--component", "python", "--prefix", stage, "--strip"])
    found = sorted(p.parent for p in stage.rglob(f"{PACKAGE}/__init__.py"))
    if not found:  # a tree configured before the rules had COMPONENT python: install it all, take the package
        _say("no 'python' install component in this build tree (configured before it existed): installing everything")
        _run([cmake, "--install", build_dir, "--config", "Release", "--prefix", stage])
        found = sorted(p.parent for p in stage.rglob(f"{PACKAGE}/__init__.py"))
    if len(found) != 1:
        raise BuildError(f"expected one {PACKAGE}/__init__.py installed under {stage}, found {found or 'none'} "
                         "(is ICE_PYTHON_INSTALL_DIR an absolute path in this build?)")
    package = found[0]
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    if not (package / f"_ice{suffix}").exists():
        built = sorted(p.name for p in package.glob("_ice*"))
        raise BuildError(f"the build {build_dir} made {built or 'no extension'}, not _ice{suffix} for this Python "
                         f"({sys.executable}, Python {sys.version.split()[0]}); its Python_EXECUTABLE is "
                         f"{_cache_entry(build_dir, 'Python_EXECUTABLE')}. Build with this interpreter "
                         "(or without build-dir).")
    return package


# ---- wheel ---------------------------------------------------------------------------------------

def _record_hash(data: bytes) -> str:
    return "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()


def _zip_time() -> tuple:
    epoch = max(int(os.environ.get("SOURCE_DATE_EPOCH", ZIP_EPOCH)), ZIP_EPOCH)
    return time.gmtime(epoch)[:6]


def _dist_info_files(name: str, version: str, metadata: str) -> dict[str, bytes]:
    files = {"METADATA": metadata.encode(),
             "WHEEL": (f"Wheel-Version: 1.0\nGenerator: ice_build_backend {version}\n"
                       f"Root-Is-Purelib: false\nTag: {_wheel_tag()}\n").encode()}
    entry_points = _entry_points()
    if entry_points:
        files["entry_points.txt"] = entry_points.encode()
    return files


def _write_wheel(path: pathlib.Path, contents: list[tuple[str, bytes, int]], dist_info: str) -> None:
    """contents: (name in the wheel, bytes, unix mode); RECORD is added last."""
    stamp = _zip_time()
    record = [f"{name},{_record_hash(data)},{len(data)}" for name, data, _ in contents]
    record.append(f"{dist_info}/RECORD,,")
    contents = contents + [(f"{dist_info}/RECORD", ("\n".join(record) + "\n").encode(), 0o644)]
    partial = path.with_suffix(".part")
    with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, data, mode in contents:
            info = zipfile.ZipInfo(name, date_time=stamp)
            info.external_attr = (0o100000 | mode) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, data)
    partial.replace(path)


def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_sdist(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    name, version, metadata = _metadata()
    dist_info = f"{_normalized(name)}-{version}.dist-info"
    folder = pathlib.Path(metadata_directory) / dist_info
    folder.mkdir(parents=True, exist_ok=True)
    for file, data in _dist_info_files(name, version, metadata).items():
        (folder / file).write_bytes(data)
    return dist_info


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    start = time.monotonic()
    name, version, metadata = _metadata()
    dist_info = f"{_normalized(name)}-{version}.dist-info"
    wheel = pathlib.Path(wheel_directory) / f"{_normalized(name)}-{version}-{_wheel_tag()}.whl"
    build_dir = _setting(config_settings, "build-dir", "ICE_WHEEL_BUILD_DIR")
    with contextlib.ExitStack() as stack:
        scratch = pathlib.Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="ice-wheel-")))
        if build_dir:
            build_dir = pathlib.Path(build_dir).expanduser().resolve()
        else:
            build_dir = scratch / "build"
            _say(f"building in the temporary folder {build_dir} (removed afterwards; "
                 "--config-settings build-dir=DIR keeps one)")
        package = _stage(build_dir, scratch / "stage", config_settings)
        contents = []
        for path in sorted(package.rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".pyc":
                mode = 0o755 if path.stat().st_mode & 0o111 else 0o644  # as installed
                contents.append((f"{PACKAGE}/{path.relative_to(package).as_posix()}", path.read_bytes(), mode))
        contents += [(f"{dist_info}/{file}", data, 0o644)
                     for file, data in _dist_info_files(name, version, metadata).items()]
        pathlib.Path(wheel_directory).mkdir(parents=True, exist_ok=True)
        _write_wheel(wheel, contents, dist_info)
    _say(f"wrote {wheel} ({wheel.stat().st_size / 1e6:.1f} MB) in {time.monotonic() - start:.0f} s")
    return wheel.name


# ---- sdist ---------------------------------------------------------------------------------------

# Never in an sdist: build trees, the mesh set scripts/setup.sh makes, caches, the viewer's npm folder.
_SDIST_SKIP = re.compile(r"^(build[^/]*|data/default|\.git|\.cache)(/|$)|(^|/)(__pycache__|node_modules)(/|$)|\.pyc$")


def _source_files() -> list[str]:
    """The tree's files: git's (tracked and untracked-not-ignored) in a checkout, else a walk."""
    try:
        listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                                capture_output=True, check=True).stdout.decode().split("\0")
        if (ROOT / ".git").exists():
            files = [f for f in listed if f and (ROOT / f).is_file()]
            return sorted(set(f for f in files if not _SDIST_SKIP.search(f)))
    except (OSError, subprocess.CalledProcessError):
        pass
    files = []
    for directory, names, file_names in os.walk(ROOT):
        relative = pathlib.Path(directory).relative_to(ROOT).as_posix()
        relative = "" if relative == "." else relative + "/"
        names[:] = [n for n in names if not _SDIST_SKIP.search(relative + n)]
        files += [relative + f for f in file_names if not _SDIST_SKIP.search(relative + f)]
    return sorted(files)


def build_sdist(sdist_directory, config_settings=None):
    name, version, metadata = _metadata()
    base = f"{_normalized(name)}-{version}"
    target = pathlib.Path(sdist_directory) / f"{base}.tar.gz"
    mtime = max(int(os.environ.get("SOURCE_DATE_EPOCH", ZIP_EPOCH)), 0)

    def clean(info: tarfile.TarInfo) -> tarfile.TarInfo:
        info.uid = info.gid = 0
        info.uname = info.gname = ""
        info.mtime = mtime
        return info

    pathlib.Path(sdist_directory).mkdir(parents=True, exist_ok=True)
    with tarfile.open(target, "w:gz", format=tarfile.PAX_FORMAT) as archive:
        for file in _source_files():
            archive.add(ROOT / file, f"{base}/{file}", recursive=False, filter=clean)
        info = clean(tarfile.TarInfo(f"{base}/PKG-INFO"))
        data = metadata.encode()
        info.size, info.mode = len(data), 0o644
        archive.addfile(info, io.BytesIO(data))
    _say(f"wrote {target}")
    return target.name
