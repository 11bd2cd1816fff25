"""Progress reporting and cancellation shared by every long-running stage.

Long stages take two optional callables:

- ``progress(fraction, message)``: fraction in [0, 1] of the whole call, and a
  short human-readable stage description;
- ``cancel()``: returns True when the user asked to stop (ESC in Blender).

`Reporter` wraps both, maps a sub-stage's own [0, 1] onto its slice of the
parent's range, and raises `Cancelled` at the next check after cancel()
turned True.

What the artist reads are counted steps of a few stages, "Distance fields 2/4", "Maps 3/6",
"Paths 1/3", "Frames 12/25": a unit of work opens its step (`Reporter.step`) and the stages
beneath it (a solver's iterations, a distance field's passes) move the fraction within it
under the step's words. A whole bake counts its steps in a `Tally`: each step's share of the
fraction is its expected cost, steps another process did are counted as they end
(`Reporter.elsewhere`), and the fraction never goes back. Without a tally a step is its
slice of the reporter it was opened on.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator, Mapping

__all__ = ["Cancelled", "Reporter", "Tally"]


class Cancelled(Exception):
    """Raised inside the core when the caller's cancel() returned True."""


class Reporter:
    """Forward progress of a (sub-)stage to the caller's callbacks.

    Parameters
    ----------
    progress : callable(fraction, message), Reporter or None
        A `Reporter` (a stage given its caller's): the new one covers its slice, under its
        tally, checking its cancel too.
    cancel : callable() -> bool or None
    start, stop : float
        The slice [start, stop] of the caller's progress range this reporter covers.
    tally : Tally, optional
        The counted steps of the whole call: its reporters then report only through the
        steps they open (`step`), and their own reports only check for cancellation.
    """

    def __init__(self, progress: Callable[[float, str], object] | None = None,
                 cancel: Callable[[], bool] | None = None, start: float = 0.0,
                 stop: float = 1.0, tally: Tally | None = None) -> None:
        if isinstance(progress, Reporter):  # a stage given its caller's reporter: its slice
            parent, span = progress, progress.stop - progress.start
            progress, tally = parent._progress, tally or parent.tally
            start, stop = parent.start + start * span, parent.start + stop * span
            cancel = _either(parent._cancel, cancel)
        self._progress = progress
        self._cancel = cancel
        self.start = float(start)
        self.stop = float(stop)
        self.tally = tally

    def __call__(self, fraction: float, message: str = "") -> None:
        """Report ``fraction`` of this stage done, then check for cancellation."""
        if self.tally is None:
            self.forward(fraction, message)
        self.check()

    def forward(self, fraction: float, message: str) -> None:
        """Forward ``fraction`` of this stage, in the caller's range, and ``message``, with
        no cancellation check (`step`'s reporters forward their own stage's words)."""
        if self._progress is not None:
            f = min(max(float(fraction), 0.0), 1.0)
            self._progress(self.start + f * (self.stop - self.start), message)

    def check(self) -> None:
        """Raise `Cancelled` if the caller asked to stop."""
        if self._cancel is not None and self._cancel():
            raise Cancelled("cancelled by the user")

    def sub(self, start: float, stop: float) -> Reporter:
        """A reporter for the slice [start, stop] (fractions of this stage)."""
        span = self.stop - self.start
        return Reporter(self._progress, self._cancel,
                        self.start + start * span, self.start + stop * span, self.tally)

    @contextmanager
    def step(self, stage: str, index: int, count: int) -> Iterator[Reporter]:
        """Step ``index`` (from 0) of the ``count`` of ``stage`` this reporter's work has:
        a reporter whose reports, whatever their words, read "``stage`` i/n" and move the
        fraction within the step.

        Under a `Tally` the step is the tally's next of that stage (its number counts the
        whole call's) and it is counted done when the block ends without an error; else it
        is the slice [index / count, (index + 1) / count] of this reporter. Cancellation is
        checked as the step begins, and by the step's own reports.
        """
        if self.tally is None:
            part = self.sub(index / count, (index + 1) / count)
            words = f"{stage} {index + 1}/{count}"
            inner = Reporter(lambda f, _message: part.forward(f, words), self._cancel)
            inner(0.0)
            yield inner
            part.forward(1.0, words)
            return
        self.tally.started(stage)
        inner = Reporter(lambda f, _message: self.tally.within(stage, f), self._cancel)
        self.check()
        yield inner
        self.tally.ended(stage)

    def elsewhere(self, stage: str, steps: int = 1) -> None:
        """``steps`` steps of ``stage`` another process (or thread) has done: counted done
        by the tally (nothing without one). Safe from any thread (`Tally` reports from its
        own); no cancellation check."""
        if self.tally is not None:
            for _ in range(steps):
                self.tally.started(stage)
                self.tally.ended(stage)


def _either(first, second):
    """A cancel callable true when either is (None when both are)."""
    if first is None or second is None or first is second:
        return first or second
    return lambda: bool(first()) or bool(second())


class Tally:
    """The counted steps of a long call's stages, each step's share of the progress its
    expected cost: the fraction reported is the cost of the steps done, plus the part of
    the steps under way that they report, and never goes back.

    Reports go out only from the thread that made the tally (the call's own), so that
    ``progress`` needs no lock and a failure in it is the call's: steps counted from
    another thread (a helper process's, as their results come in) show in that thread's
    next report.

    Parameters
    ----------
    progress : callable(fraction, message) or None
        Receives the fraction and "``stage`` i/n", i the steps of the stage begun so far
        (here or elsewhere: it never goes back either).
    stages : mapping
        {stage: (steps, cost of one step)}, in the order the work runs; the costs in any
        unit (only their ratios count). A stage with no steps may be left out.
    """

    def __init__(self, progress: Callable[[float, str], object] | None,
                 stages: Mapping[str, tuple[int, float]]) -> None:
        total = sum(n * cost for n, cost in stages.values()) or 1.0
        self._progress = progress
        self.count = {name: int(n) for name, (n, _) in stages.items()}
        self.share = {name: cost / total for name, (_, cost) in stages.items()}
        self.begun = {name: 0 for name in stages}
        self._done = 0.0
        self._at = 0.0
        self._lock = threading.Lock()
        self._thread = threading.get_ident()

    def reporter(self, cancel: Callable[[], bool] | None = None) -> Reporter:
        """The call's root reporter: its work reports through the steps it opens."""
        return Reporter(self._progress, cancel, tally=self)

    def started(self, stage: str) -> None:
        """Begin a step of ``stage``, reported at once."""
        with self._lock:
            self.begun[stage] = min(self.begun[stage] + 1, self.count[stage])
        self.within(stage, 0.0)

    def ended(self, stage: str) -> None:
        """A step of ``stage`` is done: its whole cost counts."""
        with self._lock:
            self._done += self.share[stage]
        self.within(stage, 0.0)

    def within(self, stage: str, fraction: float) -> None:
        """Report a step of ``stage`` ``fraction`` done: the steps done so far plus this
        part of one more, never less than reported before."""
        if self._progress is None or threading.get_ident() != self._thread:
            return
        with self._lock:
            f = min(max(float(fraction), 0.0), 1.0)
            self._at = min(1.0, round(max(self._at, self._done + f * self.share[stage]), 12))
            at, words = self._at, f"{stage} {self.begun[stage]}/{self.count[stage]}"
        self._progress(at, words)
