"""More than two keyframes played one after another, one template throughout.

Each adjacent pair (k, k+1) has its own feature points and its own map and
in-betweens (`levelset.inbetween`). The template mesh is the surface of the
first keyframe; it is carried through segment 0, and its vertices on the last
frame of segment k -- which lie on keyframe k+1's surface -- are the template
of segment k+1. So the frame of keyframe k shows the template on keyframe k's
surface, and vertex identity is kept across the whole animation.

Where topology changes one template cannot stay clean (PAPER-NOTES section
9), so every frame's own surface is also kept, with the velocity of its
vertices for motion blur, and both outputs are measured against it
(`quality`): the caller picks the output.

The thesis's own limitation remains (its chapter 5): there is no inertial
term, so velocities jump at every inner keyframe.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .grid import Grid
from .progress import Reporter
from .quality import frame_quality
from .surface import extract_surface
from .template import DetailTrack, _initial_template, track_template, uncovered_area

__all__ = ["animate_chain", "ChainResult"]


@dataclass
class ChainResult:
    """Result of `animate_chain`.

    frames : (n,) int array, every timeline frame from the first keyframe's to the last's.
    vertices : (n, V, d) float array, template vertices on every frame (world units).
    faces : (F, 3) int triangles (3D) or (E, 2) segments (2D), the same on every frame.
    stats : dict: ``segments`` (one dict per keyframe pair: map / trajectory / level-set
        figures), per-frame lists ``max_abs_phi``, ``uncovered_area``,
        ``uncovered_fraction``, and ``seconds``; with surfaces, ``quality``: per output
        ("shape_keys", "mesh_sequence") a list of `quality.frame_quality` dicts, one per frame.
    surfaces : list of (V_f, 3) float32 vertices and (F_f, 3) int32 triangles, each
        frame's own surface (empty when not asked for).
    velocities : list of (V_f, 3) float32, velocity of every vertex of ``surfaces`` in
        world units per frame.
    levelsets : list of float32 arrays of grid.shape, each frame's level set (when asked for).
    """

    frames: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    stats: dict = field(default_factory=dict)
    surfaces: list = field(default_factory=list)
    velocities: list = field(default_factory=list)
    levelsets: list = field(default_factory=list)


def animate_chain(phis, grid, features, frames, *, maps=None, coverage=True, surfaces=True,
                  levelsets=False, template=None, keyframe_meshes=None, progress=None,
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
    surfaces : bool
        3D only: also keep every frame's own surface (marching cubes of its
        level set) with its vertices' velocities (`Inbetween.velocity`), and
        measure both outputs against it (`quality.frame_quality`).
    levelsets : bool
        Also keep every frame's level set (float32, grid.shape), e.g. for a volume export.
    template : (vertices, faces), optional
        The mesh carried through the frames, lying on keyframe 0's surface (e.g. the
        artist's own mesh); default: marching cubes of ``phis[0]``.
    keyframe_meshes : sequence of (vertices, triangles), optional
        3D only: every keyframe's own mesh. The template then keeps its sub-cell detail
        and ends each segment on the next keyframe's mesh itself (`template.DetailTrack`),
        instead of on its grid's zero set; and each keyframe's frame in ``surfaces`` is
        that keyframe's own mesh, not its grid surface.
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
    if template is None:
        verts, faces = _initial_template(phis[0], grid)
    else:
        verts, faces = np.asarray(template[0]), np.asarray(template[1], dtype=np.int64)
    if keyframe_meshes is not None and len(keyframe_meshes) != nk:
        raise ValueError(f"keyframe_meshes must hold one mesh per keyframe ({nk}), "
                         f"got {len(keyframe_meshes)}.")
    out = np.empty((all_frames.size,) + verts.shape)
    stats = {"segments": [], "max_abs_phi": [], "uncovered_area": [], "uncovered_fraction": []}
    per_frame = surfaces and grid.dim == 3
    if per_frame:
        stats["quality"] = {"shape_keys": [], "mesh_sequence": []}
    meshes, velocities, fields = [], [], []
    for k in range(nk - 1):  # loop over segments (keyframe pairs)
        seg = rep.sub(k / (nk - 1), (k + 1) / (nk - 1))
        if maps is not None:
            inb = Inbetween.from_map(phis[k], phis[k + 1], grid, maps[k], cancel=cancel, **options)
        else:
            fa, fb = features[k]
            inb = inbetween(phis[k], phis[k + 1], grid, fa, fb, progress=seg.sub(0.0, 0.5),
                            cancel=cancel, **options)
        f0, f1 = frames[k], frames[k + 1]
        local = np.arange(f0 if k == 0 else f0 + 1, f1 + 1)
        frame_rep = seg.sub(0.5, 1.0)
        t_seg = time.perf_counter()
        detail = None if keyframe_meshes is None else DetailTrack(inb, verts,
                                                                  keyframe_meshes[k + 1])
        # loop over the segment's frames; each step of a frame is followed by a cancel check
        for i, f in enumerate(local):
            s = (f - f0) / float(f1 - f0)
            if detail is None:
                tr = track_template(inb, [s], template=(verts, faces), coverage=False)
                p, err = tr.vertices[0], tr.stats["max_abs_phi"][0]
            else:
                p, err = detail(s)
                err = float(err.max()) if err.size else 0.0
            out[f - frames[0]] = p
            stats["max_abs_phi"].append(err)
            frame_rep.check()
            if levelsets:
                fields.append(inb.levelset(s).astype(np.float32))
            if coverage or per_frame:
                ls = inb.levelset(s)
                surf = extract_surface(ls, grid)
                frame_rep.check()
            if coverage:
                unc, tot = uncovered_area(ls, grid, p, faces, surface=surf)
                stats["uncovered_area"].append(unc)
                stats["uncovered_fraction"].append(unc / tot if tot > 0 else 0.0)
                frame_rep.check()
            if per_frame:
                own = _frame_mesh(surf, keyframe_meshes, k, s)
                stats["quality"]["shape_keys"].append(frame_quality(ls, grid, p, faces, surf))
                stats["quality"]["mesh_sequence"].append(frame_quality(ls, grid, *own, surf))
                frame_rep.check()
                meshes.append((own[0].astype(np.float32), own[1].astype(np.int32)))
                step = 1.0 / float(f1 - f0)  # the neighbouring frames' paths are kept
                velocities.append((inb.velocity(own[0], s, ds=step) * step).astype(np.float32))
            frame_rep((i + 1) / local.size, f"frame {f} ({i + 1}/{local.size})")
        verts = out[local[-1] - frames[0]]
        stats["segments"].append(dict(inb.stats, template_seconds=time.perf_counter() - t_seg))
        del inb
    stats["seconds"] = time.perf_counter() - t0
    stats["vertices"] = int(len(verts))
    stats["faces"] = int(len(faces))
    return ChainResult(all_frames, out, faces, stats, meshes, velocities, fields)


def _frame_mesh(surface, keyframe_meshes, k, s):
    """A frame's own mesh for the mesh sequence: on a keyframe's frame (s = 0 of the first
    segment, s = 1 of every segment) the keyframe mesh the artist modelled, when given;
    else the frame's grid surface."""
    if keyframe_meshes is not None and (s == 1.0 or (s == 0.0 and k == 0)):
        v, tris = keyframe_meshes[k + int(s == 1.0)]
        return np.asarray(v, dtype=float).reshape(-1, 3), np.asarray(tris).reshape(-1, 3)
    return surface
