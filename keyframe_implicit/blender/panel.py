"""Sidebar: View3D > Sidebar > "Keyframe Implicit".

Main panel: keyframe list, problems (from `validate`, before baking), grid
resolution, output and Bake. Sub-panels: feature pairs per segment with
select buttons, and the objective weights ("Advanced", collapsed).
"""

import bpy

from . import features, validate


class KFI_UL_keyframes(bpy.types.UIList):
    """One row per keyframe: object and frame."""

    bl_idname = "KFI_UL_keyframes"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.label(text=f"{index}", icon="KEYFRAME" if item.object else "ERROR")
        row.prop(item, "object", text="")
        row.prop(item, "frame", text="")


class _Sidebar:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Keyframe Implicit"


class KFI_PT_main(_Sidebar, bpy.types.Panel):
    bl_idname = "KFI_PT_main"
    bl_label = "Keyframe Implicit"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        settings = scene.keyframe_implicit

        layout.label(text="Keyframes")
        row = layout.row()
        row.template_list("KFI_UL_keyframes", "", settings, "keyframes", settings,
                          "active_keyframe_index", rows=3)
        col = row.column(align=True)
        col.operator("keyframe_implicit.add_keyframe", icon="ADD", text="")
        op = col.operator("keyframe_implicit.remove_keyframe", icon="REMOVE", text="")
        op.index = settings.active_keyframe_index
        col.separator()
        op = col.operator("keyframe_implicit.move_keyframe", icon="TRIA_UP", text="")
        op.index, op.direction = settings.active_keyframe_index, "UP"
        op = col.operator("keyframe_implicit.move_keyframe", icon="TRIA_DOWN", text="")
        op.index, op.direction = settings.active_keyframe_index, "DOWN"

        found = validate.problems(scene, settings)
        if found:
            box = layout.box()
            for p in found:
                _wrapped(box, p.message, p.icon)

        layout.prop(settings, "resolution")
        col = layout.column(align=True)
        col.prop(settings, "output_collection")
        col.prop(settings, "output_name")
        col.prop(settings, "output_mode")
        from .ops import _running

        if _running:
            fraction, message = _running[0].status()
            layout.label(text=f"Baking {100 * fraction:.0f}%: {message}", icon="SORTTIME")
            layout.label(text="Press ESC in the 3D view to cancel.")
        row = layout.row()
        row.scale_y = 1.4
        row.enabled = not validate.errors(found) and not _running
        row.operator("keyframe_implicit.bake", icon="RENDER_ANIMATION")
        out = settings.output_object
        if out is not None:
            span = out.get("kfi_frames")
            text = f"Output: {out.name}"
            if span is not None:
                text += f" (frames {span[0]}-{span[1]})"
            layout.label(text=text, icon="OUTLINER_OB_MESH")
            if out.get("kfi_report"):
                _wrapped(layout, out["kfi_report"], "INFO")


class KFI_PT_features(_Sidebar, bpy.types.Panel):
    bl_idname = "KFI_PT_features"
    bl_label = "Feature Pairs"
    bl_parent_id = "KFI_PT_main"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        settings = scene.keyframe_implicit
        kfs = settings.keyframes
        if len(kfs) < 2:
            layout.label(text="Add two keyframes to place feature pairs.", icon="INFO")
            return
        all_pairs = list(features.pairs(scene).values())
        layout.operator("keyframe_implicit.pair_selected", icon="LINKED")
        for seg in range(len(kfs) - 1):
            a, b = kfs[seg].object, kfs[seg + 1].object
            box = layout.box()
            head = box.row()
            head.label(text=f"{seg}: {a.name if a else '?'} -> {b.name if b else '?'}")
            op = head.operator("keyframe_implicit.add_feature_pair", icon="ADD", text="")
            op.segment = seg
            seg_pairs = [p for p in all_pairs if p.segment == seg]
            if not seg_pairs:
                box.label(text="No pairs yet (Add places them at the 3D cursor).")
            for pair in seg_pairs:
                row = box.row(align=True)
                ok = pair.complete
                title = pair.pair_id + (f" {pair.label}" if pair.label else "")
                row.label(text=title, icon="EMPTY_DATA" if ok else "ERROR")
                op = row.operator("keyframe_implicit.select_pair", icon="RESTRICT_SELECT_OFF",
                                  text="")
                op.pair = pair.pair_id
                op = row.operator("keyframe_implicit.remove_feature_pair", icon="X", text="")
                op.pair = pair.pair_id
        orphans = [p for p in all_pairs if not 0 <= p.segment < len(kfs) - 1]
        for pair in orphans:
            row = layout.row(align=True)
            row.label(text=f"{pair.pair_id}: no such segment", icon="ERROR")
            op = row.operator("keyframe_implicit.remove_feature_pair", icon="X", text="")
            op.pair = pair.pair_id


class KFI_PT_advanced(_Sidebar, bpy.types.Panel):
    bl_idname = "KFI_PT_advanced"
    bl_label = "Advanced"
    bl_parent_id = "KFI_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = context.scene.keyframe_implicit
        col = self.layout.column(align=True)
        col.label(text="Objective weights (eq. 2.6)")
        col.prop(settings, "volume_weight")
        col.prop(settings, "rigidity_weight")
        col.prop(settings, "levelset_weight")


def _wrapped(layout, text, icon, width=48):
    """Multi-line label (the sidebar does not wrap)."""
    words, line, first = text.split(), "", True
    col = layout.column(align=True)
    for word in words:
        if line and len(line) + 1 + len(word) > width:
            col.label(text=line, icon=icon if first else "BLANK1")
            line, first = word, False
        else:
            line = f"{line} {word}" if line else word
    if line:
        col.label(text=line, icon=icon if first else "BLANK1")


classes = (KFI_UL_keyframes, KFI_PT_main, KFI_PT_features, KFI_PT_advanced)
