"""End to end through `inbetween` (solve_map + trajectories + level sets), no analytic map."""

import numpy as np
import pytest
from scipy import ndimage

from inbetween_cases import bend_case, l_shape, merge_case, rigid_case, rigid_expected
from keyframe_implicit.core import extract_surface, inbetween
from keyframe_implicit.core.surface.extract import loop_area, mesh_volume


def test_rigid_turn_through_the_solver():
    grid, phi_a, phi_b, _, info = rigid_case(n=36)
    h = grid.spacing
    c = info["centroid"]
    fa = np.array([[0.4, -0.25, 0.1], [-0.4, -0.25, -0.1], [0.35, 0.3, 0.1],
                   [0.0, -0.3, 0.15], [0.3, 0.1, -0.15]])
    assert np.all(l_shape(fa) < 0)
    fb = c + info["t"] + (fa - c) @ info["R"].T
    ib = inbetween(phi_a, phi_b, grid, fa, fb)
    assert "map_seconds" in ib.stats and ib.map_result is not None
    vol_a = mesh_volume(*extract_surface(ib.levelset(0.0), grid))
    for s in (0.25, 0.5, 0.75):
        V, F = extract_surface(ib.levelset(s), grid)
        err = np.abs(rigid_expected(V, s, info)) / h
        assert err.mean() <= 0.3 and err.max() <= 1.0
        assert abs(mesh_volume(V, F) / vol_a - 1) <= 0.01
    V1, _ = extract_surface(ib.levelset(1.0), grid)
    assert np.abs(rigid_expected(V1, 1.0, info)).mean() <= 0.25 * h
    # feature points travel with the trajectories and land on their targets
    np.testing.assert_allclose(ib.trajectory(fa, 1.0), fb, atol=1e-6)


def test_2d_merge_through_the_solver():
    grid, phi_a, phi_b, _, info = merge_case(d=2, n=40, gap=0.12, overlap=0.04)
    r = info["r"]
    base = np.array([[0.15, 0.1], [-0.1, 0.15], [0.05, -0.15]])
    e = np.array([1.0, 0.0])
    fa = np.concatenate([base - (r + 0.06) * e, base + (r + 0.06) * e])
    fb = np.concatenate([base - (r - 0.02) * e, base + (r - 0.02) * e])
    ib = inbetween(phi_a, phi_b, grid, fa, fb)
    counts, areas = [], []
    for s in np.linspace(0.0, 1.0, 13):
        ls = ib.levelset(s)
        counts.append(ndimage.label(ls < 0)[1])
        areas.append(sum(loop_area(lp) for lp in extract_surface(ls, grid)))
    assert counts[0] == 2 and counts[-1] == 1 and max(counts) <= 2 and min(counts) >= 1
    assert np.abs(np.array(areas) / areas[0] - 1).max() <= 0.02


@pytest.mark.parametrize("d", [2, 3])
def test_bend_through_the_solver_keeps_the_parts(d):
    grid, phi_a, phi_b, _, info = bend_case(d=d, n=40 if d == 2 else 32)
    fa = np.zeros((6, d))
    fa[:, 0] = [-0.55, -0.35, -0.05, 0.05, 0.35, 0.55]
    fa[1, 1], fa[4, 1] = 0.05, -0.05
    if d == 3:
        fa[2, 2], fa[5, 2] = 0.05, -0.05
    fb = fa.copy()
    right = fa[:, 0] > 0
    fb[right, 0], fb[right, 1] = -fa[right, 1], fa[right, 0]  # right half turned 90 degrees
    ib = inbetween(phi_a, phi_b, grid, fa, fb)
    pts = np.zeros((4, d))
    pts[:, 0] = [-0.6, -0.2, 0.2, 0.6]  # the rigid parts of both halves, away from the joint
    for s in np.linspace(0.0, 1.0, 5):
        q = ib.trajectory(pts, s)
        assert abs(np.linalg.norm(q[1] - q[0]) / 0.4 - 1) <= 0.02
        assert abs(np.linalg.norm(q[3] - q[2]) / 0.4 - 1) <= 0.02
        assert ndimage.label(ib.levelset(s) < 0)[1] == 1
