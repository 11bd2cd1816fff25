"""Grid fitting and the memory estimate (keyframe_implicit.core.bake.gridfit, .memory)."""

import re
import tracemalloc

import numpy as np
import pytest

from keyframe_implicit.core import Grid, MemoryLimitError, check_memory, estimate_memory, fit_grid
from keyframe_implicit.core.bake import gridfit
from keyframe_implicit.core.bake.gridfit import LATTICE_STEPS, lattice_spacing


def _on_lattice(g):
    """Whether ``g``'s origin is a whole multiple of its spacing, which is a ladder step."""
    index = g.origin / g.spacing
    step = np.log2(g.spacing) * LATTICE_STEPS
    return np.array_equal(index, np.round(index)) and step == pytest.approx(round(step), abs=1e-9)


def test_grid_holds_all_keyframes_with_padding_and_resolution_on_longest_side():
    rng = np.random.default_rng(1)
    a = rng.uniform([-1, 0, 0], [1, 0.5, 0.3], size=(50, 3))
    b = rng.uniform([0, -0.2, 0], [2.0, 0.4, 0.6], size=(40, 3))
    g = fit_grid([a, b], 30, padding_cells=3)
    pts = np.concatenate([a, b])
    lo, hi = pts.min(0), pts.max(0)
    assert g.dim == 3 and _on_lattice(g)
    # the ladder step nearest to the asked cell: within half a step (2**(1/16)) of it
    assert abs(np.log2(g.spacing / ((hi - lo).max() / 30))) <= 0.5 / LATTICE_STEPS + 1e-12
    # every point at least padding cells inside the box, at most one cell more
    assert np.all(lo - g.origin >= 3 * g.spacing - 1e-9)
    assert np.all(g.upper - hi >= 3 * g.spacing - 1e-9)
    assert np.all(lo - g.origin < 4 * g.spacing) and np.all(g.upper - hi < 4 * g.spacing)


def test_extra_points_and_2d_keyframes():
    a = np.array([[0.0, 0.0], [1.0, 0.5]])
    g = fit_grid([a], 10, padding_cells=2, extra_points=[[3.0, 0.2]])
    # the extra point widens the box, not the cells: the keyframe's side sets them
    assert g.dim == 2 and g.spacing == lattice_spacing(1.0, 10) == 2 ** (-27 / LATTICE_STEPS)
    assert g.contains(np.array([[3.0, 0.2], [0.0, 0.0]]), margin=2 * g.spacing - 1e-9).all()
    g1 = fit_grid(a, 10, padding_cells=0)  # a single array is one keyframe
    assert g1.shape == (12, 7) and np.array_equal(g1.origin, [0.0, 0.0])


def test_grids_stay_on_their_lattice_while_points_move_within_a_cell():
    """An extra point (an Empty) moved within its lattice cell, or a keyframe moved by less
    than a cell so that its box keeps to the same lattice cells, leaves the grid and the
    motion grid as they were; moved by whole cells, the grid moves by them."""
    rng = np.random.default_rng(3)
    a = rng.uniform([-1, 0, 0], [1, 0.5, 0.3], size=(50, 3))
    b = rng.uniform([0, -0.2, 0], [2.0, 0.4, 0.6], size=(40, 3))
    empty = np.array([[2.3, 0.1, 0.2]])
    g = fit_grid([a, b], 30, extra_points=empty)
    h = g.spacing
    cell = np.floor(empty / h)
    moved = (cell + rng.uniform(0.05, 0.95, size=(7, 3))) * h  # anywhere in its cell
    for e in moved:
        assert fit_grid([a, b], 30, extra_points=e[None]) == g
    lo, hi = np.concatenate([a, b, empty]).min(0), np.concatenate([a, b, empty]).max(0)
    room = np.minimum(lo - np.floor(lo / h) * h, np.ceil(hi / h) * h - hi)  # to a lattice line
    nudge = 0.9 * room.min() * np.array([1.0, -1.0, 1.0]) / np.sqrt(3)
    assert np.linalg.norm(nudge) < h
    assert fit_grid([a, b + nudge], 30, extra_points=empty) == g
    assert gridfit.motion_grid(fit_grid([a, b + nudge], 30, extra_points=empty), 30, 17) == \
        gridfit.motion_grid(g, 30, 17)
    whole = 5 * h * np.array([1.0, -2.0, 3.0])
    far = fit_grid([a + whole, b + whole], 30, extra_points=empty + whole)
    assert far.shape == g.shape and far.spacing == h
    np.testing.assert_allclose(far.origin, g.origin + whole, atol=1e-12)
    # a keyframe grown by a small fraction keeps the spacing (the ladder's step)
    assert fit_grid([a, b * 1.001], 30).spacing == fit_grid([a, b], 30).spacing


def test_motion_grid_sits_on_its_own_lattice_and_covers_the_grid():
    g = fit_grid([np.array([[0.1, 0.2, 0.3], [1.3, 0.9, 0.7]])], 24)
    mg = gridfit.motion_grid(g, 24, 10)
    assert mg.spacing == pytest.approx(g.spacing * 2.4)
    index = mg.origin / mg.spacing
    np.testing.assert_array_equal(index, np.round(index))
    assert np.all(g.origin - mg.origin >= 2 * mg.spacing - 1e-9)
    assert np.all(mg.upper - g.upper >= 2 * mg.spacing - 1e-9)


@pytest.mark.parametrize("args, kwargs, words", [
    (([np.zeros((3, 3)), np.zeros((3, 2))], 10), {}, "mix 2D and 3D"),
    (([np.array([[0, 0, 0], [1, np.nan, 0]])], 10), {}, "NaN"),
    (([np.ones((4, 3))], 10), {}, "coincide"),
    (([np.eye(3)], 1), {}, "resolution"),
    (([np.eye(3)], 10.5), {}, "resolution"),
    (([np.eye(3)], 10), {"padding_cells": -1}, "padding_cells"),
    (([], 10), {}, "no keyframe vertices"),
    (([np.zeros((3, 4))], 10), {}, r"shape \(N, 2\) or \(N, 3\)"),
])
def test_bad_requests_are_refused_with_a_reason(args, kwargs, words):
    with pytest.raises(ValueError, match=words):
        fit_grid(*args, **kwargs)


def test_estimate_grows_with_the_grid_and_adds_up():
    pts = np.array([[0, 0, 0], [1, 1, 1.0]])
    small = estimate_memory(fit_grid(pts, 16))
    big = estimate_memory(fit_grid(pts, 32))
    for est in (small, big):
        assert est["peak"] == est["process"] + est["grid_nodes"] + est["solves"]
        assert 0 < est["active_nodes"] < est["nodes"]
    ratio = big["nodes"] / small["nodes"]
    assert big["peak"] > small["peak"] and big["process"] == small["process"]
    for part in ("grid_nodes", "solves"):  # linear in the nodes at most: no factorisation
        assert 0.5 * ratio < big[part] / small[part] <= ratio * 1.01
    more = estimate_memory(fit_grid(pts, 32), material_fraction=0.8)
    assert more["solves"] > big["solves"] and more["active_nodes"] > big["active_nodes"]
    assert estimate_memory(fit_grid(pts, 32), n_keyframes=4)["peak"] > big["peak"]
    with pytest.raises(ValueError, match="material_fraction"):
        estimate_memory(fit_grid(pts, 16), material_fraction=1.5)


def test_oversized_request_fails_before_any_work_and_names_what_fits():
    pts = np.array([[0, 0, 0], [2.0, 1.0, 1.0]])
    limit = estimate_memory(fit_grid(pts, 100), material_fraction=0.3)["peak"]
    tracemalloc.start()
    try:
        with pytest.raises(MemoryLimitError) as info:
            fit_grid([pts], 2000, max_bytes=limit, material_fraction=0.3)  # ~ 2000 x 1000 x 1000 nodes
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20  # nothing of grid size was allocated
    err = info.value
    assert isinstance(err, ValueError) and err.limit == limit and err.required > limit
    fits = err.max_resolution
    assert re.search(rf"largest resolution that fits is {fits}\b", str(err))
    assert "lower the resolution" in str(err)
    assert estimate_memory(fit_grid(pts, fits), material_fraction=0.3)["peak"] <= limit
    assert estimate_memory(fit_grid(pts, fits + 1), material_fraction=0.3)["peak"] > limit
    # the limit was the estimate at resolution 100: the largest resolution on its ladder step
    assert fits >= 100 and fit_grid(pts, fits) == fit_grid(pts, 100)
    # within the limit: the grid comes back
    assert isinstance(fit_grid(pts, fits, max_bytes=limit, material_fraction=0.3), Grid)
    # nothing fits at all
    with pytest.raises(MemoryLimitError, match="raise the memory limit"):
        fit_grid(pts, 50, max_bytes=1000)
    # without a material fraction the keyframes' box gives one: a grid padded around a
    # box gets a smaller guess (and estimate) than a tight one
    loose = fit_grid(pts, 40, padding_cells=20)
    tight = fit_grid(pts, 40, padding_cells=0)
    from keyframe_implicit.core.bake.gridfit import _box_fraction
    f_loose = _box_fraction(pts.min(0), pts.max(0), loose)
    f_tight = _box_fraction(pts.min(0), pts.max(0), tight)
    assert 0 < f_loose < f_tight <= 0.5


def test_check_memory_on_a_given_grid():
    g = Grid((0, 0, 0), 0.1, (200, 100, 100))
    est = check_memory(g, 1 << 40)
    assert est["nodes"] == 2_000_000
    with pytest.raises(MemoryLimitError, match="largest that fits has") as info:
        check_memory(g, est["peak"] // 4)
    assert info.value.max_resolution < 200


_MEASURE_BAKE = r"""
import json, sys
import numpy as np
sys.path.insert(0, "tests/core")
from inbetween_cases import rotation, sphere_features, uv_sphere
from keyframe_implicit.core import Keyframe, animate, estimate_memory, mesh_to_sdf
from keyframe_implicit.core.bake.gridfit import motion_grid

def main():
    res = int(sys.argv[1])
    va, fa = uv_sphere(np.zeros(3), 0.3)
    off, R = np.array([0.4, 0.1, -0.2]), rotation([0.3, 1.0, 0.2], np.deg2rad(50))
    vb = va @ R.T + off
    pa, pb = sphere_features(np.zeros(3), 0.3, R, off)
    anim = animate([Keyframe(va, fa, 1), Keyframe(vb, fa, 9)], [(pa, pb)], resolution=res,
                   processes=2)
    with open("/proc/self/status") as fh:
        own = next(int(l.split()[1]) for l in fh if l.startswith("VmHWM")) * 1024
    frac = float(np.mean(mesh_to_sdf(va, fa, anim.grid) < 0))
    motion = motion_grid(anim.grid, res, anim.stats["motion_resolution"])
    print(json.dumps(dict(nodes=anim.grid.size, motion=anim.stats["motion_resolution"],
                          peak=own + anim.stats["helper_peak_rss_kib"] * 1024,
                          est=estimate_memory(anim.grid, material_fraction=frac,
                                              motion_grid=motion)["peak"])))

if __name__ == "__main__":
    main()
"""


@pytest.mark.heavy
def test_whole_bake_estimate_within_25_percent_of_the_measured_peak_rss():
    """A turning sphere through `animate` with its helper process, in a fresh interpreter:
    the peak resident sets of both processes against the model with the motion grid the
    bake chose, at two sizes. The model is fitted on Python 3.13 / numpy 2 to the
    benchmark's cases (benchmarks/README.md, "Scale and the memory model": 11.7 % at most
    on 21 rows). The sphere is lighter than those cases for its grid, and below 64 cells
    the two interpreters are most of the peak; with the current constants the model is
    high by 3.4 % at 72 cells (motion 51) and by 8.2 % at 88 (motion 52) on 3.13 / numpy 2."""
    import json
    import pathlib
    import subprocess
    import sys

    root = pathlib.Path(__file__).resolve().parents[2]
    rows = []
    for res in (72, 88):
        run = subprocess.run([sys.executable, "-c", _MEASURE_BAKE, str(res)], cwd=root,
                             capture_output=True, text=True, timeout=900)
        assert run.returncode == 0, run.stderr
        rows.append(json.loads(run.stdout.strip().splitlines()[-1]))
    for r in rows:
        assert abs(r["est"] - r["peak"]) <= 0.25 * r["peak"], r
    assert rows[1]["nodes"] > 1.6 * rows[0]["nodes"]
