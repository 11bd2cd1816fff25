"""Benchmark of mesh_to_sdf: seconds for a 20k-triangle mesh at 64^3 and 128^3.

Prints, per grid size: wall seconds (best of --repeat), seconds per step, band
nodes, and the largest distance error on a random subset of band nodes against a
brute-force reference (every node against every triangle), in cells.

Targets (2 cores): 64^3 <= 1 s, 128^3 <= 5 s.

    python benchmarks/bench_sdf.py [--sizes 64,128] [--repeat 3] [--check 2000]
"""

import argparse
import time

import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from keyframe_implicit.core import Grid, mesh_to_sdf
from keyframe_implicit.shapes import icosphere
from keyframe_implicit.core.fields.triangles import point_triangle_distance
from keyframe_implicit.core.fields.winding import winding_number


def noisy_sphere(n_sub=5, radius=1.0, noise=0.03, seed=0):
    """Icosphere (20 * 4**n_sub triangles; 20480 for n_sub=5) with radial noise."""
    v, f = icosphere(n_sub)
    rng = np.random.default_rng(seed)
    # smooth-ish bumps plus per-vertex noise
    bumps = 0.08 * np.sin(5 * v[:, 0]) * np.cos(4 * v[:, 1]) * np.sin(3 * v[:, 2] + 1)
    r = radius * (1 + bumps + noise * rng.standard_normal(len(v)))
    return v * r[:, None], f


def brute_force(points, v, f, chunk=200):
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        p = points[s:s + chunk]
        P, T = len(p), len(f)
        pp = np.repeat(p, T, axis=0)
        t = np.tile(np.arange(T), P)
        out[s:s + chunk] = point_triangle_distance(pp, v[f[t, 0]], v[f[t, 1]], v[f[t, 2]]) \
            .reshape(P, T).min(axis=1)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="64,128")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--check", type=int, default=2000, help="band nodes checked by brute force")
    args = ap.parse_args()
    v, f = noisy_sphere()
    print(f"mesh: {len(v)} vertices, {len(f)} triangles (noisy icosphere)")
    lo, hi = v.min(0), v.max(0)
    rng = np.random.default_rng(1)
    for n in (int(s) for s in args.sizes.split(",")):
        h = (hi - lo).max() / (n - 9)  # 4 cells of padding on each side
        grid = Grid((lo + hi) / 2 - h * (n - 1) / 2, h, (n, n, n))
        best, stats = np.inf, None
        for _ in range(args.repeat):
            st = {}
            t0 = time.perf_counter()
            d = mesh_to_sdf(v, f, grid, stats=st)
            dt = time.perf_counter() - t0
            if dt < best:
                best, stats = dt, st
        band = np.flatnonzero(np.abs(d).reshape(-1) <= 3 * h)
        pick = rng.choice(band, size=min(args.check, len(band)), replace=False)
        pts = grid.points().reshape(-1, 3)[pick]
        ref = brute_force(pts, v, f)
        err = np.abs(np.abs(d.reshape(-1)[pick]) - ref).max() / h
        w = winding_number(v, f, pts, beta=1e9)  # exact winding numbers as sign reference
        sign_bad = int(np.sum((d.reshape(-1)[pick] < 0) != (w >= 0.5)))
        steps = ", ".join(f"{k[8:]} {stats[k]:.2f}" for k in stats if k.startswith("seconds_")
                          and k != "seconds_total" and k != "seconds_sign")
        print(f"{n}^3: {best:.2f} s (best of {args.repeat}; {steps}); band nodes "
              f"{stats['shell_nodes']}, winding evaluations {stats['winding_nodes']}; max |error| on "
              f"{len(pick)} band nodes vs brute force {err:.2e} h, sign errors {sign_bad}")


if __name__ == "__main__":
    main()
