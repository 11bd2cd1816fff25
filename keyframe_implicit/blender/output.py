"""Write an `Animation` into the scene: shape keys or a mesh sequence.

Two outputs (`resolve_output` picks one: the artist's choice, or Auto, which
takes the core's choice -- shape keys when every frame of the tracked
template passes the cleanliness limits of `core.surface.quality`, else the sequence).

Shape keys:

- a mesh whose Basis is the first frame's shape, smooth shaded, in its own
  collection, with the keyframes' materials in its slots: the faces use the
  first keyframe's, the others are there to pick from;
- one relative shape key per timeline frame f ("Frame f"), keyed 1 on f and 0
  on f-1 and f+1 with LINEAR interpolation, so exactly one key is 1.0 on every
  integer frame and sub-frames (motion blur) blend the two neighbouring frames;
- a link from the setup (``settings.output_object``) so that baking again
  replaces this object and only it.

Mesh sequence (topology free, for merges and splits; docs/method.md, section 9):

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

The mesh comes as `core.meshdata.MeshData` (made by the worker process, edges
included) and is copied in with ``foreach_set`` through the mesh's attributes
and shape keys' points, one copy per array (as glTF-Blender-IO's importer
writes with ``foreach_set``); F-curves go through `fcurves`. `write_steps`
does the writing a piece at a time, so the modal bake gives the main loop a
turn between pieces. If anything fails half way, or the writing is stopped,
every data-block created here is removed again, so the scene is as before.

What the output object keeps of its bake, as custom properties, is what the add-on reads
back: its tags (`OUTPUT_TAG`, `SEQUENCE_TAG`), its frames (``kfi_frames``, for the
frame range), its kind (``kfi_output_kind``), the report the panel shows
(``kfi_report``, ``kfi_report_details``) and the grids the report's figures are measured
on (`STATS`, the Figures' first line, `grid_line`). Nothing else: no timings, no counts.
"""

from __future__ import annotations

from collections.abc import Generator, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, TypeVar

import bpy
import numpy as np

from ..core.surface.meshdata import FRAME_ATTRIBUTE, MESH_SEQUENCE, SHAPE_KEYS, resolve_output
from ..core.surface.quality import describe_worst, worst_frame
from . import fcurves, features

if TYPE_CHECKING:
    from ..core.bake.animation import Animation
    from ..core.surface.meshdata import MeshData
    from .props import KFI_Settings

_Result = TypeVar("_Result")  # what a generator of steps returns (`run_steps`)

OUTPUT_TAG = "kfi_output"
COLLECTION_TAG = "kfi_output_collection"
SEQUENCE_TAG = "kfi_sequence"
VOLUME_TAG = "kfi_volume"  # the output's OpenVDB Volume object (a child of the output)
#: The output's figures of its bake's grids (`grid_figures`): resolution, motion_resolution
#: (absent without a motion grid) and spacing, the grid cell the report's distances are in.
STATS = "kfi_stats"
#: Shape-key points written between two turns of the main loop (`frame_key_steps`).
KEY_POINTS_PER_STEP = 1_000_000


def frame_key_name(frame: int) -> str:
    """The shape key of a timeline frame, as the artist sees it in the list."""
    return f"Frame {int(frame)}"


def key_schedule(frames: Iterable[int]) -> list[tuple[list[int], list[float]]]:
    """Per frame f: (key frames, values) = ([f-1, f, f+1] clipped to the range, [0, 1, 0])."""
    frames = [int(f) for f in frames]
    first, last = frames[0], frames[-1]
    out = []
    for f in frames:
        ks = [g for g in (f - 1, f, f + 1) if first <= g <= last]
        out.append((ks, [1.0 if g == f else 0.0 for g in ks]))
    return out


def _ints(a):
    return np.ascontiguousarray(a, dtype=np.int32).ravel()


def _floats(a):
    return np.ascontiguousarray(a, dtype=np.float32).ravel()


def mesh_steps(mesh: bpy.types.Mesh, data: MeshData, fps: float = 1.0
               ) -> Generator[None, None, None]:
    """Copy ``data`` (`core.meshdata.MeshData`) into the new, empty ``mesh``, yielding
    between copies so that a caller on Blender's main loop can give it a turn.

    Positions, corners and edges go through the mesh's own attributes (one copy each; the
    ``mesh.vertices`` / ``mesh.loops`` route costs a property call per element), and the
    edges come made (``mesh.update(calc_edges=True)`` would build them here). Point vectors
    (the sequence's velocity, per frame) are scaled by ``fps`` to world units per second.
    """
    polygons = data.polygons
    mesh.vertices.add(len(data.positions))
    mesh.attributes["position"].data.foreach_set("vector", _floats(data.positions))
    mesh.loops.add(polygons.n_loops)
    mesh.attributes[".corner_vert"].data.foreach_set("value", _ints(polygons.loop_vertices))
    yield
    mesh.polygons.add(polygons.n_polygons)
    mesh.polygons.foreach_set("loop_start", _ints(polygons.loop_start))
    yield
    mesh.edges.add(len(data.edges))
    mesh.attributes[".edge_verts"].data.foreach_set("value", _ints(data.edges))
    mesh.attributes[".corner_edge"].data.foreach_set("value", _ints(data.corner_edges))
    mesh.update()
    yield
    write_attributes(mesh, data)
    for name, values in data.face_ints.items():
        mesh.attributes.new(name, "INT", "FACE").data.foreach_set("value", _ints(values))
    for name, values in data.point_vectors.items():
        attr = mesh.attributes.new(name, "FLOAT_VECTOR", "POINT")
        attr.data.foreach_set("vector", _floats(np.asarray(values, dtype=np.float32) * fps))
    mesh.update()


def write_attributes(mesh: bpy.types.Mesh, data: MeshData) -> None:
    """UV maps (the first active), colour attributes, material indices, smooth flags, sharp
    and seam edges and custom split normals of ``data`` (`core.meshdata.MeshData`) onto
    ``mesh``, whose polygons and edges are ``data``'s own."""
    attributes = data.polygons
    n_poly = attributes.n_polygons
    for name, uv in attributes.uv_maps.items():
        layer = mesh.uv_layers.new(name=name, do_init=False)
        layer.uv.foreach_set("vector", _floats(uv))
    if len(mesh.uv_layers):
        mesh.uv_layers.active_index = 0
        mesh.uv_layers[0].active_render = True
    for name, (domain, data_type, values) in attributes.colors.items():
        col = mesh.color_attributes.new(name, data_type, domain)
        col.data.foreach_set("color", _floats(values))
    # new faces are smooth and in slot 0; the face attributes below keep their names on
    # every supported line and take one copy (``mesh.polygons`` costs a call per face)
    if attributes.material_index is not None:
        _write_face_attribute(mesh, "material_index", "INT", _ints(attributes.material_index))
    if attributes.smooth is not None:
        sharp = ~np.asarray(attributes.smooth, dtype=bool).reshape(n_poly)
        _write_face_attribute(mesh, "sharp_face", "BOOLEAN", sharp)
    for prop, flags in (("use_edge_sharp", data.sharp_edges), ("use_seam", data.seams)):
        if flags is not None:
            _write_edge_flag(mesh, prop, np.asarray(flags, dtype=bool))
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


def frame_key_steps(obj: bpy.types.Object, frames: Sequence[int], vertices: np.ndarray,
                    action_name: str) -> Generator[None, None, None]:
    """Basis + one shape key per frame on ``obj``, keyed by `key_schedule` through
    `fcurves`; yields after every `KEY_POINTS_PER_STEP` points written."""
    obj.shape_key_add(name="Basis", from_mix=False)
    blocks = []
    written = 0
    for f, verts in zip(frames, vertices):
        kb = obj.shape_key_add(name=frame_key_name(f), from_mix=False)
        kb.points.foreach_set("co", _floats(verts))  # ``kb.data``: a property call per point
        kb.slider_min = 0.0
        kb.slider_max = 1.0
        blocks.append(kb)
        written += len(verts)
        if written >= KEY_POINTS_PER_STEP:
            written = 0
            yield
    key = obj.data.shape_keys
    key.name = f"{obj.name} Key"
    key.use_relative = True
    channels = fcurves.channels_for(key, action_name)
    for kb, (ks, vals) in zip(blocks, key_schedule(frames)):
        path = f'key_blocks["{bpy.utils.escape_identifier(kb.name)}"].value'
        fc = fcurves.ensure_fcurve(key, path, 0, channels=channels)
        fcurves.set_keyframes(fc, ks, vals, "LINEAR")


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


def frame_switch_group(name: str, first: int, count: int) -> bpy.types.NodeTree:
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


def slot_materials(own: Sequence[str] | None, material_names: Iterable[str]
                   ) -> list[bpy.types.Material | None]:
    """The output's material slots: ``own`` slot names in order (the first keyframe's own
    slots when its mesh is the template, or every frame's slots of a mesh sequence; "" for
    an empty one), then the keyframes' other materials to pick from."""
    own = list(own or [])
    mats = [bpy.data.materials.get(n) if n else None for n in own]
    mats += [bpy.data.materials.get(n) for n in material_names if n not in own]
    return [m for m in mats if m is not None] if not own else \
        [m for i, m in enumerate(mats) if i < len(own) or m is not None]


OUTPUT_LABELS = {SHAPE_KEYS: "Shape keys", MESH_SEQUENCE: "Mesh sequence"}


def bake_report(kind: str, reason: str, frames: Sequence[int]) -> str:
    """What the artist reads after a bake, in one line: what was made, on which frames, why
    ("Mesh sequence, frames 1-25: one mesh cannot follow the shape at frame 14 ...")."""
    return f"{OUTPUT_LABELS[kind]}, frames {frames[0]}-{frames[-1]}" + (f": {reason}." if reason else ".")


def report_details(kind: str, frames: Sequence[int], stats: Mapping | None) -> list[str]:
    """The figures behind `bake_report`, one explained figure a line (`describe_worst`):
    what the panel shows behind its disclosure and the bake prints to the info log. A mesh
    sequence stored because the shape keys fail the limits shows the shape keys' figures
    first (why not them), then its own."""
    quality = (stats or {}).get("quality") or {}
    lines = []
    for name in ((SHAPE_KEYS, kind) if kind != SHAPE_KEYS else (kind,)):
        if quality.get(name) and (name == kind or worst_frame(frames, quality[name])[2]):
            lines += describe_worst(frames, quality[name], OUTPUT_LABELS[name])
    return lines


def grid_figures(animation: "Animation", resolution: int = 0) -> dict:
    """The figures `STATS` keeps of ``animation``'s bake: its ``resolution`` (when given),
    its motion grid's resolution (when it had one) and its grid ``spacing``."""
    figures = {"resolution": int(resolution)} if resolution else {}
    motion = (getattr(animation, "stats", {}) or {}).get("motion_resolution")
    if motion is not None:
        figures["motion_resolution"] = int(motion)
    grid = getattr(animation, "grid", None)
    if grid is not None:
        figures["spacing"] = float(grid.spacing)
    return figures


def grid_line(figures: Mapping) -> str:
    """The Figures' first line: the grids of the bake (`STATS`), whose cell is the unit of
    the distances below it ("Grid: resolution 48, a cell 0.0521 across; motion grid
    resolution 32")."""
    parts = []
    if "resolution" in figures:
        parts.append(f"resolution {figures['resolution']}")
    if "spacing" in figures:
        parts.append(f"a cell {figures['spacing']:.3g} across")
    line = "Grid: " + ", ".join(parts)
    if "motion_resolution" in figures:
        line += f"; motion grid resolution {figures['motion_resolution']}"
    return line


def _ensure_collection(scene, name):
    """The output collection, created/linked to the scene if missing: (collection, created, linked)."""
    coll = bpy.data.collections.get(name)
    created = linked = False
    if coll is None or coll.library is not None:
        coll = bpy.data.collections.new(name)
        coll[COLLECTION_TAG] = True
        created = True
    if coll not in features.scene_collections(scene):
        scene.collection.children.link(coll)
        linked = True
    return coll, created, linked


def remove_output(obj: bpy.types.Object | None) -> None:
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
    found = [f"keyframe {i}" for i, kf in enumerate(settings.keyframes, start=1) if kf.object == obj]
    found += [f"feature point '{e.name}'" for e in features.feature_objects(scene) if e.parent == obj]
    return found


def retire_output(scene: bpy.types.Scene, settings: KFI_Settings, old: bpy.types.Object) -> str:
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


def write_animation(scene: bpy.types.Scene, settings: bpy.types.PropertyGroup,
                    animation: "Animation", *, resolution: int = 0,
                    material_names: Sequence[str] = (), notes: list | None = None,
                    ) -> bpy.types.Object:
    """Create the output object for ``animation`` and make it the setup's output.

    The output is shape keys or a mesh sequence (`resolve_output` with
    ``settings.output_mode``); the choice is stored on the object
    (``kfi_output_kind``) and its reason said in its report (``kfi_report``);
    ``resolution``, the bake's, goes with its grid figures (`STATS`). The previous output
    (``settings.output_object``) is removed only once the new one is
    complete, and only if the setup no longer uses it (`retire_output`; its
    note, if any, is appended to ``notes``). On any error everything created
    here is removed and the scene is left as it was. The mesh is
    ``animation.output_mesh(kind)``, made by the worker when it knew the kind.

    Returns the new object. `write_steps` does the same a step at a time.
    """
    return run_steps(write_steps(scene, settings, animation, resolution=resolution,
                                 material_names=material_names, notes=notes))


def run_steps(steps: Generator[None, None, _Result]) -> _Result:
    """Run a generator of steps to its end; its return value."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value


def write_steps(scene: bpy.types.Scene, settings: bpy.types.PropertyGroup,
                animation: "Animation", *, resolution: int = 0,
                material_names: Sequence[str] = (), notes: list | None = None,
                ) -> Generator[None, None, bpy.types.Object]:
    """`write_animation` as a generator: it yields after each piece of work (a few copies
    into the mesh, a batch of shape keys, the object) and returns the new object, so the
    modal bake writes a large result over several turns of the main loop. Closed before
    its end (``close()``) or failing, it removes everything it created: the scene is as
    before."""
    frames = [int(f) for f in np.asarray(animation.frames).reshape(-1)]
    verts = np.asarray(animation.vertices)
    if verts.ndim != 3 or verts.shape[0] != len(frames) or verts.shape[2] != 3:
        raise ValueError(f"Animation has vertices of shape {verts.shape} for {len(frames)} frames; "
                         "expected (frames, V, 3).")
    kind, reason = resolve_output(getattr(settings, "output_mode", "AUTO"),
                                  getattr(animation, "stats", {}) or {})
    data = animation.output_mesh(kind)
    name = settings.output_name or "KFI Animation"
    coll_name = settings.output_collection or "Keyframe Implicit"
    mesh = obj = group = coll = None
    coll_created = coll_linked = False
    try:
        mesh = bpy.data.meshes.new(name)
        yield from mesh_steps(mesh, data, scene.render.fps / scene.render.fps_base)
        for m in slot_materials(data.polygons.material_names, material_names):
            mesh.materials.append(m)
        obj = bpy.data.objects.new(name, mesh)
        if kind == SHAPE_KEYS:
            yield from frame_key_steps(obj, frames, verts, f"{name} Frames")
            key = mesh.shape_keys
            names = ((key, bpy.data.shape_keys, f"{name} Key"),
                     (key.animation_data.action, bpy.data.actions, f"{name} Frames"))
        else:
            group = frame_switch_group(f"{name} Frame Switch", frames[0], len(frames))
            obj.modifiers.new("Frame Switch", "NODES").node_group = group
            obj[SEQUENCE_TAG] = True
            names = ((group, bpy.data.node_groups, f"{name} Frame Switch"),)
        yield
        coll, coll_created, coll_linked = _ensure_collection(scene, coll_name)
        coll.objects.link(obj)
        _tag_output(obj, kind, reason, frames, animation, resolution)
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
    except BaseException:  # an error, or closed half way (GeneratorExit)
        _undo_partial(scene, obj, mesh, group, coll, coll_created, coll_linked)
        raise
    return obj


def _tag_output(obj, kind, reason, frames, animation, resolution):
    """What the output object says of itself (the module's list): its tag, frames, kind,
    report and grid figures."""
    obj[OUTPUT_TAG] = True
    obj["kfi_frames"] = [frames[0], frames[-1]]
    obj["kfi_output_kind"] = kind
    obj["kfi_report"] = bake_report(kind, reason, frames)
    obj["kfi_report_details"] = "\n".join(report_details(kind, frames,
                                                         getattr(animation, "stats", {})))
    obj[STATS] = grid_figures(animation, resolution)


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
