"""The package as a whole: documentation on everything public, stubs that match it, the example."""
import ast
import inspect
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
    assert set(ice.__all__) <= set(stubbed), set(ice.__all__) - set(stubbed)
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
