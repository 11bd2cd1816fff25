"""Scene -> numpy: keyframe meshes (evaluated, world space) and feature points.

Only reads; never modifies the keyframe objects or their data. Evaluated
meshes come from ``Object.evaluated_get(depsgraph).to_mesh()`` (a temporary
mesh outside ``bpy.data``) and are read with ``foreach_get``.
"""

from dataclasses import dataclass, field

import numpy as np

from ..core.pipeline import Keyframe
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

    @property
    def frames(self):
        return [k.frame for k in self.keyframes]


def mesh_arrays(obj, depsgraph):
    """World-space vertices (V, 3) float64 and triangles (T, 3) int64 of ``obj`` evaluated."""
    ob_eval = obj.evaluated_get(depsgraph)
    mesh = ob_eval.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
    finally:
        ob_eval.to_mesh_clear()
    matrix = np.array(ob_eval.matrix_world, dtype=np.float64)
    verts = co.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    return verts, tris.reshape(-1, 3).astype(np.int64)


def feature_arrays(scene, settings, depsgraph):
    """Per segment: (points_a (N, 3), points_b (N, 3)) world positions, and the pair ids."""
    n_seg = max(len(settings.keyframes) - 1, 0)
    rows = [[] for _ in range(n_seg)]
    for pair in features.pairs(scene).values():
        if pair.complete and 0 <= pair.segment < n_seg:
            rows[pair.segment].append(pair)
    out, ids = [], []
    for seg_pairs in rows:
        a = np.array([_world(p.a, depsgraph) for p in seg_pairs], dtype=np.float64).reshape(-1, 3)
        b = np.array([_world(p.b, depsgraph) for p in seg_pairs], dtype=np.float64).reshape(-1, 3)
        out.append((a, b))
        ids.append([p.pair_id for p in seg_pairs])
    return out, ids


def _world(obj, depsgraph):
    return tuple(obj.evaluated_get(depsgraph).matrix_world.translation)


def collect(scene, depsgraph, resolution=0):
    """Validate ``scene``'s setup and copy it out as a `BakeInput`.

    ``resolution`` <= 0 means the scene setting. Raises ValueError (what is
    wrong and what to do) when validation finds a blocking problem.
    """
    settings = scene.keyframe_implicit
    validate.raise_on_errors(scene, settings)
    keyframes = []
    for kf in settings.keyframes:
        verts, tris = mesh_arrays(kf.object, depsgraph)
        if len(tris) == 0:
            raise ValueError(f"Keyframe '{kf.object.name}' has no faces after modifiers: a keyframe "
                             "must be a closed surface.")
        keyframes.append(Keyframe(vertices=verts, faces=tris, frame=int(kf.frame)))
    feats, ids = feature_arrays(scene, settings, depsgraph)
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
    )
