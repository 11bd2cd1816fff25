"""Feature points: paired Empties parented to their keyframe objects.

A feature pair says "this point of keyframe i goes to that point of keyframe
i+1" (thesis sec. 2.2: feature points drive the RBF initial map and are
matched exactly, eq. 2.14-2.20). Each side is an Empty parented to its
keyframe object (so it moves with it) and identified by custom properties:

``kfi_pair``     str, the pair id ("<segment>.<n>", e.g. "0.3")
``kfi_segment``  int i: the pair lies between keyframe i and keyframe i+1
``kfi_side``     "A" (on keyframe i) or "B" (on keyframe i+1)

Names ("KFI 0.3 A" / "KFI 0.3 B") and the object colour make a pair obvious
in the outliner and the viewport. Plain functions only; the operators in
`ops` are thin wrappers, and `edits` keeps the pairs when the keyframe list changes.
"""

from __future__ import annotations

import colorsys
import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any


import bpy
from mathutils import Matrix, Vector

if TYPE_CHECKING:
    from collections.abc import Iterator, Sequence

    from .props import KFI_Settings

PAIR = "kfi_pair"
SEGMENT = "kfi_segment"
SIDE = "kfi_side"
LABEL = "kfi_label"


@dataclass
class Pair:
    """The Empties of one pair id (either side may be missing: an unpaired Empty)."""

    pair_id: str
    segment: int
    a: bpy.types.Object | None = None
    b: bpy.types.Object | None = None
    label: str = ""

    @property
    def complete(self) -> bool:
        """Whether both sides have their Empty: only a complete pair guides the bake."""
        return self.a is not None and self.b is not None


def is_feature(obj: bpy.types.Object | None) -> bool:
    """True for an Empty that is one side of a feature pair."""
    return obj is not None and obj.type == "EMPTY" and PAIR in obj.keys()


def feature_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """All feature Empties of ``scene``, sorted by name."""
    return sorted((o for o in scene.objects if is_feature(o)), key=lambda o: o.name)


def pairs(scene: bpy.types.Scene) -> dict[str, Pair]:
    """Dict pair id -> `Pair`, sorted by segment then pair number.

    An Empty whose side is neither "A" nor "B", or whose side is already taken
    by another Empty of the same id, is reported under a key of its own
    (``"<id>#<object name>"``) so validation can point at it.
    """
    found = {}
    for obj in feature_objects(scene):
        pid = str(obj[PAIR])
        seg = _int(obj.get(SEGMENT), -1)
        side = str(obj.get(SIDE, ""))
        pair = found.get(pid)
        if pair is None:
            pair = found[pid] = Pair(pid, seg, label=str(obj.get(LABEL, "")))
        if side == "A" and pair.a is None and pair.segment == seg:
            pair.a = obj
        elif side == "B" and pair.b is None and pair.segment == seg:
            pair.b = obj
        else:
            found[f"{pid}#{obj.name}"] = Pair(pid, seg, a=obj if side == "A" else None,
                                              b=None if side == "A" else obj)
    return dict(sorted(found.items(), key=lambda kv: (kv[1].segment, _pair_number(kv[0]), kv[0])))


def _int(value: Any, default: int) -> int:
    try:
        return int(value)
    except (TypeError, ValueError):
        return default


def _pair_number(pid: str) -> int:
    try:
        return int(str(pid).split("#")[0].split(".")[1])
    except (IndexError, ValueError):
        return 1 << 30


def new_pair_id(scene: bpy.types.Scene, segment: int) -> str:
    """The next free id "<segment>.<n>" of a segment."""
    used = {_pair_number(p.pair_id) for p in pairs(scene).values() if p.segment == segment}
    n = 0
    while n in used:
        n += 1
    return f"{segment}.{n}"


def pair_color(pair_id: str) -> tuple[float, float, float, float]:
    """A distinct RGBA colour per pair (golden-angle hues), the same for both sides."""
    n = _pair_number(pair_id)
    if n >= (1 << 30):  # not "<segment>.<n>": a stable number from the id itself
        n = zlib.crc32(str(pair_id).encode()) % 97
    seg = _int(str(pair_id).split(".")[0], 0)
    hue = (0.618034 * n + 0.13 * seg) % 1.0
    r, g, b = colorsys.hsv_to_rgb(hue, 0.75, 1.0)
    return (r, g, b, 1.0)


def object_name(pair_id: str, side: str, label: str = "") -> str:
    """"KFI 0.3 A" or, with a label, "KFI 0.3 nose A"."""
    return f"KFI {pair_id} {label} {side}" if label else f"KFI {pair_id} {side}"


def display_size(keyframe_object: bpy.types.Object | None) -> float:
    """Empty size: a small share of the keyframe object's largest dimension, so that the
    Empties mark points on it without hiding its surface."""
    dims = keyframe_object.dimensions if keyframe_object is not None else (0.0, 0.0, 0.0)
    size = 0.025 * max(dims)
    return size if size > 0 else 0.03


def tag(empty: bpy.types.Object, pair_id: str, segment: int, side: str, label: str = "",
        keyframe_object: bpy.types.Object | None = None) -> None:
    """Make ``empty`` side ``side`` of pair ``pair_id``: properties, name, colour, look, parent."""
    empty[PAIR] = str(pair_id)
    empty[SEGMENT] = int(segment)
    empty[SIDE] = side
    if label:
        empty[LABEL] = label
    empty.name = object_name(pair_id, side, label)
    empty.color = pair_color(pair_id)
    empty.empty_display_type = "SPHERE"
    empty.empty_display_size = display_size(keyframe_object)
    empty.show_name = False  # many labels overlap; the selected one's name is in the header
    if keyframe_object is not None and empty.parent != keyframe_object:
        parent_keep_world(empty, keyframe_object)


def parent_keep_world(child: bpy.types.Object, parent: bpy.types.Object) -> None:
    """Parent ``child`` to ``parent`` without moving it in world space."""
    world = child.matrix_world.copy()
    child.parent = parent
    child.matrix_parent_inverse = parent.matrix_world.inverted()
    # world = parent_world @ parent_inverse @ basis  ->  basis = world (parent_inverse cancels)
    child.matrix_basis = world


def create_pair(scene: bpy.types.Scene, settings: KFI_Settings, segment: int,
                location_a: Sequence[float], location_b: Sequence[float], label: str = "") -> str:
    """Create the two Empties of a new pair between keyframe ``segment`` and ``segment + 1``.

    Raises ValueError (with what to do) when the segment has no keyframe objects.
    Returns the pair id.
    """
    kf_a, kf_b = segment_objects(settings, segment)
    pid = new_pair_id(scene, segment)
    made = []
    try:
        for side, kf, loc in (("A", kf_a, location_a), ("B", kf_b, location_b)):
            empty = bpy.data.objects.new(object_name(pid, side, label), None)
            made.append(empty)
            link_like(scene, empty, kf)
            empty.matrix_world = Matrix.Translation(Vector(loc))
            tag(empty, pid, segment, side, label, kf)
    except Exception:
        for obj in made:
            bpy.data.objects.remove(obj)
        raise
    return pid


def segment_objects(settings: KFI_Settings,
                    segment: int) -> tuple[bpy.types.Object, bpy.types.Object]:
    """The keyframe objects (A, B) of segment ``segment``; ValueError saying what to fix."""
    n = len(settings.keyframes)
    if n < 2:
        raise ValueError("Feature pairs join two keyframes: add at least two keyframes first.")
    if not 0 <= segment < n - 1:
        raise ValueError(f"Segment {segment} does not exist: with {n} keyframes the segments "
                         f"are 0..{n - 2} (segment i lies between keyframes i+1 and i+2 of the "
                         "list).")
    a = settings.keyframes[segment].object
    b = settings.keyframes[segment + 1].object
    for i, obj in ((segment, a), (segment + 1, b)):
        if obj is None:
            raise ValueError(f"Keyframe {i + 1} has no mesh object: pick one in the keyframe list.")
    return a, b


def link_like(scene: bpy.types.Scene, obj: bpy.types.Object,
               like: bpy.types.Object | None) -> None:
    """Link ``obj`` into the first collection of ``like`` that is in the scene (else the scene's):
    a feature Empty goes where its keyframe object is."""
    target = scene.collection
    if like is not None:
        scene_colls = set(scene_collections(scene))
        for coll in like.users_collection:
            if coll in scene_colls:
                target = coll
                break
    target.objects.link(obj)


def scene_collections(scene: bpy.types.Scene) -> Iterator[bpy.types.Collection]:
    """Every collection in ``scene``'s tree, its master collection first.

    Linking an object into a collection puts it in the scene only when that collection is
    one of these (`link_like`, and the output's collection in `output`).
    """
    stack = [scene.collection]
    while stack:
        coll = stack.pop()
        yield coll
        stack.extend(coll.children)


def remove_pair(scene: bpy.types.Scene, pair_id: str) -> int:
    """Delete both Empties of ``pair_id``; returns how many were removed."""
    removed = 0
    for obj in feature_objects(scene):
        if str(obj[PAIR]) == pair_id:
            bpy.data.objects.remove(obj)
            removed += 1
    return removed


def keyframe_indices(settings: KFI_Settings, obj: bpy.types.Object | None) -> list[int]:
    """Indices of the keyframes that use ``obj``."""
    return [i for i, kf in enumerate(settings.keyframes) if kf.object is not None and kf.object == obj]


def pair_empties(scene: bpy.types.Scene, settings: KFI_Settings, first: bpy.types.Object | None,
                 second: bpy.types.Object | None, segment: int = -1) -> str:
    """Turn two plain (or re-used) Empties into one pair.

    The side of each Empty comes from its parent when both are parented to the
    objects of adjacent keyframes i and i+1 (then the pair's segment is i);
    otherwise ``segment`` must be given and ``second`` (the active Empty) goes
    on keyframe ``segment + 1``. Returns the new pair id.
    """
    for e in (first, second):
        if e is None or e.type != "EMPTY":
            raise ValueError("Select exactly two Empties (the active one goes on the later keyframe).")
    seg, a, b = None, None, None
    ia = keyframe_indices(settings, first.parent) if first.parent else []
    ib = keyframe_indices(settings, second.parent) if second.parent else []
    for i in ia:
        if i + 1 in ib:
            seg, a, b = i, first, second
        elif i - 1 in ib:
            seg, a, b = i - 1, second, first
    if seg is None:
        if segment < 0:
            if len(settings.keyframes) == 2:
                segment = 0
            else:
                raise ValueError("Cannot tell which keyframes these Empties belong to: parent each "
                                 "to its keyframe object (Ctrl+P), or give the segment.")
        seg, a, b = segment, first, second
    kf_a, kf_b = segment_objects(settings, seg)
    pid = new_pair_id(scene, seg)
    for e in (a, b):
        for key in (PAIR, SEGMENT, SIDE, LABEL):
            if key in e.keys():
                del e[key]
    tag(a, pid, seg, "A", "", kf_a)
    tag(b, pid, seg, "B", "", kf_b)
    return pid


def select_pair(view_layer: bpy.types.ViewLayer, scene: bpy.types.Scene,
                pair_id: str) -> list[bpy.types.Object]:
    """Select both Empties of ``pair_id`` (B active); returns them."""
    found = [o for o in feature_objects(scene) if str(o[PAIR]) == pair_id]
    if not found:
        raise ValueError(f"No feature pair {pair_id!r} in this scene.")
    select_only(view_layer, sorted(found, key=lambda o: str(o.get(SIDE, ""))))
    return found


def select_only(view_layer: bpy.types.ViewLayer, chosen: Sequence[bpy.types.Object]) -> None:
    """Select ``chosen`` (shown, the last one active) and nothing else."""
    for obj in view_layer.objects:
        obj.select_set(False)
    for obj in chosen:
        obj.hide_set(False)
        obj.select_set(True)
    if chosen:
        view_layer.objects.active = chosen[-1]
