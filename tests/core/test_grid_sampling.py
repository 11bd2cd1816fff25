"""Grid coordinates and multilinear sampling (no Blender needed)."""

import numpy as np
import pytest

from keyframe_implicit.core import Grid, cell_weights, sample, sample_with_gradient
from keyframe_implicit.core.base.sampling import central_differences


def test_node_positions_follow_origin_and_spacing():
    g = Grid(origin=(-1.0, 0.5, 2.0), spacing=0.25, shape=(5, 4, 3))
    pts = g.points()
    assert pts.shape == (5, 4, 3, 3)
    np.testing.assert_allclose(pts[2, 1, 0], [-0.5, 0.75, 2.0])
    np.testing.assert_allclose(g.upper, [0.0, 1.25, 2.5])
    np.testing.assert_allclose(g.to_index(pts[3, 2, 1]), [3, 2, 1])


@pytest.mark.parametrize("bad", [dict(origin=(0, 0), spacing=0.0, shape=(3, 3)),
                                 dict(origin=(0, 0), spacing=1.0, shape=(3, 3, 3)),
                                 dict(origin=(0, 0, 0, 0), spacing=1.0, shape=(3, 3, 3, 3)),
                                 dict(origin=(0, 0), spacing=1.0, shape=(1, 3))])
def test_bad_grid_is_refused(bad):
    with pytest.raises(ValueError):
        Grid(**bad)


def test_linear_field_is_reproduced_with_exact_gradient():
    g = Grid(origin=(0.0, 0.0, 0.0), spacing=0.1, shape=(8, 9, 10))
    a = np.array([0.3, -1.2, 2.0])
    field = g.points() @ a + 0.7
    rng = np.random.default_rng(0)
    p = g.origin + rng.random((200, 3)) * (g.upper - g.origin)
    v, grad = sample_with_gradient(field, g, p)
    np.testing.assert_allclose(v, p @ a + 0.7, atol=1e-12)
    np.testing.assert_allclose(grad, np.broadcast_to(a, grad.shape), atol=1e-10)


def test_random_field_matches_scipys_trilinear_interpolation():
    """Values and gradients on a non-linear field, on an anisotropic grid whose axes all
    differ in length (a swapped stride or corner order shows), against scipy's
    RegularGridInterpolator and a one-sided difference of it."""
    from scipy.interpolate import RegularGridInterpolator

    g = Grid(origin=(0.3, -1.0, 2.0), spacing=0.2, shape=(5, 7, 6))
    rng = np.random.default_rng(4)
    field = rng.standard_normal(g.shape)
    axes = [g.origin[a] + g.spacing * np.arange(n) for a, n in enumerate(g.shape)]
    ref = RegularGridInterpolator(axes, field)
    p = g.origin + (0.05 + 0.9 * rng.random((300, 3))) * (g.upper - g.origin)
    v, grad = sample_with_gradient(field, g, p)
    np.testing.assert_allclose(v, ref(p), atol=1e-12)
    step = 1e-7
    for a in range(3):  # inside one cell the interpolant is linear along each axis
        q = p.copy()
        q[:, a] += step
        same_cell = np.floor(g.to_index(q)[:, a]) == np.floor(g.to_index(p)[:, a])
        np.testing.assert_allclose(grad[same_cell, a], (ref(q) - ref(p))[same_cell] / step,
                                   atol=1e-5)


@pytest.mark.parametrize("dim", [2, 3])
def test_central_differences_equal_the_probes_one_cell_away(dim):
    """The shared-weight shortcut against sampling p +- h e_a one probe at a time, on a
    grid whose axes all differ in length, at points deep inside, in the outermost cells
    (where a probe leaves the grid and the shortcut must not be used) and outside."""
    shape = (9, 11, 8)[:dim]
    g = Grid(origin=(0.3, -1.0, 2.0)[:dim], spacing=0.2, shape=shape)
    rng = np.random.default_rng(7)
    field = rng.standard_normal(g.shape)
    p = g.origin + (-0.1 + 1.2 * rng.random((400, dim))) * (g.upper - g.origin)
    h, eye = g.spacing, g.spacing * np.eye(dim)
    for outside in ("clamp", "distance"):
        ref = np.stack([sample(field, g, p + eye[a], outside=outside)
                        - sample(field, g, p - eye[a], outside=outside)
                        for a in range(dim)], axis=1) / (2 * h)
        np.testing.assert_allclose(central_differences(field, g, p, outside=outside), ref,
                                   rtol=0, atol=1e-12)
    inner = np.all((g.to_index(p) >= 1) & (g.to_index(p) < np.array(shape) - 2), axis=1)
    assert 100 < inner.sum() < len(p) - 100  # both ways are exercised


def test_weights_are_a_partition_of_unity_and_reproduce_position():
    g = Grid(origin=(1.0, -2.0), spacing=0.5, shape=(6, 7))
    rng = np.random.default_rng(1)
    p = g.origin + rng.random((50, 2)) * (g.upper - g.origin)
    flat, w = cell_weights(g, p)
    assert np.all(w >= 0)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    nodes = g.points().reshape(-1, 2)
    np.testing.assert_allclose(np.einsum("pk,pkd->pd", w, nodes[flat]), p, atol=1e-12)


def test_distance_extension_stays_outside_beyond_the_grid():
    g = Grid(origin=(0.0, 0.0), spacing=1.0, shape=(4, 4))
    field = np.full(g.shape, -0.5)  # "inside" everywhere on the grid
    far = np.array([[10.0, 1.0], [-5.0, -5.0]])
    assert np.all(sample(field, g, far, outside="distance") > 0)
    assert np.all(sample(field, g, far, outside="clamp") < 0)


def test_vector_field_sampling():
    g = Grid(origin=(0.0, 0.0), spacing=1.0, shape=(3, 3))
    y = g.points() * 2.0
    np.testing.assert_allclose(sample(y, g, np.array([[0.5, 1.5]])), [[1.0, 3.0]])


def test_distance_extension_gradient_inside_is_the_interpolant_gradient():
    # points inside the box whose world -> index round trip is inexact must not get
    # the outward unit vector of the extension added to their gradient
    g = Grid(origin=(-0.37, 0.11, 0.29), spacing=0.1 / 3, shape=(7, 6, 5))
    a = np.array([-0.44, 0.3, 0.9])
    field = g.points() @ a
    pts = g.points().reshape(-1, 3)  # on nodes, including the box faces
    _, grad = sample_with_gradient(field, g, pts, outside="distance")
    np.testing.assert_allclose(grad, np.broadcast_to(a, grad.shape), atol=1e-9)


def test_distance_extension_gradient_outside_points_away_from_the_box():
    g = Grid(origin=(0.0, 0.0), spacing=1.0, shape=(4, 4))
    field = np.zeros(g.shape)
    v, grad = sample_with_gradient(field, g, np.array([[5.0, 1.5], [-2.0, -2.0]]), outside="distance")
    np.testing.assert_allclose(v, [2.0, np.sqrt(8.0)])
    np.testing.assert_allclose(grad, [[1.0, 0.0], [-np.sqrt(0.5), -np.sqrt(0.5)]], atol=1e-12)


@pytest.mark.parametrize("lo", [0, 700])
def test_unique_nodes_are_numpys_unique(lo):
    """Marking instead of sorting: the same sorted nodes, each entry found among them."""
    g = Grid(origin=(0.0, 0.0, 0.0), spacing=1.0, shape=(10, 11, 12))
    flat = np.random.default_rng(5).integers(lo, lo + 300, size=(400, 8))
    nodes, inverse = g.unique_nodes(flat)
    want, want_inverse = np.unique(flat, return_inverse=True)
    np.testing.assert_array_equal(nodes, want)
    assert inverse.shape == flat.shape
    np.testing.assert_array_equal(inverse.reshape(-1), want_inverse.reshape(-1))
    empty_nodes, empty_inverse = g.unique_nodes(np.zeros((0, 8), dtype=np.int64))
    assert empty_nodes.size == 0 and empty_inverse.shape == (0, 8)


@pytest.mark.parametrize("shape", [(6, 5), (5, 6, 4)])
def test_cells_within_match_a_cell_by_cell_count(shape):
    """`elements.cells_within` and the transport's border against a loop over the cells."""
    import itertools

    from keyframe_implicit.core.base import elements
    from keyframe_implicit.core.motion.transport import _region_cells

    g = Grid(origin=(0.0,) * len(shape), spacing=1.0, shape=shape)
    region = np.random.default_rng(3).random(shape) < 0.8
    offsets = elements.corners(g.dim)
    want = [c for c in itertools.product(*(range(n - 1) for n in shape))
            if all(region[tuple(np.add(c, o))] for o in offsets)]
    lower, nodes, local, border = _region_cells(g, region.reshape(-1))
    assert 0 < len(want) < np.prod(np.subtract(shape, 1))
    np.testing.assert_array_equal(lower, [np.ravel_multi_index(c, shape) for c in want])
    corner_flat = [[np.ravel_multi_index(tuple(np.add(c, o)), shape) for o in offsets] for c in want]
    np.testing.assert_array_equal(nodes[local], corner_flat)
    assert np.array_equal(nodes, np.unique(corner_flat))
    # a node is on the border when some cell around it (or past the grid's edge) is not kept
    kept = {tuple(c) for c in want}
    around = [tuple(np.subtract(np.unravel_index(n, shape), o)) for n in nodes for o in offsets]
    surrounded = np.reshape([a in kept for a in around], (len(nodes), len(offsets))).all(axis=1)
    np.testing.assert_array_equal(border, nodes[~surrounded])
