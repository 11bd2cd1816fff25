"""Quality and speed of this project side by side with the alternatives.

One command produces the table and plots::

    python benchmarks/compare.py                      # 32, 48, 64 (all cases, all methods)
    python benchmarks/compare.py --sizes 32,48,64,96  # choose grid sizes
    python benchmarks/compare.py --quick              # 32^3 smoke run
    python benchmarks/compare.py --methods blend,morph,rbf --merge   # add to the committed results
    python benchmarks/compare.py --cases unequal-merge,unequal-split --methods project,one-sided
    python benchmarks/compare.py --cases scan --sizes 96   # the scanned bunny (needs pymeshfix)
    python benchmarks/compare.py --cases bunny --sizes 96  # the npm bunny (fetched once)

The default cases are the seven of ``cases.CASE_NAMES``; ``cases.EXTRA_CASES`` run by name.

Every (case, method, size) runs in its own subprocess, so its peak memory is
that subprocess's ru_maxrss (includes the Python + numpy + scipy baseline,
reported separately as ``import_rss_mb``). Results go to benchmarks/results/:
results.json (everything), results.csv, results.md (the table) and two plots.

Methods and metrics: see baselines.py and metrics.py. Frames: 9 per keyframe
pair, s = 0, 1/8, ..., 1. The splash chain is run pair by pair (3 segments);
its figures are the worst segment's (drift, spurious pieces, errors) and the
sum of the segments' seconds.
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import resource
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
HERE = pathlib.Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402

METHOD_ORDER = ("project", "one-iso", "torn", "one-sided", "blend", "morph", "rbf")
METHOD_LABEL = {"project": "this project", "one-sided": "this project, one-sided (thesis eq. 3.4)",
                "one-iso": "this project, one iso-value per frame",
                "torn": "this project, maps that tear (tear=True)",
                "blend": "linear SDF blend", "morph": "morph flow (OpenVDB-style)",
                "rbf": "plain RBF warp"}


def _rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


# -- one (case, method, size) --------------------------------------------------
def evaluate(case_name, method, n, n_frames=9):
    """Run one method on one case and size; return a dict of figures (no files written)."""
    import baselines
    import cases
    import metrics

    import_rss = _rss_mb()
    case = cases.make_case(case_name, n)
    grid = case.grid
    h = grid.spacing
    times = np.linspace(0.0, 1.0, n_frames)
    run_fn = baselines.METHODS[method]
    out = {"case": case_name, "method": method, "n": n, "h": h, "frames": n_frames,
           "import_rss_mb": import_rss, "active_voxels": metrics.active_voxels(case.fields[0], grid)}
    seconds, drifts, drift_s, spurious, comps, end_err, feat, infos, vols = {}, [], [], [], [], [], [], [], []
    pieces, dets = [], {"forward": [], "backward": []}
    for k, (fa, fb) in enumerate(case.features):
        phi_a, phi_b = case.fields[k], case.fields[k + 1]
        run = run_fn(phi_a, phi_b, grid, fa, fb, times)
        if run.paths is not None:
            recs = metrics.part_volume_errors(run.frames, times, grid, phi_a, phi_b, *run.paths)
            pieces += [dict(r, segment=k) for r in recs]
            if case_name == "splash" and k == 0:
                out.update(_droplet_and_pool(recs, run.frames, times, grid, phi_a))
        cracks = run.cracks or (None, None)
        for side, mapped, phi, crack in (("forward", run.mapped, phi_a, cracks[0]),
                                         ("backward", run.mapped_back, phi_b, cracks[1])):
            if mapped is not None:
                dets[side].append(metrics.det_f(mapped, grid, phi, crack))
        for st, sec in run.seconds.items():
            seconds[st] = seconds.get(st, 0.0) + sec
        v = [metrics.volume(f, grid) for f in run.frames]
        vols.append(v)
        vkey = (metrics.volume(phi_a, grid), metrics.volume(phi_b, grid))
        drifts.append(metrics.volume_drift(v, times, vkey))
        lin = (1 - times) * vkey[0] + times * vkey[1]
        drift_s.append(float(times[int(np.argmax(np.abs(np.asarray(v) - lin) / lin))]))
        c = [metrics.components(f) for f in run.frames]
        comps.append(c)
        spurious.append(metrics.spurious_components(c, case.expected_components[k],
                                                    case.expected_components[k + 1]))
        end_err.append(metrics.surface_error(run.frames[0], grid, phi_a)[0])
        end_err.append(metrics.surface_error(run.frames[-1], grid, phi_b)[0])
        if run.mapped is not None:
            feat.append(metrics.feature_error(run.mapped, grid, fa, fb))
        infos.append(run.info)
        if case.truth is not None:
            mid = int(np.argmin(np.abs(times - 0.5)))
            gmean, gmax = metrics.surface_error(run.frames[mid], grid, lambda p: case.truth(p, times[mid]))
            out["truth_mean_h"], out["truth_max_h"] = gmean, gmax
            # all in-between frames, for the record
            errs = [metrics.surface_error(f, grid, lambda p, s=s: case.truth(p, s))
                    for f, s in zip(run.frames, times)]
            out["truth_mean_h_all"] = max(e[0] for e in errs)
            out["truth_max_h_all"] = max(e[1] for e in errs)
            # the metric's own floor: drift of the ground-truth sequence sampled on this grid
            pts = grid.points()
            out["volume_drift_floor"] = metrics.volume_drift(
                [metrics.volume(case.truth(pts, s), grid) for s in times], times)
    out["seconds"] = seconds
    out["total_seconds"] = float(sum(seconds.values()))
    out["volume_drift"] = float(max(drifts))
    out["volume_drift_at_s"] = drift_s[int(np.argmax(drifts))]
    out["volumes"] = vols
    out["components"] = comps
    out["spurious_components"] = int(max(spurious))
    out["keyframe_end_error_h"] = float(np.nanmax(end_err)) if not np.all(np.isnan(end_err)) else float("nan")
    if feat:
        allf = np.concatenate(feat)
        out["feature_error_mean_h"] = float(allf.mean())
        out["feature_error_max_h"] = float(allf.max())
    if pieces:
        worst = max(pieces, key=lambda r: r["error"])
        out["part_volume_error"] = worst["error"]
        out["part_volume_error_at_s"] = worst["s"]
        out["part_volume_error_segment"] = worst["segment"]
        out["part_volume_own_error"] = max(r["own_error"] for r in pieces)
        out["part_volumes"] = pieces
    for side, d in dets.items():
        if d:  # over the material of every segment's map
            out[f"det_f_{side}"] = metrics.det_f_summary(*(np.concatenate(a) for a in zip(*d)))
    out["info"] = infos
    out["peak_rss_mb"] = _rss_mb()
    return out


def _droplet_and_pool(pieces, frames, times, grid, phi_a):
    """The splash's first segment until the droplet touches the pool: the droplet's worst
    part-volume error (the smaller piece, `metrics.part_volume_errors` records ``pieces``)
    and the dent, max over those frames of the pool's top under the droplet (x = y = 0) in
    A minus in the frame, in h."""
    import metrics

    start = {r["piece"]: r["reference"] for r in pieces if r["s"] == 0.0}
    drop = [r for r in pieces if r["piece"] == min(start, key=start.get)]
    worst = max(drop, key=lambda r: r["error"])
    apart = {r["s"] for r in drop}
    top = metrics.top_height(phi_a, grid)
    dent = max(top - metrics.top_height(f, grid) for f, s in zip(frames, times) if s in apart)
    return {"droplet_volume_error": worst["error"], "droplet_volume_error_at_s": worst["s"],
            "droplet_volume_own_error": max(r["own_error"] for r in drop),
            "dent_h": dent / grid.spacing}


def _worker(args):
    try:
        res = evaluate(args.worker_case, args.worker_method, args.worker_n, args.frames)
    except ImportError as exc:
        res = {"case": args.worker_case, "method": args.worker_method, "n": args.worker_n,
               "error": f"not available: {exc}"}
    except NotImplementedError as exc:
        res = {"case": args.worker_case, "method": args.worker_method, "n": args.worker_n,
               "error": f"not implemented: {exc}"}
    print("RESULT " + json.dumps(res, default=float))


def run_one(case_name, method, n, frames, timeout):
    """Run `evaluate` in a fresh subprocess; returns its dict (or an error record)."""
    cmd = [sys.executable, str(pathlib.Path(__file__).resolve()), "--worker-case", case_name,
           "--worker-method", method, "--worker-n", str(n), "--frames", str(frames)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=str(ROOT))
    except subprocess.TimeoutExpired:
        return {"case": case_name, "method": method, "n": n, "error": f"timeout after {timeout} s"}
    for line in proc.stdout.splitlines()[::-1]:
        if line.startswith("RESULT "):
            res = json.loads(line[7:])
            res["subprocess_seconds"] = time.perf_counter() - t0
            return res
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
    return {"case": case_name, "method": method, "n": n, "error": "failed: " + " | ".join(tail)}


# -- table and plots -----------------------------------------------------------
def _fmt(v, spec):
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "n/a"
    return format(v, spec)


COLUMNS = [
    ("case", "case", "s"), ("n", "n", "d"), ("method", "method", "s"),
    ("volume_drift", "vol drift %", "pct"), ("truth_mean_h", "truth mean h", ".2f"),
    ("truth_max_h", "truth max h", ".2f"), ("keyframe_end_error_h", "end err h", ".2f"),
    ("feature_error_max_h", "feat err max h", ".2g"), ("spurious_components", "spurious", "d"),
    ("part_volume_error", "part vol err %", "pct"), ("part_volume_error_at_s", "at s", ".3g"),
    ("part_volume_own_error", "own %", "pct"),
    ("det_f_forward", "det F A->B p5/p50/p95 (max dev)", "det"),
    ("det_f_backward", "det F B->A p5/p50/p95 (max dev)", "det"),
    ("total_seconds", "seconds", ".2f"), ("stages", "stages (s)", "s"), ("peak_rss_mb", "peak MB", ".0f"),
]


def _row(r):
    row = {}
    for key, _, spec in COLUMNS:
        if "error" in r and key not in ("case", "n", "method"):
            row[key] = "n/a"
            continue
        if key == "stages":
            row[key] = " ".join(f"{k} {v:.2f}" for k, v in r.get("seconds", {}).items())
        elif spec == "det":
            v = r.get(key)
            row[key] = "n/a" if v is None else (
                f"{v['p5']:.2f}/{v['p50']:.2f}/{v['p95']:.2f} ({v['max_dev']:.2f}), "
                f"{100 * v['in_band']:.0f} % in band" + (f", crack {100 * v['crack']:.0f} %"
                                                         if v.get("crack") else ""))
        elif spec == "pct":
            v = r.get(key)
            row[key] = _fmt(None if v is None else 100 * v, ".2f")
        elif key == "method":
            row[key] = r[key]
        else:
            row[key] = _fmt(r.get(key), spec) if spec != "s" else str(r.get(key, ""))
    if "error" in r:
        row["stages"] = r["error"][:60]
    return row


def write_results(results, outdir):
    from cases import ALL_CASES, CASE_NAMES
    outdir = pathlib.Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    order = {m: i for i, m in enumerate(METHOD_ORDER)}
    corder = {c: i for i, c in enumerate(ALL_CASES)}
    results = sorted(results, key=lambda r: (corder.get(r["case"], 99), r["n"], order.get(r["method"], 9)))
    (outdir / "results.json").write_text(json.dumps(results, indent=1, default=float) + "\n")
    rows = [_row(r) for r in results]
    with open(outdir / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[k for k, _, _ in COLUMNS])
        w.writeheader()
        w.writerows(rows)
    head = "| " + " | ".join(t for _, t, _ in COLUMNS) + " |"
    sep = "|" + "|".join("---" for _ in COLUMNS) + "|"
    lines = [head, sep] + ["| " + " | ".join(row[k] for k, _, _ in COLUMNS) + " |" for row in rows]
    md = [
        "# Comparison benchmark results",
        "",
        "Produced by `python benchmarks/compare.py` (see the module docstring and benchmarks/README section "
        "in the top-level README). Shared 2-core machine: seconds and memory are as measured, noisy.",
        "",
        "Columns: vol drift = max over the 9 frames of |V(s) - V_lin(s)| / V_lin(s); truth = |ground-truth SDF| "
        "at the zero-set vertices at s = 0.5 (rigid case only), in h; end err = mean |keyframe SDF| at the "
        "zero set of s = 0 and s = 1 (worse of the two), in h; feat err = max |y(x'_i) - y'_i| in h "
        "(n/a where the method has no map); spurious = max over frames of pieces beyond the keyframes' count; "
        "part vol err = max over frames and pieces apart of |V(part) - V_lin(piece)| / V_lin(piece), the "
        "pieces followed along the maps' paths (metrics.part_volume_errors; n/a for methods without paths), "
        "at s its frame; own = the same against the piece's share of its own keyframe on the total's straight "
        "line (a reference the maps do not decide); det F = 5th/50th/95th percentile of det F at the material's cell centres of the map "
        "A -> B and B -> A (max |det F - 1| in brackets; in band = share in [0.8, 1.25]; over the material "
        "off the crack of a torn map, crack = the crack's share of the material; metrics.det_f); "
        "seconds = sum of the method's stages (metrics excluded); peak MB = ru_maxrss of the subprocess "
        "(Python + numpy + scipy alone take about " + _fmt(_import_rss(results), ".0f") + " MB).",
        "",
    ] + lines + [""]
    splash = [r for r in results if "dent_h" in r]
    if splash:
        md += ["## Splash before contact", "",
               "Droplet = max over the first segment's frames until it touches the pool of its part-volume "
               "error; dent = max over those frames of the pool's top under the droplet (x = y = 0) in the "
               "keyframe minus in the frame, in h (metrics.top_height).", "",
               "| n | method | droplet vol err % | at s | own % | dent h |", "|---|---|---|---|---|---|"]
        md += [f"| {r['n']} | {r['method']} | {100 * r['droplet_volume_error']:.2f} | "
               f"{r['droplet_volume_error_at_s']:.3g} | {100 * r['droplet_volume_own_error']:.2f} | "
               f"{r['dent_h']:.2f} |" for r in splash]
        md.append("")
    floors = [r for r in results if "volume_drift_floor" in r and r["method"] == "blend"]
    if floors:
        md += ["Volume metric floor (drift of the exact rigid motion sampled on the grid): "
               + ", ".join(f"{r['n']}^3 {100 * r['volume_drift_floor']:.2f}%" for r in sorted(floors, key=lambda r: r["n"]))
               + ".", ""]
    md += ["## Cost growth", "",
           "Log-log slope (numpy polyfit) of wall seconds and of peak RSS above the import baseline against "
           "active voxels (phi_a < 2h), per case over the grid sizes run, and pooled over all cases and sizes.", "",
           "| method | case | time slope | memory slope | runs |", "|---|---|---|---|---|"]
    for m in METHOD_ORDER:
        for c in CASE_NAMES + (None,):
            sl = cost_slopes(results, m, c)
            if sl:
                md.append(f"| {METHOD_LABEL[m]} | {c or 'all (pooled)'} | {sl['time_slope']:.2f} | "
                          f"{sl['memory_slope']:.2f} | {sl['points']} |")
    md.append("")
    (outdir / "results.md").write_text("\n".join(md))
    _plots(results, outdir)
    return outdir / "results.md"


def _import_rss(results):
    v = [r["import_rss_mb"] for r in results if "import_rss_mb" in r]
    return float(np.median(v)) if v else None


def cost_slopes(results, method="project", case=None):
    """Log-log slopes (numpy polyfit) of seconds and peak MB against active voxels for ``method``.

    With ``case`` the fit runs over that case's grid sizes only; without, over
    every (case, size) run of the method (cases differ in shape, so the pooled
    slope mixes shape with size: the per-case slopes are the cleaner figure).
    Memory is peak RSS above the import baseline.
    """
    rs = [r for r in results if r["method"] == method and "error" not in r and (case is None or r["case"] == case)]
    if len(rs) < 2 or len({r["active_voxels"] for r in rs}) < 2:
        return None
    x = np.log([r["active_voxels"] for r in rs])
    t = np.log([max(r["total_seconds"], 1e-6) for r in rs])
    m = np.log([max(r["peak_rss_mb"] - r["import_rss_mb"], 1.0) for r in rs])
    return {"time_slope": float(np.polyfit(x, t, 1)[0]), "memory_slope": float(np.polyfit(x, m, 1)[0]),
            "points": len(rs)}


_COLOURS = {"project": "C3", "one-iso": "C5", "torn": "C6", "one-sided": "C4", "blend": "C0",
            "morph": "C2", "rbf": "C1"}


def _plots(results, outdir):
    """quality.png and cost.png in ``outdir`` from the seven cases' rows that ran."""
    import matplotlib
    from cases import CASE_NAMES
    matplotlib.use("Agg")

    results = [r for r in results if r["case"] in CASE_NAMES]
    ok = [r for r in results if "error" not in r]
    if not ok:
        return
    methods = [m for m in METHOD_ORDER if any(r["method"] == m for r in ok)]
    _quality_plot(ok, methods, outdir)
    _cost_plot(results, ok, methods, outdir)


def _quality_plot(ok, methods, outdir):
    """Volume drift per case and method at the largest size run, and the rigid case's
    error to the ground truth over the sizes."""
    import matplotlib.pyplot as plt
    from cases import CASE_NAMES

    colours = _COLOURS
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    nmax = max(r["n"] for r in ok)
    width = 0.8 / max(len(methods), 1)
    for j, m in enumerate(methods):
        vals = []
        for c in CASE_NAMES:
            rr = [r for r in ok if r["case"] == c and r["method"] == m and r["n"] == nmax]
            vals.append(100 * rr[0]["volume_drift"] if rr else np.nan)
        axes[0].bar(np.arange(len(CASE_NAMES)) + j * width, vals, width, label=METHOD_LABEL[m],
                    color=colours[m])
    axes[0].set_xticks(np.arange(len(CASE_NAMES)) + 0.4 - width / 2)
    axes[0].set_xticklabels(CASE_NAMES)
    axes[0].set_ylabel("max volume drift over frames (%)")
    axes[0].set_title(f"volume drift at {nmax}^3")
    axes[0].set_yscale("log")
    axes[0].legend(fontsize=8)
    for m in methods:
        rr = sorted([r for r in ok if r["case"] == "rigid" and r["method"] == m and "truth_mean_h" in r],
                    key=lambda r: r["n"])
        if rr:
            axes[1].plot([r["n"] for r in rr], [r["truth_mean_h"] for r in rr], "o-", color=colours[m],
                         label=METHOD_LABEL[m] + " (mean)")
            axes[1].plot([r["n"] for r in rr], [r["truth_max_h"] for r in rr], "x--", color=colours[m],
                         label=METHOD_LABEL[m] + " (max)")
    axes[1].set_xlabel("grid nodes per axis")
    axes[1].set_ylabel("|ground truth SDF| at zero set, s = 0.5 (h)")
    axes[1].set_yscale("log")
    axes[1].set_title("rigid case: error to ground truth")
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(outdir / "quality.png", dpi=110)
    plt.close(fig)



def _cost_plot(results, ok, methods, outdir):
    """Time and peak memory against active voxels: one line per (method, case) over the
    sizes, with the median per-case log-log slope in the legend."""
    import matplotlib.pyplot as plt
    from cases import CASE_NAMES

    colours = _COLOURS
    from matplotlib.ticker import NullFormatter
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    markers = dict(zip(CASE_NAMES, "osD^vPX"))
    for m in methods:
        slopes = [cost_slopes(results, m, c) for c in CASE_NAMES]
        slopes = [sl for sl in slopes if sl]
        lab_t = lab_m = METHOD_LABEL[m]
        if slopes:
            lab_t += f" (slope {np.median([sl['time_slope'] for sl in slopes]):.2f})"
            lab_m += f" (slope {np.median([sl['memory_slope'] for sl in slopes]):.2f})"
        for i, c in enumerate(CASE_NAMES):
            rr = sorted([r for r in ok if r["method"] == m and r["case"] == c], key=lambda r: r["n"])
            if not rr:
                continue
            x = [r["active_voxels"] for r in rr]
            axes[0].loglog(x, [max(r["total_seconds"], 1e-4) for r in rr], "-", marker=markers[c],
                           color=colours[m], label=lab_t if i == 0 else None, lw=2 if m == "project" else 0.8)
            axes[1].loglog(x, [max(r["peak_rss_mb"] - r["import_rss_mb"], 1.0) for r in rr], "-",
                           marker=markers[c], color=colours[m], label=lab_m if i == 0 else None,
                           lw=2 if m == "project" else 0.8)
    for ax in axes:
        ax.set_xlabel("active voxels (phi_a < 2h)")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.legend(fontsize=7, title="median per-case log-log slope", title_fontsize=7)
    axes[0].set_ylabel("wall seconds, all stages (shared 2-core machine)")
    axes[1].set_ylabel("peak RSS above import baseline (MB)")
    axes[0].set_title("time against active voxels (lines: one case over sizes)")
    axes[1].set_title("memory against active voxels")
    fig.suptitle("markers: " + ", ".join(f"{c} '{markers[c]}'" for c in CASE_NAMES), fontsize=8, y=0.99)
    fig.tight_layout()
    fig.savefig(outdir / "cost.png", dpi=110)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", default="32,48,64", help="comma-separated nodes per axis (e.g. 32,48,64,96,128)")
    p.add_argument("--cases", default=None, help="comma-separated case names (default: all)")
    p.add_argument("--methods", default=",".join(METHOD_ORDER))
    p.add_argument("--quick", action="store_true", help="smoke run at 32^3 only")
    p.add_argument("--frames", type=int, default=9, help="frames per keyframe pair including both ends")
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per (case, method, size)")
    p.add_argument("--out", default=str(HERE / "results"))
    p.add_argument("--merge", action="store_true",
                   help="keep rows of the existing results.json that this run does not redo")
    p.add_argument("--render-only", action="store_true",
                   help="rewrite the table and plots from the existing results.json without running anything")
    p.add_argument("--worker-case")
    p.add_argument("--worker-method")
    p.add_argument("--worker-n", type=int)
    args = p.parse_args(argv)
    if args.worker_case:
        _worker(args)
        return 0
    if args.render_only:
        print(f"wrote {write_results(json.loads((pathlib.Path(args.out) / 'results.json').read_text()), args.out)}")
        return 0
    sizes = [32] if args.quick else [int(s) for s in args.sizes.split(",") if s.strip()]
    from cases import ALL_CASES, CASE_NAMES
    case_names = list(CASE_NAMES) if args.cases is None else [c.strip() for c in args.cases.split(",") if c.strip()]
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [c for c in case_names if c not in ALL_CASES] + [m for m in methods if m not in METHOD_ORDER]
    if bad:
        raise ValueError(f"unknown case/method {bad}; cases: {ALL_CASES}, methods: {METHOD_ORDER}.")
    if any(n < 16 for n in sizes):
        raise ValueError(f"sizes {sizes}: use 16 or more nodes per axis.")
    results = []
    outdir = pathlib.Path(args.out)
    if args.merge and (outdir / "results.json").exists():
        redo = {(c, m, n) for c in case_names for m in methods for n in sizes}
        results = [r for r in json.loads((outdir / "results.json").read_text())
                   if (r["case"], r["method"], r["n"]) not in redo]
    for n in sizes:
        for c in case_names:
            for m in methods:
                r = run_one(c, m, n, args.frames, args.timeout)
                results.append(r)
                msg = r.get("error") or (f"drift {100 * r['volume_drift']:.2f}%  spurious {r['spurious_components']}"
                                         f"  end {r['keyframe_end_error_h']:.2f}h  {r['total_seconds']:.2f}s"
                                         f"  {r['peak_rss_mb']:.0f}MB")
                if "part_volume_error" in r:
                    msg += f"  part {100 * r['part_volume_error']:.2f}% at s {r['part_volume_error_at_s']:.3g}"
                print(f"{c:13s} {n:4d} {m:9s} {msg}", flush=True)
    md = write_results(results, outdir)
    sl = cost_slopes(results)
    if sl:
        print(f"project cost growth: time ~ active^{sl['time_slope']:.2f}, memory ~ active^{sl['memory_slope']:.2f}")
    print(f"wrote {md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
