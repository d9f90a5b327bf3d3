"""Point clouds and non-manifold meshes from Python: nonmanifold="tufted" and ice.point_cloud_triangles."""
import numpy as np
import pytest

import ice


def sphere_points(n):
    """n points spread evenly over the unit sphere (a Fibonacci spiral)."""
    i = np.arange(n)
    z = 1 - (2 * i + 1) / n
    r = np.sqrt(1 - z * z)
    phi = i * np.pi * (3 - np.sqrt(5))
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def test_point_cloud_poisson_near_the_sphere_solution():
    P = sphere_points(3000)
    F = ice.point_cloud_triangles(P)
    assert F.shape[1] == 3 and F.shape[0] > 5000
    assert np.array_equal(np.unique(F), np.arange(3000))  # every point on a triangle
    with pytest.raises(ice.MeshError, match="nonmanifold|inconsistent"):
        ice.coarsen(P, F, ratio=0.1)
    coarse = ice.coarsen(P, F, ratio=0.1, nonmanifold="tufted")
    assert np.allclose(coarse.P @ np.ones(coarse.P.shape[1]), 1, atol=1e-12)
    # −Δu = z on the unit sphere: u = z/2 (zero mean both)
    u = ice.solve_poisson(P, F, P[:, 2], ratio=0.1, nonmanifold="tufted", cache=False)
    exact = P[:, 2] / 2
    u, exact = u - u.mean(), exact - exact.mean()
    assert np.linalg.norm(u - exact) / np.linalg.norm(exact) < 0.05
    with pytest.raises(ValueError, match="galerkin"):
        ice.Proxy(P, F, coarse, operators="intrinsic")


def test_point_cloud_faces_refuse_bad_points():
    P = sphere_points(100)
    with pytest.raises(ValueError, match="same position"):
        ice.point_cloud_triangles(np.vstack([P, P[:1]]))
    with pytest.raises(ValueError, match="one line"):
        ice.point_cloud_triangles(np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)]))


def test_separate_thin_parts_keeps_a_thin_tube_open(tmp_path):
    # Rings of 6 points along a tube of radius 1, as far apart as the points around: by default the 30
    # neighbours reach across and edges pass by the axis; with separate_thin_parts no edge does.
    rng = np.random.default_rng(5)
    around, rings, step = 6, 40, 2 * np.pi / 6
    k, ring = np.meshgrid(np.arange(around), np.arange(rings))
    angle = (k + 0.5 * (ring % 2) + rng.uniform(-0.1, 0.1, k.shape)) * step
    P = np.column_stack([np.cos(angle).ravel(), np.sin(angle).ravel(), (ring * step).ravel()])

    def inner_faces(F):  # faces between the rings away from the open ends
        return F[((F // around >= 2) & (F // around < rings - 2)).all(axis=1)]

    def nearest_edge_midpoint_to_axis(F):
        middle = (P[F] + P[np.roll(F, 1, axis=1)]) / 2
        return np.linalg.norm(middle[..., :2], axis=-1).min()

    apart = ice.point_cloud_triangles(P, separate_thin_parts=True)
    assert len(inner_faces(apart)) == 2 * around * (rings - 5)  # the tube's: two per point
    assert nearest_edge_midpoint_to_axis(inner_faces(apart)) > 0.7
    assert nearest_edge_midpoint_to_axis(inner_faces(ice.point_cloud_triangles(P))) < 0.5
    path = tmp_path / "tube.xyz"
    np.savetxt(path, P)
    assert np.array_equal(ice.load_mesh(path, nonmanifold="tufted", separate_thin_parts=True).F, apart)


def test_point_files_load_with_the_option(tmp_path):
    P = sphere_points(500)
    path = tmp_path / "points.xyz"
    np.savetxt(path, P)
    with pytest.raises(ice.MeshError, match="point cloud of 500 points"):
        ice.load_mesh(path)
    loaded = ice.load_mesh(path, nonmanifold="tufted")
    assert loaded.point_cloud and loaded.V.shape == (500, 3)
    assert np.allclose(loaded.V, P)
    # Heat from one point spreads on the cloud: far hotter near it than on the far side.
    u0 = np.zeros(500)
    u0[0] = 1
    h = ice.heat_flow(loaded.V, loaded.F, u0, time_step=0.01, ratio=0.2, nonmanifold="tufted", cache=False)
    distance = np.linalg.norm(P - P[0], axis=1)
    assert h.shape == (500,) and h[distance < 0.3].mean() > 100 * abs(h[distance > 1.5]).mean()
    repeated = tmp_path / "repeated.xyz"
    np.savetxt(repeated, np.vstack([P, P[7:8]]))
    with pytest.raises(ice.MeshError, match="repeat an earlier point"):
        ice.load_mesh(repeated, nonmanifold="tufted")
    merged = ice.load_mesh(repeated, repair=True, nonmanifold="tufted")
    assert merged.V.shape == (500, 3) and list(merged.source_vertex) == list(range(500))


def test_what_a_cover_does_not_take_yet_is_refused_and_a_setup_saves(tmp_path):
    P = sphere_points(800)
    F = ice.point_cloud_triangles(P)
    coarse = ice.coarsen(P, F, ratio=0.2, nonmanifold="tufted")
    with pytest.raises(ValueError, match="tufted cover"):
        coarse.save(tmp_path / "coarse.ilm")
    with pytest.raises(ValueError, match="tufted cover"):
        ice.VectorHeatSolver(P, F, coarse)
    # The oracle places each point by one of its copies on the cover: the sphere's great-circle
    # distances from point 0 within a few per cent.
    assert coarse.map is not None and coarse.summary["tufted_cover"]
    oracle = ice.DistanceOracle.from_mesh(P, F, coarse)
    pairs = np.array([[0, j] for j in range(0, 800, 7)])
    exact = np.arccos(np.clip(P[pairs[:, 1]] @ P[0], -1, 1))
    got = oracle.distances(pairs)
    assert np.abs(got - exact).mean() < 0.05 * exact.mean()
    with pytest.raises(ValueError, match="tufted cover"):
        ice.DistanceOracle.from_mesh(P, F, coarse, lengths="traced")
    space, proxy = ice.setup_proxy(P, F, ratio=0.2, nonmanifold="tufted", cache=False)
    with pytest.raises(ValueError, match="tufted cover"):
        ice.ProxyGeodesicSolver(proxy)
    # A covered setup saves and loads as any other: the same solves, the cover's fine operators.
    ice.save_setup(tmp_path / "setup.bin", P, F, space, proxy)
    space2, proxy2 = ice.load_setup(tmp_path / "setup.bin", P, F)
    assert space2.summary["tufted_cover"]
    assert (proxy2.fine_laplacian != proxy.fine_laplacian).nnz == 0
    f = P[:, 0] * P[:, 1]
    assert np.array_equal(ice.ProxyPoissonSolver(proxy2).solve(f), ice.ProxyPoissonSolver(proxy).solve(f))
    with pytest.raises(ValueError, match="tufted cover"):
        ice.ProxyGeodesicSolver(proxy2)


def test_multigrid_hierarchy_through_the_cover(tmp_path):
    """A point cloud's hierarchy on its points (the cover's copies merged): PCG with it solves the fine
    robust Laplacian to scipy's solution; refused without the option."""
    import scipy.sparse.linalg
    P = sphere_points(3000)
    F = ice.point_cloud_triangles(P)
    with pytest.raises(ice.MeshError, match="nonmanifold|inconsistent"):
        ice.hierarchy(P, F, coarsest=50, cache=False)
    prolongations, order = ice.hierarchy(P, F, coarsest=50, return_order=True, nonmanifold="tufted", cache=False)
    assert len(prolongations) >= 2 and prolongations[0].shape[0] == 3000
    assert np.array_equal(np.sort(order), np.arange(3000))
    for fine, coarse in zip(prolongations, prolongations[1:]):
        assert fine.shape[1] == coarse.shape[0]
    for Pk in prolongations:
        assert np.allclose(Pk @ np.ones(Pk.shape[1]), 1, atol=1e-12) and Pk.min() >= 0
    # Through a store: saved once, loaded the second time, the same arrays as built without it.
    stored = ice.hierarchy(P, F, coarsest=50, nonmanifold="tufted", cache=tmp_path)
    assert len(list(tmp_path.iterdir())) == 1
    loaded = ice.hierarchy(P, F, coarsest=50, nonmanifold="tufted", cache=tmp_path)
    for built, a, b in zip(prolongations, stored, loaded):
        assert (built != a).nnz == 0 and (a != b).nnz == 0
    _, proxy = ice.setup_proxy(P, F, ratio=0.1, nonmanifold="tufted", cache=False)
    A = (proxy.fine_laplacian + 1e-2 * proxy.fine_mass).tocsr()
    b = proxy.fine_mass @ P[:, 2]
    solver = ice.MultigridSolver(prolongations, tolerance=1e-10, locality_order=order)
    solver.setup(A)
    x = solver.solve(b)
    assert solver.report["converged"] and solver.report["convergence_factor"] < 0.3
    reference = scipy.sparse.linalg.spsolve(A.tocsc(), b)
    assert np.linalg.norm(x - reference) < 1e-7 * np.linalg.norm(reference)


def test_point_cloud_geodesics_by_marching_and_the_heat_method():
    P = sphere_points(3000)
    F = ice.point_cloud_triangles(P)
    d = ice.geodesic_distance(P, F, [0], method="heat", ratio=0.1, nonmanifold="tufted")
    exact = np.arccos(np.clip(P @ P[0], -1, 1))  # great-circle distance on the unit sphere
    assert d.shape == (3000,) and np.isfinite(d).all()
    assert d[0] == pytest.approx(0, abs=1e-12)
    assert np.linalg.norm(d - exact) / np.linalg.norm(exact) < 0.05
    # Coarse marching (the default) on the coarse mesh's own lengths: nearer the sphere's distance.
    marched = ice.geodesic_distance(P, F, [0], ratio=0.1, nonmanifold="tufted")
    assert np.isfinite(marched).all() and marched[0] == pytest.approx(0, abs=1e-12)
    assert np.linalg.norm(marched - exact) < np.linalg.norm(d - exact)
    coarse = ice.coarsen(P, F, ratio=0.1, nonmanifold="tufted", use="geodesic", cache=False)
    own = ice.ProxyGeodesicSolver.from_coarse(P, F, coarse, lengths="intrinsic", curvature_correction=False)
    assert np.array_equal(ice.ProxyGeodesicSolver.from_coarse(P, F, coarse).distance([0]), own.distance([0]))  # the cover's default
    with pytest.raises(ValueError, match="tufted cover"):
        ice.geodesic_distance(P, F, [0], coarse=coarse, lengths="traced")
    with pytest.raises(ValueError, match="from_coarse"):  # a Proxy's fine mesh has one fan per sheet
        ice.ProxyGeodesicSolver(ice.Proxy(P, F, coarse))


def test_vectors_in_space_through_the_cover(project_mesh):
    """ice.transport_directions on a point cloud's cover: tangent to the sphere, the source's direction
    at the source; on a manifold mesh the option changes nothing."""
    P = sphere_points(1500)
    F = ice.point_cloud_triangles(P)
    d = np.array([[0.0, 0.0, 1.0]]) - (P[0] @ [0.0, 0.0, 1.0]) * P[0]  # tangent at point 0
    field = ice.transport_directions(P, F, [0], d, ratio=0.2, nonmanifold="tufted")
    assert field.shape == (1500, 3) and np.isfinite(field).all()
    norms = np.linalg.norm(field, axis=1)
    assert norms.min() > 0
    # Tangent to the sphere up to the triangles' tilt against its tangent planes (spacing ~0.09: ~0.05).
    assert np.median(np.abs(np.einsum("ij,ij->i", field, P)) / norms) < 0.15
    assert np.dot(field[0], d[0]) / (norms[0] * np.linalg.norm(d[0])) > 0.99
    with pytest.raises(ValueError, match="normal to the surface"):
        ice.transport_directions(P, F, [0], [[0.0, 0.0, 0.0]], ratio=0.2, nonmanifold="tufted")
    mesh = ice.load_mesh(project_mesh("spot.obj"))
    plain = ice.transport_directions(mesh.V, mesh.F, [0], [[0.0, 0.0, 1.0]], ratio=0.1)
    assert np.array_equal(plain, ice.transport_directions(mesh.V, mesh.F, [0], [[0.0, 0.0, 1.0]], ratio=0.1, nonmanifold="tufted"))
