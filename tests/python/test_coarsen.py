"""ice.coarsen: the coarse space's invariants, agreement with ice-coarsen, .ilm round trips."""
import os
import time

import numpy as np
import pytest
import scipy.io

import ice
from conftest import extended_meshes


def check_coarse_space(coarse, V, F):
    n, nc = V.shape[0], coarse.n_vertices
    P = coarse.P
    assert P.format == "csr" and P.shape == (n, nc)
    assert np.abs(np.asarray(P.sum(axis=1)).ravel() - 1).max() < 1e-12   # P·1 = 1
    assert P.data.min() >= -1e-12 and np.diff(P.indptr).max() <= 3
    # survivors: their row of P is e_j, and to_input / from_input are inverse maps
    to_input, from_input = coarse.to_input, coarse.from_input
    survivors = np.flatnonzero(from_input >= 0)
    assert np.array_equal(to_input[from_input[survivors]], survivors)
    # (sparse: a cancelled coarsening keeps most vertices, and dense rows of them would take gigabytes)
    unit_rows = scipy.sparse.csr_matrix((np.ones(len(survivors)), (np.arange(len(survivors)), from_input[survivors])),
                                        shape=(len(survivors), nc))
    assert abs(P[survivors, :] - unit_rows).max() < 1e-12
    # the map agrees with P: barycentric coordinates of each vertex in its coarse face
    face, bary, coarse_vertex = coarse.map
    assert np.array_equal(coarse_vertex, from_input)
    rebuilt = scipy.sparse.csr_matrix((bary.ravel(), coarse.faces[face].ravel(), np.arange(0, 3 * n + 1, 3)), shape=(n, nc))
    assert abs(rebuilt - P).max() < 1e-12
    # the coarse mesh: triangle inequality on every face, symmetric gluing with matching lengths
    L = coarse.lengths
    assert (L > 0).all() and (L < np.roll(L, 1, axis=1) + np.roll(L, 2, axis=1)).all()
    twin = coarse.twin
    sides = np.flatnonzero(twin >= 0)
    assert np.array_equal(twin[twin[sides]], sides)
    assert np.allclose(L.ravel()[sides], L.ravel()[twin[sides]])
    # Gauss–Bonnet on the intrinsic mesh: angle defects sum to 2πχ (closed meshes)
    if (twin >= 0).all():
        a, b, c = L[:, 0], L[:, 1], L[:, 2]
        angles = np.stack([np.arccos(np.clip((a**2 + c**2 - b**2) / (2 * a * c), -1, 1)),
                           np.arccos(np.clip((a**2 + b**2 - c**2) / (2 * a * b), -1, 1)),
                           np.arccos(np.clip((b**2 + c**2 - a**2) / (2 * b * c), -1, 1))], axis=1)
        angle_sums = np.bincount(coarse.faces.ravel(), angles.ravel(), minlength=nc)
        chi = nc - 3 * coarse.n_faces // 2 + coarse.n_faces
        assert abs((2 * np.pi - angle_sums).sum() - 2 * np.pi * chi) < 1e-8


def test_coarsen_invariants(project_mesh):
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    coarse = ice.coarsen(V, F, ratio=0.05)
    assert coarse.n_vertices == int(np.ceil(0.05 * V.shape[0]))
    assert coarse.summary["stop_reason"] == "target_reached" and coarse.summary["method"] == "ice"
    check_coarse_space(coarse, V, F)
    assert coarse.positions.shape == (coarse.n_vertices, 3)
    assert np.array_equal(coarse.positions, V[coarse.to_input])


def test_locked_vertices_survive_and_boundary_kept(project_mesh):
    V, F = ice.load_mesh(project_mesh("elephant-with-holes.off"))
    locked = [5, 17, 400]
    coarse = ice.coarsen(V, F, n=300, locked=locked)
    assert (coarse.from_input[locked] >= 0).all()
    check_coarse_space(coarse, V, F)
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    boundary = np.unique(unique[count == 1])
    assert (coarse.from_input[boundary] < 0).any()  # by default boundary vertices may go
    kept = ice.coarsen(V, F, n=len(boundary) + 50, remove_boundary=False)
    assert (kept.from_input[boundary] >= 0).all()


@pytest.mark.parametrize("name", ["spot.obj", "elephant-with-holes.off", "blobby_3cc.off"])
def test_equals_the_ice_coarsen_tool(tmp_path, tool, project_mesh, name):
    path = project_mesh(name)
    V, F = ice.load_mesh(path)
    coarse = ice.coarsen(V, F, ratio=0.05)
    tool("ice-coarsen", path, "--ratio", "0.05", "-q", "-o", tmp_path)
    P_tool = scipy.io.mmread(tmp_path / "prolongation.mtx").tocsr()
    assert P_tool.shape == coarse.P.shape and abs(P_tool - coarse.P).max() == 0  # to the last bit
    from_file = ice.load_coarse_mesh(tmp_path / "coarse.ilm")
    for name in ("faces", "lengths", "twin", "to_input", "from_input"):
        assert np.array_equal(getattr(from_file, name), getattr(coarse, name)), name


def test_shared_meshes_equal_the_tool(tmp_path, tool):
    """The same on the shared real meshes (scans, CAD, several components) when they are there."""
    folder = extended_meshes()
    names = ["bunny_zipper_holes.obj", "fandisk.obj", "camelhead.off", "dragon_fat.obj"]
    paths = [folder / name for name in names if (folder / name).exists()]
    if not paths:
        pytest.skip(f"the shared mesh set is not at {folder} (set ICE_EXTENDED_MESHES)")
    for path in paths:
        V, F = ice.load_mesh(path, repair=True)
        coarse = ice.coarsen(V, F, ratio=0.02)
        check_coarse_space(coarse, V, F)
        out = tmp_path / path.stem
        tool("ice-coarsen", path, "--repair", "--ratio", "0.02", "-q", "-o", out)
        assert abs(scipy.io.mmread(out / "prolongation.mtx").tocsr() - coarse.P).max() == 0, path


def test_save_and_load_round_trip(tmp_path, project_mesh):
    V, F = ice.load_mesh(project_mesh("lion-head.off"))
    coarse = ice.coarsen(V, F, n=200, refine_angle=25)
    assert coarse.summary["refinement"]["inserted"] > 0
    assert (coarse.to_input[-1] == -1) and coarse.inserted[0].shape[0] == coarse.n_vertices - 200
    check_coarse_space(coarse, V, F)
    path = tmp_path / "coarse.ilm"
    coarse.save(path)
    back = ice.load_coarse_mesh(path)
    for name in ("faces", "lengths", "twin", "to_input", "from_input"):
        assert np.array_equal(getattr(back, name), getattr(coarse, name)), name
    assert back.P is None and back.map is None and back.summary is None and back.input_vertices == V.shape[0]
    assert back.n_vertices == coarse.n_vertices and f"{coarse.n_vertices} vertices" in repr(back)
    with pytest.raises(ice.MeshError) as error:
        coarse.save(path)
    assert error.value.kind == "unwritable"
    coarse.save(path, overwrite=True, comment="again")
    path.write_text(path.read_text().replace("\nf ", "\nf 9999 ", 1))
    with pytest.raises(ice.MeshError, match=str(path)):
        ice.load_coarse_mesh(path)
    with pytest.raises(ValueError, match="no prolongation"):
        ice.Proxy(V, F, back)


def test_qem_and_targets(project_mesh):
    V, F = ice.load_mesh(project_mesh("bear.off"))
    qem = ice.coarsen(V, F, n=500, method="qem")
    assert qem.n_vertices == 500 and qem.summary["method"] == "qem"
    check_coarse_space(qem, V, F)
    by_error = ice.coarsen(V, F, max_error=1e-4)
    assert by_error.summary["stop_reason"] == "error_threshold"
    with pytest.raises(ValueError, match="not both"):
        ice.coarsen(V, F, n=10, ratio=0.1)
    with pytest.raises(ValueError, match="say how far"):
        ice.coarsen(V, F)
    with pytest.raises(ValueError, match="out of range"):
        ice.coarsen(V, F, n=V.shape[0] + 1)
    with pytest.raises(ValueError, match="method must be one of"):
        ice.coarsen(V, F, n=10, method="fast")


def test_progress_callback_and_cancel(project_mesh):
    V, F = ice.load_mesh(project_mesh("bear.off"))
    seen = []
    # Progress is reported while a space is built (cache=False: not loaded from the store).
    coarse = ice.coarsen(V, F, n=500, progress=lambda state: seen.append(state["vertices"]), cache=False)
    assert seen and seen == sorted(seen, reverse=True) and coarse.n_vertices == 500
    stopped = ice.coarsen(V, F, n=500, progress=lambda state: False, cache=False)
    assert stopped.summary["stop_reason"] == "cancelled" and stopped.n_vertices > 500
    check_coarse_space(stopped, V, F)

    def fail(state):
        raise KeyError("from the callback")
    with pytest.raises(KeyError, match="from the callback"):
        ice.coarsen(V, F, n=500, progress=fail, cache=False)


def test_long_calls_release_the_gil(project_mesh):
    """While one thread coarsens, another Python thread keeps running (it could not, holding no GIL)."""
    import threading
    V, F = ice.loop_subdivide(*ice.load_mesh(project_mesh("spot.obj")), 2)  # 47k vertices: ~0.5 s
    ticks, running = [], threading.Event()

    def tick():
        running.set()
        while running.is_set():
            ticks.append(1)
            time.sleep(0.001)
    ticker = threading.Thread(target=tick)
    ticker.start()
    try:
        before = len(ticks)
        coarse = ice.coarsen(V, F, ratio=0.05, cache=False)  # built, not loaded
        during = len(ticks) - before
    finally:
        running.clear()
        ticker.join()
    assert coarse.summary["seconds"] > 0.05 and during >= 10


def test_two_threads_coarsen_two_meshes(project_mesh):
    import threading
    meshes = [ice.load_mesh(project_mesh(name)) for name in ("spot.obj", "bear.off")]
    serial = [ice.coarsen(V, F, ratio=0.05).P for V, F in meshes]
    results = [None, None]

    def work(i):
        results[i] = ice.coarsen(*meshes[i], ratio=0.05).P
    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(abs(a - b).max() == 0 for a, b in zip(serial, results))


def test_option_types_and_ranges(project_mesh):
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    with pytest.raises(TypeError, match="n must be an integer"):
        ice.coarsen(V, F, n=500.0)
    with pytest.raises(TypeError, match="ratio must be a number"):
        ice.coarsen(V, F, ratio="0.05")
    with pytest.raises(ValueError, match="threads = 99 is out of range"):
        ice.coarsen(V, F, ratio=0.05, threads=99)
    with pytest.raises(ValueError, match="coarsest = 4294967496 is out of range"):
        ice.hierarchy(V, F, coarsest=2**32 + 200)
    assert ice.coarsen(V, F, n=np.int64(300), refine_angle=0).n_vertices == 300  # 0: no refinement, as the tools
    with pytest.raises(ValueError, match="refine_angle"):
        ice.coarsen(V, F, n=300, refine_angle=45)

    def odd(state):
        return np.array([1, 2])  # no single truth value: the callback's own error is raised
    with pytest.raises(ValueError, match="truth value"):
        ice.coarsen(V, F, n=300, progress=odd, cache=False)
