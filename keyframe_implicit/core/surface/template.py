"""One mesh tracked through all in-between frames (docs/method.md, section 7).

Marching cubes gives a different mesh on every frame; a Blender shape key
needs the same vertices on every frame. So one template -- the surface of
keyframe A (marching cubes of the level set at s = 0) -- is carried along
the as-rigid-as-possible trajectories to each frame and then pulled onto
that frame's zero level set by a few projection steps

    p <- p - phi(p) n / (n . grad phi(p))

with multilinear sampling of the frame's field, n the unit normal from central
differences over one cell (for a distance field this is p - phi grad/|grad|^2
with a gradient that stays reliable near ridges); each step is limited to one
cell. Vertex count and faces never change, so vertices keep their identity
(UVs, colours, motion blur, morph-target export).

The template cannot grow new parts: where a frame's own surface has pieces
that no template vertex reaches (a merge neck stretches triangles; a part of
B with no counterpart in A), their area is measured and reported
(``stats["uncovered_area"]``) rather than hidden.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.progress import Reporter
from ..base.sampling import central_differences, sample, sample_with_gradient, smoothstep
from .extract import (closed_pieces, extract_surface, material_topology, mesh_area, mesh_pieces,
                      piece_means, piece_volumes)
from .quality import turned_faces

if TYPE_CHECKING:
    from collections.abc import Callable
    from typing import Protocol

    from numpy.typing import ArrayLike

    from ..base.grid import Grid

    class Inbetweens(Protocol):
        """What the template reads of a keyframe pair's in-betweens
        (`core.motion.levelset.Inbetween`), named here so that this stage need not know
        the motion stage's module."""

        grid: Grid

        def levelset(self, s: float) -> np.ndarray: ...

        def trajectory(self, points: ArrayLike, s: float) -> np.ndarray: ...

__all__ = ["track_template", "initial_template", "project_to_zero_set", "TemplateTrack",
           "uncovered_area", "unfold"]


class TemplateTrack:
    """Result of `track_template`.

    Attributes
    ----------
    times : (n,) float array, the s of every frame.
    vertices : (n, V, d) float array, template vertices on every frame.
    faces : (F, 3) int array (3D triangles) or (E, 2) segments (2D loops), the same on every frame.
    stats : dict with per-frame lists ``max_abs_phi`` / ``mean_abs_phi`` (world units, after
        projection), ``uncovered_area`` / ``uncovered_fraction`` (when coverage is measured)
        and ``seconds``.
    """

    def __init__(self, times: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                 stats: dict[str, Any]) -> None:
        self.times = times
        self.vertices = vertices
        self.faces = faces
        self.stats = stats


def project_to_zero_set(points: ArrayLike, levelset: np.ndarray, grid: Grid, steps: int = 3,
                        tol: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """Pull points onto the zero set of a grid field (Newton steps along the normal).

    Each step moves a point along the unit normal n (central differences of the
    field over one cell) by phi / (n . grad phi), at most one cell. Points
    still farther than ``tol`` cells from the zero set then get a bracketed
    root search (regula falsi) along their normal, within 1.5 cells; the
    sign change nearest to the point is taken.

    Parameters
    ----------
    points : (P, d) array, world units.
    levelset : ndarray, grid.shape
    grid : Grid
    steps : int

    Returns
    -------
    (P, d) array of projected points and (P,) array of |phi| at them.
    """
    p = np.array(points, dtype=float, copy=True)
    h = grid.spacing
    for _ in range(int(steps)):
        phi, g = sample_with_gradient(levelset, grid, p, outside="distance")
        n = _normals(levelset, grid, p)
        # Newton along n with the exact slope of the multilinear field, kept away from zero
        slope = np.maximum(np.einsum("pd,pd->p", n, g), 0.3)
        step = np.clip(phi / slope, -h, h)
        p -= step[:, None] * n
    # where the gradient jumps between cells (sharp features, ridges) Newton can cycle:
    # finish those points with a bracketed root search along the normal
    phi = sample(levelset, grid, p, outside="distance")
    bad = np.flatnonzero(np.abs(phi) > tol * h)
    if bad.size:
        p[bad] = _line_search(levelset, grid, p[bad], _normals(levelset, grid, p[bad]))
    phi = sample(levelset, grid, p, outside="distance")
    return p, np.abs(phi)


def _normals(levelset: np.ndarray, grid: Grid, p: np.ndarray) -> np.ndarray:
    """Unit normals from central differences over one cell (smooth across cell faces)."""
    n = central_differences(levelset, grid, p, outside="distance")
    nn = np.linalg.norm(n, axis=1)
    return np.where(nn[:, None] > 1e-12, n / np.maximum(nn, 1e-12)[:, None], 0.0)


def _line_search(levelset: np.ndarray, grid: Grid, p: np.ndarray, n: np.ndarray,
                 reach: float = 1.5, samples: int = 13, iterations: int = 8) -> np.ndarray:
    """Root of phi(p - t n) for t in [-reach, reach] cells nearest t = 0 (regula falsi)."""
    h = grid.spacing
    ts = np.linspace(-reach * h, reach * h, samples)
    vals = sample(levelset, grid, p[:, None, :] - ts[None, :, None] * n[:, None, :],
                  outside="distance")  # (P, samples)
    change = np.signbit(vals[:, :-1]) != np.signbit(vals[:, 1:])
    mid = np.abs(0.5 * (ts[:-1] + ts[1:]))
    score = np.where(change, mid[None], np.inf)
    k = np.argmin(score, axis=1)
    found = np.isfinite(score[np.arange(len(p)), k])
    a, b = ts[k], ts[k + 1]
    fa, fb = vals[np.arange(len(p)), k], vals[np.arange(len(p)), k + 1]
    for _ in range(iterations):  # Illinois regula falsi, vectorised over points
        denom = np.where(fb != fa, fb - fa, 1.0)
        c = np.where(fb != fa, b - fb * (b - a) / denom, 0.5 * (a + b))
        fc = sample(levelset, grid, p - c[:, None] * n, outside="distance")
        same = np.signbit(fc) == np.signbit(fb)
        a = np.where(same, a, b)
        fa = np.where(same, 0.5 * fa, fb)
        b, fb = c, fc
    t = np.where(found, b, 0.0)
    return p - t[:, None] * n


def _template_samples(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Points covering a template: vertices, edge midpoints and face centroids."""
    if faces.shape[1] == 2:
        return np.concatenate([vertices, 0.5 * (vertices[faces[:, 0]] + vertices[faces[:, 1]])])
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    return np.concatenate([vertices, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a),
                           (a + b + c) / 3.0])


def uncovered_area(levelset: np.ndarray, grid: Grid, vertices: np.ndarray, faces: np.ndarray,
                   tol: float | None = None,
                   surface: tuple[np.ndarray, np.ndarray] | list[np.ndarray] | None = None,
                   ) -> tuple[float, float]:
    """Area (3D) or length (2D) of a frame's own zero set that the template does not reach.

    The frame's surface is extracted (marching cubes / contours); a piece of it
    counts as uncovered when its centre is farther than ``tol`` (default one
    cell) from every sample of the template (vertices, edge midpoints,
    centroids). ``surface``: the frame's surface when already extracted.

    Returns
    -------
    uncovered, total : floats
    """
    from scipy.spatial import cKDTree

    tol = grid.spacing if tol is None else float(tol)
    surf = extract_surface(levelset, grid) if surface is None else surface
    if grid.dim == 3:
        V, F = surf
        if len(F) == 0:
            return 0.0, 0.0
        centres = V[F].mean(axis=1)
        size = mesh_area(V, F, per_face=True)
    else:
        if not surf:
            return 0.0, 0.0
        segs_a = np.concatenate(surf)
        segs_b = np.concatenate([np.roll(loop, -1, axis=0) for loop in surf])
        centres = 0.5 * (segs_a + segs_b)
        size = np.linalg.norm(segs_b - segs_a, axis=1)
    if len(vertices) == 0:
        return float(size.sum()), float(size.sum())
    tree = cKDTree(_template_samples(vertices, faces), balanced_tree=False, compact_nodes=False)
    dist, _ = tree.query(centres, distance_upper_bound=tol, workers=-1)  # inf beyond tol
    return float(size[dist > tol].sum()), float(size.sum())


def initial_template(levelset: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """The default template: the zero set of ``levelset`` as a mesh (3D), or its contour
    loops joined into one list of segments (2D)."""
    surf = extract_surface(levelset, grid)
    if grid.dim == 3:
        return surf
    verts, segs, start = [], [], 0
    for loop in surf:
        m = len(loop)
        verts.append(loop)
        idx = np.arange(m) + start
        segs.append(np.stack([idx, np.roll(idx, -1)], axis=1))
        start += m
    if not verts:
        return np.zeros((0, 2)), np.zeros((0, 2), dtype=np.int64)
    return np.concatenate(verts), np.concatenate(segs)


def track_template(inb: Inbetweens, times: ArrayLike, *,
                   template: tuple[ArrayLike, ArrayLike] | None = None,
                   projection_steps: int = 4, coverage: bool = True,
                   progress: Callable[[float, str], object] | None = None,
                   cancel: Callable[[], bool] | None = None) -> TemplateTrack:
    """Carry one template mesh through the in-betweens of one keyframe pair.

    Parameters
    ----------
    inb : Inbetween
        The keyframe pair's in-betweens (`levelset.Inbetween`).
    times : sequence of float in [0, 1]
        Normalised times s of the frames wanted (e.g. ``np.linspace(0, 1, 24)``).
    template : (vertices, faces), optional
        The mesh at s = 0 (world units; it should lie on keyframe A's
        surface). Default: marching cubes (3D) / contours (2D) of the level
        set at s = 0.
    projection_steps : int
        Projection steps onto each frame's zero set.
    coverage : bool
        Also measure the area of each frame's surface the template misses
        (costs one marching cubes per frame).
    progress, cancel : callables, optional (`progress.Reporter`).

    Returns
    -------
    TemplateTrack
    """
    rep = Reporter(progress, cancel)
    times = np.asarray(times, dtype=float).reshape(-1)
    if times.size == 0:
        raise ValueError("times is empty: pass at least one s in [0, 1].")
    if np.any((times < 0) | (times > 1)) or not np.all(np.isfinite(times)):
        raise ValueError("times must lie in [0, 1] (normalised time between the two keyframes).")
    grid = inb.grid
    t0 = time.perf_counter()
    if template is None:
        verts0, faces = initial_template(inb.levelset(0.0), grid)
    else:
        verts0 = np.asarray(template[0], dtype=float)
        faces = np.asarray(template[1], dtype=np.int64)
        if verts0.ndim != 2 or verts0.shape[1] != grid.dim:
            raise ValueError(f"template vertices must have shape (V, {grid.dim}), "
                             f"got {verts0.shape}.")
    out = np.empty((times.size,) + verts0.shape)
    stats = {"max_abs_phi": [], "mean_abs_phi": [], "uncovered_area": [],
             "uncovered_fraction": [], "vertices": int(len(verts0)), "faces": int(len(faces))}
    for k, s in enumerate(times):  # loop over frames
        ls = inb.levelset(s)
        p = inb.trajectory(verts0, s) if len(verts0) else verts0.copy()
        if len(p):
            p, err = project_to_zero_set(p, ls, grid, projection_steps)
        else:
            err = np.zeros(0)
        out[k] = p
        stats["max_abs_phi"].append(float(err.max()) if err.size else 0.0)
        stats["mean_abs_phi"].append(float(err.mean()) if err.size else 0.0)
        if coverage:
            unc, tot = uncovered_area(ls, grid, p, faces)
            stats["uncovered_area"].append(unc)
            stats["uncovered_fraction"].append(unc / tot if tot > 0 else 0.0)
        rep((k + 1) / times.size, f"template frame {k + 1}/{times.size}")
    stats["seconds"] = time.perf_counter() - t0
    return TemplateTrack(times, out, faces, stats)


def local_rotations(inb: Inbetweens, points: ArrayLike, s: float, step: float = 0.5) -> np.ndarray:
    """Rotation part (P, 3, 3) of the trajectories' local motion at time s.

    The Jacobian of x -> ``inb.trajectory(x, s)`` at each point (central
    differences over ``step`` cells), split F = R S by `rotations.polar`:
    the locally rigid part of the motion (eq. 3.1's R(s)).
    """
    return local_motion(inb, points, s, step)[0]


def local_motion(inb: Inbetweens, points: ArrayLike, s: float,
                 step: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """`local_rotations` and the stretch S (P, 3, 3) of the polar split F = R S."""
    from ..base.rotations import polar

    p = np.asarray(points, dtype=float)
    d = p.shape[1]
    delta = step * inb.grid.spacing
    probes = np.concatenate([p[None] + delta * e[None, None] for e in np.eye(d)]
                            + [p[None] - delta * e[None, None] for e in np.eye(d)])
    moved = inb.trajectory(probes.reshape(-1, d), s).reshape(2 * d, len(p), d)
    jac = np.stack([(moved[i] - moved[d + i]) / (2 * delta) for i in range(d)], axis=-1)
    return polar(jac)


def surface_filter(points: np.ndarray, radius: float,
                   passes: int = 3) -> Callable[[np.ndarray], np.ndarray]:
    """Low-pass filter over points (V, 3): ``passes`` rounds of Gaussian-weighted averages
    over neighbours within ``radius`` (sigma = radius / 2). Returns f(values) -> values."""
    from scipy.sparse import csr_matrix, identity
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    dist = tree.sparse_distance_matrix(tree, radius, output_type="coo_matrix")
    w = np.exp(-2.0 * (dist.data / radius) ** 2)
    n = len(points)
    W = csr_matrix((w, (dist.row, dist.col)), shape=(n, n)) + identity(n, format="csr")
    W = csr_matrix(W.multiply(1.0 / np.asarray(W.sum(axis=1))))

    def apply(values: np.ndarray) -> np.ndarray:
        for _ in range(passes):
            values = W @ values
        return values
    return apply


def same_vertices(landing: np.ndarray, end_vertices: ArrayLike, spacing: float,
                  median_cells: float = 1.0, max_cells: float = 6.0) -> bool:
    """Whether keyframe B's vertices are the template's own, posed: the same count, and
    the template's landing points on B (closest points) lie near B's vertex of the same
    index (median within ``median_cells`` cells, all within ``max_cells``). A different
    mesh with the same vertex count fails the median by far: its vertex i lies elsewhere."""
    end_vertices = np.asarray(end_vertices, dtype=float).reshape(-1, 3)
    if len(end_vertices) != len(landing) or not len(landing):
        return False
    d = np.linalg.norm(landing - end_vertices, axis=1) / float(spacing)
    return bool(np.median(d) <= median_cells and d.max() <= max_cells)


def unfold(start: np.ndarray, faces: np.ndarray, points: np.ndarray, offset: np.ndarray,
           rounds: int = 4) -> np.ndarray:
    """``offset`` from ``points`` (a mesh that turns no face of ``start``, such as its
    points carried along their paths) with no face of ``points + offset`` turned over
    since ``start``: each cluster of faces it would turn (joined by their corners) takes
    its corners' mean offset, so it moves as its points do. Marching cubes leaves slivers a
    small fraction of a cell high; an offset smooth at the scale of a cell still turns
    them. A cluster that turns a neighbour takes it in on the next of ``rounds``."""
    for _ in range(rounds):
        turned = turned_faces(start, points + offset, faces)
        if not turned.any():
            break
        count, cluster = mesh_pieces(faces[turned], len(points))
        size = np.bincount(cluster, minlength=count)[:, None]
        mean = np.stack([np.bincount(cluster, offset[:, a], count) for a in range(3)], 1)
        offset = np.where((size > 1)[cluster], (mean / size)[cluster], offset)
    return offset


#: The gap from a path's end to keyframe B's surface, in cells, up to which it closes as
#: the offsets trade places (`DetailTrack`); from twice it, late, with w^4.
LANDING_CELLS = 1.0

#: The most `DetailTrack._hold_volumes` scales a piece by: the offsets change a piece's
#: volume by a few per cent, and a larger factor means its volume is not its own (a mesh
#: wound inward in places, whose signed volume nearly cancels).
HOLD_SCALE = 0.03

#: The scale, in cells, under which `DetailTrack.ripple` counts a mesh's detail.
RIPPLE_CELLS = 2.0

#: Stretch of the trajectories' local motion, |S - I|, from which the zero set steers the
#: template fully (`DetailTrack`); a part moving more rigidly follows its paths.
RIGID_STRAIN = 0.02


class DetailTrack:
    """The artist's mesh of keyframe A carried through one segment with its sub-cell detail.

    The grid sees each keyframe only down to about a cell, so pulling the
    artist's vertices onto an in-between's zero set would flatten all finer
    detail. Instead only the smooth part of that pull is applied: with p(s)
    the trajectory of the artist's vertex V0 (eq. 3.1), P_s the projection
    onto the zero set at s (`project_to_zero_set`), L a low-pass filter over
    the mesh that removes wavelengths under about two cells
    (`surface_filter`), u(s) = L[P_s(p(s)) - p(s)] that smooth pull and R(s)
    the local rotation of the trajectories (`local_rotations`),

        x(s) = p(s) + g (u(s) - R(s) [(1 - w) c_A + W R(1)^T u(1)])
               + W R(s) R(1)^T (x(1) - p(1)),

    where c_A = u(0) is the smooth offset between the artist's mesh and its own
    grid surface (so x(0) = V0) and x(1) = C_B(p(1) + u(1)), the closest point on
    keyframe B's own triangles. The zero set steers the mesh by what its pull adds
    to the keyframes' own offsets carried along; detail under a cell travels with
    the locally rigid motion. With g = 1 this is p(s) + u(s) - (1 - w) R c_A +
    W R R(1)^T c_B, c_B = x(1) - p(1) - u(1). The offsets trade places with
    w = `smoothstep`(s), which leaves both keyframes at rest: the frame after a
    keyframe moves from it as its paths do. W = a w + (1 - a) w^4 lands late a path
    that misses B by more than `LANDING_CELLS` (a, per vertex, from 1 at that gap
    |x(1) - p(1)| to 0 at twice it): material a merge encloses ends cells deep inside B,
    and keeps to its paths until the parts meet. x(0) is returned exactly as given. Faces
    the offsets would turn over move with their paths instead (`unfold`).

    The zero set guides, it does not constrain: g, per piece of the mesh, is the mean
    over its vertices of the stretch of the trajectories' local motion (|S - I| of
    F = R S, smoothed by L) over `RIGID_STRAIN`, each at most 1. A piece that moves
    rigidly follows its paths exactly, while the zero set of a part only a few cells
    thick wobbles with the grid as the part turns (a rod 2 cells thick loses a
    fifth of its volume to it, and a different fifth at every angle); a piece that
    deforms is steered as much everywhere: a g varying across a piece creases it
    where the pull is large (merging balls drew lips facing each other). ``guides``
    keeps, per time s, the largest g.

    The offsets c_A and c_B are shape, not volume: each closed piece of the mesh is then
    scaled about its vertices' mean by the one factor that gives it the volume
    (1 - s) V_A + s V_B, V_A its own on A and V_B its share of the pieces of keyframe B
    it lands on (`_volume_ends`), where the mesh's pieces are the material's parts (as
    many) and as long as the in-between's material keeps the topology it has at s = 0
    (`extract.material_topology`); once parts meet, the pieces' volumes are no longer
    their own. Without it
    the offsets add volume the in-betweens already hold: c_A is measured from keyframe
    A's grid surface, which holds the grid's volume where the in-betweens hold the
    mesh's, and c_B, ramped in from s = 0, holds what the smooth pull leaves short of B's
    zero set, over a cell where parts merge (two balls grew 5 % before they touched).

    When keyframe B is the same mesh as the template, posed (the artist
    duplicated A and moved its vertices: same vertex count, and the closest
    points above lie near B's own vertices, `same_vertices`), x(1) is B's
    vertex for vertex instead: a point of the closest-point landing may slide
    along B's surface by a fraction of a cell, which shows as swimming texture
    on a UV-mapped keyframe.

    Parameters
    ----------
    inb : Inbetween of the segment.
    vertices : (V, 3) the template on keyframe A's mesh (world units).
    faces : (F, 3) the template's triangles.
    end_mesh : (vertices (V_B, 3), triangles (T_B, 3)) of keyframe B.
    projection_steps : int, steps of `project_to_zero_set`.
    filter_cells : float, the filter's radius in cells.
    """

    def __init__(self, inb: Inbetweens, vertices: ArrayLike, faces: ArrayLike,
                 end_mesh: tuple[ArrayLike, ArrayLike], projection_steps: int = 4,
                 filter_cells: float = 1.0) -> None:
        from .attributes import closest_points

        self.inb = inb
        self.guides = {}
        self.start = np.asarray(vertices)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.pieces = mesh_pieces(self.faces, len(self.start))
        self.steps = projection_steps
        v0 = self.start.astype(float)
        self.smooth = surface_filter(v0, filter_cells * inb.grid.spacing)
        self.offset_a = self._pull(v0, 0.0)[1]
        p1 = inb.trajectory(v0, 1.0)
        pulled = self._pull(p1, 1.0)[0]
        self.end, landed = closest_points(pulled, *end_mesh)[:2]
        self.volumes, self.held = self._volume_ends(v0, landed, end_mesh)
        topology = material_topology(inb.levelset(0.0))
        self.topology = topology if topology[0] == self.pieces[0] else None
        self.end_by_index = same_vertices(self.end, end_mesh[0], inb.grid.spacing)
        if self.end_by_index:
            self.end = np.asarray(end_mesh[0], dtype=float).copy()
        rot_b = local_rotations(inb, v0, 1.0)
        self.offset_b = np.einsum("pji,pj->pi", rot_b, self.end - pulled)
        self.pull_b = np.einsum("pji,pj->pi", rot_b, pulled - p1)
        gap = np.linalg.norm(self.end - p1, axis=1) / inb.grid.spacing
        self.early = 1.0 - smoothstep(gap / LANDING_CELLS - 1.0)  # a: its share landing with w
        self._fine = None  # `ripple`'s filter and the start's detail, made when first asked

    def _volume_ends(self, v0: np.ndarray, landed: np.ndarray,
                     end_mesh: tuple[ArrayLike, ArrayLike]) -> tuple[tuple, np.ndarray]:
        """((V_A, V_B), held): per piece of the template its volume on A and on B, and
        whether it holds them (closed, and landing on closed pieces of B only). On B a
        piece has, of each piece of B its points land on (``landed``, their triangles of
        B), its share by A's volume and the fraction of its points there: all of one
        piece, or of the two it splits into; half of one, for each of two equal balls
        that merge."""
        count, label = self.pieces
        end_v = np.asarray(end_mesh[0], dtype=float).reshape(-1, 3)
        end_tris = np.asarray(end_mesh[1], dtype=np.int64).reshape(-1, 3)
        count_b, label_b = pieces_b = mesh_pieces(end_tris, len(end_v))
        lands = np.zeros((count, count_b))
        np.add.at(lands, (label, label_b[end_tris[landed, 0]]), 1.0)
        lands /= np.maximum(lands.sum(axis=1, keepdims=True), 1.0)
        on_a = piece_volumes(v0, self.faces, self.pieces)
        weight = lands * on_a[:, None]
        shares = np.divide(weight, weight.sum(axis=0), out=np.zeros_like(weight),
                           where=weight.sum(axis=0) != 0)
        on_b = shares @ piece_volumes(end_v, end_tris, pieces_b)
        held = (closed_pieces(self.faces, label, count)
                & (lands @ ~closed_pieces(end_tris, label_b, count_b) == 0))
        return (on_a, on_b), held

    def _hold_volumes(self, x: np.ndarray, s: float) -> np.ndarray:
        """``x`` with each held piece scaled about its vertices' mean by the one factor
        that gives it the volume (1 - s) V_A + s V_B, within `HOLD_SCALE`. A scaling is
        affine, so no face turns over, however thin: an offset along vertex normals turns
        a marching-cubes mesh's slivers, whose corners' normals differ by more than the
        slivers are high."""
        count, label = self.pieces
        target = (1.0 - s) * self.volumes[0] + s * self.volumes[1]
        volume = piece_volumes(x, self.faces, self.pieces)
        ok = self.held & (volume > 0) & (target > 0)
        scale = np.clip(np.cbrt(np.divide(target, volume, out=np.ones(count), where=ok)),
                        1.0 - HOLD_SCALE, 1.0 + HOLD_SCALE)
        centre = piece_means(x, self.pieces)[label]
        return centre + scale[label][:, None] * (x - centre)

    def _pull(self, p: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """p + L[P_s(p) - p], L[P_s(p) - p] and |phi| at P_s(p)."""
        q, err = project_to_zero_set(p, self.inb.levelset(s), self.inb.grid, self.steps)
        smooth = self.smooth(q - p)
        return p + smooth, smooth, err

    def ripple(self, x: np.ndarray) -> float:
        """How much finer detail the mesh at ``x`` has gained since its start, in cells
        (`quality.ripple` under `RIPPLE_CELLS`).

        Pulled onto the zero set of a grid field, a mesh finer than the grid picks up the
        field's sub-cell kinks: rings where its surface crosses the grid's planes at a
        grazing angle, which smooth shading shows, growing with the distance from the
        keyframe."""
        from .quality import fine_detail, ripple

        if self._fine is None:  # the filter and the start's detail, once
            smooth = surface_filter(self.start.astype(float),
                                    RIPPLE_CELLS * self.inb.grid.spacing)
            self._fine = smooth, fine_detail(self.start, self.faces, smooth)
        smooth, start_detail = self._fine
        return ripple(start_detail, x, self.faces, smooth) / self.inb.grid.spacing

    def __call__(self, s: float) -> tuple[np.ndarray, np.ndarray]:

        """(V, 3) vertices at time s in [0, 1] and (V,) |phi| of their projection."""
        s = float(s)
        if s == 0.0:
            return self.start.copy(), np.zeros(len(self.start))
        if s == 1.0:
            return self.end.copy(), np.zeros(len(self.end))
        v0 = self.start.astype(float)
        p = self.inb.trajectory(v0, s)
        _, pull, err = self._pull(p, s)
        rot, stretch = local_motion(self.inb, v0, s)
        w = float(smoothstep(s))
        lands = (self.early * w + (1.0 - self.early) * w ** 4)[:, None]  # W
        expected = np.einsum("pij,pj->pi", rot, (1.0 - w) * self.offset_a + lands * self.pull_b)
        strain = np.linalg.norm(stretch - np.eye(3), axis=(1, 2))
        stretch_share = np.clip(self.smooth(strain) / RIGID_STRAIN, 0.0, 1.0)
        guide = piece_means(stretch_share, self.pieces)[self.pieces[1]]
        landing = np.einsum("pij,pj->pi", rot, lands * (self.offset_b + self.pull_b))
        self.guides[s] = float(guide.max(initial=0.0))
        x = p + unfold(self.start, self.faces, p,
                       guide[:, None] * (pull - expected) + landing)
        if (self.topology is not None
                and material_topology(self.inb.levelset(s)) == self.topology):
            x = self._hold_volumes(x, s)
        return x, err
