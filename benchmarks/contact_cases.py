"""Contact benchmark cases: parts that meet, part, open a hole, or pass close by.

Each case is a `cases.Case` on the benchmark box [-1, 1]^3, its keyframes analytic signed
distances. `bench_contact.py` turns them into meshes and bakes them through
`keyframe_implicit.core.animate`, as an artist's scene would be. Three are new here:

- ``drop``: a ball (radius 0.18) 0.27 above a square pool (a box 1.4 x 1.4 x 0.4) falls
  and ends as a half-ellipsoid bump of its volume on the pool (semi-axes 0.27, 0.27,
  0.16). Feature points near the pool's four corners (still), on the ball's centre and
  near its top (to the bump's centroid and near its top).
- ``torus``: a ball whose middle opens into a torus of its volume (major radius 0.3,
  tube 0.12); six feature points on a ring of radius 0.16 go to the tube's centre line.
- ``scissors``: two plates along x (1.2 x 0.24), each 6 h thick with a gap of 1.5 h
  between them, turn -90 and +90 degrees about the z axis. h is the cell of a bake at
  resolution 48, whose box is 1.22 wide (the plates' sweep): the plates are fixed in
  world units (`SCISSORS_H` = 0.0254), so at 64 they are 7.9 h thick, 2 h apart.

The others are `cases.py`'s: the splash (its four keyframes), the merge, the unequal
merge, the split and the unequal split. ``event`` says which topology change each is
about: "merge" (parts meet), "split" (a part parts), "hole" (a hole opens), None.
"""

from __future__ import annotations

import numpy as np

import cases
from cases import Case, make_grid, rotation, sd_box, sd_spheroid
from keyframe_implicit.shapes import sphere_sdf as sd_sphere

__all__ = ["CONTACT_CASES", "EVENTS", "SCISSORS_H", "make_contact_case", "scissors_case"]

#: The contact table's cases, in its order.
CONTACT_CASES = ("drop", "splash", "merge", "unequal-merge", "split", "unequal-split", "torus",
                 "scissors")
#: The topology change each case is about.
EVENTS = {"drop": "merge", "splash": "merge", "merge": "merge", "unequal-merge": "merge",
          "split": "split", "unequal-split": "split", "torus": "hole", "scissors": None}
#: The scissors' cell: that of a bake at resolution 48 (the plates sweep a box 1.22 wide).
SCISSORS_H = 0.0254

POOL_CENTRE, POOL_HALF = np.array([0.0, 0.0, -0.6]), np.array([0.7, 0.7, 0.2])
POOL_TOP = POOL_CENTRE[2] + POOL_HALF[2]
DROP_RADIUS, DROP_HEIGHT = 0.18, 0.45  # the ball's radius; its centre's height over the pool
BUMP_AXES = (0.27, 0.16)  # a^2 c = 2 r^3: half the spheroid holds the ball's volume
POOL_CORNERS = np.array([[-0.5, -0.5, -0.6], [0.5, -0.5, -0.6], [0.5, 0.5, -0.6],
                         [-0.5, 0.5, -0.6]])


def _drop(grid):
    """Ball above a pool -> a bump of its volume on the pool (two keyframes)."""
    x = grid.points()
    pool = sd_box(x, POOL_CENTRE, POOL_HALF)
    centre = np.array([0.0, 0.0, POOL_TOP + DROP_HEIGHT])
    a, c = BUMP_AXES
    phi_a = np.minimum(pool, sd_sphere(x, centre, DROP_RADIUS))
    phi_b = np.minimum(pool, sd_spheroid(x, (0.0, 0.0, POOL_TOP), a, c))
    fa = np.vstack([POOL_CORNERS, centre, centre + [0, 0, 0.8 * DROP_RADIUS]])
    fb = np.vstack([POOL_CORNERS, [0, 0, POOL_TOP + 3 * c / 8], [0, 0, POOL_TOP + 0.8 * c]])
    return Case("drop", grid, [phi_a, phi_b], [(fa, fb)], None, [2, 1],
                {"radius": DROP_RADIUS})


TORUS_RADII = (0.3, 0.12)  # major, tube


def _sd_torus(p, major, tube):
    """Signed distance to the torus about the z axis."""
    return np.hypot(np.hypot(p[..., 0], p[..., 1]) - major, p[..., 2]) - tube


def _torus(grid):
    """A ball opens a hole through its middle and becomes a torus of its volume."""
    x = grid.points()
    major, tube = TORUS_RADII
    ball = (3 * 2 * np.pi ** 2 * major * tube ** 2 / (4 * np.pi)) ** (1 / 3)
    angle = np.arange(6) * np.pi / 3
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(6)], axis=1)
    return Case("torus", grid, [sd_sphere(x, (0, 0, 0), ball), _sd_torus(x, major, tube)],
                [(0.16 * ring, major * ring)], None, [1, 1], {"radius": ball})


SCISSORS_PLATE = (0.6, 0.12)  # half length (x), half width (y)


def scissors_plates(h: float = SCISSORS_H) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre, half extents) of the two plates: 6 ``h`` thick, 1.5 ``h`` apart along z."""
    half_z, gap = 3 * h, 1.5 * h
    length, width = SCISSORS_PLATE
    return [(np.array([0, 0, sign * (gap / 2 + half_z)]), np.array([length, width, half_z]))
            for sign in (1.0, -1.0)]


def _scissors(grid, h=SCISSORS_H):
    """Two close plates turn opposite ways (-90 and +90 degrees about z), like scissors:
    6 ``h`` thick, 1.5 ``h`` apart."""
    x = grid.points()
    plates = scissors_plates(h)
    fields = [np.minimum(*[sd_box(x, c, half) for c, half in plates]),
              np.minimum(*[sd_box(x, c, half[[1, 0, 2]]) for c, half in plates])]
    fa, fb = [], []
    for (c, _), turn in zip(plates, (-np.pi / 2, np.pi / 2)):
        pts = c + np.array([[0.45, 0, 0], [-0.45, 0, 0], [0.2, 0.06, 0], [-0.2, -0.06, 0]])
        fa.append(pts)
        fb.append(pts @ rotation((0, 0, 1), turn).T)
    return Case("scissors", grid, fields, [(np.vstack(fa), np.vstack(fb))], None, [2, 2],
                {"turns": (-90.0, 90.0), "h48": h})


def scissors_case(n: int, h: float = SCISSORS_H) -> Case:
    """The scissors on the ``n``^3 benchmark grid, their plates 6 ``h`` thick and 1.5 ``h``
    apart (a bake's cell at resolution r is about 1.22 / r: 1.5 of its cells at
    ``h`` = 1.22 / r)."""
    return _scissors(make_grid(n), h)


_BUILDERS = {"drop": _drop, "torus": _torus, "scissors": _scissors}


def make_contact_case(name: str, n: int) -> Case:
    """Case ``name`` (one of `CONTACT_CASES`) on the ``n``^3 benchmark grid."""
    if name not in CONTACT_CASES:
        raise ValueError(f"unknown case {name!r}; choose one of {', '.join(CONTACT_CASES)}.")
    if name in _BUILDERS:
        return _BUILDERS[name](make_grid(n))
    return cases.make_case(name, n)
