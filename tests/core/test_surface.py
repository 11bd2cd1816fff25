"""Surface extraction: marching cubes / contours in world units, outward orientation."""

import numpy as np
import pytest

from inbetween_cases import make_grid, sd_sphere
from keyframe_implicit.core import Grid, extract_surface
from keyframe_implicit.core.surface.extract import loop_area, mesh_area, mesh_volume


def test_sphere_mesh_in_world_units_with_outward_normals():
    grid = Grid((-0.3, 0.2, -1.0), 0.05, (30, 34, 32))
    c = np.array([0.42, 1.0, -0.2])
    r = 0.45
    V, F = extract_surface(sd_sphere(grid.points(), c, r), grid)
    assert V.shape[1] == 3 and F.shape[1] == 3 and F.dtype.kind == "i"
    assert np.abs(np.linalg.norm(V - c, axis=1) - r).max() < 0.1 * grid.spacing
    assert mesh_volume(V, F) == pytest.approx(4 / 3 * np.pi * r ** 3, rel=0.02)
    assert mesh_area(V, F) == pytest.approx(4 * np.pi * r ** 2, rel=0.02)
    a, b, cc = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    normals = np.cross(b - a, cc - a)
    outward = np.einsum("ij,ij->i", normals, (a + b + cc) / 3 - c)
    assert np.all(outward[np.linalg.norm(normals, axis=1) > 1e-12] > 0)


def test_body_cut_by_the_grid_box_is_closed():
    grid = make_grid(3, 20)
    V, F = extract_surface(sd_sphere(grid.points(), (1.2, 0.0, 0.0), 0.6), grid)
    # closed: every edge is shared by exactly two triangles
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert np.all(counts == 2)
    assert mesh_volume(V, F) == pytest.approx(0.5 * 4 / 3 * np.pi * 0.6 ** 3, rel=0.05)


def test_empty_level_set_gives_empty_arrays():
    grid = make_grid(3, 10)
    V, F = extract_surface(np.ones(grid.shape), grid)
    assert V.shape == (0, 3) and F.shape == (0, 3)
    assert extract_surface(np.ones((10, 10)), make_grid(2, 10)) == []


def test_2d_loops_are_closed_and_counter_clockwise_around_material():
    grid = make_grid(2, 48)
    p = grid.points()
    ring = np.maximum(sd_sphere(p, (0.1, -0.1), 0.7), -sd_sphere(p, (0.1, -0.1), 0.35))
    loops = extract_surface(ring, grid)
    assert len(loops) == 2
    areas = sorted(loop_area(lp) for lp in loops)
    assert areas[0] == pytest.approx(-np.pi * 0.35 ** 2, rel=0.02)  # hole: clockwise
    assert areas[1] == pytest.approx(np.pi * 0.7 ** 2, rel=0.02)
    for lp in loops:
        assert lp.shape[1] == 2
        assert not np.allclose(lp[0], lp[-1])  # closing point not repeated


def test_wrong_field_shape_is_refused():
    grid = make_grid(3, 10)
    with pytest.raises(ValueError, match="shape"):
        extract_surface(np.ones((10, 10, 9)), grid)
