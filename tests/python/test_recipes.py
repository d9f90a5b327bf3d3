"""The recipe floor (ICE::proxy) is one recipe: its C++ one-call functions (docs/examples/recipes.cpp),
the tools and the Python package give the same numbers, to the last bit."""
import os
import subprocess

import numpy as np
import pytest

import ice
from conftest import read_ascii_ply_fields


def example_binary():
    build = os.environ.get("ICE_BUILD_DIR")
    path = os.path.join(build, "tests", "ice-recipes-example") if build else None
    if not path or not os.path.exists(path):
        pytest.skip("the C++ example (ice-recipes-example) is built with the tests (ICE_BUILD_TESTS)")
    return path


def test_cpp_one_calls_python_and_tools_agree_to_the_last_bit(tmp_path, tool, project_mesh):
    path = project_mesh("spot.obj")
    V, F = ice.load_mesh(path)
    f = np.cos(3 * V[:, 1]) + V[:, 0]
    np.savetxt(tmp_path / "f.txt", f, fmt="%.17g")
    source = 7

    out = subprocess.run([example_binary(), path, str(source), str(tmp_path / "f.txt")], check=True,
                         capture_output=True, text=True).stdout.split()
    values = np.array([float(x) for x in out])
    n = V.shape[0]
    assert values.shape == (2 * n,)
    cpp_distance, cpp_solution = values[:n], values[n:]

    tool("geodesic-coarse", path, "--ratio", "0.05", "--source", str(source), "--no-reference", "--ascii", "-q",
         "-o", tmp_path / "d.ply")
    tool("poisson-coarse", path, "--ratio", "0.05", "--rhs", tmp_path / "f.txt", "--no-reference", "--ascii", "-q",
         "-o", tmp_path / "u.ply")
    tool_distance = read_ascii_ply_fields(tmp_path / "d.ply")["distance"]
    tool_solution = read_ascii_ply_fields(tmp_path / "u.ply")["solution"]

    assert np.array_equal(cpp_distance, tool_distance)
    assert np.array_equal(cpp_solution, tool_solution)
    assert np.array_equal(ice.geodesic_distance(V, F, [source], ratio=0.05), cpp_distance)
    assert np.array_equal(ice.solve_poisson(V, F, f, ratio=0.05), cpp_solution)
    assert cpp_distance[source] == 0 and cpp_distance.max() > 0
