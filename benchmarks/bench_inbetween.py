"""Benchmark of the in-between stage: trajectories, 24 level sets, surfaces, template.

Usage (from the repository root):

    python benchmarks/bench_inbetween.py            # 64^3 and 128^3, each in its own process
    python benchmarks/bench_inbetween.py --n 64     # one size
    python benchmarks/bench_inbetween.py --method idw

The map is analytic (the rigid L-shape of tests/core/inbetween_cases.py turned
90 degrees about a tilted axis and translated) unless ``--solver`` is given, in
which case it comes from `solve_map` with four feature points. Prints seconds
per stage, the zero-set error against the exact turned solid, and the peak
resident memory of the process. Target: level sets + surfaces + template for
24 frames at 64^3 within 5 s on 2 cores.

Measured on the shared 2-core machine (load 4-7 from other jobs, figures noisy),
analytic map: 64^3 (10.8k active nodes) 1.96 s for the 24 frames (trajectories
0.54, level sets 0.80, surfaces 0.11, template 0.51) + 0.41 s setup, peak 539 MB;
128^3 (54k active nodes) 19.2 s (trajectories 10.7 -- the back-substitution of
the 27M-entry factor, 0.45 s a frame -- level sets 5.4, surfaces 0.7, template
2.3) + 4.6 s setup, peak 1.37 GB. Zero-set error 0.016 h (64^3) / 0.018 h
(128^3) mean. ``--method idw``: level sets 5.8 s at 64^3, error 0.065 h.
"""

from __future__ import annotations

import argparse
import pathlib
import resource
import subprocess
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "core"))


def _frame_pass(ib, grid, times, info):
    """One pass over the frames, as the pipeline makes them (trajectories, level set,
    surface, template step: track_template's loop body), timed stage by stage; with each
    frame's zero-set error against the exact turned solid and the template's |phi|."""
    from inbetween_cases import rigid_expected
    from keyframe_implicit.core.surface.extract import extract_surface
    from keyframe_implicit.core.surface.template import project_to_zero_set

    h = grid.spacing
    V0, F0 = extract_surface(ib.levelset(0.0), grid)
    ib._cache.clear()
    stage = dict(trajectories=0.0, levelset=0.0, surface=0.0, template=0.0)
    errs, phis = [], []
    for s in times:
        t1 = time.perf_counter()
        ib.trajectories.positions(s)
        t2 = time.perf_counter()
        ls = ib.levelset(s)
        t3 = time.perf_counter()
        V, F = extract_surface(ls, grid)
        t4 = time.perf_counter()
        p = ib.trajectory(V0, s)
        p, err = project_to_zero_set(p, ls, grid)
        t5 = time.perf_counter()
        stage["trajectories"] += t2 - t1
        stage["levelset"] += t3 - t2
        stage["surface"] += t4 - t3
        stage["template"] += t5 - t4
        errs.append(np.abs(rigid_expected(V, s, info)).mean() / h)
        phis.append(err.max() / h)
    return V0, F0, stage, errs, phis


def run(n, frames, method, solver):
    from inbetween_cases import rigid_case
    from keyframe_implicit.core.bake.maps import inbetween
    from keyframe_implicit.core.motion.levelset import Inbetween
    from keyframe_implicit.core.surface.template import track_template

    t = time.perf_counter()
    grid, phi_a, phi_b, mapped, info = rigid_case(n=n)
    print(f"grid {grid.shape}, h = {grid.spacing:.4g}; analytic keyframes "
          f"{time.perf_counter() - t:.2f} s")
    t = time.perf_counter()
    if solver:
        c = info["centroid"]
        fa = c + np.array([[0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.2], [-0.3, -0.2, 0.0]])
        fb = c + info["t"] + (fa - c) @ info["R"].T
        ib = inbetween(phi_a, phi_b, grid, fa, fb, resample=method)
        print(f"solve_map                 {ib.stats['map_seconds']:7.2f} s")
    else:
        ib = Inbetween.from_map(phi_a, phi_b, grid, mapped, resample=method)
    setup = time.perf_counter() - t - ib.stats.get("map_seconds", 0.0)
    ts = ib.trajectories.stats
    print(f"trajectory setup          {setup:7.2f} s   (setup {ts.get('setup_seconds', 0):.2f} s, "
          f"{ts.get('active_nodes', 0)} active nodes, multigrid levels {ts.get('multigrid_levels')})")
    times = np.linspace(0.0, 1.0, frames)
    V0, F0, stage, errs, phis = _frame_pass(ib, grid, times, info)
    for k, v in stage.items():
        print(f"{frames} x {k:<22s}{v:7.2f} s")
    total = sum(stage.values())
    print(f"TOTAL level sets + surfaces + template ({frames} frames): {total:.2f} s"
          f"   (+ trajectory setup {setup:.2f} s once)")
    print(f"template: {len(V0)} vertices, {len(F0)} faces, max |phi| {max(phis):.3f} h")
    t = time.perf_counter()
    sub = times[:: max(1, frames // 4)]
    tr = track_template(ib, sub, coverage=True)
    print(f"track_template with coverage on {len(sub)} frames: {time.perf_counter() - t:.2f} s "
          f"(uncovered fraction max {max(tr.stats['uncovered_fraction']):.4f})")
    print(f"zero-set error vs exact turned solid: mean {np.mean(errs):.3f} h, "
          f"worst frame {np.max(errs):.3f} h")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"peak resident memory {peak:.0f} MB")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=None, help="nodes per side (default: 64 and 128)")
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--method", default="lookup", choices=["lookup", "idw"])
    ap.add_argument("--solver", action="store_true", help="solve the map instead of the analytic one")
    args = ap.parse_args()
    if args.n is None:
        for n in (64, 128):
            print(f"=== {n}^3 ===", flush=True)
            cmd = [sys.executable, __file__, "--n", str(n), "--frames", str(args.frames),
                   "--method", args.method] + (["--solver"] if args.solver else [])
            subprocess.run(cmd, check=True)
        return
    run(args.n, args.frames, args.method, args.solver)


if __name__ == "__main__":
    main()
