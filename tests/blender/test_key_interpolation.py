"""Each keyframe's Interpolation (Smooth, Linear, Ease): stored per keyframe, read by the
bake and passed to the core, shown in the keyframe list."""

import bpy
import numpy as np

from keyframe_implicit.blender import bake

THREE = [("K0", (0.0, 0.0, 0.0), 1.0, 1), ("K1", (1.2, 0.0, 1.2), 1.0, 7),
         ("K2", (2.4, 0.0, 0.0), 1.0, 13)]


def _read(scene, kfi):
    return bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES)


def test_the_interpolation_is_stored_per_keyframe_and_read_by_the_bake(scene, kfi):
    kfi.build_spheres(THREE)
    items = scene.keyframe_implicit.keyframes
    assert [kf.interpolation for kf in items] == ["SMOOTH"] * 3
    items[1].interpolation = "EASE"
    items[2].interpolation = "LINEAR"
    assert [kf.interpolation for kf in items] == ["SMOOTH", "EASE", "LINEAR"]
    inputs = _read(scene, kfi)
    assert inputs.key_interpolation == ["smooth", "ease", "linear"]
    assert inputs.core_arguments()["options"].key_interpolation == ["smooth", "ease", "linear"]


def _step_at_the_middle_keyframe(scene, kfi, kind):
    """The baked mesh's centre: its step into the middle keyframe's frame over its mean step."""
    scene.keyframe_implicit.keyframes[1].interpolation = kind
    job = bake.BakeJob(_read(scene, kfi))
    job.run()
    assert job.state == bake.DONE, job.error_message()
    centre = np.asarray(job.result.vertices, dtype=float).mean(axis=1)
    steps = np.linalg.norm(np.diff(centre, axis=0), axis=1)
    return steps[5] / steps.mean()  # frame 6 -> 7


def test_an_eased_keyframe_is_where_the_baked_motion_slows_down(scene, kfi):
    kfi.build_spheres(THREE)
    linear = _step_at_the_middle_keyframe(scene, kfi, "LINEAR")
    eased = _step_at_the_middle_keyframe(scene, kfi, "EASE")
    assert linear > 0.9 and eased < 0.6, (linear, eased)


def test_the_list_shows_each_keyframes_interpolation(scene, kfi):
    from test_panel import draw_all, list_rows

    kfi.build_spheres(THREE, pairs=False)
    scene.keyframe_implicit.keyframes[1].interpolation = "EASE"
    rows = list_rows(draw_all(bpy.context))
    shown = [[e[2] for e in row if e[0] == "drawn"][-1] for row in rows]
    assert shown == ["SMOOTH", "EASE", "SMOOTH"]
    assert all(("prop", "interpolation") in row for row in rows)


def test_surface_tension_is_stored_per_segment_and_shown_under_the_list(scene, kfi):
    from test_panel import draw_all

    kfi.build_spheres(THREE, pairs=False)
    settings = scene.keyframe_implicit
    items = settings.keyframes
    items[1].surface_tension = 0.0  # the second segment as clay
    inputs = _read(scene, kfi)
    assert inputs.surface_tension == [1.0, 0.0]  # one per segment: the last keyframe starts none
    options = inputs.core_arguments()["options"]
    assert [m.surface_tension for m in options.segment_motion(2)] == [1.0, 0.0]
    for index, shown in ((0, True), (1, True), (2, False)):
        settings.active_keyframe_index = index
        log = draw_all(bpy.context)
        after_list = log[[e[0] for e in log].index("template_list"):]
        assert (("prop", "surface_tension") in after_list) == shown, index
        assert ("prop", "interpolation") in after_list
