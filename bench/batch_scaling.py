#!/usr/bin/env python3
"""ice-batch on a mesh folder: 2 Dask workers against 1, and the per-mesh overhead of a batch over
calling the library directly.

    PYTHONPATH=build/release/python python3 bench/batch_scaling.py [FOLDER] [--ratio 0.05] [--rounds 3]

Each round (alternating, fresh output folders) runs: the library directly in this process (for every
mesh: ice.load_mesh, ice.coarsen with the batch's options on one thread, CoarseSpace.save, P and the
map saved with numpy, one process, no Dask), then ice.batch.run with 1 worker and with 2 (the batch's
default threads per mesh: 1 and 2, for meshes of 20,000+ vertices). Prints medians of the wall
times, the speed-up of 2 workers over 1, and (batch with 1 worker − direct) / meshes, with and
without the cluster's start.
Default folder: ../shared/data/meshes beside the repository (with --repair, as it has defective files).
"""
import argparse
import pathlib
import shutil
import statistics
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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", default=ROOT.parent / "shared" / "data" / "meshes")
    parser.add_argument("--ratio", type=float, default=0.05)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    coarsen = {"ratio": args.ratio}
    jobs, _ = batch.manifest(str(args.folder))
    times = {"direct": [], "1 worker": [], "2 workers": []}
    cluster = {"1 worker": [], "2 workers": []}
    outcomes = None
    for _ in range(args.rounds):
        scratch = pathlib.Path(tempfile.mkdtemp(prefix="ice-batch-bench-"))
        try:
            times["direct"].append(direct(jobs, scratch / "direct", coarsen, True))
            for workers, name in ((1, "1 worker"), (2, "2 workers")):
                options = batch.BatchOptions(coarsen=coarsen, repair=True, workers=workers, progress=False)
                result = batch.run(str(args.folder), scratch / name.replace(" ", "_"), options)
                times[name].append(result.seconds)
                cluster[name].append(result.cluster_seconds)
                outcomes = result.counts()
        finally:
            shutil.rmtree(scratch)
    median = {name: statistics.median(values) for name, values in times.items()}
    start = {name: statistics.median(values) for name, values in cluster.items()}
    n = len(jobs)
    print(f"{args.folder}: {n} meshes at ratio {args.ratio} ({outcomes}), {args.rounds} rounds, medians")
    for name in times:
        extra = f" (of which {start[name]:.2f} s starting Dask)" if name in start else ""
        print(f"  {name:10} {median[name]:7.2f} s{extra}")
    print(f"  speed-up of 2 workers over 1: {median['1 worker'] / median['2 workers']:.2f}x "
          f"(without the cluster's start: {(median['1 worker'] - start['1 worker']) / (median['2 workers'] - start['2 workers']):.2f}x)")
    print(f"  batch overhead per mesh (1 worker - direct) / {n}: {(median['1 worker'] - median['direct']) / n * 1000:.0f} ms, "
          f"without the cluster's start: {(median['1 worker'] - start['1 worker'] - median['direct']) / n * 1000:.0f} ms")


if __name__ == "__main__":
    main()
