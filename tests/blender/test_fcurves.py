"""The one F-curve helper: Action.fcurves on 4.2/4.3, slotted actions on 4.4+ (5.0 here)."""

import bpy
import pytest

from keyframe_implicit.blender import fcurves


def _key_object(scene):
    mesh = bpy.data.meshes.new("M")
    mesh.vertices.add(1)
    obj = bpy.data.objects.new("O", mesh)
    scene.collection.objects.link(obj)
    obj.shape_key_add(name="Basis")
    obj.shape_key_add(name="K1")
    obj.shape_key_add(name="K2")
    return obj


def test_api_flavour_matches_running_blender():
    slotted = fcurves.uses_slotted_actions()
    assert slotted == (bpy.app.version >= (4, 4, 0))
    if bpy.app.version >= (5, 0, 0):
        assert "fcurves" not in bpy.types.Action.bl_rna.properties  # why the helper exists


def test_fcurves_on_shape_keys_share_one_action_and_slot(scene):
    obj = _key_object(scene)
    key = obj.data.shape_keys
    n_actions = len(bpy.data.actions)
    fc1 = fcurves.ensure_fcurve(key, 'key_blocks["K1"].value', action_name="Shapes")
    fc2 = fcurves.ensure_fcurve(key, 'key_blocks["K2"].value')
    assert fcurves.ensure_fcurve(key, 'key_blocks["K1"].value') == fc1  # found, not duplicated
    assert len(bpy.data.actions) == n_actions + 1
    assert key.animation_data.action.name == "Shapes"
    if fcurves.uses_slotted_actions():
        slot = key.animation_data.action_slot
        assert slot is not None and slot.target_id_type == "KEY"
        assert len(key.animation_data.action.slots) == 1
    assert {fc.data_path for fc in fcurves.fcurves_for(key)} == {
        'key_blocks["K1"].value', 'key_blocks["K2"].value'}

    fcurves.set_keyframes(fc1, [1, 2, 3], [0.0, 1.0, 0.0], "LINEAR")
    fcurves.set_keyframes(fc2, [2, 3], [0.0, 1.0], "CONSTANT")
    assert [tuple(k.co) for k in fc1.keyframe_points] == [(1, 0), (2, 1), (3, 0)]
    assert {k.interpolation for k in fc1.keyframe_points} == {"LINEAR"}
    assert fc1.evaluate(1.5) == pytest.approx(0.5)
    assert fc2.evaluate(2.5) == pytest.approx(0.0)  # constant holds until the next key
    scene.frame_set(2, subframe=0.5)
    assert key.key_blocks["K1"].value == pytest.approx(0.5)
    scene.frame_set(3)
    assert key.key_blocks["K2"].value == pytest.approx(1.0)
    # replacing keys clears the old ones
    fcurves.set_keyframes(fc1, [5], [0.25])
    assert len(fc1.keyframe_points) == 1
    with pytest.raises(ValueError, match="2 frames but 1 values"):
        fcurves.set_keyframes(fc1, [1, 2], [0.0])


def test_fcurves_on_an_object_transform(scene):
    obj = bpy.data.objects.new("E", None)
    scene.collection.objects.link(obj)
    assert fcurves.fcurves_for(obj) == []
    fc = fcurves.ensure_fcurve(obj, "location", 2)
    fcurves.set_keyframes(fc, [1, 11], [0.0, 10.0])
    scene.frame_set(6)
    assert obj.location.z == pytest.approx(5.0)
    assert [(c.data_path, c.array_index) for c in fcurves.fcurves_for(obj)] == [("location", 2)]
