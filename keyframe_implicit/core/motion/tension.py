"""Surface tension at a neck: the concave creases of an in-between filled where it moves.

Where two parts meet, the blend of the two transports (`levelset`, eq. 3.4's two-sided
form) joins them with a crease: each keyframe's distance field has a kink on the plane
between the parts (its medial surface), and the blend inherits it, so the neck is a sharp
concave fold, as of clay pressed together. A liquid's neck is round from the first
moments (surface tension pulls the fold open).

`fill_creases` rounds it the way a closing does: L -> min(L, G_sigma * L). Blurring
raises a distance field where its Laplacian is positive (flat or convex surface: the
minimum keeps L) and lowers it where it is negative (a crease, a neck): only concave
folds fill, over about sigma. It acts only where a keyframe's parts meet as its
transport carries them (`transport.Transport.carry_meeting`), and never between parts of
the frame that have not met, so nothing moves before it is touched and the rest of the
frame, thin parts and the keyframes' own concave corners included, stays as the blend
made it; the per-part iso-value that follows (`isovolume`) gives back the volume the
filling adds. A split is a merge seen from the
other keyframe: its neck is filled the same way until it parts.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..base.grid import Grid
from .components import component_labels

__all__ = ["fill_creases", "meeting_reach", "CELLS_PER_TENSION", "GAUSSIAN_TRUNCATE"]

#: The filling's Gaussian sigma, in cells, at surface tension 1.
CELLS_PER_TENSION = 2.0
#: How far the filling's Gaussian reads, in sigmas (`scipy.ndimage.gaussian_filter`'s
#: ``truncate``): how deep under the surface the filling looks (`band.band_depth`).
GAUSSIAN_TRUNCATE = 4.0


def meeting_reach(grid: Grid, tension: float) -> float:
    """How close (world units) two parts' carried surfaces must both be for a node to lie
    where they meet (`transport.Transport.carry_meeting`): twice the filling's sigma."""
    return 2.0 * tension * CELLS_PER_TENSION * grid.spacing


def fill_creases(field: np.ndarray, meeting: np.ndarray | None, grid: Grid, tension: float,
                 weight: float = 1.0) -> np.ndarray:
    """``field`` with its concave creases filled over a Gaussian of ``tension`` times
    `CELLS_PER_TENSION` cells, where parts meet.

    Parameters
    ----------
    field : ndarray, grid.shape
        An in-between's blended field (negative inside).
    meeting : bool ndarray, grid.shape, or None
        Where a keyframe's parts meet at this time, as either transport carries them
        (`transport.Transport.carry_meeting`); None: nowhere.
    grid : Grid
    tension : float
        0 returns ``field`` itself.
    weight : float in [0, 1]
        How much of the filling is applied (the frames next to a keyframe ease it in).

    Returns
    -------
    ndarray, grid.shape: field - weight max(field - G * field, 0) within the Gaussian's
    reach of ``meeting``, else ``field``; never between two parts of ``field`` (nodes within
    that reach of both), so parts that have not met stay apart.
    """
    if tension <= 0 or weight <= 0 or meeting is None or not meeting.any():
        return field
    sigma = tension * CELLS_PER_TENSION
    reach = int(np.ceil(3 * sigma))
    box = _box(meeting, 2 * reach)
    part = field[box]
    where = (ndimage.binary_dilation(meeting[box], iterations=reach)
             & ~_between_parts(part, reach))
    blurred = ndimage.gaussian_filter(part, sigma, mode="nearest", truncate=GAUSSIAN_TRUNCATE)
    out = field.copy()
    out[box] = part - weight * np.where(where, np.maximum(part - blurred, 0.0), 0.0)
    return out


def _between_parts(field, reach):
    """The nodes within ``reach`` nodes of two different parts of ``field``'s material:
    filling there would join parts that have not met."""
    labels, count = component_labels(field)
    if count < 2:
        return np.zeros(field.shape, bool)
    size = 2 * reach + 1
    none = count + 1
    most = ndimage.maximum_filter(labels, size)
    least = ndimage.minimum_filter(np.where(labels > 0, labels, none), size)
    return (most > 0) & (least < none) & (most != least)


def _box(mask, margin):
    """The slices of ``mask``'s bounding box grown by ``margin`` nodes (clipped)."""
    nz = np.nonzero(mask)
    return tuple(slice(max(int(i.min()) - margin, 0), int(i.max()) + margin + 1) for i in nz)
