"""Write an `Animation` into the scene: shape keys or a mesh sequence.

Two outputs (`resolve_output` picks one: the artist's choice, or Auto, which
takes the core's choice -- shape keys when every frame of the tracked
template passes the cleanliness limits of `core.quality`, else the sequence).

Shape keys (issue 5, item 4):

- a mesh whose Basis is the first frame's shape, smooth shaded, in its own
  collection, with the keyframes' materials in its slots: the faces use the
  first keyframe's, the others are there to pick from;
- one relative shape key per timeline frame f ("Frame f"), keyed 1 on f and 0
  on f-1 and f+1 with LINEAR interpolation, so exactly one key is 1.0 on every
  integer frame and sub-frames (motion blur) blend the two neighbouring frames;
- a link from the setup (``settings.output_object``) so that baking again
  replaces this object and only it.

Mesh sequence (topology free, for merges and splits; PAPER-NOTES section 9):

- one mesh holding every frame's own surface, the frames laid end to end,
  with the integer face attribute ``kfi_frame`` (the frame's index from the
  first frame) and the float3 point attribute ``velocity`` in world units per
  second (scene fps / fps_base), which Cycles uses for motion blur when the
  vertex count changes from frame to frame;
- on the output object a Geometry Nodes modifier (group "<name> Frame
  Switch") keeps the faces whose ``kfi_frame`` is the scene frame minus the
  first frame (rounded, clamped to the range) with Separate Geometry. The
  evaluated mesh thus always comes from the object's own mesh and keeps its
  name, so the Alembic exporter writes one animated shape (it names shapes
  after the mesh). Only built-in nodes, so the .blend plays and renders
  without the add-on.

Geometry and shape keys are written with ``foreach_set`` (as glTF-Blender-IO's
importer does); F-curves go through `fcurves`. If anything fails half way,
every data-block created here is removed again, so the scene is as before.
"""

import bpy
import numpy as np

from ..core.quality import describe_worst
from . import fcurves

OUTPUT_TAG = "kfi_output"
COLLECTION_TAG = "kfi_output_collection"
SEQUENCE_TAG = "kfi_sequence"
VOLUME_TAG = "kfi_volume"  # the output's OpenVDB Volume object (a child of the output)
FRAME_ATTRIBUTE = "kfi_frame"


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


def build_mesh(name, vertices, faces, attributes=None):
    """A new mesh from (V, 3) vertices and (F, 3) triangles (degenerate ones dropped), via
    foreach_set, smooth shaded; or, with ``attributes`` (`core.attributes.MeshAttributes`),
    from their polygons, with their UVs, colours, materials, edge flags and normals."""
    from ..core.attributes import MeshAttributes

    if attributes is None:
        attributes = MeshAttributes.from_triangles(_clean_faces(faces))
    verts = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    mesh = bpy.data.meshes.new(name)
    try:
        mesh.vertices.add(len(verts))
        mesh.vertices.foreach_set("co", verts.ravel())
        mesh.loops.add(attributes.n_loops)
        mesh.loops.foreach_set("vertex_index", _ints(attributes.loop_vertices))
        mesh.polygons.add(attributes.n_polygons)
        mesh.polygons.foreach_set("loop_start", _ints(attributes.loop_start))
        try:  # read-only (derived from loop_start) since Blender 4.0; kept for older files
            mesh.polygons.foreach_set("loop_total", _ints(attributes.loop_total))
        except (AttributeError, TypeError, RuntimeError):
            pass
        mesh.update(calc_edges=True)
        write_attributes(mesh, attributes)
        mesh.update()
    except Exception:
        bpy.data.meshes.remove(mesh)
        raise
    return mesh


def _ints(a):
    return np.ascontiguousarray(a, dtype=np.int32).ravel()


def write_attributes(mesh, attributes):
    """UV maps (the first active), colour attributes, material indices, smooth flags, sharp
    and seam edges (matched by their vertex pair) and custom split normals onto ``mesh``,
    whose polygons are ``attributes``' own."""
    n_poly = attributes.n_polygons
    for name, uv in attributes.uv_maps.items():
        layer = mesh.uv_layers.new(name=name, do_init=False)
        layer.uv.foreach_set("vector", np.ascontiguousarray(uv, dtype=np.float32).ravel())
    if len(mesh.uv_layers):
        mesh.uv_layers.active_index = 0
        mesh.uv_layers[0].active_render = True
    for name, (domain, data_type, data) in attributes.colors.items():
        col = mesh.color_attributes.new(name, data_type, domain)
        col.data.foreach_set("color", np.ascontiguousarray(data, dtype=np.float32).ravel())
    # new faces are smooth and in slot 0; the face attributes below keep their names on
    # every supported line and take one copy (``mesh.polygons`` costs a call per face)
    if attributes.material_index is not None:
        _write_face_attribute(mesh, "material_index", "INT", _ints(attributes.material_index))
    if attributes.smooth is not None:
        sharp = ~np.asarray(attributes.smooth, dtype=bool).reshape(n_poly)
        _write_face_attribute(mesh, "sharp_face", "BOOLEAN", sharp)
    if attributes.edges is not None and len(mesh.edges):
        edges = np.empty(2 * len(mesh.edges), dtype=np.int32)
        mesh.edges.foreach_get("vertices", edges)
        rows = _match_edges(edges.reshape(-1, 2), attributes.edges)
        for prop, flags in (("use_edge_sharp", attributes.sharp_edges),
                            ("use_seam", attributes.seams)):
            if flags is not None:
                out = np.zeros(len(mesh.edges), dtype=bool)
                out[rows >= 0] = np.asarray(flags, dtype=bool)[rows[rows >= 0]]
                _write_edge_flag(mesh, prop, out)
    if attributes.custom_normals is not None:
        mesh.normals_split_custom_set(np.asarray(attributes.custom_normals, dtype=np.float32))


def _write_face_attribute(mesh, name, data_type, values):
    """Face attribute ``name`` from ``values`` (one per face); nothing when all are zero."""
    if values.any():
        attr = mesh.attributes.get(name) or mesh.attributes.new(name, data_type, "FACE")
        attr.data.foreach_set("value", values)


def _write_edge_flag(mesh, prop, flags):
    """The edges' flag ``prop`` (``use_seam``, ``use_edge_sharp``) from ``flags`` (E,) bool.

    The flags live in boolean edge attributes whose names differ between Blender lines
    (seams: ".uv_seam", later "uv_seam"); written through ``mesh.edges`` they cost one
    property call per edge (0.1 s for 300k edges), through the attribute one copy. So one
    edge is flagged the ordinary way, which makes the attribute, and the rest is copied in.
    New edges are unflagged: nothing to write when no flag is set.
    """
    flagged = np.flatnonzero(flags)
    if flagged.size == 0:
        return
    before = set(mesh.attributes.keys())
    setattr(mesh.edges[int(flagged[0])], prop, True)
    made = [a for a in mesh.attributes
            if a.name not in before and a.domain == "EDGE" and a.data_type == "BOOLEAN"]
    if len(made) == 1:
        made[0].data.foreach_set("value", flags)
    else:  # no attribute of its own (or not one we can tell): the slow way
        mesh.edges.foreach_set(prop, flags)


def _match_edges(edges, source):
    """Row of ``source`` (E_s, 2) holding each edge of ``edges`` (E, 2) (either order), or -1."""
    scale = int(max(np.max(edges, initial=0), np.max(source, initial=0))) + 1

    def key(e):
        e = np.sort(np.asarray(e, dtype=np.int64), axis=1)
        return e[:, 0] * scale + e[:, 1]
    src = key(source)
    order = np.argsort(src)
    want = key(edges)
    pos = np.clip(np.searchsorted(src[order], want), 0, max(len(src) - 1, 0))
    found = (len(src) > 0) & (src[order][pos] == want)
    return np.where(found, order[pos], -1)


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


def add_velocity(mesh, velocity):
    """The float3 point attribute ``velocity`` (world units per second) on ``mesh``."""
    attr = mesh.attributes.new("velocity", "FLOAT_VECTOR", "POINT")
    attr.data.foreach_set("vector", np.ascontiguousarray(velocity, dtype=np.float32).ravel())
    return attr


def _link(tree, a, out, b, inp):
    tree.links.new(a.outputs[out], b.inputs[inp])


def _math(tree, operation, a=None, value=None):
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = operation
    if value is not None:
        node.inputs[1].default_value = float(value)
    if a is not None:
        tree.links.new(a, node.inputs[0])
    return node


def frame_switch_group(name, first, count):
    """Geometry Nodes group: the faces of the input mesh that belong to the scene frame.

    A face belongs to frame ``first + i`` when its ``FRAME_ATTRIBUTE`` is i; the
    scene frame is rounded (sub-frames of motion blur keep their frame's mesh) and
    clamped to the ``count`` baked frames. Separate Geometry on faces drops the other
    frames' faces, edges and vertices.
    """
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    for in_out in ("INPUT", "OUTPUT"):
        tree.interface.new_socket("Geometry", in_out=in_out, socket_type="NodeSocketGeometry")
    source = tree.nodes.new("NodeGroupInput")
    time = tree.nodes.new("GeometryNodeInputSceneTime")
    offset = _math(tree, "SUBTRACT", time.outputs["Frame"], first)
    low = _math(tree, "MAXIMUM", _math(tree, "ROUND", offset.outputs[0]).outputs[0], 0)
    pick = _math(tree, "MINIMUM", low.outputs[0], count - 1)
    index = tree.nodes.new("GeometryNodeInputNamedAttribute")
    index.data_type = "INT"
    index.inputs["Name"].default_value = FRAME_ATTRIBUTE
    same = _math(tree, "COMPARE", index.outputs["Attribute"], None)
    _link(tree, pick, 0, same, 1)
    same.inputs[2].default_value = 0.25
    keep = tree.nodes.new("GeometryNodeSeparateGeometry")
    keep.domain = "FACE"
    _link(tree, source, 0, keep, "Geometry")
    _link(tree, same, 0, keep, "Selection")
    out = tree.nodes.new("NodeGroupOutput")
    _link(tree, keep, "Selection", out, "Geometry")
    for i, node in enumerate(tree.nodes):  # readable when an artist opens the group
        node.location = (200 * i, 0)
    return tree


def build_sequence(name, surfaces, velocities, fps, attributes=None):
    """One mesh holding every frame's surface, frame after frame, with the face attribute
    ``FRAME_ATTRIBUTE`` (the frame's index) and ``velocity`` per second (``velocities`` are
    per frame). ``attributes``, per frame, optional `MeshAttributes` (UVs, colours,
    material indices) of each surface; without them a surface's degenerate triangles are
    dropped."""
    from ..core.attributes import MeshAttributes, concatenate

    attributes = attributes or [None] * len(surfaces)
    parts = [a if a is not None else MeshAttributes.from_triangles(_clean_faces(faces))
             for (_, faces), a in zip(surfaces, attributes)]
    verts = [np.asarray(v, dtype=np.float32).reshape(-1, 3) for v, _ in surfaces]
    mesh = build_mesh(name, np.concatenate(verts), None,
                      concatenate(parts, [len(v) for v in verts]))
    try:
        frame = mesh.attributes.new(FRAME_ATTRIBUTE, "INT", "FACE")
        frame.data.foreach_set("value", _ints(np.repeat(np.arange(len(parts)),
                                                        [p.n_polygons for p in parts])))
        add_velocity(mesh, np.concatenate([np.asarray(v, dtype=np.float64).reshape(-1, 3)
                                           for v in velocities]) * fps)
    except Exception:
        bpy.data.meshes.remove(mesh)
        raise
    return mesh


def _surface_attributes(animation):
    """Per frame, the attributes of the frame's own surface (None without the artist's mesh)."""
    if getattr(animation, "attributes", None) is None:
        return None
    return [animation.surface_attributes(i) for i in range(len(animation.surfaces))]


def slot_materials(own, material_names):
    """The output's material slots: ``own`` slot names in order (the first keyframe's own
    slots when its mesh is the template, or every frame's slots of a mesh sequence; "" for
    an empty one), then the keyframes' other materials to pick from."""
    own = list(own or [])
    mats = [bpy.data.materials.get(n) if n else None for n in own]
    mats += [bpy.data.materials.get(n) for n in material_names if n not in own]
    return [m for m in mats if m is not None] if not own else \
        [m for i, m in enumerate(mats) if i < len(own) or m is not None]


def resolve_output(mode, stats):
    """("shape_keys" | "mesh_sequence", reason) for the setting ``mode`` (AUTO,
    SHAPE_KEYS, MESH_SEQUENCE) and the core's figures (``Animation.stats``)."""
    if mode == "SHAPE_KEYS":
        return "shape_keys", "chosen in the output settings"
    if mode == "MESH_SEQUENCE":
        return "mesh_sequence", "chosen in the output settings"
    if "output" in stats:
        return stats["output"], stats.get("output_reason", "")
    return "shape_keys", "no per-frame surfaces to choose from"


def bake_report(kind, reason, frames, stats):
    """What the artist reads after a bake: the output, why, and its worst frame."""
    label = "shape keys" if kind == "shape_keys" else "a mesh sequence"
    text = f"Stored as {label}" + (f": {reason}." if reason else ".")
    quality = (stats or {}).get("quality")
    if quality:
        text += f" {describe_worst(frames, quality[kind]).capitalize()}."
    return text


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
    """Delete a baked object with its mesh, shape keys and their action, and the frame switch
    of a sequence (also one of the earlier layout, `_sequence_blocks`), only what is unused
    elsewhere."""
    if obj is None:
        return
    mesh = obj.data if obj.type == "MESH" else None
    key = mesh.shape_keys if mesh is not None else None
    action = key.animation_data.action if key is not None and key.animation_data else None
    colls = list(obj.users_collection)
    sequence = _sequence_blocks(obj) if obj.get(SEQUENCE_TAG) else []
    for child in [c for c in obj.children if c.get(VOLUME_TAG)]:  # its OpenVDB volume
        volume = child.data
        bpy.data.objects.remove(child)
        if volume is not None and volume.users == 0:
            bpy.data.volumes.remove(volume)
    bpy.data.objects.remove(obj)
    _remove_sequence(sequence)
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

    The output is shape keys or a mesh sequence (`resolve_output` with
    ``settings.output_mode``); the choice and its reason are stored on the
    object (``kfi_output_kind``, ``kfi_output_reason``). The previous output
    (``settings.output_object``) is removed only once the new one is
    complete, and only if the setup no longer uses it (`retire_output`; its
    note, if any, is appended to ``notes``). On any error everything created
    here is removed and the scene is left as it was.

    Returns the new object.
    """
    frames = [int(f) for f in np.asarray(animation.frames).reshape(-1)]
    verts = np.asarray(animation.vertices)
    if verts.ndim != 3 or verts.shape[0] != len(frames) or verts.shape[2] != 3:
        raise ValueError(f"Animation has vertices of shape {verts.shape} for {len(frames)} frames; "
                         "expected (frames, V, 3).")
    kind, reason = resolve_output(getattr(settings, "output_mode", "AUTO"),
                                  getattr(animation, "stats", {}) or {})
    surfaces = getattr(animation, "surfaces", None) or []
    if kind == "mesh_sequence" and len(surfaces) != len(frames):
        raise ValueError("This bake holds no per-frame surfaces: choose Shape Keys as the output.")
    name = settings.output_name or "KFI Animation"
    coll_name = settings.output_collection or "Keyframe Implicit"
    mesh = obj = group = coll = None
    coll_created = coll_linked = False
    try:
        attributes = getattr(animation, "attributes", None)
        if kind == "shape_keys":
            mesh = build_mesh(name, verts[0], animation.faces, attributes)
            own = getattr(attributes, "material_names", None)
        else:
            fps = scene.render.fps / scene.render.fps_base
            per_frame = _surface_attributes(animation)
            mesh = build_sequence(name, surfaces, animation.velocities, fps, per_frame)
            own = list(dict.fromkeys(n for a in per_frame or [] if a is not None
                                     for n in a.material_names))
        for m in slot_materials(own, material_names):
            mesh.materials.append(m)
        obj = bpy.data.objects.new(name, mesh)
        if kind == "shape_keys":
            add_frame_keys(obj, frames, verts, f"{name} Frames")
            key = mesh.shape_keys
            names = ((key, bpy.data.shape_keys, f"{name} Key"),
                     (key.animation_data.action, bpy.data.actions, f"{name} Frames"))
        else:
            group = frame_switch_group(f"{name} Frame Switch", frames[0], len(frames))
            obj.modifiers.new("Frame Switch", "NODES").node_group = group
            obj[SEQUENCE_TAG] = True
            names = ((group, bpy.data.node_groups, f"{name} Frame Switch"),)
        coll, coll_created, coll_linked = _ensure_collection(scene, coll_name)
        coll.objects.link(obj)
        obj[OUTPUT_TAG] = True
        obj["kfi_frames"] = [frames[0], frames[-1]]
        obj["kfi_output_kind"] = kind
        obj["kfi_output_reason"] = reason
        obj["kfi_report"] = bake_report(kind, reason, frames, getattr(animation, "stats", {}))
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
        for block, coll_, wanted in ((obj, bpy.data.objects, name),
                                     (mesh, bpy.data.meshes, name)) + names:
            if block.name != wanted and coll_.get(wanted) is None:
                block.name = wanted  # the old output is gone: take back the plain names
    except Exception:
        _undo_partial(scene, obj, mesh, group, coll, coll_created, coll_linked)
        raise
    return obj


def _sequence_blocks(obj):
    """The frame-switch groups of a sequence output, and what they reach of the layout
    of earlier versions (one object per frame in an unlinked collection, picked by
    Collection Info): the frame collection, objects and meshes."""
    groups = [m.node_group for m in obj.modifiers if m.type == "NODES" and m.node_group]
    blocks = []
    for group in groups:
        for node in group.nodes:
            if node.bl_idname == "GeometryNodeCollectionInfo":
                coll = node.inputs["Collection"].default_value
                if coll is not None:
                    blocks += [o for o in coll.objects] + [o.data for o in coll.objects] + [coll]
        blocks.append(group)
    return blocks


def _remove_sequence(blocks):
    """Remove the blocks of `_sequence_blocks` that nothing else uses any more."""
    for kind, store in ((bpy.types.NodeTree, bpy.data.node_groups),
                        (bpy.types.Collection, bpy.data.collections),
                        (bpy.types.Object, bpy.data.objects), (bpy.types.Mesh, bpy.data.meshes)):
        for block in blocks:
            if isinstance(block, kind) and block.users == 0:
                store.remove(block)


def _undo_partial(scene, obj, mesh, group, coll, coll_created, coll_linked):
    """Remove what a failed `write_animation` created (object, mesh, keys, action, frame
    switch, collection)."""
    key = mesh.shape_keys if mesh is not None else None
    action = key.animation_data.action if key is not None and key.animation_data else None
    if obj is not None:
        bpy.data.objects.remove(obj)
    if mesh is not None:
        bpy.data.meshes.remove(mesh)
    if action is not None:
        bpy.data.actions.remove(action)
    if group is not None:
        bpy.data.node_groups.remove(group)
    if coll is not None:
        if coll_created:
            bpy.data.collections.remove(coll)
        elif coll_linked:
            scene.collection.children.unlink(coll)
