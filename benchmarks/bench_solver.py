"""Benchmark of the volume map (`keyframe_implicit.core.solve_map`).

Sphere (radius 0.3 in the unit box) -> equal-volume ellipsoid (semi-axes
0.3 * (1.3, 1/sqrt 1.3, 1/sqrt 1.3)), 6 feature points at the poles, on
n^3 grids. Prints active nodes, unknowns, seconds per stage, Gauss-Newton
iterations (finest level, and per level), min det F, max |det F - 1|, the
feature residual and peak memory (resource.getrusage ru_maxrss of this
process: the peak resident set size, includes the Python interpreter and
the input grids).

    python benchmarks/bench_solver.py                 # 32 48 64 96 128
    python benchmarks/bench_solver.py --sizes 32 64
    python benchmarks/bench_solver.py --region        # 2D merge, margin weight 0 / 0.1 / 1
    python benchmarks/bench_solver.py --features --sizes 64 128   # det F near features

Each size runs in its own process so that peak memory is per size.

Measured 2026-11-22 04:19 UTC on the shared 2-core machine (load average
3-5 from other jobs, so times are inflated; run it again on a quiet machine):

    n^3   active   unknowns  total s  assembly  lin.solve  line search  GN it (levels)        min detF  max|detF-1|  peak MiB
    32     9328     26886     1.34      0.35      0.65       0.20        32:2                  0.877     0.086         150
    48    23672     67182     2.77      1.07      0.85       0.46        25:2 48:2             0.869     0.105         225
    64    48416    136446     6.33      2.39      1.80       1.21        33:4 64:2             0.841     0.120         382
    96   140624    395286    15.72      3.49      6.18       3.71        25:4 49:2 96:2        0.809     0.129         901
    128  306504    863046    45.67     11.78     16.52       8.34        33:2 65:2 128:2       0.792     0.129        1894

Feature residual below 3e-14 h everywhere.

After ``patch_rigidity`` = 10 (04:40 UTC, load average 0.5): 32^3 0.75 s, 4 GN
iterations, min det F 0.797 (0.45 s, 2 iterations, 0.877 with factor 1 in
the same run); 64^3 3.28 s, min det F 0.824 (3.27 s, 0.841 with factor 1).
Targets (2-core machine): 32^3 <= 1 s, 64^3 <= 5 s, 96^3 <= 25 s,
128^3 <= 2 min, peak memory <= 3 GB.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from keyframe_implicit.core import Grid, solve_map  # noqa: E402
from keyframe_implicit.core.base import elements  # noqa: E402
from keyframe_implicit.core.base.sampling import sample  # noqa: E402


def ellipsoid_sdf(P, c, ax):
    """Approximate signed distance of an axis-aligned ellipsoid (exact on the surface)."""
    q = (P - c) / ax
    k0 = np.linalg.norm(q, axis=-1)
    k1 = np.linalg.norm((P - c) / ax ** 2, axis=-1)
    return k0 * (k0 - 1) / np.maximum(k1, 1e-12)


def sphere_case(n):
    g = Grid((0.0, 0.0, 0.0), 1.0 / (n - 1), (n, n, n))
    P = g.points()
    c = np.array([0.5, 0.5, 0.5])
    phi_a = np.linalg.norm(P - c, axis=-1) - 0.3
    ax = np.array([1.3, 1 / np.sqrt(1.3), 1 / np.sqrt(1.3)]) * 0.3
    phi_b = ellipsoid_sdf(P, c, ax)
    dirs = np.vstack([np.eye(3), -np.eye(3)])
    return g, phi_a, phi_b, c + 0.3 * dirs, c + ax * dirs


def run_one(n):
    g, phi_a, phi_b, fa, fb = sphere_case(n)
    t0 = time.perf_counter()
    res = solve_map(phi_a, phi_b, g, fa, fb)
    wall = time.perf_counter() - t0
    s = res.stats
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB -> MiB on Linux
    return dict(n=n, wall=wall, active=s["active_nodes"], unknowns=s["unknowns"],
                iterations=s["iterations"], levels=[(lv["shape"][0], lv["iterations"], lv["cg_iterations"])
                                                    for lv in s["levels"]],
                min_det=s["min_det"], max_det_dev=s["max_abs_det_minus_1"],
                residual_h=s["feature_residual_h"], seconds=s["seconds"], peak_mib=peak,
                terms=s["terms"])


def region_measure(n=48):
    """2D merge (two discs -> one disc of the same area): band weight 0 / 0.1 / 1."""
    from scipy.spatial import cKDTree
    g = Grid((0.0, 0.0), 1.0 / (n - 1), (n, n))
    h = g.spacing
    P = g.points()
    c, r1, s = np.array([0.5, 0.5]), 0.16, 0.18
    R = r1 * np.sqrt(2)
    phi_a = np.minimum(np.linalg.norm(P - (c - [s, 0]), axis=-1) - r1,
                       np.linalg.norm(P - (c + [s, 0]), axis=-1) - r1)
    phi_b = np.linalg.norm(P - c, axis=-1) - R
    fa, fb = [], []
    for side in (-1, 1):
        fa += [[.5 + side * (s - r1), .5], [.5 + side * (s + r1), .5], [.5 + side * s, .5 + r1],
               [.5 + side * s, .5 - r1]]
        fb += [[.5 + side * 0.015, .5], [.5 + side * R, .5], [.5 + side * 0.04, .5 + 0.96 * R],
               [.5 + side * 0.04, .5 - 0.96 * R]]
    fa, fb = np.array(fa), np.array(fb)
    cs = elements.corners(2)
    cshape = (n - 1, n - 1)
    centre = sum(phi_a[tuple(slice(o, o + m) for o, m in zip(cc, cshape))] for cc in cs) / 4
    base = np.argwhere(centre < 0)
    nodes = base[:, None, :] + cs[None]
    G = np.concatenate([elements.quadrature(2, h, "gauss").G, elements.quadrature(2, h, "centre").G])
    print(f"2D merge, {n}x{n} grid, margin_cells=3, default weights")
    print(f"{'margin_weight':>11} {'min detF':>9} {'in[.8,1.25]':>11} {'mapped>h/2 out of B':>19} "
          f"{'B uncovered(>h)':>15} {'levelset term':>13} {'rigidity':>9} {'s':>5}")
    for bw in (0.0, 0.1, 1.0):
        t0 = time.perf_counter()
        res = solve_map(phi_a, phi_b, g, fa, fb, margin_weight=bw)
        sec = time.perf_counter() - t0
        Y = res.mapped[tuple(nodes[..., a] for a in range(2))]
        det = elements.determinant(elements.deformation_gradient(Y, G))
        inr = np.mean((det[:, -1] >= 0.8) & (det[:, -1] <= 1.25))
        ym = res.mapped[phi_a < 0]
        out = np.mean(sample(phi_b, g, ym, outside="distance") > 0.5 * h)
        dist, _ = cKDTree(ym).query(P[phi_b < -0.5 * h])
        unc = np.mean(dist > h)
        print(f"{bw:>11} {det.min():>9.3f} {inr:>11.3f} {out:>19.3f} {unc:>15.3f} "
              f"{res.stats['terms']['levelset']:>13.4f} {res.stats['terms']['rigidity']:>9.4f} {sec:>5.2f}")


def feature_measure(sizes):
    """min det F near the feature points: affine patches (default) vs plain hard constraints."""
    print("sphere -> ellipsoid, min det F over material cells within 0.1 of a feature point")
    print(f"{'n':>4} {'patch (default)':>15} {'hard (feature_radius=0)':>23}")
    for n in sizes:
        g, phi_a, phi_b, fa, fb = sphere_case(n)
        h = g.spacing
        cs = elements.corners(3)
        cshape = (n - 1,) * 3
        centre = sum(phi_a[tuple(slice(o, o + m) for o, m in zip(cc, cshape))] for cc in cs) / 8
        base = np.argwhere(centre < 0)
        near = np.min(np.linalg.norm(g.to_world(base + 0.5)[:, None] - fa[None], axis=-1), axis=1) < 0.1
        nodes = base[near][:, None, :] + cs[None]
        G = np.concatenate([elements.quadrature(3, h, "gauss").G, elements.quadrature(3, h, "centre").G])
        row = []
        for radius in (None, 0.0):
            res = solve_map(phi_a, phi_b, g, fa, fb, feature_radius=radius)
            Y = res.mapped[tuple(nodes[..., a] for a in range(3))]
            row.append(elements.determinant(elements.deformation_gradient(Y, G)).min())
        print(f"{n:>4} {row[0]:>15.3f} {row[1]:>23.3f}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 48, 64, 96, 128])
    ap.add_argument("--region", action="store_true", help="run the integration-region measurement")
    ap.add_argument("--features", action="store_true",
                    help="min det F near feature points, patches vs hard constraints, at --sizes")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one)))
        return
    if args.region:
        region_measure()
        return
    if args.features:
        feature_measure(args.sizes)
        return
    print("sphere r=0.3 -> equal-volume ellipsoid, 6 pole features; peak = ru_maxrss of the run's process")
    print(f"{'n':>4} {'active':>8} {'unknowns':>9} {'total s':>8} {'initial':>7} {'setup':>6} {'assemb':>6} "
          f"{'linsolve':>8} {'lsearch':>7} {'GN it':>5} {'levels (n,it,cg)':>26} {'min detF':>8} "
          f"{'max|detF-1|':>11} {'resid/h':>8} {'peak MiB':>8}")
    for n in args.sizes:
        out = subprocess.run([sys.executable, os.path.abspath(__file__), "--one", str(n)],
                             capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        s = r["seconds"]
        lv = " ".join(f"({a},{b},{c})" for a, b, c in r["levels"])
        print(f"{n:>4} {r['active']:>8} {r['unknowns']:>9} {r['wall']:>8.2f} {s['initial map']:>7.2f} "
              f"{s['setup']:>6.2f} {s['assembly']:>6.2f} {s['linear solve']:>8.2f} {s['line search']:>7.2f} "
              f"{r['iterations']:>5} {lv:>26} {r['min_det']:>8.3f} {r['max_det_dev']:>11.3f} "
              f"{r['residual_h']:>8.1e} {r['peak_mib']:>8.0f}", flush=True)


if __name__ == "__main__":
    main()
