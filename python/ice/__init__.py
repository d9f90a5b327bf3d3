"""ICE: PDE solves on triangle meshes through a small intrinsic proxy of the mesh.

Meshes are numpy arrays as in libigl, potpourri3d and trimesh: V (n×3 float64 positions) and
F (m×3 integer vertex indices, counter-clockwise); operators and P are scipy.sparse matrices.

    import ice
    V, F = ice.load_mesh("bunny.ply")
    coarse = ice.coarsen(V, F, ratio=0.05)          # intrinsic coarse mesh, P, fine-to-coarse map
    u = ice.solve_poisson(V, F, f, coarse=coarse)   # Poisson through the proxy, on every vertex

Long calls release the GIL. Bad arrays raise TypeError/ValueError naming the argument and entry;
refused meshes and unreadable files raise ice.MeshError with the tools' message.
"""
from __future__ import annotations

from ._ice import (  # noqa: F401  (the package's API)
    DEFAULT_COARSENING_REGIONS,
    CoarseSpace,
    DistanceOracle,
    MeshError,
    MultigridSolver,
    Proxy,
    ProxyGeodesicSolver,
    ProxyHeatSolver,
    ProxyPoissonSolver,
    VectorHeatSolver,
    boundary_vertices,
    coarsen,
    cotan_laplacian,
    curvature_corrected_lengths,
    face_lengths,
    heat_kernel_signature,
    hierarchy,
    intrinsic_delaunay,
    load_coarse_mesh,
    load_coarse_space,
    load_hierarchy,
    load_setup,
    loop_subdivide,
    mass_matrix,
    point_cloud_triangles,
    proxy_eigenbasis,
    refined_coarse_vertices,
    refined_eigenbasis,
    reconstruction_error,
    save_coarse_space,
    save_hierarchy,
    save_mesh,
    save_setup,
    setup_proxy,
    validate,
    wave_kernel_signature,
)
from . import _ice

import os
import warnings

import numpy as np

__all__ = [
    "DEFAULT_COARSENING_REGIONS", "CoarseSpace", "DistanceOracle", "LoadedMesh", "MeshError", "MultigridSolver", "Proxy",
    "ProxyGeodesicSolver", "ProxyHeatSolver", "ProxyPoissonSolver", "coarsen", "cotan_laplacian",
    "boundary_vertices", "curvature_corrected_lengths", "eigenbasis", "face_lengths", "geodesic_distance", "heat_flow", "heat_kernel_signature",
    "hierarchy", "intrinsic_delaunay", "load_coarse_mesh", "load_coarse_space", "load_hierarchy", "load_mesh", "load_setup", "loop_subdivide", "mass_matrix",
    "point_cloud_triangles", "proxy_eigenbasis", "refined_coarse_vertices", "refined_eigenbasis",
    "read_mesh", "reconstruction_error", "save_coarse_space", "save_hierarchy", "save_mesh", "save_setup", "setup_proxy", "solve_poisson", "transport_directions", "transport_vectors", "validate", "wave_kernel_signature",
    "VectorHeatSolver",
]
__version__ = "0.1.0"


class LoadedMesh:
    """A mesh read by ice.load_mesh. Unpacks as ``V, F = ice.load_mesh(path)``.

    Attributes: V (n×3 float64), F (m×3 int32), report (validation of the loaded mesh, the keys of
    ``ice-info --json``), input_report (of the file as read), repairs (what repair=True did, one line
    each), source_vertex / source_face (the file's index of each mesh vertex / face), format,
    point_cloud (the file had points only: F are their local Delaunay triangles).
    """

    __slots__ = ("V", "F", "report", "input_report", "repairs", "source_vertex", "source_face", "format", "point_cloud")

    def __init__(self, fields: dict):
        for name in self.__slots__:
            setattr(self, name, fields[name])

    def __iter__(self):
        return iter((self.V, self.F))

    def __len__(self) -> int:
        return 2

    def __getitem__(self, index):
        return (self.V, self.F)[index]

    def __repr__(self) -> str:
        return f"<ice.LoadedMesh {self.V.shape[0]} vertices, {self.F.shape[0]} faces ({self.format})>"


def load_mesh(path, repair: bool = False, weld: bool = False, nonmanifold: str = "refuse",
              neighbours: int = 30, separate_thin_parts: bool = False) -> LoadedMesh:
    """Reads and validates an OBJ, OFF, PLY or STL mesh (or an XYZ/PWN point set) under ICE's loading policy.

    Refused meshes (non-manifold, inconsistently oriented, zero-area or duplicate faces, ...) raise
    ice.MeshError naming the file and each defect; repair=True applies the safe repairs first
    (triangulate, drop zero-area/duplicate faces and unused vertices, re-orient; weld=True also welds
    exactly coincident vertices). nonmanifold="tufted" keeps what the tufted cover solves on (non-manifold
    and non-orientable sheets), and reads a file of points only as its points with the triangles of their
    local Delaunay fans (ice.point_cloud_triangles with `neighbours` and `separate_thin_parts`; repeated points refused, merged with
    repair=True); pass nonmanifold="tufted" to the solvers too. Returns a LoadedMesh
    (``V, F = ice.load_mesh(path)``).
    """
    return LoadedMesh(_ice._load_mesh(str(path), repair, weld, nonmanifold, neighbours, separate_thin_parts))


# The extensions ICE's own reader takes (libice/src/mesh_io.cpp: read_mesh_file); read_mesh hands the rest to meshio.
_ICE_FORMATS = (".obj", ".off", ".ply", ".stl", ".xyz", ".pwn")


def read_mesh(path, *, skip_cells=(), **kw):
    """Reads a triangle mesh as ``(V, F)``: n×3 float64 positions and m×3 int32 vertex indices.

    OBJ, OFF, PLY and STL are read by ICE's own reader, ice.load_mesh (validated under ICE's loading
    policy; keywords: repair, weld). Any other format is read by meshio when it is installed (Debian:
    python3-meshio), e.g. .vtu, .vtk, .msh (Gmsh), .mesh (Medit), .xdmf; keywords go to meshio.read
    (e.g. file_format="gmsh"). Such a file must hold triangles only: other cells raise ValueError
    naming the file and the cell types, unless their types are listed in skip_cells (e.g.
    skip_cells={"line", "vertex"} drops the boundary curves and points of a Gmsh surface mesh); 2D
    points get z = 0. Meshes read by meshio are not validated here: the calls that take (V, F)
    validate them where they enter (ice.validate(V, F) reports on them first).
    """
    name = os.fspath(path)
    if os.path.splitext(name)[1].lower() in _ICE_FORMATS:
        loaded = load_mesh(name, **kw)
        return (np.ascontiguousarray(loaded.V, dtype=np.float64), np.ascontiguousarray(loaded.F, dtype=np.int32))
    try:
        import meshio
    except ImportError:
        raise ValueError(f"{name}: not a format ICE reads ({', '.join(_ICE_FORMATS)}) and meshio, which reads "
                         "many more, is not installed (Debian: apt-get install python3-meshio)") from None
    mesh = meshio.read(name, **kw)
    skip = {skip_cells} if isinstance(skip_cells, str) else set(skip_cells)
    triangles, refused = [], {}
    for block in mesh.cells:
        if block.type == "triangle":
            triangles.append(np.asarray(block.data))
        elif block.type not in skip:
            refused[block.type] = refused.get(block.type, 0) + len(block.data)
    if refused:
        listed = ", ".join(f"{count} {kind}" for kind, count in refused.items())
        raise ValueError(f"{name}: ICE reads triangle meshes only, and this file has other cells ({listed}); "
                         f"skip_cells={sorted(refused)!r} drops them, if they only mark boundaries or points")
    if not triangles or not sum(len(t) for t in triangles):
        kinds = sorted({block.type for block in mesh.cells}) or ["none"]
        raise ValueError(f"{name}: no triangles in this file (its cells: {', '.join(kinds)})")
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"{name}: points of shape {points.shape}; need 2D or 3D positions")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    faces = np.concatenate(triangles).astype(np.int64, copy=False)
    bad = faces[(faces < 0) | (faces >= len(points))]
    if bad.size:
        raise ValueError(f"{name}: a triangle refers to vertex {int(bad[0])}, but the file has {len(points)} points")
    return np.ascontiguousarray(points), np.ascontiguousarray(faces, dtype=np.int32)


def _with_defaults(coarsening, use):
    """The one-calls' coarsening options: 5 % of the vertices and the metric of `use` unless given."""
    if not {"n", "ratio", "max_error"} & coarsening.keys():
        coarsening["ratio"] = 0.05
    coarsening.setdefault("use", use)
    return coarsening


def _coarse_for(V, F, coarse, coarsening, use, locked=None, cache=None):
    if coarse is not None:
        if coarsening:
            raise ValueError(f"give coarse or coarsening options ({', '.join(sorted(coarsening))}), not both")
        return coarse
    _with_defaults(coarsening, use)
    if locked is not None:  # the fixed vertices must stay: locked besides the caller's own
        own = coarsening.get("locked")
        coarsening["locked"] = locked if own is None else np.union1d(np.asarray(own), np.asarray(locked))
    return coarsen(V, F, cache=cache, **coarsening)


def _stored_proxy(V, F, coarsening, use, operators, fine, prolongation, fixed, cache):
    """(coarse, proxy) through the store of set-up proxies (ice.setup_proxy)."""
    return setup_proxy(V, F, operators=operators, fine=fine, prolongation=prolongation, fixed=fixed, cache=cache,
                       **_with_defaults(coarsening, use))


def solve_poisson(V, F, f, *, coarse: CoarseSpace | None = None, fixed=None, values=None,
                  operators: str = "galerkin", fine: str = "intrinsic_delaunay", polish: int = 0,
                  tolerance: float = 0.0, prolongation: str = "auto", cache=None, **coarsening):
    """Poisson −Δu = f on (V, F) through a coarse proxy, in one call (poisson-coarse).

    coarse: a CoarseSpace of this mesh, or coarsening options for ice.coarsen (default ratio=0.05);
    fixed vertices are then locked so they stay coarse vertices. Without fixed vertices the zero-mean
    Neumann solution (on a mesh of several components, zero-mean on each); with them, Dirichlet
    values there (values, default zeros; every component needs one). For many right-hand
    sides build Proxy and ProxyPoissonSolver once instead. prolongation: "barycentric", "smoothed"
    (see Proxy; not with fixed vertices) or "auto" (smoothed with Galerkin operators and no fixed
    vertices, as poisson-coarse). f of shape (n, k): k sources solved as one block. cache: without a
    given coarse space the setup goes through the store of set-up proxies (ice.setup_proxy): None the
    default store ($ICE_CACHE, else ~/.cache/ice), a directory, or False for none.
    """
    if coarse is None and cache is not False:
        _, proxy = _stored_proxy(V, F, coarsening, "poisson_heat", operators, fine, prolongation, fixed, cache)
    else:
        coarse = _coarse_for(V, F, coarse, coarsening, "poisson_heat", fixed)
        prolongation = _ice._resolve_prolongation(prolongation, operators, fixed is not None and len(fixed) > 0)
        proxy = Proxy(V, F, coarse, operators=operators, fine=fine, prolongation=prolongation)
    return ProxyPoissonSolver(proxy, fixed=fixed, polish=polish, tolerance=tolerance).solve(f, values)


def heat_flow(V, F, u0, time_step: float, steps: int = 1, *, coarse: CoarseSpace | None = None,
              restriction: str = "l2", operators: str = "galerkin", fine: str = "intrinsic_delaunay",
              polish: int = 0, tolerance: float = 0.0, prolongation: str = "auto", every: int | None = None,
              cache=None, **coarsening):
    """Backward-Euler heat flow from u0 for `steps` steps of `time_step` through a coarse proxy.

    coarse / coarsening options, prolongation and cache as for solve_poisson. every: None gives the
    last state; an integer M gives (states, step_counts), the states after every M-th step (and the
    last) stepped on the coarse mesh with only those prolonged (ProxyHeatSolver.steps).
    """
    if coarse is None and cache is not False:
        _, proxy = _stored_proxy(V, F, coarsening, "poisson_heat", operators, fine, prolongation, None, cache)
    else:
        coarse = _coarse_for(V, F, coarse, coarsening, "poisson_heat")
        proxy = Proxy(V, F, coarse, operators=operators, fine=fine,
                      prolongation=_ice._resolve_prolongation(prolongation, operators, False))
    solver = ProxyHeatSolver(proxy, time_step, restriction=restriction, polish=polish, tolerance=tolerance)
    return solver.integrate(u0, steps) if every is None else solver.steps(u0, steps, every)


def eigenbasis(V, F, k: int, *, boundary: str = "neumann", coarse: CoarseSpace | None = None,
               fine: str = "intrinsic_delaunay", prolongation: str = "auto", tolerance: float = 1e-10, cache=None,
               refine_tolerance: float = 0.0, **coarsening):
    """(values, vectors): the k smallest Laplace–Beltrami eigenpairs of (V, F) through a coarse proxy
    (spectral-coarse): L φ = λ M φ with the cotan L and lumped M, solved on the coarse Galerkin pencil
    and prolonged. values increasing; vectors (n × k) M-orthonormal on the input mesh.

    boundary: "neumann", or "dirichlet" (φ = 0 on the mesh's boundary, whose vertices the coarsening then
    keeps). coarse / coarsening options (default ratio=0.05; with refine_tolerance and none of n, ratio,
    min_vertices, max_error: refined_coarse_vertices(k) vertices besides the Dirichlet ones, at most the
    mesh's) and cache as for solve_poisson; prolongation
    "auto" (the default) is the eigenbasis's own: P smoothed twice where allowed, else barycentric;
    k must be below the coarse vertex count (ValueError otherwise).
    Without `coarse` the coarse eigenpairs go through `cache` too: a second call with the same mesh,
    options and k loads them (the same numbers to the last bit; only the prolongation, and with
    refine_tolerance the refinement, is redone).
    refine_tolerance > 0: the refined route (spectral-coarse --tolerance): the pairs improved on the input
    mesh until each relative residual |Lφ − λMφ| / (λ|Mφ|) is at most this (refined_eigenbasis; its
    multigrid hierarchy goes through `cache` too). A refinement that does not converge warns. A mesh
    that is not coarsened (smaller than that size) is solved by the fine eigensolver each call instead
    (nothing of it stored).
    """
    if boundary not in ("neumann", "dirichlet"):
        raise ValueError(f"boundary must be 'neumann' or 'dirichlet', not {boundary!r}")
    fixed = boundary_vertices(F) if boundary == "dirichlet" else None
    if fixed is not None and len(fixed) == 0:
        fixed = None  # a closed mesh: the same as Neumann
    # "auto" means the eigenbasis's own default (the P smoothed twice where allowed), as spectral-coarse's.
    prolongation = _ice._resolve_prolongation(prolongation, "galerkin", fixed is not None, eigenpairs=True)
    if refine_tolerance and coarse is None and not {"n", "ratio", "min_vertices", "max_error"} & coarsening.keys():
        # The refined route's coarse size follows its pairs, not the mesh (ice::proxy::refined_coarse_vertices).
        wanted = refined_coarse_vertices(k, dirichlet_vertices=0 if fixed is None else len(fixed))
        n = len(np.asarray(V))
        # At most the mesh, which refined_eigenbasis then solves by the fine eigensolver directly.
        coarsening["n"] = min(wanted, n)
    if coarse is None and cache is not False:
        _, proxy = _stored_proxy(V, F, coarsening, "poisson_heat", "galerkin", fine, prolongation, fixed, cache)
    else:
        coarse = _coarse_for(V, F, coarse, coarsening, "poisson_heat", fixed)
        proxy = Proxy(V, F, coarse, operators="galerkin", fine=fine, prolongation=prolongation)
    if refine_tolerance:
        values, vectors, info = refined_eigenbasis(proxy, V, F, k, refine_tolerance=refine_tolerance, tolerance=tolerance,
                                                   dirichlet=fixed, cache=cache)
        if not info["converged"]:
            what = ("the fine eigensolver's pairs have" if info["fine_eigensolve"] else
                    f"the refinement stopped after {info['iterations']} iterations with")
            warnings.warn(f"eigenbasis: {what} a largest residual of {max(info['residuals']):.3g} "
                          f"(refine_tolerance {refine_tolerance:g})", RuntimeWarning, stacklevel=2)
        return values, vectors
    return proxy_eigenbasis(proxy, k, tolerance=tolerance, dirichlet=fixed, cache=cache if coarse is None else False)


def geodesic_distance(V, F, sources, *, coarse: CoarseSpace | None = None, method: str = "marching",
                      time_factor: float = 1.0, operators: str = "galerkin", fine: str = "intrinsic_delaunay",
                      lengths: str = "auto", subdivisions: int = 1, curvature_correction: bool | None = None,
                      cache=None, **coarsening):
    """Geodesic distance to `sources` through a coarse proxy (geodesic-coarse).

    method: "marching" (fast marching on the coarse mesh, the default; operators and fine are then
    unused) or "heat" (the coarse heat method, t = (time_factor · mean coarse edge length)²). coarse / coarsening options as for
    solve_poisson, with the metric measured best for geodesics (use="geodesic") by default. lengths
    (marching): "traced" (the coarse edges' lengths on the surface; an ICE coarse space), "intrinsic"
    (the coarse mesh's own), or "auto" (the default, as geodesic-coarse --coarse-lengths auto: traced
    for an ICE coarse space that has its fine-to-coarse map, intrinsic otherwise). subdivisions: marching on the coarse mesh split
    1:4 that many times (geodesic-coarse --marching-subdivisions). curvature_correction: with marching,
    edge lengths scaled for the curvature each coarse face flattens (None: for ICE coarse spaces not of
    a tufted cover, as geodesic-coarse --curvature-correction auto). On a mesh of several components
    the distance is +inf on the components without a source. With nonmanifold="tufted" (a mesh
    that is not an oriented manifold, or a point cloud's faces) marching runs on the coarse mesh's own
    lengths (its coarse edges lie on the cover's sheets, not on the input's triangles: lengths="traced"
    is refused). For many
    sources or pairs see ProxyGeodesicSolver and DistanceOracle. cache: the coarse space (with its
    map and traced lengths) goes through the store as in ice.coarsen: None the default store, a
    directory, or False for none.
    """
    if method not in ("marching", "heat"):
        raise ValueError(f"method must be 'marching' or 'heat', not {method!r}")
    coarse = _coarse_for(V, F, coarse, coarsening, "geodesic", cache=cache)
    if lengths == "traced" and method != "marching":
        raise ValueError(f"lengths={lengths!r} is for method='marching'")
    if method == "marching":  # needs only the coarse mesh and P: no Proxy (fine mesh, operators) to build
        return ProxyGeodesicSolver.from_coarse(V, F, coarse, lengths=lengths, subdivisions=subdivisions,
                                               curvature_correction=curvature_correction).distance(sources)
    proxy = Proxy(V, F, coarse, operators=operators, fine=fine)
    return ProxyGeodesicSolver(proxy, method=method, time_factor=time_factor).distance(sources)


def transport_directions(V, F, sources, directions, *, solver: str = "sweep", operators: str = "galerkin",
                         time_factor: float | None = None, fine: str = "intrinsic_delaunay", sweep_passes: int = 50,
                         sweep_coarse_interval: int = 2, **coarsening):
    """Tangent vectors carried from `sources` to every vertex, given and returned in space, in one call
    (vector-coarse --direction).

    directions: one 3D direction per source (k×3), projected into the surface at the source, of its
    length. Returns n×3 vectors (one source: parallel transport along shortest geodesics; several: the
    smooth field through them). coarsening options as for ice.coarsen (default ratio=0.05); solver,
    operators, time_factor, fine, sweep_passes and sweep_coarse_interval as for VectorHeatSolver.
    nonmanifold="tufted": a mesh that is not an oriented manifold (or a point cloud's faces) is solved on
    the copies of its tufted cover's sheets (each with a tangent plane of its own), every copy of a source
    carrying its direction, each vertex's vector the area-weighted mean of its copies' that carry one (an
    open sheet keeps its boundary, as on a manifold; a sheet's two sides are joined only through the
    wedges at non-manifold edges, so across two crossing sheets a field does not reach the straight
    continuation, and sheets touching at a vertex alone are not joined). Not through the store. Raises
    ValueError for a direction normal to the surface at its source.
    """
    return _ice._transport_directions(V, F, np.atleast_1d(np.asarray(sources)), np.atleast_2d(np.asarray(directions, dtype=float)),
                                      solver=solver, operators=operators, time_factor=time_factor, fine=fine,
                                      sweep_passes=sweep_passes, sweep_coarse_interval=sweep_coarse_interval,
                                      **_with_defaults(coarsening, "poisson_heat"))


def transport_vectors(V, F, sources, vectors=1.0, *, coarse: CoarseSpace | None = None, solver: str = "sweep",
                      operators: str = "galerkin", time_factor: float | None = None, fine: str = "intrinsic_delaunay",
                      sweep_passes: int = 50, sweep_coarse_interval: int = 2, ambient: bool = False, cache=None,
                      **coarsening):
    """Tangent vectors carried from `sources` to every vertex through a coarse proxy, in one call (vector-coarse).

    vectors: one complex number per source, in its tangent frame (see VectorHeatSolver; default 1, the
    direction of the source's reference edge); one source is parallel-transported along shortest
    geodesics, several give the smooth field through them. coarse / coarsening options as for
    solve_poisson; solver, operators, time_factor, fine, sweep_passes and sweep_coarse_interval as for VectorHeatSolver. Returns the complex field (one tangent vector per vertex), or with ambient=True its
    n×3 vectors in the planes of the input triangles. For many calls build VectorHeatSolver once.
    cache: the coarse space (with its map and traced lengths) through the store, as geodesic_distance.
    """
    coarse = _coarse_for(V, F, coarse, coarsening, "poisson_heat", cache=cache)
    heat = VectorHeatSolver(V, F, coarse, operators=operators, time_factor=time_factor, fine=fine, solver=solver,
                            sweep_passes=sweep_passes, sweep_coarse_interval=sweep_coarse_interval)
    indices = np.atleast_1d(np.asarray(sources))
    values = np.broadcast_to(np.asarray(vectors, dtype=complex), indices.shape)
    field = heat.interpolate(indices, np.ascontiguousarray(values))
    return heat.to_ambient(field) if ambient else field
