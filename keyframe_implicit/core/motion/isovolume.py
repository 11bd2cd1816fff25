"""The iso-value that gives an in-between the volume it should have.

Each transport of the two-sided in-betweens (`levelset`) keeps its own
keyframe's volume, as far as its map does (the volume term of eq. 2.6), but a
blend of two signed distance fields whose shapes differ does not: it loses
volume where they are offset and gains it where one has a part the other has
not yet. The thesis promises volume; so each in-between is shifted by one
iso-value c(s), L_s - c(s), chosen so that the enclosed volume is the linear
interpolation (1 - s) V_A + s V_B of the keyframes' volumes. A uniform shift
moves the whole surface along its normals by about c (a distance field has
unit gradient), i.e. it is the least change of shape that fixes the volume.

Volumes are those of the surface the artist gets (`surface.extract.enclosed_volume`,
marching cubes of the field). The root is found by a few secant-like steps:
the change of volume with c comes from a smoothed Heaviside of L / |grad L|
on the grid (cheap, monotone in c; solved by safeguarded Newton), the volume
itself from one surface per step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from scipy import ndimage
from skimage.segmentation import expand_labels

from ..base.grid import Grid
from ..surface.extract import enclosed_volume
from .components import sub_grid

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["volume_iso_value", "component_iso_values"]

_CHUNK = 1 << 18  # nodes per gradient chunk (bounds the index temporaries)


def volume_iso_value(field: ArrayLike, grid: Grid, target: float, *, rtol: float = 1e-3,
                     max_steps: int = 3, max_cells: float = 3.0) -> tuple[float, float]:
    """The iso-value with ``enclosed_volume(field - iso_value) = target``.

    Parameters
    ----------
    field : ndarray, grid.shape
        Signed field, negative inside (close to a distance near its zero set).
    grid : Grid
    target : float
        Volume (3D) or area (2D) wanted, world units.
    rtol : float
        Relative volume error at which to stop.
    max_steps : int
        Surfaces extracted at most.
    max_cells : float
        |iso_value| stays below this many grid spacings: a volume that needs a larger
        shift is not a blending error, and is left to the caller to report.
        A truncated field (its maximum, the value where no transport reached, is
        under the search's reach of ``max_cells + 2`` cells) keeps the iso-value half a
        cell below that plateau, whose nodes are outside at any such one and are not read.

    Returns
    -------
    iso_value : float
        World units; 0 when the field encloses the target already.
    error : float
        Relative volume error left, (V(iso_value) - target) / target.
    """
    h = grid.spacing
    f = np.asarray(field, dtype=float)
    flat = f.reshape(-1)
    reach = (max_cells + 2) * h
    lim = max_cells * h
    top = flat.max()  # under reach: a truncated field's plateau, outside at any iso-value below it
    lim_up = lim if top >= reach else max(0.0, min(lim, top - 0.5 * h))
    near = np.flatnonzero((flat > -reach) & (flat < min(reach, top)))  # the nodes it can cross
    fn = flat[near]
    ghn = np.empty(len(near))  # a chunk at a time: bounds the index temporaries
    for s in range(0, len(near), _CHUNK):
        part = slice(s, s + _CHUNK)
        ghn[part] = np.maximum(_gradient_norm(f, grid, near[part]), 0.05) * h
    inner = (np.count_nonzero(flat < 0) - np.count_nonzero(fn < 0)) * grid.cell_volume

    def smooth(iso_value: float) -> tuple[float, float]:
        """Smoothed-Heaviside volume of {f < iso_value} and its derivative (both increasing)."""
        ramp = 0.5 - (fn - iso_value) / ghn
        inside = (ramp > 0.0) & (ramp < 1.0)
        vol = inner + np.clip(ramp, 0.0, 1.0).sum() * grid.cell_volume
        return vol, float(np.sum(1.0 / ghn[inside])) * grid.cell_volume

    iso_value = 0.0
    err = 0.0
    for _ in range(max_steps):
        v = enclosed_volume(f, grid, level=iso_value)
        err = (v - target) / target
        if abs(err) <= rtol:
            break
        want = smooth(iso_value)[0] + (target - v)
        lo, hi = -lim, lim_up
        for _ in range(30):  # safeguarded Newton on the monotone smooth volume
            vol, slope = smooth(iso_value)
            lo, hi = (iso_value, hi) if vol < want else (lo, iso_value)
            if abs(vol - want) <= 1e-6 * abs(target):
                break
            step = iso_value + (want - vol) / slope if slope > 0 else np.inf
            iso_value = step if lo < step < hi else 0.5 * (lo + hi)
    else:
        err = (enclosed_volume(f, grid, level=iso_value) - target) / target
    return float(iso_value), float(err)


def component_iso_values(field: np.ndarray, grid: Grid, labels: np.ndarray,
                         targets: np.ndarray, *, max_cells: float = 3.0, passes: int = 2,
                         **keywords: Any) -> tuple[np.ndarray, np.ndarray]:
    """Shift each labelled component of ``field`` by its own iso-value, in place, so that
    its volume is its target (`components.ComponentVolumes.targets`).

    Every node within ``max_cells + 2`` cells of some component (the reach of
    `volume_iso_value`) belongs to the nearest component (`skimage.segmentation.
    expand_labels`) and is shifted by that component's iso-value; nodes farther from
    every component are outside at any such shift and keep their value. It changes only
    between two components, where the field is outside by half their gap. A component
    with no target (no material arrives in it) keeps an iso-value of 0.

    Each iso-value is found on the component's box with the other components' inside set to
    the plateau, as if the whole box moved by it. Across a gap of a cell or two, some of
    the component's surface edges end on a node that moves with its neighbour instead,
    so a second pass corrects what the first left.

    Parameters
    ----------
    field : ndarray, grid.shape
        Modified in place.
    labels : int ndarray, grid.shape
        The components of ``field < 0`` (`components.component_labels`), 1..len(targets).
    targets : (P,) array
        Volume wanted of each component, world units.
    max_cells, **keywords
        As `volume_iso_value`, per component.
    passes : int
        Rounds of the per-component solves.

    Returns
    -------
    iso_values : (P,) array
        Each component's iso-value, world units.
    error : (P,) array
        Each component's relative volume error left after the last pass, as its box
        measures it (NaN for a component with no target).
    """
    reach = int(np.ceil(max_cells)) + 2
    whole = ndimage.find_objects((labels > 0).astype(np.int8))[0]
    box = tuple(slice(max(b.start - reach - 1, 0), min(b.stop + reach + 1, n))
                for b, n in zip(whole, grid.shape))
    near = expand_labels(labels[box], distance=reach)
    plateau = float(field.max())
    local = field[box]  # a view: shifting it shifts ``field``
    inside = labels[box]
    iso_values, err = np.zeros(len(targets)), np.full(len(targets), np.nan)
    parts = ndimage.find_objects(near, max_label=len(targets))
    for _ in range(passes):
        for k, part in enumerate(parts):
            if part is None or targets[k] <= 0:
                continue
            part = tuple(slice(max(b.start - 1, 0), min(b.stop + 1, n))
                         for b, n in zip(part, near.shape))
            others = inside[part]
            own = np.where((others > 0) & (others != k + 1), plateau, local[part])
            origin = tuple(slice(b.start + p.start, b.start + p.stop) for b, p in zip(box, part))
            step, err[k] = volume_iso_value(own, sub_grid(grid, origin), targets[k],
                                            max_cells=max_cells, **keywords)
            mine = local[part]  # a view of the component's box: its nodes are all in it
            mine[near[part] == k + 1] -= step
            iso_values[k] += step
    return iso_values, err


def _gradient_norm(f: np.ndarray, grid: Grid, nodes: np.ndarray) -> np.ndarray:

    """|grad f| at the flat indices ``nodes`` of the field ``f`` on ``grid``, with
    `numpy.gradient`'s differences: central inside, one-sided on the grid's faces. Only
    these nodes are read, so no gradient of the whole grid is made."""
    flat = f.reshape(-1)
    total = np.zeros(len(nodes))
    for i, n, stride in zip(np.unravel_index(nodes, grid.shape), grid.shape, grid.strides):
        lo = np.where(i > 0, nodes - stride, nodes)
        hi = np.where(i < n - 1, nodes + stride, nodes)
        g = (flat[hi] - flat[lo]) / ((hi - lo) // stride * grid.spacing)
        total += g * g
    return np.sqrt(total)
