"""Initial map from feature points, radial basis functions (thesis sec. 2.2, eq. 2.1-2.5).

As corrected in docs/method.md, section 1, the centres are the feature points x'_i
and the interpolated quantity is the displacement y'_i - x'_i:

    y(x) = x + p(x) + sum_i lambda_i R(|x - x'_i|),   y(x'_i) = y'_i      (eq. 2.1-2.2)

with p of degree 1, R(r) = r^2 log r in 2D (eq. 2.3) and r^3 in 3D (eq. 2.4).
The saddle-point system of eq. 2.5 is what ``scipy.interpolate.RBFInterpolator``
(kernel ``thin_plate_spline`` / ``cubic``, ``degree=1``) solves.

The solver keeps whatever folds its start has (it refuses steps that add
folds, and cannot remove them), so a start that folds the material is not
used: in 3D, where the thesis's r^3 folds it (feature pairs asking for very
different stretches, e.g. a merge seen backwards: the cubic overshoots
between them), the biharmonic kernel R(r) = r (the 3D thin-plate spline,
least bending, least overshoot) is used instead (`_rbf_map`).

The map is built per connected component of A's material (``phi_a < 0``,
face connectivity), each with the feature points that lie in it (a point
slightly outside goes to the nearest component). Where the RBF cannot be used
-- fewer than d+1 points, all of them on one line (2D) / plane (3D), or an
interpolant that would carry the material out of the grid (`_rbf_map`) -- the
component gets a rigid alignment onto keyframe B instead (centroid and
principal axes; sign/permutation of the axes chosen to best overlap B's
material, pinned by whatever feature points exist), plus a smooth Gaussian
correction that makes the feature points land exactly. Components without
any feature point are aligned rigidly with the component of B whose centroid
is nearest. The optimiser (`keyframe_implicit.core.map.solver`) refines all of it.

Outside the material every node still gets a smooth value: inside component k
the map is component k's; elsewhere an inverse-distance blend (weights
1 / dist_k^4) of the components' maps. Never NaN.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import ndimage

from ..base import elements
from ..base.grid import Grid
from ..base.rotations import rigid_fit
from ..base.sampling import sample
from .parts import cut_components, nearest_label

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike
    from scipy.interpolate import RBFInterpolator

__all__ = ["InitialMap", "initial_map", "label_material", "rigid_alignment"]


@dataclass
class InitialMap:
    """Result of `initial_map`.

    mapped : (shape + (d,)) y(x) at every node.
    components : int array (shape), label of A's material components (0 = outside).
    methods : list of str, per component (index k-1): "rbf" or "rigid".
    feature_component : (N,) int, the component each feature point belongs to.
    """

    mapped: np.ndarray
    components: np.ndarray
    methods: list[str] = field(default_factory=list)
    feature_component: np.ndarray | None = None


def label_material(phi: ArrayLike) -> tuple[np.ndarray, int]:
    """Connected components of ``phi < 0`` (face connectivity): (labels, count)."""
    labels, n = ndimage.label(np.asarray(phi) < 0)
    return labels, int(n)


def _nearest_label(labels: np.ndarray, grid: Grid, points: np.ndarray) -> np.ndarray:
    """Label of the material node nearest to each world point (0 if no material)."""
    if labels.max() == 0:
        return np.zeros(len(points), dtype=np.int64)
    return nearest_label(labels)[tuple(grid.nearest_node(points).T)]


def _affinely_independent(points: np.ndarray, d: int) -> bool:
    """True if ``points`` (n, d) span a d-simplex (n >= d+1, not on a line/plane)."""
    if len(points) < d + 1:
        return False
    c = points - points.mean(axis=0)
    s = np.linalg.svd(c, compute_uv=False)
    return s[-1] > 1e-6 * max(s[0], 1e-300)


def _rbf_map(fa: np.ndarray, fb: np.ndarray, pts: np.ndarray, grid: Grid,
             material: np.ndarray) -> np.ndarray | None:
    """y(x) = x + RBF displacement (eq. 2.1-2.5) at ``pts``, or None where it cannot be trusted.

    Guard on the map's conditioning and range: the interpolant is refused when
    its saddle-point system is singular, when its result is not finite, or when
    it sends any of the component's material nodes (``material``) out of the
    grid (`_guarded`). Feature points that are nearly coplanar or
    almost on top of each other with different targets make the cubic's
    polynomial part explode far from them; the rigid start with a smooth
    correction is used instead. In 3D a cubic that folds the material is
    replaced by the biharmonic kernel (module docstring); if that folds too,
    the less folded of the two is returned.
    """
    kernels = ("thin_plate_spline",) if grid.dim == 2 else ("cubic", "linear")
    best, best_det = None, -np.inf
    for kernel in kernels:
        y = _guarded(lambda: pts + _rbf(fa, fb - fa, kernel=kernel, degree=1)(pts),
                     grid, material)
        if y is None:
            continue
        det = min_det(y, grid, material)
        if det > 0:
            return y
        if det > best_det:
            best, best_det = y, det
    return best


def min_det(mapped: ArrayLike, grid: Grid, material: ArrayLike) -> float:
    """Smallest det F of a map over the cells touching ``material`` (bool, flat).

    F is that of the multilinear cell (`elements`), at the cell centre and the
    2**d Gauss points, as the solver measures it; <= 0 means the map folds.
    """
    d = grid.dim
    cs = elements.corners(d)
    views = elements.corner_views(np.asarray(material, dtype=bool).reshape(grid.shape))
    touch = functools.reduce(np.logical_or, views)  # a corner in the material
    lower = np.argwhere(touch)
    if lower.size == 0:
        return np.inf
    y = np.asarray(mapped, dtype=float).reshape(grid.shape + (d,))
    Y = np.stack([y[tuple((lower + c).T)] for c in cs], axis=1)  # (cells, 2**d, d)
    h = grid.spacing
    G = np.concatenate([elements.quadrature(d, h, "gauss").G, elements.quadrature(d, h, "centre").G])
    return float(elements.determinant(elements.deformation_gradient(Y, G)).min())


def _guarded(build: Callable[[], np.ndarray], grid: Grid,
             material: np.ndarray) -> np.ndarray | None:
    """``build()`` if it succeeds with a finite map keeping ``material`` near the grid, else None.

    "Near": out of the grid box by at most a quarter of its size (the solver
    pulls a start that overshoots a little back onto B).
    """
    try:
        y = build()
    except (np.linalg.LinAlgError, ValueError):
        return None
    slack = 0.25 * float(np.max(grid.upper - grid.origin))
    if not np.all(np.isfinite(y)) or not np.all(grid.contains(y[material], margin=-slack)):
        return None
    return y


def _principal_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = points.mean(axis=0)
    cov = np.cov((points - c).T) if len(points) > 1 else np.eye(points.shape[1])
    vals, vecs = np.linalg.eigh(np.atleast_2d(cov))
    order = np.argsort(vals)[::-1]
    return c, vecs[:, order], np.sqrt(np.maximum(vals[order], 0.0))


def rigid_alignment(points_a: np.ndarray, phi_b: np.ndarray, grid: Grid, target_points: np.ndarray,
                    features_a: np.ndarray | None = None,
                    features_b: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rigid motion (R, t) carrying a component of A onto a component of B.

    Parameters
    ----------
    points_a : (n, d) world positions of the component's material nodes.
    phi_b : keyframe B's signed distance grid (scores the overlap).
    target_points : (m, d) world positions of the target component's material nodes.
    features_a, features_b : (k, d) feature points of this component (k may be 0).

    Returns
    -------
    R : (d, d) proper rotation; t : (d,) so that y = R x + t.

    Notes
    -----
    Candidates: the identity, the Kabsch fit of the feature points when they
    pin a rotation (>= d-1 independent directions), and every proper
    signed permutation of the principal axes (A's axes onto B's). With
    features the translation matches their centroids, else the components'
    centroids. Score: fraction of A's nodes landing in B's material, minus the
    feature misfit (relative to the component size), minus a small penalty on
    the rotation angle (so symmetric shapes are not spun for nothing).
    """
    d = grid.dim
    ca, Va, sa = _principal_frame(points_a)
    cb, Vb, _ = _principal_frame(target_points)
    size = max(float(np.sqrt(np.sum(sa ** 2))), grid.spacing)
    k = 0 if features_a is None else len(features_a)
    cands = [np.eye(d)]
    if k >= 2:
        c = features_a - features_a.mean(axis=0)
        s = np.linalg.svd(c, compute_uv=False)
        if np.sum(s > 1e-6 * max(s[0], 1e-300)) >= d - 1:
            cands.append(rigid_fit(features_a, features_b)[2])
    for perm in itertools.permutations(range(d)):
        P = np.eye(d)[:, perm]
        for signs in itertools.product((1.0, -1.0), repeat=d):
            R = Vb @ np.diag(signs) @ P.T @ Va.T
            if np.linalg.det(R) > 0:
                cands.append(R)
    rng = np.random.default_rng(0)
    sub = points_a if len(points_a) <= 4000 else points_a[rng.choice(len(points_a), 4000, replace=False)]
    best, best_score = None, -np.inf
    for R in cands:
        if k:
            t = features_b.mean(axis=0) - R @ features_a.mean(axis=0)
            misfit = np.sqrt(np.mean(np.sum((features_a @ R.T + t - features_b) ** 2, axis=1))) / size
        else:
            t = cb - R @ ca
            misfit = 0.0
        inside = np.mean(sample(phi_b, grid, sub @ R.T + t, outside="distance") < 0)
        angle = np.arccos(np.clip((np.trace(R) - (d - 2)) / 2.0, -1.0, 1.0))
        score = inside - misfit - 0.01 * angle / np.pi
        if score > best_score + 1e-12:
            best, best_score = (R, t), score
    return best


def _rigid_map(mask: np.ndarray, fa: np.ndarray, fb: np.ndarray, phi_b: np.ndarray,
               labels_b: np.ndarray, centroids_b: np.ndarray, grid: Grid,
               pts: np.ndarray) -> np.ndarray:
    """The map of one component of A (``mask``) whose features cannot carry an RBF: the rigid
    motion onto the component of B its features (or, without any, its centroid) point at
    (`rigid_alignment`), plus a Gaussian RBF correction that lands the features exactly
    where that is well conditioned. Returns y at every point of ``pts``."""
    nb = len(centroids_b)
    comp_pts = grid.to_world(np.argwhere(mask))
    if len(fb):
        tlab = _nearest_label(labels_b, grid, fb)
        target = np.bincount(tlab, minlength=nb + 1)[1:].argmax() + 1
    else:
        ca = comp_pts.mean(axis=0)
        target = int(np.argmin(np.sum((centroids_b - ca) ** 2, axis=1))) + 1
    target_pts = grid.to_world(np.argwhere(labels_b == target))
    R, t = rigid_alignment(comp_pts, phi_b, grid, target_pts, fa, fb)
    y = pts @ R.T + t
    if len(fa):
        resid = fb - (fa @ R.T + t)
        if np.max(np.abs(resid)) > 0:
            _, _, s = _principal_frame(comp_pts)
            sigma = max(float(np.sqrt(np.sum(s ** 2))), 2 * grid.spacing)
            rigid = y
            y = _guarded(lambda: rigid + _rbf(
                fa, resid, kernel="gaussian", epsilon=1.0 / sigma, degree=-1)(pts),
                grid, mask.reshape(-1))
            if y is None:  # an ill-conditioned correction: the solver's constraints do it
                y = rigid
    return y


def _blend(maps: list[np.ndarray], labels: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """One map from the components' maps: each component's own map on its material, and
    between them the maps weighted by 1 / distance^4 to each component."""
    num = np.zeros_like(pts)
    den = np.zeros(len(pts))
    out = np.zeros_like(pts)
    flat = labels.reshape(-1)
    for k in range(1, len(maps) + 1):
        dist = ndimage.distance_transform_edt(labels != k).reshape(-1)
        w = np.where(dist > 0, 1.0 / np.maximum(dist, 1e-12) ** 4, 0.0)
        num += w[:, None] * maps[k - 1]
        den += w
        out[flat == k] = maps[k - 1][flat == k]
    outside = flat == 0
    out[outside] = num[outside] / den[outside, None]
    return out


def initial_map(phi_a: np.ndarray, phi_b: np.ndarray, grid: Grid, features_a: ArrayLike,
                features_b: ArrayLike, parts: np.ndarray | None = None) -> InitialMap:
    """Initial map y(x) of every node (eq. 2.1-2.5 per component, rigid fallback).

    Parameters
    ----------
    phi_a, phi_b : signed distance grids of keyframes A and B (negative inside).
    grid : `Grid`.
    features_a, features_b : (N, d) paired feature points (world units), N >= 0.
    parts : int array (grid.shape), optional
        The parts the map keeps apart (`parts.part_labels`): a component they cut is one
        component per part, each with its own map.

    Returns
    -------
    InitialMap
    """
    d = grid.dim
    xa = np.asarray(features_a, dtype=float).reshape(-1, d)
    ya = np.asarray(features_b, dtype=float).reshape(-1, d)
    labels, n = label_material(phi_a)
    if parts is not None:
        labels, n = cut_components(labels, parts)
    labels_b, nb = label_material(phi_b)
    pts = grid.points().reshape(-1, d)
    comp_of = _nearest_label(labels, grid, xa) if len(xa) else np.zeros(0, dtype=np.int64)
    centroids_b = ndimage.center_of_mass(np.ones(grid.shape), labels_b, range(1, nb + 1))
    centroids_b = grid.to_world(np.asarray(centroids_b, dtype=float).reshape(-1, d))

    maps, methods = [], []
    for k in range(1, n + 1):
        sel = comp_of == k
        fa, fb = xa[sel], ya[sel]
        mask = labels == k
        if _affinely_independent(fa, d):
            y = _rbf_map(fa, fb, pts, grid, mask.reshape(-1))
            if y is not None:
                maps.append(y)
                methods.append("rbf")
                continue
        y = _rigid_map(mask, fa, fb, phi_b, labels_b, centroids_b, grid, pts)
        maps.append(y)
        methods.append("rigid")

    shape = grid.shape + (d,)
    if n == 0:
        return InitialMap(pts.reshape(shape).copy(), labels, methods, comp_of)
    if n == 1:
        return InitialMap(maps[0].reshape(shape), labels, methods, comp_of)
    out = _blend(maps, labels, pts)
    return InitialMap(out.reshape(shape), labels, methods, comp_of)


def _rbf(*args: Any, **kwargs: Any) -> RBFInterpolator:

    """``scipy.interpolate.RBFInterpolator``, imported when first used: a process that
    only builds trajectories from solved maps (a farm's later tasks) does not pay for
    scipy.interpolate."""
    from scipy.interpolate import RBFInterpolator

    return RBFInterpolator(*args, **kwargs)
