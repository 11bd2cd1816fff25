"""Merges, splits and morphs through the two-sided in-betweens (docs/method.md, section 8).

The benchmark's own cases (benchmarks/cases.py), solved end to end with
`inbetween`: the volume of every frame's surface stays on the linear path
between the keyframes' volumes, topology changes exactly once, the ends are
the keyframes, and neither map folds.
"""

import functools

import numpy as np
import pytest
from scipy import ndimage

from benchmark_modules import load
from keyframe_implicit.core import Inbetween, inbetween
from keyframe_implicit.core.surface.extract import enclosed_volume

cases = load("cases")
TIMES = np.linspace(0.0, 1.0, 9)


def components(field):
    return ndimage.label(field < 0)[1]


def volume_drift(ib, times=TIMES):
    """max over frames of |V(s) - V_lin(s)| / V_lin(s), volumes of the surfaces."""
    g = ib.grid
    vols = np.array([enclosed_volume(ib.levelset(s), g) for s in times])
    lin = (1 - times) * vols[0] + times * vols[-1]
    return float(np.max(np.abs(vols - lin) / lin))


SIZES = {"merge": 52, "split": 40, "morph": 40}


@functools.lru_cache(maxsize=None)
def solve(name):
    case = cases.make_case(name, SIZES[name])
    (fa, fb), = case.features
    return case, inbetween(case.fields[0], case.fields[1], case.grid, fa, fb)


@pytest.fixture(params=sorted(SIZES))
def solved(request):
    return (request.param,) + solve(request.param)


def test_the_pinned_merge_is_wide():
    # the hard merge: the balls start at least 6 cells apart
    case, _ = solve("merge")
    assert case.info["gap"] >= 6 * case.grid.spacing


def test_volume_stays_on_its_linear_path(solved):
    name, case, ib = solved
    assert volume_drift(ib) <= 0.02, name


def test_topology_changes_exactly_once(solved):
    name, case, ib = solved
    counts = [components(ib.levelset(s)) for s in TIMES]
    start, end = case.expected_components
    assert counts[0] == start and counts[-1] == end
    assert set(counts) <= {start, end}, counts  # no spurious piece on any frame
    changes = np.count_nonzero(np.diff(counts))
    assert changes == (0 if start == end else 1), counts


def test_ends_are_the_keyframes(solved):
    name, case, ib = solved
    h = case.grid.spacing
    assert np.abs(ib.levelset(0.0) - case.fields[0]).max() <= 1e-6 * h
    assert np.abs(ib.levelset(1.0) - case.fields[1]).max() <= 1e-6 * h
    # and the frames next to them are close to them (the blend is continuous at the ends),
    # up to the truncation of the carried fields
    near = 1e-3
    for s, field in ((near, case.fields[0]), (1 - near, case.fields[1])):
        ls = ib.levelset(s)
        surface = np.abs(field) < min(2 * h, ib.outside_value - 0.1 * h)
        assert np.count_nonzero(surface) > 1000
        assert np.abs(ls - field)[surface].max() <= 0.1 * h


def test_neither_map_folds(solved):
    name, case, ib = solved
    assert ib.stats["map"]["min_det"] >= 0.2 - 1e-9
    assert ib.stats["map_back"]["min_det"] >= 0.2 - 1e-9


def test_the_one_sided_form_swells_the_merge():
    # the failure the two-sided transport removes: the volume check must be able to see it
    case, ib = solve("merge")
    one = Inbetween.from_map(case.fields[0], case.fields[1], case.grid, ib.mapped,
                             transport="one-sided")
    assert volume_drift(one) > 0.1
