"""Cleanliness of the baked frames per case, size and output, and the mesh sequence's cost.

Run with the bpy venv (scripts/env.sh)::

    python benchmarks/bench_output.py [--sizes 48 64] [--cases merge splash bend suzanne drop3]
                                      [--blend-sizes 64 128]

Part 1 (core only): per case and grid size, for each output (shape keys = the tracked
template, mesh sequence = each frame's own surface), the worst frame's figures of
`core.surface.quality` (area ratio range, largest inverted share, smallest coverage, keyframe
frames' two-way distance mean / max in h), and the bake time with and without the
per-frame surfaces and velocities.

Part 2 (bpy): the merge example baked as a mesh sequence into a .blend: file size,
load time and playback rate (frame_set + evaluation of every frame, no drawing), and
the bake time of each output (the core's run, which measures both outputs, plus writing
the result into the scene).
"""

import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from keyframe_implicit import examples  # noqa: E402
from keyframe_implicit.core import animate  # noqa: E402


def suzanne():
    """Blender's Suzanne turning 90 degrees about z with a slight squash (as in
    suzanne_check.py), six feature pairs on its silhouette; needs bpy."""
    import bpy

    from keyframe_implicit.core import Keyframe

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True, load_ui=False)
    bpy.ops.mesh.primitive_monkey_add(size=2.0)
    mesh = bpy.context.active_object.data
    co = np.empty(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3).astype(float)
    faces = [tuple(p.vertices) for p in mesh.polygons]
    c, s = 0.0, 1.0  # cos, sin of 90 degrees
    m = np.diag([1.05, 1.05, 0.9]) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    cob = co @ m.T + [0.3, 0.0, 0.0]
    x, y, z = co.T
    mid = np.abs(x) < 0.02
    picks = [np.argmin(x), np.argmax(x), np.argmin(np.where(mid, z, np.inf)),
             np.argmax(np.where(mid, z, -np.inf)), np.argmax(np.where(mid, y, -np.inf))]
    return [Keyframe(co, faces, 1), Keyframe(cob, faces, 13)], [(co[picks], cob[picks])]


def case(name):
    """Keyframes and features of a case; "drop3" is the splash's first three keyframes."""
    if name == "suzanne":
        return suzanne()
    if name == "drop3":
        ex = examples.example("splash")
        return ex.keyframes[:3], ex.features[:2]
    ex = examples.example(name)
    return ex.keyframes, ex.features


def summary(per_frame):
    ar = [q["area_ratio"] for q in per_frame]
    km = [q["keyframe_mean"] for q in per_frame if "keyframe_mean" in q]
    kx = [q["keyframe_max"] for q in per_frame if "keyframe_max" in q]
    return (f"{min(ar):6.3f}-{max(ar):5.3f} {100 * max(q['inverted_fraction'] for q in per_frame):7.2f}"
            f" {100 * min(q['coverage'] for q in per_frame):7.1f} {max(km):6.2f} {max(kx):6.2f}")


def core_table(cases, sizes):
    print(f"{'case':7} {'n':>4} {'output':14} {'area ratio':>12} {'inv %':>7} {'cov %':>7}"
          f" {'kf mean':>6} {'kf max':>6}   seconds (shape keys only / with sequence)")
    for name in cases:
        kfs, feats = case(name)
        for n in sizes:
            t0 = time.perf_counter()
            animate(kfs, feats, resolution=n, surfaces=False)
            t_sk = time.perf_counter() - t0
            t0 = time.perf_counter()
            an = animate(kfs, feats, resolution=n)
            t_seq = time.perf_counter() - t0
            for out in ("shape_keys", "mesh_sequence"):
                mark = "*" if an.stats["output"] == out else " "
                print(f"{name:7} {n:4d} {out + mark:14} {summary(an.stats['quality'][out])}"
                      f"   {t_sk:5.1f} / {t_seq:5.1f} ({t_seq / t_sk:.2f}x)", flush=True)


def _write(mode, an):
    """Seconds to write ``an`` into a fresh scene as ``mode``; the scene is left with it."""
    import bpy

    import keyframe_implicit
    from keyframe_implicit.blender import output

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True, load_ui=False)
    keyframe_implicit.register()
    scene = bpy.context.scene
    scene.keyframe_implicit.output_mode = mode
    t0 = time.perf_counter()
    output.write_animation(scene, scene.keyframe_implicit, an)
    return time.perf_counter() - t0


def blend_figures(sizes):
    """The merge as a mesh sequence in a .blend, and the bake time of each output: the
    core's run (the same for both: Auto needs every frame's surface to choose) plus writing
    the result into the scene."""
    import bpy

    import keyframe_implicit

    ex = examples.example("merge")
    print(f"\n{'merge':7} {'n':>4} {'vertices/frame':>15} {'file MB':>8} {'load s':>7} {'play fps':>9}"
          f"   bake s: core + write shape keys / + write sequence (ratio)")
    for n in sizes:
        t0 = time.perf_counter()
        an = animate(ex.keyframes, ex.features, resolution=n)
        t_core = time.perf_counter() - t0
        t_sk = _write("SHAPE_KEYS", an)
        t_seq = _write("MESH_SEQUENCE", an)
        path = os.path.join(tempfile.mkdtemp(), f"merge_{n}.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path, compress=False)
        keyframe_implicit.unregister()
        t0 = time.perf_counter()
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
        t_load = time.perf_counter() - t0
        scene = bpy.context.scene
        obj = bpy.data.objects["KFI Animation"]
        dg = bpy.context.evaluated_depsgraph_get()
        frames = list(an.frames)
        t0 = time.perf_counter()
        for _ in range(2):
            for f in frames:
                scene.frame_set(int(f))
                obj.evaluated_get(dg)
        fps = 2 * len(frames) / (time.perf_counter() - t0)
        verts = np.mean([len(v) for v, _ in an.surfaces])
        print(f"{'merge':7} {n:4d} {verts:15.0f} {os.path.getsize(path) / 2**20:8.1f} {t_load:7.2f}"
              f" {fps:9.1f}   {t_core:.1f} + {t_sk:.2f} / + {t_seq:.2f} "
              f"({(t_core + t_seq) / (t_core + t_sk):.2f}x)", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=["merge", "splash", "bend", "suzanne", "drop3"])
    ap.add_argument("--sizes", nargs="+", type=int, default=[48, 64])
    ap.add_argument("--blend-sizes", nargs="*", type=int, default=[64, 128])
    args = ap.parse_args(argv)
    if args.cases:
        core_table(args.cases, args.sizes)
    if args.blend_sizes:
        blend_figures(args.blend_sizes)


if __name__ == "__main__":
    main()
