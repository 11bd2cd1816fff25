"""Sidebar panels draw without errors for an empty, a half-set-up and a baked scene.

Headless Blender has no UI region to draw into, so each panel's ``draw`` is
called with a recording stand-in for ``UILayout`` that checks what a real
layout would: ``prop`` names an existing property, ``operator`` an existing
operator and only its real properties are set, ``template_list`` a registered
UIList and existing collection/index properties.
"""

import bpy
import pytest

from keyframe_implicit.blender import panel


class OpProps:
    def __init__(self, idname):
        mod, name = idname.split(".")
        self._rna = getattr(getattr(bpy.ops, mod), name).get_rna_type()

    def __setattr__(self, key, value):
        if key != "_rna" and key not in self._rna.properties:
            raise AttributeError(f"operator {self._rna.identifier} has no property {key!r}")
        object.__setattr__(self, key, value)


class Layout:
    """Records calls; validates the arguments the way UILayout would."""

    def __init__(self, log):
        object.__setattr__(self, "log", log)

    def __setattr__(self, key, value):  # enabled, scale_y, alert, ...
        if key not in bpy.types.UILayout.bl_rna.properties:
            raise AttributeError(f"UILayout has no property {key!r}")

    def _child(self, kind):
        self.log.append((kind,))
        return Layout(self.log)

    def row(self, **kw):
        return self._child("row")

    def column(self, **kw):
        return self._child("column")

    def box(self):
        return self._child("box")

    def split(self, *, factor=0.0, **kw):
        self.log.append(("split", factor))
        return Layout(self.log)

    def separator(self, **kw):
        self.log.append(("separator",))

    def label(self, *, text="", icon="NONE", **kw):
        assert icon in bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items, icon
        self.log.append(("label", text))

    def prop(self, data, prop, *, text=None, icon="NONE", **kw):
        assert prop in data.bl_rna.properties, f"{data} has no property {prop!r}"
        assert icon in bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items, icon
        self.log.append(("prop", prop))
        # what Blender draws: the given text, or the property's name; an ID field shows the name
        value = getattr(data, prop)
        shown = value.name if isinstance(value, bpy.types.ID) else str(value)
        self.log.append(("drawn", text if text is not None else data.bl_rna.properties[prop].name,
                         shown))

    def operator(self, idname, *, icon="NONE", **kw):
        assert icon in bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items, icon
        self.log.append(("operator", idname))
        return OpProps(idname)

    def template_list(self, listtype, list_id, dataptr, propname, active_dataptr, active_propname,
                      **kw):
        cls = getattr(bpy.types, listtype)
        assert issubclass(cls, bpy.types.UIList)
        assert propname in dataptr.bl_rna.properties
        assert active_propname in active_dataptr.bl_rna.properties
        items = getattr(dataptr, propname)
        ui_list = type("ListSelf", (cls,), {"layout_type": "DEFAULT"})  # a drawn list's self
        for i, item in enumerate(items):  # draw each row like the UI would
            self.log.append(("list_row", i))
            cls.draw_item(ui_list, bpy.context, Layout(self.log), dataptr, item, 0, active_dataptr,
                          active_propname, i)
        self.log.append(("template_list", listtype, len(items)))


def draw_all(context):
    log = []
    for cls in (panel.KFI_PT_main, panel.KFI_PT_features, panel.KFI_PT_advanced):
        assert cls.bl_space_type == "VIEW_3D" and cls.bl_region_type == "UI"
        assert cls.bl_category == "Keyframe Implicit"
        fake = type("PanelSelf", (), {"layout": Layout(log)})()
        cls.draw(fake, context)
    return log


def list_rows(log):
    """The entries drawn for each row of the keyframe list."""
    rows, current = [], None
    for entry in log:
        if entry[0] == "list_row":
            current = []
            rows.append(current)
        elif entry[0] == "template_list":
            current = None
        elif current is not None:
            current.append(entry)
    return rows


def labels(log):
    return " ".join(e[1] for e in log if e[0] == "label")


def test_panels_draw_empty_scene(scene):
    log = draw_all(bpy.context)
    assert ("template_list", "KFI_UL_keyframes", 0) in log
    assert "add at least two" in labels(log)
    assert ("operator", "keyframe_implicit.bake") in log
    assert ("prop", "volume_weight") in log and ("prop", "levelset_weight") in log


def test_panels_draw_half_set_up_scene(scene, kfi):
    kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (3, 0, 0), 1, 5)], pairs=False)
    bpy.ops.keyframe_implicit.add_feature_pair(segment=0)
    bpy.ops.keyframe_implicit.add_feature_pair(segment=0)
    bpy.data.objects.remove(bpy.data.objects["KFI 0.1 A"])
    log = draw_all(bpy.context)
    text = labels(log)
    assert ("template_list", "KFI_UL_keyframes", 2) in log
    assert "A \u2192 B" in text
    assert "no partner" in text  # the unpaired Empty is shown before baking
    assert log.count(("operator", "keyframe_implicit.select_pair")) == 2


def test_panels_draw_baked_scene(scene, kfi):
    kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (1.5, 0, 0), 1, 4)])
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    log = draw_all(bpy.context)
    text = labels(log)
    # what was made, on which frames and why, once (the report names the frames)
    assert "Output: KFI Animation" in text and text.count("frames 1-4") == 1
    assert "Frames 1-4" not in text
    assert log.count(("operator", "keyframe_implicit.select_pair")) == 4
    assert "no partner" not in text


def test_panel_shows_a_running_bake(scene, kfi):
    from keyframe_implicit.blender import bake, ops

    kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (1.5, 0, 0), 1, 4)])
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
    job._progress(0.42, "solving the volume map")
    ops.running.append(job)
    try:
        text = labels(draw_all(bpy.context))
    finally:
        ops.running.remove(job)
    assert "Baking 42%: solving the volume map" in text and "ESC" in text


def test_layout_stand_in_catches_mistakes(scene):
    # the checks above would fail on a typo in a panel
    layout = Layout([])
    with pytest.raises(AssertionError):
        layout.prop(scene.keyframe_implicit, "resolutoin")
    with pytest.raises(AttributeError):
        layout.operator("keyframe_implicit.bake").resolutoin = 3


def test_object_menu_lists_every_operator(scene):
    from keyframe_implicit.blender import ops

    log = []
    ops.KFI_MT_menu.draw(type("MenuSelf", (), {"layout": Layout(log)})(), bpy.context)
    listed = {e[1] for e in log if e[0] == "operator"}
    assert listed == {c.bl_idname for c in ops.classes if issubclass(c, bpy.types.Operator)}
    assert ops.menu_func in bpy.types.VIEW3D_MT_object._dyn_ui_initialize()
