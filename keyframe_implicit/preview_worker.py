"""The live preview in a worker process: `core.bake.preview.Preview`, kept alive while the
preview is on.

Launched as the bake's worker is (`worker.start_process`: the same Python, ``-P -m``, the
same ``PYTHONPATH``, never bpy, the bake's messages on its standard streams), for the same
reasons: the core's numpy calls hold the GIL, and a crash must not take Blender with it;
and at the same lower priority, so that Blender's main loop and drawing go first (at
Blender's own priority it was not measurably faster beside a busy window:
benchmarks/README.md, "Live preview"). It stays alive between requests and keeps the
solved in-betweens, so a frame change costs only that frame's transport, level set and
marching cubes.

Protocol (parent -> stdin: the sender's package name, then requests; worker -> stdout:
answers, each carrying the id of the request it answers):

- ``("solve", id, arguments, frame)``: `Preview.solve`'s keyword arguments; answered by
  ``("solved", id, figures)`` (`Preview.figures`, and ``received``, ``started`` and
  ``ended``: when it arrived, started and ended, on ``time.perf_counter``, which all
  processes share), then ``("frame", id, frame, vertices, triangles)``;
- ``("frame", id, frame)``: answered by ``("frame", id, frame, vertices, triangles)``;
- ``("stop", id)``: the work in flight ends, nothing more is answered for earlier ids;
- ``("clear", id)``: the work kept between solves (`Preview.cache`) is dropped at once, not
  answered;
- any failure: ``("failed", id, type name, text, is a ValueError)``.

A solve or a stop cancels the work in flight (the core's ``cancel`` callable, checked
between its steps); a frame cancels a frame in flight. Requests that arrive while the
worker is busy coalesce: it takes the last solve, then the last frame. The worker leaves
when stdin ends (the parent has gone or closed it: `wire.follow_parent`).

The worker imports the core's preview (`main`) only once it follows its parent and takes
requests: that import is the longest part of its start, and a parent gone meanwhile ends it.
"""

from __future__ import annotations

import pickle
import queue
import threading
import time
import traceback
from typing import Any

from .core.base.progress import Cancelled
from .core.base.wire import follow_parent, receive, send
from .worker import ROOT, WORKER_ROOT, connect_parent, lower_priority, no_sigpipe, start_process

__all__ = ["PreviewWorker", "CACHE_BYTES"]

#: The memory the worker keeps results in (`core.bake.cache.WorkCache`): an edit re-solves
#: one pair, so the latest results are the ones taken again; a bound four times this took
#: no more of them over an hour of edits (benchmarks/README.md, "Live preview").
CACHE_BYTES = 64 * 2**20


class PreviewWorker:
    """The parent's side: one preview worker process, started at once.

    Requests go out with `solve`, `frame` and `stop`, which never wait: a thread writes
    them (a solve's meshes fill the pipe faster than the busy worker empties it). `answers`
    returns what has come back since it was last called, also without waiting (another
    thread reads the worker's stream). When the worker has ended, `answers` ends with
    ``("ended", None, exit code)``.
    """

    def __init__(self) -> None:
        self.process, self._stream = start_process("preview_worker")
        self._answers, self._requests = queue.SimpleQueue(), queue.SimpleQueue()
        self._last_id = 0
        self._requests.put(ROOT)
        for target, name in ((self._read, "answers"), (self._write, "requests")):
            threading.Thread(target=target, daemon=True,
                             name=f"keyframe_implicit preview {name}").start()

    def _write(self):
        while True:
            message = self._requests.get()
            if message is None:
                return
            try:
                with no_sigpipe():  # the worker may have just ended: never SIGPIPE in Blender
                    send(self._stream, message)
            except (OSError, ValueError):  # the worker has ended: `answers` says so
                return

    def _request(self, kind, *parts):
        self._last_id += 1
        self._requests.put((kind, self._last_id) + parts)
        return self._last_id

    def solve(self, arguments: dict[str, Any], frame: int) -> int:
        """Ask for a new solve (`Preview.solve`'s keyword arguments) and then ``frame``;
        returns the request's id."""
        return self._request("solve", arguments, int(frame))

    def frame(self, frame: int) -> int:
        """Ask for timeline frame ``frame``'s mesh; returns the request's id."""
        return self._request("frame", int(frame))

    def stop(self) -> int:
        """End the work in flight; returns the request's id."""
        return self._request("stop")

    def clear(self) -> int:
        """Drop the work the worker keeps between solves; returns the request's id."""
        return self._request("clear")

    def _read(self):
        while True:
            try:
                self._answers.put(receive(self._stream, (WORKER_ROOT, ROOT)))
            except (EOFError, OSError, ValueError, pickle.UnpicklingError):
                break
        self._answers.put(("ended", None, self.process.wait()))

    def answers(self) -> list[tuple]:
        """Every answer received since the last call, oldest first (never waits)."""
        out = []
        while True:
            try:
                out.append(self._answers.get_nowait())
            except queue.Empty:
                return out

    @property
    def alive(self) -> bool:
        """Whether the worker process is running."""
        return self.process.poll() is None

    def close(self) -> None:
        """End the worker now (killed: it holds nothing the scene depends on)."""
        self._requests.put(None)
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            try:
                with no_sigpipe():  # closing flushes what a failed write left buffered
                    stream.close()
            except OSError:
                pass


class _Requests:
    """The worker's side of stdin: a thread keeps the last solve and the last frame asked
    for, and cancels the work in flight that a new request makes pointless. When stdin
    ends (the parent has gone) the worker ends, with nothing to answer."""

    def __init__(self, parent, sender, cache):
        self._ready = threading.Condition()
        self._solve = self._frame = None
        self._busy = None  # (kind, threading.Event) of the work in flight
        self._cache = cache
        follow_parent(parent, self._take, rename=(sender, ROOT), code=0)

    def _take(self, message):
        message += (time.perf_counter(),)  # when it arrived
        if message[0] == "clear":  # at once, beside any work: the cache has its own lock
            self._cache.clear()
            return
        with self._ready:
            kind = message[0]
            if kind == "solve":
                self._solve, self._frame = message, None
            elif kind == "frame":
                self._frame = message
            else:  # stop
                self._solve = self._frame = None
            if self._busy is not None and (kind != "frame" or self._busy[0] == "frame"):
                self._busy[1].set()
            self._ready.notify()

    def next(self):
        """The next request to work on (the last solve, else the last frame) and the event
        that cancels it; waits until there is one."""
        with self._ready:
            while self._solve is None and self._frame is None:
                self._ready.wait()
            if self._solve is not None:
                message, self._solve = self._solve, None
            else:
                message, self._frame = self._frame, None
            self._busy = (message[0], threading.Event())
            return message, self._busy[1]


def main() -> None:
    """The worker: answer requests (module docstring) until stdin ends."""
    lower_priority()
    parent, sender = connect_parent()
    from .core.bake.cache import WorkCache

    cache = WorkCache(memory_bytes=CACHE_BYTES)
    requests = _Requests(parent, sender, cache)
    from .core.bake.preview import Preview  # only now (module docstring)

    preview = Preview(cache)
    while True:
        message, cancelled = requests.next()
        kind, rid = message[:2]
        try:
            if kind == "solve":
                started = time.perf_counter()
                figures = preview.solve(**message[2], cancel=cancelled.is_set)
                send(parent, ("solved", rid, dict(figures, received=message[-1], started=started,
                                                  ended=time.perf_counter())))
                message = ("frame", rid, message[3])
            if cancelled.is_set():
                continue
            mesh = preview.frame(message[2])
            if not cancelled.is_set():
                send(parent, ("frame", rid, message[2]) + mesh)
        except Cancelled:
            continue
        except Exception as exc:  # every failure is the parent's to show
            if not isinstance(exc, ValueError):
                traceback.print_exc()
            send(parent, ("failed", rid, type(exc).__name__, str(exc),
                          isinstance(exc, ValueError)))


if __name__ == "__main__":
    main()
