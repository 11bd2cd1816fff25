"""The bake's worker process (issue 14): cancel at any stage within a second, crashes and
out-of-memory in the worker told clearly, the core's own errors kept, the same result as
the core in this process, and a main loop that is never held up by the bake."""

import os
import threading
import time

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import bake
from keyframe_implicit.blender.diagnostics import Diagnostics
from keyframe_implicit.core.bake import pipeline
from keyframe_implicit.core import Animation
from keyframe_implicit.core.surface.meshdata import resolve_output

TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]

#: Bound on the seconds from ESC to the ended bake. The promise is about a second (issue 14);
#: measured 25-46 ms alone and 0.54-0.62 s beside two busy processes on 2 cores (the worker
#: and its helper are niced, so a loaded machine slows them most). CI runs two test stages
#: side by side on 2 cores: the bound leaves room for that and more, so that it fails on a
#: cancel nobody looks at (a hang), not on a loaded machine.
CANCEL_LATENCY = 5.0

#: In the worker: after the first progress report past AFTER, do ACTION once (the report's
#: message is the stage the parent last heard of).
FAULT = """
    import os, resource, signal, sys, time
    from keyframe_implicit.core.bake import pipeline

    _bake = pipeline.bake
    done = []

    def bake(*args, progress, **kwargs):
        def report(fraction, message):
            progress(fraction, message)
            if fraction > {after} and not done:
                done.append(message)
                {action}
        return _bake(*args, progress=report, **kwargs)

    pipeline.bake = bake
"""


def _job(scene, kfi, **kwargs):
    return bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES),
                        **kwargs)


# (frames 1-7: this process reports frames 1-3, its helper process bakes 4-7 meanwhile)
@pytest.mark.processes
# (a step's later reports come from the work inside it: the 4th of the first map's is in
# the solver's iterations)
@pytest.mark.parametrize("stage, nth", [("Maps 1/", 4), ("Paths", 1), ("Frames 2/", 1)])
def test_cancel_mid_bake_ends_within_a_second(scene, kfi, stage, nth):
    kfi.build_spheres(TWO)
    state = kfi.snapshot()
    asked, seen = [], []

    def observer(job, fraction, message):
        if stage in message and not asked:  # the worker has begun that stage
            seen.append(message)
            if len(seen) == nth:
                job.cancel()  # what ESC does
                asked.append(time.perf_counter())

    job = _job(scene, kfi, on_progress=observer)
    job.start()
    deadline = time.perf_counter() + 300
    while not job.finished:
        assert time.perf_counter() < deadline, "the bake neither ended nor was cancelled in 5 min"
        time.sleep(0.005)
    assert asked, f"the bake ended without reporting {stage!r}"
    latency = time.perf_counter() - asked[0]
    print(f"cancel at {stage!r}: the bake ended {latency * 1000:.0f} ms later")
    assert job.state == bake.CANCELLED and job.result is None and job.error is None
    assert latency < CANCEL_LATENCY, f"the bake ended {latency:.2f} s after ESC"
    assert job._worker.process.returncode is not None  # the worker is gone too
    with pytest.raises(RuntimeError):
        job.apply(scene)
    assert kfi.snapshot() == state


@pytest.mark.processes
@pytest.mark.parametrize("action, text", [
    ("os.kill(os.getpid(), signal.SIGKILL)",  # what the kernel's out-of-memory killer does
     "The bake's worker process ran out of memory (killed by the system) at '{stage}': lower "
     "the resolution (it is 20)"),
    ("raise MemoryError()",
     "The bake's worker process ran out of memory at '{stage}': lower the resolution (it is 20)"),
    # (with no core file left behind)
    ("resource.setrlimit(resource.RLIMIT_CORE, (0, 0)); os.kill(os.getpid(), signal.SIGSEGV)",
     "The bake's worker process crashed (SIGSEGV) at '{stage}'"),
    ("os._exit(139)",
     "The bake's worker process stopped unexpectedly (exit code 139) at '{stage}'"),
    ("raise TypeError('a bug in the core')", "TypeError at '{stage}': a bug in the core"),
])
def test_worker_failure_is_told_clearly_and_changes_nothing(scene, kfi, in_worker, action, text):
    kfi.build_spheres(TWO)
    assert bpy.ops.keyframe_implicit.bake(resolution=10) == {"FINISHED"}  # an output to keep
    state = kfi.snapshot()
    in_worker(FAULT.format(after=0.1, action=action))
    stages = []
    job = _job(scene, kfi, on_progress=lambda j, f, m: stages.append((f, m)))
    job.run()
    stage = next(m for f, m in stages if f > 0.1)
    assert job.state == bake.FAILED and stages[-1][1] == stage  # nothing reported after it
    assert text.format(stage=stage) in job.error_message()
    assert kfi.snapshot() == state
    # the Bake button says the same and leaves the scene as it was
    with pytest.raises(RuntimeError, match="worker process|TypeError at") as err:
        bpy.ops.keyframe_implicit.bake(resolution=kfi.RES)
    assert "The scene is unchanged." in str(err.value)
    assert kfi.snapshot() == state


def test_core_refusal_keeps_its_text(scene, kfi):
    kfi.build_spheres(TWO)
    state = kfi.snapshot()
    inputs = bake.collect(scene, bpy.context.evaluated_depsgraph_get(), 4000)
    with pytest.raises(ValueError) as here:  # the core's own refusal, in this process
        pipeline.animate(inputs.keyframes, inputs.features, resolution=4000)
    job = bake.BakeJob(inputs)
    job.run()
    assert job.state == bake.FAILED and type(job.error) is ValueError
    assert job.error_message() == str(here.value)
    assert kfi.snapshot() == state


def test_worker_result_applied_equals_the_core_in_this_process(scene, kfi):
    kfi.build_spheres(TWO)
    job = _job(scene, kfi)
    job.run()
    assert job.state == bake.DONE, job.error_message()
    # in this process without a helper (Blender's own process starts none): the worker's
    # helper solves the map B -> A and half the frames, equal to the trajectories' CG tolerance
    mine = pipeline.bake(**job.inputs.core_arguments())
    np.testing.assert_allclose(job.result.vertices, mine.vertices, rtol=0, atol=1e-5)
    np.testing.assert_array_equal(job.result.faces, mine.faces)
    assert type(job.result) is Animation  # mapped onto this process's classes
    kind, _ = resolve_output(scene.keyframe_implicit.output_mode, job.result.stats)
    assert list(job.result.prepared) == [kind]  # the output's mesh came made from the worker
    out = job.apply(scene)
    # the artist's object keeps what the add-on reads back, and no figure of the bake's running
    assert set(out.keys()) == {"kfi_output", "kfi_frames", "kfi_output_kind", "kfi_report",
                               "kfi_report_details", "kfi_stats"}
    assert out["kfi_stats"].to_dict() == {"resolution": kfi.RES,
                                          "motion_resolution": mine.stats["motion_resolution"],
                                          "spacing": pytest.approx(mine.grid.spacing)}
    keys = out.data.shape_keys.key_blocks[1:]
    assert len(keys) == len(mine.frames)
    world = np.array(out.matrix_world)
    for key, expected in zip(keys, mine.vertices):
        co = np.empty(len(key.data) * 3, np.float32)
        key.data.foreach_get("co", co)
        co = co.reshape(-1, 3) @ world[:3, :3].T + world[:3, 3]
        np.testing.assert_allclose(co, expected, rtol=0, atol=1e-5)


#: Turns of the main loop (the modal operator's polls) a bake waits for in the middle of a
#: stage (`GATE`): a bake that stops the main loop never gets them.
TURNS = 5

#: In the worker, or in this process: at the first progress report past 0.3, report "held"
#: and hold the GIL in one C call (as the core's long numpy calls do; a ctypes.PyDLL call
#: keeps it) until the test writes into the FIFO ``gate``, which it does once the main loop
#: has polled `TURNS` times since "held", or until ``bound`` ms have passed (a bound for a
#: hang, not a figure); then report "released" and go on, or fail when nothing came.
GATE = """
    import ctypes, os
    from keyframe_implicit.core.bake import pipeline

    _bake = pipeline.bake

    class _PollFd(ctypes.Structure):
        _fields_ = [("fd", ctypes.c_int), ("events", ctypes.c_short), ("revents", ctypes.c_short)]

    def bake(*args, progress, **kwargs):
        held = []

        def report(fraction, message):
            progress(fraction, message)
            if fraction > 0.3 and not held:
                held.append(message)
                fd = os.open({gate!r}, os.O_RDONLY | os.O_NONBLOCK)  # open while "held" is shown
                progress(fraction, "held")
                released = ctypes.PyDLL(None).poll(ctypes.byref(_PollFd(fd, 1, 0)), 1, {bound}) > 0
                progress(fraction, "released")
                os.close(fd)
                if not released:
                    raise RuntimeError("the main loop did not turn while the bake held a stage")
        return _bake(*args, progress=report, **kwargs)

    pipeline.bake = bake
"""


class _InThreadJob(bake.BakeJob):
    """The bake as it ran before the worker process: the core in a thread of this process."""

    def _bake(self):
        return pipeline.bake(**self.inputs.core_arguments(), progress=self._progress)


@pytest.mark.processes
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="the held stage waits on a POSIX FIFO")
def test_main_loop_keeps_its_turns_during_a_bake(scene, kfi, in_worker, monkeypatch, tmp_path):
    """The worker's stage waits for the main loop's turns, and gets them; the same stage in a
    thread of this process holds the main loop, which never gets one before the hold ends."""
    from test_bake import _drive, _modal_operator

    from keyframe_implicit.blender import ops

    kfi.build_spheres(TWO)
    outcome = {}
    for kind, bound in ((bake.BakeJob, 120_000), (_InThreadJob, 1_000)):
        gate = str(tmp_path / f"gate_{kind.__name__}")
        os.mkfifo(gate)
        fault = GATE.format(gate=gate, bound=bound)
        if kind is bake.BakeJob:
            in_worker(fault)
        else:  # the same stage, in this process's core
            monkeypatch.setattr(pipeline, "bake", pipeline.bake)
            exec(compile(__import__("textwrap").dedent(fault), "gate", "exec"), {})
        turns = []
        job = kind(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
        real_poll = job.poll

        def poll(job=job, gate=gate, turns=turns, real_poll=real_poll):
            if job.status()[1] == "held":  # a turn of the main loop while the stage is held
                turns.append(1)
                if len(turns) == TURNS:  # release it
                    fd = os.open(gate, os.O_WRONLY | os.O_NONBLOCK)
                    os.write(fd, b"go")
                    os.close(fd)
            return real_poll()

        job.poll = poll
        me, ctx, reports = _modal_operator(job, scene)
        job.start()
        _drive(ops.KFI_OT_bake, me, ctx)
        outcome[kind.__name__] = (job.state, job.error_message(), len(turns))
    print("turns of the main loop while the stage was held:", outcome)
    state, error, turns = outcome["_InThreadJob"]  # the test sees a held main loop
    assert state == bake.FAILED and "did not turn" in error and turns < TURNS, outcome
    state, error, turns = outcome["BakeJob"]
    assert state == bake.DONE and turns >= TURNS, outcome


def test_poll_never_waits_and_its_gaps_are_measured_on_request(scene, kfi):
    """`BakeJob.poll` answers at once while the bake runs (here a bake held until the polls
    are done: a poll that waited for it would see it finished), and the longest gap between
    polls, counted from the start, is what a `Diagnostics` with a fake clock says."""
    kfi.build_spheres(TWO)
    now = [100.0]
    diagnostics = Diagnostics(clock=lambda: now[0])
    release = threading.Event()

    class Held(bake.BakeJob):
        def _bake(self):
            release.wait(60.0)  # a bound for a hang: a poll that waits fails below
            return None

    job = Held(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES),
               diagnostics=diagnostics)
    job.start()
    answers = []
    for step in (0.5, 0.1, 0.1, 0.3, 0.1):  # the main loop held 0.5 s right after the start
        now[0] += step
        answers.append(job.poll())
    release.set()
    job.join(60.0)
    assert answers == [False] * 5 and job.state == bake.DONE
    assert diagnostics.max_poll_gap == pytest.approx(0.5, abs=1e-12)
    assert job.poll() and diagnostics.max_poll_gap == pytest.approx(0.5, abs=1e-12)


def _descendants(pid):
    """The process ids below ``pid`` (Linux's /proc children lists)."""
    import glob

    found = []
    for path in glob.glob(f"/proc/{pid}/task/*/children"):
        with open(path) as fh:
            for child in map(int, fh.read().split()):
                found += [child] + _descendants(child)
    return found


@pytest.mark.processes
@pytest.mark.skipif(not hasattr(os, "getpriority") or not os.path.isdir("/proc/self/task"),
                    reason="reads the processes' priorities from Linux's /proc")
def test_worker_and_its_helper_yield_the_cores_to_blender(scene, kfi):
    from keyframe_implicit import worker

    kfi.build_spheres(TWO)
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    seen, maps = {}, []

    def observer(job, fraction, message):
        maps.extend(message[:4] == "Maps" and not seen and [message] or [])
        if len(maps) == 4 and not seen:  # within the first map's solve: both are being solved
            pids = [job._worker.process.pid] + _descendants(job._worker.process.pid)
            seen.update({pid: os.getpriority(os.PRIO_PROCESS, pid) for pid in pids})

    job = _job(scene, kfi, on_progress=observer)
    job.run()
    assert job.state == bake.DONE, job.error_message()
    # the worker, its helper on two cores (and multiprocessing's resource tracker)
    assert len(seen) >= worker._PROCESSES, seen
    assert all(nice == min(mine + worker.NICENESS, 19) for nice in seen.values()), (mine, seen)
