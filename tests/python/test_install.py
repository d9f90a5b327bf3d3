"""`pip install .`: the wheel pyproject.toml's backend (python/pep517_backend) makes from the source tree,
installed offline (--no-index) into a fresh `python3 -m venv --system-site-packages` venv, whose
numpy and scipy are the system's (Debian's), then imported and run there.

To stay fast the wheel packs this test's own build (ICE_BUILD_DIR, set by ctest) as it is, through the
backend's config settings build-dir=... no-build=1; a user's `pip install .` builds from scratch in
a temporary folder instead (the same configure/install/zip steps, plus the compile). Nothing is
written into the source tree: wheels, venv and runs live in tmp_path.
"""
import base64
import csv
import hashlib
import io
import os
import pathlib
import re
import subprocess
import sys
import sysconfig
import zipfile

import pytest

import ice

ROOT = pathlib.Path(__file__).resolve().parents[2]
MESHES = pathlib.Path(os.environ.get("ICE_PROJECT_MESHES") or os.environ.get("ICE_PROJECT_MESHES_DIR")
                      or ROOT / "data" / "default")
# The small example run when README.md has no Python section with a ```python block.
SMALL_EXAMPLE = """
import ice, numpy as np
V, F = ice.load_mesh(%r)
d = ice.geodesic_distance(V, F, [0])
assert d[0] == 0 and np.isfinite(d).all() and d.max() > 0, d
print("ok", d.max())
"""


def _build_dir() -> pathlib.Path:
    build = os.environ.get("ICE_BUILD_DIR")
    if build:
        return pathlib.Path(build)
    guess = pathlib.Path(ice.__file__).resolve().parents[2]  # <build>/python/ice/__init__.py
    if (guess / "CMakeCache.txt").exists():
        return guess
    pytest.skip("ICE_BUILD_DIR is not set and ice is not imported from a build tree (run through ctest)")


def _environment(**more) -> dict:
    """The subprocesses' environment: not the build tree's package (ctest's PYTHONPATH), no pip network."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV") and not k.startswith("ICE_WHEEL_")}
    env.update(PIP_DISABLE_PIP_VERSION_CHECK="1", PIP_NO_INPUT="1", **more)
    return env


def _run(command, **kw) -> subprocess.CompletedProcess:
    result = subprocess.run([str(c) for c in command], capture_output=True, text=True,
                            env=kw.pop("env", None) or _environment(), **kw)
    if result.returncode != 0:
        raise AssertionError(f"{' '.join(map(str, command))} exited {result.returncode}:\n"
                             f"{result.stdout[-4000:]}\n{result.stderr[-6000:]}")
    return result


@pytest.fixture(scope="module")
def venv(tmp_path_factory) -> pathlib.Path:
    """A fresh venv of this interpreter that sees the system's packages (numpy, scipy, pytest)."""
    path = tmp_path_factory.mktemp("install") / "venv"
    made = subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(path)],
                          capture_output=True, text=True, env=_environment())
    if made.returncode != 0:
        message = made.stdout + made.stderr
        if "ensurepip" in message or "venv" in message:
            pytest.skip(f"{sys.executable} cannot make a venv with pip (Debian: apt-get install python3-venv): "
                        f"{message.strip().splitlines()[-1] if message.strip() else made.returncode}")
        raise AssertionError(f"python3 -m venv failed:\n{message}")
    python = path / "bin" / "python"
    if subprocess.run([str(python), "-m", "pip", "--version"], capture_output=True).returncode != 0:
        pytest.skip("the venv has no pip (Debian: apt-get install python3-venv python3-pip)")
    return path


def _settings(build: pathlib.Path) -> list[str]:
    return ["--config-settings", f"build-dir={build}", "--config-settings", "no-build=1"]


def test_wheel_has_the_package_and_valid_metadata(venv, tmp_path):
    wheels = tmp_path / "wheels"
    _run([venv / "bin" / "python", "-m", "pip", "wheel", "--no-index", "--no-build-isolation", "--no-deps",
          "-w", wheels, *_settings(_build_dir()), ROOT], cwd=tmp_path)
    [wheel] = wheels.glob("*.whl")
    version = re.search(r"project\s*\(\s*ICE\s+VERSION\s+([0-9.]+)", (ROOT / "CMakeLists.txt").read_text()).group(1)
    assert wheel.name.startswith(f"ice_mesh-{version}-cp{sys.version_info.major}{sys.version_info.minor}-"), wheel.name
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
        info = f"ice_mesh-{version}.dist-info"
        extension = f"ice/_ice{sysconfig.get_config_var('EXT_SUFFIX')}"
        package = {p.name for p in (ROOT / "python" / "ice").iterdir() if p.is_file() and p.suffix != ".pyc"}
        assert {extension, *(f"ice/{p}" for p in package)} <= names, names
        assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
        metadata = archive.read(f"{info}/METADATA").decode()
        assert f"Version: {version}\n" in metadata and "Requires-Dist: numpy\n" in metadata
        assert "ice-batch = ice.batch:main" in archive.read(f"{info}/entry_points.txt").decode()
        assert "Root-Is-Purelib: false" in archive.read(f"{info}/WHEEL").decode()
        rows = list(csv.reader(io.StringIO(archive.read(f"{info}/RECORD").decode())))
        assert {row[0] for row in rows} == names
        for name, digest, size in rows:
            if name == f"{info}/RECORD":
                assert digest == size == ""
                continue
            data = archive.read(name)
            expected = "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            assert (digest, int(size)) == (expected, len(data)), name


def test_pip_install_offline_then_import_and_run(venv, tmp_path):
    python = venv / "bin" / "python"
    # `pip install .` with build isolation (the default): the backend needs nothing, so nothing is downloaded.
    _run([python, "-m", "pip", "install", "--no-index", *_settings(_build_dir()), ROOT], cwd=tmp_path)
    shown = _run([python, "-m", "pip", "show", "ice-mesh"]).stdout
    assert "Name: ice-mesh" in shown
    # Imported from the venv, not from the build tree; numpy and scipy are the system's.
    where = _run([python, "-c", "import ice, numpy, scipy; print(ice.__file__); print(numpy.__file__)"],
                 cwd=tmp_path).stdout.split()
    assert where[0].startswith(str(venv)), where
    assert not where[1].startswith(str(venv)), where  # not downloaded into the venv
    assert "--scheduler" in _run([venv / "bin" / "ice-batch", "--help"], cwd=tmp_path).stdout

    out = _run([python, "-c", SMALL_EXAMPLE % str(MESHES / "spot.obj")], cwd=tmp_path).stdout
    assert out.startswith("ok ")
    # The README's Python example (the section "## In Python", or "## Python"), with the project's meshes.
    code = _readme_example()
    if code is None:
        return
    code = code.replace('"data/default/', f'"{MESHES}/').replace("'data/default/", f"'{MESHES}/")
    run_dir = tmp_path / "readme"
    run_dir.mkdir()
    _run([python, "-c", code], cwd=run_dir)


def _readme_example() -> str | None:
    readme = (ROOT / "README.md").read_text()
    for heading in ("\n## In Python\n", "\n## Python\n"):
        if heading in readme:
            section = readme[readme.index(heading) + len(heading):]
            section = section[:section.index("\n## ")] if "\n## " in section else section
            match = re.search(r"```python\n(.*?)\n```", section, re.DOTALL)
            if match:
                return match.group(1)
    return None
