"""Scene -> a plain description of the bake (`BakeInput`), read once (`read`).

`read` is the one function that reads a bake's setup from the scene: the keyframe list,
the feature pairs, the settings, what the pre-bake checks need (as plain facts: each
keyframe object's kind and its mesh as the bake reads it, which feature Empties are not parented to
their keyframe objects and which lie outside their keyframe's material, and how far, whether the
OpenVDB export can run) and, for a bake, the
keyframes' evaluated meshes and the feature points. `validate` checks that description
and `bake` bakes it; neither reads the scene again.

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

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, overload

import numpy as np

from ..core.surface.attributes import MeshAttributes
from ..core.bake.gridfit import lattice_spacing
from ..core.bake.options import BakeOptions
from ..core.bake.keyframe import Keyframe
from ..core.fields.measure import MeshReading
from ..core.fields.mesh import clean_triangles
from ..core.fields.winding import WindingTree
from ..core.fields.measure import read_mesh as measure_mesh
from . import features, volumes

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Iterator, Sequence
    from typing import Literal

    import bpy

    from .props import KFI_Keyframe


@dataclass(frozen=True)
class ListedKeyframe:
    """One entry of the keyframe list as read: what the checks need to know of it.

    Attributes
    ----------
    frame : int
        The entry's timeline frame.
    name : str or None
        Its object's name; None when the entry has no object.
    kind : str
        Its object's type ("MESH", "CURVE", ...); "" without an object.
    in_scene : bool
        Whether the object is in the scene that is read.
    reading : core.fields.measure.MeshReading or None
        Its evaluated mesh as the bake reads it (`cached_reading`), for a mesh object in
        the scene; else None.
    modified : bool
        Whether that mesh is the object's after its modifiers.
    """

    frame: int
    name: str | None = None
    kind: str = ""
    in_scene: bool = False
    reading: MeshReading | None = None
    modified: bool = False

    @property
    def readable(self) -> bool:
        """Whether its mesh can be read for a bake: a mesh object in the scene."""
        return self.kind == "MESH" and self.in_scene


@dataclass(frozen=True)
class ListedPair:
    """One feature pair of the scene, or a lone Empty (`features.pairs`), as read.

    Attributes
    ----------
    pair_id : str
        The pair id ("<segment>.<n>").
    segment : int
        The pair lies between keyframe ``segment`` and ``segment + 1`` (from 0).
    a, b : str or None
        The names of the Empties on side A and side B; None for a missing side.
    unparented : tuple of (str, str or None)
        The sides ("A", "B") of a complete pair of an existing segment whose Empty is not
        parented to its keyframe's object, each with the name of the object it is parented
        to instead (None: none); a fact only the objects tell, read with them.
    off_surface : tuple of (str, float)
        The sides of a complete pair of an existing segment whose Empty lies outside its
        keyframe's material, each with how far, in cells of the bake's grid at the
        resolution read (`surface_cell`); only for keyframes that enclose a volume.
    """

    pair_id: str
    segment: int
    a: str | None = None
    b: str | None = None
    unparented: tuple[tuple[str, str | None], ...] = ()
    off_surface: tuple[tuple[str, float], ...] = ()

    @property
    def complete(self) -> bool:
        """Whether both sides have an Empty."""
        return self.a is not None and self.b is not None


@dataclass
class BakeInput:
    """A plain description of a bake, read from the scene once (`read`).

    Everything the checks (`validate.check`) and the core need, copied out of the scene:
    plain values and numpy arrays, safe to hand to another thread.

    Attributes
    ----------
    keyframes : list of core.bake.keyframe.Keyframe
        The keyframes' evaluated meshes in world space, each read on its frame; empty when
        the meshes were not read (`read` with ``meshes=False``, or an entry of the list
        that is not a mesh object in the scene).
    features : list of (ndarray, ndarray)
        Per segment, the feature points (N, 3) of side A and side B; empty with the meshes.
    resolution : int
        The grid resolution of this bake.
    motion_resolution : int or None
        The motion grid's resolution (`props.KFI_Settings.motion`; None: automatic).
    weights : dict
        The objective's weights (`props.KFI_Settings.weights`).
    material_names : list of str
        The keyframes' materials, first use first (with the meshes).
    pair_ids : list of list of str
        Per segment, the ids of its complete pairs in row order.
    feature_names : list of list of (str, str)
        Per segment, the (A, B) Empty names of each row, for the core's messages.
    levelsets : bool
        Keep every frame's level set (the OpenVDB volume).
    output_mode : str
        The output setting when the bake started.
    key_interpolation : list of str
        Per listed keyframe, how the motion passes it, as the core names it ("smooth",
        "linear", "ease": the list's Interpolation).
    surface_tension : list of float
        Per segment, from the keyframe that starts it, how parts join where they meet
        (the list's Surface Tension).
    listed_keyframes : list of ListedKeyframe
        The keyframe list as read, for the checks.
    listed_pairs : list of ListedPair
        Every feature pair and lone Empty, sorted as `features.pairs` sorts them.
    scene_frames : tuple of int
        The scene's (frame_start, frame_end).
    volume_problem : str
        Why the OpenVDB export asked for cannot run ("" when it can, `volumes.problem`).
    """

    keyframes: list[Keyframe]
    features: list[tuple[np.ndarray, np.ndarray]]
    resolution: int
    weights: dict[str, float]
    motion_resolution: int | None = None
    material_names: list[str] = field(default_factory=list)
    pair_ids: list[list[str]] = field(default_factory=list)
    feature_names: list[list[tuple[str, str]]] = field(default_factory=list)
    levelsets: bool = False
    output_mode: str = "AUTO"
    key_interpolation: list[str] = field(default_factory=list)
    surface_tension: list[float] = field(default_factory=list)
    listed_keyframes: list[ListedKeyframe] = field(default_factory=list)
    listed_pairs: list[ListedPair] = field(default_factory=list)
    scene_frames: tuple[int, int] = (1, 250)
    volume_problem: str = ""

    @property
    def frames(self) -> list[int]:
        """The frames of the keyframes read, in list order."""
        return [k.frame for k in self.keyframes]

    def core_arguments(self) -> dict:
        """`core.bake.pipeline.bake`'s keyword arguments for this bake: the keyframes, the
        feature pairs and their names, and the bake's options (`BakeOptions`). The one
        translation of the panel's settings into the core's: the bake's worker, the farm
        job and the live preview (`core.bake.preview.Preview.solve`) all take it. An output
        set in the panel (not Auto) is the only one the bake makes and measures
        (`SurfaceOptions.output`)."""
        options = BakeOptions.from_keywords(
            resolution=self.resolution, motion_resolution=self.motion_resolution,
            weights=self.weights, levelsets=self.levelsets, output=self.output_mode.lower(),
            key_interpolation=self.key_interpolation or None,
            surface_tension=self.surface_tension or None)
        return dict(keyframes=self.keyframes, features=self.features,
                    feature_names=self.feature_names or None, options=options)


def _get(collection: bpy.types.bpy_prop_collection, prop: str, n: int, dtype: type,
         width: int = 1) -> np.ndarray:
    out = np.empty(n * width, dtype=dtype)
    collection.foreach_get(prop, out)
    return out.reshape(-1, width) if width > 1 else out


def mesh_attributes(obj: bpy.types.Object, mesh: bpy.types.Mesh,
                    matrix: np.ndarray) -> MeshAttributes:
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


@overload
def mesh_arrays(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph,
                attributes: Literal[False] = False) -> tuple[np.ndarray, np.ndarray]: ...


@overload
def mesh_arrays(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph,
                attributes: Literal[True]) -> tuple[np.ndarray, np.ndarray, MeshAttributes]: ...


def mesh_arrays(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph, attributes: bool = False,
                ) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, MeshAttributes]:

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


def read_mesh(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> MeshReading:
    """``obj``'s evaluated mesh in world space as the bake reads it: faces only, each part
    facing one way (`core.fields.measure.read_mesh`, the measure the bake's own check uses).

    Parameters
    ----------
    obj : bpy.types.Object
        A mesh object.
    depsgraph : bpy.types.Depsgraph
        Evaluates an object with modifiers.

    Returns
    -------
    core.fields.measure.MeshReading
        With no triangles when the mesh has no faces. The panel asks through
        `cached_reading`.
    """
    return _measure(*mesh_arrays(obj, depsgraph))


def _measure(verts: np.ndarray, tris: np.ndarray) -> MeshReading:
    try:
        return measure_mesh(verts, tris)
    except ValueError:  # no faces
        return MeshReading(triangles=0)


#: Cheap state of a keyframe object (`_state`) -> its `Surface` and its `read_mesh` answer.
_readings: dict[tuple, tuple[Surface, MeshReading]] = {}
#: (state, feature points' bytes) -> how far those points lie outside (`Surface.nearest`): the panel asks on
#: every redraw, the answer changes only when an Empty or the keyframe moves.
_outside: dict[tuple, np.ndarray] = {}
#: Answers `_outside` keeps at most (a drag adds one per redraw).
OUTSIDE_KEPT = 64


@dataclass(frozen=True)
class Surface:
    """A keyframe object's evaluated mesh in world space, as the bake reads it.

    Attributes
    ----------
    vertices : ndarray
        (V, 3) float64, world space.
    triangles : ndarray
        (T, 3) int64.
    """

    vertices: np.ndarray
    triangles: np.ndarray

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) corners of its faces' box (loose vertices are not read: `fit_grid`'s box)."""
        used = self.vertices[np.unique(self.triangles)] if len(self.triangles) else self.vertices
        return np.array([used.min(axis=0), used.max(axis=0)])

    @cached_property
    def winding(self) -> WindingTree:
        """Its winding numbers' tree (`core.fields.winding`): built once, asked at every
        redraw while an Empty moves."""
        return WindingTree(self.vertices, clean_triangles(self.vertices, self.triangles, None))

    def nearest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The nearest surface point (P, 3) of each of ``points`` (P, 3), and how far each
        point lies outside the material (P,), 0 inside it (where the winding number reads
        inside, as the distance field does)."""
        from ..core.surface.attributes import closest_points

        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        closest = closest_points(points, self.vertices, self.triangles)[0]
        far = np.linalg.norm(points - closest, axis=1)
        inside = np.zeros(len(points), dtype=bool)
        if far.any():
            inside[far > 0] = self.winding(points[far > 0]) >= 0.5
        return closest, np.where(inside, 0.0, far)


def _state(obj: bpy.types.Object) -> tuple:
    """What `cached_surface` keys ``obj``'s reading by: its mesh, counts, modifiers and
    world transform (the measure is in world units)."""
    mesh = obj.data
    return (obj.as_pointer(), mesh.as_pointer(), len(mesh.vertices), len(mesh.polygons),
            tuple((m.name, m.type, m.show_viewport) for m in obj.modifiers),
            tuple(map(tuple, obj.matrix_world)))


def _kept(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> tuple[Surface, MeshReading]:
    key = _state(obj)
    if key not in _readings:
        verts, tris = mesh_arrays(obj, depsgraph)
        _readings[key] = (Surface(verts, tris), _measure(verts, tris))
    return _readings[key]


def cached_reading(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> MeshReading:
    """`read_mesh`, kept per cheap state of ``obj`` (its mesh, counts and modifiers)
    and its world transform (the measure is in world units).

    The panel and the Bake button's poll read the setup on every redraw; the readings are
    kept until a depsgraph update changes some geometry (`forget_readings`).
    """
    return _kept(obj, depsgraph)[1]


def cached_surface(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> Surface:
    """``obj``'s evaluated mesh in world space, kept as `cached_reading` keeps its reading."""
    return _kept(obj, depsgraph)[0]


def outside_distances(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph,
                      points: np.ndarray) -> np.ndarray:
    """How far each of ``points`` (P, 3) lies outside ``obj``'s material (`Surface.nearest`),
    kept for the same object state and points (at most `OUTSIDE_KEPT` answers)."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    key = (_state(obj), points.tobytes())
    if key not in _outside:
        if len(_outside) >= OUTSIDE_KEPT:
            _outside.clear()
        _outside[key] = cached_surface(obj, depsgraph).nearest(points)[1]
    return _outside[key]


def forget_readings(scene: bpy.types.Scene | None = None,
                    depsgraph: bpy.types.Depsgraph | None = None) -> None:
    """Drop the kept mesh readings: after a geometry update, a file load, re-registering.

    Parameters
    ----------
    scene : bpy.types.Scene, optional
        Unused; the handlers pass it.
    depsgraph : bpy.types.Depsgraph, optional
        A depsgraph update: the readings go only if it updated some geometry. None forgets
        them in any case.
    """
    if depsgraph is None or any(u.is_updated_geometry for u in depsgraph.updates):
        _readings.clear()
        _outside.clear()


def _world(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> tuple[float, ...]:
    return tuple(obj.evaluated_get(depsgraph).matrix_world.translation)


def _animated(id_data: bpy.types.ID | None) -> bool:
    """Whether an ID block (or None) carries an action, NLA strips or drivers."""
    ad = getattr(id_data, "animation_data", None)
    return ad is not None and (ad.action is not None or len(ad.drivers) > 0
                               or len(ad.nla_tracks) > 0)


#: Modifiers that read neither the time nor another object: with no animation of their
#: own (which `_animated` sees on the object) they give the same mesh on every frame.
_TIMELESS_MODIFIERS = frozenset(("SUBSURF", "TRIANGULATE", "WELD", "SOLIDIFY", "BEVEL",
                                 "EDGE_SPLIT", "WEIGHTED_NORMAL"))


def _timeless(modifier: bpy.types.Modifier) -> bool:
    return modifier.type in _TIMELESS_MODIFIERS or (
        modifier.type == "MIRROR" and modifier.mirror_object is None)


def frame_dependent(obj: bpy.types.Object | None) -> bool:
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
def _on_frames(scene: bpy.types.Scene) -> Iterator[Callable[[int], None]]:
    """A function ``go(frame)`` that evaluates ``scene`` on ``frame`` (unless it is there
    already); afterwards the scene is back on the frame it was on, if it left it."""
    start = (scene.frame_current, scene.frame_subframe)
    moved = []

    def go(frame: int) -> None:
        if (scene.frame_current, scene.frame_subframe) != (frame, 0.0):
            scene.frame_set(frame)
            moved.append(frame)
    try:
        yield go
    finally:
        if moved:
            scene.frame_set(start[0], subframe=start[1])


def _read_on_frames(scene: bpy.types.Scene, kfs: Sequence[KFI_Keyframe],
                    rows: Sequence[Sequence[features.Pair]], depsgraph: bpy.types.Depsgraph,
                    ) -> tuple[list[Keyframe], list[tuple[np.ndarray, np.ndarray]]]:
    """The keyframes' meshes and the feature points, each on its keyframe's frame (on the
    current frame where nothing read there depends on the frame: `frame_dependent`).

    Returns (keyframes, features): the `Keyframe` list and, per segment, (points_a (N, 3),
    points_b (N, 3)) in world space -- side A read on keyframe i's frame, side B on
    keyframe i+1's, where the Empties sit on their keyframe objects.
    """
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
            keyframes.append(Keyframe(vertices=verts, faces=tris, frame=int(kf.frame),
                                      name=kf.object.name, attributes=attrs))
            if i < len(rows):
                side_a[i] = [_world(p.a, depsgraph) for p in rows[i]]
            if i > 0:
                side_b[i - 1] = [_world(p.b, depsgraph) for p in rows[i - 1]]
    feats = [(np.array(a, dtype=np.float64).reshape(-1, 3), np.array(b, dtype=np.float64).reshape(-1, 3))
             for a, b in zip(side_a, side_b)]
    return keyframes, feats


def _segment_rows(found: Iterable[features.Pair], n_seg: int) -> list[list[features.Pair]]:
    """The complete feature pairs (`features.Pair`) of each segment, in order."""
    rows = [[] for _ in range(n_seg)]
    for pair in found:
        if pair.complete and 0 <= pair.segment < n_seg:
            rows[pair.segment].append(pair)
    return rows


def _listed_keyframe(scene: bpy.types.Scene, kf: KFI_Keyframe,
                     depsgraph: bpy.types.Depsgraph) -> ListedKeyframe:
    """A `ListedKeyframe` of one entry of the keyframe list."""
    obj = kf.object
    if obj is None:
        return ListedKeyframe(int(kf.frame))
    in_scene = obj.name in scene.objects
    reading = cached_reading(obj, depsgraph) if obj.type == "MESH" and in_scene else None
    return ListedKeyframe(int(kf.frame), obj.name, obj.type, in_scene, reading,
                          len(obj.modifiers) > 0)


def _listed_pair(pair: features.Pair, objects: Sequence[bpy.types.Object | None],
                 off_surface: dict[str, list[tuple[str, float]]]) -> ListedPair:
    """A `ListedPair` of a `features.Pair`; ``objects`` are the keyframe list's objects,
    ``off_surface`` what `_off_surface` found."""
    unparented = ()
    if pair.complete and 0 <= pair.segment < len(objects) - 1:
        sides = (("A", pair.a, objects[pair.segment]), ("B", pair.b, objects[pair.segment + 1]))
        unparented = tuple((side, e.parent.name if e.parent is not None else None)
                           for side, e, kf in sides if kf is not None and e.parent != kf)
    return ListedPair(pair.pair_id, pair.segment, pair.a.name if pair.a is not None else None,
                      pair.b.name if pair.b is not None else None, unparented,
                      tuple(off_surface.get(pair.pair_id, ())))


def empties_on(found: Iterable[features.Pair], n_keyframes: int,
               ) -> dict[int, list[tuple[str, str, bpy.types.Object]]]:
    """Keyframe index -> the (pair id, side, Empty) of the complete pairs' Empties meant to
    sit on it: side A of its segment's pairs, side B of the segment before."""
    on: dict[int, list[tuple[str, str, bpy.types.Object]]] = {}
    for pair in found:
        if pair.complete and 0 <= pair.segment < n_keyframes - 1:
            on.setdefault(pair.segment, []).append((pair.pair_id, "A", pair.a))
            on.setdefault(pair.segment + 1, []).append((pair.pair_id, "B", pair.b))
    return on


def _encloses(kf: ListedKeyframe) -> bool:
    return kf.readable and kf.reading is not None and kf.reading.encloses_volume


def surface_cell(listed: Sequence[ListedKeyframe], objects: Sequence[bpy.types.Object | None],
                 resolution: int, depsgraph: bpy.types.Depsgraph) -> float:
    """The bake's cell at ``resolution``: the lattice spacing of the longest side of the box
    of the keyframes' faces (`core.bake.gridfit.lattice_spacing`, as `fit_grid` reads it: the
    feature points widen the grid, not its cells); 0 when no keyframe encloses a volume."""
    corners = [cached_surface(obj, depsgraph).bounds for kf, obj in zip(listed, objects)
               if _encloses(kf)]
    if not corners:
        return 0.0
    return lattice_spacing(float(np.ptp(np.concatenate(corners), axis=0).max()), resolution)


def _off_surface(found: Iterable[features.Pair], listed: Sequence[ListedKeyframe],
                 objects: Sequence[bpy.types.Object | None], resolution: int,
                 depsgraph: bpy.types.Depsgraph) -> dict[str, list[tuple[str, float]]]:
    """Pair id -> the sides whose Empty lies outside its keyframe's material, with how far
    in cells of the bake's grid (`surface_cell`), for keyframes that enclose a volume. An
    Empty parented to another keyframe of the list is not measured: it is on that one (the
    list changed since it was placed), which the checks say instead."""
    keyframes = {obj for obj in objects if obj is not None}
    on = {i: [row for row in rows if row[2].parent in (None, objects[i])
              or row[2].parent not in keyframes]
          for i, rows in empties_on(found, len(listed)).items()}
    points = {i: np.array([tuple(e.matrix_world.translation) for _, _, e in rows])
              for i, rows in on.items()}
    h = surface_cell(listed, objects, resolution, depsgraph)
    out: dict[str, list[tuple[str, float]]] = {}
    for i, rows in on.items():
        if h <= 0 or not rows or not _encloses(listed[i]):
            continue
        far = outside_distances(objects[i], depsgraph, points[i]) / h
        for (pid, side, _), cells in zip(rows, far):
            if cells > 0:
                out.setdefault(pid, []).append((side, float(cells)))
    return out


def _material_names(objects: Iterable[bpy.types.Object]) -> list[str]:
    """The keyframe objects' active materials' names, first use first."""
    names = []
    for obj in objects:
        mat = obj.active_material if obj.material_slots else None
        if mat is not None and mat.name not in names:
            names.append(mat.name)
    return names


def read(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None = None,
         resolution: int = 0, meshes: bool = True) -> BakeInput:

    """Read the bake ``scene``'s settings describe, once, into a `BakeInput`.

    The one reading of a bake's setup: `validate.check` checks what it returns and
    `bake.BakeJob` bakes it. Reading refuses nothing (the checks do) and changes nothing:
    the scene is evaluated on each keyframe's frame where something read there may change
    with time (`frame_dependent`), and left on the frame it was on.

    Parameters
    ----------
    scene : bpy.types.Scene
    depsgraph : bpy.types.Depsgraph, optional
        Evaluates the keyframe objects; default: the scene's first view layer's.
    resolution : int, optional
        The grid resolution; 0 or less means the scene setting.
    meshes : bool, optional
        Also read the keyframes' meshes, materials and the feature points (a bake), when
        every entry of the keyframe list is a mesh object in the scene. False reads only
        what the checks need, cheaply enough for every redraw of the panel.

    Returns
    -------
    BakeInput
    """
    settings = scene.keyframe_implicit
    if depsgraph is None:
        depsgraph = scene.view_layers[0].depsgraph
    kfs = list(settings.keyframes)
    objects = [kf.object for kf in kfs]
    found = list(features.pairs(scene).values())
    rows = _segment_rows(found, max(len(kfs) - 1, 0))
    resolution = int(resolution) if resolution and resolution > 0 else int(settings.resolution)
    listed = [_listed_keyframe(scene, kf, depsgraph) for kf in kfs]
    off_surface = _off_surface(found, listed, objects, resolution, depsgraph)
    inputs = BakeInput(
        keyframes=[], features=[],
        resolution=resolution,
        weights=settings.weights(),
        motion_resolution=settings.motion(),
        pair_ids=[[p.pair_id for p in seg] for seg in rows],
        feature_names=[[(p.a.name, p.b.name) for p in seg] for seg in rows],
        levelsets=bool(settings.volume_export),
        output_mode=str(settings.output_mode),
        key_interpolation=[str(kf.interpolation).lower() for kf in kfs],
        surface_tension=[float(kf.surface_tension) for kf in kfs[:-1]],
        listed_keyframes=listed,
        listed_pairs=[_listed_pair(p, objects, off_surface) for p in found],
        scene_frames=(int(scene.frame_start), int(scene.frame_end)),
        volume_problem=volumes.problem(settings),
    )
    if meshes and all(k.readable for k in inputs.listed_keyframes):
        inputs.keyframes, inputs.features = _read_on_frames(scene, kfs, rows, depsgraph)
        inputs.material_names = _material_names(objects)
    return inputs
