"""Cleanliness of baked frames (core/surface/quality.py) and of what animate picks for the examples."""

import numpy as np
import pytest

from inbetween_cases import sphere_field
from keyframe_implicit import examples
from keyframe_implicit.core import Grid, animate, extract_surface
from keyframe_implicit.core.surface.quality import (LIMITS, failures, frame_quality, keyframe_distance,
                                            worst_frame)


@pytest.fixture(scope="module")
def ball():
    grid = Grid(origin=(-1.5,) * 3, spacing=0.1, shape=(31,) * 3)
    phi = sphere_field(grid, (0, 0, 0), 1.0)
    return grid, phi, extract_surface(phi, grid)


def test_the_true_surface_is_clean(ball):
    grid, phi, (V, F) = ball
    q = frame_quality(phi, grid, V, F)
    assert q == pytest.approx({"area_ratio": 1.0, "inverted_fraction": 0.0, "coverage": 1.0})
    assert failures(q) == []


def test_a_buried_inverted_sheet_and_a_missing_half_are_seen(ball):
    grid, phi, (V, F) = ball
    # a second, inward-facing sheet 2 cells inside: 1 + 0.8^2 times the area, 0.64 of it turned
    inner = np.concatenate([V, 0.8 * V]), np.concatenate([F, F[:, ::-1] + len(V)])
    q = frame_quality(phi, grid, *inner)
    assert q["area_ratio"] == pytest.approx(1.64, abs=0.02)
    assert q["inverted_fraction"] == pytest.approx(0.64 / 1.64, abs=0.01)
    assert q["coverage"] == pytest.approx(1.0)
    # the upper half only: half the area, half the true surface reached
    keep = V[F].mean(axis=1)[:, 2] > 0
    q = frame_quality(phi, grid, V, F[keep])
    assert q["area_ratio"] == pytest.approx(0.5, abs=0.03)
    assert q["coverage"] == pytest.approx(0.5, abs=0.05)
    names = " ".join(failures(q))
    assert "surface area" in names and "covered" in names and "inward" not in names


def test_keyframe_distance_of_a_shifted_mesh_is_the_shift(ball):
    grid, phi, (V, F) = ball
    d = keyframe_distance(V * 1.03, F, V, F, grid.spacing)  # 0.03 units out = 0.3 h
    assert d["keyframe_mean"] == pytest.approx(0.3, abs=0.03)
    assert d["keyframe_max"] == pytest.approx(0.3, abs=0.05)


def test_worst_frame_is_the_one_farthest_past_a_limit():
    ok = {"area_ratio": 1.0, "inverted_fraction": 0.0, "coverage": 1.0}
    bad = dict(ok, coverage=0.95)
    worse = dict(ok, inverted_fraction=0.05)
    frame, q, fails = worst_frame([3, 4, 5], [ok, bad, worse])
    assert frame == 5 and fails == ["5.0 % of the surface facing inward"]
    assert worst_frame([3, 4], [ok, ok])[2] == []
    near = dict(ok, area_ratio=1.02)  # within the limits, but the nearest to them
    assert worst_frame([3, 4, 5], [ok, near, dict(ok, coverage=0.995)])[:3:2] == (4, [])


@pytest.mark.parametrize("name", ["merge", "splash"])
def test_auto_output_of_the_examples_meets_every_limit(name):
    """Every frame of what the artist gets passes the limits, keyframe frames included."""
    ex = examples.example(name)
    an = animate(ex.keyframes, ex.features, resolution=20)
    out = an.stats["output"]
    assert out == "mesh_sequence", an.stats["output_reason"]  # both change topology
    per_frame = an.stats["quality"][out]
    assert len(per_frame) == len(an.frames) == len(an.surfaces) == len(an.velocities)
    for f, q in zip(an.frames, per_frame):
        assert failures(q) == [], (f, q)
    for kf in ex.keyframes:
        assert "keyframe_max" in per_frame[kf.frame - an.frames[0]]
    assert LIMITS["keyframe_max"] == 1.0


def test_mesh_distance_is_the_nearest_of_every_triangle_when_all_are_candidates():
    """With every triangle a candidate, `mesh_distance` is the brute-force minimum of the
    exact point-triangle distances (each pair measured on its own)."""
    from keyframe_implicit.core.surface.quality import mesh_distance
    from keyframe_implicit.core.fields.triangles import point_triangle_distance

    rng = np.random.default_rng(4)
    v = rng.standard_normal((30, 3))
    f = np.array([rng.choice(30, 3, replace=False) for _ in range(40)])
    p = 2.0 * rng.standard_normal((300, 3))
    pairs = np.repeat(p, len(f), axis=0), *(np.tile(v[f[:, i]], (len(p), 1)) for i in range(3))
    want = point_triangle_distance(*pairs).reshape(len(p), len(f)).min(axis=1)
    np.testing.assert_array_equal(mesh_distance(p, v, f, candidates=len(f)), want)
    assert np.all(mesh_distance(p, v, f, candidates=3) >= want)  # fewer: never nearer
