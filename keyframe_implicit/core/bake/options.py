"""The options of a whole bake, as one frozen object (`BakeOptions`).

A bake's options are built once where the bake is asked for: from `pipeline.animate`'s
keyword arguments (`BakeOptions.from_keywords`), from the panel's settings on the Blender
side (`blender.scene_io.BakeInput.core_arguments`), or read back from a farm job's
directory. Each stage then reads its own part: the planner the grids' settings
(`pipeline.plan_bake`), the chain the key interpolation and the processes
(`chain.Chain`), the map solve `map`, the trajectories and transports `motion`, each
frame's outputs `surface`. Every default is written once, in these fields.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..map.options import MapOptions, weight_options
from ..motion.options import MotionOptions
from ..surface.options import SurfaceOptions

__all__ = ["BakeOptions", "refuse_unread"]

#: The fields holding one stage's options each, and the class of each, in the order a
#: keyword is looked up.
_STAGES = {"surface": SurfaceOptions, "motion": MotionOptions, "map": MapOptions}
#: `pipeline.animate`'s keywords whose field has another name: the keyword stays as the
#: public API has it, the field says what it holds.
_FIELDS = {"template": "tracked_mesh"}


@dataclass(frozen=True)
class BakeOptions:
    """Settings of one bake (docs/method.md, sections 11 and 12 for the two grids and the
    key interpolation).

    Attributes
    ----------
    resolution : int
        Grid cells along the longest side of the keyframes' bounding box (48).
    motion_resolution : int or None
        Cells along the same side of the motion grid, on which the maps and the
        trajectories are solved; from 8 to ``resolution``, which reproduces a bake on one
        grid. None (default): chosen from a cost budget (`gridfit.auto_motion_resolution`).
    padding_cells : int
        Empty cells around the keyframes' bounding box (4).
    max_bytes : int or None
        Memory limit of the bake; None (default): 75 % of the physical memory.
    tracked_mesh : {"keyframe", "grid"}
        Which mesh is the template carried through the frames (`animate`'s ``template``):
        the first keyframe's own mesh with its attributes and sub-cell detail (default;
        `template.DetailTrack`; the grid's when it has loose vertices), or marching cubes
        of its distance grid.
    key_interpolation : str, sequence of str, or None
        Per keyframe, how the motion passes it (`spline.KEY_INTERPOLATIONS`): "smooth"
        (None, the default: continuous velocity), "linear" or "ease".
    surface_tension : float, sequence of float, or None
        How parts join where they meet, for every segment or per segment (one value per
        keyframe pair): `motion.options.MotionOptions.surface_tension`, which holds the
        default (None).
    processes : int
        1 (default): everything in this process; 2 or more: a helper process shares the
        maps and the frames (`chain.animate_chain`).
    map : `map.options.MapOptions`
        The map solve's settings, eq. 2.6's weights among them.
    motion : `motion.options.MotionOptions`
        The trajectories', the transports' and the blend's settings.
    surface : `surface.options.SurfaceOptions`
        What each frame yields besides the template's vertices.
    """

    resolution: int = 48
    motion_resolution: int | None = None
    padding_cells: int = 4
    max_bytes: int | None = None
    tracked_mesh: str = "keyframe"
    key_interpolation: str | tuple | list | None = None
    surface_tension: float | tuple | list | None = None
    processes: int = 1
    map: MapOptions = field(default_factory=MapOptions)
    motion: MotionOptions = field(default_factory=MotionOptions)
    surface: SurfaceOptions = field(default_factory=SurfaceOptions)

    @staticmethod
    def stage_names(*stages: str) -> frozenset[str]:
        """The keywords `from_keywords` gives to the options of ``stages`` ("map",
        "motion", "surface"; none named: all three), and ``weights``."""
        return frozenset({"weights"}).union(
            *(_STAGES[name].names() for name in stages or _STAGES))

    @classmethod
    def from_keywords(cls, *, weights: dict | None = None, **keywords: Any) -> BakeOptions:
        """The options `pipeline.animate`'s keywords ask for, each keyword given to the one
        class that names it: this one's own fields (``template`` for ``tracked_mesh``), then
        `SurfaceOptions`', `MotionOptions`' and `MapOptions`' (``volume_weight`` and the
        like included). ``weights`` ({"volume": 30.0, ...}, by term name) sets the map's
        weights over any ``<term>_weight`` keyword.

        ValueError names an unknown keyword or weight and lists the known ones.
        """
        own = ({f.name for f in dataclasses.fields(cls)} - set(_STAGES) - set(_FIELDS.values())
               | set(_FIELDS))
        known = {"": own, **{name: stage.names() for name, stage in _STAGES.items()}}
        parts = {name: {} for name in known}
        for key, value in keywords.items():
            owner = next((name for name, names in known.items() if key in names), None)
            if owner is None:
                raise ValueError(f"unknown option {key!r}; known options: "
                                 f"{sorted(set().union(*known.values()) | {'weights'})}.")
            parts[owner][key] = value
        parts["map"].update(_weight_keywords(weights))
        own_fields = {_FIELDS.get(key, key): value for key, value in parts[""].items()}
        return cls(**own_fields, map=MapOptions.from_keywords(**parts["map"]),
                   motion=MotionOptions(**parts["motion"]),
                   surface=SurfaceOptions(**parts["surface"]))


    def segment_motion(self, segments: int) -> tuple[MotionOptions, ...]:
        """The motion options of each of ``segments`` keyframe pairs: ``motion`` with each
        segment's ``surface_tension``. ValueError when the list's length or a value is
        wrong."""
        tension = self.surface_tension
        if tension is None:
            return (self.motion,) * segments
        values = [tension] * segments if np.isscalar(tension) else list(tension)
        if len(values) != segments:
            raise ValueError(f"surface_tension must hold one value per segment ({segments}), "
                             f"got {len(values)}.")
        return tuple(dataclasses.replace(self.motion, surface_tension=float(v)) for v in values)


def refuse_unread(keywords: Iterable[str], read: Iterable[str], caller: str) -> None:
    """ValueError naming the keywords among ``keywords`` that ``caller`` does not read
    (``read``): options a part of the bake takes but ignores would be silently lost."""
    unread = sorted(set(keywords) - set(read))
    if unread:
        raise ValueError(f"{caller} does not take {unread}; it takes {sorted(read)}.")


def _weight_keywords(weights):
    """The weights of eq. 2.6's terms by name ({"volume": 30.0, ...}) as the map's keywords
    ({"volume_weight": 30.0, ...}); ValueError naming an unknown one."""
    names = {term: option for option, term in weight_options().items()}
    unknown = sorted(set(weights or {}) - set(names))
    if unknown:
        raise ValueError(f"Unknown weight {unknown[0]!r}; use {sorted(names)}.")
    return {names[key]: float(value) for key, value in (weights or {}).items()}
