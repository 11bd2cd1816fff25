"""A re-bake that reuses the work kept by content (`core.bake.cache.WorkCache`), against a cold bake.

Each bake runs `core.bake.pipeline.bake`, as the worker process of Blender's Bake does, with a
`WorkCache` of its own on one directory (each bake's worker is a new process: it finds the
earlier bakes' work on disk). The keyframes are those of `bench_contact.py` (meshes of the
case's fields, 24 frames apart; the splash's 8), the worker's two processes:

1. cold: an empty directory;
2. one Empty moved: the first feature point of the first pair moved by 0.3 cells along x
   (within its cell: the grids stay, `gridfit.lattice_grid`);
3. Interpolation changed: every keyframe "ease" (from the moved setup).

Prints seconds, the fractions of the cold bake, and the maps and distance grids reused.

    python benchmarks/bench_rebake.py                    # merge at 48
    python benchmarks/bench_rebake.py --cases merge splash --resolution 48
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.dirname(HERE), HERE]


def _timed(keyframes, features, options, directory):
    """(seconds, animation, cache) of one bake with a new `WorkCache` on ``directory``."""
    from keyframe_implicit.core.bake.cache import WorkCache
    from keyframe_implicit.core.bake.pipeline import bake

    cache = WorkCache(directory)
    t0 = time.perf_counter()
    anim = bake(keyframes, features, options, cache=cache)
    return time.perf_counter() - t0, anim, cache


def _reused(cache):
    return {kind: f"{c['hits']}/{c['hits'] + c['misses']}" for kind, c in cache.counts.items()}


def run(name: str, resolution: int, processes: int) -> None:
    """Print the three bakes of case ``name``."""
    from bench_contact import MESH_NODES, keyframes
    from contact_cases import make_contact_case
    from keyframe_implicit.core.bake.options import BakeOptions

    case = make_contact_case(name, MESH_NODES)
    kfs, feats = keyframes(case), [(np.array(a), np.array(b)) for a, b in case.features]
    options = BakeOptions(resolution=resolution, processes=processes)
    with tempfile.TemporaryDirectory() as directory:
        cold, anim, cache = _timed(kfs, feats, options, directory)
        print(f"{name} {resolution}: cold bake {cold:.1f} s, grid {anim.grid.shape}, "
              f"reused {_reused(cache)}", flush=True)
        feats[0][0][0] += (0.3 * anim.grid.spacing, 0.0, 0.0)
        moved, anim2, cache = _timed(kfs, feats, options, directory)
        same = anim2.grid == anim.grid
        print(f"  one Empty moved: {moved:.1f} s = {moved / cold:.0%} of cold (target <= 40 %), "
              f"same grid {same}, reused {_reused(cache)}", flush=True)
        eased = BakeOptions(resolution=resolution, processes=processes, key_interpolation="ease")
        interp, _, cache = _timed(kfs, feats, eased, directory)
        print(f"  Interpolation changed: {interp:.1f} s = {interp / cold:.0%} of cold "
              f"(target <= 30 %), reused {_reused(cache)}", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--cases", nargs="+", default=["merge"])
    p.add_argument("--resolution", type=int, default=48)
    p.add_argument("--processes", type=int, default=2, help="2: the worker's, with a helper")
    args = p.parse_args()
    for name in args.cases:
        run(name, args.resolution, args.processes)


if __name__ == "__main__":
    main()
