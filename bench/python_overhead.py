#!/usr/bin/env python3
"""What calling ICE through its Python package adds: the same operations from C++ and from Python.

    PYTHONPATH=build/release/python python3 bench/python_overhead.py \
        --parity build/release/bench/python-parity [MESH] [--subdivide 1] [--rounds 7]

Each round runs the C++ program python-parity (the library calls alone, timed inside the process)
and then this script in a child process doing the same operations through the package (timed the
same way: perf_counter around each call, the conversions and checks included); both processes load
the mesh and run once untimed before the timed run, and they alternate, so both see the same
machine noise. Prints the median seconds of each operation on both sides and their ratio Python / C++.
Default input: data/default/armadillo.off Loop-subdivided once (104k vertices).
"""
import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import time

import numpy as np

import ice

ROOT = pathlib.Path(__file__).resolve().parents[1]
OPERATIONS = ["coarsen", "proxy", "poisson_setup", "poisson_solve", "geodesic_setup", "geodesic_solve"]


def median_seconds(call, repeats=9):
    """Solves take milliseconds: the median of `repeats` (as python-parity does)."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def python_round(V, F, f, ratio):
    times = {}
    start = time.perf_counter()
    coarse = ice.coarsen(V, F, ratio=ratio)
    coarse.P  # the prolongation as scipy.sparse, as a user reads it
    times["coarsen"] = time.perf_counter() - start
    start = time.perf_counter()
    proxy = ice.Proxy(V, F, coarse)
    times["proxy"] = time.perf_counter() - start
    start = time.perf_counter()
    poisson = ice.ProxyPoissonSolver(proxy)
    times["poisson_setup"] = time.perf_counter() - start
    times["poisson_solve"] = median_seconds(lambda: poisson.solve(f))
    start = time.perf_counter()
    geodesic = ice.ProxyGeodesicSolver(proxy)
    times["geodesic_setup"] = time.perf_counter() - start
    times["geodesic_solve"] = median_seconds(lambda: geodesic.distance([0]))
    return times, coarse.n_vertices


def child(args):
    """One Python process's round, as python-parity's: load and subdivide (untimed), a warm round,
    then the timed one (printed as JSON)."""
    V, F = ice.load_mesh(args.mesh)
    V, F = ice.loop_subdivide(V, F, args.subdivide)
    f = np.sin(3 * V[:, 0]) + V[:, 1]
    start = time.perf_counter()
    python_round(V, F, f, args.ratio)  # also validates (V, F), once: later calls find its fingerprint
    first = time.perf_counter() - start
    times, coarse_vertices = python_round(V, F, f, args.ratio)
    print(json.dumps({"vertices": len(V), "coarse_vertices": coarse_vertices, "first_round": first, **times}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mesh", nargs="?", default=ROOT / "data" / "default" / "armadillo.off")
    parser.add_argument("--parity", default=ROOT / "build" / "release" / "bench" / "python-parity")
    parser.add_argument("--subdivide", type=int, default=1)
    parser.add_argument("--ratio", type=float, default=0.05)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return child(args)

    # Both sides alike: a fresh process per round that loads and subdivides the mesh, runs the
    # operations once untimed (thread pools, first-touch pages; in Python also the one validation of
    # (V, F)) and once timed; the C++ and Python processes alternate, so both see the same noise.
    common = [str(args.mesh), "--subdivide", str(args.subdivide), "--ratio", str(args.ratio)]
    cpp, python = {op: [] for op in OPERATIONS}, {op: [] for op in OPERATIONS}
    first_rounds = []
    for _ in range(args.rounds):
        out = subprocess.run([str(args.parity), *common, "--rounds", "2"], capture_output=True, text=True,
                             check=True).stdout
        row = json.loads(out.splitlines()[-1])
        out = subprocess.run([sys.executable, __file__, "--child", *common], capture_output=True, text=True,
                             check=True).stdout
        prow = json.loads(out)
        assert (prow["vertices"], prow["coarse_vertices"]) == (row["vertices"], row["coarse_vertices"])
        first_rounds.append(prow["first_round"])
        for op in OPERATIONS:
            cpp[op].append(row[op])
            python[op].append(prow[op])

    print(f"{args.mesh} x{args.subdivide} Loop: {row['vertices']} vertices -> {row['coarse_vertices']} coarse, "
          f"{args.rounds} alternating rounds, medians")
    print(f"{'operation':16} {'C++ s':>9} {'Python s':>9} {'Python/C++':>11}")
    total_cpp = total_python = 0.0
    for op in OPERATIONS:
        a, b = statistics.median(cpp[op]), statistics.median(python[op])
        total_cpp, total_python = total_cpp + a, total_python + b
        print(f"{op:16} {a:9.4f} {b:9.4f} {b / a:11.3f}")
    print(f"{'sum of medians':16} {total_cpp:9.4f} {total_python:9.4f} {total_python / total_cpp:11.3f}")
    print(f"(the untimed first Python round, with the one validation of (V, F): median "
          f"{statistics.median(first_rounds):.3f} s)")


if __name__ == "__main__":
    main()
