"""Conjugate gradients preconditioned by multigrid on blocks of grid nodes.

The trajectory solve (`trajectory.Trajectories`, the Poisson problem of
thesis section 3.1 in its global form) is a weighted graph Laplacian L of the
grid edges inside the region (material and margin). A direct factorisation fills in
faster than the region grows and cannot be interrupted; conjugate gradients cost
one sparse product per iteration and stop between any two.

The preconditioner is one V-cycle of smoothed-aggregation multigrid whose
aggregates are the 2 x 2 x 2 blocks of grid nodes (2 x 2 in 2D), level after
level: the grid's own coarse levels, with the region's ragged edge handled
algebraically (Vanek, Mandel and Brezina, 1996). The tentative prolongation
P0 copies a coarse value onto its block; one damped Jacobi step smooths it,
P = (I - w D^-1 L) P0, and the coarse operator is P^T L P (Galerkin). Jacobi
sweeps smooth on every level; the coarsest is solved with a dense
pseudo-inverse.

L is singular: its null space holds one constant per connected component
(a translation). Both P0 and its smoothing keep constants, so every level
shares that null space; right-hand sides of the form B T (edge differences)
are consistent, and CG converges on the range of L. The caller fixes each
component's translation afterwards (`Trajectories` puts its centroid on the
straight path).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

__all__ = ["BlockMultigrid", "block_pcg"]


def _no_check() -> None:
    return None


def _largest_eigenvalue(A: sp.csr_matrix, dinv: np.ndarray, iterations: int = 12,
                        seed: int = 0) -> float:
    """Estimate of the largest eigenvalue of D^-1 A by power iteration (a safe upper guess)."""
    v = np.random.default_rng(seed).standard_normal(A.shape[0])
    v /= max(np.linalg.norm(v), 1e-300)
    lam = 1.0
    for _ in range(iterations):  # |v| = 1: |D^-1 A v| is the estimate
        w = dinv * (A @ v)
        lam = float(np.linalg.norm(w))
        v = w / max(lam, 1e-300)
    return 1.1 * lam


def aggregate_blocks(coords: np.ndarray, side: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The block of side^d grid nodes each node (grid index ``coords`` (n, d)) falls in:
    (aggregate index per node, the aggregates' block coordinates, sorted by flat index)."""
    block = coords // side
    span = block.max(axis=0) + 1
    key = np.ravel_multi_index(tuple(block.T), tuple(span))
    keys, agg = np.unique(key, return_inverse=True)
    coarse = np.stack(np.unravel_index(keys, tuple(span)), axis=1)
    return agg.reshape(-1), coarse


class BlockMultigrid:
    """Smoothed-aggregation V-cycle for a grid Laplacian, aggregates = 2^d blocks of nodes.

    Parameters
    ----------
    A : sparse matrix (n, n)
        Symmetric positive semi-definite, constants in its null space per
        connected component, positive diagonal (e.g. a weighted graph Laplacian).
    coords : int ndarray (n, d)
        Grid index of every unknown; nodes in one 2^d block form one aggregate.
    coarse_size : int
        Levels are added until at most this many unknowns remain.
    sweeps : int
        Damped Jacobi sweeps before the coarse correction on the finest level (the first
        from zero) and as many after it, so that the V-cycle is symmetric.
    coarse_sweeps : int
        The same on the coarser levels. Their Galerkin operators are denser than the
        grid's (about 30 and 130 entries a row on the first two, against 7), so a sweep
        there costs more than one on the finest level and buys less.
    check : callable, optional
        Called between levels of the setup (cancellation).
    """

    def __init__(self, A: sp.spmatrix | sp.sparray, coords: ArrayLike, *, coarse_size: int = 200,
                 sweeps: int = 2, coarse_sweeps: int = 1,
                 check: Callable[[], None] | None = None) -> None:
        check = check or _no_check
        self.sweeps, self.coarse_sweeps = int(sweeps), int(coarse_sweeps)
        # (A, damped inverse diagonal, P) per fine level
        self.levels: list[tuple[sp.csr_matrix, np.ndarray, sp.csr_matrix]] = []
        A = sp.csr_matrix(A)
        coords = np.asarray(coords, dtype=np.int64)
        while A.shape[0] > coarse_size:
            check()
            dinv = 1.0 / A.diagonal()
            omega = 4.0 / (3.0 * _largest_eigenvalue(A, dinv))
            agg, coarse = aggregate_blocks(coords)
            if coarse.shape[0] > 0.9 * A.shape[0]:  # blocks no longer shrink the problem
                break
            n, nc = A.shape[0], coarse.shape[0]
            P0 = sp.csr_matrix((np.ones(n), (np.arange(n), agg)), shape=(n, nc))
            P = (P0 - sp.diags(omega * dinv) @ (A @ P0)).tocsr()
            self.levels.append((A, omega * dinv, P))
            # P^T as CSR: the product with A P is then CSR by CSR (half the time); the
            # cycle's restriction keeps P.T, whose CSC product is the faster one there
            A = (P.T.tocsr() @ (A @ P)).tocsr()
            coords = coarse
        check()
        # the constants are an exact null vector: cut them (and roundoff) from the inverse
        self.coarse = np.linalg.pinv(A.toarray(), rcond=1e-10, hermitian=True)
        self.sizes = [lv[0].shape[0] for lv in self.levels] + [A.shape[0]]

    def __call__(self, r: np.ndarray) -> np.ndarray:
        """Apply one V-cycle to the residual r ((n,) or (n, k)): an approximation of A^+ r."""
        return self._cycle(0, r)

    def _cycle(self, k: int, r: np.ndarray) -> np.ndarray:
        if k == len(self.levels):
            return self.coarse @ r
        A, wd, P = self.levels[k]
        wd = wd if r.ndim == 1 else wd[:, None]
        sweeps = self.sweeps if k == 0 else self.coarse_sweeps

        def residual(x: np.ndarray) -> np.ndarray:  # r - A x, in the product's own array
            t = A @ x
            return np.subtract(r, t, out=t)

        def smooth(x: np.ndarray) -> None:  # one damped Jacobi sweep, in place
            t = residual(x)
            t *= wd
            x += t

        x = wd * r
        for _ in range(sweeps - 1):
            smooth(x)
        x += P @ self._cycle(k + 1, P.T @ residual(x))
        for _ in range(sweeps):
            smooth(x)
        return x


def block_pcg(A: sp.spmatrix | sp.sparray, b: np.ndarray,
              precond: Callable[[np.ndarray], np.ndarray], x0: ArrayLike | None = None, *,
              tol: float = 1e-9, maxiter: int = 500,
              check: Callable[[], None] | None = None) -> tuple[np.ndarray, int]:

    """Preconditioned CG on every column of b at once (independent systems, one matrix).

    Parameters
    ----------
    A : sparse matrix (n, n), symmetric positive semi-definite; b in its range.
    b : ndarray (n, k)
    precond : callable (n, k) -> (n, k), symmetric positive (semi-)definite.
    x0 : ndarray (n, k), optional
        Start (e.g. the previous frame's solution); zeros by default.
    tol : float
        Stop when every column's residual is below ``tol`` times its right-hand side's norm.
    maxiter : int
    check : callable, optional
        Called once per iteration (cancellation).

    Returns
    -------
    x : ndarray (n, k)
    iterations : int
    """
    check = check or _no_check
    x = np.zeros_like(b) if x0 is None else np.array(x0, dtype=float)
    r = b - A @ x
    goal = tol * np.maximum(np.linalg.norm(b, axis=0), 1e-300)
    z = precond(r)
    p = z.copy()
    rz = np.einsum("ij,ij->j", r, z)
    it = 0
    while it < maxiter and np.any(np.linalg.norm(r, axis=0) > goal):
        check()
        it += 1
        Ap = A @ p
        pAp = np.einsum("ij,ij->j", p, Ap)
        alpha = np.divide(rz, pAp, out=np.zeros_like(rz), where=pAp > 0)
        x += alpha * p
        r -= alpha * Ap
        z = precond(r)
        rz_new = np.einsum("ij,ij->j", r, z)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
        p = z + beta * p
        rz = rz_new
    return x, it
