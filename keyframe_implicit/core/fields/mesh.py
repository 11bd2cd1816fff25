"""Keyframe meshes made fit for measuring: vertices checked, faces triangulated,
degenerate triangles dropped, and each connected part's faces oriented alike.

Artists' meshes are open, self-intersecting, made of overlapping loose parts and
contain degenerate faces; the distance field (`sdf`) needs triangles whose normals
agree within each part, or the winding number of a part cancels to ~0 and its inside
disappears (docs/method.md, section 3). What such a mesh encloses is measured in
`measure`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["check_vertices", "triangulate", "clean_triangles", "orient_faces"]


def check_vertices(vertices: ArrayLike, dim: int = 3) -> np.ndarray:
    """``vertices`` as a float (N, dim) array, or ValueError saying what to fix."""
    try:
        v = np.asarray(vertices, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"vertices must be a numeric (N, {dim}) array: {exc}") from None
    if v.ndim != 2 or v.shape[1] != dim:
        raise ValueError(
            f"vertices must have shape (N, {dim}), got {v.shape}; pass one row of "
            f"{dim} coordinates per vertex.")
    if v.shape[0] == 0:
        raise ValueError("vertices is empty; the mesh needs vertices and faces.")
    bad = ~np.all(np.isfinite(v), axis=1)
    if bad.any():
        raise ValueError(
            f"{int(bad.sum())} vertices have NaN or infinite coordinates (first: vertex "
            f"{int(np.flatnonzero(bad)[0])}); fix or delete them before baking.")
    return v


def triangulate(faces: ArrayLike, n_vertices: int) -> np.ndarray:
    """Triangles (T, 3) from triangles, quads or polygons, as fans around each first corner.

    Parameters
    ----------
    faces : (F, k) int array_like, k >= 3, or sequence of index sequences (ragged)
    n_vertices : int
        Number of vertices, for the index range check.

    Raises
    ------
    ValueError
        No faces, faces with fewer than 3 corners, non-integer or out-of-range indices.
    """
    if faces is None:
        raise ValueError("faces is None; pass (F, 3) triangles or a list of polygons.")
    groups = []  # (F_k, k) int arrays
    arr = None
    if isinstance(faces, np.ndarray) and faces.dtype != object:
        arr = faces
    else:
        try:
            arr = np.asarray(faces)
            if arr.dtype == object or arr.ndim != 2:
                arr = None
        except ValueError:  # ragged lists on newer numpy
            arr = None
    if arr is not None:
        if arr.ndim != 2:
            raise ValueError(f"faces must be (F, k) indices or a list of polygons, got shape "
                             f"{arr.shape}.")
        if arr.shape[0] == 0:
            raise ValueError("the mesh has no faces; a signed distance needs a surface.")
        groups.append(_as_index(arr))
    else:
        faces = list(faces)
        if len(faces) == 0:
            raise ValueError("the mesh has no faces; a signed distance needs a surface.")
        lengths = np.fromiter(map(len, faces), dtype=np.int64, count=len(faces))
        flat = _as_index(np.concatenate([np.asarray(f).reshape(-1) for f in faces]))
        offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]])
        for k in np.unique(lengths):  # a handful of distinct polygon sizes
            sel = offsets[lengths == k]
            groups.append(flat[sel[:, None] + np.arange(k)[None, :]])
    tris = []
    for g in groups:
        k = g.shape[1]
        if k < 3:
            raise ValueError(f"faces with {k} corners found; every face needs at least 3 "
                             f"vertex indices (drop loose edges and points).")
        lo, hi = g.min(), g.max()
        if lo < 0 or hi >= n_vertices:
            raise ValueError(
                f"face indices range over [{lo}, {hi}] but there are {n_vertices} vertices; "
                f"indices must lie in [0, {n_vertices - 1}].")
        for i in range(1, k - 1):  # fan: (0, i, i+1)
            tris.append(np.stack([g[:, 0], g[:, i], g[:, i + 1]], axis=1))
    return np.concatenate(tris, axis=0)


def _as_index(a):
    a = np.asarray(a)
    if a.dtype.kind in "iu":
        return a.astype(np.int64)
    if a.dtype.kind == "f":
        if not np.all(np.isfinite(a)) or np.any(a != np.round(a)):
            raise ValueError("face indices must be whole numbers; pass integer vertex indices.")
        return a.astype(np.int64)
    raise ValueError(f"face indices must be integers, got dtype {a.dtype}.")


def clean_triangles(v: np.ndarray, tris: np.ndarray, stats: dict[str, int] | None) -> np.ndarray:
    """Drop zero-area triangles (relative to the mesh size); raise if none is left."""
    a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    good = area2 > 1e-12 * max(diag, 1e-300) ** 2
    n_bad = int((~good).sum())
    if stats is not None:
        stats["triangles"] = int(good.sum())
        stats["degenerate_triangles"] = n_bad
    if not good.any():
        raise ValueError(
            f"all {len(tris)} triangles have zero area (collapsed or repeated vertices); "
            f"the mesh has no surface to measure distance to.")
    return tris[good]


def orient_faces(vertices: np.ndarray, tris: ArrayLike) -> tuple[np.ndarray, int, int]:
    """Make the triangles of every connected part face the same way, outward where repaired.

    The winding number reads a closed part as inside only when its faces agree
    (a sphere with every other face reversed has w ~ 0 everywhere). Two
    triangles sharing a manifold edge (used by exactly two triangles) agree when
    they run along it in opposite directions. Orientations are propagated
    through a double cover of the face graph -- node (f, s) is face f flipped
    (s = 1) or not, an agreeing edge joins (f, s)-(g, s), a disagreeing one
    (f, s)-(g, 1 - s) -- whose connected components (`scipy.sparse.csgraph`)
    give each part its two consistent orientations at once, without a walk over
    the faces. A part whose (f, 0) and (f, 1) fall in one component is
    non-orientable (Moebius strip, or made inconsistent by its non-manifold
    edges) and is left as it is. A consistent part is left as it is (so an
    inner shell facing its cavity stays a cavity); a part that needed repair is
    turned outward, by the sign of its volume about its centroid.

    Parameters
    ----------
    vertices : (V, 3) float array
    tris : (T, 3) int array

    Returns
    -------
    tris : (T, 3) int array, reoriented.
    disagreeing : int
        Faces that disagreed with the rest of their part (the smaller side of
        each repaired part).
    non_orientable : int
        Faces in parts that cannot be oriented consistently.
    """
    tris = np.asarray(tris, dtype=np.int64)
    nt = len(tris)
    a = tris.reshape(-1)
    b = tris[:, [1, 2, 0]].reshape(-1)
    face = np.repeat(np.arange(nt), 3)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    order = np.lexsort((hi, lo))
    lo, hi, face, forward = lo[order], hi[order], face[order], (a < b)[order]
    same = (lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1])
    run_start = np.flatnonzero(np.concatenate([[True], ~same]))
    run_len = np.diff(np.append(run_start, len(lo)))
    pair = run_start[run_len == 2]  # manifold edges: first of their two half-edges
    f, g = face[pair], face[pair + 1]
    agree = forward[pair] != forward[pair + 1]
    # double cover: node f (not flipped) and nt + f (flipped)
    src = np.concatenate([f, f + nt])
    dst = np.concatenate([np.where(agree, g, g + nt), np.where(agree, g + nt, g)])
    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(2 * nt, 2 * nt))
    _, label = connected_components(graph, directed=False)
    keep_label, flip_label = label[:nt], label[nt:]
    bad = keep_label == flip_label
    part = np.minimum(keep_label, flip_label)
    flip = (keep_label > flip_label) & ~bad  # one of the two consistent choices per part
    size = np.bincount(part, minlength=2 * nt)
    n_flip = np.bincount(part, weights=flip, minlength=2 * nt)
    fewer = n_flip > size / 2  # the choice that flips fewer faces
    flip ^= fewer[part] & ~bad
    n_flip = np.where(fewer, size - n_flip, n_flip)
    repaired = (n_flip > 0)[part] & ~bad
    if repaired.any():  # turn each repaired part outward: volume about its centroid
        out = np.where(flip[:, None], tris[:, ::-1], tris)
        p0, p1, p2 = vertices[out[:, 0]], vertices[out[:, 1]], vertices[out[:, 2]]
        tri_centre = (p0 + p1 + p2) / 3.0
        c = np.stack([np.bincount(part, weights=tri_centre[:, i], minlength=2 * nt)
                      for i in range(3)], axis=1)[part] / size[part, None]
        vol = np.einsum("ij,ij->i", p0 - c, np.cross(p1 - c, p2 - c))
        inward = np.bincount(part, weights=vol, minlength=2 * nt) < 0
        flip ^= inward[part] & repaired
    out = np.where(flip[:, None], tris[:, ::-1], tris)
    return out, int(n_flip[np.unique(part[repaired])].sum()), int(bad.sum())
