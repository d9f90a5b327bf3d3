"""Set up once, solve many times from Python: the store of set-up proxies, block sources, heat steps."""
import warnings

import numpy as np
import pytest

import ice


@pytest.fixture(scope="module")
def spot(project_mesh):
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    return V, F


def sources(V, k):
    return np.stack([np.cos((j + 1) * V[:, 0]) + j * V[:, 1] * V[:, 2] for j in range(k)], axis=1)


def test_setup_proxy_store_cold_warm_off(spot, tmp_path):
    V, F = spot
    f = sources(V, 1)[:, 0]
    coarse, cold = ice.setup_proxy(V, F, ratio=0.05, cache=tmp_path)
    assert cold.cache["status"] == "miss" and len(cold.cache["keys"]) == 1
    assert len(list(tmp_path.glob("proxy-*.ice"))) == 1
    coarse_warm, warm = ice.setup_proxy(V, F, ratio=0.05, cache=tmp_path)
    assert warm.cache["status"] == "hit" and warm.cache["keys"] == cold.cache["keys"]
    assert np.array_equal(coarse_warm.faces, coarse.faces) and np.array_equal(coarse_warm.lengths, coarse.lengths)
    assert coarse_warm.summary["removed"] == coarse.summary["removed"]
    u_cold = ice.ProxyPoissonSolver(cold).solve(f)
    u_warm = ice.ProxyPoissonSolver(warm).solve(f)
    assert np.array_equal(u_cold, u_warm)
    # The one-call through the store equals the one without it (and the classic Proxy route), bit for bit.
    u_off = ice.solve_poisson(V, F, f, cache=False)
    assert np.array_equal(ice.solve_poisson(V, F, f, cache=tmp_path), u_off)
    assert np.array_equal(ice.solve_poisson(V, F, f, cache=tmp_path), u_off)
    assert np.array_equal(u_warm, u_off)
    # The fine mesh of a stored proxy is made on demand.
    assert warm.fine_faces.shape == cold.fine_faces.shape
    _, off = ice.setup_proxy(V, F, ratio=0.05, cache=False)
    assert off.cache["status"] == "off"
    with pytest.raises(ValueError, match="cache must be"):
        ice.setup_proxy(V, F, ratio=0.05, cache=True)


def test_damaged_entry_is_rebuilt(spot, tmp_path):
    V, F = spot
    _, cold = ice.setup_proxy(V, F, ratio=0.05, cache=tmp_path)
    entry = next(tmp_path.glob("proxy-*.ice"))
    data = bytearray(entry.read_bytes())
    data[-50] ^= 0xFF
    entry.write_bytes(bytes(data))
    _, again = ice.setup_proxy(V, F, ratio=0.05, cache=tmp_path)
    assert again.cache["status"] == "rebuilt" and "checksum" in again.cache["damage"]
    f = sources(V, 1)[:, 0]
    assert np.array_equal(ice.ProxyPoissonSolver(again).solve(f), ice.ProxyPoissonSolver(cold).solve(f))
    _, warm = ice.setup_proxy(V, F, ratio=0.05, cache=tmp_path)
    assert warm.cache["status"] == "hit"


def test_block_poisson_matches_single_solves(spot, tmp_path):
    V, F = spot
    S = sources(V, 7)
    _, proxy = ice.setup_proxy(V, F, ratio=0.05, cache=tmp_path)
    solver = ice.ProxyPoissonSolver(proxy)
    U = solver.solve(S)
    assert U.shape == S.shape
    for j in range(S.shape[1]):
        u = solver.solve(np.ascontiguousarray(S[:, j]))
        assert np.linalg.norm(U[:, j] - u) <= 1e-12 * np.linalg.norm(u)
    # Dirichlet values per column
    fixed = [0, 1000]
    _, dproxy = ice.setup_proxy(V, F, ratio=0.05, fixed=fixed, cache=tmp_path)
    dsolver = ice.ProxyPoissonSolver(dproxy, fixed=fixed)
    values = np.vstack([np.arange(7.0), -np.ones(7)])
    W = dsolver.solve(S, values)
    assert np.array_equal(W[fixed, :], values)
    with pytest.raises(ValueError, match="one column per column"):
        dsolver.solve(S, values[:, :3])
    # the one-call takes the block too
    assert np.allclose(ice.solve_poisson(V, F, S, cache=tmp_path), U, rtol=0, atol=1e-12 * np.abs(U).max())


def test_heat_steps_on_the_coarse_level(spot, tmp_path):
    V, F = spot
    u0 = sources(V, 2)[:, 1]
    _, proxy = ice.setup_proxy(V, F, ratio=0.05, cache=tmp_path)
    heat = ice.ProxyHeatSolver(proxy, 1e-3)
    states, counts = heat.steps(u0, 12, 5)
    assert counts == [5, 10, 12] and states.shape == (V.shape[0], 3)
    for j, k in enumerate(counts):
        assert np.array_equal(states[:, j], heat.integrate(u0, k))
    states2, counts2 = ice.heat_flow(V, F, u0, 1e-3, 12, every=5, cache=tmp_path)
    assert counts2 == counts and np.array_equal(states2, states)
    assert np.array_equal(ice.heat_flow(V, F, u0, 1e-3, 12, cache=tmp_path), states[:, -1])
    with pytest.raises(ValueError, match="every"):
        heat.steps(u0, 12, 0)


def test_two_processes_fill_one_entry(spot, tmp_path, project_mesh):
    """Two processes set up the same proxy into one store at once: both succeed, with identical
    solutions, and the store holds one whole entry."""
    import subprocess
    import sys
    import textwrap
    script = textwrap.dedent(f"""
        import sys, numpy as np, ice
        V, F = ice.load_mesh({str(project_mesh("spot.obj"))!r})
        _, proxy = ice.setup_proxy(V, F, ratio=0.05, cache={str(tmp_path / "store")!r})
        u = ice.ProxyPoissonSolver(proxy).solve(np.cos(3 * V[:, 0]))
        np.save(sys.argv[1], u)
        print(proxy.cache["status"])
    """)
    runs = [subprocess.Popen([sys.executable, "-c", script, str(tmp_path / f"u{i}.npy")], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True) for i in range(2)]
    results = [run.communicate(timeout=300) for run in runs]
    for run, (out, err) in zip(runs, results):
        assert run.returncode == 0, err
        assert out.strip() in ("miss", "hit")
    assert np.array_equal(np.load(tmp_path / "u0.npy"), np.load(tmp_path / "u1.npy"))
    assert [p.name for p in (tmp_path / "store").iterdir()] == [next((tmp_path / "store").glob("proxy-*.ice")).name]
    _, warm = ice.setup_proxy(*spot, ratio=0.05, cache=tmp_path / "store")
    assert warm.cache["status"] == "hit"


def test_hierarchy_from_the_store(spot, tmp_path):
    V, F = spot
    plain, order = ice.hierarchy(V, F, coarsest=200, return_order=True, cache=False)
    assert not list(tmp_path.glob("hierarchy-*.ice"))
    cold, cold_order = ice.hierarchy(V, F, coarsest=200, return_order=True, cache=tmp_path)
    assert len(list(tmp_path.glob("hierarchy-*.ice"))) == 1
    warm, warm_order = ice.hierarchy(V, F, coarsest=200, return_order=True, cache=tmp_path)
    assert np.array_equal(order, cold_order) and np.array_equal(order, warm_order)
    assert len(plain) == len(warm) >= 2
    for a, b in zip(plain, warm):
        assert a.shape == b.shape and (a != b).nnz == 0
    # A damaged entry is rebuilt to the same prolongations.
    entry = next(tmp_path.glob("hierarchy-*.ice"))
    data = bytearray(entry.read_bytes())
    data[len(data) // 2] ^= 0x01
    entry.write_bytes(bytes(data))
    again = ice.hierarchy(V, F, coarsest=200, cache=tmp_path)
    for a, b in zip(plain, again):
        assert (a != b).nnz == 0


def test_save_and_load_setup_explicitly(spot, tmp_path):
    V, F = spot
    f = sources(V, 1)[:, 0]
    coarse, proxy = ice.setup_proxy(V, F, ratio=0.05, prolongation="smoothed", cache=False)
    path = tmp_path / "spot-setup.ice"
    ice.save_setup(path, V, F, coarse, proxy)
    with pytest.raises(ice.MeshError, match="exists"):
        ice.save_setup(path, V, F, coarse, proxy)
    ice.save_setup(str(path), V, F, coarse, proxy, overwrite=True)
    coarse2, proxy2 = ice.load_setup(path, V, F)
    assert proxy2.cache["status"] == "off" and proxy2.cache["file"] == str(path)
    assert np.array_equal(coarse2.faces, coarse.faces) and np.array_equal(coarse2.lengths, coarse.lengths)
    assert (coarse2.P != coarse.P).nnz == 0
    assert np.array_equal(ice.ProxyPoissonSolver(proxy2).solve(f), ice.ProxyPoissonSolver(proxy).solve(f))
    # Polishing needs the fine operators: the loaded proxy makes them from (V, F) as saved.
    assert np.array_equal(ice.ProxyPoissonSolver(proxy2, polish=1).solve(f), ice.ProxyPoissonSolver(proxy, polish=1).solve(f))
    moved = V.copy()
    moved[0, 0] += 1e-9
    with pytest.raises(RuntimeError, match="another mesh"):
        ice.load_setup(path, moved, F)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x20
    path.write_bytes(bytes(data))
    with pytest.raises(RuntimeError, match="checksum"):
        ice.load_setup(path, V, F)
    with pytest.raises(RuntimeError, match="no such file"):
        ice.load_setup(tmp_path / "none.ice", V, F)
    # A coarse space of another mesh is not saved with it.
    Vs, Fs = ice.loop_subdivide(V, F, 1)
    with pytest.raises(ValueError, match="another mesh"):
        ice.save_setup(tmp_path / "other.ice", Vs, Fs, coarse, proxy)


def test_save_and_load_hierarchy_explicitly(spot, tmp_path):
    V, F = spot
    levels, order = ice.hierarchy(V, F, cache=False, return_order=True)
    path = tmp_path / "spot-levels.ice"
    ice.save_hierarchy(path, V, F, levels, order=order)
    loaded, loaded_order = ice.load_hierarchy(path, V, F, return_order=True)
    assert len(loaded) == len(levels)
    for P, Q in zip(loaded, levels):
        assert P.shape == Q.shape and (P != Q).nnz == 0
    assert np.array_equal(loaded_order, order)
    A = ice.cotan_laplacian(V, F) + 1e-3 * ice.mass_matrix(V, F)
    b = sources(V, 1)[:, 0]
    solver = ice.MultigridSolver(loaded)
    solver.setup(A)
    x = solver.solve(b)
    assert np.linalg.norm(A @ x - b) <= 1e-7 * np.linalg.norm(b)
    with pytest.raises(RuntimeError, match="another mesh"):
        ice.load_hierarchy(path, V, F[::-1])
    broken = [P.copy() for P in levels]
    broken[0].data[0] *= 0.5
    with pytest.raises(ValueError, match="does not sum to 1"):
        ice.save_hierarchy(tmp_path / "broken.ice", V, F, broken)
    assert not (tmp_path / "broken.ice").exists()


def test_saved_proxy_keeps_its_fine_geometry_and_parts_must_match(spot, tmp_path):
    V, F = spot
    coarse = ice.coarsen(V, F, ratio=0.1)
    proxy = ice.Proxy(V, F, coarse, fine="input")
    ice.save_setup(tmp_path / "input.ice", V, F, coarse, proxy)
    _, loaded = ice.load_setup(tmp_path / "input.ice", V, F)
    # The loaded proxy makes its fine operators on the input triangles, as the saved one did.
    assert np.array_equal(loaded.fine_faces, proxy.fine_faces)
    assert (loaded.fine_laplacian != proxy.fine_laplacian).nnz == 0
    # A coarse space and a proxy of two coarsenings of the mesh are not one setup.
    other = ice.coarsen(V, F, ratio=0.05)
    with pytest.raises(ValueError, match="not one setup"):
        ice.save_setup(tmp_path / "mixed.ice", V, F, other, proxy)
    assert not (tmp_path / "mixed.ice").exists()


def test_coarsen_geodesics_and_vectors_through_the_store(spot, tmp_path):
    """ice.coarsen stores the space with its map; marching and the vector sweep store the traced lengths
    beside it; every result from the store equals the one set up from scratch, bit for bit."""
    V, F = spot
    plain = ice.coarsen(V, F, ratio=0.05, use="geodesic", cache=False)
    assert plain.cache["status"] == "off"
    cold = ice.coarsen(V, F, ratio=0.05, use="geodesic", cache=tmp_path)
    warm = ice.coarsen(V, F, ratio=0.05, use="geodesic", cache=tmp_path)
    assert (cold.cache["status"], warm.cache["status"]) == ("miss", "hit")
    assert warm.cache["keys"] == cold.cache["keys"] and warm.cache["load_seconds"] > 0
    for name in ("faces", "lengths", "twin", "to_input", "from_input", "positions"):
        assert np.array_equal(getattr(warm, name), getattr(plain, name)), name
    assert (warm.P != plain.P).nnz == 0
    for a, b in zip(warm.map, plain.map):
        assert np.array_equal(a, b)
    assert warm.summary["removed"] == plain.summary["removed"]
    # Marching on traced lengths: traced once, then loaded (the space's key names them).
    d_plain = ice.ProxyGeodesicSolver.from_coarse(V, F, plain, lengths="traced").distance([0])
    assert len(list(tmp_path.glob("traced-*.ice"))) == 0
    d_cold = ice.ProxyGeodesicSolver.from_coarse(V, F, warm, lengths="traced").distance([0])
    assert len(list(tmp_path.glob("traced-*.ice"))) == 1
    d_warm = ice.ProxyGeodesicSolver.from_coarse(V, F, warm, lengths="traced").distance([0])
    assert np.array_equal(d_cold, d_plain) and np.array_equal(d_warm, d_plain)
    assert np.array_equal(ice.geodesic_distance(V, F, [0], cache=tmp_path), ice.geodesic_distance(V, F, [0], cache=False))
    # The vector sweep marches on traced lengths of the Poisson metric's space.
    field_off = ice.transport_vectors(V, F, [0], cache=False)
    assert np.array_equal(ice.transport_vectors(V, F, [0], cache=tmp_path), field_off)
    assert np.array_equal(ice.transport_vectors(V, F, [0], cache=tmp_path), field_off)
    assert len(list(tmp_path.glob("space-*.ice"))) == 2 and len(list(tmp_path.glob("traced-*.ice"))) == 2
    # What is not stored: the history of trace=True, a space without a map.
    assert ice.coarsen(V, F, ratio=0.05, trace=True, cache=tmp_path).cache["status"] == "off"
    assert ice.coarsen(V, F, ratio=0.05, method="qem", qem_geometry="intrinsic_delaunay", cache=tmp_path).cache["status"] == "off"
    # A coarsening its progress callback cancelled is not the space its key names: never stored.
    before = sorted(tmp_path.glob("*.ice"))
    stopped = ice.coarsen(V, F, ratio=0.02, progress=lambda state: False, cache=tmp_path)
    assert stopped.summary["stop_reason"] == "cancelled" and sorted(tmp_path.glob("*.ice")) == before
    assert ice.coarsen(V, F, ratio=0.02, cache=tmp_path).summary["stop_reason"] == "target_reached"
    # A damaged entry is reported (a warning), never used, and rebuilt to the same space.
    entry = tmp_path / f"space-{cold.cache['keys'][0]}.ice"
    data = bytearray(entry.read_bytes())
    data[len(data) // 2] ^= 0x40
    entry.write_bytes(bytes(data))
    with pytest.warns(RuntimeWarning, match="damaged"):
        rebuilt = ice.coarsen(V, F, ratio=0.05, use="geodesic", cache=tmp_path)
    assert rebuilt.cache["status"] == "rebuilt"
    # With warnings as errors the warning is raised as itself.
    entry.write_bytes(bytes(data))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(RuntimeWarning, match="damaged"):
            ice.coarsen(V, F, ratio=0.05, use="geodesic", cache=tmp_path)
    assert np.array_equal(rebuilt.lengths, plain.lengths) and (rebuilt.P != plain.P).nnz == 0


def test_save_and_load_coarse_space_explicitly(spot, tmp_path):
    V, F = spot
    coarse = ice.coarsen(V, F, ratio=0.05, cache=False)
    path = tmp_path / "spot.ices"
    ice.save_coarse_space(path, V, F, coarse)
    back = ice.load_coarse_space(path, V, F)
    assert back.cache["status"] == "off" and back.cache["file"] == str(path)
    for name in ("faces", "lengths", "twin", "to_input", "from_input", "positions"):
        assert np.array_equal(getattr(back, name), getattr(coarse, name)), name
    assert (back.P != coarse.P).nnz == 0 and back.summary == coarse.summary
    for a, b in zip(back.map, coarse.map):
        assert np.array_equal(a, b)
    # What the map serves works from the loaded space: the same distances bit for bit.
    assert np.array_equal(ice.ProxyGeodesicSolver.from_coarse(V, F, back).distance([3]),
                          ice.ProxyGeodesicSolver.from_coarse(V, F, coarse).distance([3]))
    with pytest.raises(ice.MeshError, match="exists"):
        ice.save_coarse_space(path, V, F, coarse)
    ice.save_coarse_space(path, V, F, coarse, overwrite=True)
    # Another mesh, damage, another kind of file: refused naming the file.
    W = V.copy()
    W[0, 0] += 1e-3
    with pytest.raises(RuntimeError, match="another mesh"):
        ice.load_coarse_space(path, W, F)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x08
    (tmp_path / "bad.ices").write_bytes(bytes(data))
    with pytest.raises(RuntimeError, match="bad.ices"):
        ice.load_coarse_space(tmp_path / "bad.ices", V, F)
    ice.save_setup(tmp_path / "setup.ice", V, F, *ice.setup_proxy(V, F, ratio=0.05, cache=False))
    with pytest.raises(RuntimeError, match="setup.ice"):
        ice.load_coarse_space(tmp_path / "setup.ice", V, F)
    with pytest.raises(ValueError, match="no fine-to-coarse map"):
        ice.save_coarse_space(tmp_path / "nomap.ices", V, F, ice.coarsen(V, F, ratio=0.05, keep_map=False, cache=False))
