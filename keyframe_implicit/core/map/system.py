"""Eq. 2.6 discretised on one grid of the coarse-to-fine hierarchy: the solved region,
its elements and node stencil, the feature constraints, and the energy with its
gradient and Gauss-Newton Hessian (docs/method.md, sections 2-4).

`MapSystem` is what `solver.solve_map` iterates on; `constrained_system` builds it with
feature patches no larger than the start allows; `det_floor` is the det F bound every
step keeps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..base import elements
from ..base.grid import Grid
from ..base.sampling import cell_weights
from .constraints import FeatureConstraints
from . import terms
from .terms import ElementBatch, NodeBatch, heaviside

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping, Sequence
    from concurrent.futures import Executor

    from .options import MapOptions

__all__ = ["HESSIAN_DTYPE", "MapSystem", "constrained_system", "det_floor"]

#: Storage of the Gauss-Newton Hessian (the stencil blocks and the BSR matrix made from them):
#: the largest array of a solve (3^d d^2 values per node). Single precision halves it; its
#: rounding (1e-7 relative) is far below the loose CG tolerance it serves (``cg_tolerance``),
#: and energy, gradient and line search stay in double precision (benchmarks/README.md).
HESSIAN_DTYPE = np.float32

#: Levels of fewer active nodes assemble and multiply their Hessian in one thread
#: (`MapSystem._element_halves`, `MapSystem.product`).
_SPLIT_FROM = 4096

def _solved_cells(phi_a, grid, xa, margin_cells, margin_weight, crack=None):
    """The cells the map is solved on: A's material (Phi < 0 at the cell's centre, weight
    1), its margin of ``margin_cells`` cells (weight ``margin_weight``) and every feature
    point's cell, but the cells of a ``crack`` (bool, the cells' shape: the map tears
    there, `tear.find_tear`). Returns (material, weight, solved), each of the cells' shape."""
    h, cs = grid.spacing, elements.corners(grid.dim)
    centre = np.zeros(tuple(n - 1 for n in grid.shape))  # Phi at each cell's centre
    for v in elements.corner_views(phi_a):
        centre += v
    centre /= len(cs)
    mat = centre < 0
    margin = ((~mat) & (centre < margin_cells * h) if (margin_weight > 0 and margin_cells > 0)
              else np.zeros_like(mat))
    if crack is not None:
        mat, margin = mat & ~crack, margin & ~crack
    weight = np.where(mat, 1.0, np.where(margin, margin_weight, 0.0))
    forced = np.zeros(centre.shape, dtype=bool)
    if len(xa):
        flat, _ = cell_weights(grid, xa)
        base = np.stack(np.unravel_index(flat[:, 0], grid.shape), axis=-1)
        forced[tuple(base.T)] = True
    return mat, weight, mat | margin | forced


def _stencil(grid, active, idx, cs):
    """The 3**d neighbour stencil of the solved nodes (``active``, grid indices ``idx``):
    its offsets, the centre's column, each element's corner pairs as stencil columns, and
    the BSR pattern over the whole stencil."""
    d, n, K = grid.dim, len(active), len(cs)
    offs = np.array(list(np.ndindex(*(3,) * d))) - 1  # lexicographic -> sorted columns
    lookup = np.full(grid.size, -1, dtype=np.int64)
    lookup[active] = np.arange(n)
    nbr = np.full((n, len(offs)), -1, dtype=np.int32)
    for o, off in enumerate(offs):
        q = idx + off
        ok = np.all((q >= 0) & (q < np.asarray(grid.shape)), axis=1)
        nbr[ok, o] = lookup[np.ravel_multi_index(tuple(q[ok].T), grid.shape)]
    centre_off = int(np.flatnonzero(np.all(offs == 0, axis=1))[0])
    code = {tuple(o): i for i, o in enumerate(offs.tolist())}
    # offset of corner c' seen from corner c: block [c, c'] of an element is stencil block
    # (node of c, pair_off[c, c'])
    pair_off = np.array([[code[tuple((cs[c2] - cs[c1]).tolist())] for c2 in range(K)]
                         for c1 in range(K)], dtype=np.int32)
    # BSR pattern over the whole stencil: a missing neighbour points at the node itself and
    # its block stays zero, so the stencil array is the BSR data without a copy
    own = np.broadcast_to(np.arange(n, dtype=np.int32)[:, None], nbr.shape)
    bsr_indices = np.where(nbr >= 0, nbr, own).reshape(-1)
    bsr_indptr = (np.arange(n + 1) * len(offs)).astype(np.int32)
    return offs, centre_off, pair_off, bsr_indices, bsr_indptr


class MapSystem:
    """Eq. 2.6 on one grid of the hierarchy: the solved region (its nodes `active`, its
    cells `elem`), the elements' quadrature, the node stencil and the feature constraints."""

    def __init__(self, phi_a: np.ndarray, phi_b: np.ndarray, grid: Grid, xa: np.ndarray,
                 yb: np.ndarray, margin_cells: float, margin_weight: float, radius: float,
                 patch_rigidity: float, crack: np.ndarray | None = None) -> None:
        d = grid.dim
        self.grid, self.d = grid, d
        self.phi_b = phi_b
        h = grid.spacing
        self.eps = 1.5 * h  # eq. 2.7
        cs = elements.corners(d)
        mat, weight, act_cell = _solved_cells(phi_a, grid, xa, margin_cells, margin_weight, crack)
        cells = np.argwhere(act_cell)  # (E, d)
        self.cell_weight = weight[act_cell]
        self.cell_material = mat[act_cell]
        self.material_cells = mat
        node_idx = cells[:, None, :] + cs[None, :, :]
        flat_nodes = np.ravel_multi_index(tuple(node_idx[..., a] for a in range(d)), grid.shape)
        active = np.unique(flat_nodes)
        self.active = active
        # int32 indices: the index tables cost more than the Hessian's blocks otherwise
        self.elem = np.searchsorted(active, flat_nodes).astype(np.int32)  # (E, K)
        self.n = len(active)
        self.gauss = elements.quadrature(d, h, "gauss")
        self.centre = elements.quadrature(d, h, "centre")
        K = len(cs)
        self.node_weight = np.zeros(self.n)
        for c in range(K):
            self.node_weight += np.bincount(self.elem[:, c], weights=self.cell_weight * h ** d / K,
                                            minlength=self.n)
        self.h_phi = heaviside(phi_a.reshape(-1)[active], self.eps)
        idx = np.stack(np.unravel_index(active, grid.shape), axis=-1)
        (self.offsets, self.centre_off, self.pair_off, self.bsr_indices,
         self.bsr_indptr) = _stencil(grid, active, idx, cs)
        self.cons = FeatureConstraints(grid, active, xa, yb, radius)
        self.x = grid.to_world(idx)
        # cells inside one feature patch: their F is the patch's affine A_i (see `patch_rigidity`)
        self.patch_cell = np.all(self.cons.patch_of_node[self.elem] >= 0, axis=1)
        self.term_weight = {"rigidity": np.where(self.patch_cell, float(patch_rigidity), 1.0) * self.cell_weight}

    def cell_weights_of(self, name: str) -> np.ndarray:
        """Per-cell weight of term ``name`` (region weight, times ``patch_rigidity`` in patch cells for rigidity)."""
        return self.term_weight.get(name, self.cell_weight)

    # -- energy ----------------------------------------------------------------
    def evaluate(self, y: np.ndarray, weights: Mapping[str, float], chunk: int,
                 hessian: bool = True, check: Callable[[], None] | None = None,
                 pool: Executor | None = None
                 ) -> tuple[float, dict[str, float], np.ndarray, np.ndarray | None]:
        """Total energy, per-term energies, node gradient (n, d), stencil Hessian.

        ``check`` (optional) is called before every chunk of elements (cancellation).
        With a ``pool`` (one thread) the element terms run in two halves at once
        (`_element_halves`), as the Hessian product does (`product`).
        """
        d = self.d
        grad = np.zeros((self.n, d))
        Hs = np.zeros((self.n, len(self.offsets), d, d), HESSIAN_DTYPE) if hessian else None
        energies = dict.fromkeys((t.name for t in terms.TERMS), 0.0)

        def run(lo, hi):
            return self._element_terms(lo, hi, y, weights, chunk, grad, Hs, check)
        parts = self._element_halves(chunk) if pool is not None else None
        if parts is None:
            found = [run(0, len(self.elem))]
        else:  # two halves that touch no common node at once, then the elements between
            (a, b), (c, e), (m, m2) = parts
            job = pool.submit(run, c, e)
            try:
                found = [run(a, b)]
            finally:
                found.append(job.result())
            found.append(run(m, m2))
        for part in found:
            for name, value in part.items():
                energies[name] += value
        for t in terms.TERMS:
            if t.kind != "node" or weights[t.name] == 0:
                continue
            w = weights[t.name]
            tv = t.function(NodeBatch(y, self.node_weight, self.h_phi, self.phi_b, self.grid, self.eps),
                            hessian=hessian)
            energies[t.name] += w * tv.energy
            grad += w * tv.grad
            if hessian:
                Hs[:, self.centre_off] += w * tv.hess
        return sum(energies.values()), energies, grad, Hs

    def _element_terms(self, lo, hi, y, weights, chunk, grad, Hs, check=None):
        """Add the element terms of elements ``lo`` to ``hi`` into ``grad`` and ``Hs`` (None:
        no Hessian), ``chunk`` elements at a time; their energies, by term name."""
        K = self.elem.shape[1]
        energies = {}
        for s in range(lo, hi, chunk):
            if check is not None:
                check()
            e = min(s + chunk, hi)
            el = self.elem[s:e]
            Y = y[el]
            g_sum, h_sum = None, None
            for t in terms.TERMS:
                w = weights[t.name]
                if t.kind != "element" or w == 0:
                    continue
                # the user weight rides on the cell weights: the term returns weighted values
                batch = ElementBatch(Y, w * self.cell_weights_of(t.name)[s:e], self.gauss, self.centre)
                tv = t.function(batch, hessian=Hs is not None)
                energies[t.name] = energies.get(t.name, 0.0) + tv.energy
                if g_sum is None:
                    g_sum, h_sum = tv.grad, tv.hess
                else:
                    g_sum += tv.grad
                    if Hs is not None:
                        h_sum += tv.hess
            if g_sum is None:
                continue
            for c in range(K):
                grad[el[:, c]] += g_sum[:, c]  # rows el[:, c] are distinct for a fixed corner c
            if Hs is not None:
                self._add_blocks(Hs, el, h_sum)
        return energies

    def _element_halves(self, chunk):
        """((lo, hi) of the first half, (lo, hi) of the second, (lo, hi) of the elements
        between) or None when the level is too small to split (`_SPLIT_FROM`).

        Elements are in the order of their first corner, and so of their last; an
        element writes gradient and Hessian rows of its corners only. The second half
        starts after every element sharing a corner with the first half: the two halves
        write disjoint rows and run in two threads without locks, and the elements between
        (about one slab of cells) run after them.
        """
        E = len(self.elem)
        if self.n < _SPLIT_FROM or E < 4 * chunk:
            return None
        m = E // 2
        m2 = int(np.searchsorted(self.elem[:, 0], self.elem[m - 1, -1], side="right"))
        if m2 >= E:
            return None
        return (0, m), (m2, E), (m, m2)

    def _add_blocks(self, Hs, el, hess):
        """Add the element Hessian blocks ``hess`` (E, K, K, d, d) of elements ``el`` into ``Hs``.

        Block [c, c'] of element e goes to stencil block (el[e, c], pair_off[c, c']); up to 2**d
        blocks of a chunk share a target. One sparse product (a column per block, a row per
        stencil block) sums them in C, into the slice of ``Hs`` between the chunk's first and
        last target (about one grid slab of nodes: the temporary is a small part of ``Hs``).
        All K*K blocks are added, the lower ones too: the element blocks are symmetric
        ([c', c] = [c, c']^T), so this is the mirror of the upper ones without a pass over the
        whole Hessian.
        """
        dd = self.d * self.d
        rows = (el[:, :, None] * np.int32(len(self.offsets)) + self.pair_off).reshape(-1)
        lo, hi = rows.min(), rows.max() + 1
        indptr = np.arange(len(rows) + 1, dtype=np.int32)  # one entry per column
        scatter = sp.csc_matrix((np.ones(len(rows)), rows - lo, indptr), shape=(hi - lo, len(rows)))
        Hs.reshape(-1, dd)[lo:hi] += scatter @ hess.reshape(-1, dd)

    def det_stats(self, y: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
        """min det F over every quadrature point, and centre det F, of the material cells."""
        el_all = self.elem[self.cell_material]
        G = np.concatenate([self.gauss.G, self.centre.G])
        mins, centres = [], []
        for s in range(0, len(el_all), chunk):
            F = elements.deformation_gradient(y[el_all[s:s + chunk]], G)
            det = elements.determinant(F)
            mins.append(det.min(axis=1))
            centres.append(det[:, -1])
        if not mins:
            return np.zeros(0), np.zeros(0)
        return np.concatenate(mins), np.concatenate(centres)

    def bsr(self, Hs: np.ndarray, lo: int = 0, hi: int | None = None) -> sp.bsr_matrix:
        """Rows ``lo`` to ``hi`` (nodes; default all) of the Hessian of stencil blocks ``Hs``
        (n, 3**d, d, d) as a BSR matrix, sharing ``Hs``'s memory."""
        d, k = self.d, len(self.offsets)
        hi = self.n if hi is None else hi
        data = Hs.reshape(-1, d, d)[lo * k:hi * k]
        return sp.bsr_matrix((data, self.bsr_indices[lo * k:hi * k], self.bsr_indptr[:hi - lo + 1]),
                             shape=((hi - lo) * d, self.n * d), copy=False)

    def product(self, Hs: np.ndarray,
                pool: Executor | None = None) -> Callable[[np.ndarray], np.ndarray]:
        """x -> H x for the stencil blocks ``Hs``. With a ``pool`` (one thread) the first
        half of the rows is multiplied there: scipy's BSR product releases the GIL, so when
        the bake's other process is idle (its map solved first) a product takes about 0.6
        of the time, and when both are busy about the same (benchmarks/README.md)."""
        if pool is None or self.n < _SPLIT_FROM:
            return self.bsr(Hs).dot
        half = self.n // 2
        first, second = self.bsr(Hs, 0, half), self.bsr(Hs, half)

        def apply(x):
            job = pool.submit(first.dot, x)
            out = second.dot(x)
            return np.concatenate([job.result(), out])
        return apply


def constrained_system(pa: np.ndarray, pb: np.ndarray, g: Grid, xa: np.ndarray, yb: np.ndarray,
                       options: MapOptions, base: np.ndarray,
                       crack: np.ndarray | None = None) -> MapSystem:
    """The `MapSystem` of grid ``g`` with feature patches no larger than the start allows
    (without the cells of a ``crack``, `tear.find_tear`).

    A patch moves its nodes by one affine map. Where the features ask for a kink at a
    feature point (stretched 4x on one side, squeezed on the other, as a body torn in
    two seen backwards), no affine map fits both sides and the patch's rim folds the
    start. The radius is then halved, down to the plain hard constraint on the
    feature's cell, until imposing the constraints folds nothing the start did not.
    """
    d, chunk = g.dim, int(options.chunk_elements)
    diag = 1.01 * np.sqrt(d) * g.spacing  # a patch must hold its feature's cell
    radius, margin_weight = options.feature_radius, options.margin_weight
    rad = max(float(radius), diag) if radius > 0 else 0.0
    floor = None  # the start's own det F floor: the region and its cells do not depend on rad
    while True:
        system = MapSystem(pa, pb, g, xa, yb, options.margin_cells, margin_weight, rad,
                          options.patch_rigidity, crack)
        if rad == 0.0 or system.cons.n_patch == 0:
            return system
        raw = base.reshape(-1, d)[system.active]
        if floor is None:
            floor = det_floor(system.det_stats(raw, chunk), options.min_det)
        if det_floor(system.det_stats(system.cons.enforce(raw), chunk), options.min_det) >= floor:
            return system
        rad = rad / 2 if rad / 2 >= diag else 0.0


def det_floor(dets: Sequence[np.ndarray], min_det: float) -> float:
    """What a step may not lower: the material's smallest det F, counted up to ``min_det``.

    A step is refused if it takes any quadrature point of the material below
    ``min_det`` (or below the current minimum, where the start is already
    lower), so the map never folds and never comes close to folding.
    """
    low = dets[0]
    return float(min(low.min(), min_det)) if low.size else float(min_det)
