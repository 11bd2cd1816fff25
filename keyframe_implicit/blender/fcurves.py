"""The one place that creates and reads F-curves, on every supported Blender.

Blender 4.2/4.3 keep F-curves directly on the Action (``Action.fcurves``).
Blender 4.4 introduced slotted (layered) actions: an Action has ``slots``
(one per animated ID), ``layers`` -> ``strips`` -> one channelbag per slot,
and the channelbag holds the F-curves; 4.4/4.5 still proxy ``Action.fcurves``
for the first slot, 5.0 removed it. Everything here goes through
`channels_for`, which returns whatever holds ``.fcurves`` for one ID on the
running Blender, so callers never branch on the version.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import bpy

if TYPE_CHECKING:
    from collections.abc import Iterable

__all__ = [
    "uses_slotted_actions",
    "channels_for",
    "ensure_fcurve",
    "fcurves_for",
    "set_keyframes",
]


def uses_slotted_actions() -> bool:
    """True on Blender 4.4+ (actions with slots, layers, strips and channelbags)."""
    return "action_slot" in bpy.types.AnimData.bl_rna.properties


def _action_for(id_data: bpy.types.ID,
                action_name: str | None) -> tuple[bpy.types.AnimData, bpy.types.Action]:
    anim = id_data.animation_data or id_data.animation_data_create()
    if anim.action is None:
        anim.action = bpy.data.actions.new(action_name or f"{id_data.name}Action")
    return anim, anim.action


def channels_for(id_data: bpy.types.ID, action_name: str | None = None,
                 ) -> bpy.types.Action | bpy.types.ActionChannelbag:
    """Return the container of ``id_data``'s F-curves (it has ``.fcurves``), creating it.

    Parameters
    ----------
    id_data : bpy.types.ID
        The animated data-block (an Object, a shape-key ``Key``, ...).
    action_name : str, optional
        Name of the Action created when the ID has none yet.

    Returns
    -------
    bpy.types.Action (4.2/4.3) or bpy.types.ActionChannelbag (4.4+)
    """
    anim, action = _action_for(id_data, action_name)
    if not uses_slotted_actions():
        return action
    slot = anim.action_slot
    if slot is None:
        slot = action.slots.new(id_type=id_data.id_type, name=id_data.name)
        anim.action_slot = slot
    layer = action.layers[0] if len(action.layers) else action.layers.new("Layer")
    strip = layer.strips[0] if len(layer.strips) else layer.strips.new(type="KEYFRAME")
    return strip.channelbag(slot, ensure=True)


def ensure_fcurve(id_data: bpy.types.ID, data_path: str, index: int = 0, *,
                  action_name: str | None = None,
                  channels: bpy.types.Action | bpy.types.ActionChannelbag | None = None,
                  ) -> bpy.types.FCurve:
    """The F-curve of ``id_data`` for ``data_path[index]``, created if missing.

    Pass ``channels`` (from `channels_for`) when creating many curves on one ID.
    """
    if channels is None:
        channels = channels_for(id_data, action_name)
    fc = channels.fcurves.find(data_path, index=index)
    if fc is None:
        fc = channels.fcurves.new(data_path, index=index)
    return fc


def fcurves_for(id_data: bpy.types.ID) -> list[bpy.types.FCurve]:
    """All F-curves animating ``id_data`` through its assigned action (and slot); [] if none."""
    anim = id_data.animation_data
    if anim is None or anim.action is None:
        return []
    action = anim.action
    if not uses_slotted_actions():
        return list(action.fcurves)
    slot = anim.action_slot
    if slot is None:
        return []
    curves = []
    for layer in action.layers:
        for strip in layer.strips:
            bag = strip.channelbag(slot)
            if bag is not None:
                curves.extend(bag.fcurves)
    return curves


def _interpolation_value(name: str) -> int:
    return bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items[name].value


def set_keyframes(fcurve: bpy.types.FCurve, frames: Iterable[float], values: Iterable[float],
                  interpolation: str = "LINEAR") -> bpy.types.FCurve:

    """Replace ``fcurve``'s keys by (frames[i], values[i]) with one interpolation, via foreach_set."""
    frames = [float(f) for f in frames]
    values = [float(v) for v in values]
    if len(frames) != len(values):
        raise ValueError(f"set_keyframes: {len(frames)} frames but {len(values)} values.")
    points = fcurve.keyframe_points
    if len(points):
        if hasattr(points, "clear"):
            points.clear()
        else:  # older API: remove one by one (a handful of keys)
            for kp in reversed(list(points)):
                points.remove(kp, fast=True)
    points.add(len(frames))
    co = [c for pair in zip(frames, values) for c in pair]
    points.foreach_set("co", co)
    points.foreach_set("interpolation", [_interpolation_value(interpolation)] * len(frames))
    fcurve.update()
    return fcurve
