"""The terms of the objective, eq. 2.6 -- one function per term.

    f(y) = w_vol * int (det F - 1)^2                      `volume_term`
         + w_rig * int ||F^T F - I||_F^2                  `rigidity_term`
         + w_ls  * int (H(Phi(x)) - H(Psi(y(x))))^2       `levelset_term`

with F = dy/dx (discretised in `keyframe_implicit.core.base.elements`), H the
smeared Heaviside of eq. 2.7 (middle case -eps <= phi <= eps as corrected in
docs/method.md, section 2, eps = 1.5 h) and the weights given to `solve_map` as
``volume_weight``, ``rigidity_weight``, ``levelset_weight`` (each term's
default is in `TERMS`).

Every term returns a `TermValue`: its energy (the weighted integral, world
units h**d per cell), its gradient and its Gauss-Newton Hessian blocks
``2 J^T J`` in closed form (no Jacobian matrix is ever formed). Each term is
a sum of squared residuals ``r``: energy ``sum w r^2``, gradient ``2 w J^T r``.

Two kinds of term exist:

``"element"``
    takes an `ElementBatch` (corner positions of E cells) and returns the
    gradient per element ``(E, 2**d, d)`` and the Hessian blocks
    ``(E, 2**d, 2**d, d, d)`` (block [c, c'] couples corners c and c');
``"node"``
    takes a `NodeBatch` (the mapped nodes) and returns the gradient ``(n, d)``
    and diagonal Hessian blocks ``(n, d, d)`` (nodal quadrature: each node
    carries the lumped volume of the weighted cells around it).

Adding a fourth term
--------------------
Write ``def my_term(batch, hessian=True) -> TermValue`` for one of the two
kinds (see `volume_term` for the pattern: residual, its derivative w.r.t. the
corner positions, then energy / gradient / ``2 w J J^T``) and append
``Term("my", "my_weight", "element", my_term, default=...)`` to `TERMS`.
`solve_map` then accepts ``my_weight=...`` and `animate` ``weights={"my": ...}``; the
solver assembles the term into the Gauss-Newton system and reports its value per
iteration in ``stats["history"]`` and at the end in ``stats["terms"]``. The Blender panel
shows a property for each of the three terms it knows (blender/props.py).
Rigid motions must cost nothing if the term is physical.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable


import numpy as np

from ..base.elements import Quadrature, cofactor, deformation_gradient, determinant, gram
from ..base.sampling import sample_with_gradient

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ..base.grid import Grid

__all__ = ["TermValue", "ElementBatch", "NodeBatch", "Term", "TERMS", "heaviside",
           "heaviside_derivative", "volume_term", "rigidity_term", "levelset_term"]


@dataclass
class TermValue:
    """Energy, gradient and Gauss-Newton Hessian blocks of one term (unweighted by the user weight)."""

    energy: float
    grad: np.ndarray | None
    hess: np.ndarray | None


@dataclass
class ElementBatch:
    """E cells of the solved region.

    Y : (E, 2**d, d) mapped corner positions.
    weight : (E,) region weight of each cell (1 in A's material, less in the margin).
    gauss, centre : `Quadrature` rules of `keyframe_implicit.core.base.elements`.
    """

    Y: np.ndarray
    weight: np.ndarray
    gauss: Quadrature
    centre: Quadrature


@dataclass
class NodeBatch:
    """The mapped nodes of the solved region.

    y : (n, d) mapped positions y(x).
    weight : (n,) lumped volume (region weight * h**d) of each node.
    h_phi : (n,) H(Phi(x)) at the node (constant during the solve).
    psi : ndarray, Psi on ``grid`` (keyframe B's signed distance).
    grid : `Grid` of ``psi``.
    eps : float, the smearing width of eq. 2.7.
    """

    y: np.ndarray
    weight: np.ndarray
    h_phi: np.ndarray
    psi: np.ndarray
    grid: Grid
    eps: float


@dataclass(frozen=True)
class Term:
    """Registry entry: name, option name of its weight, kind ("element"/"node"), function,
    and the weight `solve_map` uses when the caller gives none."""

    name: str
    weight_option: str
    kind: str
    function: Callable[..., TermValue]

    default: float = 0.0


def heaviside(phi: ArrayLike, eps: float) -> np.ndarray:
    """Smeared Heaviside H of eq. 2.7 (0 inside below -eps, 1 outside above eps)."""
    phi = np.asarray(phi, dtype=float)
    mid = 0.5 + phi / (2 * eps) + np.sin(np.pi * phi / eps) / (2 * np.pi)
    return np.where(phi < -eps, 0.0, np.where(phi > eps, 1.0, mid))


def heaviside_derivative(phi: ArrayLike, eps: float) -> np.ndarray:
    """dH/dphi of eq. 2.7: (1 + cos(pi phi / eps)) / (2 eps) on |phi| <= eps, else 0."""
    phi = np.asarray(phi, dtype=float)
    mid = (1.0 + np.cos(np.pi * phi / eps)) / (2 * eps)
    return np.where(np.abs(phi) <= eps, mid, 0.0)


def volume_term(batch: ElementBatch, hessian: bool = True) -> TermValue:
    """Volume term of eq. 2.6, (det F - 1)^2 at the cell centre.

    Residual r_e = det F_e - 1 with F_e at the cell centre; its derivative
    w.r.t. corner c, coordinate j is ``(cof F G)[j, c]`` (cof = cofactor,
    d det F / dF). Zero for every rigid motion (det R = 1).
    """
    G = batch.centre.G  # (1, d, K)
    vol = batch.centre.weights[0]
    F = deformation_gradient(batch.Y, G)[:, 0]  # (E, d, d)
    r = determinant(F) - 1.0
    w = batch.weight * vol
    energy = float(np.sum(w * r * r))
    # (E, K, d): dr / dY[c, j], in C order so that the gradient and the Hessian blocks are too
    J = np.ascontiguousarray((cofactor(F) @ G[0]).transpose(0, 2, 1))
    grad = (2.0 * w * r)[:, None, None] * J
    hess = None
    if hessian:
        E, K, d = J.shape
        Js = np.sqrt(2.0 * w)[:, None, None] * J
        # (E, c, c', j, j') = Js[c, j] Js[c', j'], multiplied as rows of d*d so that numpy's
        # inner loop runs over (j, j') rather than over j' alone (twice as fast)
        row, col = np.repeat(Js, d, axis=2), np.tile(Js, d)  # [c, (j, j')]: Js[c, j], Js[c, j']
        hess = (row[:, :, None] * col[:, None]).reshape(E, K, K, d, d)
    return TermValue(energy, grad, hess)


def rigidity_term(batch: ElementBatch, hessian: bool = True) -> TermValue:
    """Rigidity term of eq. 2.6, ||F^T F - I||_F^2 at the 2**d Gauss points.

    With R = F^T F - I (symmetric) and B = F G (d x 2**d):
    gradient ``4 (F R G)[j, c]`` per Gauss point, and the Gauss-Newton block
    ``2 J^T J = 4 ( (G^T G)[c, c'] (F F^T)[j, j'] + B[j', c] B[j, c'] )``.
    Zero for every rigid motion (F^T F = I); the Gauss points see the
    hourglass modes that the cell centre misses (see `elements`).
    """
    G = batch.gauss.G  # (Q, d, K)
    qw = batch.gauss.weights  # (Q,)
    F = deformation_gradient(batch.Y, G)  # (E, Q, d, d)
    E, Q, d = F.shape[0], F.shape[1], F.shape[-1]
    nK = G.shape[2]
    FFt = gram(F)
    M = FFt - np.eye(d)  # same Frobenius norm as R = F^T F - I, and F R = M F
    w = batch.weight[:, None] * qw[None, :]  # (E, Q)
    energy = float(np.sum(w * np.sum(M * M, axis=(-1, -2))))
    B = F @ G[None]  # (E, Q, d, K)
    grad = 4.0 * np.einsum("eq,eqjc->ecj", w, M @ B)  # F R G = M F G = M B
    hess = None
    if hessian:
        Kq = (G.swapaxes(1, 2) @ G).reshape(Q, nK * nK)  # G^T G per Gauss point
        S = ((4.0 * w)[:, :, None, None] * FFt).reshape(E, Q, d * d)
        # 4 sum_q w (G^T G)[c, c'] (F F^T)[j, j']  ->  (E, c, c', j, j')
        hess = (Kq.T[None] @ S).reshape(E, nK, nK, d, d)
        # 4 sum_q w B[j', c] B[j, c']: Gram matrix over q of V[q, (j, c)] = 2 sqrt(w) B[j, c]
        # (B's own layout), t2[e, j, c', j', c] = 4 sum_q w B[j, c'] B[j', c]; V^T @ V is
        # faster with V^T copied to C order (small: 2**d d floats per Gauss point)
        V = ((2.0 * np.sqrt(w))[:, :, None, None] * B).reshape(E, Q, d * nK)
        t2 = (np.ascontiguousarray(V.transpose(0, 2, 1)) @ V).reshape(E, d, nK, d, nK)
        hess += t2.transpose(0, 4, 2, 1, 3)
    return TermValue(energy, grad, hess)


def levelset_term(batch: NodeBatch, hessian: bool = True) -> TermValue:
    """Level-set term of eq. 2.6, (H(Phi(x)) - H(Psi(y(x))))^2 at the nodes.

    Psi is read at the off-grid mapped positions y with
    `keyframe_implicit.core.base.sampling.sample_with_gradient` (multilinear
    interpolation, piecewise-constant gradient; outside the grid it grows as
    the distance to the box, so far points stay "outside"). Residual
    r = H(Phi) - H(Psi(y)), derivative ``-H'(Psi) grad Psi``.
    """
    psi, gpsi = _sample_sdf(batch.psi, batch.grid, batch.y)
    r = batch.h_phi - heaviside(psi, batch.eps)
    w = batch.weight
    energy = float(np.sum(w * r * r))
    J = -heaviside_derivative(psi, batch.eps)[:, None] * gpsi  # (n, d)
    grad = (2.0 * w * r)[:, None] * J
    hess = None
    if hessian:
        hess = (2.0 * w)[:, None, None] * J[:, :, None] * J[:, None, :]
    return TermValue(energy, grad, hess)


def _sample_sdf(psi: np.ndarray, grid: Grid, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Multilinear Psi and its gradient at y; outside the grid box Psi grows as the distance to it."""
    return sample_with_gradient(psi, grid, y, outside="distance")


#: The terms of eq. 2.6 in evaluation order. Append a `Term` to add one.
TERMS = (
    Term("volume", "volume_weight", "element", volume_term, default=30.0),
    Term("rigidity", "rigidity_weight", "element", rigidity_term, default=1.0),
    Term("levelset", "levelset_weight", "node", levelset_term, default=10.0),
)
