"""As-rigid-as-possible trajectories from a volume map (thesis section 3.1, docs/method.md, section 5).

Given the map y(x) on every grid node, `Trajectories` gives each node a path
x(s), s in [0, 1], with x(0) = x and x(1) = y(x) exactly.

Two forms are implemented:

``method="global"`` (default) — the shape interpolation of Alexa, Cohen-Or and
Levin (2000), the "stronger reading" of docs/method.md, section 5:

1. every active cell gets one deformation gradient F_c (least-squares fit of
   the map to the cell's edges, i.e. the mean of its parallel edge
   differences) and its polar decomposition F_c = R_c S_c;
2. at time s the target gradient is F_c(s) = R_c^s ((1 - s) I + s S_c), where
   R_c^s turns by the fraction s of R_c's angle about its axis (log map /
   rotation vector);
3. node positions Y(s) minimise  sum_c w_c sum_{edges (i, j) of c} |Y_j - Y_i - F_c(s) (x_j - x_i)|^2,
   a Poisson problem whose matrix (a weighted graph Laplacian of the grid
   edges) does not depend on s: its multigrid preconditioner is built ONCE and
   every frame is a few conjugate-gradient iterations (`multigrid`), which any
   iteration can stop on cancel, started from the parabola through the
   solutions at s = 0, 1/2 and 1. That start depends on s alone, so a frame's
   positions do not depend on which frames were made before it: a frame made
   alone (the live preview, the helper's half of a segment, a farm's task) is
   the same as in a bake. Each connected component's translation is fixed by putting the
   centroid of its material on the straight path (1 - s) x_bar + s y_bar;
4. the residual r = y - Y(1) is added linearly, x(s) = Y(s) + s r, so the path
   ends exactly at y (eq. 3.1's last term).

Cells the map folds (det F_c <= 0, e.g. where two parts are pressed into each
other in a merge) keep the closest rotation (the smallest singular value takes
the sign), so S_c has one negative eigenvalue and the cell passes through a
flat state on its way to the fold. Rotation vectors are taken per cell with
angles in [0, pi]: near half turns neighbouring cells may pick opposite axes
(a limit of per-element log maps; keyframes turned more than ~170 degrees
apart need an inner keyframe).

In a chain, a `spline.Bend` set on the paths (``bend``) adds a cubic correction that is
zero at s = 0 and 1, so the velocity flows through the keyframes (docs/method.md,
section 12); the construction above is unchanged.

Rigid maps are reproduced exactly (F_c = R, S = I: Y(s) is the rotation by s of
the whole body about its centroid); articulated maps keep each part rigid and
the parts joined, because every edge is shared by neighbouring cells.

The region is the keyframe's material (Phi < 0) plus a margin of
``margin_cells`` cells around it. Cells touching the material have weight 1,
pure margin cells ``margin_weight``, so that empty space keeps the
trajectories regular without resisting merges. Outside the region every node
follows the body formula below (the thesis's eq. 3.1 with the rotation of its
whole component) and the two are blended smoothly over the outer half of the
margin, so every node has a continuous path.

``method="local"`` — the thesis's per-node formula (eq. 3.1 as read in
docs/method.md, section 5):
    x(s) = x_bar + s (y_bar - x_bar) + R_n^s (x - x_bar) + s r,
    r = y - [y_bar + R_n (x - x_bar)],
with x_bar, y_bar the centroids of the node's component before and after the
map and R_n the best rotation of the node's grid neighbourhood (polar
decomposition of the central-difference gradient, the closed form of
appendix A / Horn). Kept for comparison: it separates articulated parts at the
joint half-way (see tests/core/test_trajectory.py).
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy import ndimage
from scipy.sparse.csgraph import connected_components

from ..base import elements
from ..base.grid import Grid
from ..base.multigrid import BlockMultigrid, block_pcg
from ..base.progress import Reporter
from ..base.rotations import polar, rigid_fit, rotation_exp, rotation_log
from ..base.sampling import cell_weights, sample, smoothstep
from ..map.parts import cut_components
from .options import MotionOptions

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

__all__ = ["Trajectories"]


_CACHED = 3  # times whose active-node positions `Trajectories` keeps
_TARGET_CHUNK = 32_768  # cells whose target gradients `Trajectories._rhs` makes at once


def _edge_pairs(d):
    """The d 2^(d-1) edges of a cell: (axis, lower corner, upper corner), corners in
    `elements.corners` order."""
    corners = elements.corners(d)
    index = {tuple(c): k for k, c in enumerate(corners.tolist())}
    return [(a, k, index[tuple(c + np.eye(d, dtype=int)[a])])
            for a in range(d) for k, c in enumerate(corners.tolist()) if c[a] == 0]


def _edge_operators(lc, weight, n, d):
    """The trajectory solve's operators from the cells' edges (thesis sec. 3.1, global form).

    An edge i -> j along axis a of cell c, with the cell's ``weight`` w, should equal
    h F_c(s)[:, a]. Its least-squares term adds w (e_i - e_j)(e_i - e_j)^T to the
    weighted graph Laplacian L (n, n) and w (e_j - e_i) to column (c, a) of B
    (n, nc d), so that the right-hand side is B T with T's row (c, a) the target.

    L = D^T W D (D the edge differences), a sparse matrix, built without an edge-sized
    matrix: a lattice edge is shared by up to 2^(d-1) cells, so its weight is summed per
    lower node and axis first (L then has one entry per node and neighbour). B = D^T W E
    (E the edges' targets) is kept as the cells' corners and weights (`EdgeSums`), not
    as a matrix of 2^d d entries a cell.
    """
    pairs = _edge_pairs(d)
    # the corners at the lower and upper ends of the cell's 2^(d-1) edges along each axis
    lower = np.array([[k for a, k, _ in pairs if a == axis] for axis in range(d)])
    upper = np.array([[hi for a, _, hi in pairs if a == axis] for axis in range(d)])
    rows, cols, vals = [], [], []
    diag = np.zeros(n)
    for a in range(d):  # the lattice edges along axis a, one per lower node
        i, j = lc[:, lower[a]].reshape(-1), lc[:, upper[a]].reshape(-1)
        w_edge = np.bincount(i, np.repeat(weight, lower.shape[1]), minlength=n)
        neighbour = np.zeros(n, dtype=np.int64)
        neighbour[i] = j
        i = np.flatnonzero(w_edge)
        j, w = neighbour[i], w_edge[i]
        rows += [i, j]
        cols += [j, i]
        vals += [-w, -w]
        diag += np.bincount(i, w, minlength=n) + np.bincount(j, w, minlength=n)
    rows.append(np.arange(n))
    cols.append(np.arange(n))
    vals.append(diag)
    L = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n))
    return L, EdgeSums(lc, weight, n)


class EdgeSums:
    """B = D^T W E of `_edge_operators` as an operator: ``B @ T`` (T of shape (nc d, m),
    row (c, a) the target of cell c's edges along axis a) without B's 2^d d entries a cell.

    Each corner k of a cell is one end of exactly one of the cell's edges along each axis
    a: the upper end (+w) where k's bit a is set, else the lower end (-w). So corner k
    of cell c receives w_c sum_a sign_ka T[(c, a)], and the nodes sum what their cells'
    corners receive (one `np.bincount` per column of T). Kept: each cell's corners and
    weight, 72 bytes a cell in 3D against B's 300 (benchmarks/README.md, "The
    trajectories' right-hand side without its matrix").

    Parameters
    ----------
    lc : (nc, 2^d) int, each cell's corners as node indices (`elements.cells_within`).
    weight : (nc,) float, each cell's weight.
    n : int, the number of nodes.
    """

    def __init__(self, lc: ArrayLike, weight: ArrayLike, n: int) -> None:
        lc = np.asarray(lc)
        self._corners = lc.reshape(-1).astype(np.intp)  # cell-major, as B's columns hold them
        self._weight = np.asarray(weight, dtype=float)
        d = int(np.log2(lc.shape[1]))
        self._signs = 2.0 * elements.corners(d).T - 1.0  # (d, 2^d)
        self.shape = (int(n), lc.shape[0] * d)

    def __matmul__(self, T: ArrayLike) -> np.ndarray:
        T = np.asarray(T, dtype=float)
        nc, d = self._weight.size, self._signs.shape[0]
        if T.ndim != 2 or T.shape[0] != nc * d:
            raise ValueError(f"T must have shape ({nc * d}, m), got {T.shape}.")
        T = T.reshape(nc, d, -1)
        out = np.empty((self.shape[0], T.shape[2]))
        for m in range(T.shape[2]):  # a column at a time: the temporaries are (nc, 2^d)
            at = (T[..., m] * self._weight[:, None]) @ self._signs  # what corner k of c receives
            out[:, m] = np.bincount(self._corners, at.reshape(-1), minlength=self.shape[0])
        return out


def _cell_polar(y, lc, h):
    """Polar decomposition F = R S of every cell's deformation gradient F at its centre
    (the mean of its parallel edge differences over h), from the mapped positions ``y``
    (n, d) of the nodes; also whether F folds (det F <= 0). Returns R, S (nc, d, d) and
    folded (nc,)."""
    centre = elements.quadrature(y.shape[1], h, "centre").G
    F = elements.deformation_gradient(y[lc], centre)[:, 0]
    R, S = polar(F)
    return R, S, np.linalg.det(F) <= 0


# ----------------------------------------------------------------------------
def _checked(grid, mapped, material, components, method, margin_cells, margin_weight):
    """`Trajectories`' inputs checked, as (map, material, components labels on the
    material only); ValueError saying which to fix."""
    if not isinstance(grid, Grid):
        raise ValueError("grid must be a keyframe_implicit.core.Grid.")
    d = grid.dim
    y = np.asarray(mapped, dtype=float)
    if y.shape != grid.shape + (d,):
        raise ValueError(f"mapped has shape {y.shape}; expected grid.shape + (d,) = "
                         f"{grid.shape + (d,)} (one mapped position per node).")
    if not np.all(np.isfinite(y)):
        raise ValueError("mapped contains NaN or infinite positions; the map must be finite.")
    mat = np.asarray(material, dtype=bool)
    if mat.shape != grid.shape:
        raise ValueError(f"material has shape {mat.shape}; expected grid shape {grid.shape}.")
    if not mat.any():
        raise ValueError("material is empty: keyframe A has no node with Phi < 0; "
                         "check the sign convention (negative inside) and the grid.")
    if method not in ("global", "local"):
        raise ValueError(f'method must be "global" or "local", got {method!r}.')
    if not margin_cells >= 1:
        raise ValueError(f"margin_cells must be at least 1 cell, got {margin_cells}.")
    if not 0 < margin_weight <= 1:
        raise ValueError(f"margin_weight must lie in (0, 1], got {margin_weight}.")
    if components is None:
        components, _ = ndimage.label(mat)
    components = np.asarray(components)
    if components.shape != grid.shape:
        raise ValueError(f"components has shape {components.shape}; expected {grid.shape}.")
    components = np.where(mat, components, 0).astype(np.int64)
    return y, mat, components


class Trajectories:
    """As-rigid-as-possible node paths x(s) from x to the map y(x) (section 3.1).

    Parameters
    ----------
    grid : Grid
    mapped : ndarray, shape grid.shape + (d,)
        y(x) for every node, world units.
    material : bool ndarray, shape grid.shape
        Keyframe A's material (Phi < 0).
    components : int ndarray, shape grid.shape, optional
        Labels 1..k of A's material components (0 outside). Computed with
        `scipy.ndimage.label` (face connectivity) when omitted.
    method : {"global", "local"}
        Poisson-based ARAP interpolation (default) or the thesis's per-node
        formula; see the module docstring.
    margin_cells : float
        Width in cells of the margin around the material solved with the
        material (global method). Must be >= 1.
    margin_weight : float
        Weight of margin cells (cells that do not touch the material), in (0, 1].
    mass : ndarray, shape grid.shape, optional
        How much material each node stands for, for the centroids that fix each
        component's translation (global method); default 1 on the material, 0 elsewhere.
        On a motion grid: the surface grid's material restricted to its nodes
        (`finepaths.material_mass`), so the centroids are the surface material's.
    parts : int ndarray, shape grid.shape, optional
        The part of every node, where the map tears between parts that are apart in
        both keyframes (`map.parts`): the cells with corners in two parts leave the
        solve, so each part moves as a body of its own (global method).
    tolerance : float
        Global method: CG stops when the residual of every coordinate is below
        ``tolerance`` times its right-hand side's norm (the default keeps positions
        within about 1e-4 cells of the exact solve; benchmarks/README.md, "Trajectory solves").
    cancel : callable() -> bool, optional
        Polled during the setup and every CG iteration; `progress.Cancelled`
        is raised once it returns True.

    Attributes
    ----------
    stats : dict
        ``components``; global method, once `setup` has run: ``active_nodes``,
        ``active_cells``, ``setup_seconds``, ``multigrid_levels`` (unknowns per level) and
        ``cg_iterations`` (one entry per solve).
    """

    def __init__(self, grid: Grid, mapped: ArrayLike, material: ArrayLike,
                 components: ArrayLike | None = None, *,
                 method: str = MotionOptions.trajectory_method,
                 margin_cells: float = MotionOptions.trajectory_margin_cells,
                 margin_weight: float = MotionOptions.trajectory_margin_weight,
                 mass: ArrayLike | None = None, parts: ArrayLike | None = None,
                 tolerance: float = 1e-5, cancel: Callable[[], bool] | None = None) -> None:
        y, mat, components = _checked(grid, mapped, material, components, method, margin_cells,
                                      margin_weight)
        self._parts = None if parts is None else np.asarray(parts).reshape(-1)
        if self._parts is not None:  # a component the parts cut is a body per part
            components, _ = cut_components(components, self._parts.reshape(grid.shape))
        d = grid.dim

        self.grid = grid
        self.method = method
        self.margin_cells = float(margin_cells)
        self.margin_weight = float(margin_weight)
        self.tolerance = float(tolerance)
        self._check = Reporter(None, cancel).check
        self.dim = d
        self._y = y.reshape(-1, d)
        self.material = mat
        self._mass = mat if mass is None else np.asarray(mass, dtype=float)
        self.stats = {"method": method}
        self.bend = None  # a `spline.Bend` of the paths through keyframes, or None
        self._cache = {}  # positions of the active nodes at the last few times s

        # Per grid node only what every node needs (the map, the region, the body); the
        # rest is kept for the active nodes, or computed for the nodes asked about.
        # distance (cells) to the material, and the body (component) of the nearest material
        dist, inds = ndimage.distance_transform_edt(~mat, return_indices=True)
        nearest = np.ravel_multi_index(tuple(inds), grid.shape).reshape(-1)
        del inds
        self._region = (dist <= self.margin_cells).reshape(-1)
        labels = np.unique(components[mat])
        lab_flat = components.reshape(-1)
        self._body_label = lab_flat[nearest].astype(np.min_scalar_type(max(labels.max(), 1)))
        del nearest

        # body rigid motion: centroids and best rotation, per material component
        self._bodies = {}
        for lab in labels:
            sel = np.flatnonzero(lab_flat == lab)
            xb, yb, R = rigid_fit(self.grid.node_points(sel), self._y[sel])
            self._bodies[int(lab)] = (xb, yb, R, rotation_log(R[None])[0])
        self.stats["components"] = len(labels)

        self._unset = None  # global method: the distances `setup` still needs
        if method == "local":
            self._init_local()
        else:
            self._unset = dist.reshape(-1)[self._region]  # at the region's nodes only
            self._setup_lock = threading.Lock()

    def setup(self) -> None:
        """Build the global method's Poisson problem, its multigrid and Y(1); done the first
        time a time strictly between 0 and 1 is asked, since the ends need only the map
        (the template on a segment's last frame, made alone, needs no solve)."""
        if self._unset is None:
            return
        with self._setup_lock:  # the two transports of a frame may ask at once
            if self._unset is not None:
                t0 = time.perf_counter()
                self._init_global(self._unset)
                self._unset = None
                self.stats["setup_seconds"] = time.perf_counter() - t0

    # ------------------------------------------------------------------
    @property
    def mapped(self) -> np.ndarray:
        """The map y(x), array of grid.shape + (d,)."""
        return self._y.reshape(self.grid.shape + (self.dim,))

    def region_nodes(self) -> np.ndarray:
        """Flat bool mask of the region's nodes: the material and its margin."""
        return self._region

    @property
    def parts(self) -> np.ndarray | None:
        """The part of every node (flat), or None: the parts the paths keep apart."""
        return self._parts

    def body_positions(self, s: float, nodes: ArrayLike, like: ArrayLike) -> np.ndarray:
        """Positions at time s of the grid ``nodes`` moved rigidly with the body of the
        nodes ``like`` (one each): x_bar + s (y_bar - x_bar) + R^s (x - x_bar), that
        body's motion carried beyond it (where a part's motion is read across a gap)."""
        nodes, like = (np.asarray(n, dtype=np.int64).reshape(-1) for n in (nodes, like))
        xb, yb, _, rv = self._body_arrays(like)
        rel = self.grid.node_points(nodes) - xb
        return xb + s * (yb - xb) + np.einsum("nij,nj->ni", rotation_exp(s * rv, self.dim), rel)

    def _local(self, nodes):
        """Index of each node among the active nodes (global method), -1 where not active."""
        loc = np.searchsorted(self._nodes, nodes)
        loc = np.minimum(loc, self._nodes.size - 1)
        return np.where(self._nodes[loc] == nodes, loc, -1)

    def _body_arrays(self, nodes):
        """x_bar, y_bar, R, rotation vector of the body of each node (arrays over nodes)."""
        lab = self._body_label[nodes]
        d = self.dim
        xb = np.empty((nodes.size, d))
        yb = np.empty((nodes.size, d))
        R = np.empty((nodes.size, d, d))
        rv = np.empty((nodes.size,) + ((3,) if d == 3 else ()))
        for key, (x0, y0, R0, v0) in self._bodies.items():
            m = lab == key
            xb[m], yb[m], R[m], rv[m] = x0, y0, R0, v0
        return xb, yb, R, rv

    def _body_path(self, s, nodes):
        """Eq. 3.1 with the rotation of the whole body, for the given flat node indices:
        x(s) = x_bar + s (y_bar - x_bar) + R^s (x - x_bar) + s r, with the residual
        r = y - y_bar - R (x - x_bar) of the node w.r.t. its body's motion."""
        out = np.empty((nodes.size, self.dim))
        lab = self._body_label[nodes]
        for key, (xb, yb, R, rv) in self._bodies.items():  # one R^s per body
            m = lab == key
            if not m.any():
                continue
            sel = nodes[m]
            Rs = rotation_exp((s * rv)[None], self.dim)[0]
            rel = self.grid.node_points(sel) - xb
            resid = self._y[sel] - yb - rel @ R.T
            out[m] = xb + s * (yb - xb) + rel @ Rs.T + s * resid
        return out

    def _init_local(self):
        d = self.dim
        grid = self.grid
        y = self._y.reshape(grid.shape + (d,))
        # central-difference gradient of the map = best-fit of the 2d-neighbour stencil
        J = np.stack(np.gradient(y, grid.spacing, axis=tuple(range(d))), axis=-1)  # dy_i/dx_a
        R, _ = polar(J.reshape(-1, d, d))
        self._local_R = R
        self._local_rv = rotation_log(R)
        nodes = np.arange(grid.size)
        self._ext = self._body_arrays(nodes)

    def _init_global(self, region_dist):
        """`setup`: ``region_dist`` holds each region node's distance to the material."""
        grid, d = self.grid, self.dim
        _, nodes, lc = elements.cells_within(grid, self.region_nodes())
        if self._parts is not None:  # no edge joins two parts
            part = self._parts[nodes][lc]
            used, lc = np.unique(lc[np.all(part == part[:, :1], axis=1)], return_inverse=True)
            nodes, lc = nodes[used], lc.reshape(-1, 2 ** d)
        touch = self.material.reshape(-1)[nodes][lc].any(axis=1)  # a corner inside
        nc, n = len(lc), nodes.size
        if nc == 0:
            raise ValueError("no active cell: the material is thinner than one cell; "
                             "use a finer grid.")
        self._check()
        # each edge of a cell pulls towards h F_c[:, a]; margin cells pull more weakly
        self._L, self._B = _edge_operators(lc, np.where(touch, 1.0, self.margin_weight), n, d)
        ncomp, comp = connected_components(self._L, directed=False)
        # L is singular (one translation per component) and the right-hand sides are
        # consistent: CG on its range, the translation fixed afterwards (`_poisson`)
        coords = np.stack(np.unravel_index(nodes, grid.shape), axis=1)
        self._mg = BlockMultigrid(self._L, coords, check=self._check)
        del coords
        self.stats["multigrid_levels"] = self._mg.sizes
        self.stats["cg_iterations"] = []

        # per-cell F and its polar decomposition: the targets' rotation and stretch
        self._check()
        ya = self._y[nodes]
        R, S, folded = _cell_polar(ya, lc, grid.spacing)
        del lc
        self._check()
        self._cell_rv = rotation_log(R)
        self._cell_S = S
        self.stats["folded_cells"] = int(folded.sum())

        # centroid constraint per component of the active graph: material nodes of it
        self._comp = comp
        self._ncomp = ncomp
        self._cw = np.asarray(self._mass.reshape(-1)[nodes], dtype=float)
        self._xbar = self._component_centroids(self.grid.node_points(nodes))
        self._ybar = self._component_centroids(ya)
        self._nodes = nodes
        self._ncells = nc
        self.stats["active_nodes"] = int(n)
        self.stats["active_cells"] = int(nc)
        self.stats["active_components"] = int(ncomp)

        # residual so that x(1) = y exactly; the map itself starts CG (it differs from Y(1)
        # by that residual and a translation). Y(0) is the grid itself (F_c(0) = I).
        self._check()
        y1 = self._poisson(1.0, start=ya)
        self._resid = ya - y1
        self._anchors = {0.0: self.grid.node_points(nodes), 1.0: y1}  # `_start`
        self.stats["residual_max"] = float(np.abs(self._resid).max()) if n else 0.0

        # blend of the Poisson paths with the body formula over the outer half of the margin
        dl = region_dist[np.searchsorted(np.flatnonzero(self._region), nodes)]
        self._wblend = 1.0 - smoothstep((dl - 0.5 * self.margin_cells) / (0.5 * self.margin_cells))
        self._blended = np.flatnonzero(self._wblend < 1.0)  # where the body formula counts

    def _component_centroids(self, points):
        """Centroid (ncomp, d) of the material nodes of each component of the active graph
        (of all its nodes where it holds no material), from the active nodes' points."""
        out = np.zeros((self._ncomp, self.dim))
        for c in range(self._ncomp):  # components are few
            m = self._comp == c
            w = self._cw[m] if self._cw[m].sum() > 0 else np.ones(m.sum())
            out[c] = (w[:, None] * points[m]).sum(0) / w.sum()
        return out

    def _cell_targets(self, s, cells=slice(None)):
        """Target gradients F_c(s) = R_c^s ((1 - s) I + s S_c) of the active cells (or of
        the ``cells`` given), (nc, d, d)."""
        d = self.dim
        return rotation_exp(s * self._cell_rv[cells], d) @ ((1.0 - s) * np.eye(d)
                                                             + s * self._cell_S[cells])

    def _rhs(self, s):
        """The Poisson right-hand side B T at time s, (n, d): T's row (c, a) is the target
        h F_c(s)[:, a] of cell c's edges along axis a (`_edge_operators`). T is made
        `_TARGET_CHUNK` cells at a time, so the rotations' temporaries stay small."""
        d, nc = self.dim, self._ncells
        T = np.empty((nc, d, d))
        for c0 in range(0, nc, _TARGET_CHUNK):
            cells = slice(c0, min(c0 + _TARGET_CHUNK, nc))
            np.multiply(self.grid.spacing, np.swapaxes(self._cell_targets(s, cells), 1, 2),
                        out=T[cells])
        return self._B @ T.reshape(-1, d)

    def _poisson(self, s, start=None):
        """Poisson positions Y(s) of the active nodes (before the residual); CG starts from
        ``start``, by default from `_start`."""
        rhs = self._rhs(s)
        start = self._start(s) if start is None else start
        Y, its = block_pcg(self._L, rhs, self._mg, start, tol=self.tolerance,
                           check=self._check)
        self.stats["cg_iterations"].append(its)
        # fix each component's translation: material centroid on the straight path
        target = (1.0 - s) * self._xbar + s * self._ybar
        Y += (target - self._component_centroids(Y))[self._comp]
        return Y

    def _start(self, s):
        """CG's start at time s: the parabola through Y(0), Y(1/2) and Y(1), the middle one
        solved (from the line through the ends) the first time it is needed. A function of
        s alone, so that Y(s) does not depend on the times solved before it."""
        a = self._anchors
        if 0.5 not in a:
            a[0.5] = self._poisson(0.5, start=0.5 * (a[0.0] + a[1.0]))
        return ((1.0 - s) * (1.0 - 2.0 * s) * a[0.0] + 4.0 * s * (1.0 - s) * a[0.5]
                + s * (2.0 * s - 1.0) * a[1.0])

    def _formula(self, s, x, y, xb, yb, R, rv):
        d = self.dim
        Rs = rotation_exp(s * rv, d)
        rel = x - xb
        r = y - yb - np.einsum("nij,nj->ni", R, rel)
        return xb + s * (yb - xb) + np.einsum("nij,nj->ni", Rs, rel) + s * r

    # ------------------------------------------------------------------
    def _check_s(self, s):
        s = float(s)
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"time s must lie in [0, 1], got {s}.")
        return s

    def _active_positions(self, s):
        """Blended paths of the active nodes at time s (global method).

        The last ``_CACHED`` times are kept: a frame's velocity is a central difference
        over its neighbouring frames, which the frame loop asks for anyway.
        """
        key = round(s, 12)  # i/n + 1/n and (i + 1)/n may differ in the last bit
        if key not in self._cache:
            Y = self._poisson(s) + s * self._resid
            b = self._blended
            w = self._wblend[b, None]
            Y[b] = w * Y[b] + (1.0 - w) * self._body_path(s, self._nodes[b])
            self._cache[key] = Y
            if len(self._cache) > _CACHED:
                self._cache.pop(next(iter(self._cache)))
        return self._cache[key]

    def node_positions(self, s: float, nodes: ArrayLike) -> np.ndarray:
        """Positions x(s) of the grid nodes with the given flat indices, (len(nodes), d):
        the as-rigid-as-possible paths, plus the ``bend`` when one is set."""
        s = self._check_s(s)
        nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
        if s == 0.0:
            return self.grid.node_points(nodes)
        if s == 1.0:
            return self._y[nodes].copy()
        out = self._arap_positions(s, nodes)
        if self.bend is not None:
            out += self.bend(s, nodes)
        return out

    def _arap_positions(self, s, nodes):
        """`node_positions` without the bend, for 0 < s < 1."""
        if self.method == "local":
            xb, yb, R, rv = (a[nodes] for a in self._ext)
            return self._formula(s, self.grid.node_points(nodes), self._y[nodes], xb, yb,
                                 self._local_R[nodes], self._local_rv[nodes])
        self.setup()
        out = np.empty((nodes.size, self.dim))
        loc = self._local(nodes)
        act = loc >= 0
        out[act] = self._active_positions(s)[loc[act]]
        if not act.all():
            out[~act] = self._body_path(s, nodes[~act])
        return out

    def positions(self, s: float) -> np.ndarray:
        """Positions x(s) of every grid node, array of shape grid.shape + (d,)."""
        out = self.node_positions(s, np.arange(self.grid.size))
        return out.reshape(self.grid.shape + (self.dim,))

    def __call__(self, points: ArrayLike, s: float) -> np.ndarray:
        """Positions at time s of points given at time 0 ((P, d) -> (P, d)).

        Multilinear interpolation of the node trajectories (only the nodes of
        the points' cells are evaluated); points outside the grid are clamped
        to it (their displacement is that of the boundary).
        """
        p = np.asarray(points, dtype=float)
        if p.ndim != 2 or p.shape[1] != self.dim:
            raise ValueError(f"points must have shape (P, {self.dim}), got {p.shape}.")
        s = self._check_s(s)
        if p.shape[0] == 0 or s == 0.0:
            return p.copy()
        if s == 1.0:  # the map itself, read where the points are: no path to evaluate
            box = np.asarray(self.grid.shape) - 1
            clamped = self.grid.to_world(np.clip(self.grid.to_index(p), 0, box))
            return p - clamped + sample(self.mapped, self.grid, p)
        flat, w = cell_weights(self.grid, p)
        nodes, inv = self.grid.unique_nodes(flat)
        disp = self.node_positions(s, nodes) - self.grid.node_points(nodes)
        return p + np.einsum("pk,pkd->pd", w, disp[inv])
