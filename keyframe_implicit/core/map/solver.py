"""Volume map between two keyframes: constrained Gauss-Newton (thesis sec. 2.3-2.5).

`solve_map` minimises eq. 2.6 (one function per term in `terms`, cells in
`base.elements`) subject to the feature constraints of eq. 2.8 / 2.14-2.20
(`constraints`), starting from the RBF map of eq. 2.1-2.5 (`rbf`). Every setting
and its default is a field of `options.MapOptions`; benchmarks/README.md ("Map
solver") has the measurement behind each.

Algorithm (docs/method.md, section 4)
-------------------------------------
* Coarse to fine (`hierarchy`): the grid is coarsened by 2 while the coarsest
  keeps ``coarse_nodes`` nodes per side. Each level solves for a correction of the
  (fine) RBF map, prolonged multilinearly to the next level; the constraints are
  re-imposed exactly.
* Gauss-Newton (eq. 2.11-2.13) on the reduced unknowns of the constraint null space
  (eq. 2.16 by elimination rather than a KKT system). Energy, gradient and the
  Gauss-Newton Hessian are assembled per element in closed form straight into a
  3**d-neighbour block stencil (`system.MapSystem`), handed to scipy as a
  block-sparse matrix in single precision (`system.HESSIAN_DTYPE`).
* Linear solve: projected conjugate gradients with a d x d block-Jacobi
  preconditioner at the loose relative tolerance ``cg_tolerance``, plus a
  Levenberg-Marquardt shift ``damping`` x mean diagonal so that unpinned rigid modes
  stay bounded. Levels of ``coarse_space_from`` unknowns or more add a coarse
  correction (`coarse.CoarseSpace`): block Jacobi alone needs iterations in
  proportion to the grid's resolution. Each Hessian product runs in two row halves,
  one in a second thread, on the core the bake's other process leaves idle once its
  own map is solved.
* Safeguard: backtracking line search on the true energy (Armijo) that also
  refuses any step taking det F of the material below ``min_det``, or below its
  current minimum where the start is lower; a level starts from the coarser
  correction only as far as that keeps det F there (`hierarchy.start_map`). The
  transports of the in-betweens assume maps that do not fold.
* Stop when an accepted step lowers the energy by less than ``tolerance`` or after
  ``max_iterations`` per level.
* With ``tear`` (off by default): where a level's map spreads a component of A over
  several of B, that level is solved again with the component cut into pieces, and
  every finer level tears where its start does (`tear`, docs/method.md, section 4).
* With ``separate_parts`` (on by default): where A's components go to different
  components of B, the cells between them leave every level's solve, so each part is
  mapped as a body of its own however close they are (`parts`).

Weights, feature patches and the integration region (docs/method.md, section 2)
-------------------------------------------------------------------------------
The material is nearly incompressible (the volume weight far above the rigidity
weight: with equal weights the optimiser trades volume for rigidity). Each feature
point moves the solved nodes within ``feature_radius`` by one affine map
y'_i + A_i (x - x'_i); a feature marks material that must follow the artist's point,
so the rigidity of a patch's cells is multiplied by ``patch_rigidity``, or the patch
would shear and scale as a whole to absorb what the volume term pushes into it.
Cells inside A's material have weight 1, those of the map's margin
(``margin_cells`` wide) ``margin_weight``: without a margin the material's boundary
nodes are held by nothing and fold; at full weight the empty gap of a merge resists
it. Nodes outside the region carry a smooth extension of the solved correction.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.grid import Grid
from ..base.parallel import cores
from ..base.progress import Reporter
from .coarse import CoarseSpace
from .options import MapOptions
from .hierarchy import coarse_to_fine, correction, fields_on, prolong, start_map
from .rbf import initial_map
from .system import HESSIAN_DTYPE, MapSystem, constrained_system, det_floor
from .result import MapResult
from .parts import part_crack, part_labels, parts_on
from .tear import Tear, find_tear, prolong_pieces

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

__all__ = ["MapResult", "solve_map"]


# ----------------------------------------------------------------------------
# input checks
# ----------------------------------------------------------------------------
def _check_inputs(phi_a, phi_b, grid, features_a, features_b):
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be a keyframe_implicit.core.Grid, got {type(grid).__name__}.")
    d = grid.dim
    out = []
    for name, phi in (("phi_a", phi_a), ("phi_b", phi_b)):
        arr = grid.check_field(phi, name)
        if not np.any(arr < 0):
            raise ValueError(f"{name} has no negative value: that keyframe is empty on this grid. "
                             "Check the mesh is closed and lies inside the grid box.")
        out.append(arr)
    feats = []
    for name, f in (("features_a", features_a), ("features_b", features_b)):
        arr = np.asarray(f if f is not None else np.zeros((0, d)), dtype=float)
        if arr.size == 0:
            arr = arr.reshape(0, d)
        if arr.ndim != 2 or arr.shape[1] != d:
            raise ValueError(f"{name} must be an (N, {d}) array of points for a {d}D grid, "
                             f"got shape {arr.shape}.")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} contains NaN or infinite coordinates; remove those points.")
        inside = grid.contains(arr)
        if not np.all(inside):
            i = int(np.flatnonzero(~inside)[0])
            raise ValueError(f"{name}[{i}] = {arr[i].tolist()} lies outside the grid box "
                             f"[{grid.origin.tolist()}, {grid.upper.tolist()}]; move it inside or "
                             "enlarge the grid.")
        feats.append(arr)
    if len(feats[0]) != len(feats[1]):
        raise ValueError(f"features_a has {len(feats[0])} points but features_b has {len(feats[1])}; "
                         "row i of features_a must pair with row i of features_b.")
    xa = feats[0]
    if len(xa) > 1:
        u, inv, cnt = np.unique(np.round(xa / (1e-9 * grid.spacing)), axis=0, return_inverse=True,
                                return_counts=True)
        if np.any(cnt > 1):
            raise ValueError("features_a contains the same point twice; remove the duplicate pair.")
    return out[0], out[1], feats[0], feats[1]


def _pcg(apply_A, b, precond, project, tol, maxiter, check=None):
    """Projected preconditioned CG for A x = b on the range of ``project``, from 0; it
    stops at a residual of ``tol`` times |b| (projected).

    ``check`` (optional) is called every iteration (cancellation).
    """
    x = np.zeros_like(b)
    r = project(b.copy())
    bn = np.linalg.norm(r)
    if bn == 0:
        return x, 0
    z = project(precond(r))
    p = z.copy()
    rz = r @ z
    it = 0
    for it in range(1, maxiter + 1):
        if check is not None:
            check()
        Ap = project(apply_A(p))
        pAp = p @ Ap
        if pAp <= 0:
            break
        alpha = rz / pAp
        x += alpha * p
        r -= alpha * Ap
        if np.linalg.norm(r) <= tol * bn:
            break
        z = project(precond(r))
        rz_new = r @ z
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, it


def _solve_level(system: MapSystem, y, opts, rep, timing, pool=None):
    """Constrained Gauss-Newton on one level; returns y (n, d), per-iteration history.
    ``pool``: a one-thread executor for half of each assembly and Hessian product
    (`MapSystem.evaluate`, `MapSystem.product`)."""
    cons, weights = system.cons, opts.weights
    max_iterations, tolerance = int(opts.max_iterations), float(opts.tolerance)
    chunk = int(opts.chunk_elements)
    t0 = time.perf_counter()
    E, energies, g, Hs = system.evaluate(y, weights, chunk, hessian=True, check=rep.check, pool=pool)
    timing["assembly"] += time.perf_counter() - t0
    dets = system.det_stats(y, chunk)
    floor = det_floor(dets, opts.min_det)
    history = [dict(energy=E, **energies)]
    it = 0
    cg_total = 0
    fresh = True  # Hs was assembled at the current y
    t0 = time.perf_counter()
    coarse = _coarse_space(system, opts)
    timing["setup"] += time.perf_counter() - t0
    for it in range(1, max_iterations + 1):
        rep((it - 1) / max_iterations, f"Gauss-Newton iteration {it}")
        t0 = time.perf_counter()
        if fresh:
            apply_A, precond = _step_system(system, Hs, coarse, opts.damping, pool)
        b = -cons.reduce(g)
        z, ncg = _pcg(apply_A, b, precond, cons.project, opts.cg_tolerance, int(opts.cg_max_iterations),
                       rep.check)
        cg_total += ncg
        dy = cons.expand(cons.project(z))
        timing["linear solve"] += time.perf_counter() - t0
        slope = float(np.sum(g * dy))
        if slope >= 0:
            break
        t0 = time.perf_counter()
        step = _line_search(system, y, dy, E, slope, floor, weights, chunk, opts.min_det,
                            rep.check, pool)
        timing["line search"] += time.perf_counter() - t0
        if step is None:
            break
        alpha, y_new, E_new, energies_new, g_new, dets_new = step
        rel = (E - E_new) / max(E, 1e-300)
        y, dets, energies = y_new, dets_new, energies_new
        floor = det_floor(dets, opts.min_det)
        history.append(dict(energy=E_new, step=alpha, cg_iterations=ncg, **energies_new))
        E = E_new
        if rel < tolerance or it == max_iterations:
            break
        if opts.reuse_hessian and alpha == 1.0 and fresh:
            # a full step was accepted: the model was good, so keep its Hessian for one more
            # step (the gradient is exact, it came with the line search's evaluation)
            g, fresh = g_new, False
            continue
        t0 = time.perf_counter()
        apply_A = Hs = precond = None  # the old Hessian goes before the new one is assembled
        E, energies, g, Hs = system.evaluate(y, weights, chunk, hessian=True, check=rep.check,
                                         pool=pool)
        fresh = True
        timing["assembly"] += time.perf_counter() - t0
    return y, history, len(history) - 1, cg_total, dets, energies


def _step_system(system, Hs, coarse, damping, pool):
    """The reduced Gauss-Newton operator of a step, damped by ``damping`` times its mean
    diagonal so that unpinned rigid modes stay bounded, and its preconditioner (block
    Jacobi, plus the ``coarse`` correction where there is one)."""
    cons, d = system.cons, system.d
    diag = Hs[:, system.centre_off]
    mu = damping * max(float(np.mean(np.trace(diag, axis1=1, axis2=2))) / d, 1e-300)
    Hs[:, system.centre_off] += mu * np.eye(d)
    H = system.product(Hs, pool)
    precond = cons.block_preconditioner(Hs[:, system.centre_off].astype(float))
    if coarse is not None:
        precond = _with_correction(precond, coarse.correction(Hs), cons.n_free, d)

    def apply_A(z):  # the product in the Hessian's precision (a cast, not an upcast of H)
        Tz = cons.expand(z).reshape(-1).astype(HESSIAN_DTYPE)
        return cons.reduce(H(Tz).reshape(-1, d).astype(float))

    return apply_A, precond


def _second_thread():
    """A one-thread executor for half of each assembly and Hessian product
    (`MapSystem.evaluate`, `MapSystem.product`), or a context of None on a single core."""
    if cores() < 2:
        return nullcontext(None)
    return ThreadPoolExecutor(max_workers=1, thread_name_prefix="keyframe_implicit solver")


def _coarse_space(system, opts):
    """The level's `CoarseSpace`, or None where its systems are small enough for block
    Jacobi alone (fewer than ``coarse_space_from`` unknowns)."""
    if system.cons.size < opts.coarse_space_from:
        return None
    coords = np.stack(np.unravel_index(system.active, system.grid.shape), axis=-1)
    return CoarseSpace(coords, system.bsr_indices.reshape(system.n, -1), system.cons.free_nodes,
                       opts.coarse_space_size)


def _with_correction(precond, correction, n_free, d):
    """The additive two-level preconditioner: ``precond`` plus the coarse ``correction``
    on the free nodes' unknowns (the first ``n_free * d`` of the reduced vector)."""
    m = n_free * d

    def apply(r):
        out = precond(r)
        out[:m] += correction(r[:m].reshape(n_free, d)).reshape(-1)
        return out

    return apply


def _line_search(system, y, dy, E, slope, floor, weights, chunk, min_det, check, pool=None):
    """Backtracking from the full step: the first of 1, 1/2, 1/4, ... (down to 1e-4) that
    keeps det F of the material at or above ``floor`` (`det_floor`) and lowers the
    energy by the Armijo fraction 1e-4 of ``slope``. The det F test is tried first: it
    costs a few per cent of an energy evaluation and refuses most steps near folding.

    Returns (alpha, y, energy, energies, gradient, det stats) at the accepted step, or None.
    """
    alpha = 1.0
    while alpha > 1e-4:
        check()
        y_new = y + alpha * dy
        dets_new = system.det_stats(y_new, chunk)
        if det_floor(dets_new, min_det) >= floor:
            E_new, energies_new, g_new, _ = system.evaluate(y_new, weights, chunk, hessian=False,
                                                        check=check, pool=pool)
            if E_new <= E + 1e-4 * alpha * slope:
                return alpha, y_new, E_new, energies_new, g_new, dets_new
        alpha *= 0.5
    return None


def _level(pa, pb, g, xa, yb, options, base, corr, tear, gaps, rep, timing, pool,
           refine=True):
    """One level of the hierarchy solved: its system (without the cells of the ``tear``'s
    crack, if any, nor those of the ``gaps`` between separate parts), the solution on its
    active nodes, its correction of ``base`` on every node, det F figures, term energies
    and the level's stats. It starts from ``corr`` on this level's grid: a coarser level's
    correction prolonged (``refine``, as far as `start_map` allows), or this level's own,
    to be solved again."""
    t0 = time.perf_counter()
    crack = gaps if tear is None else tear.crack if gaps is None else tear.crack | gaps
    system = constrained_system(pa, pb, g, xa, yb, options, base, crack)
    if refine:
        start, y = start_map(system, base, corr, options)
    else:
        start = base + corr
        y = system.cons.enforce(start.reshape(-1, g.dim)[system.active])
    timing["setup"] += time.perf_counter() - t0
    y, history, iters, cg_total, dets, energies = _solve_level(system, y, options, rep, timing,
                                                               pool)
    t0 = time.perf_counter()
    corr = correction(system, y, start, base, int(options.extension_passes))
    timing["extension"] += time.perf_counter() - t0
    stats = dict(shape=g.shape, active_nodes=system.n, unknowns=system.cons.size,
                 iterations=iters, cg_iterations=cg_total, history=history,
                 torn=tear is not None)
    return system, y, corr, dets, energies, stats


# ----------------------------------------------------------------------------
# public entry point
# ----------------------------------------------------------------------------


def solve_map(phi_a: ArrayLike, phi_b: ArrayLike, grid: Grid, features_a: ArrayLike,
              features_b: ArrayLike, *, options: MapOptions | None = None,
              parts: ArrayLike | None = None,
              progress: Callable[[float, str], object] | None = None,
              cancel: Callable[[], bool] | None = None, **keywords: Any) -> MapResult:
    """Map keyframe A's grid nodes onto keyframe B (thesis chapter 2).

    Parameters
    ----------
    phi_a, phi_b : ndarray, grid.shape
        Signed distances of keyframes A ("initial", Phi) and B ("final", Psi),
        negative inside, world units.
    grid : `Grid`
    features_a, features_b : (N, d) array_like
        Feature points x'_i of A and their targets y'_i in B (row i pairs with
        row i), world units, inside the grid box. N may be 0.
    options : `options.MapOptions`, optional
        All settings at once: how the bake passes them. Give them so or as keywords,
        not both.
    parts : int ndarray, grid.shape, optional
        The part of every node (`parts.part_labels`), where ``grid``'s fields cannot tell
        the parts apart: on a motion grid, the surface grid's parts read at its nodes
        (`parts.parts_on`). Read with ``separate_parts`` only; by default found here.
    progress, cancel : callables, see `keyframe_implicit.core.base.progress`.
    **keywords
        Any field of `options.MapOptions` (``max_iterations`` 20, ``tolerance`` 1 %,
        ``margin_cells`` 3, ``margin_weight`` 0.1, ``feature_radius``, ``min_det`` 0.2,
        ...: its docstring lists them with their defaults), and ``volume_weight``,
        ``rigidity_weight``, ``levelset_weight`` (30, 1, 10: eq. 2.6's weights,
        `terms`) or the weight of any term registered in `terms.TERMS`: the form for
        callers outside the bake (`options.MapOptions.from_keywords`).

    Returns
    -------
    MapResult

    Raises
    ------
    ValueError
        Bad input (shapes, NaN, empty keyframe, feature points outside the
        grid or unpaired, unknown option).
    keyframe_implicit.core.Cancelled
        When ``cancel()`` returned True.
    """
    t_start = time.perf_counter()
    phi_a, phi_b, xa, yb = _check_inputs(phi_a, phi_b, grid, features_a, features_b)
    if options is None:
        options = MapOptions.from_keywords(**keywords)
    elif keywords:
        raise TypeError(f"solve_map takes options= or keywords, not both; got options and "
                        f"{sorted(keywords)}.")
    options = options.on_grid(grid)
    weights = options.weights
    rep = Reporter(progress, cancel)
    timing = {"initial map": 0.0, "setup": 0.0, "assembly": 0.0, "linear solve": 0.0,
              "line search": 0.0, "extension": 0.0}

    t0 = time.perf_counter()
    rep(0.0, "Initial map (radial basis functions)")
    parts = _parts(phi_a, phi_b, grid, xa, yb, options, parts)
    init = initial_map(phi_a, phi_b, grid, xa, yb, parts)
    y0 = init.mapped if options.initial is None else options.initial
    timing["initial map"] = time.perf_counter() - t0
    disp0 = y0 - grid.points()

    grids = coarse_to_fine(grid, int(options.coarse_nodes))
    nlev = len(grids)
    # work per level grows ~2**d per refinement: give progress slices accordingly
    cost = np.array([2.0 ** (grid.dim * i) for i in range(nlev)])
    edges = np.concatenate([[0.05], 0.05 + 0.9 * np.cumsum(cost) / cost.sum()])
    corr, tear, pieces = None, None, None
    level_stats = []
    with _second_thread() as pool:
        for li, g in enumerate(grids):  # coarse to fine; the last is ``grid``
            t0 = time.perf_counter()
            pa, pb, base = ((phi_a, phi_b, y0) if li == nlev - 1
                            else fields_on(phi_a, phi_b, disp0, grid, g))
            if not np.any(pa < 0):
                continue  # material too thin for this coarse level
            step = None if corr is None else prolong(corr, g.shape)
            coarse_pieces, pieces = pieces, None if parts is None else _pieces(parts, grid, g)
            if tear is not None:  # a coarser level tore: this one tears where its start does
                coarse, tear = tear, find_tear(pa, pb, g, base + step)
                if tear is not None:  # and each piece starts from its own coarse piece
                    step = prolong_pieces(corr, coarse, tear, int(options.extension_passes))
            elif coarse_pieces is not None:  # each part starts from its own coarse part
                step = prolong_pieces(corr, coarse_pieces, pieces, int(options.extension_passes))
            gaps = None if pieces is None else pieces.crack
            timing["setup"] += time.perf_counter() - t0
            part = rep.sub(edges[li], edges[li + 1])
            system, y, corr, dets, energies, st = _level(pa, pb, g, xa, yb, options, base, step,
                                                         tear, gaps, part, timing, pool)
            level_stats.append(st)
            if tear is None and options.tear:
                tear = find_tear(pa, pb, g, base + corr)
                if tear is not None:  # this level once more, each piece a body of its own
                    system, y, corr, dets, energies, st = _level(
                        pa, pb, g, xa, yb, options, base, corr, tear, gaps, part, timing, pool,
                        refine=False)
                    level_stats.append(st)
    rep(1.0, "Volume map done")
    stats = _map_stats(system, y, dets, energies, weights, level_stats, init)
    stats["seconds"] = dict(timing, total=time.perf_counter() - t_start)
    stats["tear"] = None if tear is None else tear.stats
    region = np.zeros(grid.size, dtype=bool)
    region[system.active] = True
    return MapResult(mapped=y0 + corr, stats=stats, grid=grid, region=region.reshape(grid.shape),
                     material=phi_a < 0, components=init.components, tear=tear, parts=parts)


def _parts(phi_a, phi_b, grid, xa, yb, options, parts):
    """The parts the map keeps apart: None without ``separate_parts``, the ``parts`` given,
    or those of the fields (`parts.part_labels`)."""
    if not options.separate_parts:
        return None
    if parts is None:
        return part_labels(phi_a, phi_b, grid, xa, yb)
    return grid.check_field(parts, "parts").astype(np.int64)


def _pieces(parts, grid, level):
    """The parts on the nodes of a ``level`` of ``grid``'s hierarchy, as the `tear.Tear`
    of a map that tears between them (each part maps onto itself)."""
    own = parts_on(parts, grid, level)
    return Tear(own, part_crack(own), np.arange(1, own.max() + 1), 0.0)


def _map_stats(system, y, dets, energies, weights, level_stats, init):
    """`MapResult.stats` (but its ``seconds``) from the finest level's last accepted iterate."""
    mind, cdet = dets
    res = system.cons.residual(y)
    h = system.grid.spacing
    return dict(
        iterations=level_stats[-1]["iterations"],
        cg_iterations=level_stats[-1]["cg_iterations"],
        history=level_stats[-1]["history"],
        levels=level_stats,
        energy=float(sum(energies.values())),
        terms=energies,
        weights=dict(weights),
        min_det=float(mind.min()) if len(mind) else 1.0,
        max_abs_det_minus_1=float(np.max(np.abs(cdet - 1))) if len(cdet) else 0.0,
        feature_residual=float(res.max()) if len(res) else 0.0,
        feature_residual_h=float(res.max() / h) if len(res) else 0.0,
        active_nodes=system.n,
        unknowns=system.cons.size,
        patch_features=int(np.sum(system.cons.is_patch)),
        hard_features=int(len(system.cons.hard)),
        initial_methods=list(init.methods),
    )
