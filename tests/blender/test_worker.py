"""The bake's worker process (issue 14): cancel at any stage within a second, crashes and
out-of-memory in the worker told clearly, the core's own errors kept, the same result as
the core in this process, and a main loop that is never held up by the bake."""

import os
import time

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import bake
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

#: A main-loop gap this long is a stall a user notices: the bake in a thread of this process
#: makes one of 0.75-1.1 s (HOLD_GIL, below); the worker's bake leaves gaps of 24-31 ms alone
#: and 61 ms beside two busy processes on 2 cores (the main loop polls every 20 ms). The bound
#: sits between the two with room on both sides for a loaded machine.
STALL = 0.25

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
@pytest.mark.parametrize("stage", ["Gauss-Newton iteration 2", "trajectories", "frame 2 "])
def test_cancel_mid_bake_ends_within_a_second(scene, kfi, stage):
    kfi.build_spheres(TWO)
    state = kfi.snapshot()
    asked = []

    def observer(job, fraction, message):
        if stage in message and not asked:  # the worker has begun that stage
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
    assert "kfi_main_loop_stall" not in out  # nothing polled this job: no main loop to speak of
    keys = out.data.shape_keys.key_blocks[1:]
    assert len(keys) == len(mine.frames)
    world = np.array(out.matrix_world)
    for key, expected in zip(keys, mine.vertices):
        co = np.empty(len(key.data) * 3, np.float32)
        key.data.foreach_get("co", co)
        co = co.reshape(-1, 3) @ world[:3, :3].T + world[:3, 3]
        np.testing.assert_allclose(co, expected, rtol=0, atol=1e-5)


#: A core stage holding the GIL for a while, as a long C call does at high resolution (at
#: the tests' resolution none lasts long enough to show): a bake in a thread of this process
#: stops the main loop for that long, a bake in the worker process does not.
HOLD_GIL = "sum(range(40_000_000))"


class _InThreadJob(bake.BakeJob):
    """The bake as it ran before the worker process: the core in a thread of this process."""

    def _bake(self):
        return pipeline.bake(**self.inputs.core_arguments(), progress=self._progress)


@pytest.mark.processes
def test_main_loop_keeps_its_turns_during_a_bake(scene, kfi, in_worker, monkeypatch):
    from test_bake import _drive, _modal_operator

    from keyframe_implicit.blender import ops

    kfi.build_spheres(TWO)
    fault = FAULT.format(after=0.3, action=HOLD_GIL)
    in_worker(fault)
    gaps = {}
    for kind in (bake.BakeJob, _InThreadJob):
        if kind is _InThreadJob:  # the same stage, in this process's core
            monkeypatch.setattr(pipeline, "bake", pipeline.bake)
            exec(compile(__import__("textwrap").dedent(fault), "fault", "exec"), {})
        job = kind(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
        me, ctx, reports = _modal_operator(job, scene)
        job.start()
        assert _drive(ops.KFI_OT_bake, me, ctx) == {"FINISHED"}, reports
        gaps[kind.__name__] = job.max_poll_gap
    print("largest gap between the modal operator's polls (20 ms apart):",
          ", ".join(f"{k} {v * 1000:.0f} ms" for k, v in gaps.items()))
    assert gaps["_InThreadJob"] > STALL  # the measurement sees a stalled main loop
    assert gaps["BakeJob"] < STALL


@pytest.mark.processes
def test_main_loop_stall_is_the_longest_poll_gap_beyond_the_step(scene, kfi):
    step, held = 0.1, 0.5
    kfi.build_spheres(TWO)
    job = _job(scene, kfi, poll_step=step)
    job.start()
    time.sleep(held)  # the main loop held up right after the start (reading the inputs, ...)
    while not job.poll():
        time.sleep(step)
    assert job.state == bake.DONE, job.error_message()
    out = job.apply(scene)
    print(f"held {held * 1000:.0f} ms: longest gap {job.max_poll_gap * 1000:.0f} ms, "
          f"stall kept on the output {out['kfi_main_loop_stall'] * 1000:.0f} ms")
    assert out["kfi_main_loop_stall"] == pytest.approx(job.max_poll_gap - step)
    # the held gap less the step: a sleep never ends early, and overshoots by 1-11 ms here
    # (alone or beside two busy processes on 2 cores); the upper bound leaves room for a
    # loaded machine and still tells a gap counted from the wrong time or summed over the
    # main loop's turns (the whole bake: 1.5 s alone)
    assert held - step <= out["kfi_main_loop_stall"] < held + 0.25


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
    seen = {}

    def observer(job, fraction, message):
        if "Gauss-Newton iteration 2" in message and not seen:  # both maps are being solved
            pids = [job._worker.process.pid] + _descendants(job._worker.process.pid)
            seen.update({pid: os.getpriority(os.PRIO_PROCESS, pid) for pid in pids})

    job = _job(scene, kfi, on_progress=observer)
    job.run()
    assert job.state == bake.DONE, job.error_message()
    # the worker, its helper on two cores (and multiprocessing's resource tracker)
    assert len(seen) >= worker._PROCESSES, seen
    assert all(nice == min(mine + worker._NICENESS, 19) for nice in seen.values()), (mine, seen)
