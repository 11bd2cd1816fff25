"""Parts apart in both keyframes move on their own, however close (map/parts.py)."""

import numpy as np
import pytest

from benchmark_modules import load
from keyframe_implicit.core.map.parts import part_crack, part_labels

bench = load("bench_contact")
contact = load("contact_cases")

RESOLUTION = 32
H = 1.22 / RESOLUTION  # the bake's cell: the plates' sweep is 1.22 wide


@pytest.fixture(scope="module")
def scissors():
    """The scissors at 32^3, their plates 1.5 cells apart, on one grid and on a motion
    grid whose cells are wider than the gap."""
    case = contact.scissors_case(bench.MESH_NODES, H)
    return {motion: bench.bake_and_measure(case, RESOLUTION, motion) for motion in ("full", "24")}


@pytest.mark.parametrize("motion", ["full", "24"])
def test_close_plates_follow_their_own_turns_without_extra_pieces(scissors, motion):
    row = scissors[motion]
    assert "error" not in row, row.get("error")
    # the worst frame's mean distance of a plate from its own rigid turn, in cells
    assert row["follow"] <= 0.5
    assert row["extra"] == 0 and row["bubbles"] == 0 and row["tiny"] == 0


def test_parts_are_found_only_where_both_keyframes_keep_them_apart():
    case = contact.scissors_case(65, 2 / 64)
    (fa, fb), g = case.features[0], case.grid
    a, b = case.fields
    parts = part_labels(a, b, g, fa, fb)
    assert parts is not None
    top = np.unique(parts[(a < 0) & (g.points()[..., 2] > 0)])
    bottom = np.unique(parts[(a < 0) & (g.points()[..., 2] < 0)])
    assert len(top) == len(bottom) == 1 and top[0] != bottom[0]
    crack = part_crack(parts)  # one layer of cells, in the gap
    z = g.points()[:-1, :-1, :-1, 2][crack] + g.spacing / 2
    assert np.abs(z).max() < g.spacing
    # the plates turned into one body (a merge) keep no parts apart
    one = np.minimum(b, np.abs(g.points()[..., 2]) - 0.2)
    assert part_labels(a, one, g, fa, fb) is None
