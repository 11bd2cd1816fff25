"""How a whole bake scales with the grid: seconds per stage, peak memory, cost growth.

Every (case, size) runs `core.animate` end to end in a fresh subprocess: the
keyframes are meshes (a scanned mesh's own, else marching cubes of the case's fields on a
fixed 97^3 grid, so the input is the same at every size), 24 frames between them.
Cases: the single-segment cases of `compare.py`, the sphere -> ellipsoid
of `bench_solver.py`, and a scanned mesh (the npm package's bunny, `cases.bunny_mesh`)
morphed into a ball and squashed (``bunny``, ``bunny-squash``); on request
(``--cases splash``) the three-segment splash, 24 frames a segment, its stages summed
over the segments.

    python benchmarks/bench_scale.py                  # 64 128
    python benchmarks/bench_scale.py --sizes 64 128 192 256
    python benchmarks/bench_scale.py --cases rigid squash --sizes 128

Columns: seconds of each stage (distance grids, the two maps, the trajectory
setup, the frame loop with its level sets, surfaces and quality figures, and
the rest: grid choice, keyframe measures and output), the total, the peak
resident set (VmHWM, read by the child at its end, plus its helper process's
peak when ``--processes`` is 2: an upper bound of the two together; both
include an interpreter and numpy), the solver's active nodes on the
finest level, and ``estimate_memory``'s prediction. The last line is the
slope of log(total seconds) against log(active nodes), pooled over the cases
(one intercept per case, one common slope).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path[:0] = [ROOT, HERE]

CASES = ("rigid", "merge", "split", "bend", "squash", "morph", "ellipsoid", "bunny",
         "bunny-squash")
CHAINS = ("splash",)  # several segments: printed, not in the slope
MESH_NODES = 97
STAGES = (("sdf", "distance"), ("maps", "maps"), ("trajectories", "trajectories"),
          ("frames", "frames"), ("rest", "rest"))


def keyframes(name):
    """(keyframes, features) of a case: its meshes (`cases.keyframe_meshes`), 24 frames
    apart (1, 25, ...)."""
    from keyframe_implicit.core import Keyframe

    if name == "ellipsoid":
        from bench_solver import sphere_case
        from keyframe_implicit.core.surface.extract import extract_surface

        grid, phi_a, phi_b, fa, fb = sphere_case(MESH_NODES)
        meshes, features = [extract_surface(f, grid) for f in (phi_a, phi_b)], [(fa, fb)]
    else:
        import cases

        case = cases.make_case(name, MESH_NODES)
        meshes, features = cases.keyframe_meshes(case), case.features
    return [Keyframe(v, t, 1 + 24 * k) for k, (v, t) in enumerate(meshes)], features


def peak_rss_mb():
    """This process's peak resident set (VmHWM), MiB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("VmHWM not found in /proc/self/status")


def motion_arg(value, n):
    """animate's motion_resolution for ``--motion`` at size ``n``: "auto" None, "full" n."""
    return None if value == "auto" else n if value == "full" else int(value)


def run_one(name, n, processes, motion="auto", options=None):
    """Bake one case at ``n`` cells (``options``: animate's stage options); figures as a dict
    (runs in the child)."""
    from keyframe_implicit.core import animate
    from keyframe_implicit.core.bake.memory import estimate_memory
    from keyframe_implicit.core.bake.pipeline import _material_fraction

    kfs, features = keyframes(name)
    t0 = time.perf_counter()
    anim = animate(kfs, features, resolution=n, processes=processes,
                   motion_resolution=motion_arg(motion, n), **(options or {}))
    total = time.perf_counter() - t0
    st = anim.stats
    segs = st["segments"]
    seg = segs[0]
    sec = dict(sdf=st["sdf_seconds"], maps=sum(s["map_seconds"] for s in segs),
               trajectories=sum(s["trajectory_setup_seconds"] for s in segs),
               frames=sum(s["template_seconds"] for s in segs))
    sec["rest"] = total - sum(sec.values())
    frac = max(_material_fraction(kf, anim.grid) for kf in kfs)
    model = estimate_memory(anim.grid, n_keyframes=len(kfs), material_fraction=frac)
    est = model["peak"]
    helper_mb = (st.get("helper_peak_rss_kib") or 0) / 1024.0
    return dict(case=name, n=n, shape=list(anim.grid.shape), seconds=sec, total=total,
                motion=st["motion_resolution"], motion_shape=list(st.get("motion_grid_shape", [])),
                rss_mb=peak_rss_mb() + helper_mb, helper_rss_mb=helper_mb,
                active=seg["map"]["active_nodes"], nodes=int(anim.grid.size),
                material_fraction=frac, model_active=model["active_nodes"],
                estimate_mb=est / 2 ** 20)


def run_child(name, n, processes, motion="auto", options=None):
    """Run `run_one` in a fresh interpreter; its result dict (or the error it printed)."""
    cmd = [sys.executable, os.path.abspath(__file__), "--child", name, str(n), str(processes),
           str(motion), json.dumps(options or {})]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        return dict(case=name, n=n, error=out.stderr.strip().splitlines()[-25:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def pooled_slope(rows, key="active"):
    """Common slope of log(total) on log(``key``), one intercept per case (least squares):
    ``active`` the map's active nodes, ``model_active`` the surface grid's material and
    margin as the memory model counts them (the work's size when the motion grid is
    coarser)."""
    rows = [r for r in rows if "error" not in r and r["case"] in CASES]
    names = sorted({r["case"] for r in rows})
    if len({r["n"] for r in rows}) < 2:
        return float("nan")
    x = np.log([r[key] for r in rows])
    y = np.log([r["total"] for r in rows])
    dummies = np.array([[r["case"] == c for c in names] for r in rows], dtype=float)
    A = np.column_stack([x, dummies])
    return float(np.linalg.lstsq(A, y, rcond=None)[0][0])


def print_table(rows):
    head = " ".join(f"{label:>12}" for _, label in STAGES)
    print(f"{'case':>9} {'n':>4} {'motion':>6} {head} {'total s':>8} {'RSS MiB':>8} "
          f"{'est MiB':>8} {'active':>9}")
    for r in rows:
        if "error" in r:
            print(f"{r['case']:>9} {r['n']:>4} failed: {r['error']}")
            continue
        stages = " ".join(f"{r['seconds'][key]:>12.2f}" for key, _ in STAGES)
        print(f"{r['case']:>9} {r['n']:>4} {r.get('motion', r['n']):>6} {stages} "
              f"{r['total']:>8.2f} {r['rss_mb']:>8.0f} {r['estimate_mb']:>8.0f} {r['active']:>9}")
    print(f"pooled log-log slope of seconds against the map's active nodes: "
          f"{pooled_slope(rows):.2f}; against the surface grid's: "
          f"{pooled_slope(rows, 'model_active'):.2f}")


def run_rows(sizes, names, run, table, json_path=None):
    """``run(name, n)`` for every size and case, each row to stderr as it comes (a long run
    shows its progress), then ``table(rows)`` and the rows to ``json_path`` if given."""
    rows = []
    for n in sizes:
        for name in names:
            rows.append(run(name, n))
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    table(rows)
    if json_path:
        with open(json_path, "w") as fh:
            json.dump(rows, fh, indent=1)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES + CHAINS)
    ap.add_argument("--json", help="also write the rows to this file")
    ap.add_argument("--processes", type=int, default=2,
                    help="animate's processes (2: the worker and its helper, as a bake in "
                         "Blender on two cores or more)")
    ap.add_argument("--motion", default="auto",
                    help='motion_resolution: "auto" (the bake\'s choice), "full" (the size: one '
                         'grid) or a number of cells')
    ap.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE",
                    help="stage options for the bakes (JSON values), e.g. band_cells=Infinity")
    ap.add_argument("--child", nargs=5, metavar=("CASE", "N", "P", "M", "OPTIONS"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(run_one(args.child[0], int(args.child[1]), int(args.child[2]),
                                 args.child[3], json.loads(args.child[4]))))
        return
    options = {k: json.loads(v) for k, v in (kv.split("=", 1) for kv in args.set)}
    run_rows(args.sizes, args.cases,
             lambda name, n: run_child(name, n, args.processes, args.motion, options),
             print_table, args.json)


if __name__ == "__main__":
    main()
