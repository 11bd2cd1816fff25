"""The options of the map solve, as one frozen object (`MapOptions`).

`solve_map` takes them as keywords (`MapOptions.from_keywords`) or as one object; the
bake's `bake.options.BakeOptions` holds one and hands it to the solve. The defaults are measured
choices: benchmarks/README.md ("Map solver") has the table behind each.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from . import terms

if TYPE_CHECKING:
    from ..base.grid import Grid

__all__ = ["MapOptions", "default_weights", "weight_options"]


def weight_options() -> dict[str, str]:
    """{option name: term name} of every term registered in `terms.TERMS`, read now, so
    that a term appended there is taken (``"volume_weight": "volume"``, ...)."""
    return {t.weight_option: t.name for t in terms.TERMS}


def default_weights() -> dict[str, float]:
    """{term name: default weight} of every term registered in `terms.TERMS`, read now:
    the one place the weights' defaults are read from (the options, the Blender panel)."""
    return {t.name: float(t.default) for t in terms.TERMS}


@dataclass(frozen=True)
class MapOptions:
    """Settings of `solve_map` (thesis ch. 2; docs/method.md, sections 2-4).

    Attributes
    ----------
    weights : dict
        Weight of each term of eq. 2.6 by its name in `terms.TERMS` ("volume" 30,
        "rigidity" 1, "levelset" 10, and any registered term's default). As keywords:
        ``volume_weight=...`` and so on.
    max_iterations : int
        Gauss-Newton iterations per level of the hierarchy at most (20).
    tolerance : float
        A level stops when an accepted step lowers the energy by less than this
        fraction (1 %).
    margin_cells : float
        Width in cells of the map's margin: the cells outside A's material solved with
        weight ``margin_weight`` (3 cells, weight 0.1).
    margin_weight : float
    feature_radius : float or None
        Radius (world units) of each feature point's affine patch; None: 8 % of the
        grid's largest extent, never less than one cell diagonal; 0: a plain hard
        constraint on the feature's cell (`constraints`).
    patch_rigidity : float
        Factor on the rigidity weight inside feature patches (10).
    coarse_nodes : int
        Nodes per side of the coarsest level (24); a huge value: no hierarchy.
    cg_tolerance, cg_max_iterations : float, int
        The projected CG of each Gauss-Newton step (3e-2 relative, 300).
    coarse_space_from, coarse_space_size : int
        Unknowns from which a level's CG adds the coarse correction (120,000), and its
        coarse unknowns at most (9000) (`coarse.CoarseSpace`).
    damping : float
        Levenberg-Marquardt shift, times the mean diagonal (1e-6).
    chunk_elements : int
        Elements assembled at once (512: memory against speed).
    extension_passes : int
        Smoothing passes of the correction beyond the solved region (8).
    initial : ndarray or None
        A map (grid.shape + (d,)) to start from instead of the RBF map.
    reuse_hessian : bool
        After a full accepted step, the next reuses the Gauss-Newton matrix.
    min_det : float
        No step takes det F of the material below this (0.2), or below its current
        minimum where the start is lower.
    tear : bool
        Where the map spreads a component of A over several components of B (one
        ball into two), cut it into one piece per component, each solved as a body of
        its own (`tear`). Off by default: the pieces keep det F near 1, but the crack
        they leave shows as a groove at a merge's neck (benchmarks/README.md, "Maps
        that tear"). False: one continuous map, which stretches across the gap.
    separate_parts : bool
        Components of A that go to different components of B are bodies of their own:
        the cells between them leave the solve, however close they are (`parts`).
        False: one map over both, whose gap drags each by the other.
    """

    weights: dict = field(default_factory=default_weights)
    max_iterations: int = 20
    tolerance: float = 1e-2
    margin_cells: float = 3.0
    margin_weight: float = 0.1
    feature_radius: float | None = None
    patch_rigidity: float = 10.0
    coarse_nodes: int = 24
    cg_tolerance: float = 3e-2
    cg_max_iterations: int = 300
    coarse_space_from: int = 120_000
    coarse_space_size: int = 9000
    damping: float = 1e-6
    chunk_elements: int = 512
    extension_passes: int = 8
    initial: np.ndarray | None = None
    reuse_hessian: bool = True
    min_det: float = 0.2
    tear: bool = False
    separate_parts: bool = True

    @classmethod
    def from_keywords(cls, **keywords: Any) -> MapOptions:
        """The options `solve_map`'s keywords ask for: ``<term>_weight`` keywords set
        ``weights``, the others the fields of the same name. ValueError names an unknown
        keyword and lists the known ones."""
        by_option, names = weight_options(), cls.names()
        weights, values = default_weights(), {}
        for key, value in keywords.items():
            if key in by_option:
                weights[by_option[key]] = value
            elif key in names:
                values[key] = value
            else:
                raise ValueError(f"unknown option {key!r} for solve_map; known options: "
                                 f"{sorted(names)}.")
        return cls(weights=weights, **values)

    @classmethod
    def names(cls) -> frozenset:
        """The keyword names `from_keywords` takes: the fields but ``weights``, and the
        ``<term>_weight`` of every registered term."""
        return frozenset(f.name for f in dataclasses.fields(cls) if f.name != "weights") \
            | frozenset(weight_options())

    def __post_init__(self) -> None:
        by_name = {name: option for option, name in weight_options().items()}
        weights = {}
        for name, w in self.weights.items():
            w = float(w)
            if not np.isfinite(w) or w < 0:
                raise ValueError(f"{by_name.get(name, name)} must be a finite number >= 0, got {w}.")
            weights[name] = w
        object.__setattr__(self, "weights", weights)
        if int(self.max_iterations) < 0:
            raise ValueError("max_iterations must be >= 0.")
        patch_rigidity = float(self.patch_rigidity)
        if not np.isfinite(patch_rigidity) or patch_rigidity < 0:
            raise ValueError(f"patch_rigidity must be a finite number >= 0 (a factor on rigidity_weight "
                             f"inside the feature patches; 1 = plain material, default 10), got "
                             f"{patch_rigidity}.")
        object.__setattr__(self, "patch_rigidity", patch_rigidity)
        object.__setattr__(self, "margin_weight", float(self.margin_weight))
        for name, least in (("coarse_space_from", 0), ("coarse_space_size", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < least:
                raise ValueError(f"{name} must be an integer >= {least}, got {v!r} (unknowns: "
                                 "coarse_space_from is the smallest system with a coarse "
                                 "correction, coarse_space_size the most coarse unknowns).")

    def on_grid(self, grid: Grid) -> MapOptions:
        """These options with what depends on the grid settled: ``feature_radius`` from the
        grid's extent when None, ``initial`` checked as a finite map of every node."""
        radius = self.feature_radius
        if radius is None:
            radius = 0.08 * float(np.max(grid.upper - grid.origin))
        initial = self.initial
        if initial is not None:
            initial = np.asarray(initial, dtype=float)
            if initial.shape != grid.shape + (grid.dim,) or not np.all(np.isfinite(initial)):
                raise ValueError(f"initial must be a finite array of shape {grid.shape + (grid.dim,)} "
                                 "(y(x) of every node), e.g. the .mapped of an earlier solve.")
        return dataclasses.replace(self, feature_radius=radius, initial=initial)
