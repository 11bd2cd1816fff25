"""``python -m keyframe_implicit demo``: bake an example scene, save it, render a contact sheet.

Usage (with the bpy module, from the repository root)::

    python -m keyframe_implicit demo [--scene NAME] [--out DIR] [--resolution N]
                                     [--frames K] [--tile WxH]

Stages, one progress line each on the terminal:

1. open ``assets/NAME.blend`` (built by ``assets/make_assets.py`` when the file is missing)
   and register the add-on from this checkout;
2. bake it with ``bpy.ops.keyframe_implicit.bake`` (blocking ``execute``), at ``--resolution``
   cells along the longest side (default `DEFAULT_RESOLUTION`);
3. save ``DIR/NAME.blend``: the keyframes are hidden in the viewport (Alt+H shows them), so
   opening the file and pressing play shows the baked object alone;
4. render K frames headless with Workbench and compose them into ``DIR/NAME.png``, a grid of
   tiles labelled with their frame numbers; keyframe tiles get an orange border.

`render_contact_sheet` works on any scene with a camera, e.g. any shape-keyed mesh.

bpy is imported in the functions that use it: ``demo --help`` works without it, and `main`
says how to get it when it is missing.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import tempfile
import time
from collections.abc import Callable, Collection, Container, Sequence
from typing import TYPE_CHECKING

import numpy as np

from .. import register

if TYPE_CHECKING:  # read by type checkers only: bpy is imported where it is used
    import bpy

SCENES = ("rigid", "merge", "bend", "splash", "suzanne")
DEFAULT_SCENE = "merge"
DEFAULT_RESOLUTION = 32
#: The checkout: the folder above this package, where assets/ lies.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ASSETS = os.path.join(ROOT, "assets")

KEY_BORDER = np.array([0.95, 0.55, 0.1, 1.0], dtype=np.float32)  # sRGB, keyframe tiles
BACKGROUND = np.array([1.0, 1.0, 1.0, 1.0], dtype=np.float32)


def _say(message):
    print(f"[demo] {message}", flush=True)


def _parse_tile(text):
    try:
        w, h = (int(t) for t in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--tile wants WIDTHxHEIGHT in pixels, e.g. 320x240; got {text!r}")
    if not (16 <= w <= 4096 and 16 <= h <= 4096):
        raise argparse.ArgumentTypeError(f"--tile {text}: each side must be 16..4096 pixels")
    return w, h


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """The demo's command line (``python -m keyframe_implicit demo --help``)."""
    p = argparse.ArgumentParser(
        prog="python -m keyframe_implicit demo",
        description="Bake an example scene and write OUT/NAME.blend and a contact sheet OUT/NAME.png.")
    p.add_argument("--scene", default=DEFAULT_SCENE, choices=SCENES,
                   help=f"example scene from assets/ (default: {DEFAULT_SCENE})")
    p.add_argument("--out", default="out", help="output folder (default: ./out)")
    p.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION,
                   help=f"grid cells along the longest side (default: {DEFAULT_RESOLUTION})")
    p.add_argument("--frames", type=int, default=12, help="frames on the contact sheet (default: 12)")
    p.add_argument("--tile", type=_parse_tile, default=(320, 240),
                   help="size of one frame on the sheet, WxH pixels (default: 320x240)")
    args = p.parse_args(argv)
    if args.resolution < 8:
        p.error(f"--resolution {args.resolution} is too coarse: use 8 or more (16-64 is typical)")
    if args.frames < 2:
        p.error("--frames must be at least 2")
    return args


# --------------------------------------------------------------------------- scene
def ensure_registered() -> None:
    """Register the add-on from this checkout (once per process)."""
    import bpy

    if not hasattr(bpy.types.Scene, "keyframe_implicit"):
        register()


def open_scene(name: str) -> bpy.types.Scene:
    """Open assets/NAME.blend (build it with assets/make_assets.py if it is missing)."""
    import bpy

    path = os.path.join(ASSETS, f"{name}.blend")
    ensure_registered()
    if os.path.exists(path):
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    else:
        spec = importlib.util.spec_from_file_location("kfi_make_assets",
                                                      os.path.join(ASSETS, "make_assets.py"))
        if spec is None:
            raise FileNotFoundError(f"{path} is missing and so is assets/make_assets.py to build it")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        module.build(name)
    ensure_registered()
    return bpy.context.scene


def keyframe_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The scene's keyframe mesh objects in timeline order."""
    return [k.object for k in scene.keyframe_implicit.keyframes if k.object is not None]


def output_object(scene: bpy.types.Scene) -> bpy.types.Object | None:
    """The baked object: the setup's output pointer, else the mesh with the most shape keys."""
    settings = scene.keyframe_implicit
    obj = getattr(settings, "output_object", None)
    if obj is not None:
        return obj
    keyed = [o for o in scene.objects if o.type == "MESH" and o.data.shape_keys is not None]
    if not keyed:
        return None
    return max(keyed, key=lambda o: len(o.data.shape_keys.key_blocks))


def bake(scene: bpy.types.Scene, resolution: int) -> bpy.types.Object:
    """Run the add-on's bake (blocking) and return the baked object."""
    import bpy

    result = bpy.ops.keyframe_implicit.bake(resolution=int(resolution))
    if "FINISHED" not in result:
        raise RuntimeError(f"bake did not finish ({result}); see the messages above")
    obj = output_object(scene)
    if obj is None:
        raise RuntimeError("bake finished but no baked object was found in the scene")
    return obj


def hide_setup(scene: bpy.types.Scene) -> None:
    """Hide keyframes and feature Empties in the viewport and in renders (Alt+H shows them)."""
    import bpy

    keys = set(keyframe_objects(scene))
    view_layer = bpy.context.view_layer
    for obj in scene.objects:
        if obj in keys or (obj.type == "EMPTY" and "kfi_pair" in obj.keys()):
            obj.hide_render = True
            if obj.name in view_layer.objects:
                obj.hide_set(True, view_layer=view_layer)


# --------------------------------------------------------------------------- rendering
def sheet_frames(start: int, end: int, count: int, keyframes: Collection[int] = ()
                 ) -> list[int]:
    """About `count` frames from start to end (both included), keyframe frames always in."""
    even = np.rint(np.linspace(start, end, max(2, count))).astype(int)
    frames = set(even.tolist()) | {int(f) for f in keyframes if start <= f <= end}
    if len(frames) > count:  # drop even frames nearest a keyframe, never a keyframe or an end
        keep = {start, end} | {int(f) for f in keyframes}
        spare = sorted(frames - keep,
                       key=lambda f: min(abs(f - k) for k in keep))
        for f in spare[: len(frames) - count]:
            frames.discard(f)
    return sorted(frames)


def _read_png(path):
    """(H, W, 4) float32 pixels of a PNG, top row first."""
    import bpy

    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1]


def _write_png(path, pixels):
    """Write (H, W, 4) float pixels in [0, 1], top row first, as an 8-bit PNG."""
    import bpy

    h, w = pixels.shape[:2]
    img = bpy.data.images.new("kfi_contact_sheet", w, h, alpha=False)
    try:
        img.pixels.foreach_set(np.ascontiguousarray(pixels[::-1], dtype=np.float32).ravel())
        img.filepath_raw = os.path.abspath(path)
        img.file_format = "PNG"
        img.save()
    finally:
        bpy.data.images.remove(img)


def compose(tiles: Sequence[np.ndarray], columns: int, keyed: Container[int] = (),
            gap: int = 10, border: int = 4) -> np.ndarray:
    """Lay (H, W, 4) tiles out in a grid, row by row; tiles whose index is in `keyed` get an
    orange frame drawn in the gap around them (the tile itself is left untouched)."""
    h, w = tiles[0].shape[:2]
    rows = -(-len(tiles) // columns)
    sheet = np.empty((rows * (h + gap) + gap, columns * (w + gap) + gap, 4), dtype=np.float32)
    sheet[:] = BACKGROUND
    for n, tile in enumerate(tiles):
        r, c = divmod(n, columns)
        y, x = gap + r * (h + gap), gap + c * (w + gap)
        if n in keyed:
            sheet[y - border:y + h + border, x - border:x + w + border] = KEY_BORDER
        sheet[y:y + h, x:x + w] = tile
    sheet[..., 3] = 1.0
    return sheet


def render_contact_sheet(scene: bpy.types.Scene, path: str, frames: Sequence[int],
                         keyframes: Collection[int] = (), tile: tuple[int, int] = (320, 240),
                         columns: int | None = None,
                         progress: Callable[[int, int, int], object] | None = None
                         ) -> np.ndarray:
    """Render `frames` of `scene` with Workbench and write them as one grid image to `path`.

    Parameters
    ----------
    scene : bpy.types.Scene with a camera.
    path : output PNG path.
    frames : timeline frames to render, in order.
    keyframes : frames drawn with an orange border.
    tile : (width, height) of one frame in pixels.
    columns : tiles per row (default: 4, or fewer for few frames).

    Returns
    -------
    (H, W, 4) float32 array: the sheet as written (top row first).
    """
    import bpy

    if scene.camera is None:
        raise ValueError(f"scene {scene.name!r} has no camera: add one (or run assets/make_assets.py)")
    r = scene.render
    saved = {k: getattr(r, k) for k in (
        "engine", "resolution_x", "resolution_y", "resolution_percentage", "filepath",
        "use_stamp", "use_stamp_note", "stamp_note_text", "stamp_font_size", "use_file_extension",
        "stamp_foreground", "stamp_background")}
    current = scene.frame_current
    r.engine = "BLENDER_WORKBENCH"
    r.resolution_x, r.resolution_y = tile
    r.resolution_percentage = 100
    r.use_file_extension = True
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGBA"
    _stamp_frame_only(r, font=max(12, tile[1] // 14))
    tiles = []
    try:
        with tempfile.TemporaryDirectory(prefix="kfi_demo_") as tmp:
            for n, f in enumerate(frames):
                scene.frame_set(int(f))
                is_key = int(f) in {int(k) for k in keyframes}
                r.use_stamp_note = is_key
                r.stamp_note_text = "keyframe" if is_key else ""
                r.filepath = os.path.join(tmp, f"frame_{int(f):04d}.png")
                bpy.ops.render.render(write_still=True)
                tiles.append(_read_png(r.filepath))
                if progress is not None:
                    progress(n + 1, len(frames), int(f))
    finally:
        for k, v in saved.items():
            setattr(r, k, v)
        scene.frame_set(current)
    if columns is None:
        columns = min(4, len(tiles))
    keyed = {n for n, f in enumerate(frames) if int(f) in {int(k) for k in keyframes}}
    sheet = compose(tiles, columns, keyed)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    _write_png(path, sheet)
    return sheet


def _stamp_frame_only(render, font):
    render.use_stamp = True
    render.stamp_font_size = font
    for name in dir(render):
        if name.startswith("use_stamp_") and name not in ("use_stamp_frame", "use_stamp_note",
                                                          "use_stamp_labels"):
            try:
                setattr(render, name, False)
            except (AttributeError, TypeError):
                pass
    render.use_stamp_frame = True
    render.use_stamp_labels = True
    render.stamp_foreground = (0.05, 0.05, 0.05, 1.0)
    render.stamp_background = (1.0, 1.0, 1.0, 0.55)


# --------------------------------------------------------------------------- main
def run(scene_name: str = DEFAULT_SCENE, out: str = "out", resolution: int = DEFAULT_RESOLUTION,
        frames: int = 12, tile: tuple[int, int] = (320, 240)
        ) -> tuple[str, str, str, dict[str, float]]:
    """Do the four stages; returns (blend path, png path, baked object name, timings dict)."""
    import bpy

    t0 = time.perf_counter()
    times = {}
    _say(f"1/4 opening example scene '{scene_name}'")
    scene = open_scene(scene_name)
    keys = scene.keyframe_implicit.keyframes
    _say(f"    {len(keys)} keyframes on frames {[k.frame for k in keys]}, "
         f"timeline {scene.frame_start}-{scene.frame_end}")
    times["open"] = time.perf_counter() - t0

    t = time.perf_counter()
    _say(f"2/4 baking at resolution {resolution} (grid cells along the longest side)")
    obj = bake(scene, resolution)
    times["bake"] = time.perf_counter() - t
    if obj.get("kfi_output_kind") == "mesh_sequence":
        span = obj["kfi_frames"]
        stored = f"a mesh sequence of {span[1] - span[0] + 1} frames"
    else:
        nkeys = len(obj.data.shape_keys.key_blocks) - 1 if obj.data.shape_keys else 0
        stored = f"{len(obj.data.vertices)} vertices with {nkeys} frame shape keys"
    _say(f"    baked '{obj.name}': {stored} in {times['bake']:.1f} s")

    os.makedirs(out, exist_ok=True)
    blend = os.path.abspath(os.path.join(out, f"{scene_name}.blend"))
    png = os.path.abspath(os.path.join(out, f"{scene_name}.png"))
    t = time.perf_counter()
    hide_setup(scene)
    scene.frame_set(scene.frame_start)
    bpy.ops.wm.save_as_mainfile(filepath=blend, compress=True, copy=True, check_existing=False)
    times["save"] = time.perf_counter() - t
    _say(f"3/4 saved {blend} (open it and press play)")

    t = time.perf_counter()
    key_frames = [k.frame for k in keys]
    chosen = sheet_frames(scene.frame_start, scene.frame_end, frames, key_frames)
    _say(f"4/4 rendering {len(chosen)} frames (Workbench) -> {png}")
    render_contact_sheet(scene, png, chosen, key_frames, tile=tile)
    times["render"] = time.perf_counter() - t
    times["total"] = time.perf_counter() - t0
    _say(f"done in {times['total']:.1f} s (bake {times['bake']:.1f} s, render {times['render']:.1f} s)")
    return blend, png, obj.name, times


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m keyframe_implicit demo``; returns a process exit code."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        import bpy  # noqa: F401
    except ImportError:
        print("The demo needs Blender's Python module: pip install bpy==5.0.1 (Python 3.11), "
              "or run scripts/demo which sets that up.", file=sys.stderr)
        return 2
    try:
        run(args.scene, args.out, args.resolution, args.frames, args.tile)
    except Exception as exc:  # one clear line for the terminal, non-zero exit
        print(f"[demo] failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
