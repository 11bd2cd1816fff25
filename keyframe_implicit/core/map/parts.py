"""Parts that are apart in both keyframes, and the cells between them.

Two plates a cell apart that turn opposite ways are two bodies: nothing joins them in
either keyframe. One map solved over both, with the rigidity and volume terms on the
cells of the gap between them, drags each by the other (the scissors of
benchmarks/bench_contact.py followed their turns 2.5 h off on the mean). Here keyframe
A's components are grouped by the component of B they go to; a node belongs to the
group of its nearest material, and the cells with corners in two groups (the gap's) are
left out of the map's solve and of the trajectories' (`trajectory.Trajectories`), so
each group moves as a body of its own (docs/method.md, section 4, "Separate parts").

Components that go to one component of B (a merge) stay one group: their contact is
the map's to shape.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from ..base import elements

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ..base.grid import Grid

__all__ = ["part_labels", "parts_on", "part_crack", "cut_components", "nearest_label"]


def part_labels(phi_a: ArrayLike, phi_b: ArrayLike, grid: Grid, features_a: ArrayLike,
                   features_b: ArrayLike) -> np.ndarray | None:
    """Each node's part (1, 2, ...: the component of B its nearest material of A goes to),
    grid.shape, or None where all of A's components go to one component of B.

    A component of A goes where its feature points' partners lie (the component of B
    nearest to most of them); one without feature points stays in place (the component
    of B nearest to most of its material nodes).
    """
    labels_a, count_a = ndimage.label(np.asarray(phi_a) < 0)
    labels_b, count_b = ndimage.label(np.asarray(phi_b) < 0)
    if count_a < 2 or count_b < 2:
        return None
    near_a = nearest_label(labels_a)
    near_b = nearest_label(labels_b)
    xa, yb = (np.asarray(f, dtype=float).reshape(-1, grid.dim) for f in (features_a, features_b))
    own = near_a[_node_of(xa, grid)] if len(xa) else np.zeros(0, np.int64)
    goes = np.zeros(count_a + 1, np.int64)
    for c in range(1, count_a + 1):
        votes = (near_b[_node_of(yb[own == c], grid)] if np.any(own == c)
                 else near_b[labels_a == c])
        goes[c] = np.bincount(votes).argmax()
    if len(np.unique(goes[1:])) < 2:
        return None
    return goes[near_a]


def parts_on(parts: np.ndarray, grid: Grid, other: Grid) -> np.ndarray:
    """``parts`` (on ``grid``'s nodes) read at the nodes of ``other`` (a coarser level or a
    motion grid over the same box): each takes the part of the nearest node of ``grid``."""
    return parts[_node_of(other.points().reshape(-1, grid.dim), grid)].reshape(other.shape)


def part_crack(parts: np.ndarray) -> np.ndarray:
    """The cells (bool, the cells' shape) whose corners lie in two parts."""
    views = elements.corner_views(parts)
    low, high = views[0].copy(), views[0].copy()
    for v in views[1:]:
        np.minimum(low, v, out=low)
        np.maximum(high, v, out=high)
    return low < high


def cut_components(components: np.ndarray, parts: np.ndarray) -> tuple[np.ndarray, int]:
    """Component labels (0 outside, 1.. on the material) cut where ``parts`` differ: one
    label per (component, part) met on the material, and their count. On a coarse grid
    two parts a cell apart may share a component; here they never do."""
    pairs = components * (int(parts.max()) + 1) + parts
    keys = np.unique(pairs[components > 0])
    return np.where(components > 0, np.searchsorted(keys, pairs) + 1, 0), len(keys)


def nearest_label(labels: np.ndarray) -> np.ndarray:
    """The label of the nearest labelled node, at every node (``labels`` must have one)."""
    _, idx = ndimage.distance_transform_edt(labels == 0, return_indices=True)
    return labels[tuple(idx)]


def _node_of(points: np.ndarray, grid: Grid) -> tuple[np.ndarray, ...]:
    """The index tuple of the node nearest each point (`Grid.nearest_node`)."""
    return tuple(grid.nearest_node(points).T)
