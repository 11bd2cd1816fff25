"""Write an `Animation` into the scene: one mesh object with a shape key per frame.

Layout of the result (issue 5, item 4):

- a mesh whose Basis is the first frame's shape, smooth shaded, in its own
  collection, with the keyframes' materials in its slots: the faces use the
  first keyframe's, the others are there to pick from;
- one relative shape key per timeline frame f ("Frame f"), keyed 1 on f and 0
  on f-1 and f+1 with LINEAR interpolation, so exactly one key is 1.0 on every
  integer frame and sub-frames (motion blur) blend the two neighbouring frames;
- a link from the setup (``settings.output_object``) so that baking again
  replaces this object and only it.

Geometry and shape keys are written with ``foreach_set`` (as glTF-Blender-IO's
importer does); F-curves go through `fcurves`. If anything fails half way,
every data-block created here is removed again, so the scene is as before.
"""

import bpy
import numpy as np

from . import fcurves

OUTPUT_TAG = "kfi_output"
COLLECTION_TAG = "kfi_output_collection"


def frame_key_name(frame):
    return f"Frame {int(frame)}"


def key_schedule(frames):
    """Per frame f: (key frames, values) = ([f-1, f, f+1] clipped to the range, [0, 1, 0])."""
    frames = [int(f) for f in frames]
    first, last = frames[0], frames[-1]
    out = []
    for f in frames:
        ks = [g for g in (f - 1, f, f + 1) if first <= g <= last]
        out.append((ks, [1.0 if g == f else 0.0 for g in ks]))
    return out


def _clean_faces(faces):
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    return faces[keep]


def build_mesh(name, vertices, faces):
    """A new mesh from (V, 3) vertices and (F, 3) triangles (degenerate ones dropped), via foreach_set."""
    faces = _clean_faces(faces)
    verts = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    mesh = bpy.data.meshes.new(name)
    try:
        mesh.vertices.add(len(verts))
        mesh.vertices.foreach_set("co", verts.ravel())
        mesh.loops.add(faces.size)
        mesh.loops.foreach_set("vertex_index", faces.ravel().astype(np.int32))
        mesh.polygons.add(len(faces))
        mesh.polygons.foreach_set("loop_start", np.arange(0, faces.size, 3, dtype=np.int32))
        try:  # read-only (derived from loop_start) since Blender 4.0; kept for older files
            mesh.polygons.foreach_set("loop_total", np.full(len(faces), 3, dtype=np.int32))
        except (AttributeError, TypeError, RuntimeError):
            pass
        mesh.update(calc_edges=True)
        mesh.polygons.foreach_set("use_smooth", np.ones(len(faces), dtype=bool))
        mesh.update()
    except Exception:
        bpy.data.meshes.remove(mesh)
        raise
    return mesh


def add_frame_keys(obj, frames, vertices, action_name):
    """Basis + one shape key per frame on ``obj``, keyed by `key_schedule` through `fcurves`."""
    obj.shape_key_add(name="Basis", from_mix=False)
    blocks = []
    for f, verts in zip(frames, vertices):
        kb = obj.shape_key_add(name=frame_key_name(f), from_mix=False)
        kb.data.foreach_set("co", np.ascontiguousarray(verts, dtype=np.float32).ravel())
        kb.slider_min = 0.0
        kb.slider_max = 1.0
        blocks.append(kb)
    key = obj.data.shape_keys
    key.name = f"{obj.name} Key"
    key.use_relative = True
    channels = fcurves.channels_for(key, action_name)
    for kb, (ks, vals) in zip(blocks, key_schedule(frames)):
        path = f'key_blocks["{bpy.utils.escape_identifier(kb.name)}"].value'
        fc = fcurves.ensure_fcurve(key, path, 0, channels=channels)
        fcurves.set_keyframes(fc, ks, vals, "LINEAR")
    return key


def _ensure_collection(scene, name):
    """The output collection, created/linked to the scene if missing: (collection, created, linked)."""
    coll = bpy.data.collections.get(name)
    created = linked = False
    if coll is None or coll.library is not None:
        coll = bpy.data.collections.new(name)
        coll[COLLECTION_TAG] = True
        created = True
    if not _in_scene(scene, coll):
        scene.collection.children.link(coll)
        linked = True
    return coll, created, linked


def _in_scene(scene, coll):
    stack = [scene.collection]
    while stack:
        c = stack.pop()
        if c == coll:
            return True
        stack.extend(c.children)
    return False


def remove_output(obj):
    """Delete a baked object with its mesh, shape keys and their action (only if unused elsewhere)."""
    if obj is None:
        return
    mesh = obj.data if obj.type == "MESH" else None
    key = mesh.shape_keys if mesh is not None else None
    action = key.animation_data.action if key is not None and key.animation_data else None
    colls = list(obj.users_collection)
    bpy.data.objects.remove(obj)
    if mesh is not None and mesh.users == 0:
        if key is not None and key.animation_data is not None:
            key.animation_data.action = None
        bpy.data.meshes.remove(mesh)
    if action is not None and action.users == 0:
        bpy.data.actions.remove(action)
    for coll in colls:
        if coll.get(COLLECTION_TAG) and not coll.objects and not coll.children and coll.users <= 1:
            bpy.data.collections.remove(coll)


def _uses(scene, settings, obj):
    """How the setup still reaches ``obj``: as a keyframe or as the parent of a feature point."""
    from . import features

    found = [f"keyframe {i}" for i, kf in enumerate(settings.keyframes, start=1) if kf.object == obj]
    found += [f"feature point '{e.name}'" for e in features.feature_objects(scene) if e.parent == obj]
    return found


def retire_output(scene, settings, old):
    """Remove the previous output, or keep it renamed if the setup still uses it.

    A baked object the artist made a keyframe (or put feature points on) is the
    artist's object now: deleting it would lose data. Returns a note for the
    user when it was kept, else "".
    """
    uses = _uses(scene, settings, old)
    if not uses:
        remove_output(old)
        return ""
    name = old.name
    old.name = f"{name} (kept)"
    return (f"The previous result '{name}' is used as {', '.join(uses)}, so it was kept as "
            f"'{old.name}' instead of being replaced.")


def write_animation(scene, settings, animation, *, material_names=(), stats=None, notes=None):
    """Create the output object for ``animation`` and make it the setup's output.

    The previous output (``settings.output_object``) is removed only once the
    new one is complete, and only if the setup no longer uses it (`retire_output`;
    its note, if any, is appended to ``notes``). On any error everything created
    here is removed and the scene is left as it was.

    Returns the new object.
    """
    frames = [int(f) for f in np.asarray(animation.frames).reshape(-1)]
    verts = np.asarray(animation.vertices)
    if verts.ndim != 3 or verts.shape[0] != len(frames) or verts.shape[2] != 3:
        raise ValueError(f"Animation has vertices of shape {verts.shape} for {len(frames)} frames; "
                         "expected (frames, V, 3).")
    name = settings.output_name or "KFI Animation"
    coll_name = settings.output_collection or "Keyframe Implicit"
    mesh = obj = coll = None
    coll_created = coll_linked = False
    try:
        mesh = build_mesh(name, verts[0], animation.faces)
        for mat in filter(None, map(bpy.data.materials.get, material_names)):
            mesh.materials.append(mat)
        obj = bpy.data.objects.new(name, mesh)
        add_frame_keys(obj, frames, verts, f"{name} Frames")
        coll, coll_created, coll_linked = _ensure_collection(scene, coll_name)
        coll.objects.link(obj)
        obj[OUTPUT_TAG] = True
        obj["kfi_frames"] = [frames[0], frames[-1]]
        grid = getattr(animation, "grid", None)
        if grid is not None:
            obj["kfi_spacing"] = float(grid.spacing)
        for k, v in (stats or {}).items():  # scalar figures only (timings, iterations, ...)
            if isinstance(v, (bool, np.bool_)) or len(str(k)) > 58:
                continue
            if isinstance(v, (int, np.integer)):
                obj[f"kfi_{k}"] = int(v)
            elif isinstance(v, (float, np.floating)):
                obj[f"kfi_{k}"] = float(v)
        old = settings.output_object
        if old is not None and old != obj:
            note = retire_output(scene, settings, old)
            if note and notes is not None:
                notes.append(note)
        settings.output_object = obj
        key = mesh.shape_keys
        for block, coll_, wanted in ((obj, bpy.data.objects, name), (mesh, bpy.data.meshes, name),
                                     (key, bpy.data.shape_keys, f"{name} Key"),
                                     (key.animation_data.action, bpy.data.actions, f"{name} Frames")):
            if block.name != wanted and coll_.get(wanted) is None:
                block.name = wanted  # the old output is gone: take back the plain names
    except Exception:
        _undo_partial(scene, obj, mesh, coll, coll_created, coll_linked)
        raise
    return obj


def _undo_partial(scene, obj, mesh, coll, coll_created, coll_linked):
    """Remove what a failed `write_animation` created (object, mesh, keys, action, collection)."""
    key = mesh.shape_keys if mesh is not None else None
    action = key.animation_data.action if key is not None and key.animation_data else None
    if obj is not None:
        bpy.data.objects.remove(obj)
    if mesh is not None:
        bpy.data.meshes.remove(mesh)
    if action is not None:
        bpy.data.actions.remove(action)
    if coll is not None:
        if coll_created:
            bpy.data.collections.remove(coll)
        elif coll_linked:
            scene.collection.children.unlink(coll)
