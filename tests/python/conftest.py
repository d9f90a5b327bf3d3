"""Shared fixtures of the Python package's tests (run by ctest: python/CMakeLists.txt sets PYTHONPATH
to the build's package and ICE_BIN_DIR to its tools)."""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest


def _project_meshes() -> pathlib.Path:
    return pathlib.Path(os.environ.get("ICE_PROJECT_MESHES") or os.environ.get("ICE_PROJECT_MESHES_DIR")
                        or pathlib.Path(__file__).resolve().parents[2] / "data" / "default")


def extended_meshes() -> pathlib.Path:
    return pathlib.Path(os.environ.get("ICE_EXTENDED_MESHES") or os.environ.get("ICE_EXTENDED_MESHES_DEFAULT")
                        or pathlib.Path(__file__).resolve().parents[3] / "shared" / "data" / "meshes")


def pytest_configure(config):
    # Debian's dask.distributed (2022.12) on its tornado: a deprecation inside tornado, not ours.
    config.addinivalue_line("filterwarnings", "ignore:make_current is deprecated:DeprecationWarning")


@pytest.fixture(scope="session")
def project_mesh():
    """Path of a mesh of the project set (data/default, made by scripts/setup.sh)."""
    def path(name: str) -> pathlib.Path:
        p = _project_meshes() / name
        if not p.exists():
            pytest.fail(f"{p} is missing: run scripts/setup.sh to make the project's mesh set")
        return p
    return path


@pytest.fixture(scope="session")
def tool():
    """Runs one of this build's tools; returns the CompletedProcess (stdout/stderr as text)."""
    bin_dir = os.environ.get("ICE_BIN_DIR")
    if not bin_dir:
        pytest.skip("ICE_BIN_DIR is not set (run through ctest to compare with the tools)")

    def run(name: str, *args, check: bool = True) -> subprocess.CompletedProcess:
        result = subprocess.run([str(pathlib.Path(bin_dir) / name), *map(str, args)], capture_output=True, text=True)
        if check and result.returncode != 0:
            raise AssertionError(f"{name} {' '.join(map(str, args))} exited {result.returncode}:\n{result.stderr}")
        return result
    return run


def read_ascii_ply_fields(path) -> dict:
    """Vertex properties of an ASCII PLY (as the tools write with --ascii) as float arrays."""
    with open(path) as file:
        lines = file.read().splitlines()
    names, vertices, in_vertex, end = [], 0, False, 0
    for i, line in enumerate(lines):
        words = line.split()
        if words[:2] == ["element", "vertex"]:
            vertices, in_vertex = int(words[2]), True
        elif words[:1] == ["element"]:
            in_vertex = False
        elif words[:1] == ["property"] and in_vertex:
            names.append(words[-1])
        elif words == ["end_header"]:
            end = i + 1
            break
    table = np.array([[float(x) for x in lines[end + v].split()] for v in range(vertices)])
    return {name: table[:, k] for k, name in enumerate(names)}


def read_json(path) -> dict:
    with open(path) as file:
        return json.load(file)
