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
nearest it on the first frame, when it has one of its own (not the droplet's centre,
whose nearest vertex is one of many at its distance). Per inner keyframe and path:

- turn: the angle (degrees) between the displacements of the frame before and the frame
  after the keyframe, against the largest such angle at any other frame of its two
  segments, and the turn there of the curve the keyframes ask for (a cubic Hermite
  curve through the path's own keyframe positions with the bake's tangents: large where
  the keyframes themselves turn the point round);
- speed ratio: the larger of the two displacements over the smaller, across the keyframe,
  against the largest between other consecutive frames of its two segments;
- the arc's own turn a frame: a circle through the ball's three positions, run at a
  uniform speed;
- ease: the speed at the eased keyframe (second-order one-sided differences on either
  side, the larger) as a percentage of the mean speed of its two segments.

Also: the ball with its keyframes at frames 1, 5 and 25 (speeds either side of the middle
one, whether it rises above the top or runs back); the splash's volume drift, extra
pieces and changes of topology (Euler characteristic against linear's) on its frames' own
surfaces; ``--plot PNG`` draws every path and its speed a frame.

Cost: seconds of a whole bake of the ball, "linear" (the code path of a chain without
bends) against "smooth", the smallest of ``--repeat`` alternating runs.

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
    """(keyframes, features, names of the first segment's feature points) of the splash
    chain of `keyframe_implicit.examples`."""
    from keyframe_implicit.examples import splash as example

    ex = example()
    return ex.keyframes, ex.features, ex.feature_names[0]


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


def has_own_vertex(vertices, points, margin=0.01):
    """Whether each point's nearest vertex is its own ((V, 3), (P, 3) -> (P,) bool): the
    next nearest lies at least ``margin`` (a fraction) farther. A point deep inside a round
    part, such as the droplet's centre, has many vertices at almost its distance (ten within
    0.1 %), and which of them is "nearest" is a matter of rounding: its path would be
    that of an arbitrary point of the surface."""
    d = np.sort(np.linalg.norm(vertices[:, None, :] - np.asarray(points)[None], axis=-1),
                axis=0)
    return d[1] > (1.0 + margin) * d[0]


def keyframe_curve(path, frames, key_frames):
    """The curve the keyframes ask of a path: a cubic Hermite curve through the path's own
    positions at the keyframes, with the tangents `spline` gives the paths (each side's
    chord weighted by its own segment's frames; natural first and last keyframes),
    sampled on ``frames``. Where its turn at a keyframe is large, the keyframes
    themselves ask for the turn (a point that rises, then sinks)."""
    frames = np.asarray(frames)
    at = [int(np.flatnonzero(frames == f)[0]) for f in key_frames]
    p = np.asarray(path, dtype=float)[at]
    gaps = np.diff(np.asarray(key_frames, dtype=float))
    chords = np.diff(p, axis=0) / gaps[:, None]
    v = np.empty_like(p)
    v[1:-1] = ((gaps[:-1, None] * chords[:-1] + gaps[1:, None] * chords[1:])
               / (gaps[:-1] + gaps[1:])[:, None])
    if len(p) > 2:  # natural ends: no second derivative there
        v[0], v[-1] = 1.5 * chords[0] - 0.5 * v[1], 1.5 * chords[-1] - 0.5 * v[-2]
    else:
        v[0] = v[-1] = chords[0]
    k = np.clip(np.searchsorted(key_frames, frames, side="right") - 1, 0, len(p) - 2)
    n = gaps[k][:, None]
    s = (frames - np.asarray(key_frames)[k])[:, None] / n
    h00, h10 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s
    h01, h11 = -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
    return h00 * p[k] + h10 * n * v[k] + h01 * p[k + 1] + h11 * n * v[k + 1]


def turns_and_speeds(path):
    """Per frame, the turn (degrees) between the displacement before and after it
    (frames 1 .. n - 2) and every displacement's length (n - 1)."""
    v = np.diff(np.asarray(path, dtype=float), axis=0)
    speed = np.linalg.norm(v, axis=1)
    cos = np.einsum("ij,ij->i", v[:-1], v[1:]) / np.maximum(speed[:-1] * speed[1:], 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), speed


def across_keyframes(path, frames, key_frames):
    """Per inner keyframe: dict of its ``turn`` and ``speed_ratio`` across it, the
    largest of each elsewhere in its two segments (``turn_elsewhere``,
    ``speed_ratio_elsewhere``), and the turn there of the curve its keyframe positions
    ask for (``turn_asked``, `keyframe_curve`)."""
    frames = np.asarray(frames)
    turn, speed = turns_and_speeds(path)
    asked = turns_and_speeds(keyframe_curve(path, frames, key_frames))[0]
    ratio = np.maximum(speed[1:], speed[:-1]) / np.maximum(np.minimum(speed[1:], speed[:-1]),
                                                          1e-300)
    out = []
    for k in range(1, len(key_frames) - 1):
        i = int(np.flatnonzero(frames == key_frames[k])[0])  # turn[i - 1] is at frame i
        lo = int(np.flatnonzero(frames == key_frames[k - 1])[0])
        hi = int(np.flatnonzero(frames == key_frames[k + 1])[0])
        others = [j - 1 for j in range(lo + 1, hi) if j != i]
        out.append(dict(turn=float(turn[i - 1]), turn_elsewhere=float(turn[others].max()),
                        turn_asked=float(asked[i - 1]),
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


def paths(anim, features, droplet=None, names=None):
    """The measured paths of a bake: {name: (n, 3)}: the material centroid ("centre"), or
    with ``droplet`` (a centre and radius on the first keyframe) the mean of the template
    vertices within it ("droplet"), and each feature point of the first segment within
    that region (all when None) by its nearest template vertex, under its name in
    ``names`` (default "feature j"); a point with no vertex of its own (`has_own_vertex`)
    is left out: the droplet's centre is the "droplet" path."""
    verts = np.asarray(anim.vertices, dtype=float)
    points = np.asarray(features[0][0], dtype=float)
    names = np.array(names or [f"feature {j}" for j in range(len(points))])
    out = {}
    if droplet is None:
        out["centre"] = material_centroid(verts, np.asarray(anim.faces))
    else:
        centre, radius = droplet
        on = np.linalg.norm(verts[0] - centre, axis=1) <= radius
        out["droplet"] = verts[:, on].mean(axis=1)
        near = np.linalg.norm(points - centre, axis=1) <= radius
        points, names = points[near], names[near]
    own = has_own_vertex(verts[0], points)
    for name, idx in zip(names[own], nearest_vertices(verts[0], points[own])):
        out[str(name)] = verts[:, idx]
    return out


def plot_trails(trails, path):
    """One picture of the paths: per chain two rows, the paths seen from the front (x, z,
    a dot a frame) and their speed a frame, the linear bake on the left and the smooth
    one on the right; keyframes ringed (paths) or dashed (speeds) in orange."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2 * len(trails), 2, figsize=(11, 4.2 * 2 * len(trails)),
                             squeeze=False)
    for c, (chain, (frames, key_frames, by_kind)) in enumerate(trails.items()):
        keys = [int(np.flatnonzero(frames == f)[0]) for f in key_frames]
        top = max(np.linalg.norm(np.diff(p, axis=0), axis=1).max()
                  for named in by_kind.values() for p in named.values())
        for col, (kind, named) in enumerate(by_kind.items()):
            trail, speed = axes[2 * c, col], axes[2 * c + 1, col]
            for i, (name, p) in enumerate(named.items()):
                colour = "black" if i == 0 else f"C{i - 1}"
                trail.plot(p[:, 0], p[:, 2], ".-", color=colour, ms=5, lw=0.7, label=name)
                trail.plot(p[keys, 0], p[keys, 2], "o", mfc="none", mec="orange", ms=10,
                           mew=1.5)
                step = np.linalg.norm(np.diff(p, axis=0), axis=1)
                speed.plot(frames[:-1] + 0.5, step, ".-", color=colour, ms=5, lw=0.7)
            for f in key_frames:
                speed.axvline(f, color="orange", ls="--", lw=1)
            trail.set_title(f"{chain}, {kind}: paths (front view)")
            trail.set_aspect("equal")
            trail.set_xlabel("x")
            trail.set_ylabel("z")
            speed.set_title(f"{chain}, {kind}: distance moved each frame")
            speed.set_xlabel("frame")
            speed.set_ylim(0, 1.05 * top)
        axes[2 * c, 0].legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=80)


def euler_characteristics(anim):
    """V - E + F of every frame's own surface: 2 a closed piece, less a hole through one."""
    out = []
    for _, f in anim.surfaces:
        f = np.asarray(f)
        edges = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]),
                                  axis=1), axis=0)
        out.append(len(np.unique(f)) - len(edges) + len(f))
    return np.array(out)


def volume_and_pieces(anim, key_frames):
    """The largest volume drift (%) of any frame's own surface from the keyframes' volumes
    interpolated linearly in time, and the most pieces (connected surfaces) of any frame
    beyond the more of its two keyframes'."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from keyframe_implicit.core.surface.extract import mesh_volume

    def pieces(v, f):
        n = len(v)
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
        graph = coo_matrix((np.ones(len(edges)), tuple(edges.T)), shape=(n, n))
        return connected_components(graph, directed=False)[0] - int(n - len(np.unique(f)))

    vols = np.array([abs(mesh_volume(np.asarray(v, float), np.asarray(f))) for v, f in
                     anim.surfaces])
    count = np.array([pieces(np.asarray(v), np.asarray(f)) for v, f in anim.surfaces])
    frames = np.asarray(anim.frames)
    at = [int(np.flatnonzero(frames == f)[0]) for f in key_frames]
    lin = np.interp(frames, key_frames, vols[at])
    seg = np.clip(np.searchsorted(key_frames, frames, side="right") - 1, 0, len(at) - 2)
    most = np.maximum(count[np.asarray(at)[seg]], count[np.asarray(at)[seg + 1]])
    return float(100 * np.abs(vols / lin - 1).max()), int(np.maximum(count - most, 0).max())


def _row(label, figures):
    cells = [f"{f['turn']:.1f} / {f['turn_elsewhere']:.1f} ({f['turn_asked']:.1f})"
             for f in figures]
    cells += [f"{f['speed_ratio']:.2f} / {f['speed_ratio_elsewhere']:.2f}" for f in figures]
    return f"| {label} | " + " | ".join(cells) + " |"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=3, help="cost runs of each timing")
    ap.add_argument("--skip-splash", action="store_true")
    ap.add_argument("--plot", help="also draw the paths into this PNG (matplotlib)")
    args = ap.parse_args()
    n = args.resolution
    kfs, feats = ball_arc()
    keys = [kf.frame for kf in kfs]
    print(f"ball on an arc, {n} cells; the arc through the three positions turns "
          f"{arc_turn_per_frame():.1f} degrees a frame")
    print("| timing, path | turn at the top / elsewhere (keyframes' curve) (deg) | speed ratio "
          "at the top / "
          "elsewhere |\n|---|---|---|")
    seconds = {"linear": [], "smooth": []}
    trails = {}
    for kind in ("linear", "smooth"):
        anim, sec = bake(kfs, feats, n, kind)
        seconds[kind].append(sec)
        named = paths(anim, feats)
        trails.setdefault("ball on an arc", (anim.frames, keys, {}))[2][kind] = named
        for name, path in named.items():
            print(_row(f"{kind}, {name}", across_keyframes(path, anim.frames, keys)))
    anim, _ = bake(kfs, feats, n, ["smooth", "ease", "smooth"])
    centre = paths(anim, feats)["centre"]
    print(f"ease at the top: centre's speed there {100 * speed_at(centre, anim.frames, 13):.1f} "
          "% of its segments' mean")
    for _ in range(args.repeat - 1):
        for kind in ("linear", "smooth"):
            seconds[kind].append(bake(kfs, feats, n, kind)[1])
    uneven = (1, 5, 25)
    anim, _ = bake(*ball_arc(uneven), n, "smooth")
    centre = paths(anim, feats)["centre"]
    before, after = sided_speeds(centre, anim.frames, uneven[1])
    print(f"keyframes at {uneven}: speeds either side of the middle one {before:.3f} / "
          f"{after:.3f} a frame; top {centre[:, 2].max():.4f} (keyframe {ARC[1, 2]}), x "
          f"increasing every frame: {bool(np.all(np.diff(centre[:, 0]) > 0))}")
    lin, smo = min(seconds["linear"]), min(seconds["smooth"])
    print(f"cost, three keyframes: linear {lin:.2f} s, smooth {smo:.2f} s: {smo / lin:.2f}x "
          f"(smallest of {args.repeat})")
    if not args.skip_splash:
        splash_figures(n, trails)
    if args.plot:
        plot_trails(trails, args.plot)


def splash_figures(n, trails):
    """The splash chain's table, its paths added to ``trails``."""
    kfs, feats, names = splash()
    keys = [kf.frame for kf in kfs]
    drop = (np.asarray(feats[0][0][4]), 0.5)  # the droplet: its centre feature, radius 0.35
    print(f"\nsplash, {n} cells, keyframes {keys}: per inner keyframe turn at / elsewhere "
          "(the keyframes' own curve's) (deg), then speed ratio at / elsewhere")
    print("| timing, path | " + " | ".join(f"turn {f}" for f in keys[1:-1]) + " | "
          + " | ".join(f"speed {f}" for f in keys[1:-1]) + " |")
    print("|---" * (1 + 2 * (len(keys) - 2)) + "|")
    euler = {}
    for kind in ("linear", "smooth"):
        anim, _ = bake(kfs, feats, n, kind)
        euler[kind] = euler_characteristics(anim)
        named = paths(anim, feats, droplet=drop, names=names)
        trails.setdefault("splash", (anim.frames, keys, {}))[2][kind] = named
        for name, path in named.items():
            print(_row(f"{kind}, {name}", across_keyframes(path, anim.frames, keys)))
        drift, extra = volume_and_pieces(anim, keys)
        print(f"| {kind}: volume drift of the frames' own surfaces {drift:.2f} %, pieces "
              f"beyond the keyframes' {extra} |")
    differ = anim.frames[euler["smooth"] != euler["linear"]].tolist()
    print(f"frames whose own surface's Euler characteristic differs from linear's: {differ}")


if __name__ == "__main__":
    main()
