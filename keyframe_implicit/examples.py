"""Example keyframe shapes and feature points (pure numpy / scikit-image, no bpy).

The thesis (chapter 4) shows four kinds of example; this module builds the same kinds in
3D as closed triangle meshes, and in 2D as polygons, each with the feature point pairs an
artist would place:

=========  ===============================================================  ==========
name       what moves                                                       thesis
=========  ===============================================================  ==========
rigid      an L-shaped block with a knob turns 90 degrees and translates    fig. 4.1
merge      two blobs join into one blob of the same volume                  fig. 4.2
bend       a rod bends 90 degrees at a joint (two rigid parts)              fig. 4.3
splash     a droplet falls into a pool: four keyframes (above, touching,    fig. 4.4
           merged bump, settled pool)
=========  ===============================================================  ==========

Every 3D example is an `Example`: a list of `keyframe_implicit.core.bake.keyframe.Keyframe`
(world-space vertices (V, 3), closed outward-wound triangles (F, 3), a timeline frame)
and, per segment (keyframe i -> i + 1), a pair of (N, 3) arrays of feature points, row j
of the first pairing with row j of the second. All keyframes of one example enclose the
same volume (the method keeps volume; the splash's pool rises as the droplet settles).
Units are Blender metres, z is up. ``Example.features`` is exactly what
`keyframe_implicit.core.animate` takes.

The shapes are built from analytic signed distance functions (negative inside) and
meshed by marching cubes; where a keyframe must match another's volume, one shape
parameter (a radius, a height) is solved for by the secant method on the mesh volume.

`example_2d` gives the 2D versions (merge, bend, splash) as counter-clockwise polygons
for ``polygon_to_sdf`` and the 2D core.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .core.bake.keyframe import Keyframe
from .core.surface.extract import loop_area, mesh_volume
from .shapes import (capsule_sdf, match_volume, mesh_of, rigid_motion, rotation, round_box_sdf,
                     round_cylinder_sdf, smooth_union, sphere_sdf)

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike

__all__ = [
    "Example",
    "Example2D",
    "NAMES",
    "NAMES_2D",
    "example",
    "example_2d",
    "rigid",
    "merge",
    "bend",
    "splash",
]

NAMES = ("rigid", "merge", "bend", "splash")
NAMES_2D = ("merge", "bend", "splash")



@dataclass
class Example:
    """A 3D example: keyframes on the timeline and feature point pairs per segment.

    Attributes
    ----------
    name : str
    keyframes : list of `Keyframe` (vertices (V, 3) float64, faces (F, 3) int64, frame int).
    features : list of (points_a, points_b), one per segment, (N, 3) float arrays.
    feature_names : list of lists of str, one name per pair (for the Empties in Blender).
    description : str, one line for people.
    """

    name: str
    keyframes: list[Keyframe]
    features: list[tuple[np.ndarray, np.ndarray]]
    feature_names: list[list[str]]
    description: str = ""

    @property
    def frames(self) -> list[int]:
        """Timeline frames of the keyframes."""
        return [k.frame for k in self.keyframes]

    @property
    def volumes(self) -> list[float]:
        """Enclosed volume of each keyframe mesh."""
        return [mesh_volume(k.vertices, k.faces) for k in self.keyframes]


@dataclass
class Example2D:
    """A 2D example: polygons per keyframe and feature point pairs per segment.

    Attributes
    ----------
    name : str
    shapes : list (one per keyframe) of lists of (M, 2) counter-clockwise closed polygons
        (the last vertex is not repeated); several polygons = several components.
    frames : list of int, timeline frame of each keyframe.
    features : list of (points_a, points_b), (N, 2) arrays, one per segment.
    """

    name: str
    shapes: list[list[np.ndarray]]
    frames: list[int]
    features: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)

    @property
    def areas(self) -> list[float]:
        """Enclosed area of each keyframe (sum over its polygons)."""
        return [sum(loop_area(p) for p in polys) for polys in self.shapes]


# --------------------------------------------------------------------------- geometry
# --------------------------------------------------------------------------- 3D examples
def rigid() -> Example:
    """An L-shaped block with a knob turns 90 degrees about z, rises and slides (fig. 4.1).

    The block has no mirror symmetry (the knob sits off the L's plane) so a viewer can
    tell its orientation. Keyframe B is keyframe A moved rigidly, vertex for vertex, so
    the volumes are identical. Eight pairs: the two arm tips, the corner, the knob, and
    points on the faces, all moved by the same rigid motion.
    """
    def sdf(p):
        long_arm = round_box_sdf(p, (0.0, 0.0, 0.0), (1.0, 0.3, 0.3), 0.12)
        short_arm = round_box_sdf(p, (0.7, 0.0, 0.55), (0.3, 0.3, 0.6), 0.12)
        knob = sphere_sdf(p, (-0.55, -0.3, 0.15), 0.24)
        return smooth_union(smooth_union(long_arm, short_arm, 0.1), knob, 0.08)

    va, fa = mesh_of(sdf, (-1.0, -0.55, -0.3), (1.0, 0.3, 1.15))
    shift_a = np.array([-1.2, 0.0, 0.0])
    va = va + shift_a
    rot = rotation((0.0, 0.0, 1.0), 90.0)
    centre = np.array([-1.2, 0.0, 0.3])
    move = np.array([2.4, 0.4, 0.4])
    vb = rigid_motion(va, rot, centre, move)

    names = ["tip_long", "tip_short", "corner", "knob", "long_top", "long_bottom",
             "short_side", "long_front"]
    pa = np.array([
        [-0.85, 0.0, 0.0],    # tip of the long arm (inside)
        [0.7, 0.0, 1.0],      # tip of the short arm
        [0.7, 0.0, 0.0],      # corner of the L
        [-0.55, -0.45, 0.2],  # knob
        [-0.3, 0.0, 0.29],    # top face of the long arm
        [0.0, 0.0, -0.29],    # bottom face of the long arm
        [0.99, 0.0, 0.5],     # outer side of the short arm
        [0.2, -0.29, 0.0],    # front face of the long arm
    ]) + shift_a
    pb = rigid_motion(pa, rot, centre, move)
    return Example(
        "rigid",
        [Keyframe(va, fa, 1), Keyframe(vb, fa.copy(), 25)],
        [(pa, pb)],
        [names],
        "an L-shaped block with a knob turns 90 degrees and translates (rigid motion)",
    )


def merge() -> Example:
    """Two blobs join into one blob of the same volume (fig. 4.2).

    Keyframe A: two spheres of radius 0.6, 2.2 apart. Keyframe B: one rounded blob (a fat
    capsule) centred between them whose radius is solved so it encloses the same volume.
    Eight pairs: the outer pole, top and front of each blob go to the matching places of
    the merged blob; the two centres go to either side of its middle.
    """
    r = 0.6
    ca, cb = np.array([-1.1, 0.0, 0.0]), np.array([1.1, 0.0, 0.0])

    def sdf_a(p):
        return np.minimum(sphere_sdf(p, ca, r), sphere_sdf(p, cb, r))

    va, fa = mesh_of(sdf_a, (-1.8, -0.7, -0.7), (1.8, 0.7, 0.7))
    half = 0.35  # half-length of the merged capsule's axis

    def make_b(radius):
        return mesh_of(lambda p: capsule_sdf(p, (-half, 0, 0), (half, 0, 0), radius),
                         (-half - 1.0, -1.0, -1.0), (half + 1.0, 1.0, 1.0))

    vb, fb = match_volume(make_b, mesh_volume(va, fa), 0.7, 0.72)
    rb = float(np.max(np.abs(vb[:, 1])))  # the merged blob's radius, read off the mesh
    names = ["left_pole", "right_pole", "left_centre", "right_centre",
             "left_top", "right_top", "left_front", "right_front"]
    pa = np.array([
        ca - [r * 0.9, 0, 0], cb + [r * 0.9, 0, 0], ca, cb,
        ca + [0, 0, r * 0.9], cb + [0, 0, r * 0.9],
        ca - [0, r * 0.9, 0], cb - [0, r * 0.9, 0],
    ])
    pb = np.array([
        [-half - 0.9 * rb, 0, 0], [half + 0.9 * rb, 0, 0], [-0.4 * rb, 0, 0], [0.4 * rb, 0, 0],
        [-half, 0, 0.9 * rb], [half, 0, 0.9 * rb],
        [-half, -0.9 * rb, 0], [half, -0.9 * rb, 0],
    ])
    return Example(
        "merge",
        [Keyframe(va, fa, 1), Keyframe(vb, fb, 25)],
        [(pa, pb)],
        [names],
        "two blobs join into one blob of the same volume (topology change)",
    )


def bend() -> Example:
    """A rod bends 90 degrees at a joint: two rigid parts (fig. 4.3).

    Keyframe A: a straight capsule from x = -1.5 to 1.5 (radius 0.3) with a knuckle at the
    joint x = 0. Keyframe B: the right half turned 90 degrees up about the joint (y axis);
    the rod's radius is solved (a fraction of a percent) so the bent rod keeps the volume.
    Eight pairs: both ends, the joint, the middle of each part and two off-axis points on
    the moving part (they fix its twist).
    """
    r = 0.3
    rot = rotation((0.0, -1.0, 0.0), 90.0)  # takes +x to +z

    def sdf_a(p):
        rod = capsule_sdf(p, (-1.5, 0, 0), (1.5, 0, 0), r)
        return smooth_union(rod, sphere_sdf(p, (0, 0, 0), 1.2 * r), 0.1)

    def make_b(radius):
        def sdf(p):
            fixed = capsule_sdf(p, (-1.5, 0, 0), (0, 0, 0), radius)
            moving = capsule_sdf(p, (0, 0, 0), (0, 0, 1.5), radius)
            return smooth_union(np.minimum(fixed, moving),
                                 sphere_sdf(p, (0, 0, 0), 1.2 * radius), 0.1)
        return mesh_of(sdf, (-1.5 - r, -r * 1.3, -r * 1.3), (r * 1.3, r * 1.3, 1.5 + r))

    va, fa = mesh_of(sdf_a, (-1.5 - r, -r * 1.3, -r * 1.3), (1.5 + r, r * 1.3, r * 1.3))
    vb, fb = match_volume(make_b, mesh_volume(va, fa), r, r * 1.01)
    names = ["end_fixed", "end_moving", "joint", "mid_fixed", "mid_moving",
             "moving_side", "moving_top", "fixed_top"]
    pa = np.array([
        [-1.6, 0, 0], [1.6, 0, 0], [0, 0, 0], [-0.75, 0, 0], [0.75, 0, 0],
        [0.9, 0.25, 0], [1.2, 0, 0.25], [-1.2, 0, 0.25],
    ])
    moving = pa[:, 0] > 0.1
    pb = pa.copy()
    pb[moving] = pa[moving] @ rot.T
    return Example(
        "bend",
        [Keyframe(va, fa, 1), Keyframe(vb, fb, 25)],
        [(pa, pb)],
        [names],
        "a rod bends 90 degrees at a joint (articulated, rigid in its parts)",
    )


def splash() -> Example:
    """A droplet falls into a pool: four keyframes (fig. 4.4).

    1. a droplet (radius 0.35) above a round pool (radius 1.6, depth 0.4, surface z = 0);
    2. the droplet touching the pool (joined by a thin neck);
    3. a bump on the pool where the droplet merged;
    4. the settled pool, its surface raised so it holds the droplet's volume.
    Keyframes 2-4 each solve one parameter (droplet radius, bump height, surface height) so
    all four enclose the same volume. Per segment: four pool points (near the rim, they stay)
    and three to four droplet points (centre, top, sides) that fall, merge and spread.
    """
    R, depth, rd = 1.6, 0.4, 0.35
    zc = -depth / 2

    def pool(p, top=0.0):
        h = (top + depth) / 2
        return round_cylinder_sdf(p, (0, 0, top - h), R, h, 0.1)

    lo, hi = (-R, -R, -depth), (R, R, 2.2)
    drop_z = 1.4

    def sdf_0(p):
        return np.minimum(pool(p), sphere_sdf(p, (0, 0, drop_z), rd))

    v0, f0 = mesh_of(sdf_0, lo, hi)
    target = mesh_volume(v0, f0)

    def make_1(radius):  # droplet resting on the surface, joined by a small neck
        return mesh_of(lambda p: smooth_union(pool(p), sphere_sdf(p, (0, 0, radius * 0.95), radius),
                                                 0.08), lo, (R, R, 1.0))

    def make_2(height):  # a bump: a flattened ellipsoid (semi-axes 0.6, 0.6, height) on the pool
        height = max(height, 0.05)

        def sdf(p):
            q = p / np.array([0.6, 0.6, height])
            return smooth_union(pool(p), (np.linalg.norm(q, axis=-1) - 1.0) * min(0.6, height),
                                 0.05)
        return mesh_of(sdf, lo, (R, R, 1.0))

    def make_3(top):
        return mesh_of(lambda p: pool(p, top), lo, (R, R, 0.3))

    v1, f1 = match_volume(make_1, target, rd, rd * 0.98)
    v2, f2 = match_volume(make_2, target, 0.2, 0.25)
    v3, f3 = match_volume(make_3, target, 0.03, 0.04)
    top3 = float(v3[:, 2].max())
    bump_top = float(v2[:, 2].max())
    drop1_top = float(v1[:, 2].max())

    rim = 0.8 * R
    pool_pts = np.array([[rim, 0, zc], [0, rim, zc], [-rim, 0, zc], [0, -rim, zc]])
    # the droplet's centre, top and two sides in each of the first three keyframes
    drop_0 = np.array([[0, 0, drop_z], [0, 0, drop_z + 0.9 * rd],
                       [0.8 * rd, 0, drop_z], [0, 0.8 * rd, drop_z]])
    c1 = drop1_top - rd
    drop_1 = np.array([[0, 0, c1], [0, 0, c1 + 0.9 * rd], [0.8 * rd, 0, c1], [0, 0.8 * rd, c1]])
    drop_2 = np.array([[0, 0, 0.5 * bump_top], [0, 0, 0.95 * bump_top],
                       [0.45, 0, 0.05], [0, 0.45, 0.05]])
    drop_3 = np.array([[0, 0, 0.5 * top3 - 0.1], [0, 0, top3 - 0.03],
                       [0.9, 0, top3 - 0.05], [0, 0.9, top3 - 0.05]])
    # the pool points rise with the settled surface (the pool keeps its shape otherwise)
    pool_3 = pool_pts + [0, 0, top3 / 2]
    names = ["pool_east", "pool_north", "pool_west", "pool_south",
             "drop_centre", "drop_top", "drop_east", "drop_north"]
    feats = [
        (np.vstack([pool_pts, drop_0]), np.vstack([pool_pts, drop_1])),
        (np.vstack([pool_pts, drop_1]), np.vstack([pool_pts, drop_2])),
        (np.vstack([pool_pts, drop_2]), np.vstack([pool_3, drop_3])),
    ]
    return Example(
        "splash",
        [Keyframe(v0, f0, 1), Keyframe(v1, f1, 9), Keyframe(v2, f2, 15), Keyframe(v3, f3, 25)],
        feats,
        [names, list(names), list(names)],
        "a droplet falls into a pool: four keyframes (above, touching, bump, settled)",
    )


_BUILDERS = {"rigid": rigid, "merge": merge, "bend": bend, "splash": splash}


def example(name: str) -> Example:
    """The 3D example called `name` (one of `NAMES`)."""
    if name not in _BUILDERS:
        raise ValueError(f"unknown example {name!r}: choose one of {', '.join(NAMES)}")
    return _BUILDERS[name]()


# --------------------------------------------------------------------------- 2D examples
def _circle(centre: Sequence[float], radius: float, n: int = 48) -> np.ndarray:
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)], axis=1)


def _stadium(a: ArrayLike, b: ArrayLike, radius: float, n: int = 64) -> np.ndarray:
    """Counter-clockwise outline of a 2D capsule around segment a-b."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = (b - a) / np.linalg.norm(b - a)
    ang = np.arctan2(d[1], d[0])
    m = n // 2
    t1 = ang - np.pi / 2 + np.linspace(0, np.pi, m)           # cap around b
    t2 = ang + np.pi / 2 + np.linspace(0, np.pi, m)           # cap around a
    cap_b = b + radius * np.stack([np.cos(t1), np.sin(t1)], 1)
    cap_a = a + radius * np.stack([np.cos(t2), np.sin(t2)], 1)
    return np.vstack([cap_b, cap_a])


def _rounded_rect(x0: float, y0: float, x1: float, y1: float, radius: float,
                  n: int = 12) -> np.ndarray:
    """Counter-clockwise rounded rectangle."""
    corners = [((x1 - radius, y0 + radius), -np.pi / 2), ((x1 - radius, y1 - radius), 0.0),
               ((x0 + radius, y1 - radius), np.pi / 2), ((x0 + radius, y0 + radius), np.pi)]
    pts = []
    for (cx, cy), start in corners:
        t = start + np.linspace(0, np.pi / 2, n)
        pts.append(np.stack([cx + radius * np.cos(t), cy + radius * np.sin(t)], 1))
    return np.vstack(pts)


def _bend_2d_outline(angle_deg: float, r: float = 0.3, length: float = 1.5,
                     n: int = 24) -> np.ndarray:

    """Outline of a rod bent at the origin: fixed part along -x, moving part at `angle_deg`."""
    ang = np.radians(angle_deg)
    d = np.array([np.cos(ang), np.sin(ang)])
    nrm = np.array([-d[1], d[0]])
    end_m = length * d
    end_f = np.array([-length, 0.0])
    pts = []
    # cap of the moving end (from -nrm side to +nrm side, counter-clockwise)
    t = np.arctan2(-nrm[1], -nrm[0]) + np.linspace(0, np.pi, n)
    pts.append(end_m + r * np.stack([np.cos(t), np.sin(t)], 1))
    # inner (upper-left) side: the two offset lines meet at their intersection
    inner = np.array([-r * np.tan((np.pi - ang) / 2) if ang > 1e-9 else 0.0, r])
    if angle_deg <= 1e-9:
        inner = np.array([0.0, r])
    pts.append(inner[None])
    # cap of the fixed end (top to bottom around the left)
    t = np.pi / 2 + np.linspace(0, np.pi, n)
    pts.append(end_f + r * np.stack([np.cos(t), np.sin(t)], 1))
    # outer side: a round elbow around the joint from -y to -nrm direction
    t = -np.pi / 2 + np.linspace(0, ang, max(2, int(n * ang / np.pi) + 2))
    pts.append(r * np.stack([np.cos(t), np.sin(t)], 1))
    return np.vstack(pts)


def example_2d(name: str) -> Example2D:

    """The 2D version of a thesis example (one of `NAMES_2D`), as polygons + feature points.

    merge: two discs join into one capsule of equal area (fig. 4.2); bend: a rod bends 90
    degrees (fig. 4.3); splash: a droplet above a pool, touching, a bump, the settled pool
    (fig. 4.4, four keyframes). Areas are equal across keyframes within 1%.
    """
    if name == "merge":
        r = 0.6
        a = [_circle((-1.1, 0.0), r), _circle((1.1, 0.0), r)]
        target = 2 * np.pi * r * r
        half = 0.35
        # stadium area: pi rb^2 + 4 half rb = target
        rb = (-4 * half + np.sqrt(16 * half * half + 4 * np.pi * target)) / (2 * np.pi)
        b = [_stadium((-half, 0), (half, 0), rb)]
        pa = np.array([[-1.1 - 0.9 * r, 0], [1.1 + 0.9 * r, 0], [-1.1, 0], [1.1, 0],
                       [-1.1, 0.9 * r], [1.1, 0.9 * r], [-1.1, -0.9 * r], [1.1, -0.9 * r]])
        pb = np.array([[-half - 0.9 * rb, 0], [half + 0.9 * rb, 0], [-0.4 * rb, 0], [0.4 * rb, 0],
                       [-half, 0.9 * rb], [half, 0.9 * rb], [-half, -0.9 * rb], [half, -0.9 * rb]])
        return Example2D("merge", [a, b], [1, 13], [(pa, pb)])
    if name == "bend":
        a = [_bend_2d_outline(0.0)]
        b = [_bend_2d_outline(90.0)]
        c, s = 0.0, 1.0
        rot = np.array([[c, -s], [s, c]])
        pa = np.array([[-1.6, 0], [1.6, 0], [0, 0], [-0.75, 0], [0.75, 0], [1.2, 0.2],
                       [1.2, -0.2], [-1.2, 0.2]])
        pb = pa.copy()
        mv = pa[:, 0] > 0.1
        pb[mv] = pa[mv] @ rot.T
        return Example2D("bend", [a, b], [1, 13], [(pa, pb)])
    if name == "splash":
        W, depth, rd = 1.6, 0.5, 0.35
        pool = _rounded_rect(-W, -depth, W, 0.0, 0.1)
        drop_area = np.pi * rd * rd
        s0 = [pool, _circle((0, 1.4), rd)]
        # touching: the droplet just overlapping the surface (one component)
        s1 = [_union_outline(pool, _circle((0, rd * 0.92), rd))]
        # bump: half ellipse on the pool, area = droplet area
        bw = 0.7
        bh = 2 * drop_area / (np.pi * bw)
        s2 = [_pool_with_bump(W, depth, bw, bh)]
        rise = drop_area / (2 * W)
        s3 = [_rounded_rect(-W, -depth, W, rise, 0.1)]
        pool_pts = np.array([[1.2, -0.25], [-1.2, -0.25], [0.6, -0.35], [-0.6, -0.35]])
        d0 = np.array([[0, 1.4], [0, 1.4 + 0.9 * rd], [0.8 * rd, 1.4], [-0.8 * rd, 1.4]])
        c1 = rd * 0.92
        d1 = np.array([[0, c1], [0, c1 + 0.9 * rd], [0.8 * rd, c1], [-0.8 * rd, c1]])
        d2 = np.array([[0, 0.5 * bh], [0, 0.9 * bh], [0.5 * bw, 0.3 * bh], [-0.5 * bw, 0.3 * bh]])
        d3 = np.array([[0, 0.5 * rise - 0.1], [0, 0.8 * rise], [0.9, 0.5 * rise],
                       [-0.9, 0.5 * rise]])
        p3 = pool_pts + [0, rise / 2]
        feats = [(np.vstack([pool_pts, d0]), np.vstack([pool_pts, d1])),
                 (np.vstack([pool_pts, d1]), np.vstack([pool_pts, d2])),
                 (np.vstack([pool_pts, d2]), np.vstack([p3, d3]))]
        return Example2D("splash", [s0, s1, s2, s3], [1, 5, 8, 11], feats)
    raise ValueError(f"unknown 2D example {name!r}: choose one of {', '.join(NAMES_2D)}")


def _pool_with_bump(W: float, depth: float, bw: float, bh: float, n: int = 40) -> np.ndarray:
    """Pool outline whose flat top carries a half-ellipse bump (width 2 bw, height bh)."""
    base = _rounded_rect(-W, -depth, W, 0.0, 0.1)
    # the rounded rect's vertices run counter-clockwise starting on the right side;
    # replace its top edge (between the top-right and top-left corners) by the bump
    t = np.linspace(0.0, np.pi, n)[1:-1]
    bump = np.stack([bw * np.cos(t), bh * np.sin(t)], 1)
    k = len(base) // 4
    return np.vstack([base[: 2 * k], bump, base[2 * k:]])


def _union_outline(pool: np.ndarray, circle: np.ndarray) -> np.ndarray:

    """Outline of pool (top edge at y = 0) united with a circle dipping just below y = 0."""
    k = len(pool) // 4
    above = circle[circle[:, 1] > 0.0]
    # order the circle's points above the surface from right to left
    ang = np.arctan2(above[:, 1] - circle[:, 1].mean(), above[:, 0] - circle[:, 0].mean())
    above = above[np.argsort(np.where(ang < -np.pi / 2, ang + 2 * np.pi, ang))]
    return np.vstack([pool[: 2 * k], above, pool[2 * k:]])
