"""The bake's stages, each runnable on its own over a job directory (bpy-free).

They are the bake itself taken apart where its work is independent, not a second
implementation: `pipeline.plan_bake` and `pipeline.distance_fields` (prepare), a pair's
maps as `chain.Inbetweens` solves them (maps), the bends of every segment's paths
(`Inbetweens.bend_all`) and the template each segment starts from (`Chain.end_template`)
(paths), one segment's frames (`Chain.segment`), and `pipeline.finish_bake` with the
output mesh the worker makes (assemble). Pairs and segments are numbered from 1, as the
panel's "keyframes 1 → 2" counts them.

Each stage reads the files of the stages before it and writes its own (`store`); rerun,
it writes the same file again. Prepare and Maps, given the folder where the exporting
session's bakes kept their work (`core.bake.cache.WorkCache`, `work_cache`), take the
distance grids and maps it holds for exactly their inputs instead of computing them: the
same results, so the job's output is the same.

The core's bake is imported in the stages' functions: the command line imports this module
for every stage (and for ``--help``), and a task starts its helper process first, which
loads the core while the task imports the rest of it and reads its files.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.base.parallel import Helper, can_start_helper, cores, one_blas_thread
from ..core.base.progress import Reporter
from . import store

if TYPE_CHECKING:  # read by type checkers only (module docstring)
    from ..core.bake.animation import Animation
    from ..core.bake.cache import WorkCache

__all__ = ["prepare", "solve_pair", "bend_paths", "make_segment", "assemble", "JobFiles",
           "work_cache"]


class JobFiles:
    """Where each stage's file lives in the job directory ``root``."""

    def __init__(self, root: str) -> None:
        self.root = os.path.abspath(root)

    def path(self, *parts: str) -> str:
        return os.path.join(self.root, *parts)

    @property
    def inputs(self) -> str:
        return self.path("inputs.npz")

    @property
    def plan(self) -> str:
        return self.path("plan.npz")

    def pair(self, i: int) -> str:
        return self.path("maps", f"pair_{i}.npz")

    def paths(self, i: int) -> str:
        return self.path("paths", f"segment_{i}.npz")

    def segment(self, i: int) -> str:
        return self.path("segments", f"segment_{i}.npz")


def work_cache(directory: str | None) -> WorkCache | None:
    """The work a session's bakes kept in ``directory`` (a `WorkCache` on it), or None when
    no such folder is here (none given, or a farm machine without it): then every result is
    computed."""
    from ..core.bake.cache import WorkCache

    return WorkCache(directory) if directory and os.path.isdir(directory) else None


def prepare(arguments: dict[str, Any], output_mode: str | None, job_dir: str,
            source: dict[str, str], progress: Callable[[float, str], None] | None = None,
            cache_dir: str | None = None) -> dict[str, Any]:
    """Write the job directory's inputs, plan and the keyframes' distance grids.

    Parameters
    ----------
    arguments : dict
        `pipeline.bake`'s keyword arguments (the keyframes, the feature pairs and their
        names, and the bake's `BakeOptions`), as the panel's Bake passes them to the worker.
    output_mode : str
        The output setting (`meshdata.resolve_output`).
    job_dir : str
    source : dict
        Where the inputs were read (``scene``: the .blend's path, ``scene_name``), kept in
        the manifest.
    progress : callable, optional
    cache_dir : str, optional
        The folder of the work kept by content (`work_cache`).

    Returns
    -------
    dict, the manifest.
    """
    from ..core.bake.pipeline import distance_fields, plan_bake

    files, rep = JobFiles(job_dir), Reporter(progress)
    inputs = {"arguments": arguments, "output_mode": output_mode}
    plan = plan_bake(**arguments)  # refuses bad input before any file is written
    t0 = time.perf_counter()
    with _task_helper() as helper, one_blas_thread():
        phis = distance_fields(plan, rep.sub(0.0, 0.95), helper=helper,
                               cache=work_cache(cache_dir))
    plan.stats["sdf_seconds"] = time.perf_counter() - t0
    job = store.fingerprint(inputs)
    store.save(files.inputs, {"job": job, "inputs": inputs})
    store.save(files.plan, {"job": job, "plan": plan, "phis": phis})
    n = len(plan.keyframes)
    manifest = dict(source, fingerprint=job, keyframes=n, segments=n - 1,
                    frames=[int(f) for f in plan.frames],
                    resolution=int(plan.options.resolution))
    store.write_manifest(job_dir, manifest)
    rep(1.0, f"prepared {n} keyframes, {n - 1} segments")
    return manifest


def solve_pair(job_dir: str, pair: int | Sequence[int],
               progress: Callable[[float, str], None] | None = None,
               cache_dir: str | None = None) -> None:
    """Solve the maps of pair ``pair`` (keyframes ``pair`` -> ``pair + 1``), both ways, or of
    every pair in ``pair`` (a sequence): their maps shared between this process and a
    helper, each taking the next map when it is free, as the local bake shares them; those
    the work kept in ``cache_dir`` holds (`work_cache`) are taken from it."""
    with _task_helper() as helper:
        files, job, plan, chain = _open(job_dir, work_cache(cache_dir))
        pairs = [pair] if np.ndim(pair) == 0 else list(pair)
        ks = [_index(p, len(plan.keyframes) - 1, "pair") for p in pairs]
        with one_blas_thread():  # one map here, one there
            chain.inbetweens.solve(ks, helper, Reporter(progress))
    for p, k in zip(pairs, ks):
        store.save(files.pair(p), {"job": job, "maps": chain.inbetweens.solved[k]})


def bend_paths(job_dir: str, progress: Callable[[float, str], None] | None = None) -> None:
    """Every segment's bends (`spline.Bend`, None when no path bends) and the template's
    vertices on its first frame, from every pair's maps; a file per segment."""
    files, job, plan, chain = _open(job_dir)
    nseg, rep = len(plan.keyframes) - 1, Reporter(progress)
    inb = chain.inbetweens
    inb.solved.update({k: _read(files.pair(k + 1), job, f"maps {job_dir} --pair {k + 1}")["maps"]
                       for k in range(nseg)})
    with one_blas_thread():
        if inb.bends is not None:
            inb.bend_all(None, rep.sub(0.0, 0.5))
        starts = [chain.template[0]]
        for k in range(nseg - 1):
            starts.append(chain.end_template(k, starts[-1]))
            rep(0.5 + 0.5 * (k + 1) / nseg, f"template on keyframe {k + 2}")
    for k in range(nseg):
        bends = None if inb.bends is None else inb.bends[k]
        store.save(files.paths(k + 1), {"job": job, "bends": bends, "start": starts[k]})


def make_segment(job_dir: str, segment: int,
                 progress: Callable[[float, str], None] | None = None) -> None:
    """Segment ``segment``'s frames (keyframes ``segment`` -> ``segment + 1``)."""
    with _task_helper() as helper:
        files, job, plan, chain = _open(job_dir)
        k = _index(segment, len(plan.keyframes) - 1, "segment")
        paths = _read(files.paths(segment), job, f"paths {job_dir}")
        inb = chain.inbetweens
        inb.solved[k] = _read(files.pair(segment), job,
                              f"maps {job_dir} --pair {segment}")["maps"]
        if inb.bends is not None:
            inb.bends[k] = paths["bends"]
        with one_blas_thread():
            local, records, stats = chain.segment(k, paths["start"], helper,
                                                  Reporter(progress))
    store.save(files.segment(segment), {"job": job, "frames": local, "records": records,
                                        "stats": stats})


def assemble(job_dir: str, progress: Callable[[float, str], None] | None = None) -> Animation:
    """The bake's `Animation` from every segment's frames, exactly as the worker returns
    it (output mesh included); `store.JobError` naming the segments not made yet."""
    from ..core.bake.chain import Kept
    from ..core.bake.pipeline import finish_bake
    from ..core.surface.meshdata import resolve_output

    files, job, plan, chain = _open(job_dir)
    nseg = len(plan.keyframes) - 1
    missing = [i for i in range(1, nseg + 1) if not os.path.isfile(files.segment(i))]
    if missing:
        raise store.JobError(
            f"{job_dir!r} lacks the frames of segment{'s' if len(missing) > 1 else ''} "
            f"{', '.join(map(str, missing))} of {nseg}: run "
            + "; ".join(f"'farm segment {job_dir} --segment {i}'" for i in missing) + ".")
    frames = np.asarray(plan.frames)
    kept = Kept(np.arange(frames[0], frames[-1] + 1), chain.template[0].shape, chain.outputs)
    seconds = plan.stats.get("sdf_seconds", 0.0)
    for i in range(1, nseg + 1):
        part = _read(files.segment(i), job, f"segment {job_dir} --segment {i}")
        kept.add(part["frames"] - frames[0], part["records"])
        kept.stats["segments"].append(part["stats"])
        seconds += part["stats"].get("map_seconds", 0.0) + part["stats"]["template_seconds"]
    t0 = time.perf_counter() - seconds
    result = finish_bake(plan, kept.animation(chain, seconds), t0, Reporter(progress))
    mode = _read(files.inputs, job, _PREPARE)["inputs"]["output_mode"]
    if mode is not None:
        result.output_mesh(resolve_output(mode, result.stats)[0])
    return result


def inputs(job_dir: str) -> dict[str, Any]:
    """What ``prepare`` was given: {"arguments": ..., "output_mode": ...}."""
    files = JobFiles(job_dir)
    manifest = store.read_manifest(job_dir)
    return _read(files.inputs, manifest["fingerprint"], _PREPARE)["inputs"]


def _open(job_dir, cache=None):
    """(files, the inputs' fingerprint, `BakePlan`, `chain.Chain`) of a prepared job, its
    maps looked for in ``cache`` when given."""
    files = JobFiles(job_dir)
    job = store.read_manifest(job_dir)["fingerprint"]
    data = _read(files.plan, job, _PREPARE)
    plan = data["plan"]
    return files, job, plan, plan.chain(data["phis"], cache=cache)


#: How a missing or stale file of ``prepare`` is made again.
_PREPARE = "prepare SCENE.blend DIR"


def _read(path, job, command):
    """The file ``path`` that ``farm command`` made for the inputs ``job``; `store.JobError`
    saying to run it when the file is missing or was made for other inputs."""
    if not os.path.isfile(path):
        raise store.JobError(f"{path!r} is missing: run 'farm {command}' first.")
    data = store.load(path)
    if data.get("job") != job:
        raise store.JobError(f"{path!r} was made for other inputs (another scene, or the scene "
                             f"changed since): run 'farm {command}' again.")
    return data


def _index(number, count, what):
    """0-based index of the 1-based ``number``, or `store.JobError`."""
    if not 1 <= int(number) <= count:
        raise store.JobError(f"--{what} must be from 1 to {count} (this job has {count} "
                             f"segment{'s' if count > 1 else ''}), got {number}.")
    return int(number) - 1


@contextlib.contextmanager
def _task_helper() -> Iterator[Helper | None]:
    """A helper process for the second core, as the worker starts one (None on one core, or
    where none can start: in Blender's own process, for prepare). Started first thing in a
    task, it imports while the task reads its files."""
    from ..core.bake.chain import HELPER_PRELOAD

    helper = Helper(HELPER_PRELOAD) if cores() >= 2 and can_start_helper() else None
    try:
        yield helper
    finally:
        if helper is not None:
            helper.close()
