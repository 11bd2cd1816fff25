"""Where the trajectories' Poisson solves start (`motion.trajectory.Trajectories._start`):
their cost in a whole bake, and whether a frame depends on the frames made before it.

Per example scene, a bake with one process and one with a helper (which makes the later
half of each segment's frames from no history). Printed: CG solves and iterations, the
seconds spent in CG, the bake's seconds, and the largest difference of the two bakes'
vertices (template and every frame's own surface), in cells.

Usage: ``python benchmarks/bench_trajectory_start.py [--resolution N] [SCENE ...]`` from
the repository root (default: merge and bend at 32, splash at 40, the preview's grids).
"""

import argparse
import time

import numpy as np

from keyframe_implicit import examples
from keyframe_implicit.core import animate
from keyframe_implicit.core.motion import trajectory

DEFAULT = {"merge": 32, "bend": 32, "splash": 40}


class CountingCG:
    """`block_pcg` wrapped to count its iterations and seconds."""

    def __init__(self):
        self.iterations, self.seconds = [], 0.0
        self.solve = trajectory.block_pcg

    def __call__(self, *args, **kwargs):
        t0 = time.perf_counter()
        Y, its = self.solve(*args, **kwargs)
        self.seconds += time.perf_counter() - t0
        self.iterations.append(its)
        return Y, its


def measure(name, resolution):
    ex = examples.example(name)
    arguments = dict(keyframes=ex.keyframes, features=ex.features,
                     feature_names=ex.feature_names, resolution=resolution)
    counting = CountingCG()
    trajectory.block_pcg = counting
    try:
        t0 = time.perf_counter()
        one = animate(**arguments, processes=1)
        seconds = time.perf_counter() - t0
    finally:
        trajectory.block_pcg = counting.solve
    two = animate(**arguments, processes=2)
    h = one.grid.spacing
    apart = max([np.abs(one.vertices - two.vertices).max()]
                + [np.abs(a[0] - b[0]).max() for a, b in zip(one.surfaces, two.surfaces)])
    its = np.asarray(counting.iterations)
    print(f"| {name} {resolution} | {its.size} | {its.sum()} ({its.mean():.1f} a solve) | "
          f"{counting.seconds:.2f} | {seconds:.1f} | {apart / h:.1e} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=list(DEFAULT))
    parser.add_argument("--resolution", type=int)
    args = parser.parse_args()
    print("| scene, cells | CG solves | CG iterations | CG seconds | bake seconds "
          "| one process against a helper, h |")
    print("|---|---|---|---|---|---|")
    for name in args.scenes:
        measure(name, args.resolution or DEFAULT[name])


if __name__ == "__main__":
    main()
