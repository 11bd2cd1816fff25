"""Multilinear sampling of grid fields at off-grid points.

Used wherever a field must be read between nodes: Psi(y(x)) in the level-set
term of eq. 2.6 (with its gradient for the Gauss-Newton Jacobian), the
bilinear/trilinear feature constraints of eq. 2.19 (as corrected in
docs/method.md, section 4), and the backward values of eq. 3.4.

Interpolation is (bi/tri)linear: the gradient is piecewise constant per cell,
exact for fields that are linear in the cell, and the weights are the
``t_i`` of eq. 2.19 (non-negative, summing to one).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .elements import corners
from .grid import Grid

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["cell_weights", "central_differences", "multilinear_in_cells", "sample",
           "sample_with_gradient", "smoothstep"]


def smoothstep(t: ArrayLike) -> np.ndarray:
    """t^2 (3 - 2 t) of t clipped to [0, 1]: a weight that rises from 0 to 1 and leaves
    both ends at rest (zero slope), for a blend that must not jump at either end."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def cell_weights(grid: Grid, points: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Corner nodes and multilinear weights of the cell holding each point.

    Points outside the grid are clamped onto its boundary first.

    Returns
    -------
    flat_index : ndarray of int, shape (P, 2**d)
        Flat (C-order) node index of each corner of the point's cell, corners in
        ``itertools.product((0, 1), repeat=d)`` order.
    weights : ndarray, shape (P, 2**d)
        Multilinear weights, non-negative, each row summing to 1.
    """
    idx, frac, _ = _locate(grid, points)
    return _corner_nodes(grid, idx), _corner_products(1.0 - frac, frac)


def _corner_nodes(grid: Grid, idx: np.ndarray) -> np.ndarray:
    """Flat node index (P, 2**d) of every corner of the cells whose lowest corner is ``idx``."""
    return (idx @ grid.strides)[:, None] + (corners(grid.dim) @ grid.strides)[None, :]


def _corner_products(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Per point, the product over the axes of ``lo`` or ``hi`` (P, d) picked by each corner
    bit: (P, 2**d), corners in ``itertools.product((0, 1), repeat=d)`` order (first axis
    slowest), built as an outer product one axis at a time."""
    pairs = np.stack([lo, hi], axis=-1)  # (P, d, 2): axis a's factor for bit 0 and bit 1
    out = pairs[:, 0]
    for a in range(1, lo.shape[1]):
        out = (out[:, :, None] * pairs[:, a, None, :]).reshape(lo.shape[0], -1)
    return out


def multilinear_in_cells(values: np.ndarray, corner_index: np.ndarray, cell: np.ndarray,
                         local: np.ndarray) -> np.ndarray:
    """Multilinear interpolation of node values at points given by their cells.

    Parameters
    ----------
    values : ndarray, shape (N, m)
        Values at N nodes.
    corner_index : ndarray of int, shape (C, 2^d)
        Each cell's corners as rows of ``values`` (`elements.corners` order).
    cell : ndarray of int, shape (M,)
        The cell of each point.
    local : ndarray, shape (d, M)
        Each point's coordinates about its cell's centre (the cell is |v_a| <= 1/2).

    Returns
    -------
    ndarray, shape (M, m): what `sample` reads at those points, without finding
    their cells again.
    """
    w = _corner_products((0.5 - local).T, (0.5 + local).T)
    out = np.zeros((cell.size, values.shape[1]))
    for c in range(w.shape[1]):  # loop over the 2^d corners
        out += w[:, c, None] * values[corner_index[cell, c]]
    return out


def _locate(grid: Grid, points: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lowest corner (P, d) of each point's cell, its place in that cell (P, d, in [0, 1]) and
    its unclamped index coordinates (P, d); points outside the grid are clamped onto it."""
    p = np.asarray(points, dtype=float).reshape(-1, grid.dim)
    u = grid.to_index(p)
    hi = np.asarray(grid.shape) - 1
    uc = np.clip(u, 0.0, hi)
    idx = np.minimum(np.floor(uc).astype(np.int64), hi - 1)
    return idx, uc - idx, u


def sample(field: ArrayLike, grid: Grid, points: ArrayLike, outside: str = "clamp") -> np.ndarray:
    """Multilinear value of ``field`` at world ``points``.

    Parameters
    ----------
    field : ndarray, shape grid.shape or grid.shape + (k,)
    points : ndarray, shape (..., d)
    outside : {"clamp", "distance"}
        ``"clamp"`` takes the value at the nearest boundary point. ``"distance"``
        (for signed distance fields) adds the distance to that boundary point,
        so the field keeps growing outside the grid and never turns "inside".

    Returns
    -------
    ndarray, shape points.shape[:-1] (+ (k,) for vector fields)
    """
    return _sample(field, grid, points, outside, gradient=False)


def sample_with_gradient(field: ArrayLike, grid: Grid, points: ArrayLike,
                         outside: str = "clamp") -> tuple[np.ndarray, np.ndarray]:
    """Value and spatial gradient (world units) of a scalar ``field`` at ``points``.

    The gradient is that of the multilinear interpolant (zero across the
    clamped direction outside the grid, plus the unit outward direction when
    ``outside="distance"``).
    """
    return _sample(field, grid, points, outside, gradient=True)


def central_differences(field: ArrayLike, grid: Grid, points: ArrayLike,
                        outside: str = "clamp") -> np.ndarray:
    """Central differences over one cell of the multilinear interpolant of a scalar
    ``field`` at ``points``: (f(p + h e_a) - f(p - h e_a)) / 2h for each axis a, (P, d).

    Unlike the interpolant's own gradient (`sample_with_gradient`, constant in a cell
    and jumping across its faces) this varies continuously with the point.

    A probe one cell along an axis lies at the same place in the neighbouring cell. So
    where every probe stays inside the grid the 2d probes share the point's weights, and
    each difference is those weights applied to the corners' differences across two
    cells. The other points are sampled probe by probe, with ``outside`` as in `sample`.
    """
    p = np.asarray(points, dtype=float).reshape(-1, grid.dim)
    h, d = grid.spacing, grid.dim
    out = np.empty_like(p)
    idx, frac, u = _locate(grid, p)
    inner = np.all((u >= 1.0) & (u < np.asarray(grid.shape) - 2.0), axis=1)
    if inner.any():
        flat = np.asarray(field, dtype=float).reshape(-1)
        nodes = _corner_nodes(grid, idx[inner])
        w = _corner_products(1.0 - frac[inner], frac[inner])
        for a, stride in enumerate(grid.strides):
            out[inner, a] = np.einsum("pk,pk->p", w, flat[nodes + stride] - flat[nodes - stride])
        out[inner] /= 2 * h
    rest = np.flatnonzero(~inner)
    if rest.size:
        eye = h * np.eye(d)
        probes = sample(field, grid, p[rest, None, :] + np.concatenate([eye, -eye])[None],
                        outside=outside)
        out[rest] = (probes[:, :d] - probes[:, d:]) / (2 * h)
    return out


def _sample(field: ArrayLike, grid: Grid, points: ArrayLike, outside: str, gradient: bool):

    field = np.asarray(field, dtype=float)
    pts = np.asarray(points, dtype=float)
    lead = pts.shape[:-1]
    if pts.shape[-1] != grid.dim:
        raise ValueError(f"points have {pts.shape[-1]} coordinates, the grid has {grid.dim} axes.")
    extra = field.shape[grid.dim:]
    if field.shape[: grid.dim] != grid.shape:
        raise ValueError(f"field shape {field.shape} does not start with grid shape {grid.shape}.")
    flat_field = field.reshape((grid.size,) + extra)
    p = pts.reshape(-1, grid.dim)
    idx, frac, u = _locate(grid, p)
    vals = flat_field[_corner_nodes(grid, idx)]  # (P, 2**d, *extra)
    w = _corner_products(1.0 - frac, frac)
    value = np.einsum("pk,pk...->p...", w, vals)

    if outside == "distance":
        if extra:
            raise ValueError('outside="distance" is for scalar fields only.')
        clamped = grid.to_world(idx + frac)
        off = p - clamped
        dist = np.linalg.norm(off, axis=-1)
        value = value + dist
    elif outside != "clamp":
        raise ValueError(f'outside must be "clamp" or "distance", got {outside!r}.')

    value = value.reshape(lead + extra)
    if not gradient:
        return value
    if extra:
        raise ValueError("sample_with_gradient is for scalar fields only.")
    grad = np.empty((p.shape[0], grid.dim))
    lo, hi = 1.0 - frac, frac.copy()
    for a in range(grid.dim):  # d/du_a of the multilinear weights: the factor of axis a is -1 / +1
        lo_a, hi_a = lo[:, a].copy(), hi[:, a].copy()
        lo[:, a], hi[:, a] = -1.0, 1.0
        grad[:, a] = np.einsum("pk,pk->p", _corner_products(lo, hi), vals) / grid.spacing
        lo[:, a], hi[:, a] = lo_a, hi_a
    if outside == "distance":
        # Along a clamped axis the interpolant is flat and the distance term supplies
        # the slope. Decide "clamped" from the index (not from dist > 0, which rounding
        # makes true for points inside the box) and take the slope per clamped axis.
        tol = 1e-9  # in cells: a node on the box's face is inside, whatever the rounding
        clamped_axis = (u < -tol) | (u > np.asarray(grid.shape) - 1 + tol)
        off = np.where(clamped_axis, off, 0.0)
        dist = np.linalg.norm(off, axis=-1)
        unit = np.divide(off, dist[:, None], out=np.zeros_like(off), where=dist[:, None] > 0)
        grad = np.where(clamped_axis, 0.0, grad) + unit
    return value, grad.reshape(lead + (grid.dim,))
