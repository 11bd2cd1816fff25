"""Edits of the keyframe list that keep the feature pairs, and Empties snapped to their surface.

Feature pairs belong to segments by index (`features`: pair "<segment>.<n>" joins keyframe
``segment`` to keyframe ``segment + 1`` of the list), so inserting or removing a keyframe
changes what every later pair means. These functions keep the setup:

- `keyframe_inserted`: later pairs move up one segment; each pair spanning the new keyframe
  becomes two, A -> new and new -> B, whose two new Empties sit on the new keyframe's
  surface where that material is (`proposed_points`). The operator selects them for review.
- `keyframe_removed`: later pairs move down one segment; the pairs A -> M and M -> B through
  the removed keyframe M whose Empties on M meet (`JOIN_REACH`) are joined into A -> B, their
  Empties on M removed; the rest of M's pairs are deleted.
- `object_picked`: a keyframe whose object was deleted takes the Empties it left, unparented,
  when an object is picked for it.
- `snap`: Empties outside their keyframe's material moved onto its nearest surface point.

The keyframe objects are never changed: only the feature Empties are made, moved, renamed
and removed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import bpy
import numpy as np
from mathutils import Matrix, Vector

from . import features, output, scene_io

if TYPE_CHECKING:
    from collections.abc import Sequence

    from .props import KFI_Keyframe, KFI_Settings

#: Two Empties on a removed keyframe mark the same point (their pairs are joined through it)
#: when they lie within this share of the keyframe's largest side of each other.
JOIN_REACH = 0.05
#: Vertices of a baked path whose motion carries an Empty (their mean, nearest first).
PATH_VERTICES = 4


@dataclass
class Insertion:
    """What `keyframe_inserted` did.

    Attributes
    ----------
    proposed : list of bpy.types.Object
        The new Empties on the new keyframe, two per pair that spanned it.
    split : int
        Pairs that spanned the new keyframe, each now two pairs.
    from_bake : bool
        Whether the new Empties were placed by the baked output's paths (else on the straight
        path between the pair's points, put on the new keyframe's surface).
    """

    proposed: list[bpy.types.Object] = field(default_factory=list)
    split: int = 0
    from_bake: bool = False


@dataclass
class Removal:
    """What `keyframe_removed` did.

    Attributes
    ----------
    joined : int
        Pairs A -> M and M -> B joined into one pair A -> B.
    empties : int
        Empties removed from the removed keyframe M.
    deleted : int
        Pairs deleted: through M without a partner on its other side, or of a first or last M.
    """

    joined: int = 0
    empties: int = 0
    deleted: int = 0


def _shift(found: Sequence[features.Pair], first: int, step: int) -> None:
    """Move the complete pairs of segments ``first`` and later by ``step`` segments, keeping
    their numbers: "2.3" becomes "3.3" for ``step`` 1. Renamed in the order that frees each
    new name before it is taken (Blender would add ".001" to a name in use)."""
    moving = [p for p in found if p.complete and p.segment >= first]
    moving.sort(key=lambda p: p.segment, reverse=step > 0)
    for pair in moving:
        _retag(pair.a, pair.segment + step, _number(pair), "A", pair.label)
        _retag(pair.b, pair.segment + step, _number(pair), "B", pair.label)


def _number(pair: features.Pair) -> str:
    return pair.pair_id.split(".", 1)[1]


def _retag(empty: bpy.types.Object, segment: int, number: str, side: str, label: str) -> None:
    """Make ``empty`` side ``side`` of pair "<segment>.<number>" (its parent is left alone)."""
    pair_id = f"{segment}.{number}"
    empty[features.PAIR] = pair_id
    empty[features.SEGMENT] = segment
    empty[features.SIDE] = side
    empty.name = features.object_name(pair_id, side, label)
    empty.color = features.pair_color(pair_id)


def keyframe_inserted(scene: bpy.types.Scene, settings: KFI_Settings, index: int,
                      depsgraph: bpy.types.Depsgraph) -> Insertion:
    """Keep the pairs after a keyframe was inserted at ``index`` of the list.

    Parameters
    ----------
    scene : bpy.types.Scene
    settings : KFI_Settings
        The scene's settings, the new keyframe already in its list.
    index : int
        The new keyframe's place in the list (from 0).
    depsgraph : bpy.types.Depsgraph
        Evaluates the new keyframe's mesh.

    Returns
    -------
    Insertion
        Pairs of later segments have moved up one; each pair "i.n" of the segment the new
        keyframe splits (i = index - 1) stays "i.n" with a new Empty B on the new keyframe, and
        a new pair "index.n" leads from a second new Empty there to its old Empty B.
    """
    found = list(features.pairs(scene).values())
    _shift(found, index, 1)
    done = Insertion()
    spanning = [p for p in found if p.complete and p.segment == index - 1]
    new = settings.keyframes[index]
    if not spanning or new.object is None or not 0 < index < len(settings.keyframes) - 1:
        return done
    before, after = settings.keyframes[index - 1], settings.keyframes[index + 1]
    points, done.from_bake = proposed_points(scene, spanning, (before.frame, new.frame, after.frame),
                                             new.object, depsgraph)
    done.split = len(spanning)
    for pair, point in zip(spanning, points):
        number = _number(pair)
        _retag(pair.b, index, number, "B", pair.label)
        for segment, side in ((index - 1, "B"), (index, "A")):
            empty = bpy.data.objects.new(features.object_name(f"{segment}.{number}", side), None)
            features.link_like(scene, empty, new.object)
            empty.matrix_world = Matrix.Translation(Vector(point))
            features.tag(empty, f"{segment}.{number}", segment, side, pair.label, new.object)
            done.proposed.append(empty)
    return done


def proposed_points(scene: bpy.types.Scene, spanning: Sequence[features.Pair],
                    frames: tuple[int, int, int], keyframe: bpy.types.Object,
                    depsgraph: bpy.types.Depsgraph) -> tuple[np.ndarray, bool]:
    """Where the material of each spanning pair is on a new keyframe: (P, 3) world points,
    and whether the baked output's paths gave them.

    The pair's Empty A moves as the baked output's nearest `PATH_VERTICES` vertices move from
    the earlier keyframe's frame to the new one's (`_baked_motion`); without a shape-key
    output covering both frames, it moves along the straight path to its Empty B, to where
    it is at the new keyframe's frame. The Empty then goes to the nearest point of the new
    keyframe's surface (`scene_io.Surface.nearest`), inside or outside: feature points mark
    the surface, and a keyframe unlike the in-between there (a ball larger than the two it
    joins) holds the moved point deep in its material, where the artist neither sees nor
    picks it.
    """
    fa, fm, fb = frames
    a = np.array([tuple(p.a.matrix_world.translation) for p in spanning])
    b = np.array([tuple(p.b.matrix_world.translation) for p in spanning])
    moved = _baked_motion(scene, a, fa, fm)
    if moved is None:
        s = (fm - fa) / (fb - fa) if fb != fa else 0.5
        points = (1.0 - s) * a + s * b
    else:
        points = a + moved
    if scene_io.cached_reading(keyframe, depsgraph).triangles == 0:  # nothing to put them on
        return points, moved is not None
    return scene_io.cached_surface(keyframe, depsgraph).nearest(points)[0], moved is not None


def _baked_motion(scene: bpy.types.Scene, points: np.ndarray, start: int,
                  end: int) -> np.ndarray | None:
    """How the baked material near each of ``points`` (P, 3) on frame ``start`` moves by frame
    ``end`` (P, 3): the mean of the nearest `PATH_VERTICES` vertices' moves in the shape-key
    output, whose vertices keep their identity from frame to frame. None without such an
    output holding both frames."""
    from scipy.spatial import cKDTree

    out = scene.keyframe_implicit.output_object
    keys = out.data.shape_keys if out is not None and out.type == "MESH" else None
    if keys is None:
        return None
    blocks = [keys.key_blocks.get(output.frame_key_name(f)) for f in (start, end)]
    if any(kb is None for kb in blocks):
        return None
    matrix = np.array(out.matrix_world)
    shapes = []
    for kb in blocks:
        co = np.empty(len(kb.points) * 3, dtype=np.float32)
        kb.points.foreach_get("co", co)
        shapes.append(co.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3])
    k = min(PATH_VERTICES, len(shapes[0]))
    _, near = cKDTree(shapes[0]).query(points, k=k)
    near = near.reshape(len(points), k)
    return (shapes[1][near] - shapes[0][near]).mean(axis=1)


def keyframe_removed(scene: bpy.types.Scene, settings: KFI_Settings, index: int) -> Removal:
    """Keep the pairs consistent before keyframe ``index`` leaves the list.

    Pairs A -> M (segment index - 1) and M -> B (segment index) whose Empties on M lie within
    `JOIN_REACH` of each other, matched one to one, nearest first, become one pair A -> B
    (segment index - 1, the first pair's id) and their Empties on M are removed; the other
    pairs touching M are deleted; pairs of later segments move down one.

    Returns
    -------
    Removal
    """
    found = list(features.pairs(scene).values())
    into = [p for p in found if p.complete and p.segment == index - 1]
    out_of = [p for p in found if p.complete and p.segment == index]
    done = Removal()
    for first, second in _matches(into, out_of, settings.keyframes[index].object):
        number, label = _number(first), first.label
        for empty in (first.b, second.a):
            bpy.data.objects.remove(empty)
        _retag(second.b, index - 1, number, "B", label)
        into.remove(first)
        out_of.remove(second)
        done.joined += 1
        done.empties += 2
    lone = [p for p in found if not p.complete and p.segment in (index - 1, index)]
    for pair in into + out_of + lone:
        done.deleted += 1 if features.remove_pair(scene, pair.pair_id) else 0
    _shift(list(features.pairs(scene).values()), index + 1, -1)
    return done


def _matches(into: Sequence[features.Pair], out_of: Sequence[features.Pair],
             keyframe: bpy.types.Object | None) -> list[tuple[features.Pair, features.Pair]]:
    """Pairs (A -> M, M -> B) whose Empties on M lie within `JOIN_REACH` of M's largest side
    (of their own box when M has no object), one to one, the nearest first."""
    if not into or not out_of:
        return []
    ends = np.array([tuple(p.b.matrix_world.translation) for p in into])
    starts = np.array([tuple(p.a.matrix_world.translation) for p in out_of])
    size = (max(keyframe.dimensions) if keyframe is not None else
            float(np.ptp(np.vstack([ends, starts]), axis=0).max()))
    dist = np.linalg.norm(ends[:, None] - starts[None], axis=2)
    found, used_a, used_b = [], set(), set()
    for i, j in zip(*np.unravel_index(np.argsort(dist, axis=None), dist.shape)):
        if dist[i, j] > JOIN_REACH * size:
            break
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            found.append((into[i], out_of[j]))
    return found


def object_picked(keyframe: KFI_Keyframe, _context: bpy.types.Context) -> None:
    """A keyframe's object was set (`props.ON_CHANGE`): it takes the feature Empties meant
    for it that are parented to nothing (its object was deleted), keeping them where they
    are."""
    obj = keyframe.object
    if obj is None:
        return
    scene = keyframe.id_data
    kfs = list(scene.keyframe_implicit.keyframes)
    index = next(i for i, kf in enumerate(kfs) if kf.as_pointer() == keyframe.as_pointer())
    for _, _, empty in scene_io.empties_on(features.pairs(scene).values(), len(kfs)).get(index, ()):
        if empty.parent is None:
            features.parent_keep_world(empty, obj)


def snap(scene: bpy.types.Scene, names: Sequence[str],
         depsgraph: bpy.types.Depsgraph) -> list[str]:
    """Move the feature Empties ``names`` that lie outside their keyframe's material onto the
    nearest point of its surface; returns the names of those moved.

    An Empty of a pair of an existing segment is moved; others (lone, or of a keyframe
    without a closed mesh) are left where they are.
    """
    settings = scene.keyframe_implicit
    objects = [kf.object for kf in settings.keyframes]
    wanted = set(names)
    moved = []
    for i, rows in scene_io.empties_on(features.pairs(scene).values(), len(objects)).items():
        rows = [e for _, _, e in rows if e.name in wanted]
        obj = objects[i]
        if not rows or obj is None or obj.type != "MESH":
            continue
        if scene_io.cached_reading(obj, depsgraph).triangles == 0:
            continue
        closest, outside = scene_io.cached_surface(obj, depsgraph).nearest(np.array([tuple(e.matrix_world.translation)
                                                     for e in rows]))
        for empty, point, far in zip(rows, closest, outside):
            if far > 0:
                world = empty.matrix_world.copy()
                world.translation = Vector(point)
                empty.matrix_world = world
                moved.append(empty.name)
    return moved


def off_surface(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph,
                cells: float) -> list[str]:
    """Names of the feature Empties more than ``cells`` cells of the bake's grid outside
    their keyframe's material (as the checks read them: `scene_io.ListedPair.off_surface`)."""
    inputs = scene_io.read(scene, depsgraph, meshes=False)
    return [pair.a if side == "A" else pair.b for pair in inputs.listed_pairs
            for side, far in pair.off_surface if far > cells]
