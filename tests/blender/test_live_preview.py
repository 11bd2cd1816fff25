"""The live preview (`blender.preview`): edits schedule one solve, a drag's moves coalesce,
frames are answered by the worker, and turning it off, loading a file or baking ends the
worker and removes the overlay; nothing enters bpy.data. The preview is the session's: a
file saved with it on, the farm's assembled one too, opens with it off.

In background mode no timer runs: the tests call `preview.tick` themselves, on a clock they
step (`preview.clock`), and count the solves and frames asked for with a `Diagnostics` on
that clock.
"""

import time

import bpy
import pytest

from keyframe_implicit.blender import diagnostics, overlay, preview
from keyframe_implicit.blender.diagnostics import Diagnostics
from keyframe_implicit.core.bake.preview import PREVIEW_RESOLUTION

TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]
#: Seconds the worker may take to answer (a solve at the preview's 32 cells takes 1-3 s
#: alone on 2 cores): a bound for a hang, not a speed figure (benchmarks/README.md has those).
ANSWER = 120.0


def _until(condition):
    """Tick until ``condition()`` holds; the figures of the wait."""
    deadline = time.perf_counter() + ANSWER
    while not condition():
        assert time.perf_counter() < deadline, f"no answer in {ANSWER} s: {preview.state.message}"
        preview.tick()
        time.sleep(0.01)


class _Clock:
    """Seconds that pass only when the test says so (``clock.now += ...``)."""

    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def _solves():
    """How many solves the preview has sent."""
    return len(diagnostics.current.solves)


def _feature_empty():
    return next(o for o in bpy.context.scene.objects if o.get("kfi_pair") and o.get("kfi_side") == "A")


def _move(obj, dx):
    obj.location.x += dx
    bpy.context.view_layer.update()  # what the depsgraph does after an edit: the handlers run


@pytest.fixture
def clock(monkeypatch):
    """The preview's clock and the diagnostics' (asked for by these tests), stepped by hand."""
    clock = _Clock()
    monkeypatch.setattr(preview, "clock", clock)
    monkeypatch.setattr(diagnostics, "current", Diagnostics(clock=clock))
    return clock


def _session():
    """The session's add-on state, where the Live Preview toggle is."""
    return bpy.context.window_manager.keyframe_implicit


@pytest.fixture
def live(scene, kfi, clock):
    kfi.build_spheres(TWO)
    _session().live_preview = True
    preview.tick()  # the first solve goes out at once
    assert preview.active() and _solves() == 1
    yield _session()
    _session().live_preview = False  # a file load may have made another window manager
    preview.stop()


def test_moving_an_empty_schedules_one_solve_and_the_frame_comes_back(live, clock):
    state = preview.state
    _until(lambda: state.mesh is not None)
    frame, vertices, triangles = state.mesh
    assert frame == bpy.context.scene.frame_current and len(vertices) > 100 and len(triangles) > 100
    assert state.figures["resolution"] == PREVIEW_RESOLUTION and state.message == ""
    # a batch where this process can draw (a GPU context: an earlier render may have made
    # one), else the mesh alone
    assert (state.drawn is not None) == overlay.available()
    assert state.handle is not None

    other = bpy.data.objects.new("Other", None)  # not a keyframe, not a feature point
    bpy.context.scene.collection.objects.link(other)
    bpy.context.view_layer.update()
    state.due = None
    _move(other, 0.3)
    assert state.due is None, "an unrelated object's move scheduled a solve"

    _move(_feature_empty(), 0.05)
    assert state.due == clock.now + preview.COALESCE
    clock.now = state.due - 0.01
    preview.tick()
    assert _solves() == 1, "the solve went out before the edits settled"
    clock.now = state.due
    preview.tick()
    assert _solves() == 2
    clock.now += 1.0
    preview.tick()
    assert _solves() == 2, "one move asked for more than one solve"


@pytest.mark.parametrize("edit", [("keyframe", "interpolation", "EASE"),
                                  ("settings", "resolution", 24)])
def test_a_setting_the_bake_reads_schedules_a_solve_and_greys_the_preview_until_it_is_back(
        live, clock, edit):
    state = preview.state
    _until(lambda: state.mesh is not None)
    assert not state.stale
    settings = bpy.context.scene.keyframe_implicit
    owner, name, value = edit
    setattr(settings.keyframes[0] if owner == "keyframe" else settings, name, value)
    assert state.due == clock.now + preview.COALESCE, f"changing {name} asked for no solve"
    assert state.stale and state.mesh is not None  # the old frame stays, marked
    clock.now = state.due
    preview.tick()
    assert _solves() == 2
    _until(lambda: not state.stale)  # the new solve's frame replaces it
    assert state.mesh is not None and state.message == ""


def test_ten_moves_within_100_ms_coalesce_into_one_solve(live, clock):
    state = preview.state
    empty = _feature_empty()
    t0 = clock.now
    for _ in range(10):  # a move every 8 ms: the last 72 ms after the first
        _move(empty, 0.005)
        preview.tick()  # the timer's turns during the drag send nothing
        clock.now += 0.008
    assert _solves() == 1
    last = state.due - preview.COALESCE
    assert last == pytest.approx(t0 + 9 * 0.008)  # the due time followed the moves
    clock.now = t0 + preview.COALESCE + 0.01  # 160 ms after the first move, not the last
    preview.tick()
    assert _solves() == 1
    clock.now = last + preview.COALESCE + 0.001
    preview.tick()
    clock.now = last + 2.0
    preview.tick()
    assert _solves() == 2


def test_a_drag_sends_a_solve_only_when_none_is_in_flight_and_its_end_sends_one_at_once(
        live, clock, monkeypatch):
    state = preview.state
    dragging = [True]
    monkeypatch.setattr(preview, "transforming", lambda: dragging[0])
    empty = _feature_empty()
    first = state.solve_id  # sent by the toggle, not answered yet: no tick took answers
    _move(empty, 0.02)
    clock.now = state.due + 0.5  # the move has settled, but the first solve is in flight
    preview.tick()
    assert _solves() == 1, "a solve went out during a drag while another was in flight"
    _until(lambda: _solves() == 2)  # the first one answered: the drag's solve goes out
    assert state.answered >= first and state.solve_id > first

    _move(empty, 0.02)  # the drag goes on while that one is in flight
    clock.now = state.due + 0.5
    preview.tick()
    assert _solves() == 2
    dragging[0] = False  # the release: its solve goes out at once, before COALESCE
    clock.now = state.due - preview.COALESCE
    preview.tick()
    assert _solves() == 3, "the end of the transform did not send its solve at once"
    _until(lambda: state.answered >= state.solve_id)
    assert not state.stale and state.message == ""


def test_frame_change_asks_for_that_frame(live):
    state = preview.state
    _until(lambda: state.mesh is not None)
    bpy.context.scene.frame_set(4)
    assert len(diagnostics.current.frames) == 1
    _until(lambda: state.mesh[0] == 4)
    assert state.message == ""


def test_toggling_off_ends_the_worker_and_removes_the_overlay(live):
    state = preview.state
    worker, handle = state.worker, state.handle
    live.live_preview = False
    assert worker.process.wait(10) is not None
    assert state.worker is None and state.handle is None and state.mesh is None
    assert not bpy.app.timers.is_registered(preview.tick)
    with pytest.raises(ValueError):  # the draw handler is gone: it cannot be removed again
        bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
    _move(_feature_empty(), 0.05)
    assert state.due is None


def test_loading_a_file_ends_the_worker(live, tmp_path):
    worker = preview.state.worker
    live.live_preview = False
    path = str(tmp_path / "off.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    live.live_preview = True
    worker = preview.state.worker
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    assert worker.process.wait(10) is not None and not preview.active()
    assert preview.state.handle is None
    assert not _session().live_preview


@pytest.mark.parametrize("load_ui", [False, True])
def test_a_file_saved_with_the_preview_on_opens_with_it_off(live, tmp_path, load_ui):
    path = str(tmp_path / "on.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert preview.active(), "saving turned the preview off"
    worker = preview.state.worker
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=load_ui)
    assert worker.process.wait(10) is not None
    assert not preview.active() and preview.state.handle is None
    assert not _session().live_preview
    assert not bpy.app.timers.is_registered(preview.tick)
    assert "live_preview" not in bpy.context.scene.keyframe_implicit.keys()


def test_the_farm_assembles_a_file_with_the_preview_off(live, kfi, tmp_path):
    from keyframe_implicit.__main__ import main

    setup, job, out = (str(tmp_path / n) for n in ("setup.blend", "job", "baked.blend"))
    bpy.ops.wm.save_as_mainfile(filepath=setup)
    for stage in (["prepare", setup, job, "--resolution", str(kfi.RES)],
                  ["maps", job, "--pair", "1"], ["paths", job],
                  ["segment", job, "--segment", "1"], ["assemble", job, "--out", out]):
        assert main(["farm", *stage]) == 0, stage
    assert not preview.active() and not _session().live_preview
    bpy.ops.wm.open_mainfile(filepath=out, load_ui=True)
    assert bpy.context.scene.keyframe_implicit.output_object is not None
    assert not preview.active() and preview.state.handle is None
    assert not _session().live_preview
    assert "live_preview" not in bpy.context.scene.keyframe_implicit.keys()


def test_pressing_bake_ends_the_worker(live, kfi):
    worker = preview.state.worker
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    assert worker.process.wait(10) is not None and not preview.active()
    assert not live.live_preview


def test_no_data_block_is_created(scene, kfi):
    kfi.build_spheres(TWO)
    before = kfi.snapshot()
    counts = {name: len(getattr(bpy.data, name)) for name in dir(bpy.data)
              if isinstance(getattr(bpy.data, name, None), bpy.types.bpy_prop_collection)}
    _session().live_preview = True
    preview.tick()
    _until(lambda: preview.state.mesh is not None)
    scene.frame_set(3)
    _until(lambda: preview.state.mesh[0] == 3)
    scene.frame_set(1)
    _session().live_preview = False
    assert kfi.snapshot() == before
    assert {name: len(getattr(bpy.data, name)) for name in counts} == counts


def test_a_refused_setup_and_a_crash_become_messages(live, clock):
    state = preview.state
    keyframes = bpy.context.scene.keyframe_implicit.keyframes
    keyframes[1].frame = keyframes[0].frame  # two keyframes on one frame
    preview.schedule()
    clock.now += 1.0
    preview.tick()
    assert "frame" in state.message and state.mesh is None and _solves() == 1
    keyframes[1].frame = 7
    state.worker.process.kill()
    _until(lambda: not preview.active())
    assert "worker process stopped" in state.message and state.mesh is None
    live.live_preview = False  # off and on starts it again
    live.live_preview = True
    assert preview.active() and state.message == ""
    preview.tick()
    _until(lambda: state.mesh is not None)


#: Draws an octahedron with `overlay` into a 64 x 64 offscreen buffer, identity matrices
#: (the octahedron's middle covers the middle of the buffer), and prints the alpha of the
#: middle pixel and of a corner.
DRAW = """
import bpy  # noqa: F401  (loads the gpu module)
import gpu
import numpy as np
from mathutils import Matrix
from keyframe_implicit.blender import overlay

gpu.init()
v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float32) * 0.5
t = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5],
              [0, 3, 5]], np.int32)
drawn = overlay.batch(v, t)
off = gpu.types.GPUOffScreen(64, 64)
with off.bind():
    fb = gpu.state.active_framebuffer_get()
    fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
    with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
        gpu.matrix.load_matrix(Matrix.Identity(4))
        gpu.matrix.load_projection_matrix(Matrix.Identity(4))
        overlay.draw(drawn)
    px = np.array(fb.read_color(0, 0, 64, 64, 4, 0, "FLOAT").to_list()).reshape(64, 64, 4)
print("ALPHA", px[32, 32, 3], px[1, 1, 3])
"""


def test_overlay_draws_the_mesh_where_a_gpu_context_exists():
    import os
    import subprocess
    import sys

    import gpu
    import numpy as np

    v = np.eye(3, dtype=np.float32)
    t = np.array([[0, 1, 2]], np.int32)
    if not hasattr(gpu, "init"):  # no GPU context of the test's own making on this Blender:
        # a batch where an earlier render left one, none otherwise
        assert (overlay.batch(v, t) is not None) == overlay.available()
        return
    # gpu.init in a process of its own: this one's GPU state stays as the other tests left it
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = subprocess.run([sys.executable, "-c", DRAW], capture_output=True, text=True,
                         timeout=120, env=dict(os.environ, PYTHONPATH=root))
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("ALPHA")]
    assert line, out.stdout + out.stderr
    middle, corner = map(float, line[0].split()[1:])
    # the middle is covered by a front and a back face, each blended at COLOR's opacity
    a = overlay.COLOR[3]
    assert middle == pytest.approx(a + a * (1 - a), abs=0.02) and corner == 0.0


def _empties():
    """{name: location} of every feature Empty."""
    return {o.name: tuple(o.location) for o in bpy.context.scene.objects if o.get("kfi_pair")}


def _settle(clock):
    """What the preview, when on, does between two edits: its due solve sent, the answers
    taken."""
    if preview.active():
        clock.now += 1.0
        preview.tick()
        _until(lambda: preview.state.due is None and preview.state.mesh is not None)


def _moved_and_undone(clock):
    """Ten moves of the Empties, each its undo step, a frame step after each; then ten undos
    and ten redos, the preview (when on) solving after each. Returns every Empty's place
    after each move, each undo and each redo."""
    names = sorted(_empties())
    bpy.ops.ed.undo_push(message="before the moves")
    moved = [_empties()]
    for i in range(10):
        obj = bpy.data.objects[names[i % len(names)]]
        obj.location.x += 0.02 * (i + 1)
        bpy.context.view_layer.update()
        bpy.ops.ed.undo_push(message=f"move {i + 1}")
        _settle(clock)
        assert bpy.ops.screen.frame_offset(delta=1) == {"FINISHED"}
        _settle(clock)
        moved.append(_empties())
    undone, redone = [], []
    for steps, trail in ((bpy.ops.ed.undo, undone), (bpy.ops.ed.redo, redone)):
        for _ in range(10):
            assert steps() == {"FINISHED"}
            _settle(clock)
            trail.append(_empties())
    return moved, undone, redone


def test_ten_moves_are_undone_by_ten_undos_with_the_preview_on(scene, kfi, clock):
    kfi.build_spheres(TWO)
    for on in (False, True):  # the same moves, undos and redos without and with the preview
        _session().live_preview = on
        moved, undone, redone = _moved_and_undone(clock)
        assert undone == moved[-2::-1], f"preview {on}: an undo did not take back one move"
        assert redone == moved[1:], f"preview {on}: a redo did not bring back one move"
    assert _solves() > 20, "the moves asked for no solves: the preview was not updating"
    assert _session().live_preview and preview.active()
    _session().live_preview = False


def test_undo_past_turning_the_preview_on_leaves_it_on(scene, kfi, clock):
    # the toggle is the session's: undo does not turn it off behind the running preview
    kfi.build_spheres(TWO)
    bpy.ops.ed.undo_push(message="setup")
    _session().live_preview = True
    bpy.ops.ed.undo_push(message="Live Preview")  # what the toggle's click pushes
    obj = bpy.data.objects[sorted(_empties())[0]]
    obj.location.x += 0.1
    bpy.ops.ed.undo_push(message="move")
    for _ in range(2):
        assert bpy.ops.ed.undo() == {"FINISHED"}
        assert _session().live_preview and preview.active()
    _session().live_preview = False
    assert not preview.active()
