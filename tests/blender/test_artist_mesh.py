"""The bake keeps the artist's mesh: Suzanne with UVs, a checker and two materials, turning."""

import importlib.util
import os
import pathlib

import bpy
import numpy as np

from keyframe_implicit.core.surface.quality import mesh_distance

_PATH = pathlib.Path(__file__).resolve().parents[2] / "benchmarks" / "suzanne_check.py"
_SPEC = importlib.util.spec_from_file_location("suzanne_check", _PATH)
sc = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(sc)


def test_suzanne_keeps_uvs_materials_and_exact_keyframes(scene):
    a, b = sc.build(scene, resolution=16)
    obj = sc.bake(scene, "SHAPE_KEYS")
    h = obj["kfi_stats"]["spacing"]
    src_a, src_b = sc.evaluated(a, sc.FRAMES[0]), sc.evaluated(b, sc.FRAMES[1])
    first, last = sc.evaluated(obj, sc.FRAMES[0]), sc.evaluated(obj, sc.FRAMES[1])
    # the artist's own mesh: same polygons, UVs, slots and per-face materials
    assert len(first["co"]) == len(src_a["co"])
    np.testing.assert_array_equal(first["lv"], src_a["lv"])
    np.testing.assert_array_equal(first["uv"], src_a["uv"])
    assert first["names"] == ["Checker Red", "Checker Blue"]
    np.testing.assert_array_equal(last["material"], src_a["material"])
    assert 0 < src_a["material"].sum() < len(src_a["material"])
    # frame A is the artist's float32 positions, frame B lies on B's mesh
    assert np.array_equal(first["co"], src_a["co"])
    assert mesh_distance(last["co"], src_b["co"], src_b["tris"]).max() <= 0.05 * h
    # where B's mesh holds each loop's UV, the result is near it (a coarse grid: 16 cells)
    assert np.mean(sc.uv_agreement(last, src_b) <= 0.03) >= 0.9
    # the artist's sharp edges and seams, edge by edge (the same vertices, edges made anew)
    for prop in ("use_edge_sharp", "use_seam"):
        got, want = _flagged_edges(obj.data, prop), _flagged_edges(a.data, prop)
        assert got == want and len(want) > 0, prop


def _flagged_edges(mesh, prop):
    """The vertex pairs of ``mesh``'s edges whose flag ``prop`` is set."""
    flags = np.empty(len(mesh.edges), bool)
    mesh.edges.foreach_get(prop, flags)
    ev = np.empty(2 * len(mesh.edges), np.int32)
    mesh.edges.foreach_get("vertices", ev)
    return {tuple(sorted(e)) for e in ev.reshape(-1, 2)[flags].tolist()}


def test_render_on_the_first_keyframe_equals_the_original(scene):
    a, b = sc.build(scene, resolution=12)
    obj = sc.bake(scene, "SHAPE_KEYS")
    tmp = bpy.app.tempdir
    a.hide_render = b.hide_render = True
    result = sc.render(scene, sc.FRAMES[0], os.path.join(tmp, "kfi_result.png"), size=96)
    obj.hide_render, a.hide_render = True, False
    original = sc.render(scene, sc.FRAMES[0], os.path.join(tmp, "kfi_original.png"), size=96)
    assert (original[..., 3] > 0.5).mean() > 0.05  # the head is in the picture
    assert np.abs(result - original)[..., :3].mean() <= 0.01


def test_mesh_sequence_keyframe_frames_are_the_artists_meshes(scene):
    a, b = sc.build(scene, resolution=12)
    obj = sc.bake(scene, "MESH_SEQUENCE")
    for f, key in zip(sc.FRAMES, (a, b)):
        out, src = sc.evaluated(obj, f), sc.evaluated(key, f)
        if key == a:  # the artist's float32 positions; B's went through its object transform
            assert np.array_equal(out["co"], src["co"])
        np.testing.assert_allclose(out["co"], src["co"], atol=1e-6)
        np.testing.assert_array_equal(out["lv"], src["lv"])
        np.testing.assert_array_equal(out["uv"], src["uv"])
        np.testing.assert_array_equal(out["material"], src["material"])
    assert sc.evaluated(obj, sc.FRAMES[0])["names"] == ["Checker Red", "Checker Blue"]


def test_mesh_sequence_in_betweens_get_uvs_and_materials(scene):
    """The mesh sequence's first frames are the artist's mesh, tracked, with its UVs; the
    later ones (at 10 cells the grid's material changes topology) their own surfaces, with
    UVs and materials transferred, but for those just before keyframe B, which may be B's
    own mesh (Suzanne posed: the same polygons and UVs) tracked back."""
    a, b = sc.build(scene, resolution=10)
    obj = sc.bake(scene, "MESH_SEQUENCE")
    first = sc.evaluated(obj, sc.FRAMES[0])
    tracked = []
    for f in range(sc.FRAMES[0] + 1, sc.FRAMES[1]):
        out = sc.evaluated(obj, f)
        tracked.append(len(out["co"]) == len(a.data.vertices))
        if tracked[-1]:
            np.testing.assert_array_equal(out["uv"], first["uv"])
        uv = out["uv"][out["tri_loops"]]
        assert np.abs(uv).sum() > 0
        span = np.ptp(uv, axis=1).max(axis=1)
        assert span.max() < 0.5  # no triangle spans a seam (Suzanne's islands lie apart)
        assert set(np.unique(out["material"])) == {0, 1}
    own = tracked.index(False)
    assert own > 0 and tracked[own:] == sorted(tracked[own:])


def test_mesh_sequence_after_a_merge_shows_the_next_keyframes_mesh(scene, kfi):
    """Two balls merge by frame 9 into the ball the artist modelled there (its own
    material), which then moves to frame 15: the frames after frame 9 play that ball's
    mesh tracked, its polygons, UVs and material, not each frame's own surface."""
    kfi.add_sphere("Left", (-0.9, 0, 0), 0.6)
    kfi.add_sphere("Right", (0.9, 0, 0), 0.6)
    bpy.context.view_layer.objects.active = bpy.data.objects["Left"]
    bpy.data.objects["Left"].select_set(True)
    bpy.data.objects["Right"].select_set(True)
    assert bpy.ops.object.join() == {"FINISHED"}
    scene.frame_set(1)
    assert bpy.ops.keyframe_implicit.add_keyframe() == {"FINISHED"}
    blue = bpy.data.materials.new("Blue")
    radius = 0.6 * 2 ** (1 / 3)
    for name, x, frame in (("Ball", 0.0, 9), ("Ball Moved", 1.2, 15)):
        ball = kfi.add_sphere(name, (x, 0, 0), radius)
        ball.data.materials.append(blue)
        scene.frame_set(frame)
        assert bpy.ops.keyframe_implicit.add_keyframe() == {"FINISHED"}
    cross = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]]) * 0.3
    pairs = [(c + [sx * 0.9, 0, 0], c + [sx * 0.32, 0, 0], 0) for c in cross for sx in (-1, 1)]
    pairs += [(a, b, 1) for a, b in zip(kfi.sphere_points((0, 0, 0), radius),
                                         kfi.sphere_points((1.2, 0, 0), radius))]
    for a, b, seg in pairs:
        assert bpy.ops.keyframe_implicit.add_feature_pair(
            segment=seg, location_a=tuple(a), location_b=tuple(b)) == {"FINISHED"}
    scene.keyframe_implicit.output_mode = "MESH_SEQUENCE"
    assert bpy.ops.keyframe_implicit.bake(resolution=20) == {"FINISHED"}
    obj = scene.keyframe_implicit.output_object
    ball = sc.evaluated(bpy.data.objects["Ball"], 9)
    shows_ball = []
    for f in range(10, 15):
        out = sc.evaluated(obj, f)
        shows_ball.append(len(out["co"]) == len(ball["co"])
                          and np.array_equal(out["lv"], ball["lv"]))
        if shows_ball[-1]:
            np.testing.assert_array_equal(out["uv"], ball["uv"])
            assert {out["names"][i] for i in np.unique(out["material"])} == {"Blue"}
    assert sum(shows_ball) >= 3 and shows_ball == sorted(shows_ball, reverse=True)
