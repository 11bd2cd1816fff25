"""Hostile scenes: a user's objects are never lost, each keyframe is read on its own frame.

Each test here reproduces one defect of a hostile-input sweep (re-baking deleted a keyframe
object; keyframes animated by their own object were read on the current frame; negative frames
were ignored; messages used the wrong article) and asserts what an artist expects instead.
"""

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import bake, output

TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]


def test_rebake_keeps_previous_output_used_as_keyframe(scene, kfi):
    kfi.build_spheres(TWO)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    first = scene.keyframe_implicit.output_object
    # the artist likes the result and makes it a keyframe of a longer shot
    scene.frame_set(12)
    assert bpy.ops.keyframe_implicit.add_keyframe(object_name=first.name) == {"FINISHED"}
    before = kfi.mesh_hash(first.data), first.data.shape_keys.key_blocks[-1].name
    name_before = first.name

    notes = []
    bake.bake_scene(scene, kfi.RES, notes=notes)
    settings = scene.keyframe_implicit
    second = settings.output_object
    kept = settings.keyframes[2].object
    assert kept is not None and kept.name in bpy.data.objects, "the keyframe object was deleted"
    assert kept != second and settings.output_object == second
    assert (kfi.mesh_hash(kept.data), kept.data.shape_keys.key_blocks[-1].name) == before
    assert kept.name != name_before and second.name == name_before
    assert len(notes) == 1 and f"'{kept.name}'" in notes[0] and "keyframe 3" in notes[0], notes
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


def _collect(scene):
    return bake.collect(scene, bpy.context.evaluated_depsgraph_get(), 0)


def _keyed_on_two_frames(obj, owner, prop, values, frames=(1, 9)):
    """Key ``owner.prop`` to ``values`` on ``frames``, and add ``obj`` as a keyframe on each."""
    for frame, value in zip(frames, values):
        setattr(owner, prop, value)
        owner.keyframe_insert(prop, frame=frame)
    for frame in frames:
        assert bpy.ops.keyframe_implicit.add_keyframe(object_name=obj.name, frame=frame) == {"FINISHED"}


def _same_object_twice(scene, kfi):
    """One sphere, its location keyed from x=0 (frame 1) to x=3 (frame 9), added on both frames."""
    obj = kfi.add_sphere("Mover", (0.0, 0.0, 0.0))
    _keyed_on_two_frames(obj, obj, "location", [(0.0, 0.0, 0.0), (3.0, 0.0, 0.0)])
    return obj


def test_object_animated_by_its_transform_is_read_on_each_keyframe_frame(scene, kfi):
    _same_object_twice(scene, kfi)
    pa = kfi.sphere_points((0, 0, 0), 1.0)
    for a in pa:  # the feature points ride on the object: the same Empties on both sides
        assert bpy.ops.keyframe_implicit.add_feature_pair(
            segment=0, location_a=tuple(a), location_b=tuple(a)) == {"FINISHED"}
    scene.frame_set(5)  # in between: the object is at x = 1.5
    inp = _collect(scene)
    assert scene.frame_current == 5  # the scene is back on its frame
    centres = [kf.vertices.mean(axis=0) for kf in inp.keyframes]
    np.testing.assert_allclose(centres[0], (0, 0, 0), atol=1e-5)
    np.testing.assert_allclose(centres[1], (3, 0, 0), atol=1e-5)
    a, b = inp.features[0]
    np.testing.assert_allclose(b - a, np.tile((3.0, 0.0, 0.0), (4, 1)), atol=1e-5)
    assert [kf.name for kf in inp.keyframes] == ["Mover", "Mover"]
    # and the bake moves: the result's first and last frames follow the object
    out = bake.bake_scene(scene, kfi.RES)
    assert scene.frame_current == 5
    centres = []
    for frame in (1, 9):  # whatever the output kind (shape keys or mesh sequence)
        scene.frame_set(frame)
        centres.append(kfi.evaluated_arrays(out)[0].mean(axis=0))
    np.testing.assert_allclose(centres[0], (0, 0, 0), atol=0.1)
    np.testing.assert_allclose(centres[1], (3, 0, 0), atol=0.1)


def test_shape_key_animation_is_read_on_each_keyframe_frame(scene, kfi):
    obj = kfi.add_sphere("Breathe", (0.0, 0.0, 0.0))
    obj.shape_key_add(name="Basis")
    big = obj.shape_key_add(name="Big")
    co = np.empty(len(big.data) * 3)
    big.data.foreach_get("co", co)
    big.data.foreach_set("co", 1.5 * co)
    _keyed_on_two_frames(obj, big, "value", [0.0, 1.0])
    scene.frame_set(1)
    radii = [np.linalg.norm(kf.vertices, axis=1).max() for kf in _collect(scene).keyframes]
    np.testing.assert_allclose(radii, [1.0, 1.5], atol=1e-5)
    assert scene.frame_current == 1 and obj.data.shape_keys.key_blocks["Big"].value == 0.0


def test_animated_modifier_is_read_on_each_keyframe_frame(scene, kfi):
    obj = kfi.add_sphere("Pulse", (0.0, 0.0, 0.0))
    mod = obj.modifiers.new("Displace", "DISPLACE")  # no texture: every vertex moves along its normal
    _keyed_on_two_frames(obj, mod, "strength", [0.0, 1.0])
    scene.frame_set(9)
    ref = [kfi.evaluated_arrays(obj)[0]]
    scene.frame_set(1)
    ref.insert(0, kfi.evaluated_arrays(obj)[0])
    inp = _collect(scene)
    for kf, want in zip(inp.keyframes, ref):
        np.testing.assert_allclose(kf.vertices, want, atol=1e-6)
    r0, r1 = (np.linalg.norm(kf.vertices, axis=1).mean() for kf in inp.keyframes)
    assert r1 > r0 + 0.25, (r0, r1)


class _FrameChanges:
    """Counts the scene's frame changes (`frame_change_pre`) while in the block."""

    def __enter__(self):
        self.frames = []
        bpy.app.handlers.frame_change_pre.append(self._seen)
        return self

    def _seen(self, scene, *args):
        self.frames.append(scene.frame_current)

    def __exit__(self, *exc):
        bpy.app.handlers.frame_change_pre.remove(self._seen)


def test_static_keyframes_are_read_without_a_frame_change(scene, kfi):
    a, b = kfi.build_spheres(TWO)
    b.modifiers.new("Smooth", "SUBSURF")  # a modifier that does not read the time
    scene.frame_set(3)
    with _FrameChanges() as changes:
        inp = _collect(scene)
    # every frame change redraws the 3D views: none is needed when nothing is animated
    assert changes.frames == [] and scene.frame_current == 3
    centres = [kf.vertices.mean(axis=0) for kf in inp.keyframes]
    np.testing.assert_allclose(centres, [(0, 0, 0), (1.5, 0, 0)], atol=1e-5)
    assert len(inp.keyframes[1].vertices) > len(a.data.vertices)  # read after the subdivision
    pa, pb = inp.features[0]
    np.testing.assert_allclose(pb - pa, np.tile((1.5, 0.0, 0.0), (4, 1)), atol=1e-5)


def _added_on_frames(scene, kfi, obj, frames):
    """Add ``obj`` as a keyframe on each of ``frames``; its evaluated vertices on each."""
    for frame in frames:
        assert bpy.ops.keyframe_implicit.add_keyframe(object_name=obj.name, frame=frame) == {"FINISHED"}
    ref = {}
    for frame in frames:
        scene.frame_set(frame)
        ref[frame] = kfi.evaluated_arrays(obj)[0]
    return ref


def test_time_reading_modifier_is_read_on_its_keyframe_frame(scene, kfi):
    obj = kfi.add_sphere("Ripple", (0.0, 0.0, 0.0))
    wave = obj.modifiers.new("Wave", "WAVE")  # moves with the time, without any animation data
    wave.height = 0.3
    ref = _added_on_frames(scene, kfi, obj, (1, 9))
    assert np.abs(ref[1] - ref[9]).max() > 0.05  # the wave does move the sphere
    scene.frame_set(5)
    with _FrameChanges() as changes:
        inp = _collect(scene)
    assert changes.frames == [1, 9, 5] and scene.frame_current == 5
    for kf, frame in zip(inp.keyframes, (1, 9)):
        np.testing.assert_allclose(kf.vertices, ref[frame], atol=1e-6)


def test_keyframe_on_a_bone_moved_by_a_constraint_is_read_on_its_frame(scene, kfi):
    # nothing on the keyframe or its armature is keyed: the bone follows an animated target
    target = bpy.data.objects.new("Target", None)
    scene.collection.objects.link(target)
    for frame, x in ((1, 0.0), (9, 3.0)):
        target.location = (x, 0.0, 0.0)
        target.keyframe_insert("location", frame=frame)
    bpy.ops.object.armature_add(location=(0.0, 0.0, 0.0))
    rig = bpy.context.active_object
    follow = rig.pose.bones[0].constraints.new("COPY_LOCATION")
    follow.target = target
    obj = kfi.add_sphere("Carried", (0.0, 0.0, 0.0))
    obj.parent, obj.parent_type, obj.parent_bone = rig, "BONE", rig.pose.bones[0].name
    ref = _added_on_frames(scene, kfi, obj, (1, 9))
    assert np.abs(ref[9] - ref[1]).max() > 2.0  # the bone does carry the sphere
    scene.frame_set(5)
    inp = _collect(scene)
    for kf, frame in zip(inp.keyframes, (1, 9)):
        np.testing.assert_allclose(kf.vertices, ref[frame], atol=1e-5)


def test_animated_feature_point_on_a_static_keyframe_is_read_on_its_frame(scene, kfi):
    kfi.build_spheres(TWO)
    empty = bpy.data.objects["KFI 0.1 B"]  # on KeyB (keyframe 2, frame 7)
    start = tuple(empty.location)
    empty.keyframe_insert("location", frame=1)
    empty.location = (start[0], start[1], start[2] + 0.25)
    empty.keyframe_insert("location", frame=7)
    scene.frame_set(1)
    with _FrameChanges() as changes:
        inp = _collect(scene)
    assert changes.frames == [7, 1] and scene.frame_current == 1
    scene.frame_set(7)
    want = tuple(empty.matrix_world.translation)
    row = [str(i) for i in inp.pair_ids[0]].index("0.1")
    np.testing.assert_allclose(inp.features[0][1][row], want, atol=1e-6)


def test_negative_explicit_frame_is_honoured_and_unset_means_current(scene, kfi):
    kfi.add_sphere("Early", (0.0, 0.0, 0.0))
    scene.frame_set(4)
    assert bpy.ops.keyframe_implicit.add_keyframe(frame=-2) == {"FINISHED"}
    kfi.add_sphere("Now", (2.0, 0.0, 0.0))
    assert bpy.ops.keyframe_implicit.add_keyframe() == {"FINISHED"}  # no frame: the current one
    assert [(k.object.name, k.frame) for k in scene.keyframe_implicit.keyframes] == [
        ("Early", -2), ("Now", 4)]
    with pytest.raises(RuntimeError, match=r"Frame -2 \(the frame given\) already has a keyframe"):
        bpy.ops.keyframe_implicit.add_keyframe(object_name="Now", frame=-2)
    assert list(bake.bake_scene(scene, kfi.RES).get("kfi_frames")) == [-2, 4]


@pytest.mark.parametrize("kind, add, words", [
    ("CURVE", lambda: bpy.ops.curve.primitive_bezier_circle_add(), "is a Curve, not a mesh"),
    ("EMPTY", lambda: bpy.ops.object.empty_add(), "is an Empty, not a mesh"),
    ("FONT", lambda: bpy.ops.object.text_add(), "is a Text, not a mesh"),
])
def test_non_mesh_keyframe_is_named_with_its_kind(scene, kind, add, words):
    add()
    obj = bpy.context.active_object
    obj.name = "Nothing"
    assert obj.type == kind
    with pytest.raises(RuntimeError, match=f"'Nothing' {words}: .*Convert > Mesh"):
        bpy.ops.keyframe_implicit.add_keyframe()


def test_far_empty_is_refused_naming_it_and_nothing_changes(scene, kfi):
    kfi.build_spheres(TWO)
    stray = bpy.data.objects["KFI 0.2 B"]
    stray.parent = None
    stray.location = (1000.0, 0.0, 0.0)
    bpy.context.view_layer.update()
    state = kfi.snapshot()
    with pytest.raises(RuntimeError) as err:
        bpy.ops.keyframe_implicit.bake(resolution=kfi.RES)
    msg = str(err.value)
    assert "'KFI 0.2 B'" in msg and "keyframe 2" in msg and "close the mesh" not in msg, msg
    assert ".;" not in msg and "..;" not in msg
    assert kfi.snapshot() == state


def test_loose_vertices_and_reversed_faces_are_reported_after_the_bake(scene, kfi):
    a, b = kfi.build_spheres(TWO)
    a.data.vertices.add(1)
    a.data.vertices[-1].co = (50.0, 0.0, 0.0)  # a stray vertex far away
    for quad in [p for p in b.data.polygons if p.loop_total == 4][:2]:  # 2 quads: 4 triangles
        quad.flip()
    b.data.update()
    warnings = []
    bake.bake_scene(scene, kfi.RES, notes=warnings)
    assert any(m.startswith("Keyframe 1 ('KeyA', frame 1): ignored 1 loose vert") for m in warnings), warnings
    assert any(m.startswith("Keyframe 2 ('KeyB', frame 7): 4 triangles faced the wrong way") for m in warnings), warnings
    out = scene.keyframe_implicit.output_object
    assert max(np.abs(np.array([v.co for v in out.data.vertices])).max(axis=0)) < 4.0
