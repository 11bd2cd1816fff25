"""A second process for the independent halves of a bake, so that both cores work.

A segment's two maps (A -> B and B -> A) are independent, and so are its frames
once the maps are known. Threads share one interpreter: the Python-level work of
the Gauss-Newton loop and of the frame loop (many mid-sized numpy calls) keeps
one of them waiting for the other, and a two-core machine bakes at about one
core's speed. `Helper` is one more interpreter of the same Python (started with
``spawn``, so it is the same on Linux, macOS and Windows) that runs one call at
a time: its arguments and result travel pickled over a pipe.

The helper dies with its parent: it watches a second pipe (a "lifeline") that
only the parent holds, so a parent killed outright (a cancelled bake's worker)
takes its helper with it. `Helper.close` ends it at once, finished or not.
"""

from __future__ import annotations

import multiprocessing
import os
import threading

__all__ = ["Helper", "HelperError"]


class HelperError(RuntimeError):
    """The helper process ended without answering (killed, or out of memory)."""


class Helper:
    """One helper process running calls ``fn(*args, **kwargs)`` one at a time.

    Parameters
    ----------
    preload : sequence of str
        Modules the helper imports as soon as it starts, so that the first call
        does not wait for them.
    """

    def __init__(self, preload=("keyframe_implicit.core.chain",)):
        ctx = multiprocessing.get_context("spawn")
        self._conn, theirs = ctx.Pipe()
        lifeline, their_lifeline = ctx.Pipe()
        self._lifeline = lifeline
        self._proc = ctx.Process(target=_serve, args=(theirs, their_lifeline, tuple(preload)),
                                 name="keyframe_implicit helper", daemon=True)
        self._proc.start()
        theirs.close()
        their_lifeline.close()

    def submit(self, fn, *args, **kwargs):
        """Start ``fn(*args, **kwargs)`` in the helper; `result` gives its value."""
        self._conn.send((fn, args, kwargs))

    def result(self, check=None, poll_seconds=0.05):
        """The value of the call `submit` started; re-raises its exception.

        ``check`` (e.g. a `progress.Reporter`'s) is called while waiting, so a
        cancel is seen within ``poll_seconds``; the caller then `close`s the helper.
        """
        while not self._conn.poll(poll_seconds):
            if check is not None:
                check()
            if not self._proc.is_alive() and not self._conn.poll():
                raise HelperError(_ended(self._proc.exitcode))
        try:
            ok, value = self._conn.recv()
        except (EOFError, ConnectionResetError):
            self._proc.join(1.0)
            raise HelperError(_ended(self._proc.exitcode)) from None
        if not ok:
            raise value
        return value

    def peak_rss_kib(self):
        """The helper's peak resident set (VmHWM) so far, KiB (Linux; None elsewhere)."""
        try:
            with open(f"/proc/{self._proc.pid}/status") as fh:
                for line in fh:
                    if line.startswith("VmHWM:"):
                        return int(line.split()[1])
        except OSError:
            return None
        return None

    def close(self):
        """End the helper now, whether or not a call is running."""
        if self._proc.is_alive():
            self._proc.kill()
        self._proc.join()
        self._conn.close()
        self._lifeline.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _ended(code):
    what = f"was killed by signal {-code}" if code is not None and code < 0 else \
        f"exited with code {code}"
    return (f"the bake's helper process {what} before answering "
            "(signal 9 is usually the system running out of memory)")


def _serve(conn, lifeline, preload):
    """The helper's loop: answer each (fn, args, kwargs) with (True, value) or (False, exc)."""
    threading.Thread(target=_leave_with_parent, args=(lifeline,), daemon=True).start()
    for name in preload:
        __import__(name)
    while True:
        try:
            fn, args, kwargs = conn.recv()
        except EOFError:
            return
        except BaseException as exc:  # unpickling runs code: an `Inbetween` rebuilds itself
            fn, args, kwargs = _reraise, (exc,), {}
        try:
            answer = (True, fn(*args, **kwargs))
        except BaseException as exc:  # every failure is the caller's to raise
            answer = (False, exc)
        try:
            conn.send(answer)
        except Exception as exc:  # pickling failed before anything was sent
            conn.send((False, HelperError(f"the helper's answer could not be sent back: {exc!r}")))


def _reraise(exc):
    raise exc


def _leave_with_parent(lifeline):
    """Exit at once when the parent's end of the lifeline closes (the parent is gone)."""
    try:
        lifeline.recv()
    except (EOFError, OSError):
        pass
    os._exit(1)
