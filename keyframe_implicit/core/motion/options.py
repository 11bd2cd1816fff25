"""The options of the in-betweens, as one frozen object (`MotionOptions`).

`Inbetween.from_map` takes them as keywords; the bake builds one `MotionOptions` and
hands it down with the maps. The defaults are measured choices: benchmarks/README.md
("Trajectories and transport", "In-betweens") has the table behind each.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

__all__ = ["MotionOptions", "TRANSPORTS", "RESAMPLES"]

#: Both keyframes carried and blended, or the thesis's eq. 3.4 on A's nodes only.
TRANSPORTS = ("two-sided", "one-sided")
#: How carried values return to the grid: the inverse lookup of the moved cells, or the
#: thesis's inverse-distance weights (eq. 3.2-3.3; one-sided only).
RESAMPLES = ("lookup", "idw")


@dataclass(frozen=True)
class MotionOptions:
    """Settings of the trajectories, the transports and their blend (thesis ch. 3;
    docs/method.md, sections 5, 6 and 8).

    Attributes
    ----------
    transport : {"two-sided", "one-sided"}
        Both keyframes' fields carried and blended (default), or eq. 3.4 on A's nodes.
    keep_volume : bool
        Two-sided only: each in-between shifted by the iso-value that gives it the
        linearly interpolated volume of the keyframes (`isovolume`).
    volume_per_component : bool
        With ``keep_volume``: a frame of several parts shifts each part by its own
        iso-value, for the volume of the material arriving in it (`components`; default), or
        (False) the whole frame by one iso-value for the total.
    trajectory_method : {"global", "local"}
        The Poisson interpolation of the cells' rotations (default), or the thesis's
        per-node formula (`trajectory.Trajectories`).
    trajectory_margin_cells : float
        The trajectories' margin in cells around each keyframe's material (4): the region
        each transport carries, its field truncated at its value on the border. Wider
        than the map's margin (`map.options.MapOptions.margin_cells`, 3).
    trajectory_margin_weight : float
        Weight of the margin's cells in the trajectory solve (0.1).
    resample : {"lookup", "idw"}
        How carried values return to the grid (`RESAMPLES`); "idw" only one-sided.
    idw_radius : float
        Search radius in cells of ``resample="idw"`` (1.5).
    newton_steps : int
        Newton iterations of the inverse lookup (6).
    interpolation : {"cubic", "linear"}
        How the keyframes' fields are read at off-grid points.
    surface_tension : float
        Two-sided only: how parts join where they meet (`tension.fill_creases`). 0, as
        clay pressed together: the blend's crease. 1 (default), as a liquid: the concave
        folds where the frame moves are filled over about two cells, so the neck rounds
        off within a few frames; larger, rounder. A split's neck thins the same way.
    band_cells : float
        Two-sided only: how deep inside the material, in cells, each frame's transports
        read their fields (`band.Band`); deeper, only the inside is known (3). A frame
        whose surface comes near the band's floor is made again on the whole region; inf
        reads the whole region always.
    """

    transport: str = "two-sided"
    keep_volume: bool = True
    volume_per_component: bool = True
    trajectory_method: str = "global"
    trajectory_margin_cells: float = 4.0
    trajectory_margin_weight: float = 0.1
    resample: str = "lookup"
    idw_radius: float = 1.5
    newton_steps: int = 6
    interpolation: str = "cubic"
    surface_tension: float = 1.0
    band_cells: float = 3.0

    def __post_init__(self) -> None:
        if self.resample not in RESAMPLES:
            raise ValueError(f'resample must be "lookup" or "idw", got {self.resample!r}.')
        if self.transport not in TRANSPORTS:
            raise ValueError(f"transport must be one of {TRANSPORTS}, got {self.transport!r}.")
        if not self.surface_tension >= 0:
            raise ValueError(f"surface_tension must be 0 or more, got {self.surface_tension!r}.")
        if not self.band_cells >= 1:
            raise ValueError(f"band_cells must be 1 or more (inf: the whole region), got "
                             f"{self.band_cells!r}.")
        if self.resample == "idw" and self.transport != "one-sided":
            raise ValueError('resample="idw" is the thesis\'s one-sided form: '
                             'use it with transport="one-sided".')

    @property
    def two_sided(self) -> bool:
        """Whether both keyframes are carried: the pair then needs both maps."""
        return self.transport == "two-sided"

    @classmethod
    def names(cls) -> frozenset[str]:
        """The keyword names these options take."""
        return frozenset(f.name for f in dataclasses.fields(cls))

    def trajectory_keywords(self) -> dict[str, Any]:
        """`trajectory.Trajectories`' keywords from these options."""
        return dict(method=self.trajectory_method, margin_cells=self.trajectory_margin_cells,
                    margin_weight=self.trajectory_margin_weight)

    def lookup_keywords(self) -> dict[str, Any]:
        """`transport.Transport`'s keywords from these options."""
        return dict(interpolation=self.interpolation, newton_steps=self.newton_steps)
