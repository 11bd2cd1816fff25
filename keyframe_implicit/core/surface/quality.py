"""How clean a baked frame is: the output mesh against the frame's own surface.

The true surface of a frame is the zero set of its in-between level set
(eq. 3.4), extracted on the same grid (`extract.extract_surface`). A baked
mesh -- the tracked template (shape keys) or the frame's own surface (mesh
sequence) -- is measured against it by three figures per frame:

``area_ratio``
    output area / true area. Buried doubled sheets and folds raise it above
    1, stretched triangles that cut corners lower it.
``inverted_fraction``
    share of the output's area on faces whose normal opposes grad phi (sampled
    at the face centroid): sheets turned inside out.
``coverage``
    share of the true surface's area within 0.5 h of the output (distance from
    each true face's centroid to the output mesh): parts the output misses.

On a keyframe's frame the output is also compared with the keyframe mesh
the artist modelled (not with its distance grid): ``keyframe_mean`` and
``keyframe_max`` are the mean and the largest distance, in cells h, over
points of both meshes (vertices and face centroids) to the other mesh.

`LIMITS` holds the limits a clean frame meets; `failures` lists what a frame
breaks and `worst_frame` picks the frame to tell the artist about.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.sampling import sample_with_gradient
from ..fields.triangles import Triangles, nearest_candidates, proper
from .extract import extract_surface, mesh_area

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping, Sequence

    from numpy.typing import ArrayLike

    from ..base.grid import Grid

__all__ = ["LIMITS", "frame_quality", "keyframe_distance", "mesh_distance", "flipped_fraction",
           "fine_detail", "ripple", "turned_faces", "failures", "worst_frame", "choose_output",
           "describe_worst"]

# per-frame limits of a clean result (area ratio band, largest inverted share, smallest
# coverage, and on keyframe frames the mean and largest two-way distance in cells)
LIMITS: dict[str, Any] = {"area_ratio": (0.97, 1.03), "inverted_fraction": 0.005, "coverage": 0.99,
          "keyframe_mean": 0.1, "keyframe_max": 1.0}


def _triangles(vertices: ArrayLike, faces: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Float vertices and the triangles of non-zero area."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    return v, f[proper(v, f)] if len(f) else f


def mesh_distance(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike,
                  candidates: int = 16) -> np.ndarray:
    """Distance from points (P, 3) to a triangle mesh.

    Exact point-triangle distances (`triangles.Triangles.distance`, its constants made once
    per triangle of the mesh, not per pair) to the ``candidates`` triangles whose
    centroids are nearest; the smallest is taken.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    v, f = _triangles(vertices, faces)
    if len(f) == 0:
        return np.full(len(p), np.inf)
    if len(p) == 0:
        return np.zeros(0)
    idx = nearest_candidates(p, v, f, candidates)
    k = idx.shape[1]
    d = Triangles(v, f).distance(np.repeat(p, k, axis=0), idx.reshape(-1))
    return d.reshape(len(p), k).min(axis=1)


def frame_quality(levelset: np.ndarray, grid: Grid, vertices: ArrayLike, faces: ArrayLike,
                  surface: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, float]:
    """Area ratio, inverted-area share and coverage of one frame's output (module docstring).

    Parameters
    ----------
    levelset : ndarray, grid.shape
        The frame's in-between level set.
    grid : Grid (3D)
    vertices, faces : the output mesh of the frame (world units, outward triangles).
    surface : (V, F), optional
        The frame's true surface when already extracted.

    Returns
    -------
    dict with ``area_ratio``, ``inverted_fraction``, ``coverage``.
    """
    tv, tf = extract_surface(levelset, grid) if surface is None else surface
    itself = surface is not None and vertices is surface[0] and faces is surface[1]
    tv, tf = _triangles(tv, tf)
    v, f = _triangles(vertices, faces)
    true_area = mesh_area(tv, tf, per_face=True)
    area = mesh_area(v, f, per_face=True)
    if true_area.sum() == 0 or area.sum() == 0:
        empty = true_area.sum() == area.sum()
        return {"area_ratio": 1.0 if empty else (np.inf if area.sum() else 0.0),
                "inverted_fraction": 0.0, "coverage": 1.0 if empty else 0.0}
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    _, grad = sample_with_gradient(levelset, grid, (a + b + c) / 3.0, outside="distance")
    turned = np.einsum("ij,ij->i", np.cross(b - a, c - a), grad) < 0
    if itself:  # the output is the true surface: it covers itself
        covered = 1.0
    else:
        near = _within(tv[tf].mean(axis=1), v, f, 0.5 * grid.spacing)
        covered = float(true_area[near].sum() / true_area.sum())
    return {"area_ratio": float(area.sum() / true_area.sum()),
            "inverted_fraction": float(area[turned].sum() / area.sum()), "coverage": covered}


def _within(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
            tol: float) -> np.ndarray:
    """Which points lie within ``tol`` of a mesh: a sample of the mesh (vertex, edge
    midpoint, centroid) that close settles it; the rest get `mesh_distance`."""
    from scipy.spatial import cKDTree

    a, b, c = (vertices[faces[:, i]] for i in range(3))
    corner = np.zeros(len(vertices), dtype=bool)
    corner[faces] = True  # loose vertices reach nothing
    samples = np.concatenate([vertices[corner], 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a),
                              (a + b + c) / 3.0])
    # built once and queried once: an unbalanced tree builds in half the time
    tree = cKDTree(samples, balanced_tree=False, compact_nodes=False)
    d, _ = tree.query(points, distance_upper_bound=tol, workers=-1)
    near = d <= tol
    rest = np.flatnonzero(~near)
    near[rest] = mesh_distance(points[rest], vertices, faces) <= tol
    return near


def keyframe_distance(vertices: ArrayLike, faces: ArrayLike, key_vertices: ArrayLike,
                      key_faces: ArrayLike, spacing: float) -> dict[str, float]:
    """Two-way distance between a frame's output and the keyframe mesh, in cells.

    Points of each mesh (vertices and face centroids) are measured to the
    other mesh with `mesh_distance`.

    Returns
    -------
    dict with ``keyframe_mean`` and ``keyframe_max`` (units of ``spacing``).
    """
    v, f = _triangles(vertices, faces)
    kv, kf = _triangles(key_vertices, key_faces)
    d = np.concatenate([mesh_distance(np.concatenate([v[np.unique(f)], v[f].mean(axis=1)]), kv, kf),
                        mesh_distance(np.concatenate([kv[np.unique(kf)], kv[kf].mean(axis=1)]), v, f)])
    d = d / float(spacing)
    return {"keyframe_mean": float(d.mean()), "keyframe_max": float(d.max())}


def flipped_fraction(start: ArrayLike, vertices: ArrayLike, faces: ArrayLike) -> float:
    """The share of a tracked mesh's area on faces turned over since its first frame
    (`turned_faces`), which a render shows as specks of the inside."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        return 0.0
    area = np.linalg.norm(_face_normals(vertices, f), axis=1)
    total = float(area.sum())
    return float(area[turned_faces(start, vertices, f)].sum()) / total if total > 0 else 0.0


def turned_faces(start: ArrayLike, vertices: ArrayLike, faces: ArrayLike) -> np.ndarray:
    """(F,) bool: the ``faces`` of ``vertices`` whose normals point against their own at
    ``start`` (a fold). Faces of no area at either count as not turned."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    return np.einsum("ij,ij->i", _face_normals(vertices, f), _face_normals(start, f)) < 0.0


def fine_detail(vertices: ArrayLike, faces: ArrayLike,
                smooth: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """(V,) how far each vertex of a mesh stands out of its ``smooth``ed self (a low-pass
    filter over the mesh, `template.surface_filter`), along its normal (area-weighted
    over its faces): the mesh's detail finer than the filter."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    normal = np.zeros_like(v)
    area = _face_normals(v, f)
    for k in range(3):
        np.add.at(normal, f[:, k], area)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
    return np.einsum("ij,ij->i", v - smooth(v), normal)


def ripple(start_detail: np.ndarray, vertices: ArrayLike, faces: ArrayLike,
           smooth: Callable[[np.ndarray], np.ndarray]) -> float:
    """How much detail finer than ``smooth`` a tracked mesh has gained since its first
    frame, whose `fine_detail` is ``start_detail``, in world units: the root mean square
    of the change of `fine_detail`, less its own smoothed part. A change of shape over
    more than the filter (a ball stretched by a fifth) shifts the fine detail smoothly
    and counts for little (0.0006 cells, against 0.035 for rings 0.05 cells high)."""
    change = fine_detail(vertices, faces, smooth) - start_detail
    return float(np.sqrt(np.mean((change - smooth(change)) ** 2)))


def _face_normals(points: ArrayLike, f: np.ndarray) -> np.ndarray:
    """(F, 3): each triangle's normal, as long as twice its area."""
    v = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])


def failures(figures: Mapping[str, float], limits: Mapping[str, Any] = LIMITS) -> list[str]:
    """The limits one frame's figures break (dict from `frame_quality`, maybe with the
    `keyframe_distance` keys), each as what the artist sees with its value, e.g.
    ``["96.2 % of the shape covered"]``; distances in grid cells (the bake report's
    details say how wide a cell is)."""
    out = []
    lo, hi = limits["area_ratio"]
    if not lo <= figures["area_ratio"] <= hi:
        out.append(f"surface area {figures['area_ratio']:.3f} times the shape's own")
    if figures["inverted_fraction"] > limits["inverted_fraction"]:
        out.append(f"{100 * figures['inverted_fraction']:.1f} % of the surface facing inward")
    if figures["coverage"] < limits["coverage"]:
        out.append(f"{100 * figures['coverage']:.1f} % of the shape covered")
    if "keyframe_mean" in figures and figures["keyframe_mean"] > limits["keyframe_mean"]:
        out.append(f"{figures['keyframe_mean']:.2f} cells off the keyframe on average")
    if "keyframe_max" in figures and figures["keyframe_max"] > limits["keyframe_max"]:
        out.append(f"up to {figures['keyframe_max']:.2f} cells off the keyframe")
    return out


def _badness(figures: Mapping[str, float], limits: Mapping[str, Any] = LIMITS) -> float:
    """How far a frame is past its limits, each figure relative to its own limit."""
    lo, hi = limits["area_ratio"]
    r = figures["area_ratio"]
    parts = [max(lo - r, r - hi, 0.0) / (hi - lo),
             max(figures["inverted_fraction"] - limits["inverted_fraction"], 0.0)
             / limits["inverted_fraction"],
             max(limits["coverage"] - figures["coverage"], 0.0) / (1.0 - limits["coverage"])]
    for key in ("keyframe_mean", "keyframe_max"):
        if key in figures:
            parts.append(max(figures[key] - limits[key], 0.0) / limits[key])
    return max(parts)


def _nearness(figures: Mapping[str, float], limits: Mapping[str, Any] = LIMITS) -> float:
    """How close a frame comes to its limits: each figure's departure from its ideal
    value as a share of what the limit allows (1 = on the limit)."""
    lo, hi = limits["area_ratio"]
    r = figures["area_ratio"]
    parts = [(1.0 - r) / (1.0 - lo) if r < 1.0 else (r - 1.0) / (hi - 1.0),
             figures["inverted_fraction"] / limits["inverted_fraction"],
             (1.0 - figures["coverage"]) / (1.0 - limits["coverage"])]
    parts += [figures[key] / limits[key] for key in ("keyframe_mean", "keyframe_max")
              if key in figures]
    return max(parts)


def worst_frame(frames: Sequence[int] | np.ndarray, per_frame: Sequence[Mapping[str, float]],
                limits: Mapping[str, Any] = LIMITS) -> tuple[int, Mapping[str, float], list[str]]:
    """(frame, figures, failures) of the frame farthest past the limits, or, when every
    frame passes (its failures list is then empty), of the frame nearest to them."""
    if not len(per_frame):
        raise ValueError("no frames to rank")
    k = max(range(len(per_frame)),
            key=lambda i: (_badness(per_frame[i], limits), _nearness(per_frame[i], limits)))
    return int(frames[k]), per_frame[k], failures(per_frame[k], limits)


#: How a mesh sequence's reason ends (`choose_output`); a bake whose first frames keep the
#: artist's mesh says so instead (`pipeline`).
OWN_SURFACES = ", so each frame has its own surface"


def choose_output(frames: Sequence[int] | np.ndarray,
                  quality: Mapping[str, Sequence[Mapping[str, float]]],
                  limits: Mapping[str, Any] = LIMITS) -> tuple[str, str]:
    """The Auto output: shape keys when every frame of the tracked template passes the
    limits, the mesh sequence otherwise.

    Parameters
    ----------
    frames : (n,) timeline frames.
    quality : dict output name -> list of per-frame figures (``Animation.stats["quality"]``).

    Returns
    -------
    (output, reason) : "shape_keys" or "mesh_sequence", and one sentence for the artist.
    """
    frame, _, fails = worst_frame(frames, quality["shape_keys"], limits)
    if not fails:
        return "shape_keys", "one mesh follows the shape on every frame"
    return "mesh_sequence", (f"one mesh cannot follow the shape at frame {frame} (it would "
                             f"stretch, fold or leave gaps){OWN_SURFACES}")


def describe_worst(frames: Sequence[int] | np.ndarray, per_frame: Sequence[Mapping[str, float]],
                   what: str, limits: Mapping[str, Any] = LIMITS) -> list[str]:


    """The figures of an output's worst frame in words, for the details of the bake report:
    the frame farthest past the limits, or, when all pass, the one nearest to them; ``what``
    names the output ("Shape keys"). A grid cell is the bake's grid spacing (Resolution cells
    along the keyframes' longest side)."""
    frame, q, fails = worst_frame(frames, per_frame, limits)
    lo, hi = limits["area_ratio"]
    lines = [f"{what}: {'worst' if fails else 'least clean'} frame {frame}"
             + (f" (past the limits: {', '.join(fails)})" if fails else
                " (every frame is within the limits)"),
             f"Surface area: {q['area_ratio']:.3f} times the shape's own (clean: {lo}-{hi})",
             f"Surface facing inward: {100 * q['inverted_fraction']:.1f} % "
             f"(clean: at most {100 * limits['inverted_fraction']:.1f} %)",
             f"Shape covered by the mesh: {100 * q['coverage']:.1f} % "
             f"(clean: at least {100 * limits['coverage']:.0f} %)"]
    if "keyframe_max" in q:
        lines.append(f"Off the keyframe's own mesh: {q['keyframe_mean']:.2f} cells on average, "
                     f"{q['keyframe_max']:.2f} at most (clean: at most "
                     f"{limits['keyframe_mean']} and {limits['keyframe_max']})")
    return lines