"""Rotations of small matrices: polar decomposition, log and exp maps, rigid fits.

The as-rigid-as-possible construction (docs/method.md, section 5) takes the
rotation out of each cell's deformation gradient (`polar`), turns it by a
fraction of its angle (`rotation_log`, `rotation_exp`), and fits the best
rigid motion to point sets (`rigid_fit`, thesis appendix A). The RBF start,
the template tracker and the bake's feature checks use the same routines.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .elements import cofactor

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["polar", "rotation_log", "rotation_exp", "rigid_fit"]


def polar(F: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Polar decomposition F = R S of a batch of d x d matrices (d = 2 or 3).

    R is a proper rotation (det R = +1) and S = R^T F is symmetric. For
    reflecting F (det F < 0) the closest rotation is taken and S gets one
    negative eigenvalue. 3 x 3 matrices with det F > 0 take a Newton iteration
    (`_newton_rotation`), the rest the SVD.

    Parameters
    ----------
    F : ndarray, shape (..., d, d)

    Returns
    -------
    R, S : ndarrays, shape (..., d, d)
    """
    F = np.asarray(F, dtype=float)
    d = F.shape[-1]
    flat = F.reshape(-1, d, d)
    R = np.empty_like(flat)
    newton = np.zeros(len(flat), dtype=bool)
    if d == 3 and len(flat):
        scale = (np.einsum("mij,mij->m", flat, flat) / 3.0) ** 1.5
        newton = np.linalg.det(flat) > _NEWTON_MIN_DET * scale
        R[newton], converged = _newton_rotation(flat[newton])
        newton[np.flatnonzero(newton)[~converged]] = False
    R[~newton] = _svd_rotation(flat[~newton])
    R = R.reshape(F.shape)
    S = np.swapaxes(R, -1, -2) @ F
    S = 0.5 * (S + np.swapaxes(S, -1, -2))
    return R, S


#: Relative det F below which `polar` takes the SVD: folded (det <= 0) or nearly flat
#: matrices, whose rotation the Newton iteration would not give (or only slowly).
_NEWTON_MIN_DET = 1e-6


def _svd_rotation(F: np.ndarray) -> np.ndarray:
    """The closest rotation (M, d, d) to each matrix of F (M, d, d), by the SVD."""
    U, _, Vt = np.linalg.svd(F)
    U[..., :, -1] *= np.where(np.linalg.det(U @ Vt) < 0, -1.0, 1.0)[..., None]
    return U @ Vt


def _newton_rotation(F: np.ndarray, iterations: int = 30,
                     tol: float = 1e-14) -> tuple[np.ndarray, np.ndarray]:
    """Rotation factors (M, 3, 3) of 3 x 3 matrices with det F > 0 by the scaled Newton
    iteration X <- (g X + X^-T / g) / 2 (Higham; g the Frobenius-norm scaling for the
    first steps), and whether each converged to ``tol``. Elementwise on arrays of the
    matrices' entries: faster than a batched SVD, to ~1e-15 of it."""
    X = np.ascontiguousarray(np.moveaxis(F, 0, -1))  # (3, 3, M)
    change = np.zeros(F.shape[0])
    for it in range(iterations if F.shape[0] else 0):
        step = _inverse_transpose_3(X)
        if it < 3:
            g = np.sqrt(np.sqrt(np.einsum("ijm,ijm->m", step, step)
                                / np.einsum("ijm,ijm->m", X, X)))
            X *= g
            step /= g
        step += X
        step *= 0.5
        X -= step
        change = np.abs(X).max(axis=(0, 1))
        X = step
        if change.max() < tol:
            break
    return np.moveaxis(X, -1, 0), change < tol


def _inverse_transpose_3(X: np.ndarray) -> np.ndarray:
    """X^-T (3, 3, M) of 3 x 3 matrices (3, 3, M): their cofactors over their determinants."""
    cof = cofactor(X, batch_last=True)
    return cof / np.einsum("jm,jm->m", X[0], cof[0])


def rotation_log(R: ArrayLike) -> np.ndarray:
    """Rotation vector (3D: axis * angle, (..., 3)) or angle (2D: (...,)) of rotations R.

    The angle lies in [0, pi]; at exactly pi the axis sign is arbitrary.
    """
    R = np.asarray(R, dtype=float)
    if R.shape[-1] == 2:
        return np.arctan2(R[..., 1, 0], R[..., 0, 0])
    from scipy.spatial.transform import Rotation

    flat = R.reshape(-1, 3, 3)
    if flat.shape[0] == 0:
        return np.zeros(R.shape[:-2] + (3,))
    return Rotation.from_matrix(flat).as_rotvec().reshape(R.shape[:-2] + (3,))


def rotation_exp(v: ArrayLike, d: int) -> np.ndarray:
    """Rotation matrices (..., d, d) from rotation vectors (3D) or angles (2D)."""
    v = np.asarray(v, dtype=float)
    if d == 2:
        c, s = np.cos(v), np.sin(v)
        return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    from scipy.spatial.transform import Rotation

    flat = v.reshape(-1, 3)
    if flat.shape[0] == 0:
        return np.zeros(v.shape[:-1] + (3, 3))
    return Rotation.from_rotvec(flat).as_matrix().reshape(v.shape[:-1] + (3, 3))


def rigid_fit(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:

    """Centroids and best rotation (Kabsch / Horn, thesis appendix A) mapping points x onto y.

    Returns ``(x_bar, y_bar, R)`` with R the proper rotation minimising
    sum |R (x - x_bar) - (y - y_bar)|^2.
    """
    xb = x.mean(axis=0)
    yb = y.mean(axis=0)
    H = (y - yb).T @ (x - xb)
    R, _ = polar(H[None])
    return xb, yb, R[0]
