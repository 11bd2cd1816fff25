"""Coarse correction for the Gauss-Newton systems: one unknown per block of nodes and coordinate.

A system of `solver` (eq. 2.13 on the reduced unknowns) is solved by CG with a
d x d block-Jacobi preconditioner. Block Jacobi sees each node alone, so the
smooth part of the error, spread over many nodes, takes CG a number of
iterations that grows with the resolution of the grid (the fine level's
systems of `bench_scale.py`'s bend: a few dozen at 64 cells, a few hundred at
256; benchmarks/README.md, "Coarse correction").

The coarse space lets every aggregate -- an a x a x a block of the solved grid
nodes -- move as one, one unknown per coordinate. With P the piecewise-constant
prolongation from the aggregates to the free nodes (feature patches' unknowns
are left to block Jacobi), the preconditioner is additive:

    M^-1 r = B^-1 r + P A_c^-1 P^T r,    A_c = P^T H P,

B the block diagonal. Because a stencil block of H couples a node with a
neighbour at most one node away and a >= 2, it couples aggregates whose
lattice positions differ by at most one: A_c is again a 3^d block stencil,
summed from H's stencil blocks without a sort (`CoarseSpace.operator`). A_c
is small (at most ``unknowns``) and is factored directly, once per Hessian.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..base.multigrid import aggregate_blocks

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

__all__ = ["CoarseSpace"]


class CoarseSpace:
    """Aggregates of one level's free nodes, and the coarse correction of a Hessian.

    Parameters
    ----------
    coords : int ndarray (n, d)
        Grid index of every solved node.
    neighbours : int ndarray (n, S)
        The Hessian's stencil columns of every node (its own index where the
        neighbour is missing: that block is zero).
    free_nodes : int ndarray
        The nodes whose displacements are unknowns of their own (not in a feature patch).
    unknowns : int
        The most coarse unknowns to make: the aggregates' side is the smallest
        (at least 2 nodes) that gives no more.
    """

    def __init__(self, coords: np.ndarray, neighbours: np.ndarray, free_nodes: ArrayLike,
                 unknowns: int) -> None:
        n, d = coords.shape
        self.d = d
        self.free_nodes = np.asarray(free_nodes)
        side = max(2, int(np.ceil((d * len(self.free_nodes) / float(unknowns)) ** (1.0 / d))))
        free_coords = coords[self.free_nodes]
        while True:  # a ragged region fills its blocks partly: widen them until few enough
            agg_free, lattice = aggregate_blocks(free_coords, side)
            if d * len(lattice) <= unknowns or len(lattice) == 1:
                break
            side += 1
        self.side = side
        self.agg_free = agg_free
        nc = len(lattice)
        self.n_aggregates = nc
        agg = np.full(n, -1, np.int64)
        agg[self.free_nodes] = agg_free
        # every stencil block (i, o) lands in coarse stencil block (agg i, lattice offset of
        # agg nbr from agg i); blocks with a node outside the free ones go to a last, dropped bin
        block = (coords // side).astype(np.int32)
        code = np.zeros(neighbours.shape, np.int32)
        for a in range(d):  # one axis at a time: the temporaries stay (n, S) int32
            code *= 3
            code += block[neighbours, a] - block[:, a, None] + 1  # in {0, 1, 2}
        slot = agg[:, None] * 3 ** d + code
        slot[(agg[:, None] < 0) | (agg[neighbours] < 0)] = nc * 3 ** d
        self._slot = slot.reshape(-1)
        # the coarse stencil's columns: the aggregate at each lattice offset, -1 where none
        offs = np.array(list(np.ndindex(*(3,) * d))) - 1
        span = lattice.max(axis=0) + 1
        keys = np.ravel_multi_index(tuple(lattice.T), tuple(span))  # sorted (aggregate_blocks)
        q = lattice[:, None, :] + offs[None, :, :]
        inside = np.all((q >= 0) & (q < span), axis=-1)
        qkey = np.where(inside, np.ravel_multi_index(tuple(np.moveaxis(np.clip(q, 0, span - 1), -1, 0)),
                                                     tuple(span)), -1)
        pos = np.minimum(np.searchsorted(keys, qkey), nc - 1)
        self._columns = np.where(inside & (keys[pos] == qkey), pos, -1)

    def operator(self, Hs: np.ndarray) -> sp.csc_matrix:
        """A_c = P^T H P from the stencil blocks ``Hs`` (n, S, d, d): CSC matrix (nc d, nc d)."""
        d, nc = self.d, self.n_aggregates
        flat = Hs.reshape(-1, d * d)
        nbins = nc * 3 ** d + 1
        blocks = np.stack([np.bincount(self._slot, weights=flat[:, k], minlength=nbins)[:-1]
                           for k in range(d * d)], axis=1).reshape(nc, 3 ** d, d, d)
        ok = self._columns >= 0
        I = np.broadcast_to(np.arange(nc)[:, None], ok.shape)[ok]
        J = self._columns[ok]
        comp = np.arange(d)
        shape = (len(I), d, d)
        rows = np.broadcast_to(I[:, None, None] * d + comp[None, :, None], shape)
        cols = np.broadcast_to(J[:, None, None] * d + comp[None, None, :], shape)
        return sp.csc_matrix((blocks[ok].reshape(-1), (rows.reshape(-1), cols.reshape(-1))),
                             shape=(nc * d, nc * d))

    def correction(self, Hs: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """The coarse correction r -> P A_c^-1 P^T r of the Hessian ``Hs``, on the free nodes'
        residuals (n_free, d) -> (n_free, d)."""
        d, nc = self.d, self.n_aggregates
        lu = splu(self.operator(Hs), permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True))
        agg = self.agg_free

        def apply(r: np.ndarray) -> np.ndarray:

            rc = np.stack([np.bincount(agg, weights=r[:, k], minlength=nc) for k in range(d)], axis=1)
            return lu.solve(rc.reshape(-1)).reshape(nc, d)[agg]

        return apply
