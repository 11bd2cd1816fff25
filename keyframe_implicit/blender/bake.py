"""Baking: scene -> `BakeInput` -> core.animate (any thread) -> output (main thread).

`BakeJob` is the one cancellation path: the modal operator calls
``job.cancel()`` on ESC, a script or test may call it from anywhere (e.g. from
``on_progress``). The job only ever touches numpy data; `BakeJob.apply` writes
the result into the scene and must run on the main thread.

Blocking use (scripts, ``blender -b``)::

    obj = bake_scene(bpy.context.scene)            # raises ValueError / Cancelled

Threaded use (what the modal operator does)::

    job = BakeJob(scene_io.collect(scene, depsgraph))
    job.start()            # worker thread
    ... job.fraction, job.message, job.cancel() ...
    if job.state == DONE: job.apply(scene)
"""

import os
import threading
import time

from ..core import pipeline
from ..core.progress import Cancelled
from . import output, scene_io, volumes

READY, RUNNING, DONE, CANCELLED, FAILED = "READY", "RUNNING", "DONE", "CANCELLED", "FAILED"


class BakeJob:
    """One run of the core on data already copied out of the scene.

    Parameters
    ----------
    inputs : scene_io.BakeInput
    on_progress : callable(job, fraction, message), optional
        Called from the thread running the core after each progress report.
    """

    def __init__(self, inputs, on_progress=None):
        self.inputs = inputs
        self.on_progress = on_progress
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

    # -- cancellation (the path ESC uses) ---------------------------------
    def cancel(self):
        """Ask the running core to stop at its next progress check."""
        self._cancel.set()

    @property
    def cancel_requested(self):
        return self._cancel.is_set()

    # -- running -----------------------------------------------------------
    def _progress(self, fraction, message):
        with self._lock:
            self.fraction = float(fraction)
            self.message = str(message)
        if self.on_progress is not None:
            self.on_progress(self, float(fraction), str(message))

    def run(self):
        """Run the core in the calling thread; sets state to DONE, CANCELLED or FAILED."""
        self.state = RUNNING
        t0 = time.perf_counter()
        try:
            if self._cancel.is_set():
                raise Cancelled("cancelled before start")
            inp = self.inputs
            self.result = pipeline.animate(
                inp.keyframes,
                inp.features,
                resolution=inp.resolution,
                weights=inp.weights,
                progress=self._progress,
                cancel=self._cancel.is_set,
                feature_names=inp.feature_names or None,
                levelsets=inp.levelsets,
            )
            self.state = DONE
        except Cancelled:
            self.result = None
            self.state = CANCELLED
        except Exception as exc:  # reported to the user by the caller
            self.result = None
            self.error = exc
            self.state = FAILED
        finally:
            self.seconds = time.perf_counter() - t0
        return self.state

    def start(self):
        """Run the core in a daemon worker thread."""
        self._thread = threading.Thread(target=self.run, name="keyframe_implicit bake", daemon=True)
        self.state = RUNNING
        self._thread.start()

    @property
    def finished(self):
        return self.state in (DONE, CANCELLED, FAILED) and (
            self._thread is None or not self._thread.is_alive())

    def join(self, timeout=None):
        if self._thread is not None:
            self._thread.join(timeout)

    def status(self):
        """(fraction, message) of the last progress report, safe from any thread."""
        with self._lock:
            return self.fraction, self.message

    def error_message(self):
        if self.error is None:
            return ""
        if isinstance(self.error, ValueError):
            return str(self.error)
        return f"{type(self.error).__name__}: {self.error}"

    # -- writing back (main thread only) ------------------------------------
    def apply(self, scene):
        """Write the result into ``scene`` (main thread); returns the output object."""
        if self.state != DONE:
            raise RuntimeError(f"Nothing to apply: the bake is {self.state.lower()}.")
        stats = dict(getattr(self.result, "stats", {}) or {})
        self.notes = list(stats.pop("notes", []))
        stats.setdefault("seconds", self.seconds)
        stats["resolution"] = self.inputs.resolution
        settings = scene.keyframe_implicit
        paths = volumes.write_result(settings, self.result) if self.inputs.levelsets else []
        obj = output.write_animation(scene, settings, self.result,
                                     material_names=self.inputs.material_names, stats=stats,
                                     notes=self.notes)
        if paths:
            vol = volumes.add_volume_object(obj, paths, int(self.result.frames[0]))
            obj["kfi_report"] += (f" OpenVDB volume '{vol.name}': {len(paths)} files in "
                                  f"{os.path.dirname(paths[0])}.")
        return obj


def bake_scene(scene, resolution=0, depsgraph=None, on_progress=None, notes=None):
    """Blocking bake of ``scene``'s setup; returns the output object.

    ``notes``, a list, receives what the user should be told about the result
    (faces reoriented, loose vertices ignored, a previous output kept, ...).

    Raises ValueError (setup or input problems, with what to do), `Cancelled`
    (``on_progress`` called ``job.cancel()``), or the core's own exception.
    The scene is unchanged unless the bake succeeds.
    """
    import bpy

    if depsgraph is None:
        if bpy.context.scene == scene:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        else:
            depsgraph = scene.view_layers[0].depsgraph
            depsgraph.update()
    job = BakeJob(scene_io.collect(scene, depsgraph, resolution), on_progress=on_progress)
    job.run()
    if job.state == CANCELLED:
        raise Cancelled("Bake cancelled; the scene is unchanged.")
    if job.state == FAILED:
        raise job.error
    obj = job.apply(scene)
    if notes is not None:
        notes.extend(job.notes)
    return obj
