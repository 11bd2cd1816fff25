"""The artist's mesh carried through a bake: detail, exact keyframes, cost, and Suzanne's UVs.

Run with the bpy venv (scripts/env.sh)::

    python benchmarks/bench_artist_mesh.py [--size 64] [--repeat 3] [--renders DIR] [--skip-cost]

Part 1 (core): a keyframe with bumps of amplitude 0.3 h and wavelength 2 h turns 90
degrees rigidly; the share of the bump amplitude kept at the middle frame with the
artist's mesh as the template (`template.DetailTrack`) and with the same mesh pulled
onto every frame's zero set.

Part 2 (core): bake time at ``--size`` cells for a 20,000-vertex keyframe (a sphere
turning with a slight squash), template "keyframe" against "grid" (the marching-cubes
template of before), median of ``--repeat`` runs each.

Part 3 (bpy): Suzanne with its UV map, a checker texture and two materials turning 90
degrees with a slight squash (`suzanne_scene`): mean pixel difference between the render
of the result and of the original object on the first keyframe frame, UV agreement on
the keyframe frames, materials kept, frame A exact, frame B's distance to B's mesh; with
``--renders`` the first, middle and last frames are written there as PNG.
"""

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from keyframe_implicit import shapes  # noqa: E402
from keyframe_implicit.core import Keyframe, animate, animate_chain, mesh_to_sdf  # noqa: E402
from keyframe_implicit.core.bake.gridfit import fit_grid  # noqa: E402
from keyframe_implicit.core.fields.mesh import triangulate  # noqa: E402


def rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def uv_sphere(n_lat, radius=1.0, bump=None):
    """Vertices and triangles of a UV sphere; ``bump(theta, phi)`` is added to the radius."""
    v, polys = shapes.uv_sphere(n_lat, radius, bump)
    return v, triangulate(polys, len(v))


def bump_kept(res):
    """Share of the bump amplitude kept at the middle frame: (artist's mesh, zero set)."""
    h = fit_grid([np.array([[-1.0, -1, -1], [1, 1, 1]])], res, padding_cells=4).spacing
    k = np.pi / h

    def bump(t, p):
        return 0.3 * h * np.sin(k * t) * np.sin(np.round(k * np.sin(t)) * p)
    v, tris = uv_sphere(int(np.ceil(np.pi / (2 * h) * 8)), bump=bump)
    grid = fit_grid([v], res, padding_cells=4)
    turn = rot_z(np.pi / 2)
    phis = [mesh_to_sdf(v, tris, grid), mesh_to_sdf(v @ turn.T, tris, grid)]
    out = []
    for extra in (dict(keyframe_meshes=[(v, tris), (v @ turn.T, tris)]), {}):
        ch = animate_chain(phis, grid, None, [1, 9], maps=[grid.points() @ turn.T],
                           coverage=False, surfaces=False, template=(v, tris), **extra)
        r = np.linalg.norm(ch.vertices[4], axis=1)
        r0 = np.linalg.norm(v, axis=1)
        out.append(np.dot(r - r.mean(), r0 - r0.mean()) / np.dot(r0 - r0.mean(), r0 - r0.mean()))
    return len(v), out


def cost(res, repeat):
    """Median bake seconds of a 20,000-vertex keyframe: {"keyframe": s, "grid": s}."""
    v, tris = uv_sphere(100)  # 19,802 vertices
    squash = np.diag([1.05, 1.05, 0.9])
    vb = v @ rot_z(np.pi / 2).T @ squash.T + [0.4, 0.0, 0.0]
    fa = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1]])
    fb = fa @ rot_z(np.pi / 2).T @ squash.T + [0.4, 0.0, 0.0]
    kfs = [Keyframe(v, tris, 1), Keyframe(vb, tris, 13)]
    times = {"keyframe": [], "grid": []}
    for _ in range(repeat):
        for kind in times:
            t0 = time.perf_counter()
            animate(kfs, [(fa, fb)], resolution=res, template=kind)
            times[kind].append(time.perf_counter() - t0)
    return len(v), {k: statistics.median(t) for k, t in times.items()}, times


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--renders", default=None)
    ap.add_argument("--skip-cost", action="store_true")
    ap.add_argument("--skip-suzanne", action="store_true")
    args = ap.parse_args()
    n, (kept, flat) = bump_kept(16)
    print(f"bumps 0.3 h / 2 h, {n} vertices, 16 cells: kept at mid-frame {100 * kept:.0f} % "
          f"(pulled onto the zero set: {100 * flat:.0f} %)")
    if not args.skip_cost:
        n, med, raw = cost(args.size, args.repeat)
        print(f"bake at {args.size} cells, {n}-vertex keyframe, median of {args.repeat}: "
              f"artist's mesh {med['keyframe']:.1f} s, grid template {med['grid']:.1f} s, "
              f"ratio {med['keyframe'] / med['grid']:.2f}  (runs: {raw})")
    if not args.skip_suzanne:
        import suzanne_check

        suzanne_check.report(args.renders)


if __name__ == "__main__":
    main()
