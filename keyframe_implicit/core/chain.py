"""More than two keyframes played one after another, one template throughout.

Each adjacent pair (k, k+1) has its own feature points and its own map and
in-betweens (`levelset.inbetween`). The template mesh is the surface of the
first keyframe; it is carried through segment 0, and its vertices on the last
frame of segment k -- which lie on keyframe k+1's surface -- are the template
of segment k+1. So the frame of keyframe k shows the template on keyframe k's
surface, and vertex identity is kept across the whole animation.

The thesis's own limitation remains (its chapter 5): there is no inertial
term, so velocities jump at every inner keyframe.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .grid import Grid
from .progress import Reporter
from .template import _initial_template, track_template

__all__ = ["animate_chain", "ChainResult"]


@dataclass
class ChainResult:
    """Result of `animate_chain`.

    frames : (n,) int array, every timeline frame from the first keyframe's to the last's.
    vertices : (n, V, d) float array, template vertices on every frame (world units).
    faces : (F, 3) int triangles (3D) or (E, 2) segments (2D), the same on every frame.
    stats : dict: ``segments`` (one dict per keyframe pair: map / trajectory / level-set
        figures), per-frame lists ``max_abs_phi``, ``uncovered_area``,
        ``uncovered_fraction``, and ``seconds``.
    """

    frames: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    stats: dict = field(default_factory=dict)


def animate_chain(phis, grid, features, frames, *, maps=None, coverage=True, progress=None,
                  cancel=None, **options):
    """Animate a chain of keyframes given as signed distance grids.

    Parameters
    ----------
    phis : sequence of ndarray, each grid.shape
        Signed distance grids of the keyframes, in timeline order (at least two).
    grid : Grid
        The grid all keyframes are sampled on.
    features : sequence of (points_a, points_b)
        One pair of (N, d) arrays per segment (keyframe k -> k+1): feature
        points on keyframe k and their targets on keyframe k+1. May be None
        when ``maps`` is given.
    frames : sequence of int
        Timeline frame of every keyframe, strictly increasing.
    maps : sequence of ndarray, optional
        One map y(x) (grid.shape + (d,)) per segment, used instead of solving
        (`solve_map`) -- for maps computed elsewhere or known in closed form.
    coverage : bool
        Measure each frame's surface area the template does not reach
        (one marching cubes per frame).
    progress, cancel : callables, optional (`progress.Reporter`).
    **options
        Passed to `levelset.inbetween` (solver weights and options, ``margin_cells``,
        ``resample``, ...) or to `Inbetween.from_map` when ``maps`` is given.

    Returns
    -------
    ChainResult
        ``vertices[i]`` is the template on timeline frame ``frames[0] + i``.
    """
    from .levelset import Inbetween, inbetween

    rep = Reporter(progress, cancel)
    if not isinstance(grid, Grid):
        raise ValueError("grid must be a keyframe_implicit.core.Grid.")
    phis = [grid.check_field(p, f"phis[{k}]") for k, p in enumerate(phis)]
    nk = len(phis)
    if nk < 2:
        raise ValueError(f"need at least two keyframes, got {nk}.")
    frames = np.asarray(frames)
    if frames.shape != (nk,) or not np.all(np.equal(np.mod(frames, 1), 0)):
        raise ValueError(f"frames must be {nk} integers, one per keyframe; got {frames!r}.")
    frames = frames.astype(np.int64)
    if np.any(np.diff(frames) <= 0):
        raise ValueError(f"keyframe frames must be strictly increasing; got {frames.tolist()}.")
    if maps is not None:
        if len(maps) != nk - 1:
            raise ValueError(f"maps must hold one map per segment ({nk - 1}), got {len(maps)}.")
    elif features is None or len(features) != nk - 1:
        raise ValueError(f"features must hold one (points_a, points_b) pair per segment "
                         f"({nk - 1}); got {0 if features is None else len(features)}.")

    t0 = time.perf_counter()
    all_frames = np.arange(frames[0], frames[-1] + 1)
    verts, faces = _initial_template(phis[0], grid)
    out = np.empty((all_frames.size,) + verts.shape)
    stats = {"segments": [], "max_abs_phi": [], "uncovered_area": [], "uncovered_fraction": []}
    for k in range(nk - 1):  # loop over segments (keyframe pairs)
        seg = rep.sub(k / (nk - 1), (k + 1) / (nk - 1))
        if maps is not None:
            inb = Inbetween.from_map(phis[k], phis[k + 1], grid, maps[k], **options)
        else:
            fa, fb = features[k]
            inb = inbetween(phis[k], phis[k + 1], grid, fa, fb, progress=seg.sub(0.0, 0.5),
                            cancel=cancel, **options)
        f0, f1 = frames[k], frames[k + 1]
        local = np.arange(f0 if k == 0 else f0 + 1, f1 + 1)
        times = (local - f0) / float(f1 - f0)
        tr = track_template(inb, times, template=(verts, faces), coverage=coverage,
                            progress=seg.sub(0.5, 1.0), cancel=cancel)
        out[local - frames[0]] = tr.vertices
        verts = tr.vertices[-1]
        for key in ("max_abs_phi", "uncovered_area", "uncovered_fraction"):
            stats[key].extend(tr.stats[key])
        stats["segments"].append(dict(inb.stats, template_seconds=tr.stats["seconds"]))
        del inb
    stats["seconds"] = time.perf_counter() - t0
    stats["vertices"] = int(len(verts))
    stats["faces"] = int(len(faces))
    return ChainResult(all_frames, out, faces, stats)
