"""The map solved coarse to fine: the nested grids, the keyframes' fields and the start
map on a coarser grid, and each level's correction carried to the next finer one
(docs/method.md, section 4).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from ..base.grid import Grid
from ..base.sampling import sample
from .system import det_floor

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from .options import MapOptions
    from .system import MapSystem

__all__ = ["coarse_to_fine", "fields_on", "start_map", "correction", "prolong", "extend"]


def extend(full: np.ndarray, known: np.ndarray, passes: int) -> np.ndarray:
    """Fill nodes where ``known`` is False smoothly from the known ones (nearest + smoothing)."""
    if np.all(known):
        return full
    _, idx = ndimage.distance_transform_edt(~known, return_indices=True)
    out = full[tuple(idx)]
    unknown = ~known
    d = full.shape[-1]
    for _ in range(passes):
        for j in range(d):
            sm = ndimage.uniform_filter(out[..., j], size=3, mode="nearest")
            out[..., j][unknown] = sm[unknown]
    return out


def prolong(field: ArrayLike, shape: tuple[int, ...]) -> np.ndarray:
    """Multilinear prolongation from a level of spacing 2h onto the nested level of spacing h.

    Coarse node k sits on fine node 2k (same origin), so per axis fine 2k takes
    coarse k and fine 2k+1 the mean of coarse k and k+1; the result is cropped
    to ``shape``. Equal to multilinear sampling, without per-point work.
    """
    out = np.asarray(field, dtype=float)
    for a, n in enumerate(shape):
        m = out.shape[a]
        up = np.empty(out.shape[:a] + (2 * m - 1,) + out.shape[a + 1:])
        even = [slice(None)] * out.ndim
        odd = [slice(None)] * out.ndim
        even[a] = slice(0, None, 2)
        odd[a] = slice(1, None, 2)
        lo = [slice(None)] * out.ndim
        hi = [slice(None)] * out.ndim
        lo[a] = slice(0, m - 1)
        hi[a] = slice(1, m)
        up[tuple(even)] = out
        up[tuple(odd)] = 0.5 * (out[tuple(lo)] + out[tuple(hi)])
        crop = [slice(None)] * out.ndim
        crop[a] = slice(0, n)
        out = up[tuple(crop)]
    return out


def coarse_to_fine(grid: Grid, coarse_nodes: int) -> list[Grid]:
    """The grids of the hierarchy, coarsest first, ending with ``grid``: each coarser one
    has twice the spacing and the same origin, while it keeps ``coarse_nodes`` per side."""
    grids = [grid]
    while True:
        g = grids[-1]
        shape = tuple(int(np.ceil((n - 1) / 2)) + 1 for n in g.shape)
        if min(shape) < coarse_nodes:
            break
        grids.append(Grid(g.origin, 2 * g.spacing, shape))
    return grids[::-1]


def fields_on(phi_a: np.ndarray, phi_b: np.ndarray, disp0: np.ndarray, grid: Grid,
              g: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The keyframes' fields and the start map on the coarse grid ``g``: (pa, pb, base)."""
    pts = g.points()
    return (sample(phi_a, grid, pts, outside="distance"), sample(phi_b, grid, pts, outside="distance"),
            pts + sample(disp0, grid, pts))


def correction(system: MapSystem, y: np.ndarray, y_start_full: np.ndarray, base: np.ndarray,
               passes: int) -> np.ndarray:
    """The level's solution as a correction of its start map ``base`` on every node of
    its grid: solved on the active nodes, extended beyond them (`extend`)."""
    g, d = system.grid, system.d
    full = y_start_full.reshape(-1, d).copy()
    full[system.active] = y
    known = np.zeros(g.size, dtype=bool)
    known[system.active] = True
    corr = (full - base.reshape(-1, d)).reshape(g.shape + (d,))
    return extend(corr, known.reshape(g.shape), passes)


def start_map(system: MapSystem, base: np.ndarray, corr_prev: np.ndarray | None,
              options: MapOptions) -> tuple[np.ndarray, np.ndarray]:
    """Start of one level: its base map plus as much of the coarser level's correction,
    prolonged onto this level (``corr_prev``, this level's shape; None: none), as keeps
    the material's det F at ``min_det`` (or at the base's own minimum, if lower).

    The correction comes from coarser cells and is extended past their region, so at
    the finer level's material boundary it can fold cells the coarse level never saw;
    it is halved until it does not. Returns the start on every node and on the active ones.
    """
    d, chunk = system.d, int(options.chunk_elements)

    def start(scale: float) -> tuple[np.ndarray, np.ndarray]:

        full = base if scale == 0 else base + scale * corr_prev
        return full, system.cons.enforce(full.reshape(-1, d)[system.active])

    full, y = start(0.0)
    if corr_prev is None:
        return full.copy(), y
    floor = det_floor(system.det_stats(y, chunk), options.min_det)
    for scale in (1.0, 0.5, 0.25, 0.125):
        full_s, y_s = start(scale)
        if det_floor(system.det_stats(y_s, chunk), options.min_det) >= floor:
            return full_s, y_s
    return full.copy(), y
