"""Analytic keyframe pairs with known maps, shared by the in-between tests and benchmark.

Every case returns (grid, phi_a, phi_b, mapped, info) with exact (or nearly exact)
signed distance functions and a smooth map y(x) given in closed form, so the
in-between stage can be checked without the solver.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial.transform import Rotation

from keyframe_implicit.core.base.grid import Grid


# ---------------------------------------------------------------- SDF primitives
def sd_box(p, centre, half, rounding=0.0):
    q = np.abs(p - np.asarray(centre)) - (np.asarray(half) - rounding)
    out = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(np.max(q, axis=-1), 0.0)
    return out + inside - rounding


def sd_sphere(p, centre, radius):
    return np.linalg.norm(p - np.asarray(centre), axis=-1) - radius


def sd_capsule(p, a, b, radius):
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    pa = p - a
    ba = b - a
    t = np.clip(pa @ ba / (ba @ ba), 0.0, 1.0)
    return np.linalg.norm(pa - t[..., None] * ba, axis=-1) - radius


def make_grid(d, n, lo=-1.2, hi=1.2):
    h = (hi - lo) / (n - 1)
    return Grid(origin=(lo,) * d, spacing=h, shape=(n,) * d)


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
