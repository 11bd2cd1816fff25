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
docs/method.md, section 6).

`levelset.Inbetween` blends two transports, one per keyframe (docs/method.md,
section 8); `Transport.carry` says how each treats material its map tears.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from ..base import elements
from ..base.elements import cofactor
from ..base.grid import Grid
from ..base.progress import Reporter
from ..base.sampling import multilinear_in_cells, sample, smoothstep
from .band import Band, inside
from .options import MotionOptions

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

    from .finepaths import FinePaths
    from .trajectory import Trajectories

__all__ = ["Transport", "inverse_lookup"]


_CONVERGED = 1e-7  # cells: a source point this close reads the field to ~1e-7 h
_GUESS_SLACK = 0.35  # cells: the widest a candidate's affine guess may stray outside its cell
_ON_FACE = 1e-4  # cells: local coordinates this far outside the unit cell still count as in it


def inverse_lookup(grid: Grid, corner_positions: np.ndarray, cells: np.ndarray, *,
                   newton_steps: int = MotionOptions.newton_steps, tol: float = 1e-6,
                   max_candidates: int = 65_536,
                   check: Callable[[], None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Semi-Lagrangian inverse lookup: for grid nodes z, source points x with x(s) = z.

    Every cell listed in ``cells`` is moved (its corners to
    ``corner_positions``; its interior is the multilinear image of the unit
    cell). Each grid node z in the moved cell's bounding box is first placed
    with the cell's affine part (candidates that cannot be in the cell are
    dropped), then refined by Newton steps on the multilinear map; z is kept when its local
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
        Cells are processed in chunks of at most this many candidate nodes (a
        chunk's arrays then stay small: less memory, and faster than large chunks),
        taken from runs of at most this many cells.
    check : callable, optional
        Called before every chunk (cancellation).

    Returns
    -------
    target : ndarray of int, shape (M,)
        Flat index of the grid node found.
    source : ndarray, shape (M, d)
        Its source point x in continuous node-index coordinates.
    """
    target, cell, local = _lookup_in_cells(grid, _index_corners(grid, corner_positions), cells,
                                           newton_steps=newton_steps, tol=tol,
                                           max_candidates=max_candidates, check=check)
    return target, _index_coordinates(grid, cells, cell, local)


def _index_coordinates(grid: Grid, cells: np.ndarray, cell: np.ndarray,
                       local: np.ndarray) -> np.ndarray:
    """Source points (M, d) in continuous node-index coordinates from their cells (indices
    into ``cells``) and local coordinates about the cell centres (d, M)."""
    base = np.stack(np.unravel_index(cells[cell], grid.shape), axis=-1)
    return base + 0.5 + local.T


def _lookup_in_cells(grid, corners, cells, *, newton_steps=MotionOptions.newton_steps, tol=1e-6,
                     max_candidates=65_536, check=None):
    """`inverse_lookup`'s nodes found (M,), each with its cell (an index into ``cells``) and
    its local coordinates about the cell's centre (d, M): what a multilinear read of node
    values at the source points needs (`multilinear_in_cells`). ``corners``: the moved
    cells' corners in index units, corner-major (2^d, d, C) (`_index_corners`), or a
    callable (c0, c1) -> those of cells c0:c1 (`_corner_gather`), made ``max_candidates``
    cells at a time so that no array of every cell's corners is held."""
    d = grid.dim
    if len(cells) == 0:  # an empty region: nothing moves, nothing is found
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((d, 0))
    corners_of = corners if callable(corners) else (lambda c0, c1: corners[..., c0:c1])
    found, local = [], []
    for b0 in range(0, len(cells), max_candidates):  # loop over chunks of cells
        block = corners_of(b0, min(b0 + max_candidates, len(cells)))
        lo, ext = _bounding_boxes(grid, block, tol)
        cnt = np.prod(ext, axis=0)
        for c0, c1 in _candidate_chunks(cnt, max_candidates):
            if check is not None:
                check()
            coef, Jinv, slack = _cell_maps(block[..., c0:c1], tol)
            cell, z, v = _lookup_chunk(cnt[c0:c1], ext[:, c0:c1], lo[:, c0:c1], coef, Jinv,
                                       slack, newton_steps)
            found.append((cell + b0 + c0, z))
            local.append(v)
    cell, zi = (np.concatenate(x, axis=-1) for x in zip(*found))
    return np.ravel_multi_index(tuple(zi), grid.shape), cell, np.concatenate(local, axis=1)


def _candidate_chunks(cnt, max_candidates):
    """(c0, c1) runs of cells with at most ``max_candidates`` bounding-box nodes in all
    (``cnt`` each cell's), or one cell where a cell alone has more: every per-cell and
    per-candidate array lives for one run only (bounded memory, even where a bad map
    stretches cells over many nodes)."""
    total = np.cumsum(cnt)
    bounds = np.searchsorted(total, np.arange(1, int(total[-1]) // max_candidates + 1)
                             * max_candidates)
    edges = np.unique(np.concatenate([[0], bounds, [cnt.size]]))
    return zip(edges[:-1], edges[1:])


def _index_corners(grid, corner_positions):
    """Moved corners (C, 2^d, d) in world units as the lookup takes them: in index units,
    corner-major (2^d, d, C), contiguous."""
    u = grid.to_index(np.asarray(corner_positions, dtype=float))
    return np.ascontiguousarray(u.transpose(1, 2, 0))


def _corner_gather(grid, node_positions, corner_of_cell):
    """`_index_corners` of cells whose corners are nodes, as a callable (c0, c1) -> the
    corners of cells c0:c1 (2^d, d, c1 - c0): ``node_positions`` (N, d) in world units,
    ``corner_of_cell`` (C, 2^d) rows into it. The nodes go to index units once, then each
    coordinate is gathered into its own rows, rather than gathering the cells' corners
    (C, 2^d, d) and laying them out again (benchmarks/README.md, "Inverse lookup in
    runs of candidates")."""
    u = np.ascontiguousarray(grid.to_index(node_positions).T)  # (d, N)

    def corners_of(c0, c1):
        index = corner_of_cell[c0:c1].T
        out = np.empty((index.shape[0], u.shape[0], index.shape[1]))
        for a in range(u.shape[0]):
            np.take(u[a], index, out=out[:, a])
        return out
    return corners_of


def _bounding_boxes(grid, corners, tol):
    """The grid nodes' index box of every moved cell (corners (2^d, d, C), index units):
    its lowest node (d, C) and its extent in nodes (d, C), 0 where it holds none."""
    low, high = corners.min(axis=0), corners.max(axis=0)  # (d, C), this call's own arrays
    low -= tol
    np.ceil(low, out=low)
    high += tol
    np.floor(high, out=high)
    np.maximum(low, 0, out=low)
    np.minimum(high, np.asarray(grid.shape)[:, None] - 1, out=high)
    high -= low
    high += 1
    np.maximum(high, 0, out=high)
    return low.astype(np.int64), high.astype(np.int64)


def _cell_maps(corners, tol):
    """The moved cells' multilinear maps (corners (2^d, d, C), index units), batch axis
    last: centred coefficients (2^d, d, C), inverse Jacobians at the centres (d, d, C) and
    how far outside the unit cell an affine guess may fall (d, C; `_affine_slack`)."""
    coef = _centred_coefficients(corners)
    Jinv = _inverse_small(_centre_jacobian(coef))
    return coef, Jinv, np.minimum(_affine_slack(coef, Jinv), _GUESS_SLACK) + _ON_FACE + tol


def _lookup_chunk(cnt, ext, lo, coef, Jinv, slack, newton_steps):
    """Inverse lookup for one chunk of cells (their candidate counts, bounding boxes,
    coefficients, centre inverses and slacks, batch axis last): the cell (index into
    the chunk) and node index (d, M) found, and their local coordinates (d, M).

    Local coordinates v are about the cell's centre (the unit cell is |v_a| <= 1/2).
    A candidate whose affine guess lies farther than its cell's ``slack`` outside
    the unit cell cannot be in the cell (`_affine_slack`) and gets no Newton steps.
    """
    d = lo.shape[0]
    # every grid node inside every moved cell's bounding box (variable-size boxes, vectorised)
    cc = np.repeat(np.arange(cnt.size), cnt)
    start = np.cumsum(cnt) - cnt
    rem = np.arange(int(cnt.sum())) - np.repeat(start, cnt)
    z = np.empty((d, cc.size))
    for a in reversed(range(d)):
        e = ext[a, cc]
        z[a] = lo[a, cc] + rem % e
        rem = rem // e
    # affine guess from the cell centre; drop candidates that cannot be in the cell
    v = _apply_small(Jinv[..., cc], z - coef[0][:, cc])
    keep = np.all(np.abs(v) < 0.5 + slack[:, cc], axis=0)
    cc, z, v = cc[keep], z[:, keep], v[:, keep]
    todo = np.arange(cc.size)  # Newton only on candidates not yet converged
    res = np.full(cc.size, np.inf)
    a = coef[..., cc]
    for it in range(newton_steps + 1):
        # after the affine guess nearly every candidate needs a step: its Jacobian comes
        # with the values (they share their partial sums); later only the live ones get one
        T, J = _poly_eval(a, v[:, todo], jacobian=(it == 0 and newton_steps > 0))
        r = T - z[:, todo]
        res[todo] = np.einsum("dm,dm->m", r, r)
        live = res[todo] > _CONVERGED ** 2
        todo, r, a = todo[live], r[:, live], a[..., live]
        if it == newton_steps or todo.size == 0:
            break
        J = _poly_eval(a, v[:, todo])[1] if J is None else J[..., live]
        # a singular cell: no step
        v[:, todo] = np.clip(v[:, todo] - _apply_small(_inverse_small(J, singular=0.0), r), -1.0, 1.0)
    inside = np.all(np.abs(v) <= 0.5 + _ON_FACE, axis=0) & (res < 1e-8)
    return cc[inside], z[:, inside].astype(np.int64), v[:, inside]


def _centred_coefficients(P):
    """Monomial coefficients (2^d, d, C) of multilinear cells about their centres.

    A cell's map is T(0.5 + v) = sum_S c_S prod_{a in S} v_a over the subsets S
    of the axes (S <-> the corner with bits S, `elements.corners` order): c_{} is
    the centre's image, c_{a} the Jacobian's column a there. Along axis a, values
    p0, p1 at its two ends give (p0 + p1) / 2 + v_a (p1 - p0); over all axes that is
    the corners ``P`` (2^d, d, C) times the Kronecker product of d copies of
    [[1/2, 1/2], [-1, 1]], one matrix product over the corner axis.
    """
    return np.tensordot(_centring_matrix(P.shape[1]), P, axes=(1, 0))


def _centring_matrix(d):
    """The (2^d, 2^d) matrix of `_centred_coefficients`."""
    m = np.ones((1, 1))
    for _ in range(d):
        m = np.kron(m, [[0.5, 0.5], [-1.0, 1.0]])
    return m


def _centre_jacobian(coef):
    """The Jacobians (d, d, C) at the cells' centres: column a is the coefficient of v_a."""
    d = coef.shape[1]
    return coef[2 ** np.arange(d)[::-1]].swapaxes(0, 1)  # the corner with only bit a set


def _poly_eval(coef, v, jacobian=True):
    """T (d, M) and its Jacobian (d, d, M) at local points v (d, M) of multilinear maps
    given by their monomial coefficients (2^d, d, M).

    The coefficients, seen as an array (2, ..., 2, d, M) with one binary axis per
    coordinate (`elements.corners` order), are contracted one axis at a time, last
    first: c0 + v_a c1 for T. dT/dv_a takes c1 where T contracts axis a and is then
    contracted over the axes before it as T is, so the Jacobian shares T's partial sums.
    """
    d = v.shape[0]
    val = coef.reshape((2,) * d + coef.shape[1:])
    derivs = []  # dT/dv_b of the axes b contracted so far, the last axis first

    def contract(x, a):
        at = (slice(None),) * a
        return x[at + (0,)] + v[a] * x[at + (1,)]

    for a in reversed(range(d)):
        derivs = [contract(x, a) for x in derivs]
        if jacobian:
            derivs.append(val[(slice(None),) * a + (1,)])
        val = contract(val, a)
    if not jacobian:
        return val, None
    return val, np.stack(derivs[::-1], axis=1)


def _affine_slack(coef, Jinv):
    """How far, per local axis, a node's affine guess can lie from its exact local
    coordinates in a multilinear cell, (d, C).

    With centred coefficients (`_centred_coefficients`), T(0.5 + v) = c_{} + J0 v
    + N(v), N the monomials of two or more axes (|v_a| <= 1/2 in the cell); for z =
    T(0.5 + v) the affine guess J0^-1 (z - c_{}) is v + J0^-1 N(v), so it is off
    by at most |J0^-1| max|N| per axis.
    """
    d = coef.shape[1]
    degree = elements.corners(d).sum(axis=1)
    high = degree >= 2
    bound = np.einsum("kdc,k->dc", np.abs(coef[high]), 0.5 ** degree[high])
    return _apply_small(np.abs(Jinv), bound)


def _inverse_small(J: np.ndarray, singular: float = 1.0) -> np.ndarray:
    """Inverses (d, d, M) of a batch of 2x2 / 3x3 matrices (d, d, M), by the adjugate;
    ``singular`` times the identity where a matrix is singular."""
    d = J.shape[0]
    cof = cofactor(J, batch_last=True)
    adj = cof.swapaxes(0, 1)
    det = np.einsum("dm,dm->m", J[0], cof[0])
    ok = np.abs(det) > 1e-12
    out = adj / np.where(ok, det, 1.0)
    out[:, :, ~ok] = singular * np.eye(d)[:, :, None]
    return out


def _apply_small(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A x for a batch of small matrices (d, d, M) and vectors (d, M)."""
    return np.einsum("ijm,jm->im", A, x)


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
    torn : bool ndarray over the grid's cells, optional
        The cells where the map tears (`map.tear`): their corners lie on two pieces
        that part, so they carry nothing; the pieces part with empty space between.

    Attributes
    ----------
    border_value : float
        The field's smallest value on the border of the region (world units).
    truncation : float
    """

    def __init__(self, field: ArrayLike, trajectories: Trajectories | FinePaths, *,
                 interpolation: str = MotionOptions.interpolation,
                 newton_steps: int = MotionOptions.newton_steps,
                 truncation: float | None = None, cancel: Callable[[], bool] | None = None,
                 torn: ArrayLike | None = None) -> None:
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
        self._torn = (np.zeros(len(self._cells), bool) if torn is None
                      else np.asarray(torn)[np.unravel_index(self._cells, grid.shape)])
        self.truncation = self.border_value if truncation is None else float(truncation)
        self.band_depth = np.inf  # the whole region, read (`band.Band`; set by `levelset`)
        self._lift: np.ndarray | None = None  # `_lifted`, made once
        self._band: tuple[tuple, Band] | None = None  # `_band_for`'s last, with its key

    def read(self, field: np.ndarray, u: np.ndarray, coef: np.ndarray | None = None) -> np.ndarray:
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

    def sources(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Inverse lookup at time t: (target node, source point in index coordinates) pairs."""
        band = Band.whole(self._cnodes_local)
        target, cell, local = self._sources_in_cells(t, band)
        return target, _index_coordinates(self.grid, self._cells, cell, local)

    def _sources_in_cells(self, t: float,
                          band: Band) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`sources` of the ``band``'s cells as (target node, source cell (an index into
        ``band.cells``), local coordinates (d, M)) (`_lookup_in_cells`)."""
        pos = self.trajectories.node_positions(t, self._corner_nodes[band.nodes])
        return _lookup_in_cells(self.grid, _corner_gather(self.grid, pos, band.local),
                                self._cells[band.cells], newton_steps=self.newton_steps,
                                check=self._check)

    def value_at(self, points: ArrayLike) -> np.ndarray:
        """The keyframe's own field at world points (P, d)."""
        return self.read(self.field, self.grid.to_index(points), self._coef)

    def carry(self, t: float, other: Transport | None = None,
              values: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
        """The field carried to time t, flat (grid.size,); NaN where no moved cell reaches.

        Each source point x carries its own keyframe's value f(x); with
        ``other`` (the other keyframe's `Transport`) it carries

            v_t(x) = f(x) + w max(0, g(y(x)) - f(x)) = (1 - w) f + w max(f, g(y)),

        g the other keyframe's field and y this transport's map: where the
        map takes material into the other keyframe's empty space (a tear:
        a merge seen backwards, or a split), that material fades out on the
        way, while the other keyframe never adds depth to this one's empty
        space. The lift max(0, g(y) - f) is taken at the region's nodes once and
        read multilinearly between them (`_lifted`). The fade's weight w is t, as
        fast as straight-timed paths open the tear from its start. Paths bent through a chain's keyframes leave
        a keyframe without spreading its material (their velocity there has no
        divergence, `spline.incompressible`), so their tear opens from rest and
        w = t^2 (3 - 2 t) fades it from rest too, at both ends, and as far as t
        half-way: a fade at full rate would take volume the paths do not
        spread, which the iso-value would give back by moving the whole surface
        (docs/method.md, section 12). In the crack of a map that tears
        (``torn``) the weight is min(2 t, 1): that material is gone by
        half-way. ``values(u)`` (u source points in index coordinates)
        replaces both. Values are truncated at
        ``truncation``; overlaps keep the smallest. With a finite `band_depth`
        only the narrow band is read (`band.Band`): the nodes its deep cells cover
        take -`band_depth`.
        """
        return self._carried(t, other, values)[0]

    def carry_meeting(self, t: float, other: Transport | None, reach: float | None,
                      whole: bool = False) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """`carry`, where this keyframe's parts meet at time t, and the nodes that took
        the band's deep value (bool, grid.size); ``whole``: the whole region moved and read,
        whatever `band_depth` (a frame the band could not make).

        Parts meet at the nodes that moved cells of two different parts (`ndimage.label`
        of its material, each region cell taking the part nearest it) reach with values
        under ``reach`` (world units), i.e. within ``reach`` of both parts' carried
        surfaces. None for a keyframe of one part, or when ``reach`` is None (not asked)."""
        out, target, cell, vals, band, deep = self._carried(t, other, None, reach, whole)
        parts = None if reach is None else self._cell_part
        if parts is None:
            return out, None, deep
        parts = parts[band.cells]
        near = vals < reach
        count = np.zeros(self.grid.size, np.int16)
        for k in range(int(parts.max()) + 1):
            reached = np.zeros(self.grid.size, bool)
            reached[target[near & (parts[cell] == k)]] = True
            count += reached
        return out, count >= 2, deep

    @functools.cached_property
    def _cell_part(self) -> np.ndarray | None:
        """The part (0-based) of every region cell (`carry_meeting`), or None."""
        return _cell_parts(self.grid, self.field < 0, self._cells, self._corner_nodes)

    @property
    def parts(self) -> bool:
        """Whether the keyframe has several parts (`carry_meeting` can find them meeting)."""
        return self._cell_part is not None

    def _carried(self, t, other, values, reach=None, whole=False):
        """`carry`'s field, with the inverse lookup's target nodes, their source cells (in
        the band), the values they carry, the `band.Band` moved, and the nodes that took
        its deep value (bool, grid.size; `band.inside`)."""
        faded = other is not None and t > 0 and values is None
        band = (Band.whole(self._cnodes_local) if values is not None or whole
                else self._band_for(other if faded else None, reach))
        target, cell, local = self._sources_in_cells(t, band)
        source = _index_coordinates(self.grid, self._cells[band.cells], cell, local)
        if values is not None:
            vals = values(source)
        else:
            vals = self.read(self.field, source, self._coef)
            if faded:
                fade = t if self.trajectories.bend is None else float(smoothstep(t))
                fade = np.where(self._torn[band.cells[cell]], min(2.0 * t, 1.0), fade)
                vals += fade * multilinear_in_cells(self._lifted(other)[band.nodes, None],
                                                    band.local, cell, local)[:, 0]
        vals = np.minimum(vals, self.truncation)
        out = np.full(self.grid.size, np.inf)
        np.minimum.at(out, target, vals)
        out[np.isinf(out)] = np.nan
        deep = inside(out, self.grid) if band.deep else np.zeros(self.grid.size, bool)
        out[deep] = -band.depth
        return out, target, cell, vals, band, deep

    def _lifted(self, other: Transport) -> np.ndarray:
        """max(0, g(y(x)) - f(x)) at the region's corner nodes x (`carry`): how far the
        other keyframe's field g at the map's image lies above this one's f."""
        if self._lift is None:
            y = self.trajectories.node_positions(1.0, self._corner_nodes)
            self._lift = np.maximum(other.value_at(y) - self._corner_values, 0.0)
        return self._lift

    @functools.cached_property
    def _corner_values(self) -> np.ndarray:
        """The keyframe's field at the region's corner nodes (``_corner_nodes``)."""
        return self.field.reshape(-1)[self._corner_nodes]

    def _band_for(self, other: Transport | None, reach: float | None) -> Band:
        """The `band.Band` a frame moves: its cells' values lie between f and f plus the
        lift (with ``other``); a cell counts as beyond the truncation only where that is
        also beyond ``reach``, so that `carry_meeting` sees every value under it."""
        beyond = self.truncation if reach is None or reach <= self.truncation else np.inf
        key = (other is not None, beyond, self.band_depth)
        if self._band is None or self._band[0] != key:
            own = self._corner_values
            upper = own if other is None else own + self._lifted(other)
            self._band = (key, Band.of(self._cnodes_local, own, upper, beyond,
                                       self.band_depth, self.grid.spacing))
        return self._band[1]

    def surface_motion(self, t: float, near: float,
                       dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
        """The nodes within ``near`` (world units) of the keyframe's surface at time t:
        their positions (M, d) and velocities dx/dt (M, d).

        Second-order finite differences with step ``dt``: central, or one-sided over
        three times where t is within ``dt`` of an end. With ``dt`` one frame, the
        times are the neighbouring frames' (which the trajectories keep).
        """
        nodes = self._corner_nodes[np.abs(self._corner_values) <= near]
        paths = self.trajectories
        pos = paths.node_positions(t, nodes)
        dt = min(float(dt), 0.25)  # so that one of the one-sided triples fits in [0, 1]

        def at(time: float) -> np.ndarray:  # the ends exactly (i/n - 1/n is not always 0)
            return paths.node_positions(min(max(round(time, 12), 0.0), 1.0), nodes)
        if t - dt >= 0.0 and t + dt <= 1.0:
            return pos, (at(t + dt) - at(t - dt)) / (2.0 * dt)
        step = dt if t + 2.0 * dt <= 1.0 else -dt  # (-3 x0 + 4 x1 - x2) / (2 step)
        one, two = at(t + step), at(t + 2.0 * step)
        return pos, (4.0 * one - 3.0 * pos - two) / (2.0 * step)


def _cell_parts(grid: Grid, material: np.ndarray, cells: np.ndarray,
                nodes: np.ndarray) -> np.ndarray | None:
    """The part (0-based) of every region cell: that of the material component nearest its
    lower corner (labels grown from the material a cell a step until every region node
    has one); None for a keyframe of one part."""
    labels, count = ndimage.label(material)
    if count < 2:
        return None
    flat = labels.reshape(-1)
    while not np.all(flat[nodes]):
        labels = np.where(labels > 0, labels,
                          ndimage.grey_dilation(labels, size=(3,) * grid.dim))
        flat = labels.reshape(-1)
    return (flat[cells] - 1).astype(np.int16)


def _region_cells(grid: Grid,
                  region: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:

    """`elements.cells_within` of ``region``, and its border nodes: corners of some region
    cell that are not surrounded by region cells (fewer than 2**d region cells use them)."""
    cells, nodes, local = elements.cells_within(grid, region)
    surrounded = np.bincount(local.reshape(-1), minlength=len(nodes)) == 2 ** grid.dim
    return cells, nodes, local, nodes[~surrounded]
