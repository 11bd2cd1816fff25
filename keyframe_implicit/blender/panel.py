"""Sidebar: View3D > Sidebar > "Keyframe Implicit".

Main panel: keyframe list, problems (from `validate`, before baking), grid
resolution, output and Bake. Sub-panels: feature pairs per pair of keyframes
with select buttons, and the weights of the three goals ("Advanced", collapsed).

The sidebar does not wrap labels: `wrap` breaks messages at the region's real
width, measured with the UI font at the UI scale.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import blf
import bpy

from . import features, limits, output, preview, validate
from .ops import running

if TYPE_CHECKING:
    from collections.abc import Sequence

    from .props import KFI_Keyframe, KFI_Settings

# Width (px at UI scale 1) a sidebar label loses to the category tabs, the panel's and a
# box's margins and the label's own padding (measured on a 4.3 window: 81 without a box),
# and to its icon: what is left is the text's.
LABEL_MARGIN = 76
ICON_WIDTH = 20


class KFI_UL_keyframes(bpy.types.UIList):
    """One row per keyframe: its object's name (editable in place), its frame and its
    interpolation (an icon, as on an F-curve key), compact."""

    bl_idname = "KFI_UL_keyframes"
    NAME_SHARE = 0.72  # the frame number keeps the rest beside the interpolation's icon

    def draw_item(self, context: bpy.types.Context, layout: bpy.types.UILayout,
                  data: bpy.types.AnyType, item: KFI_Keyframe, icon: int,
                  active_data: bpy.types.AnyType, active_propname: str,
                  index: int = 0) -> None:
        """One keyframe: its object's name (a field to pick one when it has none), its frame and
        its interpolation."""
        if self.layout_type == "GRID":
            layout.label(text=item.object.name if item.object else "?")
            return
        row = layout.row(align=True)  # the icon beside the split: the frame keeps its share
        split = row.split(factor=self.NAME_SHARE, align=True)
        if item.object is not None:  # the name, as Blender's lists show it: no clear button
            split.prop(item.object, "name", text="", emboss=False, icon="OUTLINER_OB_MESH")
        else:  # its object was deleted (or never picked): pick one here
            split.prop(item, "object", text="", icon="ERROR")
        split.prop(item, "frame", text="", emboss=False)
        row.prop(item, "interpolation", text="", icon_only=True, emboss=False)


class _Sidebar:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Keyframe Implicit"


class KFI_PT_main(_Sidebar, bpy.types.Panel):
    """Keyframes, problems to fix, and the bake"""

    bl_idname = "KFI_PT_main"
    bl_label = "Keyframe Implicit"

    def draw(self, context: bpy.types.Context) -> None:
        """The keyframe list, the problems found, the output and the Bake button."""

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
        if len(settings.keyframes) < 2:  # the button the first problem names, by its name
            layout.operator("keyframe_implicit.add_keyframe", icon="ADD")

        _active_keyframe(layout, settings)
        _problems(layout, context, settings, validate.problems(scene, context.view_layer.depsgraph))

        col = layout.column(align=True)
        col.use_property_split = True  # labels in a column of their own: not cut at 291 px
        col.use_property_decorate = False
        col.prop(settings, "resolution")
        _memory(col, context)
        col.separator()
        col.prop(settings, "output_collection")
        col.prop(settings, "output_name")
        col.prop(settings, "output_mode")
        col.prop(settings, "volume_export")
        if settings.volume_export:
            col.prop(settings, "volume_directory")
        if running:
            fraction, message = running[0].status()
            _wrapped(layout, context, f"Baking {100 * fraction:.0f}%: {message}", "SORTTIME")
            layout.label(text="ESC in the 3D view cancels.", icon="BLANK1")
        _live_preview(layout, context)
        row = layout.row()
        row.scale_y = 1.4
        row.operator("keyframe_implicit.bake", icon="RENDER_ANIMATION")  # poll says why not
        layout.operator("keyframe_implicit.export_farm_job", icon="NETWORK_DRIVE")
        out = settings.output_object
        if out is not None:
            col = layout.column(align=True)
            _wrapped(col, context, f"Output: {out.name}", "OUTLINER_OB_MESH")
            if out.get("kfi_report"):  # what was made and why, in one line
                _wrapped(col, context, out["kfi_report"], "INFO")
            if out.get("kfi_report_details"):  # its figures, each explained, folded
                col.prop(settings, "show_report_details", emboss=False,
                         icon="DOWNARROW_HLT" if settings.show_report_details else "RIGHTARROW")
                if settings.show_report_details:
                    if out.get(output.STATS):  # the grids, whose cell the figures are in
                        _wrapped(col, context, output.grid_line(out[output.STATS]), "BLANK1")
                    for line in out["kfi_report_details"].split("\n"):
                        _wrapped(col, context, line, "BLANK1")
            layout.prop(settings, "show_keyframes", icon="MOD_WIREFRAME")


def _active_keyframe(layout: bpy.types.UILayout, settings: bpy.types.AnyType) -> None:
    """The active keyframe's Interpolation and, when a segment starts at it, that segment's
    Surface Tension, under the list."""
    index = settings.active_keyframe_index
    if not 0 <= index < len(settings.keyframes):
        return
    item = settings.keyframes[index]
    col = layout.column(align=True)
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(item, "interpolation")
    if index < len(settings.keyframes) - 1:
        col.prop(item, "surface_tension")


class KFI_PT_features(_Sidebar, bpy.types.Panel):
    """Feature pairs: points of one keyframe that must land on points of the next"""

    bl_idname = "KFI_PT_features"
    bl_label = "Feature Pairs"
    bl_parent_id = "KFI_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        """The pairs of the active keyframe's segment, with their tools."""
        layout = self.layout
        scene = context.scene
        settings = scene.keyframe_implicit
        kfs = settings.keyframes
        if len(kfs) < 2:  # the main panel says what to do: not again, cut off
            _wrapped(layout, context, "None until there are two keyframes.", "INFO")
            return
        all_pairs = list(features.pairs(scene).values())
        layout.operator("keyframe_implicit.pair_selected", icon="LINKED")
        for seg in range(len(kfs) - 1):
            a, b = kfs[seg].object, kfs[seg + 1].object
            box = layout.box()
            head = box.row()
            head.label(text=f"{a.name if a else '?'} \u2192 {b.name if b else '?'}")
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
            row.label(text=f"{pair.pair_id}: its keyframes are gone", icon="ERROR")
            op = row.operator("keyframe_implicit.remove_feature_pair", icon="X", text="")
            op.pair = pair.pair_id


class KFI_PT_advanced(_Sidebar, bpy.types.Panel):
    """Term weights, output and volume export"""

    bl_idname = "KFI_PT_advanced"
    bl_label = "Advanced"
    bl_parent_id = "KFI_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context: bpy.types.Context) -> None:
        """The weights of eq. 2.6, the Motion Resolution and the button that clears the work
        kept for re-bakes (`work_cache`)."""
        settings = context.scene.keyframe_implicit
        col = self.layout.column(align=True)
        col.label(text="What the in-betweens keep:")
        col.prop(settings, "volume_weight")
        col.prop(settings, "rigidity_weight")
        col.prop(settings, "levelset_weight")
        col = self.layout.column(heading="Motion Resolution")  # "[x] Auto", not "0"
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(settings, "motion_auto")
        if not settings.motion_auto:
            col.prop(settings, "motion_resolution", text="Cells")
        self.layout.operator("keyframe_implicit.clear_cache", icon="TRASH")


def _memory(layout: bpy.types.UILayout, context: bpy.types.Context) -> None:
    """Under Resolution: the memory a bake would need against the limit (`limits.line`),
    as the Resolution changes; nothing until two keyframes are set."""
    found = limits.need(context.scene)
    if found is not None:
        text, icon = limits.line(found, context.scene.keyframe_implicit.resolution)
        _wrapped(layout, context, text, icon)


def _live_preview(layout: bpy.types.UILayout, context: bpy.types.Context) -> None:
    """The Live Preview toggle (the session's, `props.KFI_Session`); while it is on, its
    grids or why it shows nothing."""
    session = context.window_manager.keyframe_implicit
    layout.prop(session, "live_preview", icon="HIDE_OFF" if session.live_preview else "HIDE_ON")
    if not session.live_preview:
        return
    state = preview.state
    if state.message:
        _wrapped(layout, context, state.message, "ERROR")
    elif state.stale:
        layout.label(text="Preview: updating (grey until then)", icon="SORTTIME")
    elif state.figures:
        f = state.figures
        _wrapped(layout, context, f"Preview grid {f['resolution']} cells, motion "
                 f"{f['motion_resolution']}: solved in {f['seconds']:.1f} s", "INFO")
    elif preview.active():
        layout.label(text="Preview: solving\u2026", icon="SORTTIME")


#: Problems listed before the rest fold away: Bake and the first problems stay in view at
#: the default sidebar height.
SHOWN_PROBLEMS = 2


def _problems(layout: bpy.types.UILayout, context: bpy.types.Context, settings: KFI_Settings,
              found: Sequence[validate.Problem]) -> None:
    """The problems found, errors first; past `SHOWN_PROBLEMS` behind a disclosure."""
    if not found:
        return
    box = layout.box()
    shown = found if settings.show_all_problems else found[:SHOWN_PROBLEMS]
    for p in shown:
        _wrapped(box, context, p.message, p.icon)
        if p.fix:
            box.operator(p.fix, icon="SNAP_ON")
    if len(found) > SHOWN_PROBLEMS:
        more = len(found) - SHOWN_PROBLEMS
        box.prop(settings, "show_all_problems", emboss=False,
                 text="Fewer" if settings.show_all_problems else f"{more} more",
                 icon="DOWNARROW_HLT" if settings.show_all_problems else "RIGHTARROW")


def ui_scale(context: bpy.types.Context) -> float:
    """The UI scale factor (1 in background mode, where it reads 0)."""
    return context.preferences.system.ui_scale or 1.0


def text_width(text: str, scale: float) -> float:
    """Width in pixels of ``text`` in the UI font at ``scale`` (blf measures it)."""
    blf.size(0, bpy.context.preferences.ui_styles[0].widget.points * scale)
    return blf.dimensions(0, text)[0]


def wrap(text: str, width: float, scale: float = 1.0) -> list[str]:
    """Lines of ``text`` (broken at spaces) that each fit ``width`` pixels of label text.

    Greedy, like a text editor: each line takes as many words as fit. A word
    wider than the line gets a line of its own.
    """
    lines, line = [], ""
    for word in text.split():
        wider = f"{line} {word}" if line else word
        if line and text_width(wider, scale) > width:
            lines.append(line)
            line = word
        else:
            line = wider
    if line:
        lines.append(line)
    return lines


def label_width(context: bpy.types.Context) -> float:
    """Pixels of text a sidebar label with an icon has, in a box, in this region."""
    scale = ui_scale(context)
    region = context.region
    width = region.width if region is not None and region.width > 1 else 291 * scale
    return max(width - (LABEL_MARGIN + ICON_WIDTH) * scale, 60 * scale)


def _wrapped(layout: bpy.types.UILayout, context: bpy.types.Context, text: str,
             icon: str) -> None:

    """A message as labels wrapped to the region's width; the icon on the first line."""
    col = layout.column(align=True)
    for i, line in enumerate(wrap(text, label_width(context), ui_scale(context))):
        col.label(text=line, icon=icon if i == 0 else "BLANK1")


classes = (KFI_UL_keyframes, KFI_PT_main, KFI_PT_features, KFI_PT_advanced)
