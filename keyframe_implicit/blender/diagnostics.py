"""What the bake and the live preview measure of themselves, only when asked for.

The add-on measures nothing for itself and writes no figure of its own running into the
artist's file. A benchmark, a window script or a test that wants the figures makes a
`Diagnostics` and hands it over: to `bake.BakeJob` directly, or, for what the user starts
from the UI (the modal bake, the live preview), by setting `current` before starting it.
It then reads:

- the modal bake's polls (`Diagnostics.polled`): `max_poll_gap`, the longest time the main
  loop went without polling the bake, the poller's own step included;
- the live preview's calls on the main loop (`Diagnostics.call`): the longest (`longest`),
  what it was doing then (`longest_in`) and the most processor time one used
  (`longest_cpu`); and when each solve and frame request went out and each answer became
  the preview (`solves`, `frames`, `shown`).

Its clock is replaceable: tests pass a fake one and step it themselves.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator

__all__ = ["Diagnostics", "current", "call", "step", "mark"]


class Diagnostics:
    """Figures of the bake's polling and of the live preview's work on the main loop.

    Parameters
    ----------
    clock : callable, optional
        Seconds, as a float, from any fixed start (default `time.perf_counter`).

    Attributes
    ----------
    max_poll_gap : float
        The longest time, in seconds, between `started` or a `polled` call and the next
        `polled` call.
    longest : float
        The longest `call`, in seconds.
    longest_in : str
        What that call did: its name and the last `step` it began.
    longest_cpu : float
        The most processor time one `call` used (`time.thread_time`): ``longest`` also
        counts the time the system gave the processor to other programs meanwhile.
    solves, frames : list of float
        When each solve and each frame request of the live preview went out (``clock()``).
    shown : list of (float, int)
        When each answered frame became the preview, and its frame.
    """

    def __init__(self, clock: Callable[[], float] = time.perf_counter) -> None:
        self.clock = clock
        self.max_poll_gap = 0.0
        self._last_poll = None
        self.longest = 0.0
        self.longest_in = ""
        self.longest_cpu = 0.0
        self.step = ""
        self.solves, self.frames, self.shown = [], [], []

    def started(self) -> None:
        """The polled work has started: a gap before its first poll counts too."""
        self._last_poll = self.clock()

    def polled(self) -> None:
        """A poll of the running work (a turn of the main loop): updates `max_poll_gap`."""
        now = self.clock()
        if self._last_poll is not None:
            self.max_poll_gap = max(self.max_poll_gap, now - self._last_poll)
        self._last_poll = now

    @contextlib.contextmanager
    def call(self, name: str) -> Iterator[None]:
        """Time the block, one call named ``name`` on the main loop, into `longest`,
        `longest_in` and `longest_cpu`."""
        t0, cpu0 = self.clock(), time.thread_time()
        try:
            yield
        finally:
            took = self.clock() - t0
            self.longest_cpu = max(self.longest_cpu, time.thread_time() - cpu0)
            if took > self.longest:
                self.longest, self.longest_in = took, f"{name}: {self.step}"
            self.step = ""


#: The `Diagnostics` the modal bake and the live preview record into when the user starts
#: them; None (nothing is measured) unless a benchmark, a window script or a test sets one.
current = None


def call(name: str) -> contextlib.AbstractContextManager:
    """`Diagnostics.call` of `current`; a block that measures nothing when there is none."""
    return current.call(name) if current is not None else contextlib.nullcontext()


def step(what: str) -> None:
    """Name what the main loop's call in progress does now (`Diagnostics.longest_in`); nothing
    when no one asked."""
    if current is not None:
        current.step = what


def mark(event: str, *what: object) -> None:
    """Note that ``event`` happened now: ``clock()`` (with ``what``, when given) appended to
    `current`'s list of that name (``"solves"``, ``"frames"``, ``"shown"``); nothing when no
    one asked."""
    if current is not None:
        getattr(current, event).append((current.clock(), *what) if what else current.clock())
