"""The comparison benchmark's metric functions, checked on analytic cases.

Each assertion would fail if the metric were wrong (volume formula, component
labelling, drift definition, surface distance in h, feature error in h).
"""

import numpy as np
import pytest

from benchmark_modules import load
from inbetween_cases import sd_sphere, sphere_field
from keyframe_implicit.core import Grid

metrics = load("metrics")


@pytest.fixture(scope="module")
def grid():
    return Grid(origin=(-1.0, -1.0, -1.0), spacing=2.0 / 47, shape=(48, 48, 48))


def test_volume_of_sphere_is_second_order_accurate(grid):
    # the surface the artist gets (marching cubes) cuts chords: about 1 % low for a ball
    # 7 cells in radius, and a quarter of that on a grid twice as fine
    def error(g, r):
        v = metrics.volume(sphere_field(g, (0.01, -0.02, 0.03), r), g)
        return abs(v / (4 / 3 * np.pi * r ** 3) - 1)

    assert error(grid, 0.3) < 0.015 and error(grid, 0.5) < 0.005
    fine = Grid(origin=(-1.0, -1.0, -1.0), spacing=2.0 / 95, shape=(96, 96, 96))
    assert error(fine, 0.3) < error(grid, 0.3) / 3


def test_volume_is_not_fooled_by_a_scaled_field(grid):
    # 3 * SDF has the same zero set; a plain ramp on phi / h would be off by the gradient
    phi = sphere_field(grid, (0, 0, 0), 0.4)
    assert abs(metrics.volume(3 * phi, grid) / metrics.volume(phi, grid) - 1) < 0.005


def test_components(grid):
    two = np.minimum(sphere_field(grid, (-0.5, 0, 0), 0.25), sphere_field(grid, (0.5, 0, 0), 0.25))
    assert metrics.components(two) == 2
    assert metrics.components(sphere_field(grid, (0, 0, 0), 0.4)) == 1
    assert metrics.components(np.ones(grid.shape)) == 0


def test_volume_drift_of_blend_of_separated_spheres_is_positive(grid):
    # a sphere moved apart: the blend (1-s) A + s B shrinks in between; the true motion does not
    times = np.linspace(0, 1, 9)
    a = sphere_field(grid, (-0.4, 0, 0), 0.3)
    b = sphere_field(grid, (0.4, 0, 0), 0.3)
    blend = [metrics.volume((1 - s) * a + s * b, grid) for s in times]
    moved = [metrics.volume(sphere_field(grid, (-0.4 + 0.8 * s, 0, 0), 0.3), grid) for s in times]
    assert metrics.volume_drift(blend, times) > 0.2
    assert metrics.volume_drift(moved, times) < 0.01


def test_volume_drift_is_relative_to_the_linear_volume():
    times = np.array([0.0, 0.5, 1.0])
    assert metrics.volume_drift([1.0, 1.5, 2.0], times) == pytest.approx(0.0)
    assert metrics.volume_drift([1.0, 1.2, 2.0], times) == pytest.approx(0.3 / 1.5)
    # against the keyframes' own volumes: an end frame that lost half of B is charged
    assert metrics.volume_drift([1.0, 1.0, 1.0], times, (1.0, 2.0)) == pytest.approx(0.5)


def test_spurious_components():
    assert metrics.spurious_components([2, 2, 1, 1], 2, 1) == 0
    assert metrics.spurious_components([2, 3, 1, 1], 2, 1) == 1
    assert metrics.spurious_components([1, 0, 1], 1, 1) == 1  # vanished material counts


def test_surface_error_in_grid_spacings(grid):
    h = grid.spacing
    phi = sphere_field(grid, (0, 0, 0), 0.4)
    mean, mx = metrics.surface_error(phi, grid, lambda p: sd_sphere(p, (0, 0, 0), 0.4))
    assert mean < 0.05 and mx < 0.1
    mean, mx = metrics.surface_error(phi, grid, lambda p: sd_sphere(p, (0, 0, 0), 0.4 + h))
    assert 0.9 < mean < 1.1
    # a grid reference gives the same answer
    mean_g, _ = metrics.surface_error(phi, grid, sphere_field(grid, (0, 0, 0), 0.4 + h))
    assert 0.9 < mean_g < 1.1
    assert np.isnan(metrics.surface_error(np.ones(grid.shape), grid, phi)[0])


def test_feature_error_in_grid_spacings(grid):
    t = np.array([0.1, -0.05, 0.2])
    mapped = grid.points() + t
    fa = np.array([[0.1, 0.2, 0.3], [-0.33, 0.01, 0.5]])
    assert np.all(metrics.feature_error(mapped, grid, fa, fa + t) < 1e-9)
    err = metrics.feature_error(mapped, grid, fa, fa + t + np.array([grid.spacing, 0, 0]))
    assert np.allclose(err, 1.0)
