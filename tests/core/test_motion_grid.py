"""Maps and trajectories on a coarser motion grid, fields at full resolution (docs/method.md,
section 11)."""

import numpy as np
import pytest

from inbetween_cases import (make_grid, rigid_case, rigid_expected, sd_box, sd_sphere,
                             turning_sphere)
from keyframe_implicit.core import Grid, Inbetween, Keyframe, animate, extract_surface, inbetween
from keyframe_implicit.core.bake import gridfit, pipeline


def motion_grid(grid, factor):
    """A motion grid with cells ``factor`` times the surface grid's, covering its box."""
    n = max(grid.shape) - 1
    return gridfit.motion_grid(grid, n, n / factor)


def test_a_motion_grid_equal_to_the_surface_grid_gives_the_one_grid_result():
    """The paths read from a motion grid that is the surface grid itself are the surface
    nodes' own paths: the in-betweens are those of the one-grid form, to 1e-6 h."""
    grid, phi_a, phi_b, mapped, _ = rigid_case(n=28)
    one = Inbetween.from_map(phi_a, phi_b, grid, mapped)
    read = Inbetween.from_map(phi_a, phi_b, grid, mapped, motion_grid=grid)
    for s in (0.0, 0.3, 0.5, 1.0):
        a, b = one.levelset(s), read.levelset(s)
        near = np.abs(a) < 3 * grid.spacing
        assert np.abs(a - b)[near].max() <= 1e-6 * grid.spacing, s


def test_motion_resolution_equal_to_resolution_is_the_one_grid_bake():
    kfs, feats = turning_sphere()
    assert gridfit.motion_grid(Grid((0, 0, 0), 0.1, (30, 30, 30)), 24, 24) is None
    full = animate(kfs, feats, resolution=20, motion_resolution=20, surfaces=False)
    assert full.stats["motion_resolution"] == 20 and "motion_grid_shape" not in full.stats
    coarse = animate(kfs, feats, resolution=20, motion_resolution=10, surfaces=False)
    assert coarse.stats["motion_grid_shape"] < full.stats["grid_shape"]
    assert not np.allclose(coarse.vertices, full.vertices)  # the motion grid was used


def test_rigid_l_turned_120_degrees_stays_rigid_on_a_motion_grid():
    """Surface 64, motion 24: the displacement of a rotation is affine, which multilinear
    reads reproduce, so the turned L stays within 0.1 h of the exact solid."""
    grid, phi_a, phi_b, _, info = rigid_case(n=65, angle=2 * np.pi / 3)
    mg = gridfit.motion_grid(grid, 64, 24)
    c = info["centroid"]
    mapped = c + info["t"] + (mg.points() - c) @ info["R"].T
    ib = Inbetween.from_map(phi_a, phi_b, grid, mapped, motion_grid=mg)
    for s in (0.25, 0.5, 0.75):
        V, _ = extract_surface(ib.levelset(s), grid)
        assert np.abs(rigid_expected(V, s, info)).mean() <= 0.1 * grid.spacing, s


@pytest.mark.parametrize("factor", [1.5, 2.0, 3.0])
def test_feature_points_land_exactly_on_any_motion_grid(factor):
    grid = make_grid(3, 33)
    x = grid.points()
    phi_a = sd_sphere(x, (-0.3, 0.0, 0.0), 0.45)
    phi_b = sd_sphere(x, (0.3, 0.1, 0.0), 0.45)
    fa = np.array([[-0.3, 0.0, 0.3], [-0.3, 0.3, 0.0], [0.0, 0.0, 0.0], [-0.6, 0.0, 0.0]])
    fb = fa + (0.6, 0.1, 0.0) + np.array([[0.05, 0, 0], [0, 0.04, 0], [0, 0, 0.03], [0, 0, 0]])
    ib = inbetween(phi_a, phi_b, grid, fa, fb, motion_grid=motion_grid(grid, factor),
                   max_iterations=4)
    assert np.abs(ib.trajectory(fa, 1.0) - fb).max() <= 1e-6 * grid.spacing
    assert np.abs(ib.mapped.reshape(-1, 3)[0]).max() < np.inf  # the surface grid's map exists


def test_detail_finer_than_the_motion_grid_travels_at_full_resolution():
    """Bumps of 0.3 h at a 2 h wavelength, on a body moved by a translation solved on a
    motion grid of 3 h cells (too coarse to hold them): half-way the field is the bumpy
    keyframe moved half-way, to well under the bumps' size. (Half the translation is a
    whole number of cells across the bumps, where a 2 h wave is all a grid can hold.)"""
    grid = make_grid(3, 49)
    h = grid.spacing
    shift = np.array([8 * h, -4 * h, 0.13])

    def bumpy(p):
        wave = 0.3 * h * np.cos(np.pi * (p[..., 0] + 1.2) / h) * np.cos(np.pi * (p[..., 1] + 1.2) / h)
        return sd_sphere(p, (0.0, 0.0, 0.0), 0.5) + wave

    x = grid.points()
    phi_a, phi_b = bumpy(x), bumpy(x - shift)
    mg = motion_grid(grid, 3.0)
    ib = Inbetween.from_map(phi_a, phi_b, grid, mg.points() + shift, motion_grid=mg)
    half = ib.levelset(0.5)
    expected = bumpy(x - shift / 2)
    near = np.abs(expected) < h
    assert np.abs(half - expected)[near].max() <= 0.1 * h
    # the bumps are there: the smooth sphere is farther from the half-way field than they are
    smooth = sd_sphere(x - shift / 2, (0.0, 0.0, 0.0), 0.5)
    assert np.abs(half - smooth)[near].max() >= 0.25 * h


@pytest.mark.parametrize("motion, words", [(4, "below 8"), (7, "below 8"), (21, "above the Resolution 20"),
                                           (2.5, "whole number")])
def test_a_motion_resolution_the_bake_cannot_use_is_refused_before_any_work(monkeypatch, motion,
                                                                            words):
    def no_work(*args, **kwargs):
        raise AssertionError("the distance grids were started")

    monkeypatch.setattr(pipeline, "_distance_grids", no_work)
    kfs, feats = turning_sphere()
    with pytest.raises(ValueError, match=words):
        animate(kfs, feats, resolution=20, motion_resolution=motion)


def test_automatic_motion_resolution_follows_the_budget():
    grid = Grid((0.0, 0.0, 0.0), 1.0, (137, 137, 109))
    small = gridfit.auto_motion_resolution(24, 0.2, Grid((0.0, 0.0, 0.0), 1.0, (33, 33, 29)))
    assert small == 24  # a small bake keeps one grid
    sparse = gridfit.auto_motion_resolution(128, 0.01, grid)  # the budget decides
    assert 64 < sparse < 128
    nodes = 0.01 * grid.size * (sparse / 128) ** 3
    assert 0.8 * gridfit.MOTION_NODES <= nodes <= 1.25 * gridfit.MOTION_NODES
    dense = gridfit.auto_motion_resolution(128, 0.3, grid)  # never coarser than half
    assert dense == 128 // gridfit.MAX_COARSENING


def _ball_into_torus(grid):
    """A ball whose middle opens into a torus of its volume (major radius 0.3, tube 0.12),
    six feature points on a ring going to the tube's centre line."""
    x = grid.points()
    major, tube = 0.3, 0.12
    ball = (1.5 * np.pi * major * tube ** 2) ** (1 / 3)
    torus = np.hypot(np.hypot(x[..., 0], x[..., 1]) - major, x[..., 2]) - tube
    angle = np.arange(6) * np.pi / 3
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(6)], axis=1)
    return [sd_sphere(x, (0, 0, 0), ball), torus], [(0.16 * ring, major * ring)]


def _two_plates(grid):
    """Two plates 1.2 x 0.6 x 0.1, 0.06 apart, each turned a quarter about z."""
    x = grid.points()
    half, z = np.array([0.6, 0.3, 0.05]), 0.08

    def plates(h):
        return np.minimum(sd_box(x, (0, 0, z), h), sd_box(x, (0, 0, -z), h))

    fa = np.array([[0.45, 0, z], [-0.45, 0, z], [0.45, 0, -z], [-0.45, 0, -z]])
    return [plates(half), plates(half[[1, 0, 2]])], [(fa, fa[:, [1, 0, 2]])]


@pytest.mark.parametrize("scene, resolution", [(_ball_into_torus, 48), (_two_plates, 58)])
def test_the_automatic_motion_grid_never_has_more_nodes_than_the_surface_grid(scene, resolution):
    """The motion grid pads the surface grid's box with cells of its own: a Motion Resolution
    just below Resolution, or a flat box, would give a motion grid larger than the surface
    grid (the ball opening into a torus at 48 would pick 46, a 61x61x45 motion grid against
    59x59x41; the two plates at 58 would pick 52, 73x73x25 against 75x75x23). The bake keeps
    one grid there."""
    grid = make_grid(3, 40)
    fields, feats = scene(grid)
    kfs = [Keyframe(*extract_surface(f, grid), 1 + 24 * k) for k, f in enumerate(fields)]
    meshes = [pipeline.checked_mesh(k, kf) for k, kf in enumerate(kfs)]
    _, m, mg = pipeline._bake_grid(kfs, meshes, feats, None, resolution, None, 4, None)
    assert m == resolution and mg is None


@pytest.mark.parametrize("height", [1.0, 0.6, 0.25])
def test_every_automatic_motion_grid_is_smaller_than_its_surface_grid(height):
    """Over resolutions and material shares, the automatic Motion Resolution gives one grid
    or a motion grid with fewer nodes than the surface grid; and it still coarsens where
    the budget asks (a motion grid is kept somewhere in the sweep)."""
    box = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, height]])
    separate = 0
    for resolution in range(25, 129, 3):
        grid = gridfit.fit_grid(box, resolution)
        for fraction in (0.02, 0.05, 0.1, 0.2, 0.4):
            m = gridfit.auto_motion_resolution(resolution, fraction, grid)
            mg = gridfit.motion_grid(grid, resolution, m)
            assert mg is None or mg.size < grid.size, (resolution, fraction, m)
            separate += mg is not None
    assert separate > 0


def test_the_preview_keeps_one_grid_where_its_motion_grid_would_be_larger():
    """At a bake Resolution of 18 the preview's 16-cell motion grid would be padded past the
    18-cell surface grid: the preview keeps one grid, as the bake's automatic rule does."""
    from keyframe_implicit.core.bake.options import BakeOptions
    from keyframe_implicit.core.bake.preview import preview_grids

    kfs, feats = turning_sphere()
    plan = pipeline.plan_bake(kfs, feats, BakeOptions(resolution=18), grid_rule=preview_grids)
    assert plan.resolution == 18
    assert plan.stats["motion_resolution"] == 18 and plan.motion_grid is None
    assert gridfit.motion_grid(plan.grid, 18, 16).size > plan.grid.size  # what it would be


def test_features_closer_than_a_motion_cell_raise_the_automatic_motion_resolution():
    """Two features 1.3 surface cells apart whose partners are far apart would share a
    motion cell: the automatic choice goes finer than it would without them; a given
    Motion Resolution is refused."""
    kfs, feats = turning_sphere()
    meshes = [pipeline.checked_mesh(k, kf) for k, kf in enumerate(kfs)]
    _, plain, plain_grid = pipeline._bake_grid(kfs, meshes, feats, None, 64, None, 4, None)
    fa, fb = (np.array(f, dtype=float) for f in feats[0])
    fa[1] = fa[0] + 0.015 * (fa[1] - fa[0]) / np.linalg.norm(fa[1] - fa[0])
    close = [(fa, fb)]
    grid, m, mg = pipeline._bake_grid(kfs, meshes, close, None, 64, None, 4, None)
    assert plain_grid is not None and plain_grid.spacing > 0.015  # they would share a cell
    assert m > plain and (mg is None or mg.spacing <= 0.015)
    with pytest.raises(ValueError, match="motion grid cell.*Motion Resolution"):
        pipeline._bake_grid(kfs, meshes, close, None, 64, 8, 4, None)


def test_the_memory_estimate_counts_the_motion_grid():
    from keyframe_implicit.core import estimate_memory

    grid = Grid((0.0, 0.0, 0.0), 1.0 / 128, (137, 137, 137))
    one = estimate_memory(grid, material_fraction=0.2)
    mg = gridfit.motion_grid(grid, 128, 48)
    two = estimate_memory(grid, material_fraction=0.2, motion_grid=mg)
    assert one["band_nodes"] == two["band_nodes"]  # the band is the surface grid's
    assert 0.1 * (48 / 128) ** 3 < two["active_nodes"] / one["active_nodes"] < 0.3
    assert two["peak"] < one["peak"] and two["grid_nodes"] == one["grid_nodes"]
