"""The package as a whole: documentation on everything public, stubs that match it, the example."""
import ast
import inspect
import os
import pathlib
import re
import subprocess
import sys
import types

import ice

PACKAGE = pathlib.Path(ice.__file__).parent
EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "python" / "examples" / "poisson_picture.py"


def public_members(owner):
    return [(name, member) for name, member in vars(owner).items() if not name.startswith("_")]


def test_everything_public_is_documented():
    for name in ice.__all__:
        item = getattr(ice, name)
        assert inspect.getdoc(item), f"ice.{name} has no docstring"
        if inspect.isclass(item) and item is not ice.MeshError:
            for member_name, member in public_members(item):
                if isinstance(member, types.MemberDescriptorType):
                    continue  # __slots__ fields: documented in the class docstring
                doc = getattr(member, "__doc__", None) or ""
                # pybind11 puts the signature first; a documented member has text after it
                text = re.sub(r"^\w+\(.*?\) -> .*?\n", "", doc.strip(), count=1).strip()
                assert text, f"ice.{name}.{member_name} has no docstring"


def test_stubs_list_every_public_name_and_member():
    tree = ast.parse((PACKAGE / "__init__.pyi").read_text())
    stubbed = {node.name: node for node in tree.body if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
    constants = {node.target.id for node in tree.body if isinstance(node, ast.AnnAssign)}
    assert set(ice.__all__) <= set(stubbed) | constants, set(ice.__all__) - set(stubbed) - constants
    for name in ice.__all__:
        item = getattr(ice, name)
        if inspect.isclass(item) and item is not ice.MeshError:
            members = {node.name for node in stubbed[name].body if isinstance(node, ast.FunctionDef)}
            members |= {node.target.id for node in stubbed[name].body if isinstance(node, ast.AnnAssign)}
            missing = {m for m, _ in public_members(item)} - members
            assert not missing, f"stub of ice.{name} lacks {missing}"
    assert (PACKAGE / "py.typed").exists()


def test_example_saves_a_picture(tmp_path, project_mesh):
    picture = tmp_path / "poisson.png"
    result = subprocess.run([sys.executable, str(EXAMPLE), str(project_mesh("spot.obj")), "-o", str(picture)],
                            capture_output=True, text=True, check=True)
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and picture.stat().st_size > 20000
    error = float(re.search(r"relative L2 error ([0-9.]+)%", result.stdout).group(1))
    assert 0 < error < 10  # measured 3.42 % on spot at 5 %


def test_installed_package_imports_and_solves(tmp_path, project_mesh):
    """`cmake --install` puts a working package under the prefix (lib/python3.X/{dist,site}-packages)."""
    build = pathlib.Path(os.environ.get("ICE_BUILD_DIR", pathlib.Path(ice.__file__).parents[2]))
    subprocess.run(["cmake", "--install", str(build), "--prefix", str(tmp_path)], check=True, capture_output=True)
    sites = list((tmp_path / "lib").glob(f"python{sys.version_info.major}.{sys.version_info.minor}/*-packages"))
    assert len(sites) == 1, sites
    site = sites[0]
    assert (site / "ice" / "__init__.pyi").exists() and (site / "ice" / "py.typed").exists()
    script = ("import ice, numpy as np; V, F = ice.load_mesh(%r); "
              "u = ice.solve_poisson(V, F, V[:, 0], ratio=0.1); print(ice.__file__, float(np.abs(u).max()))"
              % str(project_mesh("spot.obj")))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                            env={**os.environ, "PYTHONPATH": str(site)})
    assert result.stdout.startswith(str(site)) and float(result.stdout.split()[1]) > 0
    batch_help = subprocess.run([str(tmp_path / "bin" / "ice-batch"), "--help"], capture_output=True, text=True,
                                check=True, env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    assert "--scheduler" in batch_help.stdout


def test_readme_example_runs():
    """The README's ten-line example, as printed there (run from the repository's root)."""
    root = pathlib.Path(__file__).resolve().parents[2]
    readme = (root / "README.md").read_text()
    section = readme[readme.index("\n## In Python\n"):]
    code = section[section.index("```python\n") + len("```python\n"):section.index("\n```", section.index("```python"))]
    meshes = os.environ.get("ICE_PROJECT_MESHES") or os.environ.get("ICE_PROJECT_MESHES_DIR")
    if meshes:
        code = code.replace('"data/default/', '"' + meshes.rstrip("/") + "/")
    result = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True)
    assert 0 < float(result.stdout.split()[-1]) < 0.1  # a relative error against the fine solve
