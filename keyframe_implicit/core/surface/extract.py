"""Zero level set of a grid field as a mesh (3D) or contour loops (2D) (docs/method.md, section 7).

3D: `skimage.measure.marching_cubes` with spacing and origin in world units.
2D: `skimage.measure.find_contours`. The field is padded by one node of a
positive value first, so a body touching the grid boundary still gives a
closed surface / closed loops (the grid box closes it).

Orientation: triangles wind counter-clockwise seen from outside (normals
point out of the negative region, the mesh's signed volume is positive);
2D loops run counter-clockwise around the inside (positive signed area) and
clockwise around holes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, overload

import numpy as np

from ..base.grid import Grid

if TYPE_CHECKING:
    from typing import Literal

    from numpy.typing import ArrayLike

__all__ = ["extract_surface", "enclosed_volume", "mesh_volume", "piece_volumes", "mesh_pieces",
           "closed_pieces", "piece_means", "mesh_area", "loop_area", "material_topology"]


def mesh_volume(vertices: ArrayLike, faces: ArrayLike) -> float:
    """Signed volume enclosed by a closed triangle mesh (positive for outward normals)."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return 0.0
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def mesh_pieces(faces: ArrayLike, vertices: int) -> tuple[int, np.ndarray]:
    """(count, label): the connected pieces of a mesh of ``vertices`` vertices, joined by its
    faces' edges; pieces numbered in the order of their lowest vertex."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(faces, dtype=np.int64)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(vertices,) * 2)
    count, label = connected_components(graph, directed=False)
    return int(count), label


def closed_pieces(faces: ArrayLike, label: np.ndarray, count: int) -> np.ndarray:
    """(count,) bool: whether each piece (`mesh_pieces`) is closed, every edge of it shared
    by exactly two triangles, so that its volume is its own and not where it is measured
    from."""
    f = np.asarray(faces, dtype=np.int64)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, which, shared = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    open_edges = shared[which.reshape(-1)] != 2
    return np.bincount(label[edges[open_edges, 0]], minlength=count) == 0


def piece_volumes(vertices: ArrayLike, faces: ArrayLike,
                  pieces: tuple[int, np.ndarray] | None = None) -> np.ndarray:
    """The volume of each connected piece of a mesh, about the piece's own centroid (so an
    open piece's moves with it), in the order of its lowest vertex. ``pieces``: the mesh's
    `mesh_pieces`, when known."""
    v, f = np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64)
    count, label = pieces = mesh_pieces(f, len(v)) if pieces is None else pieces
    centre = piece_means(v, pieces)
    a, b, c = (v[f[:, i]] - centre[label[f[:, 0]]] for i in range(3))
    return np.bincount(label[f[:, 0]], np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0, count)


def piece_means(values: ArrayLike, pieces: tuple[int, np.ndarray]) -> np.ndarray:
    """The mean over each piece's vertices (``pieces``: `mesh_pieces`) of per-vertex
    ``values`` (V,) or (V, k): (count,) or (count, k)."""
    count, label = pieces
    v = np.asarray(values, dtype=float)
    size = np.bincount(label, minlength=count)
    if v.ndim == 1:
        return np.bincount(label, v, count) / size
    return np.stack([np.bincount(label, v[:, a], count) for a in range(v.shape[1])],
                    axis=1) / size[:, None]


@overload
def mesh_area(vertices: ArrayLike, faces: ArrayLike, per_face: Literal[False] = False) -> float: ...


@overload
def mesh_area(vertices: ArrayLike, faces: ArrayLike, per_face: Literal[True]) -> np.ndarray: ...


def mesh_area(vertices: ArrayLike, faces: ArrayLike, per_face: bool = False) -> np.ndarray | float:

    """Total (or per-face) area of a triangle mesh."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return np.zeros(0) if per_face else 0.0
    ar = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    return ar if per_face else float(ar.sum())


def material_topology(levelset: ArrayLike) -> tuple[int, int]:
    """(pieces, Euler characteristic) of the material ``levelset < 0``, its nodes joined
    across faces, edges and corners (`skimage.measure.euler_number`): what changes when
    parts meet or part, or a hole opens or closes. Read off the nodes rather than off the
    surface marching cubes makes, whose corners where the field is exactly zero on a node
    can leave a closed part with an odd V - E + F."""
    from scipy import ndimage
    from skimage.measure import euler_number

    inside = np.asarray(levelset) < 0
    full = np.ones((3,) * inside.ndim, dtype=bool)
    return (int(ndimage.label(inside, structure=full)[1]),
            int(euler_number(inside, connectivity=3)))


def loop_area(loop: ArrayLike) -> float:
    """Signed area of a closed 2D loop (M, 2) (shoelace; positive counter-clockwise)."""
    p = np.asarray(loop, dtype=float)
    x, y = p[:, 0], p[:, 1]
    return float(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def enclosed_volume(levelset: ArrayLike, grid: Grid, level: float = 0.0) -> float:
    """Volume (3D) or area (2D) inside the surface `extract_surface` gives, world units."""
    surf = extract_surface(levelset, grid, level)
    if grid.dim == 3:
        return mesh_volume(*surf)
    return float(sum(loop_area(loop) for loop in surf))


def extract_surface(levelset: ArrayLike, grid: Grid,
                    level: float = 0.0) -> tuple[np.ndarray, np.ndarray] | list[np.ndarray]:
    """Zero set of ``levelset`` in world coordinates.

    Parameters
    ----------
    levelset : ndarray, grid.shape
        Signed field, negative inside.
    grid : Grid
    level : float
        Iso-value (0 for the surface).

    Returns
    -------
    3D grids: (vertices, faces)
        vertices (V, 3) float world coordinates, faces (F, 3) int, outward
        winding. Both empty (shapes (0, 3)) when the field does not cross
        ``level``.
    2D grids: list of (M, 2) arrays
        Closed loops in world coordinates (last point not repeated),
        counter-clockwise around the inside. Empty list when nothing crosses.
    """
    if not isinstance(grid, Grid):
        raise ValueError("grid must be a keyframe_implicit.core.Grid.")
    h = grid.spacing
    if grid.dim == 3:
        f = grid.check_field(levelset, "levelset")
        level = float(level)
        lowest = float(f.min()) - level
        if not lowest < 0.0:
            return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
        from skimage.measure import marching_cubes

        padded, corner = _padded_box(f, level, lowest, h)
        verts, faces, _, _ = marching_cubes(padded, level=0.0, spacing=(h, h, h),
                                            allow_degenerate=False)
        verts = verts + (grid.origin + h * (corner - 1))
        faces = faces.astype(np.int64)
        # skimage's winding depends on its gradient convention: make normals point outward
        if mesh_volume(verts, faces) < 0:
            faces = faces[:, ::-1].copy()
        return verts, faces
    from skimage.measure import find_contours

    f = grid.check_field(levelset, "levelset") - float(level)
    padded = np.pad(f, 1, mode="constant", constant_values=float(np.abs(f).max()) + h)
    origin = grid.origin - h
    if not (padded.min() < 0.0 < padded.max()):
        return []
    loops = []
    # "low": loops wind counter-clockwise (in (x, y) = (i, j)) around the negative region
    for c in find_contours(padded, 0.0, positive_orientation="low"):
        if len(c) > 1 and np.allclose(c[0], c[-1]):
            c = c[:-1]
        if len(c) < 3:
            continue
        loops.append(np.ascontiguousarray(origin + h * c))
    return loops


def _padded_box(f: np.ndarray, level: float, lowest: float,
                h: float) -> tuple[np.ndarray, np.ndarray]:

    """``f - level`` over the box of nodes that marching cubes needs, closed by padding
    (``lowest``: min(f) - level, which the caller has).

    The field is padded by one node of a positive value (max |f - level| + h) so that
    a body touching the grid's faces gets a closed surface. Only cells with a corner
    at or below ``level`` can hold surface, so only the box around those nodes, one
    node wider on each side, is made: on a grid much larger than the body this is a
    small part of the padded grid. Returns the box and the padded-grid index of its
    first node (the grid's own node index is one less).
    """
    level_or_below = f <= level
    first, last = [], []
    for a in range(f.ndim):
        rows = np.flatnonzero(level_or_below.any(axis=tuple(b for b in range(f.ndim) if b != a)))
        first.append(rows[0])
        last.append(rows[-1] + 2)  # padded index of the node after the last one
    del level_or_below
    corner = np.array(first)
    pad = max(abs(float(f.max()) - level), abs(lowest)) + h
    box = np.full(tuple(np.array(last) - corner + 1), pad)
    lo = np.maximum(corner - 1, 0)  # the grid nodes inside the box
    hi = np.minimum(np.array(last) - 1, np.array(f.shape) - 1)
    box[tuple(slice(l + 1 - c, u + 2 - c) for l, u, c in zip(lo, hi, corner))] = \
        f[tuple(slice(l, u + 1) for l, u in zip(lo, hi))] - level
    return box, corner
