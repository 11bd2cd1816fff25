"""Property-based tests of `mesh_to_sdf` and `animate` on generated meshes, features and frames.

The only allowed outcomes are a correct result or a ValueError that says what to fix. Examples
are derandomized and no database is written, so every run checks the same cases, quickly.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from keyframe_implicit.core import Grid, Keyframe, animate, mesh_to_sdf
from keyframe_implicit.shapes import icosphere

FIXED = settings(derandomize=True, database=None, deadline=None, max_examples=30,
                 suppress_health_check=[HealthCheck.too_slow])
V1, F1 = icosphere(1, radius=1.0)

# messages of numpy/scipy internals, never shown to a user
INTERNAL = ("reshape", "index", "broadcast", "singular", "LinAlg", "dtype", "axis", "extra points")


def _user_message(exc):
    msg = str(exc)
    assert msg and not any(word in msg for word in INTERNAL), msg
    return msg


@st.composite
def closed_meshes(draw):
    """An icosphere, scaled (anisotropically), moved, with some faces reversed and loose vertices."""
    size = draw(st.floats(0.05, 20.0))
    scale = size * np.array(draw(st.tuples(*[st.floats(0.5, 2.0)] * 3)))  # not thinner than a cell
    offset = np.array(draw(st.tuples(*[st.floats(-100.0, 100.0)] * 3)))
    flip = np.array(draw(st.lists(st.booleans(), min_size=len(F1), max_size=len(F1))))
    n_loose = draw(st.integers(0, 3))
    loose = np.array(draw(st.lists(st.tuples(*[st.floats(-1e3, 1e3)] * 3),
                                   min_size=n_loose, max_size=n_loose))).reshape(-1, 3)
    return V1 * scale + offset, flip, loose


@FIXED
@given(closed_meshes())
def test_mesh_to_sdf_field_ignores_orientation_and_loose_vertices(mesh):
    v, flip, loose = mesh
    lo, hi = v.min(axis=0), v.max(axis=0)
    h = float((hi - lo).max()) / 16
    grid = Grid(lo - 3 * h, h, tuple(int(n) for n in np.ceil((hi - lo) / h) + 7))
    clean = mesh_to_sdf(v, F1, grid)
    faces = np.where(flip[:, None], F1[:, ::-1], F1)
    stats = {}
    phi = mesh_to_sdf(np.vstack([v, loose]), faces, grid, stats=stats)
    assert np.abs(phi - clean).max() <= 0.05 * h
    assert stats["reoriented_faces"] == min(flip.sum(), len(flip) - flip.sum()) or flip.all()
    centre = tuple(int(n) // 2 for n in grid.shape)
    assert np.all(np.isfinite(phi)) and (phi < 0).any() and phi[centre] < 0


feature_arrays = st.one_of(
    st.integers(0, 6).map(lambda n: (n, 3)),
    st.sampled_from([(4, 2), (6, 2), (3, 4), (2, 3, 1), (0,)]),
)


@st.composite
def setups(draw):
    """Two spheres on generated frames; feature sets well placed or hostile (shape, spacing, reach)."""
    f0 = draw(st.integers(-50, 50))
    f1 = f0 + draw(st.integers(1, 5))
    shift = np.array(draw(st.tuples(*[st.floats(-3.0, 3.0)] * 3)))
    radius_b = draw(st.floats(0.8, 1.25))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 16)))
    kind = draw(st.sampled_from(["on the surface", "near duplicate", "far away", "wrong shape"]))
    if kind == "wrong shape":
        pa = rng.random(draw(st.sampled_from([(4, 2), (6, 2), (3, 4), (2, 3, 1)])))
        pb = pa
    else:
        d = rng.normal(size=(draw(st.integers(0, 6)), 3))
        d /= np.maximum(np.linalg.norm(d, axis=1), 1e-9)[:, None]
        pa, pb = 0.6 * d, 0.6 * radius_b * d + shift
        if len(pa) and kind == "near duplicate":
            gap = draw(st.sampled_from([1e-3, 1e-2, 0.1]))
            pa = np.vstack([pa, pa[0] + gap])
            pb = np.vstack([pb, pb[0] + rng.normal(size=3) * 0.3])
        elif len(pa) and kind == "far away":
            pb[0] += draw(st.sampled_from([10.0, 1e3]))
    kfs = [Keyframe(V1 * 0.6, F1, f0, "A"), Keyframe(V1 * 0.6 * radius_b + shift, F1, f1, "B")]
    return kfs, [(pa, pb)]


@FIXED
@given(setups())
def test_animate_gives_a_correct_result_or_says_what_to_fix(setup):
    kfs, feats = setup
    try:
        anim = animate(kfs, feats, resolution=10, coverage=False)
    except ValueError as exc:
        _user_message(exc)
        return
    g = anim.grid
    verts = anim.vertices
    assert np.all(np.isfinite(verts)) and np.all(g.contains(verts, margin=-g.spacing))
    assert list(anim.frames) == list(range(kfs[0].frame, kfs[-1].frame + 1))
    for kf, on in ((kfs[0], verts[0]), (kfs[-1], verts[-1])):  # the keyframes' frames on them
        centre = kf.vertices.mean(axis=0)
        radius = np.linalg.norm(kf.vertices - centre, axis=1).mean()
        off = np.abs(np.linalg.norm(on - centre, axis=1) - radius)
        assert np.median(off) <= 0.5 * g.spacing, (kf.frame, np.median(off) / g.spacing)
