"""Quality metrics of an in-between sequence (vectorised numpy / scipy / scikit-image).

All lengths are reported in grid spacings h. A "sequence" is a list of level
set grids at times ``s`` (negative inside), keyframe A at s = 0 and B at s = 1.

- `volume`: volume inside the surface the artist gets (marching cubes of the
  frame's field, `keyframe_implicit.core.surface.extract.enclosed_volume`), the same for
  every method whether its field is a distance or not.
- `volume_drift`: max over s of |V(s) - V_lin(s)| / V_lin(s), V_lin the linear
  interpolation of the keyframe volumes.
- `components`: connected pieces of {phi < 0} (6-connected voxels).
- `spurious_components`: max over frames of components - max(components of the
  two keyframes), floored at 0; a frame with no material counts as spurious too.
- `surface_error`: |reference signed distance| at the vertices of the method's
  zero set (marching cubes), mean and max, in h.
- `feature_error`: |map(x'_i) - y'_i| in h, map sampled multilinearly.
- `parts`, `part_volumes`: the 6-connected parts of {phi < 0} (the pieces `components`
  counts), each measured as `volume` measures the whole: marching cubes of the frame's
  field, here of that part alone.
- `part_volume_errors`: each material piece's volume, while it is a part on its own, against
  the straight line between its volumes in the two keyframes; pieces are followed along the
  maps' paths (`material_pieces`, `land`).
- `det_f`, `det_f_summary`: det F of a map at the centre of every cell of the keyframe's
  material (the volume term's own element Jacobian), and its percentiles off the crack of a
  torn map, with the crack's share of the material.
- `top_height`: height of the top of the lowest inside run along a vertical line (the
  splash's pool under the droplet).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage import measure

from keyframe_implicit.core.base import elements
from keyframe_implicit.core.base.sampling import sample
from keyframe_implicit.core.surface.extract import enclosed_volume

__all__ = [
    "volume", "volume_drift", "components", "spurious_components", "zero_set",
    "surface_error", "feature_error", "active_voxels", "parts", "part_volumes", "land",
    "material_pieces", "part_volume_errors", "det_f", "det_f_summary", "top_height",
]


def volume(phi, grid):
    """Volume inside the zero set of ``phi`` (marching cubes), world units^3."""
    return enclosed_volume(np.asarray(phi, dtype=float), grid)


def volume_drift(volumes, times, keyframe_volumes=None):
    """max over frames of |V(s) - V_lin(s)| / V_lin(s) (fraction, not percent).

    ``volumes`` and ``times`` list every frame. V_lin(s) = (1 - s) V_A + s V_B
    with (V_A, V_B) = ``keyframe_volumes``, the volumes of the keyframes
    themselves (so a method whose end frame misses B is charged for it);
    without it, the first and last frames' volumes.
    """
    v = np.asarray(volumes, dtype=float)
    s = np.asarray(times, dtype=float)
    va, vb = (v[0], v[-1]) if keyframe_volumes is None else keyframe_volumes
    lin = (1 - s) * va + s * vb
    return float(np.max(np.abs(v - lin) / lin))


def components(phi):
    """Number of 6-connected components of {phi < 0}."""
    return parts(phi)[1]


def parts(phi):
    """The 6-connected parts of {phi < 0}: labels (grid.shape, 0 outside, 1..n) and n."""
    labels, n = ndimage.label(np.asarray(phi) < 0)
    return labels, int(n)


def spurious_components(counts, expected_a, expected_b):
    """max over frames of (count - max(expected_a, expected_b)), floored at 0.

    A frame whose material vanished (count 0) counts as max(expected) spurious
    pieces lost, so a sequence that empties out does not look clean.
    """
    c = np.asarray(counts)
    ref = max(expected_a, expected_b)
    extra = np.maximum(c - ref, 0)
    lost = np.where(c == 0, ref, 0)
    return int(np.max(np.maximum(extra, lost)))


def zero_set(phi, grid):
    """Marching-cubes vertices (V, 3) of phi = 0 in world units; (0, 3) if none."""
    phi = np.asarray(phi, dtype=float)
    if not (phi.min() < 0 < phi.max()):
        return np.zeros((0, 3))
    verts, _, _, _ = measure.marching_cubes(phi, 0.0, spacing=(grid.spacing,) * 3)
    return verts + grid.origin


def surface_error(phi, grid, reference):
    """Mean and max |reference(v)| / h over the zero-set vertices v of ``phi``.

    ``reference`` is a callable (P, 3) -> signed distance (e.g. the analytic
    ground truth) or a grid array (sampled multilinearly, distance outside).
    Returns (nan, nan) when phi has no zero set.
    """
    v = zero_set(phi, grid)
    if len(v) == 0:
        return float("nan"), float("nan")
    if callable(reference):
        d = np.abs(reference(v))
    else:
        d = np.abs(sample(reference, grid, v, outside="distance"))
    return float(d.mean() / grid.spacing), float(d.max() / grid.spacing)


def feature_error(mapped, grid, features_a, features_b):
    """|y(x'_i) - y'_i| / h for each feature pair, y the node map ``mapped`` (grid.shape + (3,))."""
    y = sample(np.asarray(mapped, dtype=float), grid, np.asarray(features_a, dtype=float))
    return np.linalg.norm(y - np.asarray(features_b, dtype=float), axis=-1) / grid.spacing


def active_voxels(phi, grid, band=2.0):
    """Nodes with phi < band * h (material of A plus a band), the cost-growth abscissa."""
    return int(np.count_nonzero(np.asarray(phi) < band * grid.spacing))


# -- volume held per part ------------------------------------------------------
def part_volumes(phi, grid, labels=None):
    """Volume of each part of {phi < 0}, (n,) with entry k - 1 for label k.

    Each part is measured as `volume` measures the whole, by marching cubes of ``phi``
    with the other parts' inside nodes made positive (|phi|). Parts are 6-connected, so
    no cell edge joins two parts: every crossing of the part's own surface is kept.
    ``labels`` as `parts` gives them (made here when omitted).
    """
    phi = np.asarray(phi, dtype=float)
    labels, n = parts(phi) if labels is None else (labels, int(labels.max()))
    inside = labels > 0
    return np.array([volume(np.where(inside & (labels != k), np.abs(phi), phi), grid)
                     for k in range(1, n + 1)])


def land(labels, grid, points):
    """The part (label, 0 for none) at the grid node nearest to each world point (P, d)."""
    idx = np.rint(grid.to_index(points)).astype(np.int64)
    idx = np.clip(idx, 0, np.asarray(grid.shape) - 1)
    return labels[tuple(idx.T)]


def _nearest_part(labels, grid, points):
    """The part (label >= 1) nearest to each world point (P, d): that of the inside node
    nearest to the point's nearest node."""
    _, near = ndimage.distance_transform_edt(labels == 0, return_indices=True)
    return land(labels[tuple(near)], grid, points)


def _inside_samples(phi, grid, per_axis=3):
    """World points inside {phi < 0} on a lattice ``per_axis`` times finer than the grid
    (phi read multilinearly), (M, d): the material as equal small volumes."""
    h = grid.spacing
    near = np.asarray(phi) < h
    offsets = (np.arange(per_axis) + 0.5) / per_axis - 0.5
    sub = np.stack(np.meshgrid(*[offsets] * grid.dim, indexing="ij"), axis=-1).reshape(-1, grid.dim)
    pts = (grid.points()[near][:, None, :] + h * sub[None]).reshape(-1, grid.dim)
    return pts[sample(phi, grid, pts, outside="distance") < 0]


def material_pieces(phi_a, phi_b, grid, forward, backward=None):
    """The material of a keyframe pair divided into pieces along the maps.

    The pieces are the parts of the keyframe with more parts (A on a tie); the other
    keyframe's material goes to the piece its map sends it nearest to (a merge's one
    ball is shared between the two balls by where the backward map sends it, a split's
    by where the forward map sends it). Without ``backward`` (the one-sided transport)
    B's material goes to the piece of the nearest forward image of A's material.

    Parameters
    ----------
    phi_a, phi_b : ndarray, grid.shape, the keyframes (negative inside).
    grid : Grid
    forward : callable (points (P, d), t) -> positions (P, d)
        Paths of A's material, A at t = 0, B at t = 1.
    backward : callable like ``forward``, optional
        Paths of B's material, B at t = 0, A at t = 1.

    Returns
    -------
    piece_a, piece_b : int ndarray, grid.shape
        The piece (1..n) of every inside node of A and of B, 0 elsewhere.
    volumes : (n, 2) array
        Each piece's volume in A and in B: a part's own `part_volumes`, or the sum over the
        other keyframe's parts of each part's volume times the fraction of it the piece
        gets (fractions of `_inside_samples`, 27 per cell).
    own : int
        The column of ``volumes`` where the pieces are parts (0: A, 1: B).
    """
    lab_a, na = parts(phi_a)
    lab_b, nb = parts(phi_b)
    own_is_a = na >= nb
    own, other = (lab_a, lab_b) if own_is_a else (lab_b, lab_a)
    phi_other = phi_b if own_is_a else phi_a

    def to_own(points):
        if not own_is_a:
            return _nearest_part(own, grid, forward(points, 1.0))
        if backward is not None:
            return _nearest_part(own, grid, backward(points, 1.0))
        from scipy.spatial import cKDTree
        source = grid.points()[lab_a > 0]
        _, i = cKDTree(forward(source, 1.0)).query(points)
        return lab_a[lab_a > 0][i]

    n, m = max(na, nb), min(na, nb)
    piece_other = np.zeros_like(other)
    piece_other[other > 0] = to_own(grid.points()[other > 0])
    samples = _inside_samples(phi_other, grid)
    counts = np.bincount(_nearest_part(other, grid, samples) * (n + 1) + to_own(samples),
                         minlength=(m + 1) * (n + 1)).reshape(m + 1, n + 1)[1:, 1:]
    fraction = counts / np.maximum(counts.sum(axis=1, keepdims=True), 1)
    shared = part_volumes(phi_other, grid, other) @ fraction
    own_volumes = part_volumes(phi_a if own_is_a else phi_b, grid, own)
    if own_is_a:
        return own, piece_other, np.stack([own_volumes, shared], axis=1), 0
    return piece_other, own, np.stack([shared, own_volumes], axis=1), 1


def part_volume_errors(frames, times, grid, phi_a, phi_b, forward, backward=None):
    """Each piece's volume while it is a part on its own, against its straight line.

    The pieces are `material_pieces`. At time s, A's inside nodes are moved along
    ``forward`` to s and B's along ``backward`` to 1 - s (when given) and each lands on
    the part of the frame at its nearest node (`land`); a piece's part is the one most
    of its nodes land on. A piece is apart when no other piece has the same part; its
    part's volume (`part_volumes`) is then compared with
    V_lin(s) = (1 - s) V_A(piece) + s V_B(piece), and with V_own(s), the piece's share of
    the keyframe where it is a part held on the straight line of the total,
    V_own(s) = V(piece) / V * ((1 - s) V_A + s V_B): a reference the maps do not decide,
    where V_B(piece) is only as good as the map that shares B out. Parts no piece claims
    are spurious pieces (`spurious_components` counts them), not measured here.

    Parameters
    ----------
    frames : list of ndarray, grid.shape, the in-betweens at ``times``.
    times : (T,) array in [0, 1]
    grid, phi_a, phi_b, forward, backward : as in `material_pieces`.

    Returns
    -------
    list of dict, one per (frame, piece apart): ``s``, ``piece`` (1..n), ``volume``,
    ``reference`` (V_lin), ``error`` = |volume - reference| / reference and ``own_error``,
    the same against V_own.
    """
    piece_a, piece_b, ends, own = material_pieces(phi_a, phi_b, grid, forward, backward)
    share = ends[:, own] / ends[:, own].sum()
    total = (volume(phi_a, grid), volume(phi_b, grid))
    pts_a = grid.points()[piece_a > 0]
    pts_b = grid.points()[piece_b > 0]
    n = len(ends)
    out = []
    for phi, s in zip(frames, times):
        labels, m = parts(phi)
        if m == 0:
            continue
        hits = [(piece_a[piece_a > 0], land(labels, grid, forward(pts_a, s)))]
        if backward is not None:
            hits.append((piece_b[piece_b > 0], land(labels, grid, backward(pts_b, 1.0 - s))))
        piece, part = (np.concatenate(x) for x in zip(*hits))
        keep = part > 0
        votes = np.bincount(piece[keep] * (m + 1) + part[keep], minlength=(n + 1) * (m + 1))
        votes = votes.reshape(n + 1, m + 1)[1:, 1:]
        claimed = np.where(votes.max(axis=1) > 0, votes.argmax(axis=1) + 1, 0)
        vols = None
        for p in range(1, n + 1):
            j = claimed[p - 1]
            if j == 0 or np.count_nonzero(claimed == j) > 1:
                continue
            vols = part_volumes(phi, grid, labels) if vols is None else vols
            v = vols[j - 1]
            ref = (1 - s) * ends[p - 1, 0] + s * ends[p - 1, 1]
            ref_own = share[p - 1] * ((1 - s) * total[0] + s * total[1])
            out.append({"s": float(s), "piece": p, "volume": float(v), "reference": float(ref),
                        "error": float(abs(v - ref) / ref),
                        "own_error": float(abs(v - ref_own) / ref_own)})
    return out


# -- the maps' volume change ---------------------------------------------------
def det_f(mapped, grid, phi, crack=None):
    """det F of the node map ``mapped`` (grid.shape + (d,)) at the centre of every cell of
    the material of ``phi`` (Phi < 0 at the cell's centre), (E,), and whether each of
    those cells lies in the map's ``crack`` (bool over the cells, where the map tears,
    `map.tear`; None: nowhere), (E,).

    The solver's volume term reads det F there (eq. 2.6's first term, `elements`'s
    one-point rule); the cells are equal, so the array is the distribution over the
    material. A crack cell's corners lie on two pieces mapped apart: its det F measures
    the gap it spans, not a deformation of material.
    """
    d = grid.dim
    centre = sum(elements.corner_views(np.asarray(phi, dtype=float))) / 2 ** d < 0
    Y = np.stack([v[centre] for v in elements.corner_views(np.asarray(mapped, float), d)], axis=1)
    G = elements.quadrature(d, grid.spacing, "centre").G
    torn = np.zeros(len(Y), bool) if crack is None else np.asarray(crack)[centre]
    return elements.determinant(elements.deformation_gradient(Y, G))[:, 0], torn


def det_f_summary(dets, torn=None, band=(0.8, 1.25)):
    """Over the material off the crack (``torn`` False): 5th, 50th and 95th percentiles of
    det F, max |det F - 1| and the fraction with det F in ``band``; and ``crack``, the
    fraction of the material in the crack, as a dict (``p5``, ``p50``, ``p95``,
    ``max_dev``, ``in_band``, ``crack``)."""
    dets = np.asarray(dets, dtype=float)
    torn = np.zeros(len(dets), bool) if torn is None else np.asarray(torn, bool)
    kept = dets[~torn]
    p5, p50, p95 = np.percentile(kept, [5, 50, 95])
    return {"p5": float(p5), "p50": float(p50), "p95": float(p95),
            "max_dev": float(np.max(np.abs(kept - 1))),
            "in_band": float(np.mean((kept >= band[0]) & (kept <= band[1]))),
            "crack": float(np.mean(torn))}


def top_height(phi, grid, x=0.0, y=0.0):
    """Height z of the top of the lowest inside run of ``phi`` along the vertical line
    (x, y): phi read multilinearly at the nodes' heights, the zero crossing interpolated
    linearly. NaN where the line meets no material or the run reaches the grid's top."""
    z = grid.axes()[2]
    line = np.stack([np.full_like(z, x), np.full_like(z, y), z], axis=-1)
    v = sample(phi, grid, line)
    inside = np.flatnonzero(v < 0)
    if inside.size == 0:
        return float("nan")
    out = np.flatnonzero(v[inside[0]:] >= 0)
    if out.size == 0:
        return float("nan")
    k = inside[0] + out[0]  # first node above the run: the crossing is in (k - 1, k)
    return float(z[k - 1] + (z[k] - z[k - 1]) * v[k - 1] / (v[k - 1] - v[k]))
