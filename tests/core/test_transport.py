"""The semi-Lagrangian inverse lookup of `transport` on bent cells (docs/method.md, section 6)."""

import numpy as np
import pytest

from keyframe_implicit.core.base import elements

from keyframe_implicit.core.base import sampling

from keyframe_implicit.core.motion import transport
from keyframe_implicit.core import Grid, sample


def bent_cells(d, n=9, jitter=0.2, seed=3):
    """Every cell of an n^d grid moved by a smooth bend plus random corner jitter
    (cells far from parallelepipeds), as (grid, corner positions (C, 2^d, d), cells)."""
    rng = np.random.default_rng(seed)
    grid = Grid(np.zeros(d), 1.0, (n,) * d)
    nodes = grid.points().reshape(-1, d)
    bend = 0.6 * np.sin(nodes[:, ::-1] * 0.7)  # each axis moved by a wave along another
    moved = nodes + bend + rng.uniform(-jitter, jitter, nodes.shape)
    lower = np.ravel_multi_index(np.indices((n - 1,) * d).reshape(d, -1), grid.shape)
    corners = lower[:, None] + elements.corners(d) @ grid.strides
    return grid, moved[corners], lower, moved


@pytest.mark.parametrize("d", [2, 3])
def test_small_inverses_and_the_singular_fallback(d):
    """`_inverse_small` (by `elements.cofactor` on the batch-last layout) inverts each matrix of a batch, and
    gives ``singular`` times the identity for a singular one."""
    rng = np.random.default_rng(1)
    J = rng.normal(size=(d, d, 50)) + 2.0 * np.eye(d)[:, :, None]
    J[..., 0] = 0.0
    J[0, :, 1] = J[1, :, 1]  # two equal rows
    inv = transport._inverse_small(J, singular=0.5)
    np.testing.assert_allclose(np.einsum("ijm,jkm->ikm", inv[..., 2:], J[..., 2:]),
                               np.broadcast_to(np.eye(d)[:, :, None], (d, d, 48)), atol=1e-10)
    np.testing.assert_array_equal(inv[..., :2], np.broadcast_to(0.5 * np.eye(d)[:, :, None],
                                                                (d, d, 2)))


@pytest.mark.parametrize("d", [2, 3])
def test_bounding_boxes_hold_each_moved_cell(d):
    """Each moved cell's node box: from its corners' lowest and highest coordinates,
    rounded inwards and clipped to the grid; empty boxes have extent 0."""
    _, P, cells, _ = bent_cells(d)
    grid = Grid(np.full(d, -0.3), 0.7, (13,) * d)  # the cells seen on another lattice
    P = P.copy()
    P[0] += 50.0  # moved off the grid, above and below
    P[1] -= 50.0
    lo, ext = transport._bounding_boxes(grid, transport._index_corners(grid, P), 1e-6)
    u_low, u_high = grid.to_index(P.min(axis=1)).T, grid.to_index(P.max(axis=1)).T
    top = np.asarray(grid.shape)[:, None] - 1
    np.testing.assert_array_equal(lo, np.maximum(np.ceil(u_low - 1e-6), 0))
    np.testing.assert_array_equal(ext, np.maximum(np.minimum(np.floor(u_high + 1e-6), top)
                                                  - lo + 1, 0))
    assert ext[:, 0].min() == 0 and ext[:, 1].min() == 0 and ext[:, 2:].any()
    assert ext.dtype == lo.dtype == np.int64


@pytest.mark.parametrize("d", [2, 3])
def test_corners_gathered_from_nodes_are_the_cells_corners_in_index_units(d):
    """`_corner_gather` (the nodes' coordinates gathered one axis at a time) gives what
    `_index_corners` makes of the cells' corners: corner-major (2^d, d, C), index units,
    for any run of cells."""
    _, _, cells, moved = bent_cells(d)
    grid = Grid(np.full(d, -0.3), 0.7, (13,) * d)
    corner_of_cell = cells[:, None] + elements.corners(d) @ Grid(np.zeros(d), 1.0, (9,) * d).strides
    gather = transport._corner_gather(grid, moved, corner_of_cell)
    got = gather(0, cells.size)
    expected = transport._index_corners(grid, moved[corner_of_cell])
    assert got.shape == (2 ** d, d, cells.size) and expected.flags.c_contiguous
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(gather(3, 7), expected[..., 3:7])
    np.testing.assert_allclose(got[:, :, 5].T, (moved[corner_of_cell[5]] + 0.3).T / 0.7,
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_affine_guess_stays_within_its_slack(d):
    grid, P, cells, _ = bent_cells(d)
    coef = transport._centred_coefficients(grid.to_index(P).transpose(1, 2, 0))
    Jinv = transport._inverse_small(transport._centre_jacobian(coef))
    slack = transport._affine_slack(coef, Jinv)
    rng = np.random.default_rng(0)
    for _ in range(20):  # random points of every cell: their images, then the affine guess
        v = rng.uniform(-0.5, 0.5, (d, cells.size))
        z, _ = transport._poly_eval(coef, v, jacobian=False)
        guess = transport._apply_small(Jinv, z - coef[0])
        assert np.all(np.abs(guess - v) <= slack + 1e-12)
    # the bound is not vacuous: bent cells need a slack, and it stays below the cap
    assert 0.0 < np.median(slack) < transport._GUESS_SLACK


@pytest.mark.parametrize("d", [2, 3])
def test_corners_and_their_map_agree(d):
    grid, P, cells, _ = bent_cells(d)
    coef = transport._centred_coefficients(P.transpose(1, 2, 0))
    v = (elements.corners(d) - 0.5).T  # the corners in centred local coordinates
    for k in range(2 ** d):
        at = np.repeat(v[:, k:k + 1], cells.size, axis=1)
        T, J = transport._poly_eval(coef, at)
        np.testing.assert_allclose(T, P[:, k].T, atol=1e-12)
        # the Jacobian's column a is the difference along axis a at that corner
        for a in range(d):
            step = np.zeros(d)
            step[a] = 1e-6
            T2, _ = transport._poly_eval(coef, at + step[:, None], jacobian=False)
            np.testing.assert_allclose(J[:, a], (T2 - T) / 1e-6, atol=1e-5)


@pytest.mark.parametrize("d", [2, 3])
def test_inverse_lookup_finds_every_node_of_bent_cells(d, monkeypatch):
    grid, P, cells, moved = bent_cells(d)
    target, source = transport.inverse_lookup(grid, P, cells)
    assert target.size > 0.5 * cells.size
    # each source point is carried onto its node: the moved nodes, read multilinearly there
    at = grid.to_world(source)
    image = np.stack([sample(moved[:, a].reshape(grid.shape), grid, at) for a in range(d)], -1)
    np.testing.assert_allclose(image, grid.points().reshape(-1, d)[target], atol=1e-6)
    # the same nodes and sources as a lookup that gives every candidate Newton steps
    monkeypatch.setattr(transport, "_affine_slack",
                        lambda coef, Jinv: np.full((d, coef.shape[-1]), np.inf))
    t_all, s_all = transport.inverse_lookup(grid, P, cells)
    key = np.lexsort(np.vstack([source.T, target]))
    key_all = np.lexsort(np.vstack([s_all.T, t_all]))
    np.testing.assert_array_equal(target[key], t_all[key_all])
    np.testing.assert_allclose(source[key], s_all[key_all], atol=1e-9)


def test_inverse_lookup_of_no_cells_finds_nothing():
    grid = Grid(np.zeros(3), 1.0, (4, 4, 4))
    target, source = transport.inverse_lookup(grid, np.zeros((0, 8, 3)), np.zeros(0, np.int64))
    assert target.shape == (0,) and source.shape == (0, 3)


@pytest.mark.parametrize("d", [2, 3])
def test_values_read_in_the_cells_the_lookup_found_are_a_multilinear_sample(d):
    # the lookup's cells and local coordinates give the sources it returns, and node values
    # read there (the map, in `Transport.carry`) are what `sample` reads at those sources
    grid, P, cells, moved = bent_cells(d)
    target, source = transport.inverse_lookup(grid, P, cells)
    t2, cell, local = transport._lookup_in_cells(grid, transport._index_corners(grid, P), cells)
    np.testing.assert_array_equal(t2, target)
    np.testing.assert_array_equal(transport._index_coordinates(grid, cells, cell, local), source)
    corner_index = cells[:, None] + elements.corners(d) @ grid.strides
    read = sampling.multilinear_in_cells(moved, corner_index, cell, local)
    at = grid.to_world(source)
    expected = np.stack([sample(moved[:, a].reshape(grid.shape), grid, at) for a in range(d)], -1)
    inside = np.all(np.abs(local) <= 0.5, axis=0)  # on a face, sample reads the next cell
    assert inside.mean() > 0.9
    np.testing.assert_allclose(read[inside], expected[inside], rtol=0, atol=1e-12)
    np.testing.assert_allclose(read, expected, rtol=0, atol=1e-3)
    # and the corners themselves: a point at a corner reads that corner's value
    for c, bits in enumerate(elements.corners(d)):
        at_corner = np.repeat((bits - 0.5)[:, None], 4, axis=1)
        got = sampling.multilinear_in_cells(moved, corner_index, np.arange(4), at_corner)
        np.testing.assert_allclose(got, moved[corner_index[:4, c]], atol=1e-12)


def test_torn_material_fades_from_rest_on_bent_paths():
    # a disk mapped onto itself by the identity, against a smaller one: its outer ring is
    # torn (it lands in the other's empty space) and fades, at rate t on straight-timed
    # paths and from rest, t^2 (3 - 2t), on bent ones (here a bend of zero: same paths)
    from keyframe_implicit.core.motion.spline import Bend
    from keyframe_implicit.core.motion.trajectory import Trajectories

    grid = Grid(origin=(-1.0, -1.0), spacing=2.0 / 32, shape=(33, 33))
    x = grid.points()
    r = np.linalg.norm(x, axis=-1)
    phi_a, phi_b = r - 0.6, r - 0.4

    other = transport.Transport(phi_b, Trajectories(grid, x.copy(), phi_b < 0))
    ring = (r > 0.45) & (r < 0.55)  # inside A, outside B: torn
    f, g = phi_a[ring], phi_b[ring]
    for bent, fade in ((False, lambda t: t), (True, lambda t: t * t * (3 - 2 * t))):
        paths = Trajectories(grid, x.copy(), phi_a < 0)
        if bent:
            paths.bend = Bend(np.zeros((grid.size, 2)), np.zeros((grid.size, 2)))
        forward = transport.Transport(phi_a, paths)
        for t in (0.2, 0.5, 0.8):
            w = fade(t)
            carried = forward.carry(t, other=other).reshape(grid.shape)[ring]
            assert np.allclose(carried, (1 - w) * f + w * g, atol=1e-6), (bent, t)
