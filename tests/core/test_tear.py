"""A map that spreads one component over several tears instead of stretching (map/tear.py)."""

import numpy as np
import pytest
from scipy import ndimage

from keyframe_implicit.core.base import elements
from keyframe_implicit.core.base.sampling import sample
from keyframe_implicit.core.map.solver import solve_map
from keyframe_implicit.core.map.tear import find_tear

from inbetween_cases import unequal_balls


def _det_f(result, phi):
    """det F at the centres of the material cells of ``phi``, and whether each is a crack cell."""
    centre = sum(elements.corner_views(phi)) / 2 ** phi.ndim < 0
    Y = np.stack([v[centre] for v in elements.corner_views(result.mapped, 3)], axis=1)
    G = elements.quadrature(3, result.grid.spacing, "centre").G
    det = elements.determinant(elements.deformation_gradient(Y, G))[:, 0]
    crack = np.zeros(len(det), bool) if result.tear is None else result.tear.crack[centre]
    return det, crack


def _in_band(det):
    return float(np.mean((det >= 0.8) & (det <= 1.25)))


@pytest.fixture(scope="module")
def backward():
    """The unequal merge seen backwards (one ball into two) at 48^3, two levels: torn and
    as one continuous map."""
    g, phi_a, phi_b, fa, fb = unequal_balls(48)
    torn = solve_map(phi_b, phi_a, g, fb, fa, tear=True)
    whole = solve_map(phi_b, phi_a, g, fb, fa)  # the default: one continuous map
    return g, phi_a, phi_b, torn, whole


def test_a_merges_backward_map_tears_and_keeps_det_f_in_band(backward):
    g, phi_a, phi_b, torn, whole = backward
    assert torn.tear is not None and whole.tear is None
    assert torn.stats["tear"]["pieces"] == 2 and torn.stats["levels"][-1]["torn"]
    det, crack = _det_f(torn, phi_b)
    assert _in_band(det[~crack]) >= 0.95
    assert 0 < crack.mean() < 0.25  # one layer of cells across the ball
    assert torn.stats["tear"]["crack_material"] == pytest.approx(crack.mean())
    # the continuous map stretches the whole ball to fill the gap
    det_whole, _ = _det_f(whole, phi_b)
    assert _in_band(det_whole) < 0.5 and np.median(det_whole) > 1.25


def test_each_piece_lands_in_its_own_ball(backward):
    g, phi_a, phi_b, torn, _ = backward
    balls, _ = ndimage.label(phi_a < 0)
    piece = torn.tear.piece
    for p, target in enumerate(torn.tear.target, start=1):
        away = [ndimage.distance_transform_edt(balls != j) * g.spacing for j in (1, 2)]
        ends = torn.mapped[(piece == p) & (phi_b < 0)]
        own, other = (sample(away[j - 1], g, ends) for j in (target, 3 - target))
        # in its ball or within a cell of it; the few others lie on the crack, where a node
        # in crack cells only is not solved and takes the extension of its neighbours
        assert np.mean(own <= g.spacing) > 0.9
        assert np.mean(own < other) > 0.9


def test_pieces_hold_their_balls_share_of_the_material(backward):
    g, phi_a, phi_b, torn, _ = backward
    small = 0.13 ** 3 / (0.13 ** 3 + 0.18 ** 3)  # the balls' radii (unequal_balls)
    balls, _ = ndimage.label(phi_a < 0)
    share = {int(balls[phi_a < 0][np.argmin(phi_a[phi_a < 0])]): 1 - small}  # the big ball
    pieces = np.bincount(torn.tear.piece[phi_b < 0]) / np.count_nonzero(phi_b < 0)
    for p, target in enumerate(torn.tear.target, start=1):
        assert pieces[p] == pytest.approx(share.get(int(target), small), abs=0.01)


def test_no_tear_where_each_component_reaches_one():
    g, phi_a, phi_b, fa, fb = unequal_balls(32)
    x = g.points()
    # two balls into one: B has one component
    assert find_tear(phi_a, phi_b, g, x) is None
    # two balls moved apart rigidly: each still reaches its own
    shifted = x + np.where(x[..., :1] < 0, -0.05, 0.05) * np.array([1.0, 0, 0])
    moved = sample(phi_a, g, x - np.where(x[..., :1] < 0, -0.05, 0.05) * np.array([1.0, 0, 0]))
    assert find_tear(phi_a, moved, g, shifted) is None


def test_a_cracks_material_fades_by_mid_way():
    """In the cells of a crack the carried value fades with min(2t, 1), elsewhere with t."""
    from keyframe_implicit.core import Grid
    from keyframe_implicit.core.motion.trajectory import Trajectories
    from keyframe_implicit.core.motion.transport import Transport

    g = Grid((-1.0, -1.0), 2.0 / 30, (31, 31))
    phi = np.linalg.norm(g.points(), axis=-1) - 0.6
    empty = np.ones(g.shape)  # the other keyframe has nothing here
    torn = np.zeros((30, 30), bool)
    torn[12:18, :] = True  # a band of cells across the disc
    paths = Trajectories(g, g.points(), phi < 0)  # standing still
    other = Transport(empty, Trajectories(g, g.points(), phi < 0))
    plain, torn_t = Transport(phi, paths), Transport(phi, paths, torn=torn)
    whole = plain.carry(0.25, other=other).reshape(g.shape)
    cracked = torn_t.carry(0.25, other=other).reshape(g.shape)
    inner = np.zeros(g.shape, bool)
    inner[13:18, :] = True  # nodes whose every cell is torn
    inside = (phi < 0) & np.isfinite(whole)
    cap = plain.truncation  # the largest value carried
    np.testing.assert_allclose(whole[inside], np.minimum(0.75 * phi + 0.25, cap)[inside], atol=1e-9)
    np.testing.assert_allclose(cracked[inside & inner],
                               np.minimum(0.5 * phi + 0.5, cap)[inside & inner], atol=1e-9)
    np.testing.assert_allclose(cracked[inside & ~inner], whole[inside & ~inner], atol=1e-9)
    assert np.any(cracked[inside & inner] > whole[inside & inner])
    half = Transport(phi, paths, torn=torn).carry(0.5, other=other).reshape(g.shape)
    assert np.all(half[inside & inner] >= 0.0)  # gone by mid-way


def test_a_crack_on_the_motion_grid_reaches_the_surface_cells_it_holds():
    from keyframe_implicit.core import Grid
    from keyframe_implicit.core.motion.levelset import _Paths
    from keyframe_implicit.core.motion.options import MotionOptions

    surface = Grid((0.0, 0.0, 0.0), 0.1, (21, 21, 21))
    motion = Grid((0.0, 0.0, 0.0), 0.2, (11, 11, 11))
    crack = np.zeros((10, 10, 10), bool)
    crack[4] = True  # motion cells with 0.8 <= x < 1.0
    cells = _Paths(surface, motion, MotionOptions(), None).cells(crack)
    centres = (np.arange(20) + 0.5) * 0.1
    assert cells.shape == (20, 20, 20)
    np.testing.assert_array_equal(cells[:, 0, 0], (centres >= 0.8) & (centres < 1.0))
    assert np.all(cells == cells[:, :1, :1])
    assert _Paths(surface, None, MotionOptions(), None).cells(None) is None
