"""The example scenes in assets/: they open, are set up for the add-on, match their script, bake."""

import importlib.util
import os

import bpy
import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ASSETS = os.path.join(ROOT, "assets")
SCENES = ("rigid", "merge", "bend", "splash", "suzanne")
BAKE_RESOLUTION = 16


def _make_assets():
    spec = importlib.util.spec_from_file_location("kfi_make_assets",
                                                  os.path.join(ASSETS, "make_assets.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _open(name):
    import keyframe_implicit

    path = os.path.join(ASSETS, f"{name}.blend")
    assert os.path.exists(path), f"{path} missing: run python assets/make_assets.py"
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    if not hasattr(bpy.types.Scene, "keyframe_implicit"):
        keyframe_implicit.register()
    return bpy.context.scene


def _world_vertices(obj):
    co = np.empty(len(obj.data.vertices) * 3)
    obj.data.vertices.foreach_get("co", co)
    m = np.array(obj.matrix_world)
    return co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]


def _pairs(scene):
    """pair id -> {"A": empty, "B": empty}, and pair id -> segment."""
    pairs, segs = {}, {}
    for obj in scene.objects:
        if obj.type == "EMPTY" and "kfi_pair" in obj.keys():
            pid = str(obj["kfi_pair"])
            side = str(obj["kfi_side"])
            assert side in ("A", "B"), (obj.name, side)
            assert side not in pairs.setdefault(pid, {}), f"two {side} sides for pair {pid}"
            pairs[pid][side] = obj
            segs.setdefault(pid, int(obj["kfi_segment"]))
            assert segs[pid] == int(obj["kfi_segment"]), f"pair {pid} spans two segments"
    return pairs, segs


def test_asset_folder_is_small():
    total = sum(os.path.getsize(os.path.join(ASSETS, f)) for f in os.listdir(ASSETS))
    assert total < 5 * 1024 * 1024, f"assets/ is {total / 1e6:.1f} MB; keep it a few MB"


@pytest.mark.parametrize("name", SCENES)
def test_asset_is_set_up_for_the_add_on(name):
    scene = _open(name)
    keys = scene.keyframe_implicit.keyframes
    assert len(keys) >= 2
    frames = [k.frame for k in keys]
    assert all(b > a for a, b in zip(frames, frames[1:])), frames
    assert (scene.frame_start, scene.frame_end) == (frames[0], frames[-1])
    objs = [k.object for k in keys]
    assert all(o is not None and o.type == "MESH" and len(o.data.polygons) > 100 for o in objs)
    assert objs[0].active_material is not None, "keyframe A carries the material the bake copies"
    assert scene.camera is not None

    pairs, segs = _pairs(scene)
    for seg in range(len(keys) - 1):
        ids = [p for p, s in segs.items() if s == seg]
        assert len(ids) >= 4, f"segment {seg} has {len(ids)} pairs"
        for pid in ids:
            assert set(pairs[pid]) == {"A", "B"}, f"pair {pid} is missing a side"
            a, b = pairs[pid]["A"], pairs[pid]["B"]
            assert a.parent == objs[seg] and b.parent == objs[seg + 1], pid
            # each Empty sits on or inside its keyframe's bounding box (not at the origin by mistake)
            for empty, obj in ((a, objs[seg]), (b, objs[seg + 1])):
                v = _world_vertices(obj)
                p = np.array(empty.matrix_world.translation)
                assert np.all(p >= v.min(0) - 0.05) and np.all(p <= v.max(0) + 0.05), (pid, p)
    assert not [p for p, s in segs.items() if s >= len(keys) - 1], "pair on a segment that does not exist"


@pytest.mark.parametrize("name", SCENES)
def test_asset_matches_its_script(name):
    """assets/NAME.blend is what assets/make_assets.py builds now (rebuild after changing it)."""
    scene = _open(name)
    saved_v = [_world_vertices(k.object) for k in scene.keyframe_implicit.keyframes]
    saved_p = sorted((str(o["kfi_pair"]), str(o["kfi_side"]), tuple(np.round(o.matrix_world.translation, 4)))
                     for o in scene.objects if "kfi_pair" in o.keys())
    _make_assets().build(name)
    scene = bpy.context.scene
    built_v = [_world_vertices(k.object) for k in scene.keyframe_implicit.keyframes]
    built_p = sorted((str(o["kfi_pair"]), str(o["kfi_side"]), tuple(np.round(o.matrix_world.translation, 4)))
                     for o in scene.objects if "kfi_pair" in o.keys())
    assert len(saved_v) == len(built_v)
    for a, b in zip(saved_v, built_v):
        assert a.shape == b.shape and np.allclose(a, b, atol=1e-5)
    assert saved_p == built_p


@pytest.mark.heavy
@pytest.mark.parametrize("name", SCENES)
def test_asset_bakes_at_low_resolution(name):
    """The Auto output of every example: one frame per timeline frame, a report naming
    the output and its worst frame, and on every keyframe's frame the surface
    Blender evaluates lies on the modelled keyframe within the limits of a clean result
    (two-way distance 0.1 h mean, 1 h max), even on this coarse grid: a keyframe's
    frame is the keyframe's own mesh, or the artist's mesh landed on it."""
    from keyframe_implicit.core.surface.quality import LIMITS, keyframe_distance

    scene = _open(name)
    keys = scene.keyframe_implicit.keyframes
    objs = [k.object for k in keys]
    frames = [k.frame for k in keys]
    result = bpy.ops.keyframe_implicit.bake(resolution=BAKE_RESOLUTION)
    assert "FINISHED" in result
    out = scene.keyframe_implicit.output_object
    assert out is not None and out not in objs
    assert out["kfi_output_kind"] in ("shape_keys", "mesh_sequence")
    label = "Shape keys" if out["kfi_output_kind"] == "shape_keys" else "Mesh sequence"
    report = out["kfi_report"]  # one line: what was made, on which frames, why
    assert report.startswith(f"{label}, frames {frames[0]}-{frames[-1]}: ") and "\n" not in report
    assert " h " not in report and "limits" not in report and len(report) < 160, report
    details = out["kfi_report_details"].splitlines()  # the figures, each in words
    assert details[0].startswith(("Shape keys: ", "Mesh sequence: ")), details
    assert len(details) >= 4 and not any(line.endswith(" h") or " h " in line for line in details)
    if out["kfi_output_kind"] == "shape_keys":
        blocks = out.data.shape_keys.key_blocks
        assert len(blocks) == 1 + frames[-1] - frames[0] + 1  # Basis + one per frame
    h = float(out["kfi_stats"]["spacing"])
    dg = bpy.context.evaluated_depsgraph_get()
    for obj, f in zip(objs, frames):
        scene.frame_set(f)
        ev = out.evaluated_get(dg)
        m = ev.to_mesh()
        try:
            m.calc_loop_triangles()
            co = np.empty(len(m.vertices) * 3)
            m.vertices.foreach_get("co", co)
            tri = np.empty(len(m.loop_triangles) * 3, np.int64)
            m.loop_triangles.foreach_get("vertices", tri)
        finally:
            ev.to_mesh_clear()
        mw = np.array(out.matrix_world)
        co = co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
        ref = obj.data
        ref.calc_loop_triangles()
        rtri = np.empty(len(ref.loop_triangles) * 3, np.int64)
        ref.loop_triangles.foreach_get("vertices", rtri)
        d = keyframe_distance(co, tri.reshape(-1, 3), _world_vertices(obj), rtri.reshape(-1, 3), h)
        assert d["keyframe_mean"] <= LIMITS["keyframe_mean"], (f, d)
        assert d["keyframe_max"] <= LIMITS["keyframe_max"], (f, d)


@pytest.mark.parametrize("name", SCENES)
def test_asset_was_saved_by_the_oldest_supported_blender(name):
    """Blender 5.0 writes a file header 4.x cannot read ("not a blend file"), while newer
    versions read older files: the assets must be saved by 4.2 (see assets/make_assets.py)."""
    bpy.ops.wm.open_mainfile(filepath=os.path.join(ASSETS, f"{name}.blend"))
    assert tuple(bpy.data.version[:2]) == (4, 2), (
        f"{name}.blend was saved by Blender {bpy.data.version}; regenerate it with bpy 4.2")


@pytest.mark.parametrize("name", SCENES)
def test_asset_opens_tidy_on_its_first_keyframe(name):
    """One shape in view on the first frame, not every keyframe on top of each other; small
    feature Empties without a label each; the scene's frames are the keyframes' range."""
    scene = _open(name)
    keys = scene.keyframe_implicit.keyframes
    objs = [k.object for k in keys]
    assert scene.frame_current == keys[0].frame == scene.frame_start
    assert scene.frame_end == keys[-1].frame
    assert objs[0].visible_get() and not any(o.visible_get() for o in objs[1:])
    pairs, _ = _pairs(scene)
    empties = [e for sides in pairs.values() for e in sides.values()]
    assert empties and not any(e.show_name for e in empties)
    assert all(e.visible_get() == (e.parent == objs[0]) for e in empties)
    size = max(objs[0].dimensions)
    assert all(e.empty_display_size <= 0.03 * max(e.parent.dimensions) for e in empties), size


@pytest.mark.parametrize("name", SCENES)
def test_asset_timeline_shows_the_scene_range(name):
    """The file's timelines open framed on the scene's frames, not the factory 0-250."""
    path = os.path.join(ASSETS, f"{name}.blend")
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=True)
    scene = bpy.context.scene
    views = []
    for area in bpy.context.screen.areas:
        if area.type == "DOPESHEET_EDITOR":
            region = next(r for r in area.regions if r.type == "WINDOW")
            views.append((region.view2d.region_to_view(0, 0)[0],
                          region.view2d.region_to_view(region.width, 0)[0]))
    assert views, "the file's layout has no timeline"
    for first, last in views:
        assert scene.frame_start - 2 <= first <= scene.frame_start
        assert scene.frame_end <= last <= scene.frame_end + 2
