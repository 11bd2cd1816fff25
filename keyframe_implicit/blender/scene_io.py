"""Scene -> numpy: keyframe meshes (evaluated, world space) and feature points.

Only reads; never modifies the keyframe objects or their data. Each keyframe is
read on its own frame: its object's transform, shape keys and modifiers may be
animated (the same object may even be several keyframes), so the scene is
evaluated on a keyframe's frame (`Scene.frame_set`, as exporters do) whenever
something read there may change with time (`frame_dependent`), and put back on
the frame it was on. Objects that cannot change with time are read on the
current frame: a frame change makes Blender redraw every 3D view, several times
over while the viewport accumulates its anti-aliasing samples, and a bake of
static keyframes should not pay those redraws (benchmarks/README.md, "Static
keyframes read without a frame change"). Evaluated meshes come from
``Object.evaluated_get(depsgraph).to_mesh()`` (a temporary mesh outside
``bpy.data``) and are read with ``foreach_get``.
"""

from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..core.surface.attributes import MeshAttributes
from ..core.bake.pipeline import Keyframe
from . import features, validate


@dataclass
class BakeInput:
    """Everything the core needs, copied out of the scene (plain numpy, thread-safe)."""

    keyframes: list
    features: list  # per segment (points_a (N,3), points_b (N,3))
    resolution: int
    weights: dict
    material_names: list = field(default_factory=list)  # the keyframes' materials, first use first
    pair_ids: list = field(default_factory=list)  # per segment, the pair ids in row order
    feature_names: list = field(default_factory=list)  # per segment, (Empty A, Empty B) per row
    levelsets: bool = False  # keep every frame's level set (the OpenVDB volume)
    output_mode: str = "AUTO"  # the output setting when the bake started

    @property
    def frames(self):
        return [k.frame for k in self.keyframes]


def _get(collection, prop, n, dtype, width=1):
    out = np.empty(n * width, dtype=dtype)
    collection.foreach_get(prop, out)
    return out.reshape(-1, width) if width > 1 else out


def mesh_attributes(obj, mesh, matrix):
    """`MeshAttributes` of an evaluated mesh: polygons, UV maps (active first), colour
    attributes, the object's material slots with per-face indices, smooth flags, sharp and
    seam edges, custom split normals (world space) when the mesh has them."""
    polys, loops, edges = mesh.polygons, mesh.loops, mesh.edges
    n_poly, n_loop = len(polys), len(loops)
    attrs = MeshAttributes(_get(polys, "loop_start", n_poly, np.int32).astype(np.int64),
                           _get(polys, "loop_total", n_poly, np.int32).astype(np.int64),
                           _get(loops, "vertex_index", n_loop, np.int32).astype(np.int64))
    layers = sorted(mesh.uv_layers, key=lambda layer: not layer.active_render)
    for layer in layers:
        attrs.uv_maps[layer.name] = _get(layer.uv, "vector", n_loop, np.float32, 2)
    for col in mesh.color_attributes:
        if col.domain in ("POINT", "CORNER"):
            n = len(mesh.vertices) if col.domain == "POINT" else n_loop
            attrs.colors[col.name] = (col.domain, col.data_type,
                                      _get(col.data, "color", n, np.float32, 4))
    attrs.material_names = [slot.material.name if slot.material else "" for slot in
                            obj.material_slots]
    attrs.material_index = _get(polys, "material_index", n_poly, np.int32).astype(np.int64)
    attrs.smooth = _get(polys, "use_smooth", n_poly, bool)
    attrs.edges = _get(edges, "vertices", len(edges), np.int32, 2).astype(np.int64)
    attrs.sharp_edges = _get(edges, "use_edge_sharp", len(edges), bool)
    attrs.seams = _get(edges, "use_seam", len(edges), bool)
    if mesh.has_custom_normals:
        normals = _get(mesh.corner_normals, "vector", n_loop, np.float32, 3).astype(np.float64)
        normals = normals @ np.linalg.inv(matrix[:3, :3])  # inverse transpose, row vectors
        norm = np.linalg.norm(normals, axis=1, keepdims=True)
        attrs.custom_normals = (normals / np.maximum(norm, 1e-12)).astype(np.float32)
    return attrs


def mesh_arrays(obj, depsgraph, attributes=False):
    """World-space vertices (V, 3) float64 and triangles (T, 3) int64 of ``obj`` evaluated;
    with ``attributes``, also its `MeshAttributes` (`mesh_attributes`)."""
    ob_eval = obj.evaluated_get(depsgraph)
    matrix = np.array(ob_eval.matrix_world, dtype=np.float64)
    mesh = ob_eval.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = _get(mesh.vertices, "co", len(mesh.vertices), np.float32, 3)
        tris = _get(mesh.loop_triangles, "vertices", len(mesh.loop_triangles), np.int32, 3)
        attrs = mesh_attributes(obj, mesh, matrix) if attributes else None
    finally:
        ob_eval.to_mesh_clear()
    verts = co.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    if attributes:
        return verts, tris.astype(np.int64), attrs
    return verts, tris.astype(np.int64)


def _segment_pairs(scene, n_seg):
    """The complete feature pairs of each segment, in order."""
    rows = [[] for _ in range(n_seg)]
    for pair in features.pairs(scene).values():
        if pair.complete and 0 <= pair.segment < n_seg:
            rows[pair.segment].append(pair)
    return rows


def _world(obj, depsgraph):
    return tuple(obj.evaluated_get(depsgraph).matrix_world.translation)


def _animated(id_data):
    """Whether an ID block (or None) carries an action, NLA strips or drivers."""
    ad = getattr(id_data, "animation_data", None)
    return ad is not None and (ad.action is not None or len(ad.drivers) > 0
                               or len(ad.nla_tracks) > 0)


#: Modifiers that read neither the time nor another object: with no animation of their
#: own (which `_animated` sees on the object) they give the same mesh on every frame.
_TIMELESS_MODIFIERS = frozenset(("SUBSURF", "TRIANGULATE", "WELD", "SOLIDIFY", "BEVEL",
                                 "EDGE_SPLIT", "WEIGHTED_NORMAL"))


def _timeless(modifier):
    return modifier.type in _TIMELESS_MODIFIERS or (
        modifier.type == "MIRROR" and modifier.mirror_object is None)


def frame_dependent(obj):
    """Whether ``obj`` may evaluate differently on another frame (conservative).

    True when the object or one of its parents has animation (an action, NLA strips or
    drivers, which live on the ID they drive), constraints (a parent armature's bone
    constraints too), a modifier that may read the time or another object (all but
    `_TIMELESS_MODIFIERS`: Wave, simulations, geometry nodes, Armature, Boolean ...), a
    rigid body, or object data or shape keys with animation. Otherwise its evaluated
    mesh and transform are the same on every frame.
    """
    while obj is not None:
        data = obj.data
        if (_animated(obj) or len(obj.constraints) > 0
                or not all(_timeless(m) for m in obj.modifiers)
                or obj.rigid_body is not None or _animated(data)
                or _animated(getattr(data, "shape_keys", None))
                or (obj.pose is not None and any(len(b.constraints) for b in obj.pose.bones))):
            return True
        obj = obj.parent
    return False


@contextmanager
def _on_frames(scene):
    """A function ``go(frame)`` that evaluates ``scene`` on ``frame`` (unless it is there
    already); afterwards the scene is back on the frame it was on, if it left it."""
    start = (scene.frame_current, scene.frame_subframe)
    moved = []

    def go(frame):
        if (scene.frame_current, scene.frame_subframe) != (frame, 0.0):
            scene.frame_set(frame)
            moved.append(frame)
    try:
        yield go
    finally:
        if moved:
            scene.frame_set(start[0], subframe=start[1])


def read_keyframes(scene, settings, depsgraph):
    """Keyframe meshes and feature points, each evaluated on its keyframe's frame (on the
    current frame where nothing read there depends on the frame: `frame_dependent`).

    Returns (keyframes, features, pair ids): the `Keyframe` list, per segment
    (points_a (N, 3), points_b (N, 3)) in world space -- side A read on keyframe
    i's frame, side B on keyframe i+1's, where the Empties sit on their keyframe
    objects -- and per segment the pair ids in row order.
    """
    kfs = list(settings.keyframes)
    rows = _segment_pairs(scene, max(len(kfs) - 1, 0))
    keyframes = []
    side_a = [[] for _ in rows]
    side_b = [[] for _ in rows]
    with _on_frames(scene) as go:
        for i, kf in enumerate(kfs):
            read_here = [kf.object]
            read_here += [p.a for p in rows[i]] if i < len(rows) else []
            read_here += [p.b for p in rows[i - 1]] if i > 0 else []
            if any(frame_dependent(obj) for obj in read_here):
                go(int(kf.frame))
            verts, tris, attrs = mesh_arrays(kf.object, depsgraph, attributes=True)
            if len(tris) == 0:
                raise ValueError(f"Keyframe {i} ('{kf.object.name}', frame {kf.frame}) has no "
                                 "faces after modifiers on that frame: check its modifier stack "
                                 "(a keyframe must be a closed surface).")
            keyframes.append(Keyframe(vertices=verts, faces=tris, frame=int(kf.frame),
                                      name=kf.object.name, attributes=attrs))
            if i < len(rows):
                side_a[i] = [_world(p.a, depsgraph) for p in rows[i]]
            if i > 0:
                side_b[i - 1] = [_world(p.b, depsgraph) for p in rows[i - 1]]
    feats = [(np.array(a, dtype=np.float64).reshape(-1, 3), np.array(b, dtype=np.float64).reshape(-1, 3))
             for a, b in zip(side_a, side_b)]
    return keyframes, feats, [[p.pair_id for p in seg] for seg in rows]


def feature_names(scene, settings):
    """Per segment, the (A, B) Empty names of each pair in row order (for messages)."""
    rows = _segment_pairs(scene, max(len(settings.keyframes) - 1, 0))
    return [[(p.a.name, p.b.name) for p in seg] for seg in rows]


def collect(scene, depsgraph, resolution=0):
    """Validate ``scene``'s setup and copy it out as a `BakeInput`.

    ``resolution`` <= 0 means the scene setting. Raises ValueError (what is
    wrong and what to do) when validation finds a blocking problem. The scene
    is evaluated on each keyframe's frame where something read there may change with
    time (`frame_dependent`), and left on the frame it was on.
    """
    settings = scene.keyframe_implicit
    validate.raise_on_errors(scene, settings)
    keyframes, feats, ids = read_keyframes(scene, settings, depsgraph)
    materials = []
    for kf in settings.keyframes:
        mat = kf.object.active_material if kf.object.material_slots else None
        if mat is not None and mat.name not in materials:
            materials.append(mat.name)
    return BakeInput(
        keyframes=keyframes,
        features=feats,
        resolution=int(resolution) if resolution and resolution > 0 else int(settings.resolution),
        weights=settings.weights(),
        material_names=materials,
        pair_ids=ids,
        feature_names=feature_names(scene, settings),
        levelsets=bool(settings.volume_export),
        output_mode=str(settings.output_mode),
    )
