"""Contact as a viewer sees it: the measures of `contact_metrics.py` on whole bakes.

Each case of `contact_cases.py` is baked by `core.animate` as an artist's scene would be:
its keyframes are meshes (marching cubes of the case's fields on the 129^3 benchmark box,
the same input at every resolution), 24 frames apart (the splash's three segments 8 frames
each), one process. Every measure reads the frames the bake ships (`shipped_frames`),
keyframe frames included.

    python benchmarks/bench_contact.py                         # resolution 48, automatic motion
    python benchmarks/bench_contact.py --resolution 64 --motion full --cases drop merge

Columns (lengths in the bake's cell h):

- pre: before contact (`contact_frame`: fewer pieces than keyframe A, or two within 1 h),
  the largest movement of each part's surface where the other is about to arrive, against
  its keyframe carried by its own motion (`pre_contact_movement`), the parts in keyframe
  A's order (the pool, the left ball, the lower plate first); "-" for a part whose feature
  points do not move rigidly (the drop's ball);
- follow: the worst frame's mean distance of a part's vertices from its own rigid motion,
  before contact (all frames of the scissors);
- still: `stillness` where both keyframes agree, every segment;
- event: the frame (from 0) of the case's topology change: contact (merges), the last
  frame in one piece (splits), the last frame before the hole opens;
- fold e+1 / e+3 / e+8: `neck_fold` (99th percentile / max, degrees) that many frames
  after contact; at a split or a hole, e-1 / e-3 / e-8: before the pieces part;
- <=45: the first frame after contact whose max fold is 45 degrees or less (offset);
- extra/tiny: most pieces beyond the keyframes' count on one frame / pieces under 10 h^3;
- bubbles: most closed inner surfaces on one frame, and the largest, h^3;
- changes: frames on which the pieces, bubbles or genus change;
- part vol: before contact, each piece's volume against its part's in keyframe A.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from cases import Case
    from keyframe_implicit.core import Animation, Keyframe

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.dirname(HERE), HERE]

MESH_NODES = 129
FRAMES = {"splash": [1, 9, 17, 25]}
FOLD_AFTER = (1, 3, 8)
FOLD_LIMIT = 45.0
TINY = 10.0  # h^3


def keyframes(case: Case) -> list[Keyframe]:
    """The case's keyframes as meshes on their timeline frames."""
    from keyframe_implicit.core import Keyframe
    from keyframe_implicit.core.surface.extract import extract_surface

    frames = FRAMES.get(case.name, [1, 25])
    return [Keyframe(*extract_surface(f, case.grid), fr) for f, fr in zip(case.fields, frames)]


def _features_of_parts(labels, fine, points):
    """The part (0-based) each feature point belongs to: the nearest inside node's."""
    from scipy import ndimage

    _, near = ndimage.distance_transform_edt(labels == 0, return_indices=True)
    idx = np.clip(np.rint(fine.to_index(points)).astype(int), 0, np.asarray(fine.shape) - 1)
    return labels[tuple(near)][tuple(idx.T)] - 1


def _parts(case, h):
    """Keyframe A's parts: own fields, centroids, own motions (None: deformed), where each
    part's centroid is at time s (along its motion, or with its feature points' mean),
    and the reach of its footprint (the other parts' widths across the line between
    centroids, plus 2 h)."""
    import contact_metrics as cm
    from scipy import ndimage

    fine = case.grid
    fa, fb = case.features[0]
    fields, centroids = cm.part_fields(case.fields[0], fine)
    labels, _ = ndimage.label(case.fields[0] < 0)
    owner = _features_of_parts(labels, fine, fa)
    points = fine.points()
    paths, carried, insides = [], [], []
    for p in range(len(fields)):
        mine = owner == p
        motion, miss = cm.rigid_path(fa[mine], fb[mine]) if mine.sum() >= 2 else (None, np.inf)
        paths.append(motion if miss < 0.5 * h else None)
        shift = (fb[mine] - fa[mine]).mean(axis=0) if mine.any() else np.zeros(3)
        carried.append(_carry(centroids[p], paths[-1], shift))
        insides.append(points[labels == p + 1])
    reaches = []
    for p in range(len(fields)):
        others = [k for k in range(len(fields)) if k != p]
        reach = 0.0
        for k in others:
            u = centroids[k] - centroids[p]
            u /= np.linalg.norm(u)
            d = insides[k] - centroids[k]
            reach = max(reach, np.linalg.norm(d - np.outer(d @ u, u), axis=1).max())
        reaches.append(reach + 2 * h)
    return fields, centroids, paths, carried, reaches


def _carry(centroid, path, shift):
    """s -> the centroid at time s: along ``path`` (x -> R x + t), else moved by s ``shift``."""
    if path is None:
        return lambda s: centroid + s * shift

    def at(s):
        R, t = path(s)
        return R @ centroid + t

    return at


def _event(shipped, case, h, pieces):
    """The frame index of the case's topology change (`contact_cases.EVENTS`), or None."""
    import contact_metrics as cm
    from contact_cases import EVENTS

    kind = EVENTS[case.name]
    first = len(pieces[0].outer)
    if kind == "merge":
        return cm.contact_frame(shipped, first, h, pieces=pieces)
    if kind == "split":
        more = [i for i, p in enumerate(pieces) if len(p.outer) > first]
        return more[0] - 1 if more else None
    if kind == "hole":
        opened = [i for i, p in enumerate(pieces) if p.genus[p.outer].sum() > pieces[0].genus.sum()]
        return opened[0] - 1 if opened else None
    return None


def measure(case: Case, anim: Animation, keyframe_meshes: list[tuple]) -> dict:
    """The row of one bake (see the module's columns) of ``case`` from its keyframes'
    meshes (vertices, faces); ``anim`` keeps its level sets."""
    import contact_metrics as cm
    from contact_cases import EVENTS
    from keyframe_implicit.core.surface.extract import extract_surface

    h = anim.grid.spacing
    shipped = cm.shipped_frames(anim)
    pieces = [cm.mesh_pieces(v, f) for v, f in shipped]
    key = [int(np.flatnonzero(anim.frames == kf)[0]) for kf in FRAMES.get(case.name, [1, 25])]
    row = {"motion": anim.stats["motion_resolution"], "output": anim.stats.get("output"), "h": h}
    event = _event(shipped, case, h, pieces)
    kind = EVENTS[case.name]
    row["event"] = event
    # before contact: the first segment's frames up to the event (all of it without one)
    end = key[1] + 1 if kind is None or event is None else event
    if kind in ("merge", None):
        fields, centroids, paths, carried, reaches = _parts(case, h)
        times = (anim.frames[:end] - anim.frames[0]) / (anim.frames[key[1]] - anim.frames[0])
        worst, follow = cm.pre_contact_movement(shipped[:end], times, case.grid, fields,
                                                centroids, paths, carried, h, reaches,
                                                pieces=pieces[:end])
        row["pre"] = [float(w) for w in worst]
        row["follow"] = _nanmax(follow)
        row["part_vol"] = _part_volume_error(pieces[:end], shipped[:end], times, carried,
                                             extract_surface(anim.levelsets[0], anim.grid))
    still = []
    for k in range(len(key) - 1):
        vert_a = keyframe_meshes[k][0]
        pts = cm.agreement_points(vert_a, case.fields[k], case.fields[k + 1], case.grid,
                                  case.features[k], h,
                                  reading=extract_surface(anim.levelsets[key[k]], anim.grid))
        still.append(cm.stillness(shipped[key[k]:key[k + 1] + 1], pts, h))
    row["still"] = _nanmax(still)
    row["still_each"] = still  # per segment, with each segment's largest iso-value shift
    row["iso_value_h"] = [max(map(abs, seg.get("iso_value_h", {0: 0.0}).values()))
                       for seg in anim.stats["segments"]]
    if event is not None:
        sign = 1 if kind == "merge" else -1
        row["folds"] = [cm.neck_fold(*shipped[event + sign * d], h)
                        if 0 <= event + sign * d < len(shipped) else None for d in FOLD_AFTER]
        if kind == "merge":
            row["settle"] = next((d for d in range(1, len(shipped) - event)
                                  if cm.neck_fold(*shipped[event + d], h)[1] <= FOLD_LIMIT), None)
    expected = max(case.expected_components)
    row["extra"] = max(max(len(p.outer) - expected, 0) for p in pieces)
    row["tiny"] = max(int(np.count_nonzero(p.volumes[p.outer] < TINY * h ** 3)) for p in pieces)
    row["bubbles"] = max(len(p.bubbles) for p in pieces)
    row["bubble_h3"] = max((-p.volumes[p.bubbles].min() / h ** 3 if len(p.bubbles) else 0.0)
                           for p in pieces)
    state = [(len(p.outer), len(p.bubbles), int(p.genus.sum())) for p in pieces]
    row["changes"] = sum(a != b for a, b in zip(state[:-1], state[1:]))
    return row


def _nanmax(values):
    values = np.asarray(values, float)
    return float(np.nanmax(values)) if np.any(np.isfinite(values)) else float("nan")


def _part_volume_error(pieces, shipped, times, carried, reading):
    """Before contact, the in-betweens' largest |V(piece) - V(part in A)| / V(part in A), each piece the
    part `contact_metrics.piece_owners` gives it (``carried`` as `_parts` gives them), the
    parts' volumes in keyframe A as the bake's grid reads it (``reading``: its surface)."""
    import contact_metrics as cm

    v_a, f_a = reading
    pieces_a = cm.mesh_pieces(v_a, f_a)
    owner_a = cm.piece_owners(v_a, pieces_a, [c(0.0) for c in carried])
    reference = np.full(len(carried), np.nan)  # NaN: the grid holds two parts as one
    if len(pieces_a.volumes) == len(carried):
        reference[owner_a[np.unique(pieces_a.labels, return_index=True)[1]]] = pieces_a.volumes
    worst = np.nan
    for p, (v, _), s in zip(pieces[1:], shipped[1:], times[1:]):  # frame 0: A's own mesh
        owner = cm.piece_owners(v, p, [c(s) for c in carried])
        first = np.unique(p.labels, return_index=True)[1]  # a vertex of every piece
        for k in p.outer:
            ref = reference[owner[first[k]]]
            worst = np.nanmax([worst, abs(p.volumes[k] - ref) / ref])
    return float(worst)


def run_case(name: str, resolution: int, motion: str, options: dict | None = None) -> dict:
    """Bake case ``name`` and measure it: one row. ``options``: stage options for
    `core.animate` (e.g. ``{"trust_strain": 0.3}``)."""
    from contact_cases import make_contact_case

    return bake_and_measure(make_contact_case(name, MESH_NODES), resolution, motion, options)


def bake_and_measure(case: Case, resolution: int, motion: str,
                     options: dict | None = None) -> dict:
    """`run_case` of a given ``case`` (its fields on the benchmark box): one row, or
    ``error`` where the bake refuses it."""
    from keyframe_implicit.core import animate

    kfs = keyframes(case)
    row = {"case": case.name, "resolution": resolution}
    t0 = time.perf_counter()
    try:
        anim = animate(kfs, case.features, resolution=resolution, processes=1, levelsets=True,
                       motion_resolution=None if motion == "auto" else
                       resolution if motion == "full" else int(motion), **(options or {}))
    except ValueError as exc:
        row["error"] = str(exc)
        return row
    row["seconds"] = time.perf_counter() - t0
    row.update(measure(case, anim, [(kf.vertices, kf.faces) for kf in kfs]))
    return row


def _fmt(v, spec=".2f"):
    return "n/a" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def print_table(rows: list[dict]) -> None:
    """One markdown table of the rows."""
    head = ["case", "res", "motion", "pre h", "follow h", "still h", "event",
            "fold e±1", "fold e±3", "fold e±8", "<=45 at", "extra/tiny", "bubbles (h^3)",
            "changes", "part vol %"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        if "error" in r:
            print(f"| {r['case']} | {r['resolution']} | refused: {r['error']} |")
            continue
        folds = r.get("folds") or [None] * len(FOLD_AFTER)
        pre = "/".join(_fmt(w).replace("n/a", "-") for w in r["pre"]) if "pre" in r else "n/a"
        cells = [r["case"], str(r["resolution"]), str(r["motion"]), pre,
                 _fmt(r.get("follow")), _fmt(r.get("still")), _fmt(r["event"], "d"),
                 *[("n/a" if f is None else f"{f[0]:.0f}/{f[1]:.0f}") for f in folds],
                 _fmt(r.get("settle"), "d"), f"{r['extra']}/{r['tiny']}",
                 f"{r['bubbles']} ({r['bubble_h3']:.0f})", str(r["changes"]),
                 _fmt(None if r.get("part_vol") is None else 100 * r["part_vol"], ".1f")]
        print("| " + " | ".join(cells) + " |", flush=True)


def main() -> None:
    import json

    from contact_cases import CONTACT_CASES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, nargs="+", default=[48])
    ap.add_argument("--motion", default="auto",
                    help='"auto" (the bake\'s Motion Resolution), "full" or a number of cells')
    ap.add_argument("--cases", nargs="+", default=list(CONTACT_CASES), choices=CONTACT_CASES)
    ap.add_argument("--json", help="also write the rows to this file")
    ap.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE",
                    help="stage options for the bakes, e.g. trust_strain=0.3")
    args = ap.parse_args()
    options = {k: json.loads(v) for k, v in (kv.split("=", 1) for kv in args.set)}
    rows = []
    for n in args.resolution:
        for name in args.cases:
            rows.append(run_case(name, n, args.motion, options))
            print(json.dumps(rows[-1], default=float), file=sys.stderr, flush=True)
    print_table(rows)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1, default=float)


if __name__ == "__main__":
    main()
