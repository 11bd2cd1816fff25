"""Cancel takes effect within the stage that is running, in every long stage of `animate`.

The bake runs in a thread. Cancel is flipped from the progress callback as soon as a
stage reports (so the stage is under way, and it is flipped at the same point of the
bake on every run), and the bake must raise `Cancelled` before any later stage reports
progress: the event that shows cancel is seen within the stage. No wall time is measured;
a bound of ten minutes only keeps a hang from stopping the suite.
"""

import threading

import pytest

from keyframe_implicit.core import Cancelled, animate

from inbetween_cases import turning_sphere


def _bake_and_cancel(stage, nth=1):
    """Bake a turning, squashed sphere; cancel when ``stage`` is reported the ``nth`` time
    (a step's second report comes from the work inside it). Returns the messages reported
    after the flip."""
    keyframes, features = turning_sphere()
    flipped = threading.Event()
    after, outcome, seen = [], {}, []

    def progress(fraction, message):
        if flipped.is_set():
            after.append(message)
        elif stage in message:
            seen.append(message)
            if len(seen) == nth:
                flipped.set()

    def bake():
        try:
            animate(keyframes, features, resolution=36,
                    progress=progress, cancel=flipped.is_set, template="grid")
            outcome["finished"] = True
        except Cancelled:
            outcome["cancelled"] = True

    worker = threading.Thread(target=bake, daemon=True)
    worker.start()
    worker.join(600)
    assert not worker.is_alive(), "the bake neither ended nor was cancelled in ten minutes"
    assert flipped.is_set(), f"the bake never reported {stage!r}"
    assert "cancelled" in outcome, "the bake finished although cancel was set"
    return after


@pytest.mark.parametrize("stage, nth, later", [
    ("Maps 1/", 3, ("Maps 2/", "Paths", "Frames")),  # asked within the solver's iterations
    ("Paths", 1, ("Frames",)),
    ("Frames 2/", 1, ("Frames 3/", "Frames 4/")),
])
def test_cancel_is_seen_within_the_stage_it_is_asked_in(stage, nth, later):
    after = _bake_and_cancel(stage, nth)
    stopped_later = [m for m in after if any(word in m for word in later)]
    assert not stopped_later, f"cancelled only at a later stage: {stopped_later}"
