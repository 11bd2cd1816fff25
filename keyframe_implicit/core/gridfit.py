"""Choosing the grid for a set of keyframes, and what a bake on it will cost in memory.

The thesis samples all keyframes on one regular grid (section 2.1); the map y(x)
and the in-betweens live on the same nodes, so the grid must hold every keyframe,
every feature point and the room the motion needs, with some padding so that the
signed distance fields have a margin of positive values around the material.

`fit_grid` builds that grid from a resolution (cells along the longest side of the
box). `estimate_memory` predicts the peak memory of the whole bake on a grid from
array sizes (the model is spelled out in its docstring; its constants were fitted
to tracemalloc peaks of `mesh_to_sdf`, `solve_map` and `animate`, and the tests
check the solver and whole-bake figures at two sizes), and `check_memory` /
``fit_grid(..., max_bytes=...)`` refuse a request that would not fit BEFORE any
work starts, naming the largest resolution that would.
"""

from __future__ import annotations

import numpy as np

from .grid import Grid
from .renamed import take_renamed

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
# Signed distance stage (mesh_to_sdf): per grid node the unsigned and signed
# float64 fields, EDT distances and nearest-node indices, labels, masks; plus the
# chunked exact-distance work (candidate tables of sdf._CHUNK nodes, winding-number pair
# lists), bounded independently of the grid. Measured with tracemalloc on a
# 5120-triangle sphere: 64 / 89 / 115 / 145 MB at 41^3 / 57^3 / 73^3 / 105^3 nodes;
# this model gives 70 / 76 / 86 / 123 MB.
_SDF_BYTES_PER_NODE = {2: 40, 3: 48}
_SDF_FIXED = 64 * 2 ** 20
# Solver (solve_map, default options): fixed + per grid node (per dimension) + per
# active node (material of A plus its margin: the 3**d-block stencil Hessian, the
# neighbour tables, gradient and CG vectors over all levels). Fitted to tracemalloc
# peaks of solve_map on a sphere -> ellipsoid case (tests/core/test_gridfit.py):
# measured 99 / 141 / 203 / 437 MB at 33^3 / 41^3 / 49^3 / 65^3 nodes, this model
# (with the measured material fraction) 93 / 141 / 212 / 434 MB. 2D: the same
# per-node cost, per-active scaled by the stencil size (9 vs 27 blocks of d x d),
# not measured.
_SOLVER_BYTES_PER_NODE_PER_DIM = 45
_SOLVER_BYTES_PER_ACTIVE = {2: 1000, 3: 4600}
_SOLVER_FIXED = 43_400_000
# In-between stage (levelset.Inbetween.from_map: trajectories over A's material
# plus a 4-cell margin, whose Laplacian is factored once with scipy's splu, then the
# level sets and the template): per node plus a fill-in term c * M_t ** p, M_t the
# trajectory nodes. p = 4/3 is the fill growth of a sparse 3D factorisation with a
# good ordering; c fitted to tracemalloc peaks of the whole `animate` (two UV
# spheres, tests/core/test_pipeline.py case, 5 frames) at resolution 32 / 48 / 64 / 80
# (45,920 / 117,648 / 240,462 / 428,802 nodes): measured 91 / 346 / 808 / 1,662 MB,
# this model 95 / 330 / 808 / 1,662 MB. 2D: linear guess, not measured.
_INBETWEEN_BYTES_PER_NODE = {2: 64, 3: 44}
_INBETWEEN_FILL = {2: (2000.0, 1.0), 3: (330.0, 4.0 / 3.0)}  # bytes * M_t ** power
_TRAJECTORY_MARGIN_CELLS = 4.0
# The two-sided in-betweens solve two maps at once (on two cores) and hold two
# transports, each with its trajectories' factor. Refitted to the tracemalloc peaks of the
# same `animate` case (two-sided transport, one surface per frame) at resolution 32 / 48 /
# 64: measured 137 / 261 / 541 MB, this model 142 / 271 / 539 MB. The two solves do not
# peak together (1.5 times one solve), and the factors' fill is 0.62 of the one-sided fit.
_CONCURRENT_SOLVES = 1.5
_TRANSPORT_FILL = 0.62


def estimate_memory(grid: Grid, *, material_fraction=None, n_keyframes=2, margin_cells=3,
                    **renamed):
    """Estimated peak bytes of a bake on ``grid``, per stage, from array sizes.

    Model (N = grid nodes, d = dimension, M = active solver nodes):

    - ``keyframes``: the distance grids kept for the whole bake, ``n_keyframes * N * 8``;
    - ``sdf``: transient arrays of one `mesh_to_sdf` call, ``N * c_sdf(d) + c_chunk``;
    - ``solver``: one map, ``N * d * c_node + M * c_active(d)``, M =
      ``material_fraction * N`` plus the map's margin of ``margin_cells`` around the
      material (surface ~ N^((d-1)/d));
    - ``inbetween``: ``N * c_node(d) + 0.62 c_fill * M_t ** p``, M_t the trajectory
      nodes of one keyframe (material plus a 4-cell margin), p = 4/3 in 3D (sparse LU
      fill-in); one factor per keyframe.

    The constants (module source) were fitted to tracemalloc peaks; the solver part
    is checked to stay within 30 % of `solve_map`'s measured peak by the tests.

    Stages run one after another while the keyframe grids stay, so
    ``peak = keyframes + max(sdf, 1.5 solver, inbetween)`` (two maps solved at once).

    Parameters
    ----------
    grid : Grid
    material_fraction : float, optional
        Fraction of the grid inside keyframe A (0..1), e.g. ``np.mean(phi_a < 0)``;
        default 0.25 (a fitted grid around one compact object; `fit_grid` guesses
        it from the keyframes' box).
    n_keyframes : int
        Distance grids held at once.
    margin_cells : float
        Width of the map's margin around the material the solver also works on.

    Returns
    -------
    dict
        ``nodes``, ``active_nodes``, ``keyframes``, ``sdf``, ``solver``,
        ``inbetween`` and ``peak``, in bytes (ints).
    """
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be a keyframe_implicit.core.Grid, got {type(grid).__name__}.")
    f = 0.25 if material_fraction is None else float(material_fraction)
    if not 0.0 <= f <= 1.0:
        raise ValueError(f"material_fraction must lie in [0, 1], got {material_fraction}.")
    renamed = take_renamed(dict(renamed), {"band_cells": "margin_cells"}, "estimate_memory")
    margin_cells = renamed.pop("margin_cells", margin_cells)
    if renamed:
        raise TypeError(f"estimate_memory got unexpected options {sorted(renamed)}.")
    N, d = grid.size, grid.dim
    # margin nodes around a compact blob holding f * N nodes: its surface ~ (f N)^((d-1)/d)
    surface = (f * N) ** ((d - 1) / d) * (4.84 if d == 3 else 3.55)  # sphere / disc
    M = min(N, f * N + 2 * margin_cells * surface)
    M_t = min(N, f * N + 2 * _TRAJECTORY_MARGIN_CELLS * surface)
    fill, power = _INBETWEEN_FILL[d]
    out = {
        "nodes": int(N),
        "active_nodes": int(M),
        "keyframes": int(n_keyframes * N * 8),
        "sdf": int(N * _SDF_BYTES_PER_NODE[d] + _SDF_FIXED),
        "solver": int(N * d * _SOLVER_BYTES_PER_NODE_PER_DIM + M * _SOLVER_BYTES_PER_ACTIVE[d]
                      + _SOLVER_FIXED),
        "inbetween": int(N * _INBETWEEN_BYTES_PER_NODE[d] + _TRANSPORT_FILL * fill * M_t ** power),
    }
    out["peak"] = out["keyframes"] + int(max(out["sdf"], _CONCURRENT_SOLVES * out["solver"],
                                             out["inbetween"]))
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
