"""The bake's inputs checked before any heavy work, and its result checked after.

Every refusal names the keyframe (its number, object name and frame) or the feature
pair (the Empties' names) and says what to fix; the notes say what was repaired on the
way (loose vertices ignored, faces reoriented).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Iterable, Mapping, Sequence

    from numpy.typing import ArrayLike

    from ..base.grid import Grid
    from ..fields.measure import MeshReading
    from .animation import Animation
    from .keyframe import Keyframe

    #: Per segment, per feature pair, the two Empties' names (on keyframe A, on B).
    FeatureNames = Sequence[Sequence[tuple[str, str]]]


__all__ = ["check_motion_resolution", "keyframe_label", "checked_mesh", "no_volume_words", "check_inputs", "check_feature_reach", "rigid_sweep", "check_feature_spacing", "no_volume_message", "check_result", "notes", "CLOSE_HOLES", "THICKEN", "FACE_OUTWARD", "FIXES"]

#: What a refusal or a note asks the artist to do to a keyframe's mesh, in the mesh's own
#: terms. Each is worded here only; an application adds where its tools do it (the Blender
#: side, `blender.validate.with_menu_paths`, puts the menu path after these words).
CLOSE_HOLES = "close its holes"
THICKEN = "give it thickness"
FACE_OUTWARD = "turn them to face outward"
FIXES = (CLOSE_HOLES, THICKEN, FACE_OUTWARD)


def keyframe_label(k: int, kf: Keyframe) -> str:
    """"Keyframe 1 ('Ball', frame 1)" for keyframes[0]: numbered from 1, as in the panel."""
    name = getattr(kf, "name", "")
    n = k + 1
    return f"Keyframe {n} ('{name}', frame {kf.frame})" if name else f"Keyframe {n} (frame {kf.frame})"


def _segment_label(i: int) -> str:
    """"keyframes 1 → 2" for segment 0 (keyframes[0] -> keyframes[1]), as in the panel."""
    return f"keyframes {i + 1} → {i + 2}"


def checked_mesh(k: int, kf: Keyframe) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """(vertices (V, 3), triangles, loose, face vertices) of a keyframe; loose counts vertices
    of no face. Refuses, before any grid work, a keyframe that encloses no volume
    (`fields.measure.read_mesh`, the measure the Blender panel judges it by too)."""
    from ..fields.measure import read_mesh
    from ..fields.mesh import check_vertices, triangulate

    label = keyframe_label(k, kf)
    try:
        v = check_vertices(kf.vertices)
        tris = triangulate(kf.faces, len(v))
    except ValueError as exc:
        raise ValueError(f"{label}: {exc}") from None
    reading = read_mesh(v, tris)
    if not reading.encloses_volume:
        raise ValueError(f"{label} {no_volume_words(reading)}")
    used = np.zeros(len(v), dtype=bool)
    used[tris.reshape(-1)] = True
    return v, tris, reading.loose, v[used]


def no_volume_words(reading: MeshReading) -> str:
    """What is wrong with a keyframe mesh that encloses no volume and what to do (`FIXES`), after
    the keyframe's name ("Keyframe 2 'Plane' is open and ...").

    Parameters
    ----------
    reading : fields.measure.MeshReading
        A reading whose ``encloses_volume`` is False.
    """
    if reading.triangles == 0:
        return "has only faces of zero area: a keyframe must be a closed surface."
    if reading.open_edges:
        return (f"is open ({reading.open_edges} open edges) and encloses no volume: "
                f"{CLOSE_HOLES}, or {THICKEN}.")
    return ("encloses no volume (it is flat, or made of parts that cancel, such as a copy "
            f"turned inside out on top of it): {THICKEN}.")


def _feature_array(points: ArrayLike, what: str) -> np.ndarray:
    """A feature array as (N, 3) float; ValueError for any other shape (never reshaped)."""
    try:
        a = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be numbers in an (N, 3) array.") from None
    if a.size == 0:
        return np.zeros((0, 3))
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{what} must have shape (N, 3), one row of x, y, z per point; got "
                         f"shape {a.shape}.")
    return a


def _feature_label(names: FeatureNames | None, i: int, j: int, side: int) -> str:
    """'KFI 0.3 A' (the Empty) when names are known, else "feature point 1 of keyframes 1 → 2
    (on keyframe 1)" for row 0 of segment 0's side 0."""
    if names is not None and i < len(names) and j < len(names[i]):
        return f"feature point '{names[i][j][side]}'"
    return f"feature point {j + 1} of {_segment_label(i)} (on keyframe {i + side + 1})"


def check_inputs(keyframes: Iterable[Keyframe], features: Iterable[tuple[ArrayLike, ArrayLike]],
                 feature_names: FeatureNames | None = None,
                 ) -> tuple[list[Keyframe], list[tuple[np.ndarray, np.ndarray]]]:
    """Keyframes and (N, 3) feature arrays, every problem named before any work."""
    keyframes = list(keyframes)
    if len(keyframes) < 2:
        raise ValueError(f"Need at least two keyframes, got {len(keyframes)}: add another keyframe.")
    frames = [kf.frame for kf in keyframes]
    if any(int(f) != f for f in frames):
        raise ValueError(f"Keyframe frames must be whole numbers, got {frames}.")
    if any(b <= a for a, b in zip(frames, frames[1:])):
        raise ValueError(f"Keyframes must be on strictly increasing frames, got {frames}: "
                         "give each keyframe its own frame, in timeline order.")
    features = list(features)
    if len(features) != len(keyframes) - 1:
        raise ValueError(f"{len(keyframes)} keyframes need {len(keyframes) - 1} sets of feature "
                         f"pairs (one per segment), got {len(features)}.")
    clean: list[tuple[np.ndarray, np.ndarray]] = []
    for i, pair in enumerate(features):
        try:
            pa, pb = pair
        except (TypeError, ValueError):
            raise ValueError(f"Features of {_segment_label(i)}: they must be a pair "
                             "(points_a, points_b).") from None
        fa = _feature_array(pa, f"Features of {_segment_label(i)}: the points on keyframe {i + 1}")
        fb = _feature_array(pb, f"Features of {_segment_label(i)}: the points on keyframe {i + 2}")
        if len(fa) != len(fb):
            raise ValueError(f"Features of {_segment_label(i)}: {len(fa)} points on keyframe {i + 1} "
                             f"but {len(fb)} on keyframe {i + 2}; every point needs a partner.")
        for side, arr in ((0, fa), (1, fb)):
            bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
            if len(bad):
                raise ValueError(f"The {_feature_label(feature_names, i, int(bad[0]), side)} has a "
                                 "NaN or infinite coordinate: move it onto its keyframe.")
        clean.append((fa, fb))
    return keyframes, clean


def check_feature_reach(features: Sequence[tuple[np.ndarray, np.ndarray]], lo: np.ndarray,
                        hi: np.ndarray, feature_names: FeatureNames | None) -> None:
    """Refuse feature points farther outside the keyframes' box than the box's size.

    Such a point (an Empty left far away) would stretch the grid around
    nothing and leave the keyframes a few cells wide.
    """
    size = float(np.max(hi - lo))
    for i, pair in enumerate(features):
        for side, pts in enumerate(pair):
            if not len(pts):
                continue
            out = np.linalg.norm(np.maximum(np.maximum(lo - pts, pts - hi), 0.0), axis=1)
            j = int(np.argmax(out))
            if out[j] > size:
                raise ValueError(
                    f"The {_feature_label(feature_names, i, j, side)} is {out[j]:.3g} away from "
                    f"the keyframes (which are {size:.3g} across): move it onto keyframe "
                    f"{i + side + 1}, or delete the pair.")


def rigid_sweep(points: Sequence[np.ndarray], features: Iterable[tuple[ArrayLike, ArrayLike]],
                steps: int = 8, most: int = 2048) -> list[np.ndarray]:
    """Points along each segment's rigid part of the motion, for the grid to hold.

    A body turning between two keyframes sweeps past both keyframes' boxes (a square's
    corner half-way through a quarter turn lies 41 % of its half-width beyond them), and
    a fixed padding in cells shrinks as the resolution grows. Where a segment has three
    feature pairs or more, the best rigid motion between them (`rotations.rigid_fit`)
    carries keyframe A's points forward and B's backward through ``steps`` in-betweens
    (at most ``most`` points of each); their positions are returned, one array per
    segment.
    """
    from ..base.rotations import rigid_fit, rotation_exp, rotation_log

    out: list[np.ndarray] = []
    for k, (fa, fb) in enumerate(features):
        fa, fb = np.asarray(fa, dtype=float), np.asarray(fb, dtype=float)
        if len(fa) < 3 or np.linalg.matrix_rank(fa - fa.mean(axis=0)) < 2:
            continue  # no rotation is known
        xb, yb, R = rigid_fit(fa, fb)
        rv = rotation_log(R[None])[0]
        a = points[k][:: max(1, len(points[k]) // most)]
        b = points[k + 1][:: max(1, len(points[k + 1]) // most)]
        for s in np.arange(1, steps) / steps:
            centre = xb + s * (yb - xb)
            out.append(centre + (a - xb) @ rotation_exp(s * rv, 3).T)
            out.append(centre + (b - yb) @ rotation_exp((s - 1.0) * rv, 3).T)
    return out


def check_feature_spacing(features: Sequence[tuple[np.ndarray, np.ndarray]], h: float,
                          feature_names: FeatureNames | None, grid_name: str = "grid",
                          raise_what: str = "resolution") -> None:
    """Refuse two feature points closer than one cell of the ``grid_name`` (spacing ``h``)
    whose partners are farther apart.

    The grid the maps are solved on cannot tell the two points apart, yet the map would
    have to pull them more than two cells apart (or the reverse): it tears space between
    them, and the initial map sends points far off.
    """
    for i, (fa, fb) in enumerate(features):
        if len(fa) < 2:
            continue
        da = np.linalg.norm(fa[:, None] - fa[None], axis=2)
        db = np.linalg.norm(fb[:, None] - fb[None], axis=2)
        for side, near, other in ((0, da, db), (1, db, da)):
            close = np.argwhere(np.triu((near < h) & (other > 2 * h), k=1))
            if not len(close):
                continue
            j, k = (int(x) for x in close[0])
            first = _feature_label(feature_names, i, j, side)
            second = _feature_label(feature_names, i, k, side)
            raise ValueError(
                f"The {first} and the {second} are {near[j, k]:.3g} apart on keyframe {i + side + 1}, "
                f"less than one {grid_name} cell ({h:.3g}), but their partners are {other[j, k]:.3g} "
                f"apart: move them apart or delete one of the pairs (or raise the {raise_what}).")


def no_volume_message(k: int, kf: Keyframe, v: np.ndarray, tris: np.ndarray, grid: Grid) -> str:
    """Why a keyframe has no inside node on the grid, with the advice that fits (`FIXES`)."""
    label = keyframe_label(k, kf)
    cells = float(np.max(np.ptp(v[np.unique(tris)], axis=0))) / grid.spacing
    if cells < 3:
        return (f"{label} is only {cells:.1f} grid cells across: the grid spans all keyframes and "
                "feature points, which are far apart compared to this keyframe. Move them closer "
                "together or raise the resolution.")
    from ..fields.measure import read_mesh

    open_edges = read_mesh(v, tris).open_edges
    if open_edges:
        return (f"{label} encloses no volume: its surface has {open_edges} open edges; "
                f"{CLOSE_HOLES}.")
    return (f"{label} encloses no volume on a grid of cell size {grid.spacing:.3g}: it is thinner "
            f"than a cell. Raise the resolution or {THICKEN}.")


def check_result(chain: Animation, grid: Grid, keyframes: Sequence[Keyframe]) -> None:
    """Last guard: every frame's vertices finite and on the grid (where the shapes live)."""
    verts = np.asarray(chain.vertices)
    ok = np.all(np.isfinite(verts), axis=-1) & grid.contains(verts, margin=-grid.spacing)
    if ok.all():
        return
    f = int(np.argwhere(~ok)[0][0])
    frame = int(chain.frames[f])
    seg = int(np.searchsorted([kf.frame for kf in keyframes], frame, side="left")) - 1
    seg = min(max(seg, 0), len(keyframes) - 2)
    raise ValueError(f"On frame {frame} the shape left the working box: the feature pairs between "
                     f"{_segment_label(seg)} ask for a tearing or folding motion. Check that "
                     "each pair joins matching points, and delete pairs that cross each other.")


def notes(keyframes: Sequence[Keyframe], loose: Sequence[int],
          sdf_stats: Sequence[Mapping[str, Any]]) -> list[str]:
    """What the user should know about a bake that succeeded (plain sentences; what to
    fix in the words of `FIXES`)."""
    notes = []
    for k, (kf, n_loose, st) in enumerate(zip(keyframes, loose, sdf_stats)):
        label = keyframe_label(k, kf)
        if n_loose:
            notes.append(f"{label}: ignored {n_loose} loose vertices (not part of any face).")
        if st.get("reoriented_faces"):
            notes.append(f"{label}: {st['reoriented_faces']} triangles faced the wrong way and were "
                         f"read flipped; {FACE_OUTWARD}.")
        if st.get("non_orientable_faces"):
            notes.append(f"{label}: {st['non_orientable_faces']} triangles cannot be given a consistent "
                         "inside and outside (a twisted or non-manifold surface); the result there "
                         "may be wrong: check that part of the mesh.")
    return notes


def check_motion_resolution(motion_resolution: float | None, resolution: int) -> None:

    """Refuse a Motion Resolution the bake cannot use, before any work: it is None
    (automatic) or a whole number from `gridfit.MIN_MOTION_RESOLUTION` to ``resolution``."""
    from .gridfit import MIN_MOTION_RESOLUTION as least

    if motion_resolution is None:
        return
    m = motion_resolution
    if isinstance(m, bool) or not isinstance(m, (int, float, np.integer, np.floating)) \
            or not float(m).is_integer():
        raise ValueError(f"motion_resolution must be a whole number of cells, or None to let the "
                         f"bake choose it; got {m!r}.")
    if m < least:
        raise ValueError(f"Motion Resolution {int(m)} is below {least}: a motion grid that coarse "
                         f"cannot tell a keyframe's parts apart. Raise it to {least} or more, or "
                         "leave it automatic.")
    if m > resolution:
        raise ValueError(f"Motion Resolution {int(m)} is above the Resolution {resolution}: the "
                         "motion grid is never finer than the surface grid. Lower it to "
                         f"{resolution} or less, or leave it automatic.")
