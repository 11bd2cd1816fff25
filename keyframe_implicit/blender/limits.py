"""Limits before Bake: what the bake would need in memory, known as the Resolution changes.

`need` estimates it from what the scene shows at once: the keyframe objects' bounding
boxes and volumes (`scene_io.cached_reading`, the readings the panel's checks keep) and
the feature Empties' places, through the core's `pipeline.memory_need` (no mesh work).
The estimate is kept per input (`_need`), so the panel's redraws and the Bake button's
poll only read the scene. `line` says it in the panel, under Resolution; over the limit
Bake is disabled with the same words (`ops.KFI_OT_bake.poll`), before any work.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

from mathutils import Vector

from ..core.bake.memory import megabytes
from ..core.bake.pipeline import MemoryNeed, memory_need
from . import features, scene_io

if TYPE_CHECKING:
    import bpy

    from .props import KFI_Settings

__all__ = ["need", "line", "motion_auto_changed"]

#: Decimals of the world coordinates and volumes the estimate is kept by: moves below
#: them do not change its figures.
_DECIMALS = 4


def _corners(obj: bpy.types.Object) -> tuple[tuple[float, ...], ...]:
    """The world-space corners of ``obj``'s (evaluated) bounding box, rounded."""
    m = obj.matrix_world
    return tuple(tuple(round(c, _DECIMALS) for c in m @ Vector(corner))
                 for corner in obj.bound_box)


@functools.lru_cache(maxsize=64)
def _need(boxes: tuple, volumes: tuple, extra: tuple, resolution: int,
          motion_resolution: int | None) -> MemoryNeed:
    """`pipeline.memory_need` of rounded inputs, kept per inputs."""
    return memory_need(boxes, volumes, resolution, motion_resolution,
                       extra_points=extra if extra else None)


def need(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None = None,
         resolution: int = 0, auto_motion: bool = False) -> MemoryNeed | None:
    """What a bake of ``scene`` at ``resolution`` (0: the scene's) would need in memory,
    with the scene's Motion Resolution or, with ``auto_motion``, the automatic one; None
    until two keyframes have mesh objects that enclose a volume (the checks say what is
    missing). ``depsgraph`` evaluates the keyframes with modifiers (default: the scene's
    first view layer's)."""
    settings = scene.keyframe_implicit
    depsgraph = depsgraph or scene.view_layers[0].depsgraph
    objs = [kf.object for kf in settings.keyframes
            if kf.object is not None and kf.object.type == "MESH"]
    if len(objs) < 2:
        return None
    volumes = tuple(round(scene_io.cached_reading(o, depsgraph).volume, _DECIMALS)
                    for o in objs)
    if not any(volumes):
        return None
    extra = tuple(tuple(round(c, _DECIMALS) for c in o.matrix_world.translation)
                  for o in features.feature_objects(scene))
    return _need(tuple(_corners(o) for o in objs), volumes, extra,
                 int(resolution or settings.resolution),
                 None if auto_motion else settings.motion())


def motion_auto_changed(settings: KFI_Settings, _context: bpy.types.Context) -> None:
    """Motion Resolution's Auto unticked (`props.ON_CHANGE`): the field starts from the
    value Auto chooses for these keyframes (Resolution until two keyframes are set)."""
    found = None if settings.motion_auto else need(settings.id_data, auto_motion=True)
    if found is not None:
        settings.motion_resolution = found.motion_resolution


def line(found: MemoryNeed, resolution: int) -> tuple[str, str]:
    """(text, icon) the panel shows under Resolution: the memory a bake at ``resolution``
    needs of what a bake may use here, or, over that, what it needs against it and the
    resolution that fits."""
    if found.limit is None:
        return f"About {megabytes(found.peak)} of memory", "MEMORY"
    if not found.over:  # one line beside the memory icon: Bake stays in view
        return f"About {megabytes(found.peak)} of {megabytes(found.limit)}", "MEMORY"
    advice = (f"lower it to {found.fits} or less" if found.fits else
              "even the lowest does not fit: free memory or simplify the keyframes")
    return (f"Resolution {resolution} needs about {megabytes(found.peak)} of memory, more "
            f"than the {megabytes(found.limit)} a bake may use here: {advice}."), "ERROR"
