"""Keyframe meshes and polygons -> signed distance grids (thesis section 2.1).

The thesis samples every keyframe as a signed distance function Phi / Psi on one
regular grid, negative inside the material (docs/method.md, "Notation and input"). Artists'
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
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..base.grid import Grid
from ..base.progress import Reporter
from .mesh import check_vertices, clean_triangles, orient_faces, triangulate
from .triangles import Triangles, corner_radius
from .winding import WindingTree

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from numpy.typing import ArrayLike

__all__ = ["mesh_to_sdf"]

_CHUNK = 1 << 14  # nodes per vectorised chunk (bounds temporary memory)
_PAIRS = 1 << 15          # (node, triangle) pairs per chunk of the exact shell (in cache)
_SAMPLE_RADIUS = 0.7      # triangle points lie within this many cells of a sample
_WORKERS = -1             # cKDTree query threads (all cores)
_K = 32                   # nearest samples fetched per shell node (more on demand)
_BOXED_RADIUS = 0.4       # corner radius (cells) from which a triangle is measured over its box
_MAX_LATTICE = 256        # subdivisions per triangle edge at most (delta grows beyond)



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
    rad = corner_radius(a, b, c)
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
    idx = grid.nearest_node(samples)
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


def mesh_to_sdf(vertices: ArrayLike, faces: ArrayLike | Sequence[Sequence[int]], grid: Grid, *,
                exact_cells: float = 3, progress: Callable[[float, str], object] | None = None,
                cancel: Callable[[], bool] | None = None, stats: dict[str, float] | None = None,
                beta: float = 2.0) -> np.ndarray:
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
    v = check_vertices(vertices)
    tris = clean_triangles(v, triangulate(faces, len(v)), st)
    tris, st["reoriented_faces"], st["non_orientable_faces"] = orient_faces(v, tris)
    h = grid.spacing
    rep(0.02, "exact distance near the surface")
    small = corner_radius(*v[tris].transpose(1, 0, 2)) < _BOXED_RADIUS * h
    by_size = tris[np.argsort(small, kind="stable")]  # the ones measured over boxes first
    tri = Triangles(v, by_size)
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
    wt = WindingTree(v, tris, beta=beta)
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


def _exact_cells_option(grid: Grid, exact_cells: float) -> float:
    """``exact_cells`` checked, with the grid it applies to."""
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be a keyframe_implicit.core.Grid, got {type(grid).__name__}.")
    if grid.dim != 3:
        raise ValueError("mesh_to_sdf needs a 3D grid; use polygon_to_sdf for 2D loops.")
    exact_cells = float(exact_cells)
    if not np.isfinite(exact_cells) or exact_cells < 1.0:
        raise ValueError(f"exact_cells must be >= 1 (cells of exact distance), got {exact_cells}.")
    return exact_cells


def _lap(stats: dict[str, float], key: str, since: float) -> float:

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
