"""Motion through keyframes: corners, speed jumps and easing, measured on the baked mesh.

Two chains are baked with `core.animate` (the artist's mesh as the template, as in
Blender), with every keyframe "linear" (each segment on its own: today's timing),
"smooth" (the default) and, for the ball, its top keyframe "ease":

- the ball thrown on an arc: a ball (radius 0.3) at the left, the top and the right
  (frames 1, 13, 25), four feature points a segment that move with it;
- the splash chain of `keyframe_implicit.examples` (frames 1, 9, 15, 25): a droplet falls,
  touches, merges and settles.

Paths, every frame, keyframe frames included: the ball's centre is the material centroid
of the baked mesh (the volume centroid of the closed mesh); the droplet's centre is the
mean of the template vertices on the droplet; a feature point is the template vertex
nearest it on the first frame. Per inner keyframe and path:

- turn: the angle (degrees) between the displacements of the frame before and the frame
  after the keyframe, against the largest such angle at any other frame of its two
  segments;
- speed ratio: the larger of the two displacements over the smaller, across the keyframe,
  against the largest between other consecutive frames of its two segments;
- the arc's own turn a frame: a circle through the ball's three positions, run at a
  uniform speed;
- ease: the speed at the eased keyframe (second-order one-sided differences on either
  side, the larger) as a percentage of the mean speed of its two segments.

Cost: seconds of a whole bake of the ball, "linear" (the code path of a chain without
bends, today's) against "smooth", the smallest of ``--repeat`` alternating runs.

    python benchmarks/bench_smooth.py --resolution 40
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.dirname(HERE), HERE]

#: The ball's three positions: left, top, right (half-width 1, height 0.845).
ARC = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 0.845], [1.0, 0.0, 0.0]])
BALL_RADIUS = 0.3


def ball_arc(frames=(1, 13, 25), positions=ARC):
    """(keyframes, features) of the ball thrown on an arc: an icosphere at each position,
    four feature points a segment (the centre and three points inside) moving with it."""
    from keyframe_implicit.core import Keyframe
    from keyframe_implicit.shapes import icosphere

    v, f = icosphere(3, BALL_RADIUS)
    positions = np.asarray(positions, dtype=float)
    kfs = [Keyframe(v + c, f, int(fr)) for c, fr in zip(positions, frames)]
    offsets = 0.6 * BALL_RADIUS * np.vstack([np.zeros(3), np.eye(3)])
    feats = [(positions[k] + offsets, positions[k + 1] + offsets)
             for k in range(len(positions) - 1)]
    return kfs, feats


def splash():
    """(keyframes, features) of the splash chain of `keyframe_implicit.examples`."""
    from keyframe_implicit.examples import splash as example

    ex = example()
    return ex.keyframes, ex.features


def material_centroid(vertices, faces):
    """Volume centroid (n, 3) of a closed triangle mesh on every frame ((n, V, 3) vertices)."""
    v = np.asarray(vertices, dtype=float)
    a, b, c = (v[:, faces[:, i]] for i in range(3))
    six_vol = np.einsum("nfi,nfi->nf", a, np.cross(b, c))
    return (six_vol[..., None] * (a + b + c)).sum(1) / (4.0 * six_vol.sum(1)[:, None])


def nearest_vertices(vertices, points):
    """Index of the vertex nearest each point ((V, 3), (P, 3) -> (P,))."""
    d = np.linalg.norm(vertices[:, None, :] - np.asarray(points)[None], axis=-1)
    return d.argmin(axis=0)


def turns_and_speeds(path):
    """Per frame, the turn (degrees) between the displacement before and after it
    (frames 1 .. n - 2) and every displacement's length (n - 1)."""
    v = np.diff(np.asarray(path, dtype=float), axis=0)
    speed = np.linalg.norm(v, axis=1)
    cos = np.einsum("ij,ij->i", v[:-1], v[1:]) / np.maximum(speed[:-1] * speed[1:], 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), speed


def across_keyframes(path, frames, key_frames):
    """Per inner keyframe: dict of its ``turn`` and ``speed_ratio`` across it, and the
    largest of each elsewhere in its two segments (``turn_elsewhere``,
    ``speed_ratio_elsewhere``)."""
    frames = np.asarray(frames)
    turn, speed = turns_and_speeds(path)
    ratio = np.maximum(speed[1:], speed[:-1]) / np.maximum(np.minimum(speed[1:], speed[:-1]),
                                                          1e-300)
    out = []
    for k in range(1, len(key_frames) - 1):
        i = int(np.flatnonzero(frames == key_frames[k])[0])  # turn[i - 1] is at frame i
        lo = int(np.flatnonzero(frames == key_frames[k - 1])[0])
        hi = int(np.flatnonzero(frames == key_frames[k + 1])[0])
        others = [j - 1 for j in range(lo + 1, hi) if j != i]
        out.append(dict(turn=float(turn[i - 1]), turn_elsewhere=float(turn[others].max()),
                        speed_ratio=float(ratio[i - 1]),
                        speed_ratio_elsewhere=float(ratio[others].max())))
    return out


def sided_speeds(path, frames, key_frame):
    """The speed (per frame) at a keyframe as the frames before it and after it give it:
    second-order one-sided differences, (|3 p_i - 4 p_i-1 + p_i-2|, |-3 p_i + 4 p_i+1 -
    p_i+2|) / 2. Equal for a path whose velocity is continuous there, up to its change
    of acceleration; a per-frame displacement mixes in half a frame of acceleration."""
    p = np.asarray(path, dtype=float)
    i = int(np.flatnonzero(np.asarray(frames) == key_frame)[0])
    before = (3.0 * p[i] - 4.0 * p[i - 1] + p[i - 2]) / 2.0
    after = (-3.0 * p[i] + 4.0 * p[i + 1] - p[i + 2]) / 2.0
    return float(np.linalg.norm(before)), float(np.linalg.norm(after))


def speed_at(path, frames, key_frame):
    """The speed at a keyframe (the larger of `sided_speeds`) as a fraction of the mean
    speed of the path."""
    mean = np.linalg.norm(np.diff(np.asarray(path, dtype=float), axis=0), axis=1).mean()
    return max(sided_speeds(path, frames, key_frame)) / float(mean)


def arc_turn_per_frame(positions=ARC, frames=(1, 13, 25)):
    """Degrees a frame of the circle through three positions run at a uniform speed."""
    a, b, c = np.asarray(positions, dtype=float)
    ab, cb = a - b, c - b
    inscribed = np.arccos(ab @ cb / np.linalg.norm(ab) / np.linalg.norm(cb))
    return float(np.degrees(2.0 * (np.pi - inscribed)) / (frames[-1] - frames[0]))


def bake(keyframes, features, resolution, key_interpolation):
    """`core.animate` of a chain, and its seconds."""
    from keyframe_implicit.core import animate

    t0 = time.perf_counter()
    anim = animate(keyframes, features, resolution=resolution,
                   key_interpolation=key_interpolation)
    return anim, time.perf_counter() - t0


def paths(anim, keyframes, features, droplet=None):
    """The measured paths of a bake: {name: (n, 3)}: the material centroid ("centre"), or
    with ``droplet`` (a centre and radius on the first keyframe) the mean of the template
    vertices within it ("droplet"), and each feature point of the first segment within
    that region (all when None) by its nearest template vertex."""
    verts = np.asarray(anim.vertices, dtype=float)
    points = np.asarray(features[0][0], dtype=float)
    out = {}
    if droplet is None:
        out["centre"] = material_centroid(verts, np.asarray(anim.faces))
    else:
        centre, radius = droplet
        on = np.linalg.norm(verts[0] - centre, axis=1) <= radius
        out["droplet"] = verts[:, on].mean(axis=1)
        points = points[np.linalg.norm(points - centre, axis=1) <= radius]
    for j, idx in enumerate(nearest_vertices(verts[0], points)):
        out[f"feature {j}"] = verts[:, idx]
    return out


def _row(label, figures):
    cells = [f"{f['turn']:.1f} / {f['turn_elsewhere']:.1f}" for f in figures]
    cells += [f"{f['speed_ratio']:.2f} / {f['speed_ratio_elsewhere']:.2f}" for f in figures]
    return f"| {label} | " + " | ".join(cells) + " |"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=3, help="cost runs of each timing")
    ap.add_argument("--skip-splash", action="store_true")
    args = ap.parse_args()
    n = args.resolution
    kfs, feats = ball_arc()
    keys = [kf.frame for kf in kfs]
    print(f"ball on an arc, {n} cells; the arc through the three positions turns "
          f"{arc_turn_per_frame():.1f} degrees a frame")
    print("| timing, path | turn at the top / elsewhere (deg) | speed ratio at the top / "
          "elsewhere |\n|---|---|---|")
    seconds = {"linear": [], "smooth": []}
    for kind in ("linear", "smooth"):
        anim, sec = bake(kfs, feats, n, kind)
        seconds[kind].append(sec)
        for name, path in paths(anim, kfs, feats).items():
            print(_row(f"{kind}, {name}", across_keyframes(path, anim.frames, keys)))
    anim, _ = bake(kfs, feats, n, ["smooth", "ease", "smooth"])
    centre = paths(anim, kfs, feats)["centre"]
    print(f"ease at the top: centre's speed there {100 * speed_at(centre, anim.frames, 13):.1f} "
          "% of its segments' mean")
    for _ in range(args.repeat - 1):
        for kind in ("linear", "smooth"):
            seconds[kind].append(bake(kfs, feats, n, kind)[1])
    lin, smo = min(seconds["linear"]), min(seconds["smooth"])
    print(f"cost, three keyframes: linear {lin:.2f} s, smooth {smo:.2f} s: {smo / lin:.2f}x "
          f"(smallest of {args.repeat})")
    if args.skip_splash:
        return
    kfs, feats = splash()
    keys = [kf.frame for kf in kfs]
    drop = (np.asarray(feats[0][0][4]), 0.5)  # the droplet: its centre feature, radius 0.35
    print(f"\nsplash, {n} cells, keyframes {keys}: per inner keyframe turn at / elsewhere "
          "(deg), then speed ratio at / elsewhere")
    print("| timing, path | " + " | ".join(f"turn {f}" for f in keys[1:-1]) + " | "
          + " | ".join(f"speed {f}" for f in keys[1:-1]) + " |")
    print("|---" * (1 + 2 * (len(keys) - 2)) + "|")
    for kind in ("linear", "smooth"):
        anim, _ = bake(kfs, feats, n, kind)
        for name, path in paths(anim, kfs, feats, droplet=drop).items():
            print(_row(f"{kind}, {name}", across_keyframes(path, anim.frames, keys)))


if __name__ == "__main__":
    main()
