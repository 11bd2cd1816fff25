"""Analytic shapes the examples are built from (pure numpy / scikit-image, no bpy).

Meshes made directly (`icosphere`, `uv_sphere`), signed distance primitives (negative
inside; ``p`` is (..., 3)), the marching-cubes mesher of their zero set (`mesh_of`), and
the search that gives a mesh a target volume (`match_volume`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .core.surface.extract import mesh_volume

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

__all__ = ["MESH_STEP", "icosphere", "uv_sphere", "rotation", "rigid_motion", "sphere_sdf",
           "capsule_sdf", "round_box_sdf", "round_cylinder_sdf", "smooth_union", "mesh_of",
           "match_volume"]

#: Grid step of the marching-cubes meshes (metres): ~1-4 thousand triangles per keyframe.
MESH_STEP = 0.09


def icosphere(n_sub: int, radius: float = 1.0,
              center: ArrayLike = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Icosahedron subdivided n_sub times, projected on the sphere, outward faces."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    v /= np.linalg.norm(v, axis=1)[:, None]
    for _ in range(n_sub):
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        ue, inv = np.unique(e, axis=0, return_inverse=True)
        mid = v[ue[:, 0]] + v[ue[:, 1]]
        mid /= np.linalg.norm(mid, axis=1)[:, None]
        m = len(v) + inv.reshape(3, -1).T
        v = np.concatenate([v, mid])
        a, b, c = f.T
        ab, bc, ca = m.T
        f = np.concatenate([np.stack(x, 1) for x in
                            ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])])
    return v * radius + np.asarray(center), f


def uv_sphere(n_lat: int, radius: float = 1.0,
              bump: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
              ) -> tuple[np.ndarray, list[list[np.int64]]]:

    """A UV sphere: quads, and triangle fans at the poles; ``bump(theta, phi)`` adds to r.

    Returns vertices (V, 3) and polygons (a list of index lists, quads first).
    """
    n_lon = 2 * n_lat
    th = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    r = radius + (0.0 if bump is None else bump(T, P))
    ring = np.stack([r * np.sin(T) * np.cos(P), r * np.sin(T) * np.sin(P), r * np.cos(T)], -1)
    v = np.concatenate([[[0, 0, radius]], ring.reshape(-1, 3), [[0, 0, -radius]]])
    idx = 1 + np.arange(n_lat - 1)[:, None] * n_lon + np.arange(n_lon)[None]
    nxt = np.roll(idx, -1, axis=1)
    quads = np.stack([idx[:-1], idx[1:], nxt[1:], nxt[:-1]], -1).reshape(-1, 4)
    top = np.stack([np.zeros(n_lon, int), idx[0], nxt[0]], -1)
    bottom = np.stack([np.full(n_lon, len(v) - 1), nxt[-1], idx[-1]], -1)
    return v, [list(q) for q in quads] + [list(t) for t in top] + [list(t) for t in bottom]


def rotation(axis: ArrayLike, degrees: float) -> np.ndarray:
    """3x3 rotation matrix about `axis` (any non-zero 3-vector) by `degrees` (right hand)."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    a = np.radians(degrees)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(a) * k + (1.0 - np.cos(a)) * (k @ k)


# signed distance primitives (negative inside); p is (..., 3)
def sphere_sdf(p: np.ndarray, centre: ArrayLike, radius: float) -> np.ndarray:
    """Signed distance to a sphere."""
    return np.linalg.norm(p - np.asarray(centre, float), axis=-1) - radius


def capsule_sdf(p: np.ndarray, a: ArrayLike, b: ArrayLike, radius: float) -> np.ndarray:
    """Signed distance to a capsule: the segment a-b grown by ``radius``."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    ab = b - a
    t = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1) - radius


def round_box_sdf(p: np.ndarray, centre: ArrayLike, half: ArrayLike, radius: float) -> np.ndarray:
    """Signed distance to a box of half extents ``half`` with edges rounded by ``radius``."""
    q = np.abs(p - np.asarray(centre, float)) - (np.asarray(half, float) - radius)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(q.max(axis=-1), 0.0)
    return outside + inside - radius


def round_cylinder_sdf(p: np.ndarray, centre: ArrayLike, radius: float, half_height: float,
                       rounding: float) -> np.ndarray:
    """Vertical (z) cylinder with rounded rims."""
    d = p - np.asarray(centre, float)
    q = np.stack([np.hypot(d[..., 0], d[..., 1]) - (radius - rounding),
                  np.abs(d[..., 2]) - (half_height - rounding)], axis=-1)
    return (np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)
            - rounding)


def smooth_union(d1: np.ndarray, d2: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum: blends two distance fields over a band of width k."""
    h = np.clip(0.5 + 0.5 * (d2 - d1) / k, 0.0, 1.0)
    return d2 * (1.0 - h) + d1 * h - k * h * (1.0 - h)


def mesh_of(sdf: Callable[[np.ndarray], np.ndarray], lo: ArrayLike, hi: ArrayLike,
            step: float = MESH_STEP) -> tuple[np.ndarray, np.ndarray]:
    """Mesh the zero level set of `sdf` inside the box [lo, hi] by marching cubes.

    Returns closed, outward-wound (V, 3) float64 vertices and (F, 3) int64 faces. The box is
    padded by two steps so the surface never touches the grid boundary (closed mesh).
    """
    from skimage.measure import marching_cubes

    lo = np.asarray(lo, float) - 2 * step
    hi = np.asarray(hi, float) + 2 * step
    n = np.ceil((hi - lo) / step).astype(int) + 1
    axes = [lo[i] + step * np.arange(n[i]) for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    field_ = sdf(pts)
    # keep nodes off the exact zero so marching cubes makes no degenerate triangles
    field_ = np.where(np.abs(field_) < 1e-7, 1e-7, field_)
    verts, faces, _, _ = marching_cubes(field_, level=0.0, spacing=(step, step, step))
    verts = verts.astype(np.float64) + lo
    faces = faces.astype(np.int64)
    if mesh_volume(verts, faces) < 0:
        faces = faces[:, ::-1].copy()
    return verts, faces


def match_volume(make: Callable[[float], tuple[np.ndarray, np.ndarray]], target: float,
                 p0: float, p1: float, tol: float = 1e-4,
                 iterations: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Secant search on a scalar shape parameter so the mesh made by `make(p)` has volume `target`.

    `make(p)` returns (vertices, faces). Stops at relative volume error `tol`.
    """
    v0 = mesh_volume(*make(p0)) - target
    mesh = make(p1)
    v1 = mesh_volume(*mesh) - target
    for _ in range(iterations):
        if abs(v1) <= tol * target or v1 == v0:
            break
        p0, p1 = p1, p1 - v1 * (p1 - p0) / (v1 - v0)
        v0 = v1
        mesh = make(p1)
        v1 = mesh_volume(*mesh) - target
    return mesh


def rigid_motion(points: ArrayLike, rot: np.ndarray, centre: ArrayLike,
                 move: ArrayLike) -> np.ndarray:

    """Rotate `points` by `rot` about `centre`, then translate by `move`."""
    centre = np.asarray(centre, float)
    return (np.asarray(points, float) - centre) @ rot.T + centre + np.asarray(move, float)
