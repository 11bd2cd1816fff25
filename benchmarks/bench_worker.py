"""The bake's worker process against the core in a thread of Blender's process (bpy module).

Two unit spheres 1.5 apart on frames 1 and 7, baked at each resolution given (default 48):

- ``process``: `BakeJob` (the worker process), polled by a loop that, like the modal
  operator's timer, calls ``job.poll()`` every 20 ms: seconds and the longest gap between
  two polls (`Diagnostics.max_poll_gap`; 20 ms is no stall at all);
- ``thread``: the same poll loop while `pipeline.bake` runs in a thread of this process
  (how the bake ran before the worker process);
- ``in-process``: `pipeline.bake` alone: the worker's overhead is ``process`` minus this;
- cancel latency: ``job.cancel()`` at the first report of each stage, until ``finished``.

Usage: ``python benchmarks/bench_worker.py [RESOLUTION ...]`` from the repository root.
"""

import sys
import time

import bpy

import keyframe_implicit
from keyframe_implicit.blender import bake
from keyframe_implicit.blender.diagnostics import Diagnostics
from keyframe_implicit.core.bake import pipeline

POLL = 0.02
STAGES = ("Distance fields", "Maps", "Paths", "Frames 4/")


def two_spheres():
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True, load_ui=False)
    keyframe_implicit.register()
    for x, frame in ((0.0, 1), (1.5, 7)):
        bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, location=(x, 0, 0))
        bpy.context.scene.frame_set(frame)
        bpy.ops.keyframe_implicit.add_keyframe()
    for d in ((0, 0, 1), (0, 0, -1), (0, 1, 0), (-1, 0, 0)):
        bpy.ops.keyframe_implicit.add_feature_pair(location_a=d, location_b=(d[0] + 1.5, *d[1:]))
    return bpy.context.scene


class InThreadJob(bake.BakeJob):
    """The core in a thread of this process, as before the worker process."""

    def _bake(self):
        return pipeline.bake(**self.inputs.core_arguments(), progress=self._progress)


def polled(kind, inputs):
    """Run a ``kind`` job of ``inputs`` under a 20 ms poll loop; (seconds, longest gap
    between polls)."""
    job = kind(inputs, diagnostics=Diagnostics())
    t0 = time.perf_counter()
    job.start()
    while not job.poll():
        time.sleep(POLL)
    assert job.state == bake.DONE, job.error_message()
    return time.perf_counter() - t0, job.diagnostics.max_poll_gap


def cancel_latency(inputs, stage):
    asked = []

    def observer(job, fraction, message):
        if stage in message and not asked:
            job.cancel()
            asked.append(time.perf_counter())

    job = bake.BakeJob(inputs, on_progress=observer)
    job.start()
    while not job.finished:
        time.sleep(0.001)
    return time.perf_counter() - asked[0]


def main(resolutions):
    scene = two_spheres()
    print(f"{'res':>4} {'mode':<10} {'seconds':>8} {'max gap between 20 ms polls':>28}")
    for res in resolutions:
        inputs = bake.collect(scene, bpy.context.evaluated_depsgraph_get(), res)
        for mode, kind in (("process", bake.BakeJob), ("thread", InThreadJob)):
            seconds, gap = polled(kind, inputs)
            print(f"{res:>4} {mode:<10} {seconds:8.2f} {gap * 1000:25.0f} ms", flush=True)
        t0 = time.perf_counter()
        pipeline.bake(**inputs.core_arguments())
        print(f"{res:>4} {'in-process':<10} {time.perf_counter() - t0:8.2f}", flush=True)
        print(f"{res:>4} cancel latency: " + ", ".join(
            f"{stage} {cancel_latency(inputs, stage) * 1000:.0f} ms" for stage in STAGES))


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [48])
