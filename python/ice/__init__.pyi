"""Type stubs of the ice package (the extension module ice._ice and the helpers of __init__.py)."""
from os import PathLike
from typing import Any, Callable, Iterable, Iterator, Literal, Sequence, overload

import numpy as np
import numpy.typing as npt
import scipy.sparse

__version__: str
DEFAULT_COARSENING_REGIONS: int  # what coarsen(regions=0) runs with on large meshes

Path = str | PathLike[str]
FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.int32]
Indices = Sequence[int] | npt.NDArray[np.integer[Any]] | int
ArrayLike = npt.ArrayLike

class MeshError(RuntimeError):
    """A file ICE cannot read or write, or a mesh its loading policy refuses; str() is the tools' message."""
    kind: Literal["unreadable", "defective", "unwritable"]
    path: str

class LoadedMesh:
    """ice.load_mesh's result; unpacks as ``V, F = ice.load_mesh(path)``."""
    V: FloatArray
    F: IndexArray
    report: dict[str, Any]
    input_report: dict[str, Any]
    repairs: list[str]
    source_vertex: IndexArray
    source_face: IndexArray
    format: str
    point_cloud: bool
    def __iter__(self) -> Iterator[FloatArray | IndexArray]: ...
    def __len__(self) -> int: ...
    def __getitem__(self, index: int) -> FloatArray | IndexArray: ...

def load_mesh(path: Path, repair: bool = False, weld: bool = False, nonmanifold: str = "refuse",
              neighbours: int = 30, separate_thin_parts: bool = False) -> LoadedMesh:
    """Reads and validates an OBJ, OFF, PLY or STL mesh under ICE's loading policy."""
def read_mesh(path: Path, *, skip_cells: str | Iterable[str] = (), **kw: Any) -> tuple[FloatArray, IndexArray]:
    """(V, F) of a triangle mesh: OBJ/OFF/PLY/STL by ice.load_mesh, other formats by meshio (triangles only)."""
def validate(V: ArrayLike, F: ArrayLike) -> dict[str, Any]:
    """The validation report of (V, F) (ice-info --json keys); report["clean"]: accepted by the solvers."""
def save_mesh(path: Path, V: ArrayLike, F: ArrayLike, *, overwrite: bool = False, binary: bool = False) -> None:
    """Writes (V, F) as OBJ, OFF, PLY or STL; an existing file only with overwrite=True."""
def face_lengths(V: ArrayLike, F: ArrayLike) -> FloatArray:
    """Per-face edge lengths (m×3), column k from corner k to corner (k+1)%3."""
def intrinsic_delaunay(V: ArrayLike, F: ArrayLike) -> tuple[IndexArray, FloatArray, int]:
    """(F, lengths, flips) of the intrinsic Delaunay triangulation of (V, F)."""
def point_cloud_triangles(P: ArrayLike, *, neighbours: int = 30, threads: int = 0,
                          separate_thin_parts: bool = False) -> IndexArray:
    """Faces of a point cloud: its points' local Delaunay triangles (a soup; solve with nonmanifold="tufted")."""
def loop_subdivide(V: ArrayLike, F: ArrayLike, levels: int = 1) -> tuple[FloatArray, IndexArray]:
    """Loop subdivision `levels` times (about 4x the vertices each)."""
def cotan_laplacian(V: ArrayLike | None = None, F: ArrayLike | None = None, *, lengths: ArrayLike | None = None,
                    n: int | None = None) -> scipy.sparse.csc_matrix:
    """The cotan Laplacian (positive semidefinite) of (V, F) or of (F, lengths=L)."""
def mass_matrix(V: ArrayLike | None = None, F: ArrayLike | None = None, *, lengths: ArrayLike | None = None,
                n: int | None = None, kind: Literal["lumped", "consistent"] = "lumped") -> scipy.sparse.csc_matrix:
    """The lumped or consistent mass matrix of (V, F) or of (F, lengths=L)."""

class CoarseSpace:
    """A coarse intrinsic mesh of an input mesh, P and the fine-to-coarse map."""
    @property
    def faces(self) -> IndexArray: ...
    @property
    def lengths(self) -> FloatArray: ...
    @property
    def twin(self) -> IndexArray: ...
    @property
    def to_input(self) -> IndexArray: ...
    @property
    def from_input(self) -> IndexArray: ...
    @property
    def n_vertices(self) -> int: ...
    @property
    def n_faces(self) -> int: ...
    @property
    def input_vertices(self) -> int: ...
    @property
    def P(self) -> scipy.sparse.csr_matrix | None:
        """Input vertices × coarse vertices, rows summing to 1; None when read from a file."""
    @property
    def map(self) -> tuple[IndexArray, FloatArray, IndexArray] | None:
        """(face, bary, coarse_vertex) of every input vertex; None when not kept."""
    @property
    def summary(self) -> dict[str, Any] | None: ...
    @property
    def cache(self) -> dict[str, Any]:
        """Where coarsen's space came from: status 'hit', 'miss', 'rebuilt' or 'off'."""
    @property
    def positions(self) -> FloatArray | None: ...
    @property
    def traced_edges(self) -> tuple[list[FloatArray], IndexArray] | None:
        """With coarsen(..., trace=True): each coarse edge's polyline on the input surface and its (tail, head)."""
    @property
    def inserted(self) -> tuple[IndexArray, FloatArray]: ...
    def save(self, path: Path, *, overwrite: bool = False, comment: str = "") -> None:
        """Writes the coarse mesh as .ilm (exact round trip with load_coarse_mesh)."""

def coarsen(V: ArrayLike, F: ArrayLike, *, n: int | None = None, ratio: float | None = None,
            min_vertices: int | None = None, max_error: float | None = None, method: Literal["ice", "qem"] = "ice",
            use: Literal["poisson_heat", "geodesic"] = "poisson_heat", area_weight: float | None = None,
            normalize_curvature: bool | None = None, locked: Indices | None = None, remove_boundary: bool = True,
            threads: int = 0, regions: int = 0, qem_geometry: Literal["extrinsic", "intrinsic_delaunay"] = "extrinsic",
            refine_angle: float | None = None, refine_budget: float = 1.5, keep_map: bool = True,
            locality_numbering: bool = True, trace: bool = False,
            progress: Callable[[dict[str, Any]], bool | None] | None = None,
            nonmanifold: Literal["refuse", "tufted"] = "refuse", cache: str | PathLike[str] | Literal[False] | None = None) -> CoarseSpace:
    """Coarsens (V, F) by ICE (or QEM) to n vertices, a ratio of them, or an error bound."""
def save_coarse_space(path: Path, V: ArrayLike, F: ArrayLike, coarse: CoarseSpace, *, overwrite: bool = False) -> None:
    """Writes a coarse space of (V, F) with P, its map and summary (the store's binary format)."""
def load_coarse_space(path: Path, V: ArrayLike, F: ArrayLike) -> CoarseSpace:
    """The coarse space save_coarse_space wrote for (V, F), checked, bit for bit."""
def load_coarse_mesh(path: Path) -> CoarseSpace:
    """Reads an .ilm coarse mesh (faces, lengths, gluing, vertex map)."""

class Proxy:
    """The fine discretisation and a coarse space linked by P, with the proxy solvers' operators."""
    def __init__(self, V: ArrayLike, F: ArrayLike, coarse: CoarseSpace, *,
                 operators: Literal["galerkin", "intrinsic"] = "galerkin",
                 fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay",
                 prolongation: Literal["barycentric", "smoothed", "smoothed_twice"] = "barycentric") -> None: ...
    @property
    def prolongation(self) -> scipy.sparse.csc_matrix: ...
    @property
    def fine_size(self) -> int: ...
    @property
    def coarse_size(self) -> int: ...
    @property
    def fine_faces(self) -> IndexArray: ...
    @property
    def fine_lengths(self) -> FloatArray: ...
    @property
    def fine_flips(self) -> int: ...
    @property
    def cache(self) -> dict[str, Any]: ...
    @property
    def fine_laplacian(self) -> scipy.sparse.csc_matrix: ...
    @property
    def fine_mass(self) -> scipy.sparse.csc_matrix: ...
    @property
    def coarse_laplacian(self) -> scipy.sparse.csc_matrix: ...
    @property
    def coarse_mass(self) -> scipy.sparse.csc_matrix: ...
    def prolong(self, values: ArrayLike) -> FloatArray: ...
    def restrict_weighted(self, values: ArrayLike) -> FloatArray: ...

class ProxyPoissonSolver:
    """Poisson through the proxy (zero-mean Neumann, or Dirichlet at `fixed`), optionally polished."""
    def __init__(self, proxy: Proxy, *, fixed: Indices | None = None, polish: int = 0, tolerance: float = 0.0) -> None: ...
    def solve(self, f: ArrayLike, values: ArrayLike | None = None) -> FloatArray: ...
    @property
    def polish_report(self) -> dict[str, Any]: ...
    @property
    def times(self) -> dict[str, float]: ...
    @property
    def is_zero_mean(self) -> bool: ...

class ProxyHeatSolver:
    """Backward-Euler heat flow through the proxy."""
    def __init__(self, proxy: Proxy, time_step: float, *, restriction: Literal["l2", "injection"] = "l2",
                 polish: int = 0, tolerance: float = 0.0) -> None: ...
    def integrate(self, u0: ArrayLike, steps: int = 1) -> FloatArray: ...
    def steps(self, u0: ArrayLike, steps: int, every: int = 1) -> tuple[FloatArray, list[int]]: ...
    @property
    def polish_report(self) -> dict[str, Any]: ...
    @property
    def times(self) -> dict[str, float]: ...

def curvature_corrected_lengths(V: ArrayLike, F: ArrayLike, coarse: CoarseSpace, *,
                                lengths: ArrayLike | None = None, divisor: float = 48.0) -> FloatArray:
    """Coarse edge lengths scaled for the curvature each coarse face flattens (what marching uses for ICE)."""
class ProxyGeodesicSolver:
    """Geodesic distance through the proxy (coarse fast marching, or the coarse heat method)."""
    def __init__(self, proxy: Proxy, *, method: Literal["marching", "heat"] = "marching",
                 time_factor: float = 1.0, subdivisions: int = 1, curvature_correction: bool | None = None) -> None: ...
    @staticmethod
    def from_coarse(V: ArrayLike, F: ArrayLike, coarse: CoarseSpace, *,
                    lengths: Literal["auto", "intrinsic", "traced"] = "auto",
                    subdivisions: int = 1, curvature_correction: bool | None = None) -> ProxyGeodesicSolver:
        """Coarse marching from a coarse space of (V, F) alone, without a Proxy."""
    def distance(self, sources: Indices) -> FloatArray: ...
    @property
    def times(self) -> dict[str, float]: ...

@overload
def hierarchy(V: ArrayLike, F: ArrayLike, *, ratio: float = 0.25, coarsest: int = 500,
              max_levels: int = 20, threads: int = 0,
              return_order: Literal[False] = False, nonmanifold: Literal["refuse", "tufted"] = "refuse", cache: str | PathLike[str] | Literal[False] | None = None) -> list[scipy.sparse.csr_matrix]:
    """Prolongations of an ICE multigrid hierarchy of (V, F)."""
@overload
def hierarchy(V: ArrayLike, F: ArrayLike, *, ratio: float = 0.25, coarsest: int = 500,
              max_levels: int = 20, threads: int = 0,
              return_order: Literal[True], nonmanifold: Literal["refuse", "tufted"] = "refuse", cache: str | PathLike[str] | Literal[False] | None = None) -> tuple[list[scipy.sparse.csr_matrix], IndexArray]:
    """Prolongations and the breadth-first numbering the hierarchy coarsened in."""
@overload
def hierarchy(V: ArrayLike, F: ArrayLike, *, ratio: float = 0.25, coarsest: int = 500,
              max_levels: int = 20, threads: int = 0, return_order: bool = False,
              nonmanifold: Literal["refuse", "tufted"] = "refuse", cache: str | PathLike[str] | Literal[False] | None = None
              ) -> list[scipy.sparse.csr_matrix] | tuple[list[scipy.sparse.csr_matrix], IndexArray]: ...

def save_hierarchy(path: str | PathLike[str], V: ArrayLike, F: ArrayLike, prolongations: Sequence[Any], *,
                   order: Indices | None = None, overwrite: bool = False) -> None:
    """Writes a hierarchy of (V, F) to a checksummed file that load_hierarchy takes back for (V, F) only."""
@overload
def load_hierarchy(path: str | PathLike[str], V: ArrayLike, F: ArrayLike, *,
                   return_order: Literal[False] = False) -> list[scipy.sparse.csr_matrix]:
    """The hierarchy save_hierarchy wrote for (V, F), checked."""
@overload
def load_hierarchy(path: str | PathLike[str], V: ArrayLike, F: ArrayLike, *,
                   return_order: Literal[True]) -> tuple[list[scipy.sparse.csr_matrix], IndexArray]:
    """The hierarchy and its order."""

class MultigridSolver:
    """Galerkin multigrid on given prolongations for SPD systems."""
    def __init__(self, prolongations: Sequence[scipy.sparse.spmatrix], *, tolerance: float = 1e-8,
                 max_iterations: int = 200, mode: Literal["pcg", "vcycle"] = "pcg",
                 smoother: Literal["sgs", "gs", "chebyshev"] = "sgs", smoothing_steps: int = 1,
                 threads: int = 0, locality_order: Indices | None = None) -> None: ...
    def setup(self, A: scipy.sparse.spmatrix | ArrayLike, constrained: Indices | None = None) -> None: ...
    def solve(self, b: ArrayLike, constrained_values: ArrayLike | None = None,
              x0: ArrayLike | None = None) -> FloatArray: ...
    @property
    def report(self) -> dict[str, Any]: ...
    @property
    def size(self) -> int: ...

class DistanceOracle:
    """All-pairs geodesic distances of the fine vertices from a coarse space."""
    def __init__(self, coarse: CoarseSpace, *, method: Literal["marching", "heat"] = "marching",
                 heat_time_factor: float = 1.0, threads: int = 0, subdivisions: int = 1,
                 lengths: ArrayLike | None = None) -> None: ...
    @staticmethod
    def from_mesh(V: ArrayLike, F: ArrayLike, coarse: CoarseSpace, *, method: Literal["marching", "heat"] = "marching",
                  heat_time_factor: float = 1.0, threads: int = 0, subdivisions: int = 1,
                  lengths: Literal["auto", "intrinsic", "traced"] = "auto",
                  curvature_correction: bool | None = None) -> DistanceOracle:
        """The oracle of geodesic-coarse's oracle modes: corrected for ICE coarse spaces, traced on request."""
    def distance(self, u: int, v: int) -> float: ...
    def distances(self, pairs: ArrayLike) -> FloatArray: ...
    def distances_from(self, source: int) -> FloatArray: ...
    def distance_matrix(self, rows: Indices, cols: Indices | None = None) -> npt.NDArray[np.float32]: ...
    def farthest_point_samples(self, count: int, first: int = 0) -> IndexArray: ...
    @property
    def fine_size(self) -> int: ...
    @property
    def coarse_size(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...

ComplexArray = npt.NDArray[np.complex128]

class VectorHeatSolver:
    """The vector heat method on the input mesh (its intrinsic Delaunay triangulation by default), or through a coarse space (vector-coarse)."""
    def __init__(self, V: ArrayLike, F: ArrayLike, coarse: CoarseSpace | None = None, *,
                 operators: Literal["galerkin", "intrinsic"] = "galerkin", time_factor: float | None = None,
                 fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay",
                 solver: Literal["sweep", "diffusion"] = "sweep", sweep_passes: int = 50,
                 sweep_coarse_interval: int = 2) -> None: ...
    def interpolate(self, sources: Indices, vectors: ArrayLike) -> ComplexArray: ...
    def transport(self, source: int, vector: complex = 1) -> ComplexArray: ...
    def to_ambient(self, field: ArrayLike) -> FloatArray: ...
    def to_tangent(self, vertices: Indices, directions: ArrayLike) -> ComplexArray: ...
    @property
    def vector_prolongation(self) -> scipy.sparse.csc_matrix | None: ...
    @property
    def prolongation_stats(self) -> dict[str, Any] | None: ...
    @property
    def size(self) -> int: ...

def solve_poisson(V: ArrayLike, F: ArrayLike, f: ArrayLike, *, coarse: CoarseSpace | None = None,
                  fixed: Indices | None = None, values: ArrayLike | None = None,
                  operators: Literal["galerkin", "intrinsic"] = "galerkin",
                  fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay", polish: int = 0,
                  tolerance: float = 0.0, prolongation: Literal["auto", "barycentric", "smoothed", "smoothed_twice"] = "auto",
                  cache: str | PathLike[str] | Literal[False] | None = None, **coarsening: Any) -> FloatArray:
    """Poisson −Δu = f through a coarse proxy in one call (f of shape (n, k): k sources as a block)."""
def heat_flow(V: ArrayLike, F: ArrayLike, u0: ArrayLike, time_step: float, steps: int = 1, *,
              coarse: CoarseSpace | None = None, restriction: Literal["l2", "injection"] = "l2",
              operators: Literal["galerkin", "intrinsic"] = "galerkin",
              fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay", polish: int = 0,
              tolerance: float = 0.0, prolongation: Literal["auto", "barycentric", "smoothed", "smoothed_twice"] = "auto",
              every: int | None = None, cache: str | PathLike[str] | Literal[False] | None = None,
              **coarsening: Any) -> FloatArray | tuple[FloatArray, list[int]]:
    """Backward-Euler heat flow through a coarse proxy in one call (every=M: the states every M steps)."""
def setup_proxy(V: ArrayLike, F: ArrayLike, *, operators: Literal["galerkin", "intrinsic"] = "galerkin",
                fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay",
                prolongation: Literal["auto", "barycentric", "smoothed", "smoothed_twice"] = "auto", fixed: Indices | None = None,
                cache: str | PathLike[str] | Literal[False] | None = None, **coarsening: Any) -> tuple[CoarseSpace, Proxy]:
    """Coarsens and builds the Proxy in one step, through the store of set-up proxies."""
def save_setup(path: str | PathLike[str], V: ArrayLike, F: ArrayLike, coarse: CoarseSpace, proxy: Proxy, *,
               overwrite: bool = False) -> None:
    """Writes a setup_proxy result of (V, F) to a checksummed file that load_setup takes back for (V, F) only."""
def load_setup(path: str | PathLike[str], V: ArrayLike, F: ArrayLike) -> tuple[CoarseSpace, Proxy]:
    """(coarse, proxy) as setup_proxy returned them when save_setup wrote the file, checked, bit for bit."""
def geodesic_distance(V: ArrayLike, F: ArrayLike, sources: Indices, *, coarse: CoarseSpace | None = None,
                      method: Literal["marching", "heat"] = "marching",
                      time_factor: float = 1.0, operators: Literal["galerkin", "intrinsic"] = "galerkin",
                      fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay",
                      lengths: Literal["auto", "intrinsic", "traced"] = "auto", subdivisions: int = 1,
                      curvature_correction: bool | None = None, cache: str | PathLike[str] | Literal[False] | None = None,
                      **coarsening: Any) -> FloatArray:
    """Geodesic distance through a coarse proxy in one call (coarse fast marching by default)."""
def transport_vectors(V: ArrayLike, F: ArrayLike, sources: Indices, vectors: ArrayLike = 1.0, *,
                      coarse: CoarseSpace | None = None, solver: Literal["sweep", "diffusion"] = "sweep",
                      operators: Literal["galerkin", "intrinsic"] = "galerkin",
                      time_factor: float | None = None, fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay",
                      sweep_passes: int = 50, sweep_coarse_interval: int = 2, ambient: bool = False,
                      cache: str | PathLike[str] | Literal[False] | None = None, **coarsening: Any) -> ComplexArray | FloatArray:
    """Tangent vectors carried from sources to every vertex through a coarse proxy in one call."""

def transport_directions(V: ArrayLike, F: ArrayLike, sources: Indices, directions: ArrayLike, *,
                         solver: Literal["sweep", "diffusion"] = "sweep", operators: Literal["galerkin", "intrinsic"] = "galerkin",
                         time_factor: float | None = None, fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay",
                         sweep_passes: int = 50, sweep_coarse_interval: int = 2, **coarsening: Any) -> FloatArray:
    """Tangent vectors from one 3D direction per source to every vertex (n×3), on any mesh or a tufted cover."""

def boundary_vertices(F: ArrayLike) -> IndexArray:
    """The vertices on a boundary edge, sorted."""
def eigenbasis(V: ArrayLike, F: ArrayLike, k: int, *, boundary: Literal["neumann", "dirichlet"] = "neumann",
               coarse: CoarseSpace | None = None,
               fine: Literal["intrinsic_delaunay", "input"] = "intrinsic_delaunay",
               prolongation: Literal["auto", "barycentric", "smoothed", "smoothed_twice"] = "auto", tolerance: float = 1e-10,
               cache: str | PathLike[str] | Literal[False] | None = None, refine_tolerance: float = 0.0,
               **coarsening: Any) -> tuple[FloatArray, FloatArray]:
    """The k smallest Laplace–Beltrami eigenpairs through a coarse proxy: (values, vectors (n × k))."""
def proxy_eigenbasis(proxy: Proxy, k: int, *, tolerance: float = 1e-10, dirichlet: Indices | None = None,
                     cache: str | PathLike[str] | Literal[False] | None = False) -> tuple[FloatArray, FloatArray]: ...
def refined_coarse_vertices(k: int, *, coarse_directions: int = -1, dirichlet_vertices: int = 0) -> int: ...
def refined_eigenbasis(proxy: Proxy, V: ArrayLike, F: ArrayLike, k: int, *, refine_tolerance: float = 1e-6,
                       max_iterations: int = 200, tolerance: float = 1e-10, dirichlet: Indices | None = None,
                       cache: str | PathLike[str] | Literal[False] | None = None) -> tuple[FloatArray, FloatArray, dict[str, Any]]: ...
def heat_kernel_signature(values: ArrayLike, vectors: ArrayLike, times: ArrayLike) -> FloatArray: ...
def wave_kernel_signature(values: ArrayLike, vectors: ArrayLike, energies: ArrayLike, sigma: float) -> FloatArray: ...
def reconstruction_error(values: ArrayLike, vectors: ArrayLike, mass: ArrayLike, f: ArrayLike) -> float: ...
