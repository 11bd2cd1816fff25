"""Measure how long Blender's main loop stalls during a bake, in a windowed Blender
(runs inside Blender, for scripts/window_stall.sh).

    blender --python scripts/window_stall.py -- SCENE.blend OUTDIR RESOLUTION [RESOLUTION ...]

For each resolution (0: the scene's own): open SCENE with the sidebar on the extension's tab, then record the
main loop's turns with a `bpy.app.timers` callback asking for a call every `TICK` seconds
(its gaps are what any other UI code feels) during

- ``idle``: `IDLE` seconds with nothing going on;
- ``redraws``: `IDLE` seconds with the 3D view redrawn every `REDRAW` seconds, without a
  bake (what one redraw costs this window: any redraw during the bake costs as much);
- the bake, started as a user starts it (the modal operator), split into ``start`` (the
  operator's invoke: the scene is read and the worker started), ``running`` (the worker
  bakes, the operator polls; then ``writing``: the result is written into the scene a piece
  per turn) and ``end`` (the operator's last turn, then the result's first redraw).

A gap's stall is the gap beyond the asked step. Printed per phase: the longest gap, its
median and 99th percentile, and the gaps over 50 ms of stall; for ``running``, the longest
gaps with the bake's stage at their start and the 3D view's drawing inside them, the gaps
without 3D view drawing split by whether the sidebar was drawn in them (a new progress
text redraws it: Blender's drawing, not the bake's work) and when the 3D view drew; and the
modal operator's own figure (the longest gap between its polls beyond its timer step, from
the `Diagnostics` this script sets as the add-on's ``diagnostics.current``). OUTDIR receives ``window_baking_<res>.png``,
the window grabbed (by ``xwd`` in a process of its own) half-way through each bake; the gap
around that grab is left out of ``running``. Blender quits when done, with exit code 1 on
any error.
"""

import os
import sys
import time

import bpy
import numpy as np
from blender_window import addon_module, decode_xwd, open_scene, run, save_png, view3d, xwd

ARGS = sys.argv[sys.argv.index("--") + 1:]
SCENE, OUT, RESOLUTIONS = ARGS[0], ARGS[1], [int(a) for a in ARGS[2:]]
TICK = 0.01  # seconds the recording timer asks for between its calls
IDLE = 3.0  # seconds of each reference phase
STALL = 0.05  # the longest stall of Blender's main loop the add-on allows itself
REDRAW = 0.1  # seconds between the 3D view's redraws in the ``redraws`` phase


class Recorder:
    """When the main loop gave the recording timer a turn, what the bake was doing then,
    when the 3D view drew (its main region, from PRE_VIEW to POST_PIXEL) and when the
    sidebar finished drawing (its POST_PIXEL: the UI region has no PRE_VIEW)."""

    def __init__(self):
        self.times, self.labels, self.draws, self.sidebar = [], [], [], []
        self.label = "idle"
        self._draw_start = None
        self._handles = [
            (bpy.types.SpaceView3D.draw_handler_add(self._drawing, (), "WINDOW", "PRE_VIEW"), "WINDOW"),
            (bpy.types.SpaceView3D.draw_handler_add(self._drawn, (), "WINDOW", "POST_PIXEL"), "WINDOW"),
            (bpy.types.SpaceView3D.draw_handler_add(self._sidebar_drawn, (), "UI", "POST_PIXEL"), "UI")]
        self._timer = self._tick  # one bound method: unregister wants the registered object
        bpy.app.timers.register(self._timer, first_interval=TICK)

    def _tick(self):
        self.times.append(time.perf_counter())
        self.labels.append(self.label() if callable(self.label) else self.label)
        return TICK

    def _drawing(self):
        self._draw_start = time.perf_counter()

    def _drawn(self):
        if self._draw_start is not None:
            self.draws.append((self._draw_start, time.perf_counter()))
            self._draw_start = None

    def _sidebar_drawn(self):
        self.sidebar.append(time.perf_counter())

    def stop(self):
        bpy.app.timers.unregister(self._timer)
        for h, region in self._handles:
            bpy.types.SpaceView3D.draw_handler_remove(h, region)

    def sidebar_drawn(self, a, b):
        """Whether the sidebar finished drawing between ``a`` and ``b``."""
        return any(a <= t <= b for t in self.sidebar)

    def gaps(self, keep):
        """(start, gap, label at the start) of the gaps that pass ``keep(start, end, label)``."""
        t = self.times
        return [(a, b - a, lab) for a, b, lab in zip(t[:-1], t[1:], self.labels) if keep(a, b, lab)]

    def drawing(self, a, b):
        """Seconds the 3D view spent drawing between ``a`` and ``b``."""
        return sum(max(0.0, min(e, b) - max(s, a)) for s, e in self.draws)


def figures(rec, name, gaps):
    """One line: the phase's gaps (ms), their stalls beyond `TICK`, and the 3D view's
    drawing inside the longest."""
    g = np.array([x[1] for x in gaps]) * 1000
    if not len(g):
        return f"  {name:<14} no turns recorded"
    a, longest, _ = gaps[int(np.argmax(g))]
    over = int(np.sum(g - TICK * 1000 > STALL * 1000))
    return (f"  {name:<14} {len(g):5d} gaps  longest {g.max():6.1f} (stall {g.max() - TICK * 1000:5.1f}, "
            f"3D view drawing {rec.drawing(a, a + longest) * 1000:3.0f})  median {np.median(g):5.1f}  "
            f"p99 {np.percentile(g, 99):5.1f}  stalls over {STALL * 1000:.0f}: {over}")


def reference(rec, name, redraw=False):
    """`IDLE` seconds labelled ``name``; with ``redraw``, the 3D view redrawn every `REDRAW`."""
    area = view3d()[1]

    def update():
        area.tag_redraw()
        return REDRAW

    rec.label = name
    if redraw:
        bpy.app.timers.register(update, first_interval=REDRAW)
    yield IDLE
    if redraw:
        bpy.app.timers.unregister(update)
    rec.label = "between"
    yield 0.5


def bake(rec, res):
    """Steps: one modal bake at ``res``, recorded, its polling measured (the job's
    ``diagnostics``); returns the job (via StopIteration)."""
    ops = addon_module("blender.ops")
    measured = addon_module("blender.diagnostics")
    measured.current = measured.Diagnostics()
    win, area, _, main = view3d()
    settings = bpy.context.scene.keyframe_implicit
    settings.resolution = res or settings.resolution

    def label():
        if not ops.running:
            return "after"
        job = ops.running[0]
        return f"{job.state.lower()}: {job.status()[1]}"

    marks = {}
    rec.label = "before"
    yield 0.1
    marks["invoke"] = time.perf_counter()
    with bpy.context.temp_override(window=win, area=area, region=main):
        assert bpy.ops.keyframe_implicit.bake("INVOKE_DEFAULT") == {"RUNNING_MODAL"}
    marks["invoked"] = time.perf_counter()
    measured.current = None  # the job keeps it
    rec.label = label
    job = ops.running[0]
    grab, shot = None, os.path.join(OUT, f"window_baking_{settings.resolution}.xwd")
    while ops.running:
        if grab is None and job.status()[0] >= 0.5:
            marks["grab"] = time.perf_counter()
            grab = xwd(shot)
            marks["grabbed"] = time.perf_counter()
        yield 0.2
    yield 1.0  # the first redraws of the result
    rec.label = "between"
    if grab is not None:
        grab.wait()
        with open(shot, "rb") as f:
            save_png(decode_xwd(f.read())[:win.height, :win.width], shot[:-4] + ".png")
        os.remove(shot)
    return job, marks


def report(rec, job, marks, load):
    grab = (marks.get("grab", 0.0), marks.get("grabbed", 0.0))
    first = next(t for t in rec.times if t > marks["invoked"])
    end = max(t for t, lab in zip(rec.times, rec.labels) if lab != "after" and t > first)
    running = rec.gaps(lambda a, b, _: first <= a and b <= end and not (a <= grab[1] and b >= grab[0]))
    start = rec.gaps(lambda a, b, _: a <= marks["invoke"] and b >= marks["invoked"])
    ending = rec.gaps(lambda a, b, _: a == end)
    shot = rec.gaps(lambda a, b, _: first <= a and b <= end and a <= grab[1] and b >= grab[0])
    print(f"[window_stall] resolution {job.inputs.resolution}: bake {job.seconds:.1f} s in the worker "
          f"(load average {load[0]:.1f} before, {os.getloadavg()[0]:.1f} after; "
          f"{os.cpu_count()} CPUs; region overlap "
          f"{'on' if bpy.context.preferences.system.use_region_overlap else 'off'})", flush=True)
    print(f"  recording timer asks for a call every {TICK * 1000:.0f} ms; gaps in ms:")
    for name in ("idle", "redraws"):
        print(figures(rec, name, rec.gaps(lambda a, b, lab, n=name: lab == n)))
    print(figures(rec, "start", start) + f"  (invoke {1000 * (marks['invoked'] - marks['invoke']):.0f})")
    print(figures(rec, "running", running))
    undrawn = [x for x in running if not rec.drawing(x[0], x[0] + x[1])]
    sidebar = [x for x in undrawn if rec.sidebar_drawn(x[0], x[0] + x[1])]
    print(figures(rec, "  undrawn", undrawn) + "  (gaps without 3D view drawing)")
    print(figures(rec, "    sidebar", sidebar) + "  (of those, the sidebar drawn in the gap)")
    print(figures(rec, "    nothing", [x for x in undrawn if x not in sidebar])
          + "  (nothing of the 3D view drawn: the bake's own share)")
    print(figures(rec, "  writing", [x for x in running if x[2].startswith("done")])
          + "  (the result written into the scene, a piece per turn)")
    print(figures(rec, "end", ending) + "  (the operator's last turn and the first redraw)")
    if shot:
        print(f"  (the gap around the screenshot's start, {shot[0][1] * 1000:.0f} ms, is left out)")
    print("  longest gaps while running: " + "; ".join(
        f"{g * 1000:.0f} ms at {a - marks['invoke']:.1f} s ({lab}; 3D view drawing "
        f"{rec.drawing(a, a + g) * 1000:.0f} ms)" for a, g, lab in sorted(running, key=lambda x: -x[1])[:3]))
    print("  longest gaps without 3D view drawing: " + "; ".join(
        f"{g * 1000:.0f} ms at {a - marks['invoke']:.1f} s ({lab})"
        for a, g, lab in sorted(undrawn, key=lambda x: -x[1])[:5]))
    draws = [(s, e - s) for s, e in rec.draws if first <= s <= end]
    if draws:
        print(f"  3D view drawn {len(draws)} times while running, "
              f"{np.median([d for _, d in draws]) * 1000:.0f} ms median, "
              f"{max(d for _, d in draws) * 1000:.0f} ms longest; at (s after the invoke) "
              + ", ".join(f"{s - marks['invoke']:.2f}" for s, _ in draws))
    step, gap = addon_module("blender.ops").TIMER_STEP, job.diagnostics.max_poll_gap
    print(f"  modal operator: timer step {step * 1000:.0f} ms, longest gap between its polls "
          f"{gap * 1000:.0f} ms, stall {max(0.0, gap - step) * 1000:.0f} ms", flush=True)


def steps():
    for res in RESOLUTIONS:
        yield from open_scene(SCENE)
        yield 2.0
        rec = Recorder()
        yield from reference(rec, "idle")
        yield from reference(rec, "redraws", redraw=True)
        load = os.getloadavg()
        job, marks = yield from bake(rec, res)
        rec.stop()
        report(rec, job, marks, load)


run(steps())
