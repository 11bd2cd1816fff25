"""The bake in a worker process: `core.bake.pipeline.bake` in a Python process of its own.

Why a process and not a thread of Blender's: the core's long numpy/scipy calls hold the
GIL, so a thread stalls Blender's main loop for as long as each call lasts, and a crash or
an out-of-memory kill in the core would take the artist's session with it. With the work in
another process the main loop only polls, a crash is an exit code, and cancel always ends
the work at once (the process is killed; it holds nothing the scene depends on). The
worker starts one helper process of its own for the second core (`core.base.parallel`), which
ends with it.

The worker is the same Python (``sys.executable``: Blender's bundled Python, or the Python
that has the bpy module) running ``python -m <package>.worker`` on this package's own files;
it never imports bpy. Its ``PYTHONPATH`` holds the folder above this package and the folders
numpy, scipy, scikit-image and threadpoolctl were found in (in Blender: the extension's
unpacked wheels), ahead of the parent's own ``PYTHONPATH``.

Protocol: the bake's messages (`core.base.wire`) on the worker's standard streams.

- parent -> stdin: the sender's package name, then `bake`'s keyword arguments (the
  keyframes, the feature pairs and their names, the `BakeOptions`) and,
  optionally, ``output_mode`` (the output setting: the worker then also makes the output's
  mesh, `Animation.output_mesh`, so Blender's main loop only copies it in) and ``cache_dir``
  (a folder where the bakes keep their work by content, `core.bake.cache.WorkCache`: the
  distance grids and maps an edit left as they were are taken from it). The worker
  leaves as soon as stdin reaches its end (the parent has gone: `wire.follow_parent`).
- worker -> stdout: ``("progress", fraction, message)`` any number of times, then
  ``("done", animation)`` or ``("failed", type name, text, is a ValueError)``. Whatever else
  the worker prints goes to stderr (the console), never into this stream.

Pickles name this package's classes by the sender's package name (in an installed extension
``bl_ext.user_default.keyframe_implicit``, in the worker ``keyframe_implicit``); the receiver
maps them onto its own (`wire.receive`'s ``rename``).

The live preview's worker (`preview_worker`) is started, lowered and connected the same
way: `start_process`, `lower_priority`, `connect_parent`.

The worker imports the core's bake (`main`) only after it has started its helper and read
the inputs: that import is the longest part of its start, and the helper's interpreter
loads meanwhile.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import os
import signal
import site
import subprocess
import sys
import traceback
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from .core.base.parallel import Helper, cores
from .core.base.progress import Cancelled
from .core.base.wire import Stream, follow_parent, receive, send

if TYPE_CHECKING:  # read by type checkers only: the worker imports the core when it bakes
    from .core.bake.animation import Animation

__all__ = ["Worker", "WorkerError", "start_process", "lower_priority", "connect_parent",
           "no_sigpipe", "python_path", "NICENESS"]

#: This package's name here, and as the worker imports it (the name of its folder).
ROOT = __package__
WORKER_ROOT = os.path.basename(os.path.dirname(os.path.abspath(__file__)))
#: The distributions the core imports, found by the worker where the parent found them.
_NEEDS = ("numpy", "scipy", "skimage", "threadpoolctl")
#: Processes the bake uses (`BakeOptions.processes`): the worker and, on a
#: machine with two cores or more, one helper it starts for the second core.
_PROCESSES = 2 if cores() >= 2 else 1
#: How far below Blender's own the worker's scheduling priority is (a POSIX nice increment;
#: on Windows the worker starts in the below-normal class): when the bake and Blender's main
#: loop want the same cores, the main loop and its drawing go first. The worker's helper
#: process inherits it.
NICENESS = 10
_BELOW_NORMAL = getattr(subprocess, "BELOW_NORMAL_PRIORITY_CLASS", 0)  # 0: not Windows


class WorkerError(RuntimeError):
    """The worker process failed in a way the user cannot fix by changing the input: it
    crashed, ran out of memory, or the core raised something other than a ValueError.
    The text says what happened, at which stage, and what to try."""


@contextlib.contextmanager
def no_sigpipe() -> Iterator[None]:
    """Within this block a write to a process that has ended raises BrokenPipeError instead
    of SIGPIPE: Python ignores that signal, but Blender's embedded interpreter does not, and
    its default action ends Blender. The signal is blocked in this thread for the block and
    one that a failed write left pending is taken before it is unblocked (POSIX; Windows has
    no SIGPIPE)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGPIPE})
    try:
        yield
    finally:
        if signal.SIGPIPE not in before:
            signal.sigtimedwait({signal.SIGPIPE}, 0)
            signal.pthread_sigmask(signal.SIG_SETMASK, before)


def python_path() -> str:
    """The worker's PYTHONPATH: the folder holding this package, then the folders numpy,
    scipy, scikit-image and threadpoolctl come from unless they are this Python's own
    site-packages (which the worker has anyway), then the parent's PYTHONPATH."""
    own = set(site.getsitepackages())
    dirs = [os.path.dirname(os.path.dirname(os.path.abspath(__file__)))]
    for name in _NEEDS:
        spec = importlib.util.find_spec(name)
        if spec is None:
            continue
        # a package's folder, or a single module's file (threadpoolctl.py)
        inside = list(spec.submodule_search_locations or []) or [spec.origin]
        where = os.path.dirname(os.path.abspath(inside[0]))
        if where not in own and where not in dirs:
            dirs.append(where)
    given = os.environ.get("PYTHONPATH", "").split(os.pathsep)
    return os.pathsep.join(dirs + [p for p in given if p and p not in dirs])


def start_process(module: str) -> tuple[subprocess.Popen, Stream]:
    """Start this package's ``module`` (``worker`` or ``preview_worker``) as a worker
    process: the same Python, ``python -P -m`` (no working directory on its sys.path: it
    could shadow any module) with `python_path`, at a lower priority on Windows (on POSIX
    the worker lowers its own: `lower_priority`). Returns the process and the stream to it
    (its stdin and stdout)."""
    process = subprocess.Popen(
        [sys.executable, "-P", "-m", f"{WORKER_ROOT}.{module}"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, creationflags=_BELOW_NORMAL,
        env=dict(os.environ, PYTHONPATH=python_path()))
    return process, Stream(process.stdout, process.stdin)


def lower_priority() -> None:
    """In a worker process: lower its scheduling priority by `NICENESS` (POSIX; a no-op
    elsewhere, where `start_process` starts it below normal)."""
    if hasattr(os, "nice"):
        os.nice(NICENESS)


def connect_parent() -> tuple[Stream, str]:
    """In a worker process: the stream to the parent and the parent's package name (its
    first message). Standard output is kept for the answers alone: whatever Python or a
    library prints goes to stderr (the console), never into the stream. Both ends are
    unbuffered files, so a thread that follows the parent (`wire.follow_parent`) holds no
    buffer's lock when the interpreter exits."""
    answers = open(os.dup(1), "wb", buffering=0)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    parent = Stream(open(0, "rb", buffering=0, closefd=False), answers)
    return parent, receive(parent)  # a str: no class to rename


class Worker:
    """One worker process running `core.bake.pipeline.bake` on ``arguments`` (started at once).

    Parameters
    ----------
    arguments : dict
        `bake`'s keyword arguments, all picklable (no callables), and optionally
        ``output_mode`` (see the protocol above).
    """

    def __init__(self, arguments: dict) -> None:
        self.arguments = arguments
        self.stage = "starting"  # the last progress message, named in failure messages
        self.cancelled = False
        self.process, self._stream = start_process("worker")

    def cancel(self) -> None:
        """End the bake now (from any thread): the process is killed, `result` raises
        `Cancelled`."""
        self.cancelled = True
        self.process.kill()

    def result(self, progress: Callable[[float, str], object]) -> Animation:
        """Send the inputs, pass progress on to ``progress(fraction, message)`` (in this
        thread) and return the `Animation`, once the worker has ended.

        Raises `Cancelled` after `cancel`, ValueError with the core's own text on input the
        user must fix, and `WorkerError` on any other failure.
        """
        answer = None
        try:
            self._send_inputs()
            for message in self._messages():
                if message[0] == "progress":
                    self.stage = message[2]
                    progress(message[1], message[2])
                else:
                    answer = message
        finally:
            with no_sigpipe(), contextlib.suppress(OSError):  # flushes what a failed write left
                self.process.stdin.close()
            self.process.stdout.close()
            self.process.wait()
        if self.cancelled:
            raise Cancelled("cancelled by the user")
        if answer is None:
            raise WorkerError(self._exit_text(self.process.returncode))
        if answer[0] == "failed":
            raise self._failure(*answer[1:])
        return answer[1]

    def _send_inputs(self):
        try:
            with no_sigpipe():
                send(self._stream, ROOT)
                send(self._stream, self.arguments)
        except OSError:  # the worker ended early (killed, or it could not start): say why below
            pass

    def _messages(self):
        while True:
            try:
                yield receive(self._stream, (WORKER_ROOT, ROOT))
            except EOFError:
                return

    def _failure(self, kind, text, is_value_error):
        if is_value_error:
            return ValueError(text)
        if kind == "MemoryError":
            return WorkerError(f"The bake's worker process ran out of memory at '{self.stage}': "
                               f"{self._lower_resolution()}")
        return WorkerError(f"{kind} at '{self.stage}': {text}")

    def _exit_text(self, code):
        """What an exit without an answer means for the user."""
        if code == -getattr(signal, "SIGKILL", 9):
            return (f"The bake's worker process ran out of memory (killed by the system) at "
                    f"'{self.stage}': {self._lower_resolution()}")
        if code < 0:
            return (f"The bake's worker process crashed ({_signal_name(-code)}) at "
                    f"'{self.stage}'; the console shows what it printed. Try again, or another "
                    f"resolution.")
        return (f"The bake's worker process stopped unexpectedly (exit code {code}) at "
                f"'{self.stage}'; the console shows what it printed.")

    def _lower_resolution(self):
        return (f"lower the resolution (it is {self.arguments['options'].resolution}), or close "
                "other programs, and bake again.")


def _signal_name(number):
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def main() -> None:
    """The worker: read the inputs from stdin, run `bake` (its options' ``processes`` this
    machine's), answer on stdout."""
    lower_priority()
    # the helper's interpreter loads while this one reads the inputs and imports the core
    # (named, not imported, here: `chain.HELPER_PRELOAD` would import the core first)
    helper = Helper((f"{__package__}.core.bake.chain",)) if _PROCESSES > 1 else None
    parent, sender = connect_parent()
    arguments = receive(parent, (sender, ROOT))
    follow_parent(parent)  # a worker whose parent has gone stops at once, not bakes on
    from .core.bake import pipeline  # only now (module docstring)
    from .core.bake.cache import WorkCache
    from .core.surface.meshdata import resolve_output

    mode = arguments.pop("output_mode", None)
    folder = arguments.pop("cache_dir", None)
    options = dataclasses.replace(arguments.pop("options"), processes=_PROCESSES)
    try:
        try:
            result = pipeline.bake(**arguments, options=options, helper=helper,
                                   cache=None if folder is None else WorkCache(
                                       folder, memory_bytes=0),  # it bakes once: disk only
                                   progress=lambda f, m: send(parent, ("progress", f, m)))
        finally:  # before the output mesh: the helper's memory goes with it
            if helper is not None:
                helper.close()
        if mode is not None:  # the output's mesh, edges and all, made here, not in Blender
            send(parent, ("progress", 1.0, "Preparing the output mesh"))
            result.output_mesh(resolve_output(mode, result.stats)[0])
    except Exception as exc:  # every failure is the parent's to report
        if not isinstance(exc, ValueError):
            traceback.print_exc()
        send(parent, ("failed", type(exc).__name__, str(exc), isinstance(exc, ValueError)))
        return
    send(parent, ("done", result))


if __name__ == "__main__":
    main()
