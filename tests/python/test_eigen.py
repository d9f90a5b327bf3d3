"""The eigenbasis through a coarse proxy from Python: M-orthonormal vectors, eigenvalues above the fine
ones (Galerkin Rayleigh quotients) and close to them, the descriptors' sums, bad k refused."""
import warnings

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse.linalg

import ice


@pytest.fixture(scope="module")
def spot(project_mesh):
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    return V, F


def test_eigenbasis_against_the_fine_pencil(spot, tmp_path):
    V, F = spot
    k = 12
    values, vectors = ice.eigenbasis(V, F, k, ratio=0.1, cache=tmp_path)
    assert values.shape == (k,) and vectors.shape == (len(V), k)
    assert np.all(np.diff(values) >= 0)
    Fi, lengths, _ = ice.intrinsic_delaunay(V, F)
    L = ice.cotan_laplacian(F=Fi, lengths=lengths, n=len(V))
    M = ice.mass_matrix(F=Fi, lengths=lengths, n=len(V))
    assert np.abs(vectors.T @ (M @ vectors) - np.eye(k)).max() < 1e-8
    fine = np.sort(scipy.sparse.linalg.eigsh(L.tocsc(), k=k, M=M.tocsc(), sigma=-1e-6, which="LM")[0])
    assert abs(values[0]) < 1e-8 and abs(fine[0]) < 1e-6
    assert np.all(values[1:] >= fine[1:] * (1 - 1e-9))
    assert np.median(values[1:] / fine[1:] - 1) < 0.05
    # Warm from the store (the proxy and the coarse pairs): the same basis to the bit; without it too.
    assert len(list(tmp_path.glob("eigenpairs-*.ice"))) == 1
    again = ice.eigenbasis(V, F, k, ratio=0.1, cache=tmp_path)
    assert np.array_equal(again[0], values) and np.array_equal(again[1], vectors)
    unstored = ice.eigenbasis(V, F, k, ratio=0.1, cache=False)
    assert np.array_equal(unstored[0], values) and np.array_equal(unstored[1], vectors)
    # Descriptors: Σ_x M_x HKS(x, t) = Σ_i exp(−λ_i t); the WKS weights are normalised per energy.
    mass = M.diagonal()
    times = np.array([0.001, 0.01])
    hks = ice.heat_kernel_signature(values, vectors, times)
    assert hks.shape == (len(V), 2)
    np.testing.assert_allclose(mass @ hks, np.exp(-np.outer(np.maximum(values, 0), times)).sum(axis=0), rtol=1e-9)
    wks = ice.wave_kernel_signature(values, vectors, np.log(values[2:4]), 0.3)
    np.testing.assert_allclose(mass @ wks, 1.0, rtol=1e-9)
    assert ice.reconstruction_error(values, vectors, mass, vectors[:, 3]) < 1e-9
    assert ice.reconstruction_error(values, vectors, mass, np.cos(40 * V[:, 0])) > 0.1
    with pytest.raises(ValueError, match="coarse space has"):
        ice.eigenbasis(V, F, 10_000, ratio=0.1, cache=False)
    # "auto" is the eigenbasis's own default, P smoothed twice (as spectral-coarse), closer to the fine
    # eigenvalues than P smoothed once; a Proxy given that prolongation gives the same basis.
    assert ice._ice._resolve_prolongation("auto", "galerkin", False, eigenpairs=True) == "smoothed_twice"
    assert ice._ice._resolve_prolongation("auto", "galerkin", False) == "smoothed"
    coarse = ice.coarsen(V, F, ratio=0.1)
    twice = ice.proxy_eigenbasis(ice.Proxy(V, F, coarse, prolongation="smoothed_twice"), k)
    assert np.array_equal(twice[0], values) and np.array_equal(twice[1], vectors)
    once = ice.eigenbasis(V, F, k, ratio=0.1, prolongation="smoothed", cache=False)[0]
    assert np.median(values[1:] / fine[1:] - 1) < np.median(once[1:] / fine[1:] - 1)


def test_dirichlet_eigenbasis_vanishes_on_the_boundary(project_mesh):
    V, F = ice.load_mesh(project_mesh("lion-head.off"))  # an open surface: 36 boundary vertices
    boundary = ice.boundary_vertices(F)
    assert len(boundary) > 0
    values, vectors = ice.eigenbasis(V, F, 6, boundary="dirichlet", ratio=0.05, cache=False)
    assert np.all(vectors[boundary] == 0)
    assert values[0] > 0  # no constant mode under Dirichlet conditions
    Fi, lengths, _ = ice.intrinsic_delaunay(V, F)
    M = ice.mass_matrix(F=Fi, lengths=lengths, n=len(V))
    assert np.abs(vectors.T @ (M @ vectors) - np.eye(6)).max() < 1e-8
    with pytest.raises(ValueError, match="boundary must be"):
        ice.eigenbasis(V, F, 6, boundary="robin")


def test_refined_eigenbasis_reaches_the_fine_pairs(spot, tmp_path):
    V, F = spot
    k = 12
    Fi, lengths, _ = ice.intrinsic_delaunay(V, F)
    L = ice.cotan_laplacian(F=Fi, lengths=lengths, n=len(V))
    M = ice.mass_matrix(F=Fi, lengths=lengths, n=len(V))
    fine = np.sort(scipy.sparse.linalg.eigsh(L.tocsc(), k=k, M=M.tocsc(), sigma=-1e-6, which="LM", tol=1e-13)[0])
    values, vectors = ice.eigenbasis(V, F, k, ratio=0.05, cache=tmp_path, refine_tolerance=1e-7)
    assert np.abs(vectors.T @ (M @ vectors) - np.eye(k)).max() < 1e-10
    residuals = np.linalg.norm(L @ vectors - (M @ vectors) * values, axis=0) / (
        np.maximum(np.abs(values), np.abs(values).max() * (np.abs(values) <= 1e-6 * np.abs(values).max()))
        * np.linalg.norm(M @ vectors, axis=0))
    assert residuals.max() <= 1e-7
    np.testing.assert_allclose(values[1:], fine[1:], rtol=1e-8)
    # The proxy's start was a few per cent off; the hierarchy went through the store with the proxy.
    start, _ = ice.eigenbasis(V, F, k, ratio=0.05, cache=tmp_path)
    assert np.median(start[1:] / fine[1:] - 1) > 1e-4
    proxy = ice.Proxy(V, F, ice.coarsen(V, F, ratio=0.05, cache=False), operators="galerkin")
    again, _, info = ice.refined_eigenbasis(proxy, V, F, k, refine_tolerance=1e-7, cache=tmp_path)
    assert info["converged"] and info["iterations"] >= 1 and info["hierarchy_cache"]["status"] == "hit"
    assert max(info["residuals"]) <= 1e-7
    np.testing.assert_allclose(again, values, rtol=1e-9, atol=1e-9 * values.max())  # the zero mode: round-off
    with pytest.raises(ValueError, match="refine_tolerance must be > 0"):
        ice.refined_eigenbasis(proxy, V, F, k, refine_tolerance=0)
    with pytest.raises(ValueError, match="vertices, the proxy's fine mesh"):
        ice.refined_eigenbasis(proxy, V[:-1], F[:10], k)
    # A refinement stopped before its tolerance says so.
    _, _, info = ice.refined_eigenbasis(proxy, V, F, k, refine_tolerance=1e-7, max_iterations=1, cache=tmp_path)
    assert not info["converged"] and info["iterations"] == 1 and max(info["residuals"]) > 1e-7


def test_refined_route_sizes_its_coarse_space_by_its_pairs(spot, tmp_path):
    """Without a ratio or a vertex count the refined route coarsens to refined_coarse_vertices(k): a fixed
    number per coarse pair it computes (k + guard + 2 (k + guard) by default), the same run as naming it."""
    V, F = spot
    k = 4
    per_pair = ice.refined_coarse_vertices(k) // 24  # guard 4, 16 coarse directions
    assert ice.refined_coarse_vertices(k) == 24 * per_pair and per_pair >= 1
    assert ice.refined_coarse_vertices(k, coarse_directions=0) == 8 * per_pair
    values, vectors = ice.eigenbasis(V, F, k, refine_tolerance=1e-7, cache=False)
    named, named_vectors = ice.eigenbasis(V, F, k, refine_tolerance=1e-7, cache=False, n=ice.refined_coarse_vertices(k))
    assert np.array_equal(values, named) and np.array_equal(vectors, named_vectors)
    five_percent, _ = ice.eigenbasis(V, F, k, refine_tolerance=1e-7, cache=False, ratio=0.05)
    np.testing.assert_allclose(five_percent, values, rtol=1e-8, atol=1e-9 * values.max())
    with pytest.raises(ValueError, match="k must be >= 1"):
        ice.refined_coarse_vertices(0)
    # A mesh below that size (12 x 12 grid, 144 vertices; k = 4: 480) is not coarsened: the fine
    # eigensolver gives its pairs directly, with no warning, to the tolerance, as scipy's.
    x, y = np.meshgrid(np.arange(12.0), np.arange(12.0))
    grid = np.column_stack([x.ravel(), y.ravel(), np.zeros(144)])
    cells = np.array([[i * 12 + j, i * 12 + j + 1, (i + 1) * 12 + j + 1] for i in range(11) for j in range(11)]
                     + [[i * 12 + j, (i + 1) * 12 + j + 1, (i + 1) * 12 + j] for i in range(11) for j in range(11)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        small, small_vectors = ice.eigenbasis(grid, cells, k, refine_tolerance=1e-8, cache=False)
    Fi, lengths, _ = ice.intrinsic_delaunay(grid, cells)
    L = ice.cotan_laplacian(F=Fi, lengths=lengths, n=144)
    M = ice.mass_matrix(F=Fi, lengths=lengths, n=144)
    fine = np.sort(scipy.linalg.eigh(L.toarray(), M.toarray(), eigvals_only=True)[:k])
    assert abs(small[0]) < 1e-8
    np.testing.assert_allclose(small[1:], fine[1:], rtol=1e-9)
    residuals = np.linalg.norm(L @ small_vectors - (M @ small_vectors) * small, axis=0)[1:] / (
        small[1:] * np.linalg.norm(M @ small_vectors, axis=0)[1:])
    assert residuals.max() <= 1e-8
    proxy = ice.Proxy(grid, cells, ice.coarsen(grid, cells, n=144, cache=False), operators="galerkin")
    _, _, info = ice.refined_eigenbasis(proxy, grid, cells, k, refine_tolerance=1e-8, cache=False)
    assert info["fine_eigensolve"] and info["converged"] and info["iterations"] == 0


def test_a_refinement_that_stops_early_warns(spot, tmp_path, monkeypatch):
    V, F = spot
    refine = ice.refined_eigenbasis
    monkeypatch.setattr(ice, "refined_eigenbasis", lambda *args, **kw: refine(*args, max_iterations=1, **kw))
    with pytest.warns(RuntimeWarning, match="the refinement stopped after 1 iterations"):
        ice.eigenbasis(V, F, 6, ratio=0.05, cache=tmp_path, refine_tolerance=1e-7)
