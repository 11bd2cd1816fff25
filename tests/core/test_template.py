"""One template mesh tracked through the in-betweens (shape keys)."""

import numpy as np
import pytest

from inbetween_cases import make_grid, rigid_case, rigid_expected, sd_sphere
from keyframe_implicit.core import Inbetween, sample, track_template


@pytest.fixture(scope="module")
def rigid_track():
    grid, phi_a, phi_b, mapped, info = rigid_case(n=36)
    ib = Inbetween.from_map(phi_a, phi_b, grid, mapped)
    times = np.linspace(0.0, 1.0, 24)
    return grid, info, ib, times, track_template(ib, times)


def test_template_keeps_vertices_and_faces_and_sits_on_every_frame(rigid_track):
    grid, info, ib, times, tr = rigid_track
    h = grid.spacing
    n, V, _ = tr.vertices.shape
    assert n == 24 and V == tr.stats["vertices"] > 100
    assert tr.faces.shape == (tr.stats["faces"], 3) and tr.faces.max() < V
    for k, s in enumerate(times):
        phi = sample(ib.levelset(s), grid, tr.vertices[k])
        assert np.abs(phi).max() <= 0.1 * h
        # and on the true turned solid, not just on some zero set
        assert np.abs(rigid_expected(tr.vertices[k], s, info)).max() <= 1.0 * h
    assert max(tr.stats["max_abs_phi"]) <= 0.1 * h
    assert max(tr.stats["uncovered_fraction"]) == 0.0


def test_template_moves_continuously(rigid_track):
    grid, info, ib, times, tr = rigid_track
    jumps = np.linalg.norm(np.diff(tr.vertices, axis=0), axis=2)
    assert jumps.max() <= 2 * grid.spacing
    # a vertex keeps its identity: it follows the rigid motion, it is not re-meshed
    from scipy.spatial.transform import Rotation
    c = info["centroid"]
    R = Rotation.from_rotvec(info["angle"] * np.array([1.0, 2.0, 0.5])
                             / np.linalg.norm([1.0, 2.0, 0.5])).as_matrix()
    rigidly = c + info["t"] + (tr.vertices[0] - c) @ R.T
    assert np.linalg.norm(tr.vertices[-1] - rigidly, axis=1).mean() <= 0.3 * grid.spacing


def test_uncovered_area_reports_parts_the_template_cannot_reach():
    # B has a small ball next to A that nothing of A maps onto (identity map)
    grid = make_grid(3, 32)
    h = grid.spacing
    p = grid.points()
    phi_a = sd_sphere(p, (0.0, 0.0, 0.0), 0.5)
    phi_b = np.minimum(phi_a, sd_sphere(p, (0.5 + 2.5 * h, 0.0, 0.0), 1.6 * h))
    ib = Inbetween.from_map(phi_a, phi_b, grid, p)
    tr = track_template(ib, [0.0, 1.0])
    assert tr.stats["uncovered_area"][0] == 0.0
    assert tr.stats["uncovered_area"][1] > 2 * h * h
    assert 0.0 < tr.stats["uncovered_fraction"][1] < 0.2


def test_bad_times_are_refused(rigid_track):
    grid, info, ib, times, tr = rigid_track
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        track_template(ib, [0.0, 1.2])
    with pytest.raises(ValueError, match="empty"):
        track_template(ib, [])


def test_2d_template_is_closed_loops_on_every_frame():
    from inbetween_cases import bend_case

    grid, phi_a, phi_b, mapped, _ = bend_case(d=2, n=40)
    ib = Inbetween.from_map(phi_a, phi_b, grid, mapped)
    tr = track_template(ib, np.linspace(0.0, 1.0, 7))
    assert tr.faces.shape[1] == 2 and tr.vertices.shape[2] == 2
    # closed: every vertex starts one segment and ends one
    assert np.array_equal(np.sort(tr.faces[:, 0]), np.arange(tr.vertices.shape[1]))
    assert np.array_equal(np.sort(tr.faces[:, 1]), np.arange(tr.vertices.shape[1]))
    assert max(tr.stats["max_abs_phi"]) <= 0.1 * grid.spacing
    # the farthest point (the pole of the right cap, 0.72 from the joint) travels
    # 0.72 * (pi / 2) / 6 per frame on its arc; no vertex moves more than that
    step = np.linalg.norm(np.diff(tr.vertices, axis=0), axis=2).max()
    assert step <= 1.03 * 0.72 * (np.pi / 2) / 6
