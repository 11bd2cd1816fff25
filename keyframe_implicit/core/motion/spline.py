"""Paths that flow through keyframes: a segment's paths bent so the velocity is continuous
at its keyframes (docs/method.md, section 12).

Each segment's as-rigid-as-possible paths x(s) (`trajectory`) run from one keyframe to the
next on their own, so a material point's velocity jumps where two segments meet. Here
every path gets a cubic Hermite correction, its `Bend`,

    x(s) = x_arap(s) + h10(s) a0 + h11(s) a1,
    h10(s) = s (1 - s)^2,   h11(s) = -s^2 (1 - s),

zero at both keyframes (so they, and the feature points, stay exact), whose slopes there
are a0 and a1 (per unit s of the segment): a0 = dx/ds wanted at s = 0 minus the
as-rigid-as-possible path's own slope there, and a1 the same at s = 1. The correction
only changes the paths' timing and shape between keyframes; the Poisson solve per frame,
its rotations and the keyframes' volumes are section 5's.

The slope wanted at keyframe k, for every material point of k, comes from the two
segments that meet there, as velocities per frame: ``arrive`` at the end of segment k - 1
(minus the start velocity of its backward paths, which sit on k's nodes) and ``leave`` at
the start of segment k (its forward paths'). Per keyframe, by its `KEY_INTERPOLATIONS`:

- "smooth": the two velocities weighted by their own segment's length,
  v = (n_{k-1} arrive + n_k leave) / (n_{k-1} + n_k) with n the segments' frames: for
  straight paths the point's displacement from keyframe k - 1 to k + 1 over their
  frames (Catmull-Rom with the keyframes' own times). A point four frames from one
  keyframe and twenty from the next passes at its mean speed over the two segments and
  overshoots neither (the parabola's tangent, weighted the other way, throws it forward
  out of the box: benchmarks/README.md, "Tangents for uneven gaps"). Of that mean only
  its divergence-free part is kept (`incompressible`): material does not squeeze or
  swell as it passes a keyframe. The backward paths that give ``arrive`` spread keyframe
  k's material wherever their map tears (a merge seen backwards; in the splash's bump,
  19 % of its volume a frame), and the mean would hand that squeeze to segment k's
  paths; the iso-value that holds the volume (`isovolume`) would then move the whole
  surface back, a jump in every surface point's speed at the keyframe. At the first and
  last keyframe, a natural end: the correction's second derivative vanishes there;
- "linear": each segment keeps its own slope (a corner);
- "ease": velocity zero, the motion comes to rest on the keyframe.

Built from the as-rigid-as-possible velocities themselves, not from chords between
keyframe positions: where a part turns at one rate through a keyframe the two velocities
agree and its correction is zero, so a rigid part keeps its rigid path. (A tangent from
the chords between keyframe positions would not: for a body turning by an angle t a
segment about its centre, chord tangents differ from the turning paths' own slopes by
(1 - cos t) times the radius, outward, and the body would swell between keyframes, by
2 % of its size at 30 degrees.) Where the rate of turn changes, the correction is the
difference of two turning velocity fields: itself a turn, so rigid to first order.

A point carried forward from keyframe k and the same point carried backward from k + 1
get the same correction (each reads the other end's at its own position through the
segment's map), so the two transports of a segment stay on the same curves and their
blend has no seam.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..base.sampling import sample

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from numpy.typing import ArrayLike

    from ..base.grid import Grid
    from .trajectory import Trajectories

__all__ = ["Bend", "KEY_INTERPOLATIONS", "check_key_interpolation", "start_velocity",
           "velocities_needed", "chain_bends", "bends_needed", "incompressible"]

#: How the motion passes a keyframe (Blender's F-curve names): continuous velocity, a
#: corner, or coming to rest.
KEY_INTERPOLATIONS = ("smooth", "linear", "ease")

_START_STEP = 1.0 / 64.0  # s of the one-sided difference that gives a path's start velocity


def check_key_interpolation(key_interpolation: str | Sequence[str] | None,
                            nk: int) -> tuple[str, ...]:
    """Per keyframe its interpolation as a tuple of ``nk`` names (None: all "smooth"); a
    single name applies to every keyframe; ValueError saying what to fix."""
    if key_interpolation is None:
        return ("smooth",) * nk
    if isinstance(key_interpolation, str):
        key_interpolation = [key_interpolation] * nk
    out = tuple(str(v).lower() for v in key_interpolation)
    if len(out) != nk:
        raise ValueError(f"key_interpolation must hold one entry per keyframe ({nk}), "
                         f"got {len(out)}.")
    bad = sorted(set(out) - set(KEY_INTERPOLATIONS))
    if bad:
        raise ValueError(f"key_interpolation {bad} unknown: use one of {KEY_INTERPOLATIONS}.")
    return out


def bends_needed(key_interpolation: Sequence[str]) -> bool:
    """Whether any segment's paths bend: an inner keyframe that is not "linear", or an
    "ease" anywhere (two natural ends bend nothing)."""
    inner = key_interpolation[1:-1]
    return any(v != "linear" for v in inner) or "ease" in key_interpolation


class Bend:
    """A Hermite correction h(s) = h10(s) a0 + h11(s) a1 of paths on a grid's nodes: zero
    at s = 0 and 1, slope a0 at 0 and a1 at 1 (per unit s).

    Parameters
    ----------
    start, end : (grid.size, d) arrays
        a0 and a1 of every node, world units per unit s.
    """

    def __init__(self, start: ArrayLike, end: ArrayLike) -> None:
        self.start = np.asarray(start, dtype=float)
        self.end = np.asarray(end, dtype=float)

    def __call__(self, s: float, nodes: np.ndarray) -> np.ndarray:
        """The correction at time s of the nodes with the given flat indices, (len, d)."""
        s = float(s)
        a, b = s * (1.0 - s) ** 2, -s * s * (1.0 - s)
        return a * self.start[nodes] + b * self.end[nodes]

    def reversed(self) -> Bend:
        """The same correction seen from the other end (time t = 1 - s): the slopes swap
        ends and change sign."""
        return Bend(-self.end, -self.start)


def start_velocity(paths: Trajectories) -> np.ndarray:
    """dx/ds at s = 0 of every node of ``paths`` (`trajectory.Trajectories`), (size, d):
    second-order one-sided difference over two steps of `_START_STEP`."""
    nodes = np.arange(paths.grid.size)
    x0 = paths.grid.node_points(nodes)
    x1 = paths.node_positions(_START_STEP, nodes)
    x2 = paths.node_positions(2.0 * _START_STEP, nodes)
    return (4.0 * x1 - 3.0 * x0 - x2) / (2.0 * _START_STEP)


def _sets_velocity(key_interpolation: Sequence[str], k: int) -> bool:
    """Whether keyframe ``k`` sets the velocity there: neither "linear" nor a natural end."""
    kind, last = key_interpolation[k], len(key_interpolation) - 1
    return kind == "ease" or (kind == "smooth" and 0 < k < last)


def velocities_needed(key_interpolation: Sequence[str]) -> list[tuple[int, str]]:
    """The paths whose `start_velocity` `chain_bends` reads: (segment, "forward") for the
    segment leaving a keyframe, (segment, "backward") for the one arriving at it, at
    every keyframe that sets its velocity."""
    nk = len(key_interpolation)
    out = []
    for k in range(nk):
        if not _sets_velocity(key_interpolation, k):
            continue
        if k > 0:
            out.append((k - 1, "backward"))
        if k < nk - 1:
            out.append((k, "forward"))
    return out


def chain_bends(grid: Grid, frames: ArrayLike, key_interpolation: Sequence[str],
                forward: Sequence[np.ndarray], backward: Sequence[np.ndarray],
                velocities: dict[tuple[int, str], np.ndarray]) -> list[tuple[Bend, Bend] | None]:
    """Every segment's (forward, backward) `Bend` on the maps' ``grid``, or None for a
    segment that keeps its paths.

    Parameters
    ----------
    grid : Grid
        The grid the maps and trajectories are solved on.
    frames : (nk,) ints, the keyframes' timeline frames.
    key_interpolation : tuple of `KEY_INTERPOLATIONS`, one per keyframe.
    forward, backward : list of (grid.shape + (d,)) arrays, per segment its maps A -> B
        and B -> A.
    velocities : dict (segment, "forward" or "backward") -> (grid.size, d)
        The `start_velocity` of the paths `velocities_needed` lists.

    Returns
    -------
    list of (Bend, Bend) or None, per segment: the forward paths' on A's nodes, and the
    backward paths' on B's nodes, in their own time.
    """
    frames = np.asarray(frames, dtype=float)
    gaps = np.diff(frames)
    nk = len(frames)
    d = grid.dim
    # per keyframe, velocities per frame of its own material at its nodes
    leaving = {k: velocities[k, "forward"] / gaps[k] for k in range(nk - 1)
               if (k, "forward") in velocities}
    arriving = {k + 1: -velocities[k, "backward"] / gaps[k] for k in range(nk - 1)
                if (k, "backward") in velocities}
    # per keyframe: the slope change (per frame) wanted of the segment leaving it and of
    # the one arriving at it; None where that segment keeps its slope (or ends naturally)
    depart, reach = [None] * nk, [None] * nk
    for k, kind in enumerate(key_interpolation):
        if not _sets_velocity(key_interpolation, k):
            continue
        if kind == "ease":
            wanted = np.zeros((grid.size, d))
        else:  # each side weighted by its own segment's frames
            wanted = incompressible((gaps[k - 1] * arriving[k] + gaps[k] * leaving[k])
                                    / (gaps[k - 1] + gaps[k]), grid)
        if k in leaving:
            depart[k] = wanted - leaving[k]
        if k in arriving:
            reach[k] = wanted - arriving[k]
    out: list[tuple[Bend, Bend] | None] = []

    for k in range(nk - 1):
        fw, bw = _read_at(forward[k], grid), _read_at(backward[k], grid)
        a0 = None if depart[k] is None else (depart[k] * gaps[k], bw(depart[k] * gaps[k]))
        a1 = None if reach[k + 1] is None else (fw(reach[k + 1] * gaps[k]),
                                                reach[k + 1] * gaps[k])
        if a0 is None and a1 is None:
            out.append(None)
            continue
        natural = (key_interpolation[k] == "smooth" and k == 0,
                   key_interpolation[k + 1] == "smooth" and k + 1 == nk - 1)
        a0, a1 = _ends(a0, a1, natural)
        out.append((Bend(a0[0], a1[0]), Bend(a0[1], a1[1]).reversed()))
    return out


def incompressible(velocity: ArrayLike, grid: Grid) -> np.ndarray:
    """The divergence-free part of a node velocity field (size, d) on ``grid``: v - grad p
    with lap p = div v inside the grid's box and p = 0 on its faces (Helmholtz projection).

    With p = 0 on the faces nothing is asked of the flow through them, so a uniform or
    turning field (divergence zero) is kept as it is, and a rigid part's velocity with it.
    Central differences for div and grad; the compact Laplacian is solved exactly by a
    sine transform over the inner nodes, so the divergence left is that of the two
    stencils' difference (5 % of a smooth squeeze's)."""
    from scipy.fft import dstn, idstn

    d, h = grid.dim, grid.spacing
    v = np.asarray(velocity, dtype=float).reshape(grid.shape + (d,))
    div = sum(np.gradient(v[..., a], h, axis=a) for a in range(d))
    inner = (slice(1, -1),) * d
    eigen = 0.0
    for a, n in enumerate(grid.shape):
        shape = [1] * d
        shape[a] = n - 2
        theta = np.pi * np.arange(1, n - 1) / (n - 1)
        eigen = eigen + ((2.0 * np.cos(theta) - 2.0) / (h * h)).reshape(shape)
    p = np.zeros(grid.shape)
    p[inner] = idstn(dstn(div[inner], type=1) / eigen, type=1)
    grad = np.stack(np.gradient(p, h), axis=-1)
    return (v - grad).reshape(-1, d)


def _ends(a0, a1, natural):
    """The slopes (on A's nodes, on B's nodes) at both ends of a segment: a missing end is
    zero, or, at a natural end, minus half the other (h'' = 0 there)."""
    def fill(mine, other, free):
        if mine is not None:
            return mine
        if free and other is not None:
            return tuple(-0.5 * o for o in other)
        return tuple(np.zeros_like(o) for o in other)
    return fill(a0, a1, natural[0]), fill(a1, a0, natural[1])


def _read_at(mapped: ArrayLike, grid: Grid) -> Callable[[np.ndarray], np.ndarray]:
    """A node field of the other end read where each node's map takes it: (size, d) ->
    (size, d), multilinear."""
    points = np.asarray(mapped, dtype=float).reshape(-1, grid.dim)

    def read(field: np.ndarray) -> np.ndarray:

        return sample(field.reshape(grid.shape + (grid.dim,)), grid, points)
    return read
