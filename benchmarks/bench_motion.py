"""The motion grid against the full-resolution one: what the in-betweens lose.

For each case of `cases.py` (the splash pair by pair), the in-betweens are made twice,
with the maps and trajectories on the surface grid and on the motion grid the bake
would choose (`gridfit.auto_motion_resolution`, or ``--motion``), and compared frame by
frame (9 frames a pair, s = 0 ... 1):

- the two-way distance between the two surfaces, mean and max, in surface cells h;
- the volume drift of each (as `compare.py`);
- spurious pieces, and how many times the number of pieces changes;
- the rigid case: the mean distance of the half-way surface to the exact turned solid;
- seconds of each (maps and in-betweens).

    python benchmarks/bench_motion.py --sizes 96
    python benchmarks/bench_motion.py --sizes 64 --cases rigid merge --motion 24
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.dirname(HERE), HERE]


def inbetweens(case, k, times, motion_grid):
    """Pair ``k``'s frames (level sets at ``times``) and seconds, on one motion grid."""
    from keyframe_implicit.core import inbetween

    (fa, fb), phi_a, phi_b = case.features[k], case.fields[k], case.fields[k + 1]
    t0 = time.perf_counter()
    ib = inbetween(phi_a, phi_b, case.grid, fa, fb, motion_grid=motion_grid)
    frames = [np.asarray(ib.levelset(s), float) for s in times]
    return frames, time.perf_counter() - t0


def two_way(frame_a, frame_b, grid):
    """Mean and max two-way distance (h) between the zero sets of two fields."""
    from keyframe_implicit.core import extract_surface
    from keyframe_implicit.core.surface.quality import mesh_distance

    va, fa = extract_surface(frame_a, grid)
    vb, fb = extract_surface(frame_b, grid)
    if len(fa) == 0 or len(fb) == 0:
        return (0.0, 0.0) if len(fa) == len(fb) else (np.inf, np.inf)
    d = np.concatenate([mesh_distance(va, vb, fb), mesh_distance(vb, va, fa)]) / grid.spacing
    return float(d.mean()), float(d.max())


def run_case(name, n, motion):
    """The figures of one case at ``n`` nodes a side."""
    import cases
    import metrics
    from keyframe_implicit.core.bake import gridfit

    case = cases.make_case(name, n)
    grid = case.grid
    resolution = max(grid.shape) - 1
    fraction = max(float(np.mean(f < 0)) for f in case.fields)
    m = gridfit.auto_motion_resolution(resolution, fraction, grid) if motion == "auto" else int(motion)
    mg = gridfit.motion_grid(grid, resolution, m)
    times = np.linspace(0.0, 1.0, 9)
    out = dict(case=name, n=n, motion=m, motion_shape=None if mg is None else list(mg.shape),
               mean_h=0.0, max_h=0.0, seconds={"full": 0.0, "motion": 0.0}, drift={},
               spurious={}, changes={})
    for k in range(len(case.features)):
        runs = {}
        for label, g in (("full", None), ("motion", mg)):
            frames, sec = inbetweens(case, k, times, g)
            runs[label] = frames
            out["seconds"][label] += sec
            v = [metrics.volume(f, grid) for f in frames]
            vkey = (metrics.volume(case.fields[k], grid), metrics.volume(case.fields[k + 1], grid))
            out["drift"][label] = max(out["drift"].get(label, 0.0),
                                      metrics.volume_drift(v, times, vkey))
            pieces = [metrics.components(f) for f in frames]
            out["spurious"][label] = max(out["spurious"].get(label, 0), metrics.spurious_components(
                pieces, case.expected_components[k], case.expected_components[k + 1]))
            out["changes"][label] = out["changes"].get(label, 0) + int(np.count_nonzero(np.diff(pieces)))
            if case.truth is not None:
                out[f"truth_mean_h_{label}"] = metrics.surface_error(
                    frames[4], grid, lambda p: case.truth(p, 0.5))[0]
        for fa_, fb_ in zip(runs["full"], runs["motion"]):
            mean, mx = two_way(fa_, fb_, grid)
            out["mean_h"], out["max_h"] = max(out["mean_h"], mean), max(out["max_h"], mx)
    return out


def print_table(rows):
    print(f"{'case':>7} {'n':>4} {'motion':>6} {'mean h':>7} {'max h':>6} {'drift full':>10} "
          f"{'drift mot':>9} {'spur':>5} {'changes':>8} {'rigid h':>12} {'s full':>7} {'s mot':>6}")
    for r in rows:
        rigid = (f"{r['truth_mean_h_full']:.3f}/{r['truth_mean_h_motion']:.3f}"
                 if "truth_mean_h_full" in r else "-")
        print(f"{r['case']:>7} {r['n']:>4} {r['motion']:>6} {r['mean_h']:>7.3f} {r['max_h']:>6.2f} "
              f"{100 * r['drift']['full']:>9.2f}% {100 * r['drift']['motion']:>8.2f}% "
              f"{r['spurious']['full']}/{r['spurious']['motion']:<3} "
              f"{r['changes']['full']:>3}/{r['changes']['motion']:<4} {rigid:>12} "
              f"{r['seconds']['full']:>7.1f} {r['seconds']['motion']:>6.1f}")


def main():
    import cases
    from bench_scale import run_rows

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[96])
    ap.add_argument("--cases", nargs="+", default=list(cases.CASE_NAMES), choices=cases.CASE_NAMES)
    ap.add_argument("--motion", default="auto", help='"auto" or a Motion Resolution')
    ap.add_argument("--json", help="also write the rows to this file")
    args = ap.parse_args()
    run_rows(args.sizes, args.cases, lambda name, n: run_case(name, n, args.motion), print_table,
             args.json)


if __name__ == "__main__":
    main()
