"""What the artist sees after a bake.

The result is selected and active (so the timeline shows its keys and the
Properties editor shows it), the keyframe objects and their feature Empties are
hidden in the viewport and in renders (the result sits where they are), and the
scene's frame range is widened to cover the baked frames. `show_keyframes`
brings the keyframes back as wireframe overlays for comparison (the Empties stay
hidden: their names would cover the result; Select Pair shows a pair); their own
display type is kept in the setup (``KFI_Keyframe.display_type``) and restored
when they are hidden again. Everything here is ordinary scene state, so one
undo step of the bake brings it all back.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from . import features

if TYPE_CHECKING:
    import bpy

    from .props import KFI_Settings


def keyframe_objects(settings: KFI_Settings) -> list[bpy.types.Object]:
    """The distinct objects of the keyframe list, in list order."""
    seen = []
    for item in settings.keyframes:
        if item.object is not None and item.object not in seen:
            seen.append(item.object)
    return seen


def _set_hidden(obj: bpy.types.Object, view_layer: bpy.types.ViewLayer, hidden: bool) -> None:
    try:
        obj.hide_set(hidden, view_layer=view_layer)
    except RuntimeError:  # not in this view layer: nothing to show or hide there
        pass


def toggled(settings: KFI_Settings, context: bpy.types.Context) -> None:
    """The Show Keyframes toggle's handler (`props.ON_CHANGE`)."""
    show_keyframes(settings, context.view_layer, settings.show_keyframes)


def show_keyframes(settings: KFI_Settings, view_layer: bpy.types.ViewLayer, show: bool) -> None:
    """Show the keyframes as wireframes, or hide them (with their feature Empties).

    They stay out of renders either way. The first call remembers each
    object's display type; hiding them again restores it.
    """
    for item in settings.keyframes:
        obj = item.object
        if obj is None:
            continue
        if not item.display_type:
            item.display_type = obj.display_type
        if not show and obj.display_type == "WIRE":
            obj.display_type = item.display_type
    for obj in keyframe_objects(settings):
        obj.hide_render = True
        if show:
            obj.display_type = "WIRE"
        _set_hidden(obj, view_layer, not show)
    if not show:
        for empty in features.feature_objects(view_layer.id_data):  # the view layer's scene
            _set_hidden(empty, view_layer, True)


def cover_frames(scene: bpy.types.Scene, first: int, last: int) -> tuple[int, int] | None:
    """Widen the scene's frame range to include first..last; returns the old range if changed."""
    old = (scene.frame_start, scene.frame_end)
    if first >= old[0] and last <= old[1]:
        return None
    # set the end first when moving right, so start <= end holds at every step
    if last > old[1]:
        scene.frame_end = last
    scene.frame_start = min(first, old[0])
    scene.frame_end = max(last, old[1])
    return old


def present(scene: bpy.types.Scene, view_layer: bpy.types.ViewLayer, settings: KFI_Settings,
            obj: bpy.types.Object) -> list[str]:

    """Select ``obj``, hide the keyframes, cover its frames; returns notes for the report."""
    for other in view_layer.objects.selected:
        if other is not None:  # (the replaced output, removed a moment ago)
            other.select_set(False, view_layer=view_layer)
    obj.select_set(True, view_layer=view_layer)
    view_layer.objects.active = obj
    settings.show_keyframes = False
    show_keyframes(settings, view_layer, False)
    notes = ["keyframes hidden (Show Keyframes in the panel brings them back as wireframes)"]
    mats = [m.name for m in obj.data.materials if m is not None]
    if len(mats) > 1:
        notes.append(f"it uses keyframe 1's material '{mats[0]}'; the other keyframes' "
                     f"({', '.join(repr(m) for m in mats[1:])}) are in its material slots")
    span = obj.get("kfi_frames")
    if span is not None:
        old = cover_frames(scene, int(span[0]), int(span[1]))
        if old is not None:
            notes.append(f"scene frame range {old[0]}-{old[1]} widened to "
                         f"{scene.frame_start}-{scene.frame_end}")
    return notes
