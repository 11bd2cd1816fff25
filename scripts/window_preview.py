"""Measure the live preview in a windowed Blender (runs inside Blender, for
scripts/window_preview.sh).

    blender --python scripts/window_preview.py -- OUTDIR SCENE.blend [SCENE.blend ...]

For each scene: open it (sidebar on the extension's tab, keyframes framed), go to the middle
of its first segment, turn the Live Preview on and wait for its first frame; then

- ``drag``: `DRAGS` times, a feature Empty of the first keyframe is moved with real input
  events (``xdotool``: the pointer onto the Empty, G, the pointer moved in `STEPS` steps, a
  click to confirm, alternately right and left) and the time from the click to the updated
  preview on screen is taken: the first 3D view redraw (its POST_PIXEL callback, after every
  POST_VIEW one, the preview's included) once the preview holds the frame answered to the
  first solve sent after the click;
- ``scrub``: `SCRUBS` times the Right arrow key (next frame), with the maps solved, and the
  time from the key to that frame's preview on screen.

Throughout, a `bpy.app.timers` callback asking for a call every `TICK` seconds records the
main loop's turns: the longest gap is Blender's whole (its drawing included); the preview
records into a `Diagnostics` set as the add-on's ``diagnostics.current`` when each solve and
frame went out and came back, and ``longest``, the longest call of its own code. OUTDIR receives
``preview_<scene>_{on,stale,dragged,scrubbed}.png`` (stale: just after the first
release, before its solve is back) (the display grabbed with ``xwd``). Blender
quits when done, exit code 1 on any error.
"""

import os
import subprocess
import sys
import time

import bpy
import numpy as np
from bpy_extras.view3d_utils import location_3d_to_region_2d
from blender_window import addon_module, decode_xwd, open_scene, run, save_png, view3d, xwd

ARGS = sys.argv[sys.argv.index("--") + 1:]
OUT, SCENES = ARGS[0], ARGS[1:]
#: Viewport anti-aliasing samples (Preferences > Viewport), or None: as the preferences have
#: it (8). Software GL draws each sample on the processor, 8 redraws after every edit that
#: take both cores for about a second; with a graphics card they take none of them, as with 0.
VIEWPORT_AA = None
if SCENES and SCENES[0].startswith("--viewport-aa="):
    VIEWPORT_AA, SCENES = SCENES[0].split("=", 1)[1], SCENES[1:]
TICK = 0.01  # seconds the recording timer asks for between its calls
DRAGS, SCRUBS = 10, 10
STEPS = 6  # pointer moves per drag
STEP_PIXELS = 5
WAIT = 120.0  # seconds to wait for an answer before the run fails (a hang, not a figure)


class Recorder:
    """The main loop's turns (a timer's calls) and the 3D view's finished redraws."""

    def __init__(self):
        self.times, self.draws = [], []
        self._handle = bpy.types.SpaceView3D.draw_handler_add(self._drawn, (), "WINDOW", "POST_PIXEL")
        self._timer = self._tick
        bpy.app.timers.register(self._timer, first_interval=TICK)

    def _tick(self):
        self.times.append(time.perf_counter())
        return TICK

    def _drawn(self):
        self.draws.append(time.perf_counter())

    def drawn_after(self, t):
        """The first finished 3D view redraw after ``t``, or None."""
        return next((d for d in self.draws if d > t), None)

    def longest_gap(self, start):
        t = np.array([x for x in self.times if x >= start])
        return float(np.diff(t).max()) if len(t) > 1 else float("nan")

    def stop(self):
        bpy.app.timers.unregister(self._timer)
        bpy.types.SpaceView3D.draw_handler_remove(self._handle, "WINDOW")


def xdotool(*args):
    """Send input events to the display, without waiting."""
    return subprocess.Popen(["xdotool", *map(str, args)])


def wait_for(condition, what):
    """Steps: until ``condition()`` holds."""
    deadline = time.perf_counter() + WAIT
    while not condition():
        if time.perf_counter() > deadline:
            raise RuntimeError(f"no {what} in {WAIT:.0f} s")
        yield 0.005


def grab(name, shots):
    shots.append((xwd(os.path.join(OUT, name + ".xwd")), name))


def screen_point(obj):
    """Where ``obj``'s origin is on the X display (pixels from the top left)."""
    win, area, _, main = view3d()
    p = location_3d_to_region_2d(main, area.spaces.active.region_3d, obj.matrix_world.translation)
    return int(win.x + main.x + p.x), int(win.height - (main.y + p.y))


def on_screen(diag, rec, after):
    """Steps: until the preview holds a frame answered after ``after`` and the 3D view has
    redrawn since; returns (answer's time, redraw's time)."""
    yield from wait_for(lambda: any(t > after for t, _ in diag.shown), "preview answer")
    shown = next(t for t, _ in diag.shown if t > after)
    yield from wait_for(lambda: rec.drawn_after(shown) is not None, "redraw")
    return shown, rec.drawn_after(shown)


def drag(pv, diag, rec, empty, direction, shot=None):
    """Steps: one G-move of ``empty`` with real input events; returns the figures. ``shot``
    (name, shots): the screen grabbed once the solve after the release is sent, while the
    overlay still shows the frame before the move (grey: stale)."""
    x, y = screen_point(empty)
    xdotool("mousemove", x, y).wait()
    yield 0.2
    xdotool("key", "g")
    yield 0.2
    for _ in range(STEPS):
        xdotool("mousemove_relative", "--", direction * STEP_PIXELS, 0)
        yield 0.03
    yield 0.1
    before = len(diag.solves)
    release = time.perf_counter()
    xdotool("click", "1")
    yield from wait_for(lambda: len(diag.solves) > before, "solve after the release")
    sent = diag.solves[before]
    if shot is not None:
        grab(*shot)
    shown, drawn = yield from on_screen(diag, rec, sent)
    f = dict(pv.state.figures)
    return dict(latency=drawn - release, sent=sent - release, answered=shown - sent,
                drawn=drawn - shown, figures=f, arrived=f["received"] - sent,
                waited=f["started"] - f["received"], framed=shown - f["ended"])


def scrub(diag, rec, scene):
    """Steps: one Right arrow (next frame); returns the seconds to that frame on screen."""
    frame = scene.frame_current + 1
    start = time.perf_counter()
    xdotool("key", "Right")
    yield from wait_for(lambda: any(t > start and f == frame for t, f in diag.shown),
                        f"frame {frame}")
    shown = next(t for t, f in diag.shown if t > start and f == frame)
    yield from wait_for(lambda: rec.drawn_after(shown) is not None, "redraw")
    asked = next((t for t in diag.frames if t > start), shown)
    return dict(latency=rec.drawn_after(shown) - start, asked=asked - start,
                answered=shown - asked, drawn=rec.drawn_after(shown) - shown)


def scene_steps(path, shots):
    name = os.path.splitext(os.path.basename(path))[0]
    yield from open_scene(path)
    yield 1.0
    pv = addon_module("blender.preview")
    measured = addon_module("blender.diagnostics")
    diag = measured.current = measured.Diagnostics()
    scene = bpy.context.scene
    settings = scene.keyframe_implicit
    frames = [kf.frame for kf in settings.keyframes]
    scene.frame_set((frames[0] + frames[1]) // 2)
    empty = next(o for o in scene.objects
                 if o.get("kfi_side") == "A" and int(o.get("kfi_segment", -1)) == 0)
    for obj in scene.objects:
        obj.select_set(obj == empty)
    bpy.context.view_layer.objects.active = empty
    rec = Recorder()
    load = os.getloadavg()
    t_on = time.perf_counter()
    bpy.context.window_manager.keyframe_implicit.live_preview = True
    shown, drawn = yield from on_screen(diag, rec, t_on)
    first = drawn - t_on
    yield 1.0
    grab(f"preview_{name}_on", shots)
    yield 1.0
    drags = []
    for i in range(DRAGS):
        drags.append((yield from drag(pv, diag, rec, empty, 1 if i % 2 == 0 else -1,
                                      (f"preview_{name}_stale", shots) if i == 0 else None)))
        yield 0.5
    grab(f"preview_{name}_dragged", shots)
    yield 1.0
    scrubs = []
    for _ in range(SCRUBS):
        scrubs.append((yield from scrub(diag, rec, scene)))
        yield 0.3
    grab(f"preview_{name}_scrubbed", shots)
    yield 1.0
    longest, longest_in, cpu = diag.longest, diag.longest_in, diag.longest_cpu
    gap = rec.longest_gap(t_on)
    bpy.context.window_manager.keyframe_implicit.live_preview = False
    measured.current = None
    rec.stop()
    lat = np.array([d["latency"] for d in drags])
    f = drags[-1]["figures"]
    print(f"[window_preview] {name}: preview grid {f['grid_shape']} (resolution {f['resolution']}), "
          f"motion grid {f['motion_grid_shape']} (motion resolution {f['motion_resolution']}); "
          f"load average {load[0]:.1f} before, {os.getloadavg()[0]:.1f} after; {os.cpu_count()} CPUs",
          flush=True)
    print(f"  first preview {first:.2f} s after the toggle")
    print(f"  release -> preview on screen ({DRAGS} drags): median {np.median(lat):.2f} s, "
          f"min {lat.min():.2f}, max {lat.max():.2f}; per drag: "
          + ", ".join(f"{x:.2f}" for x in lat))
    print("    of which (medians): release -> solve sent "
          f"{np.median([d['sent'] for d in drags]):.3f} s, solve sent -> frame answered "
          f"{np.median([d['answered'] for d in drags]):.3f} s, answered -> drawn "
          f"{np.median([d['drawn'] for d in drags]):.3f} s; worker solve "
          f"{np.median([d['figures']['seconds'] for d in drags]):.2f} s")
    print("    the answer's way (medians): sent -> in the worker "
          f"{np.median([d['arrived'] for d in drags]):.3f} s, waiting there "
          f"{np.median([d['waited'] for d in drags]):.3f} s, solve's end -> frame taken "
          f"{np.median([d['framed'] for d in drags]):.3f} s")
    lat = np.array([d["latency"] for d in scrubs])
    print(f"  scrub, key -> frame on screen ({SCRUBS} frames): median {np.median(lat):.3f} s, "
          f"max {lat.max():.3f}; per frame: " + ", ".join(f"{x:.2f}" for x in lat))
    print("    of which (medians): key -> frame asked "
          f"{np.median([d['asked'] for d in scrubs]):.3f} s, asked -> answered "
          f"{np.median([d['answered'] for d in scrubs]):.3f} s, answered -> drawn "
          f"{np.median([d['drawn'] for d in scrubs]):.3f} s")
    print(f"  main loop: longest call of the preview's code {longest * 1000:.1f} ms ({longest_in}), "
          f"at most {cpu * 1000:.1f} ms of processor time in one call; longest gap "
          f"between the main loop's turns (Blender's drawing included) {gap * 1000:.0f} ms",
          flush=True)


def save_shots(shots):
    win = view3d()[0]
    for proc, name in shots:
        proc.wait()
        path = os.path.join(OUT, name + ".xwd")
        with open(path, "rb") as fh:
            save_png(decode_xwd(fh.read())[:win.height, :win.width], path[:-4] + ".png")
        os.remove(path)


def steps():
    if VIEWPORT_AA is not None:
        bpy.context.preferences.system.viewport_aa = VIEWPORT_AA
    print(f"[window_preview] viewport anti-aliasing: {bpy.context.preferences.system.viewport_aa}")
    shots = []
    for path in SCENES:
        yield from scene_steps(path, shots)
    save_shots(shots)


run(steps())
