"""Measures of contact on the meshes a bake ships (vectorised numpy / scipy).

A frame is a triangle mesh (V (n, 3), F (m, 3)) with outward normals, as the bake outputs
it (`shipped_frames`). Lengths are in the bake's cell h unless a docstring says otherwise.

- `mesh_pieces`: the frame's connected pieces, each with its signed volume (negative: a
  closed inner surface, a bubble) and genus.
- `fold_angles`, `neck_fold`: how sharply the surface folds inwards at its concave edges.
- `contact_frame`: the first frame on which parts that were apart touch.
- `rigid_path`: a part's own motion, from its feature points.
- `pre_contact_movement`: how far a part's surface moved, where the other part is about to
  arrive, before they touch.
- `agreement_points`, `stillness`: how far the surface moved where both keyframes agree.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage, sparse
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from keyframe_implicit.core.base.sampling import sample
from keyframe_implicit.core.surface.quality import mesh_distance

if TYPE_CHECKING:
    from keyframe_implicit.core import Animation, Grid

__all__ = ["Pieces", "shipped_frames", "mesh_pieces", "fold_angles", "neck_fold",
           "contact_frame", "rigid_path", "part_fields", "piece_owners", "pre_contact_movement",
           "agreement_points", "stillness"]


def shipped_frames(animation: Animation) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per frame, the (vertices, faces) the bake ships in the output it chose
    (``stats["output"]``): each frame's mesh in a mesh sequence (`Animation.sequence_frame`:
    the tracked template before a topology change, else the frame's own surface), the
    tracked template's vertices with its faces for shape keys."""
    if animation.stats.get("output") == "mesh_sequence":
        return [tuple(np.asarray(a, t) for a, t in zip(animation.sequence_frame(i),
                                                       (float, np.int64)))
                for i in range(len(animation.surfaces))]
    faces = np.asarray(animation.faces, np.int64)
    return [(np.asarray(v, float), faces) for v in animation.vertices]


@dataclass
class Pieces:
    """The connected pieces of one frame's mesh.

    labels : (n,) int, each vertex's piece (0..count - 1).
    volumes : (count,) signed volumes, world units^3 (negative: an inner surface).
    genus : (count,) int, each closed piece's genus, (2 - Euler characteristic) / 2.
    """

    labels: np.ndarray
    volumes: np.ndarray
    genus: np.ndarray

    @property
    def outer(self) -> np.ndarray:
        """Indices of the pieces that enclose material (positive volume)."""
        return np.flatnonzero(self.volumes > 0)

    @property
    def bubbles(self) -> np.ndarray:
        """Indices of the closed inner surfaces (negative volume): voids in the material."""
        return np.flatnonzero(self.volumes < 0)


def mesh_pieces(vertices: ArrayLike, faces: ArrayLike) -> Pieces:
    """The pieces of a mesh: vertices joined by faces' edges (`Pieces`).

    Volume is the divergence theorem's sum over each piece's faces; genus comes from
    V - E + F of each piece, so a torus reads 1 and a ball 0 (closed manifold pieces).
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    n = len(v)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    graph = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, labels = sparse.csgraph.connected_components(graph, directed=False)
    face_piece = labels[f[:, 0]]
    cross = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])) / 6.0
    volumes = np.bincount(face_piece, cross, minlength=count)
    unique = np.unique(np.sort(edges, axis=1), axis=0)
    chi = (np.bincount(labels, minlength=count) - np.bincount(labels[unique[:, 0]], minlength=count)
           + np.bincount(face_piece, minlength=count))
    used = np.bincount(face_piece, minlength=count) > 0  # loose vertices are no piece
    keep = np.flatnonzero(used)
    remap = np.full(count, -1)
    remap[keep] = np.arange(len(keep))
    return Pieces(remap[labels], volumes[keep], ((2 - chi[keep]) // 2).astype(int))


def fold_angles(vertices: ArrayLike, faces: ArrayLike, min_area: float = 0.0) -> np.ndarray:
    """The fold at every concave edge of a mesh, in degrees: the angle between the normals
    of the edge's two faces (0 flat, 180 folded flat onto itself).

    An edge is concave where the far vertex of one face lies outside the other face's
    plane (on its normal's side): the surface folds towards the outside there, as at the
    crease where two balls meet. Only edges with exactly two faces, both of area above
    ``min_area`` (world units^2), are measured; sliver faces have no reliable normal.
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area = 0.5 * np.linalg.norm(normal, axis=1)
    unit = normal / np.maximum(2 * area, 1e-300)[:, None]
    # each face's three edges with the vertex opposite: (a, b, opposite, face)
    rows = np.concatenate([np.stack([f[:, i], f[:, (i + 1) % 3], f[:, (i + 2) % 3],
                                     np.arange(len(f))], axis=1) for i in range(3)])
    _, edge, count = np.unique(np.sort(rows[:, :2], axis=1), axis=0, return_inverse=True,
                               return_counts=True)
    edge = edge.reshape(-1)
    two = count[edge] == 2  # edges of exactly two faces, their two rows made adjacent
    rows = rows[two][np.argsort(edge[two], kind="stable")]
    first, second = rows[0::2], rows[1::2]
    ok = (area[first[:, 3]] > min_area) & (area[second[:, 3]] > min_area)
    first, second = first[ok], second[ok]
    n1, n2 = unit[first[:, 3]], unit[second[:, 3]]
    cos = np.clip(np.einsum("ij,ij->i", n1, n2), -1.0, 1.0)
    outside = np.einsum("ij,ij->i", v[second[:, 2]] - v[first[:, 0]], n1) > 0
    return np.degrees(np.arccos(cos[outside]))


def neck_fold(vertices: ArrayLike, faces: ArrayLike, h: float,
              percentile: float = 99.0) -> tuple[float, float]:
    """(``percentile``, max) of `fold_angles` over a frame's concave edges, in degrees,
    faces below 1e-4 h^2 left out; (0, 0) without a concave edge. A crease where two
    solids interpenetrate reads near 180, a neck rounded over a few cells a few tens."""
    folds = fold_angles(vertices, faces, 1e-4 * h * h)
    if folds.size == 0:
        return 0.0, 0.0
    return float(np.percentile(folds, percentile)), float(folds.max())


def contact_frame(frames: Sequence[tuple[np.ndarray, np.ndarray]], parts: int, h: float,
                  touch: float = 1.0, pieces: Sequence[Pieces] | None = None) -> int | None:
    """Index of the first frame on which parts that were apart touch: it has fewer pieces
    enclosing material than ``parts`` (the keyframe's), or two of its pieces come within
    ``touch`` h of each other (nearest vertices). None if that never happens. ``pieces``:
    the frames' `mesh_pieces` when the caller has them."""
    for i, (v, f) in enumerate(frames):
        pieces_i = mesh_pieces(v, f) if pieces is None else pieces[i]
        outer = pieces_i.outer
        if len(outer) < parts:
            return i
        trees = [cKDTree(v[pieces_i.labels == k]) for k in outer]
        for a in range(len(trees)):
            for b in range(a + 1, len(trees)):
                if trees[a].query(trees[b].data, distance_upper_bound=touch * h)[0].min() <= touch * h:
                    return i
    return None


def rigid_path(points_a: ArrayLike, points_b: ArrayLike) -> tuple[Callable, float]:
    """A part's own motion from its feature points: the rigid fit (Kabsch) of ``points_a``
    (N, 3) onto ``points_b``, travelled at constant speed: the rotation's angle grows
    linearly about its axis through the points' centroid, which moves on a straight line.
    Returns (motion, residual): ``motion(s)`` is (R (3, 3), t (3,)), x -> R x + t at time
    s; ``residual`` the fit's largest miss, world units (large: the keyframes deform the
    part)."""
    a, b = np.asarray(points_a, float), np.asarray(points_b, float)
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    full = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    residual = float(np.max(np.linalg.norm((a - ca) @ full.T + cb - b, axis=1)))
    rotvec = Rotation.from_matrix(full).as_rotvec()

    def motion(s):
        R = Rotation.from_rotvec(s * rotvec).as_matrix()
        return R, ca + s * (cb - ca) - R @ ca

    return motion, residual


def part_fields(phi: np.ndarray, grid: Grid) -> tuple[list[np.ndarray], np.ndarray]:
    """Each part of keyframe field ``phi`` (6-connected inside nodes) as a field of its own,
    the other parts' inside made outside (|phi|), and each part's centroid: (fields,
    centroids (P, 3))."""
    labels, n = ndimage.label(np.asarray(phi) < 0)
    points = grid.points()
    fields = [np.where((labels > 0) & (labels != k), np.abs(phi), phi) for k in range(1, n + 1)]
    centroids = np.array([points[labels == k].mean(axis=0) for k in range(1, n + 1)])
    return fields, centroids


def _footprint(q, own, other, reach):
    """Which points q (in the part's keyframe position) lie where the other part arrives:
    on the own centroid's half facing the other's centroid, within ``reach`` of the line
    joining the two centroids."""
    u = (other - own) / np.linalg.norm(other - own)
    facing = (q - own) @ u > 0
    off = (q - other) - np.outer((q - other) @ u, u)
    return facing & (np.linalg.norm(off, axis=1) < reach)


def piece_owners(vertices: ArrayLike, pieces: Pieces, places: ArrayLike) -> np.ndarray:
    """The part (0-based) each vertex belongs to: its piece's, the part whose place
    (``places`` (P, 3), e.g. each part's centroid carried along its motion) is nearest to
    the piece's vertices' mean. Before contact every part is a piece of its own."""
    v = np.asarray(vertices, float)
    means = np.array([v[pieces.labels == k].mean(axis=0) for k in range(len(pieces.volumes))])
    nearest = np.argmin(np.linalg.norm(means[:, None] - np.asarray(places)[None], axis=2), axis=1)
    return nearest[pieces.labels]


def pre_contact_movement(frames: Sequence[tuple[np.ndarray, np.ndarray]], times: ArrayLike,
                         fine: Grid, part_phis: Sequence[np.ndarray], centroids: np.ndarray,
                         paths: Sequence[Callable | None], carried: Sequence[Callable],
                         h: float, reaches: Sequence[float],
                         pieces: Sequence[Pieces] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Before contact, how far each part's surface moved where another part is about to
    arrive, against its own keyframe carried by its own motion, in h.

    A frame's vertices belong to parts by their pieces (`piece_owners`, each part's
    centroid at ``carried[p](s)``). A part's vertices are taken back along its motion
    (``paths[p](s)`` = (R, t), `rigid_path`) into keyframe A, where their movement is
    |the part's own distance| (``part_phis[p]``, read multilinearly on ``fine``). Of them,
    those in its footprint count (`_footprint`: on its half facing another part, within
    ``reaches[p]`` of the line between the parts' ``centroids``). A part whose
    ``paths[p]`` is None (its keyframes deform it) is not measured.

    ``frames`` (vertices, faces) are the frames before contact (`contact_frame`), at
    ``times`` (``pieces``: their `mesh_pieces` when the caller has them). Returns (largest movement in the footprint per part (P,), the worst frame's
    mean movement over all of each part's vertices (P,)), in h; NaN for parts not measured
    or without frames.
    """
    P = len(part_phis)
    worst, follow = np.full(P, np.nan), np.full(P, np.nan)
    for i, ((v, f), s) in enumerate(zip(frames, times)):
        owner = piece_owners(v, mesh_pieces(v, f) if pieces is None else pieces[i],
                             [c(s) for c in carried])
        for p in range(P):
            mine = owner == p
            if paths[p] is None or not mine.any():
                continue
            R, t = paths[p](s)
            q = (v[mine] - t) @ R  # R^T (v - t): back in keyframe A
            d = np.abs(sample(part_phis[p], fine, q, outside="distance")) / h
            follow[p] = np.nanmax([follow[p], d.mean()])
            near = np.zeros(len(q), bool)
            for k, c in enumerate(centroids):
                if k != p:
                    near |= _footprint(q, centroids[p], c, reaches[p])
            if near.any():
                worst[p] = np.nanmax([worst[p], d[near].max()])
    return worst, follow


def agreement_points(vertices_a: ArrayLike, phi_a: np.ndarray, phi_b: np.ndarray, fine: Grid,
                     features: tuple[ArrayLike, ArrayLike], h: float,
                     reading: tuple[np.ndarray, np.ndarray] | None = None,
                     radius: float = 6.0, agree: float = 0.1, limit: int = 4000) -> np.ndarray:
    """Points where both keyframes agree and nothing asks for motion: vertices of keyframe
    A's mesh within ``agree`` h of B's surface (|phi_b| read on ``fine``), farther than
    ``radius`` h from every feature point that moves (by more than h/2, at either end) and
    from every node where the keyframes' materials differ (inside one, outside the other).
    With ``reading`` (vertices, faces: keyframe A's surface as the bake's grid holds it),
    only where that is within ``agree`` h too: a grid rounds a box's edges off on every
    frame alike, which is no motion. At most ``limit`` points, evenly spread over the
    list; (0, 3) if none."""
    v = np.asarray(vertices_a, float)
    keep = np.abs(sample(phi_b, fine, v, outside="distance")) < agree * h
    fa, fb = (np.asarray(x, float) for x in features)
    moving = np.linalg.norm(fb - fa, axis=1) > 0.5 * h
    anchors = np.vstack([fa[moving], fb[moving], fine.points()[(phi_a < 0) != (phi_b < 0)]])
    if len(anchors):
        keep &= cKDTree(anchors).query(v, distance_upper_bound=radius * h)[0] > radius * h
    if reading is not None and keep.any():
        keep[keep] = mesh_distance(v[keep], *reading) < agree * h
    v = v[keep]
    return v[np.linspace(0, len(v) - 1, min(limit, len(v))).astype(int)] if len(v) else v


def stillness(frames: Sequence[tuple[np.ndarray, np.ndarray]], points: np.ndarray,
              h: float) -> float:
    """Largest distance, over ``frames`` (vertices, faces), from the agreement ``points``
    (`agreement_points`) to the frame's surface, in h; NaN without points: how far the
    in-between surface moved where both keyframes agree."""
    if len(points) == 0:
        return float("nan")
    return float(max(mesh_distance(points, v, f).max() for v, f in frames) / h)
