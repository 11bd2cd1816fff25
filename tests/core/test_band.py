"""`motion.band`: the frame loop on a narrow band gives the whole region's frames."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from inbetween_cases import bend_case, make_grid, merge_case, rotation, sd_sphere
from keyframe_implicit.core import Inbetween, extract_surface
from keyframe_implicit.core.motion.band import inside
from keyframe_implicit.core.surface.extract import enclosed_volume



def ball_case(n=32, radius=0.55):
    """A ball some eight cells across turned by 60 degrees about an axis off its centre:
    most of its material lies deeper than a thin band."""
    grid = make_grid(3, n)
    x = grid.points()
    R, pivot = rotation((1.0, 1.0, 0.0), np.pi / 3), np.array([0.3, -0.2, 0.0])
    mapped = pivot + (x - pivot) @ R.T
    centre = np.array([-0.3, 0.1, 0.05])
    return (grid, sd_sphere(x, centre, radius),
            sd_sphere(x, pivot + R @ (centre - pivot), radius), mapped, None)


CASES = {
    "merge": lambda: merge_case(d=3, n=36, gap=0.12, overlap=0.04),
    "bend": lambda: bend_case(d=3, n=32, radius=0.22),
    "ball": ball_case,
}


def band_and_whole(name, **options):
    """The case's in-betweens read on a band 1.5 cells deep, and on the whole region."""
    grid, phi_a, phi_b, mapped, _ = CASES[name]()
    return grid, [Inbetween.from_map(phi_a, phi_b, grid, mapped, band_cells=cells, **options)
                  for cells in (1.5, np.inf)]


def surface_gap(a, b, grid):
    """Mean and largest distance between the zero sets of two fields, in cells."""
    va, vb = extract_surface(a, grid)[0], extract_surface(b, grid)[0]
    d = np.concatenate([cKDTree(vb).query(va)[0], cKDTree(va).query(vb)[0]]) / grid.spacing
    return d.mean(), d.max()


@pytest.mark.parametrize("name, tension", [("merge", 0.0), ("merge", 1.0), ("bend", 1.0),
                                           ("ball", 1.0)])
def test_the_band_frames_are_the_whole_regions(name, tension):
    grid, (band, whole) = band_and_whole(name, surface_tension=tension)
    for s in (0.25, 0.5, 0.75):
        mean, largest = surface_gap(band.levelset(s), whole.levelset(s), grid)
        assert mean < 0.1 and largest < 0.5, (s, mean, largest)
    assert not band.stats.get("band_widened")  # the band itself made these frames
    if name == "merge" and tension > 0:  # parts that meet: the band reaches the tension's
        assert max(band.stats["deep_nodes"].values()) == 0  # blur, deeper than the balls
    else:
        assert min(band.stats["deep_nodes"].values()) > 0  # deep material was not read


def test_a_surface_shifted_under_the_band_widens_it_and_is_the_whole_regions():
    grid, (band, whole) = band_and_whole("ball")
    volumes = (0.4 * enclosed_volume(band.phi_a, grid), 0.4 * enclosed_volume(band.phi_b, grid))
    for ib in (band, whole):  # a target that pulls every frame's surface cells inward
        ib.hold_volumes(volumes)
    for s in (0.3, 0.6):
        mean, largest = surface_gap(band.levelset(s), whole.levelset(s), grid)
        assert mean < 1e-9 and largest < 1e-9, (s, mean, largest)
    assert band.stats["band_widened"] == [0.3, 0.6]


def test_inside_fills_the_pockets_a_band_encloses_on_its_negative_side():
    grid = make_grid(3, 41)
    h = grid.spacing
    r = np.linalg.norm(grid.points(), axis=-1)
    field = np.abs(r - 0.6) - 0.3  # a ball with a hollow core of radius 0.3
    carried = np.where(np.abs(field) < 2 * h, field, np.nan).reshape(-1)
    got = inside(carried, grid).reshape(grid.shape)
    unreached = np.isnan(carried).reshape(grid.shape)
    np.testing.assert_array_equal(got, unreached & (field < 0))  # the shell, not the hollow
    assert got.any() and (unreached & (r < 0.3)).any()
