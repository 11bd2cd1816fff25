"""The test cases tests/core shares: grids, fields, keyframe pairs and meshes.

One place for the inputs many tests build, so that a test names its case instead of
repeating its arithmetic (and benchmarks/bench_inbetween.py uses the rigid case too):

* grids: `make_grid` (n^d nodes from lo to hi, by default [-1.2, 1.2]^d), `unit_grid`
  ([0, 1]^d);
* signed distance primitives on points, ``sd_*``, and `sphere_field` on a grid's nodes;
  `sd_ellipsoid` is the first-order ellipsoid distance (exact on the surface only);
* `rotation` (axis, angle) as a matrix;
* analytic in-between cases with known maps (`rigid_case`, `merge_case`, `bend_case`):
  each returns (grid, phi_a, phi_b, mapped, info) with exact (or nearly exact) signed
  distance functions and a smooth map y(x) given in closed form, so the in-between stage
  can be checked without the solver;
* volume map cases for `solve_map` (`sphere_to_ellipsoid`, `two_discs`,
  `unequal_balls`): each returns
  (grid, phi_a, phi_b, features_a, features_b); `nudged_spheres` and
  `capsule_and_balls` give a pair of fields on a given grid;
* meshes for `animate`: `uv_sphere`, `sphere_features` and the keyframes of
  `turning_sphere` and `moving_growing_sphere`.

A case's arrays are the tests' contract: changing one changes what every test using it
asserts, so a new variant is a new function (or argument), never an edit of an old one.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial.transform import Rotation

from keyframe_implicit.core import Grid, Keyframe


# ---------------------------------------------------------------- SDF primitives
def sd_box(p, centre, half, rounding=0.0):
    """Exact SDF of an axis-aligned box (half extents ``half``), its edges rounded by ``rounding``."""
    q = np.abs(p - np.asarray(centre)) - (np.asarray(half) - rounding)
    out = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(np.max(q, axis=-1), 0.0)
    return out + inside - rounding


def sd_sphere(p, centre, radius):
    """Exact SDF of the ball (disc in 2D) of ``radius`` about ``centre``, at the points ``p``."""
    return np.linalg.norm(p - np.asarray(centre), axis=-1) - radius


def sd_capsule(p, a, b, radius):
    """Exact SDF of the capsule of ``radius`` about the segment from ``a`` to ``b``."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    pa = p - a
    ba = b - a
    t = np.clip(pa @ ba / (ba @ ba), 0.0, 1.0)
    return np.linalg.norm(pa - t[..., None] * ba, axis=-1) - radius


def sd_ellipsoid(p, centre, axes):
    """Approximate SDF of an axis-aligned ellipsoid with semi-axes ``axes`` (exact on the
    surface, first order near it)."""
    q = (p - centre) / axes
    k0 = np.linalg.norm(q, axis=-1)
    k1 = np.linalg.norm((p - centre) / axes ** 2, axis=-1)
    return k0 * (k0 - 1) / np.maximum(k1, 1e-12)


# ---------------------------------------------------------------- grids and fields on them
def make_grid(d, n, lo=-1.2, hi=1.2):
    """n^d nodes from ``lo`` to ``hi`` on every axis."""
    h = (hi - lo) / (n - 1)
    return Grid(origin=(lo,) * d, spacing=h, shape=(n,) * d)


def unit_grid(d, n):
    """n^d nodes on the unit cube [0, 1]^d (spacing 1 / (n - 1))."""
    return make_grid(d, n, 0.0, 1.0)


def sphere_field(grid, centre, radius):
    """Exact SDF of the ball (disc in 2D) of ``radius`` about ``centre``, on the grid's nodes."""
    return sd_sphere(grid.points(), centre, radius)


def nudged_spheres(grid):
    """A sphere of radius 0.3 about (0.5, ..., 0.5) and the same moved by 0.02 along every
    axis: a small, well-posed map on the unit cube (phi_a, phi_b)."""
    return sphere_field(grid, 0.5, 0.3), sphere_field(grid, 0.52, 0.3)


def capsule_and_balls(grid, capsule_radius, ball_radius):
    """A capsule along x (its segment |x| <= 0.35) and two balls about x = -1.1 and 1.1:
    the example merge seen backwards, one body torn into two (3D; phi_a, phi_b)."""
    P = grid.points()
    axis = np.clip(P[..., 0], -0.35, 0.35)
    capsule = np.sqrt((P[..., 0] - axis) ** 2 + P[..., 1] ** 2 + P[..., 2] ** 2) - capsule_radius
    balls = np.minimum(sd_sphere(P, [-1.1, 0, 0], ball_radius),
                       sd_sphere(P, [1.1, 0, 0], ball_radius))
    return capsule, balls


def rotation(axis, angle):
    """The 3x3 rotation by ``angle`` about ``axis`` (Rodrigues' formula)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


# ---------------------------------------------------------------- rigid L-shape
def l_shape(p):
    """A non-convex solid: union of two rounded boxes (an L), in 3D."""
    b1 = sd_box(p, (0.0, -0.25, 0.0), (0.5, 0.15, 0.2), 0.06)
    b2 = sd_box(p, (0.35, 0.12, 0.0), (0.15, 0.3, 0.2), 0.06)
    return np.minimum(b1, b2)


@functools.lru_cache(maxsize=None)
def l_centroid(n=160):
    """Centroid of the L-shape by dense sampling (independent of the code under test)."""
    ax = np.linspace(-0.8, 0.8, n)
    p = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    inside = l_shape(p) < 0
    out = p[inside].mean(axis=0)
    out.setflags(write=False)
    return out


RIGID_AXIS = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
RIGID_T = np.array([0.25, -0.1, 0.15])


def rigid_case(n=36, angle=np.pi / 2):
    """L-shape turned by ``angle`` about a tilted axis through its centroid and translated."""
    grid = make_grid(3, n)
    x = grid.points()
    c = l_centroid()
    R = Rotation.from_rotvec(angle * RIGID_AXIS).as_matrix()
    mapped = c + RIGID_T + (x - c) @ R.T
    phi_a = l_shape(x)
    phi_b = l_shape(c + (x - c - RIGID_T) @ R)  # R^T (z - c - t) + c
    return grid, phi_a, phi_b, mapped, dict(centroid=c, R=R, t=RIGID_T, angle=angle)


def rigid_expected(p, s, info):
    """Exact SDF of the solid turned by s * angle about its centroid, centroid on the line."""
    c = info["centroid"]
    Rs = Rotation.from_rotvec(s * info["angle"] * RIGID_AXIS).as_matrix()
    q = c + (p - c - s * info["t"]) @ Rs
    return l_shape(q)


# ---------------------------------------------------------------- merge
def merge_case(d=3, n=36, r=0.35, gap=0.2, overlap=0.05):
    """Two balls (discs) of radius r, ``gap`` apart, pressed into one body.

    Each ball moves rigidly toward the other along x until they overlap by
    ``overlap`` (a lens far below 1% of the volume), the space between them is
    squeezed by a smooth step of the displacement. B is the union of the moved
    balls: one body of (nearly) equal volume.
    """
    grid = make_grid(d, n)
    x = grid.points()
    c0 = r + 0.5 * gap
    c1 = r - 0.5 * overlap
    shift = c0 - c1
    e = np.zeros(d)
    e[0] = 1.0
    # displacement along x: +shift for x < -w, -shift for x > w, smooth in between
    w = 0.5 * gap
    t = np.clip(x[..., 0] / w, -1.0, 1.0)
    step = 0.5 * t * (3.0 - t * t)  # C1 odd step from -1 to 1
    mapped = x.copy()
    mapped[..., 0] = x[..., 0] - shift * step
    phi_a = np.minimum(sd_sphere(x, -c0 * e, r), sd_sphere(x, c0 * e, r))
    phi_b = np.minimum(sd_sphere(x, -c1 * e, r), sd_sphere(x, c1 * e, r))
    return grid, phi_a, phi_b, mapped, dict(r=r)


# ---------------------------------------------------------------- articulated bend
def bend_case(d=2, n=40, half=0.6, radius=0.12, blend=0.15, left=None):
    """A rod (capsule) along x, bent 90 degrees at its middle (the origin).

    The left half stays, the right half turns rigidly by 90 degrees about the
    joint (to +y); across |x| < blend the angle goes smoothly from 0 to 90
    degrees. B is the union of the two halves in their final places. ``left``
    (default ``half``) is the length of the left part: a longer left part puts
    the joint away from the rod's centroid.
    """
    left = half if left is None else left
    grid = make_grid(d, n, -1.0, 1.0)
    x = grid.points()
    t = np.clip((x[..., 0] + blend) / (2 * blend), 0.0, 1.0)
    ang = 0.5 * np.pi * t * t * (3.0 - 2.0 * t)
    c, s = np.cos(ang), np.sin(ang)
    mapped = x.copy()
    mapped[..., 0] = c * x[..., 0] - s * x[..., 1]
    mapped[..., 1] = s * x[..., 0] + c * x[..., 1]
    z = np.zeros(d)
    ex = z.copy()
    ex[0] = half
    ey = z.copy()
    ey[1] = half
    el = z.copy()
    el[0] = -left
    phi_a = sd_capsule(x, el, ex, radius)
    phi_b = np.minimum(sd_capsule(x, el, z, radius), sd_capsule(x, z, ey, radius))
    return grid, phi_a, phi_b, mapped, dict(half=half, left=left, radius=radius, tip_a=el,
                                            tip_b=ex, joint=z, blend=blend)


# ---------------------------------------------------------------- volume map cases
def sphere_to_ellipsoid(n):
    """Sphere r = 0.3 -> equal-volume prolate ellipsoid, six pole features (3D, n^3 nodes
    on the unit cube)."""
    g = unit_grid(3, n)
    P = g.points()
    c = np.array([0.5, 0.5, 0.5])
    phi_a = sd_sphere(P, c, 0.3)
    ax = np.array([1.3, 1 / np.sqrt(1.3), 1 / np.sqrt(1.3)]) * 0.3
    dirs = np.vstack([np.eye(3), -np.eye(3)])
    return g, phi_a, sd_ellipsoid(P, c, ax), c + 0.3 * dirs, c + ax * dirs


def two_discs(n):
    """Two discs (r = 0.16, 0.36 apart) merged into one disc of their area, four features
    on each disc onto its half of the merged one (2D, n^2 nodes on the unit square)."""
    g = unit_grid(2, n)
    P = g.points()
    c, r1, s = np.array([0.5, 0.5]), 0.16, 0.18
    R = r1 * np.sqrt(2)  # same area as the two discs
    phi_a = np.minimum(sd_sphere(P, c - [s, 0], r1), sd_sphere(P, c + [s, 0], r1))
    phi_b = sd_sphere(P, c, R)
    fa, fb = [], []
    for side in (-1, 1):  # each disc onto its half of the merged disc
        fa += [[.5 + side * (s - r1), .5], [.5 + side * (s + r1), .5], [.5 + side * s, .5 + r1], [.5 + side * s, .5 - r1]]
        fb += [[.5 + side * 0.015, .5], [.5 + side * R, .5], [.5 + side * 0.04, .5 + 0.96 * R],
               [.5 + side * 0.04, .5 - 0.96 * R]]
    return g, phi_a, phi_b, np.array(fa), np.array(fb)


def unequal_balls(n, gap_cells=3.0):
    """Two balls (r = 0.13, 0.18, ``gap_cells`` cells of a 40^3 unit-box grid apart) merged
    into one ball of their volume, four features on each onto its share of the merged ball
    (3D, n^3 nodes on [-1, 1]^3). Returns (grid, phi_a, phi_b, features_a, features_b)."""
    g = make_grid(3, n, -1.0, 1.0)
    P = g.points()
    ra, rb = 0.13, 0.18
    gap = gap_cells * 2.0 / 39
    ca, cb = np.array([-(ra + gap / 2), 0, 0]), np.array([rb + gap / 2, 0, 0])
    R = (ra ** 3 + rb ** 3) ** (1 / 3)
    # the plane x = x0 cuts the merged ball in the two balls' volumes; each share's centroid
    x = np.linspace(-R, R, 4001)
    area = np.pi * (R ** 2 - x ** 2)
    left = np.cumsum(area) / area.sum() <= ra ** 3 / R ** 3
    share = [(x[m] * area[m]).sum() / area[m].sum() for m in (left, ~left)]
    fa, fb = [], []
    for c, r, x0 in ((ca, ra, share[0]), (cb, rb, share[1])):
        off = 0.5 * r * np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]])
        fa.append(c + off)
        fb.append(np.array([x0, 0, 0]) + off)
    phi_a = np.minimum(sd_sphere(P, ca, ra), sd_sphere(P, cb, rb))
    return g, phi_a, sd_sphere(P, (0, 0, 0), R), np.vstack(fa), np.vstack(fb)


# ---------------------------------------------------------------- meshes and keyframes for animate
def uv_sphere(center, radius, n=24):
    """Closed, outward-wound UV sphere (triangles): n rings of 2 n vertices between the poles.

    The tests' own mesh (not `keyframe_implicit.shapes.uv_sphere`, which has quads)."""
    th = np.linspace(0, np.pi, n + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    v = np.vstack([[0, 0, 1], ring, [0, 0, -1]]) * radius + center
    m = 2 * n
    idx = lambda r, c: 1 + r * m + (c % m)  # noqa: E731
    faces = []
    c = np.arange(m)
    faces.append(np.stack([np.zeros(m, int), idx(0, c), idx(0, c + 1)], 1))
    for r in range(n - 2):
        a, b, cc, d = idx(r, c), idx(r, c + 1), idx(r + 1, c), idx(r + 1, c + 1)
        faces += [np.stack([a, cc, b], 1), np.stack([b, cc, d], 1)]
    last = len(v) - 1
    faces.append(np.stack([np.full(m, last), idx(n - 2, c + 1), idx(n - 2, c)], 1))
    return v, np.vstack(faces)


def sphere_features(center, radius, rot=np.eye(3), offset=np.zeros(3)):
    """Six feature points at 0.7 ``radius`` inside a sphere about ``center``, and where the
    sphere turned by ``rot`` about its centre and moved by ``offset`` takes them."""
    dirs = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0.6, -0.8]])
    a = center + 0.7 * radius * dirs
    b = (a - center) @ rot.T + center + offset
    return a, b


def moving_growing_sphere(shift=0.0, moved=(0, 1)):
    """Three keyframes on frames 0, 4 and 9: a sphere moves, then moves and grows; six
    feature pairs a segment. ``shift`` moves one feature point along x: point 0 of the
    segment and side (0: A, 1: B) ``moved`` names, as an artist drags one Empty."""
    v0, f0 = uv_sphere(np.zeros(3), 0.25, n=16)
    o1, o2 = np.array([0.3, 0.0, 0.0]), np.array([0.3, 0.3, 0.0])
    feats = [sphere_features(np.zeros(3), 0.25, offset=o1),
             sphere_features(o1, 0.25, offset=o2 - o1)]
    feats[moved[0]][moved[1]][0] += (shift, 0.0, 0.0)
    keyframes = [Keyframe(v0, f0, 0), Keyframe(v0 + o1, f0, 4), Keyframe(v0 * 1.3 + o2, f0, 9)]
    return keyframes, feats


def turning_sphere(n=24, last=13):
    """A sphere turning about (1, 2, 0.5) while it squashes and moves: keyframes on frames
    1 and ``last``, six feature pairs."""
    r = 0.3
    rot = rotation((1.0, 2.0, 0.5), 0.8)
    squash = np.diag([1.2, 1.0, 1 / 1.2])
    va, fa = uv_sphere(np.zeros(3), r, n=n)
    pa, _ = sphere_features(np.zeros(3), r)
    vb, pb = (x @ squash @ rot.T + [0.1, 0.0, 0.0] for x in (va, pa))
    return [Keyframe(va, fa, 1), Keyframe(vb, fa, last)], [(pa, pb)]
