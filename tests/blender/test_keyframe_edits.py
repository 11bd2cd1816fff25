"""Edits keep the setup: a feature Empty moved off its keyframe's surface is pointed out and
snapped back."""

import os

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import scene_io, validate
from test_panel import Layout

SPLASH = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(
    __file__)))), "assets", "splash.blend")


@pytest.fixture
def splash(scene):
    """The splash example (keyframes splash_A..D on frames 1, 9, 15, 25; 8 pairs a segment)."""
    bpy.ops.wm.open_mainfile(filepath=SPLASH, load_ui=False)
    if not hasattr(bpy.types.Scene, "keyframe_implicit"):
        import keyframe_implicit

        keyframe_implicit.register()
    scene = bpy.context.scene
    assert not validate.problems(scene)
    return scene


def _where(obj):
    return np.array(obj.matrix_world.translation)


def _cell(scene):
    inputs = scene_io.read(scene, meshes=False)
    objects = [kf.object for kf in scene.keyframe_implicit.keyframes]
    return scene_io.surface_cell(inputs.listed_keyframes, objects, [], inputs.resolution,
                                 bpy.context.evaluated_depsgraph_get())


def _outside(obj, points):
    dg = bpy.context.evaluated_depsgraph_get()
    return scene_io.cached_surface(obj, dg).nearest(np.asarray(points))[1]


def test_an_empty_off_its_surface_is_named_and_snapped_back(splash, kfi):
    mesh = kfi.mesh_hash(bpy.data.objects["splash_B"].data)
    h = _cell(splash)
    top = bpy.data.objects["KFI 1.5 drop_top A"]  # on splash_B, the droplet touching the pool
    top.matrix_world.translation.z += 3 * h
    bpy.context.view_layer.update()
    [line] = validate.problems(splash)
    assert line.severity == validate.WARNING and line.fix == "keyframe_implicit.snap_features"
    assert "'KFI 1.5 drop_top A'" in line.message and "Snap to Surface" in line.message
    assert validate.OFF_SURFACE_CELLS < _outside(bpy.data.objects["splash_B"], [_where(top)])[0] / h
    for resolution in (8, 128):  # a warning at any resolution: whether it bakes does not change
        splash.keyframe_implicit.resolution = resolution
        assert not validate.errors(validate.problems(splash))
    splash.keyframe_implicit.resolution = 40
    log = []
    from keyframe_implicit.blender import panel

    panel.KFI_PT_main.draw(type("PanelSelf", (), {"layout": Layout(log)})(), bpy.context)
    assert ("operator", "keyframe_implicit.snap_features") in log
    assert bpy.ops.keyframe_implicit.snap_features() == {"FINISHED"}
    bpy.context.view_layer.update()
    assert _outside(bpy.data.objects["splash_B"], [_where(top)])[0] < 1e-6
    assert top.parent.name == "splash_B" and not validate.problems(splash)
    assert mesh == kfi.mesh_hash(bpy.data.objects["splash_B"].data)
    bpy.ops.ed.undo_push(message="snapped")
    assert bpy.ops.keyframe_implicit.snap_features() == {"CANCELLED"}  # nothing left


def test_many_empties_off_their_surfaces_are_one_counted_line(splash):
    h = _cell(splash)
    for name in ("KFI 0.4 drop_centre A", "KFI 0.5 drop_top A", "KFI 2.0 pool_east B"):
        bpy.data.objects[name].matrix_world.translation.z += 8 * h
    bpy.context.view_layer.update()
    [line] = validate.problems(splash)
    assert line.message.startswith("3 feature Empties lie more than one grid cell outside their "
                                   "keyframes ("), line.message
    assert "and 1 more" in line.message
    assert bpy.ops.keyframe_implicit.snap_features(empty="KFI 2.0 pool_east B") == {"FINISHED"}
    bpy.context.view_layer.update()
    assert validate.problems(splash)[0].message.startswith("2 feature Empties")
