"""Hostile scenes: a user's objects are never lost, each keyframe is read on its own frame.

Each test here reproduces one defect of a hostile-input sweep (re-baking deleted a keyframe
object; keyframes animated by their own object were read on the current frame; negative frames
were ignored; messages used the wrong article) and asserts what an artist expects instead.
"""

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import bake, output, scene_io

TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]


def _reports(capfd):
    """(kind, message) of what operators reported since the last call (printed without a window)."""
    out = capfd.readouterr().out
    return [tuple(line.split(": ", 1)) for line in out.splitlines() if ": " in line]


def test_rebake_keeps_previous_output_used_as_keyframe(scene, kfi, capfd):
    kfi.build_spheres(TWO)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    first = scene.keyframe_implicit.output_object
    # the artist likes the result and makes it a keyframe of a longer shot
    scene.frame_set(12)
    assert bpy.ops.keyframe_implicit.add_keyframe(object_name=first.name) == {"FINISHED"}
    before = kfi.mesh_hash(first.data), first.data.shape_keys.key_blocks[-1].name
    name_before = first.name

    _reports(capfd)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    reports = _reports(capfd)
    settings = scene.keyframe_implicit
    second = settings.output_object
    kept = settings.keyframes[2].object
    assert kept is not None and kept.name in bpy.data.objects, "the keyframe object was deleted"
    assert kept != second and settings.output_object == second
    assert (kfi.mesh_hash(kept.data), kept.data.shape_keys.key_blocks[-1].name) == before
    assert kept.name != name_before and second.name == name_before
    notes = [m for kind, m in reports if kind == "Warning" and f"'{kept.name}'" in m]
    assert len(notes) == 1 and "keyframe 2" in notes[0], reports
    # and the setup still bakes (the old defect left an empty entry that refused the next bake)
    assert bake.bake_scene(scene, kfi.RES) is not None
    assert settings.keyframes[2].object == kept


def test_rebake_keeps_previous_output_carrying_a_feature_point(scene, kfi):
    kfi.build_spheres(TWO)
    first = bake.bake_scene(scene, kfi.RES)
    empty = next(o for o in scene.objects if o.type == "EMPTY")
    empty.parent = first  # a feature point placed on the result
    notes = []
    bake.bake_scene(scene, kfi.RES, notes=notes)
    assert first.name in bpy.data.objects and empty.parent == first
    assert len(notes) == 1 and empty.name in notes[0]


def test_rebake_unreferenced_output_is_still_replaced(scene, kfi):
    kfi.build_spheres(TWO)
    first = bake.bake_scene(scene, kfi.RES)
    name = first.name
    notes = []
    second = bake.bake_scene(scene, kfi.RES, notes=notes)
    assert notes == [] and second.name == name
    assert [o.name for o in bpy.data.objects if o.get(output.OUTPUT_TAG)] == [name]
