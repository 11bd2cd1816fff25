"""The narrow band: the part of a keyframe's region a transport moves and reads each frame.

A transport's frame costs an inverse lookup and a cubic read per node its moved
region reaches (`transport`), so a frame over the whole region grows with the
keyframe's volume. Only the values near the in-between's zero set shape it; deep
inside, the sign is all the surface, the volume and the components need
(docs/method.md, section 15). Each region cell is therefore one of:

- **band**: its values may come within ``depth`` of the surface: moved and read;
- **deep**: every value it can carry is at most ``-depth`` (the carried value of a
  node is at most max(f, g(y)), `transport.Transport.carry`): not moved;
- **beyond**: every value it can carry is at least the truncation ``w``: not moved,
  as "not reached" already reads as ``w``.

The moved band is a shell at least ``depth`` thick around the deep cells, without holes
(moved cells share faces), so the nodes it does not reach split into pockets: those
open to the outside, and those it encloses. An enclosed pocket whose rim carries
negative values is the deep material's image (`inside`): its nodes take ``-depth``,
an upper bound of their true values, so the blend there is at least as high as the
dense one. The band changes nothing as long as no such node touches a cell the final
zero set crosses, which `touches_surface` checks on every frame (`levelset.Inbetween`
then redoes the frame on the whole region).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..base.grid import Grid
from .tension import CELLS_PER_TENSION, GAUSSIAN_TRUNCATE

__all__ = ["Band", "band_depth", "inside", "touches_surface"]

#: Cells of slack on a cell's bounds: how far a cubic read between its corners may stray
#: from the corners' range.
SLACK_CELLS = 0.5
#: A deep node this far under the final zero set, in cells, lies on no cell the zero set
#: crosses while the field climbs less than this over a cell's diagonal (a distance
#: field's climbs sqrt(3) cells at most); closer ones have their neighbours checked.
_CLEAR_CELLS = 3.0


@dataclass(frozen=True)
class Band:
    """The region cells a transport moves each frame, and which of them it reads.

    Attributes
    ----------
    cells : (C,) int
        The moved cells, as indices into the transport's region cells.
    nodes : (N,) int
        Their corner nodes, as indices into the region's corner nodes.
    local : (C, 2^d) int
        Each moved cell's corners as indices into ``nodes``.
    deep : bool
        Whether the region has deep cells (not moved; the nodes they cover take ``-depth``,
        `inside`).
    depth : float
        The band's depth inside the material (world units; inf: the whole region, read).
    """

    cells: np.ndarray
    nodes: np.ndarray
    local: np.ndarray
    deep: bool
    depth: float

    @classmethod
    def whole(cls, corner_local: np.ndarray) -> Band:
        """Every region cell, moved and read (``corner_local``: the region's (C, 2^d))."""
        count = len(corner_local)
        return cls(np.arange(count), np.arange(int(corner_local.max(initial=-1)) + 1),
                   corner_local, False, np.inf)

    @classmethod
    def of(cls, corner_local: np.ndarray, lower: np.ndarray, upper: np.ndarray,
           truncation: float, depth: float, h: float) -> Band:
        """The band of a region whose carried values lie in [``lower``, ``upper``] at its
        corner nodes (``corner_local`` the cells' corners as rows of those), for a field
        truncated at ``truncation``, ``depth`` deep (world units, grid spacing ``h``)."""
        if not np.isfinite(depth):
            return cls.whole(corner_local)
        slack = SLACK_CELLS * h
        low = lower[corner_local].min(axis=1)
        high = upper[corner_local].max(axis=1)
        deep = high <= -(depth + slack)
        cells = np.flatnonzero((low < truncation + slack) & ~deep)
        used = corner_local[cells]
        nodes, local = np.unique(used, return_inverse=True)
        return cls(cells, nodes, local.reshape(used.shape).astype(np.int32),
                   bool(deep.any()), float(depth))


def inside(carried: np.ndarray, grid: Grid) -> np.ndarray:
    """The nodes a band encloses that its carried values (flat, NaN where not reached)
    mark as inside: bool, flat.

    Within the box of the reached nodes (one node wider, so that the outside is one
    pocket around them), the pockets of unreached nodes that do not touch the box's
    faces are inside where the reached nodes on their rim are mostly negative.
    """
    flat = carried.reshape(-1)
    reached = np.flatnonzero(~np.isnan(flat))
    out = np.zeros(flat.size, bool)
    if reached.size == 0:
        return out
    index = np.unravel_index(reached, grid.shape)
    box = tuple(slice(max(int(i.min()) - 1, 0), min(int(i.max()) + 2, n))
                for i, n in zip(index, grid.shape))
    values = flat.reshape(grid.shape)[box]
    pockets, count = ndimage.label(np.isnan(values))
    if count == 0:
        return out
    rim = np.zeros(count + 1)
    for a in range(grid.dim):  # each pocket's rim: its reached neighbours along each axis
        lo = [slice(None)] * grid.dim
        hi = [slice(None)] * grid.dim
        lo[a], hi[a] = slice(None, -1), slice(1, None)
        for p, v in ((pockets[tuple(lo)], values[tuple(hi)]),
                     (pockets[tuple(hi)], values[tuple(lo)])):
            edge = (p > 0) & ~np.isnan(v)
            rim += np.bincount(p[edge], weights=np.sign(v[edge]), minlength=count + 1)
    open_ = np.zeros(count + 1, bool)
    for a in range(grid.dim):  # pockets on the box's faces open to the outside
        for end in (0, -1):
            open_[np.take(pockets, end, axis=a)] = True
    enclosed = (rim < 0) & ~open_
    enclosed[0] = False
    out.reshape(grid.shape)[box] = enclosed[pockets]
    return out


def band_depth(cells: float, grid: Grid, tension: float, parts: bool) -> float:
    """The band's depth (world units) for ``cells`` asked: deeper where the surface
    tension's Gaussian (`tension.fill_creases`, sigma = ``tension`` x its cells, read to
    `tension.GAUSSIAN_TRUNCATE` sigmas) may reach deep values, i.e. where a keyframe has
    several ``parts``."""
    if parts and tension > 0:
        cells = max(cells, GAUSSIAN_TRUNCATE * tension * CELLS_PER_TENSION + 1.0)
    return float(cells) * grid.spacing


def touches_surface(field: np.ndarray, deep: np.ndarray, grid: Grid) -> bool:
    """Whether a node that took the band's deep value (``deep``, bool over the grid,
    `inside`) is not under the zero set of ``field`` or lies on a cell the zero set
    crosses: then the band's bound may have moved the surface or the volume, and the frame
    needs the whole region.
    """
    flat = field.reshape(-1)
    nodes = np.flatnonzero(deep.reshape(-1))
    values = flat[nodes]
    if np.any(values >= 0):
        return True
    near = nodes[values > -_CLEAR_CELLS * grid.spacing]
    if near.size == 0:
        return False
    index = np.stack(np.unravel_index(near, grid.shape), axis=-1)
    shape = np.asarray(grid.shape)
    steps = np.array(list(itertools.product((-1, 0, 1), repeat=grid.dim)))  # the 3^d around
    around = np.clip(index[:, None, :] + steps[None], 0, shape - 1)
    return bool(np.any(flat[np.ravel_multi_index(tuple(np.moveaxis(around, -1, 0)),
                                                 grid.shape)] >= 0))
