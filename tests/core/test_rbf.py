"""Initial map from feature points (eq. 2.1-2.5 as corrected in docs/method.md, section 1)."""

import numpy as np

from inbetween_cases import capsule_and_balls, sd_ellipsoid, sd_sphere, unit_grid
from keyframe_implicit.core import Grid, sample
from keyframe_implicit.core.map.rbf import initial_map, label_material


def test_rbf_interpolates_features_and_reproduces_affine_maps_3d():
    g = unit_grid(3, 20)
    P = g.points()
    phi = sd_sphere(P, 0.5, 0.35)
    # feature points on nodes so that y(x'_i) = y'_i can be read off the grid exactly
    idx = np.array([[10, 10, 10], [16, 10, 9], [10, 15, 11], [9, 8, 15], [6, 12, 7]])
    fa = g.to_world(idx)
    A = np.array([[1.1, 0.2, 0.0], [-0.1, 0.9, 0.1], [0.05, 0.0, 1.0]])
    fb = fa @ A.T + [0.02, -0.01, 0.03]
    m = initial_map(phi, phi, g, fa, fb)
    assert m.methods == ["rbf"]
    assert np.allclose(m.mapped[tuple(idx.T)], fb, atol=1e-10)
    # degree-1 polynomial part: an affine feature motion is reproduced everywhere
    assert np.allclose(m.mapped, P @ A.T + [0.02, -0.01, 0.03], atol=1e-8)


def test_rbf_thin_plate_is_not_affine_for_non_affine_features_2d():
    g = unit_grid(2, 30)
    P = g.points()
    phi = sd_sphere(P, 0.5, 0.35)
    idx = np.array([[15, 15], [25, 15], [15, 24], [7, 10], [20, 20]])
    fa = g.to_world(idx)
    fb = fa.copy()
    fb[4] += [0.03, -0.02]  # one point moves alone
    m = initial_map(phi, phi, g, fa, fb)
    assert np.allclose(m.mapped[tuple(idx.T)], fb, atol=1e-10)
    disp = np.linalg.norm(m.mapped - P, axis=-1)
    assert disp[phi < 0].max() > 0.02 and disp[15, 15] < 1e-10


def test_each_component_gets_its_own_map_and_outside_stays_finite():
    g = unit_grid(2, 40)
    P = g.points()
    phi = np.minimum(sd_sphere(P, [0.25, 0.5], 0.15), sd_sphere(P, [0.75, 0.5], 0.15))
    labels, n = label_material(phi)
    assert n == 2
    left = np.array([[0.25, 0.5], [0.35, 0.5], [0.25, 0.6]])
    right = np.array([[0.75, 0.5], [0.85, 0.5], [0.75, 0.6], [0.7, 0.45]])
    fa = np.vstack([left, right])
    fb = np.vstack([left + [0.1, 0.0], right - [0.1, 0.05]])
    m = initial_map(phi, phi, g, fa, fb)
    assert m.methods == ["rbf", "rbf"]
    lab_left = labels[np.rint(g.to_index([0.25, 0.5])).astype(int)[0], 20]
    in_left = labels == lab_left
    in_right = (labels > 0) & ~in_left
    assert np.allclose(m.mapped[in_left], P[in_left] + [0.1, 0.0], atol=1e-9)
    assert np.allclose(m.mapped[in_right], P[in_right] - [0.1, 0.05], atol=1e-9)
    assert np.all(np.isfinite(m.mapped))
    # between the components the blend lies between the two translations
    mid = m.mapped[20, 20] - P[20, 20]
    assert -0.1 - 1e-9 <= mid[0] <= 0.1 + 1e-9


def _rot3(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_coplanar_points_fall_back_to_the_rigid_motion_they_pin():
    g = unit_grid(3, 24)
    P = g.points()
    c, ax = np.array([0.5, 0.5, 0.5]), np.array([0.3, 0.2, 0.15])
    R, t = _rot3(0.6), np.array([0.04, -0.02, 0.03])
    phi_a = sd_ellipsoid(P, c, ax)
    phi_b = sd_ellipsoid((P - c - t) @ R + c, c, ax)
    fa = np.array([[0.79, 0.5, 0.5], [0.5, 0.68, 0.5], [0.3, 0.45, 0.5], [0.55, 0.4, 0.5]])  # plane z=0.5
    fb = (fa - c) @ R.T + c + t
    m = initial_map(phi_a, phi_b, g, fa, fb)
    assert m.methods == ["rigid"]
    assert np.allclose(m.mapped, (P - c) @ R.T + c + t, atol=1e-9)


def test_fewer_than_d_plus_1_points_and_no_points_align_principal_axes():
    g = unit_grid(3, 24)
    P = g.points()
    c, ax = np.array([0.5, 0.5, 0.5]), np.array([0.3, 0.2, 0.12])
    R, t = _rot3(np.pi / 2), np.array([0.03, 0.0, 0.0])
    phi_a = sd_ellipsoid(P, c, ax)
    phi_b = sd_ellipsoid((P - c - t) @ R + c, c, ax)
    for fa in (np.zeros((0, 3)), np.array([[0.5, 0.5, 0.5]]), np.array([[0.5, 0.5, 0.5], [0.7, 0.5, 0.5]])):
        fb = (fa - c) @ R.T + c + t
        m = initial_map(phi_a, phi_b, g, fa, fb)
        assert m.methods == ["rigid"]
        y = m.mapped[phi_a < 0]
        # rigid: pairwise distances kept
        i = np.random.default_rng(0).choice(len(y), 200)
        x = P[phi_a < 0]
        assert np.allclose(np.linalg.norm(y[i, None] - y[None, i], axis=-1),
                           np.linalg.norm(x[i, None] - x[None, i], axis=-1), atol=1e-9)
        # and lands on B: (almost) all mapped material inside B
        assert np.mean(sample(phi_b, g, y) < g.spacing) > 0.97
        if len(fa):
            # multilinear interpolation of a rigid (affine) field is exact
            assert np.allclose(sample(m.mapped, g, fa), fb, atol=1e-9)


def test_start_does_not_fold_a_merge_seen_backwards_3d():
    # a capsule split into two balls (the example merge's backward map): the centre pairs
    # ask for a 4x stretch, the pole pairs for 0.8x; the thesis's r^3 overshoots between
    # them and folds the capsule's ends, which the solver could never undo
    from keyframe_implicit.core.map.rbf import min_det

    g = Grid((-2.0, -0.9, -0.9), 0.1, (41, 19, 19))
    capsule, balls = capsule_and_balls(g, 0.64, 0.6)
    fa = np.array([[-0.9, 0, 0], [0.9, 0, 0], [-0.25, 0, 0], [0.25, 0, 0],
                   [-0.35, 0, 0.55], [0.35, 0, 0.55], [-0.35, -0.55, 0], [0.35, -0.55, 0]])
    fb = np.array([[-1.64, 0, 0], [1.64, 0, 0], [-1.1, 0, 0], [1.1, 0, 0],
                   [-1.1, 0, 0.54], [1.1, 0, 0.54], [-1.1, -0.54, 0], [1.1, -0.54, 0]])
    m = initial_map(capsule, balls, g, fa, fb)
    assert m.methods == ["rbf"]
    assert min_det(m.mapped, g, (capsule < 0).reshape(-1)) > 0
