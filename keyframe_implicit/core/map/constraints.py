"""Feature-point constraints C y = d (thesis eq. 2.8 and 2.14-2.20).

As corrected in docs/method.md, section 4: each feature point x'_i gives one row
of C per coordinate, holding the multilinear (bilinear / trilinear,
"barycentric" in the thesis) weights t of the 2**d nodes of the cell that
contains x'_i (they sum to one), and the right-hand side is the target y'_i
(eq. 2.18 / 2.20 are garbled in the thesis). The initial map satisfies
C y = d; every Gauss-Newton step must stay in the null space of C.

Bounded distortion near a feature point
---------------------------------------
Constraining only the 2**d nodes of one cell is a point load: the optimal map
has a strain singularity there, and min det F near the point drops as the
grid is refined. Here a
feature's influence reaches a fixed *physical* radius ``radius``: all solved
nodes within that distance of x'_i (a "patch") move by one affine map

    y(x) = y'_i + A_i (x - x'_i),     A_i a free d x d matrix,

so the point lands exactly (multilinear interpolation reproduces affine
fields, so C y = d holds to rounding), the patch stretches smoothly, and the
load is spread over a sphere of fixed size: the distortion no longer grows
with resolution. The unknowns are the free nodes' positions plus the A_i
(``y = y0 + T z``). A feature whose patch would overlap another feature's (two
points closer than about twice ``radius``), or whose patch cannot contain its
own cell (``radius`` below the cell diagonal), falls back to the plain hard
constraint on its cell's nodes, enforced by the orthogonal projection
``z -> z - C^T (C C^T)^+ C z`` in the null space of C.

The bound on the distortion depends on how far a point is pulled relative to
the radius, not on the resolution (measurements: benchmarks/README.md,
"Feature patches"). `solve_map` defaults to 8 % of the grid's largest extent
(``feature_radius``).

The patch cells' rigidity weight is multiplied by `solve_map`'s
``patch_rigidity`` (default 10; the free A_i otherwise let a patch shear and
scale as a whole -- see `keyframe_implicit.core.map.solver`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from ..base.elements import inverse
from ..base.grid import Grid
from ..base.sampling import cell_weights

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

__all__ = ["FeatureConstraints"]


def _patches(x, xa, cell_nodes, radius, spacing):
    """Which features get an affine patch, its radius, and its nodes among ``x`` (the
    solved nodes): a feature's patch must reach past its own cell and may not reach half
    way to another feature; a patch that shares a node with another patch or with a hard
    feature's cell becomes a hard constraint. Returns (is_patch, rho, members)."""
    N = len(xa)
    reach = np.linalg.norm(x[cell_nodes] - xa[:, None, :], axis=-1).max(axis=1) if N else np.zeros(0)
    rho = np.full(N, float(radius))
    if N > 1:
        dist = np.linalg.norm(xa[:, None] - xa[None], axis=-1)
        np.fill_diagonal(dist, np.inf)
        rho = np.minimum(rho, 0.5 * dist.min(axis=1))
    is_patch = rho >= reach * (1 + 1e-9) + 1e-12 * spacing
    tree = cKDTree(x) if N else None
    members = [np.asarray(tree.query_ball_point(xa[i], rho[i]), dtype=np.int64) if is_patch[i]
               else np.zeros(0, np.int64) for i in range(N)]
    for _ in range(N + 1):
        owner = np.zeros(len(x), dtype=np.int64)
        for i in range(N):
            if is_patch[i]:
                owner[members[i]] += 1
            else:
                owner[cell_nodes[i]] += 1
        bad = [i for i in range(N) if is_patch[i] and np.any(owner[members[i]] > 1)]
        if not bad:
            break
        for i in bad:
            is_patch[i] = False
    return is_patch, rho, members


class FeatureConstraints:
    """Null-space parameterisation of the feature constraints on the solved nodes.

    Parameters
    ----------
    grid : `Grid`
    active : (n,) int array of the flat grid indices of the solved nodes (sorted).
    features_a, features_b : (N, d) feature points x'_i and targets y'_i.
    radius : float
        Physical radius of the affine patch around each feature (world units);
        0 gives plain hard constraints on the cell nodes.

    Notes
    -----
    Every node of each feature's cell must be in ``active``.
    """

    def __init__(self, grid: Grid, active: np.ndarray, features_a: ArrayLike,
                 features_b: ArrayLike, radius: float) -> None:
        d = grid.dim
        self.d = d
        self.n = len(active)
        xa = np.asarray(features_a, dtype=float).reshape(-1, d)
        yb = np.asarray(features_b, dtype=float).reshape(-1, d)
        self.xa, self.yb = xa, yb
        N = len(xa)
        lookup = np.full(grid.size, -1, dtype=np.int64)
        lookup[active] = np.arange(len(active))
        self.x = grid.node_points(active)
        flat, w = cell_weights(grid, xa) if N else (np.zeros((0, 2 ** d), int), np.zeros((0, 2 ** d)))
        cell_nodes = lookup[flat]
        if np.any(cell_nodes < 0):
            raise ValueError("internal: a feature cell is not in the solved region")
        self.cell_nodes, self.cell_w = cell_nodes, w

        is_patch, rho, members = _patches(self.x, xa, cell_nodes, radius, grid.spacing)
        self.is_patch = is_patch
        self.rho = np.where(is_patch, rho, 0.0)
        pid = np.full(self.n, -1, dtype=np.int64)
        patches = np.flatnonzero(is_patch)
        for p, i in enumerate(patches):
            pid[members[i]] = p
        self.patches = patches
        self.patch_of_node = pid
        self.patch_nodes = np.flatnonzero(pid >= 0)
        self.patch_id = pid[self.patch_nodes]
        self.patch_r = self.x[self.patch_nodes] - xa[patches][self.patch_id]
        self.free_nodes = np.flatnonzero(pid < 0)
        self.n_free = len(self.free_nodes)
        self.n_patch = len(patches)
        self.size = self.n_free * d + self.n_patch * d * d
        free_pos = np.full(self.n, -1, dtype=np.int64)
        free_pos[self.free_nodes] = np.arange(self.n_free)

        # hard constraints: rows over the free-node unknowns
        hard = np.flatnonzero(~is_patch)
        self.hard = hard
        if len(hard):
            cols = free_pos[cell_nodes[hard]]  # (m, 2**d)
            self._hard_cols = cols
            self._hard_w = w[hard]
            m = len(hard)
            # C C^T per coordinate is the same m x m matrix (rows of different coordinates are orthogonal)
            Cm = np.zeros((m, self.n_free))
            np.add.at(Cm, (np.repeat(np.arange(m), cols.shape[1]), cols.reshape(-1)), w[hard].reshape(-1))
            self._hard_nodes = np.unique(cols)
            Cl = Cm[:, self._hard_nodes]
            self._Cl = Cl
            self._CCinv = np.linalg.pinv(Cl @ Cl.T)

    # -- exact feasibility ---------------------------------------------------
    def enforce(self, y: np.ndarray) -> np.ndarray:
        """Return a copy of ``y`` (n, d) that satisfies C y = d exactly.

        Patch nodes get the least-squares affine fit of ``y`` through y'_i
        (keeps the map's local stretch); hard cells get the minimum-norm
        correction.
        """
        y = np.array(y, dtype=float, copy=True)
        d = self.d
        if self.n_patch:
            A = self._fit_affine(y)
            y[self.patch_nodes] = self.yb[self.patches][self.patch_id] + np.einsum(
                "nja,na->nj", A[self.patch_id], self.patch_r)
        if len(self.hard):
            yl = y[self.free_nodes[self._hard_nodes]]  # (k, d)
            resid = self.yb[self.hard] - self._Cl @ yl  # (m, d)
            yl = yl + self._Cl.T @ (self._CCinv @ resid)
            y[self.free_nodes[self._hard_nodes]] = yl
        del d
        return y

    def _fit_affine(self, y: np.ndarray) -> np.ndarray:
        d = self.d
        A = np.empty((self.n_patch, d, d))
        dy = y[self.patch_nodes] - self.yb[self.patches][self.patch_id]
        r = self.patch_r
        for p in range(self.n_patch):
            s = self.patch_id == p
            M = r[s].T @ r[s]
            A[p] = np.linalg.solve(M, r[s].T @ dy[s]).T
        return A

    def residual(self, y: np.ndarray) -> np.ndarray:
        """|C y - d| per feature point (world units), y of the solved nodes (n, d)."""
        if len(self.xa) == 0:
            return np.zeros(0)
        yi = np.einsum("pc,pcj->pj", self.cell_w, y[self.cell_nodes])
        return np.linalg.norm(yi - self.yb, axis=1)

    # -- null-space parameterisation y = y0 + T z ------------------------------
    def expand(self, z: np.ndarray) -> np.ndarray:
        """Node displacements (n, d) of the reduced unknowns ``z``: T z."""
        d = self.d
        out = np.zeros((self.n, d))
        out[self.free_nodes] = z[: self.n_free * d].reshape(-1, d)
        if self.n_patch:
            A = z[self.n_free * d:].reshape(-1, d, d)
            out[self.patch_nodes] = np.einsum("nja,na->nj", A[self.patch_id], self.patch_r)
        return out

    def reduce(self, g: np.ndarray) -> np.ndarray:
        """T^T g for node vectors ``g`` (n, d)."""
        d = self.d
        out = np.empty(self.size)
        out[: self.n_free * d] = g[self.free_nodes].reshape(-1)
        if self.n_patch:
            gp = g[self.patch_nodes]
            A = np.empty((self.n_patch, d, d))
            for j in range(d):
                for a in range(d):
                    A[:, j, a] = np.bincount(self.patch_id, weights=gp[:, j] * self.patch_r[:, a],
                                             minlength=self.n_patch)
            out[self.n_free * d:] = A.reshape(-1)
        return out

    def project(self, z: np.ndarray) -> np.ndarray:
        """Orthogonal projection of ``z`` onto the null space of the hard constraints."""
        if not len(self.hard):
            return z
        d = self.d
        z = z.copy()
        zf = z[: self.n_free * d].reshape(-1, d)
        zl = zf[self._hard_nodes]
        zl = zl - self._Cl.T @ (self._CCinv @ (self._Cl @ zl))
        zf[self._hard_nodes] = zl
        return z

    def block_preconditioner(self, diag: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """Block-Jacobi inverse in reduced coordinates from node diagonal blocks (n, d, d).

        Free nodes: inverse of their d x d block. Patch matrices A_i: inverse of
        sum_n H_nn (x) r_n r_n^T (the exact block when off-diagonal couplings
        inside the patch are ignored). Returns a function z -> M^{-1} z.
        """
        d = self.d
        blocks = diag[self.free_nodes]
        inv_free = inverse(blocks)
        inv_patch = None
        if self.n_patch:
            Hn = diag[self.patch_nodes]
            r = self.patch_r
            blk = np.einsum("njk,na,nb->njakb", Hn, r, r).reshape(len(r), d * d * d * d)
            M = np.stack([np.bincount(self.patch_id, weights=blk[:, q], minlength=self.n_patch)
                          for q in range(blk.shape[1])], axis=1).reshape(self.n_patch, d * d, d * d)
            inv_patch = np.linalg.pinv(M)
        nf = self.n_free * d

        def apply(z: np.ndarray) -> np.ndarray:

            out = np.empty_like(z)
            out[:nf] = np.einsum("njk,nk->nj", inv_free, z[:nf].reshape(-1, d)).reshape(-1)
            if inv_patch is not None:
                out[nf:] = np.einsum("pjk,pk->pj", inv_patch, z[nf:].reshape(-1, d * d)).reshape(-1)
            return out

        return apply
