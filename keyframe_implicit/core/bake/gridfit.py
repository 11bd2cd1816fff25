"""Choosing the grid for a set of keyframes, and what a bake on it will cost in memory.

The thesis samples all keyframes on one regular grid (section 2.1); the map y(x)
and the in-betweens live on the same nodes, so the grid must hold every keyframe,
every feature point and the room the motion needs, with some padding so that the
signed distance fields have a margin of positive values around the material.

`fit_grid` builds that grid from a resolution (cells along the longest side of the
box). `estimate_memory` predicts the peak resident memory of the whole bake on a
grid (the model is spelled out in its docstring; its constants are fitted to the
peaks `benchmarks/bench_scale.py` measured), and `check_memory` /
``fit_grid(..., max_bytes=...)`` refuse a request that would not fit BEFORE any
work starts, naming the largest resolution that would.
"""

from __future__ import annotations

import numpy as np

from ..base.grid import Grid

__all__ = ["MemoryLimitError", "fit_grid", "estimate_memory", "check_memory"]


class MemoryLimitError(ValueError):
    """The requested grid would need more memory than allowed.

    Attributes
    ----------
    required : int
        Estimated peak bytes of the request.
    limit : int
        The allowed bytes.
    max_resolution : int or None
        Largest resolution (cells along the longest side) that fits, None if even
        the smallest does not.
    """

    def __init__(self, message, required, limit, max_resolution):
        super().__init__(message)
        self.required = int(required)
        self.limit = int(limit)
        self.max_resolution = max_resolution


# ---------------------------------------------------------------------------
# grid
# ---------------------------------------------------------------------------
def _points(vertex_arrays, extra_points):
    if isinstance(vertex_arrays, np.ndarray) and vertex_arrays.dtype != object and vertex_arrays.ndim == 2:
        vertex_arrays = [vertex_arrays]
    arrays = []
    for i, v in enumerate(list(vertex_arrays)):  # a handful of keyframes
        a = np.asarray(v, dtype=float)
        if a.ndim != 2 or a.shape[1] not in (2, 3):
            raise ValueError(f"keyframe {i} vertices must have shape (N, 2) or (N, 3), got {a.shape}.")
        arrays.append(a)
    if not arrays or all(len(a) == 0 for a in arrays):
        raise ValueError("no keyframe vertices given; pass one (N, d) vertex array per keyframe.")
    dims = {a.shape[1] for a in arrays}
    if len(dims) > 1:
        raise ValueError(f"keyframes mix 2D and 3D vertices (dimensions {sorted(dims)}); use one.")
    d = dims.pop()
    if extra_points is not None:
        e = np.asarray(extra_points, dtype=float).reshape(-1, d) if np.size(extra_points) else None
        if e is not None:
            arrays.append(e)
    pts = np.concatenate(arrays)
    if not np.all(np.isfinite(pts)):
        raise ValueError("keyframe vertices or feature points contain NaN or infinity; fix them first.")
    return pts


def _grid_for(lo, hi, resolution, padding_cells):
    extent = hi - lo
    h = float(extent.max()) / resolution
    cells = np.ceil(extent / h - 1e-9).astype(int)
    cells = np.maximum(cells, 1) + 2 * padding_cells
    center = (lo + hi) / 2
    origin = center - h * cells / 2
    return Grid(origin, h, tuple(int(c) + 1 for c in cells))


def fit_grid(vertex_arrays, resolution, *, padding_cells=4, extra_points=None, max_bytes=None,
             **memory_options):
    """Grid holding all keyframes (and extra points), with cubic cells and padding.

    Parameters
    ----------
    vertex_arrays : sequence of (N_i, d) array_like, or one (N, d) array
        Vertices of every keyframe (d = 2 or 3 decides the grid's dimension).
    resolution : int
        Cells along the longest side of the bounding box (before padding), >= 2.
    padding_cells : int
        Empty cells added on every side (the SDF needs positive values around the
        material; the motion may need room).
    extra_points : (M, d) array_like, optional
        More points the box must hold (feature points, points along the motion).
    max_bytes : int, optional
        Refuse (`MemoryLimitError`) before any work if `estimate_memory` says the
        bake needs more; the message names the largest resolution that fits.
    **memory_options
        Passed to `estimate_memory` (e.g. ``material_fraction``; by default half
        the points' bounding box relative to the grid box).

    Returns
    -------
    Grid
        Box centred on the points' bounding box; its longest side spans
        ``resolution + 2 * padding_cells`` cells.
    """
    if isinstance(resolution, bool) or not float(resolution).is_integer() or resolution < 2:
        raise ValueError(f"resolution must be a whole number of cells >= 2, got {resolution!r}.")
    if isinstance(padding_cells, bool) or not float(padding_cells).is_integer() or padding_cells < 0:
        raise ValueError(f"padding_cells must be a whole number >= 0, got {padding_cells!r}.")
    resolution, padding_cells = int(resolution), int(padding_cells)
    pts = _points(vertex_arrays, extra_points)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    if not (hi - lo).max() > 0:
        raise ValueError("all keyframe vertices coincide; the bounding box has no size.")
    grid = _grid_for(lo, hi, resolution, padding_cells)
    if max_bytes is not None and memory_options.get("material_fraction") is None:
        memory_options["material_fraction"] = _box_fraction(lo, hi, grid)
    if max_bytes is not None:
        need = estimate_memory(grid, **memory_options)["peak"]
        if need > max_bytes:
            fits = None
            a, b = 2, resolution - 1  # binary search over resolutions (a handful of steps)
            while a <= b:
                m = (a + b) // 2
                g = _grid_for(lo, hi, m, padding_cells)
                if estimate_memory(g, **memory_options)["peak"] <= max_bytes:
                    fits, a = m, m + 1
                else:
                    b = m - 1
            raise MemoryLimitError(_refusal(grid, resolution, need, max_bytes, fits),
                                   need, max_bytes, fits)
    return grid


def _box_fraction(lo, hi, grid):
    """Material fraction guessed before any SDF exists: half the points' box (a blob
    fills about half its bounding box), relative to the grid box."""
    ext = np.maximum(hi - lo, grid.spacing)
    return float(min(1.0, 0.5 * np.prod(ext) / np.prod(grid.upper - grid.origin)))


def _mb(x):
    return f"{x / 2 ** 20:,.0f} MB"


def _refusal(grid, resolution, need, limit, fits):
    shape = "x".join(str(n) for n in grid.shape)
    msg = (f"resolution {resolution} ({shape} grid) needs about {_mb(need)} but the limit is "
           f"{_mb(limit)}; ")
    if fits is None:
        return msg + "even the smallest resolution does not fit: raise the memory limit."
    return msg + f"the largest resolution that fits is {fits}: lower the resolution to {fits} or below."


# ---------------------------------------------------------------------------
# memory model
# ---------------------------------------------------------------------------
# Peak resident set of a bake (VmHWM of the process running `animate`, plus its helper
# process's with processes=2), per process: an interpreter with numpy, scipy and
# scikit-image; per grid node the keyframes' distance grids, their spline coefficients,
# the maps, the in-between fields and the level-set transients; per active solver node
# the Gauss-Newton Hessian blocks (27 of 3 x 3) with their index tables, and the
# trajectories' multigrid. Fitted to the largest relative error (benchmarks/fit_memory.py)
# on the peaks benchmarks/bench_scale.py measured on its seven cases at 64 and 128 cells
# and two of them (bend, morph) at 256; tables in benchmarks/README.md.
# 2D: not measured; per active node scaled by the stencil (9 blocks of 2 x 2 against 27
# of 3 x 3).
_COPIES = 2
_PROCESS_BYTES = 106.9 * 2 ** 20
_NODE_BYTES = {2: 194.5, 3: 194.5}
_ACTIVE_BYTES = {2: 2285.3 * 36 / 243, 3: 2285.3}


def estimate_memory(grid: Grid, *, material_fraction=None, n_keyframes=2, margin_cells=3):
    """Estimated peak resident bytes of a bake on ``grid``, before any work.

    Model (N grid nodes, M active solver nodes):
    ``peak = 2 (c_process + c_node N + c_active M)``, with M = the material
    (``material_fraction * N``) plus the map's margin of ``margin_cells`` around it
    (a compact blob's surface ~ N^((d-1)/d)). Two of everything: the Blender bake runs
    in a worker and its helper process, each solving one of a segment's two maps and
    holding a copy of its in-betweens (`chain.animate_chain` with ``processes=2``); in
    one process the two maps are solved in two threads at once. The constants (module
    source) are fitted to measured peaks; benchmarks/bench_scale.py prints the estimate
    beside the measured peak.

    Parameters
    ----------
    grid : Grid
    material_fraction : float, optional
        Fraction of the grid inside the largest keyframe (0..1), e.g.
        ``np.mean(phi < 0)``; default 0.25 (`fit_grid` guesses it from the box).
    n_keyframes : int
        Distance grids held at once (the per-node part grows by 8 bytes per grid).
    margin_cells : float
        Width of the map's margin around the material the solver also works on.

    Returns
    -------
    dict
        ``nodes``, ``active_nodes``, ``process`` (the fixed part), ``grid_nodes`` and
        ``active`` (the parts per node and per active node, both copies together) and
        ``peak``, in bytes (ints).
    """
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be a keyframe_implicit.core.Grid, got {type(grid).__name__}.")
    f = 0.25 if material_fraction is None else float(material_fraction)
    if not 0.0 <= f <= 1.0:
        raise ValueError(f"material_fraction must lie in [0, 1], got {material_fraction}.")
    N, d = grid.size, grid.dim
    P = _COPIES
    # margin nodes around a compact blob holding f * N nodes: its surface ~ (f N)^((d-1)/d)
    surface = (f * N) ** ((d - 1) / d) * (4.84 if d == 3 else 3.55)  # sphere / disc
    M = min(N, f * N + 2 * margin_cells * surface)
    out = {
        "nodes": int(N),
        "active_nodes": int(M),
        "process": int(P * _PROCESS_BYTES),
        "grid_nodes": int(P * N * (_NODE_BYTES[d] + 8 * max(int(n_keyframes) - 2, 0))),
        "active": int(P * M * _ACTIVE_BYTES[d]),
    }
    out["peak"] = out["process"] + out["grid_nodes"] + out["active"]
    return out


def check_memory(grid: Grid, max_bytes, **memory_options):
    """Raise `MemoryLimitError` if `estimate_memory` (grid) exceeds ``max_bytes``.

    The message names the largest grid of the same box (resolution counted along
    the longest side without padding is unknown here, so nodes along the longest
    axis are given). Use ``fit_grid(..., max_bytes=...)`` to get a resolution.
    Returns the estimate otherwise.
    """
    est = estimate_memory(grid, **memory_options)
    if est["peak"] > max_bytes:
        longest = max(grid.shape)
        fits = None
        a, b = 2, longest - 1
        while a <= b:  # shrink the grid uniformly (a handful of steps)
            m = (a + b) // 2
            s = m / longest
            g = Grid(grid.origin, grid.spacing / s,
                     tuple(max(2, int(round(n * s))) for n in grid.shape))
            if estimate_memory(g, **memory_options)["peak"] <= max_bytes:
                fits, a = m, m + 1
            else:
                b = m - 1
        shape = "x".join(str(n) for n in grid.shape)
        msg = (f"a {shape} grid needs about {_mb(est['peak'])} but the limit is {_mb(max_bytes)}; ")
        msg += ("even the smallest grid does not fit: raise the memory limit." if fits is None else
                f"the largest that fits has {fits} nodes along its longest axis: lower the resolution.")
        raise MemoryLimitError(msg, est["peak"], max_bytes, fits)
    return est
