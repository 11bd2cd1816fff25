"""A windowed Blender driven by a script (runs inside Blender; shared by
scripts/screenshot_panel.py and scripts/window_stall.py).

The driving script is a generator of pauses (seconds) between its steps, run by a
`bpy.app.timers` callback (`run`), so the window keeps drawing and handling events in
between, as it does for a user.
"""

import os
import subprocess
import sys
import traceback

import bpy
import numpy as np

CATEGORY = "Keyframe Implicit"
ADDON = "bl_ext.user_default.keyframe_implicit"


def addon_module(name):
    """The installed extension's module ``name`` (e.g. "blender.ops")."""
    return sys.modules[f"{ADDON}.{name}"]


def view3d():
    """(window, 3D view area, its sidebar region, its main region)."""
    win = bpy.context.window_manager.windows[0]
    area = max((a for a in win.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    regions = {r.type: r for r in area.regions}
    return win, area, regions["UI"], regions["WINDOW"]


def xwd(path=None):
    """``xwd -root``: the X display's pixels, as bytes, or into the file ``path`` without
    waiting (returns the process)."""
    if path is None:
        return subprocess.run(["xwd", "-root", "-silent"], check=True, capture_output=True).stdout
    return subprocess.Popen(["xwd", "-root", "-silent", "-out", path])


def decode_xwd(raw):
    """An XWD image as an (H, W, 4) float RGBA array, bottom row first (as Blender's images).

    screen.screenshot reads back black under Xvfb with Mesa's software GL, so the
    display's own pixels are taken with ``xwd -root`` and decoded here (XWD: a
    big-endian header of 25 uint32, the window name, the colour map, then rows).
    """
    head = np.frombuffer(raw[:100], ">u4")
    header_size, width, height = int(head[0]), int(head[4]), int(head[5])
    byte_order, bits, row_bytes, ncolors = int(head[7]), int(head[11]), int(head[12]), int(head[19])
    masks = [int(m) for m in head[14:17]]
    if bits != 32:
        raise RuntimeError(f"xwd gave {bits} bits per pixel; run the display at depth 24")
    start = header_size + 12 * ncolors
    words = np.frombuffer(raw[start:start + row_bytes * height], "<u4" if byte_order == 0 else ">u4")
    words = words.reshape(height, row_bytes // 4)[:, :width]
    rgba = np.ones((height, width, 4), np.float32)
    for k, mask in enumerate(masks):
        shift = (mask & -mask).bit_length() - 1
        rgba[..., k] = ((words & mask) >> shift) / float(mask >> shift)
    return rgba[::-1]


def save_png(pixels, path):
    h, w = pixels.shape[:2]
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=True)
    img.pixels.foreach_set(np.ascontiguousarray(pixels, np.float32).ravel())
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)


def open_scene(path):
    """Steps: open ``path`` as File > Open does by default (with its own UI: its timeline
    framed on its frames), open the 3D view's sidebar on the extension's tab, and frame
    the keyframe objects."""
    assert ADDON in bpy.context.preferences.addons, "the extension is not enabled"
    win, _, _, _ = view3d()
    with bpy.context.temp_override(window=win):
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=True)
    yield 1.0
    win, area, sidebar, main = view3d()
    area.spaces.active.show_region_ui = True
    yield 0.5
    for _ in range(20):  # the tabs exist once the sidebar has been drawn
        win, area, sidebar, main = view3d()
        if sidebar.active_panel_category == CATEGORY:
            break
        try:
            sidebar.active_panel_category = CATEGORY
        except TypeError:
            pass
        sidebar.tag_redraw()
        yield 0.5
    assert sidebar.active_panel_category == CATEGORY, sidebar.active_panel_category
    keyframes = [kf.object for kf in bpy.context.scene.keyframe_implicit.keyframes]
    for obj in bpy.context.scene.objects:
        obj.select_set(obj in keyframes)
    with bpy.context.temp_override(window=win, area=area, region=main):
        bpy.ops.view3d.view_selected()


def run(steps):
    """Run the generator ``steps`` from a timer, then quit Blender; on any error, leave
    with exit code 1."""

    def tick():
        try:
            return next(steps)
        except StopIteration:
            bpy.ops.wm.quit_blender()
        except Exception:
            traceback.print_exc()
            sys.stdout.flush()
            os._exit(1)
        return None

    bpy.app.timers.register(tick, first_interval=2.0, persistent=True)
