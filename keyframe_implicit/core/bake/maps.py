"""The maps of a keyframe pair solved, and the pair's in-betweens built from them.

`inbetween` is the whole of one segment before its frames: `solver.solve_map` A -> B
(and B -> A with the feature pairs swapped, for the two-sided transport), then
`levelset.Inbetween.from_map`. The two maps are independent: they run in two threads,
or one here and one in a helper process. Across a chain the maps of several segments
are shared out the same way (`solve_maps_shared`), each process taking the next map
when it is free.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

from ..base.parallel import cores, share
from ..base.progress import Reporter
from ..map import solver
from ..motion.levelset import Inbetween, Recipe

__all__ = ["inbetween", "solve_maps_shared", "from_solved", "split_options", "is_two_sided"]

_TRAJ_OPTIONS = ("trajectory_method", "trajectory_margin_cells", "trajectory_margin_weight")
_LS_OPTIONS = ("transport", "keep_volume", "resample", "idw_radius", "newton_steps", "interpolation")


def inbetween(phi_a, phi_b, grid, features_a, features_b, *, progress=None, cancel=None,
              on_maps=None, **options):
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
    **options
        ``transport``, ``keep_volume``, ``trajectory_method``,
        ``trajectory_margin_cells``, ``trajectory_margin_weight``, ``resample``, ``idw_radius``,
        ``newton_steps``, ``interpolation`` go to `Inbetween.from_map`;
        ``parallel`` (True: solve the two maps at once, in two threads, when two
        cores are free) or ``helper`` (a `parallel.Helper`: the map B -> A is
        solved in that process instead); all others are passed to `solve_map`.

    Returns
    -------
    Inbetween
    """
    rep = Reporter(progress, cancel)
    mine, options = split_options(options)
    parallel = options.pop("parallel", True)
    helper = options.pop("helper", None)
    two_sided = is_two_sided(mine)
    t0 = time.perf_counter()
    if helper is not None:
        res, back, _ = solve_maps_shared([phi_a, phi_b], grid, [(features_a, features_b)],
                                         range(1), two_sided, helper, rep.sub(0.0, 0.8), cancel,
                                         options)[0]
    else:
        res, back = _solve_maps(phi_a, phi_b, grid, features_a, features_b, two_sided,
                                parallel, rep.sub(0.0, 0.8), cancel, options)
    rep(0.8, "trajectories")
    out = from_solved(phi_a, phi_b, grid, res, back, mine, time.perf_counter() - t0,
                      on_maps=on_maps, cancel=cancel)
    rep(1.0, "in-betweens ready")
    return out


def split_options(options):
    """`inbetween`'s ``options`` as (those of `Inbetween.from_map`, the rest: `solve_map`'s,
    ``parallel`` and ``helper``); ``options`` is left as it was."""
    rest = dict(options)
    mine = {k: rest.pop(k) for k in list(rest) if k in _TRAJ_OPTIONS + _LS_OPTIONS}
    return mine, rest


def is_two_sided(mine):
    """Whether `from_map` options ``mine`` ask for the two-sided transport (two maps)."""
    return mine.get("transport", "two-sided") == "two-sided"


def from_solved(phi_a, phi_b, grid, res, back, mine, seconds, on_maps=None, cancel=None):
    """The `Inbetween` of solved maps: ``res`` A -> B and ``back`` B -> A (None: one-sided)
    `solver.MapResult`; ``mine`` the `from_map` options (`split_options`); ``seconds`` the
    time the maps took, for its stats. ``on_maps`` as in `inbetween`."""
    st = {"map_seconds": seconds, "map": res.stats}
    if back is not None:
        st["map_back"] = back.stats
    inputs = dict(mapped_back=None if back is None else back.mapped, material=res.material,
                  components=res.components, **mine)
    if on_maps is not None:
        on_maps(Recipe((phi_a, phi_b, grid, res.mapped), inputs))
    return Inbetween.from_map(phi_a, phi_b, grid, res.mapped, stats=st, map_result=res,
                              map_result_back=back, cancel=cancel, **inputs)


def _solve_maps(phi_a, phi_b, grid, features_a, features_b, two_sided, parallel, rep, cancel,
                options):
    """The map A -> B and, for the two-sided transport, B -> A (feature pairs swapped).

    The two solves are independent: with ``parallel`` and two cores free the
    backward one runs in a second thread (numpy and scipy release the GIL in
    their kernels); it reports no progress of its own and stops when the
    forward one fails or the caller cancels.
    """
    if not two_sided:
        return solver.solve_map(phi_a, phi_b, grid, features_a, features_b, progress=rep,
                         cancel=cancel, **options), None
    if not (parallel and cores() >= 2):
        res = solver.solve_map(phi_a, phi_b, grid, features_a, features_b, progress=rep.sub(0.0, 0.5),
                        cancel=cancel, **options)
        back = solver.solve_map(phi_b, phi_a, grid, features_b, features_a, progress=rep.sub(0.5, 1.0),
                         cancel=cancel, **options)
        return res, back
    failed = threading.Event()

    def stop():
        return failed.is_set() or (cancel is not None and cancel())

    with ThreadPoolExecutor(max_workers=1) as pool:
        job = pool.submit(solver.solve_map, phi_b, phi_a, grid, features_b, features_a, cancel=stop,
                          **options)
        try:
            res = solver.solve_map(phi_a, phi_b, grid, features_a, features_b, progress=rep,
                            cancel=cancel, **options)
        except BaseException:
            failed.set()
            raise
        return res, job.result()


def solve_maps_shared(phis, grid, features, window, two_sided, helper, rep, cancel, options):
    """The maps of the segments in ``window`` of a chain (keyframe fields ``phis``, feature
    pairs ``features`` per segment), shared by this process and the ``helper``.

    The maps (A -> B and, two-sided, B -> A of each segment) are independent jobs, and
    one can take several times another (a merge seen backwards is a split). Two at a time,
    one per process, the process with the short one would wait; here each process takes
    the next job when it is free (`parallel.share`): this process the first (a segment's
    A -> B), the helper the second. With one segment (`inbetween`'s ``helper``) that is
    one map each.

    Returns {segment: (map A -> B, map B -> A or None, seconds)}: a segment's seconds run
    from the end of the one before it (or the window's start) until both its maps are
    solved, so they add up to the window's time.
    """
    t0 = time.perf_counter()
    jobs = [(k, side) for k in window for side in ((0, 1) if two_sided else (0,))]
    mine = []

    def arguments(job):
        k, side = job
        (fa, fb), a, b = features[k], phis[k], phis[k + 1]
        return (a, b, grid, fa, fb) if side == 0 else (b, a, grid, fb, fa)

    def here(job, stop):
        mine.append(job)
        part = rep.sub((len(mine) - 1) / len(jobs), len(mine) / len(jobs))
        return solver.solve_map(*arguments(job), progress=part, cancel=stop, **options)

    def there(job):
        return solver.solve_map, arguments(job), options

    done, ends, _ = share(jobs, here, there, helper, check=rep.check, cancel=cancel)
    out, start = {}, t0
    for k in window:
        end = max([start] + [ends[(k, side)] for side in (0, 1) if (k, side) in ends])
        out[k] = (done[(k, 0)], done.get((k, 1)), end - start)
        start = end
    return out
