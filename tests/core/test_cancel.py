"""Cancel takes effect within a second in the middle of every long stage of `animate`.

The bake runs in a thread; once a stage's progress message has been seen, the test
waits a little (so the stage is under way and its own progress report is past),
then flips cancel and measures the wall time until `Cancelled` arrives. The stage
must still be the one running when the bake stops: no later stage reported progress
(the event that shows cancel is seen within the stage); the wall time has a bound with
room for a loaded machine (`LATENCY`).
"""

import threading
import time

import pytest

from keyframe_implicit.core import Cancelled, animate

from inbetween_cases import turning_sphere

#: Bound on the seconds from the flip to `Cancelled`. Issue 14 promises about a second;
#: measured 0.01-0.03 s, alone and beside two busy processes on 2 cores. CI runs two test
#: stages side by side on 2 cores: the bound leaves room for that and more, so that it fails
#: on a cancel nobody looks at (a hang), not on a loaded machine. A stage that ran to its end
#: before stopping fails the check on later stages' reports instead.
LATENCY = 5.0


def _bake_and_cancel(stage, later, delay):
    """Bake a turning, squashed sphere; cancel ``delay`` s after ``stage`` is reported.

    Returns the seconds from the flip to `Cancelled` and the messages reported after it.
    """
    keyframes, features = turning_sphere()
    seen, flipped = threading.Event(), threading.Event()
    after, outcome = [], {}

    def progress(fraction, message):
        if flipped.is_set():
            after.append(message)
        if stage in message:
            seen.set()

    def bake():
        try:
            animate(keyframes, features, resolution=36,
                    progress=progress, cancel=flipped.is_set, template="grid")
            outcome["finished"] = True
        except Cancelled:
            outcome["cancelled"] = time.perf_counter()

    worker = threading.Thread(target=bake, daemon=True)
    worker.start()
    assert seen.wait(600), f"the bake never reported {stage!r}"
    time.sleep(delay)
    t_flip = time.perf_counter()
    flipped.set()
    worker.join(60)
    assert not worker.is_alive(), "the bake ignored cancel for a minute"
    assert "cancelled" in outcome, "the bake finished although cancel was set"
    stopped_later = [m for m in after if any(word in m for word in later)]
    assert not stopped_later, f"cancelled only at a later stage: {stopped_later}"
    return outcome["cancelled"] - t_flip


@pytest.mark.parametrize("stage, later, delay", [
    ("Gauss-Newton iteration", ("trajectories", "frame"), 0.3),
    ("trajectories", ("in-betweens ready", "frame"), 0.05),
    ("frame 2 ", ("frame 4 ", "Measuring"), 0.2),
])
def test_cancel_in_the_middle_of_a_stage_within_a_second(stage, later, delay):
    latency = _bake_and_cancel(stage, later, delay)
    assert latency < LATENCY, f"cancel took {latency:.2f} s during {stage!r}"
