"""Feature Empties snapped onto their keyframe's surface.

- `snap`: Empties outside their keyframe's material moved onto its nearest surface point.

The keyframe objects are never changed: only the feature Empties are moved.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import bpy
import numpy as np
from mathutils import Vector

from . import features, scene_io

if TYPE_CHECKING:
    from collections.abc import Sequence


def snap(scene: bpy.types.Scene, names: Sequence[str],
         depsgraph: bpy.types.Depsgraph) -> list[str]:
    """Move the feature Empties ``names`` that lie outside their keyframe's material onto the
    nearest point of its surface; returns the names of those moved.

    An Empty of a pair of an existing segment is moved; others (lone, or of a keyframe
    without a closed mesh) are left where they are.
    """
    settings = scene.keyframe_implicit
    objects = [kf.object for kf in settings.keyframes]
    wanted = set(names)
    moved = []
    for i, rows in scene_io.empties_on(features.pairs(scene).values(), len(objects)).items():
        rows = [e for _, _, e in rows if e.name in wanted]
        obj = objects[i]
        if not rows or obj is None or obj.type != "MESH":
            continue
        if scene_io.cached_reading(obj, depsgraph).triangles == 0:
            continue
        closest, outside = scene_io.cached_surface(obj, depsgraph).nearest(np.array([tuple(e.matrix_world.translation)
                                                     for e in rows]))
        for empty, point, far in zip(rows, closest, outside):
            if far > 0:
                world = empty.matrix_world.copy()
                world.translation = Vector(point)
                empty.matrix_world = world
                moved.append(empty.name)
    return moved


def off_surface(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph,
                cells: float) -> list[str]:
    """Names of the feature Empties more than ``cells`` cells of the bake's grid outside
    their keyframe's material (as the checks read them: `scene_io.ListedPair.off_surface`)."""
    inputs = scene_io.read(scene, depsgraph, meshes=False)
    return [pair.a if side == "A" else pair.b for pair in inputs.listed_pairs
            for side, far in pair.off_surface if far > cells]
