#!/usr/bin/env python3
"""Poisson through an ICE coarse proxy, compared with scipy on the fine mesh, drawn with matplotlib.

    python3 poisson_picture.py [MESH] [--ratio 0.05] [-o poisson.png]

Saves a picture of the mesh coloured by the prolonged proxy solution beside its error against the
fine solution (scipy's spsolve on ICE's fine operators), and prints the sizes, times and errors.
"""
import argparse
import pathlib
import time

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import scipy.sparse.linalg  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

import ice  # noqa: E402

DEFAULT_MESH = pathlib.Path(__file__).resolve().parents[2] / "data" / "default" / "spot.obj"


def draw(axis, V, F, values, title, cmap, limits):
    """The mesh's faces coloured by the mean of `values` at their corners, seen from the front."""
    colours = plt.get_cmap(cmap)(plt.Normalize(*limits)(values[F].mean(axis=1)))
    axis.add_collection3d(Poly3DCollection(V[F], facecolors=colours, edgecolors="none"))
    low, high = V.min(axis=0), V.max(axis=0)
    centre, half = (low + high) / 2, (high - low).max() / 2
    axis.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
             zlim=(centre[2] - half, centre[2] + half), title=title)
    axis.view_init(elev=20, azim=40, vertical_axis="y")  # y up, as most scanned and modelled meshes
    axis.set_axis_off()
    plt.colorbar(plt.cm.ScalarMappable(plt.Normalize(*limits), cmap), ax=axis, shrink=0.6)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mesh", nargs="?", default=DEFAULT_MESH)
    parser.add_argument("--ratio", type=float, default=0.05)
    parser.add_argument("-o", "--output", default="poisson.png")
    args = parser.parse_args()

    V, F = ice.load_mesh(args.mesh)
    f = np.sin(4 * V[:, 0]) * np.cos(3 * V[:, 1])           # any right-hand side

    start = time.perf_counter()
    coarse = ice.coarsen(V, F, ratio=args.ratio)
    proxy = ice.Proxy(V, F, coarse)
    u = ice.ProxyPoissonSolver(proxy).solve(f)               # zero-mean Neumann, through the proxy
    proxy_seconds = time.perf_counter() - start

    # the fine solution by scipy on the same fine operators (one vertex pinned, then re-centred)
    start = time.perf_counter()
    L, M = proxy.fine_laplacian.tocsc(), proxy.fine_mass
    ones = np.ones(len(f))
    b = M @ (f - ones @ (M @ f) / (ones @ (M @ ones)))
    reference = np.zeros(len(f))
    reference[1:] = scipy.sparse.linalg.spsolve(L[1:, 1:], b[1:])
    reference -= ones @ (M @ reference) / (ones @ (M @ ones))
    fine_seconds = time.perf_counter() - start

    error = u - reference
    relative = np.sqrt(error @ (M @ error) / (reference @ (M @ reference)))
    print(f"{len(V)} vertices -> {coarse.n_vertices} coarse; proxy {proxy_seconds:.2f} s, "
          f"scipy on the fine mesh {fine_seconds:.2f} s; relative L2 error {relative:.2%}")

    figure = plt.figure(figsize=(12, 5))
    scale = np.abs(reference).max()
    draw(figure.add_subplot(1, 2, 1, projection="3d"), V, F, u,
         f"ICE proxy solution ({coarse.n_vertices} of {len(V)} vertices)", "viridis", (-scale, scale))
    bound = np.abs(error).max()
    draw(figure.add_subplot(1, 2, 2, projection="3d"), V, F, error,
         f"error against the fine solution (relative L2 {relative:.2%})", "coolwarm", (-bound, bound))
    figure.tight_layout()
    figure.savefig(args.output, dpi=120)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
