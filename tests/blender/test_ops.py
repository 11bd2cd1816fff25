"""Operators: keyframe list, feature pairs, validation messages, registration."""

import bpy
import numpy as np
import pytest

import keyframe_implicit
from keyframe_implicit.blender import features, ops, panel, props, validate

OPS = ("add_keyframe", "remove_keyframe", "move_keyframe", "add_feature_pair", "pair_selected",
       "remove_feature_pair", "select_pair", "snap_features", "bake", "export_farm_job",
       "clear_cache")


def test_operators_are_registered_undoable_and_searchable(scene):
    for name in OPS:
        op = getattr(bpy.ops.keyframe_implicit, name)
        rna = op.get_rna_type()
        assert rna.identifier  # registered
    operators = [c for c in ops.classes if issubclass(c, bpy.types.Operator)]
    assert sorted(c.bl_idname.split(".")[1] for c in operators) == sorted(OPS)
    for cls in operators:
        # every operator that changes the scene is one undo step; the bake has no redo panel
        # (see test_redo_panels); Export Farm Job writes files only, Clear Cache removes them:
        # no undo step
        expected = {ops.KFI_OT_bake: {"UNDO"}, ops.KFI_OT_export_farm_job: set(),
                    ops.KFI_OT_clear_cache: set()}
        assert cls.bl_options == expected.get(cls, {"REGISTER", "UNDO"})
        assert cls.bl_idname.startswith("keyframe_implicit.")
        assert cls.__doc__  # the F3 search / tooltip text


def test_register_unregister_twice(scene):
    keyframe_implicit.unregister()
    assert not hasattr(bpy.types.Scene, "keyframe_implicit")
    assert not hasattr(bpy.types, "KFI_PT_main")
    with pytest.raises((AttributeError, RuntimeError, KeyError)):
        bpy.ops.keyframe_implicit.bake.get_rna_type()
    keyframe_implicit.register()
    keyframe_implicit.register()  # second call is a no-op, not an error
    assert bpy.context.scene.keyframe_implicit.resolution == 48
    keyframe_implicit.unregister()
    keyframe_implicit.register()
    assert bpy.ops.keyframe_implicit.add_keyframe.get_rna_type().identifier


def test_add_keyframe_defaults_and_order(scene, kfi):
    s = scene.keyframe_implicit
    a = kfi.add_sphere("A", (0, 0, 0))
    scene.frame_set(10)
    assert bpy.ops.keyframe_implicit.add_keyframe() == {"FINISHED"}  # active object, current frame
    b = kfi.add_sphere("B", (3, 0, 0))
    assert bpy.ops.keyframe_implicit.add_keyframe(object_name="B", frame=2) == {"FINISHED"}
    assert [(k.object, k.frame) for k in s.keyframes] == [(b, 2), (a, 10)]  # ordered by frame
    assert s.active_keyframe_index == 0
    with pytest.raises(RuntimeError, match="already has a keyframe"):
        bpy.ops.keyframe_implicit.add_keyframe(object_name="A", frame=10)
    bpy.ops.object.empty_add()
    with pytest.raises(RuntimeError, match="not a mesh"):
        bpy.ops.keyframe_implicit.add_keyframe(frame=20)
    assert len(s.keyframes) == 2


def test_move_keyframe_swaps_frames(scene, kfi):
    kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (3, 0, 0), 1, 5), ("C", (6, 0, 0), 1, 9)],
                      pairs=False)
    s = scene.keyframe_implicit
    assert bpy.ops.keyframe_implicit.move_keyframe(index=2, direction="UP") == {"FINISHED"}
    assert [(k.object.name, k.frame) for k in s.keyframes] == [("A", 1), ("C", 5), ("B", 9)]
    assert s.active_keyframe_index == 1
    assert bpy.ops.keyframe_implicit.move_keyframe(index=0, direction="UP") == {"CANCELLED"}
    assert [k.object.name for k in s.keyframes] == ["A", "C", "B"]


def test_add_feature_pair_names_colours_parents(scene, kfi):
    a, b = kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (3, 0, 0), 2, 5)], pairs=False)
    scene.cursor.location = (0.5, 0.25, 0.0)
    assert bpy.ops.keyframe_implicit.add_feature_pair(segment=0, location_b=(3, 0, 2),
                                                      name="top") == {"FINISHED"}
    bpy.context.view_layer.update()
    pair = features.pairs(scene)["0.0"]
    assert pair.complete and pair.label == "top"
    assert (pair.a.name, pair.b.name) == ("KFI 0.0 top A", "KFI 0.0 top B")
    assert (pair.a.parent, pair.b.parent) == (a, b)
    assert pair.a["kfi_side"] == "A" and pair.b["kfi_side"] == "B" and pair.a["kfi_segment"] == 0
    np.testing.assert_allclose(pair.a.matrix_world.translation, (0.5, 0.25, 0.0), atol=1e-6)
    np.testing.assert_allclose(pair.b.matrix_world.translation, (3, 0, 2), atol=1e-6)
    assert tuple(pair.a.color) == tuple(pair.b.color)
    assert pair.a.empty_display_type == "SPHERE"
    assert pair.b.empty_display_size > pair.a.empty_display_size  # relative to the keyframe size
    assert bpy.ops.keyframe_implicit.add_feature_pair(segment=0) == {"FINISHED"}
    second = features.pairs(scene)["0.1"]
    assert tuple(second.a.color) != tuple(pair.a.color)
    # the Empties follow their keyframe object
    b.location.x += 1.0
    bpy.context.view_layer.update()
    np.testing.assert_allclose(pair.b.matrix_world.translation, (4, 0, 2), atol=1e-6)
    with pytest.raises(RuntimeError, match="Segment 1 does not exist"):
        bpy.ops.keyframe_implicit.add_feature_pair(segment=1)


def test_pair_selected_select_and_remove(scene, kfi):
    a, b = kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (3, 0, 0), 1, 5)], pairs=False)
    bpy.ops.object.empty_add(location=(3, 0, 1))
    eb = bpy.context.active_object
    features.parent_keep_world(eb, b)
    bpy.ops.object.empty_add(location=(0, 0, 1))
    ea = bpy.context.active_object
    features.parent_keep_world(ea, a)
    bpy.ops.object.select_all(action="DESELECT")
    ea.select_set(True)
    eb.select_set(True)
    bpy.context.view_layer.objects.active = ea  # active is on the EARLIER keyframe: parents win
    assert bpy.ops.keyframe_implicit.pair_selected() == {"FINISHED"}
    pair = features.pairs(scene)["0.0"]
    assert (pair.a, pair.b) == (ea, eb)
    assert ea.name == "KFI 0.0 A"
    bpy.context.view_layer.update()
    np.testing.assert_allclose(ea.matrix_world.translation, (0, 0, 1), atol=1e-6)

    bpy.ops.object.select_all(action="DESELECT")
    assert bpy.ops.keyframe_implicit.select_pair(pair="0.0") == {"FINISHED"}
    assert set(bpy.context.selected_objects) == {ea, eb}
    assert bpy.context.view_layer.objects.active == eb

    ea.select_set(False)
    with pytest.raises(RuntimeError, match="select exactly two"):
        bpy.ops.keyframe_implicit.pair_selected()

    n = len(bpy.data.objects)
    bpy.ops.keyframe_implicit.add_feature_pair(segment=0)
    # from the menu / F3 (no pair given): the active feature Empty's pair
    bpy.context.view_layer.objects.active = bpy.data.objects["KFI 0.1 B"]
    assert bpy.ops.keyframe_implicit.remove_feature_pair() == {"FINISHED"}
    assert sorted(features.pairs(scene)) == ["0.0"]
    assert bpy.ops.keyframe_implicit.remove_feature_pair(pair="0.0") == {"FINISHED"}
    assert len(bpy.data.objects) == n - 2 and not features.pairs(scene)
    with pytest.raises(RuntimeError, match="No feature pair"):
        bpy.ops.keyframe_implicit.remove_feature_pair(pair="0.0")


def test_remove_keyframe_joins_its_pairs_and_renumbers(scene, kfi):
    specs = [("A", (0, 0, 0), 1, 1), ("B", (3, 0, 0), 1, 5), ("C", (6, 0, 0), 1, 9),
             ("D", (9, 0, 0), 1, 13)]
    kfi.build_spheres(specs)  # 4 pairs per segment, segments 0, 1, 2, meeting on B and C
    assert bpy.ops.keyframe_implicit.remove_keyframe(index=1) == {"FINISHED"}
    s = scene.keyframe_implicit
    assert [k.object.name for k in s.keyframes] == ["A", "C", "D"]
    found = features.pairs(scene)
    # A-B and B-C, meeting on B, became A-C; C-D is now segment 1
    assert sorted(found) == ["0.0", "0.1", "0.2", "0.3", "1.0", "1.1", "1.2", "1.3"]
    assert all((p.a.parent.name, p.b.parent.name) == (("A", "C") if p.segment == 0 else ("C", "D"))
               for p in found.values())
    assert found["1.2"].a.name == "KFI 1.2 A" and found["0.2"].b.name == "KFI 0.2 B"
    assert not bpy.data.objects["B"].children
    assert not validate.problems(scene)
    # a first keyframe takes its pairs with it
    assert bpy.ops.keyframe_implicit.remove_keyframe(index=0) == {"FINISHED"}
    assert sorted(features.pairs(scene)) == ["0.0", "0.1", "0.2", "0.3"]
    msgs = [p.message for p in validate.problems(scene)]
    assert not any("no feature pairs" in m for m in msgs)
    assert bpy.ops.keyframe_implicit.remove_keyframe(index=1) == {"FINISHED"}
    assert not features.pairs(scene)


def test_validation_messages_say_what_to_do(scene, kfi):
    msgs = lambda: [(p.severity, p.message) for p in validate.problems(scene)]  # noqa: E731
    assert any("add at least two" in m for _, m in msgs())
    a, b = kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (3, 0, 0), 1, 5)], pairs=False)
    found = msgs()
    assert not validate.errors(validate.problems(scene))
    assert any(lvl == "WARNING" and "have no feature pairs:" in m and "Add Feature Pair" in m
               for lvl, m in found)
    bpy.ops.keyframe_implicit.add_feature_pair(segment=0)
    assert any("have 1 feature pair:" in m for _, m in msgs())  # counted in words, no "(s)"
    # unpaired Empty
    bpy.data.objects.remove(bpy.data.objects["KFI 0.0 B"])
    assert any(lvl == "ERROR" and "KFI 0.0 A" in m and "no partner" in m and "Pair Selected" in m
               for lvl, m in msgs())
    with pytest.raises(RuntimeError, match="no partner"):
        bpy.ops.keyframe_implicit.bake()
    bpy.ops.keyframe_implicit.remove_feature_pair(pair="0.0")
    # duplicate frame and out-of-order list
    s = scene.keyframe_implicit
    s.keyframes[1].frame = 1
    assert any("both on frame 1" in m for _, m in msgs())
    s.keyframes[1].frame = 0
    assert any("order the list" in m for _, m in msgs())
    s.keyframes[1].frame = 5
    # keyframe without a mesh
    s.keyframes[1].object = None
    assert any(lvl == "ERROR" and "has no object" in m for lvl, m in msgs())
    with pytest.raises(RuntimeError, match="has no object"):
        bpy.ops.keyframe_implicit.bake()


def test_property_group_contract(scene):
    s = scene.keyframe_implicit
    assert isinstance(s, props.KFI_Settings)
    for name in ("keyframes", "active_keyframe_index", "resolution", "volume_weight",
                 "rigidity_weight", "levelset_weight", "output_collection", "output_object"):
        assert name in s.bl_rna.properties, name
    item = s.keyframes.add()
    assert {"object", "frame"} <= set(item.bl_rna.properties.keys())
    # the panel starts from the solver's measured weights, not a guess of its own
    from keyframe_implicit.core.map.options import MapOptions

    assert s.weights() == MapOptions().weights  # what solve_map uses when given none
    assert s.weights() == {"volume": 30.0, "rigidity": 1.0, "levelset": 10.0}
    assert "DEFAULT_CLOSED" in panel.KFI_PT_advanced.bl_options

