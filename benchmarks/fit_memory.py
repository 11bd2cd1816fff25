"""Fit `memory.estimate_memory`'s constants to the peak resident sets `bench_scale.py` measured.

    python benchmarks/bench_scale.py --sizes 64 128 192 --json rows.json
    python benchmarks/fit_memory.py rows.json [more.json ...]

The model: peak = processes * (c_process + c_node * N + c_active * M), N the grid's
nodes and M the solver's active nodes as the model itself predicts them from the
material fraction (``model_active``; what `estimate_memory` can know before any
work). The three constants (non-negative) minimise the largest relative error over
the rows, a linear programme: the model is held to a bound on every case (15 % is the
target), which a least-squares fit trades against the rows' mean. Prints them,
then every row's measured peak, the fitted model's and the current model's, and the
largest relative error.
"""

from __future__ import annotations

import json
import sys

import numpy as np
from scipy.optimize import linprog

MIB = 2 ** 20


def fit(rows, processes=2):
    """(c_process, c_node, c_active) in bytes, fitted to the rows' measured peaks: the
    smallest t with |model / peak - 1| <= t on every row. Returns them and the model's
    peaks."""
    A = processes * np.array([[1.0, r["nodes"], r["model_active"]] for r in rows])
    y = np.array([r["rss_mb"] * MIB for r in rows])
    ratio = A / y[:, None]
    unit = np.array([MIB, 100.0, 1000.0])  # unknowns of order one: MiB, 100 B, 1000 B
    m = len(rows)
    # variables (c / unit, t): minimise t subject to ratio c - 1 <= t and 1 - ratio c <= t
    lhs = np.block([[ratio * unit, -np.ones((m, 1))], [-ratio * unit, -np.ones((m, 1))]])
    rhs = np.concatenate([np.ones(m), -np.ones(m)])
    res = linprog(np.r_[0.0, 0.0, 0.0, 1.0], A_ub=lhs, b_ub=rhs, bounds=[(0, None)] * 4)
    if not res.success:
        raise SystemExit(f"the fit failed: {res.message}")
    coef = res.x[:3] * unit
    return coef, A @ coef


def main(paths):
    rows = [r for p in paths for r in json.load(open(p)) if "error" not in r and "nodes" in r]
    if len(rows) < 3:
        raise SystemExit("need at least three measured rows with 'nodes' and 'model_active'")
    coef, model = fit(rows)
    print(f"c_process = {coef[0] / MIB:.1f} MiB, c_node = {coef[1]:.1f} B, "
          f"c_active = {coef[2]:.1f} B")
    print(f"{'case':>9} {'n':>4} {'nodes':>10} {'active':>9} {'RSS MiB':>8} {'fit MiB':>8} "
          f"{'was MiB':>8} {'fit err':>8}")
    worst = 0.0
    for r, m in zip(rows, model):
        err = m / (r["rss_mb"] * MIB) - 1.0
        worst = max(worst, abs(err))
        print(f"{r['case']:>9} {r['n']:>4} {r['nodes']:>10} {r['model_active']:>9} "
              f"{r['rss_mb']:>8.0f} {m / MIB:>8.0f} {r['estimate_mb']:>8.0f} {100 * err:>7.1f}%")
    print(f"largest relative error of the fit: {100 * worst:.1f} %")


if __name__ == "__main__":
    main(sys.argv[1:])
