"""One frame of the bake on demand: the live preview's maps solved once, then any frame alone.

`Preview.solve` plans with the bake's planner (`pipeline.plan_bake`: the same checks, the
same options, the artist's template) and its own grid rule (`preview_grids`: coarse grids),
then keeps the in-betweens of every segment of the bake's chain (`chain.Chain`);
`Preview.frame` then makes one timeline frame's own surface as the bake's mesh sequence
makes it (the frame's level set, eq. 3.4, its marching cubes, or the keyframe's own mesh
on a keyframe's frame): the same functions on the same inputs, so a bake at the preview's
resolutions has the same mesh on that frame (docs/method.md, sections 10 and 11).

Kept between solves, by content (`cache.WorkCache`): the keyframes' distance grids and the
pairs' maps, each under a key of exactly its inputs, so a solve computes only what an edit
changed. The grids sit on a lattice in world space (`gridfit.lattice_grid`): a feature point
moved within a cell leaves them as they were, so the distance grids are kept and only that
pair's maps are solved again; an Interpolation changed solves no map. A map is never started
from another: the solver starts from its own initial map (the RBF of the feature points,
eq. 2.14-2.20), so a kept map is the one a fresh solve gives, which must stay the bake's.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.parallel import one_blas_thread
from ..base.progress import Reporter
from ..surface.extract import extract_surface
from .cache import WorkCache
from .chain import frame_mesh
from .gridfit import one_grid_unless_smaller
from .options import BakeOptions
from .pipeline import distance_fields, plan_bake

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from numpy.typing import ArrayLike

    from ..base.grid import Grid
    from .checks import FeatureNames
    from .keyframe import Keyframe
    from .pipeline import GridFit

__all__ = ["Preview", "preview_grids", "PREVIEW_RESOLUTION", "PREVIEW_MOTION_RESOLUTION"]

#: Cells along the longest side of the preview's surface grid (no finer than the bake's; finer
#: where two feature points would share a cell).
PREVIEW_RESOLUTION = 32
#: Cells of its motion grid, where the feature points allow it (else the bake's own rule).
PREVIEW_MOTION_RESOLUTION = 16


class Preview:
    """The in-betweens of one setup, kept for frames asked one at a time.

    Attributes
    ----------
    figures : dict
        Of the last solve: ``resolution``, ``motion_resolution``, ``grid_shape``,
        ``motion_grid_shape`` (None: the maps are on the surface grid), ``seconds``,
        ``distance_grids_kept`` (how many keyframes' distance grids were not recomputed) and
        ``maps_kept`` (how many pairs' maps were not solved again).
    cache : `cache.WorkCache`
        What is kept between solves (given, or one in memory only).
    """

    def __init__(self, cache: WorkCache | None = None) -> None:
        self.cache = WorkCache() if cache is None else cache
        self._solved = None
        self.figures = {}

    def solve(self, keyframes: Sequence[Keyframe], features: Sequence[tuple[ArrayLike, ArrayLike]],
              options: BakeOptions | None = None, *, feature_names: FeatureNames | None = None,
              progress: Callable[[float, str], object] | None = None,
              cancel: Callable[[], bool] | None = None) -> dict[str, Any]:
        """Solve every segment's maps and in-betweens at the preview's resolutions.

        The parameters are `pipeline.bake`'s: the bake's own ``options`` (None: the
        defaults), planned by the bake's planner with the preview's grid rule
        (`preview_grids`), so the preview's surface grid is no finer than the bake's.

        Raises ValueError on input the user must fix (the bake's own refusals), `Cancelled`
        when ``cancel()`` returns True. On either the previous solve is gone.
        """
        t0 = time.perf_counter()
        self._solved = None
        rep = Reporter(progress, cancel)
        plan = plan_bake(keyframes, features, options or BakeOptions(),
                         feature_names=feature_names, grid_rule=preview_grids)
        rep(0.05, "Distance grids")
        before = self.cache.hits().get("distance", 0)
        phis = distance_fields(plan, rep.sub(0.05, 0.2), cancel, cache=self.cache)
        kept = self.cache.hits().get("distance", 0) - before
        chain = plan.chain(phis, cancel, self.cache)
        nseg = len(phis) - 1
        with one_blas_thread():  # as in the bake: BLAS's threads round differently
            inbetweens = [chain.inbetweens.make(k, None, None,
                                                rep.sub(0.2 + 0.8 * k / nseg,
                                                        0.2 + 0.8 * (k + 1) / nseg))
                          for k in range(nseg)]
        self._solved = (plan.grid, chain.frames, inbetweens, chain.keyframe_meshes)
        self.figures = dict(resolution=plan.resolution,
                            motion_resolution=plan.stats["motion_resolution"],
                            grid_shape=plan.stats["grid_shape"],
                            motion_grid_shape=plan.stats.get("motion_grid_shape"),
                            seconds=time.perf_counter() - t0, distance_grids_kept=kept,
                            maps_kept=chain.inbetweens.reused)
        return self.figures

    @property
    def solved(self) -> bool:
        """Whether the maps of a setup are solved (`frame` can answer)."""
        return self._solved is not None

    def frame(self, f: int) -> tuple[np.ndarray, np.ndarray]:
        """Timeline frame ``f``'s own surface, as the bake's mesh sequence has it.

        Returns (vertices (V, 3) float32, triangles (F, 3) int32), world units. Frames
        before the first keyframe or after the last show that keyframe's. RuntimeError
        before a solve.
        """
        if self._solved is None:
            raise RuntimeError("nothing solved yet: call solve first.")
        grid, frames, inbetweens, meshes = self._solved
        f = int(min(max(f, frames[0]), frames[-1]))
        # an inner keyframe's frame ends the segment before it, as in the bake
        k = max(0, int(np.searchsorted(frames, f, side="left")) - 1)
        s = (f - frames[k]) / float(frames[k + 1] - frames[k])
        own_mesh = meshes is not None and (s == 1.0 or (s == 0.0 and k == 0))
        with one_blas_thread():
            surface = None if own_mesh else extract_surface(inbetweens[k].levelset(s), grid)
        v, tris = frame_mesh(surface, meshes, k, s)
        return np.asarray(v, dtype=np.float32), np.asarray(tris, dtype=np.int32)


def preview_grids(fit: GridFit, options: BakeOptions) -> tuple[int, tuple[Grid, int, Grid | None]]:
    """The preview's grid rule (`pipeline.plan_bake`'s ``grid_rule``): `PREVIEW_RESOLUTION`
    cells and a motion grid of `PREVIEW_MOTION_RESOLUTION` (one grid where that motion grid
    would not have fewer nodes, as the bake's automatic rule has it:
    `gridfit.one_grid_unless_smaller`), or the bake's automatic one where two feature points
    would share a motion cell; raised by a quarter at a time, up to the bake's
    ``options.resolution``, where two would share a surface cell (the bake's own refusal
    when even that does not hold them apart). No memory limit: the preview's grids are no
    finer than the bake's."""
    top = int(options.resolution)
    res = min(top, PREVIEW_RESOLUTION)
    while True:
        for motion in (min(res, PREVIEW_MOTION_RESOLUTION), None):
            try:
                grid, m, mgrid = fit(res, motion, None)
            except ValueError:
                if res >= top and motion is None:
                    raise
                continue
            if one_grid_unless_smaller(grid, res, m) == res:
                return res, (grid, res, None)
            return res, (grid, m, mgrid)
        res = min(top, int(np.ceil(1.25 * res)))
