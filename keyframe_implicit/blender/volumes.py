"""Optional output: the in-between level sets as an OpenVDB sequence and a Volume object.

For Houdini and volume workflows. One .vdb file per frame ("<name>_<frame>.vdb",
frame zero padded as Blender's sequence detection expects), each holding one
float level-set grid named ``level_set`` (negative inside, world transform of
the bake grid, inactive background = the far-field value). The Volume object
reads the files as a sequence starting on the first baked frame.

OpenVDB's Python module ships with Blender; the PyPI bpy wheel (4.4 and later)
exposes it after ``bpy.utils.expose_bundled_modules()``. Where it does not
exist (e.g. bpy 4.2) `openvdb_module` says so and nothing is written.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import bpy
import numpy as np

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence
    from types import ModuleType


    from numpy.typing import ArrayLike

    from ..core.bake.animation import Animation
    from ..core.base.grid import Grid
    from .props import KFI_Settings

GRID_NAME = "level_set"


def openvdb_module() -> tuple[ModuleType, str] | tuple[None, str]:
    """(module, "") or (None, reason) for the OpenVDB Python module Blender ships."""
    expose = getattr(bpy.utils, "expose_bundled_modules", None)
    if expose is not None:
        expose()
    try:
        import openvdb
    except ImportError:
        return None, (f"Blender {bpy.app.version_string} ships no OpenVDB Python module "
                      "(it comes with Blender 4.4 and later)")
    return openvdb, ""


def frame_path(directory: str, name: str, frame: int) -> str:
    """The .vdb file of one frame: ``<name>_0001.vdb`` in ``directory``."""
    return os.path.join(directory, f"{name}_{int(frame):04d}.vdb")


def write_levelset(vdb: ModuleType, path: str, levelset: ArrayLike, grid: Grid,
                   background: float) -> None:
    """One level set (grid.shape float array) as a float grid in a .vdb file."""
    out = vdb.FloatGrid(float(background))
    out.copyFromArray(np.ascontiguousarray(levelset, dtype=np.float32), ijk=(0, 0, 0),
                      tolerance=0.0)
    h = float(grid.spacing)
    o = [float(x) for x in grid.origin]
    out.transform = vdb.createLinearTransform(
        [[h, 0, 0, 0], [0, h, 0, 0], [0, 0, h, 0], [o[0], o[1], o[2], 1]])
    out.gridClass = vdb.GridClass.LEVEL_SET
    out.name = GRID_NAME
    vdb.write(path, grids=[out])


def write_sequence(directory: str, name: str, frames: Iterable[int],
                   levelsets: Sequence[np.ndarray], grid: Grid) -> list[str]:
    """Write every frame's level set; returns the paths (raises RuntimeError without openvdb)."""
    vdb, reason = openvdb_module()
    if vdb is None:
        raise RuntimeError(f"{reason}: the volume export cannot run.")
    os.makedirs(directory, exist_ok=True)
    background = max(float(np.max(ls)) for ls in levelsets)
    paths = []
    for f, ls in zip(frames, levelsets):
        paths.append(frame_path(directory, name, f))
        write_levelset(vdb, paths[-1], ls, grid, background)
    return paths


def add_volume_object(output_obj: bpy.types.Object, paths: Sequence[str],
                      first_frame: int) -> bpy.types.Object:
    """A Volume object that plays the .vdb sequence from ``first_frame``, in the output's
    collection and parented to it, so that removing the output removes it too."""
    from .output import VOLUME_TAG

    name = f"{output_obj.name} Volume"
    vol = bpy.data.volumes.new(name)
    vol.filepath = paths[0]
    vol.is_sequence = len(paths) > 1
    vol.frame_start = int(first_frame)
    vol.frame_duration = len(paths)
    vol.frame_offset = int(first_frame) - 1  # file number = scene frame
    obj = bpy.data.objects.new(name, vol)
    obj[VOLUME_TAG] = True
    obj.parent = output_obj
    for coll in output_obj.users_collection:
        coll.objects.link(obj)
    return obj


def directory(settings: KFI_Settings) -> str:
    """The absolute folder the settings name for the .vdb files."""
    return bpy.path.abspath(settings.volume_directory or "//kfi_volumes/")


def problem(settings: KFI_Settings) -> str:
    """Why the volume export asked for in ``settings`` cannot run ("" when it can): no
    OpenVDB module, or a folder relative to a .blend that was never saved."""
    if not settings.volume_export:
        return ""
    vdb, reason = openvdb_module()
    if vdb is None:
        return f"{reason}: turn OpenVDB Volume off."
    if settings.volume_directory.startswith("//") and not bpy.data.filepath:
        return (f"The OpenVDB folder '{settings.volume_directory}' is relative to the .blend, "
                "which is not saved yet: save the file or pick an absolute folder.")
    return ""


def write_result(settings: KFI_Settings, animation: Animation) -> list[str]:

    """Write a bake's level sets where ``settings`` say; returns the paths. The files are
    written before anything enters the scene, so a full disk leaves the scene unchanged."""
    levelsets = getattr(animation, "levelsets", None) or []
    if not levelsets:
        return []
    name = bpy.path.clean_name(settings.output_name or "KFI Animation")
    return write_sequence(directory(settings), name, animation.frames, levelsets, animation.grid)
