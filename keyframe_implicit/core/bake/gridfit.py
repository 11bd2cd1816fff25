"""Choosing the grid for a set of keyframes.

The thesis samples all keyframes on one regular grid (section 2.1); the map y(x)
and the in-betweens live on the same nodes, so the grid must hold every keyframe,
every feature point and the room the motion needs, with some padding so that the
signed distance fields have a margin of positive values around the material.

`fit_grid` builds that grid from a resolution (cells along the longest side of the
box); with ``max_bytes`` it refuses a request that would not fit BEFORE any work
starts, naming the largest resolution that would (`memory`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.grid import Grid
from .options import BakeOptions
from .memory import MemoryLimitError, estimate_memory, largest_fitting, megabytes

if TYPE_CHECKING:
    from collections.abc import Iterable

    from numpy.typing import ArrayLike


__all__ = ["fit_grid", "auto_motion_resolution", "motion_grid", "one_grid_unless_smaller",
           "MIN_MOTION_RESOLUTION"]


def _points(vertex_arrays: np.ndarray | Iterable[ArrayLike],
            extra_points: ArrayLike | None) -> np.ndarray:
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


def _grid_for(lo: np.ndarray, hi: np.ndarray, resolution: int, padding_cells: int) -> Grid:
    extent = hi - lo
    h = float(extent.max()) / resolution
    cells = np.ceil(extent / h - 1e-9).astype(int)
    cells = np.maximum(cells, 1) + 2 * padding_cells
    center = (lo + hi) / 2
    origin = center - h * cells / 2
    return Grid(origin, h, tuple(int(c) + 1 for c in cells))


def fit_grid(vertex_arrays: np.ndarray | Iterable[ArrayLike], resolution: int, *,
             padding_cells: int = BakeOptions.padding_cells,
             extra_points: ArrayLike | None = None, max_bytes: int | None = None,
             **memory_options: Any) -> Grid:
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
            fits = largest_fitting(lambda r: _grid_for(lo, hi, r, padding_cells), 2,
                                   resolution - 1, max_bytes, **memory_options)
            raise MemoryLimitError(_refusal(grid, resolution, need, max_bytes, fits),
                                   need, max_bytes, fits)
    return grid


def _box_fraction(lo: np.ndarray, hi: np.ndarray, grid: Grid) -> float:
    """Material fraction guessed before any SDF exists: half the points' box (a blob
    fills about half its bounding box), relative to the grid box."""
    ext = np.maximum(hi - lo, grid.spacing)
    return float(min(1.0, 0.5 * np.prod(ext) / np.prod(grid.upper - grid.origin)))


def _refusal(grid: Grid, resolution: int, need: int, limit: int, fits: int | None) -> str:
    """`fit_grid`'s refusal: what the resolution needs, and the largest that fits."""
    shape = "x".join(str(n) for n in grid.shape)
    msg = (f"resolution {resolution} ({shape} grid) needs about {megabytes(need)} but the limit is "
           f"{megabytes(limit)}; ")
    if fits is None:
        return msg + "even the smallest resolution does not fit: raise the memory limit."
    return msg + f"the largest resolution that fits is {fits}: lower the resolution to {fits} or below."


#: The smallest Motion Resolution: coarser, a keyframe's parts are a cell or two wide.
MIN_MOTION_RESOLUTION = 8
#: Material nodes of the motion grid the automatic Motion Resolution aims at: the size at
#: which one map solve takes a couple of seconds (benchmarks/README.md, "Motion grid").
MOTION_NODES = 16_000
#: The automatic motion cell is at most this many surface cells wide: coarser, a merge's
#: or a splash's in-betweens move by more than a surface cell (benchmarks/README.md).
MAX_COARSENING = 2
#: The automatic Motion Resolution is never below this (unless Resolution is).
MIN_AUTO_MOTION = 24


def auto_motion_resolution(resolution: int, material_fraction: float, grid: Grid) -> int:
    """The Motion Resolution the bake picks: the one whose motion grid holds about
    `MOTION_NODES` nodes of the largest keyframe (``material_fraction`` of ``grid``'s box),
    but no coarser than ``resolution / MAX_COARSENING`` or `MIN_AUTO_MOTION`, and no finer
    than ``resolution``; ``resolution`` (one grid) where that motion grid would not have
    fewer nodes than ``grid`` (`one_grid_unless_smaller`)."""
    material = max(float(material_fraction) * grid.size, 1.0)
    r = int(round(resolution * (MOTION_NODES / material) ** (1.0 / grid.dim)))
    least = max(MIN_AUTO_MOTION, int(np.ceil(resolution / MAX_COARSENING)))
    return one_grid_unless_smaller(grid, resolution, int(min(resolution, max(least, r))))


def one_grid_unless_smaller(grid: Grid, resolution: int, motion_resolution: int) -> int:
    """``motion_resolution``, or ``resolution`` where the `motion_grid` it gives on ``grid``
    would have as many nodes as ``grid`` or more.

    The motion grid covers the surface grid's box and pads it with cells of its own, so a
    Motion Resolution just below Resolution (or a flat box, whose thin side the padding
    doubles) gives a motion grid larger than the surface grid: the maps then cost more than
    on one grid, and the transfer between the grids saves nothing. The automatic Motion
    Resolution and the preview's keep to one grid then.
    """
    mgrid = motion_grid(grid, resolution, motion_resolution)
    return int(resolution) if mgrid is not None and mgrid.size >= grid.size else int(motion_resolution)


def motion_grid(grid: Grid, resolution: int, motion_resolution: int,
                padding_cells: int = 2) -> Grid | None:

    """The motion grid of a bake on ``grid`` (``resolution`` cells along the longest side
    of the keyframes' box): cells ``resolution / motion_resolution`` times as large, centred
    on ``grid``'s box and covering it with ``padding_cells`` more cells on every side. None
    when the two resolutions are equal: the maps then live on ``grid`` itself."""
    if int(motion_resolution) >= int(resolution):
        return None
    spacing = grid.spacing * resolution / motion_resolution
    cells = np.ceil((grid.upper - grid.origin) / spacing - 1e-9).astype(int) + 2 * padding_cells
    centre = (grid.origin + grid.upper) / 2
    return Grid(centre - spacing * cells / 2, spacing, tuple(int(c) + 1 for c in cells))
