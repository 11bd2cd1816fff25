"""Fit `memory.estimate_memory`'s constants to the peak resident sets `bench_scale.py` measured.

    python benchmarks/bench_scale.py --sizes 64 128 --json full.json --motion full
    python benchmarks/bench_scale.py --sizes 64 128 --json auto.json
    python benchmarks/fit_memory.py full.json auto.json

The model: peak = processes * (c_process + c_node N + c_motion M + c_band B), N the
surface grid's nodes, M the motion grid's active nodes and B the surface grid's band
nodes, as the model itself predicts them from the material fraction
(`memory.active_nodes`: what it can know before any work). The four constants
(non-negative) minimise the largest relative error over the rows, a linear programme:
the model is held to a bound on every case (15 % is the target), which a least-squares
fit trades against the rows' mean. Prints them, then every row's measured peak, the
fitted model's and the current model's, and the largest relative error.
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np
from scipy.optimize import linprog

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

MIB = 2 ** 20


def counts(row):
    """(N, M, B) of a row: its grid rebuilt from its shape (the counts do not depend on the
    spacing), its motion grid from its Motion Resolution."""
    from keyframe_implicit.core import Grid
    from keyframe_implicit.core.bake.gridfit import motion_grid
    from keyframe_implicit.core.bake.memory import active_nodes

    grid = Grid((0.0,) * len(row["shape"]), 1.0, tuple(row["shape"]))
    motion = motion_grid(grid, row["n"], row.get("motion", row["n"]))
    M, B = active_nodes(grid, row["material_fraction"], motion_grid=motion)
    return grid.size, M, B


def fit(rows, processes=2):
    """(c_process, c_node, c_motion, c_band) in bytes, fitted to the rows' measured peaks:
    the smallest t with |model / peak - 1| <= t on every row. Returns them and the
    model's peaks."""
    A = processes * np.array([[1.0, *counts(r)] for r in rows])
    y = np.array([r["rss_mb"] * MIB for r in rows])
    ratio = A / y[:, None]
    unit = np.array([MIB, 100.0, 1000.0, 1000.0])  # unknowns of order one
    m, k = len(rows), len(unit)
    # variables (c / unit, t): minimise t subject to ratio c - 1 <= t and 1 - ratio c <= t
    lhs = np.block([[ratio * unit, -np.ones((m, 1))], [-ratio * unit, -np.ones((m, 1))]])
    rhs = np.concatenate([np.ones(m), -np.ones(m)])
    res = linprog(np.r_[np.zeros(k), 1.0], A_ub=lhs, b_ub=rhs, bounds=[(0, None)] * (k + 1))
    if not res.success:
        raise SystemExit(f"the fit failed: {res.message}")
    coef = res.x[:k] * unit
    return coef, A @ coef


def main(paths):
    rows = [r for p in paths for r in json.load(open(p)) if "error" not in r and "nodes" in r]
    if len(rows) < 4:
        raise SystemExit("need at least four measured rows")
    coef, model = fit(rows)
    print(f"c_process = {coef[0] / MIB:.1f} MiB, c_node = {coef[1]:.1f} B, "
          f"c_motion = {coef[2]:.1f} B, c_band = {coef[3]:.1f} B")
    print(f"{'case':>9} {'n':>4} {'motion':>6} {'nodes':>10} {'RSS MiB':>8} {'fit MiB':>8} "
          f"{'was MiB':>8} {'fit err':>8}")
    worst = 0.0
    for r, m in zip(rows, model):
        err = m / (r["rss_mb"] * MIB) - 1.0
        worst = max(worst, abs(err))
        print(f"{r['case']:>9} {r['n']:>4} {r.get('motion', r['n']):>6} {r['nodes']:>10} "
              f"{r['rss_mb']:>8.0f} {m / MIB:>8.0f} {r['estimate_mb']:>8.0f} {100 * err:>7.1f}%")
    print(f"largest relative error of the fit: {100 * worst:.1f} %")


if __name__ == "__main__":
    main(sys.argv[1:])
