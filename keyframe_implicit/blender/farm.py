"""The farm job's two Blender stages and the panel's Export Farm Job.

``prepare`` reads a scene exactly as the Bake button does (`bake.collect`, the worker's
arguments: `scene_io.BakeInput.core_arguments`) into a job directory; ``assemble`` writes
the job's result into the scene exactly as a local bake does (`bake.apply_result`). The
stages between them need no Blender (`farm.stages`). Assemble reads the scene again and
refuses a job prepared from another scene, or from this one before it changed.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..farm import stages, store
from ..farm.job_template import write_job_template
from . import bake

if TYPE_CHECKING:  # read by type checkers only
    import bpy

__all__ = ["prepare_scene", "assemble_scene", "job_dir_of", "export_job"]


def _inputs_of(inputs):
    """What ``prepare`` keeps of a `scene_io.BakeInput` (its fingerprint is the job's)."""
    return {"arguments": inputs.core_arguments(), "output_mode": inputs.output_mode}


def prepare_scene(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None, job_dir: str,
                  scene_path: str, resolution: int = 0, segments: int | None = None,
                  progress: Callable[[float, str], None] | None = None,
                  cache_dir: str | None = None) -> dict[str, Any]:
    """Write ``scene``'s bake into ``job_dir`` (`farm.stages.prepare`, the distance grids
    kept in ``cache_dir`` taken from it); the scene is only read.

    ``segments``: the number of segments the job was written for (its job template's task
    ranges); ValueError when the scene has another.
    """
    inputs = bake.collect(scene, depsgraph, resolution)
    n = len(inputs.keyframes) - 1
    if segments is not None and n != segments:
        raise ValueError(f"The scene '{scene.name}' has {n} segments but the job was written "
                         f"for {segments}: write the job again ('farm template', or Export "
                         f"Farm Job in the panel).")
    kept = _inputs_of(inputs)
    source = {"scene": os.path.abspath(scene_path), "scene_name": scene.name}
    return stages.prepare(kept["arguments"], kept["output_mode"], job_dir, source, progress,
                          cache_dir)


def assemble_scene(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None, job_dir: str,
                   progress: Callable[[float, str], None] | None = None) -> bpy.types.Object:
    """Write the job's result into ``scene`` as a local bake would; returns the output object.

    Raises `store.JobError` when the job was prepared from another scene or the scene has
    changed since, or when frames are missing.
    """
    manifest = store.read_manifest(job_dir)
    inputs = bake.collect(scene, depsgraph, manifest["resolution"])
    if store.fingerprint(_inputs_of(inputs)) != manifest["fingerprint"]:
        raise store.JobError(
            f"{job_dir!r} was prepared from '{manifest.get('scene_name')}' in "
            f"{manifest.get('scene')!r}, not from this scene as it is now ('{scene.name}'): "
            "assemble into the scene the job was prepared from, or prepare the job again.")
    result = stages.assemble(job_dir, progress)
    return bake.apply_result(scene, inputs, result)


def job_dir_of(blend_path: str) -> str:
    """The job directory Export Farm Job writes beside a saved .blend: NAME_farm."""
    folder, name = os.path.split(os.path.abspath(blend_path))
    return os.path.join(folder, os.path.splitext(name)[0] + "_farm")


def export_job(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None, blend_path: str,
               blender_path: str = "", job_dir: str | None = None, resolution: int = 0,
               cache: str = "") -> str:
    """Check ``scene``'s bake (`bake.collect`) and write its job template into ``job_dir``
    (default: `job_dir_of` ``blend_path``), Prepare and Assemble run by ``blender_path``
    ("": a Python with the bpy module), Prepare and Maps taking what the bakes kept in
    ``cache`` (the panel's: this session's, `work_cache.directory`); returns the job
    directory. ValueError when the bake could not start."""
    inputs = bake.collect(scene, depsgraph, resolution)
    job_dir = job_dir or job_dir_of(blend_path)
    write_job_template(job_dir, blend_path, len(inputs.keyframes) - 1, inputs.resolution,
                       blender=blender_path, cache=cache)
    return job_dir
