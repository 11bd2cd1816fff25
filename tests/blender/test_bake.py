"""Bake end to end through the operators (issue 5, "Checked by")."""

import re

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import bake, fcurves, features, output, scene_io, validate
from keyframe_implicit.core import Cancelled

# Two unit spheres (equal volume), the second moved along x: frames 1..7.
TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]


def _active_keys(obj):
    return [kb.name for kb in obj.data.shape_keys.key_blocks[1:] if abs(kb.value - 1.0) < 1e-6]


def _nonzero_keys(obj):
    return [kb.name for kb in obj.data.shape_keys.key_blocks[1:] if abs(kb.value) > 1e-6]


def test_two_keyframes_bake_matches_keyframes_and_keeps_volume(scene, kfi):
    objs = kfi.build_spheres(TWO)
    mat = bpy.data.materials.new("Skin")
    objs[0].data.materials.append(mat)
    before = {o.name: kfi.mesh_hash(o.data) for o in objs}

    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    out = scene.keyframe_implicit.output_object
    assert out is not None and out.type == "MESH"
    # own collection, material of keyframe A, keyframe A's own mesh and shading (the
    # topology stays the same, so the result is the artist's mesh with shape keys)
    assert [c.name for c in out.users_collection] == [scene.keyframe_implicit.output_collection]
    assert out.data.materials[0] == mat
    assert len(out.data.polygons) == len(objs[0].data.polygons)
    assert [p.use_smooth for p in out.data.polygons] == [p.use_smooth for p in objs[0].data.polygons]
    frames = list(range(1, 8))
    keys = out.data.shape_keys.key_blocks
    assert len(keys) - 1 == len(frames)  # Basis + one per frame
    assert [kb.name for kb in keys[1:]] == [output.frame_key_name(f) for f in frames]
    # keyframes untouched
    assert {o.name: kfi.mesh_hash(o.data) for o in objs} == before

    h = out["kfi_stats"]["spacing"]
    vols = []
    for f in frames:
        scene.frame_set(f)
        assert _active_keys(out) == [output.frame_key_name(f)]
        assert _nonzero_keys(out) == [output.frame_key_name(f)]
        verts, tris = kfi.evaluated_arrays(out)
        vols.append(kfi.volume(verts, tris))
        for name, center, radius, frame in TWO:
            if frame == f:
                dist = np.abs(np.linalg.norm(verts - np.asarray(center), axis=1) - radius)
                assert dist.mean() <= 0.25 * h, (f, dist.mean(), h)
    vols = np.array(vols)
    ref = vols[[0, -1]].mean()
    assert np.all(np.abs(vols / ref - 1.0) <= 0.02), vols / ref

    # sub-frame (motion blur) blends the two neighbouring frames linearly
    scene.frame_set(3, subframe=0.25)
    vals = {kb.name: kb.value for kb in keys[1:] if kb.value > 1e-6}
    assert vals.keys() == {output.frame_key_name(3), output.frame_key_name(4)}
    assert vals[output.frame_key_name(3)] == pytest.approx(0.75, abs=1e-5)
    assert vals[output.frame_key_name(4)] == pytest.approx(0.25, abs=1e-5)


def test_three_keyframes_bake_into_one_object(scene, kfi):
    specs = [("K0", (0, 0, 0), 1.0, 1), ("K1", (1.2, 0, 0), 1.0, 4), ("K2", (1.2, 1.2, 0), 1.0, 7)]
    kfi.build_spheres(specs)
    n_objects = len(bpy.data.objects)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    assert len(bpy.data.objects) == n_objects + 1
    out = scene.keyframe_implicit.output_object
    assert len(out.data.shape_keys.key_blocks) - 1 == 7
    h = out["kfi_stats"]["spacing"]
    for name, center, radius, frame in specs:
        scene.frame_set(frame)
        assert _active_keys(out) == [output.frame_key_name(frame)]
        verts, _ = kfi.evaluated_arrays(out)
        dist = np.abs(np.linalg.norm(verts - np.asarray(center), axis=1) - radius)
        assert dist.mean() <= 0.25 * h, (name, dist.mean(), h)
    # every frame in between is covered by exactly one key at 1.0
    for f in range(1, 8):
        scene.frame_set(f)
        assert _active_keys(out) == [output.frame_key_name(f)]


#: A bake's progress: counted steps in the artist's words; the worker's last line names the
#: output mesh it makes after them.
STEP = re.compile(r"^(Distance fields|Maps|Paths|Frames) (\d+)/(\d+)$")


def test_progress_is_counted_steps_and_never_goes_back(scene, kfi):
    specs = [("K0", (0, 0, 0), 1.0, 1), ("K1", (1.2, 0, 0), 1.0, 4), ("K2", (1.2, 1.2, 0), 1.0, 7)]
    kfi.build_spheres(specs)
    seen = []
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES),
                       on_progress=lambda j, f, m: seen.append((f, m)))
    assert job.run() == bake.DONE, job.error_message()
    fractions, messages = [f for f, _ in seen], [m for _, m in seen]
    assert messages[-1] == "Preparing the output mesh" and fractions[-2:] == [1.0, 1.0]
    assert all(STEP.match(m) for m in messages[:-1]), [m for m in messages if not STEP.match(m)]
    assert all(b >= a for a, b in zip(fractions, fractions[1:])), fractions
    last = {}
    for m in messages[:-1]:
        stage, i, n = STEP.match(m).groups()
        assert int(i) >= last.get(stage, 1), f"{m} after {stage} {last[stage]}"
        last[stage] = int(i)
    assert {m for m in messages if m.endswith(("4/4", "3/3", "7/7"))} >= {
        "Maps 4/4", "Distance fields 3/3", "Frames 7/7"}
    assert "Initial map" not in " ".join(messages) and "%" not in " ".join(messages)


def test_bake_twice_replaces_only_its_own_output(scene, kfi):
    kfi.build_spheres(TWO)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    state = kfi.snapshot()
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    after = kfi.snapshot()
    # one output, and exactly the same data-block names: the old one was replaced, nothing left over
    for kind in ("objects", "meshes", "collections", "actions", "shape_keys"):
        assert after[kind] == state[kind], kind
    out = scene.keyframe_implicit.output_object
    assert [o for o in bpy.data.objects if o.get(output.OUTPUT_TAG)] == [out]

    keep = out.copy()  # a user's duplicate of the result must survive the next bake
    keep.data = out.data.copy()
    scene.collection.objects.link(keep)
    old_name = out.name
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    new = scene.keyframe_implicit.output_object
    assert keep.name in bpy.data.objects and keep.data.shape_keys is not None
    assert sorted(o.name for o in bpy.data.objects if o.get(output.OUTPUT_TAG)) == sorted(
        [keep.name, new.name])
    assert new.name == old_name


def _cancel_after_first_stage(job, fraction, message):
    job.cancel()


def test_cancel_mid_bake_leaves_scene_unchanged(scene, kfi):
    kfi.build_spheres(TWO)
    state = kfi.snapshot()
    messages = []

    def observer(job, fraction, message):
        messages.append((fraction, message))
        if fraction > 0.0:  # the first stage is under way: cancel mid-bake
            job.cancel()  # exactly what ESC does in the modal operator

    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES),
                       on_progress=observer)
    job.start()  # worker thread, as from invoke()
    job.join(120)
    assert job.finished and job.state == bake.CANCELLED
    assert messages and messages[-1][0] > 0.0 and job.fraction < 1.0  # stopped part way
    assert job.result is None and job.error is None
    with pytest.raises(RuntimeError):
        job.apply(scene)
    assert kfi.snapshot() == state

    # the blocking path raises Cancelled and also changes nothing
    with pytest.raises(Cancelled):
        bake.bake_scene(scene, kfi.RES, on_progress=_cancel_after_first_stage)
    assert kfi.snapshot() == state


def test_failing_core_leaves_scene_unchanged(scene, kfi, in_worker):
    kfi.build_spheres(TWO)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    state = kfi.snapshot()
    in_worker("""
        from keyframe_implicit.core.bake import pipeline

        def broken(*args, progress=None, **kwargs):
            progress(0.2, "signed distance grids")
            raise ValueError("Keyframe 1 is not a closed surface: close its holes.")

        pipeline.bake = broken
    """)
    with pytest.raises(RuntimeError) as err:
        bpy.ops.keyframe_implicit.bake(resolution=kfi.RES)
    # the core's own text, without a type name in front, with where Blender does the fix
    assert ("Error: Keyframe 1 is not a closed surface: close its holes (Mesh > Clean Up > "
            "Fill Holes).") in str(err.value)
    assert "ValueError" not in str(err.value)
    assert kfi.snapshot() == state


def test_failure_while_writing_output_removes_partial_data(scene, kfi, monkeypatch):
    kfi.build_spheres(TWO)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    scene.keyframe_implicit.output_collection = "Fresh Collection"  # created, then removed again
    state = kfi.snapshot()
    real = fcurves.set_keyframes
    calls = []

    def fail_late(fc, *a, **k):
        calls.append(fc)
        if len(calls) == 5:  # mesh, object, shape keys and action exist by now
            raise RuntimeError("disk full")
        return real(fc, *a, **k)

    monkeypatch.setattr(fcurves, "set_keyframes", fail_late)
    with pytest.raises(RuntimeError, match="disk full"):
        bpy.ops.keyframe_implicit.bake(resolution=kfi.RES)
    assert len(calls) == 5
    assert kfi.snapshot() == state


def test_invalid_setup_is_refused_without_changes(scene, kfi):
    kfi.add_sphere("Lonely", (0, 0, 0))
    assert bpy.ops.keyframe_implicit.add_keyframe() == {"FINISHED"}
    state = kfi.snapshot()
    with pytest.raises(RuntimeError, match="add at least two"):
        bpy.ops.keyframe_implicit.bake()
    assert kfi.snapshot() == state


class _Recorder:
    """Stand-in for the window manager / workspace the modal bake talks to."""

    def __init__(self):
        self.calls = []

    def __getattr__(self, name):
        return lambda *a, **k: self.calls.append((name, a))


def _modal_operator(job, scene):
    """A bake operator 'self' and context as invoke() leaves them, without a window."""
    import types

    from keyframe_implicit.blender import ops

    reports = []
    me = types.SimpleNamespace(_job=job, _timer=None, _shown=None, _writer=None,
                               _write_budget=ops.WRITE_BUDGET)
    me.report = lambda kind, msg: reports.append((next(iter(kind)), msg))
    for name in ("_status", "_finish", "_hints", "_done", "_write_step", "_stop_writing"):
        setattr(me, name, getattr(ops.KFI_OT_bake, name).__get__(me))
    ctx = types.SimpleNamespace(window_manager=_Recorder(), workspace=_Recorder(), screen=None,
                                scene=scene, view_layer=bpy.context.view_layer)
    ops.running.append(job)
    return me, ctx, reports


def _event(kind, value="PRESS"):
    import types

    return types.SimpleNamespace(type=kind, value=value)


def _drive(op, me, ctx, timeout=120.0):
    import time

    t0 = time.time()
    while time.time() - t0 < timeout:
        result = op.modal(me, ctx, _event("TIMER"))
        if result != {"RUNNING_MODAL"}:
            return result
        time.sleep(0.02)
    raise AssertionError("modal bake did not finish")


def test_modal_bake_esc_cancels_and_changes_nothing(scene, kfi):
    from keyframe_implicit.blender import ops

    kfi.build_spheres(TWO)
    state = kfi.snapshot()
    started = []
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES),
                       on_progress=lambda j, f, m: started.append(m) or _wait_for_esc(j))
    me, ctx, reports = _modal_operator(job, scene)
    job.start()
    job.join(0.0)
    for _ in range(3000):
        if started:
            break
        __import__("time").sleep(0.01)
    assert ops.KFI_OT_bake.modal(me, ctx, _event("MOUSEMOVE")) == {"PASS_THROUGH"}  # responsive
    assert ops.KFI_OT_bake.modal(me, ctx, _event("ESC")) == {"RUNNING_MODAL"}
    assert job.cancel_requested
    assert _drive(ops.KFI_OT_bake, me, ctx) == {"CANCELLED"}
    assert reports and reports[-1][0] == "WARNING" and "cancelled" in reports[-1][1]
    assert ("progress_end", ()) in ctx.window_manager.calls
    assert ("status_text_set", (None,)) in ctx.workspace.calls
    assert not ops.running
    assert kfi.snapshot() == state


def _wait_for_esc(job):
    import time

    t0 = time.time()
    while not job.cancel_requested and time.time() - t0 < 30:
        time.sleep(0.01)


def test_modal_bake_applies_result_on_the_main_thread(scene, kfi):
    from keyframe_implicit.blender import ops

    kfi.build_spheres(TWO)
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
    me, ctx, reports = _modal_operator(job, scene)
    job.start()
    assert _drive(ops.KFI_OT_bake, me, ctx) == {"FINISHED"}
    out = scene.keyframe_implicit.output_object
    assert out is not None and len(out.data.shape_keys.key_blocks) == 8
    assert any(name == "progress_update" for name, _ in ctx.window_manager.calls)
    assert reports[-1][0] == "INFO" and "Baked" in reports[-1][1]
    assert not ops.running


def test_modal_bake_writes_over_several_turns_and_esc_there_changes_nothing(scene, kfi):
    """The result is written over several timer events (`BakeJob.apply_steps`); ESC half
    way through takes out what was written."""
    from keyframe_implicit.blender import ops

    kfi.build_spheres(TWO)
    state = kfi.snapshot()
    meshes = set(bpy.data.meshes)
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
    me, ctx, reports = _modal_operator(job, scene)
    me._write_budget = 0.0  # one piece a turn (the operator's budget writes this one in one)
    job.start()
    job.join(120.0)
    assert job.state == bake.DONE
    assert ops.KFI_OT_bake.modal(me, ctx, _event("TIMER")) == {"RUNNING_MODAL"}
    assert ops.KFI_OT_bake.modal(me, ctx, _event("TIMER")) == {"RUNNING_MODAL"}
    made = set(bpy.data.meshes) - meshes
    assert len(made) == 1 and len(next(iter(made)).polygons) > 0  # half written
    assert ops.KFI_OT_bake.modal(me, ctx, _event("ESC")) == {"CANCELLED"}
    assert reports[-1][0] == "WARNING" and "cancelled" in reports[-1][1]
    assert set(bpy.data.meshes) == meshes and not ops.running
    assert kfi.snapshot() == state


def test_modal_bake_redraws_only_the_sidebars_and_only_when_its_text_changes(scene, kfi):
    import types

    from keyframe_implicit.blender import ops

    kfi.build_spheres(TWO)
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
    me, ctx, _ = _modal_operator(job, scene)  # the job is not started: its text stays put
    regions = {}
    areas = []
    for area, region in (("VIEW_3D", "UI"), ("VIEW_3D", "WINDOW"), ("PROPERTIES", "UI")):
        regions[area, region] = _Recorder()
        regions[area, region].type = region
        areas.append(types.SimpleNamespace(type=area, regions=[regions[area, region]]))
    ctx.screen = types.SimpleNamespace(areas=areas)

    def redraws():
        return {k: len(r.calls) for k, r in regions.items()}

    try:
        for _ in range(3):
            assert ops.KFI_OT_bake.modal(me, ctx, _event("TIMER")) == {"RUNNING_MODAL"}
        assert [c for c, _ in ctx.workspace.calls] == ["status_text_set"]
        assert [c for c, _ in ctx.window_manager.calls] == ["progress_update"]
        assert redraws() == {("VIEW_3D", "UI"): 1, ("VIEW_3D", "WINDOW"): 0, ("PROPERTIES", "UI"): 0}
        job._progress(0.5, "trajectories")
        for _ in range(3):
            ops.KFI_OT_bake.modal(me, ctx, _event("TIMER"))
        assert ctx.workspace.calls[-1] == ("status_text_set", ("Baking 50%: trajectories (ESC to cancel)",))
        assert len(ctx.workspace.calls) == 2 and redraws()[("VIEW_3D", "UI")] == 2
    finally:
        ops.running.remove(job)


def test_modal_bake_redraws_the_3d_views_once_it_has_ended(scene, kfi):
    import types

    from keyframe_implicit.blender import ops

    kfi.build_spheres(TWO)
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
    me, ctx, _ = _modal_operator(job, scene)
    ended = []  # for each redraw of a whole 3D view: whether a bake was still running
    sidebar = _Recorder()
    sidebar.type = "UI"
    view = types.SimpleNamespace(type="VIEW_3D", regions=[sidebar],
                                 tag_redraw=lambda: ended.append(not ops.running))
    ctx.screen = types.SimpleNamespace(areas=[view])
    job.start()
    assert _drive(ops.KFI_OT_bake, me, ctx) == {"FINISHED"}
    assert ended == [True], "the 3D view was not redrawn once Bake could be pressed again"


def test_collected_inputs_are_evaluated_world_space_and_read_only(scene, kfi):
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(1.0, 2.0, 3.0))
    cube = bpy.context.active_object
    cube.scale = (2.0, 1.0, 1.0)
    cube.rotation_euler = (0.0, 0.0, 0.5)
    cube.modifiers.new("Subdivision", "SUBSURF").levels = 1
    bpy.ops.keyframe_implicit.add_keyframe(frame=1)
    kfi.add_sphere("S", (5, 0, 0))
    bpy.ops.keyframe_implicit.add_keyframe(frame=5)
    bpy.ops.keyframe_implicit.add_feature_pair(segment=0, location_a=(1, 2, 4), location_b=(5, 0, 1))
    bpy.ops.keyframe_implicit.add_feature_pair(segment=0, location_a=(1, 2, 2), location_b=(5, 0, -1))
    scene.keyframe_implicit.rigidity_weight = 3.0
    before = kfi.mesh_hash(cube.data)
    n_meshes = len(bpy.data.meshes)

    inp = bake.collect(scene, bpy.context.evaluated_depsgraph_get(), 0)
    assert inp.resolution == 48 and inp.weights["rigidity"] == 3.0 and inp.frames == [1, 5]
    ka = inp.keyframes[0]
    ref, tris = kfi.evaluated_arrays(cube)  # what Blender evaluates: 26 verts after subsurf
    assert len(ka.vertices) == len(ref) == 26 and len(cube.data.vertices) == 8
    np.testing.assert_allclose(ka.vertices, ref, atol=1e-5)
    np.testing.assert_array_equal(np.sort(ka.faces, axis=1), np.sort(tris, axis=1))
    assert ka.faces.shape[1] == 3  # triangulated
    pa, pb = inp.features[0]
    np.testing.assert_allclose(pa, [(1, 2, 4), (1, 2, 2)], atol=1e-6)
    np.testing.assert_allclose(pb, [(5, 0, 1), (5, 0, -1)], atol=1e-6)
    assert inp.pair_ids == [["0.0", "0.1"]]
    # reading never touches the keyframes' data nor leaves temporary meshes behind
    assert kfi.mesh_hash(cube.data) == before and len(bpy.data.meshes) == n_meshes
    assert bake.collect(scene, bpy.context.evaluated_depsgraph_get(), 24).resolution == 24


def test_keyframe_emptied_by_modifiers_fails_cleanly(scene, kfi):
    kfi.build_spheres(TWO)
    a = scene.keyframe_implicit.keyframes[0].object
    a.vertex_groups.new(name="nothing")
    mask = a.modifiers.new("Mask", "MASK")
    mask.vertex_group = "nothing"  # evaluated mesh has no faces
    state = kfi.snapshot()
    with pytest.raises(RuntimeError, match="no faces after its modifiers"):
        bpy.ops.keyframe_implicit.bake(resolution=kfi.RES)
    assert kfi.snapshot() == state


def test_keyframe_emptied_by_modifiers_on_its_own_frame_only_fails_cleanly(scene, kfi):
    _, b = kfi.build_spheres(TWO)
    b.vertex_groups.new(name="all").add(range(len(b.data.vertices)), 1.0, "REPLACE")
    mask = b.modifiers.new("Mask", "MASK")
    mask.vertex_group = "all"  # every face on frame 1, where the panel's checks look ...
    mask.keyframe_insert("invert_vertex_group", frame=1)
    mask.invert_vertex_group = True  # ... none on frame 7, KeyB's, where the bake reads it
    mask.keyframe_insert("invert_vertex_group", frame=7)
    scene.frame_set(1)
    assert not validate.errors(validate.problems(scene))
    state = kfi.snapshot()
    with pytest.raises(ValueError, match=r"\('KeyB', frame 7\) has no faces after modifiers on "
                                         "that frame: check its modifier stack"):
        bake.bake_scene(scene, kfi.RES)
    assert scene.frame_current == 1 and kfi.snapshot() == state


def _spy(calls, real):
    """``real``, recording each call's result in ``calls``."""
    def spy(*args, **kwargs):
        calls.append(real(*args, **kwargs))
        return calls[-1]
    return spy


def test_a_bake_reads_the_scene_once_then_checks_and_bakes_that_reading(scene, kfi, monkeypatch):
    kfi.build_spheres(TWO)
    reads, walks, checked, baked = [], [], [], []
    monkeypatch.setattr(scene_io, "read", _spy(reads, scene_io.read))
    monkeypatch.setattr(features, "pairs", _spy(walks, features.pairs))
    real_check = validate.raise_on_errors
    monkeypatch.setattr(validate, "raise_on_errors",
                        lambda inputs: checked.append(inputs) or real_check(inputs))

    class Worker:  # the worker process's stand-in: keeps what it is given to bake, then stops
        def __init__(self, arguments):
            baked.append(arguments)

        def result(self, progress):
            raise Cancelled("stopped by the test")

        def cancel(self):
            pass

    monkeypatch.setattr(bake, "Worker", Worker)
    with pytest.raises(Cancelled):
        bake.bake_scene(scene, kfi.RES)
    assert len(reads) == 1 and len(walks) == 1  # one reading, one walk over the feature pairs
    assert len(checked) == 1 and checked[0] is reads[0]  # the checks ran on that reading ...
    assert baked[0]["keyframes"] is reads[0].keyframes  # ... and the bake got the same
    assert baked[0]["features"] is reads[0].features and len(reads[0].keyframes) == 2


def test_the_problem_list_reads_each_mesh_once_per_state(scene, kfi, monkeypatch):
    kfi.build_spheres(TWO)
    scene.frame_end = 5  # keyframe B on frame 7: a problem to find
    scene_io.forget_readings()
    meshes, frames = [], []
    monkeypatch.setattr(scene_io, "mesh_arrays", _spy(meshes, scene_io.mesh_arrays))
    handlers = bpy.app.handlers.frame_change_pre
    changed = lambda *a: frames.append(a)  # noqa: E731
    handlers.append(changed)
    try:
        found = validate.problems(scene)
    finally:
        handlers.remove(changed)
    assert [p.message for p in found] == [
        "Keyframe 2 is on frame 7, outside the scene's frames 1-5: Bake widens the frame "
        "range to cover it."]
    # the panel asks on every redraw: each keyframe's faces are read once, as they are now,
    # without their attributes (those, and the keyframes' own frames, are the bake's)
    assert len(meshes) == 2 and all(len(m) == 2 for m in meshes) and frames == []
    validate.problems(scene)
    assert len(meshes) == 2
