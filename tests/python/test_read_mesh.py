"""ice.read_mesh: ICE's reader for OBJ/OFF/PLY/STL, meshio (when installed; Debian: python3-meshio) for the rest."""
import sys

import numpy as np
import pytest

import ice


def test_ice_formats_are_read_by_ice(project_mesh, tmp_path):
    path = project_mesh("spot.obj")
    V, F = ice.read_mesh(path)
    loaded = ice.load_mesh(path)
    assert V.dtype == np.float64 and F.dtype == np.int32 and V.shape[1] == 3 and F.shape[1] == 3
    np.testing.assert_array_equal(V, loaded.V)
    np.testing.assert_array_equal(F, loaded.F)
    upper = tmp_path / "SPOT.OFF"  # the extension in any case, as the tools take it
    ice.save_mesh(upper, V, F)
    V2, F2 = ice.read_mesh(str(upper), repair=False)
    np.testing.assert_allclose(V2, V)
    np.testing.assert_array_equal(F2, F)
    with pytest.raises(ice.MeshError):  # ICE's policy applies to its own formats
        ice.read_mesh(tmp_path / "missing.ply")


def test_other_formats_without_meshio_are_refused(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "meshio", None)  # import meshio now raises ImportError
    path = tmp_path / "mesh.vtu"
    path.write_text("<VTKFile/>")
    with pytest.raises(ValueError, match=r"mesh\.vtu.*meshio.*python3-meshio"):
        ice.read_mesh(path)


@pytest.fixture
def meshio():
    return pytest.importorskip("meshio", reason="meshio is not installed (Debian: apt-get install python3-meshio)")


@pytest.fixture(scope="module")
def spot(project_mesh):
    return ice.read_mesh(project_mesh("spot.obj"))


@pytest.mark.parametrize("suffix,file_format", [(".vtu", None), (".msh", "gmsh22"), (".vtk", None)])
def test_meshio_formats_round_trip(meshio, spot, tmp_path, suffix, file_format):
    V, F = spot
    path = tmp_path / f"spot{suffix}"
    meshio.write(path, meshio.Mesh(V, [("triangle", F.astype(np.int64))]), file_format=file_format, binary=False)
    V2, F2 = ice.read_mesh(path)
    assert V2.dtype == np.float64 and F2.dtype == np.int32
    assert V2.flags.c_contiguous and F2.flags.c_contiguous
    np.testing.assert_allclose(V2, V, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(F2, F)
    assert ice.validate(V2, F2)["clean"]
    d = ice.geodesic_distance(V2, F2, [0], ratio=0.1)  # usable as it is
    assert d[0] == 0 and np.isfinite(d).all()


def test_meshio_other_cells_are_refused(meshio, tmp_path):
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    lines = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    path = tmp_path / "square.msh"
    meshio.write(path, meshio.Mesh(V, [("triangle", triangles), ("line", lines)]), file_format="gmsh22", binary=False)
    with pytest.raises(ValueError, match=r"square\.msh.*triangle meshes only.*4 line"):
        ice.read_mesh(path)
    V2, F2 = ice.read_mesh(path, skip_cells={"line"})  # a Gmsh surface's boundary curves, dropped on request
    np.testing.assert_array_equal(F2, triangles)
    np.testing.assert_array_equal(V2, V)

    quads = tmp_path / "quads.vtu"
    meshio.write(quads, meshio.Mesh(V, [("quad", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(ValueError, match=r"quads\.vtu.*1 quad"):
        ice.read_mesh(quads)
    with pytest.raises(ValueError, match=r"quads\.vtu: no triangles.*quad"):
        ice.read_mesh(quads, skip_cells="quad")


def test_meshio_planar_points_get_z_zero(meshio, tmp_path):
    V = np.array([[0, 0], [1, 0], [0, 1]], dtype=float)
    path = tmp_path / "planar.mesh"  # Medit keeps 2D points 2D (VTU and Gmsh would write z = 0 themselves)
    meshio.write(path, meshio.Mesh(V, [("triangle", np.array([[0, 1, 2]]))]))
    assert meshio.read(path).points.shape == (3, 2)
    V2, F2 = ice.read_mesh(path)
    assert V2.shape == (3, 3) and not V2[:, 2].any()
    np.testing.assert_array_equal(V2[:, :2], V)
    assert F2.tolist() == [[0, 1, 2]]
