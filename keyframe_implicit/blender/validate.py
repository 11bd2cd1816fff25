"""Checks run before baking and shown in the sidebar, on the bake as read (`scene_io.read`).

`check` returns every issue of a bake's description (`scene_io.BakeInput`) as `Problem`
objects whose message says what is wrong AND what to do. ERROR problems block the bake;
WARNING problems are hints (e.g. fewer than 4 feature pairs is allowed by the core but
gives the solver a poor start). The checks read nothing from the scene: what only the
scene's objects can tell (a keyframe object's kind, its surface as the bake reads it, a
feature Empty's parent, how far it lies outside its keyframe's material) comes as plain
facts of the reading. `problems` reads a scene's setup and checks it (the panel, the Bake
button's poll); `raise_on_errors` refuses a bake.

The mesh checks (`mesh_problems`) judge each keyframe's evaluated mesh by the
bake's own measure (`core.fields.measure.read_mesh`: faces only, each part facing one
way): a keyframe that encloses no volume (a plane) is refused, in the words the bake's own
refusal uses; what the bake reads correctly as it is (faces facing inward, loose vertices,
holes, non-manifold edges) is a warning that says so. The core words what to fix in the
mesh's own terms (`core.bake.checks.FIXES`); `with_menu_paths` adds where Blender does it,
here and wherever the core's refusals and notes reach the artist. The panel and the Bake
button's poll ask on every redraw, so the readings are kept until a depsgraph update
changes some geometry (`scene_io.cached_reading`). Keyframes are numbered from 1 in list order, as the
core's messages number them; repeated problems of one kind are one line with a count. A
problem an operator fixes names it (`Problem.fix`): the panel offers its button.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..core.bake.checks import CLOSE_HOLES, FACE_OUTWARD, FIXES, THICKEN, no_volume_words
from ..core.fields.measure import MeshReading
from . import scene_io

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

    import bpy


ERROR = "ERROR"
WARNING = "WARNING"

MIN_PAIRS_HINT = 4

#: A feature Empty farther outside its keyframe's material than this many cells of the bake's
#: grid is pointed out: the bake pulls the material out to it. A warning, not an error, so
#: that whether a scene bakes does not depend on its resolution.
OFF_SURFACE_CELLS = 1.0
#: Empties a line names before it counts the rest.
NAMED = 2

#: Where Blender does each fix the core asks of a keyframe's mesh (`core.bake.checks.FIXES`).
MENU_PATHS = {CLOSE_HOLES: "Mesh > Clean Up > Fill Holes",
              THICKEN: "Solidify modifier",
              FACE_OUTWARD: "Mesh > Normals > Recalculate Outside"}


def with_menu_paths(message: str) -> str:
    """``message``, a refusal or note in the core's words, with Blender's menu path after
    each fix it asks for: "close its holes" becomes "close its holes (Mesh > Clean Up > Fill
    Holes)". Applied once, where the core's words reach the artist."""
    for fix in FIXES:
        if fix in MENU_PATHS:
            message = message.replace(fix, f"{fix} ({MENU_PATHS[fix]})")
    return message


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` ``noun``s in words: "no feature pairs", "1 feature pair", "3 feature pairs";
    ``plural`` where it is not ``noun`` + "s" ("loose vertices")."""
    return f"{n or 'no'} {noun if n == 1 else plural or noun + 's'}"


@dataclass(frozen=True)
class Problem:
    """One issue of a setup, as the panel lists it and a refused bake reports it.

    Attributes
    ----------
    severity : str
        `ERROR` (blocks the bake) or `WARNING` (a hint).
    message : str
        What is wrong and what to do.
    segment : int
        The segment it concerns, -1 for the whole setup.
    fix : str
        The operator that fixes it, offered beside the message ("" for none).
    """

    severity: str
    message: str
    segment: int = -1
    fix: str = ""

    @property
    def icon(self) -> str:
        """The panel's icon for its severity."""
        return "ERROR" if self.severity == ERROR else "INFO"


def problems(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None = None,
             ) -> list[Problem]:
    """All problems of ``scene``'s keyframe_implicit setup, errors first.

    Reads the setup without the keyframes' meshes (`scene_io.read` with
    ``meshes=False``, surface counts kept between calls) and checks it (`check`): cheap
    enough for the panel's every redraw.

    Parameters
    ----------
    scene : bpy.types.Scene
    depsgraph : bpy.types.Depsgraph, optional
        Gives the evaluated meshes of keyframes with modifiers for the mesh checks;
        default: the scene's first view layer's.

    Returns
    -------
    list of Problem
    """
    return check(scene_io.read(scene, depsgraph, meshes=False))


def check(inputs: scene_io.BakeInput) -> list[Problem]:
    """All problems of a bake's description, errors first.

    Parameters
    ----------
    inputs : scene_io.BakeInput
        The bake as read (`scene_io.read`); its keyframes' meshes are not needed.

    Returns
    -------
    list of Problem
        In the order the setup is read (keyframes, frames, feature pairs, export), errors
        before warnings.
    """
    listed = inputs.listed_keyframes
    out = _keyframe_problems(listed, inputs.listed_pairs)
    out += _frame_problems([k.frame for k in listed], inputs.scene_frames)
    out += _pair_problems(inputs.listed_pairs, listed)
    out += _off_surface_problems(inputs.listed_pairs)
    out += _motion_problems(inputs.motion_resolution, inputs.resolution)
    if inputs.volume_problem:
        out.append(Problem(ERROR, inputs.volume_problem))
    out.sort(key=lambda p: p.severity != ERROR)
    return out


def _motion_problems(motion_resolution: int | None, resolution: int) -> list[Problem]:
    """The core's own refusal of a Motion Resolution it cannot use (one measure)."""
    from ..core.bake.checks import check_motion_resolution

    try:
        check_motion_resolution(motion_resolution, resolution)
    except ValueError as exc:
        return [Problem(ERROR, f"{exc} (0: automatic)")]
    return []


def _keyframe_problems(listed: Sequence[scene_io.ListedKeyframe],
                       pairs: Sequence[scene_io.ListedPair]) -> list[Problem]:
    """Too few keyframes; entries without a mesh object in the scene (with what became of
    their feature Empties); unsound surfaces."""
    out = []
    if len(listed) < 2:
        out.append(Problem(ERROR, f"{count(len(listed), 'keyframe').capitalize()}: add at least "
                                  "two (select a mesh, set the frame, press Add Keyframe)."))
    for i, kf in enumerate(listed, start=1):
        name = f"Keyframe {i} '{kf.name}'" if kf.name is not None else f"Keyframe {i}"
        if kf.name is None:
            out.append(Problem(ERROR, f"{name} (frame {kf.frame}) has no object: pick a mesh "
                                      "object in its row or remove the keyframe."
                                      + _left_empties(i - 1, pairs)))
        elif kf.kind != "MESH":
            out.append(Problem(ERROR, f"{name} is not a mesh: convert it (Object > Convert > "
                                      "Mesh) or pick a mesh object."))
        elif not kf.in_scene:
            out.append(Problem(ERROR, f"{name} is not in this scene: link it into the scene or "
                                      "pick another object."))
        else:
            out += [Problem(severity, f"{name} {text}")
                    for severity, text in mesh_problems(kf.reading, kf.modified)]
    return out


def _left_empties(index: int, pairs: Sequence[scene_io.ListedPair]) -> str:
    """What became of the feature Empties of keyframe ``index`` (from 0) when its object
    went: "" when it had none."""
    n = sum((p.a is not None and p.segment == index) + (p.b is not None and p.segment == index - 1)
            for p in pairs)
    if not n:
        return ""
    one = n == 1
    return (f" Its {count(n, 'feature Empty', 'feature Empties')} {'stays' if one else 'stay'} "
            f"where {'it was' if one else 'they were'}, parented to nothing: the object you pick "
            f"takes {'it' if one else 'them'}. Removing the keyframe joins the pairs through it.")


def _frame_problems(frames: Sequence[int], scene_frames: tuple[int, int]) -> list[Problem]:
    """Two keyframes on one frame; a list out of frame order; frames outside the scene's."""
    out = []
    seen: dict[int, int] = {}
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
    start, end = scene_frames
    for i, f in enumerate(frames, start=1):
        if not start <= f <= end:
            out.append(Problem(WARNING, f"Keyframe {i} is on frame {f}, outside the scene's "
                                        f"frames {start}-{end}: Bake widens the frame range to "
                                        "cover it."))
    return out


def _pair_problems(pairs: Iterable[scene_io.ListedPair],
                   listed: Sequence[scene_io.ListedKeyframe]) -> list[Problem]:
    """Pairs of missing segments, lone Empties, Empties off their keyframe objects (one line
    per segment, side and parent), and segments with few pairs."""
    out = []
    counts = [0] * max(len(listed) - 1, 0)
    # (segment, keyframe number, parent) -> names of the Empties parented there
    off: dict[tuple[int, int, str | None], list[str]] = {}
    for pair in pairs:
        name = pair.a if pair.a is not None else pair.b
        if not 0 <= pair.segment < len(counts):
            out.append(Problem(ERROR, f"Feature '{name}' is for keyframes {pair.segment + 1} and "
                                      f"{pair.segment + 2}, which do not exist: remove the pair."))
            continue
        if not pair.complete:
            out.append(Problem(ERROR, f"Feature '{name}' has no partner: delete it, or select it "
                                      "with another Empty and press Pair Selected.", pair.segment))
            continue
        for side, parent in pair.unparented:
            empty, number = (pair.a, pair.segment + 1) if side == "A" else (pair.b, pair.segment + 2)
            off.setdefault((pair.segment, number, parent), []).append(empty)
        counts[pair.segment] += 1
    out += _off_keyframe_problems(off, listed)
    for seg, n in enumerate(counts):
        if n < MIN_PAIRS_HINT:
            out.append(Problem(WARNING, f"Keyframes {seg + 1} \u2192 {seg + 2} have "
                                        f"{count(n, 'feature pair')}: {MIN_PAIRS_HINT} or more on "
                                        "distinctive points guide the motion better (Add Feature "
                                        "Pair).", seg))
    return out


def _off_surface_problems(pairs: Iterable[scene_io.ListedPair]) -> list[Problem]:
    """One line naming the feature Empties that lie more than `OFF_SURFACE_CELLS` outside
    their keyframe's material, with the Snap to Surface button."""
    far = [(cells, pair.a if side == "A" else pair.b, pair.segment + (side == "B") + 1)
           for pair in pairs for side, cells in pair.off_surface if cells > OFF_SURFACE_CELLS]
    if not far:
        return []
    far.sort(key=lambda f: -f[0])
    if len(far) == 1:
        cells, name, number = far[0]
        what = (f"Feature '{name}' lies {cells:.1f} grid cells outside keyframe {number}: the "
                "bake pulls that keyframe's material out to it")
    else:
        named = ", ".join(f"'{name}'" for _, name, _ in far[:NAMED])
        rest = f" and {len(far) - NAMED} more" if len(far) > NAMED else ""
        what = (f"{len(far)} feature Empties lie more than one grid cell outside their keyframes "
                f"({named}{rest}, up to {far[0][0]:.1f} cells): the bake pulls the material out "
                "to them")
    return [Problem(WARNING, f"{what}. Snap to Surface moves "
                             f"{'it' if len(far) == 1 else 'them'} onto the nearest surface.",
                    fix="keyframe_implicit.snap_features")]


def _off_keyframe_problems(off: dict[tuple[int, int, str | None], list[str]],
                           listed: Sequence[scene_io.ListedKeyframe]) -> list[Problem]:
    """One line per kind of feature Empty off its keyframe object (`_off_kind`), with the advice
    that fits: Empties on another keyframe of the list guide the wrong keyframes (an
    `ERROR`); unparented ones or ones parented elsewhere are read where they are (a
    `WARNING`)."""
    kinds: dict[str, list[tuple[int, int, str | None]]] = {}
    for where in off:
        kinds.setdefault(_off_kind(where[2], listed), []).append(where)
    out = []
    for kind, groups in kinds.items():
        severity = ERROR if kind == "listed" else WARNING
        if len(groups) == 1:
            seg, number, parent = groups[0]
            out.append(Problem(severity, _off_keyframe(seg, number, parent, off[groups[0]], listed),
                               seg))
            continue
        n = sum(len(off[g]) for g in groups)
        segments = len({g[0] for g in groups})
        which = f"{n} feature Empties of {count(segments, 'segment')}"
        out.append(Problem(severity, which + {
            "none": " are not parented to their keyframes: they do not follow those objects; "
                    "parent each to its keyframe (Ctrl+P > Keep Transform).",
            "listed": " are on other keyframes of the list than theirs: the keyframe list changed "
                      "since they were placed. Move them onto their keyframes and parent them to "
                      "them, or remove those pairs.",
            "other": " are parented to other objects than their keyframes: parent each to its "
                     "keyframe (Ctrl+P > Keep Transform).",
        }[kind]))
    return out


def _off_kind(parent: str | None, listed: Sequence[scene_io.ListedKeyframe]) -> str:
    """"none" (parented to nothing), "listed" (to another keyframe of the list) or "other"."""
    if parent is None:
        return "none"
    return "listed" if any(kf.name == parent for kf in listed) else "other"


def _off_keyframe(seg: int, number: int, parent: str | None, empties: Sequence[str],
                  listed: Sequence[scene_io.ListedKeyframe]) -> str:
    """One line for the feature Empties of segment ``seg`` meant to sit on keyframe ``number``
    but parented to ``parent`` (an object name, or None), with the advice that fits."""
    target = f"keyframe {number} '{listed[number - 1].name}'"
    one = len(empties) == 1
    which = (f"'{empties[0]}'" if one else
             f"{len(empties)} feature Empties of keyframes {seg + 1} \u2192 {seg + 2}")
    it, does, are, were = ("it", "it does", "is", "was") if one else ("them", "they do", "are", "were")
    if parent is None:
        return (f"{which} {are} not parented to {target}: {does} not follow that object; "
                f"parent {it} to it (Ctrl+P > Keep Transform).")
    on = [i for i, kf in enumerate(listed, start=1) if kf.name == parent]
    if on:  # a keyframe was added or moved between the pair's two keyframes
        return (f"{which} {are} on keyframe {on[0]} '{parent}', not on {target}: the keyframe "
                f"list changed since {'it' if one else 'they'} {were} placed. Move {it} onto "
                f"'{listed[number - 1].name}' and parent {it} to it, or remove those pairs.")
    return (f"{which} {are} parented to '{parent}', not to {target}: parent {it} to "
            f"'{listed[number - 1].name}' (Ctrl+P > Keep Transform).")


def mesh_problems(reading: MeshReading, modified: bool = False) -> list[tuple[str, str]]:
    """``(severity, message)`` of each problem of a keyframe's mesh (none when it is sound).

    Parameters
    ----------
    reading : core.fields.measure.MeshReading
        The keyframe object's evaluated mesh as the bake reads it.
    modified : bool
        Whether that mesh is the object's after its modifiers.

    Returns
    -------
    list of (str, str)
        A surface that encloses no volume, such as a plane, is the one `ERROR`, worded as
        the bake's own refusal words it (`core.bake.checks.no_volume_words`, with Blender's
        menu paths: `with_menu_paths`). Faces facing
        inward, loose vertices, holes and non-manifold edges the bake reads correctly as
        they are: `WARNING` s that say so and how to clean the mesh. Each message follows
        the keyframe's name ("Keyframe 2 'Plane' ...").
    """
    if reading.triangles == 0:
        after = " after its modifiers" if modified else ""
        return [(ERROR, f"has no faces{after}: a keyframe must be a closed surface.")]
    if not reading.encloses_volume:
        return [(ERROR, with_menu_paths(no_volume_words(reading)))]
    out: list[tuple[str, str]] = []
    if reading.reoriented:
        out.append((WARNING, with_menu_paths(
            f"has {count(reading.reoriented, 'triangle')} facing inward: the bake reads it "
            f"correctly as it is; to clean the mesh, {FACE_OUTWARD}.")))
    if reading.loose:
        where = (f"up to {reading.loose_reach:.3g} units outside its faces" if
                 reading.loose_reach > 0 else "among its faces")
        out.append((WARNING, f"has {count(reading.loose, 'loose vertex', 'loose vertices')} "
                             f"(in no face), {where}: the bake ignores "
                             f"{'it' if reading.loose == 1 else 'them'}; Select > Select All by "
                             f"Trait > Loose Geometry finds {'it' if reading.loose == 1 else 'them'}."))
    if reading.open_edges:
        out.append((WARNING, with_menu_paths(f"has holes ({reading.open_edges} open edges): the "
                                             f"bake fills small ones; to be sure, {CLOSE_HOLES}.")))
    if reading.shared_edges:
        out.append((WARNING, f"is non-manifold ({reading.shared_edges} edges shared by 3 or more "
                             "faces): if its parts come out wrong, find them with Select > Select "
                             "All by Trait > Non Manifold."))
    return out


def errors(found: Iterable[Problem]) -> list[Problem]:
    """The `ERROR` problems among ``found`` (those that block a bake), in order."""
    return [p for p in found if p.severity == ERROR]


def raise_on_errors(inputs: scene_io.BakeInput) -> None:

    """Refuse to bake a description with blocking problems.

    Parameters
    ----------
    inputs : scene_io.BakeInput
        The bake as read, with its keyframes' meshes (`scene_io.read`).

    Raises
    ------
    ValueError
        Listing every blocking problem of `check` (what is wrong and what to do); else
        naming the first keyframe whose mesh, read on its own frame, has no faces (its
        modifiers may empty it on that frame only).
    """
    errs = errors(check(inputs))
    if errs:
        raise ValueError("Cannot bake: " + " ".join(p.message for p in errs))
    for i, kf in enumerate(inputs.keyframes):
        if len(kf.faces) == 0:
            raise ValueError(f"Keyframe {i} ('{kf.name}', frame {kf.frame}) has no faces after "
                             "modifiers on that frame: check its modifier stack (a keyframe must "
                             "be a closed surface).")
