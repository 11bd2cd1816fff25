"""A second process for the independent halves of a bake, so that both cores work.

A segment's two maps (A -> B and B -> A) are independent, and so are its frames
once the maps are known. Threads share one interpreter: the Python-level work of
the Gauss-Newton loop and of the frame loop (many mid-sized numpy calls) keeps
one of them waiting for the other, and a two-core machine bakes at about one
core's speed. `Helper` is one more interpreter of the same Python (started with
``spawn``, so it is the same on Linux, macOS and Windows) that runs one call at
a time: its arguments and result travel pickled over a pipe, their arrays out of band
(`wire`: the message format every process of the bake speaks).

Its first message says it has started (`Helper.ready`): work that this process can
do itself goes to the helper only once it is up (`pipeline._distance_grids`).

The helper dies with its parent: it follows a second pipe (a "lifeline", `wire.follow_parent`)
that only the parent holds, so a parent killed outright (a cancelled bake's worker)
takes its helper with it. `Helper.close` ends it at once, finished or not.

While a bake runs, BLAS keeps to one thread in each process (`one_blas_thread`).
After each call the helper gives its heap's free pages back to the system
(`release_memory`), as the bake's process does between a chain's segments.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import sys
import threading
import time
from collections import deque
from typing import TYPE_CHECKING, Any

from .wire import follow_parent, receive, send

if TYPE_CHECKING:
    from collections.abc import Callable, Hashable, Iterable, Sequence

    from threadpoolctl import threadpool_limits

__all__ = ["Helper", "HelperError", "cores", "can_start_helper", "one_blas_thread",
           "release_memory", "share"]


def cores() -> int:
    """The machine's cores (`os.cpu_count`; 1 when unknown): whether a second process, a
    second thread for the other map, or half of each Hessian product has a core of its own."""
    return os.cpu_count() or 1


def can_start_helper() -> bool:
    """Whether a `Helper` can start from this process: a ``spawn`` child runs the parent's
    main module again, by its module name or from its file. Code run by ``blender -b
    --python-expr`` has neither (its main "file" is "<blender string>"); a worker started
    with ``python -m`` has both."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    return getattr(main, "__spec__", None) is not None or path is None or os.path.isfile(path)


def one_blas_thread() -> threadpool_limits:
    """BLAS limited to one thread in this process (a `threadpoolctl.threadpool_limits`:
    a context manager, or in force until its ``restore_original_limits``).

    A bake's parallel work is its own: two processes (`Helper`), and in each the two maps
    or the two transports in threads, and each Hessian product in two halves
    (`system.MapSystem.product`). BLAS's threads only compete with it for the same
    cores: OpenBLAS starts one per core for a dot product of a few hundred thousand
    entries (each CG step of a Gauss-Newton system) or the multigrid's coarse product, and
    they spin while they wait for the next call. The limit covers the BLAS libraries
    loaded when it is set, so scipy's own is loaded first.
    """
    # imported here, not at the top: the worker imports this module as it starts (to start
    # its helper at once), long before a bake limits BLAS
    import scipy.linalg  # noqa: F401  (loads scipy's BLAS, which numpy's limit would miss)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def _malloc_trim():
    """glibc's ``malloc_trim``, or None where the C library has none (macOS, Windows, musl)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


_TRIM = _malloc_trim()


def release_memory() -> bool:
    """Give the free pages of this process's heap back to the system (glibc's
    ``malloc_trim``; nothing where there is none). Returns whether it could.

    numpy's mid-sized arrays come from the heap once glibc has raised its mmap threshold
    past them, and a freed heap stays resident: a segment's arrays, freed, are still
    counted in the next segment's resident set, and a chain's peak grows with its
    segments. Called where a call's or a segment's large arrays have just gone (a
    helper's call answered, a chain's segment done), it keeps them from stacking
    (benchmarks/README.md, "Free heap given back between a chain's segments"). The pages
    given back cost a page fault each when they are used again.
    """
    if _TRIM is None:
        return False
    _TRIM(0)
    return True


class HelperError(RuntimeError):
    """The helper process ended without answering (killed, or out of memory)."""


class Helper:
    """One helper process running calls ``fn(*args, **kwargs)`` one at a time.

    Parameters
    ----------
    preload : sequence of str
        Modules the helper imports as soon as it starts, so that the first call
        does not wait for them (the bake names `chain.HELPER_PRELOAD`).
    """

    def __init__(self, preload: Sequence[str] = ()) -> None:
        ctx = multiprocessing.get_context("spawn")
        self._conn, theirs = ctx.Pipe()
        lifeline, their_lifeline = ctx.Pipe()
        self._lifeline = lifeline
        self._proc = ctx.Process(target=_serve, args=(theirs, their_lifeline, tuple(preload)),
                                 name="keyframe_implicit helper", daemon=True)
        self._proc.start()
        theirs.close()
        their_lifeline.close()
        self._ready = False

    def ready(self) -> bool:
        """Whether the helper has started (imported its ``preload``): it then takes a call
        at once. Does not wait; not while another thread waits in `result`."""
        if not self._ready and self._conn.poll():
            self._take_ready()
        return self._ready

    def _take_ready(self):
        try:
            ok, value = receive(self._conn)
        except (EOFError, ConnectionResetError):  # it died before it had started
            self._proc.join(1.0)
            raise HelperError(_ended(self._proc.exitcode)) from None
        if not (ok and isinstance(value, _Ready)):
            raise HelperError(f"the helper's first message was {value!r}, not that it started")
        self._ready = True

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Start ``fn(*args, **kwargs)`` in the helper; `result` gives its value."""
        send(self._conn, (fn, args, kwargs))

    def result(self, check: Callable[[], object] | None = None,
               poll_seconds: float = 0.05) -> Any:
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
            if not self._ready:  # the message that it started comes first
                self._take_ready()
                return self.result(check, poll_seconds)
            ok, value = receive(self._conn)
        except (EOFError, ConnectionResetError):
            self._proc.join(1.0)
            raise HelperError(_ended(self._proc.exitcode)) from None
        if not ok:
            raise value
        return value

    def peak_rss_kib(self) -> int | None:
        """The helper's peak resident set (VmHWM) so far, KiB (Linux; None elsewhere)."""
        try:
            with open(f"/proc/{self._proc.pid}/status") as fh:
                for line in fh:
                    if line.startswith("VmHWM:"):
                        return int(line.split()[1])
        except OSError:
            return None
        return None

    def close(self) -> None:
        """End the helper now, whether or not a call is running."""
        if self._proc.is_alive():
            self._proc.kill()
        self._proc.join()
        self._conn.close()
        self._lifeline.close()

    def __enter__(self) -> Helper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def share(jobs: Iterable[Hashable], here: Callable[[Any, Callable[[], bool]], Any],
          there: Callable[[Any], tuple[Callable[..., Any], tuple, dict[str, Any]]],
          helper: Helper, check: Callable[[], object] | None = None,
          cancel: Callable[[], bool] | None = None, last_first: bool = False,
          when_started: bool = False, on_theirs: Callable[[Any], object] | None = None
          ) -> tuple[dict, dict[Any, float], list]:
    """Run ``jobs`` in this process and in ``helper``, each taking the next job when free.

    This process runs ``here(job, stop)`` (``stop()`` is true once the helper has failed
    or ``cancel()`` is; pass it on as the job's cancel). A thread of this process hands
    the helper ``there(job)`` = (fn, args, kwargs): the next job from the front, or with
    ``last_first`` the last one left; with ``when_started`` only once the helper is up
    (`Helper.ready`), so that this process does not wait for its start. ``check`` is
    called while this process waits for the helper's last job (a cancel). ``on_theirs(job)``,
    when given, is told of each job the helper has ended (its progress), in this thread:
    after each job of this process's and while it waits for the helper's last.

    Returns ({job: result}, {job: when it ended, `time.perf_counter`}, the jobs the helper
    ran). A failure in the helper stops this process's job and is raised; one here stops
    the helper's thread (the caller closes the helper).
    """
    left = deque(jobs)
    done, ends, errors, theirs = {}, {}, [], []
    lock, failed = threading.Lock(), threading.Event()

    def take(front):
        with lock:
            if not left or failed.is_set():
                return None
            return left.popleft() if front else left.pop()

    def stop():
        return failed.is_set() or (cancel is not None and bool(cancel()))

    def stop_waiting():
        if failed.is_set():
            raise _Stop

    def feed():
        try:
            while left and not failed.is_set():
                if when_started and not helper.ready():
                    time.sleep(0.02)
                    continue
                job = take(front=not last_first)
                if job is None:
                    return
                fn, args, kwargs = there(job)
                helper.submit(fn, *args, **kwargs)
                done[job] = helper.result(check=stop_waiting)
                ends[job] = time.perf_counter()
                with lock:
                    theirs.append(job)
        except _Stop:
            pass
        except BaseException as exc:  # this process stops its own job and raises it
            errors.append(exc)
            failed.set()

    told = [0]  # how many of the helper's ended jobs ``on_theirs`` has heard of

    def tell():
        with lock:
            ended, told[0] = theirs[told[0]:], len(theirs)
        for ended_job in ended if on_theirs is not None else ():
            on_theirs(ended_job)

    feeder = threading.Thread(target=feed, name="keyframe_implicit helper feed", daemon=True)
    job = take(front=True)  # this process's first job before the thread can take it
    feeder.start()
    try:
        while job is not None:
            done[job] = here(job, stop)
            ends[job] = time.perf_counter()
            tell()
            job = take(front=True)
        while feeder.is_alive():
            feeder.join(0.05)
            tell()
            if check is not None:
                check()
        tell()
    except BaseException:
        failed.set()
        feeder.join()
        if errors:  # the helper's failure stopped this process's job: it is the cause
            raise errors[0] from None
        raise
    if errors:
        raise errors[0]
    return done, ends, theirs


class _Stop(Exception):
    """Ends the thread that feeds the helper (`share`) when this process stops."""


def _ended(code):
    what = f"was killed by signal {-code}" if code is not None and code < 0 else \
        f"exited with code {code}"
    return (f"the bake's helper process {what} before answering "
            "(signal 9 is usually the system running out of memory)")


def _serve(conn, lifeline, preload):
    """The helper's loop: answer each (fn, args, kwargs) with (True, value) or (False, exc)."""
    follow_parent(lifeline)
    for name in preload:
        __import__(name)
    one_blas_thread()  # for the helper's life: it only ever runs a bake's half
    send(conn, (True, _Ready()))
    while True:
        try:
            fn, args, kwargs = receive(conn)
        except EOFError:
            return
        except BaseException as exc:  # unpickling runs code: an `Inbetween` rebuilds itself
            fn, args, kwargs = _reraise, (exc,), {}
        try:
            answer = (True, fn(*args, **kwargs))
        except BaseException as exc:  # every failure is the caller's to raise
            answer = (False, exc)
        try:
            send(conn, answer)
        except Exception as exc:  # pickling failed before anything was sent
            send(conn, (False, HelperError(f"the helper's answer could not be sent back: {exc!r}")))
        del fn, args, kwargs, answer  # not held while the next call arrives and is rebuilt
        release_memory()


class _Ready:
    """The helper's first message: it has started and waits for calls (`Helper.ready`)."""


def _reraise(exc):
    raise exc
