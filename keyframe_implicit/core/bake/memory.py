"""What a bake will cost in memory, known before any work.

`estimate_memory` predicts the peak resident memory of the whole bake on a grid (the
model is spelled out in its docstring; its constants are fitted to the peaks
`benchmarks/bench_scale.py` measured, `benchmarks/fit_memory.py` refits them), and
`check_memory` refuses a grid that would not fit, naming the largest that would.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.grid import Grid
from ..map.options import MapOptions
from ..motion.options import MotionOptions

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = ["MemoryLimitError", "estimate_memory", "active_nodes", "check_memory", "largest_fitting",
           "megabytes"]


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

    def __init__(self, message: str, required: int, limit: int,
                 max_resolution: int | None) -> None:
        super().__init__(message)
        self.required = int(required)
        self.limit = int(limit)
        self.max_resolution = max_resolution


# ---------------------------------------------------------------------------
# Peak resident set of a bake (VmHWM of the process running `animate`, plus its helper
# process's with processes=2), per process: an interpreter with numpy, scipy and
# scikit-image; per surface grid node the keyframes' distance grids, their spline
# coefficients, the in-between fields and the level-set transients; per active motion
# node the Gauss-Newton Hessian blocks (27 of 3 x 3) with their index tables and the
# trajectories' multigrid; per band node of the surface grid the transports' corners and
# lookups (the frame loop moves and reads only the band: `motion.band`). Fitted to the
# largest relative error (benchmarks/fit_memory.py) on the peaks benchmarks/bench_scale.py
# measured on its nine cases at 64 and 128 cells, on one grid and on the automatic motion
# grid; table in benchmarks/README.md. 2D: not measured; per active node scaled by the
# stencil (9 blocks of 2 x 2 against 27 of 3 x 3).
_COPIES = 2
_PROCESS_BYTES = 130.0 * 2 ** 20
_NODE_BYTES = {2: 144.7, 3: 144.7}
_MOTION_BYTES = {2: 1022.0 * 36 / 243, 3: 1022.0}
_BAND_BYTES = {2: 2213.1 * 36 / 243, 3: 2213.1}
#: Layers of the band the model counts around the surface: `MotionOptions.band_cells` on
#: each side and the surface's own.
_BAND_LAYERS = 2 * MotionOptions.band_cells + 1


def estimate_memory(grid: Grid, *, material_fraction: float | None = None, n_keyframes: int = 2,
                    margin_cells: float = MapOptions.margin_cells,
                    motion_grid: Grid | None = None) -> dict[str, int]:
    """Estimated peak resident bytes of a bake on ``grid``, before any work.

    Model (N surface grid nodes; M the motion grid's active nodes, B the surface grid's
    band nodes): ``peak = 2 (c_process + c_node N + c_motion M + c_band B)``. M counts
    the material (``material_fraction`` of the box) and a margin of ``margin_cells`` cells
    around it, on the motion grid (``grid`` without a ``motion_grid``): the maps'
    Gauss-Newton systems and the trajectories' multigrid. B counts the band the frame loop
    moves and reads (`_BAND_LAYERS` layers of a compact blob's surface, ~ N^((d-1)/d)
    nodes each) on the surface grid: the transports' corners and lookups. Two of
    everything: the Blender bake runs in a worker and its helper
    process, each solving one of a segment's two maps and holding a copy of its
    in-betweens (`chain.animate_chain` with ``processes=2``). The constants (module source)
    are fitted to measured peaks (`benchmarks/fit_memory.py`); benchmarks/bench_scale.py
    prints the estimate beside the measured peak.

    Parameters
    ----------
    grid : Grid
        The surface grid.
    material_fraction : float, optional
        Fraction of the grid box inside the largest keyframe (0..1), e.g.
        ``np.mean(phi < 0)``; default 0.25 (`fit_grid` guesses it from the box).
    n_keyframes : int
        Distance grids held at once (the per-node part grows by 8 bytes per grid).
    margin_cells : float
        Width of the margin around the material the solves also work on.
    motion_grid : Grid, optional
        The grid the maps and trajectories are solved on (`gridfit.motion_grid`).

    Returns
    -------
    dict
        ``nodes``, ``active_nodes`` (M), ``band_nodes`` (B), ``process`` (the fixed
        part), ``grid_nodes``, ``motion`` and ``band`` (the parts per node, both copies
        together), ``solves`` (those two) and ``peak``, in bytes (ints).
    """
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be a keyframe_implicit.core.Grid, got {type(grid).__name__}.")
    f = 0.25 if material_fraction is None else float(material_fraction)
    if not 0.0 <= f <= 1.0:
        raise ValueError(f"material_fraction must lie in [0, 1], got {material_fraction}.")
    N, d = grid.size, grid.dim
    P = _COPIES
    M, B = active_nodes(grid, f, margin_cells, motion_grid)
    out = {
        "nodes": int(N),
        "active_nodes": int(M),
        "band_nodes": int(B),
        "process": int(P * _PROCESS_BYTES),
        "grid_nodes": int(P * N * (_NODE_BYTES[d] + 8 * max(int(n_keyframes) - 2, 0))),
        "motion": int(P * M * _MOTION_BYTES[d]),
        "band": int(P * B * _BAND_BYTES[d]),
    }
    out["solves"] = out["motion"] + out["band"]
    out["peak"] = out["process"] + out["grid_nodes"] + out["solves"]
    return out


def active_nodes(grid: Grid, material_fraction: float,
                 margin_cells: float = MapOptions.margin_cells,
                 motion_grid: Grid | None = None) -> tuple[float, float]:
    """(M, B): the nodes the model counts on the motion grid (the maps' and trajectories'
    active nodes: a compact blob filling ``material_fraction`` of ``grid``'s box and a
    margin of ``margin_cells`` cells around it) and on the surface grid (the frame loop's
    band: `_BAND_LAYERS` layers of that blob's surface, ~ (f N)^((d-1)/d) nodes each)."""
    B = _BAND_LAYERS * _surface_nodes(grid, material_fraction)
    if motion_grid is None:
        return _blob_nodes(grid, material_fraction, margin_cells), B
    share = material_fraction * _box(grid) / _box(motion_grid)
    return _blob_nodes(motion_grid, share, margin_cells), B


def _box(grid: Grid) -> float:
    """The volume (area) of a grid's box."""
    return float(np.prod(grid.upper - grid.origin))


def _surface_nodes(grid: Grid, fraction: float) -> float:
    """Nodes of one layer around a compact blob filling ``fraction`` of the grid: a ball's
    (disc's) surface in cells."""
    N, d = grid.size, grid.dim
    return (fraction * N) ** ((d - 1) / d) * (4.84 if d == 3 else 3.55)


def _blob_nodes(grid: Grid, fraction: float, margin_cells: float) -> float:
    return min(grid.size, fraction * grid.size + 2 * margin_cells * _surface_nodes(grid, fraction))


def check_memory(grid: Grid, max_bytes: int, **memory_options: Any) -> dict[str, int]:
    """Raise `MemoryLimitError` if `estimate_memory` (grid) exceeds ``max_bytes``.

    The message names the largest grid of the same box (resolution counted along
    the longest side without padding is unknown here, so nodes along the longest
    axis are given). Use ``fit_grid(..., max_bytes=...)`` to get a resolution.
    Returns the estimate otherwise.
    """
    est = estimate_memory(grid, **memory_options)
    if est["peak"] > max_bytes:
        longest = max(grid.shape)

        def shrunk(m: int) -> Grid:  # the grid shrunk uniformly to m nodes along its longest axis
            s = m / longest
            return Grid(grid.origin, grid.spacing / s,
                        tuple(max(2, int(round(n * s))) for n in grid.shape))

        fits = largest_fitting(shrunk, 2, longest - 1, max_bytes, **memory_options)
        shape = "x".join(str(n) for n in grid.shape)
        msg = (f"a {shape} grid needs about {megabytes(est['peak'])} but the limit is {megabytes(max_bytes)}; ")
        msg += ("even the smallest grid does not fit: raise the memory limit." if fits is None else
                f"the largest that fits has {fits} nodes along its longest axis: lower the resolution.")
        raise MemoryLimitError(msg, est["peak"], max_bytes, fits)
    return est


def largest_fitting(grid_of: Callable[[int], Grid], low: int, high: int, max_bytes: int,
                    motion_of: Callable[[int, Grid], Grid | None] | None = None,
                    **memory_options: Any) -> int | None:
    """The largest size m in [low, high] whose grid ``grid_of(m)`` fits in ``max_bytes``
    (`estimate_memory`, with the motion grid ``motion_of(m, grid)`` when given), or None:
    a binary search, the estimate growing with m."""
    fits = None
    while low <= high:
        m = (low + high) // 2
        g = grid_of(m)
        if motion_of is not None:
            memory_options = dict(memory_options, motion_grid=motion_of(m, g))
        if estimate_memory(g, **memory_options)["peak"] <= max_bytes:
            fits, low = m, m + 1
        else:
            high = m - 1
    return fits


def megabytes(x: float) -> str:

    """``x`` bytes as the messages say them: "1,234 MB"."""
    return f"{x / 2 ** 20:,.0f} MB"
