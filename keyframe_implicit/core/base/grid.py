"""Regular Cartesian grid in world units (thesis section 2.1).

Every keyframe is sampled as a signed distance field on one `Grid`; the volume
map y(x) lives on its nodes. Node ``(i, j[, k])`` sits at
``origin + spacing * (i, j[, k])``; arrays are indexed ``field[i, j, k]`` with
``i`` along world x. Cells are cubic (one spacing ``h``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["Grid"]


@dataclass(frozen=True)
class Grid:
    """A regular grid of ``shape`` nodes, ``spacing`` apart, first node at ``origin``.

    Parameters
    ----------
    origin : array_like, shape (d,)
        World position of node 0 (d = 2 or 3).
    spacing : float
        Edge length ``h`` of the cubic cells, in world units.
    shape : tuple of int
        Nodes per axis (at least 2 each).
    """

    origin: np.ndarray
    spacing: float
    shape: tuple[int, ...]

    def __post_init__(self) -> None:
        origin = np.asarray(self.origin, dtype=float).reshape(-1)
        shape = tuple(int(n) for n in self.shape)
        spacing = float(self.spacing)
        if origin.size not in (2, 3):
            raise ValueError(f"Grid origin must have 2 or 3 coordinates, got {origin.size}.")
        if len(shape) != origin.size:
            raise ValueError(
                f"Grid shape {shape} has {len(shape)} axes but origin has {origin.size} coordinates."
            )
        if any(n < 2 for n in shape):
            raise ValueError(f"Grid needs at least 2 nodes per axis, got shape {shape}.")
        if not np.isfinite(spacing) or spacing <= 0:
            raise ValueError(f"Grid spacing must be a positive finite number, got {spacing}.")
        if not np.all(np.isfinite(origin)):
            raise ValueError("Grid origin contains NaN or infinity.")
        origin.setflags(write=False)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "spacing", spacing)

    # -- basic facts -------------------------------------------------------
    @property
    def dim(self) -> int:
        """Number of spatial dimensions d (2 or 3)."""
        return len(self.shape)

    @property
    def size(self) -> int:
        """Number of nodes."""
        return int(np.prod(self.shape))

    @property
    def strides(self) -> np.ndarray:
        """Flat-index step of one node along each axis (C order), int array (d,)."""
        return np.cumprod((1,) + self.shape[:0:-1])[::-1]

    @property
    def upper(self) -> np.ndarray:
        """World position of the last node (the far corner)."""
        return self.origin + self.spacing * (np.asarray(self.shape) - 1)

    @property
    def cell_volume(self) -> float:
        """h**d, the measure of one cell."""
        return self.spacing ** self.dim

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Grid)
            and self.shape == other.shape
            and self.spacing == other.spacing
            and np.array_equal(self.origin, other.origin)
        )

    def __hash__(self) -> int:
        return hash((self.shape, self.spacing, tuple(self.origin)))

    def __repr__(self) -> str:
        o = ", ".join(f"{v:.6g}" for v in self.origin)
        return f"Grid(origin=({o}), spacing={self.spacing:.6g}, shape={self.shape})"

    # -- coordinates ---------------------------------------------------------
    def axes(self) -> list[np.ndarray]:
        """World coordinates of the nodes along each axis (list of 1-D arrays)."""
        return [self.origin[a] + self.spacing * np.arange(n) for a, n in enumerate(self.shape)]

    def points(self) -> np.ndarray:
        """World position of every node, array of shape ``shape + (d,)``."""
        return np.stack(np.meshgrid(*self.axes(), indexing="ij"), axis=-1)

    def node_points(self, nodes: ArrayLike) -> np.ndarray:
        """World position of the nodes with the given flat indices, array (len(nodes), d)."""
        return self.to_world(np.stack(np.unravel_index(nodes, self.shape), axis=-1))

    def unique_nodes(self, flat: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The distinct nodes among flat node indices, sorted, and where each entry of
        ``flat`` is among them: ``np.unique(flat, return_inverse=True)``, by marking the
        span of nodes ``flat`` reaches instead of sorting (the nodes of points' cells
        repeat eight times and lie in a band: a sort costs 20-30 times as much).

        Returns
        -------
        nodes : (m,) int64, sorted
        inverse : int32 array of ``flat``'s shape, ``nodes[inverse] == flat``
        """
        flat = np.asarray(flat, dtype=np.int64)
        if flat.size == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(flat.shape, dtype=np.int32)
        lo = int(flat.min())
        rel = flat - lo
        mark = np.zeros(int(rel.max()) + 1, dtype=bool)
        mark[rel] = True
        found = np.flatnonzero(mark)
        position = np.empty(mark.size, dtype=np.int32)  # a grid has fewer than 2**31 nodes
        position[found] = np.arange(found.size, dtype=np.int32)
        return found + lo, position[rel]

    def to_index(self, points: ArrayLike) -> np.ndarray:
        """Continuous (fractional) node index of world ``points`` (..., d)."""
        return (np.asarray(points, dtype=float) - self.origin) / self.spacing

    def nearest_node(self, points: ArrayLike) -> np.ndarray:
        """Integer index (..., d) of the node nearest each world point (..., d), clamped
        to the grid: a point outside takes the nearest node on its border."""
        index = np.rint(self.to_index(points)).astype(np.int64)
        return np.clip(index, 0, np.asarray(self.shape) - 1)

    def to_world(self, index: ArrayLike) -> np.ndarray:
        """World position of (fractional) node ``index`` (..., d)."""
        return self.origin + self.spacing * np.asarray(index, dtype=float)

    def contains(self, points: ArrayLike, margin: float = 0.0) -> np.ndarray:
        """True for world ``points`` inside the grid box shrunk by ``margin`` (world units)."""
        p = np.asarray(points, dtype=float)
        return np.all((p >= self.origin + margin) & (p <= self.upper - margin), axis=-1)

    def check_field(self, field: ArrayLike, name: str = "field") -> np.ndarray:

        """Return ``field`` as a float array, or raise ValueError naming what is wrong and
        what to do about it."""
        arr = np.asarray(field, dtype=float)
        if arr.shape != self.shape:
            raise ValueError(f"{name} has shape {arr.shape} but the grid has shape {self.shape}; "
                             "sample every keyframe on the one grid.")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} contains NaN or infinite values; resample that keyframe "
                             "(is its mesh closed and inside the grid?).")
        return arr
