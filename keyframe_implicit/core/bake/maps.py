"""The maps of a keyframe pair solved, and the pair's in-betweens built from them.

`inbetween` is the whole of one segment before its frames: `solver.solve_map` A -> B
(and B -> A with the feature pairs swapped, for the two-sided transport), then
`levelset.Inbetween.from_map`. The two maps are independent: they run in two threads,
or one here and one in a helper process. Across a chain the maps of several segments
are shared out the same way (`solve_maps_shared`), each process taking the next map
when it is free.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

from ..base.parallel import cores, share
from ..base.progress import Reporter
from ..motion.finepaths import on_motion_grid, same_width
from ..motion.levelset import Inbetween, Recipe
from .options import BakeOptions, refuse_unread
from .steps import MAPS, PATHS

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np
    from numpy.typing import ArrayLike

    from ..base.grid import Grid
    from ..base.parallel import Helper
    from ..map.options import MapOptions
    from ..map.result import MapResult
    from ..motion.options import MotionOptions
    from ..motion.spline import Bend

__all__ = ["inbetween", "pair_inbetweens", "solve_maps_shared", "solve_fields", "on_solve_grid",
           "from_solved"]


def inbetween(phi_a: ArrayLike, phi_b: ArrayLike, grid: Grid, features_a: ArrayLike,
              features_b: ArrayLike, *, progress: Callable[[float, str], object] | None = None,
              cancel: Callable[[], bool] | None = None,
              on_maps: Callable[[Recipe], object] | None = None, parallel: bool = True,
              helper: Helper | None = None, motion_grid: Grid | None = None,
              **options: Any) -> Inbetween:
    """Solve the maps between two keyframes and return their in-betweens.

    ``inbetween = solve_map (A -> B, and B -> A with the feature pairs swapped
    for the two-sided transport) + Inbetween.from_map``.

    Parameters
    ----------
    phi_a, phi_b : ndarray, grid.shape
        Signed distance grids of keyframes A and B.
    grid : Grid
    features_a, features_b : (N, d) arrays
        Feature points of A and their targets in B.
    progress, cancel : callables, optional (see `progress.Reporter`).
    on_maps : callable, optional
        Called with the in-betweens' `Recipe` once the maps are solved, before this
        process builds its trajectories: a caller may hand it to another process
        (`parallel.Helper`), which builds its own copy meanwhile.
    parallel : bool
        Solve the two maps at once, in two threads, when two cores are free.
    helper : `parallel.Helper`, optional
        Solve the map B -> A in that process instead.
    motion_grid : Grid, optional
        A coarser grid covering ``grid``'s box to solve the maps and the trajectories on
        (`gridfit.motion_grid`); the fields travel on ``grid`` (docs/method.md, section 11).
    **options
        The fields of `motion.options.MotionOptions` (``transport``, ``resample``, ...)
        and of `map.options.MapOptions` (``volume_weight``, ``margin_cells``, ...), read
        as `options.BakeOptions.from_keywords` reads them (a pair reads its ``map`` and
        ``motion``); an unknown one is refused (ValueError).

    Returns
    -------
    Inbetween
    """
    refuse_unread(options, BakeOptions.stage_names("map", "motion"), "inbetween")
    chosen = BakeOptions.from_keywords(**options)
    return pair_inbetweens(phi_a, phi_b, grid, (features_a, features_b), chosen.map,
                           chosen.motion, parallel=parallel, helper=helper, progress=progress,
                           cancel=cancel, on_maps=on_maps, motion_grid=motion_grid)


def pair_inbetweens(phi_a: ArrayLike, phi_b: ArrayLike, grid: Grid,
                    features: Sequence[ArrayLike], map_options: MapOptions,
                    motion_options: MotionOptions, *, parallel: bool = True,
                    helper: Helper | None = None,
                    progress: Callable[[float, str], object] | None = None,
                    cancel: Callable[[], bool] | None = None,
                    on_maps: Callable[[Recipe], object] | None = None,
                    motion_grid: Grid | None = None) -> Inbetween:
    """`inbetween` with its options as the two stages' objects (``features``: the pair
    (points_a, points_b))."""
    rep = Reporter(progress, cancel)
    two_sided = motion_options.two_sided
    t0 = time.perf_counter()
    ends = solve_fields([phi_a, phi_b], grid, motion_grid)
    solve_grid = grid if motion_grid is None else motion_grid
    map_options = on_solve_grid(map_options, grid, solve_grid)
    if helper is not None:
        res, back, _ = solve_maps_shared(ends, solve_grid, [features], range(1), two_sided,
                                         helper, rep.sub(0.0, 0.8), cancel, map_options)[0]
    else:
        res, back = _solve_maps(ends, 0, solve_grid, features, two_sided, parallel,
                                rep.sub(0.0, 0.8), cancel, map_options)
    with rep.sub(0.8, 1.0).step(PATHS, 0, 1):
        return from_solved(phi_a, phi_b, grid, res, back, motion_options,
                           time.perf_counter() - t0, on_maps=on_maps, cancel=cancel)


def on_solve_grid(map_options: MapOptions, grid: Grid, solve_grid: Grid) -> MapOptions:
    """``map_options`` for a solve on ``solve_grid``: the map's margin keeps its width in
    world units (``margin_cells`` counts the surface grid's cells; `finepaths.same_width`)."""
    if solve_grid == grid:
        return map_options
    return dataclasses.replace(
        map_options, margin_cells=same_width(map_options.margin_cells, grid, solve_grid))


def solve_fields(phis: Sequence[ArrayLike], grid: Grid,
                 motion_grid: Grid | None) -> Sequence[ArrayLike]:
    """The keyframes' fields on the grid their maps are solved on: ``phis`` themselves, or
    read at the nodes of the ``motion_grid`` (`OnMotionGrid`)."""
    if motion_grid is None:
        return list(phis)
    return OnMotionGrid(phis, grid, motion_grid)


class OnMotionGrid(Sequence):
    """Keyframe fields read at the nodes of a motion grid (`finepaths.on_motion_grid`),
    each the first time it is asked for: a task that solves one pair's maps reads two,
    one that only builds trajectories from solved maps none."""

    def __init__(self, phis: Sequence[ArrayLike], grid: Grid, motion_grid: Grid) -> None:
        self.phis, self.grid, self.motion_grid = phis, grid, motion_grid
        self._read = {}

    def __len__(self) -> int:
        return len(self.phis)

    def __getitem__(self, k: int) -> np.ndarray:
        if k not in self._read:  # two threads may both read it: the same array either way
            self._read[k] = on_motion_grid(self.phis[k], self.grid, self.motion_grid)
        return self._read[k]

    def parts(self, k: int, j: int, features: Sequence[ArrayLike]) -> np.ndarray | None:
        """The parts of keyframe ``k``'s map onto keyframe ``j`` (``features``: the pair
        (points of k, points of j)), found on the surface grid, where a gap of one cell
        shows, and read at the motion grid's nodes (`map.parts`)."""
        from ..map.parts import part_labels, parts_on

        parts = part_labels(self.phis[k], self.phis[j], self.grid, *features)
        return None if parts is None else parts_on(parts, self.grid, self.motion_grid)


def _given_parts(phis: Sequence[ArrayLike], k: int, j: int, features: Sequence[ArrayLike],
                 map_options: MapOptions) -> np.ndarray | None:
    """The parts the map of keyframe ``k`` onto ``j`` is given (`OnMotionGrid.parts`), or
    None: on one grid `solve_map` finds them itself."""
    if not (isinstance(phis, OnMotionGrid) and map_options.separate_parts):
        return None
    return phis.parts(k, j, features)


def from_solved(phi_a: ArrayLike, phi_b: ArrayLike, grid: Grid, res: MapResult,
                back: MapResult | None, motion_options: MotionOptions, seconds: float,
                on_maps: Callable[[Recipe], object] | None = None,
                cancel: Callable[[], bool] | None = None,
                bends: tuple[Bend | None, Bend | None] | None = None) -> Inbetween:
    """The `Inbetween` of solved maps: ``res`` A -> B and ``back`` B -> A (None: one-sided)
    `result.MapResult`, solved on ``grid`` or on a motion grid (``res.grid``); ``seconds``
    the time the maps took, for its stats. ``on_maps`` as in `inbetween`; ``bends`` as in
    `Inbetween.from_map`."""
    st = {"map_seconds": seconds, "map": res.stats}
    if back is not None:
        st["map_back"] = back.stats
    inputs = dict(mapped_back=None if back is None else back.mapped, material=res.material,
                  components=res.components, options=motion_options,
                  motion_grid=None if res.grid == grid else res.grid, bends=bends,
                  cracks=tuple(None if m is None or m.tear is None else m.tear.crack
                               for m in (res, back)),
                  parts=tuple(None if m is None else m.parts for m in (res, back)))
    if on_maps is not None:
        on_maps(Recipe((phi_a, phi_b, grid, res.mapped), inputs))
    return Inbetween.from_map(phi_a, phi_b, grid, res.mapped, stats=st, map_result=res,
                              map_result_back=back, cancel=cancel, **inputs)


def _solve_maps(phis, k, grid, features, two_sided, parallel, rep, cancel, map_options):
    """The map A -> B of keyframes ``k`` and ``k + 1`` of ``phis`` and, for the two-sided
    transport, B -> A (feature pairs swapped).

    The two solves are independent: with ``parallel`` and two cores free the
    backward one runs in a second thread (numpy and scipy release the GIL in
    their kernels); it reports no progress of its own and stops when the
    forward one fails or the caller cancels.
    """
    from ..map.solver import solve_map  # here: a process that only reads maps never loads it

    phi_a, phi_b = phis[k], phis[k + 1]
    features_a, features_b = features
    forward = dict(options=map_options,
                   parts=_given_parts(phis, k, k + 1, features, map_options))
    if not two_sided:
        with rep.step(MAPS, 0, 1) as part:
            return solve_map(phi_a, phi_b, grid, features_a, features_b, progress=part,
                             cancel=cancel, **forward), None
    backward = dict(options=map_options,
                    parts=_given_parts(phis, k + 1, k, features[::-1], map_options))
    if not (parallel and cores() >= 2):
        with rep.step(MAPS, 0, 2) as part:
            res = solve_map(phi_a, phi_b, grid, features_a, features_b, progress=part,
                            cancel=cancel, **forward)
        with rep.step(MAPS, 1, 2) as part:
            back = solve_map(phi_b, phi_a, grid, features_b, features_a, progress=part,
                             cancel=cancel, **backward)
        return res, back
    failed = threading.Event()

    def stop():
        return failed.is_set() or (cancel is not None and cancel())

    with ThreadPoolExecutor(max_workers=1) as pool:
        job = pool.submit(solve_map, phi_b, phi_a, grid, features_b, features_a, cancel=stop,
                          **backward)
        try:
            with rep.step(MAPS, 0, 2) as part:
                res = solve_map(phi_a, phi_b, grid, features_a, features_b, progress=part,
                                cancel=cancel, **forward)
        except BaseException:
            failed.set()
            raise
        back = job.result()
        rep.elsewhere(MAPS)
        return res, back


def solve_maps_shared(phis: Sequence[ArrayLike], grid: Grid,
                      features: Sequence[Sequence[ArrayLike]], window: Sequence[int],
                      two_sided: bool, helper: Helper | None, rep: Reporter,
                      cancel: Callable[[], bool] | None, map_options: MapOptions
                      ) -> dict[int, tuple[MapResult, MapResult | None, float]]:
    """The maps of the segments in ``window`` of a chain (keyframe fields ``phis``, feature
    pairs ``features`` per segment), shared by this process and the ``helper``.

    The maps (A -> B and, two-sided, B -> A of each segment) are independent jobs, and
    one can take several times another (a merge seen backwards is a split). Two at a time,
    one per process, the process with the short one would wait; here each process takes
    the next job when it is free (`parallel.share`): this process the first (a segment's
    A -> B), the helper the second. With one segment (`inbetween`'s ``helper``) that is
    one map each.

    Without a helper (None) the segments' maps are solved here, one segment after another
    (its two maps in two threads, `inbetween`'s ``parallel``).

    Returns {segment: (map A -> B, map B -> A or None, seconds)}: a segment's seconds run
    from the end of the one before it (or the window's start) until both its maps are
    solved, so they add up to the window's time.
    """
    from ..map.solver import solve_map

    t0 = time.perf_counter()
    if helper is None:
        out, n = {}, len(window)
        for i, k in enumerate(window):
            start = time.perf_counter()
            res, back = _solve_maps(phis, k, grid, features[k], two_sided, True,
                                    rep.sub(i / n, (i + 1) / n), cancel, map_options)
            out[k] = (res, back, time.perf_counter() - start)
        return out
    jobs = [(k, side) for k in window for side in ((0, 1) if two_sided else (0,))]
    mine = []

    def arguments(job):
        k, side = job
        (fa, fb), a, b = features[k], phis[k], phis[k + 1]
        return (a, b, grid, fa, fb) if side == 0 else (b, a, grid, fb, fa)

    def keywords(job):
        k, side = job
        ends = (k, k + 1, features[k]) if side == 0 else (k + 1, k, features[k][::-1])
        return {"options": map_options, "parts": _given_parts(phis, *ends, map_options)}

    def here(job, stop):
        mine.append(job)
        with rep.step(MAPS, len(mine) - 1, len(jobs)) as part:
            return solve_map(*arguments(job), progress=part, cancel=stop, **keywords(job))

    def there(job):
        return solve_map, arguments(job), keywords(job)

    done, ends, _ = share(jobs, here, there, helper, check=rep.check, cancel=cancel,
                          on_theirs=lambda _job: rep.elsewhere(MAPS))
    out, start = {}, t0
    for k in window:
        end = max([start] + [ends[(k, side)] for side in (0, 1) if (k, side) in ends])
        out[k] = (done[(k, 0)], done.get((k, 1)), end - start)
        start = end
    return out
