"""The command line, ``python -m keyframe_implicit COMMAND ...`` (`keyframe_implicit.__main__`
reads COMMAND and hands the rest to its module's ``main``).

==========  ==================================================================
``bake``    ``bake SCENE.blend --out OUT.blend``: a .blend's bake, headless (needs bpy)
``farm``    ``farm STAGE ...``: the bake's stages one at a time, for a render farm
``demo``    ``demo ...``: bake an example scene, save it, render a contact sheet
==========  ==================================================================

Below, what the commands share: the path check before bpy is needed, the progress lines,
the failure line, and opening and saving a .blend with the add-on registered. The
commands sit above every other part of the package: nothing but `keyframe_implicit.__main__`
imports them.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from .. import register
from ..core.base.progress import Cancelled
from ..worker import WorkerError

if TYPE_CHECKING:  # read by type checkers only: bpy is imported when a command needs it
    import bpy

__all__ = ["check_paths", "percent_log", "failure_line", "open_file", "save_copy"]


def check_paths(scene_path: str | None = None, out_path: str | None = None) -> None:
    """ValueError saying what to fix when ``scene_path`` is not a file or the folder of
    ``out_path`` does not exist (None: not checked); before bpy is needed."""
    if scene_path is not None and not os.path.isfile(scene_path):
        raise ValueError(f"No such file: {scene_path!r}: give the path of a .blend file.")
    out_dir = None if out_path is None else os.path.dirname(os.path.abspath(out_path))
    if out_dir is not None and not os.path.isdir(out_dir):
        raise ValueError(f"Output folder {out_dir!r} does not exist: create it first.")


def percent_log(prefix: str, log: Callable[[str], object] = print
                ) -> Callable[[float, str], None]:
    """A progress callback ``(fraction, message)`` that logs a line ``[prefix] NN% message``
    every 10 percent and at the end."""
    last = [-1]

    def report(fraction, message):
        pct = int(100 * fraction)
        if pct >= last[0] + 10 or pct == 100:
            last[0] = pct
            log(f"[{prefix}] {pct:3d}% {message}")

    return report


def failure_line(what: str, exc: BaseException) -> str:
    """The line a command prints when ``what`` failed with ``exc``: the text alone for the
    failures that say what happened and what to do in their own words, else with the
    exception's type."""
    told = isinstance(exc, (ValueError, Cancelled, WorkerError))
    return f"error: {what} failed: {'' if told else f'{type(exc).__name__}: '}{exc}"


def open_file(scene_path: str) -> Iterator[tuple[bpy.types.Scene, bpy.types.Depsgraph | None]]:
    """Open the .blend ``scene_path`` (without its UI) with the add-on registered and yield
    (scene, depsgraph) of each of its scenes with keyframes, the scene made the window's
    when there is a window (the depsgraph then None). ValueError when none has keyframes."""
    import bpy

    register()
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(scene_path), load_ui=False)
    scenes = [s for s in bpy.data.scenes if len(s.keyframe_implicit.keyframes)]
    if not scenes:
        raise ValueError(f"{scene_path!r} has no Keyframe Implicit setup: add keyframes in the "
                         "sidebar (View3D > Sidebar > Keyframe Implicit) and save it.")
    for scene in scenes:
        window = bpy.context.window
        if window is not None:
            window.scene = scene
        depsgraph = scene.view_layers[0].depsgraph if window is None else None
        if depsgraph is not None:
            depsgraph.update()
        yield scene, depsgraph


def save_copy(out_path: str) -> None:
    """Save the open file's state to ``out_path`` as a copy (the open file keeps its path)."""
    import bpy

    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(out_path), copy=True)
