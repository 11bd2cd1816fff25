"""What the panel and the bake say, in an artist's words: one line per kind of problem with
advice that fits the situation, the first problems and Bake in view, a one-line report after
the bake with its figures behind a disclosure, and a Bake tooltip that says what Auto does."""

import bpy

from keyframe_implicit.blender import ops, output, panel, validate
from test_panel import Layout

PLANE_MIDDLE = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 25)]


def _plane_as_middle_keyframe(kfi):
    kfi.build_spheres(PLANE_MIDDLE)  # 4 feature pairs between KeyA and KeyB
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.7, 3.0, 0.0))
    bpy.context.active_object.name = "Plane"
    assert bpy.ops.keyframe_implicit.add_keyframe(frame=12) == {"FINISHED"}


def test_a_plane_added_in_the_middle_gets_its_error_and_pairs_proposed_on_it(scene, kfi):
    _plane_as_middle_keyframe(kfi)
    found = [p.message for p in validate.problems(scene)]
    # the real problem alone: the 4 pairs through the plane became 8, meeting on it
    assert len(found) == 1 and found[0].startswith("Keyframe 2 'Plane' is open"), found
    assert len(bpy.data.objects["Plane"].children) == 8


def test_empties_left_on_another_keyframe_by_a_move_are_one_error_with_advice(scene, kfi):
    kfi.build_spheres(PLANE_MIDDLE)
    kfi.add_sphere("KeyC", (3.0, 0.0, 0.0))
    assert bpy.ops.keyframe_implicit.add_keyframe(frame=30) == {"FINISHED"}
    assert bpy.ops.keyframe_implicit.move_keyframe(index=2, direction="UP") == {"FINISHED"}
    [line] = [p for p in validate.problems(scene) if "Empties" in p.message]
    assert line.message == ("4 feature Empties of keyframes 1 \u2192 2 are on keyframe 3 'KeyB', not "
                            "on keyframe 2 'KeyC': the keyframe list changed since they were "
                            "placed. Move them onto 'KeyC' and parent them to it, or remove those "
                            "pairs.")
    assert line.severity == validate.ERROR and line.icon == "ERROR"  # they guide the wrong keyframes


def test_unparented_empties_are_counted_and_told_to_parent_to_their_keyframe(scene, kfi):
    kfi.build_spheres(PLANE_MIDDLE)
    for obj in [o for o in scene.objects if o.name.endswith(" B")][:3]:
        world = obj.matrix_world.copy()
        obj.parent = None
        obj.matrix_world = world
    [line] = [p.message for p in validate.problems(scene) if "parent" in p.message]
    assert line.startswith("3 feature Empties of keyframes 1 \u2192 2 are not parented to "
                           "keyframe 2 'KeyB'"), line
    assert line.endswith("parent them to it (Ctrl+P > Keep Transform).")


def test_unparented_empties_of_several_segments_are_one_counted_line(scene, kfi):
    kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (3, 0, 0), 1, 5), ("C", (6, 0, 0), 1, 9)])
    for name in ("KFI 0.0 A", "KFI 0.1 B", "KFI 1.0 A", "KFI 1.2 B", "KFI 1.3 B"):
        obj = bpy.data.objects[name]
        world = obj.matrix_world.copy()
        obj.parent = None
        obj.matrix_world = world
    found = validate.problems(scene)
    assert [(p.severity, p.message) for p in found] == [
        (validate.WARNING, "5 feature Empties of 2 segments are not parented to their keyframes: "
                           "they do not follow those objects; parent each to its keyframe (Ctrl+P "
                           "> Keep Transform).")]


def _drawn_main(context):
    log = []
    fake = type("PanelSelf", (), {"layout": Layout(log)})()
    panel.KFI_PT_main.draw(fake, context)
    return log


def test_the_first_problems_stay_in_view_and_the_rest_fold(scene, kfi):
    _plane_as_middle_keyframe(kfi)
    scene.frame_end = 10  # one more problem: keyframes past the scene's end
    found = validate.problems(scene)
    assert len(found) > panel.SHOWN_PROBLEMS
    log = _drawn_main(bpy.context)
    text = " ".join(e[1] for e in log if e[0] == "label")
    assert [p.message in text for p in found] == [True, True, False], found
    folded = [e for e in log if e[0] == "drawn" and e[1] == f"{len(found) - panel.SHOWN_PROBLEMS} more"]
    assert folded, log
    bake_at = log.index(("operator", "keyframe_implicit.bake"))
    first_problem = next(i for i, e in enumerate(log) if e[0] == "label" and "is open" in e[1])
    labels_before_bake = sum(1 for e in log[:bake_at] if e[0] == "label")
    assert first_problem < bake_at and labels_before_bake <= 14, labels_before_bake
    scene.keyframe_implicit.show_all_problems = True
    text = " ".join(e[1] for e in _drawn_main(bpy.context) if e[0] == "label")
    assert all(p.message.split()[0] in text for p in found)


def test_the_report_is_one_line_and_its_figures_are_explained(scene, kfi):
    frames = [1, 2, 3]
    assert output.bake_report("mesh_sequence", "one mesh cannot follow the shape at frame 2",
                              frames) == ("Mesh sequence, frames 1-3: one mesh cannot follow the "
                                          "shape at frame 2.")
    q = dict(area_ratio=0.907, inverted_fraction=0.207, coverage=1.0, keyframe_mean=0.0,
             keyframe_max=0.0)
    ok = dict(q, area_ratio=1.0, inverted_fraction=0.0)
    quality = {"shape_keys": [ok, q, ok], "mesh_sequence": [ok, ok, ok]}
    lines = output.report_details("mesh_sequence", frames, {"quality": quality})
    # why not shape keys, then the mesh sequence's own figures: no contradiction
    assert lines[0] == ("Shape keys: worst frame 2 (past the limits: surface area 0.907 times "
                        "the shape's own, 20.7 % of the surface facing inward)")
    assert lines[1].startswith("Surface area: 0.907 times the shape's own")
    assert lines[2].startswith("Surface facing inward: 20.7 %")
    assert lines[4].startswith("Off the keyframe's own mesh: 0.00 cells on average, 0.00 at most")
    assert lines[5].startswith("Mesh sequence: least clean frame ") and "within the limits" in lines[5]
    clean = output.report_details("shape_keys", frames, {"quality": {"shape_keys": [ok, ok, ok]}})
    assert len(clean) == 5 and clean[0].startswith("Shape keys: least clean frame ")


def test_the_bake_after_baking_says_what_was_made_and_keeps_the_figures(scene, kfi):
    kfi.build_spheres([("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 5)])
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    out = scene.keyframe_implicit.output_object
    assert out["kfi_report"].startswith(("Shape keys, frames 1-5: ", "Mesh sequence, frames 1-5: "))
    log = _drawn_main(bpy.context)
    assert ("prop", "show_report_details") in log
    shown = " ".join(e[1] for e in log if e[0] == "label")
    assert "Surface area" not in shown  # folded until asked for
    scene.keyframe_implicit.show_report_details = True
    shown = " ".join(e[1] for e in _drawn_main(bpy.context) if e[0] == "label")
    assert "Surface area:" in shown and "Shape covered by the mesh:" in shown
    # the grids the figures are measured on, read from the output (its one figures property)
    assert f"Grid: resolution {kfi.RES}, a cell {out['kfi_stats']['spacing']:.3g} across" in shown


def test_bake_tooltip_says_what_auto_makes():
    tip = ops.KFI_OT_bake.__doc__
    assert "shape keys" in tip and "mesh sequence" in tip and "Auto" in tip


def test_every_fix_the_core_asks_for_has_its_menu_path():
    from keyframe_implicit.core.bake.checks import FIXES

    assert set(validate.MENU_PATHS) == set(FIXES)
    for fix in FIXES:
        assert validate.with_menu_paths(f"x: {fix}.") == f"x: {fix} ({validate.MENU_PATHS[fix]})."
