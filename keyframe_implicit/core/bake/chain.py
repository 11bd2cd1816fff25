"""More than two keyframes played one after another, one template throughout.

Each adjacent pair (k, k+1) has its own feature points and its own map and
in-betweens (`maps.inbetween`). The maps of different pairs do not depend on
each other: with a helper process they are solved two segments at a time
(`maps.solve_maps_shared`).

The template mesh is the surface of the first keyframe; it is carried through
segment 0, and its vertices on the last frame of segment k -- which lie on
keyframe k+1's surface -- are the template of segment k+1. So the frame of
keyframe k shows the template on keyframe k's surface, and vertex identity is
kept across the whole animation.

Where topology changes one template cannot stay clean (docs/method.md, section
9), so every frame's own surface is also kept, with the velocity of its
vertices for motion blur, and both outputs are measured against it
(`quality`): the caller picks the output. With the artist's meshes, each segment also
tracks its keyframes' own meshes into it (`_keyframe_tracks`): where the template has
stopped following, the mesh sequence shows the artist's mesh again next to a keyframe.

Each segment alone would move every point on a path of its own, its velocity
jumping at every inner keyframe (the thesis's limitation, its chapter 5). By
default the paths bend so that it does not (`spline`, docs/method.md, section
12): every map is solved first, then each segment's paths read its neighbours'.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.grid import Grid
from ..base.parallel import Helper, one_blas_thread, release_memory
from ..base.progress import Reporter
from ..fields.measure import read_mesh
from ..surface.quality import LIMITS, failures, flipped_fraction, frame_quality
from ..surface.extract import extract_surface, material_topology, piece_volumes
from ..surface.options import SurfaceOptions
from .animation import Animation, KeyframeTrack
from .options import BakeOptions, refuse_unread
from .cache import content_key, grid_key
from .steps import FRAMES, MAPS, PATHS
from ..surface.template import DetailTrack, initial_template, track_template, uncovered_area
from ..motion.spline import (bends_needed, chain_bends, check_key_interpolation,
                             velocities_needed)

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Mapping, Sequence

    from numpy.typing import ArrayLike

    from ..map.options import MapOptions
    from ..motion.levelset import Inbetween, Recipe
    from ..motion.options import MotionOptions
    from .cache import WorkCache

__all__ = ["animate_chain", "Chain", "Inbetweens", "Kept", "frame_mesh", "tracked_frames",
           "TRACKED_LIMITS", "HELPER_PRELOAD"]

#: What a helper process imports as it starts: everything a chain's work sends it.
HELPER_PRELOAD = (__name__,)


def animate_chain(phis: Sequence[ArrayLike], grid: Grid,
                  features: Sequence[Sequence[ArrayLike]] | None, frames: ArrayLike, *,
                  maps: Sequence[ArrayLike] | None = None,
                  template: tuple[ArrayLike, ArrayLike] | None = None,
                  keyframe_meshes: Sequence[tuple[ArrayLike, ArrayLike]] | None = None,
                  helper: Helper | None = None, motion_grid: Grid | None = None,
                  progress: Callable[[float, str], object] | None = None,
                  cancel: Callable[[], bool] | None = None, **options: Any) -> Animation:
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
    template : (vertices, faces), optional
        The mesh carried through the frames, lying on keyframe 0's surface (e.g. the
        artist's own mesh); default: marching cubes of ``phis[0]``.
    keyframe_meshes : sequence of (vertices, triangles), optional
        3D only: every keyframe's own mesh. The template then keeps its sub-cell detail
        and ends each segment on the next keyframe's mesh itself (`template.DetailTrack`),
        instead of on its grid's zero set; and each keyframe's frame in the surfaces kept
        is that keyframe's own mesh, not its grid surface.
    helper : `parallel.Helper`, optional
        The helper to use instead of the one ``processes=2`` starts (its caller closes it).
    motion_grid : Grid, optional
        The coarser grid the maps and trajectories are solved on (`gridfit.motion_grid`;
        ``maps`` are then given on it); None: on ``grid``.
    progress, cancel : callables, optional (`progress.Reporter`).
    **options
        The options a chain reads (`options.BakeOptions.from_keywords`, whose fields hold
        the defaults), checked before any work:

        - ``key_interpolation``: per keyframe, how the motion passes it
          (`spline.KEY_INTERPOLATIONS`): "smooth" (continuous velocity, natural first and
          last keyframes), "linear" (each segment on its own, a corner) or "ease" (coming
          to rest). Where any segment's paths bend (`spline.bends_needed`), every map is
          solved before the first segment's frames, since a segment's paths read its
          neighbours' (docs/method.md, section 12);
        - ``processes``: 1, everything in this process (the two maps, and the two
          transports of each frame, in two threads); 2 or more, one helper process
          (`parallel.Helper`) shares the maps of every two segments with this process,
          each taking the next when it is free (`maps.solve_maps_shared`), and makes the
          later half of each segment's frames. Either way BLAS keeps to one thread in
          this process while the chain runs (`parallel.one_blas_thread`);
        - ``coverage``, ``surfaces``, ``levelsets``, ``output``: what each frame yields
          (`surface.options.SurfaceOptions`; ``surfaces`` only in 3D);
        - the fields of `map.options.MapOptions` (``volume_weight``, ``margin_cells``,
          ...) and of `motion.options.MotionOptions` (``transport``, ``resample``, ...).

    Returns
    -------
    `animation.Animation`
        ``vertices[i]`` is the template on timeline frame ``frames[0] + i``.
    """
    refuse_unread(options, BakeOptions.stage_names() | {"key_interpolation", "processes"},
                  "animate_chain")
    chain = Chain(phis, grid, features, frames, BakeOptions.from_keywords(**options), maps=maps,
                  template=template, keyframe_meshes=keyframe_meshes, motion_grid=motion_grid,
                  cancel=cancel)
    return chain.run(helper, progress)


class Chain:
    """A chain's inputs checked and ready to run: all its segments in timeline order
    (`run`), or one segment at a time (`segment`), given the template it starts from
    (`end_template` gives it; a render farm runs them so).

    The parameters are `animate_chain`'s, the options as one `options.BakeOptions`, of
    which the chain reads the key interpolation, the processes and the three stages'
    options; and ``cache`` (`cache.WorkCache`), where the pairs' maps are looked for before
    they are solved and kept once they are (`Inbetweens`).
    """

    def __init__(self, phis: Sequence[ArrayLike], grid: Grid,
                 features: Sequence[Sequence[ArrayLike]] | None, frames: ArrayLike,
                 options: BakeOptions, *, maps: Sequence[ArrayLike] | None = None,
                 template: tuple[ArrayLike, ArrayLike] | None = None,
                 keyframe_meshes: Sequence[tuple[ArrayLike, ArrayLike]] | None = None,
                 motion_grid: Grid | None = None,
                 cancel: Callable[[], bool] | None = None, cache: WorkCache | None = None) -> None:
        phis, self.frames = _checked_chain(phis, grid, frames, maps, features, keyframe_meshes)
        kinds = check_key_interpolation(options.key_interpolation, len(phis))
        self.options, self.cancel = options, cancel
        self._given_template, self._first_phi, self.grid = template, phis[0], grid
        self.keyframe_meshes = keyframe_meshes
        self.volumes = None if keyframe_meshes is None or grid.dim != 3 else [
            _modelled_volume(*mesh) for mesh in keyframe_meshes]
        self.outputs = dataclasses.replace(
            options.surface, surfaces=options.surface.surfaces and grid.dim == 3)
        self.inbetweens = Inbetweens(phis, grid, features, maps, options.map,
                                     options.segment_motion(len(phis) - 1), cancel,
                                     motion_grid, (self.frames, kinds), self.volumes, cache)

    @functools.cached_property
    def template(self) -> tuple:
        """(vertices, faces) of the mesh carried through the frames on the first keyframe:
        the one given, else marching cubes of the first keyframe's field (made when first
        asked for: the live preview never asks)."""
        given = self._given_template
        if given is None:
            return initial_template(self._first_phi, self.grid)
        return np.asarray(given[0]), np.asarray(given[1], dtype=np.int64)

    def run(self, helper: Helper | None = None,
            progress: Callable[[float, str], object] | None = None) -> Animation:
        """Every segment's frames in timeline order: `animate_chain`'s result. ``helper``
        is used instead of starting one (``processes`` > 1) and left running."""
        rep = Reporter(progress, self.cancel)
        t0 = time.perf_counter()
        frames, nk = self.frames, len(self.frames)
        verts, faces = self.template
        kept = Kept(np.arange(frames[0], frames[-1] + 1), verts.shape, self.outputs)
        own = helper is None and self.options.processes > 1
        blas = one_blas_thread()
        try:
            if own:
                helper = Helper(HELPER_PRELOAD)
            for k in range(nk - 1):  # loop over segments (keyframe pairs)
                local, records, stats = self.segment(
                    k, verts, helper, rep.sub(k / (nk - 1), (k + 1) / (nk - 1)))
                kept.add(local - frames[0], records)
                verts = kept.vertices[local[-1] - frames[0]]
                kept.stats["segments"].append(stats)
                if k < nk - 2:  # the next segment's arrays then do not stack on this one's
                    release_memory()
        finally:
            blas.restore_original_limits()
            if helper is not None:
                kept.stats["helper_peak_rss_kib"] = helper.peak_rss_kib()
            if own and helper is not None:
                helper.close()
        return kept.animation(self, time.perf_counter() - t0)

    def _segment(self, k, start):
        """`Segment` ``k`` starting from the template's vertices ``start``, and its frames."""
        f0, f1 = self.frames[k], self.frames[k + 1]
        local = np.arange(f0 if k == 0 else f0 + 1, f1 + 1)
        return Segment(k, (f0, f1), (start, self.template[1]), self.keyframe_meshes,
                       self.outputs, _pair(self.volumes, k)), local

    def segment(self, k: int, start: np.ndarray, helper: Helper | None, rep: Reporter
                ) -> tuple[np.ndarray, list[dict[str, Any]], dict[str, Any]]:
        """Segment ``k``'s frames from the template's vertices ``start`` on its first frame:
        (timeline frames, one record per frame (`_frames`), the segment's figures). The
        first segment begins on the first keyframe's frame, every other one a frame after
        its first keyframe (the previous segment's last frame)."""
        segment, local = self._segment(k, start)
        split = FrameSplit(helper, local, segment)
        inb = self.inbetweens.make(k, helper, split, rep)
        t0 = time.perf_counter()
        records = split.run(inb, rep.sub(0.5, 1.0))
        return local, records, dict(inb.stats, template_seconds=time.perf_counter() - t0)

    def end_template(self, k: int, start: np.ndarray) -> np.ndarray:
        """The template's vertices on segment ``k``'s last frame (s = 1) from ``start`` on
        its first: the next segment's ``start``, without making its frames."""
        segment, _ = self._segment(k, start)
        inb = self.inbetweens.make(k, None, None, Reporter())
        return _template(inb, segment, _detail(inb, segment), 1.0)["vertices"]


def _pair(volumes, k):
    """Segment ``k``'s two keyframe volumes as modelled, or None where either is unknown."""
    pair = None if volumes is None else tuple(volumes[k:k + 2])
    return None if pair is None or None in pair else pair


def _modelled_volume(vertices, triangles):
    """The volume a keyframe mesh encloses as modelled (`measure.read_mesh`), or None when
    it has holes or edges of three faces or more: its volume then depends on how it is
    read, and the grid's reading is the one to hold."""
    reading = read_mesh(vertices, triangles)
    closed = not (reading.open_edges or reading.shared_edges or reading.non_orientable)
    return reading.volume if closed else None


def _checked_chain(phis, grid, frames, maps, features, keyframe_meshes):
    """`animate_chain`'s keyframe fields (checked against ``grid``) and frames (int64), or
    ValueError saying which input to fix."""
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
    if keyframe_meshes is not None and len(keyframe_meshes) != nk:
        raise ValueError(f"keyframe_meshes must hold one mesh per keyframe ({nk}), "
                         f"got {len(keyframe_meshes)}.")
    return phis, frames


class Inbetweens:
    """Each segment's `levelset.Inbetween`, as `animate_chain` gets its maps: given
    (``maps``), solved with a helper a window of segments at a time
    (`maps.solve_maps_shared`), or solved in this process (`maps.pair_inbetweens`).

    When the paths bend through the keyframes (``timing``: the keyframes' frames and
    `spline.KEY_INTERPOLATIONS`), every map is solved first, then every segment's `Bend`s
    made from its neighbours' paths (`spline.chain_bends`), then the segments one by one.

    ``solved`` ({segment: (map A -> B, map B -> A, seconds)}) and ``bends`` ({segment:
    its `Bend`s}) may be filled beforehand with what was solved elsewhere (a farm's
    earlier tasks): a segment found there is not solved again.

    ``volumes`` (per keyframe, its mesh's volume as modelled or None) are held by each
    segment's in-betweens where both of its keyframes' are known
    (`levelset.Inbetween.hold_volumes`).

    With a ``cache`` (`cache.WorkCache`) a segment's maps are taken from it when it holds
    those of the same inputs (`map_key`), and kept there once solved; ``reused`` counts the
    segments taken.
    """

    def __init__(self, phis: Sequence[np.ndarray], grid: Grid,
                 features: Sequence[Sequence[ArrayLike]] | None,
                 maps: Sequence[ArrayLike] | None, map_options: MapOptions,
                 segment_motion: Sequence[MotionOptions],
                 cancel: Callable[[], bool] | None = None,
                 motion_grid: Grid | None = None,
                 timing: tuple[np.ndarray, Sequence[str]] | None = None,
                 volumes: Sequence[float | None] | None = None,
                 cache: WorkCache | None = None) -> None:
        # the maps and the in-betweens are imported when first needed: this module is the
        # helper's preload and the live preview's import, which the motion stage (scipy.ndimage,
        # scikit-image) would slow
        from .maps import solve_fields

        self.phis, self.grid, self.features, self.maps = phis, grid, features, maps
        self.cancel, self.motion_grid = cancel, motion_grid
        self.solve_phis = solve_fields(phis, grid, motion_grid) if maps is None else None
        self.map_options, self.segment_motion = map_options, tuple(segment_motion)
        self.motion_options = self.segment_motion[0]  # what every segment's options share
        self.solved = {}  # segment -> its maps, solved ahead in a window
        self.timing = timing
        self.bends = None if timing is None or not bends_needed(timing[1]) else {}
        self.volumes = volumes
        self.cache, self.reused = (cache if maps is None else None), 0

    def map_key(self, k: int) -> str:
        """What segment ``k``'s maps depend on (`cache.content_key`): its keyframes' distance
        grids, the grid and motion grid, its feature pairs, the map options on the grid the
        maps are solved on and whether the map B -> A is solved too. Not the timing: the
        bends are made from the maps."""
        from .maps import on_solve_grid

        solve_grid = self.grid if self.motion_grid is None else self.motion_grid
        fa, fb = (np.asarray(f, dtype=np.float64) for f in self.features[k])
        return content_key("maps", self.phis[k], self.phis[k + 1], grid_key(self.grid),
                           grid_key(self.motion_grid), fa, fb,
                           on_solve_grid(self.map_options, self.grid, solve_grid),
                           self.motion_options.two_sided)

    def make(self, k: int, helper: Helper | None, split: FrameSplit | None,
             rep: Reporter) -> Inbetween:
        """Segment ``k``'s in-betweens, holding its keyframes' volumes as modelled where
        known; ``split`` (`FrameSplit`, or None when no other process makes frames) hears
        of them as soon as their recipe is known; progress to 0.5 of ``rep``."""
        inb = self._make(k, helper, split, rep)
        _hold_volumes(inb, _pair(self.volumes, k))
        return inb

    def _make(self, k, helper, split, rep):
        """`make` but for the volumes held."""
        from ..motion.levelset import Inbetween
        from .maps import from_solved, pair_inbetweens

        a, b, cancel = self.phis[k], self.phis[k + 1], self.cancel
        on_maps = None if split is None else split.start
        if self.bends is not None:
            return self._make_bent(k, helper, on_maps, rep)
        if self.maps is not None:
            return Inbetween.from_map(a, b, self.grid, self.maps[k], cancel=cancel,
                                      options=self.segment_motion[k],
                                      motion_grid=self.motion_grid)
        if helper is None and k not in self.solved and self.cache is None:
            return pair_inbetweens(a, b, self.grid, self.features[k], self.map_options,
                                   self.segment_motion[k], progress=rep.sub(0.0, 0.5),
                                   cancel=cancel, on_maps=on_maps,
                                   motion_grid=self.motion_grid)
        if k not in self.solved:
            window = 1 if helper is None else _MAP_WINDOW  # one process: a segment at a time
            self.solve(range(k, min(k + window, len(self.phis) - 1)), helper, rep.sub(0.0, 0.4))
        res, back, seconds = self.solved.pop(k)
        with rep.sub(0.4, 0.5).step(PATHS, 0, 1):
            return from_solved(a, b, self.grid, res, back, self.segment_motion[k], seconds,
                               on_maps=on_maps, cancel=cancel)

    def solve(self, window: Iterable[int], helper: Helper | None, rep: Reporter) -> None:
        """The maps of the segments in ``window``, into ``solved``: those the cache holds
        taken from it, the others solved and kept there."""
        from .maps import on_solve_grid, solve_maps_shared

        window = [k for k in window if k not in self.solved]  # given, or solved before
        keys = {k: self.map_key(k) for k in window} if self.cache is not None else {}
        for k, key in keys.items():
            kept = self.cache.get(key)
            if kept is not None:
                self.solved[k] = kept + (0.0,)  # (map A -> B, map B -> A, seconds here)
                self.reused += 1
                rep.elsewhere(MAPS, 2 if self.motion_options.two_sided else 1)
        window = [k for k in window if k not in self.solved]
        if not window:
            return
        solve_grid = self.grid if self.motion_grid is None else self.motion_grid
        solved = solve_maps_shared(
            self.solve_phis, solve_grid, self.features, window, self.motion_options.two_sided,
            helper, rep, self.cancel, on_solve_grid(self.map_options, self.grid, solve_grid))
        for k in solved if self.cache is not None else ():
            self.cache.put(keys[k], solved[k][:2])
        self.solved.update(solved)

    def _make_bent(self, k, helper, on_maps, rep):
        """`make` with the paths bent through the keyframes: on the first segment every
        map and every `Bend` is made (to 0.4 of ``rep``)."""
        from ..motion.levelset import Inbetween
        from .maps import from_solved

        if not self.bends:
            self.bend_all(helper, rep.sub(0.0, 0.4))
        a, b, cancel = self.phis[k], self.phis[k + 1], self.cancel
        if self.maps is not None:
            return Inbetween.from_map(a, b, self.grid, self.maps[k], cancel=cancel,
                                      mapped_back=self._back[k], bends=self.bends[k],
                                      options=self.segment_motion[k], motion_grid=self.motion_grid)
        res, back, seconds = self.solved.pop(k)
        with rep.sub(0.4, 0.5).step(PATHS, 0, 1):
            return from_solved(a, b, self.grid, res, back, self.segment_motion[k], seconds,
                               on_maps=on_maps, cancel=cancel, bends=self.bends[k])

    def bend_all(self, helper: Helper | None, rep: Reporter) -> None:
        """Every segment's maps (solved or given), the velocities of the paths that meet at
        the keyframes (`spline.velocities_needed`, two at a time: one per core), and every
        segment's `Bend`s (the maps to 0.7 of ``rep``, the rest one `PATHS` step)."""
        nseg = len(self.phis) - 1
        common = dict(motion_grid=self.motion_grid, options=self.motion_options,
                      cancel=self.cancel)
        if self.maps is None:
            self.solve(range(nseg), helper, rep.sub(0.0, 0.7))
            solved = [self.solved[k] for k in range(nseg)]
            forward = [res.mapped for res, _, _ in solved]
            ends = [dict(material=res.material, components=res.components, parts=res.parts)
                    for res, _, _ in solved]
            back = [None if b is None else b.mapped for _, b, _ in solved]
            back_parts = [None if b is None else b.parts for _, b, _ in solved]
        else:
            forward, ends = list(self.maps), [{} for _ in range(nseg)]
            back, back_parts = [None] * nseg, [None] * nseg
        with rep.sub(0.7, 1.0).step(PATHS, 0, 1):
            self._bend(forward, back, ends, back_parts, common)

    def _bend(self, forward, back, ends, back_parts, common):
        """`bend_all` once the maps are known: the maps B -> A a one-sided solve lacks (by
        inversion), the paths' velocities at the keyframes and every segment's bends
        (``back_parts``: the parts each map B -> A keeps apart, or None)."""
        from ..motion.levelset import back_map, path_start_velocity

        nseg = len(self.phis) - 1
        for k in range(nseg):  # given maps, or a one-sided solve: B -> A by inversion
            if back[k] is None:
                back[k] = back_map(self.phis[k], self.phis[k + 1], self.grid, forward[k],
                                   **ends[k], **common)
        self._back = back

        def velocity(job):
            k, side = job
            if side == "forward":
                return path_start_velocity(self.phis[k], self.grid, forward[k], **ends[k],
                                           **common)
            return path_start_velocity(self.phis[k + 1], self.grid, back[k],
                                       parts=back_parts[k], **common)

        jobs = velocities_needed(self.timing[1])
        with ThreadPoolExecutor(max_workers=2) as pool:  # independent: one per core
            velocities = dict(zip(jobs, pool.map(velocity, jobs)))
        solve_grid = self.grid if self.motion_grid is None else self.motion_grid
        self.bends.update(enumerate(chain_bends(solve_grid, *self.timing, forward, back,
                                                velocities)))


class Kept:
    """What `animate_chain` keeps of every frame's record (`_frames`): the template's
    vertices, the per-frame figures in ``stats`` (the quality figures of the outputs
    measured, `SurfaceOptions.measured`), and as ``outputs`` (`SurfaceOptions`) asks the
    level sets, the frames' own meshes and their velocities, and the keyframe tracks'
    figures (`_track_figures`, by name and row; on keyframe k's row, those of the track
    that begins there come with its segment's first frame's record)."""

    def __init__(self, frames: np.ndarray, template_shape: tuple[int, ...],
                 outputs: SurfaceOptions) -> None:
        self.frames, self.outputs = frames, outputs
        self.vertices = np.empty((frames.size,) + tuple(template_shape))
        self.stats = {"segments": [], "max_abs_phi": [], "steered": [], "uncovered_area": [],
                      "uncovered_fraction": []}
        if outputs.surfaces:
            self.stats["quality"] = {name: [] for name in outputs.measured}
            self.stats["topology"], self.stats["volumes"], self.stats["flipped"] = [], [], []
        self.meshes, self.velocities, self.fields = [], [], []
        self.tracks: dict[str, dict[int, dict[str, Any]]] = {
            "from_start": {}, "from_end": {}, "from_start_key": {}}

    def add(self, rows: Iterable[int], records: Iterable[dict[str, Any]]) -> None:
        """Keep ``records``, those of the frames at ``rows`` of ``frames``, in order."""
        outputs, st = self.outputs, self.stats
        for row, rec in zip(rows, records):
            self.vertices[row] = rec["vertices"]
            st["max_abs_phi"].append(rec["max_abs_phi"])
            st["steered"].append(rec["steered"])
            if outputs.levelsets:
                self.fields.append(rec["levelset"])
            if outputs.coverage:
                st["uncovered_area"].append(rec["uncovered"][0])
                st["uncovered_fraction"].append(rec["uncovered"][1])
            if outputs.surfaces:
                for name in outputs.measured:
                    st["quality"][name].append(rec[name])
                st["topology"].append(rec["topology"])
                st["volumes"].append(rec["volumes"])
                st["flipped"].append(rec["flipped"])
            if outputs.keeps_meshes:
                self.meshes.append(rec["mesh"])
                self.velocities.append(rec["velocity"])
            for name, kept in self.tracks.items():
                if name in rec:
                    kept[row - (name == "from_start_key")] = rec[name]

    def animation(self, chain: Chain, seconds: float) -> Animation:
        """The `animation.Animation` of the frames kept, ``chain`` (`Chain`) their source."""
        verts, faces = self.vertices[-1], chain.template[1]
        self.stats.update(seconds=seconds, vertices=int(len(verts)), faces=int(len(faces)))
        return Animation(self.frames, self.vertices, faces, chain.inbetweens.grid, self.stats,
                         self.meshes, self.velocities, self.fields,
                         keyframe_tracks=self._keyframe_tracks(chain))

    def _keyframe_tracks(self, chain: Chain) -> list[KeyframeTrack]:
        """The `animation.KeyframeTrack`s whose figures were kept, segment by segment:
        keyframe k's mesh forward over rows k .. k + 1 of its segment, and keyframe
        k + 1's back over rows k + 1 .. k (keyframe k's own row is the segment before's)."""
        rows = [int(f - self.frames[0]) for f in chain.frames]
        out = []
        for k in range(len(rows) - 1):
            for name, key in (("from_start", k), ("from_end", k + 1)):
                kept, span = self.tracks[name], range(rows[k] + 1, rows[k + 1] + 1)
                records = [kept.get(r) for r in span]
                if name == "from_start":  # the segment before holds keyframe k's own row
                    span = range(rows[k], rows[k + 1] + 1)
                    records.insert(0, self.tracks["from_start_key"].get(rows[k]))
                if any(r is None for r in records):
                    continue
                tris = np.asarray(chain.keyframe_meshes[key][1], dtype=np.int64).reshape(-1, 3)
                out.append(KeyframeTrack(rows[key], span[0], tris,
                                         np.stack([r["vertices"] for r in records]),
                                         [{n: v for n, v in r.items() if n != "vertices"}
                                          for r in records]))
        return out


#: Segments whose maps are solved together when there is a helper
#: (`maps.solve_maps_shared`). Each segment's maps are kept until its frames are made,
#: so the window bounds how many are held.
_MAP_WINDOW = 2


@dataclass(frozen=True)
class Segment:
    """What making segment ``k``'s frames needs besides its in-betweens: the keyframes'
    timeline frames ``ends``, the ``template`` (vertices, faces) on its first frame, every
    keyframe's own mesh (or None), what to keep of each frame, and the ``volumes`` of its
    two keyframes' meshes as modelled (`_modelled_volume`), which its in-betweens hold
    (None: their grids')."""

    k: int
    ends: tuple
    template: tuple
    keyframe_meshes: list | None
    outputs: SurfaceOptions
    volumes: tuple | None = None


class FrameSplit:
    """One segment's frames (`_frames`), the later half in a ``helper`` process when there
    is one (and at least 4 frames) while this process does the first half.

    `start` hands the helper its half as soon as the in-betweens' `levelset.Recipe` is
    known, so that it builds its copy of the trajectories while this process builds its
    own; `run` starts it then if it was not started before.

    A keyframe's own frame (s = 0, 1) adds no work of its own: its level set is the
    keyframe's field, and the paths its velocity needs are its neighbours' (s = 0 solves
    them first). So the split halves the in-betweens, the odd one to this process.
    """

    def __init__(self, helper: Helper | None, frames: np.ndarray, segment: Segment) -> None:
        self.helper = helper if helper is not None and len(frames) >= 4 else None
        self.frames, self.segment = frames, segment
        ends = segment.ends
        inner = (frames > ends[0]) & (frames < ends[1])
        self.half = int(np.count_nonzero(frames <= ends[0])) + (int(inner.sum()) + 1) // 2
        self.started = False

    def start(self, inbetweens: Inbetween | Recipe) -> None:
        """Submit the later half to the helper (``inbetweens`` an `Inbetween` or its recipe)."""
        if self.helper is not None and not self.started:
            self.helper.submit(_half, inbetweens, self.frames[self.half:], self.segment)
            self.started = True

    def run(self, inb: Inbetween, rep: Reporter) -> list[dict[str, Any]]:
        """Every frame's record, in order."""
        if self.helper is None:
            return _frames(inb, self.frames, self.segment, rep)
        self.start(inb)
        n, half = len(self.frames), self.half
        first = _half(inb, self.frames[:half], self.segment, rep.sub(0.0, half / n),
                      alongside=n - half - 1)
        rest = self.helper.result(check=rep.check)
        rep.elsewhere(FRAMES)  # the helper's last frame, counted once it is there
        return first + rest


def _half(inb, frames, segment, rep=None, alongside=0):
    """`_frames` in one of the two processes that share a segment's frames: each has one
    core, so its two transports carry one after the other (`Inbetween.threads`)."""
    inb.threads = 1
    return _frames(inb, frames, segment, rep, alongside)


def _frames(inb, frames, segment, rep=None, alongside=0):
    """Each timeline frame of a `Segment` as a dict: the template's ``vertices`` and
    ``max_abs_phi``; as its ``outputs`` ask, the ``levelset`` (float32), the ``uncovered``
    area and fraction, the quality of the outputs measured (``shape_keys``,
    ``mesh_sequence``: `SurfaceOptions.measured`), and the frame's own ``mesh`` with its
    ``velocity`` (world units per frame) where the mesh sequence is made.

    Each frame is a `FRAMES` step of ``rep``. ``alongside`` frames of the segment are made
    by another process meanwhile (`FrameSplit`): they are counted (`Reporter.elsewhere`)
    in step with these, as they are about as far."""
    rep = rep or Reporter()
    (f0, f1), k = segment.ends, segment.k
    _hold_volumes(inb, segment.volumes)  # a helper's in-betweens are made from the recipe
    detail, tracks = _detail(inb, segment), _keyframe_tracks(inb, segment)
    records = []
    for i, f in enumerate(frames):  # loop over frames; each step is followed by a cancel check
        s = (f - f0) / float(f1 - f0)
        with rep.step(FRAMES, i, len(frames)) as part:
            rec = _template(inb, segment, detail, s)
            part.check()
            rec.update(_frame_outputs(inb, s, segment, rec["vertices"], part, tracks))
            if "from_start" in tracks and f == f0 + 1:  # its figures on keyframe k's frame
                rec["from_start_key"] = _track_figures(inb, 0.0, tracks["from_start"], 0.0,
                                                       part)
        records.append(rec)
        rep.elsewhere(FRAMES, (i + 1) * alongside // len(frames) - i * alongside // len(frames))
    return records


def _hold_volumes(inb, volumes):
    """Have the in-betweens hold their keyframes' ``volumes`` as modelled, where known and
    kept (`levelset.Inbetween.hold_volumes`): a thin part's grid holds a fifth less or more."""
    if volumes is not None and inb.keep_volume:
        inb.hold_volumes(volumes)


def _detail(inb, segment):
    """The `template.DetailTrack` of a segment that ends on a keyframe's own mesh, else None."""
    meshes = segment.keyframe_meshes
    if meshes is None:
        return None
    return DetailTrack(inb, *segment.template, meshes[segment.k + 1])


def _keyframe_tracks(inb, segment):
    """The `template.DetailTrack`s of segment k's keyframes' own meshes, where the mesh
    sequence is made (`animation.KeyframeTrack`): ``"from_start"``, keyframe k's mesh
    forward through the segment (k >= 1: the template begins on keyframe 0's), and
    ``"from_end"``, keyframe k + 1's mesh back along B's paths (`levelset.SeenFromB`,
    two-sided transport only). They ship where no earlier mesh follows."""
    meshes = segment.keyframe_meshes
    if meshes is None or not segment.outputs.keeps_meshes:
        return {}
    k = segment.k

    def track(ends, key, other):
        v, tris = meshes[key]
        return DetailTrack(ends, np.asarray(v, dtype=float).reshape(-1, 3),
                           np.asarray(tris, dtype=np.int64).reshape(-1, 3), meshes[other])
    tracks = {} if k == 0 else {"from_start": track(inb, k, k + 1)}
    back = inb.seen_from_b()
    if back is not None:
        tracks["from_end"] = track(back, k + 1, k)
    return tracks


def _track_figures(inb, s, track, t, rep, levelset=None, surface=None):
    """A keyframe track's vertices (float32) on the frame at time ``s``, its own time
    ``t``, and what `tracked_frames` judges them by: how far the zero set steered them,
    their quality figures (as the shape keys'), their pieces' volumes and their area
    turned over and their ripple (`template.DetailTrack.ripple`). ``levelset`` and
    ``surface`` are the frame's, made here when not given."""
    ls = inb.levelset(s) if levelset is None else levelset
    surf = extract_surface(ls, inb.grid) if surface is None else surface
    q, _ = track(t)
    rep.check()
    faces = track.faces
    return dict(vertices=q.astype(np.float32), steered=track.guides.get(float(t), 0.0),
                shape_keys=frame_quality(ls, inb.grid, q, faces, surf),
                volumes=piece_volumes(q, faces), flipped=flipped_fraction(track.start, q, faces),
                ripple=track.ripple(q))


def _template(inb, segment, detail, s):
    """The template at time ``s``: its ``vertices``, ``max_abs_phi``, the largest |phi|
    of their projection onto the level set, and ``steered``, how far the zero set steered
    it (`template.DetailTrack.guides`; 1 for the grid's template, always pulled onto it;
    0 on a keyframe's own mesh)."""
    if detail is None:
        tr = track_template(inb, [s], template=segment.template, coverage=False)
        return dict(vertices=tr.vertices[0], max_abs_phi=tr.stats["max_abs_phi"][0],
                    steered=1.0)
    p, err = detail(s)
    return dict(vertices=p, max_abs_phi=float(err.max()) if err.size else 0.0,
                steered=detail.guides.get(float(s), 0.0))


def _frame_outputs(inb, s, segment, p, rep, tracks=None):
    """What ``segment.outputs`` asks of the frame at time ``s`` whose template vertices
    are ``p``: its level set, uncovered area, the quality figures of the outputs measured,
    its material's topology (`extract.material_topology`), the volumes of the template's
    pieces and its area turned over (`tracked_frames`), own mesh and velocity, and the
    figures of the keyframe ``tracks`` (`_keyframe_tracks`, `_track_figures`). The
    frame's own surface is made whenever a figure needs it; its mesh and velocities only
    for the mesh sequence."""
    outputs, grid, faces = segment.outputs, inb.grid, segment.template[1]
    out = {}
    if outputs.levelsets:
        out["levelset"] = inb.levelset(s).astype(np.float32)
    if outputs.coverage or outputs.surfaces:
        ls = inb.levelset(s)
        surf = extract_surface(ls, grid)
        rep.check()
    if outputs.coverage:
        unc, tot = uncovered_area(ls, grid, p, faces, surface=surf)
        out["uncovered"] = (unc, unc / tot if tot > 0 else 0.0)
        rep.check()
    if not outputs.surfaces:
        return out
    own = frame_mesh(surf, segment.keyframe_meshes, segment.k, s)
    meshes = {"shape_keys": (p, faces), "mesh_sequence": own}
    for name in outputs.measured:
        out[name] = frame_quality(ls, grid, *meshes[name], surf)
    out["topology"] = material_topology(ls)
    out["volumes"] = piece_volumes(p, faces)
    out["flipped"] = flipped_fraction(segment.template[0], p, faces)
    rep.check()
    if outputs.keeps_meshes:
        step = 1.0 / float(segment.ends[1] - segment.ends[0])  # a frame, in s
        out["mesh"] = (own[0].astype(np.float32), own[1].astype(np.int32))
        out["velocity"] = (inb.velocity(own[0], s, ds=step) * step).astype(np.float32)
    for name, track in (tracks or {}).items():
        t = s if name == "from_start" else 1.0 - s
        out[name] = _track_figures(inb, s, track, t, rep, ls, surf)
    return out


def frame_mesh(surface: tuple[np.ndarray, np.ndarray] | None,
               keyframe_meshes: Sequence[tuple[ArrayLike, ArrayLike]] | None, k: int,
               s: float) -> tuple[np.ndarray, np.ndarray]:
    """A frame's own mesh for the mesh sequence: on a keyframe's frame (s = 0 of the first
    segment, s = 1 of every segment) the keyframe mesh the artist modelled, when given;
    else the frame's grid surface."""
    if keyframe_meshes is not None and (s == 1.0 or (s == 0.0 and k == 0)):
        v, tris = keyframe_meshes[k + int(s == 1.0)]
        return np.asarray(v, dtype=float).reshape(-1, 3), np.asarray(tris).reshape(-1, 3)
    return surface


#: The limits a frame of the tracked template meets to ship in a mesh sequence before a
#: topology change (`tracked_frames`): the clean-output limits without coverage. Before
#: parts meet, a frame's own surface reaches ahead toward the contact (the blend of the
#: two keyframes' fields bridges the gap), while the artist's mesh keeps each part's shape
#: until they meet: coverage there measures the surface's lead, not a flaw of the mesh.
TRACKED_LIMITS = {**LIMITS, "coverage": 0.0}

#: The most the zero set may steer a frame's template (`template.DetailTrack.guides`) for
#: the frame to count as moved rigidly by its paths (`tracked_frames`).
RIGID_STEER = 0.05

#: The most a piece of a tracked frame's template may swell or shrink since the first
#: frame (`tracked_frames`): the volume step where the frames switch.
TRACKED_VOLUME = 0.01

#: The most ripple (`template.DetailTrack.ripple`, cells) a keyframe's mesh tracked from
#: it (`animation.KeyframeTrack`) may gain and still ship (`tracked_frames`): the
#: frame's own surface, which it replaces, has none. Two merged balls (marching cubes at
#: four vertices a cell) tracked back from their keyframe showed rings plainly from
#: 0.018, faintly at 0.011-0.014; the splash's coarser bump none at 0.04.
TRACK_RIPPLE = 0.015


def tracked_frames(frames: np.ndarray, shape_keys: Sequence[Mapping[str, float]],
                   topology: Sequence[tuple[int, ...]],
                   steered: Sequence[float] | None = None,
                   volumes: Sequence[np.ndarray] | None = None,
                   flipped: Sequence[float] | None = None,
                   limits: Mapping[str, Any] = TRACKED_LIMITS,
                   ripple: Sequence[float] | None = None) -> np.ndarray:
    """Which frames a mesh sequence ships as the tracked template, the artist's own mesh:
    (n,) bool over ``frames``.

    One mesh follows the shape until its topology changes (parts meet or part, or a hole
    opens: ``topology``, `extract.material_topology`, differs from the first frame's), so
    those frames keep the artist's vertices, UVs and
    sharp edges; from the change on, each frame is its own surface, and the switch comes
    where the viewer expects a change. A frame before the change on which the template
    stretches or folds ends the tracked frames there instead: its figures (``shape_keys``,
    `quality.frame_quality`'s, as measured) relative to the first frame's, where the
    template is the artist's mesh itself, break ``limits`` (`TRACKED_LIMITS`; a keyframe's
    mesh tracked after parts met answers to coverage too, `LIMITS`). A frame whose template
    its paths carried rigidly (``steered``, per frame, at most `RIGID_STEER`; None: every
    frame steered) cannot stretch or fold: its figures measure how coarse the grid's
    surface is, and it passes. A frame on which a piece of the template swells or shrinks
    by more than `TRACKED_VOLUME` since the first frame (``volumes``, per frame its
    pieces' volumes, `extract.piece_volumes`) ends them too: its volume would step back
    where the frames switch to their own surfaces, which hold it. So does a frame on which
    any face of the template has turned over since the first (``flipped``, per frame its
    area share, `quality.flipped_fraction`): a fold of the artist's mesh shows as specks
    of its inside, however small. So does a frame that has gained more ripple than
    `TRACK_RIPPLE` since the first (``ripple``, per frame; None: not judged).

    ``shape_keys`` is updated in place to those relative figures on the tracked frames.
    """
    n = len(frames)
    first, start = shape_keys[0], tuple(topology[0])
    steered = np.ones(n) if steered is None else np.asarray(steered, dtype=float)
    drift = (np.zeros(n) if volumes is None else
             np.array([np.max(np.abs(v / volumes[0] - 1.0), initial=0.0) for v in volumes]))
    folded = np.zeros(n) if flipped is None else np.asarray(flipped, dtype=float)
    rippled = np.zeros(n) if ripple is None else np.asarray(ripple, dtype=float)
    end = n
    for i, (q, t) in enumerate(zip(shape_keys, topology)):
        rel = dict(q, area_ratio=q["area_ratio"] / first["area_ratio"],
                   inverted_fraction=max(q["inverted_fraction"] - first["inverted_fraction"], 0.0))
        rigid = steered[i] <= RIGID_STEER
        if (tuple(t) != start or drift[i] > TRACKED_VOLUME or folded[i] > 0.0
                or rippled[i] > TRACK_RIPPLE or (not rigid and failures(rel, limits))):
            end = i
            break
        shape_keys[i] = rel
    return np.arange(n) < end
