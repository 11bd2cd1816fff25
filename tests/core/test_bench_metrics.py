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


# -- volume held per part ------------------------------------------------------
def _moving_apart(shift):
    """Paths of two balls either side of x = 0, moving apart by ``shift`` each over t in
    [0, 1] (A's paths), and B's paths back."""
    def forward(p, t):
        return p + t * shift * np.sign(p[:, :1]) * np.array([1.0, 0, 0])

    def backward(p, t):
        return p - t * shift * np.sign(p[:, :1]) * np.array([1.0, 0, 0])
    return forward, backward


def test_part_volume_errors_report_a_part_that_grows(grid):
    # two balls move apart; the right one is 6 % larger in every in-between: the measure
    # finds both parts apart on every frame, the growth on the right one only
    times = np.linspace(0, 1, 9)
    shift, (r1, r2) = 0.15, (0.25, 0.2)

    def frame(s, grow=1.0):
        return np.minimum(sphere_field(grid, (-0.35 - shift * s, 0, 0), r1),
                          sphere_field(grid, (0.35 + shift * s, 0.01, 0), r2 * grow ** (1 / 3)))

    frames = [frame(s, 1.06 if 0 < s < 1 else 1.0) for s in times]
    recs = metrics.part_volume_errors(frames, times, grid, frames[0], frames[-1],
                                      *_moving_apart(shift))
    assert len(recs) == 2 * len(times)
    left = [r["error"] for r in recs if r["piece"] == 1]
    right = [r for r in recs if r["piece"] == 2 and 0 < r["s"] < 1]
    assert max(left) < 0.01
    assert all(0.05 < r["error"] < 0.07 and 0.05 < r["own_error"] < 0.07 for r in right)
    exact = [r for r in recs if r["s"] in (0.0, 1.0)]
    assert all(r["error"] < 1e-9 for r in exact)  # the keyframes are their own reference


def test_material_pieces_share_a_merged_ball_by_where_the_backward_map_sends_it(grid):
    # one ball whose material left of x = 0.1 goes to the left ball: that piece's B volume
    # is the ball's volume left of the plane
    R, cut = 0.4, 0.1
    phi_a = np.minimum(sphere_field(grid, (-0.5, 0, 0), 0.25), sphere_field(grid, (0.5, 0, 0), 0.25))
    phi_b = sphere_field(grid, (0, 0, 0), R)

    def backward(p, t):
        side = np.where(p[:, :1] < cut, -1.0, 1.0)
        return p + t * 0.5 * side * np.array([1.0, 0, 0])

    piece_a, piece_b, volumes, own = metrics.material_pieces(phi_a, phi_b, grid, None, backward)
    assert own == 0 and set(np.unique(piece_b)) == {0, 1, 2}
    height = R - cut  # the cap right of the plane
    right = np.pi * height ** 2 * (3 * R - height) / 3
    fraction = volumes[:, 1] / volumes[:, 1].sum()
    assert fraction[1] == pytest.approx(right / (4 / 3 * np.pi * R ** 3), abs=0.01)
    assert volumes[:, 0] == pytest.approx(metrics.part_volumes(phi_a, grid))


def test_part_volumes_add_up_to_the_volume(grid):
    phi = np.minimum(sphere_field(grid, (-0.5, 0, 0), 0.2), sphere_field(grid, (0.4, 0, 0), 0.3))
    vols = metrics.part_volumes(phi, grid)
    assert len(vols) == 2 and vols[0] < vols[1]
    assert vols.sum() == pytest.approx(metrics.volume(phi, grid), rel=1e-6)


def test_det_f_is_the_maps_volume_change_over_the_material(grid):
    phi = sphere_field(grid, (0, 0, 0), 0.4)
    x = grid.points()
    dets, torn = metrics.det_f(x * np.array([1.2, 1.0, 0.9]), grid, phi)
    assert np.allclose(dets, 1.08) and not torn.any()
    # one det per material cell: the cells fill the ball
    assert len(dets) * grid.spacing ** 3 == pytest.approx(4 / 3 * np.pi * 0.4 ** 3, rel=0.05)
    stretched = np.where(x[..., :1] > 0, x * np.array([1.5, 1.0, 1.0]), x)  # half the ball
    summary = metrics.det_f_summary(*metrics.det_f(stretched, grid, phi))
    assert summary["p5"] == pytest.approx(1.0) and summary["p95"] == pytest.approx(1.5)
    assert summary["max_dev"] == pytest.approx(0.5) and 0.4 < summary["in_band"] < 0.6
    assert summary["crack"] == 0.0


def test_det_f_leaves_a_torn_maps_crack_out_and_counts_it(grid):
    phi = sphere_field(grid, (0, 0, 0), 0.4)
    x = grid.points()
    # the ball's halves pulled apart by 0.3: one layer of cells spans the gap
    torn_map = np.where(x[..., :1] > 0, x + np.array([0.3, 0.0, 0.0]), x)
    crack = np.zeros(tuple(n - 1 for n in grid.shape), bool)
    mid = int(np.searchsorted(grid.axes()[0], 0.0, side="right")) - 1
    crack[mid] = True  # the cells between x <= 0 and x > 0
    dets, torn = metrics.det_f(torn_map, grid, phi, crack)
    assert np.all(dets[torn] > 2.0) and np.allclose(dets[~torn], 1.0)
    summary = metrics.det_f_summary(dets, torn)
    assert summary["in_band"] == 1.0 and summary["max_dev"] == pytest.approx(0.0, abs=1e-12)
    assert summary["crack"] == pytest.approx(torn.mean()) and 0.0 < summary["crack"] < 0.2
    # without the crack the stretched layer counts as material
    assert metrics.det_f_summary(dets)["in_band"] < 1.0


def test_top_height_reads_the_zero_crossing_between_nodes(grid):
    from inbetween_cases import sd_box

    h = grid.spacing
    top = -0.4 + 0.3 * h
    pool = sd_box(grid.points(), (0, 0, -0.6 + 0.15 * h), (0.7, 0.7, 0.2 + 0.15 * h))
    drop = sphere_field(grid, (0, 0, 0.2), 0.15)  # above the pool: not its top
    assert metrics.top_height(np.minimum(pool, drop), grid) == pytest.approx(top, abs=1e-9)
    assert np.isnan(metrics.top_height(np.ones(grid.shape), grid))


@pytest.mark.parametrize("per_component", [True, False])
def test_part_measure_on_the_unequal_merge(per_component):
    # the unequal merge at 32^3: the total stays on its line either way; while the balls are
    # apart, each keeps its volume within 2 % with its own iso-value, and with one iso-value
    # per frame the small one loses volume and the big one gains it (the measure can fail)
    from keyframe_implicit.core import inbetween

    case = load("cases").make_case("unequal-merge", 32)
    (fa, fb), = case.features
    phi_a, phi_b = case.fields
    ib = inbetween(phi_a, phi_b, case.grid, fa, fb, volume_per_component=per_component)
    times = np.linspace(0, 1, 9)
    frames = [ib.levelset(s) for s in times]
    total = [metrics.volume(f, case.grid) for f in frames]
    assert metrics.volume_drift(total, times) < 0.005
    recs = metrics.part_volume_errors(frames, times, case.grid, phi_a, phi_b, ib.trajectory,
                                      ib.backward.trajectories)
    apart = {r["s"] for r in recs if 0 < r["s"] < 1}
    assert len(apart) >= 3  # the measure sees the balls apart before they touch
    worst = max(r["own_error"] for r in recs)
    assert (worst <= 0.02) if per_component else (worst > 0.02)
