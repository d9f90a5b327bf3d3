#!/usr/bin/env python3
"""What calling ICE through its Python package adds: the same operations from C++ and from Python.

    PYTHONPATH=build/release/python python3 bench/python_overhead.py \
        --parity build/release/bench/python-parity [MESH] [--subdivide 1] [--rounds 7]

Each round runs the C++ program python-parity once (the library calls alone, timed inside the
process) and then the same operations through the package (timed the same way: perf_counter around
each call, the conversions and checks included); rounds alternate so both see the same machine
noise. Prints the median seconds of each operation on both sides and their ratio Python / C++.
Default input: data/default/armadillo.off Loop-subdivided once (104k vertices).
"""
import argparse
import json
import pathlib
import statistics
import subprocess
import time

import numpy as np

import ice

ROOT = pathlib.Path(__file__).resolve().parents[1]
OPERATIONS = ["coarsen", "proxy", "poisson_setup", "poisson_solve", "geodesic_setup", "geodesic_solve"]


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
    start = time.perf_counter()
    poisson.solve(f)
    times["poisson_solve"] = time.perf_counter() - start
    start = time.perf_counter()
    geodesic = ice.ProxyGeodesicSolver(proxy)
    times["geodesic_setup"] = time.perf_counter() - start
    start = time.perf_counter()
    geodesic.distance([0])
    times["geodesic_solve"] = time.perf_counter() - start
    return times, coarse.n_vertices


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mesh", nargs="?", default=ROOT / "data" / "default" / "armadillo.off")
    parser.add_argument("--parity", default=ROOT / "build" / "release" / "bench" / "python-parity")
    parser.add_argument("--subdivide", type=int, default=1)
    parser.add_argument("--ratio", type=float, default=0.05)
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()

    V, F = ice.load_mesh(args.mesh)
    V, F = ice.loop_subdivide(V, F, args.subdivide)
    f = np.sin(3 * V[:, 0]) + V[:, 1]
    cpp, python = {op: [] for op in OPERATIONS}, {op: [] for op in OPERATIONS}
    # Both sides warm: the C++ process times its second round (its first pays the thread pools'
    # start, first-touch page faults, ...), and this process runs one untimed round first, which also
    # validates (V, F) once (later calls find its fingerprint: module.cpp, CleanMeshes).
    start = time.perf_counter()
    python_round(V, F, f, args.ratio)
    first_round = time.perf_counter() - start
    for _ in range(args.rounds):
        out = subprocess.run([str(args.parity), str(args.mesh), "--subdivide", str(args.subdivide),
                              "--ratio", str(args.ratio), "--rounds", "2"], capture_output=True, text=True,
                             check=True).stdout
        row = json.loads(out.splitlines()[-1])
        assert row["vertices"] == len(V)
        for op in OPERATIONS:
            cpp[op].append(row[op])
        times, coarse_vertices = python_round(V, F, f, args.ratio)
        assert coarse_vertices == row["coarse_vertices"]
        for op in OPERATIONS:
            python[op].append(times[op])

    print(f"{args.mesh} x{args.subdivide} Loop: {len(V)} vertices -> {row['coarse_vertices']} coarse, "
          f"{args.rounds} interleaved rounds, medians")
    print(f"{'operation':16} {'C++ s':>9} {'Python s':>9} {'Python/C++':>11}")
    total_cpp = total_python = 0.0
    for op in OPERATIONS:
        a, b = statistics.median(cpp[op]), statistics.median(python[op])
        total_cpp, total_python = total_cpp + a, total_python + b
        print(f"{op:16} {a:9.4f} {b:9.4f} {b / a:11.3f}")
    print(f"{'sum of medians':16} {total_cpp:9.4f} {total_python:9.4f} {total_python / total_cpp:11.3f}")
    print(f"(the untimed first Python round, with the one validation of (V, F): {first_round:.3f} s)")


if __name__ == "__main__":
    main()
