"""How often the Blender panel's keyframe check agrees with the bake, on generated meshes.

Each mesh of tests/hostile_meshes.py (faces flipped, loose vertices near and far, holes,
duplicated or overlapping parts, zero-area faces, scale 1e-4..1e4) becomes a Blender mesh
object; the panel's verdict (`scene_io.read_mesh`, `validate.mesh_problems`: refused or
not) is compared with the core's on the mesh as a bake reads it from Blender (`core_bakes`: its
own check, then an inside on the bake's distance grid). Also counted: meshes the measure calls volumeless although the distance grid
has an inside (sheets flat in their box, read as a one-cell slab; the core refuses those too).

    python benchmarks/bench_panel_agreement.py [--examples 500] [--resolution 48]

(with the bpy module importable and the checkout on PYTHONPATH)
"""

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))

from hypothesis import HealthCheck, given, settings  # noqa: E402

from hostile_meshes import core_bakes, grid_has_inside, hostile_meshes  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--examples", type=int, default=500)
    ap.add_argument("--resolution", type=int, default=48)
    args = ap.parse_args()
    import bpy

    from keyframe_implicit.blender import scene_io, validate

    rows = []

    @settings(derandomize=True, database=None, deadline=None, max_examples=args.examples,
              suppress_health_check=list(HealthCheck))
    @given(hostile_meshes())
    def compare(mesh):
        v, f, what = mesh
        me = bpy.data.meshes.new("Generated")
        me.from_pydata([tuple(p) for p in v], [], [tuple(int(i) for i in t) for t in f])
        obj = bpy.data.objects.new("Generated", me)
        bpy.context.scene.collection.objects.link(obj)
        t0 = time.perf_counter()
        reading = scene_io.read_mesh(obj, bpy.context.evaluated_depsgraph_get())
        refused = any(severity == validate.ERROR for severity, _ in validate.mesh_problems(reading))
        panel_s = time.perf_counter() - t0
        v, f = scene_io.mesh_arrays(obj, bpy.context.evaluated_depsgraph_get())  # as a bake reads it
        bakes = core_bakes(v, f, args.resolution)
        slab = not reading.encloses_volume and grid_has_inside(v, f, args.resolution)
        rows.append((refused, bakes, slab, panel_s, what))
        bpy.data.meshes.remove(me)

    compare()
    agree = sum(refused != bakes for refused, bakes, *_ in rows)
    print(f"{len(rows)} meshes, resolution {args.resolution}: panel and core agree on {agree} "
          f"({100 * agree / len(rows):.1f} %); core bakes {sum(r[1] for r in rows)}, "
          f"panel refuses {sum(r[0] for r in rows)}; volumeless but inside on the grid: "
          f"{sum(r[2] for r in rows)}; panel check max {1000 * max(r[3] for r in rows):.1f} ms")
    for refused, bakes, slab, _, what in rows:
        if refused == bakes:
            print(f"  disagree (panel refuses {refused}, core bakes {bakes}): {what}")


if __name__ == "__main__":
    main()
