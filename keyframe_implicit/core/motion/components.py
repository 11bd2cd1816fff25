"""The volume each component of an in-between should have, from where its material comes.

The first term of eq. 2.6 asks det F = 1 in every cell: each piece of material keeps
its volume wherever it goes. One iso-value per frame (`isovolume.volume_iso_value`) holds
only the total: in a merge of two unequal balls the small one grew while the big one
shrank, before they touched. Here the material is cut into atoms, one per pair of
components (i of keyframe A, j of B) that the maps join, each with its share of the
material fitted to both keyframes' own component volumes (`ComponentVolumes`). At time
s each connected component p of the in-between wants the volume of the atoms whose
material arrives in it, A's along A's paths and B's along B's; `isovolume.
component_iso_values` then gives each its own iso-value. docs/method.md, section 13.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..base.grid import Grid
from ..surface.extract import enclosed_volume

if TYPE_CHECKING:
    from .finepaths import FinePaths
    from .trajectory import Trajectories

__all__ = ["ComponentVolumes", "component_labels", "component_volumes", "sub_grid"]

_SAMPLED_NODES = 200_000  # material nodes followed per keyframe (every k-th beyond that)


def component_labels(field: np.ndarray) -> tuple[np.ndarray, int]:
    """Connected components of the material ``field < 0`` (faces connect nodes): (labels, count),
    labels 0 outside, 1..count inside (`scipy.ndimage.label`)."""
    return ndimage.label(field < 0)


def sub_grid(grid: Grid, box: tuple[slice, ...]) -> Grid:
    """The component of ``grid`` that a tuple of slices ``box`` cuts out, as a Grid of its own."""
    start = np.array([b.start for b in box])
    shape = tuple(b.stop - b.start for b in box)
    return Grid(origin=tuple(grid.origin + start * grid.spacing), spacing=grid.spacing,
                shape=shape)


def _padded(box: tuple[slice, ...], pad: int, shape: tuple[int, ...]) -> tuple[slice, ...]:
    return tuple(slice(max(b.start - pad, 0), min(b.stop + pad, n)) for b, n in zip(box, shape))


def component_volumes(field: np.ndarray, grid: Grid, labels: np.ndarray,
                      count: int) -> np.ndarray:
    """Volume of each labelled component's own surface, (count,) world units.

    Component k's volume is that of the surface marching cubes gives its field with every
    other component turned inside out, cut to its box and one cell more (`enclosed_volume`):
    the same measure as the whole in-between's, component by component.
    """
    out = np.zeros(count)
    for k, box in enumerate(ndimage.find_objects(labels, max_label=count)):
        if box is None:
            continue
        box = _padded(box, 2, grid.shape)
        f, lab = field[box], labels[box]
        own = np.where((lab == k + 1) | (lab == 0), f, np.abs(f))
        out[k] = enclosed_volume(own, sub_grid(grid, box))
    return out


class _Source:
    """A keyframe's components, their volumes and a sample of their material nodes, each
    node weighing its component's volume over that component's sampled nodes."""

    def __init__(self, field: np.ndarray, grid: Grid, paths: Trajectories | FinePaths) -> None:
        labels, count = component_labels(field)
        self.grid, self.paths, self.count = grid, paths, count
        nodes = np.flatnonzero(labels.reshape(-1))
        self.nodes = nodes[::max(1, -(-len(nodes) // _SAMPLED_NODES))]
        self.component = labels.reshape(-1)[self.nodes] - 1
        volume = component_volumes(field, grid, labels, count)
        self.weight = (volume / np.bincount(self.component, minlength=count))[self.component]

    def partners(self, other: _Source) -> np.ndarray:
        """The component of ``other`` (the other keyframe) each sampled node's path ends in
        at t = 1: the component of the nearest of ``other``'s sampled nodes."""
        ends = self.paths.node_positions(1.0, self.nodes)
        _, nearest = cKDTree(self.grid.node_points(other.nodes)).query(ends, workers=-1)
        return other.component[nearest]

    def arrivals(self, atom: np.ndarray, atoms: int, labels: np.ndarray, count: int,
                 t: float) -> np.ndarray:
        """Share of each atom's sampled nodes (on this side) that arrive in each of the
        ``count`` components ``labels`` marks when the paths are at time t: (atoms, count);
        nodes arriving in no component are left out, so each row sums to 1 or is 0."""
        pos = self.paths.node_positions(t, self.nodes)
        idx = np.rint(self.grid.to_index(pos)).astype(np.int64)
        inside = np.all((idx >= 0) & (idx < np.asarray(self.grid.shape)), axis=1)
        at = np.zeros(len(idx), np.int64)
        at[inside] = labels[tuple(idx[inside].T)]
        counts = np.bincount(atom * (count + 1) + at, minlength=atoms * (count + 1))
        arrived = counts.reshape(atoms, count + 1)[:, 1:].astype(float)
        total = arrived.sum(axis=1, keepdims=True)
        return np.divide(arrived, total, out=np.zeros_like(arrived), where=total > 0)


class ComponentVolumes:
    """Where the two keyframes' components go: the volume each component of an in-between
    should have.

    The material is cut into atoms, one per (component i of A, component j of B) that
    the maps join. Atom ij is the share mu_ij of the material that A's component i and
    B's component j have in common: of A's volume V_A on A's side, of V_B on B's. At
    time s it wants mu_ij ((1 - s) V_A + s V_B), handed to the in-between's components
    its material arrives in, A's side along A's paths and B's along B's.

    The shares are fitted to both keyframes' own component volumes: each row i sums to
    V_A,i / V_A and each column j to V_B,j / V_B (iterative proportional fitting, from
    the two maps' own estimates). Where the atoms form a tree (merges, splits,
    components that stay themselves) these sums alone decide the shares, so a map that
    tears a component, and stretches on the way, cannot misplace its volume: in a merge
    each ball keeps its own volume whatever the torn backward map says.

    Parameters
    ----------
    grid : Grid
    phi_a, phi_b : ndarray, grid.shape
        The keyframes' fields.
    paths_a, paths_b : paths with ``node_positions(t, nodes)``
        A's paths (A -> B) and B's (B -> A): `trajectory.Trajectories` or
        `finepaths.FinePaths`.
    volumes : (V_A, V_B), optional
        The keyframes' whole volumes the shares are of (the meshes' as modelled, where
        they differ from the grids'); default: the sums of their components' volumes.
    """

    def __init__(self, grid: Grid, phi_a: np.ndarray, phi_b: np.ndarray,
                 paths_a: Trajectories | FinePaths, paths_b: Trajectories | FinePaths,
                 volumes: tuple[float, float] | None = None) -> None:
        self.a = _Source(phi_a, grid, paths_a)
        self.b = _Source(phi_b, grid, paths_b)
        self.atoms = self.a.count * self.b.count
        self.atom_a = self.a.component * self.b.count + self.a.partners(self.b)
        self.atom_b = self.b.partners(self.a) * self.b.count + self.b.component
        grid_volumes = (self.a.weight.sum(), self.b.weight.sum())
        self.volumes = grid_volumes if volumes is None else tuple(volumes)
        self.share = _fitted_shares(
            np.bincount(self.atom_a, self.a.weight, minlength=self.atoms) / grid_volumes[0],
            np.bincount(self.atom_b, self.b.weight, minlength=self.atoms) / grid_volumes[1],
            (self.a.count, self.b.count))

    def targets(self, labels: np.ndarray, count: int, s: float) -> np.ndarray:
        """V_p(s) of each of the ``count`` components ``labels`` marks (the in-between's
        own at time s, `component_labels`): (count,) world units; 0 for a component no
        atom arrives in.

        Each atom goes whole to the component most of its material arrives in (A's
        nodes weighing 1 - s, B's s): an atom is one piece of material at both ends, and
        the few of its nodes that stray into a neighbour as two components come close
        are not that neighbour's volume."""
        arrived = ((1.0 - s) * self.a.arrivals(self.atom_a, self.atoms, labels, count, s)
                   + s * self.b.arrivals(self.atom_b, self.atoms, labels, count, 1.0 - s))
        va, vb = self.volumes
        held = self.share * ((1.0 - s) * va + s * vb)
        landed = arrived.max(axis=1) > 0
        return np.bincount(arrived.argmax(axis=1)[landed], held[landed], minlength=count)


def _fitted_shares(from_a: np.ndarray, from_b: np.ndarray, counts: tuple[int, int],
                   sweeps: int = 200) -> np.ndarray:

    """Atom shares (atoms,) with row sums those of ``from_a`` (A's component fractions) and
    column sums those of ``from_b`` (B's), on the atoms either map joins, starting from
    their mean (iterative proportional fitting: on a tree of atoms, the only such shares)."""
    a, b = from_a.reshape(counts), from_b.reshape(counts)
    rows, cols = a.sum(axis=1, keepdims=True), b.sum(axis=0, keepdims=True)
    mu = 0.5 * (a + b)
    for _ in range(sweeps):
        mu *= np.divide(rows, mu.sum(axis=1, keepdims=True), out=np.zeros_like(rows),
                        where=mu.sum(axis=1, keepdims=True) > 0)
        mu *= np.divide(cols, mu.sum(axis=0, keepdims=True), out=np.zeros_like(cols),
                        where=mu.sum(axis=0, keepdims=True) > 0)
    return mu.reshape(-1)
