"""Paths of the surface grid's nodes, read from trajectories solved on a coarser motion grid.

The maps and the as-rigid-as-possible trajectories are smooth fields: they are solved on
the motion grid (cells an arbitrary factor larger, same box), while the keyframes'
distance fields, which carry the detail the artist sees, stay on the surface grid
(docs/method.md, section 11). A surface node x moves by the multilinear interpolation of
the motion nodes' displacements around it,

    x(s) = x + sum_c w_c(x) (X_c(s) - X_c),

the weights w_c those of x in its motion cell. The displacement of a rigid motion is
affine in x, and multilinear interpolation reproduces affine fields exactly, so a rigid
part moves rigidly at every surface node. At s = 1 the paths end on the interpolated
map, so a feature point constrained on the motion grid lands exactly.

`FinePaths` offers what a `transport.Transport` asks of its trajectories (``grid``,
``region_nodes``, ``node_positions``, ``mapped``), on the surface grid.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from ..base.grid import Grid
from ..base.sampling import cell_weights, sample
from ..map.parts import nearest_label

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from .spline import Bend
    from .trajectory import Trajectories

__all__ = ["FinePaths", "material_mass", "on_motion_grid", "same_width"]

_KEPT = 3  # node sets whose motion-cell weights `FinePaths` keeps
_CHUNK = 1 << 18  # surface nodes read at once when the whole map is made


def on_motion_grid(field: ArrayLike, grid: Grid, motion_grid: Grid) -> np.ndarray:
    """A surface-grid field read at the motion grid's nodes (multilinear; beyond the surface
    grid's box the distance to it is added, so a distance field stays outside)."""
    return sample(field, grid, motion_grid.points(), outside="distance")


def same_width(cells: float, grid: Grid, motion_grid: Grid) -> float:
    """A margin ``cells`` of ``grid``'s cells wide, in cells of the ``motion_grid`` (at least
    one): the margins the solves add around the material keep their width in world units
    on the motion grid. A margin of motion cells is wider, and the empty gap of a merge
    resists it the more (benchmarks/results/motion_grid.md)."""
    return max(1.0, float(cells) * grid.spacing / motion_grid.spacing)


def material_mass(material: ArrayLike, grid: Grid, motion_grid: Grid) -> np.ndarray:
    """The surface grid's ``material`` (bool, grid.shape) restricted to the motion grid's
    nodes: each material node's multilinear weights added onto the corners of its motion
    cell. Multilinear weights reproduce linear functions, so a centroid weighted by this
    mass on the motion nodes is the surface material's centroid exactly."""
    nodes = np.flatnonzero(np.asarray(material, dtype=bool))
    out = np.zeros(motion_grid.size)
    for lo in range(0, nodes.size, _CHUNK):
        flat, w = cell_weights(motion_grid, grid.node_points(nodes[lo:lo + _CHUNK]))
        out += np.bincount(flat.reshape(-1), weights=w.reshape(-1), minlength=motion_grid.size)
    return out.reshape(motion_grid.shape)


def _surface_parts(grid: Grid, material: np.ndarray, coarse: Trajectories) -> np.ndarray:
    """The part of every surface node (flat): that of its nearest material component, each
    component taking the part most of its nodes' motion cells' nearest corners hold."""
    labels, count = ndimage.label(material)
    idx = coarse.grid.nearest_node(grid.to_world(np.argwhere(material)))
    votes = coarse.parts.reshape(coarse.grid.shape)[tuple(idx.T)]
    part = np.zeros(count + 1, np.int64)
    for c in range(1, count + 1):
        part[c] = np.bincount(votes[labels[material] == c]).argmax()
    return part[nearest_label(labels)].reshape(-1)


class FinePaths:
    """The paths x(s) of a surface grid's nodes, interpolated from coarser trajectories.

    Parameters
    ----------
    grid : Grid
        The surface grid.
    coarse : `trajectory.Trajectories`
        The trajectories on the motion grid (which covers ``grid``'s box).
    material : bool ndarray, grid.shape
        The keyframe's material on the surface grid.
    margin_cells : float
        The region's margin around the material, in surface cells (as
        `trajectory.Trajectories` ``margin_cells``).

    Where the coarse trajectories keep parts apart (``coarse.parts``), a motion cell may
    hold two parts across a gap narrower than itself: a surface node reads the corners
    of another part moved rigidly with its own part's body (`Trajectories.
    body_positions`), so a rigid part stays rigid up to the gap.
    """

    def __init__(self, grid: Grid, coarse: Trajectories, material: ArrayLike,
                 margin_cells: float) -> None:
        self.grid, self.coarse, self.dim = grid, coarse, grid.dim
        self.stats = coarse.stats
        material = np.asarray(material, dtype=bool)
        dist = ndimage.distance_transform_edt(~material)
        self._region = (dist <= float(margin_cells)).reshape(-1)
        self._weights: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._mapped: np.ndarray | None = None
        self._parts = None if coarse.parts is None else _surface_parts(grid, material, coarse)
        self._nearest: dict[int, np.ndarray] = {}  # per part: its nearest motion node

    @property
    def bend(self) -> Bend | None:
        """The `spline.Bend` of the motion grid's paths, or None: these paths follow it."""
        return self.coarse.bend

    def region_nodes(self) -> np.ndarray:
        """Flat bool mask of the region's surface nodes: the material and its margin."""
        return self._region

    @property
    def mapped(self) -> np.ndarray:
        """The map y(x) on the surface grid, array of grid.shape + (d,) (made once, a chunk
        of nodes at a time: the weights of every node at once would be 8 times its size)."""
        if self._mapped is None:
            coarse, d = self.coarse, self.dim
            disp = coarse.mapped - coarse.grid.points()
            out = np.empty((self.grid.size, d))
            for lo in range(0, self.grid.size, _CHUNK):
                nodes = np.arange(lo, min(lo + _CHUNK, self.grid.size))
                if self._parts is None:
                    x = self.grid.node_points(nodes)
                    out[lo:lo + len(x)] = x + sample(disp, coarse.grid, x)
                else:
                    out[lo:lo + len(nodes)] = self._read(1.0, nodes)
            self._mapped = out.reshape(self.grid.shape + (d,))
        return self._mapped

    def node_positions(self, s: float, nodes: ArrayLike) -> np.ndarray:
        """Positions x(s) of the surface nodes with the given flat indices, (len(nodes), d)."""
        nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
        if float(s) == 0.0:
            return self.grid.node_points(nodes)
        return self._read(s, nodes)

    def _read(self, s, nodes):
        """`node_positions` at 0 < s <= 1: the motion nodes' displacements interpolated,
        those of another part's corners replaced by the node's own part's body."""
        x = self.grid.node_points(nodes)
        w, cnodes, inv = self._cells_of(nodes, x)
        coarse = self.coarse
        disp = (coarse.node_positions(s, cnodes) - coarse.grid.node_points(cnodes))[inv]
        if self._parts is not None:
            own = self._parts[nodes]
            corner = cnodes[inv]
            for p in np.unique(own):
                foreign = (own == p)[:, None] & (coarse.parts[corner] != p)
                if foreign.any():
                    at = corner[foreign]
                    like = self._nearest_of(p)[at]
                    disp[foreign] = coarse.body_positions(s, at, like) - coarse.grid.node_points(at)
                    if coarse.bend is not None:
                        disp[foreign] += coarse.bend(s, like)
        return x + np.einsum("pk,pkd->pd", w, disp)

    def _nearest_of(self, part):
        """The material motion node of ``part`` (any node of it, where it holds no motion
        node of material) nearest each motion node (flat indices)."""
        if part not in self._nearest:
            mgrid = self.coarse.grid
            own = (self.coarse.parts == part).reshape(mgrid.shape)
            away = ~(own & self.coarse.material) if (own & self.coarse.material).any() else ~own
            _, idx = ndimage.distance_transform_edt(away, return_indices=True)
            self._nearest[part] = np.ravel_multi_index(tuple(idx), mgrid.shape).reshape(-1)
        return self._nearest[part]

    def __call__(self, points: ArrayLike, s: float) -> np.ndarray:
        """Positions at time s of points given at time 0 ((P, d) -> (P, d)): the motion
        grid's trajectories read there directly."""
        return self.coarse(points, s)

    def _cells_of(self, nodes: np.ndarray,
                  x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:

        """Motion-grid weights (P, 2**d), the motion nodes they use, and each weight's
        row among those nodes (P, 2**d); kept for the last few node sets, which every
        frame asks for again."""
        key = hash(nodes.tobytes())
        if key not in self._weights:
            flat, w = cell_weights(self.coarse.grid, x)
            cnodes, inv = self.coarse.grid.unique_nodes(flat)
            self._weights[key] = (w, cnodes, inv)
            if len(self._weights) > _KEPT:
                self._weights.pop(next(iter(self._weights)))
        return self._weights[key]
