"""In-between level sets (thesis section 3.2, eq. 3.2-3.4; PAPER-NOTES section 6).

Every grid node x of the region (material of A plus a band) carries

    v_s(x) = (1 - s) Phi(x) + s Psi(y(x))            (eq. 3.4, weights normalised)

and sits at x(s) on its as-rigid-as-possible trajectory (`trajectory.py`). The
in-between level set at time s is the field whose value at the moved point
x(s) is v_s(x). These are scattered values; they are brought back onto the
regular grid by one of two methods:

``resample="splat"`` (default): semi-Lagrangian inverse lookup by cells. Every
cell of the region is moved to time s (its corners follow their trajectories;
inside, the cell is the multilinear image of the unit cell). For every grid
node z inside a moved cell's bounding box the local coordinates u with
T_cell(u) = z are found by a few Newton steps, and z receives the multilinear
interpolation of the corner values at u. Moved cells tile the image of the
region without gaps (neighbouring cells share their faces), so no node inside
the image is missed (no holes); where cells overlap (two parts pressed into
each other, as in a merge) the smaller value wins, i.e. the union of the
material. Nodes that no cell reaches lie outside the image of the band and get
the constant ``outside_value`` (the band width in world units, which also caps
the carried values): far from the material the field is positive and never
drifts to zero.

``resample="idw"``: the thesis's inverse-distance weights (eq. 3.2-3.3),
w = 1 / (r^2 + eps^2), over the moved nodes within ``idw_radius`` cells of each
grid node. Kept as the baseline it is measured against (see
benchmarks/bench_inbetween.py and tests/core/test_levelset.py): it smears
the zero set by up to half a cell on rotated shapes and leaves uncovered nodes
where moved nodes spread apart.
"""

from __future__ import annotations

import itertools
import time

import numpy as np
from scipy import ndimage

from .grid import Grid
from .progress import Reporter
from .sampling import sample
from .trajectory import Trajectories

__all__ = ["Inbetween", "inbetween", "inverse_lookup", "idw_resample"]

_TRAJ_OPTIONS = ("trajectory_method", "band", "band_weight")
_LS_OPTIONS = ("resample", "idw_radius", "newton_steps", "interpolation")


def _corners(d):
    return np.array(list(itertools.product((0, 1), repeat=d)))


def _multilinear(u, corners):
    """Weights (M, 2^d) and their derivatives (M, 2^d, d) of the unit-cell interpolant at u (M, d)."""
    c = corners[None]
    uu = u[:, None, :]
    fac = np.where(c == 1, uu, 1.0 - uu)  # (M, 2^d, d)
    w = np.prod(fac, axis=-1)
    d = u.shape[1]
    dw = np.empty(fac.shape)
    for a in range(d):
        f = fac.copy()
        f[:, :, a] = np.where(c[:, :, a] == 1, 1.0, -1.0)
        dw[:, :, a] = np.prod(f, axis=-1)
    return w, dw


def inverse_lookup(grid: Grid, positions, cells, *, newton_steps=4, tol=1e-6):
    """Semi-Lagrangian inverse lookup: for grid nodes z, source points x with x(s) = z.

    Every cell listed in ``cells`` is moved (its corners to ``positions``; its
    interior is the multilinear image of the unit cell). Each grid node z in
    the moved cell's bounding box is inverted by Newton steps on the
    multilinear map from the cell centre; z is kept when the local coordinates
    fall inside the unit cell. Moved cells share faces, so the nodes of the
    moved region are all found (no holes); a node inside several moved cells
    (overlap) is returned once per cell.

    Parameters
    ----------
    grid : Grid
    positions : ndarray, shape (N, d)
        Moved position of every grid node (flat C order), world units.
    cells : ndarray of int, shape (C,)
        Flat node index of the lower corner of every cell to move.
    newton_steps : int
        Newton iterations per candidate (2-3 suffice for near-affine cells).

    Returns
    -------
    target : ndarray of int, shape (M,)
        Flat index of the grid node found.
    source : ndarray, shape (M, d)
        Its source point x in continuous node-index coordinates.
    """
    d = grid.dim
    shape = np.asarray(grid.shape)
    corners = _corners(d)
    strides = np.array([int(np.prod(shape[a + 1:])) for a in range(d)])
    cnodes = cells[:, None] + (corners @ strides)[None, :]
    P = (positions[cnodes] - grid.origin) / grid.spacing  # index coordinates (C, 2^d, d)
    lo = np.maximum(np.ceil(P.min(axis=1) - tol), 0).astype(np.int64)
    hi = np.minimum(np.floor(P.max(axis=1) + tol), shape - 1).astype(np.int64)
    ext = np.maximum(hi - lo + 1, 0)
    cnt = np.prod(ext, axis=1)
    # every grid node inside every moved cell's bounding box (variable-size boxes, vectorised)
    cc = np.repeat(np.arange(cells.size), cnt)
    start = np.cumsum(cnt) - cnt
    rem = np.arange(int(cnt.sum())) - np.repeat(start, cnt)
    z = np.empty((cc.size, d))
    for a in reversed(range(d)):
        e = ext[cc, a]
        z[:, a] = lo[cc, a] + rem % e
        rem = rem // e
    Pc = P[cc]  # (M, 2^d, d)
    # Newton on T(u) = sum_k w_k(u) P_k = z, starting at the cell centre
    u = np.full((cc.size, d), 0.5)
    for _ in range(newton_steps):
        w, dw = _multilinear(u, corners)
        T = np.einsum("mk,mkd->md", w, Pc)
        J = np.einsum("mka,mkd->mda", dw, Pc)  # dT_d / du_a
        u = np.clip(u - _solve_small(J, T - z), -0.5, 1.5)
    w, _ = _multilinear(u, corners)
    T = np.einsum("mk,mkd->md", w, Pc)
    res = np.einsum("md,md->m", T - z, T - z)
    inside = np.all((u >= -1e-4) & (u <= 1 + 1e-4), axis=1) & (res < 1e-8)
    zi = z[inside].astype(np.int64)
    target = np.ravel_multi_index(tuple(zi[:, a] for a in range(d)), grid.shape)
    base = np.stack(np.unravel_index(cells[cc[inside]], grid.shape), axis=-1)
    return target, base + u[inside]


def _solve_small(J, r):
    """Solve J x = r for a batch of 2x2 / 3x3 systems (x = 0 where J is singular)."""
    det = np.linalg.det(J)
    ok = np.abs(det) > 1e-12
    out = np.zeros_like(r)
    if ok.any():
        out[ok] = np.linalg.solve(J[ok], r[ok][..., None])[..., 0]
    return out


def idw_resample(grid: Grid, positions, values, *, fill, radius=1.5, eps=0.25):
    """Thesis eq. 3.2-3.3: inverse-distance weights 1 / (r^2 + eps^2) of nearby moved nodes.

    ``radius`` and ``eps`` are in cells. Grid nodes with no moved node within
    ``radius`` get ``fill``. Returns (field, covered) like `splat_cells`.
    """
    from scipy.spatial import cKDTree

    h = grid.spacing
    tree = cKDTree(positions)
    z = grid.points().reshape(-1, grid.dim)
    k = 4 * 2 ** grid.dim
    dist, idx = tree.query(z, k=k, distance_upper_bound=radius * h, workers=-1)
    valid = np.isfinite(dist)
    idx = np.where(valid, idx, 0)
    w = np.where(valid, 1.0 / (dist ** 2 + (eps * h) ** 2), 0.0)
    wsum = w.sum(axis=1)
    covered = wsum > 0
    out = np.full(z.shape[0], float(fill))
    out[covered] = (w[covered] * values[idx[covered]]).sum(axis=1) / wsum[covered]
    return out.reshape(grid.shape), covered.reshape(grid.shape)


class Inbetween:
    """In-between frames of one keyframe pair: trajectories and level sets at any s in [0, 1].

    Build with `Inbetween.from_map` (a map you already have) or `inbetween`
    (solves the map first).

    Attributes
    ----------
    grid : Grid
    mapped : ndarray, grid.shape + (d,)
        The map y(x).
    trajectories : Trajectories
    stats : dict
        Figures of the map (when solved here), the trajectories and the
        level sets (timings in seconds, coverage).
    """

    def __init__(self, phi_a, phi_b, grid, mapped, trajectories, *, resample="splat",
                 idw_radius=1.5, newton_steps=4, interpolation="cubic", stats=None,
                 map_result=None):
        if interpolation not in ("cubic", "linear"):
            raise ValueError(f'interpolation must be "cubic" or "linear", got {interpolation!r}.')
        self.grid = grid
        self.phi_a = phi_a
        self.phi_b = phi_b
        self.mapped = mapped
        self.trajectories = trajectories
        self.resample = resample
        self.idw_radius = float(idw_radius)
        self.newton_steps = int(newton_steps)
        self.map_result = map_result
        self.stats = dict(stats or {})
        self.stats.setdefault("levelset_seconds", 0.0)
        self.stats.setdefault("levelset_calls", 0)
        self.stats["trajectory"] = trajectories.stats
        h = grid.spacing
        self.outside_value = trajectories.band * h
        self.interpolation = interpolation
        if interpolation == "cubic":
            self._coef_a = ndimage.spline_filter(phi_a, order=3, mode="nearest")
            self._coef_b = ndimage.spline_filter(phi_b, order=3, mode="nearest")
        self._psi_y = self._psi(mapped.reshape(-1, grid.dim))
        dist = trajectories._dist
        shape = np.asarray(grid.shape)
        near = (dist <= trajectories.band).reshape(grid.shape)
        cell_ok = np.ones(tuple(shape - 1), dtype=bool)
        for c in _corners(grid.dim):
            cell_ok &= near[tuple(slice(c[a], c[a] + shape[a] - 1) for a in range(grid.dim))]
        self._cells = np.ravel_multi_index(
            np.unravel_index(np.flatnonzero(cell_ok), tuple(shape - 1)), grid.shape)
        self._cache = {}

    # ------------------------------------------------------------------
    @classmethod
    def from_map(cls, phi_a, phi_b, grid, mapped, *, material=None, components=None,
                 trajectory_method="global", band=4.0, band_weight=0.1, resample="splat",
                 idw_radius=1.5, newton_steps=4, interpolation="cubic", stats=None,
                 map_result=None):
        """In-betweens from a given map y(x).

        Parameters
        ----------
        phi_a, phi_b : ndarray, grid.shape
            Signed distance grids of keyframes A and B (negative inside).
        grid : Grid
        mapped : ndarray, grid.shape + (d,)
            y(x) for every node (world units).
        material : bool ndarray, optional
            A's material; ``phi_a < 0`` when omitted.
        components : int ndarray, optional
            Labels of A's material components (see `Trajectories`).
        trajectory_method : {"global", "local"}
            See `trajectory.Trajectories`.
        band : float
            Cells around the material that carry trajectories and values; also
            sets the far-field value ``band * h``.
        band_weight : float
            Weight of band cells in the trajectory solve.
        resample : {"splat", "idw"}
            How scattered values return to the grid (module docstring).
        idw_radius : float
            Search radius in cells for ``resample="idw"``.
        newton_steps : int
            Newton iterations of the inverse lookup.
        interpolation : {"cubic", "linear"}
            How Phi, Psi are read at off-grid points (cubic B-spline by
            default: it halves the zero-set error of multilinear reads on
            rotated shapes, see benchmarks/bench_inbetween.py).
        """
        if not isinstance(grid, Grid):
            raise ValueError("grid must be a keyframe_implicit.core.Grid.")
        phi_a = grid.check_field(phi_a, "phi_a")
        phi_b = grid.check_field(phi_b, "phi_b")
        mapped = np.asarray(mapped, dtype=float)
        if resample not in ("splat", "idw"):
            raise ValueError(f'resample must be "splat" or "idw", got {resample!r}.')
        if material is None:
            material = phi_a < 0
        t0 = time.perf_counter()
        traj = Trajectories(grid, mapped, material, components, method=trajectory_method,
                            band=band, band_weight=band_weight)
        st = dict(stats or {})
        st["trajectory_setup_seconds"] = time.perf_counter() - t0
        return cls(phi_a, phi_b, grid, mapped, traj, resample=resample, idw_radius=idw_radius,
                   newton_steps=newton_steps, interpolation=interpolation, stats=st,
                   map_result=map_result)

    # ------------------------------------------------------------------
    def _field_at(self, field, coef, u):
        """Value of a keyframe field at continuous node-index coordinates u (M, d).

        Cubic B-spline (``interpolation="cubic"``) or multilinear; outside the
        grid the distance to the grid box is added (the field stays outside).
        """
        hi = np.asarray(self.grid.shape) - 1
        uc = np.clip(u, 0, hi)
        extra = self.grid.spacing * np.linalg.norm(u - uc, axis=-1)
        if self.interpolation == "cubic":
            val = ndimage.map_coordinates(coef, uc.T, order=3, mode="nearest", prefilter=False)
        else:
            val = sample(field, self.grid, self.grid.to_world(uc))
        return val + extra

    def _psi(self, points):
        """Psi (keyframe B) at world points (P, d)."""
        return self._field_at(self.phi_b, getattr(self, "_coef_b", None),
                              self.grid.to_index(points))

    def _value_at_source(self, u, s):
        """(1 - s) Phi(x) + s Psi(y(x)) at source points x given in index coordinates (eq. 3.4)."""
        phi = self._field_at(self.phi_a, getattr(self, "_coef_a", None), u)
        if s == 0.0:
            return phi
        y = sample(self.mapped, self.grid, self.grid.to_world(u))
        return (1.0 - s) * phi + s * self._psi(y)

    def values(self, s):
        """Values (1 - s) Phi(x) + s Psi(y(x)) carried by every node (eq. 3.4), flat."""
        v = (1.0 - s) * self.phi_a.reshape(-1) + s * self._psi_y
        return np.minimum(v, self.outside_value)

    def levelset(self, s):
        """The in-between signed distance field at time s in [0, 1], array of grid.shape.

        Negative inside; equal to ``outside_value`` (> 0) wherever no part of
        the band reaches.
        """
        s = float(s)
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"time s must lie in [0, 1], got {s}.")
        if s in self._cache:
            return self._cache[s]
        t0 = time.perf_counter()
        pos = self.trajectories.positions(s).reshape(-1, self.grid.dim)
        if self.resample == "splat":
            target, source = inverse_lookup(self.grid, pos, self._cells,
                                            newton_steps=self.newton_steps)
            vals = np.minimum(self._value_at_source(source, s), self.outside_value)
            out = np.full(self.grid.size, np.inf)
            np.minimum.at(out, target, vals)
            covered = np.isfinite(out)
            out[~covered] = self.outside_value
            field = out.reshape(self.grid.shape)
        else:
            vals = self.values(s)
            band_nodes = np.flatnonzero(self.trajectories._dist <= self.trajectories.band)
            field, covered = idw_resample(self.grid, pos[band_nodes], vals[band_nodes],
                                          fill=self.outside_value, radius=self.idw_radius)
        self.stats["levelset_seconds"] += time.perf_counter() - t0
        self.stats["levelset_calls"] += 1
        self.stats["covered_nodes"] = int(covered.sum())
        if len(self._cache) > 4:
            self._cache.pop(next(iter(self._cache)))
        self._cache[s] = field
        return field

    def trajectory(self, points, s):
        """Positions at time s of points given at time 0: (P, d) -> (P, d).

        Multilinear interpolation of the node trajectories.
        """
        return self.trajectories(points, s)


def inbetween(phi_a, phi_b, grid, features_a, features_b, *, progress=None, cancel=None,
              **options):
    """Solve the map between two keyframes and return their in-betweens.

    ``inbetween = solve_map + Inbetween.from_map``.

    Parameters
    ----------
    phi_a, phi_b : ndarray, grid.shape
        Signed distance grids of keyframes A and B.
    grid : Grid
    features_a, features_b : (N, d) arrays
        Feature points of A and their targets in B.
    progress, cancel : callables, optional (see `progress.Reporter`).
    **options
        ``trajectory_method``, ``band``, ``band_weight``, ``resample``,
        ``idw_radius``, ``newton_steps`` go to `Inbetween.from_map`; all
        others are passed to `solve_map`.

    Returns
    -------
    Inbetween
    """
    from .solver import solve_map

    rep = Reporter(progress, cancel)
    mine = {k: options.pop(k) for k in list(options) if k in _TRAJ_OPTIONS + _LS_OPTIONS}
    t0 = time.perf_counter()
    res = solve_map(phi_a, phi_b, grid, features_a, features_b, progress=rep.sub(0.0, 0.8),
                    cancel=cancel, **options)
    st = {"map_seconds": time.perf_counter() - t0, "map": getattr(res, "stats", {})}
    rep(0.8, "trajectories")
    out = Inbetween.from_map(phi_a, phi_b, grid, res.mapped,
                             material=getattr(res, "material", None),
                             components=getattr(res, "components", None),
                             stats=st, map_result=res, **mine)
    rep(1.0, "in-betweens ready")
    return out
