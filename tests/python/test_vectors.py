"""Tangent vector fields: the vector heat method on the input triangles and through a coarse space."""
import numpy as np
import pytest
import scipy.sparse

import ice
from conftest import read_ascii_ply_fields


def angles_degrees(a, b):
    return np.degrees(np.abs(np.angle(a * np.conj(b))))


@pytest.fixture(scope="module")
def spot(project_mesh):
    V, F = ice.load_mesh(project_mesh("spot.obj"))
    return V, F, ice.coarsen(V, F, n=500)


def flat_grid(k: int = 12):
    """A k×k grid of the unit square, two triangles per cell, counter-clockwise."""
    x, y = np.meshgrid(np.linspace(0, 1, k), np.linspace(0, 1, k))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(k * k)])
    F = []
    for i in range(k - 1):
        for j in range(k - 1):
            a, b, c, d = i * k + j, i * k + j + 1, (i + 1) * k + j, (i + 1) * k + j + 1
            F += [[a, b, d], [a, d, c]]
    return V, np.array(F)


def test_transport_in_the_plane_is_the_identity():
    # Parallel transport in a flat domain keeps the vector: every vertex gets the source's 3D vector.
    V, F = flat_grid()
    solver = ice.VectorHeatSolver(V, F)
    direction = np.array([[0.6, 0.8, 0.0]])
    start = solver.to_tangent([40], direction)
    assert abs(start[0]) == pytest.approx(1.0, abs=1e-12)
    field = solver.to_ambient(solver.transport(40, start[0]))
    assert np.abs(field - direction).max() < 1e-9


def test_obtuse_input_triangles_are_solved_on_their_intrinsic_delaunay_triangulation():
    # Rows of the grid sheared alternately by 0.45 of a cell: half the triangles are obtuse, their
    # long diagonals not Delaunay. On the intrinsic Delaunay triangulation (the default) transport
    # in the plane is still the identity; the input's own triangles are kept with fine="input".
    V, F = flat_grid(16)
    row = np.round(V[:, 1] * 15).astype(int)
    V[:, 0] += np.where(row % 2 == 1, 0.45 / 15, 0.0) * (row < 15)
    default = ice.VectorHeatSolver(V, F)
    direction = np.array([[0.6, 0.8, 0.0]])
    start = default.to_tangent([100], direction)[0]
    assert np.abs(default.to_ambient(default.transport(100, start)) - direction).max() < 1e-9
    on_input = ice.VectorHeatSolver(V, F, fine="input")
    assert np.all(np.isfinite(on_input.transport(100, start)))
    with pytest.raises(ValueError, match="fine"):
        ice.VectorHeatSolver(V, F, fine="delaunay")


def test_the_proxy_approaches_the_fine_transport(spot):
    V, F, coarse = spot
    reference = ice.VectorHeatSolver(V, F).transport(0, 1j)
    for operators, bound in (("galerkin", 8.0), ("intrinsic", 12.0)):
        proxy = ice.VectorHeatSolver(V, F, coarse, operators=operators, solver="diffusion")
        field = proxy.transport(0, 1j)
        assert field.dtype == np.complex128 and field.shape == (V.shape[0],)
        assert np.median(angles_degrees(field, reference)) < bound, operators
        stats = proxy.prolongation_stats
        assert stats["unmatched"] == 0 and stats["fitted"] == V.shape[0]
        # P_vec has P's pattern, and its moduli are P's weights.
        P_vec, P = proxy.vector_prolongation, coarse.P
        assert scipy.sparse.issparse(P_vec) and P_vec.shape == P.shape
        assert abs(abs(P_vec) - P).max() < 1e-12
    assert ice.VectorHeatSolver(V, F).prolongation_stats is None


def test_the_sweep_is_the_default_and_closer_to_the_fine_transport(spot):
    V, F, coarse = spot
    reference = ice.VectorHeatSolver(V, F).transport(0, 1j)
    sweep = ice.VectorHeatSolver(V, F, coarse)
    field = sweep.transport(0, 1j)
    assert np.array_equal(field, ice.VectorHeatSolver(V, F, coarse, solver="sweep").transport(0, 1j))
    diffusion = ice.VectorHeatSolver(V, F, coarse, solver="diffusion").transport(0, 1j)
    # Measured on spot at 500 coarse vertices: 0.0004 against 4.3 degrees median; 3.2 after the first
    # pass alone.
    assert np.median(angles_degrees(field, reference)) < np.median(angles_degrees(diffusion, reference))
    first = ice.VectorHeatSolver(V, F, coarse, sweep_passes=0).transport(0, 1j)
    assert np.median(angles_degrees(field, reference)) < np.median(angles_degrees(first, reference))
    with pytest.raises(ValueError, match="sweep_passes"):
        ice.VectorHeatSolver(V, F, coarse, sweep_passes=-1)
    # The coarse-grid correction (the default, before every second pass) against the passes alone, 10 each.
    corrected = ice.VectorHeatSolver(V, F, coarse, sweep_passes=10).transport(0, 1j)
    plain = ice.VectorHeatSolver(V, F, coarse, sweep_passes=10, sweep_coarse_interval=0).transport(0, 1j)
    assert np.median(angles_degrees(corrected, reference)) < 0.5 * np.median(angles_degrees(plain, reference))
    with pytest.raises(ValueError, match="sweep_coarse_interval"):
        ice.VectorHeatSolver(V, F, coarse, sweep_coarse_interval=-1)
    assert np.abs(np.abs(field) - 1).max() < 1e-9  # one source: its magnitude everywhere
    assert sweep.vector_prolongation is None and sweep.prolongation_stats is None
    with pytest.raises(ValueError, match="solver"):
        ice.VectorHeatSolver(V, F, coarse, solver="exact")


def test_interpolation_keeps_the_prescribed_vectors(spot):
    V, F, coarse = spot
    sources, vectors = [0, 1500], np.array([1 + 0j, 2j])
    fine = ice.VectorHeatSolver(V, F).interpolate(sources, vectors)
    assert angles_degrees(fine[sources], vectors).max() < 1e-6
    assert np.abs(np.abs(fine[sources]) - np.abs(vectors)).max() < 1e-6
    proxy = ice.VectorHeatSolver(V, F, coarse).interpolate(sources, vectors)
    assert np.abs(proxy).min() > 0
    assert angles_degrees(proxy[sources], vectors).max() < 10


def test_tangent_and_ambient_round_trip(spot):
    V, F, _ = spot
    solver = ice.VectorHeatSolver(V, F)
    rng = np.random.default_rng(3)
    vertices = rng.choice(V.shape[0], 20, replace=False)
    field = np.zeros(V.shape[0], complex)
    field[vertices] = np.exp(1j * rng.uniform(0, 2 * np.pi, 20))
    ambient = solver.to_ambient(field)
    back = solver.to_tangent(vertices, ambient[vertices])
    assert np.abs(back - field[vertices]).max() < 1e-9


def test_one_call_equals_the_solver_and_the_tool(tmp_path, tool, project_mesh):
    path = project_mesh("spot.obj")
    V, F = ice.load_mesh(path)
    field = ice.transport_vectors(V, F, 0, np.exp(1j * np.radians(30)), n=500)
    coarse = ice.coarsen(V, F, n=500)
    assert np.array_equal(field, ice.VectorHeatSolver(V, F, coarse).transport(0, np.exp(1j * np.radians(30))))
    first = ice.transport_vectors(V, F, 0, np.exp(1j * np.radians(30)), n=500, sweep_passes=0)
    assert np.array_equal(first, ice.VectorHeatSolver(V, F, coarse, sweep_passes=0).transport(0, np.exp(1j * np.radians(30))))
    assert not np.array_equal(first, field)
    out = tmp_path / "v.ply"
    tool("vector-coarse", path, "--source", "0", "--vector", "30", "--vertices", "500", "--no-reference", "--ascii", "-q",
         "-o", out)
    fields = read_ascii_ply_fields(out)
    expected = np.column_stack([fields["vector_x"], fields["vector_y"], fields["vector_z"]])
    ambient = ice.transport_vectors(V, F, [0], [np.exp(1j * np.radians(30))], n=500, ambient=True)
    assert np.abs(ambient - expected).max() <= 1e-6  # the tool writes ASCII with 9 digits or more


def test_bad_arguments_are_refused(spot, tmp_path):
    V, F, coarse = spot
    solver = ice.VectorHeatSolver(V, F, coarse)
    with pytest.raises(ValueError, match="source"):
        solver.transport(V.shape[0])
    with pytest.raises(ValueError, match="nonzero"):
        solver.transport(0, 0)
    with pytest.raises(ValueError, match="vectors has 1 entries, expected 2"):
        solver.interpolate([0, 1], [1j])
    with pytest.raises(ValueError, match="not finite"):
        solver.interpolate([0], [complex(np.nan, 0)])
    with pytest.raises(ValueError, match="operators"):
        ice.VectorHeatSolver(V, F, coarse, operators="exact")
    with pytest.raises(ValueError, match="time_factor"):
        ice.VectorHeatSolver(V, F, time_factor=0)
    with pytest.raises(ValueError, match="another mesh"):
        ice.VectorHeatSolver(V[:-1], F[F.max(1) < V.shape[0] - 1], coarse)
    with pytest.raises(ValueError, match="fine-to-coarse map"):
        ice.VectorHeatSolver(V, F, ice.coarsen(V, F, n=500, keep_map=False))
    coarse.save(tmp_path / "c.ilm")
    with pytest.raises(ValueError, match="read from a file"):
        ice.VectorHeatSolver(V, F, ice.load_coarse_mesh(tmp_path / "c.ilm"))
    with pytest.raises(ValueError, match="3 columns"):
        solver.to_tangent([0], [[1.0, 0.0]])
