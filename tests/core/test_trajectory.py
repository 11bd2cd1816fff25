"""As-rigid-as-possible trajectories (thesis sec. 3.1, docs/method.md, section 5)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from inbetween_cases import bend_case, merge_case, rigid_case
from keyframe_implicit.core import Grid
from keyframe_implicit.core.base.rotations import polar, rotation_exp, rotation_log
from keyframe_implicit.core.motion.trajectory import Trajectories


def test_polar_decomposition_and_rotation_log_roundtrip():
    rng = np.random.default_rng(0)
    F = rng.normal(size=(50, 3, 3)) + 2 * np.eye(3)
    R, S = polar(F)
    np.testing.assert_allclose(R @ S, F, atol=1e-10)
    np.testing.assert_allclose(np.swapaxes(R, 1, 2) @ R, np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-10)
    assert np.all(np.linalg.det(R) > 0.999)
    np.testing.assert_allclose(S, np.swapaxes(S, 1, 2), atol=1e-10)
    v = rng.normal(size=(20, 3))
    v *= (rng.uniform(0.1, 3.0, 20) / np.linalg.norm(v, axis=1))[:, None]
    np.testing.assert_allclose(rotation_log(rotation_exp(v, 3)), v, atol=1e-9)
    ang = rng.uniform(-3.0, 3.0, 20)
    np.testing.assert_allclose(rotation_log(rotation_exp(ang, 2)), ang, atol=1e-12)


def test_polar_by_newton_is_the_closest_rotation_of_the_svd():
    """`polar` takes the Newton iteration for 3 x 3 matrices with det F > 0 and the SVD for
    folded or flat ones: both give the closest proper rotation (the SVD's, with the sign on
    the smallest singular value), whichever way a matrix went."""
    from keyframe_implicit.core.base.rotations import _newton_rotation, _svd_rotation

    rng = np.random.default_rng(3)
    F = rng.normal(size=(400, 3, 3))
    F[:100] = Rotation.from_rotvec(rng.normal(size=(100, 3))).as_matrix() \
        @ (np.eye(3) + 0.3 * rng.normal(size=(100, 3, 3)))  # stretched rotations
    F[100:110] = Rotation.from_rotvec([np.pi - 1e-4, 0, 0]).as_matrix()  # near a half turn
    F[110:115] = np.diag([1.0, 1.0, 0.0])  # flat
    F[115:120] = np.diag([-1.0, 2.0, 0.5])  # folded
    positive = np.linalg.det(F) > 1e-3
    assert positive[100:110].all() and positive.sum() > 150
    by_newton, converged = _newton_rotation(F[positive])  # the path taken, on its own
    assert converged.all()
    np.testing.assert_allclose(by_newton, _svd_rotation(F[positive].copy()), atol=1e-12)
    R, S = polar(F)
    np.testing.assert_allclose(R, _svd_rotation(F.copy()), atol=1e-12)
    np.testing.assert_allclose(R @ S, F, atol=1e-12)
    assert np.all(np.abs(np.linalg.det(R) - 1.0) < 1e-12)
    assert np.all(np.linalg.eigvalsh(S[115:120])[:, 0] < 0)  # the fold stays in S
    assert polar(np.eye(3))[0].shape == (3, 3) and polar(np.zeros((0, 3, 3)))[0].shape == (0, 3, 3)
    np.testing.assert_allclose(polar(F[115:120])[0], R[115:120], atol=0)  # none by Newton


@pytest.mark.parametrize("d", [2, 3])
def test_edge_operators_are_the_least_squares_of_every_cell_edge(d):
    """L = D^T W D and B = D^T W E, with one row of D per edge of every cell (shared
    edges once per cell), as the docstring defines them; B as an operator, applied to
    the identity and to several columns at once."""
    from keyframe_implicit.core.base import elements
    from keyframe_implicit.core.motion.trajectory import _edge_operators, _edge_pairs

    grid = Grid((0.0,) * d, 1.0, (5,) * d)
    region = np.zeros(grid.shape, dtype=bool)  # two overlapping boxes: a ragged region
    region[(slice(1, 4),) * d] = True
    region[(slice(3, 5), slice(0, 3)) + (slice(2, 4),) * (d - 2)] = True
    _, nodes, lc = elements.cells_within(grid, region.reshape(-1))
    weight = np.linspace(0.1, 1.0, len(lc))
    L, B = _edge_operators(lc, weight, nodes.size, d)
    rows_D, rows_E, w = [], [], []
    for c in range(len(lc)):
        for a, k, hi in _edge_pairs(d):
            r = np.zeros(nodes.size)
            r[lc[c, hi]], r[lc[c, k]] = 1.0, -1.0
            e = np.zeros(len(lc) * d)
            e[c * d + a] = 1.0
            rows_D.append(r)
            rows_E.append(e)
            w.append(weight[c])
    D, E, W = np.array(rows_D), np.array(rows_E), np.diag(w)
    np.testing.assert_allclose(L.toarray(), D.T @ W @ D, atol=1e-14)
    assert B.shape == (nodes.size, len(lc) * d)
    np.testing.assert_allclose(B @ np.eye(len(lc) * d), D.T @ W @ E, atol=1e-14)
    T = np.random.default_rng(1).normal(size=(len(lc) * d, d))
    np.testing.assert_allclose(B @ T, D.T @ W @ E @ T, atol=1e-13)
    with pytest.raises(ValueError, match="T must have shape"):
        B @ T[1:]


@pytest.mark.parametrize("method", ["global", "local"])
def test_rigid_map_gives_exact_circular_arcs(method):
    grid, phi_a, _, mapped, info = rigid_case(n=20)
    mat = phi_a < 0
    # exact to rounding when CG is run to rounding (its default stops at 1e-5 of the
    # right-hand side, within about 1e-4 cells)
    traj = Trajectories(grid, mapped, mat, method=method, tolerance=1e-12)
    x = grid.points()[mat]
    cbar = x.mean(axis=0)  # the trajectories use the centroid of the material nodes
    ybar = mapped[mat].mean(axis=0)
    for s in (0.0, 0.3, 0.5, 0.8, 1.0):
        Rs = Rotation.from_rotvec(s * info["angle"] * np.array([1.0, 2.0, 0.5])
                                  / np.linalg.norm([1.0, 2.0, 0.5])).as_matrix()
        expect = cbar + s * (ybar - cbar) + (x - cbar) @ Rs.T
        np.testing.assert_allclose(traj.positions(s)[mat], expect, atol=1e-9)


def test_paths_end_exactly_at_the_map_for_a_non_rigid_map():
    grid, phi_a, _, mapped, _ = bend_case(d=2, n=30)
    traj = Trajectories(grid, mapped, phi_a < 0)
    np.testing.assert_array_equal(traj.positions(0.0), grid.points())
    np.testing.assert_array_equal(traj.positions(1.0), mapped)
    # and the paths are continuous in s: small steps in time give small moves
    a = traj.positions(0.5)
    b = traj.positions(0.5 + 1e-3)
    assert np.abs(b - a).max() < 4e-3  # speed < 4 world units per unit s on this box


def test_points_at_the_ends_follow_the_node_paths_inside_and_outside_the_grid():
    # s = 0 and s = 1 take a shortcut (the points themselves, the map read at them): it
    # must give what interpolating the nodes' positions gives, clamped points included
    from keyframe_implicit.core import cell_weights

    grid, phi_a, _, mapped, _ = bend_case(d=2, n=30)
    traj = Trajectories(grid, mapped, phi_a < 0)
    rng = np.random.default_rng(3)
    lo, hi = grid.origin, grid.upper
    pts = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), size=(400, 2))
    assert (~grid.contains(pts)).sum() > 50 and grid.contains(pts).sum() > 50
    flat, w = cell_weights(grid, pts)
    for s in (0.0, 1.0):
        disp = traj.node_positions(s, flat.reshape(-1)) - grid.node_points(flat.reshape(-1))
        expect = pts + np.einsum("pk,pkd->pd", w, disp.reshape(flat.shape + (2,)))
        np.testing.assert_allclose(traj(pts, s), expect, rtol=0, atol=1e-12)
    assert np.abs(traj(pts, 1.0) - pts).max() > 0.05  # the map moves them


def test_folded_cells_keep_paths_finite_and_straight_for_a_squeeze():
    # the merge map presses the two balls into each other along x: cells in between
    # fold; a pure squeeze has no rotation, so every path is the straight one
    grid, phi_a, _, mapped, _ = merge_case(d=2, n=40, gap=0.12, overlap=0.04)
    traj = Trajectories(grid, mapped, phi_a < 0)
    x = grid.points()
    for s in (0.3, 0.7):
        np.testing.assert_allclose(traj.positions(s), (1 - s) * x + s * mapped, atol=1e-9)
    assert traj.stats["folded_cells"] > 0
    np.testing.assert_array_equal(traj.positions(1.0), mapped)


def _joint_span(method, s):
    grid, phi_a, _, mapped, info = bend_case(d=2, n=40, half=0.45, left=0.9)
    traj = Trajectories(grid, mapped, phi_a < 0, method=method)
    b = info["blend"] + 0.03
    q = traj(np.array([[-b, 0.0], [b, 0.0]]), s)
    th = s * np.pi / 2
    ideal = np.linalg.norm(np.array([-b, 0.0]) - np.array([b * np.cos(th), b * np.sin(th)]))
    return np.linalg.norm(q[1] - q[0]) / ideal


def test_global_form_keeps_the_joint_closed_where_the_per_node_formula_opens_it():
    # joint 0.2 away from the rod's centroid: the thesis's per-node formula turns the
    # right part about the centroid, not about the joint, and the joint gapes half-way
    for s in (0.25, 0.5, 0.75):
        assert _joint_span("global", s) < 1.03
    assert _joint_span("local", 0.5) > 1.12


def test_the_ends_need_no_solve():
    """At s = 0 and 1 the paths are the grid and the map: nothing is solved for them (the
    template on a segment's last frame, made alone, costs no Poisson setup)."""
    grid, phi_a, _, mapped, _ = bend_case(d=3, n=24)
    traj = Trajectories(grid, mapped, phi_a < 0)
    p = grid.points().reshape(-1, 3)[::97]
    np.testing.assert_array_equal(traj(p, 1.0), Trajectories(grid, mapped, phi_a < 0)(p, 1.0))
    np.testing.assert_array_equal(traj.positions(0.0), grid.points())
    assert "setup_seconds" not in traj.stats
    traj(p, 0.5)
    assert traj.stats["setup_seconds"] > 0 and traj.stats["cg_iterations"]


def test_bad_input_is_refused_with_a_message():
    grid = Grid((0.0, 0.0), 0.1, (8, 8))
    mat = np.zeros((8, 8), bool)
    mat[3:5, 3:5] = True
    good = grid.points()
    with pytest.raises(ValueError, match="mapped"):
        Trajectories(grid, good[:-1], mat)
    bad = good.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Trajectories(grid, bad, mat)
    with pytest.raises(ValueError, match="empty"):
        Trajectories(grid, good, np.zeros((8, 8), bool))
    with pytest.raises(ValueError, match="method"):
        Trajectories(grid, good, mat, method="straight")
    traj = Trajectories(grid, good, mat)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        traj.positions(1.5)


def test_per_grid_node_only_the_map_the_region_and_the_body_are_kept():
    """Region-only storage: of the arrays as large as the grid, a Trajectories keeps the map
    (d floats a node) and two bytes a node (region, body); everything else is per active
    node, or computed for the nodes asked about."""
    grid, phi_a, _, mapped, _ = bend_case(d=3, n=24)
    traj = Trajectories(grid, mapped, phi_a < 0)
    traj.positions(0.5)  # the Poisson problem built
    per_node = sum(v.nbytes for v in vars(traj).values()
                   if isinstance(v, np.ndarray) and v.shape[:1] == (grid.size,))
    assert per_node <= grid.size * (3 * 8 + 2 + 1)  # + the material mask given
    np.testing.assert_allclose(traj.positions(0.0), grid.points(), atol=1e-12)


def test_the_body_formula_is_blended_in_over_the_outer_half_of_the_margin_only():
    """Positions are w Y + (1 - w) body with w the margin blend; the body formula is
    evaluated only where w < 1, and that gives the same positions as everywhere."""
    grid, phi_a, _, mapped, _ = bend_case(d=3, n=24)
    tr = Trajectories(grid, mapped, phi_a < 0)
    tr.setup()
    inner = tr._wblend == 1.0
    assert inner.any() and (~inner).any()
    assert np.array_equal(np.flatnonzero(~inner), tr._blended)
    s = 0.4
    Y = tr._poisson(s) + s * tr._resid
    w = tr._wblend[:, None]
    want = w * Y + (1.0 - w) * tr._body_path(s, tr._nodes)
    np.testing.assert_allclose(tr._active_positions(s), want, atol=1e-6 * grid.spacing)
