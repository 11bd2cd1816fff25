"""Drive a windowed Blender for scripts/screenshot_panel.sh (runs inside Blender).

    blender --python scripts/screenshot_panel.py -- SCENE.blend OUTDIR

With the extension installed and enabled: open SCENE with its own UI, open the
3D view's sidebar on the "Keyframe Implicit" tab at its default width, and write
``panel_<step>.png`` (the sidebar cut out of the X display's pixels, once it has stopped
changing) for the steps before, baking (mid-bake), after, figures (the report's figures
unfolded), compare (the middle frame with Show Keyframes on), inserted (a ball added as the
middle keyframe: its feature points proposed and selected), off_surface (one of them moved
off the ball's surface) and problems (an open plane added as another keyframe);
``window_<step>.png`` keeps the whole window of the steps in `WINDOWS`. The bake is started
as a user starts it (the modal operator); the script quits Blender when done, with exit
code 1 on any error.
"""

import os
import sys

import bpy
import numpy as np
from blender_window import addon_module, decode_xwd, open_scene, run, save_png, view3d, xwd

SCENE, OUT = sys.argv[sys.argv.index("--") + 1:][:2]
WINDOWS = ("before", "after", "compare", "inserted")  # the steps whose whole window is kept too
STABLE_GRABS = 3  # identical sidebar grabs in a row (half a second apart) count as settled
MAX_GRABS = 40


def sidebar_pixels():
    """(the window's pixels, the sidebar cut out of them)."""
    win, area, sidebar, _ = view3d()
    screen = decode_xwd(xwd())[:win.height, :win.width]  # the window sits at the display's corner
    x, y, w, h = sidebar.x, sidebar.y, sidebar.width, sidebar.height  # window pixels, y up
    return screen, screen[y:y + h, x:x + w]


def settled(step, strict=True):
    """Pauses until the sidebar has stopped changing, then writes the pictures of ``step``.

    When a panel's height changes, Blender slides the panels below it to their new
    places over several redraws, and a software-GL window takes about half a second
    per redraw: a capture after a fixed pause can catch the sub-panels half-way, drawn
    over the main panel. So the sidebar is redrawn and grabbed until `STABLE_GRABS`
    grabs in a row are identical. ``strict=False`` (a running bake, whose progress
    line moves) takes the last grab instead of failing.
    """
    last, same = None, 0
    for _ in range(MAX_GRABS):
        view3d()[2].tag_redraw()
        yield 0.5
        screen, pixels = sidebar_pixels()
        same = same + 1 if last is not None and np.array_equal(pixels, last) else 0
        last = pixels
        if same + 1 >= STABLE_GRABS:
            break
    else:
        if strict:
            raise RuntimeError(f"{step}: the sidebar still changed after {MAX_GRABS} grabs")
    save(step, screen, pixels)


def save(step, screen, pixels):
    """panel_<step>.png (the sidebar region), and window_<step>.png (all) for `WINDOWS`."""
    win = view3d()[0]
    if step in WINDOWS:
        save_png(screen, os.path.join(OUT, f"window_{step}.png"))
    save_png(pixels, os.path.join(OUT, f"panel_{step}.png"))
    h, w = pixels.shape[:2]
    print(f"[screenshot_panel] {step}: window {win.width}x{win.height}, sidebar {w}x{h} px, "
          f"UI scale {bpy.context.preferences.system.ui_scale:.2f}", flush=True)


def steps():
    """The run, as a generator of pauses (seconds) between UI updates."""
    yield from open_scene(SCENE)
    win, area, sidebar, main = view3d()
    yield from settled("before")
    ops = addon_module("blender.ops")
    with bpy.context.temp_override(window=win, area=area, region=main):
        assert bpy.ops.keyframe_implicit.bake("INVOKE_DEFAULT") == {"RUNNING_MODAL"}
    while ops.running and ops.running[0].status()[0] < 0.3:
        yield 0.2
    if ops.running:
        yield from settled("baking", strict=False)
    while ops.running:
        yield 0.5
    settings = bpy.context.scene.keyframe_implicit
    assert settings.output_object is not None, "the bake made no result"
    yield from settled("after")
    settings.show_report_details = True  # the figures behind the report
    yield from settled("figures")
    settings.show_report_details = False
    # comparing: the middle frame, with the keyframes shown as wireframes
    scene = bpy.context.scene
    scene.frame_set((scene.frame_start + scene.frame_end) // 2)
    settings.show_keyframes = True
    yield from settled("compare")
    settings.show_keyframes = False
    # a keyframe inserted: a ball between the two at the middle frame; its pairs proposed
    a, b = (kf.object for kf in settings.keyframes)
    middle = (scene.frame_start + scene.frame_end) // 2
    with bpy.context.temp_override(window=win, area=area, region=main):
        bpy.ops.mesh.primitive_uv_sphere_add(
            radius=0.6 * max(a.dimensions), location=(a.matrix_world.translation
                                                       + b.matrix_world.translation) / 2)
        bpy.context.active_object.name = "Middle"
        bpy.ops.keyframe_implicit.add_keyframe(frame=middle)
    yield from settled("inserted")
    # a feature Empty dragged off its keyframe's surface: the warning names it
    ball = scene.objects["Middle"]
    empty = next(o for o in scene.objects if o.select_get() and o.parent == ball)
    centre, point = ball.matrix_world.translation, empty.matrix_world.translation
    empty.matrix_world.translation = centre + 1.3 * (point - centre)
    bpy.context.view_layer.update()
    view3d()[2].tag_redraw()  # a move by script redraws nothing; a drag redraws the sidebar
    yield from settled("off_surface")
    # what a new user hit: an open plane added as a keyframe
    with bpy.context.temp_override(window=win, area=area, region=main):
        bpy.ops.mesh.primitive_plane_add(location=(0, 3, 0))
        bpy.context.active_object.name = "Plane"
        bpy.ops.keyframe_implicit.add_keyframe(frame=middle + 4)
    yield from settled("problems")


run(steps())
