"""Live preview: the in-between on the current frame, drawn over the 3D view while the
artist edits.

While ``WindowManager.keyframe_implicit.live_preview`` is on, a preview worker process
(`keyframe_implicit.preview_worker`) keeps the setup's maps solved on a coarse grid
(`core.bake.preview`) and answers each frame with that frame's own surface; `overlay`
draws it from a ``POST_VIEW`` draw handler. Nothing enters ``bpy.data``, the undo history
or the outliner.

The preview is a state of the session, not content of the file: its toggle is a window
manager property (`props.KFI_Session`: never saved, never undone), a loaded file turns it
off (load_post), and all it holds is this module's `state`, outside the undo system, so
undo and redo work with it on as with it off.

When it updates:

- a keyframe object or a feature Empty changes (depsgraph_update_post), or a setting the
  bake reads (a keyframe's frame, Interpolation or Surface Tension, the resolutions, the
  weights, the keyframe list: `edited`): `schedule` sets a solve `COALESCE` seconds after
  the last such change. While a transform runs (a G, R or S drag: `transforming`), that
  solve goes out only when no solve is in flight, so a drag never keeps the worker
  starting solves it must drop; when the transform ends, the solve of its last move goes
  out at once, and the worker cancels a solve in flight when a new one comes. Until a
  frame of that solve comes back, the overlay shown is drawn in `overlay.STALE_COLOR`:
  never a frame of old inputs passed off as current;
- the frame changes (frame_change_post): the new frame is asked for at once; the worker
  keeps the last request of each kind, so scrubbing never queues.

The main loop only ever polls: `tick`, a ``bpy.app.timers`` callback every `POLL`
seconds, sends the due solve (reading the scene: `scene_io.read`) and takes the worker's
answers; times are read from `clock`. Turning the preview off, loading a file (load_pre,
load_post) or pressing Bake ends the worker and removes the overlay. Failures (a refused setup, a
crash of the worker) become `State.message`, shown in the panel; nothing raises into
Blender. How long the preview's own code holds the main loop, and when solves and frames
go out and come back, is measured only when asked for (`diagnostics.current`).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import bpy

from ..preview_worker import PreviewWorker
from . import diagnostics, features, overlay, scene_io, validate

if TYPE_CHECKING:
    from .props import KFI_Session

__all__ = ["State", "state", "start", "stop", "toggled", "turn_off", "schedule", "edited", "tick",
           "active", "transforming", "on_depsgraph_update", "on_frame_change", "on_load_pre",
           "on_load_post", "HANDLERS"]

#: Seconds after the last edit before its solve is asked for: a drag's moves coalesce.
COALESCE = 0.15
#: Seconds between the timer's polls of the worker.
POLL = 0.03
#: The preview's clock, in seconds: when a solve is due. Tests put a clock of their own here.
clock = time.perf_counter


class State:
    """What the live preview holds between turns of the main loop (module-level `state`).

    Attributes
    ----------
    worker : preview_worker.PreviewWorker or None
        The worker process while the preview is on.
    handle : the draw handler's handle, or None.
    due : float or None
        `clock` time at which the scheduled solve is sent.
    solve_id : int
        Id of the last solve sent (0: none yet): answers to earlier ones are stale.
    answered : int
        Id of the last request answered (a frame or a failure): the solve ``solve_id`` is
        in flight while ``answered < solve_id``.
    transforming : bool
        Whether a transform was running at the last turn of the timer (`transforming`).
    mesh : (frame, vertices, triangles) or None
        The preview shown: the last frame the worker answered.
    drawn : (shader, batch) or None
        Its `overlay.batch` (None where drawing is unavailable).
    stale : bool
        The mesh shown is from inputs edited since (drawn in `overlay.STALE_COLOR`).
    figures : dict
        Of the last solve (`core.bake.preview.Preview.figures`).
    message : str
        Why there is no preview ("" when there is one, or one is on its way).
    """

    def __init__(self) -> None:
        self.worker = self.handle = self.due = None
        self.solve_id = self.answered = 0
        self.transforming = False
        self.mesh = self.drawn = None
        self.stale = False
        self.figures = {}
        self.message = ""


state = State()


def active() -> bool:
    """Whether the preview is running (its worker started)."""
    return state.worker is not None


def _guarded(fn):
    """``fn`` with whatever it raises made `State.message` (nothing reaches Blender's
    handlers and timers), timed as a call on the main loop when diagnostics were asked for
    (`diagnostics.call`)."""
    def guarded(*args):
        try:
            with diagnostics.call(fn.__name__):
                return fn(*args)
        except Exception as exc:  # shown in the panel; the preview must not break Blender
            state.message = f"Live preview: {type(exc).__name__}: {exc}"
            return None

    guarded.__name__, guarded.__doc__ = fn.__name__, fn.__doc__
    return guarded


def start() -> None:
    """Start the worker, the draw handler and the timer, and schedule a first solve now."""
    if state.worker is not None:
        return
    state.__init__()
    state.worker = PreviewWorker()
    state.handle = bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_VIEW")
    state.due = clock()
    if not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=0.0)


def stop() -> None:
    """End the worker and remove the overlay, the draw handler and the timer."""
    if state.worker is not None:
        state.worker.close()
    if state.handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(state.handle, "WINDOW")
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    state.worker = state.handle = state.due = state.mesh = state.drawn = None
    _redraw()


def clear_cache() -> None:
    """Have the worker drop the work it keeps between solves (`core.bake.cache.WorkCache`);
    nothing while the preview is off (its worker, and its cache, are gone then)."""
    if state.worker is not None and state.worker.alive:
        state.worker.clear()


def toggled(session: KFI_Session, _context: bpy.types.Context) -> None:
    """The Live Preview toggle's handler (`props.ON_CHANGE`): start or stop the preview."""
    if session.live_preview:
        start()
    else:
        stop()


def turn_off() -> None:
    """Stop the preview and show its toggle off (what Bake and a file load do first)."""
    stop()
    wm = bpy.context.window_manager
    if wm is not None and wm.keyframe_implicit.live_preview:
        wm.keyframe_implicit.live_preview = False


def schedule() -> None:
    """Ask for a solve `COALESCE` seconds from now (a later edit moves it on)."""
    if state.worker is not None:
        state.due = clock() + COALESCE


def edited(*_args: object) -> None:
    """An input of the bake changed (also `props.ON_CHANGE`'s handler of the settings the
    bake reads): `schedule` a solve and mark the overlay shown as stale."""
    if state.worker is None:
        return
    schedule()
    if not state.stale:
        state.stale = True
        _show(state.mesh)


def _show(mesh):
    """Draw ``mesh`` ((frame, vertices, triangles) or None), in the stale colour while
    `State.stale`."""
    state.mesh = mesh
    state.drawn = None
    if mesh is not None:
        color = overlay.STALE_COLOR if state.stale else overlay.COLOR
        diagnostics.step(f"the overlay of {len(mesh[2])} triangles")
        state.drawn = overlay.batch(mesh[1], mesh[2], color)
    _redraw()


def transforming() -> bool:
    """Whether a transform (``TRANSFORM_OT_*``: a G, R or S drag) is running in a window:
    the moves of a drag come before its end, which is when the artist wants to see the
    result."""
    wm = bpy.context.window_manager
    windows = wm.windows if wm is not None else ()
    return any(op.bl_idname.startswith("TRANSFORM_OT_")
               for window in windows for op in window.modal_operators)


def _watched(scene):
    """The objects whose change needs a new solve: the keyframe objects and feature Empties
    (the originals' pointers)."""
    objs = [kf.object for kf in scene.keyframe_implicit.keyframes if kf.object is not None]
    objs += features.feature_objects(scene)
    return {o.as_pointer() for o in objs}


@bpy.app.handlers.persistent
@_guarded
def on_depsgraph_update(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    """depsgraph_update_post: a keyframe object or a feature Empty moved or changed its
    mesh: `schedule` a solve."""
    if state.worker is None or _reading:
        return
    changed = [u.id.original for u in depsgraph.updates
               if isinstance(u.id, bpy.types.Object)
               and (u.is_updated_transform or u.is_updated_geometry)]
    if changed and {o.as_pointer() for o in changed} & _watched(scene):
        edited()


@bpy.app.handlers.persistent
@_guarded
def on_frame_change(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None = None) -> None:
    """frame_change_post: ask for the new frame (once a solve has been asked for)."""
    if state.worker is None or _reading or not state.solve_id:
        return
    state.worker.frame(scene.frame_current)
    diagnostics.mark("frames")


@bpy.app.handlers.persistent
def on_load_pre(*_args: object) -> None:
    """load_pre: the preview belongs to the file being left."""
    stop()


@bpy.app.handlers.persistent
def on_load_post(*_args: object) -> None:
    """load_post: a file opens with the preview off (a load that keeps the UI keeps the
    window manager, and with it the toggle)."""
    turn_off()


#: Blender's handler lists and the functions this module adds to them.
HANDLERS = (("depsgraph_update_post", on_depsgraph_update),
            ("frame_change_post", on_frame_change),
            ("load_pre", on_load_pre), ("load_post", on_load_post))

_reading = False  # the preview itself reads the scene (frame changes of `scene_io.read`)


def _send_solve(scene):
    """Read the scene (`scene_io.read`), check it and send the solve, or say what is wrong."""
    global _reading
    diagnostics.step("reading the scene")
    _reading = True
    try:
        inputs = scene_io.read(scene, bpy.context.evaluated_depsgraph_get())
    finally:
        _reading = False
    errors = validate.errors(validate.check(inputs))
    if errors:
        state.message = f"Live preview: {errors[0].message}"
        state.mesh = state.drawn = None
        _redraw()
        return
    state.message = ""
    diagnostics.step("sending the solve")
    state.solve_id = state.worker.solve(inputs.core_arguments(), scene.frame_current)
    diagnostics.mark("solves")


def _take(answer):
    """One answer of the worker into `state`."""
    kind, rid = answer[:2]
    if kind == "ended":
        state.message = (f"Live preview: its worker process stopped (exit code {answer[2]}); "
                         "the console shows what it printed. Turn the preview off and on "
                         "to start it again.")
        state.worker.close()
        state.worker = state.mesh = state.drawn = None
        _redraw()
        return
    if rid < state.solve_id:
        return  # an answer to a setup edited since
    if kind in ("frame", "failed"):
        state.answered = rid
    if kind == "solved":
        state.figures = answer[2]
    elif kind == "frame":
        state.stale = state.due is not None  # edits since this solve went out
        _show(tuple(answer[2:5]))
        diagnostics.mark("shown", answer[2])
    elif kind == "failed":
        state.message = f"Live preview: {validate.with_menu_paths(answer[3])}"
        state.mesh = state.drawn = None
        _redraw()


def _solve_now(now, dragging):
    """Whether the scheduled solve goes out on this turn (module docstring): its edits have
    settled, or the transform that made them has just ended; during a transform only when
    no solve is in flight."""
    if state.due is None:
        return False
    ended = state.transforming and not dragging
    if not ended and now < state.due:
        return False
    return not dragging or state.answered >= state.solve_id


@_guarded
def _turn(now):
    if state.worker is None:
        return
    dragging = transforming()
    if _solve_now(now, dragging):
        state.due = None
        _send_solve(bpy.context.scene)
    state.transforming = dragging
    for answer in state.worker.answers():
        _take(answer)
        if state.worker is None:
            break


def tick() -> float | None:
    """The timer: send the due solve, take the worker's answers; returns the next interval
    (None ends the timer once the preview is off)."""
    _turn(clock())
    return POLL if state.worker is not None else None


def _draw():
    if state.drawn is not None:
        overlay.draw(state.drawn)


def _redraw():
    """Tag every 3D view for redrawing (none in background mode)."""
    wm = getattr(bpy.context, "window_manager", None)
    for window in (wm.windows if wm is not None else ()):
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
