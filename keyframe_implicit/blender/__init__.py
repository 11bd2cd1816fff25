"""Blender side: scene properties, operators, sidebar panel, bake (imports bpy).

Module map (operators and panels are thin; logic lives in plain functions):

=============  ================================================================
``props``      ``Scene.keyframe_implicit`` settings (keyframes, grid, weights, output) and
               ``WindowManager.keyframe_implicit``, the session's (Live Preview)
``features``   feature-point pairs as Empties (create, pair, find, remove)
``edits``      keyframe list edits that keep the pairs (insert, remove); Empties snapped
               onto their keyframe's surface
``scene_io``   scene -> `BakeInput`, the bake read once (meshes, points, facts)
``validate``   problems of a `BakeInput` (a setup), with what to do
``limits``     the memory a bake would need, shown before Bake (cheap, kept per settings)
``bake``       `collect` (read, check), `BakeJob` (the core, cancel), `apply_result`
               (a result into the scene), `bake_scene`
``output``     numpy -> mesh object with one shape key per frame
``fcurves``    F-curves on Blender 4.2 (Action.fcurves) and 4.4+ (slotted actions)
``materials``  shader nodes on Blender 4.x (``use_nodes``) and 5.0+ (always on)
``ops``        operators ``keyframe_implicit.*``
``panel``      View3D sidebar "Keyframe Implicit"
``preview``    live preview: the current frame's in-between from a worker process
``overlay``    the preview drawn with the ``gpu`` module
=============  ================================================================
"""

from __future__ import annotations

# The Blender side's modules and bpy are imported inside the functions below, not when this
# package is: with them imported at its import, a bpy 4.2 LTS process that enabled the
# extension ends with a segmentation fault at exit (tests/blender/test_extension_zip.py).
_registered = []
_HANDLERS = ("depsgraph_update_post", "load_post")


def _forget_readings(scene=None, depsgraph=None):
    """Handler: kept mesh readings are stale after geometry updates and loads."""
    from . import scene_io

    scene_io.forget_readings(scene, depsgraph)


def _class_lists():
    from . import ops, panel, props

    return (props.classes, ops.classes, panel.classes)


def register() -> None:
    """Register the property groups, operators and panels (idempotent after unregister)."""
    import bpy

    from . import edits, limits, ops, preview, props, result_view

    if _registered:
        return
    for group in _class_lists():
        for cls in group:
            bpy.utils.register_class(cls)
            _registered.append(cls)
    props.register_properties()
    bpy.types.VIEW3D_MT_object.append(ops.menu_func)
    bpy.app.handlers.persistent(_forget_readings)  # kept across file loads
    for name in _HANDLERS:
        getattr(bpy.app.handlers, name).append(_forget_readings)
    props.ON_CHANGE.update(live_preview=preview.toggled, show_keyframes=result_view.toggled,
                           motion_auto=limits.motion_auto_changed)
    props.ON_CHANGE["object"] = edits.object_picked  # a keyframe's object, picked in its row
    props.ON_CHANGE["input"] = preview.edited  # a setting the bake reads: a new preview
    for name, handler in preview.HANDLERS:
        getattr(bpy.app.handlers, name).append(handler)


def unregister() -> None:
    """Undo `register` in reverse order."""
    import bpy

    from . import ops, preview, props

    if not _registered:
        return
    for name in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if _forget_readings in handlers:
            handlers.remove(_forget_readings)
    _forget_readings()
    preview.stop()
    for name, handler in preview.HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if handler in handlers:
            handlers.remove(handler)
    for job in list(ops.running):
        job.cancel()
    bpy.types.VIEW3D_MT_object.remove(ops.menu_func)
    props.ON_CHANGE.clear()
    props.unregister_properties()
    for cls in reversed(_registered):
        bpy.utils.unregister_class(cls)
    _registered.clear()
