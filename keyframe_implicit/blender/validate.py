"""Checks run before baking and shown in the sidebar.

`problems` returns every issue of a scene setup as `Problem` objects whose
message says what is wrong AND what to do. ERROR problems block the bake;
WARNING problems are hints (e.g. fewer than 4 feature pairs is allowed by the
core but gives the solver a poor start).

The surface checks (`surface_check`) are cheap topology counts on each
keyframe's evaluated mesh: a keyframe that encloses no volume (a plane) is
refused before any grid is built; holes and non-manifold edges, which the
core reads anyway, are pointed out. The panel and the Bake button's poll ask
on every redraw, so answers are kept until a depsgraph update changes some
geometry (`forget_surfaces`, a handler registered with the add-on). Keyframes
are numbered from 1 in list order, as the core's messages number them.
"""

from dataclasses import dataclass

import numpy as np

from . import features, volumes

ERROR = "ERROR"
WARNING = "WARNING"

MIN_PAIRS_HINT = 4


def count(n, noun):
    """``n`` ``noun``s in words: "no feature pairs", "1 feature pair", "3 feature pairs"."""
    return f"{n or 'no'} {noun}{'' if n == 1 else 's'}"


@dataclass(frozen=True)
class Problem:
    level: str  # ERROR or WARNING
    message: str
    segment: int = -1  # the segment it concerns, -1 for the whole setup

    @property
    def icon(self):
        return "ERROR" if self.level == ERROR else "INFO"


def problems(scene, settings=None, depsgraph=None):
    """All problems of ``scene``'s keyframe_implicit setup, errors first.

    ``depsgraph`` (default: the scene's first view layer's) gives the evaluated
    meshes of keyframes with modifiers for the surface checks.
    """
    if settings is None:
        settings = scene.keyframe_implicit
    out = []
    kfs = list(settings.keyframes)
    if len(kfs) < 2:
        out.append(Problem(ERROR, f"{count(len(kfs), 'keyframe').capitalize()}: add at least "
                                  "two (select a mesh, set the frame, press Add Keyframe)."))
    for i, kf in enumerate(kfs, start=1):
        name = f"Keyframe {i} '{kf.object.name}'" if kf.object is not None else f"Keyframe {i}"
        if kf.object is None:
            out.append(Problem(ERROR, f"{name} (frame {kf.frame}) has no object: pick a mesh "
                                      "object or remove the keyframe."))
        elif kf.object.type != "MESH":
            out.append(Problem(ERROR, f"{name} is not a mesh: convert it (Object > Convert > "
                                      "Mesh) or pick a mesh object."))
        elif kf.object.name not in scene.objects:
            out.append(Problem(ERROR, f"{name} is not in this scene: link it into the scene or "
                                      "pick another object."))
        else:
            found = _cached_surface_check(kf.object, _depsgraph(scene, depsgraph))
            if found:
                out.append(Problem(found[0], f"{name} {found[1]}"))
    frames = [kf.frame for kf in kfs]
    seen = {}
    for i, f in enumerate(frames, start=1):
        if f in seen:
            out.append(Problem(ERROR, f"Keyframes {seen[f]} and {i} are both on frame {f}: give "
                                      "each keyframe its own frame."))
        seen.setdefault(f, i)
    for i in range(1, len(frames)):
        if frames[i] < frames[i - 1]:
            out.append(Problem(ERROR, f"Keyframe {i + 1} (frame {frames[i]}) comes after keyframe "
                                      f"{i} (frame {frames[i - 1]}) in the list: order the list "
                                      "by frame (Move Up/Down) or change the frames."))
    for i, f in enumerate(frames, start=1):
        if not scene.frame_start <= f <= scene.frame_end:
            out.append(Problem(WARNING, f"Keyframe {i} is on frame {f}, outside the scene's "
                                        f"frames {scene.frame_start}-{scene.frame_end}: Bake "
                                        "widens the frame range to cover it."))
    n_seg = max(len(kfs) - 1, 0)
    counts = [0] * n_seg
    for pair in features.pairs(scene).values():
        name = (pair.a or pair.b).name
        if not 0 <= pair.segment < n_seg:
            out.append(Problem(ERROR, f"Feature '{name}' is for keyframes {pair.segment + 1} and "
                                      f"{pair.segment + 2}, which do not exist: remove the pair."))
            continue
        if not pair.complete:
            out.append(Problem(ERROR, f"Feature '{name}' has no partner: delete it, or select it "
                                      "with another Empty and press Pair Selected.", pair.segment))
            continue
        kf_a = kfs[pair.segment].object
        kf_b = kfs[pair.segment + 1].object
        bad = [(s, e, kf) for s, e, kf in (("A", pair.a, kf_a), ("B", pair.b, kf_b))
               if kf is not None and e.parent != kf]
        for side, e, kf in bad:
            out.append(Problem(WARNING, f"'{e.name}' is not parented to keyframe "
                                        f"{pair.segment + 1 + (side == 'B')} '{kf.name}': it will not "
                                        "follow that object; parent it (Ctrl+P > Keep Transform).",
                               pair.segment))
        counts[pair.segment] += 1
    for seg, n in enumerate(counts):
        if n < MIN_PAIRS_HINT:
            out.append(Problem(WARNING, f"Keyframes {seg + 1} \u2192 {seg + 2} have "
                                        f"{count(n, 'feature pair')}: {MIN_PAIRS_HINT} or more on "
                                        "distinctive points guide the motion better (Add Feature "
                                        "Pair).", seg))
    volume = volumes.problem(settings)
    if volume:
        out.append(Problem(ERROR, volume))
    out.sort(key=lambda p: p.level != ERROR)
    return out


def _depsgraph(scene, depsgraph):
    return depsgraph if depsgraph is not None else scene.view_layers[0].depsgraph


def surface_check(obj, depsgraph):
    """``(level, message)`` about ``obj``'s surface as a keyframe, or None if it is sound.

    Counts faces per edge on the evaluated mesh (one ``foreach_get`` and a
    ``bincount``): an edge with one face lies on a hole, one with three or more
    is non-manifold. The core reads both as solids (generalised winding
    numbers, core/fields/sdf.py), so they are warnings; what it cannot read is a
    surface that encloses no volume, such as a plane. For an open mesh the
    volume (divergence theorem) is taken about the centre of its hole edges,
    so the holes' missing caps add next to nothing. Objects without modifiers
    are read directly.
    """
    ob = obj.evaluated_get(depsgraph) if obj.modifiers else obj
    mesh = ob.to_mesh() if obj.modifiers else obj.data
    try:
        return _surface_problem(mesh, " after its modifiers" if obj.modifiers else "")
    finally:
        if obj.modifiers:
            ob.to_mesh_clear()


_surfaces = {}  # cheap state of a keyframe object -> surface_check's answer


def _cached_surface_check(obj, depsgraph):
    mesh = obj.data
    key = (obj.as_pointer(), mesh.as_pointer(), len(mesh.vertices), len(mesh.polygons),
           tuple((m.name, m.type, m.show_viewport) for m in obj.modifiers))
    if key not in _surfaces:
        _surfaces[key] = surface_check(obj, depsgraph)
    return _surfaces[key]


def forget_surfaces(scene=None, depsgraph=None):
    """Drop the kept surface checks: after a geometry update, a file load, re-registering."""
    if depsgraph is None or any(u.is_updated_geometry for u in depsgraph.updates):
        _surfaces.clear()


def _surface_problem(mesh, after=""):
    if len(mesh.polygons) == 0:
        return ERROR, f"has no faces{after}: a keyframe must be a closed surface."
    edge_of_loop = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("edge_index", edge_of_loop)
    faces_per_edge = np.bincount(edge_of_loop, minlength=len(mesh.edges))
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    on_hole = faces_per_edge == 1
    n_open = int(np.count_nonzero(on_hole))
    if _volume(mesh, co, on_hole) <= 1e-6 * float(np.ptp(co, axis=0).max()) ** 3:
        if n_open:
            return ERROR, ("is open and encloses no volume: close it with Mesh > Clean Up > "
                           "Fill Holes, or give it thickness with a Solidify modifier.")
        return ERROR, "encloses no volume (it is flat): give it thickness with a Solidify modifier."
    if n_open:
        return WARNING, (f"has holes ({n_open} open edges): the bake fills small ones; to be "
                         "sure, close them with Mesh > Clean Up > Fill Holes.")
    shared = int(np.count_nonzero(faces_per_edge > 2))
    if shared:
        return WARNING, (f"is non-manifold ({shared} edges shared by 3 or more faces): if its "
                         "parts come out wrong, find them with Select > Select All by Trait > "
                         "Non Manifold.")
    return None


def _volume(mesh, co, on_hole):
    """|Volume| enclosed by the triangles, about the centre of the hole edges (if any)."""
    if on_hole.any():
        ends = np.empty(len(mesh.edges) * 2, dtype=np.int32)
        mesh.edges.foreach_get("vertices", ends)
        origin = co[ends.reshape(-1, 2)[on_hole].ravel()].mean(axis=0)
    else:
        origin = co.mean(axis=0)
    mesh.calc_loop_triangles()
    tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    a, b, c = (co[tris[k::3]] - origin for k in range(3))
    return abs(float(np.einsum("ij,ij->", a, np.cross(b, c)))) / 6.0


def errors(found):
    return [p for p in found if p.level == ERROR]


def raise_on_errors(scene, settings=None):
    """Raise ValueError listing every blocking problem (what is wrong and what to do)."""
    errs = errors(problems(scene, settings))
    if errs:
        raise ValueError("Cannot bake: " + " ".join(p.message for p in errs))
