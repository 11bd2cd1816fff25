"""Choosing the grid for a set of keyframes.

The thesis samples all keyframes on one regular grid (section 2.1); the map y(x)
and the in-betweens live on the same nodes, so the grid must hold every keyframe,
every feature point and the room the motion needs, with some padding so that the
signed distance fields have a margin of positive values around the material.

`fit_grid` builds that grid from a resolution (cells along the longest side of the
keyframes' box); with ``max_bytes`` it refuses a request that would not fit BEFORE any
work starts, naming the largest resolution that would (`memory`).

Every grid sits on a lattice in world space, as OpenVDB's index space does: its spacing
is a step of a fixed ladder (`lattice_spacing`) and its origin a whole multiple of its
spacing. A grid changes only when the box it must hold reaches into another lattice cell
(or the keyframes' size into another step of the ladder): an Empty dragged within a cell,
or a keyframe nudged by less than one, leaves the grids (and so everything computed on
them) as they were.
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


__all__ = ["fit_grid", "lattice_spacing", "lattice_grid", "auto_motion_resolution",
           "motion_grid", "one_grid_unless_smaller", "MIN_MOTION_RESOLUTION", "LATTICE_STEPS"]

#: Steps of the spacing ladder per doubling (`lattice_spacing`): a spacing is 2**(k / 8)
#: for a whole k, so the cells along the keyframes' longest side are within 4.4 % of the
#: Resolution asked for.
LATTICE_STEPS = 8


def _points(vertex_arrays: np.ndarray | Iterable[ArrayLike],
            extra_points: ArrayLike | None) -> tuple[np.ndarray, np.ndarray]:
    """(the keyframes' vertices, those and the extra points), checked, one array each."""
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
    keyframes = np.concatenate(arrays)
    if extra_points is not None and np.size(extra_points):
        arrays.append(np.asarray(extra_points, dtype=float).reshape(-1, d))
    pts = np.concatenate(arrays)
    if not np.all(np.isfinite(pts)):
        raise ValueError("keyframe vertices or feature points contain NaN or infinity; fix them first.")
    return keyframes, pts


def lattice_spacing(extent: float, resolution: int) -> float:
    """The spacing of a grid with ``resolution`` cells along ``extent`` (world units): the
    step of the ladder 2**(k / `LATTICE_STEPS`) nearest to ``extent / resolution`` (in
    ratio). A fixed ladder, not the ratio itself, so that a small change of ``extent``
    (a keyframe nudged, a rounding) leaves the spacing, and the lattice, as it was."""
    k = round(np.log2(float(extent) / resolution) * LATTICE_STEPS)
    return float(2.0 ** (k / LATTICE_STEPS))


def lattice_grid(lo: ArrayLike, hi: ArrayLike, spacing: float, padding_cells: int) -> Grid:
    """The grid on the lattice of ``spacing`` (nodes at whole multiples of it in world space)
    holding the box ``lo``..``hi`` with ``padding_cells`` more cells on every side: the
    lattice nodes at or below ``lo`` and at or above ``hi``, at least one cell apart."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    first = np.floor(lo / spacing)
    first -= first * spacing > lo  # where the division rounded up onto the next node
    last = np.ceil(hi / spacing)
    last += last * spacing < hi
    last = np.maximum(last, first + 1)
    first, last = first - padding_cells, last + padding_cells
    return Grid(first * spacing, spacing, tuple(int(n) + 1 for n in last - first))


def _grid_for(lo: np.ndarray, hi: np.ndarray, extent: float, resolution: int,
              padding_cells: int) -> Grid:
    return lattice_grid(lo, hi, lattice_spacing(extent, resolution), padding_cells)


def fit_grid(vertex_arrays: np.ndarray | Iterable[ArrayLike], resolution: int, *,
             padding_cells: int = BakeOptions.padding_cells,
             extra_points: ArrayLike | None = None, max_bytes: int | None = None,
             **memory_options: Any) -> Grid:
    """Grid holding all keyframes (and extra points), with cubic cells and padding, on the
    lattice of its spacing (`lattice_grid`).

    Parameters
    ----------
    vertex_arrays : sequence of (N_i, d) array_like, or one (N, d) array
        Vertices of every keyframe (d = 2 or 3 decides the grid's dimension).
    resolution : int
        Cells along the longest side of the keyframes' bounding box (before padding), >= 2,
        to the nearest step of the spacing ladder (`lattice_spacing`). The extra points
        widen the box but not the cells: moving one leaves the spacing as it was.
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
        The lattice nodes around the points' bounding box, ``padding_cells`` more on every
        side; the origin a whole multiple of the spacing.
    """
    if isinstance(resolution, bool) or not float(resolution).is_integer() or resolution < 2:
        raise ValueError(f"resolution must be a whole number of cells >= 2, got {resolution!r}.")
    if isinstance(padding_cells, bool) or not float(padding_cells).is_integer() or padding_cells < 0:
        raise ValueError(f"padding_cells must be a whole number >= 0, got {padding_cells!r}.")
    resolution, padding_cells = int(resolution), int(padding_cells)
    keyframes, pts = _points(vertex_arrays, extra_points)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    extent = float(np.ptp(keyframes, axis=0).max())
    if not extent > 0:
        raise ValueError("all keyframe vertices coincide; the bounding box has no size.")
    grid = _grid_for(lo, hi, extent, resolution, padding_cells)
    if max_bytes is not None and memory_options.get("material_fraction") is None:
        memory_options["material_fraction"] = _box_fraction(lo, hi, grid)
    if max_bytes is not None:
        need = estimate_memory(grid, **memory_options)["peak"]
        if need > max_bytes:
            fits = largest_fitting(lambda r: _grid_for(lo, hi, extent, r, padding_cells), 2,
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
    of the keyframes' box): cells ``resolution / motion_resolution`` times as large, on the
    lattice of that spacing (`lattice_grid`), covering ``grid``'s box with ``padding_cells``
    more cells on every side. None when the two resolutions are equal: the maps then live
    on ``grid`` itself."""
    if int(motion_resolution) >= int(resolution):
        return None
    spacing = grid.spacing * resolution / motion_resolution
    return lattice_grid(grid.origin, grid.upper, spacing, padding_cells)
