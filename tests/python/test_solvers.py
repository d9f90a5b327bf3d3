"""Operators and solvers: properties, scipy's own solves on the returned operators, the tools' results."""
import numpy as np
import pytest
import scipy.sparse
import scipy.sparse.csgraph
import scipy.sparse.linalg

import ice
from conftest import read_ascii_ply_fields


@pytest.fixture(scope="module")
def spot(project_mesh):
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    return V, F, ice.coarsen(V, F, ratio=0.05)


def test_operators_from_positions_and_lengths(spot):
    V, F, _ = spot
    L = ice.cotan_laplacian(V, F)
    M = ice.mass_matrix(V, F)
    assert L.format == "csc" and L.shape == (V.shape[0],) * 2
    assert abs(L - L.T).max() < 1e-12                       # symmetric
    assert np.abs(L @ np.ones(V.shape[0])).max() < 1e-10    # L·1 = 0
    x = np.random.default_rng(1).standard_normal(V.shape[0])
    assert x @ (L @ x) > 0                                   # positive semidefinite (and not zero)
    # the same operators from the intrinsic form
    lengths = ice.face_lengths(V, F)
    assert abs(ice.cotan_laplacian(F=F, lengths=lengths) - L).max() < 1e-12
    # lumped mass: diagonal, total = surface area
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    assert abs(M - scipy.sparse.diags(M.diagonal())).max() == 0 and abs(M.sum() - area) < 1e-12 * area
    assert abs(ice.mass_matrix(V, F, kind="consistent").sum() - area) < 1e-12 * area
    # intrinsic Delaunay: same vertices and area, every cotan weight >= 0 (off-diagonals <= 0)
    F_idt, L_idt, flips = ice.intrinsic_delaunay(V, F)
    W = ice.cotan_laplacian(F=F_idt, lengths=L_idt, n=V.shape[0]).tocoo()
    assert flips > 0 and W.data[W.row != W.col].max() <= 1e-12
    with pytest.raises(ValueError, match="triangle inequality"):
        bad = lengths.copy()
        bad[3] = [1, 1, 3]
        ice.cotan_laplacian(F=F, lengths=bad)


def test_poisson_matches_scipy_on_the_returned_operators(spot):
    V, F, coarse = spot
    proxy = ice.Proxy(V, F, coarse)
    f = np.sin(V[:, 0] * 3) + V[:, 1]
    u = ice.ProxyPoissonSolver(proxy).solve(f)
    # the same solve by scipy: b_c = Pᵀ M (f − mean), coarse Laplacian with one vertex pinned, u = P u_c
    P, M, Lc = coarse.P, proxy.fine_mass, proxy.coarse_laplacian
    ones = np.ones(V.shape[0])
    f0 = f - (ones @ (M @ f)) / (ones @ (M @ ones))
    b = P.T @ (M @ f0)
    uc = np.zeros(coarse.n_vertices)
    uc[1:] = scipy.sparse.linalg.spsolve(Lc[1:, 1:].tocsc(), b[1:])
    reference = P @ uc
    reference -= (ones @ (M @ reference)) / (ones @ (M @ ones))
    assert np.abs(u - reference).max() < 1e-9 * np.abs(reference).max()
    # Galerkin coarse operators are PᵀLP
    assert abs(Lc - P.T @ proxy.fine_laplacian @ P).max() < 1e-9 * abs(Lc).max()


def test_smoothed_prolongation(spot):
    V, F, coarse = spot
    plain = ice.Proxy(V, F, coarse)
    smoothed = ice.Proxy(V, F, coarse, prolongation="smoothed")
    P, S, L = coarse.P, smoothed.prolongation, smoothed.fine_laplacian
    # one damped Jacobi step of P on the fine Laplacian; rows still sum to 1
    expected = P - scipy.sparse.diags(2.0 / 3.0 / L.diagonal()) @ (L @ P)
    assert abs(S - expected).max() < 1e-12 and abs(plain.prolongation - P).max() == 0
    assert np.abs(S @ np.ones(S.shape[1]) - 1).max() < 1e-12
    assert abs(smoothed.coarse_laplacian - S.T @ L @ S).max() < 1e-9 * abs(smoothed.coarse_laplacian).max()
    # a smaller Poisson error than the barycentric P's, against scipy's fine solve
    M = plain.fine_mass
    f = np.sin(V[:, 0] * 3) + V[:, 1]
    ones = np.ones(V.shape[0])
    f0 = f - (ones @ (M @ f)) / (ones @ (M @ ones))
    reference = np.zeros(V.shape[0])
    reference[1:] = scipy.sparse.linalg.spsolve(L.tocsc()[1:, 1:], (M @ f0)[1:])
    reference -= (ones @ (M @ reference)) / (ones @ (M @ ones))

    def error(u):
        d = u - reference
        return np.sqrt(d @ (M @ d) / (reference @ (M @ reference)))
    e_plain = error(ice.ProxyPoissonSolver(plain).solve(f))
    e_smoothed = error(ice.solve_poisson(V, F, f, coarse=coarse, prolongation="smoothed"))
    assert e_smoothed < 0.8 * e_plain, (e_smoothed, e_plain)
    with pytest.raises(ValueError, match="galerkin"):
        ice.Proxy(V, F, coarse, operators="intrinsic", prolongation="smoothed")
    with pytest.raises(ValueError, match="prolongation"):
        ice.Proxy(V, F, coarse, prolongation="bogus")


def test_dirichlet_poisson_and_error_against_the_fine_solution(spot):
    V, F, _ = spot
    fixed = np.array([0, 500, 1000])
    values = np.array([0.0, 1.0, -1.0])
    coarse = ice.coarsen(V, F, ratio=0.05, locked=fixed)
    proxy = ice.Proxy(V, F, coarse)
    f = np.zeros(V.shape[0])
    u = ice.ProxyPoissonSolver(proxy, fixed=fixed).solve(f, values)
    assert np.allclose(u[fixed], values)
    # fine reference by scipy on the proxy's own fine operators
    L = proxy.fine_laplacian.tocsr()
    free = np.setdiff1d(np.arange(V.shape[0]), fixed)
    reference = np.zeros(V.shape[0])
    reference[fixed] = values
    reference[free] = scipy.sparse.linalg.spsolve(L[free][:, free].tocsc(), -L[free][:, fixed] @ values)
    error = np.abs(u - reference).max()
    polished = ice.ProxyPoissonSolver(proxy, fixed=fixed, tolerance=1e-8)
    u_polished = polished.solve(f, values)
    assert polished.polish_report["reached_tolerance"]
    assert np.abs(u_polished - reference).max() < 1e-5 and error > 1e3 * np.abs(u_polished - reference).max()
    with pytest.raises(ValueError, match="values must have 3 entries"):
        ice.ProxyPoissonSolver(proxy, fixed=fixed).solve(f, [1.0, 2.0])
    with pytest.raises(ValueError, match="not a coarse vertex|coarse vertex"):
        ice.ProxyPoissonSolver(ice.Proxy(V, F, spot[2]), fixed=[7])


def test_poisson_equals_the_poisson_coarse_tool(tmp_path, tool, project_mesh):
    path = project_mesh("bear.off")
    V, F = ice.load_mesh(path)
    f = np.cos(4 * V[:, 2]) * V[:, 0]
    np.savetxt(tmp_path / "f.txt", f, fmt="%.17g")
    out = tmp_path / "u.ply"
    tool("poisson-coarse", path, "--ratio", "0.05", "--rhs", tmp_path / "f.txt", "--no-reference", "--ascii", "-q",
         "-o", out)
    expected = read_ascii_ply_fields(out)["solution"]
    u = ice.solve_poisson(V, F, f, ratio=0.05)
    assert np.abs(u - expected).max() <= 1e-12 * np.abs(expected).max()


def test_geodesic_equals_the_geodesic_coarse_tool(tmp_path, tool, project_mesh):
    path = project_mesh("spot.obj")
    V, F = ice.load_mesh(path)
    out = tmp_path / "d.ply"
    tool("geodesic-coarse", path, "--ratio", "0.05", "--source", "7", "--no-reference", "--ascii", "-q", "-o", out)
    expected = read_ascii_ply_fields(out)["distance"]
    d = ice.geodesic_distance(V, F, [7], ratio=0.05)
    assert np.abs(d - expected).max() <= 1e-12 * expected.max()
    assert d[7] == pytest.approx(0, abs=1e-12) and d.max() > 0.5 * np.linalg.norm(V.max(0) - V.min(0))
    with pytest.raises(ValueError, match="sources"):
        ice.geodesic_distance(V, F, [V.shape[0]], ratio=0.05)
    # The tool's heat method too, and the coarse marching without a Proxy (what geodesic_distance
    # uses) equals the one through a Proxy.
    tool("geodesic-coarse", path, "--ratio", "0.05", "--source", "7", "--no-reference", "--ascii", "-q",
         "--coarse-distances", "heat", "-o", tmp_path / "h.ply")
    heat = ice.geodesic_distance(V, F, [7], ratio=0.05, method="heat")
    assert np.abs(heat - read_ascii_ply_fields(tmp_path / "h.ply")["distance"]).max() <= 1e-12 * heat.max()
    coarse = ice.coarsen(V, F, ratio=0.05, use="geodesic")
    bare = ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="intrinsic", curvature_correction=False).distance([7, 100])
    assert np.array_equal(bare, ice.ProxyGeodesicSolver(ice.Proxy(V, F, coarse), curvature_correction=False).distance([7, 100]))
    # With the curvature correction (the default for ICE), the same up to the fine triangulation's
    # vertex areas (the input's here, its intrinsic Delaunay triangulation's through a Proxy): lengths
    # that differ by ~1e-6. The marching keeps one virtual source per vertex, and which of two
    # near-equal ones a vertex keeps decides what lies downstream of it: most distances agree to
    # 1e-6, some move by up to ~1 % (measured 1.0 % here, 0.09 % on average).
    corrected = ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="intrinsic").distance([7, 100])
    moved = np.abs(corrected - ice.ProxyGeodesicSolver(ice.Proxy(V, F, coarse)).distance([7, 100])) / corrected.max()
    assert np.median(moved) <= 1e-4 and moved.mean() <= 3e-3 and moved.max() <= 3e-2
    assert np.abs(corrected - bare).max() > 1e-3 * corrected.max()
    assert np.array_equal(corrected, ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="intrinsic",
                                                                          curvature_correction=True).distance([7, 100]))
    qem = ice.coarsen(V, F, ratio=0.05, method="qem")  # not corrected by default (docs/measurements.md, "Curvature correction")
    assert np.array_equal(ice.ProxyGeodesicSolver.from_coarse(V, F, qem).distance([7]),
                          ice.ProxyGeodesicSolver.from_coarse(V, F, qem, curvature_correction=False).distance([7]))
    with pytest.raises(TypeError, match="curvature_correction"):
        ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, curvature_correction="yes")
    with pytest.raises(ValueError, match="method"):
        ice.geodesic_distance(V, F, [7], coarse=coarse, method="dijkstra")
    # Traced lengths (the default for ICE, lengths="auto"), the tool's --coarse-lengths traced; the
    # coarse mesh's own lengths on request (--coarse-lengths intrinsic); refused where there is
    # nothing to trace.
    tool("geodesic-coarse", path, "--ratio", "0.05", "--source", "7", "--no-reference", "--ascii", "-q",
         "--coarse-lengths", "traced", "-o", tmp_path / "t.ply")
    traced = ice.geodesic_distance(V, F, [7], ratio=0.05, lengths="traced")
    assert np.abs(traced - read_ascii_ply_fields(tmp_path / "t.ply")["distance"]).max() <= 1e-12 * traced.max()
    assert np.array_equal(traced, d)
    assert np.array_equal(ice.ProxyGeodesicSolver.from_coarse(V, F, coarse).distance([7]),
                          ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="traced").distance([7]))
    tool("geodesic-coarse", path, "--ratio", "0.05", "--source", "7", "--no-reference", "--ascii", "-q",
         "--coarse-lengths", "intrinsic", "-o", tmp_path / "i.ply")
    intrinsic = ice.geodesic_distance(V, F, [7], ratio=0.05, lengths="intrinsic")
    assert np.abs(intrinsic - read_ascii_ply_fields(tmp_path / "i.ply")["distance"]).max() <= 1e-12 * intrinsic.max()
    assert np.abs(traced - intrinsic).max() > 1e-6 * d.max()  # another metric: other distances
    with pytest.raises(ValueError, match="traced"):
        ice.ProxyGeodesicSolver.from_coarse(V, F, ice.coarsen(V, F, ratio=0.05, method="qem"), lengths="traced")
    with pytest.raises(ValueError, match="marching"):
        ice.geodesic_distance(V, F, [7], coarse=coarse, method="heat", lengths="traced")
    with pytest.raises(ValueError, match="lengths"):
        ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="exact")
    # Marching on the coarse mesh split 1:4 twice: the tool's --marching-subdivisions 2, other
    # distances than the default (1), and a subdivision count out of range refused.
    tool("geodesic-coarse", path, "--ratio", "0.05", "--source", "7", "--no-reference", "--ascii", "-q",
         "--marching-subdivisions", "2", "-o", tmp_path / "s.ply")
    split = ice.geodesic_distance(V, F, [7], ratio=0.05, subdivisions=2)
    assert np.abs(split - read_ascii_ply_fields(tmp_path / "s.ply")["distance"]).max() <= 1e-12 * split.max()
    assert np.abs(split - d).max() > 1e-6 * d.max()
    assert np.array_equal(ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="intrinsic", subdivisions=0,
                                                              curvature_correction=False).distance([7]),
                          ice.ProxyGeodesicSolver(ice.Proxy(V, F, coarse), subdivisions=0, curvature_correction=False).distance([7]))
    with pytest.raises(ValueError, match="subdivisions"):
        ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, subdivisions=-1)


def test_traced_coarse_edges(project_mesh):
    # coarsen(trace=True): every coarse edge drawn on the input surface exactly (ice-coarsen --trace),
    # from its tail's position to its head's, as many polylines as coarse edges; refused for QEM.
    V, F = ice.load_mesh(project_mesh("elephant-with-holes.off"))
    coarse = ice.coarsen(V, F, ratio=0.05, trace=True)
    polylines, ends = coarse.traced_edges
    twin = coarse.twin.ravel()
    assert len(polylines) == ends.shape[0] == int(np.sum((twin < 0) | (np.arange(twin.size) < twin)))
    size = np.linalg.norm(V.max(0) - V.min(0))
    for line, (tail, head) in zip(polylines, ends):
        assert line.shape[0] >= 2
        assert np.linalg.norm(line[0] - coarse.positions[tail]) <= 1e-12 * size
        assert np.linalg.norm(line[-1] - coarse.positions[head]) <= 1e-12 * size
    assert ice.coarsen(V, F, ratio=0.05).traced_edges is None
    with pytest.raises(ValueError, match="trace"):
        ice.coarsen(V, F, ratio=0.05, method="qem", trace=True)
    # Traced lengths come from the walk over the map whether or not the space was traced for
    # drawing: the same coarsening untraced gives the same distances.
    d = ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="traced").distance([0])
    assert np.isfinite(d).all() and d[0] == pytest.approx(0, abs=1e-12)
    untraced = ice.coarsen(V, F, ratio=0.05)
    assert np.array_equal(untraced.lengths, coarse.lengths)
    assert np.array_equal(ice.ProxyGeodesicSolver.from_coarse(V, F, untraced, lengths="traced").distance([0]), d)
    assert not np.array_equal(ice.ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths="intrinsic").distance([0]), d)


def test_heat_flow_conserves_mass_and_matches_scipy(spot):
    V, F, coarse = spot
    proxy = ice.Proxy(V, F, coarse)
    u0 = np.exp(-20 * np.sum((V - V[0]) ** 2, axis=1))
    tau = 1e-3
    u = ice.ProxyHeatSolver(proxy, tau).integrate(u0, 3)
    M = proxy.fine_mass
    assert u @ (M @ np.ones_like(u)) == pytest.approx(u0 @ (M @ np.ones_like(u0)), rel=1e-9)  # P·1 = 1 keeps mass
    # scipy on the coarse operators: L² projection, three backward-Euler steps, prolongation
    Mc, Lc, P = proxy.coarse_mass.tocsc(), proxy.coarse_laplacian.tocsc(), coarse.P
    state = P.T @ (M @ u0)
    A = (Mc + tau * Lc).tocsc()
    uc = scipy.sparse.linalg.spsolve(A, state)
    for _ in range(2):
        uc = scipy.sparse.linalg.spsolve(A, Mc @ uc)
    assert np.abs(P @ uc - u).max() < 1e-9 * np.abs(u).max()


def test_multigrid_on_a_scipy_matrix(spot):
    V, F, _ = spot
    prolongations = ice.hierarchy(V, F)
    assert prolongations[0].shape[0] == V.shape[0]
    for P in prolongations:
        assert np.abs(np.asarray(P.sum(axis=1)).ravel() - 1).max() < 1e-12
    L, M = ice.cotan_laplacian(V, F), ice.mass_matrix(V, F)
    A = (M + 1e-2 * L).tocsr()
    b = M @ np.cos(V[:, 1] * 5)
    solver = ice.MultigridSolver(prolongations, tolerance=1e-10)
    solver.setup(A)
    x = solver.solve(b)
    assert solver.report["converged"] and solver.report["iterations"] < 30
    assert np.abs(x - scipy.sparse.linalg.spsolve(A.tocsc(), b)).max() < 1e-7 * np.abs(x).max()
    report = solver.report  # the keys of poisson-coarse --solver multigrid
    assert len(report["levels"]) == len(prolongations) + 1 and report["tolerance"] == 1e-10
    assert report["cycle"] == "pcg" and report["operator_complexity"] > 1
    with pytest.raises(ValueError, match="square"):
        solver.setup(A[:, :-1])
    with pytest.raises(ValueError, match="b must have"):
        solver.solve(b[:-1])


def test_hierarchy_order_and_threads(spot):
    """The hierarchy's breadth-first numbering serves the solver, and its thread count changes nothing."""
    V, F, _ = spot
    prolongations, order = ice.hierarchy(V, F, threads=2, return_order=True)
    assert order.dtype == np.int32 and np.array_equal(np.sort(order), np.arange(V.shape[0]))
    # Threads matter from 50,000 live vertices on (the removals go range by range): spot Loop x3.
    Vs, Fs = ice.loop_subdivide(V, F, 3)
    assert Vs.shape[0] > 50000
    one, two = ice.hierarchy(Vs, Fs, threads=1), ice.hierarchy(Vs, Fs, threads=2)
    assert len(one) == len(two)
    for P, Q in zip(one, two):
        assert P.shape == Q.shape and (P != Q).nnz == 0
    L, M = ice.cotan_laplacian(V, F), ice.mass_matrix(V, F)
    A = (M + 1e-2 * L).tocsr()
    b = M @ np.cos(V[:, 1] * 5)
    x = {}
    for name, given in (("rcm", None), ("hierarchy", order)):
        solver = ice.MultigridSolver(prolongations, tolerance=1e-10, locality_order=given)
        solver.setup(A)
        x[name] = solver.solve(b)
        assert solver.report["converged"]
    assert np.abs(x["rcm"] - x["hierarchy"]).max() < 1e-8 * np.abs(x["rcm"]).max()
    with pytest.raises(ValueError, match="locality_order"):
        ice.MultigridSolver(prolongations, locality_order=order[:-1])
    with pytest.raises(ValueError, match="locality_order"):  # not a permutation
        ice.MultigridSolver(prolongations, locality_order=np.zeros(V.shape[0], dtype=np.int32))
    with pytest.raises(ValueError, match="threads"):
        ice.hierarchy(V, F, threads=-1)


def test_distance_oracle(spot):
    V, F, coarse = spot
    oracle = ice.DistanceOracle(coarse)
    rng = np.random.default_rng(3)
    pairs = rng.integers(0, V.shape[0], size=(200, 2))
    d = oracle.distances(pairs)
    assert np.allclose(d, oracle.distances(pairs[:, ::-1]))  # symmetric
    assert oracle.distance(5, 5) == 0
    row = oracle.distances_from(int(pairs[0, 0]))
    assert row[pairs[0, 1]] == pytest.approx(d[0])
    # close to the fine heat-method distance (a coarse space of every vertex: P = I, the fine solve)
    full = ice.coarsen(V, F, ratio=1.0)
    assert full.n_vertices == V.shape[0] and abs(full.P - scipy.sparse.identity(V.shape[0])).max() == 0
    fine = ice.ProxyGeodesicSolver(ice.Proxy(V, F, full), method="heat").distance([11])
    far = fine > 0.05 * fine.max()
    assert np.mean(np.abs(oracle.distances_from(11)[far] - fine[far]) / fine[far]) < 0.08  # measured 0.041
    samples = oracle.farthest_point_samples(10)
    assert len(set(samples.tolist())) == 10
    D = oracle.distance_matrix(samples)
    assert D.dtype == np.float32 and D.shape == (10, 10) and np.allclose(D, D.T)
    with pytest.raises(ValueError, match="pairs"):
        oracle.distances(np.array([[0, V.shape[0]]]))
    # Coarse pairs marched without subdividing the coarse mesh (the default subdivides once): other
    # distances.
    plain = ice.DistanceOracle(coarse, subdivisions=0)
    assert np.abs(plain.distances(pairs) - d).max() > 1e-6 * d.max()
    with pytest.raises(ValueError, match="subdivisions"):
        ice.DistanceOracle(coarse, subdivisions=-1)
    # On curvature-corrected lengths (geodesic-coarse's oracle modes for ICE): each edge scaled by
    # exp(K l²/24) (the oracle's divisor), nearer the fine distances here, and the same as a proxy
    # marching on them.
    lengths = ice.curvature_corrected_lengths(V, F, coarse, divisor=24)
    assert lengths.shape == coarse.lengths.shape
    assert np.all(lengths[coarse.lengths > 0] > 0) and not np.array_equal(lengths, coarse.lengths)
    corrected = ice.DistanceOracle(coarse, lengths=lengths)
    error = lambda o: np.mean(np.abs(o.distances_from(11)[far] - fine[far]) / fine[far])
    assert error(corrected) < error(oracle)
    assert np.array_equal(ice.curvature_corrected_lengths(V, F, coarse, lengths=coarse.lengths, divisor=24), lengths)
    weaker = ice.curvature_corrected_lengths(V, F, coarse)  # the proxy's divisor, 48: half the log-scale
    changed = lengths != coarse.lengths
    assert np.allclose(np.log(weaker[changed] / coarse.lengths[changed]), 0.5 * np.log(lengths[changed] / coarse.lengths[changed]), rtol=1e-6, atol=1e-12)
    with pytest.raises(ValueError, match="divisor"):
        ice.curvature_corrected_lengths(V, F, coarse, divisor=0)
    with pytest.raises(ValueError, match="lengths"):
        ice.DistanceOracle(coarse, lengths=np.ones((2, 3)))

def test_distance_oracle_from_mesh(project_mesh, tmp_path, tool):
    # DistanceOracle.from_mesh: the oracle of geodesic-coarse's oracle modes. Its default marches on
    # traced, curvature-corrected lengths for ICE (the constructor on the coarse mesh's own), on
    # QEM's own.
    path = project_mesh("spot.obj")
    V, F = ice.load_mesh(path)
    coarse = ice.coarsen(V, F, ratio=0.05, use="geodesic")
    pairs = np.random.default_rng(5).integers(0, V.shape[0], size=(300, 2))
    corrected = ice.DistanceOracle(coarse, lengths=ice.curvature_corrected_lengths(V, F, coarse, divisor=24))
    assert np.array_equal(ice.DistanceOracle.from_mesh(V, F, coarse, lengths="intrinsic").distances(pairs),
                          corrected.distances(pairs))
    assert np.array_equal(ice.DistanceOracle.from_mesh(V, F, coarse, lengths="intrinsic",
                                                       curvature_correction=False).distances(pairs),
                          ice.DistanceOracle(coarse).distances(pairs))
    qem = ice.coarsen(V, F, ratio=0.05, method="qem")
    assert np.array_equal(ice.DistanceOracle.from_mesh(V, F, qem).distances(pairs), ice.DistanceOracle(qem).distances(pairs))
    # Traced lengths: the same pairs as geodesic-coarse --pairs --coarse-lengths traced (to its 9 digits).
    np.savetxt(tmp_path / "pairs.txt", pairs, fmt="%d")
    tool("geodesic-coarse", path, "--ratio", "0.05", "--pairs", tmp_path / "pairs.txt", "--pairs-out",
         tmp_path / "out.csv", "--coarse-lengths", "traced", "-q")
    written = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)
    traced = ice.DistanceOracle.from_mesh(V, F, coarse, lengths="traced").distances(pairs)
    assert np.array_equal(ice.DistanceOracle.from_mesh(V, F, coarse).distances(pairs), traced)
    assert np.array_equal(written[:, :2].astype(int), pairs)
    assert np.abs(traced - written[:, 2]).max() <= 1e-8 * traced.max()
    assert np.abs(traced - corrected.distances(pairs)).max() > 1e-6 * traced.max()
    with pytest.raises(ValueError, match="traced"):
        ice.DistanceOracle.from_mesh(V, F, qem, lengths="traced")
    with pytest.raises(ValueError, match="marching"):
        ice.DistanceOracle.from_mesh(V, F, coarse, method="heat", lengths="traced")
    with pytest.raises(ValueError, match="another mesh"):
        ice.DistanceOracle.from_mesh(V[:-1], F[:10], coarse)


def test_dirichlet_values_follow_the_order_of_fixed(spot, project_mesh):
    """Values belong to the vertices in the caller's order, for ICE and QEM, plain and polished."""
    V, F, _ = spot
    fixed = np.array([1385, 1499, 7, 2000])  # not sorted, and QEM numbers its coarse vertices otherwise
    values = np.array([1.0, -1.0, 0.5, 2.0])
    for method in ("ice", "qem"):
        coarse = ice.coarsen(V, F, ratio=0.05, locked=fixed, method=method)
        proxy = ice.Proxy(V, F, coarse)
        for polish in (0, 50):
            u = ice.ProxyPoissonSolver(proxy, fixed=fixed, polish=polish).solve(np.zeros(len(V)), values)
            assert np.array_equal(u[fixed], values), (method, polish)
    u = ice.solve_poisson(V, F, np.zeros(len(V)), fixed=fixed[::-1], values=values[::-1], ratio=0.05, locked=[3])
    assert np.array_equal(u[fixed], values)
    with pytest.raises(ValueError, match="given twice"):
        ice.ProxyPoissonSolver(proxy, fixed=[7, 1385, 7])
    L = ice.cotan_laplacian(V, F) + ice.mass_matrix(V, F)
    solver = ice.MultigridSolver(ice.hierarchy(V, F))
    solver.setup(L, constrained=[10, 3])
    x = solver.solve(np.zeros(len(V)), [2.0, 1.0])
    assert x[10] == 2.0 and x[3] == 1.0
    with pytest.raises(ValueError, match="given twice"):
        solver.setup(L, constrained=[3, 10, 3])


def test_meshes_of_several_components_are_solved_on_each(project_mesh):
    """blobby_3cc (three components): zero-mean Poisson is solved on each component (compatible and
    re-centred on each, a constant per component gives 0), Dirichlet values are needed in every
    component, and geodesics reach the sources' components only (+inf elsewhere) by either coarse
    solver."""
    V, F = ice.load_mesh(project_mesh("blobby_3cc.off"))
    coarse = ice.coarsen(V, F, ratio=0.1)
    proxy = ice.Proxy(V, F, coarse)
    L = ice.cotan_laplacian(V, F)
    n_components, label = scipy.sparse.csgraph.connected_components(L, directed=False)
    assert n_components == 3
    mass = proxy.fine_mass @ np.ones(len(V))  # the proxy's fine mass (of the intrinsic Delaunay mesh)
    f = V[:, 2] + label  # a different mean on each component
    u = ice.ProxyPoissonSolver(proxy).solve(f)
    for c in range(3):
        assert abs(mass[label == c] @ u[label == c]) < 1e-12 * mass.sum() * np.abs(u).max()
    assert np.abs(ice.ProxyPoissonSolver(proxy).solve(label.astype(float))).max() < 1e-12
    with pytest.raises(ValueError, match="no Dirichlet vertex|no --fix"):
        ice.ProxyPoissonSolver(proxy, fixed=[int(coarse.to_input[0])])
    for method in ("marching", "heat"):
        d = ice.ProxyGeodesicSolver(proxy, method=method).distance([0])
        reached = np.isfinite(d)
        assert np.array_equal(reached, label == label[0]), method
        assert d[reached].min() > -0.05 * d[reached].max() and abs(d[0]) < 0.05 * d[reached].max(), method
    with pytest.raises(ValueError, match="marching"):
        ice.ProxyGeodesicSolver(proxy, method="dijkstra")
    u = ice.ProxyHeatSolver(proxy, 1e-3).integrate(V[:, 0])  # heat flow has no pinned vertex: fine
    assert np.isfinite(u).all()


def test_a_proxy_needs_the_mesh_that_was_coarsened(spot):
    V, F, coarse = spot
    order = np.random.default_rng(0).permutation(len(V))
    inverse = np.argsort(order)
    with pytest.raises(ValueError, match="another mesh"):
        ice.Proxy(V[order], inverse[F], coarse)  # the same surface, renumbered
    with pytest.raises(ValueError, match="another mesh"):
        ice.ProxyGeodesicSolver.from_coarse(V[order], inverse[F], coarse)


def test_shared_matrices_are_read_only_views(spot):
    V, F, coarse = spot
    P = coarse.P
    with pytest.raises(ValueError):
        P.data[0] = 2.0
    assert coarse.P.data.base is not None and np.shares_memory(coarse.P.data, P.data)  # one buffer, no copy
    proxy = ice.Proxy(V, F, coarse)
    L1, L2 = proxy.fine_laplacian, proxy.fine_laplacian
    assert np.shares_memory(L1.data, L2.data) and not L1.data.flags.writeable
    Q = 2 * P  # arithmetic makes new, writable matrices
    Q.data[0] = 1.0
    del proxy, coarse
    assert np.isfinite(L1.data).all() and abs(P.sum() - len(V)) < 1e-9  # the views keep their owners alive


def test_one_solver_shared_by_threads(spot):
    """Solver objects may be shared: calls from several threads wait for each other and agree."""
    import threading
    V, F, coarse = spot
    proxy = ice.Proxy(V, F, coarse)
    poisson = ice.ProxyPoissonSolver(proxy, polish=5)  # polishing is the part that is not re-entrant
    multigrid = ice.MultigridSolver(ice.hierarchy(V, F))
    A = ice.cotan_laplacian(V, F) + ice.mass_matrix(V, F)
    multigrid.setup(A)
    rhs = [np.cos(k * V[:, 0]) for k in range(1, 5)]
    expected = [(poisson.solve(f), multigrid.solve(f)) for f in rhs]
    results, errors = [None] * 8, []

    def work(i):
        try:
            f = rhs[i % 4]
            results[i] = (poisson.solve(f), multigrid.solve(f))
        except Exception as error:  # noqa: BLE001 - reported below
            errors.append(error)
    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for i, (u, x) in enumerate(results):
        assert np.array_equal(u, expected[i % 4][0]) and np.array_equal(x, expected[i % 4][1])
