"""Meshes + feature points + timeline frames -> one tracked mesh per frame.

This is the single entry point the Blender layer calls: it chooses a grid,
turns each keyframe mesh into a signed distance grid, solves the volume map
of every adjacent pair, and tracks one template mesh through all frames.
"""

from __future__ import annotations

import dataclasses
import os
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.grid import Grid
from ..base.parallel import Helper, one_blas_thread, share
from ..base.progress import Reporter, Tally
from ..motion.spline import bends_needed, check_key_interpolation
from ..surface.attributes import MeshAttributes
from ..surface.extract import mesh_volume
from ..surface.quality import LIMITS, OWN_SURFACES, choose_output, keyframe_distance
from .animation import Animation
from .cache import WorkCache, content_key, grid_key
from .chain import HELPER_PRELOAD, Chain, tracked_frames
from .checks import (check_feature_reach, check_feature_spacing, check_inputs,
                     check_motion_resolution, check_result,
                     keyframe_label, no_volume_message, notes, rigid_sweep, checked_mesh)
from .gridfit import auto_motion_resolution, fit_grid, motion_grid, one_grid_unless_smaller
from .keyframe import Keyframe
from .memory import MemoryLimitError, check_memory, estimate_memory, largest_fitting
from .options import BakeOptions
from .steps import DISTANCE_FIELDS, FRAMES, MAP_CELL_COST, MAPS, PATH_CELL_COST, PATHS

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping, Sequence

    from numpy.typing import ArrayLike

    from .checks import FeatureNames

    #: What a grid rule (`plan_bake`'s ``grid_rule``) is given: (surface grid, Motion
    #: Resolution, motion grid or None) of the keyframes at (resolution, motion resolution or
    #: None, memory limit or None).
    GridFit = Callable[[int, int | None, int | None], tuple[Grid, int, Grid | None]]

__all__ = ["animate", "bake", "BakePlan", "plan_bake", "bake_grids", "bake_steps",
           "memory_limit", "MemoryNeed", "memory_need",
           "distance_fields", "distance_grid", "distance_key", "finish_bake"]



def _distance_grids(keyframes, meshes, grid, rep, cancel=None, helper=None, cache=None):
    """The keyframes' signed distance grids and `sdf.mesh_to_sdf`'s figures of each.

    Those the ``cache`` (`cache.WorkCache`) holds for the same mesh on the same grid
    (`distance_key`) are taken from it, the others made and kept there. With a ``helper``
    process the ones to make are shared (`parallel.share`): this process takes the keyframes
    from the first on, the helper the last one left once it has started. A process takes
    0.5-1 s to start, more than a small grid's distance grids take, so the helper only joins
    in where that pays.
    """
    n = len(keyframes)
    keys = [distance_key(grid, m) for m in meshes] if cache is not None else None
    done = {}
    for k in range(n) if cache is not None else ():
        kept = cache.get(keys[k])
        if kept is not None:
            done[k] = kept
            rep.elsewhere(DISTANCE_FIELDS)
    todo = [k for k in range(n) if k not in done]
    if helper is None or len(todo) < 2:
        done.update((k, distance_grid(keyframes, meshes, grid, k, rep, cancel)) for k in todo)
    else:
        def here(k, stop):
            return distance_grid(keyframes, meshes, grid, k, rep, stop)

        def there(k):
            return distance_grid, (keyframes, meshes, grid, k), {}

        made, _, _ = share(todo, here, there, helper, check=rep.check, cancel=cancel,
                           last_first=True, when_started=True,
                           on_theirs=lambda _k: rep.elsewhere(DISTANCE_FIELDS))
        done.update(made)
    for k in todo if cache is not None else ():
        cache.put(keys[k], done[k])
    return [done[k][0] for k in range(n)], [done[k][1] for k in range(n)]


def distance_key(grid: Grid, mesh: tuple) -> str:
    """What a keyframe's distance grid depends on (`cache.content_key`): the grid and the
    checked mesh's vertices in world space and triangles."""
    return content_key("distance", grid_key(grid), np.asarray(mesh[0], dtype=np.float64),
                       np.asarray(mesh[1], dtype=np.int64))


def distance_grid(keyframes: Sequence[Keyframe], meshes: Sequence[tuple], grid: Grid, k: int,
                  rep: Reporter | None = None, cancel: Callable[[], bool] | None = None
                  ) -> tuple[np.ndarray, dict[str, Any]]:
    """(field, figures) of keyframe ``k`` from its checked mesh (``meshes[k]``,
    `checks.checked_mesh`); ValueError naming the keyframe on bad input."""
    # the distance fields' modules (scipy.ndimage, scipy.spatial, scipy.sparse) are imported
    # when first needed: the live preview imports this module as it starts
    from ..fields.sdf import mesh_to_sdf

    n = len(keyframes)
    kf, (v, tris) = keyframes[k], meshes[k][:2]
    figures = {}
    try:
        with (rep or Reporter()).step(DISTANCE_FIELDS, k, n) as sub:
            phi = mesh_to_sdf(v, tris, grid, progress=sub, cancel=cancel, stats=figures)
    except ValueError as exc:
        raise ValueError(f"{keyframe_label(k, kf)}: {exc}") from exc
    if not np.any(phi < 0):
        raise ValueError(no_volume_message(k, kf, v, tris, grid))
    return phi, figures


def _physical_memory():
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # not on every platform
        return None


def _material_fraction(keyframe, grid):
    """Share of the grid box enclosed by a keyframe mesh (from its volume, before any grid work)."""
    from ..fields.mesh import triangulate

    v = np.asarray(keyframe.vertices, dtype=float).reshape(-1, 3)
    try:
        vol = abs(mesh_volume(v, triangulate(keyframe.faces, len(v))))
    except ValueError:
        return 0.25  # mesh_to_sdf reports what is wrong with it; estimate_memory's default
    return float(min(1.0, vol / np.prod(grid.upper - grid.origin)))


def animate(keyframes: Sequence[Keyframe], features: Sequence[tuple[ArrayLike, ArrayLike]], *,
            resolution: int = BakeOptions.resolution,
            motion_resolution: int | None = BakeOptions.motion_resolution,
            weights: Mapping[str, float] | None = None,
            key_interpolation: str | Sequence[str] | None = BakeOptions.key_interpolation,
            template: str = BakeOptions.tracked_mesh,
            padding_cells: int = BakeOptions.padding_cells,
            max_bytes: int | None = BakeOptions.max_bytes,
            processes: int = BakeOptions.processes,
            feature_names: FeatureNames | None = None,
            progress: Callable[[float, str], object] | None = None,
            cancel: Callable[[], bool] | None = None, helper: Helper | None = None,
            cache: WorkCache | None = None, **stage_options: Any) -> Animation:
    """Bake a sequence of keyframes into one tracked mesh per timeline frame.

    Stages: `gridfit.fit_grid` (one grid holding every keyframe and feature point,
    refused before any work if it would not fit in memory), `sdf.mesh_to_sdf` per
    keyframe, then the chain (`chain.Chain`; per segment: `solver.solve_map`,
    trajectories, in-between level sets, and the template tracked through all frames).
    This is `bake` with the options as keyword arguments.

    Parameters
    ----------
    keyframes : sequence of `Keyframe`, at least two, frames strictly increasing.
    features : sequence of (points_a, points_b) pairs, one per segment (keyframe i -> i+1);
        (N, 3) arrays in world units, row j of points_a pairs with row j of points_b.
    resolution : int
        Grid cells along the longest side of the keyframes' bounding box (48).
    motion_resolution : int or None
        Cells along the same side of the motion grid, on which the maps and the
        trajectories are solved (docs/method.md, section 11); from 8 to ``resolution``,
        which reproduces a bake on one grid. None (default): chosen from a cost budget
        (`gridfit.auto_motion_resolution`).
    weights : mapping, optional
        The weights of eq. 2.6's terms by name ("volume", "rigidity", "levelset", and any
        term registered in `map.terms.TERMS`); the others keep their defaults.
    key_interpolation : str or sequence of str, optional
        Per keyframe, how the motion passes it: "smooth" (default: continuous velocity),
        "linear" (a corner) or "ease" (coming to rest); one string for every keyframe.
    template : {"keyframe", "grid"}
        The mesh carried through the frames (`BakeOptions.tracked_mesh`): the first
        keyframe's own mesh with its attributes and sub-cell detail (default; the grid's
        when it has loose vertices), or marching cubes of its distance grid.
    padding_cells : int
        Empty cells around the keyframes' bounding box (4).
    max_bytes : int, optional
        Memory limit of the bake; default: 75 % of physical memory. A resolution over it
        is refused before any work (`memory.MemoryLimitError`).
    processes : int
        1 (default): everything in this process; 2: a helper process shares the maps and
        the frames.
    feature_names : per segment, a sequence of (name_a, name_b) per feature row, optional;
        used in messages (e.g. the Empties' names).
    progress : callable(fraction, message), optional
        Counted steps in the artist's words ("Distance fields 2/4", "Maps 3/6", "Paths 1/4",
        "Frames 12/25", `bake_steps`), the fraction each step's share of the expected work
        (`progress.Tally`): it never goes back.
    cancel : callable() -> bool, optional; when it returns True, `Cancelled` is raised.
    helper : `parallel.Helper`, optional
        A helper process already started (and left running): it takes the place of the
        one ``processes=2`` starts here, whose interpreter then loads while this one
        checks the keyframes (the worker process starts it before reading its inputs).
    cache : `cache.WorkCache`, optional
        Distance grids and maps kept by content: those of the same inputs are taken from
        it instead of computed, the others kept there (a re-bake after one Empty moved
        solves only its pair's maps); how many of each were taken: ``stats["kept"]``.
    **stage_options
        The stages' own settings, each the field of the same name, checked before any
        work (an unknown one is refused with a ValueError that lists the known ones):

        - the map solve's, `map.options.MapOptions` (``volume_weight``, ``margin_cells``,
          ``feature_radius``, ``tear``, ...);
        - the in-betweens', `motion.options.MotionOptions` (``transport``,
          ``keep_volume``, ``trajectory_margin_cells``, ...);
        - what each frame yields, `surface.options.SurfaceOptions` (``coverage``,
          ``surfaces``, ``levelsets``, ``output``: "auto", or the one output to make
          and measure).

    Returns
    -------
    Animation

    Raises
    ------
    ValueError
        On input the user must fix (message says what), including
        `memory.MemoryLimitError` when the resolution is too high for this machine.
    Cancelled
        When ``cancel()`` returned True.
    """
    options = BakeOptions.from_keywords(
        resolution=resolution, motion_resolution=motion_resolution, weights=weights,
        key_interpolation=key_interpolation, template=template, padding_cells=padding_cells,
        max_bytes=max_bytes, processes=processes, **stage_options)
    return bake(keyframes, features, options, feature_names=feature_names, progress=progress,
                cancel=cancel, helper=helper, cache=cache)


def bake(keyframes: Sequence[Keyframe], features: Sequence[tuple[ArrayLike, ArrayLike]],
         options: BakeOptions, *, feature_names: FeatureNames | None = None,
         progress: Callable[[float, str], object] | None = None,
         cancel: Callable[[], bool] | None = None, helper: Helper | None = None,
         cache: WorkCache | None = None) -> Animation:
    """`animate` with its options as one `BakeOptions`: what the Blender side's worker and
    every other caller that built its options once run. The other parameters, the result
    and the errors are `animate`'s."""
    t0 = time.perf_counter()
    plan = plan_bake(keyframes, features, options, feature_names=feature_names)
    rep = Tally(progress, bake_steps(plan)).reporter(cancel)
    rep.check()
    blas, given = one_blas_thread(), helper
    before = {} if cache is None else cache.hits()
    try:
        if helper is None and options.processes > 1:
            helper = Helper(HELPER_PRELOAD)
        phis = distance_fields(plan, rep, cancel, helper, cache)
        plan.stats["sdf_seconds"] = time.perf_counter() - t0
        chain = plan.chain(phis, cancel, cache).run(helper, rep)
    finally:
        blas.restore_original_limits()
        if helper is not None and helper is not given:
            helper.close()
    if cache is not None:
        plan.stats["kept"] = {kind: n - before.get(kind, 0) for kind, n in cache.hits().items()}
    return finish_bake(plan, chain, t0, rep)


def bake_steps(plan: BakePlan) -> dict[str, tuple[int, float]]:
    """The bake's counted steps, {stage: (steps, cost of one)} (`progress.Tally`), in the
    words the artist reads: a distance field per keyframe, a map per pair's direction
    (two per pair when both keyframes are carried), a path step per segment and one more
    for the bends through the keyframes, and a frame per timeline frame; a step's cost is
    its grid's cells (the motion grid's for maps and paths) times `MAP_CELL_COST` or
    `PATH_CELL_COST`."""
    options, nk = plan.options, len(plan.keyframes)
    surface = float(np.prod(plan.grid.shape))
    motion = float(np.prod((plan.motion_grid or plan.grid).shape))
    kinds = check_key_interpolation(options.key_interpolation, nk)
    sides = 2 if options.motion.two_sided else 1
    frames = plan.frames[-1] - plan.frames[0] + 1
    return {DISTANCE_FIELDS: (nk, surface),
            MAPS: ((nk - 1) * sides, MAP_CELL_COST * motion),
            PATHS: (nk - 1 + int(bends_needed(kinds)), PATH_CELL_COST * motion),
            FRAMES: (frames, surface)}


@dataclass
class BakePlan:
    """What a bake settles before any grid work (`plan_bake`): the checked keyframes and
    feature pairs, each keyframe's checked mesh (`checks.checked_mesh`: vertices,
    triangles, loose vertices, points the grid must hold), the surface grid at
    ``resolution`` and the motion grid (None: the surface grid), the artist's template
    (vertices, triangles, `attributes.MeshAttributes`; None: the grid's), the bake's
    options and the figures so far."""

    keyframes: list
    features: list
    resolution: int
    grid: Grid
    motion_grid: Grid | None
    checked_meshes: list
    artist: tuple | None
    options: BakeOptions
    stats: dict

    @property
    def frames(self) -> list:
        """The keyframes' timeline frames."""
        return [kf.frame for kf in self.keyframes]

    def chain(self, phis: Sequence[np.ndarray], cancel: Callable[[], bool] | None = None,
              cache: WorkCache | None = None) -> Chain:
        """The `chain.Chain` of this plan's keyframes, given their distance grids ``phis``
        on ``grid``: the artist's mesh as the template when there is one; its maps taken
        from and kept in ``cache`` when given."""
        artist = self.artist
        return Chain(phis, self.grid, self.features, self.frames, self.options,
                     template=None if artist is None else artist[:2],
                     keyframe_meshes=None if artist is None else [m[:2] for m in self.checked_meshes],
                     motion_grid=self.motion_grid, cancel=cancel, cache=cache)


def plan_bake(keyframes: Sequence[Keyframe], features: Sequence[tuple[ArrayLike, ArrayLike]],
              options: BakeOptions, *, feature_names: FeatureNames | None = None,
              grid_rule: Callable[[GridFit, BakeOptions],
                                  tuple[int, tuple[Grid, int, Grid | None]]] | None = None
              ) -> BakePlan:
    """`bake`'s inputs checked and its grids chosen, before any grid work: a `BakePlan`.

    ``grid_rule`` chooses the grids: called as ``grid_rule(fit, options)``, it returns
    (resolution, `fit`'s answer at it), where ``fit(resolution, motion_resolution,
    max_bytes)`` is (surface grid, Motion Resolution, motion grid) of these keyframes at
    those resolutions, or ValueError where two feature points would share a cell or
    `memory.MemoryLimitError` over ``max_bytes`` (None: no limit). None: the bake's own
    rule (`bake_grids`); the live preview has its own (`preview.preview_grids`).

    The other parameters are `bake`'s; ValueError (and `memory.MemoryLimitError`) on
    input the user must fix.
    """
    keyframes, features = check_inputs(keyframes, features, feature_names)
    check_motion_resolution(options.motion_resolution, options.resolution)
    check_key_interpolation(options.key_interpolation, len(keyframes))
    options.segment_motion(len(keyframes) - 1)  # a surface tension per segment, or one

    stats = {}
    meshes = [checked_mesh(k, kf) for k, kf in enumerate(keyframes)]

    def fit(resolution, motion_resolution, max_bytes):
        return _bake_grid(keyframes, meshes, features, feature_names, resolution,
                          motion_resolution, options.padding_cells, max_bytes)

    resolution, (grid, stats["motion_resolution"], motion) = (grid_rule or bake_grids)(
        fit, options)
    stats.update(grid_shape=tuple(grid.shape), grid_spacing=grid.spacing)
    if motion is not None:
        stats["motion_grid_shape"] = tuple(motion.shape)
    artist = _artist_template(keyframes[0], meshes[0], options.tracked_mesh)
    return BakePlan(keyframes, features, resolution, grid, motion, meshes, artist, options,
                    stats)


def bake_grids(fit: GridFit, options: BakeOptions) -> tuple[int, tuple[Grid, int, Grid | None]]:
    """The bake's grid rule (`plan_bake`'s ``grid_rule``): the grids at the options'
    resolutions, refused over the options' memory limit (`memory_limit`)."""
    return options.resolution, fit(options.resolution, options.motion_resolution,
                                   memory_limit(options.max_bytes))


def memory_limit(max_bytes: int | None = None) -> int | None:
    """The bake's memory limit in bytes: ``max_bytes``, or None for 75 % of this computer's
    physical memory (None where that is unknown: no limit)."""
    if max_bytes is not None:
        return int(max_bytes)
    phys = _physical_memory()
    return int(0.75 * phys) if phys else None


@dataclass(frozen=True)
class MemoryNeed:
    """What a bake would need in memory (`memory_need`): the estimated ``peak`` bytes, the
    ``limit`` (None: none known), the largest resolution that fits when the peak is over
    it (``fits``, None when it is not over or nothing fits) and the Motion Resolution the
    bake would use (``motion_resolution``: the automatic one when none is set)."""

    peak: int
    limit: int | None
    fits: int | None
    motion_resolution: int

    @property
    def over(self) -> bool:
        """Whether the bake would be refused for memory."""
        return self.limit is not None and self.peak > self.limit


def memory_need(boxes: Sequence[ArrayLike], volumes: Sequence[float], resolution: int,
                motion_resolution: int | None = None, *, extra_points: ArrayLike | None = None,
                padding_cells: int = BakeOptions.padding_cells,
                max_bytes: int | None = None) -> MemoryNeed:
    """What a bake at ``resolution`` would need in memory, from the keyframes' bounding
    boxes and volumes alone: `memory.estimate_memory` on the grid and motion grid the bake
    would fit (`gridfit.fit_grid`, `gridfit.auto_motion_resolution`), with no mesh work, so
    cheap enough to follow the Resolution as it is edited. The bake's own check reads the
    meshes and the paths between the keyframes too: this is the figure it refuses by,
    about.

    Parameters
    ----------
    boxes : per keyframe, points spanning its bounding box in world units ((N, 3)).
    volumes : per keyframe, the volume it encloses.
    resolution, motion_resolution : as `animate` takes them (None: automatic).
    extra_points : (M, 3) points the grid must hold too (the feature points), optional.
    padding_cells : as `animate` takes it.
    max_bytes : the memory limit, None for the bake's (`memory_limit`).
    """
    pts = [np.asarray(b, dtype=float).reshape(-1, 3) for b in boxes]

    def fitted(r):
        return fit_grid(pts, r, padding_cells=padding_cells, extra_points=extra_points)

    grid = fitted(resolution)
    box = float(np.prod(grid.upper - grid.origin))
    fraction = float(min(1.0, max(volumes, default=0.0) / box)) if box > 0 else 1.0
    motion_of = _motion_rule(motion_resolution, fraction)
    mem = dict(n_keyframes=len(pts), material_fraction=fraction)
    mgrid = motion_of(resolution, grid)
    peak = estimate_memory(grid, motion_grid=mgrid, **mem)["peak"]
    limit = memory_limit(max_bytes)
    fits = None
    if limit is not None and peak > limit:
        fits = largest_fitting(fitted, 4, int(resolution) - 1, limit, motion_of=motion_of, **mem)
    motion = (auto_motion_resolution(resolution, fraction, grid) if motion_resolution is None
              else min(int(motion_resolution), resolution))
    return MemoryNeed(int(peak), limit, fits, int(motion))


def distance_fields(plan: BakePlan, rep: Reporter, cancel: Callable[[], bool] | None = None,
                    helper: Helper | None = None,
                    cache: WorkCache | None = None) -> list[np.ndarray]:
    """The keyframes' signed distance grids on ``plan.grid`` (`sdf.mesh_to_sdf`, shared with
    a ``helper`` process when given; those ``cache`` holds taken from it); their figures go
    to ``plan.stats["sdf"]``."""
    phis, plan.stats["sdf"] = _distance_grids(plan.keyframes, plan.checked_meshes, plan.grid, rep,
                                              cancel, helper, cache)
    return phis


def finish_bake(plan: BakePlan, chain: Animation, t0: float, rep: Reporter) -> Animation:
    """`animate`'s result from the chain's `Animation`: checked against the keyframes, its
    figures and notes gathered, the output chosen, arrays in their final types; ``t0``
    the `time.perf_counter` the bake began at."""
    keyframes, artist = plan.keyframes, plan.artist
    check_result(chain, plan.grid, keyframes)
    stats = dict(plan.stats)
    stats.update(chain.stats)
    stats["loose_vertices"] = [m[2] for m in plan.checked_meshes]
    stats["notes"] = notes(keyframes, stats["loose_vertices"], stats["sdf"])
    tracked = None
    if "quality" in stats:
        rep(0.98, "Measuring the keyframe frames")
        measured = [dict(q) for q in stats["quality"]["shape_keys"]]
        _choose_output(stats, keyframes, chain, plan.grid.spacing, artist is not None,
                       plan.options.surface.output)
        if artist is not None and "mesh_sequence" in stats["quality"]:
            tracked, reach = _sequence_tracked(stats, chain.frames, measured, keyframes,
                                               plan.options.surface.output == "auto")
            _keyframe_tracks_shipped(stats, chain.frames, chain.keyframe_tracks, tracked,
                                     keyframes)
            _say_artist_frames(stats, chain.frames, reach, len(keyframes))
    stats["total_seconds"] = time.perf_counter() - t0
    rep(1.0, "Done")
    return dataclasses.replace(
        chain, frames=np.asarray(chain.frames, dtype=np.int64),
        vertices=np.asarray(chain.vertices, dtype=np.float32),
        faces=np.asarray(chain.faces, dtype=np.int64), stats=stats, tracked=tracked,
        attributes=None if artist is None else artist[2],
        keyframe_attributes={} if artist is None else
        _keyframe_attributes(keyframes, plan.checked_meshes, artist[2]))


def _bake_grid(keyframes, meshes, features, feature_names, resolution, motion_resolution,
               padding_cells, max_bytes):
    """The bake's surface grid (`gridfit.fit_grid`), its Motion Resolution and motion grid
    (`_motion_grid`). The grid holds every keyframe's faces (loose vertices are ignored),
    every feature point and the rigid sweeps between them. Refused before any work, with
    the resolution that would fit, when `memory.estimate_memory` puts it over
    ``max_bytes`` (None: no limit)."""
    pts = [m[3] for m in meshes]
    lo = np.min([p.min(axis=0) for p in pts], axis=0)
    hi = np.max([p.max(axis=0) for p in pts], axis=0)
    check_feature_reach(features, lo, hi, feature_names)
    extra = [np.concatenate(pair) for pair in features] + rigid_sweep(pts, features)
    extra = np.concatenate(extra) if extra else None

    def fitted(r):
        return fit_grid(pts, r, padding_cells=padding_cells, extra_points=extra)

    grid = fitted(resolution)
    check_feature_spacing(features, grid.spacing, feature_names)
    # the largest keyframe's share of the box sets the solver's and the trajectories' size
    fraction = max(_material_fraction(kf, grid) for kf in keyframes)
    motion, mgrid = _motion_grid(features, feature_names, grid, resolution, motion_resolution,
                                 fraction)
    if max_bytes is None:
        return grid, motion, mgrid
    mem = dict(n_keyframes=len(keyframes), material_fraction=fraction)
    try:
        check_memory(grid, max_bytes, motion_grid=mgrid, **mem)
    except MemoryLimitError as exc:
        best = largest_fitting(fitted, 4, int(resolution) - 1, max_bytes,
                               motion_of=_motion_rule(motion_resolution, fraction), **mem)
        hint = (f"lower the resolution to {best} or less" if best else
                "even the smallest grid does not fit: free memory or simplify the keyframes")
        raise MemoryLimitError(
            f"Resolution {resolution} would need about {exc.required / 2**20:,.0f} MB but "
            f"the limit is {max_bytes / 2**20:,.0f} MB: {hint}.",
            exc.required, max_bytes, best) from None
    return grid, motion, mgrid


def _motion_rule(motion_resolution, fraction):
    """The motion grid a bake at resolution r on grid g would use, as (r, g) -> grid or
    None: the given Motion Resolution (no finer than r) or the automatic one."""
    def motion_of(r, g):
        m = (auto_motion_resolution(r, fraction, g) if motion_resolution is None
             else min(int(motion_resolution), r))
        return motion_grid(g, r, m)

    return motion_of


def _motion_grid(features, feature_names, grid, resolution, motion_resolution, fraction):
    """The bake's Motion Resolution and motion grid (`gridfit.motion_grid`; None when it is
    the surface grid). Automatic: `gridfit.auto_motion_resolution` for the largest
    keyframe's ``fraction`` of the box, raised where two feature points would share a
    motion cell, one grid where the motion grid would not have fewer nodes than ``grid``
    (`gridfit.one_grid_unless_smaller`); given: refused in that case."""
    def grid_of(m):
        return motion_grid(grid, resolution, m)

    def spacing_fits(m):
        g = grid_of(m)
        check_feature_spacing(features, grid.spacing if g is None else g.spacing,
                              feature_names, "motion grid", "Motion Resolution")

    if motion_resolution is not None:
        spacing_fits(int(motion_resolution))
        return int(motion_resolution), grid_of(int(motion_resolution))
    m = auto_motion_resolution(resolution, fraction, grid)
    while m < resolution:
        try:
            spacing_fits(m)
            break
        except ValueError:
            m = one_grid_unless_smaller(grid, resolution,
                                        min(resolution, int(np.ceil(1.25 * m))))
    return m, grid_of(m)


def _choose_output(stats, keyframes, chain, spacing, artist, output):
    """The outputs measured on the keyframes' frames too (against the keyframes' own
    meshes), then the output chosen (`quality.choose_output`; the one set when ``output``
    is not "auto"), into ``stats``. With the artist's mesh as the template (``artist``) its
    shape keys are judged relative to the keyframes' own figures, and the mesh sequence is
    the keyframes' meshes there."""
    quality = stats["quality"]
    key_frames = [kf.frame for kf in keyframes]
    if artist and "shape_keys" in quality:
        _relative_to_keyframes(quality["shape_keys"], chain.frames, key_frames)
    if artist and "mesh_sequence" in quality:
        _keyframes_are_reference(quality["mesh_sequence"], chain.frames, key_frames)
    measured = [name for name in quality if not (artist and name == "mesh_sequence")]
    _measure_keyframes(quality, keyframes, chain, spacing, measured)
    stats["output"], stats["output_reason"] = (
        choose_output(chain.frames, quality) if output == "auto" else
        (output, "chosen in the output settings"))


def _sequence_tracked(stats, frames, measured, keyframes, auto):
    """The frames the mesh sequence ships as the artist's mesh, tracked (`chain.
    tracked_frames`, from the shape keys' figures as ``measured``), but for the later
    keyframes' frames, which show each keyframe's own mesh (the first keyframe's is the
    template itself), and how many frames from the first it reaches. Their mesh-sequence
    figures become the template's (what ships there) and ``stats["tracked_frames"]``
    counts them. When the template may ship on every frame, Auto's choice (``auto``: the
    output is not set in the settings) becomes the shape keys."""
    quality = stats["quality"]
    tracked = tracked_frames(frames, measured, stats["topology"], stats["steered"],
                             stats["volumes"], stats["flipped"])
    reach = int(np.count_nonzero(tracked))
    if auto and reach == len(frames) and stats["output"] == "mesh_sequence":
        stats["output"], stats["output_reason"] = "shape_keys", (
            "one mesh follows the shape on every frame (it moves rigidly where the grid is "
            "too coarse to judge it)")
    tracked[[kf.frame - frames[0] for kf in keyframes[1:]]] = False
    for i in np.flatnonzero(tracked[1:]) + 1:  # the first frame: the keyframe mesh itself
        quality["mesh_sequence"][i] = measured[i]
    stats["tracked_frames"] = int(tracked.sum())
    return tracked, reach


def _say_artist_frames(stats, frames, reach, keyframes):
    """A mesh sequence's reason, ending on where it ships the artist's mesh: up to the
    frame the template reaches (``reach`` frames), or with keyframe tracks shipped, on
    how many frames (the ``keyframes``' own frames too)."""
    if stats["output"] != "mesh_sequence":
        return
    reason = stats["output_reason"].removesuffix(OWN_SURFACES)
    beside = stats.get("keyframe_track_frames", 0)
    if beside:
        count = stats["tracked_frames"] + beside + keyframes - 1  # the first is the template's
        stats["output_reason"] = reason + (f"; the artist's mesh on {count} of {len(frames)} "
                                           "frames")
    elif reach > 1:
        stats["output_reason"] = reason + f"; the artist's mesh up to frame {frames[reach - 1]}"


def _keyframe_tracks_shipped(stats, frames, tracks, tracked, keyframes):
    """Each `animation.KeyframeTrack`'s ``ships``. From its keyframe's frame, where it is
    the keyframe's mesh itself, outward over the frames no other mesh ships (the template
    where ``tracked``, the keyframes' frames, then the tracks forward from a keyframe,
    then those back), as long as `chain.tracked_frames` allows, coverage and shading
    ripple included: the frames' own surfaces, which they replace, have parts met or
    parted as the keyframe has (a mesh that leaves some of a surface uncovered misses a
    neck the viewer expects) and show no sub-cell ripple. Their mesh-sequence
    figures become the track's and ``stats["keyframe_track_frames"]`` counts them."""
    quality = stats["quality"]
    stats["keyframe_track_frames"] = 0
    taken = np.array(tracked, dtype=bool)
    taken[[kf.frame - frames[0] for kf in keyframes]] = True
    for track in sorted(tracks, key=lambda t: -t.step):  # forward ones first
        order = track.outward()
        rows = [track.first_row + j for j in order]
        free = next((n for n, r in enumerate(rows[1:]) if taken[r]), len(rows) - 1)
        if free == 0:
            continue
        order, rows = order[:free + 1], rows[:free + 1]
        figures = [track.figures[j] for j in order]
        rel = [dict(f["shape_keys"]) for f in figures]
        follows = tracked_frames(np.asarray(rows), rel, [stats["topology"][r] for r in rows],
                                 [f["steered"] for f in figures],
                                 [f["volumes"] for f in figures],
                                 [f["flipped"] for f in figures], LIMITS,
                                 [f["ripple"] for f in figures])
        track.ships = int(np.count_nonzero(follows)) - 1
        for n in range(1, track.ships + 1):
            taken[rows[n]] = True
            quality["mesh_sequence"][rows[n]] = rel[n]
        stats["keyframe_track_frames"] += track.ships


def _artist_template(keyframe, mesh, tracked_mesh):
    """(vertices, triangles, MeshAttributes) of the first keyframe's own mesh, or None for
    the grid's template (asked for, or loose vertices that no surface carries)."""
    if tracked_mesh not in ("keyframe", "grid"):
        raise ValueError(f'template must be "keyframe" or "grid", got {tracked_mesh!r}.')
    v, tris, loose = mesh[:3]
    if tracked_mesh == "grid" or loose:
        return None
    attrs = keyframe.attributes
    if attrs is None:
        return v, tris, MeshAttributes.from_triangles(tris)
    try:
        attrs.check(len(v))
    except ValueError as exc:
        raise ValueError(f"{keyframe_label(0, keyframe)}: {exc}") from None
    return v, attrs.triangles(), attrs


def _relative_to_keyframes(per_frame, frames, key_frames):
    """The artist's mesh measured against how it sits on the keyframes themselves.

    The artist's mesh is not the grid's surface (faces inside the body, open holes, detail
    finer than a cell), so its raw figures differ from the grid's already on the keyframe
    frames. Each frame's area ratio and coverage are divided by the keyframe frames' own
    values interpolated in time, and its inverted share reduced by the larger of its two
    keyframes' shares (faces finer than a cell, such as an eyelid, turn against the grid's
    gradient by amounts that vary from frame to frame): what a frame adds to what the
    keyframes show.
    """
    frames = np.asarray(frames)
    key_frames = np.asarray(key_frames)
    at = [per_frame[int(f - frames[0])] for f in key_frames]
    seg = np.clip(np.searchsorted(key_frames, frames, side="right") - 1, 0, len(key_frames) - 2)
    for name, relative in (("area_ratio", np.divide), ("coverage", np.divide),
                           ("inverted_fraction", np.subtract)):
        values = np.array([q[name] for q in at])
        ref = (np.interp(frames, key_frames, values) if relative is np.divide
               else np.maximum(values[seg], values[seg + 1]))
        for q, r in zip(per_frame, ref):
            value = relative(q[name], r) if r > 0 or relative is np.subtract else q[name]
            q[name] = float(min(value, 1.0) if name == "coverage" else max(value, 0.0))


def _keyframes_are_reference(per_frame, frames, key_frames):
    """On a keyframe's frame the mesh sequence shows the keyframe mesh itself: the reference
    `_relative_to_keyframes` measures the shape keys against, so its relative figures there
    are neutral (area ratio 1, coverage 1, no inverted area beyond the keyframe's own), and
    its two-way distance to the keyframe is 0 without measuring a mesh against itself."""
    for f in key_frames:
        per_frame[int(f - frames[0])].update(area_ratio=1.0, coverage=1.0, inverted_fraction=0.0,
                                             keyframe_mean=0.0, keyframe_max=0.0)


def _keyframe_attributes(keyframes, meshes, first):
    """Per keyframe frame, the `MeshAttributes` of its own mesh: the first keyframe's are the
    template's (``first``); another keyframe's are its own when they fit its mesh, else its
    triangles."""
    out = {}
    for k, (kf, mesh) in enumerate(zip(keyframes, meshes)):
        attrs = first if k == 0 else kf.attributes
        try:
            if attrs is not None:
                attrs.check(len(mesh[0]))
        except ValueError:
            attrs = None
        out[int(kf.frame)] = attrs if attrs is not None else MeshAttributes.from_triangles(mesh[1])
    return out


def _measure_keyframes(quality, keyframes, chain, spacing, outputs):
    """Add, for each of ``outputs``, the two-way distance to the keyframe mesh the artist
    gave on every keyframe frame."""
    from ..fields.mesh import triangulate

    for kf in keyframes:
        i = int(kf.frame - chain.frames[0])
        kv = np.asarray(kf.vertices, dtype=float).reshape(-1, 3)
        kt = triangulate(kf.faces, len(kv))
        for name in outputs:
            mesh = (chain.vertices[i], chain.faces) if name == "shape_keys" else chain.surfaces[i]
            quality[name][i].update(keyframe_distance(*mesh, kv, kt, spacing))
