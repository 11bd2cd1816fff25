"""One keyframe's signed distance field carried along its trajectories.

A field f given on the grid nodes x at time 0 is carried to time t by the
node paths x(t) (`trajectory.Trajectories`): the carried field g_t satisfies
g_t(x(t)) = f(x). On the grid this is a semi-Lagrangian inverse lookup by
cells (`inverse_lookup`): every cell of the keyframe's region (its material
plus ``trajectories.margin_cells`` cells around it) is moved to time t, and
every grid node z inside a moved cell gets f at its source point x, read with
cubic B-splines (or multilinearly). Moved cells share faces, so the image of
the region has no holes; where two moved cells overlap (two parts pressed into
each other) the smaller value wins, i.e. the union of the material.

The field is truncated (``truncation``, world units) at its smallest value on
the border of the region: every value the transport carries is at most that,
and a node no moved cell reaches -- beyond the moved border -- has no value,
which its user reads as the truncation. So "far outside" and "not reached"
agree, the carried field is continuous where the region ends, and nothing far
from the material can drift to zero (thesis sec. 3.2 and its artifacts,
PAPER-NOTES section 6).

`levelset.Inbetween` blends two transports, one per keyframe (PAPER-NOTES
section 8); `Transport.carry` says how each treats material its map tears.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from . import elements
from .grid import Grid
from .progress import Reporter
from .sampling import sample

__all__ = ["Transport", "inverse_lookup"]


_CONVERGED = 1e-7  # cells: a source point this close reads the field to ~1e-7 h


def inverse_lookup(grid: Grid, corner_positions, cells, *, newton_steps=6, tol=1e-6,
                   max_candidates=500_000, check=None):
    """Semi-Lagrangian inverse lookup: for grid nodes z, source points x with x(s) = z.

    Every cell listed in ``cells`` is moved (its corners to
    ``corner_positions``; its interior is the multilinear image of the unit
    cell). Each grid node z in the moved cell's bounding box is first placed
    with the cell's affine part (candidates clearly outside are dropped), then
    refined by Newton steps on the multilinear map; z is kept when its local
    coordinates fall inside the unit cell and the residual vanishes. Moved
    cells share faces, so every node of the moved region is found (no holes);
    a node inside several moved cells (overlap) is returned once per cell.

    Parameters
    ----------
    grid : Grid
    corner_positions : ndarray, shape (C, 2^d, d)
        Moved corners of every cell (corner order of ``itertools.product((0, 1), repeat=d)``),
        world units.
    cells : ndarray of int, shape (C,)
        Flat node index of the lower corner of every cell.
    newton_steps : int
        Newton iterations at most per candidate (the affine start makes 1-2 enough
        for near-rigid cells; converged candidates drop out).
    max_candidates : int
        Cells are processed in chunks of at most this many candidate nodes.
    check : callable, optional
        Called before every chunk (cancellation).

    Returns
    -------
    target : ndarray of int, shape (M,)
        Flat index of the grid node found.
    source : ndarray, shape (M, d)
        Its source point x in continuous node-index coordinates.
    """
    d = grid.dim
    shape = np.asarray(grid.shape)
    P = (np.asarray(corner_positions, dtype=float) - grid.origin) / grid.spacing
    # monomial coefficients of the multilinear map T(u) = sum_S a_S prod_{a in S} u_a
    subsets = elements.corners(d)  # subset S <-> corner with bits S
    coef = _moebius(P, subsets)  # (C, 2^d, d)
    lo = np.maximum(np.ceil(P.min(axis=1) - tol), 0).astype(np.int64)
    hi = np.minimum(np.floor(P.max(axis=1) + tol), shape - 1).astype(np.int64)
    ext = np.maximum(hi - lo + 1, 0)
    cnt = np.prod(ext, axis=1)
    half = np.full((cells.size, d), 0.5)
    T0, J0 = _poly_eval(coef, half)
    Jinv = _inverse_small(J0)
    # cells in chunks of at most ``max_candidates`` bounding-box nodes (bounded memory
    # even where a bad map stretches cells over many nodes)
    bounds = np.searchsorted(np.cumsum(cnt), np.arange(1, int(cnt.sum()) // max_candidates + 1)
                             * max_candidates)
    edges = np.unique(np.concatenate([[0], bounds, [cells.size]]))
    targets, sources = [], []
    for c0, c1 in zip(edges[:-1], edges[1:]):  # loop over a few chunks
        if check is not None:
            check()
        sel = np.arange(c0, c1)
        t, u = _lookup_chunk(sel, cnt, ext, lo, coef, T0, Jinv, newton_steps)
        targets.append(t)
        sources.append(u)
    cc_all = np.concatenate([t[0] for t in targets]) if targets else np.zeros(0, np.int64)
    zi = np.concatenate([t[1] for t in targets]) if targets else np.zeros((0, d), np.int64)
    u_all = np.concatenate(sources) if sources else np.zeros((0, d))
    target = np.ravel_multi_index(tuple(zi[:, a] for a in range(d)), grid.shape)
    base = np.stack(np.unravel_index(cells[cc_all], grid.shape), axis=-1)
    return target, base + u_all


def _lookup_chunk(sel, cnt, ext, lo, coef, T0, Jinv, newton_steps):
    """Inverse lookup for the cells ``sel``: ((cell, node index), local coordinates) found."""
    d = lo.shape[1]
    n = cnt[sel]
    # every grid node inside every moved cell's bounding box (variable-size boxes, vectorised)
    cc = np.repeat(sel, n)
    start = np.cumsum(n) - n
    rem = np.arange(int(n.sum())) - np.repeat(start, n)
    z = np.empty((cc.size, d))
    for a in reversed(range(d)):
        e = ext[cc, a]
        z[:, a] = lo[cc, a] + rem % e
        rem = rem // e
    # affine guess from the cell centre; drop candidates clearly outside the cell
    u = 0.5 + np.einsum("mab,mb->ma", Jinv[cc], z - T0[cc])
    keep = np.all((u > -0.35) & (u < 1.35), axis=1)
    cc, z, u = cc[keep], z[keep], u[keep]
    todo = np.arange(cc.size)  # Newton only on candidates not yet converged
    res = np.full(cc.size, np.inf)
    for it in range(newton_steps + 1):
        a = coef[cc[todo]]
        T, _ = _poly_eval(a, u[todo], jacobian=False)
        r = T - z[todo]
        res[todo] = np.einsum("md,md->m", r, r)
        live = res[todo] > _CONVERGED ** 2
        todo, r = todo[live], r[live]
        if it == newton_steps or todo.size == 0:
            break
        _, J = _poly_eval(a[live], u[todo])
        u[todo] = np.clip(u[todo] - _solve_small(J, r), -0.5, 1.5)
    inside = np.all((u >= -1e-4) & (u <= 1 + 1e-4), axis=1) & (res < 1e-8)
    return (cc[inside], z[inside].astype(np.int64)), u[inside]


def _moebius(P, subsets):
    """Monomial coefficients a_S = sum_{T subset S} (-1)^{|S|-|T|} P_T of a multilinear cell.

    One difference pass per axis (the fast Moebius transform over subsets).
    """
    coef = np.array(P, dtype=float, copy=True)
    index = {tuple(S): i for i, S in enumerate(subsets)}
    for a in range(subsets.shape[1]):
        for i, S in enumerate(subsets):
            if S[a]:
                T = S.copy()
                T[a] = 0
                coef[:, i] -= coef[:, index[tuple(T)]]
    return coef


def _poly_eval(coef, u, jacobian=True):
    """T(u) (M, d) and its Jacobian dT/du (M, d, d) from monomial coefficients (M, 2^d, d).

    By recursion on the axes: T(u) = T_0(u') + u_0 T_1(u'), u' = u[:, 1:], where T_0 and
    T_1 are the multilinear maps of the halves of the coefficients without and with
    axis 0 (the corner order of `elements.corners`), so dT/du_0 = T_1.
    """
    if u.shape[1] == 0:
        return coef[:, 0], np.empty(coef.shape[:1] + coef.shape[2:] + (0,))
    half = coef.shape[1] // 2
    T0, J0 = _poly_eval(coef[:, :half], u[:, 1:], jacobian)
    T1, J1 = _poly_eval(coef[:, half:], u[:, 1:], jacobian)
    u0 = u[:, :1]
    T = T0 + u0 * T1
    if not jacobian:
        return T, None
    return T, np.concatenate([T1[:, :, None], J0 + u0[:, :, None] * J1], axis=2)


def _inverse_small(J):
    """Inverse of a batch of 2x2 / 3x3 matrices by the adjugate (identity where singular)."""
    d = J.shape[-1]
    if d == 2:
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        adj = np.stack([np.stack([J[:, 1, 1], -J[:, 0, 1]], -1),
                        np.stack([-J[:, 1, 0], J[:, 0, 0]], -1)], -2)
    else:
        c0, c1, c2 = J[:, :, 0], J[:, :, 1], J[:, :, 2]
        adj = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=1)
        det = np.einsum("md,md->m", c0, adj[:, 0])
    ok = np.abs(det) > 1e-12
    out = adj / np.where(ok, det, 1.0)[:, None, None]
    out[~ok] = np.eye(d)
    return out


def _solve_small(J, r):
    """Solve J x = r for a batch of 2x2 / 3x3 systems by Cramer's rule (x = 0 where singular)."""
    d = r.shape[1]
    if d == 2:
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        x0 = r[:, 0] * J[:, 1, 1] - J[:, 0, 1] * r[:, 1]
        x1 = J[:, 0, 0] * r[:, 1] - r[:, 0] * J[:, 1, 0]
        x = np.stack([x0, x1], axis=1)
    else:
        c0, c1, c2 = J[:, :, 0], J[:, :, 1], J[:, :, 2]
        x12 = np.cross(c1, c2)
        det = np.einsum("md,md->m", c0, x12)
        x = np.stack([np.einsum("md,md->m", r, x12),
                      np.einsum("md,md->m", c0, np.cross(r, c2)),
                      np.einsum("md,md->m", c0, np.cross(c1, r))], axis=1)
    ok = np.abs(det) > 1e-12
    return np.where(ok[:, None], x / np.where(ok, det, 1.0)[:, None], 0.0)


class Transport:
    """A keyframe's field carried along its trajectories to any time t in [0, 1].

    Parameters
    ----------
    field : ndarray, grid.shape
        The keyframe's signed distance grid (negative inside).
    trajectories : `trajectory.Trajectories`
        Paths of the keyframe's nodes, x(0) = x to x(1) = y(x).
    interpolation : {"cubic", "linear"}
        How the field is read at source points between nodes (cubic B-splines
        halve the zero-set error of multilinear reads on rotated shapes).
    newton_steps : int
        Newton iterations of the inverse lookup.
    truncation : float, optional
        Largest value carried (world units); by default the field's smallest
        value on the region's border (`border_value`).
    cancel : callable() -> bool, optional
        Polled between chunks of the inverse lookup; `progress.Cancelled` is
        raised once it returns True.

    Attributes
    ----------
    border_value : float
        The field's smallest value on the border of the region (world units).
    truncation : float
    """

    def __init__(self, field, trajectories, *, interpolation="cubic", newton_steps=6,
                 truncation=None, cancel=None):
        if interpolation not in ("cubic", "linear"):
            raise ValueError(f'interpolation must be "cubic" or "linear", got {interpolation!r}.')
        grid = trajectories.grid
        self.grid = grid
        self.field = grid.check_field(field, "field")
        self.trajectories = trajectories
        self.interpolation = interpolation
        self.newton_steps = int(newton_steps)
        self._check = Reporter(None, cancel).check
        self._coef = (ndimage.spline_filter(self.field, order=3, mode="nearest")
                      if interpolation == "cubic" else None)
        self._cells, self._corner_nodes, self._cnodes_local, border = _region_cells(
            grid, trajectories.region_nodes())
        self.border_value = float(self.field.reshape(-1)[border].min()) if border.size else np.inf
        self.truncation = self.border_value if truncation is None else float(truncation)

    def read(self, field, u, coef=None):
        """A field's value at continuous node-index coordinates u (M, d).

        Cubic B-spline (``coef`` its prefiltered coefficients) or multilinear;
        outside the grid the distance to the grid box is added, so the field
        stays outside.
        """
        hi = np.asarray(self.grid.shape) - 1
        uc = np.clip(u, 0, hi)
        extra = self.grid.spacing * np.linalg.norm(u - uc, axis=-1)
        if coef is not None:
            val = ndimage.map_coordinates(coef, uc.T, order=3, mode="nearest", prefilter=False)
        else:
            val = sample(field, self.grid, self.grid.to_world(uc))
        return val + extra

    def sources(self, t):
        """Inverse lookup at time t: (target node, source point in index coordinates) pairs."""
        pos = self.trajectories.node_positions(t, self._corner_nodes)
        return inverse_lookup(self.grid, pos[self._cnodes_local], self._cells,
                              newton_steps=self.newton_steps, check=self._check)

    def value_at(self, points):
        """The keyframe's own field at world points (P, d)."""
        return self.read(self.field, self.grid.to_index(points), self._coef)

    def carry(self, t, other=None, values=None):
        """The field carried to time t, flat (grid.size,); NaN where no moved cell reaches.

        Each source point x carries its own keyframe's value f(x); with
        ``other`` (the other keyframe's `Transport`) it carries

            v_t(x) = (1 - t) f(x) + t max(f(x), g(y(x))),

        g the other keyframe's field and y this transport's map: where the
        map takes material into the other keyframe's empty space (a tear:
        a merge seen backwards, or a split), that material fades out on the
        way, while the other keyframe never adds depth to this one's empty
        space. ``values(u)`` (u source points in index coordinates) replaces
        both. Values are truncated at ``truncation``; overlaps keep the
        smallest.
        """
        target, source = self.sources(t)
        if values is not None:
            vals = values(source)
        else:
            vals = self.read(self.field, source, self._coef)
            if other is not None and t > 0:
                y = self.trajectories(self.grid.to_world(source), 1.0)
                vals = (1.0 - t) * vals + t * np.maximum(vals, other.value_at(y))
        out = np.full(self.grid.size, np.inf)
        np.minimum.at(out, target, np.minimum(vals, self.truncation))
        out[np.isinf(out)] = np.nan
        return out


    def surface_motion(self, t, near, dt=1e-3):
        """The nodes within ``near`` (world units) of the keyframe's surface at time t:
        their positions (M, d) and velocities dx/dt (M, d).

        Second-order finite differences with step ``dt``: central, or one-sided over
        three times where t is within ``dt`` of an end. With ``dt`` one frame, the
        times are the neighbouring frames' (which the trajectories keep).
        """
        nodes = self._corner_nodes[np.abs(self.field.reshape(-1)[self._corner_nodes]) <= near]
        paths = self.trajectories
        pos = paths.node_positions(t, nodes)
        dt = min(float(dt), 0.25)  # so that one of the one-sided triples fits in [0, 1]

        def at(time):  # the ends exactly (i/n - 1/n is not always 0 in floating point)
            return paths.node_positions(min(max(round(time, 12), 0.0), 1.0), nodes)
        if t - dt >= 0.0 and t + dt <= 1.0:
            return pos, (at(t + dt) - at(t - dt)) / (2.0 * dt)
        step = dt if t + 2.0 * dt <= 1.0 else -dt  # (-3 x0 + 4 x1 - x2) / (2 step)
        one, two = at(t + step), at(t + 2.0 * step)
        return pos, (4.0 * one - 3.0 * pos - two) / (2.0 * step)


def _region_cells(grid, region):
    """The cells with all corners in ``region`` (bool, flat).

    Returns their lower-corner nodes, their corner nodes (unique), each cell's
    corners as indices into those, and the border nodes: corners of some
    region cell that are not surrounded by region cells.
    """
    shape = np.asarray(grid.shape)
    d = grid.dim
    near = region.reshape(grid.shape)
    corners = elements.corners(d)
    cell_ok = np.ones(tuple(shape - 1), dtype=bool)
    for c in corners:
        cell_ok &= near[tuple(slice(c[a], c[a] + shape[a] - 1) for a in range(d))]
    cells = np.ravel_multi_index(np.unravel_index(np.flatnonzero(cell_ok), tuple(shape - 1)),
                                 grid.shape)
    cnodes = cells[:, None] + (corners @ grid.strides)[None, :]
    corner_nodes, inv = np.unique(cnodes, return_inverse=True)
    # a node is inside the union of region cells when all 2^d cells around it are region cells
    padded = np.pad(cell_ok, 1)
    inside = np.ones(grid.shape, dtype=bool)
    for c in corners:
        inside &= padded[tuple(slice(c[a], c[a] + shape[a]) for a in range(d))]
    border = corner_nodes[~inside.reshape(-1)[corner_nodes]]
    return cells, corner_nodes, inv.reshape(cnodes.shape), border
