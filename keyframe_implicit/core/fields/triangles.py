"""Exact point-triangle distances and closest points, vectorised over (point, triangle)
pairs: the kernel of the distance field's exact shell and of the surface stage's
closest-point queries."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

__all__ = ["Triangles", "corner_radius", "nearest_candidates", "point_triangle_distance",
           "proper", "row_dot"]


def row_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of two (N, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def corner_radius(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Per triangle (corners a, b, c, each (T, 3)), the largest corner distance from the
    centroid: the triangle lies in the disc of that radius around it."""
    cen = (a + b + c) / 3.0
    return np.sqrt(np.maximum.reduce([row_dot(a - cen, a - cen), row_dot(b - cen, b - cen),
                                      row_dot(c - cen, c - cen)]))


class Triangles:
    """Per-triangle constants for the vectorised distance kernel (component arrays)."""

    def __init__(self, v: np.ndarray, tris: np.ndarray) -> None:
        a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
        e0, e1 = b - a, c - a
        e2 = c - b
        n = np.cross(e0, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            # a degenerate (zero-area) triangle gets a NaN normal and Gram inverse: its
            # "inside" test is then False and `distance` measures it by its edges
            n /= np.linalg.norm(n, axis=1)[:, None]
            self.inv = 1.0 / (row_dot(e0, e0) * row_dot(e1, e1) - row_dot(e0, e1) ** 2)
        self.a = [np.ascontiguousarray(a[:, i]) for i in range(3)]
        self.e0 = [np.ascontiguousarray(e0[:, i]) for i in range(3)]
        self.e1 = [np.ascontiguousarray(e1[:, i]) for i in range(3)]
        self.n = [np.ascontiguousarray(n[:, i]) for i in range(3)]
        self.d00 = row_dot(e0, e0)
        self.d01 = row_dot(e0, e1)
        self.d11 = row_dot(e1, e1)
        self.d22 = row_dot(e2, e2)
        self.e02 = row_dot(e0, e2)
        cen = (a + b + c) / 3.0
        self.cen = [np.ascontiguousarray(cen[:, i]) for i in range(3)]
        self.rad = corner_radius(a, b, c)

    def lower_bound(self, p: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Cheap lower bound of the distance from p (P, 3) to triangles t (P,).

        The triangle lies in its plane inside the disc of radius ``rad`` around its
        centroid c, so dist^2 >= (n.(p - c))^2 + max(0, |lateral offset| - rad)^2.
        """
        vx = p[:, 0] - self.cen[0][t]
        vy = p[:, 1] - self.cen[1][t]
        vz = p[:, 2] - self.cen[2][t]
        pn = vx * self.n[0][t] + vy * self.n[1][t] + vz * self.n[2][t]
        pn2 = pn * pn
        lat = np.sqrt(np.maximum(vx * vx + vy * vy + vz * vz - pn2, 0.0)) - self.rad[t]
        lat = np.maximum(lat, 0.0)
        return np.sqrt(pn2 + lat * lat)

    def distance(self, p: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Exact distance from points p (P, 3) to triangles t (P,)."""
        return self._distance(p[:, 0], p[:, 1], p[:, 2], lambda q: q[t])

    def box_distance(self, px: np.ndarray, py: np.ndarray, pz: np.ndarray,
                     triangles: slice | np.ndarray, counts: np.ndarray) -> np.ndarray:
        """Exact distance of pairs ordered by triangle: ``counts[i]`` points (coordinate
        arrays px, py, pz) for each triangle of the slice ``triangles``."""
        return self._distance(px, py, pz, lambda q: np.repeat(q[triangles], counts))

    def _distance(self, px: np.ndarray, py: np.ndarray, pz: np.ndarray,
                  per_pair: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Ericson-style regions: the projection onto the plane has barycentric
        coordinates (u, w) from the Gram system of the edges; inside the triangle the
        distance is the plane distance, outside it is the smallest distance to the three
        edge segments. ``per_pair`` turns a per-triangle array into one per point."""
        vx = px - per_pair(self.a[0])
        vy = py - per_pair(self.a[1])
        vz = pz - per_pair(self.a[2])
        dv0 = vx * per_pair(self.e0[0]) + vy * per_pair(self.e0[1]) + vz * per_pair(self.e0[2])
        dv1 = vx * per_pair(self.e1[0]) + vy * per_pair(self.e1[1]) + vz * per_pair(self.e1[2])
        d00, d01, d11, d22 = (per_pair(q) for q in (self.d00, self.d01, self.d11, self.d22))
        inv = per_pair(self.inv)
        with np.errstate(invalid="ignore"):  # NaN on degenerate triangles: not inside
            u = (d11 * dv0 - d01 * dv1) * inv
            w = (d00 * dv1 - d01 * dv0) * inv
            inside = (u >= 0) & (w >= 0) & (u + w <= 1)
        pn = vx * per_pair(self.n[0]) + vy * per_pair(self.n[1]) + vz * per_pair(self.n[2])
        vv = vx * vx + vy * vy + vz * vz
        t0 = np.clip(dv0 / d00, 0.0, 1.0)
        dist2 = vv - t0 * (2.0 * dv0 - t0 * d00)                 # edge a-b
        t1 = np.clip(dv1 / d11, 0.0, 1.0)
        np.minimum(dist2, vv - t1 * (2.0 * dv1 - t1 * d11), out=dist2)   # edge a-c
        dv2 = (dv1 - dv0) - per_pair(self.e02)                   # (p - b).(c - b)
        wb = vv - 2.0 * dv0 + d00                                # |p - b|^2
        t2 = np.clip(dv2 / d22, 0.0, 1.0)
        np.minimum(dist2, wb - t2 * (2.0 * dv2 - t2 * d22), out=dist2)   # edge b-c
        dist2 = np.where(inside, pn * pn, dist2)
        return np.sqrt(np.maximum(dist2, 0.0))

    def closest_point(self, p: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Closest point on triangles t (P,) to points p (P, 3) (same regions as `distance`)."""
        a = np.stack([self.a[i][t] for i in range(3)], axis=1)
        e0 = np.stack([self.e0[i][t] for i in range(3)], axis=1)
        e1 = np.stack([self.e1[i][t] for i in range(3)], axis=1)
        v = p - a
        dv0, dv1 = row_dot(v, e0), row_dot(v, e1)
        d00, d01, d11 = self.d00[t], self.d01[t], self.d11[t]
        with np.errstate(invalid="ignore"):  # NaN on degenerate triangles: not inside
            u = (d11 * dv0 - d01 * dv1) * self.inv[t]
            w = (d00 * dv1 - d01 * dv0) * self.inv[t]
            inside = (u >= 0) & (w >= 0) & (u + w <= 1)
        best = a + u[:, None] * e0 + w[:, None] * e1
        bd = np.where(inside, 0.0, np.inf)
        for s0, e in ((a, e0), (a, e1), (a + e0, e1 - e0)):  # the three edges
            tt = np.clip(row_dot(p - s0, e) / row_dot(e, e), 0.0, 1.0)
            q = s0 + tt[:, None] * e
            dq = row_dot(p - q, p - q)
            use = ~inside & (dq < bd)
            best[use] = q[use]
            bd = np.where(use, dq, bd)
        return best


def point_triangle_distance(p: ArrayLike, a: ArrayLike, b: ArrayLike,
                            c: ArrayLike) -> np.ndarray:
    """Euclidean distance from points ``p`` to triangles ``(a, b, c)``, all (P, 3)."""
    p = np.asarray(p, dtype=float)
    v = np.concatenate([a, b, c])
    n = len(p)
    tris = np.stack([np.arange(n), np.arange(n, 2 * n), np.arange(2 * n, 3 * n)], axis=1)
    return Triangles(v, tris).distance(p, np.arange(n))


def proper(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Indices of the triangles (T, 3) of non-zero area: those a closest point can be on."""
    v, t = vertices, triangles
    return np.flatnonzero(np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]),
                                         axis=1) > 0)


def nearest_candidates(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
                       candidates: int) -> np.ndarray:

    """Rows (P, k) into ``triangles`` of the k = min(candidates, T) triangles whose
    centroids lie nearest each point: where the exact kernel looks for the closest one."""
    from scipy.spatial import cKDTree

    k = min(int(candidates), len(triangles))
    _, idx = cKDTree(vertices[triangles].mean(axis=1)).query(points, k=k, workers=-1)
    return idx.reshape(len(points), k)
