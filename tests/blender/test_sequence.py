"""The mesh sequence output: topology free, self-contained, motion blur, Alembic export."""

import os

import bpy
import numpy as np
import pytest

import keyframe_implicit

RES = 16


def _bake_moving_sphere(kfi, mode="MESH_SEQUENCE", distance=2.0):
    """A ball moving along +x by ``distance`` over frames 1..9, baked with ``mode``."""
    kfi.build_spheres([("A", (0, 0, 0), 0.6, 1), ("B", (distance, 0, 0), 0.6, 9)])
    scene = bpy.context.scene
    scene.keyframe_implicit.output_mode = mode
    assert bpy.ops.keyframe_implicit.bake(resolution=RES) == {"FINISHED"}
    return scene, scene.keyframe_implicit.output_object


def _evaluated_velocity(obj):
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        attr = me.attributes.get("velocity")
        assert attr is not None and attr.data_type == "FLOAT_VECTOR" and attr.domain == "POINT"
        vel = np.empty(len(me.vertices) * 3, np.float32)
        attr.data.foreach_get("vector", vel)
    finally:
        ev.to_mesh_clear()
    return vel.reshape(-1, 3)


def test_mesh_sequence_plays_each_frames_surface_with_velocity_per_second(scene, kfi):
    scene.render.fps, scene.render.fps_base = 24, 1.0
    scene, out = _bake_moving_sphere(kfi)
    assert out["kfi_output_kind"] == "mesh_sequence"
    assert out.data.shape_keys is None
    # every frame lives in the output's own mesh: no frame objects outside the scene
    assert set(bpy.data.objects) <= set(scene.objects)
    h = float(out["kfi_stats"]["spacing"])
    centres = []
    for f in range(1, 10):
        scene.frame_set(f)
        v, t = kfi.evaluated_arrays(out)
        assert len(t) > 100
        centres.append(v.mean(axis=0))
        # the ball keeps its volume on every frame (the sequence is each frame's surface)
        assert abs(kfi.volume(v, t) / (4 / 3 * np.pi * 0.6 ** 3) - 1) < 0.08, f
    centres = np.array(centres)
    assert np.allclose(centres[:, 0], np.linspace(0, 2, 9), atol=0.5 * h)
    # 2 units over 8 frames at 24 fps: 6 units per second along +x
    scene.frame_set(5)
    vel = _evaluated_velocity(out)
    assert np.allclose(np.median(vel, axis=0), [6.0, 0, 0], atol=0.3), np.median(vel, axis=0)
    # a forced shape-key bake replaces the sequence and leaves none of its blocks behind
    scene.keyframe_implicit.output_mode = "SHAPE_KEYS"
    assert bpy.ops.keyframe_implicit.bake(resolution=RES) == {"FINISHED"}
    assert not [c for c in bpy.data.collections if c.name.endswith("Frames")]
    assert not bpy.data.node_groups
    assert scene.keyframe_implicit.output_object.data.shape_keys is not None


def test_failure_while_writing_a_sequence_removes_partial_data(scene, kfi, monkeypatch):
    from keyframe_implicit.blender import output

    scene, _ = _bake_moving_sphere(kfi)
    scene.keyframe_implicit.output_collection = "Fresh Collection"  # created, then removed again
    state = kfi.snapshot()

    def fail_late(*args):  # the new mesh, frame switch, object and collection exist by now
        raise RuntimeError("disk full")

    monkeypatch.setattr(output, "retire_output", fail_late)
    with pytest.raises(RuntimeError, match="disk full"):
        bpy.ops.keyframe_implicit.bake(resolution=RES)
    assert kfi.snapshot() == state


def test_sequence_blend_plays_without_the_add_on(scene, kfi, tmp_path):
    scene, out = _bake_moving_sphere(kfi)
    counts = {}
    for f in (1, 5, 9):
        scene.frame_set(f)
        counts[f] = kfi.evaluated_arrays(out)[0].shape
    path = str(tmp_path / "sequence.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    keyframe_implicit.unregister()
    try:
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
        obj = bpy.data.objects["KFI Animation"]
        for f, shape in counts.items():
            bpy.context.scene.frame_set(f)
            assert kfi.evaluated_arrays(obj)[0].shape == shape, f
    finally:
        keyframe_implicit.register()


@pytest.mark.skipif(not bpy.app.build_options.alembic,
                    reason="this Blender is built without Alembic (Debian's 4.3 package)")
def test_alembic_export_writes_per_frame_vertex_counts(scene, kfi, tmp_path):
    _, b = kfi.build_spheres([("A", (-0.5, 0, 0), 0.6, 1), ("B", (0.0, 0, 0), 0.75, 7)])
    # B modelled finer than A: its frame shows its own mesh, the frames before it A's tracked
    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=0.75)
    finer = bpy.context.active_object
    b.data = finer.data
    bpy.data.objects.remove(finer)
    scene.keyframe_implicit.output_mode = "MESH_SEQUENCE"
    assert bpy.ops.keyframe_implicit.bake(resolution=RES) == {"FINISHED"}
    out = scene.keyframe_implicit.output_object
    counts = []
    for f in range(1, 8):
        scene.frame_set(f)
        counts.append(len(kfi.evaluated_arrays(out)[0]))
    assert len(set(counts)) > 1, counts
    for obj in list(scene.objects):
        obj.select_set(obj == out)
    path = str(tmp_path / "sequence.abc")
    assert bpy.ops.wm.alembic_export(filepath=path, start=1, end=7, selected=True,
                                     evaluation_mode="RENDER") == {"FINISHED"}
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True, load_ui=False)
    keyframe_implicit.register()
    assert bpy.ops.wm.alembic_import(filepath=path) == {"FINISHED"}
    imported = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    assert len(imported) == 1
    read = []
    for f in range(1, 8):
        bpy.context.scene.frame_set(f)
        read.append(len(kfi.evaluated_arrays(imported[0])[0]))
    assert read == counts


def _render_alpha(scene, blur):
    scene.render.use_motion_blur = blur
    scene.render.filepath = os.path.join(bpy.app.tempdir, f"kfi_blur_{int(blur)}.png")
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(scene.render.filepath, check_existing=False)
    try:
        px = np.array(img.pixels[:], dtype=np.float32).reshape(img.size[1], img.size[0], 4)
    finally:
        bpy.data.images.remove(img)
    return px[..., 3]


def test_cycles_motion_blur_streaks_along_the_motion(scene, kfi):
    """Top view of a ball moving along +x: blur widens its silhouette along x only, and
    with the shutter opening on the frame the streak lies ahead of the ball (+x)."""
    scene, out = _bake_moving_sphere(kfi, distance=4.0)
    scene.frame_set(5)
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False  # not every build has a denoiser, and 4 samples need none
    scene.cycles.device = "CPU"
    scene.render.resolution_x, scene.render.resolution_y = 96, 64
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.motion_blur_shutter = 1.0
    scene.render.motion_blur_position = "START"
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 6.0
    cam.location = (2.0, 0.0, 10.0)  # looking down -z at the ball's path (x to the right)
    scene.camera = cam
    for o in scene.objects:
        if o.type == "MESH" and o != out:
            o.hide_render = True
    sharp = _render_alpha(scene, False) > 0.5
    blurred = _render_alpha(scene, True)
    diff = np.abs(blurred - sharp) > 0.1
    assert diff.sum() > 20, "motion blur changed nothing"
    ys, xs = np.nonzero(sharp)
    dy, dx = np.nonzero(diff)
    # only along the motion: no change above or below the ball's rows
    assert dy.min() >= ys.min() - 1 and dy.max() <= ys.max() + 1
    # the streak leads: blur adds coverage past the ball's front edge (+x, image columns grow)
    gained = (blurred > 0.1) & ~sharp
    gx = np.nonzero(gained)[1]
    assert gx.size and np.mean(gx) > xs.mean(), (np.mean(gx), xs.mean())


def test_removing_a_sequence_of_the_earlier_layout_leaves_none_of_its_blocks(scene):
    """Earlier versions kept one object per frame in an unlinked collection, picked by a
    Collection Info node: re-baking such a file removes all of it."""
    from keyframe_implicit.blender import output

    frames = bpy.data.collections.new("Old Frames")
    for i in range(3):
        frames.objects.link(bpy.data.objects.new(f"Old {i}", bpy.data.meshes.new(f"Old {i}")))
    group = bpy.data.node_groups.new("Old Frame Switch", "GeometryNodeTree")
    info = group.nodes.new("GeometryNodeCollectionInfo")
    info.inputs["Collection"].default_value = frames
    old = bpy.data.objects.new("Old", bpy.data.meshes.new("Old"))
    scene.collection.objects.link(old)
    old.modifiers.new("Frame Switch", "NODES").node_group = group
    old[output.SEQUENCE_TAG] = True
    output.remove_output(old)
    assert not bpy.data.objects and not bpy.data.meshes
    assert not bpy.data.node_groups and not bpy.data.collections
