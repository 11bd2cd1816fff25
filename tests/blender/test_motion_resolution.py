"""The Motion Resolution setting: stored in the scene, read by the bake, checked by the panel
as the core checks it, shown under Advanced."""

import bpy
import pytest

from keyframe_implicit.blender import bake, panel, scene_io, validate

TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]


def test_automatic_by_default_and_read_by_the_bake(scene, kfi):
    kfi.build_spheres(TWO)
    settings = scene.keyframe_implicit
    assert settings.motion_resolution == 0 and settings.motion() is None
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert bake.collect(scene, depsgraph, kfi.RES).core_arguments()[
        "options"].motion_resolution is None
    settings.motion_resolution = 12
    inputs = bake.collect(scene, depsgraph, kfi.RES)
    assert inputs.motion_resolution == 12
    assert inputs.core_arguments()["options"].motion_resolution == 12


def test_a_bake_on_a_motion_grid_uses_it(scene, kfi):
    kfi.build_spheres(TWO)
    scene.keyframe_implicit.motion_resolution = 10
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
    job.run()
    assert job.state == bake.DONE, job.error_message()
    stats = job.result.stats
    assert stats["motion_resolution"] == 10
    assert max(stats["motion_grid_shape"]) < max(stats["grid_shape"])


@pytest.mark.parametrize("value, words", [(4, "below 8"), (41, "above the Resolution 40")])
def test_the_panel_refuses_what_the_core_refuses(scene, kfi, value, words):
    kfi.build_spheres(TWO)
    settings = scene.keyframe_implicit
    settings.resolution = 40
    settings.motion_resolution = value
    errors = [p.message for p in validate.problems(scene) if p.severity == validate.ERROR]
    assert any(words in m and "0: automatic" in m for m in errors), errors
    settings.motion_resolution = 0
    assert not [p for p in validate.problems(scene) if "Motion Resolution" in p.message]


def test_shown_under_advanced(scene, kfi):
    kfi.build_spheres(TWO)
    drawn = []

    class Layout:  # records what the panel draws
        def __getattr__(self, name):
            return lambda *a, **k: (drawn.append((name, a)), Layout())[1]

    fake = type("P", (), {"layout": Layout()})()
    panel.KFI_PT_advanced.draw(fake, bpy.context)
    assert ("prop", (scene.keyframe_implicit, "motion_auto")) in drawn  # Auto, not "0"
    scene.keyframe_implicit.motion_resolution = 12
    drawn.clear()
    panel.KFI_PT_advanced.draw(fake, bpy.context)
    assert ("prop", (scene.keyframe_implicit, "motion_resolution")) in drawn
    assert scene_io.BakeInput.__dataclass_fields__["motion_resolution"].default is None
