"""Volume of every frame of a whole bake: each frame's level set and the output shipped.

A case of `cases.py` (default: ``bunny``, the npm package's scanned bunny into a ball of its
volume) baked through `core.animate` as an artist's scene would be: its keyframes are
meshes (the scan's own mesh where the case has one, else marching cubes of the case's
fields on a 129^3 grid), 24 frames apart. For every frame the enclosed volume of its
level set and of the output the bake chose (the tracked template or the frame's own
mesh) is compared with the volume linear in time between the two keyframes' level sets;
the maps' iterations and smallest det F are printed beside them.

    python benchmarks/bench_volume.py                         # bunny, 96, full and auto
    python benchmarks/bench_volume.py --case scan --sizes 64 96 --motion full

A row per (size, Motion Resolution): the largest |error| of the level sets and of the
output, in per cent, and the frame it is on; ``--frames`` prints every frame's.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.dirname(HERE), HERE]

MESH_NODES = 129


def keyframes(name):
    """(keyframes, features) of a case, its keyframes on frames 1 and 25."""
    import cases
    from keyframe_implicit.core import Keyframe

    case = cases.make_case(name, MESH_NODES)
    meshes = cases.keyframe_meshes(case)
    return [Keyframe(v, t, 1 + 24 * k) for k, (v, t) in enumerate(meshes)], case.features


def _map_figures(stats):
    return {"iterations": [level["iterations"] for level in stats["levels"]],
            "min_det": round(float(stats["min_det"]), 3)}


def run(name, n, motion, processes):
    """Bake case ``name`` at ``n`` cells with ``motion`` ("full", "auto" or a number): the
    row's figures as a dict."""
    from keyframe_implicit.core import animate
    from keyframe_implicit.core.surface.extract import enclosed_volume, mesh_volume

    kfs, features = keyframes(name)
    t0 = time.perf_counter()
    anim = animate(kfs, features, resolution=n, processes=processes, levelsets=True,
                   motion_resolution=None if motion == "auto" else n if motion == "full"
                   else int(motion))
    seconds = time.perf_counter() - t0
    fields = np.array([enclosed_volume(f, anim.grid) for f in anim.levelsets])
    linear = np.interp(np.arange(len(fields)), [0, len(fields) - 1], fields[[0, -1]])
    output = anim.stats["output"]
    shipped = np.array([mesh_volume(*m) for m in anim.surfaces] if output == "mesh_sequence"
                       else [mesh_volume(v, anim.faces) for v in anim.vertices])
    segment = anim.stats["segments"][0]
    errors = {"levelset": 100 * (fields / linear - 1), "output": 100 * (shipped / linear - 1)}
    row = dict(case=name, n=n, motion=anim.stats["motion_resolution"], output=output,
               seconds=round(seconds, 1), frames=[int(f) for f in anim.frames],
               map=_map_figures(segment["map"]))
    if "map_back" in segment:
        row["map_back"] = _map_figures(segment["map_back"])
    for key, err in errors.items():
        row[f"{key}_error_pct"] = [round(float(e), 3) for e in err]
    return row


def print_row(row, frames):
    """One line of ``row``: the worst frame of each measure (every frame's with ``frames``)."""
    parts = [f"{row['case']} {row['n']}^3 motion {row['motion']} ({row['output']}, "
             f"{row['seconds']} s)"]
    for key in ("levelset", "output"):
        err = np.abs(row[f"{key}_error_pct"])
        parts.append(f"{key} worst {err.max():.2f} % at frame {row['frames'][int(err.argmax())]}")
    parts.append(f"maps {row['map']}" + (f" back {row['map_back']}" if "map_back" in row else ""))
    print("; ".join(parts))
    if frames:
        for key in ("levelset", "output"):
            print(f"  {key} error % per frame: {row[f'{key}_error_pct']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="bunny")
    ap.add_argument("--sizes", type=int, nargs="+", default=[96])
    ap.add_argument("--motion", nargs="+", default=["full", "auto"],
                    help='Motion Resolutions: "full" (the size), "auto" or numbers')
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--frames", action="store_true", help="print every frame's errors")
    ap.add_argument("--json", help="also write the rows to this file")
    args = ap.parse_args()
    rows = []
    for n in args.sizes:
        for motion in args.motion:
            rows.append(run(args.case, n, motion, args.processes))
            print_row(rows[-1], args.frames)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
