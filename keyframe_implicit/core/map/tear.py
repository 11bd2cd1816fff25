"""Where a map tears: a component of A that the map spreads over several components of B.

One ball into two (a split, or a merge seen backwards) has no continuous map that keeps
volume: a continuous map must fill the gap between B's components, and the volume term
of eq. 2.6 then stretches the whole ball (det F 1.6-1.9 over most of it). Here the
material of such a component is cut into pieces, one per component of B it reaches,
each holding that component's share of its volume; the cells whose corners lie in two
pieces (the crack, with the margin cells between the pieces) leave the solve, so each
piece is mapped onto its own component of B as a body of its own (docs/method.md,
section 4, "Tears").

A node's piece is decided by where the untorn map sends it: the component j of B
minimising ``d_j(y(x)) - c_j``, ``d_j`` the distance to component j and ``c_j`` one
offset per component, fitted so that each piece holds B's component j's share of the
torn component's material. The cut lies where the untorn map stretches across the gap,
and the volumes are B's, so det F = 1 can hold on every piece.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from ..base import elements
from ..base.sampling import sample
from .hierarchy import extend, prolong
from .terms import heaviside

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ..base.grid import Grid

__all__ = ["Tear", "find_tear", "prolong_pieces"]

_REACH = 0.05  # a component of B counts as reached when this share of the material lands nearest it
_MAX_COMPONENTS = 16  # B's components: one distance field each
_FIT_SWEEPS = 200


class Tear:
    """The pieces of a map's torn components.

    piece : int ndarray, grid.shape
        1..n on the nodes of the torn components' pieces (material and margin), 0
        elsewhere.
    crack : bool ndarray, the grid's cells
        The cells with corners in two pieces of one torn component.
    target : (n,) int
        The component of B (1-based labels of ``phi_b < 0``) each piece maps onto.
    stats : dict
        ``pieces``, and ``crack_material``: the share of A's material cells in the crack.
    """

    def __init__(self, piece: np.ndarray, crack: np.ndarray, target: ArrayLike,
                 crack_material: float) -> None:
        self.piece, self.crack, self.target = piece, crack, np.asarray(target)
        self.stats = {"pieces": int(len(self.target)), "crack_material": float(crack_material)}


def find_tear(phi_a: np.ndarray, phi_b: np.ndarray, grid: Grid, mapped: np.ndarray) -> Tear | None:
    """The `Tear` of ``mapped`` (y(x) on every node of ``grid``), or None where no
    component of A (a face-connected piece of ``phi_a < 0``) reaches several components
    of B."""
    labels_b, count_b = ndimage.label(phi_b < 0)
    if count_b < 2 or count_b > _MAX_COMPONENTS:
        return None
    components, _ = ndimage.label(phi_a < 0)
    d = grid.dim
    eps = 1.5 * grid.spacing
    inside_a = 1.0 - heaviside(phi_a, eps)  # the material each node stands for
    vol_b = ndimage.sum(1.0 - heaviside(phi_b, eps), labels_b, np.arange(1, count_b + 1))
    material = components > 0
    nodes = np.flatnonzero(material)
    y = mapped.reshape(-1, d)[nodes]
    dist = np.stack([sample(ndimage.distance_transform_edt(labels_b != j) * grid.spacing, grid, y)
                     for j in range(1, count_b + 1)], axis=1)  # (nodes, count_b)
    comp = components.reshape(-1)[nodes]
    piece = np.zeros(grid.size, np.int64)
    targets: list[int] = []

    for c in np.unique(comp):
        own = comp == c
        nearest = np.argmin(dist[own], axis=1)
        reached = np.flatnonzero(np.bincount(nearest, minlength=count_b) > _REACH * own.sum())
        if len(reached) < 2:
            continue
        share = vol_b[reached] / vol_b[reached].sum()
        which = _balanced(dist[own][:, reached], inside_a.reshape(-1)[nodes[own]], share,
                          grid.spacing)
        piece[nodes[own]] = len(targets) + 1 + which
        targets += list(reached + 1)
    if not targets:
        return None
    piece = _spread(piece.reshape(grid.shape), material)
    crack = _crack(piece)
    cells = sum(elements.corner_views(phi_a)) < 0  # material cells: Phi < 0 at the centre
    return Tear(piece, crack, targets, np.mean(crack[cells]))


def _balanced(dist: np.ndarray, weight: np.ndarray, share: np.ndarray, h: float) -> np.ndarray:
    """Each node's piece, argmin_j (dist_j - c_j), with the offsets c_j fitted so that
    piece j holds the fraction ``share[j]`` of ``weight``: each sweep moves c_j by the
    gap between its share and the one wanted, in units of h, until they agree to 0.1 %."""
    c = np.zeros(dist.shape[1])
    total = weight.sum()
    which = np.argmin(dist, axis=1)
    for _ in range(_FIT_SWEEPS):
        which = np.argmin(dist - c, axis=1)
        got = np.bincount(which, weight, minlength=len(share)) / total
        if np.max(np.abs(got - share)) < 1e-3:
            break
        c += 4.0 * h * (share - got)
    return which


def _spread(piece: np.ndarray, material: np.ndarray) -> np.ndarray:
    """The pieces carried from the material to every node: each takes the piece of its
    nearest material node (0 where that is untorn)."""
    _, idx = ndimage.distance_transform_edt(~material, return_indices=True)
    return piece[tuple(idx)]


def _crack(piece: np.ndarray) -> np.ndarray:
    """The cells with corners in two different pieces (0, untorn, joins any)."""
    views = elements.corner_views(piece)
    big = np.iinfo(np.int64).max
    low = np.full(views[0].shape, big)
    high = np.zeros(views[0].shape, np.int64)
    for v in views:
        low = np.minimum(low, np.where(v > 0, v, big))
        high = np.maximum(high, v)
    return (high > 0) & (low < high)


def prolong_pieces(corr: np.ndarray, coarse: Tear, fine: Tear, passes: int) -> np.ndarray:

    """A coarse level's correction ``corr`` of a map torn as ``coarse``, prolonged onto
    the next finer level, torn as ``fine``: each node of a fine piece reads the
    correction of the coarse piece with the same component of B, extended beyond that
    piece (`hierarchy.extend`), so that no node takes the mean of two pieces' positions
    across the crack; untorn nodes read ``corr`` as it is."""
    shape = fine.piece.shape
    out = np.ascontiguousarray(prolong(corr, shape))
    for p, target in enumerate(fine.target, start=1):
        match = np.flatnonzero(coarse.target == target)
        if not len(match):
            continue
        own = extend(corr.copy(), coarse.piece == match[0] + 1, passes)
        at = fine.piece == p
        out[at] = prolong(own, shape)[at]
    return out
