#!/usr/bin/env python3
"""ice-batch on a mesh folder: 2 Dask workers against 1, and the per-mesh overhead of a batch over
calling the library directly.

    PYTHONPATH=build/release/python python3 bench/batch_scaling.py [FOLDER] [--ratio 0.05] [--rounds 3]
        [--start-method spawn|forkserver]

Each round (alternating, fresh output folders) runs: the library directly in this process (for every
mesh: ice.load_mesh, ice.coarsen with the batch's options on one thread, CoarseSpace.save, P and the
map saved with numpy, one process, no Dask), then ice.batch.run with 1 worker and with 2 (the batch's
default threads per mesh: 1 and 2, for meshes of 20,000+ vertices), each batch in a fresh Python
process as a user's ice-batch runs (a forkserver started by an earlier batch would otherwise serve
the later ones). Prints medians of the batches' wall times (ice.batch.run's, from importing Dask to
the summary), the speed-up of 2 workers over 1, and (batch with 1 worker − direct) / meshes, with
and without the cluster's start. It also counts the CPU time of each batch (the whole process with
its workers, on Linux the cores' busy time from /proc/stat over the run, as a forked worker is not
a child of the batch's process; elsewhere getrusage of the ended children): a batch cannot finish
sooner than its CPU time divided by the cores, which bounds the speed-up 2 workers can give over 1
on this machine.
Default folder: ../shared/data/meshes beside the repository (with --repair, as it has defective files).
"""
import argparse
import json
import os
import pathlib
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import ice
import ice.batch as batch

ROOT = pathlib.Path(__file__).resolve().parents[1]


def direct(jobs, out: pathlib.Path, coarsen: dict, repair: bool) -> float:
    start = time.perf_counter()
    for job in jobs:
        try:
            V, F = ice.load_mesh(job.path, repair=repair)
            coarse = ice.coarsen(V, F, threads=1, **batch.canonical_options(coarsen))  # as a 1-worker batch
        except (ice.MeshError, ValueError, RuntimeError):
            continue
        target = out / job.relative
        target.parent.mkdir(parents=True, exist_ok=True)
        coarse.save(target.with_name(target.name + ".ilm"))
        P = coarse.P
        face, bary, coarse_vertex = coarse.map
        np.savez(target.with_name(target.name + ".npz"), P_data=P.data, P_indices=P.indices, P_indptr=P.indptr,
                 map_face=face, map_bary=bary, map_coarse_vertex=coarse_vertex)
    return time.perf_counter() - start


def cpu_seconds() -> float:
    """Busy CPU time: of all cores from /proc/stat where there is one (on an otherwise idle machine,
    the batch's with every process it starts), else of this process and its ended children (which
    misses workers forked by a forkserver)."""
    try:
        with open("/proc/stat") as stat:
            ticks = [int(field) for field in stat.readline().split()[1:]]
        return (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")  # all but idle and iowait
    except (OSError, ValueError, IndexError):
        own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def batch_process(folder: str, out: pathlib.Path, coarsen: dict, workers: int, start_method: str | None) -> dict:
    """Runs one batch in a fresh Python process; returns its seconds, cluster_seconds, cpu_seconds
    (over the same span) and counts."""
    options = {"coarsen": coarsen, "repair": True, "workers": workers, "progress": False}
    if start_method:
        options["start_method"] = start_method
    child = subprocess.run([sys.executable, __file__, "--child", json.dumps([folder, str(out), options])],
                           check=True, capture_output=True, text=True)
    return json.loads(child.stdout.splitlines()[-1])


def child(arguments: str) -> None:
    folder, out, options = json.loads(arguments)
    before = cpu_seconds()
    result = batch.run(folder, out, batch.BatchOptions(**options))
    print(json.dumps({"seconds": result.seconds, "cluster_seconds": result.cluster_seconds,
                      "cpu_seconds": cpu_seconds() - before, "counts": result.counts()}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", default=ROOT.parent / "shared" / "data" / "meshes")
    parser.add_argument("--ratio", type=float, default=0.05)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--start-method", choices=batch.START_METHODS,
                        help=f"how the batches start their workers (default: the batch's, {batch.DEFAULT_START_METHOD})")
    parser.add_argument("--child", help=argparse.SUPPRESS)  # one batch, in the process this script starts
    args = parser.parse_args()
    if args.child:
        return child(args.child)
    coarsen = {"ratio": args.ratio}
    jobs, _ = batch.manifest(str(args.folder))
    times = {"direct": [], "1 worker": [], "2 workers": []}
    cluster = {"1 worker": [], "2 workers": []}
    cpu = {"1 worker": [], "2 workers": []}
    outcomes = None
    for _ in range(args.rounds):
        scratch = pathlib.Path(tempfile.mkdtemp(prefix="ice-batch-bench-"))
        try:
            times["direct"].append(direct(jobs, scratch / "direct", coarsen, True))
            for workers, name in ((1, "1 worker"), (2, "2 workers")):
                result = batch_process(str(args.folder), scratch / name.replace(" ", "_"), coarsen, workers,
                                       args.start_method)
                cpu[name].append(result["cpu_seconds"])
                times[name].append(result["seconds"])
                cluster[name].append(result["cluster_seconds"])
                outcomes = result["counts"]
        finally:
            shutil.rmtree(scratch)
    median = {name: statistics.median(values) for name, values in times.items()}
    start = {name: statistics.median(values) for name, values in cluster.items()}
    busy = {name: statistics.median(values) for name, values in cpu.items()}
    n = len(jobs)
    method = args.start_method or batch.DEFAULT_START_METHOD
    print(f"{args.folder}: {n} meshes at ratio {args.ratio} ({outcomes}), {args.rounds} rounds, workers started by "
          f"{method}, medians")
    for name in times:
        extra = f" (of which {start[name]:.2f} s starting Dask)" if name in start else ""
        if name in busy:
            extra += f", CPU {busy[name]:.2f} s ({busy[name] / median[name]:.2f} cores busy on average)"
        print(f"  {name:10} {median[name]:7.2f} s{extra}")
    print(f"  speed-up of 2 workers over 1: {median['1 worker'] / median['2 workers']:.2f}x "
          f"(without the cluster's start: {(median['1 worker'] - start['1 worker']) / (median['2 workers'] - start['2 workers']):.2f}x)")
    print(f"  batch overhead per mesh (1 worker - direct) / {n}: {(median['1 worker'] - median['direct']) / n * 1000:.0f} ms, "
          f"without the cluster's start: {(median['1 worker'] - start['1 worker'] - median['direct']) / n * 1000:.0f} ms")
    # Two workers cannot finish before their CPU time is spread over min(2, cores) cores.
    cores = min(2, os.cpu_count() or 1)
    print(f"  bound from the CPU time: 2 workers >= {busy['2 workers'] / cores:.2f} s on {cores} cores, "
          f"a speed-up of at most {median['1 worker'] / (busy['2 workers'] / cores):.2f}x")


if __name__ == "__main__":
    main()
