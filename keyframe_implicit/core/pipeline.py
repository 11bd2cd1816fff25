"""Meshes + feature points + timeline frames -> one tracked mesh per frame.

This is the single entry point the Blender layer calls: it chooses a grid,
turns each keyframe mesh into a signed distance grid, solves the volume map
of every adjacent pair, and tracks one template mesh through all frames.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import numpy as np

from .progress import Reporter

__all__ = ["Keyframe", "Animation", "animate"]


@dataclass
class Keyframe:
    """One keyframe: a mesh in world space on a timeline frame.

    vertices : (V, 3) float array, world coordinates.
    faces : sequence of index sequences (triangles or polygons), or an (F, k) int array.
    frame : int, the timeline frame this shape must be matched on.
    """

    vertices: np.ndarray
    faces: object
    frame: int


@dataclass
class Animation:
    """Result of `animate`.

    frames : (n,) int array, every timeline frame from the first keyframe's to the last's.
    vertices : (n, V, 3) float32 array, the template's vertex positions on each frame.
    faces : (F, 3) int array, the template's triangles (the same on every frame).
    grid : the `Grid` used.
    stats : dict of figures (timings, solver iterations, volumes, uncovered area, ...), and
        ``quality``: per output ("shape_keys", "mesh_sequence") one dict of
        `quality.frame_quality` figures per frame (keyframe frames also carry
        `quality.keyframe_distance` to the keyframe mesh given), ``output`` /
        ``output_reason``: the output `quality.choose_output` picks.
    surfaces : list, per frame, of (V_f, 3) float32 vertices and (F_f, 3) int32 triangles:
        the frame's own surface (topology free), world units.
    velocities : list, per frame, of (V_f, 3) float32: velocity of every vertex of
        ``surfaces`` in world units per frame (the trajectories' rate, eq. 3.1).
    levelsets : list, per frame, of float32 arrays of grid.shape: the in-between level sets
        (eq. 3.4), kept when `animate` is called with ``levelsets=True``.
    """

    frames: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    grid: object
    stats: dict = field(default_factory=dict)
    surfaces: list = field(default_factory=list)
    velocities: list = field(default_factory=list)
    levelsets: list = field(default_factory=list)


_WEIGHT_NAMES = {"volume": "volume_weight", "rigidity": "rigidity_weight",
                 "levelset": "levelset_weight"}


def _physical_memory():
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # not on every platform
        return None


def _material_fraction(keyframe, grid):
    """Share of the grid box enclosed by a keyframe mesh (from its volume, before any grid work)."""
    from .sdf import triangulate
    from .surface import mesh_volume

    v = np.asarray(keyframe.vertices, dtype=float).reshape(-1, 3)
    try:
        vol = abs(mesh_volume(v, triangulate(keyframe.faces, len(v))))
    except ValueError:
        return 0.25  # mesh_to_sdf reports what is wrong with it; estimate_memory's default
    return float(min(1.0, vol / np.prod(grid.upper - grid.origin)))


def _check_inputs(keyframes, features):
    keyframes = list(keyframes)
    if len(keyframes) < 2:
        raise ValueError(f"Need at least two keyframes, got {len(keyframes)}: add another keyframe.")
    frames = [kf.frame for kf in keyframes]
    if any(int(f) != f for f in frames):
        raise ValueError(f"Keyframe frames must be whole numbers, got {frames}.")
    if any(b <= a for a, b in zip(frames, frames[1:])):
        raise ValueError(f"Keyframes must be on strictly increasing frames, got {frames}: "
                         "give each keyframe its own frame, in timeline order.")
    features = list(features)
    if len(features) != len(keyframes) - 1:
        raise ValueError(f"{len(keyframes)} keyframes need {len(keyframes) - 1} sets of feature "
                         f"pairs (one per segment), got {len(features)}.")
    clean = []
    for i, pair in enumerate(features):
        fa, fb = (np.asarray(p, dtype=float).reshape(-1, 3) for p in pair)
        if len(fa) != len(fb):
            raise ValueError(f"Segment {i}: {len(fa)} feature points on keyframe {i} but "
                             f"{len(fb)} on keyframe {i + 1}; every point needs a partner.")
        if not (np.all(np.isfinite(fa)) and np.all(np.isfinite(fb))):
            raise ValueError(f"Segment {i}: a feature point has a NaN or infinite coordinate.")
        clean.append((fa, fb))
    return keyframes, clean


def animate(keyframes, features, *, resolution=48, weights=None, progress=None, cancel=None,
            padding_cells=4, max_bytes=None, **options):
    """Bake a sequence of keyframes into one tracked mesh per timeline frame.

    Stages: `gridfit.fit_grid` (one grid holding every keyframe and feature point,
    refused before any work if it would not fit in memory), `sdf.mesh_to_sdf` per
    keyframe, then `chain.animate_chain` (per segment: `solver.solve_map`,
    trajectories, in-between level sets, and the template tracked through all frames).

    Parameters
    ----------
    keyframes : sequence of `Keyframe`, at least two, frames strictly increasing.
    features : sequence of (points_a, points_b) pairs, one per segment (keyframe i -> i+1);
        (N, 3) arrays in world units, row j of points_a pairs with row j of points_b.
    resolution : int, grid cells along the longest side of the keyframes' bounding box.
    weights : dict with optional keys "volume", "rigidity", "levelset" (the weights of
        the three terms of eq. 2.6).
    progress : callable(fraction, message), optional.
    cancel : callable() -> bool, optional; when it returns True, `Cancelled` is raised.
    padding_cells : int, empty cells around the keyframes' bounding box.
    max_bytes : int, optional memory limit for the bake; default: 75% of physical memory.
    **options : passed to `chain.animate_chain` (solver, trajectory and level-set options).

    Returns
    -------
    Animation

    Raises
    ------
    ValueError
        On input the user must fix (message says what), including
        `gridfit.MemoryLimitError` when the resolution is too high for this machine.
    Cancelled
        When ``cancel()`` returned True.
    """
    from .chain import animate_chain
    from .quality import choose_output
    from .gridfit import MemoryLimitError, check_memory, estimate_memory, fit_grid
    from .sdf import mesh_to_sdf

    t0 = time.perf_counter()
    rep = Reporter(progress, cancel)
    keyframes, features = _check_inputs(keyframes, features)
    opts = dict(options)
    for key, value in (weights or {}).items():
        if key not in _WEIGHT_NAMES:
            raise ValueError(f"Unknown weight {key!r}; use {sorted(_WEIGHT_NAMES)}.")
        opts[_WEIGHT_NAMES[key]] = float(value)
    if max_bytes is None:
        phys = _physical_memory()
        max_bytes = int(0.75 * phys) if phys else None

    rep(0.0, "Choosing the grid")
    extra = np.concatenate([np.concatenate(pair) for pair in features]) if features else None
    pts = [np.asarray(kf.vertices, dtype=float).reshape(-1, 3) for kf in keyframes]
    grid = fit_grid(pts, resolution, padding_cells=padding_cells, extra_points=extra)
    if max_bytes is not None:
        # refuse before any work; the largest keyframe's share of the box sets the solver's
        # and the trajectories' size (estimate_memory's model)
        mem = dict(n_keyframes=len(keyframes),
                   material_fraction=max(_material_fraction(kf, grid) for kf in keyframes))
        try:
            check_memory(grid, max_bytes, **mem)
        except MemoryLimitError as exc:
            def fits(r):
                g = fit_grid(pts, r, padding_cells=padding_cells, extra_points=extra)
                return estimate_memory(g, **mem)["peak"] <= max_bytes
            best = max((r for r in range(4, int(resolution)) if fits(r)), default=None)
            hint = (f"lower the resolution to {best} or less" if best else
                    "even the smallest grid does not fit: free memory or simplify the keyframes")
            raise MemoryLimitError(
                f"Resolution {resolution} would need about {exc.required / 2**20:,.0f} MB but "
                f"the limit is {max_bytes / 2**20:,.0f} MB: {hint}.",
                exc.required, max_bytes, best) from None
    stats = {"grid_shape": tuple(grid.shape), "grid_spacing": grid.spacing, "sdf": []}

    phis = []
    n = len(keyframes)
    for k, kf in enumerate(keyframes):
        sub = rep.sub(0.15 * k / n, 0.15 * (k + 1) / n)
        sub(0.0, f"Distance grid of keyframe {k + 1}/{n}")
        sdf_stats = {}
        try:
            phi = mesh_to_sdf(kf.vertices, kf.faces, grid, progress=sub, cancel=cancel,
                              stats=sdf_stats)
        except ValueError as exc:
            raise ValueError(f"Keyframe {k + 1} (frame {kf.frame}): {exc}") from exc
        if not np.any(phi < 0):
            raise ValueError(f"Keyframe {k + 1} (frame {kf.frame}) encloses no volume on the "
                             f"{grid.shape} grid: close the mesh or raise the resolution.")
        phis.append(phi)
        stats["sdf"].append(sdf_stats)
    stats["sdf_seconds"] = time.perf_counter() - t0

    chain = animate_chain(phis, grid, features, [kf.frame for kf in keyframes],
                          progress=rep.sub(0.15, 0.98), cancel=cancel, **opts)
    stats.update(chain.stats)
    if "quality" in stats:
        rep(0.98, "Measuring the keyframe frames")
        _measure_keyframes(stats["quality"], keyframes, chain, grid.spacing)
        stats["output"], stats["output_reason"] = choose_output(chain.frames, stats["quality"])
    stats["total_seconds"] = time.perf_counter() - t0
    rep(1.0, "Done")
    return Animation(frames=np.asarray(chain.frames, dtype=np.int64),
                     vertices=np.asarray(chain.vertices, dtype=np.float32),
                     faces=np.asarray(chain.faces, dtype=np.int64), grid=grid, stats=stats,
                     surfaces=chain.surfaces, velocities=chain.velocities,
                     levelsets=chain.levelsets)


def _measure_keyframes(quality, keyframes, chain, spacing):
    """Add the two-way distance to the keyframe mesh the artist gave on every keyframe frame."""
    from .quality import keyframe_distance
    from .sdf import triangulate

    for kf in keyframes:
        i = int(kf.frame - chain.frames[0])
        kv = np.asarray(kf.vertices, dtype=float).reshape(-1, 3)
        kt = triangulate(kf.faces, len(kv))
        quality["shape_keys"][i].update(keyframe_distance(chain.vertices[i], chain.faces, kv, kt,
                                                          spacing))
        quality["mesh_sequence"][i].update(keyframe_distance(*chain.surfaces[i], kv, kt, spacing))
