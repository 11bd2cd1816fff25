"""Baking: scene -> `BakeInput` (read once, checked) -> core.bake.pipeline.bake (worker
process) -> output (main thread).

`collect` reads the scene once (`scene_io.read`) into a plain description of the bake and
checks that description (`validate.raise_on_errors`); `BakeJob` bakes the same description.

The core runs in a worker process (`keyframe_implicit.worker`): Blender's main loop only
polls it, and a crash or an out-of-memory kill there leaves the session and the scene as
they were. `BakeJob` is the one cancellation path: the modal operator calls
``job.cancel()`` on ESC, a script or test may call it from anywhere (e.g. from
``on_progress``). `BakeJob.apply` writes the result into the scene and must run on the
main thread; `BakeJob.apply_steps` does it in pieces, between turns of the main loop.

Blocking use (scripts, ``blender -b``)::

    obj = bake_scene(bpy.context.scene)            # raises ValueError / Cancelled / WorkerError

Background use (what the modal operator does)::

    job = BakeJob(collect(scene, depsgraph))
    job.start()            # a thread that talks to the worker process
    ... job.poll(), job.fraction, job.message, job.cancel() ...
    if job.state == DONE: obj = job.apply(scene)   # or a step per turn: job.apply_steps(scene)
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Generator
from typing import TYPE_CHECKING

import bpy

from ..core.base.progress import Cancelled
from ..worker import Worker, WorkerError
from . import output, scene_io, validate, volumes, work_cache
from .diagnostics import Diagnostics

if TYPE_CHECKING:  # read by type checkers only
    from ..core.bake.animation import Animation

READY, RUNNING, DONE, CANCELLED, FAILED = "READY", "RUNNING", "DONE", "CANCELLED", "FAILED"


def failure_text(exc: BaseException) -> str:
    """What the user reads about a failed bake: a ValueError's or `WorkerError`'s own text
    (they say what to do), else the exception's type and text."""
    if isinstance(exc, (ValueError, WorkerError)):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


class BakeJob:
    """One run of the core, in a worker process, on data already copied out of the scene.

    Parameters
    ----------
    inputs : scene_io.BakeInput
    on_progress : callable(job, fraction, message), optional
        Called after each progress report, from the thread that runs the job (`run`).
    diagnostics : diagnostics.Diagnostics, optional
        Measures the polling (`Diagnostics.max_poll_gap`: how long the polling main loop
        went without a turn) for whoever asked; None measures nothing.
    """

    def __init__(self, inputs: scene_io.BakeInput,
                 on_progress: Callable[["BakeJob", float, str], None] | None = None,
                 diagnostics: Diagnostics | None = None) -> None:
        self.inputs = inputs
        self.on_progress = on_progress
        self.diagnostics = diagnostics
        self.state = READY
        self.fraction = 0.0
        self.message = "Waiting"
        self.result = None
        self.error = None
        self.seconds = 0.0
        self.notes = []  # what the user should know about a successful bake (warnings)
        self._cancel = threading.Event()
        self._lock = threading.Lock()
        self._thread = None
        self._worker = None
        self._cache_dir = work_cache.directory()  # read here: `_bake` runs in another thread

    # -- cancellation (the path ESC uses) ---------------------------------
    def cancel(self) -> None:
        """Stop the bake now (from any thread): its worker process is ended at once."""
        with self._lock:
            self._cancel.set()
            if self._worker is not None:
                self._worker.cancel()

    @property
    def cancel_requested(self) -> bool:
        """Whether `cancel` was called: what a progress observer can ask before the job
        has reached its end."""
        return self._cancel.is_set()

    # -- running -----------------------------------------------------------
    def _progress(self, fraction, message):
        with self._lock:
            self.fraction = float(fraction)
            self.message = str(message)
        if self.on_progress is not None:
            self.on_progress(self, float(fraction), str(message))

    def _bake(self):
        """The core's `Animation`, from a worker process started here."""
        with self._lock:
            if self._cancel.is_set():
                raise Cancelled("cancelled before start")
            self._worker = Worker(dict(self.inputs.core_arguments(),
                                       output_mode=self.inputs.output_mode,
                                       cache_dir=self._cache_dir))
        return self._worker.result(self._progress)

    def run(self) -> str:
        """Bake in a worker process, waiting in the calling thread; sets state to DONE,
        CANCELLED or FAILED (`error`: a refusal of the core as a ValueError with Blender's
        menu paths, `validate.with_menu_paths`; any other failure as it was raised)."""
        self.state = RUNNING
        t0 = time.perf_counter()
        try:
            self.result = self._bake()
            self.state = DONE
        except Cancelled:
            self.result = None
            self.state = CANCELLED
        except Exception as exc:  # reported to the user by the caller
            self.result = None
            # a refusal of the core (ValueError) says what to fix: add where Blender does it
            self.error = (ValueError(validate.with_menu_paths(str(exc)))
                          if isinstance(exc, ValueError) else exc)
            self.state = FAILED
        finally:
            self.seconds = time.perf_counter() - t0
        return self.state

    def start(self) -> None:
        """Run the job in a daemon thread (which mostly waits for the worker's messages)."""
        self._thread = threading.Thread(target=self.run, name="keyframe_implicit bake", daemon=True)
        self.state = RUNNING
        if self.diagnostics is not None:  # a stall right after the start counts too
            self.diagnostics.started()
        self._thread.start()

    @property
    def finished(self) -> bool:
        """Whether the job has ended (DONE, CANCELLED or FAILED) and its thread with it, so
        that `result`, `error` and `apply` can be read safely."""
        return self.state in (DONE, CANCELLED, FAILED) and (
            self._thread is None or not self._thread.is_alive())

    def join(self, timeout: float | None = None) -> None:
        """Wait up to ``timeout`` seconds (None: for ever) for the thread `start` began; at
        once when the job was never started."""
        if self._thread is not None:
            self._thread.join(timeout)

    def poll(self) -> bool:
        """What the main loop calls on each of its turns while the bake runs (the modal
        operator's timer events): returns `finished` at once, never waiting for the job
        (`Diagnostics.polled` counts the turn when diagnostics were asked for)."""
        if self.diagnostics is not None:
            self.diagnostics.polled()
        return self.finished

    def status(self) -> tuple[float, str]:
        """(fraction, message) of the last progress report, safe from any thread."""
        with self._lock:
            return self.fraction, self.message

    def error_message(self) -> str:
        """What the user reads about the failure (`failure_text`); "" when nothing failed."""
        return "" if self.error is None else failure_text(self.error)

    # -- writing back (main thread only) ------------------------------------
    def apply(self, scene: bpy.types.Scene) -> bpy.types.Object:
        """Write the result into ``scene`` (main thread); returns the output object."""
        return output.run_steps(self.apply_steps(scene))

    def apply_steps(self, scene: bpy.types.Scene) -> Generator[None, None, bpy.types.Object]:
        """`apply` a piece at a time (`apply_result_steps`): a generator that yields between
        pieces and returns the output object. The modal bake runs pieces until its budget
        per turn of the main loop is spent and keeps polling (`poll`), so a measured poll
        gap counts the writing too. The core's notes become `notes`, with Blender's menu
        paths."""
        if self.state != DONE:
            raise RuntimeError(f"Nothing to apply: the bake is {self.state.lower()}.")
        self.notes = []
        obj = yield from apply_result_steps(scene, self.inputs, self.result, self.notes)
        return obj


def apply_result(scene: bpy.types.Scene, inputs: scene_io.BakeInput, result: Animation,
                 notes: list[str] | None = None) -> bpy.types.Object:
    """Write a finished bake into ``scene`` (main thread); returns the output object.

    Parameters
    ----------
    scene : bpy.types.Scene
    inputs : scene_io.BakeInput
        What was baked (its output settings, resolution and materials).
    result : core.bake.animation.Animation
        The bake's result: a `BakeJob`'s, or the farm's stages' (`blender.farm`).
    notes : list, optional
        Receives what the user should know about the result (warnings): the bake's own,
        with Blender's menu paths (`validate.with_menu_paths`), and the writer's.
    """
    return output.run_steps(apply_result_steps(scene, inputs, result, notes))


def apply_result_steps(scene: bpy.types.Scene, inputs: scene_io.BakeInput, result: Animation,
                       notes: list[str] | None = None
                       ) -> Generator[None, None, bpy.types.Object]:
    """`apply_result` a piece at a time (`output.write_steps`): a generator that yields
    between pieces and returns the output object. Closed half way (the close reaches the
    writer, which removes what it made), it leaves the scene as it was (OpenVDB files
    already written stay on disk)."""
    notes = [] if notes is None else notes
    stats = getattr(result, "stats", {}) or {}
    notes.extend(validate.with_menu_paths(n) for n in stats.get("notes", []))
    settings = scene.keyframe_implicit
    paths = volumes.write_result(settings, result) if inputs.levelsets else []
    obj = yield from output.write_steps(scene, settings, result, resolution=inputs.resolution,
                                        notes=notes, material_names=inputs.material_names)
    if paths:
        vol = volumes.add_volume_object(obj, paths, int(result.frames[0]))
        obj["kfi_report"] += (f" OpenVDB volume '{vol.name}': {len(paths)} files in "
                              f"{os.path.dirname(paths[0])}.")
    return obj


def collect(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None, resolution: int = 0
            ) -> scene_io.BakeInput:
    """The bake ``scene``'s settings describe: read once and checked.

    Parameters
    ----------
    scene : bpy.types.Scene
    depsgraph : bpy.types.Depsgraph
        Evaluates the keyframe objects.
    resolution : int, optional
        The grid resolution; 0 or less means the scene setting.

    Returns
    -------
    scene_io.BakeInput
        What `BakeJob` bakes: the one reading of the scene (`scene_io.read`), the same
        object the checks passed.

    Raises
    ------
    ValueError
        What is wrong and what to do, when the checks (`validate.raise_on_errors`) find a
        blocking problem. The scene is left on the frame it was on.
    """
    inputs = scene_io.read(scene, depsgraph, resolution)
    validate.raise_on_errors(inputs)
    return inputs


def bake_scene(scene: bpy.types.Scene, resolution: int = 0,
               depsgraph: bpy.types.Depsgraph | None = None,
               on_progress: Callable[[BakeJob, float, str], None] | None = None,
               notes: list[str] | None = None) -> bpy.types.Object:
    """Blocking bake of ``scene``'s setup; returns the output object.

    ``notes``, a list, receives what the user should be told about the result
    (faces reoriented, loose vertices ignored, a previous output kept, ...).

    Raises ValueError (setup or input problems, with what to do), `Cancelled`
    (``on_progress`` called ``job.cancel()``), or `WorkerError` (the worker process crashed,
    ran out of memory, or the core failed otherwise).
    The scene is unchanged unless the bake succeeds.
    """
    if depsgraph is None:
        if bpy.context.scene == scene:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        else:
            depsgraph = scene.view_layers[0].depsgraph
            depsgraph.update()
    job = BakeJob(collect(scene, depsgraph, resolution), on_progress=on_progress)
    job.run()
    if job.state == CANCELLED:
        raise Cancelled("Bake cancelled; the scene is unchanged.")
    if job.state == FAILED:
        raise job.error
    obj = job.apply(scene)
    if notes is not None:
        notes.extend(job.notes)
    return obj

