"""Limits before Bake, in words and numbers: the memory a bake needs under Resolution as it
changes, Bake disabled over the limit with the same words, no silent clamp, Motion
Resolution's 0 shown as Auto, an empty scene's advice once with its button labelled, and
the README's preview grid as the panel states it."""

import pathlib
import re

import bpy
import pytest

from keyframe_implicit.blender import limits, panel, props
from keyframe_implicit.core.bake import pipeline
from keyframe_implicit.core.bake.memory import MemoryLimitError
from test_panel import Layout, OpProps

TWO = [("KeyA", (0.0, 0.0, 0.0), 1.0, 1), ("KeyB", (1.5, 0.0, 0.0), 1.0, 7)]


class _Labelled(Layout):
    """`test_panel.Layout` that also records the text an operator button shows."""

    def _child(self, kind):
        self.log.append((kind,))
        return _Labelled(self.log)

    def operator(self, idname, *, text=None, icon="NONE", **kw):
        Layout.operator(self, idname, icon=icon, **kw)
        op = getattr(bpy.types, _rna_name(idname))
        self.log.append(("button", idname, op.bl_label if text is None else text))
        return OpProps(idname)


def _rna_name(idname):
    module, name = idname.split(".")
    return f"{module.upper()}_OT_{name}"


def _drawn(cls, context=None):
    log = []
    cls.draw(type("PanelSelf", (), {"layout": _Labelled(log)})(), context or bpy.context)
    return log


def _labels(log):
    return [e[1] for e in log if e[0] == "label"]


def _under_resolution(log):
    """The label lines right after the Resolution field."""
    at = log.index(("prop", "resolution"))
    lines = []
    for entry in log[at + 2:]:
        if entry[0] == "label":
            lines.append(entry[1])
        elif entry[0] not in ("column",):
            break
    return " ".join(lines)


def test_the_memory_a_bake_needs_is_under_resolution_and_bake_waits_for_one_that_fits(scene, kfi):
    kfi.build_spheres(TWO)
    settings = scene.keyframe_implicit
    line = _under_resolution(_drawn(panel.KFI_PT_main))
    assert re.fullmatch(r"About [\d,]+ MB of [\d,]+ MB", line), line
    assert panel.text_width(line, panel.ui_scale(bpy.context)) <= panel.label_width(bpy.context)
    assert bpy.ops.keyframe_implicit.bake.poll()

    settings.resolution = 1000
    assert settings.resolution == 1000, "the resolution was clamped without a word"
    line = _under_resolution(_drawn(panel.KFI_PT_main))
    found = re.fullmatch(r"Resolution 1000 needs about [\d,]+ MB of memory, more than the "
                         r"[\d,]+ MB a bake may use here: lower it to (\d+) or less\.", line)
    assert found, line
    assert not bpy.ops.keyframe_implicit.bake.poll()
    with pytest.raises(RuntimeError, match="Cannot bake: Resolution 1000 needs about"):
        bpy.ops.keyframe_implicit.bake()
    # the figure the bake itself refuses by, about: its largest fitting resolution
    from keyframe_implicit.blender import bake

    inputs = bake.scene_io.read(scene, bpy.context.evaluated_depsgraph_get())
    with pytest.raises(MemoryLimitError) as refused:
        pipeline.plan_bake(**inputs.core_arguments())
    fits = int(found.group(1))
    assert abs(refused.value.max_resolution - fits) <= max(2, fits // 50), (
        refused.value.max_resolution, fits)

    settings.resolution = fits  # what the line says fits does
    assert bpy.ops.keyframe_implicit.bake.poll()
    assert _under_resolution(_drawn(panel.KFI_PT_main)).startswith("About ")


def test_the_estimate_is_kept_per_settings(scene, kfi):
    kfi.build_spheres(TWO)
    limits._need.cache_clear()
    depsgraph = bpy.context.view_layer.depsgraph
    first = limits.need(scene, depsgraph)
    for _ in range(5):  # redraws and polls with nothing changed
        assert limits.need(scene, depsgraph) == first
    assert limits._need.cache_info().misses == 1
    scene.keyframe_implicit.resolution = 64
    assert limits.need(scene, depsgraph).peak > first.peak
    assert limits._need.cache_info().misses == 2


def test_motion_resolution_reads_auto_in_the_artists_words(scene, kfi):
    kfi.build_spheres(TWO)
    settings = scene.keyframe_implicit
    log = _drawn(panel.KFI_PT_advanced)
    assert ("drawn", "Auto", "True") in log
    assert ("prop", "motion_resolution") not in log  # no "0" on show
    tips = [props.KFI_Settings.bl_rna.properties[name].description
            for name in ("motion_resolution", "motion_auto", "resolution")]
    assert not any("same side" in tip for tip in tips), tips
    settings.motion_auto = False  # from the value Auto chooses for these keyframes
    auto = limits.need(scene, bpy.context.view_layer.depsgraph).motion_resolution
    assert settings.motion_resolution == auto > 0
    log = _drawn(panel.KFI_PT_advanced)
    assert ("drawn", "Auto", "False") in log and ("drawn", "Cells", str(auto)) in log
    settings.motion_auto = True
    assert settings.motion_resolution == 0 and settings.motion() is None


def test_an_empty_scene_says_what_to_do_once_and_labels_the_button(scene):
    main = _drawn(panel.KFI_PT_main)
    text = " ".join(_labels(main))
    assert text.count("press Add Keyframe") == 1, text
    assert ("button", "keyframe_implicit.add_keyframe", "Add Keyframe") in main
    pairs = _drawn(panel.KFI_PT_features)
    assert not any("keyframe" in line.lower() and "add" in line.lower()
                   for line in _labels(pairs)), pairs
    width, scale = panel.label_width(bpy.context), panel.ui_scale(bpy.context)
    for line in _labels(main) + _labels(pairs):  # nothing cut off at the sidebar's width
        assert panel.text_width(line, scale) <= width, line


def test_the_readme_states_the_preview_grid_the_panel_shows():
    from keyframe_implicit import examples
    from keyframe_implicit.core.bake.options import BakeOptions
    from keyframe_implicit.core.bake.preview import (PREVIEW_MOTION_RESOLUTION,
                                                     PREVIEW_RESOLUTION, preview_grids)

    readme = (pathlib.Path(__file__).parents[2] / "README.md").read_text()
    said = " ".join(readme[readme.index("**Live Preview**"):].split("**OpenVDB")[0].split())
    splash = examples.example("splash")
    plan = pipeline.plan_bake(splash.keyframes, splash.features, BakeOptions(),
                              grid_rule=preview_grids)
    assert (f"coarse grid ({PREVIEW_RESOLUTION} cells and a motion grid of "
            f"{PREVIEW_MOTION_RESOLUTION}, finer where two feature points would share a cell: "
            f"{plan.resolution} on the splash") in said, said
