"""The thesis's 2D examples (figs. 4.2-4.4) with the 2D core, drawn frame by frame.

Usage, from the repository root (needs matplotlib, the ``plot`` extra)::

    python examples/figures_2d.py                 # merge, bend, splash
    python examples/figures_2d.py bend --resolution 80 --out docs/images

For each example (`keyframe_implicit.examples.example_2d`): the keyframe polygons become
signed distance grids (`polygon_to_sdf`), each adjacent pair is solved and its in-betweens
built (`inbetween`: volume map, trajectories, level sets, thesis ch. 2-3), and every frame is
drawn as one panel: the material (level set < 0) filled, its zero contour, the grid nodes of
the material carried along their trajectories (grey dots, as in the thesis's fig. 4.4) and
the feature points (red) moving with the map. Keyframe panels have an orange title. The
figure goes to OUT/2d_<name>.png; a line per stage is printed with its time.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from keyframe_implicit import examples  # noqa: E402
from keyframe_implicit.core import Grid, inbetween, polygon_to_sdf  # noqa: E402


def fit_grid_2d(shapes, resolution, margin=0.35):
    """A 2D grid around every keyframe polygon, `resolution` cells along the longest side."""
    pts = np.vstack([p for polys in shapes for p in polys])
    lo, hi = pts.min(0) - margin, pts.max(0) + margin
    h = float((hi - lo).max()) / resolution
    shape = tuple(int(n) for n in np.ceil((hi - lo) / h).astype(int) + 1)
    return Grid(lo, h, shape)


def frames_of(ex, panels_per_segment):
    """(frame number, segment, s) for every panel, keyframes included once each."""
    out = []
    for i in range(len(ex.frames) - 1):
        fa, fb = ex.frames[i], ex.frames[i + 1]
        n = panels_per_segment if panels_per_segment else fb - fa
        for k in range(n + (i == len(ex.frames) - 2)):
            s = k / n
            out.append((fa + s * (fb - fa), i, s))
    return out


def compute(ex, resolution, panels_per_segment=None, say=print):
    """Solve every segment; returns (grid, panels) with per panel the level set and points."""
    grid = fit_grid_2d(ex.shapes, resolution)
    t = time.perf_counter()
    phis = [polygon_to_sdf(polys, grid, rule="nonzero") for polys in ex.shapes]
    say(f"  signed distance grids {grid.shape}: {time.perf_counter() - t:.2f} s")
    segments = []
    for i, (fa, fb) in enumerate(ex.features):
        t = time.perf_counter()
        segments.append(inbetween(phis[i], phis[i + 1], grid, fa, fb))
        say(f"  segment {i}: map + trajectories {time.perf_counter() - t:.2f} s")
    panels = []
    material = [phi < 0 for phi in phis]
    for frame, i, s in frames_of(ex, panels_per_segment):
        ib = segments[i]
        pos = np.asarray(ib.trajectories.positions(s)).reshape(-1, 2)
        nodes = pos[material[i].reshape(-1)]
        feats = np.asarray(ib.trajectory(ex.features[i][0], s))
        is_key = s in (0.0, 1.0)
        panels.append(dict(frame=frame, s=s, segment=i, field=ib.levelset(s), nodes=nodes,
                           features=feats, key=is_key))
    return grid, panels


def draw(ex, grid, panels, path, columns=None, panel_size=2.2):
    """Draw the panels as a grid of small plots and save them to `path` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(panels)
    columns = columns or min(n, 6 if n > 8 else n)
    rows = -(-n // columns)
    x, y = grid.axes()
    fig, axes = plt.subplots(rows, columns, figsize=(panel_size * columns, panel_size * rows * 0.9),
                             squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    for ax, p in zip(axes.ravel(), panels):
        f = p["field"].T  # field[i, j] has i along x; contour wants rows along y
        ax.contourf(x, y, f, levels=[f.min() - 1.0, 0.0], colors=["#3b7dd8"], alpha=0.55)
        ax.contour(x, y, f, levels=[0.0], colors=["#16325c"], linewidths=1.0)
        ax.plot(p["nodes"][:, 0], p["nodes"][:, 1], ".", color="0.35", ms=1.0)
        ax.plot(p["features"][:, 0], p["features"][:, 1], "o", color="#d62728", ms=3.0)
        ax.set_aspect("equal")
        ax.set_xlim(x[0], x[-1])
        ax.set_ylim(y[0], y[-1])
        ax.set_xticks([])
        ax.set_yticks([])
        label = f"frame {p['frame']:g}" + (" (key)" if p["key"] else "")
        ax.set_title(label, fontsize=8, color="#d9822b" if p["key"] else "black")
    fig.suptitle(f"2D {ex.name}: level sets (blue), moved grid nodes (grey), feature points (red)",
                 fontsize=9)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("names", nargs="*", default=list(examples.NAMES_2D),
                   help=f"examples to draw (default: {' '.join(examples.NAMES_2D)})")
    p.add_argument("--resolution", type=int, default=64, help="grid cells along the longest side")
    p.add_argument("--out", default=os.path.join(ROOT, "docs", "images"), help="output folder")
    args = p.parse_args(argv)
    for name in args.names:
        ex = examples.example_2d(name)
        print(f"[2d] {name}: {len(ex.frames)} keyframes on frames {ex.frames}", flush=True)
        t = time.perf_counter()
        per_segment = 6 if len(ex.frames) == 2 else None
        grid, panels = compute(ex, args.resolution, per_segment,
                               say=lambda m: print(f"[2d] {m}", flush=True))
        path = os.path.join(args.out, f"2d_{name}.png")
        draw(ex, grid, panels, path)
        print(f"[2d] {name}: {len(panels)} panels -> {path} ({time.perf_counter() - t:.1f} s)",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
