"""Edits keep the setup: a keyframe inserted into the splash gets pairs proposed on it, a
keyframe removed joins the pairs through it, a deleted keyframe object can be picked again in
its row, and a feature Empty moved off its keyframe's surface is pointed out and snapped back."""

import os

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import edits, features, scene_io, validate
from test_panel import Layout, list_rows

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


def _by_segment(scene):
    found = features.pairs(scene).values()
    assert all(p.complete for p in found)
    return {seg: sorted((p for p in found if p.segment == seg), key=lambda p: p.pair_id)
            for seg in {p.segment for p in found}}


def _cell(scene):
    inputs = scene_io.read(scene, meshes=False)
    objects = [kf.object for kf in scene.keyframe_implicit.keyframes]
    return scene_io.surface_cell(inputs.listed_keyframes, objects, inputs.resolution,
                                 bpy.context.evaluated_depsgraph_get())


def _outside(obj, points):
    dg = bpy.context.evaluated_depsgraph_get()
    return scene_io.cached_surface(obj, dg).nearest(np.asarray(points))[1]


def _off(obj, points):
    """How far each point lies from ``obj``'s surface, inside or outside."""
    dg = bpy.context.evaluated_depsgraph_get()
    points = np.asarray(points)
    return np.linalg.norm(scene_io.cached_surface(obj, dg).nearest(points)[0] - points, axis=1)


def test_removing_a_keyframe_joins_the_pairs_through_it(splash, kfi):
    meshes = {o.name: kfi.mesh_hash(o.data) for o in splash.objects if o.type == "MESH"}
    before = _by_segment(splash)
    ends = {p.pair_id: (p.a.name, _where(p.a), _where(before[1][i].b))
            for i, p in enumerate(before[0])}
    empties = len([o for o in splash.objects if features.is_feature(o)])
    later = [(_where(p.a), _where(p.b)) for p in before[2]]
    assert bpy.ops.keyframe_implicit.remove_keyframe(index=1) == {"FINISHED"}
    s = splash.keyframe_implicit
    assert [k.object.name for k in s.keyframes] == ["splash_A", "splash_C", "splash_D"]
    after = _by_segment(splash)
    assert sorted(after) == [0, 1] and len(after[0]) == len(after[1]) == 8
    for p in after[0]:  # A -> B and B -> C became A -> C: the Empties on A and on C kept
        name, a, c = ends[p.pair_id]
        assert (p.a.name, p.a.parent.name, p.b.parent.name) == (name, "splash_A", "splash_C")
        assert np.allclose(_where(p.a), a) and np.allclose(_where(p.b), c)
        assert p.b.name == features.object_name(p.pair_id, "B", p.label)
    assert not bpy.data.objects["splash_B"].children  # its 16 Empties are gone, no others
    assert len([o for o in splash.objects if features.is_feature(o)]) == empties - 16
    assert [(p.a.parent.name, p.b.parent.name) for p in after[1]] == [("splash_C", "splash_D")] * 8
    assert all(np.allclose(_where(p.a), a) and np.allclose(_where(p.b), b)
               for p, (a, b) in zip(after[1], later))
    assert not validate.problems(splash)
    assert meshes == {o.name: kfi.mesh_hash(o.data) for o in splash.objects if o.type == "MESH"}


def _remove_and_insert_b(scene):
    assert bpy.ops.keyframe_implicit.remove_keyframe(index=1) == {"FINISHED"}
    joined = _by_segment(scene)
    assert bpy.ops.keyframe_implicit.add_keyframe(object_name="splash_B", frame=9) == {"FINISHED"}
    return joined


def test_inserting_a_keyframe_proposes_pairs_on_it(splash, kfi):
    meshes = {o.name: kfi.mesh_hash(o.data) for o in splash.objects if o.type == "MESH"}
    joined = _remove_and_insert_b(splash)
    s = splash.keyframe_implicit
    assert [k.object.name for k in s.keyframes] == ["splash_A", "splash_B", "splash_C", "splash_D"]
    after = _by_segment(splash)
    assert sorted(after) == [0, 1, 2] and [len(after[i]) for i in range(3)] == [8, 8, 8]
    parents = [(p.a.parent.name, p.b.parent.name) for seg in range(3) for p in after[seg]]
    assert parents == ([("splash_A", "splash_B")] * 8 + [("splash_B", "splash_C")] * 8
                       + [("splash_C", "splash_D")] * 8)
    proposed = set()
    for old, first, second in zip(joined[0], after[0], after[1]):
        # each pair through splash_B became two, meeting at one new point on splash_B
        assert first.a == old.a and second.b == old.b
        assert np.allclose(_where(first.b), _where(second.a))
        proposed |= {first.b.name, second.a.name}
    assert {o.name for o in bpy.context.selected_objects} == proposed  # for review
    b = bpy.data.objects["splash_B"]
    points = [_where(bpy.data.objects[n]) for n in proposed]
    assert np.all(_off(b, points) <= 1e-6)  # on splash_B's surface
    assert [p.pair_id for p in after[2]] == [p.pair_id.replace("1.", "2.", 1) for p in joined[1]]
    assert not validate.problems(splash)  # nothing left to fix by hand
    assert meshes == {o.name: kfi.mesh_hash(o.data) for o in splash.objects if o.type == "MESH"}


@pytest.mark.heavy
def test_the_splash_with_a_keyframe_removed_and_inserted_bakes(splash):
    _remove_and_insert_b(splash)
    s = splash.keyframe_implicit
    s.output_mode = "SHAPE_KEYS"  # vertices that keep their identity: the bake's paths
    assert bpy.ops.keyframe_implicit.bake(resolution=16) == {"FINISHED"}
    # a bake's own paths place the Empties of a keyframe inserted after it
    assert bpy.ops.keyframe_implicit.remove_keyframe(index=1) == {"FINISHED"}
    assert bpy.ops.keyframe_implicit.add_keyframe(object_name="splash_B", frame=9) == {"FINISHED"}
    spanning = _by_segment(splash)[0]
    points, from_bake = edits.proposed_points(
        splash, spanning, (1, 9, 15), bpy.data.objects["splash_B"],
        bpy.context.evaluated_depsgraph_get())
    assert from_bake and np.all(_off(bpy.data.objects["splash_B"], points) <= 1e-6)
    assert len(s.keyframes) == 4 and not validate.problems(splash)


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


def test_a_deleted_keyframe_object_is_picked_again_in_its_row(splash):
    c = bpy.data.objects["splash_C"]
    empties = {o.name: _where(o) for o in c.children}
    assert len(empties) == 16
    bpy.data.objects.remove(c)
    found = validate.problems(splash)
    assert found[0].severity == validate.ERROR and found[0].icon == "ERROR"
    assert found[0].message.startswith("Keyframe 3 (frame 15) has no object: pick a mesh object "
                                       "in its row")
    assert "Its 16 feature Empties stay where they were, parented to nothing" in found[0].message
    assert all(np.allclose(_where(splash.objects[n]), w) for n, w in empties.items())
    log = []
    from keyframe_implicit.blender import panel

    panel.KFI_PT_main.draw(type("PanelSelf", (), {"layout": Layout(log)})(), bpy.context)
    assert ("prop", "object") in list_rows(log)[2]  # the row offers the object field
    other = bpy.data.objects["splash_D"].copy()  # picked there, it takes the Empties left
    other.data = bpy.data.objects["splash_D"].data.copy()
    splash.collection.objects.link(other)
    splash.keyframe_implicit.keyframes[2].object = other
    assert len(other.children) == 16
    assert all(np.allclose(_where(splash.objects[n]), w) for n, w in empties.items())
    assert len(bpy.data.objects["splash_D"].children) == 8  # its own, untouched


def test_a_first_or_last_keyframe_added_moves_the_pairs_with_their_keyframes(scene, kfi):
    kfi.build_spheres([("A", (0, 0, 0), 1, 5), ("B", (3, 0, 0), 1, 9)])
    kfi.add_sphere("Z", (6, 0, 0))
    assert bpy.ops.keyframe_implicit.add_keyframe(frame=20) == {"FINISHED"}  # last: no change
    assert sorted(features.pairs(scene)) == ["0.0", "0.1", "0.2", "0.3"]
    kfi.add_sphere("First", (-3, 0, 0))
    assert bpy.ops.keyframe_implicit.add_keyframe(frame=1) == {"FINISHED"}
    found = features.pairs(scene)
    assert sorted(found) == ["1.0", "1.1", "1.2", "1.3"]  # still A -> B, now keyframes 2 -> 3
    assert all((p.a.parent.name, p.b.parent.name) == ("A", "B") for p in found.values())
    assert found["1.2"].b.name == "KFI 1.2 B"
    assert not validate.errors(validate.problems(scene))
