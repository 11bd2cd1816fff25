"""Progress reporting and cancellation shared by every long-running stage.

Long stages take two optional callables:

- ``progress(fraction, message)``: fraction in [0, 1] of the whole call, and a
  short human-readable stage description;
- ``cancel()``: returns True when the user asked to stop (ESC in Blender).

`Reporter` wraps both, maps a sub-stage's own [0, 1] onto its slice of the
parent's range, and raises `Cancelled` at the next check after cancel()
turned True.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = ["Cancelled", "Reporter"]


class Cancelled(Exception):
    """Raised inside the core when the caller's cancel() returned True."""


class Reporter:
    """Forward progress of a (sub-)stage to the caller's callbacks.

    Parameters
    ----------
    progress : callable(fraction, message) or None
    cancel : callable() -> bool or None
    start, stop : float
        The slice [start, stop] of the caller's progress range this reporter covers.
    """

    def __init__(self, progress: Callable[[float, str], object] | None = None,
                 cancel: Callable[[], bool] | None = None, start: float = 0.0,
                 stop: float = 1.0) -> None:
        self._progress = progress
        self._cancel = cancel
        self.start = float(start)
        self.stop = float(stop)

    def __call__(self, fraction: float, message: str = "") -> None:
        """Report ``fraction`` of this stage done, then check for cancellation."""
        if self._progress is not None:
            f = min(max(float(fraction), 0.0), 1.0)
            self._progress(self.start + f * (self.stop - self.start), message)
        self.check()

    def check(self) -> None:
        """Raise `Cancelled` if the caller asked to stop."""
        if self._cancel is not None and self._cancel():
            raise Cancelled("cancelled by the user")

    def sub(self, start: float, stop: float) -> Reporter:

        """A reporter for the slice [start, stop] (fractions of this stage)."""
        span = self.stop - self.start
        return Reporter(self._progress, self._cancel,
                        self.start + start * span, self.start + stop * span)
