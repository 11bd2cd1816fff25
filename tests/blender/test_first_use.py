"""What a new user meets: the state after a bake, undo, the list, wrapped messages, the
pre-bake surface checks and the redo panels (issue 16)."""

import types

import bmesh
import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import bake, ops, panel, result_view, scene_io, validate

TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]


def _state(scene):
    """Everything the bake changes outside its own data-blocks, by object name."""
    vl = bpy.context.view_layer
    return {
        "objects": sorted(o.name for o in bpy.data.objects),
        "selected": sorted(o.name for o in vl.objects if o.select_get()),
        "active": vl.objects.active.name if vl.objects.active else None,
        "hidden": sorted(o.name for o in vl.objects if o.hide_get()),
        "no_render": sorted(o.name for o in scene.objects if o.hide_render),
        "display": {o.name: o.display_type for o in scene.objects},
        "range": (scene.frame_start, scene.frame_end),
    }


def test_bake_selects_result_hides_keyframes_covers_range_and_undo_restores(scene, kfi):
    a, b = kfi.build_spheres(TWO)
    scene.frame_end = 5  # keyframe B (frame 7) lies outside: warned, then covered by the bake
    assert any(p.severity == validate.WARNING and "Keyframe 2 is on frame 7, outside the scene's "
               "frames 1-5" in p.message for p in validate.problems(scene))
    bpy.ops.ed.undo_push(message="set up")
    before = _state(scene)
    assert before["active"] == "KeyB" and not before["hidden"]

    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    # the step the UI pushes after an UNDO operator (bpy.ops in background mode pushes none)
    bpy.ops.ed.undo_push(message="Bake")
    out = scene.keyframe_implicit.output_object
    vl = bpy.context.view_layer
    assert bpy.context.selected_objects == [out] and vl.objects.active == out
    empties = [o for o in scene.objects if o.type == "EMPTY"]
    assert len(empties) == 8
    for obj in (a, b, *empties):
        assert obj.hide_get(), obj.name  # hidden in the viewport ...
    assert a.hide_render and b.hide_render  # ... and in renders
    assert not out.hide_get() and not out.hide_render
    assert (scene.frame_start, scene.frame_end) == (1, 7)
    assert not [p for p in validate.problems(scene) if "outside" in p.message]

    # the panel's toggle: wireframe overlays for comparison, never in renders; and back
    scene.keyframe_implicit.show_keyframes = True
    assert not a.hide_get() and a.display_type == "WIRE" and a.hide_render
    assert empties[0].hide_get()  # their names would cover the result
    scene.keyframe_implicit.show_keyframes = False
    assert a.hide_get() and a.display_type == "TEXTURED"

    bpy.ops.ed.undo_push(message="Show Keyframes")
    assert bpy.ops.ed.undo() == {"FINISHED"}
    assert bpy.ops.ed.undo() == {"FINISHED"}
    scene = bpy.context.scene  # undo reloads the data: old references are stale
    assert _state(scene) == before
    assert scene.keyframe_implicit.output_object is None


def test_rebake_with_hidden_keyframes_reads_the_same_shapes(scene, kfi):
    a, _ = kfi.build_spheres(TWO)
    a.modifiers.new("Subdivision", "SUBSURF").levels = 1  # only the evaluated mesh has these
    first = bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    assert a.hide_get()
    again = bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES)
    for k0, k1 in zip(first.keyframes, again.keyframes):
        np.testing.assert_array_equal(k0.vertices, k1.vertices)
        np.testing.assert_array_equal(k0.faces, k1.faces)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}


def test_differing_materials_go_into_slots_and_the_report_says_so(scene, kfi):
    a, b = kfi.build_spheres(TWO)
    skin, ice = bpy.data.materials.new("Skin"), bpy.data.materials.new("Ice")
    a.data.materials.append(skin)
    b.data.materials.append(ice)
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    out = scene.keyframe_implicit.output_object
    assert list(out.data.materials) == [skin, ice]
    notes = result_view.present(scene, bpy.context.view_layer, scene.keyframe_implicit, out)
    assert any("'Skin'" in n and "'Ice'" in n and "slots" in n for n in notes)


# -- the keyframe list -----------------------------------------------------------------

def test_list_rows_show_names_first_and_compact_frames(scene, kfi):
    from test_panel import draw_all, list_rows

    kfi.build_spheres([("merge_A", (0, 0, 0), 1, 1), ("merge_B", (3, 0, 0), 1, 40)], pairs=False)
    rows = list_rows(draw_all(bpy.context))
    assert len(rows) == 2
    for row, (name, frame) in zip(rows, (("merge_A", "1"), ("merge_B", "40"))):
        drawn = [e for e in row if e[0] == "drawn"]
        # name first, then the frame number and the interpolation's icon alone: no
        # "Object"/"Frame" captions, no index label
        assert drawn == [("drawn", "", name), ("drawn", "", frame),
                         ("drawn", "", "SMOOTH")], row
        assert not [e for e in row if e[0] == "label"], row
        factor = next(e[1] for e in row if e[0] == "split")
        assert factor >= 0.6  # the name gets most of the row
        # the object's name, not its pointer field, whose clear button reads as "remove"
        assert ("prop", "object") not in row and ("prop", "name") in row, row


def test_list_names_fit_at_the_default_sidebar_width(scene):
    # 291 px sidebar: panel margins and the +/- column leave ~230 px for a row; the name field
    # (minus its icon and padding) must hold a name like merge_A; the old 3-column row did not
    row = 291 - 2 * 10 - 40 - panel.ICON_WIDTH  # the interpolation's icon at the row's end
    name_field = panel.KFI_UL_keyframes.NAME_SHARE * row - panel.ICON_WIDTH - 10
    assert panel.text_width("merge_A", 1.0) < name_field
    # and the frame field holds a five-digit frame number
    frame_field = (1.0 - panel.KFI_UL_keyframes.NAME_SHARE) * row - 10
    assert panel.text_width("10000", 1.0) < frame_field


# -- wrapping --------------------------------------------------------------------------

MESSAGE = ("Feature 'KFI 0.3 A' has no partner: delete it, or select it with another Empty "
           "and press Pair Selected.")


def _context(width, scale=1.0):
    prefs = types.SimpleNamespace(system=types.SimpleNamespace(ui_scale=scale))
    return types.SimpleNamespace(region=types.SimpleNamespace(width=width), preferences=prefs)


@pytest.mark.parametrize("width", [200, 290, 500])
def test_messages_wrap_to_the_region_width(scene, width):
    ctx = _context(width)
    room = panel.label_width(ctx)
    assert room < width
    lines = panel.wrap(MESSAGE, room)
    assert " ".join(lines) == MESSAGE  # nothing cut, nothing lost
    for i, line in enumerate(lines):
        assert panel.text_width(line, 1.0) <= room, line
        if i + 1 < len(lines):  # greedy: the next word would not have fitted
            nxt = lines[i + 1].split()[0]
            assert panel.text_width(f"{line} {nxt}", 1.0) > room


def test_wrapping_follows_width_and_ui_scale(scene):
    counts = [len(panel.wrap(MESSAGE, panel.label_width(_context(w)))) for w in (200, 290, 500)]
    assert counts[0] > counts[1] > counts[2] >= 1
    assert counts[2] <= 2
    # the same region at UI scale 2 holds half the text per line: more lines
    big = _context(290 * 2, 2.0)
    assert len(panel.wrap(MESSAGE, panel.label_width(big), 2.0)) == counts[1]
    assert panel.text_width("WWWW", 1.0) > panel.text_width("iiii", 1.0)  # measured, not counted


# -- pre-bake surface checks -------------------------------------------------------------

def _mesh_object(name, verts, faces):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _keyframe(obj, frame):
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.keyframe_implicit.add_keyframe(frame=frame) == {"FINISHED"}


def test_open_plane_is_refused_before_any_work(scene, kfi, monkeypatch):
    kfi.add_sphere("Ball", (0, 0, 0))
    _keyframe(bpy.context.active_object, 1)
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(3, 0, 0))
    plane = bpy.context.active_object
    plane.name = "Plane"
    _keyframe(plane, 40)
    scene.frame_end = 30
    calls = []  # no worker process is started: the refusal comes before any work
    monkeypatch.setattr(bake, "Worker", lambda *a, **k: calls.append(1))
    state = kfi.snapshot()
    with pytest.raises(RuntimeError) as err:
        bpy.ops.keyframe_implicit.bake(resolution=kfi.RES)
    msg = str(err.value)
    # numbered as the list shows it, with what to do; nothing from the grid
    assert "Keyframe 2 'Plane' is open (4 open edges) and encloses no volume: close its holes " \
           "(Mesh > Clean Up > Fill Holes), or give it thickness (Solidify modifier)." in msg
    assert ".;" not in msg and "grid" not in msg and "resolution" not in msg
    assert not calls
    assert kfi.snapshot() == state
    found = validate.problems(scene)
    assert any("Keyframe 2 is on frame 40, outside the scene's frames 1-30" in p.message
               for p in found)


def _mesh_check(obj, depsgraph):
    """The mesh checks of one object: its mesh read as the bake reads it, then judged."""
    return validate.mesh_problems(scene_io.read_mesh(obj, depsgraph))


def test_surface_checks_refuse_flat_and_point_out_holes_and_non_manifold(scene, kfi):
    tets = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0, -1, 0), (0, 0, -1)]
    two_tets = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3),  # share edge 0-1 with
                (0, 4, 1), (0, 1, 5), (0, 5, 4), (1, 4, 5)]  # a second tetrahedron
    bow = _mesh_object("Bow", tets, two_tets)
    pillow = _mesh_object("Pillow", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
                          [(0, 1, 2, 3), (3, 2, 1, 0)])
    ball = kfi.add_sphere("Ball", (5, 0, 0))
    holed = kfi.add_sphere("Holed", (5, 0, 0))
    bm = bmesh.new()  # delete two quads apart: holes like Suzanne's eyes, 4 open edges each
    bm.from_mesh(holed.data)
    quads = [f for f in bm.faces if len(f.verts) == 4]
    first = quads[0]
    second = next(f for f in quads if not set(f.verts) & set(first.verts))
    bmesh.ops.delete(bm, geom=[first, second], context="FACES_ONLY")
    bm.to_mesh(holed.data)
    bm.free()
    dg = bpy.context.evaluated_depsgraph_get()
    [(severity, msg)] = _mesh_check(bow, dg)
    assert severity == validate.WARNING  # the core reads it as a solid
    assert msg.startswith("is non-manifold (1 edges shared by 3") and "Non Manifold" in msg
    [(severity, msg)] = _mesh_check(holed, dg)
    assert severity == validate.WARNING and msg.startswith("has holes (8 open edges)"), msg
    [(severity, msg)] = _mesh_check(pillow, dg)
    assert severity == validate.ERROR and msg.startswith("encloses no volume (it is flat"), msg
    assert msg.endswith("give it thickness (Solidify modifier).")
    assert _mesh_check(ball, dg) == []
    _keyframe(bow, 1)
    _keyframe(pillow, 9)
    errs = [p.message for p in validate.errors(validate.problems(scene))]
    assert len(errs) == 1 and errs[0].startswith("Keyframe 2 'Pillow' encloses no volume (it is "
                                                 "flat"), errs
    with pytest.raises(RuntimeError, match=r"Cannot bake: Keyframe 2 'Pillow' encloses no volume"):
        bpy.ops.keyframe_implicit.bake()


def test_kept_surface_checks_follow_edits(scene, kfi):
    kfi.add_sphere("Ball", (0, 0, 0))
    _keyframe(bpy.context.active_object, 1)
    pillow = _mesh_object("Pillow", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0.3, 0.3, 0)],
                          [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])  # a flattened tetrahedron
    _keyframe(pillow, 9)
    flat = lambda: [p for p in validate.problems(scene) if "no volume" in p.message]  # noqa: E731
    assert flat() and flat() == flat()  # asked twice: the second answer is the kept one
    solid = pillow.modifiers.new("Solidify", "SOLIDIFY")  # a new modifier is a new question
    bpy.context.view_layer.update()
    assert not flat()
    solid.show_viewport = False
    bpy.context.view_layer.update()
    assert flat()
    pillow.modifiers.remove(solid)
    bpy.context.view_layer.update()
    assert flat()
    pillow.data.vertices[3].co.z = 1.0  # same counts: the depsgraph update handler forgets
    pillow.data.update()
    bpy.context.view_layer.update()
    assert not flat()


# -- redo panels -------------------------------------------------------------------------

def _redo_properties(cls):
    """The properties an operator's redo panel ("Adjust Last Operation") shows."""
    rna = cls.bl_rna if hasattr(cls, "bl_rna") else cls
    return {p.identifier for p in rna.properties
            if p.identifier != "rna_type" and not p.is_hidden}


def test_redo_panels_show_only_meaningful_values(scene, kfi):
    rna = {c.bl_idname: getattr(bpy.ops.keyframe_implicit, c.bl_idname.split(".")[1]).get_rna_type()
           for c in ops.classes if issubclass(c, bpy.types.Operator)}
    # the bake: no redo panel at all (it would re-run blocking), and no visible leftovers
    assert "REGISTER" not in ops.KFI_OT_bake.bl_options
    assert not _redo_properties(rna["keyframe_implicit.bake"])
    assert rna["keyframe_implicit.bake"].properties["resolution"].is_skip_save
    assert _redo_properties(rna["keyframe_implicit.add_keyframe"]) == {"object_name", "frame"}
    assert not _redo_properties(rna["keyframe_implicit.remove_keyframe"])  # an index means nothing
    assert _redo_properties(rna["keyframe_implicit.move_keyframe"]) == {"direction"}
    assert not _redo_properties(rna["keyframe_implicit.pair_selected"])

    # Add Keyframe's panel shows the object and frame it used, not "" and a sentinel
    kfi.add_sphere("Ball", (0, 0, 0))
    scene.frame_set(12)
    me = types.SimpleNamespace(object_name="", frame=1, report=lambda *a: None,
                               properties=types.SimpleNamespace(is_property_set=lambda name: False))
    assert ops.KFI_OT_add_keyframe.execute(me, bpy.context) == {"FINISHED"}
    assert (me.object_name, me.frame) == ("Ball", 12)
    # and those values are not remembered for the next Add Keyframe
    for name in ("object_name", "frame"):
        assert rna["keyframe_implicit.add_keyframe"].properties[name].is_skip_save


def test_disabled_bake_says_why(scene):
    assert not bpy.ops.keyframe_implicit.bake.poll()
    with pytest.raises(RuntimeError, match="Cannot bake: No keyframes: add at least two"):
        bpy.ops.keyframe_implicit.bake()
