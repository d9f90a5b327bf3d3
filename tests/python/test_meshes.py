"""Reading, validating and writing meshes; arrays checked at the boundary; refusals as exceptions."""
import numpy as np
import pytest

import ice

# A square of two triangles plus a third triangle on the edge 0-1: a non-manifold edge.
NON_MANIFOLD_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"


def tetrahedron():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    return V, F


def test_load_mesh_unpacks_and_reports(project_mesh):
    loaded = ice.load_mesh(project_mesh("bear.off"))
    V, F = loaded
    assert V.shape == (13826, 3) and V.dtype == np.float64
    assert F.shape[1] == 3 and F.dtype == np.int32 and F.min() == 0 and F.max() == V.shape[0] - 1
    assert loaded.report["clean"] and loaded.report["genus"] == 0 and loaded.report["components"] == 1
    # Euler characteristic from the arrays agrees with the report
    edges = {tuple(sorted(e)) for f in F for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    assert V.shape[0] - len(edges) + F.shape[0] == loaded.report["euler_characteristic"] == 2
    assert list(loaded.source_vertex[:3]) == [0, 1, 2] and loaded.repairs == [] and loaded.format == "off"


def test_validate_matches_loader(project_mesh):
    loaded = ice.load_mesh(project_mesh("elephant-with-holes.off"))
    report = ice.validate(loaded.V, loaded.F)
    assert report == loaded.report
    assert report["boundary_loops"] > 0


def test_missing_file_raises_mesh_error(tmp_path):
    path = tmp_path / "nothing.obj"
    with pytest.raises(ice.MeshError) as error:
        ice.load_mesh(path)
    assert error.value.kind == "unreadable" and error.value.path == str(path)
    assert str(error.value).startswith(str(path))


def test_refusal_carries_the_tools_message(tmp_path, tool):
    path = tmp_path / "non_manifold.obj"
    path.write_text(NON_MANIFOLD_OBJ)
    with pytest.raises(ice.MeshError) as error:
        ice.load_mesh(path)
    assert error.value.kind == "defective"
    message = str(error.value)
    assert "non-manifold edge" in message
    result = tool("ice-coarsen", path, "--ratio", "0.5", "-o", tmp_path / "out", check=False)
    assert result.returncode == 2
    assert f"ice-coarsen: {message}" in result.stderr
    # repair cannot fix a non-manifold edge either: still refused, naming it
    with pytest.raises(ice.MeshError, match="non-manifold"):
        ice.load_mesh(path, repair=True)


def test_repair_drops_what_is_safe(tmp_path):
    V, F = tetrahedron()
    path = tmp_path / "unused_vertex.obj"
    text = "".join(f"v {x} {y} {z}\n" for x, y, z in V) + "v 5 5 5\n" + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in F)
    path.write_text(text)
    with pytest.raises(ice.MeshError, match="unreferenced"):
        ice.load_mesh(path)
    loaded = ice.load_mesh(path, repair=True)
    assert loaded.V.shape == (4, 3) and loaded.repairs


def test_save_round_trip_is_exact(tmp_path, project_mesh):
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    for name in ("copy.ply", "copy.obj", "copy.off"):
        ice.save_mesh(tmp_path / name, V, F)
        W, G = ice.load_mesh(tmp_path / name)
        assert np.array_equal(V, W) and np.array_equal(F, G)
    with pytest.raises(ice.MeshError) as error:
        ice.save_mesh(tmp_path / "copy.ply", V, F)
    assert error.value.kind == "unwritable"
    ice.save_mesh(tmp_path / "copy.ply", V, F, overwrite=True)


def test_defective_arrays_are_refused_with_the_defect():
    V, F = tetrahedron()
    flipped = F.copy()
    flipped[0] = flipped[0, ::-1]
    with pytest.raises(ice.MeshError, match="inconsistent"):
        ice.coarsen(V, flipped, n=3)
    assert not ice.validate(V, flipped)["clean"]


def test_a_mesh_changed_in_place_is_validated_again(project_mesh):
    """Validation is skipped only for content already found clean: an edit in place is caught."""
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    coarse = ice.coarsen(V, F, ratio=0.1)
    ice.Proxy(V, F, coarse)
    V[F[7, 0]] = V[F[7, 1]]  # two corners of face 7 made to coincide: a zero-area face
    with pytest.raises(ice.MeshError, match="zero-area"):
        ice.Proxy(V, F, coarse)
    with pytest.raises(ice.MeshError, match="zero-area"):
        ice.coarsen(V, F, ratio=0.1)


@pytest.mark.parametrize("make, error, words", [
    (lambda V, F: (V[:, :2], F), ValueError, "V must have shape (n, 3)"),
    (lambda V, F: (V.astype(str), F), TypeError, "V must be an n×3 array of real numbers"),
    (lambda V, F: (np.where(np.arange(12).reshape(4, 3) == 4, np.nan, V), F), ValueError, "V[1, 1] is nan"),
    (lambda V, F: (V, F.astype(float)), TypeError, "F must be an m×3 array of integers"),
    (lambda V, F: (V, np.vstack([F, [0, 1, 4]])), ValueError, "F[4, 2] = 4 is out of range: V has 4 vertices"),
    (lambda V, F: (V, F - 1), ValueError, "F[0, 0] = -1 is out of range"),
    (lambda V, F: (V, F[:, :2]), ValueError, "F must have shape (m, 3)"),
    (lambda V, F: (V, F[:0]), ValueError, "F has no faces"),
    (lambda V, F: (None, F), TypeError, "V is None"),
])
def test_bad_arrays_raise_clear_errors(make, error, words):
    V, F = make(*tetrahedron())
    calls = [ice.validate, lambda V, F: ice.coarsen(V, F, n=3), ice.face_lengths]
    if V is not None:  # cotan_laplacian(None, F) is the intrinsic form, which then asks for lengths
        calls.append(ice.cotan_laplacian)
    for call in calls:
        with pytest.raises(error) as raised:
            call(V, F)
        assert words in str(raised.value)


def test_integer_positions_and_other_index_types_are_converted():
    V, F = tetrahedron()
    for faces in (F.astype(np.int64), F.astype(np.uint16), F.tolist(), np.asfortranarray(F)):
        L = ice.cotan_laplacian(V.astype(np.int32), faces)
        assert np.allclose(L.toarray(), ice.cotan_laplacian(V, F).toarray())
