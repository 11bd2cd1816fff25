"""The alternatives a user would pick instead of this project, on the same grids.

Every method has the signature ``run(phi_a, phi_b, grid, features_a, features_b, times)``
and returns a `Run`: the level set grids at ``times`` (negative inside), the
seconds spent per stage, and the node map y(x) where the method defines one.

- `linear_blend`: (1 - s) phi_a + s phi_b, what Blender's SDF grid nodes give.
- `morph_flow`: level-set morphing in the style of OpenVDB's LevelSetMorphing
  (tools/LevelSetMorph.h): d(phi)/dt = -(phi - psi) |grad phi|, first-order
  Godunov upwind |grad phi|, forward Euler (TVD-RK1) with OpenVDB's RK1 CFL
  number 0.3 / sqrt(3), speed measured on the narrow band |phi| < 3h, and one
  Sussman renormalisation step (d(phi)/dtau = sign(phi)(1 - |grad phi|)) after
  every step, standing in for OpenVDB's narrow-band tracker. The speed is zero
  outside the band (OpenVDB updates active voxels only), so the front moves
  continuously and cannot jump to parts of B it does not touch. Iterated until
  the band speed max |phi - psi| < 0.1 h, or
    the last 50 steps moved phi by less than 1% of the path so far (a
  stationary state that is not B: reported as the final band residual), or
  4000 steps.
  Frames are taken at equal fractions of the path length: the cumulative L2
  norm of the per-step change of phi over the nodes where min(phi_a, psi) < 2h
  (the swept region plus a band), linearly interpolated between steps. This
  needs the total length, so the flow is run twice (measure, then replay);
  both passes are timed as separate stages.
- `rbf_warp`: a plain RBF warp of A's field from the feature points, no
  optimisation: y(x) = x + d(x), d = scipy RBFInterpolator (cubic kernel,
  degree 1) of the feature displacements. At time s a node z takes
  phi_a(x) where x + s d(x) = z, NOT blended with B, so s = 1 shows how far a
  warp of A alone is from B. The inverse is 6 Newton iterations with a
  finite-difference Jacobian I + s grad d, started from x = z - s d(z): plain
  fixed-point iteration x <- z - s d(x) diverges once s |grad d| > 1, which a
  90 degree rotation reaches (|R - I| = sqrt 2). Where the warp folds there is
  no inverse; the largest residual |x + s d(x) - z| is reported.
- `project`: this project's `keyframe_implicit.core.inbetween` (two-sided transport).
- `one_sided`: the same with ``transport="one-sided"``, the thesis's eq. 3.4 on A's
  nodes only (what this project did before the two-sided transport).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import RBFInterpolator

from keyframe_implicit.core.base.sampling import sample

__all__ = ["Run", "METHODS", "linear_blend", "morph_flow", "rbf_warp", "project", "one_sided", "one_iso",
           "torn"]


@dataclass
class Run:
    """Output of one method on one keyframe pair.

    frames : list of ndarray (grid.shape), the level sets at the requested times.
    seconds : dict stage -> wall seconds.
    mapped : ndarray grid.shape + (3,) or None, y(x) at every node where defined.
    info : dict of method-specific figures (iterations, residuals, ...).
    mapped_back : ndarray grid.shape + (3,) or None, the map B -> A where the method has one.
    paths : (forward, backward) or None, where the method moves material along paths:
        callables (points (P, 3), t) -> positions, A's from A (t = 0) to B (t = 1) and B's
        from B to A (None for a method without B's paths).
    cracks : (forward, backward) or None, the cells where each map tears (bool over the
        grid's cells, or None where it does not).
    """

    frames: list
    seconds: dict
    mapped: object = None
    info: dict = field(default_factory=dict)
    mapped_back: object = None
    paths: tuple = None
    cracks: tuple = None


def linear_blend(phi_a, phi_b, grid, features_a, features_b, times):
    """(1 - s) phi_a + s phi_b at every time."""
    t0 = time.perf_counter()
    frames = [(1.0 - s) * phi_a + s * phi_b for s in times]
    return Run(frames, {"frames": time.perf_counter() - t0})


# -- level-set morph flow ------------------------------------------------------
def _one_sided(phi, h):
    """Backward and forward differences along each axis, edge-replicated (zero slope at the box)."""
    out = []
    for ax in range(phi.ndim):
        d = np.diff(phi, axis=ax) / h
        pad = [(0, 0)] * phi.ndim
        pad_lo = list(pad)
        pad_lo[ax] = (1, 0)
        pad_hi = list(pad)
        pad_hi[ax] = (0, 1)
        out.append((np.pad(d, pad_lo), np.pad(d, pad_hi)))  # (D-, D+)
    return out


def godunov_norm(phi, h, speed_sign):
    """Godunov upwind |grad phi| for phi_t + F |grad phi| = 0, F of sign ``speed_sign``.

    F > 0: sum over axes of max(max(D-, 0)^2, min(D+, 0)^2); F < 0: the mirror.
    """
    pos = np.zeros(phi.shape)
    neg = np.zeros(phi.shape)
    for dm, dp in _one_sided(phi, h):
        pos += np.maximum(np.maximum(dm, 0.0) ** 2, np.minimum(dp, 0.0) ** 2)
        neg += np.maximum(np.minimum(dm, 0.0) ** 2, np.maximum(dp, 0.0) ** 2)
    return np.sqrt(np.where(speed_sign > 0, pos, neg))


def _morph_steps(phi_a, psi, h, band, tol, max_steps, mask):
    """Generator of (phi, increment) per step of the morph flow, until converged."""
    cfl = 0.3 / np.sqrt(3.0)
    phi = phi_a.copy()
    path, recent = 0.0, []
    for _ in range(max_steps):
        speed = phi - psi
        near = np.abs(phi) < band
        smax = float(np.max(np.abs(speed[near]))) if near.any() else 0.0
        if smax < tol:
            return
        if len(recent) >= 50 and sum(recent[-50:]) < 0.01 * path:
            return  # stationary: the last 50 steps moved < 1% of the path so far
        dt = min(cfl * h / smax, 0.5)  # CFL on the band; <= 0.5 keeps the relaxation stable
        speed = np.where(near, speed, 0.0)  # narrow band only, as OpenVDB's active voxels
        new = phi - dt * speed * godunov_norm(phi, h, speed)
        # one Sussman renormalisation step, smoothed sign of the pre-step field
        sgn = new / np.sqrt(new * new + h * h)
        new = new - 0.3 * h * sgn * (godunov_norm(new, h, sgn) - 1.0)
        inc = float(np.sqrt(np.sum((new - phi)[mask] ** 2)))
        phi = new
        path += inc
        recent.append(inc)
        yield phi, inc


def morph_flow(phi_a, phi_b, grid, features_a, features_b, times, tol=0.1, max_steps=4000):
    """OpenVDB-style level-set morph from phi_a to phi_b, frames at equal path fractions."""
    h = grid.spacing
    phi_a = np.asarray(phi_a, float)
    psi = np.asarray(phi_b, float)
    mask = np.minimum(phi_a, psi) < 2 * h
    t0 = time.perf_counter()
    incs = [inc for _, inc in _morph_steps(phi_a, psi, h, 3 * h, tol * h, max_steps, mask)]
    t1 = time.perf_counter()
    total = float(np.sum(incs))
    targets = np.asarray(times, float) * total
    frames = [None] * len(times)
    cum, prev = 0.0, phi_a
    for i, s in enumerate(times):
        if targets[i] <= 0.0:
            frames[i] = phi_a.copy()
    for phi, inc in _morph_steps(phi_a, psi, h, 3 * h, tol * h, max_steps, mask):
        for i in range(len(times)):
            if frames[i] is None and cum + inc >= targets[i] - 1e-12 * max(total, 1.0):
                w = (targets[i] - cum) / inc if inc > 0 else 1.0
                frames[i] = prev + np.clip(w, 0.0, 1.0) * (phi - prev)
        cum += inc
        prev = phi
    for i in range(len(times)):
        if frames[i] is None:
            frames[i] = prev.copy()
    t2 = time.perf_counter()
    band = np.abs(prev) < 3 * h
    resid = float(np.max(np.abs(prev - psi)[band]) / h) if band.any() else float("nan")
    return Run(frames, {"flow": t1 - t0, "replay": t2 - t1},
               info={"steps": len(incs), "final_band_residual_h": resid})


# -- plain RBF warp ------------------------------------------------------------
def rbf_warp(phi_a, phi_b, grid, features_a, features_b, times, iterations=6):
    """Warp of A's field along x + s d(x), d the cubic RBF of the feature displacements."""
    fa = np.asarray(features_a, float)
    fb = np.asarray(features_b, float)
    t0 = time.perf_counter()
    rbf = RBFInterpolator(fa, fb - fa, kernel="cubic", degree=1)
    z = grid.points().reshape(-1, 3)
    mapped = (z + rbf(z)).reshape(grid.shape + (3,))
    t1 = time.perf_counter()
    frames, resid = [], 0.0
    eps = 1e-3 * grid.spacing
    for s in times:
        x = z.copy()
        if s != 0.0:
            x = z - s * rbf(z)
            for _ in range(iterations):
                dx = rbf(x)
                r = x + s * dx - z
                jac = np.repeat(np.eye(3)[None], len(x), axis=0)
                for a in range(3):
                    xa = x.copy()
                    xa[:, a] += eps
                    jac[:, :, a] += s * (rbf(xa) - dx) / eps
                step = np.linalg.solve(jac, r[..., None])[..., 0]
                x = x - step
            resid = max(resid, float(np.max(np.linalg.norm(x + s * rbf(x) - z, axis=-1))))
        frames.append(sample(phi_a, grid, x, outside="distance").reshape(grid.shape))
    t2 = time.perf_counter()
    return Run(frames, {"fit": t1 - t0, "frames": t2 - t1}, mapped,
               info={"inverse_residual_h": resid / grid.spacing})


# -- this project --------------------------------------------------------------
def project(phi_a, phi_b, grid, features_a, features_b, times, **options):
    """keyframe_implicit.core.inbetween, frames from its ``.levelset(s)``."""
    from keyframe_implicit.core import inbetween

    t0 = time.perf_counter()
    res = inbetween(phi_a, phi_b, grid, features_a, features_b, **options)
    t1 = time.perf_counter()
    frames = [np.asarray(res.levelset(s), float) for s in times]
    t2 = time.perf_counter()
    info = {}
    for k, v in dict(getattr(res, "stats", {}) or {}).items():
        if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
            info[k] = float(v)
        elif isinstance(v, dict):
            for k2, v2 in v.items():
                if isinstance(v2, (int, float, np.integer, np.floating)) and not isinstance(v2, bool):
                    info[f"{k}.{k2}"] = float(v2)
    backward = None if res.backward is None else res.backward.trajectories
    cracks = tuple(None if m is None or m.tear is None else m.tear.crack
                   for m in (res.map_result, res.map_result_back))
    return Run(frames, {"map": t1 - t0, "frames": t2 - t1}, np.asarray(res.mapped, float), info,
               res.mapped_back, (res.trajectory, backward), cracks)


def one_sided(phi_a, phi_b, grid, features_a, features_b, times):
    """`project` with the thesis's one-sided transport."""
    return project(phi_a, phi_b, grid, features_a, features_b, times, transport="one-sided")


def one_iso(phi_a, phi_b, grid, features_a, features_b, times):
    """`project` with one iso-value per frame for the total volume, none per component
    (``volume_per_component=False``): what each component's own iso-value improves on."""
    return project(phi_a, phi_b, grid, features_a, features_b, times, volume_per_component=False)


def torn(phi_a, phi_b, grid, features_a, features_b, times):
    """`project` with maps that tear where they spread a component over several (``tear=True``,
    `map.tear`): a merge's backward map and a split's forward map in pieces."""
    return project(phi_a, phi_b, grid, features_a, features_b, times, tear=True)


METHODS = {"project": project, "one-sided": one_sided, "one-iso": one_iso, "torn": torn,
           "blend": linear_blend, "morph": morph_flow, "rbf": rbf_warp}
