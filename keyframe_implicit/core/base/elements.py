"""Hourglass-free discretisation of F = dy/dx on the grid cells (thesis sec. 2.4).

The thesis' "naive" one-F-per-cell difference (eq. 2.9-2.10) has hourglass
modes: a checkerboard motion of the nodes leaves the cell-centre F unchanged,
so it costs no energy. The thesis subdivides each cell (fig. 2.1-2.2); the 3D
split is not spelled out (docs/method.md, section 3). Here every cell is a
multilinear (bilinear in 2D, trilinear in 3D) finite element:

* the rigidity term of eq. 2.6 is integrated with the 2**d-point Gauss rule
  (points at 1/2 +- 1/(2 sqrt 3) of the cell): the hourglass modes have a
  non-zero gradient there, so they raise the energy;
* the volume term is integrated at the cell centre (one point). Evaluating
  det F at one point avoids the volumetric locking that full integration of a
  near-incompressible term causes, and hourglass control comes from the
  rigidity term. (A throwaway prototype measured lower converged energies
  than 5- or 6-tetrahedron splits.)

All operators are small constant matrices: ``G`` of shape ``(d, 2**d)`` with
``F[i, a] = sum_c Y[c, i] * G[a, c]`` where ``Y`` holds the cell's corner
positions y in the corner order of `corners` (the order of
`keyframe_implicit.core.base.sampling.cell_weights`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from .grid import Grid

__all__ = ["corners", "corner_views", "cells_within", "gradient_operator", "Quadrature",
           "quadrature", "deformation_gradient", "determinant", "cofactor", "inverse", "gram"]


def corners(d: int) -> np.ndarray:
    """Corner offsets of a cell, shape ``(2**d, d)``, in ``itertools.product`` order."""
    return np.array(list(itertools.product((0, 1), repeat=d)), dtype=np.int64)


def corner_views(values: np.ndarray, d: int | None = None) -> list[np.ndarray]:
    """A node array seen from the cells: one view per corner offset c (`corners` order).

    ``views[k][i]`` is the value at node ``i + corners(d)[k]`` of cell ``i`` (its lowest
    corner at node ``i``); each view has one entry fewer than the grid along each axis.
    Per-cell sums, "any corner" and "all corners" are reductions over the views.

    Parameters
    ----------
    values : ndarray, the grid's shape (plus trailing axes, if any)
    d : int, optional
        Number of grid axes (default ``values.ndim``).
    """
    d = values.ndim if d is None else d
    n = values.shape[:d]
    return [values[tuple(slice(o, o + m - 1) for o, m in zip(c, n))] for c in corners(d)]


def cells_within(grid: Grid, region: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cells whose 2**d corners all lie in ``region`` (bool over the grid's nodes).

    Returns
    -------
    lower : (nc,) int
        Flat node index of each cell's lowest corner (cells in C order).
    nodes : (n,) int
        The flat indices of their corners, sorted, each once.
    local : (nc, 2**d) int
        Each cell's corners as indices into ``nodes``, in `corners` order.
    """
    views = corner_views(np.asarray(region, dtype=bool).reshape(grid.shape))
    inside = views[0].copy()
    for v in views[1:]:
        inside &= v
    cell_shape = inside.shape
    lower = np.ravel_multi_index(np.unravel_index(np.flatnonzero(inside), cell_shape), grid.shape)
    corner_nodes = lower[:, None] + (corners(grid.dim) @ grid.strides)[None, :]
    nodes, local = grid.unique_nodes(corner_nodes)
    return lower, nodes, local


def gradient_operator(d: int, xi: ArrayLike, h: float) -> np.ndarray:
    """World-space gradients of the multilinear shape functions at local point ``xi``.

    Parameters
    ----------
    d : int
        2 or 3.
    xi : array_like, shape (d,)
        Point in the reference cell [0, 1]**d.
    h : float
        Cell edge length (world units).

    Returns
    -------
    ndarray, shape (d, 2**d)
        ``G[a, c] = dN_c / dx_a`` so that ``F = Y^T G^T`` for corner positions ``Y``.
    """
    xi = np.asarray(xi, dtype=float)
    cs = corners(d)
    lin = np.where(cs == 1, xi[None, :], 1.0 - xi[None, :])  # (2**d, d)
    sgn = np.where(cs == 1, 1.0, -1.0)
    G = np.empty((d, 2 ** d))
    for a in range(d):
        f = lin.copy()
        f[:, a] = sgn[:, a]
        G[a] = np.prod(f, axis=1) / h
    return G


@dataclass(frozen=True)
class Quadrature:
    """Gradient operators and weights of one integration rule on a cell.

    ``G`` has shape ``(Q, d, 2**d)``; ``weights`` (Q,) sum to the cell volume h**d.
    """

    G: np.ndarray
    weights: np.ndarray


def quadrature(d: int, h: float, rule: str) -> Quadrature:
    """Integration rule ``"gauss"`` (2**d points, for rigidity) or ``"centre"`` (1 point, volume)."""
    if rule == "centre":
        pts = np.full((1, d), 0.5)
    elif rule == "gauss":
        g = 0.5 / np.sqrt(3.0)
        pts = 0.5 + g * (2.0 * corners(d) - 1.0)
    else:
        raise ValueError(f'quadrature rule must be "gauss" or "centre", got {rule!r}.')
    G = np.stack([gradient_operator(d, p, h) for p in pts])
    w = np.full(len(pts), h ** d / len(pts))
    return Quadrature(G=G, weights=w)


def deformation_gradient(Y: np.ndarray, G: np.ndarray) -> np.ndarray:
    """F = dy/dx at each quadrature point of each element.

    Parameters
    ----------
    Y : ndarray, shape (E, 2**d, d)
        Mapped corner positions of E cells.
    G : ndarray, shape (Q, d, 2**d)

    Returns
    -------
    ndarray, shape (E, Q, d, d), ``F[e, q, i, a] = dy_i / dx_a``.

    One matrix product of the corners as rows (E, 2**d d) with the constant operator of
    `_corner_operator`: a single BLAS call, where a stack of E Q small products costs
    several times as much.
    """
    E, K, d = Y.shape
    return (Y.reshape(E, K * d) @ _corner_operator(G)).reshape(E, len(G), d, d)


def _corner_operator(G: np.ndarray) -> np.ndarray:
    """The (2**d d, Q d d) matrix W with F[e, (q, i, a)] = sum Y[e, (k, j)] W[(k, j), (q, i, a)],
    W = G[q, a, k] delta(i, j); made once per operator ``G`` (Q, d, 2**d)."""
    G = np.ascontiguousarray(G, dtype=float)
    key = (G.shape, G.tobytes())
    W = _OPERATORS.get(key)
    if W is None:
        Q, d, K = G.shape
        W = np.einsum("qak,ij->kjqia", G, np.eye(d)).reshape(K * d, Q * d * d)
        if len(_OPERATORS) >= 64:  # operators differ by level spacing only: a handful
            _OPERATORS.clear()
        _OPERATORS[key] = W
    return W


_OPERATORS: dict[tuple[tuple[int, ...], bytes], np.ndarray] = {}



def determinant(F: np.ndarray) -> np.ndarray:
    """det F for stacks of 2x2 or 3x3 matrices (closed form, no LAPACK call)."""
    if F.shape[-1] == 2:
        return F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0]
    return (F[..., 0, 0] * (F[..., 1, 1] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 1])
            - F[..., 0, 1] * (F[..., 1, 0] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 0])
            + F[..., 0, 2] * (F[..., 1, 0] * F[..., 2, 1] - F[..., 1, 1] * F[..., 2, 0]))


def gram(F: np.ndarray) -> np.ndarray:
    """F F^T for stacks of 2x2 or 3x3 matrices (..., d, d), symmetric by construction.

    Its d (d + 1) / 2 distinct entries are sums of d products of F's entries, taken over
    the whole stack at once, rather than one small product per matrix (``np.matmul``).
    """
    d = F.shape[-1]
    out = np.empty(F.shape[:-2] + (d, d), dtype=F.dtype)
    for i in range(d):
        for j in range(i, d):
            v = F[..., i, 0] * F[..., j, 0]
            for a in range(1, d):
                v += F[..., i, a] * F[..., j, a]
            out[..., i, j] = v
            out[..., j, i] = v
    return out


def cofactor(F: np.ndarray, batch_last: bool = False) -> np.ndarray:
    """Cofactor matrices, d(det F)/dF, of a stack of 2x2 or 3x3 matrices; defined also
    for singular F.

    ``F`` is (..., d, d), or (d, d, ...) with ``batch_last``: the layout whose entries are
    contiguous arrays, which the per-cell loops of the trajectories and the inverse lookup
    use. Each entry is one product of entry arrays over the whole stack.
    """
    M = F if batch_last else np.moveaxis(F, (-2, -1), (0, 1))
    C = np.empty_like(M)
    if M.shape[0] == 2:
        C[0, 0] = M[1, 1]
        C[0, 1] = -M[1, 0]
        C[1, 0] = -M[0, 1]
        C[1, 1] = M[0, 0]
    else:
        for i in range(3):
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            for a in range(3):
                a1, a2 = (a + 1) % 3, (a + 2) % 3
                C[i, a] = M[i1, a1] * M[i2, a2] - M[i1, a2] * M[i2, a1]
    return C if batch_last else np.moveaxis(C, (0, 1), (-2, -1))


def inverse(F: np.ndarray) -> np.ndarray:
    """Inverses of a stack (..., d, d) of non-singular 2x2 or 3x3 matrices, by the adjugate:
    much faster than a batched LAPACK call for matrices this small."""
    return cofactor(F).swapaxes(-1, -2) / determinant(F)[..., None, None]
