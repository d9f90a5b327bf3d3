"""Coarsen whole mesh datasets: resumable batch runs on one machine or a Dask cluster.

    ice-batch INPUT -o OUT --ratio 0.05 [--workers 2 | --scheduler tcp://HOST:PORT] [options]
    python3 -m ice.batch INPUT -o OUT --ratio 0.05

INPUT is a directory (searched recursively for .obj .off .ply .stl, and with --nonmanifold tufted also
.xyz .pwn point sets), a glob pattern ('scans/**/*.ply',
quoted), or a text file listing mesh paths (one a line, '#' comments). For each mesh the output tree
mirrors the input: OUT/<relative path>.ilm (the coarse intrinsic mesh), <...>.npz (P as CSR arrays
and the fine-to-coarse map; with --features eigs:K also the K smallest Laplace-Beltrami eigenpairs
through the coarse proxy, 'eigenvalues' and 'eigenvectors' (n x K, one row per vertex of the loaded
mesh), and with hks:T1:T2:... 'hks' (n x times) and 'hks_times': ``ice.batch.load_result`` reads
them back) and <...>.json (a one-line
record: sizes, stop reason, seconds, the options' hash, or the error). OUT/records.jsonl gathers the
records and OUT/summary.csv one line per mesh; a summary is printed at the end.

Safety: every file is written to a temporary name and renamed; a mesh's outputs are renamed into
place after its record is written, so a batch killed at any point leaves no output without its
record, and a mesh whose outputs are not all there is redone. A rerun skips the meshes whose record
has the same options hash, the same input (size and modification time) and its outputs (a failure that depends only on the input, a
refused or unreadable file, is not retried either); a changed option redoes every mesh. Files in OUT
that a batch did not write are never replaced without --force, and an output that would replace an
input mesh is refused before any work.

Isolation: each mesh runs in a worker process of Dask distributed (a LocalCluster of --workers
processes by default). A defective or failing mesh becomes an error record with the tools' message;
a mesh over --timeout seconds is cancelled (at the next progress report of the coarsener) and
recorded; a worker that dies (crash, --memory-limit) loses its tasks to Dask, which reruns them on
another worker (up to 3 times, Dask's allowed-failures), and a mesh that kills every worker it runs on
is recorded as crashed. The batch itself never stops for one mesh, and never hangs: when no mesh
has finished for --stall-timeout seconds (default 1800; a worker hung in the kernel, a cluster that
lost its workers), the meshes still queued or running get a "stalled" error record, which a rerun
retries, and the batch ends.

Threads: meshes of 20,000+ vertices run ICE's parallel phase with a fixed number of regions
(--regions, ice.coarsen's default 16), so their result does not depend on where or on how many threads they run;
each gets --mesh-threads threads (default: the number of local workers) for its coarsening, so the
last large meshes use the cores that workers with nothing left to do leave idle (reading and
validating a mesh and building its triangulation run their short passes on the machine's cores,
at most 8, from 100k vertices on, whatever the setting). The meshes go largest first; on a
local cluster with more than one thread per mesh, the largest ones (one per worker) keep their
priority and the others run at the lowest (the idle scheduling policy, SCHED_IDLE, on a thread of
their own; nice 19 where that policy is not available), so that they take the cores a large mesh
leaves idle instead of slowing down the batch's critical path. Each record says the threads and
the priority (`nice`, `policy`) its mesh ran with.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import glob
import hashlib
import io
import json
import multiprocessing
import os
import pathlib
import signal
import statistics
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse

from ._ice import DEFAULT_COARSENING_REGIONS

MESH_EXTENSIONS = (".obj", ".off", ".ply", ".stl")
POINT_SET_EXTENSIONS = (".xyz", ".pwn")  # in the manifest with nonmanifold="tufted" only
RECORD_VERSION = 4  # 2: eigs through P smoothed twice (the eigenbasis's default); 3: a tufted cover's sheet junctions
                    # kept as coarse vertices; 4: covered inputs' map arrays, point clouds' fans without hull
                    # slivers. Older records are redone
# Coarsening options that a batch passes to ice.coarsen (and hashes). Not the thread count: the
# batch chooses it per mesh (BatchOptions.mesh_threads) and it does not change the result.
COARSEN_OPTIONS = ("n", "ratio", "max_error", "method", "use", "area_weight", "normalize_curvature",
                   "remove_boundary", "regions", "qem_geometry", "refine_angle", "refine_budget", "nonmanifold",
                   "separate_thin_parts")
# Of those, the ones the loader takes (point sets' fans), not ice.coarsen.
LOAD_OPTIONS = ("separate_thin_parts",)
# A record's hash is of the options with these filled in, so {"ratio": 0.05} and {"ratio": 0.05,
# "method": "ice"} are the same run: what ice.coarsen does when an option is not given. Its regions
# (0 stands for DEFAULT_COARSENING_REGIONS; 1: the exact serial greedy order) fix a mesh's result
# whichever worker, machine or number of threads runs it, so a large mesh can take cores that other
# workers leave idle.
COARSEN_DEFAULTS = {"method": "ice", "use": "poisson_heat", "remove_boundary": True,
                    "regions": DEFAULT_COARSENING_REGIONS, "qem_geometry": "extrinsic", "refine_budget": 1.5}
# How a local cluster can start its worker processes (Python's multiprocessing start methods).
START_METHODS = ("spawn", "forkserver")
# forkserver where the platform has it (Linux, macOS): the shared meshes at 5 % as whole ice-batch
# processes, 5 interleaved runs, medians: 2 workers 4.99 s against 5.15 s spawned, 1 worker 8.00
# against 8.10 s (one server imports Dask, each worker is forked from it instead of importing it).
DEFAULT_START_METHOD = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
# Failures that depend only on the input file: not retried by a rerun with the same input.
DETERMINISTIC_ERRORS = ("unreadable", "defective", "invalid")


# ---- the manifest ---------------------------------------------------------------------------------

@dataclass
class Job:
    """One mesh: its path and where its outputs go (relative to the output folder, no extension)."""
    path: pathlib.Path
    relative: str
    size: int = 0
    mtime_ns: int = 0


def _is_mesh(path: pathlib.Path, point_sets: bool = False) -> bool:
    return path.suffix.lower() in MESH_EXTENSIONS + (POINT_SET_EXTENSIONS if point_sets else ()) and path.is_file()


def manifest(source: str, point_sets: bool = False) -> tuple[list[Job], pathlib.Path]:
    """The meshes of `source` (a directory, a glob pattern or a list file) and their common root; with
    `point_sets`, also the .xyz/.pwn files of a directory or pattern."""
    root: pathlib.Path
    given = pathlib.Path(source)
    if given.is_dir():
        root = given
        paths = sorted(p for p in given.rglob("*") if _is_mesh(p, point_sets))
    elif given.is_file() and given.suffix.lower() not in MESH_EXTENSIONS + POINT_SET_EXTENSIONS:
        paths = []
        for number, line in enumerate(given.read_text().splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            entry = pathlib.Path(line)
            if not entry.is_absolute():
                entry = given.parent / entry
            paths.append(entry)  # missing files become error records, not a refusal of the batch
        root = pathlib.Path(os.path.commonpath([p.resolve().parent for p in paths])) if paths else given.parent
    elif given.is_file():
        root, paths = given.parent, [given]
    else:
        paths = sorted(pathlib.Path(p) for p in glob.glob(source, recursive=True) if _is_mesh(pathlib.Path(p), point_sets))
        magic = min((i for i, c in enumerate(source) if c in "*?["), default=len(source))
        root = pathlib.Path(source[:magic]).parent if paths else pathlib.Path(".")
    if not paths:
        raise ValueError(f"{source}: no meshes found (a directory, a glob pattern or a file listing mesh paths; "
                         f"extensions {', '.join(MESH_EXTENSIONS)})")
    jobs, seen = [], set()
    for p in paths:
        try:
            relative = str(p.resolve().relative_to(root.resolve()))
        except ValueError:
            relative = p.name
        if relative in seen:
            raise ValueError(f"{source}: two inputs map to the same output {relative}")
        seen.add(relative)
        job = Job(p, relative)
        try:
            stat = p.stat()
            job.size, job.mtime_ns = stat.st_size, stat.st_mtime_ns
        except OSError:
            pass
        jobs.append(job)
    return jobs, root


# ---- one mesh -------------------------------------------------------------------------------------

def canonical_options(coarsen: dict) -> dict:
    """The coarsening options as ice.coarsen will use them (defaults filled in, None dropped)."""
    if "threads" in coarsen:
        raise ValueError("the batch chooses the threads of each mesh (BatchOptions.mesh_threads, --mesh-threads); "
                         "they do not change the result, which depends on 'regions'")
    unknown = set(coarsen) - set(COARSEN_OPTIONS)
    if unknown:
        raise ValueError(f"unknown coarsening options {sorted(unknown)} (known: {', '.join(COARSEN_OPTIONS)})")
    options = {**COARSEN_DEFAULTS, **{k: v for k, v in coarsen.items() if v is not None}}
    if options.get("nonmanifold", "refuse") not in ("refuse", "tufted"):
        raise ValueError(f"nonmanifold must be 'refuse' or 'tufted', not {options['nonmanifold']!r}")
    if options.get("nonmanifold") == "refuse":  # the default, left out (so records made before it stay valid)
        del options["nonmanifold"]
    if "separate_thin_parts" in options:
        if not isinstance(options["separate_thin_parts"], bool):
            raise ValueError(f"separate_thin_parts must be True or False, not {options['separate_thin_parts']!r}")
        if not options["separate_thin_parts"]:  # the default, left out as nonmanifold's
            del options["separate_thin_parts"]
        elif options.get("nonmanifold") != "tufted":
            raise ValueError("separate_thin_parts makes point sets' fans: point sets are read with nonmanifold='tufted' only")
    if options["regions"] == 0:  # ice.coarsen's own default, spelled out: the same run, the same hash
        options["regions"] = DEFAULT_COARSENING_REGIONS
    return options


def parse_features(text: str | None) -> dict:
    """--features "eigs:K[,hks:T1:T2:...]" as BatchOptions.features; ValueError naming what is wrong."""
    features: dict = {}
    for item in (text or "").split(","):
        if not item.strip():
            continue
        name, _, rest = item.strip().partition(":")
        if name == "eigs":
            try:
                features["eigs"] = int(rest)
            except ValueError:
                raise ValueError(f"--features: 'eigs:{rest}': K must be an integer") from None
        elif name == "hks":
            try:
                features["hks"] = [float(t) for t in rest.split(":") if t]
            except ValueError:
                raise ValueError(f"--features: 'hks:{rest}': the times must be numbers") from None
        else:
            raise ValueError(f"--features: unknown feature '{name}' (known: eigs:K, hks:T1:T2:...)")
    return check_features(features)


def check_features(features: dict) -> dict:
    """BatchOptions.features checked: eigs K >= 1; hks times > 0, and only with eigs."""
    unknown = set(features) - {"eigs", "hks"}
    if unknown:
        raise ValueError(f"unknown features {sorted(unknown)} (known: eigs, hks)")
    if "eigs" in features and not (isinstance(features["eigs"], int) and features["eigs"] >= 1):
        raise ValueError("features: eigs must be an integer K >= 1")
    if "hks" in features:
        if "eigs" not in features:
            raise ValueError("features: hks is computed from the eigenbasis: give eigs:K too")
        if not features["hks"] or not all(t > 0 for t in features["hks"]):
            raise ValueError("features: hks needs one or more times > 0")
    return features


def batch_digest(coarsen: dict, repair: bool, features: dict | None) -> str:
    """The options hash of a batch's records: coarsening options, repair and (when asked) features."""
    return options_hash({**coarsen, "repair": repair, **({"features": features} if features else {})})


def options_hash(options: dict) -> str:
    """What a record is valid for: the coarsening options, repair, and the package version."""
    from . import __version__
    text = json.dumps({"options": options, "version": __version__, "record": RECORD_VERSION}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def output_paths(out: pathlib.Path, relative: str) -> dict[str, pathlib.Path]:
    base = out / relative
    return {"ilm": base.with_name(base.name + ".ilm"), "npz": base.with_name(base.name + ".npz"),
            "record": base.with_name(base.name + ".json")}


def _write_temporary(path: pathlib.Path, write) -> str:
    """write(temporary path) beside `path` (a `.NAME.*.part` file, which a rerun cleans up); returns it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(handle)
    try:
        write(temporary)
    except BaseException:
        os.unlink(temporary)
        raise
    return temporary


def _atomic_write(path: pathlib.Path, write) -> None:
    """write(temporary path), then rename over `path`: readers see the old file or the whole new one."""
    os.replace(_write_temporary(path, write), path)


def _error_kind(error: BaseException) -> str:
    from . import MeshError
    if isinstance(error, MeshError):
        return error.kind
    if isinstance(error, (ValueError, TypeError)):
        return "invalid"
    if isinstance(error, MemoryError):
        return "memory"
    return "failed"


# The priority of the meshes that yield their cores to the batch's largest ones: the idle scheduling
# policy (SCHED_IDLE) where the system has it, else nice 19. Under nice 19 the largest mesh's threads
# lost ~0.4 s of 3.3 s to a yielding mesh (dragon_vrip_bin on 2 threads beside a nice-19 coarsening
# loop: 3.6-3.9 s against 3.2-3.6 s alone; under SCHED_IDLE 3.2-3.5 s, the loop doing as much work):
# a CPU that runs only idle-policy threads counts as idle when the scheduler places a woken thread.
YIELDING_NICE = 19
# Linux gives each thread its own priority (setpriority / sched_setscheduler on a thread id);
# elsewhere the id would name a process, so meshes run at the worker's priority there.
_PER_THREAD_PRIORITY = sys.platform.startswith("linux") and hasattr(os, "setpriority") and hasattr(threading, "get_native_id")


def _yield_cores() -> None:
    """Puts the calling thread (and the threads it starts) at the lowest priority."""
    thread = threading.get_native_id()
    try:
        os.setpriority(os.PRIO_PROCESS, thread, YIELDING_NICE)
    except OSError:
        pass
    if hasattr(os, "SCHED_IDLE"):
        try:
            os.sched_setscheduler(thread, os.SCHED_IDLE, os.sched_param(0))
        except OSError:  # not allowed here: nice 19 it is
            pass


def _scheduling_policy() -> str:
    """The calling thread's scheduling policy, for its mesh's record."""
    try:
        policy = os.sched_getscheduler(threading.get_native_id())
    except (AttributeError, OSError):
        return "unknown"
    return "idle" if policy == getattr(os, "SCHED_IDLE", None) else "other" if policy == os.SCHED_OTHER else str(policy)


def coarsen_file(path: str, relative: str, out: str, options: dict, repair: bool, timeout: float | None,
                 input_size: int, input_mtime_ns: int, threads: int = 1, yielding: bool = False,
                 features: dict | None = None) -> dict:
    """Coarsens one mesh file on `threads` threads and writes its outputs and record; returns the
    record; with `features` (BatchOptions.features) the eigenbasis and descriptors go into the .npz.
    Never raises for a problem of the mesh: that becomes an error record. Runs in a worker
    process. `yielding`: run at the lowest priority (a thread of its own under the idle scheduling
    policy, or at nice YIELDING_NICE; the mesh's threads inherit it), so that on shared cores the
    batch's largest meshes go first."""
    if yielding and _PER_THREAD_PRIORITY:
        outcome: list = []

        def low_priority():
            _yield_cores()
            try:
                outcome.append(coarsen_file(path, relative, out, options, repair, timeout, input_size,
                                            input_mtime_ns, threads, False, features))
            except BaseException as error:  # re-raised on the task's own thread, as without yielding
                outcome.append(error)
        worker = threading.Thread(target=low_priority, name=f"ice-batch {relative}")
        worker.start()
        worker.join()
        if isinstance(outcome[0], BaseException):
            raise outcome[0]
        return outcome[0]
    import ice
    started = time.perf_counter()
    paths = output_paths(pathlib.Path(out), relative)
    record = {"input": path, "output": relative, "hash": batch_digest(options, repair, features),
              "input_size": input_size, "input_mtime_ns": input_mtime_ns, "threads": threads}
    if _PER_THREAD_PRIORITY:
        record["nice"] = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())  # the priority it ran at
        record["policy"] = _scheduling_policy()
    finished: list[tuple[pathlib.Path, str]] = []  # (output, its written temporary)
    try:
        loaded = ice.load_mesh(path, repair=repair, nonmanifold=options.get("nonmanifold", "refuse"),
                               separate_thin_parts=options.get("separate_thin_parts", False))
        record["vertices"], record["faces"] = int(loaded.V.shape[0]), int(loaded.F.shape[0])
        record["repairs"] = loaded.repairs
        deadline = None if timeout is None else started + timeout
        timed_out = []

        def progress(state):
            if deadline is not None and time.perf_counter() > deadline:
                timed_out.append(True)
                return False
            return True
        # Not through the store of coarse spaces: the batch's records are its own store (it resumes from
        # them), and a dataset's spaces would crowd out a user's set-ups there.
        coarse = ice.coarsen(loaded.V, loaded.F, progress=progress, threads=threads, cache=False,
                             **{k: v for k, v in options.items() if k not in LOAD_OPTIONS})
        if timed_out:
            raise TimeoutError(f"{path}: coarsening passed the timeout of {timeout:g} s "
                               f"(at {coarse.n_vertices} vertices); cancelled")
        P = coarse.P
        face, bary, coarse_vertex = coarse.map if coarse.map is not None else (None, None, None)
        arrays = {"P_data": P.data, "P_indices": P.indices, "P_indptr": P.indptr, "P_shape": np.array(P.shape),
                  "to_input": coarse.to_input, "source_vertex": loaded.source_vertex}
        if face is not None:
            arrays.update(map_face=face, map_bary=bary, map_coarse_vertex=coarse_vertex)
        if features and "eigs" in features:
            # As spectral-coarse: the Galerkin proxy of this coarse space, its pencil's eigenpairs prolonged.
            eigen_started = time.perf_counter()
            proxy = ice.Proxy(loaded.V, loaded.F, coarse, operators="galerkin",
                              prolongation=ice._ice._resolve_prolongation("auto", "galerkin", False, eigenpairs=True))
            values, vectors = ice.proxy_eigenbasis(proxy, features["eigs"], cache=False)  # the records are the batch's store
            arrays.update(eigenvalues=values, eigenvectors=vectors)
            if "hks" in features:
                times = np.asarray(features["hks"], dtype=float)
                arrays.update(hks=ice.heat_kernel_signature(values, vectors, times), hks_times=times)
            record["eigen_seconds"] = time.perf_counter() - eigen_started

        def write_npz(temporary):
            with open(temporary, "wb") as file:
                np.savez(file, **arrays)
        # The outputs are renamed into place only after the record is written: a batch killed in
        # between leaves outputs *with* their record (redone by the rerun as incomplete), never
        # outputs without one, which a rerun would have to refuse as files a batch did not write.
        # Through a tufted cover there is no .ilm: the coarse vertices have a fan per sheet, which an
        # intrinsic mesh file cannot be read back as (the record says so; P and the features are written).
        covered = bool(coarse.summary.get("tufted_cover", False))
        if not covered:
            finished.append((paths["ilm"], _write_temporary(paths["ilm"], lambda temporary: coarse.save(temporary, overwrite=True))))
        elif paths["ilm"].exists():  # from an earlier run on another input of that name
            paths["ilm"].unlink()
        finished.append((paths["npz"], _write_temporary(paths["npz"], write_npz)))
        record["tufted_cover"] = covered
        record["point_cloud"] = bool(loaded.point_cloud)
        summary = coarse.summary
        record.update(status="ok", coarse_vertices=int(coarse.n_vertices), coarse_faces=int(coarse.n_faces),
                      stop_reason=summary["stop_reason"], target_reached=summary["target_reached"],
                      coarsen_seconds=summary["seconds"])
    except Exception as error:  # every failure of one mesh is its record
        record.update(status="error", error_kind="timeout" if isinstance(error, TimeoutError) else _error_kind(error),
                      error=str(error) or type(error).__name__)
        for _, temporary in finished:
            os.unlink(temporary)
        finished.clear()
    record["seconds"] = time.perf_counter() - started
    _atomic_write(paths["record"], lambda temporary: pathlib.Path(temporary).write_text(json.dumps(record) + "\n"))
    for path, temporary in finished:
        os.replace(temporary, path)
    return record


def load_result(out: str | os.PathLike, relative: str) -> dict:
    """A finished mesh's outputs: the record, the coarse mesh (ice.CoarseSpace from the .ilm; None for a
    mesh or point set solved on its tufted cover) and P (scipy.sparse.csr_matrix), plus the map arrays
    when they were kept."""
    import ice
    paths = output_paths(pathlib.Path(out), relative)
    record = json.loads(paths["record"].read_text())
    if record.get("status") != "ok":
        raise ValueError(f"{paths['record']}: no result ({record.get('error_kind')}: {record.get('error')})")
    with np.load(paths["npz"]) as arrays:
        result = {name: arrays[name] for name in arrays.files}
    result["P"] = scipy.sparse.csr_matrix((result.pop("P_data"), result.pop("P_indices"), result.pop("P_indptr")),
                                          shape=tuple(result.pop("P_shape")))
    result["coarse"] = None if record.get("tufted_cover") else ice.load_coarse_mesh(paths["ilm"])
    result["record"] = record
    return result


# ---- the batch ------------------------------------------------------------------------------------

@dataclass
class BatchOptions:
    coarsen: dict
    repair: bool = False
    # Spectral features written beside each coarse space (parse_features): {"eigs": K} the K smallest
    # Laplace–Beltrami eigenpairs through the mesh's Galerkin proxy (ice.proxy_eigenbasis), and
    # {"hks": [t, ...]} the heat kernel signature at those times from them. Empty: none.
    features: dict = field(default_factory=dict)
    workers: int = 2
    scheduler: str | None = None
    memory_limit: str | None = "auto"
    timeout: float | None = None
    stall_timeout: float | None = 1800.0  # seconds without any mesh finishing before the batch gives up
    # Coarsening threads per mesh (only meshes of 20,000+ vertices use more than one). None: on a
    # LocalCluster the batch's cores (= workers), so the last large meshes run on the cores the
    # finished workers left idle (while others run, the system shares the cores among them); with
    # --scheduler, 1.
    mesh_threads: int | None = None
    force: bool = False
    progress: bool = True
    # How a local cluster starts its workers (START_METHODS): "spawn", a fresh Python per worker
    # (anywhere); "forkserver", workers forked from one clean server process that imports Dask and
    # its packages once (Linux, macOS; the default there, DEFAULT_START_METHOD). Not "fork": workers
    # forked from the batch's own process start fastest (0.07 s for two against 0.4 s, ice already
    # imported) but a lock another of its threads holds at the fork stays held in the worker: in
    # one of two test-suite runs a forked worker hung at its start.
    start_method: str = DEFAULT_START_METHOD


@dataclass
class BatchResult:
    records: list[dict] = field(default_factory=list)
    skipped: int = 0
    seconds: float = 0.0          # the whole run
    cluster_seconds: float = 0.0  # of which starting (or connecting to) the Dask cluster

    def counts(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for record in self.records:
            key = "ok" if record["status"] == "ok" else record.get("error_kind", "failed")
            counts[key] = counts.get(key, 0) + 1
        return counts


def _up_to_date(job: Job, paths: dict, digest: str) -> dict | None:
    """The mesh's record when a rerun need not redo it."""
    try:
        record = json.loads(paths["record"].read_text())
    except (OSError, ValueError):
        return None
    if (record.get("hash"), record.get("input_size"), record.get("input_mtime_ns")) != (digest, job.size, job.mtime_ns):
        return None
    if record.get("status") == "ok":
        return record if (record.get("tufted_cover") or paths["ilm"].exists()) and paths["npz"].exists() else None
    return record if record.get("error_kind") in DETERMINISTIC_ERRORS else None


def _check_outputs(jobs: list[Job], out: pathlib.Path, force: bool) -> None:
    """Refuses outputs that would replace an input, or files a batch did not write (without force)."""
    inputs = {job.path.resolve() for job in jobs}
    for job in jobs:
        paths = output_paths(out, job.relative)
        for kind, path in paths.items():
            if path.resolve() in inputs:
                raise ValueError(f"{path}: an output would replace an input mesh; choose another output folder")
            if kind != "record" and path.exists() and not paths["record"].exists() and not force:
                raise FileExistsError(f"{path} exists and was not written by a batch (no {paths['record'].name}); "
                                      f"use --force to replace it")


def _start_method(options: BatchOptions) -> str:
    """How a local cluster starts its worker processes (BatchOptions.start_method)."""
    method = options.start_method
    if method not in START_METHODS:
        raise ValueError(f"unknown start method {method!r} (known: {', '.join(START_METHODS)})")
    return method


def _start_forkserver() -> None:
    """Starts the server that local workers are forked from, importing Dask and ice in it, while this
    process imports Dask itself (they took turns when Dask started it: ~0.3 s each). Dask reuses a
    running server; the modules it would preload are among these or imported by them."""
    import multiprocessing.forkserver
    multiprocessing.get_context("forkserver").set_forkserver_preload(["distributed", "numpy", "ice", "ice.batch"])
    multiprocessing.forkserver.ensure_running()


def _client(options: BatchOptions, stack: contextlib.ExitStack):
    """A client of the scheduler, or of a new local cluster whose Dask settings `stack`'s exit ends."""
    from distributed import Client, LocalCluster
    if options.scheduler:
        return Client(options.scheduler), None
    import logging
    import dask
    method = _start_method(options)
    # Dask starts workers with OMP_NUM_THREADS=OPENBLAS_NUM_THREADS=1 (numpy's threads times its
    # processes would oversubscribe the cores); ICE's own threaded passes then run on one core even
    # when the workers are fewer than the cores. Give each worker its share of them.
    share = str(max(1, (os.cpu_count() or 1) // options.workers))
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.update(OMP_NUM_THREADS=share, OPENBLAS_NUM_THREADS=share, MKL_NUM_THREADS=share)
    # Nor Dask's MALLOC_TRIM_THRESHOLD_: setting it also fixes glibc's mmap threshold, so every large
    # array of every mesh is mapped afresh and its pages faulted in and zeroed again. The batch over
    # the shared meshes on one worker: 8.97 s with it, 8.28 s without (medians of 5 interleaved).
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    # Held while the cluster lives: a nanny reads them whenever it starts a worker process, also
    # when it restarts one after a crash.
    stack.enter_context(dask.config.set({"distributed.nanny.pre-spawn-environ": environ,
                                         "distributed.worker.multiprocessing-method": method}))
    cluster = LocalCluster(n_workers=options.workers, threads_per_worker=1, processes=True,
                           memory_limit=options.memory_limit, dashboard_address=None, silence_logs=logging.ERROR)
    try:
        client = Client(cluster)
    except BaseException:
        cluster.close()
        raise
    return client, cluster


def run(source: str, out: str | os.PathLike, options: BatchOptions, log=sys.stderr) -> BatchResult:
    """Coarsens every mesh of `source` into `out` (see the module documentation); returns the records
    of this run (done now or found up to date) in manifest order."""
    started = time.perf_counter()
    if options.stall_timeout is not None and not options.stall_timeout > 0:
        raise ValueError(f"the stall timeout must be positive, not {options.stall_timeout}")
    if options.mesh_threads is not None and not 1 <= options.mesh_threads <= 64:
        raise ValueError(f"the threads per mesh must be in 1..64, not {options.mesh_threads}")
    if not options.scheduler:
        _start_method(options)  # refuse an unknown method before any work
    threads = options.mesh_threads or (1 if options.scheduler else max(1, min(options.workers, os.cpu_count() or 1)))
    options = dataclasses.replace(options, coarsen=canonical_options(options.coarsen))
    jobs, _ = manifest(source, point_sets=options.coarsen.get("nonmanifold") == "tufted")
    out = pathlib.Path(out)
    _check_outputs(jobs, out, options.force)
    features = check_features(dict(options.features))
    digest = batch_digest(options.coarsen, options.repair, features)
    result = BatchResult()
    records: dict[str, dict] = {}
    todo = []
    for job in jobs:
        record = _up_to_date(job, output_paths(out, job.relative), digest)
        if record is None:
            todo.append(job)
        else:
            records[job.relative] = record
            result.skipped += 1
    # Temporary files of an interrupted run (killed while writing) for the meshes done again.
    for job in todo:
        for path in output_paths(out, job.relative).values():
            for stale in path.parent.glob(f".{path.name}.*.part"):
                stale.unlink()
    # Largest first: the big meshes start early, so the workers finish together.
    todo.sort(key=lambda job: job.size, reverse=True)
    if todo:
        cluster_start = time.perf_counter()
        if not options.scheduler and _start_method(options) == "forkserver":
            _start_forkserver()
        from distributed import as_completed
        stack = contextlib.ExitStack()
        try:
            client, cluster = _client(options, stack)
        except BaseException:
            stack.close()
            raise
        result.cluster_seconds = time.perf_counter() - cluster_start
        stalled = False  # set by the watchdog
        try:
            # On a local cluster the largest meshes (one per worker) keep their priority and the rest
            # yield: while a large mesh runs on more threads than its share of the cores, the small
            # ones take what it leaves idle instead of slowing it down (the batch's critical path).
            yield_from = options.workers if not options.scheduler and threads > 1 else len(todo)
            # One map call, not a submit per mesh: Dask reads the calling code's source on each call
            # (for its dashboard), ~5 ms each.
            count = len(todo)
            submitted = client.map(coarsen_file, [str(job.path) for job in todo], [job.relative for job in todo],
                                   [str(out)] * count, [options.coarsen] * count, [options.repair] * count,
                                   [options.timeout] * count, [job.size for job in todo],
                                   [job.mtime_ns for job in todo], [threads] * count,
                                   [rank >= yield_from for rank in range(count)], [features] * count, pure=False,
                                   key=[f"ice-{job.relative}-{digest}" for job in todo])
            futures = dict(zip(submitted, todo))
            bar = _progress_bar(len(todo), options.progress, log)
            finished = as_completed(futures)
            last_finish = time.monotonic()
            while not finished.is_empty():
                if not finished.has_ready():
                    if options.stall_timeout is not None and time.monotonic() - last_finish > options.stall_timeout:
                        stalled = True
                        for future, job in futures.items():  # the watchdog: stop waiting, record the rest
                            if job.relative not in records:
                                future.cancel()
                                records[job.relative] = _error_record(job, out, digest, "stalled",
                                    f"{job.path}: no mesh of the batch finished for {options.stall_timeout:g} s "
                                    f"while this one was queued or running (a hung or lost worker?); the batch "
                                    f"stopped waiting: rerun to retry it")
                                bar(records[job.relative])
                        break
                    time.sleep(0.01)  # how late the batch notices its last mesh finished
                    continue
                for future in finished.next_batch(block=False):
                    job = futures[future]
                    try:
                        record = _finished_record(future, out, job)
                    except Exception as error:  # the task's workers died: KilledWorker, or the cluster went away
                        record = _error_record(job, out, digest, "crashed",
                                               f"{job.path}: the worker process died while coarsening it "
                                               f"({type(error).__name__}: {error})")
                    records[job.relative] = record
                    bar(record)
                last_finish = time.monotonic()
            bar(None)
        finally:
            with stack:
                _shut_down(client, cluster, stalled)
    result.records = [records[job.relative] for job in jobs]
    result.seconds = time.perf_counter() - started
    _write_summary(out, result)
    return result


def _finished_record(future, out: pathlib.Path, job: Job) -> dict:
    """The record of a finished task, read from the file its worker wrote before returning: fetching
    the returned copy from the worker would block for as long as that worker hangs (its result is
    held there), out of the watchdog's reach. Raises the task's exception if it failed."""
    if future.status == "finished":
        try:
            return json.loads(output_paths(out, job.relative)["record"].read_text())
        except (OSError, ValueError):
            pass
    return future.result()


def _shut_down(client, cluster, stalled: bool) -> None:
    """Closes the client and a local cluster within bounded time. After a stall the local workers
    may be hung or stopped (they answer no close request, and a stopped process keeps a SIGTERM
    pending): they are killed first."""
    if stalled and cluster is not None:
        for nanny in list(cluster.workers.values()):
            pid = getattr(getattr(nanny, "process", None), "pid", None)
            if pid:
                try:
                    os.kill(pid, signal.SIGKILL)
                except OSError:
                    pass
    for close in ([client.close] + ([cluster.close] if cluster is not None else [])):
        try:
            close(timeout=30)
        except Exception:  # a cluster that does not answer in time is left to the process exit
            pass


def _error_record(job: Job, out: pathlib.Path, digest: str, kind: str, message: str) -> dict:
    """The record of a mesh whose task did not return one (its workers died, or the batch stopped waiting)."""
    record = {"input": str(job.path), "output": job.relative, "hash": digest, "input_size": job.size,
              "input_mtime_ns": job.mtime_ns, "status": "error", "error_kind": kind, "error": message,
              "seconds": None}
    path = output_paths(out, job.relative)["record"]
    _atomic_write(path, lambda temporary: pathlib.Path(temporary).write_text(json.dumps(record) + "\n"))
    return record


def _progress_bar(total: int, enabled: bool, log):
    done = [0, 0]  # finished, failed
    start = time.perf_counter()
    try:
        from tqdm import tqdm
        bar = tqdm(total=total, unit="mesh", file=log, disable=not enabled, dynamic_ncols=True)
    except ImportError:
        bar = None

    def update(record):
        if record is None:
            if bar is not None:
                bar.close()
            return
        done[0] += 1
        done[1] += record["status"] != "ok"
        if bar is not None:
            bar.set_postfix(failed=done[1], refresh=False)
            bar.update(1)
        elif enabled:
            print(f"\r{done[0]}/{total} meshes, {done[1]} failed, {time.perf_counter() - start:.0f} s",
                  end="" if done[0] < total else "\n", file=log, flush=True)
    return update


SUMMARY_FIELDS = ("output", "status", "error_kind", "vertices", "coarse_vertices", "stop_reason", "seconds",
                  "coarsen_seconds", "error")


def _write_summary(out: pathlib.Path, result: BatchResult) -> None:
    out.mkdir(parents=True, exist_ok=True)
    lines = "".join(json.dumps(record) + "\n" for record in result.records)
    _atomic_write(out / "records.jsonl", lambda temporary: pathlib.Path(temporary).write_text(lines))
    text = io.StringIO()
    writer = csv.DictWriter(text, SUMMARY_FIELDS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for record in result.records:
        writer.writerow(record)
    _atomic_write(out / "summary.csv", lambda temporary: pathlib.Path(temporary).write_text(text.getvalue()))


def summary_text(result: BatchResult, out: pathlib.Path) -> str:
    counts = result.counts()
    lines = [f"{len(result.records)} meshes in {result.seconds:.1f} s ({result.cluster_seconds:.1f} s starting Dask): "
             + ", ".join(f"{count} {kind}" for kind, count in sorted(counts.items()))
             + f" ({result.skipped} already done)"]
    times = [r["seconds"] for r in result.records if r.get("seconds") is not None and r["status"] == "ok"]
    if times:
        q = statistics.quantiles(times, n=20, method="inclusive") if len(times) > 1 else [times[0]] * 19
        lines.append(f"seconds per mesh: median {statistics.median(times):.3f}, p95 {q[18]:.3f}, max {max(times):.3f}")
        slowest = sorted((r for r in result.records if r["status"] == "ok"), key=lambda r: -r["seconds"])[:3]
        lines.append("slowest: " + ", ".join(f"{r['output']} {r['seconds']:.2f} s" for r in slowest))
    for record in result.records:
        if record["status"] != "ok":
            lines.append(f"  {record.get('error_kind')}: {record.get('error')}")
    lines.append(f"records: {out / 'records.jsonl'}, {out / 'summary.csv'}")
    return "\n".join(lines)


# ---- command line ---------------------------------------------------------------------------------

def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ice-batch", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    parser.add_argument("input", help="a directory, a glob pattern (quoted) or a file listing mesh paths")
    parser.add_argument("-o", "--output", required=True, help="output folder (created; mirrors the input tree)")
    target = parser.add_mutually_exclusive_group()
    target.add_argument("-n", "--vertices", type=int, help="coarsen to N vertices")
    target.add_argument("-r", "--ratio", type=float, help="coarsen to a ratio of the vertices, e.g. 0.05")
    parser.add_argument("-e", "--max-error", type=float, help="bound on the ICE error metric")
    parser.add_argument("--method", choices=("ice", "qem"), default="ice")
    parser.add_argument("--use", choices=("poisson_heat", "geodesic"), default="poisson_heat",
                        help="which measured metric defaults (as the tools)")
    parser.add_argument("-w", "--area-weight", type=float)
    parser.add_argument("--keep-boundary", action="store_true", help="never remove boundary vertices")
    parser.add_argument("--refine-angle", type=float, help="intrinsic Delaunay refinement to this smallest angle")
    parser.add_argument("--repair", action="store_true", help="apply the safe mesh repairs before coarsening")
    parser.add_argument("--nonmanifold", choices=("refuse", "tufted"), default="refuse",
                        help="tufted: solve meshes that are not oriented manifolds, and point sets (.xyz, .pwn, "
                             "faceless files), on their tufted cover (no .ilm written for those)")
    parser.add_argument("--separate-thin-parts", action="store_true",
                        help="point sets: keep apart the two sides of parts sampled a few points across (limbs, "
                             "fins), as the tools' --separate-thin-parts")
    parser.add_argument("--features", help="also write eigs:K (the K smallest Laplace-Beltrami eigenpairs through the "
                                           "coarse proxy) and hks:T1:T2:... (heat kernel signatures) into each .npz")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                        help="worker processes of the local Dask cluster (default: 2, or the cores if fewer)")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://HOST:PORT) instead")
    parser.add_argument("--start-method", choices=START_METHODS, default=BatchOptions.start_method,
                        help="how the local cluster starts its workers: spawn (a fresh Python each) or forkserver "
                             "(forked from one server process that imports Dask once; the default where the "
                             "platform has it) (default: %(default)s)")
    parser.add_argument("--mesh-threads", type=int,
                        help="threads per mesh, for meshes of 20,000+ vertices (default: the number of local "
                             "workers, so the last large meshes use the cores idle workers leave; 1 with "
                             "--scheduler); the result does not depend on it")
    parser.add_argument("--regions", type=int, default=COARSEN_DEFAULTS["regions"],
                        help="regions of ICE's parallel phase for meshes of 20,000+ vertices (fixed, so a mesh's "
                             "result does not depend on the threads or the machine; 1 = the exact serial greedy "
                             "order; default: %(default)s)")
    parser.add_argument("--memory-limit", default="auto",
                        help="per worker, e.g. 4GB (Dask restarts a worker above it; default: memory / workers)")
    parser.add_argument("--timeout", type=float, help="seconds per mesh before its coarsening is cancelled")
    parser.add_argument("--stall-timeout", type=float, default=BatchOptions.stall_timeout,
                        help="seconds without any mesh finishing before the batch stops waiting and records the "
                             "meshes still queued or running as stalled (default: %(default)g)")
    parser.add_argument("--force", action="store_true", help="replace output files a batch did not write")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if args.vertices is None and args.ratio is None and args.max_error is None:
        print("ice-batch: say how far to coarsen: --vertices N, --ratio R (e.g. 0.05) or --max-error E",
              file=sys.stderr)
        return 4
    coarsen = {"method": args.method, "use": args.use, "regions": args.regions}
    for name, value in (("n", args.vertices), ("ratio", args.ratio), ("max_error", args.max_error),
                        ("area_weight", args.area_weight), ("refine_angle", args.refine_angle)):
        if value is not None:
            coarsen[name] = value
    if args.keep_boundary:
        coarsen["remove_boundary"] = False
    if args.nonmanifold != "refuse":
        coarsen["nonmanifold"] = args.nonmanifold
    if args.separate_thin_parts:
        coarsen["separate_thin_parts"] = True
    if args.workers < 1:
        print("ice-batch: --workers must be >= 1", file=sys.stderr)
        return 4
    try:
        features = parse_features(args.features)
    except ValueError as error:
        print(f"ice-batch: {error}", file=sys.stderr)
        return 4
    options = BatchOptions(coarsen=coarsen, repair=args.repair, features=features, workers=args.workers,
                           scheduler=args.scheduler,
                           mesh_threads=args.mesh_threads, start_method=args.start_method,
                           memory_limit=args.memory_limit, timeout=args.timeout,
                           stall_timeout=args.stall_timeout, force=args.force,
                           progress=not args.quiet and sys.stderr.isatty())
    try:
        result = run(args.input, args.output, options)
    except (ValueError, FileExistsError, OSError) as error:
        print(f"ice-batch: {error}", file=sys.stderr)
        return 3 if isinstance(error, FileExistsError) else 4
    print(summary_text(result, pathlib.Path(args.output)))
    return 0 if all(r["status"] == "ok" for r in result.records) else 5


if __name__ == "__main__":
    sys.exit(main())
