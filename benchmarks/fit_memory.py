"""Fit `gridfit.estimate_memory`'s constants to the peak resident sets `bench_scale.py` measured.

    python benchmarks/bench_scale.py --sizes 64 128 192 --json rows.json
    python benchmarks/fit_memory.py rows.json [more.json ...]

The model: peak = processes * (c_process + c_node * N + c_active * M), N the grid's
nodes and M the solver's active nodes as the model itself predicts them from the
material fraction (``model_active``; what `estimate_memory` can know before any
work). The three constants minimise the relative error (non-negative least squares
on rows divided by the measured peak). Prints them, then every row's measured peak,
the fitted model's and the current model's, and the largest relative error.
"""

from __future__ import annotations

import json
import sys

import numpy as np
from scipy.optimize import nnls

MIB = 2 ** 20


def fit(rows, processes=2):
    """(c_process, c_node, c_active) in bytes, fitted to the rows' measured peaks."""
    A = processes * np.array([[1.0, r["nodes"], r["model_active"]] for r in rows])
    y = np.array([r["rss_mb"] * MIB for r in rows])
    coef, _ = nnls(A / y[:, None], np.ones(len(y)))
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
