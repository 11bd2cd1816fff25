"""The farm job on one machine against the bake on one machine: wall time, the ratio, each
step's seconds, and whether the two results are equal.

Both bake a saved scene end to end from the command line: the local bake with
``python -m keyframe_implicit bake`` (worker and helper processes, as the Bake button),
the farm job with ``openjd run`` of the job template ``farm template --scene`` writes (its
steps one after another, each task a process of its own with a helper for the second
core). What the ratio above 1 costs is the tasks' own starts and reads and the Paths step.

    python benchmarks/bench_farm.py --resolution 64 [--scene assets/splash.blend] [--runs 3]
                                    [--pairs-per-task N]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STEPS = ("Prepare", "Maps", "Paths", "Segments", "Assemble")


def _env():
    path = [ROOT] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    return dict(os.environ, PYTHONPATH=os.pathsep.join(path))


def _timed(argv, cwd):
    t0 = time.perf_counter()
    done = subprocess.run(argv, cwd=cwd, env=_env(), capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"{' '.join(map(str, argv))} failed:\n{done.stdout[-2000:]}"
                         f"{done.stderr[-2000:]}")
    return time.perf_counter() - t0, done.stdout


def local_bake(scene, resolution, work):
    """Seconds of a local bake, and the .blend it wrote."""
    out = os.path.join(work, "local.blend")
    seconds, _ = _timed([sys.executable, "-m", "keyframe_implicit", "bake", scene, "--out", out,
                         "--resolution", str(resolution)], work)
    return seconds, out


def farm_job(scene, resolution, work, pairs_per_task=None):
    """Seconds of ``openjd run`` (the job template written before the clock starts; the job
    parameter PairsPerTask when given), each step's seconds from its log, and the .blend it
    wrote."""
    job = os.path.join(work, "job")
    _timed([sys.executable, "-m", "keyframe_implicit", "farm", "template", job, "--scene", scene,
            "--resolution", str(resolution)], work)
    openjd = os.path.join(os.path.dirname(sys.executable), "openjd")
    chunk = [] if pairs_per_task is None else ["-p", f"PairsPerTask={pairs_per_task}"]
    seconds, log = _timed([openjd, "run", os.path.join(job, "template.yaml"), *chunk], work)
    return seconds, step_seconds(log), os.path.join(job, "baked.blend")


def step_seconds(log):
    """{step: seconds} from an ``openjd run`` log (each line starts with the elapsed time)."""
    marks = []
    for line in log.splitlines():
        m = re.match(r"(\d+):(\d+):([\d.]+)\s+(.*)", line)
        if m:
            t = int(m[1]) * 3600 + int(m[2]) * 60 + float(m[3])
            step = re.search(r"Running step '(\w+)'", m[4])
            marks.append((t, step[1] if step else None))
    starts = [(t, s) for t, s in marks if s]
    end = marks[-1][0]
    return {s: (starts[i + 1][0] if i + 1 < len(starts) else end) - t
            for i, (t, s) in enumerate(starts)}


def largest_difference(a, b):
    """The largest difference between the baked meshes' arrays of two .blend files (run in a
    separate process: opening a .blend replaces this one's data)."""
    code = ("import sys, numpy as np, bpy\n"
            "def arrays(p):\n"
            "    bpy.ops.wm.open_mainfile(filepath=p, load_ui=False)\n"
            "    out = {}\n"
            "    for me in bpy.data.meshes:\n"
            "        if not me.name.startswith('KFI'): continue\n"
            "        for k, data in [('co', me.vertices)] + [(b.name, b.data) for b in "
            "(me.shape_keys.key_blocks if me.shape_keys else [])]:\n"
            "            a = np.empty(len(data) * 3, np.float32); data.foreach_get('co', a)\n"
            "            out[me.name + k] = a\n"
            "    return out\n"
            "a, b = arrays(sys.argv[1]), arrays(sys.argv[2])\n"
            "assert sorted(a) == sorted(b)\n"
            "print(max(float(np.abs(a[k] - b[k]).max()) for k in a))\n")
    _, out = _timed([sys.executable, "-c", code, a, b], ROOT)
    return float(out.strip().splitlines()[-1])


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolution", type=int, default=64)
    p.add_argument("--scene", default=os.path.join(ROOT, "assets", "splash.blend"))
    p.add_argument("--runs", type=int, default=1)
    p.add_argument("--pairs-per-task", type=int, default=None,
                   help="the job parameter PairsPerTask (default: the job template's)")
    args = p.parse_args(argv)
    scene = os.path.abspath(args.scene)
    local, farm, steps, diffs = [], [], [], []
    for _ in range(args.runs):  # in turn, so that a drift in the machine's speed hits both
        work = tempfile.mkdtemp()
        try:
            t_local, out_local = local_bake(scene, args.resolution, work)
            t_farm, step, out_farm = farm_job(scene, args.resolution, work, args.pairs_per_task)
            diffs.append(largest_difference(out_local, out_farm))
        finally:
            shutil.rmtree(work, ignore_errors=True)
        local.append(t_local)
        farm.append(t_farm)
        steps.append(step)
    ratios = [f / t for f, t in zip(farm, local)]
    print(f"{os.path.basename(scene)} at {args.resolution}, {os.cpu_count()} cores, "
          f"{args.runs} run(s), medians, PairsPerTask {args.pairs_per_task or 'default'}")
    print("| local bake s | openjd run s | ratio | " + " | ".join(f"{s} s" for s in STEPS)
          + " | largest difference |")
    print("|---" * (len(STEPS) + 4) + "|")
    print(f"| {statistics.median(local):.1f} | {statistics.median(farm):.1f} | "
          f"{statistics.median(ratios):.2f} | "
          + " | ".join(f"{statistics.median(s.get(n, 0.0) for s in steps):.1f}" for n in STEPS)
          + f" | {max(diffs):.1e} |")
    print("ratio of each run, in order: " + ", ".join(f"{r:.2f}" for r in ratios))


if __name__ == "__main__":
    main()
