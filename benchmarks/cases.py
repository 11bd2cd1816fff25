"""Benchmark cases: analytic signed distance fields and paired feature points.

Every case lives in the cube [-1, 1]^3 sampled with ``n`` nodes per axis
(h = 2 / (n - 1)). A case is a list of keyframe fields (2, or 4 for the
splash chain) plus, for every adjacent pair, feature points (N, 3) in A and
their targets in B (row i pairs with row i), in world units.

Fields are exact signed distances where that is cheap (spheres, boxes,
capsules, planes). Unions use ``min``, which is exact outside the material
and near the surface; it only underestimates depth far inside where two
pieces overlap, which none of the metrics reads. The oblate spheroid is
exact (closest point by a vectorised bisection on the Lagrange parameter).

`CASE_NAMES` are the seven cases of the comparison table; `EXTRA_CASES` run by name: the
unequal merge and split (two balls of radii 0.13 and 0.18 and one ball of their volume),
``scan``, the Stanford bunny as scanned (open, 100k triangles, the copy the pymeshfix
package ships) into a ball of its volume, sampled by `keyframe_implicit.core.mesh_to_sdf`,
``bunny``, the same into a ball from the closed 3.7k-triangle bunny of the npm package
``bunny`` (fetched on first use into the user's cache, `bunny_mesh`), and ``bunny-squash``,
that bunny squashed to 0.6 of its height at equal volume.

The rigid case also carries ``truth(points, s)``: the signed distance of the
solid turned by ``s`` times the keyframe rotation about its centroid, with
the centroid moved on the straight line (the ground truth of the rigid case).
"""

from __future__ import annotations

import hashlib
import importlib.util
import io
import json
import os
import pathlib
import re
import tarfile
import urllib.request
from dataclasses import dataclass, field

import numpy as np

from keyframe_implicit.core.base.grid import Grid
from keyframe_implicit.shapes import capsule_sdf as sd_capsule
from keyframe_implicit.shapes import sphere_sdf as sd_sphere

__all__ = ["Case", "make_grid", "make_case", "keyframe_meshes", "CASE_NAMES", "EXTRA_CASES", "ALL_CASES", "rotation"]

#: The seven-case table (what ``compare.py`` runs by default).
CASE_NAMES = ("rigid", "merge", "split", "bend", "squash", "morph", "splash")
#: Cases run by name only (``compare.py --cases``): the unequal merge and split, whose parts
#: keep their own volume while apart, and two scanned meshes (96^3 resolves their ears).
EXTRA_CASES = ("unequal-merge", "unequal-split", "scan", "bunny", "bunny-squash")
ALL_CASES = CASE_NAMES + EXTRA_CASES


@dataclass
class Case:
    """Keyframes, feature points and known facts of one benchmark case.

    Attributes
    ----------
    name : str
    grid : Grid
    fields : list of ndarray, one signed distance grid per keyframe (negative inside).
    features : list of (features_a, features_b), one pair of (N, 3) arrays per segment.
    truth : callable(points (P, 3), s) -> signed distance, or None.
    expected_components : list of int, connected components of each keyframe.
    info : dict of facts of the case's geometry (e.g. the merge's ``gap``, world units).
    """

    name: str
    grid: Grid
    fields: list
    features: list
    truth: object = None
    expected_components: list = field(default_factory=list)
    info: dict = field(default_factory=dict)


def keyframe_meshes(case: Case) -> list[tuple[np.ndarray, np.ndarray]]:
    """The case's keyframes as meshes, (vertices, triangles) each: its own where it has one
    (``info["meshes"]``, a scanned mesh), else marching cubes of its field."""
    from keyframe_implicit.core.surface.extract import extract_surface

    own = case.info.get("meshes", [None] * len(case.fields))
    return [extract_surface(f, case.grid) if m is None else m for f, m in zip(case.fields, own)]


def make_grid(n: int) -> Grid:
    """The benchmark grid: ``n`` nodes per axis spanning [-1, 1]^3."""
    if n < 8:
        raise ValueError(f"grid size {n} is too small for the benchmark cases; use 16 or more.")
    return Grid(origin=(-1.0, -1.0, -1.0), spacing=2.0 / (n - 1), shape=(n, n, n))


# -- primitive signed distances (points (..., 3) -> (...)) -------------------
def sd_box(p, centre, half):
    q = np.abs(p - np.asarray(centre, float)) - np.asarray(half, float)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(np.max(q, axis=-1), 0.0)
    return outside + inside


def sd_spheroid(p, centre, a, c, iterations=60):
    """Exact signed distance to the spheroid x^2/a^2 + y^2/a^2 + z^2/c^2 = 1.

    Reduced to the ellipse (rho, z) with semi-axes (a, c); the closest point is
    q_i = e_i^2 u_i / (e_i^2 + t) with t the root of sum e_i^2 u_i^2 / (e_i^2 + t)^2 = 1
    in (-min e^2, inf) (monotone there), found by bisection for all points at once.
    """
    d = p - np.asarray(centre, float)
    rho = np.hypot(d[..., 0], d[..., 1])
    z = np.abs(d[..., 2])
    e2 = np.array([a * a, c * c])
    u = np.stack([rho, z], axis=-1)
    lo = np.full(rho.shape, -e2.min() * (1 - 1e-12))
    hi = np.full(rho.shape, np.max(np.abs(u), axis=-1) * max(a, c) + e2.max())
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        f = np.sum(e2 * u * u / (e2 + mid[..., None]) ** 2, axis=-1) - 1.0
        lo = np.where(f > 0, mid, lo)
        hi = np.where(f > 0, hi, mid)
    t = 0.5 * (lo + hi)
    q = e2 * u / (e2 + t[..., None])
    # guard the medial set (u along the minor axis): project radially onto the ellipse
    scale = 1.0 / np.sqrt(np.maximum(np.sum(q * q / e2, axis=-1), 1e-300))
    q = q * scale[..., None]
    dist = np.linalg.norm(u - q, axis=-1)
    inside = np.sum(u * u / e2, axis=-1) < 1.0
    return np.where(inside, -dist, dist)


def rotation(axis, angle):
    """Rotation matrix (Rodrigues) about unit ``axis`` by ``angle`` radians."""
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


# -- cases ---------------------------------------------------------------------
# U-shaped solid: a base bar and two arms (the arms overlap the base for the
# min-union; the centroid uses the non-overlapping split).
_U_BASE = ((0.0, -0.2, 0.0), (0.38, 0.1, 0.14))
_U_ARMS = [((-0.28, 0.12, 0.0), (0.1, 0.28, 0.14)), ((0.28, 0.12, 0.0), (0.1, 0.28, 0.14))]


def _sd_u(p):
    d = sd_box(p, *_U_BASE)
    for c, hh in _U_ARMS:
        d = np.minimum(d, sd_box(p, c, hh))
    return d


def _u_centroid():
    parts = [(np.array(_U_BASE[0]), np.array(_U_BASE[1]))]
    for c, hh in _U_ARMS:  # the arm above the base only (y from -0.1 to 0.4)
        c = np.array(c)
        hh = np.array(hh)
        lo_y = _U_BASE[0][1] + _U_BASE[1][1]
        top = c[1] + hh[1]
        parts.append((np.array([c[0], 0.5 * (lo_y + top), c[2]]),
                      np.array([hh[0], 0.5 * (top - lo_y), hh[2]])))
    vols = np.array([np.prod(2 * hh) for _, hh in parts])
    cents = np.array([c for c, _ in parts])
    return (vols[:, None] * cents).sum(0) / vols.sum()


RIGID_AXIS = (1.0, 2.0, 0.5)
RIGID_ANGLE = np.pi / 2
RIGID_SHIFT = np.array([0.15, -0.1, 0.2])


def _rigid(grid):
    x = grid.points()
    c = _u_centroid()
    R = rotation(RIGID_AXIS, RIGID_ANGLE)

    def truth(p, s):
        Rs = rotation(RIGID_AXIS, s * RIGID_ANGLE)
        q = (np.asarray(p, float) - c - s * RIGID_SHIFT) @ Rs + c  # Rs^T (p - c - s t) + c
        return _sd_u(q)

    fa = np.array([[-0.3, 0.3, 0.0], [0.3, 0.3, 0.0], [-0.3, -0.2, 0.0], [0.3, -0.2, 0.0],
                   [0.0, -0.2, 0.07], [0.0, -0.2, -0.07], [-0.28, 0.05, 0.07], [0.28, 0.05, -0.07]])
    fb = (fa - c) @ R.T + c + RIGID_SHIFT
    return Case("rigid", grid, [truth(x, 0.0), truth(x, 1.0)], [(fa, fb)], truth, [1, 1])


def _merge(grid):
    x = grid.points()
    r = 0.3
    R = r * 2 ** (1 / 3)  # one sphere of the same volume as the two
    ca, cb = np.array([-0.42, 0, 0]), np.array([0.42, 0, 0])
    phi_a = np.minimum(sd_sphere(x, ca, r), sd_sphere(x, cb, r))
    phi_b = sd_sphere(x, (0, 0, 0), R)
    off = 0.5 * r * np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]])
    # each ball fills one half of the merged ball: its centre goes to the half-ball centroid
    half = 3 * R / 8
    fa = np.vstack([ca + off, cb + off])
    fb = np.vstack([np.array([-half, 0, 0]) + off, np.array([half, 0, 0]) + off])
    gap = float(np.linalg.norm(cb - ca) - 2 * r)
    return Case("merge", grid, [phi_a, phi_b], [(fa, fb)], None, [2, 1], {"gap": gap})


def _split(grid):
    """The merge played backwards: one ball tears into two (the thesis's future work)."""
    merge = _merge(grid)
    fa, fb = merge.features[0]
    return Case("split", grid, merge.fields[::-1], [(fb, fa)], None, [1, 2], merge.info)


#: The unequal merge's radii and gap: the gap is a fixed world distance, 3 cells at 40^3.
UNEQUAL_RADII = (0.13, 0.18)
UNEQUAL_GAP = 3 * 2.0 / 39


def _cap_volume(R, height):
    """Volume of a cap of ``height`` cut from a ball of radius ``R``."""
    return np.pi * height ** 2 * (3 * R - height) / 3


def _unequal_merge(grid):
    """Two balls of radii 0.13 and 0.18, 3 h (at 40^3) apart, merge into one ball of their
    volume centred at their centroid. Each ball fills the cap of the merged ball of its own
    volume, cut by a plane across x: its centre goes to its cap's centroid."""
    from scipy.optimize import brentq

    x = grid.points()
    ra, rb = UNEQUAL_RADII
    va, vb = 4 / 3 * np.pi * ra ** 3, 4 / 3 * np.pi * rb ** 3
    dist = ra + rb + UNEQUAL_GAP
    ca = np.array([-vb * dist / (va + vb), 0, 0])  # the pair's centroid at the origin
    cb = ca + np.array([dist, 0, 0])
    R = (ra ** 3 + rb ** 3) ** (1 / 3)
    height = brentq(lambda t: _cap_volume(R, t) - va, 0.0, 2 * R)  # small ball's cap, from -R
    # a cap's centroid lies 3 (2R - t)^2 / (4 (3R - t)) from the ball's centre
    share_a = np.array([-3 * (2 * R - height) ** 2 / (4 * (3 * R - height)), 0, 0])
    share_b = -va * share_a / vb
    phi_a = np.minimum(sd_sphere(x, ca, ra), sd_sphere(x, cb, rb))
    phi_b = sd_sphere(x, (0, 0, 0), R)
    unit = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]], dtype=float)
    fa = np.vstack([ca + 0.5 * ra * unit, cb + 0.5 * rb * unit])
    fb = np.vstack([share_a + 0.5 * ra * unit, share_b + 0.5 * rb * unit])
    return Case("unequal-merge", grid, [phi_a, phi_b], [(fa, fb)], None, [2, 1],
                {"gap": UNEQUAL_GAP})


def _unequal_split(grid):
    """The unequal merge played backwards."""
    merge = _unequal_merge(grid)
    fa, fb = merge.features[0]
    return Case("unequal-split", grid, merge.fields[::-1], [(fb, fa)], None, [1, 2], merge.info)


# star: a ball with six thin arms along the axes, into a ball of equal volume
_STAR_CORE = 0.22
_STAR_ARM = (0.62, 0.08)  # arm reach from the centre and radius


def _sd_star(p):
    d = sd_sphere(p, (0, 0, 0), _STAR_CORE)
    for a in range(3):
        for sign in (-1.0, 1.0):
            tip = np.zeros(3)
            tip[a] = sign * _STAR_ARM[0]
            d = np.minimum(d, sd_capsule(p, (0, 0, 0), tip, _STAR_ARM[1]))
    return d


def _star_volume():
    """Volume of the star by midpoint sampling of its bounding cube (200^3 samples)."""
    m = 200
    r = _STAR_ARM[0] + _STAR_ARM[1]
    t = (np.arange(m) + 0.5) / m * 2 * r - r
    inside = 0
    for z in t:  # slabs keep memory small
        p = np.stack(np.meshgrid(t, t, [z], indexing="ij"), axis=-1)
        inside += int(np.count_nonzero(_sd_star(p) < 0))
    return inside * (2 * r / m) ** 3


def _morph(grid):
    """A star with six thin arms becomes a ball of the same volume (arms drawn in)."""
    x = grid.points()
    R = (3 * _star_volume() / (4 * np.pi)) ** (1 / 3)
    fa = 0.1 * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    return Case("morph", grid, [_sd_star(x), sd_sphere(x, (0, 0, 0), R)], [(fa, fa.copy())], None,
                [1, 1])


def _bend(grid):
    x = grid.points()
    L, r = 0.6, 0.12
    phi_a = sd_capsule(x, (-L, 0, 0), (L, 0, 0), r)
    phi_b = np.minimum(sd_capsule(x, (-L, 0, 0), (0, 0, 0), r),
                       sd_capsule(x, (0, 0, 0), (0, L, 0), r))
    fa = np.array([[-0.55, 0, 0], [-0.3, 0, 0.05], [-0.3, 0.05, 0], [-0.1, 0, 0],
                   [0.1, 0, 0], [0.3, 0, 0.05], [0.3, 0.05, 0], [0.55, 0, 0]])
    Rz = rotation((0, 0, 1), np.pi / 2)
    right = fa[:, 0] > 0
    fb = fa.copy()
    fb[right] = fa[right] @ Rz.T  # the right half turns 90 deg about the joint (origin)
    return Case("bend", grid, [phi_a, phi_b], [(fa, fb)], None, [1, 1])


def _squash(grid):
    x = grid.points()
    r = 0.45
    c = 0.6 * r
    a = r / np.sqrt(0.6)  # a^2 c = r^3: equal volume
    phi_a = sd_sphere(x, (0, 0, 0), r)
    phi_b = sd_spheroid(x, (0, 0, 0), a, c)
    fa = 0.5 * r * np.array([[0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                            dtype=float)
    fb = fa * np.array([a / r, a / r, c / r])
    return Case("squash", grid, [phi_a, phi_b], [(fa, fb)], None, [1, 1])


def _splash(grid):
    """Droplet above a pool -> touching -> merged bump -> flat pool (4 keyframes).

    The bump is a spherical cap of the droplet's volume on the pool; the last
    pool is raised by droplet volume / pool area, so total volume is constant
    (up to the grid's resolution of the keyframes themselves).
    """
    x = grid.points()
    rd = 0.18
    vd = 4 / 3 * np.pi * rd ** 3
    half = np.array([0.7, 0.7, 0.2])
    pool_c = np.array([0.0, 0.0, -0.6])
    top = pool_c[2] + half[2]  # -0.4

    def pool(raise_by=0.0):
        c = pool_c + np.array([0, 0, raise_by / 2])
        return sd_box(x, c, half + np.array([0, 0, raise_by / 2]))

    k0 = np.minimum(pool(), sd_sphere(x, (0, 0, top + 0.45), rd))
    k1 = np.minimum(pool(), sd_sphere(x, (0, 0, top + rd - 0.02), rd))
    # cap of height hc on a sphere of radius Rc with volume vd: pi hc^2 (3 Rc - hc) / 3
    hc = 0.16
    Rc = (3 * vd / (np.pi * hc ** 2) + hc) / 3
    cap = np.maximum(sd_sphere(x, (0, 0, top + hc - Rc), Rc), -(x[..., 2] - top))
    k2 = np.minimum(pool(), cap)
    k3 = pool(vd / (4 * half[0] * half[1]))
    corners = np.array([[-0.5, -0.5, -0.6], [0.5, -0.5, -0.6], [0.5, 0.5, -0.6], [-0.5, 0.5, -0.6]])
    drop = lambda z: np.array([[0, 0, z], [0.09, 0, z], [0, 0.09, z], [0, 0, z + 0.09]])  # noqa: E731
    capz = top + 0.05
    lay = top + 0.5 * vd / (4 * half[0] * half[1])
    segs = [
        (np.vstack([corners, drop(top + 0.45)]), np.vstack([corners, drop(top + rd - 0.02)])),
        (np.vstack([corners, drop(top + rd - 0.02)]),
         np.vstack([corners, np.array([[0, 0, capz], [0.2, 0, capz - 0.02], [0, 0.2, capz - 0.02],
                                       [0, 0, capz + 0.07]])])),
        # the layer is thinner than a cell, so the bump's top gets no point of its own: two
        # targets 0.005 apart with sources 0.07 apart would ask one cell to stretch 14x
        (np.vstack([corners, np.array([[0, 0, capz], [0.2, 0, capz - 0.02], [0, 0.2, capz - 0.02]])]),
         np.vstack([corners, np.array([[0, 0, lay], [0.35, 0, lay], [0, 0.35, lay]])])),
    ]
    return Case("splash", grid, [k0, k1, k2, k3], segs, None, [2, 1, 1, 1])


def _read_ply_triangles(path):
    """Vertices (N, 3) and triangles (F, 3) of a binary little-endian PLY whose vertices
    have x, y, z floats first and whose faces are all triangles (uchar count, int indices)."""
    raw = pathlib.Path(path).read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    header = raw[:end].decode("ascii").splitlines()
    counts = {ln.split()[1]: int(ln.split()[2]) for ln in header if ln.startswith("element")}
    props = [ln.split()[-1] for ln in header if ln.startswith("property float")]
    vertex = np.dtype([(name, "<f4") for name in props])
    vert = np.frombuffer(raw, vertex, counts["vertex"], end)
    face = np.frombuffer(raw, np.dtype([("n", "u1"), ("i", "<i4", 3)]), counts["face"],
                         end + vertex.itemsize * counts["vertex"])
    if not np.all(face["n"] == 3):
        raise ValueError(f"{path}: only triangle faces are read.")
    return np.stack([vert["x"], vert["y"], vert["z"]], axis=-1).astype(float), face["i"]


def scan_mesh():
    """The Stanford bunny as scanned (50 000 vertices, open where the scanner saw nothing)
    that the pymeshfix package ships, scaled to 1.1 across and centred in the box."""
    spec = importlib.util.find_spec("pymeshfix")  # the file only: the package is not imported
    if spec is None:
        raise ImportError("the scan case reads the Stanford bunny scan the pymeshfix package "
                          "ships: pip install pymeshfix")
    v, f = _read_ply_triangles(pathlib.Path(spec.origin).parent / "examples" / "StanfordBunny.ply")
    lo, hi = v.min(axis=0), v.max(axis=0)
    return (v - 0.5 * (lo + hi)) * (1.1 / np.max(hi - lo)), f


#: The npm package ``bunny`` (public domain): its tarball and the SHA-1 the registry lists.
BUNNY_URL = "https://registry.npmjs.org/bunny/-/bunny-1.0.1.tgz"
BUNNY_SHA1 = "86383da45ab7a99571a5a572b7be0e3564815f9e"


def _cache_dir():
    """Where downloaded benchmark inputs are kept: the user's cache (``XDG_CACHE_HOME`` or
    ~/.cache), never the repository or the add-on's folder."""
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return pathlib.Path(root) / "keyframe_implicit" / "benchmarks"


def _bunny_tarball():
    """The npm ``bunny`` tarball's bytes: from the cache, else downloaded and checked
    against `BUNNY_SHA1` first. ImportError (the benchmark's "not available") saying how
    to provide it when it cannot be fetched."""
    path = _cache_dir() / pathlib.PurePosixPath(BUNNY_URL).name
    if path.is_file() and hashlib.sha1(path.read_bytes()).hexdigest() == BUNNY_SHA1:
        return path.read_bytes()
    try:
        with urllib.request.urlopen(BUNNY_URL, timeout=60) as response:
            data = response.read()
    except OSError as exc:
        raise ImportError(f"the bunny case reads the npm package bunny, which could not be "
                          f"fetched from {BUNNY_URL} ({exc}); download it there by hand and "
                          f"put it at {path}") from None
    if hashlib.sha1(data).hexdigest() != BUNNY_SHA1:
        raise ImportError(f"{BUNNY_URL} did not give the bunny-1.0.1 tarball (SHA-1 "
                          f"{BUNNY_SHA1} expected); put that file at {path}")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".part")
    tmp.write_bytes(data)
    tmp.replace(path)
    return data


def bunny_mesh():
    """The closed Stanford bunny of the npm package ``bunny`` (1839 vertices, 3674
    triangles), scaled to 1.1 across and centred in the box."""
    with tarfile.open(fileobj=io.BytesIO(_bunny_tarball()), mode="r:gz") as tar:
        text = tar.extractfile("package/index.js").read().decode("ascii")
    arrays = {name: json.loads(re.search(rf"exports\.{name}\s*=\s*(\[.*?\]\])", text, re.S)[1])
              for name in ("positions", "cells")}
    v, f = np.array(arrays["positions"], dtype=float), np.array(arrays["cells"], dtype=np.int64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    return (v - 0.5 * (lo + hi)) * (1.1 / np.max(hi - lo)), f


def _into_ball(name, mesh, grid):
    """A mesh (vertices, triangles) becomes a ball of its volume centred at its centroid;
    four feature points there stay put."""
    from keyframe_implicit.core import mesh_to_sdf
    from keyframe_implicit.core.surface.extract import enclosed_volume

    x = grid.points()
    phi_a = mesh_to_sdf(*mesh, grid)
    inside = phi_a < 0
    centre = x[inside].mean(axis=0)
    R = (3 * enclosed_volume(phi_a, grid) / (4 * np.pi)) ** (1 / 3)
    fa = centre + 0.1 * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    return Case(name, grid, [phi_a, sd_sphere(x, centre, R)], [(fa, fa.copy())], None, [1, 1],
                {"meshes": [mesh, None]})


def _squashed(name, mesh, grid, height=0.6):
    """A mesh squashed to ``height`` of itself along z and widened to keep its volume,
    about its centroid (the npm bunny sits with its ears up: they flatten); feature points
    on the centroid and the three axes follow the squash. ``info["meshes"]`` holds both
    keyframe meshes, exact."""
    from keyframe_implicit.core import mesh_to_sdf

    vertices, triangles = mesh
    phi_a = mesh_to_sdf(vertices, triangles, grid)
    centre = grid.points()[phi_a < 0].mean(axis=0)
    scale = np.array([1 / np.sqrt(height), 1 / np.sqrt(height), height])
    squashed = centre + (vertices - centre) * scale
    fa = centre + 0.1 * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    fb = centre + (fa - centre) * scale
    return Case(name, grid, [phi_a, mesh_to_sdf(squashed, triangles, grid)], [(fa, fb)], None,
                [1, 1], {"meshes": [(vertices, triangles), (squashed, triangles)]})


def _scan(grid):
    """The pymeshfix bunny scan becomes a ball of its volume."""
    return _into_ball("scan", scan_mesh(), grid)


def _bunny(grid):
    """The npm package's bunny becomes a ball of its volume."""
    return _into_ball("bunny", bunny_mesh(), grid)


def _bunny_squash(grid):
    """The npm package's bunny squashed to 0.6 of its height at equal volume."""
    return _squashed("bunny-squash", bunny_mesh(), grid)


_BUILDERS = {"rigid": _rigid, "merge": _merge, "split": _split, "bend": _bend, "squash": _squash,
             "morph": _morph, "splash": _splash, "unequal-merge": _unequal_merge,
             "unequal-split": _unequal_split, "scan": _scan, "bunny": _bunny,
             "bunny-squash": _bunny_squash}


def make_case(name: str, n: int) -> Case:
    """Build case ``name`` (one of `ALL_CASES`) on the ``n``^3 benchmark grid."""
    if name not in _BUILDERS:
        raise ValueError(f"unknown case {name!r}; choose one of {', '.join(ALL_CASES)}.")
    return _BUILDERS[name](make_grid(n))
