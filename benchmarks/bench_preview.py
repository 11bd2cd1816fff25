"""The live preview's own cost, without a window (bpy module): per scene of assets/ (default
merge, bend, splash), the setup read as the preview reads it (`scene_io.read`), then in this
process `core.bake.preview.Preview`: the first solve (distance grids included), a second one
after a feature point moved by a tenth of a grid cell (distance grids kept), and frames:
the middle of the first segment, then the next `FRAMES` one after another (a scrub).
Printed: the grids, seconds per step (median of the frames, and the longest). Then whether the
preview tells the truth: the scene baked as Bake bakes it (the panel's settings), and every
timeline frame's preview measured against the mesh that bake ships on that frame
(`quality.keyframe_distance`, both ways), in the bake's cells: the mean and the largest
distance, over every frame, keyframe frames included.

Usage: ``python benchmarks/bench_preview.py [SCENE ...]`` from the repository root.
"""

import os
import sys
import time

import bpy
import numpy as np

import keyframe_implicit
from keyframe_implicit.blender import scene_io
from keyframe_implicit.core.bake.pipeline import bake
from keyframe_implicit.core.bake.preview import Preview
from keyframe_implicit.core.surface.quality import keyframe_distance

FRAMES = 10


def arguments(name):
    bpy.ops.wm.open_mainfile(filepath=os.path.join("assets", f"{name}.blend"), load_ui=False)
    scene = bpy.context.scene
    return scene_io.read(scene, scene.view_layers[0].depsgraph).core_arguments()


def measure(name):
    args = arguments(name)
    preview = Preview()
    t0 = time.perf_counter()
    figures = preview.solve(**args)
    first = time.perf_counter() - t0
    a, b = args["features"][0]
    a = a.copy()
    extent = np.ptp(np.concatenate([k.vertices for k in args["keyframes"]]), axis=0).max()
    a[0, 0] += 0.1 * extent / figures["resolution"]
    args["features"] = [(a, b)] + list(args["features"][1:])
    t0 = time.perf_counter()
    again = preview.solve(**args)
    moved = time.perf_counter() - t0
    frames = [k.frame for k in args["keyframes"]]
    start = (frames[0] + frames[1]) // 2
    seconds = []
    for f in range(start, start + FRAMES + 1):
        t0 = time.perf_counter()
        preview.frame(f)
        seconds.append(time.perf_counter() - t0)
    print(f"{name}: {len(frames)} keyframes; grid {figures['grid_shape']} (resolution "
          f"{figures['resolution']}), motion grid {figures['motion_grid_shape']} (motion "
          f"resolution {figures['motion_resolution']}); first solve {first:.2f} s, after a "
          f"feature moved {moved:.2f} s ({again['distance_grids_kept']} distance grids kept); "
          f"frame {seconds[0]:.3f} s, then {FRAMES} in a row: median "
          f"{np.median(seconds[1:]):.3f} s, longest {max(seconds[1:]):.3f} s "
          f"(load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} CPUs)", flush=True)


def shipped(animation, i):
    """The mesh the bake ships on its frame i (the output it chose)."""
    if animation.stats["output"] == "shape_keys":
        return animation.vertices[i], animation.faces
    return animation.sequence_frame(i)


def agreement(name):
    """The preview's frames against the bake's, every frame, in the bake's cells."""
    args = arguments(name)
    options = args.pop("options")
    baked = bake(options=options, **args)
    preview = Preview()
    preview.solve(options=options, **args)
    rows = []
    for i, f in enumerate(baked.frames):
        d = keyframe_distance(*preview.frame(int(f)), *shipped(baked, i), baked.grid.spacing)
        rows.append((int(f), d["keyframe_mean"], d["keyframe_max"]))
    f, mean, top = np.array(rows).T
    print(f"{name}: preview against the bake ({baked.stats['output']}, grid {baked.grid.shape}, "
          f"motion grid {baked.stats.get('motion_grid_shape')}), {len(f)} frames, bake cells: "
          f"mean {mean.mean():.2f} (worst frame {mean.max():.2f}, frame {int(f[mean.argmax()])}), "
          f"max {top.max():.2f} (frame {int(f[top.argmax()])})", flush=True)


def main(names):
    keyframe_implicit.register()
    for name in names or ["merge", "bend", "splash"]:
        measure(name)
    for name in names or ["merge", "bend", "splash"]:
        agreement(name)


if __name__ == "__main__":
    main(sys.argv[1:])
    sys.stdout.flush()
    os._exit(0)  # the bpy module's teardown is not this benchmark's
