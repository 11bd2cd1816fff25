"""Keyframe meshes and polygons -> signed distance grids (thesis section 2.1).

The thesis samples every keyframe as a signed distance function Phi / Psi on one
regular grid, negative inside the material (PAPER-NOTES, "Notation"). Artists'
meshes are open (Suzanne's eyes), self-intersecting, made of overlapping loose
parts and contain degenerate faces, so the two halves of the job are done by
methods that do not assume a clean closed manifold:

Magnitude (`mesh_to_sdf`, steps 1-3)
    1. Every node within ``exact_cells * h`` of a triangle lies in the triangle's
       bounding box grown by ``exact_cells * h``: the (node, triangle) pairs of all
       boxes are enumerated, a cache-sized chunk at a time, and each gets the exact
       point-triangle distance. Triangles much smaller than a cell would make
       thousands of pairs per node; they are found through points sampled on them
       instead, every triangle point no farther than ``delta`` from a sample
       (barycentric lattices), with a `scipy.spatial.cKDTree` over the samples: if
       ``d0`` is the exact distance to the triangle of the nearest sample, the
       closest triangle owns a sample within ``d0 + delta``, so querying that radius
       is exact.
    2. The nodes whose smallest distance is within ``exact_cells * h`` are the exact
       *shell*, each with its closest triangle.
    3. Nodes outside the shell get ``|x - c(b)|``, ``b`` the nearest shell node
       (`scipy.ndimage.distance_transform_edt`) and ``c(b)`` its closest surface
       point: an upper bound on the true distance, exact whenever x and b share
       their closest point, and never above ``|x - b| + d(b)``. Where the surface
       leaves the grid (no shell nodes there) the distance to the triangle of the
       nearest sample on any triangle is used too; with no shell node at all, it
       alone.

Sign (steps 4-5)
    0. First every connected part's faces are made to agree (`orient_faces`): the
       winding number of a closed sphere with every other face reversed is ~0
       everywhere, so without this the inside silently disappears.
    4. The generalised winding number w (Jacobson et al. 2013) at the nodes within
       one cell of the surface, evaluated hierarchically (Barill et al. 2018, "fast
       winding numbers": an octree over the triangles, far clusters replaced by
       their area-weighted-normal dipole, near leaves summed exactly with the
       van Oosterom-Strackee solid angle). Inside is ``|w| >= 0.5`` (|w|: a mesh with all
       normals flipped is read the same): open holes are
       bridged smoothly, and overlapping loose parts (w = 2) give their union.
    5. The other nodes are split into 6-connected regions (`scipy.ndimage.label`)
       that the one-cell layer separates; each region takes the unanimous sign of
       the layer nodes bordering it. A region whose border disagrees leaks through
       a hole wider than the layer; there w is evaluated on its shell nodes and on a
       stride-2 sub-lattice, and each remaining node copies the sub-lattice node
       at most sqrt(3) cells away (same side of the surface, since the node is
       more than ``exact_cells`` cells from it).

Overlaps (step 6)
    6. Where parts overlap (|w| >= 1.5 seen near the surface) the faces inside the
       union are not boundary: inside nodes get at least ``D - sqrt(3) h``, D the
       distance to the nearest outside node, so the union's interior is not
       mistaken for a near-surface layer.

`polygon_to_sdf` is the 2D counterpart (the thesis' 2D examples): exact distance
to all segments of one or more closed loops, sign by even-odd or non-zero rule.
"""

from __future__ import annotations

import time

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..base.grid import Grid
from ..base.progress import Reporter

__all__ = ["mesh_to_sdf", "orient_faces", "polygon_to_sdf", "triangulate", "winding_number"]

_CHUNK = 1 << 14          # nodes per vectorised chunk (bounds temporary memory)
_PAIRS = 1 << 15          # (node, triangle) pairs per chunk of the exact shell (in cache)
_SAMPLE_RADIUS = 0.7      # triangle points lie within this many cells of a sample
_WORKERS = -1             # cKDTree query threads (all cores)
_K = 32                   # nearest samples fetched per shell node (more on demand)
_BOXED_RADIUS = 0.4       # corner radius (cells) from which a triangle is measured over its box
_MAX_LATTICE = 256        # subdivisions per triangle edge at most (delta grows beyond)


# ---------------------------------------------------------------------------
# input checking and triangulation
# ---------------------------------------------------------------------------
def _check_vertices(vertices, dim=3):
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


def triangulate(faces, n_vertices):
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


def _clean_triangles(v, tris, stats):
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


# ---------------------------------------------------------------------------
# consistent face orientation
# ---------------------------------------------------------------------------
def orient_faces(vertices, tris):
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
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

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


# ---------------------------------------------------------------------------
# exact point-triangle distance (vectorised over pairs)
# ---------------------------------------------------------------------------
def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _corner_radius(a, b, c):
    """Per triangle (corners a, b, c, each (T, 3)), the largest corner distance from the
    centroid: the triangle lies in the disc of that radius around it."""
    cen = (a + b + c) / 3.0
    return np.sqrt(np.maximum.reduce([_dot(a - cen, a - cen), _dot(b - cen, b - cen),
                                      _dot(c - cen, c - cen)]))


class _Triangles:
    """Per-triangle constants for the vectorised distance kernel (component arrays)."""

    def __init__(self, v, tris):
        a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
        e0, e1 = b - a, c - a
        e2 = c - b
        n = np.cross(e0, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            # a degenerate (zero-area) triangle gets a NaN normal and Gram inverse: its
            # "inside" test is then False and `distance` measures it by its edges
            n /= np.linalg.norm(n, axis=1)[:, None]
            self.inv = 1.0 / (_dot(e0, e0) * _dot(e1, e1) - _dot(e0, e1) ** 2)
        self.a = [np.ascontiguousarray(a[:, i]) for i in range(3)]
        self.e0 = [np.ascontiguousarray(e0[:, i]) for i in range(3)]
        self.e1 = [np.ascontiguousarray(e1[:, i]) for i in range(3)]
        self.n = [np.ascontiguousarray(n[:, i]) for i in range(3)]
        self.d00 = _dot(e0, e0)
        self.d01 = _dot(e0, e1)
        self.d11 = _dot(e1, e1)
        self.d22 = _dot(e2, e2)
        self.e02 = _dot(e0, e2)
        cen = (a + b + c) / 3.0
        self.cen = [np.ascontiguousarray(cen[:, i]) for i in range(3)]
        self.rad = _corner_radius(a, b, c)

    def lower_bound(self, p, t):
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

    def distance(self, p, t):
        """Exact distance from points p (P, 3) to triangles t (P,)."""
        return self._distance(p[:, 0], p[:, 1], p[:, 2], lambda q: q[t])

    def box_distance(self, px, py, pz, triangles, counts):
        """Exact distance of pairs ordered by triangle: ``counts[i]`` points (coordinate
        arrays px, py, pz) for each triangle of the slice ``triangles``."""
        return self._distance(px, py, pz, lambda q: np.repeat(q[triangles], counts))

    def _distance(self, px, py, pz, per_pair):
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

    def closest_point(self, p, t):
        """Closest point on triangles t (P,) to points p (P, 3) (same regions as `distance`)."""
        a = np.stack([self.a[i][t] for i in range(3)], axis=1)
        e0 = np.stack([self.e0[i][t] for i in range(3)], axis=1)
        e1 = np.stack([self.e1[i][t] for i in range(3)], axis=1)
        v = p - a
        dv0, dv1 = _dot(v, e0), _dot(v, e1)
        d00, d01, d11 = self.d00[t], self.d01[t], self.d11[t]
        with np.errstate(invalid="ignore"):  # NaN on degenerate triangles: not inside
            u = (d11 * dv0 - d01 * dv1) * self.inv[t]
            w = (d00 * dv1 - d01 * dv0) * self.inv[t]
            inside = (u >= 0) & (w >= 0) & (u + w <= 1)
        best = a + u[:, None] * e0 + w[:, None] * e1
        bd = np.where(inside, 0.0, np.inf)
        for s0, e in ((a, e0), (a, e1), (a + e0, e1 - e0)):  # the three edges
            tt = np.clip(_dot(p - s0, e) / _dot(e, e), 0.0, 1.0)
            q = s0 + tt[:, None] * e
            dq = _dot(p - q, p - q)
            use = ~inside & (dq < bd)
            best[use] = q[use]
            bd = np.where(use, dq, bd)
        return best


def point_triangle_distance(p, a, b, c):
    """Euclidean distance from points ``p`` to triangles ``(a, b, c)``, all (P, 3)."""
    p = np.asarray(p, dtype=float)
    v = np.concatenate([a, b, c])
    n = len(p)
    tris = np.stack([np.arange(n), np.arange(n, 2 * n), np.arange(2 * n, 3 * n)], axis=1)
    return _Triangles(v, tris).distance(p, np.arange(n))


# ---------------------------------------------------------------------------
# fast generalised winding number (Jacobson 2013, Barill 2018)
# ---------------------------------------------------------------------------
def _solid_angle_w(qx, qy, qz, A, B, C, t):
    """Winding contribution Omega / (4 pi) of triangles t seen from points q.

    Van Oosterom & Strackee (1983): tan(Omega/2) = a.(b x c) / (|a||b||c| + (a.b)|c|
    + (b.c)|a| + (c.a)|b|) with the corners a, b, c relative to q. Positive when q
    sees the triangle's back (counter-clockwise corners seen from outside, q inside).
    A, B, C are lists of corner coordinate arrays (x, y, z).
    """
    ax, ay, az = A[0][t] - qx, A[1][t] - qy, A[2][t] - qz
    bx, by, bz = B[0][t] - qx, B[1][t] - qy, B[2][t] - qz
    cx, cy, cz = C[0][t] - qx, C[1][t] - qy, C[2][t] - qz
    la = np.sqrt(ax * ax + ay * ay + az * az)
    lb = np.sqrt(bx * bx + by * by + bz * bz)
    lc = np.sqrt(cx * cx + cy * cy + cz * cz)
    det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la
           + (cx * ax + cy * ay + cz * az) * lb)
    return np.arctan2(det, den) * (0.5 / np.pi)


def _part1by2(x):
    x = x.astype(np.uint64) & np.uint64(0x3FF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x030000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x0300F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x030C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x09249249)
    return x


class _WindingTree:
    """Octree of triangles (Morton order) with per-cluster dipoles (Barill et al. 2018).

    Level l clusters are the triangles sharing the top 3*l bits of their centroid's
    Morton code; each is a contiguous range of the sorted triangles. A cluster seen
    from farther than ``beta`` times its radius contributes its dipole
    ``N . (p - q) / (4 pi |p - q|^3)`` (N = sum of area vectors, p = area-weighted
    centroid); nearer clusters are opened, and leaves (<= ``leaf`` triangles or the
    deepest level) are summed exactly.
    """

    LEVELS = 10

    def __init__(self, v, tris, beta=2.0, leaf=8):
        self.beta = float(beta)
        self.leaf = int(leaf)
        a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
        cen = (a + b + c) / 3.0
        lo, hi = cen.min(axis=0), cen.max(axis=0)
        span = max(float((hi - lo).max()), 1e-300)
        q = np.clip(((cen - lo) / span * 1023.0).astype(np.int64), 0, 1023)
        code = (_part1by2(q[:, 0]) << np.uint64(2)) | (_part1by2(q[:, 1]) << np.uint64(1)) \
            | _part1by2(q[:, 2])
        order = np.argsort(code, kind="stable")
        code = code[order]
        self.a, self.b, self.c = a[order], b[order], c[order]
        area_vec = 0.5 * np.cross(self.b - self.a, self.c - self.a)
        area = np.linalg.norm(area_vec, axis=1)
        cen = cen[order]
        self.A = [np.ascontiguousarray(self.a[:, i]) for i in range(3)]
        self.B = [np.ascontiguousarray(self.b[:, i]) for i in range(3)]
        self.C = [np.ascontiguousarray(self.c[:, i]) for i in range(3)]
        self.levels = []  # per level: dict(start, end, N, P, R, child_start, child_end)
        nt = len(order)
        for lev in range(0, self.LEVELS + 1):
            key = code >> np.uint64(3 * (self.LEVELS - lev))
            start = np.concatenate([[0], np.flatnonzero(key[1:] != key[:-1]) + 1])
            end = np.concatenate([start[1:], [nt]])
            N = np.add.reduceat(area_vec, start, axis=0)
            A = np.add.reduceat(area, start)
            P = np.add.reduceat(cen * area[:, None], start, axis=0) / np.maximum(A, 1e-300)[:, None]
            cid = np.repeat(np.arange(len(start)), end - start)
            pc = P[cid]
            r = np.sqrt(np.maximum.reduce([_dot(self.a - pc, self.a - pc), _dot(self.b - pc, self.b - pc),
                                           _dot(self.c - pc, self.c - pc)]))
            R = np.maximum.reduceat(r, start)
            self.levels.append(dict(start=start, end=end, N=[N[:, i].copy() for i in range(3)],
                                    P=[P[:, i].copy() for i in range(3)],
                                    R=R))
        for lev in range(self.LEVELS):
            nxt = self.levels[lev + 1]["start"]
            L = self.levels[lev]
            L["child_start"] = np.searchsorted(nxt, L["start"])
            L["child_end"] = np.searchsorted(nxt, L["end"])

    @staticmethod
    def _expand(starts, counts):
        """(pair index, item index) for each pair's contiguous item range."""
        total = int(counts.sum())
        rep = np.repeat(np.arange(len(counts)), counts)
        off = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        return rep, np.repeat(starts, counts) + off

    def __call__(self, points, beta=None):
        """Winding numbers at ``points`` (P, 3); ``beta`` overrides the opening criterion."""
        points = np.asarray(points, dtype=float)
        beta = self.beta if beta is None else float(beta)
        R2 = [(beta * L["R"]) ** 2 for L in self.levels]
        out = np.zeros(len(points))
        for s in range(0, len(points), _CHUNK // 4):
            out[s:s + _CHUNK // 4] = self._eval(points[s:s + _CHUNK // 4], R2)
        return out

    def sign(self, points, coarse_beta=1.3, margin=0.4):
        """Winding numbers good enough for the test w >= 0.5, at about half the cost.

        A cheap pass with ``coarse_beta`` (errors ~0.15 on typical meshes) settles
        the points with ``|w - 0.5| >= margin``; the others are evaluated again with
        the full ``beta``.
        """
        if coarse_beta >= self.beta:
            return self(points)
        w = self(points, beta=coarse_beta)
        unsure = np.flatnonzero(np.abs(np.abs(w) - 0.5) < margin)
        if len(unsure):
            w[unsure] = self(np.asarray(points, dtype=float)[unsure])
        return w

    def _eval(self, Q, R2):
        nq = len(Q)
        Qx, Qy, Qz = (np.ascontiguousarray(Q[:, i]) for i in range(3))
        w = np.zeros(nq)
        qi = np.arange(nq)
        ci = np.zeros(nq, dtype=np.int64)  # root cluster (level 0) for every query
        for lev in range(self.LEVELS + 1):
            if len(qi) == 0:
                break
            L = self.levels[lev]
            P, N = L["P"], L["N"]
            dx = P[0][ci] - Qx[qi]
            dy = P[1][ci] - Qy[qi]
            dz = P[2][ci] - Qz[qi]
            r2 = dx * dx + dy * dy + dz * dz
            far = r2 > R2[lev][ci]
            if far.any():
                cf = ci[far]
                r2f = r2[far]
                contrib = ((N[0][cf] * dx[far] + N[1][cf] * dy[far] + N[2][cf] * dz[far])
                           / (4.0 * np.pi * r2f * np.sqrt(r2f)))
                w += np.bincount(qi[far], weights=contrib, minlength=nq)
            near = ~far
            qn, cn = qi[near], ci[near]
            count = L["end"][cn] - L["start"][cn]
            is_leaf = count <= self.leaf if lev < self.LEVELS else np.ones(len(cn), bool)
            if is_leaf.any():
                ql, cl = qn[is_leaf], cn[is_leaf]
                rep, t = self._expand(L["start"][cl], count[is_leaf])
                qq = ql[rep]
                contrib = _solid_angle_w(Qx[qq], Qy[qq], Qz[qq], self.A, self.B, self.C, t)
                w += np.bincount(qq, weights=contrib, minlength=nq)
            if lev == self.LEVELS:
                break
            qo, co = qn[~is_leaf], cn[~is_leaf]
            cs = L["child_start"][co]
            rep, ci = self._expand(cs, L["child_end"][co] - cs)
            qi = qo[rep]
        return w


def winding_number(vertices, faces, points, *, beta=2.0):
    """Generalised winding number of a triangle/polygon mesh at ``points`` (P, 3).

    1 inside a closed outward-oriented mesh, 0 outside, smooth across holes,
    k inside k overlapping parts (Jacobson et al. 2013), evaluated with the
    hierarchical dipole approximation of Barill et al. 2018 (``beta``: opening
    criterion, distance / cluster radius; larger is more exact and slower).
    """
    v = _check_vertices(vertices)
    tris = _clean_triangles(v, triangulate(faces, len(v)), None)
    return _WindingTree(v, tris, beta=beta)(np.asarray(points, dtype=float).reshape(-1, 3))


# ---------------------------------------------------------------------------
# triangle samples and the distances found through them
# ---------------------------------------------------------------------------
class _Samples:
    """Steps 1 and 3: points on the triangles, every triangle point within ``delta`` of
    one of them, with a `cKDTree` over them.

    Attributes: ``points`` (S, 3), ``triangle`` (S,) the triangle of each, ``delta`` (T,)
    per triangle (0 for those not sampled), ``tree``. Only the triangles from ``first``
    on are sampled.
    """

    def __init__(self, v, tris, delta_target, first=0):
        self.points, self.triangle, delta = _triangle_samples(v, tris[first:], delta_target)
        self.triangle += first
        self.delta = np.concatenate([np.zeros(first), delta])
        self.tree = cKDTree(self.points)


def _triangle_samples(v, tris, delta_target):
    """Points on every triangle, every triangle point within ``delta`` of one of them.

    A triangle is cut into n x n similar sub-triangles (barycentric lattice) and
    each sub-triangle is represented by its centroid; every point of a sub-triangle
    lies within max|centroid - corner| / n of it, and n is the smallest count that
    brings this under ``delta_target`` (capped). Returns (points, triangle id,
    delta per triangle).
    """
    a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
    rad = _corner_radius(a, b, c)
    n = np.clip(np.ceil(rad / delta_target).astype(np.int64), 1, _MAX_LATTICE)
    pts, ids = [], []
    for k in np.unique(n):  # one lattice per subdivision count (a handful)
        sel = np.flatnonzero(n == k)
        i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        up = (i + j) <= k - 1
        down = (i + j) <= k - 2
        u = np.concatenate([(i[up] + 1.0 / 3.0), (i[down] + 2.0 / 3.0)]) / k
        w = np.concatenate([(j[up] + 1.0 / 3.0), (j[down] + 2.0 / 3.0)]) / k
        p = (a[sel, None, :] + u[None, :, None] * (b[sel] - a[sel])[:, None, :]
             + w[None, :, None] * (c[sel] - a[sel])[:, None, :])
        pts.append(p.reshape(-1, 3))
        ids.append(np.repeat(sel, len(u)))
    return np.concatenate(pts), np.concatenate(ids), rad / n


def _shell_candidates(grid, samples, radius_cells):
    """Flat indices of a superset of the nodes within ``radius_cells`` of a sample's nearest node.

    The nodes nearest to the samples are marked and dilated by a cube of half-width
    ceil(radius_cells) (separable maximum filter, cheap on the whole grid).
    """
    shape = np.asarray(grid.shape)
    idx = np.clip(np.rint(grid.to_index(samples)).astype(np.int64), 0, shape - 1)
    mask = np.zeros(grid.shape, dtype=np.uint8)
    mask[tuple(idx.T)] = 1
    R = int(np.ceil(radius_cells))
    mask = ndimage.maximum_filter(mask, size=2 * R + 1, mode="constant")
    return np.flatnonzero(mask.reshape(-1))


def _refine(best, best_t, rows_of, X, ok, ii, tri, sample_tri):
    """Lower best[rows_of[i]] to the exact distance to the candidates of row i.

    Candidates (``ok`` entries of the sample table ``ii``) whose cheap lower bound
    already exceeds the current best are skipped; the others get the exact kernel.
    ``best_t`` follows the closest triangle. ``rows_of`` must be ascending.
    """
    rows, cols = np.nonzero(ok)
    if len(rows) == 0:
        return
    node = rows_of[rows]
    t = sample_tri[ii[rows, cols]]
    p = X[node]
    lb = tri.lower_bound(p, t)
    need = lb <= best[node] * (1 + 1e-12)
    node, t = node[need], t[need]
    if len(node) == 0:
        return
    d = tri.distance(p[need], t)
    first = np.concatenate([[0], np.flatnonzero(node[1:] != node[:-1]) + 1])
    un = node[first]
    m = np.minimum.reduceat(d, first)
    better = m < best[un]
    if better.any():
        gid = np.repeat(np.arange(len(first)), np.diff(np.append(first, len(node))))
        hit = (d == m[gid]) & better[gid]
        hn, hi = np.unique(node[hit], return_index=True)
        best_t[hn] = t[hit][hi]
        best[un[better]] = m[better]


def _shell_distance(X, tri, tree, sample_tri, tri_delta, shell_r, k=_K):
    """Exact unsigned distance for the points X within ``shell_r`` of the surface.

    Returns (keep, dist, tri): ``keep`` marks the points whose distance may be <= shell_r
    (nearest sample within shell_r + delta), ``dist`` their exact distance, ``tri``
    their closest triangle. If d0 is the exact distance to the triangle of the
    nearest sample, the closest triangle t owns a sample within d0 + delta_t
    (module step 2; ``tri_delta`` holds delta_t), so all those are tested: the k
    nearest samples first, more for the rows whose k-th sample is still in reach.
    """
    delta = float(tri_delta.max())
    k = min(k, len(tree.data))
    ds, _ = tree.query(X, k=1, distance_upper_bound=shell_r + delta * (1 + 1e-9) + 1e-12,
                       workers=_WORKERS)
    keep = np.isfinite(ds)
    X = X[keep]
    dd, ii = tree.query(X, k=k, distance_upper_bound=shell_r + 2 * delta + 1e-12, workers=_WORKERS)
    dd = dd.reshape(len(X), k)
    ii = ii.reshape(len(X), k)
    best_t = sample_tri[ii[:, 0]]
    best = tri.distance(X, best_t)
    last = len(sample_tri) - 1
    slack = tri_delta[sample_tri[np.minimum(ii, last)]] * (1 + 1e-9) + 1e-12
    ok = dd <= best[:, None] + slack
    ok[:, 0] = False  # already measured
    _refine(best, best_t, np.arange(len(X)), X, ok, ii, tri, sample_tri)
    # rows whose k-th sample is still within reach of a closer triangle may have more
    reach = best + delta * (1 + 1e-9) + 1e-12
    more = np.flatnonzero(dd[:, -1] <= reach)
    kk = k
    while len(more) and kk < len(tree.data):
        kk = min(kk * 4, len(tree.data))
        dd2, ii2 = tree.query(X[more], k=kk, distance_upper_bound=float(reach[more].max()),
                              workers=_WORKERS)
        slack2 = tri_delta[sample_tri[np.minimum(ii2, last)]] * (1 + 1e-9) + 1e-12
        ok2 = dd2 <= best[more, None] + slack2
        _refine(best, best_t, more, X, ok2, ii2, tri, sample_tri)
        reach = best + delta * (1 + 1e-9) + 1e-12
        more = more[dd2[:, -1] <= reach[more]]
    return keep, best, best_t


def _nearest_sample_distance(out, nodes, grid, v, tris, tri, keep_min=False):
    """out[nodes] = distance to the triangle of the nearest sample (an upper bound, at
    most the samples' ``delta`` above the true distance)."""
    samples = _Samples(v, tris, _SAMPLE_RADIUS * grid.spacing)
    for s in range(0, len(nodes), 8 * _CHUNK):
        o = nodes[s:s + 8 * _CHUNK]
        x = grid.node_points(o)
        _, si = samples.tree.query(x, workers=_WORKERS)
        d = tri.distance(x, samples.triangle[si])
        out[o] = np.minimum(out[o], d) if keep_min else d


# ---------------------------------------------------------------------------
# public: meshes
# ---------------------------------------------------------------------------
def mesh_to_sdf(vertices, faces, grid: Grid, *, exact_cells=3, progress=None, cancel=None,
                stats=None, beta=2.0):
    """Signed distance grid of a (possibly open, self-intersecting) polygon mesh.

    Parameters
    ----------
    vertices : (N, 3) array_like
        Vertex positions in world units.
    faces : (F, k) int array_like or sequence of polygons
        Triangles, quads or n-gons (ragged lists allowed; triangulated as fans).
    grid : Grid
        3D grid to sample on.
    exact_cells : float
        Nodes within ``exact_cells * h`` of the surface get the exact distance; the rest
        the upper bound ``|x - c(b)|``, c(b) the closest surface point of the nearest
        shell node ``b``.
    progress, cancel : callables, optional
        See `keyframe_implicit.core.base.progress`.
    stats : dict, optional
        Filled with counts (triangles, degenerate_triangles, reoriented_faces,
        non_orientable_faces, boxed_triangles, shell_nodes, winding_nodes,
        leaky_regions) and seconds per step.
    beta : float
        Opening criterion of the fast winding number (see `winding_number`).

    Returns
    -------
    ndarray of grid.shape
        Signed distance in world units, negative inside (|generalised winding number|
        >= 0.5: the union of overlapping parts is inside; fully flipped normals are
        read the same as outward ones).

    Raises
    ------
    ValueError
        Wrong shapes, NaN/inf coordinates, no faces, out-of-range indices, only
        zero-area faces, or a 2D grid. Degenerate faces among good ones are skipped.
    """
    exact_cells = _exact_cells_option(grid, exact_cells)
    rep = Reporter(progress, cancel)
    st = {} if stats is None else stats
    t0 = time.perf_counter()
    v = _check_vertices(vertices)
    tris = _clean_triangles(v, triangulate(faces, len(v)), st)
    tris, st["reoriented_faces"], st["non_orientable_faces"] = orient_faces(v, tris)
    h = grid.spacing
    rep(0.02, "exact distance near the surface")
    small = _corner_radius(*v[tris].transpose(1, 0, 2)) < _BOXED_RADIUS * h
    by_size = tris[np.argsort(small, kind="stable")]  # the ones measured over boxes first
    tri = _Triangles(v, by_size)
    st["boxed_triangles"] = len(tris) - int(small.sum())
    shell, dist_shell, tri_shell = _exact_shell(grid, v, by_size, tri, st["boxed_triangles"],
                                                exact_cells * h, rep.sub(0.02, 0.45))  # 1-2
    st["shell_nodes"] = len(shell)
    t2 = _lap(st, "seconds_exact", t0)
    rep(0.5, "far field")
    unsigned, shell_mask = _far_field(grid, shell, dist_shell, tri_shell, v, by_size, tri,
                                      exact_cells * h)  # step 3
    t3 = _lap(st, "seconds_far", t2)
    rep(0.6, "inside/outside (winding numbers)")
    wt = _WindingTree(v, tris, beta=beta)
    layer = shell[dist_shell <= h * (1 + 1e-9)]
    w_layer = wt.sign(grid.node_points(layer)) if len(layer) else np.zeros(0)  # step 4
    inside = np.zeros(grid.size, dtype=bool)
    inside[layer] = np.abs(w_layer) >= 0.5
    _lap(st, "seconds_winding_layer", t3)
    rep(0.8, "inside/outside (regions)")
    st["winding_nodes"], st["leaky_regions"] = _region_signs(  # step 5
        grid, inside, layer, shell_mask, wt, exact_cells)
    st["overlap_corrected"] = bool(len(w_layer) and np.any(np.abs(w_layer) >= 1.5)
                                   and not inside.all())
    if st["overlap_corrected"]:
        rep(0.9, "inside/outside (overlapping parts)")
        _deepen_overlaps(grid, unsigned, inside)  # step 6
    _lap(st, "seconds_sign", t3)
    _lap(st, "seconds_total", t0)
    rep(1.0, "signed distance done")
    return np.where(inside, -unsigned, unsigned).reshape(grid.shape)


def _exact_cells_option(grid, exact_cells):
    """``exact_cells`` checked, with the grid it applies to."""
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be a keyframe_implicit.core.Grid, got {type(grid).__name__}.")
    if grid.dim != 3:
        raise ValueError("mesh_to_sdf needs a 3D grid; use polygon_to_sdf for 2D loops.")
    exact_cells = float(exact_cells)
    if not np.isfinite(exact_cells) or exact_cells < 1.0:
        raise ValueError(f"exact_cells must be >= 1 (cells of exact distance), got {exact_cells}.")
    return exact_cells


def _lap(stats, key, since):
    """stats[key] = seconds since ``since``; returns now."""
    now = time.perf_counter()
    stats[key] = now - since
    return now


def _exact_shell(grid, v, tris, tri, n_boxed, shell_r, rep):
    """Steps 1-2: every node within ``shell_r`` of the surface, its exact distance and
    its closest triangle, as (shell, dist, tri) sorted by node.

    The first ``n_boxed`` triangles (the larger ones) are measured over their boxes
    (`_boxed_distances`), the others through points sampled on them
    (`_sampled_distances`, cheaper for triangles much smaller than a cell); each node
    keeps its smallest distance.
    """
    best = np.full(grid.size, np.inf)
    best_t = np.zeros(grid.size, dtype=np.int32)
    part = n_boxed / len(tris)
    if n_boxed:
        _boxed_distances(best, best_t, grid, v, tris[:n_boxed], tri, shell_r, rep.sub(0, part))
    if n_boxed < len(tris):
        _sampled_distances(best, best_t, grid, v, tris, n_boxed, tri, shell_r, rep.sub(part, 1))
    shell = np.flatnonzero(best <= shell_r)
    return shell, best[shell], best_t[shell]


def _boxed_distances(best, best_t, grid, v, tris, tri, shell_r, rep):
    """Lower ``best`` (per node) to the exact distance to ``tris`` (the first of ``tri``'s
    triangles) within ``shell_r``; ``best_t`` follows the closest (the last of exact ties).

    A node within ``shell_r`` of a triangle lies in the triangle's bounding box grown
    by ``shell_r``: the boxes' (node, triangle) pairs are measured ``_PAIRS`` at a time.
    """
    lo, size = _grown_boxes(grid, v[tris], shell_r)
    count = size.prod(axis=1)
    ends = np.cumsum(count)
    starts, total = ends - count, int(ends[-1])
    for g0 in range(0, total, _PAIRS):
        g1 = min(g0 + _PAIRS, total)
        part = slice(np.searchsorted(ends, g0, side="right"),
                     np.searchsorted(ends, g1 - 1, side="right") + 1)
        skip = np.maximum(starts[part], g0) - starts[part]  # a box begun in the last chunk
        cnt = np.minimum(ends[part], g1) - starts[part] - skip
        node, x = _box_nodes(grid, lo[part], size[part], skip, cnt)
        d = tri.box_distance(*x, part, cnt)
        near = np.flatnonzero(d <= np.minimum(best[node], shell_r))
        node, d = node[near], d[near]
        t = np.repeat(np.arange(part.start, part.stop, dtype=np.int32), cnt)[near]
        np.minimum.at(best, node, d)
        hit = d == best[node]
        best_t[node[hit]] = t[hit]
        if g1 == total or g0 // _PAIRS % 32 == 31:  # about 0.1 s
            rep(g1 / total, "exact distance near the surface")


def _sampled_distances(best, best_t, grid, v, tris, first, tri, shell_r, rep):
    """Lower ``best`` (per node) to the exact distance to the triangles from ``first`` on
    within ``shell_r`` (`_shell_distance`: candidates through samples on them); ``best_t``
    follows the closest."""
    h = grid.spacing
    samples = _Samples(v, tris, _SAMPLE_RADIUS * h, first)
    cand = _shell_candidates(grid, samples.points, shell_r / h + 0.5 * np.sqrt(3.0)
                             + samples.delta.max() / h + 1e-6)
    for s in range(0, len(cand), _CHUNK):
        nodes = cand[s:s + _CHUNK]
        keep, d, t = _shell_distance(grid.node_points(nodes), tri, samples.tree,
                                     samples.triangle, samples.delta, shell_r)
        nodes = nodes[keep]
        lower = d < best[nodes]
        best[nodes[lower]] = d[lower]
        best_t[nodes[lower]] = t[lower]
        rep(min(1.0, (s + _CHUNK) / len(cand)), "exact distance near the surface")


def _grown_boxes(grid, corners, reach):
    """First node (T, 3) and node counts (T, 3) of each triangle's bounding box grown
    by ``reach``, clipped to the grid (counts 0 for a box outside it); ``corners`` (T, 3, 3)."""
    shape = np.asarray(grid.shape)
    lo = (corners.min(axis=1) - reach - grid.origin) / grid.spacing
    hi = (corners.max(axis=1) + reach - grid.origin) / grid.spacing
    first = np.clip(np.ceil(lo - 1e-9), 0, shape).astype(np.int64)
    last = np.clip(np.floor(hi + 1e-9), -1, shape - 1).astype(np.int64)
    return first, np.maximum(last - first + 1, 0)


def _box_nodes(grid, first, size, skip, count):
    """Flat indices and coordinate arrays (x, y, z) of nodes ``skip[i]`` to ``skip[i] +
    count[i] - 1`` of box i (first node ``first[i]``, ``size[i]`` nodes along each axis),
    in C order, box after box."""
    at = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count - skip, count)
    rest, k = np.divmod(at, np.repeat(size[:, 2], count))
    i, j = np.divmod(rest, np.repeat(size[:, 1], count))
    i += np.repeat(first[:, 0], count)
    j += np.repeat(first[:, 1], count)
    k += np.repeat(first[:, 2], count)
    _, ny, nz = grid.shape
    o, h = grid.origin, grid.spacing
    return (i * ny + j) * nz + k, (o[0] + h * i, o[1] + h * j, o[2] + h * k)


def _far_field(grid, shell, dist_shell, tri_shell, v, tris, tri, shell_r):
    """Step 3: the unsigned distance of every node (exact on the ``shell``, the bound
    ``|x - c(b)|`` elsewhere) and the shell as a mask over the nodes."""
    unsigned = np.empty(grid.size)
    unsigned[shell] = dist_shell
    shell_mask = np.zeros(grid.size, dtype=bool)
    shell_mask[shell] = True
    if len(shell) == 0:
        # surface entirely away from the grid: distance to the triangle of the
        # nearest sample (an upper bound, at most delta above the true distance)
        _nearest_sample_distance(unsigned, np.arange(grid.size), grid, v, tris, tri)
        return unsigned, shell_mask
    if shell_mask.all():
        return unsigned, shell_mask
    inds = ndimage.distance_transform_edt(~shell_mask.reshape(grid.shape),
                                          return_distances=False, return_indices=True)
    nb = np.ravel_multi_index(tuple(inds), grid.shape).reshape(-1)
    del inds
    off = np.flatnonzero(~shell_mask)
    need = np.unique(nb[off])  # shell nodes that are someone's nearest: their closest points
    bi = np.searchsorted(shell, need)
    cp = tri.closest_point(grid.node_points(shell[bi]), tri_shell[bi])
    for s in range(0, len(off), 8 * _CHUNK):
        o = off[s:s + 8 * _CHUNK]
        c = cp[np.searchsorted(need, nb[o])]
        unsigned[o] = np.sqrt(np.sum((grid.node_points(o) - c) ** 2, axis=1))
    del nb
    if np.any(~grid.contains(v[np.unique(tris)], margin=shell_r)):
        # surface beyond the grid has no shell nodes: bound through its samples too
        _nearest_sample_distance(unsigned, off, grid, v, tris, tri, keep_min=True)
    return unsigned, shell_mask


def _region_signs(grid, inside, layer, shell_mask, wt, exact_cells):
    """Step 5: the nodes off the one-cell ``layer`` take the sign of the layer nodes
    bordering their region (``inside`` updated in place); leaky regions are measured.

    Returns (nodes whose winding number was evaluated, leaky regions).
    """
    if len(layer) == 0:
        inside[:] = np.abs(wt.sign(grid.points().reshape(-1, 3))) >= 0.5
        return grid.size, 0
    known = np.zeros(grid.size, dtype=bool)
    known[layer] = True
    labels, nlab = ndimage.label(~known.reshape(grid.shape))
    votes_in, votes_out = _border_votes(labels, nlab, inside.reshape(grid.shape),
                                        known.reshape(grid.shape))
    labels = labels.reshape(-1)
    inside |= (votes_in > votes_out)[labels] & (labels > 0)
    mixed = np.flatnonzero((votes_in > 0) & (votes_out > 0))
    mixed = mixed[mixed > 0]
    evaluated = len(layer)
    if len(mixed):
        evaluated += _sign_leaky_regions(grid, inside, np.isin(labels, mixed), shell_mask, wt,
                                         exact_cells)
    return evaluated, len(mixed)


def _border_votes(labels, nlab, inside, known):
    """Per region label, how many (region node, layer node) 6-neighbour pairs have the
    layer node inside and how many outside: (votes_in, votes_out), each (nlab + 1,)."""
    votes_in = np.zeros(nlab + 1)
    votes_out = np.zeros(nlab + 1)
    for axis in range(3):  # both directions along each axis
        for sa, sb in ((slice(None, -1), slice(1, None)), (slice(1, None), slice(None, -1))):
            ia = [slice(None)] * 3
            ib = [slice(None)] * 3
            ia[axis], ib[axis] = sa, sb
            m = (labels[tuple(ia)] > 0) & known[tuple(ib)]
            la = labels[tuple(ia)][m]
            ii = inside[tuple(ib)][m]
            votes_in += np.bincount(la[ii], minlength=nlab + 1)
            votes_out += np.bincount(la[~ii], minlength=nlab + 1)
    return votes_in, votes_out


def _sign_leaky_regions(grid, inside, in_mixed, shell_mask, wt, exact_cells):
    """The nodes of regions whose border disagrees (``in_mixed``): the winding number on
    their shell nodes and a stride-2 sub-lattice, the rest copy a lattice node at most
    sqrt(3) cells away (module step 5). Returns the nodes evaluated."""
    if exact_cells >= 1.0 + np.sqrt(3.0):
        lattice = np.ones(grid.shape, dtype=bool)
        lattice[1::2, :, :] = False
        lattice[:, 1::2, :] = False
        lattice[:, :, 1::2] = False
        evaluate = in_mixed & (shell_mask | lattice.reshape(-1))
    else:
        evaluate = in_mixed
    ev = np.flatnonzero(evaluate)
    inside[ev] = np.abs(wt.sign(grid.node_points(ev))) >= 0.5
    rest = np.flatnonzero(in_mixed & ~evaluate)
    if len(rest):
        ijk = np.stack(np.unravel_index(rest, grid.shape), axis=1)
        top = np.asarray(grid.shape) - 1
        top = top - (top % 2)  # last even index per axis
        lat = np.minimum(2 * ((ijk + 1) // 2), top)
        inside[rest] = inside[np.ravel_multi_index(tuple(lat.T), grid.shape)]
    return len(ev)


def _deepen_overlaps(grid, unsigned, inside):
    """Step 6: where parts overlap, the faces inside the union are not boundary. The true
    distance to the union's boundary is at least D - sqrt(3) h, D the distance to the
    nearest outside node (an outside node lies within sqrt(3) h of every boundary point
    with room outside): |d| of inside nodes is raised to that (in place)."""
    h = grid.spacing
    D = ndimage.distance_transform_edt(inside.reshape(grid.shape)).reshape(-1) * h
    unsigned[inside] = np.maximum(unsigned[inside], D[inside] - np.sqrt(3.0) * h)


# ---------------------------------------------------------------------------
# public: 2D polygons
# ---------------------------------------------------------------------------
def polygon_to_sdf(loops, grid: Grid, *, rule="evenodd"):
    """Signed distance grid of one or more closed 2D loops (holes allowed).

    Parameters
    ----------
    loops : (M, 2) array_like or sequence of them
        Closed polylines (the last vertex connects back to the first; repeating the
        first vertex at the end is allowed).
    grid : Grid
        2D grid.
    rule : {"evenodd", "nonzero"}
        "evenodd": a node is inside when it lies inside an odd number of loops, so
        holes may have any orientation. "nonzero": inside when the summed winding
        number of the loops is non-zero (overlapping loops give their union; holes
        must run opposite to their outer loop).

    Returns
    -------
    ndarray of grid.shape
        Exact distance to the nearest segment, negative inside.
    """
    if not isinstance(grid, Grid) or grid.dim != 2:
        raise ValueError("polygon_to_sdf needs a 2D Grid; use mesh_to_sdf for 3D meshes.")
    if rule not in ("evenodd", "nonzero"):
        raise ValueError(f"rule must be 'evenodd' or 'nonzero', got {rule!r}.")
    if isinstance(loops, np.ndarray) and loops.ndim == 2:
        loops = [loops]
    loops = list(loops)
    if not loops:
        raise ValueError("no loops given; pass one or more (M, 2) arrays of polygon corners.")
    seg_a, seg_b = [], []
    for i, lp in enumerate(loops):  # a handful of loops
        p = _check_vertices(lp, dim=2)
        if len(p) > 1 and np.array_equal(p[0], p[-1]):
            p = p[:-1]
        if len(p) < 3:
            raise ValueError(f"loop {i} has {len(p)} distinct corners; a closed loop needs at least 3.")
        q = np.roll(p, -1, axis=0)
        good = np.any(p != q, axis=1)
        seg_a.append(p[good])
        seg_b.append(q[good])
    A, B = np.concatenate(seg_a), np.concatenate(seg_b)
    dist = _segments_distance(grid, A, B)
    inside = _crossing_rule(grid, A, B, rule)
    return np.where(inside, -dist, dist).reshape(grid.shape)


def _segments_distance(grid, A, B):
    """Exact distance from every 2D grid node to the nearest segment (A_s, B_s).

    Same scheme as the 3D shell (module step 2) on all nodes: each segment is cut
    into n pieces of at most one cell, represented by their midpoints (every point
    of a segment within L / (2 n) of one); the closest segment of a node owns a
    midpoint within d0 + delta of it, d0 the distance to the nearest midpoint's
    segment, and only those are measured exactly.
    """
    h = grid.spacing
    AB = B - A
    L = np.sqrt(np.sum(AB * AB, axis=1))
    n = np.clip(np.ceil(L / h).astype(np.int64), 1, 1 << 16)
    seg = np.repeat(np.arange(len(A)), n)
    first = np.repeat(np.cumsum(n) - n, n)
    frac = (np.arange(len(seg)) - first + 0.5) / n[seg]
    samples = A[seg] + frac[:, None] * AB[seg]
    delta = float(np.max(L / (2 * n)))
    tree = cKDTree(samples)
    L2 = np.maximum(L * L, 1e-300)

    def seg_dist(P, t):
        AP = P - A[t]
        u = np.clip(np.sum(AP * AB[t], axis=1) / L2[t], 0.0, 1.0)
        D = AP - u[:, None] * AB[t]
        return np.sqrt(np.sum(D * D, axis=1))

    pts = grid.points().reshape(-1, 2)
    out = np.empty(len(pts))
    k0 = min(8, len(samples))
    for s in range(0, len(pts), _CHUNK):
        P = pts[s:s + _CHUNK]
        _, i0 = tree.query(P, workers=_WORKERS)
        best = seg_dist(P, seg[i0])
        rows = np.arange(len(P))
        k = k0
        while len(rows):
            r = best[rows] + delta * (1 + 1e-9) + 1e-12
            dd, ii = tree.query(P[rows], k=k, distance_upper_bound=float(r.max()), workers=_WORKERS)
            dd, ii = dd.reshape(len(rows), k), ii.reshape(len(rows), k)
            ok = dd <= r[:, None]
            rr, cc = np.nonzero(ok)
            d = seg_dist(P[rows[rr]], seg[ii[rr, cc]])
            grp = np.concatenate([[0], np.flatnonzero(rr[1:] != rr[:-1]) + 1])
            best[rows[rr[grp]]] = np.minimum(best[rows[rr[grp]]], np.minimum.reduceat(d, grp))
            if k >= len(samples):
                break
            rows = rows[ok[:, -1]]  # the k-th midpoint is still in reach: look further
            k = min(4 * k, len(samples))
        out[s:s + _CHUNK] = best
    return out


def _crossing_rule(grid, A, B, rule):
    """Inside test of every 2D grid node by counting crossings of a ray towards -x.

    For each segment and each grid row it spans (half-open in y, so a shared corner
    counts once), the crossing's x is found and the nodes to its right get +-1
    (the segment's direction in y); a cumulative sum along x then gives, per node,
    the number of crossings (even-odd rule: odd is inside) or the winding number
    (non-zero rule: non-zero is inside).
    """
    nx, ny = grid.shape
    ox, oy = grid.origin
    h = grid.spacing
    ya, yb = A[:, 1], B[:, 1]
    moving = ya != yb
    A, B, ya, yb = A[moving], B[moving], ya[moving], yb[moving]
    lo, hi = np.minimum(ya, yb), np.maximum(ya, yb)
    j0 = np.clip(np.ceil((lo - oy) / h).astype(np.int64), 0, ny)
    j1 = np.clip(np.ceil((hi - oy) / h).astype(np.int64), 0, ny)  # rows j0 .. j1 - 1
    cnt = np.maximum(j1 - j0, 0)
    sid = np.repeat(np.arange(len(A)), cnt)
    j = np.repeat(j0, cnt) + (np.arange(len(sid)) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    y = oy + h * j
    x = A[sid, 0] + (y - ya[sid]) * (B[sid, 0] - A[sid, 0]) / (yb[sid] - ya[sid])
    i = np.clip(np.floor((x - ox) / h).astype(np.int64) + 1, 0, nx)  # first node right of x
    sign = np.where(yb[sid] > ya[sid], 1, -1) if rule == "nonzero" else np.ones(len(sid), np.int64)
    acc = np.zeros((nx + 1, ny), dtype=np.int64)
    np.add.at(acc, (i, j), sign)
    w = np.cumsum(acc, axis=0)[:nx]
    inside = (w % 2 == 1) if rule == "evenodd" else (w != 0)
    return inside.reshape(-1)
