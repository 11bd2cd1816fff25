"""Grid fitting and the memory estimate (issue 3, keyframe_implicit.core.gridfit)."""

import re
import tracemalloc

import numpy as np
import pytest

from keyframe_implicit.core import Grid, MemoryLimitError, check_memory, estimate_memory, fit_grid


def test_grid_holds_all_keyframes_with_padding_and_resolution_on_longest_side():
    rng = np.random.default_rng(1)
    a = rng.uniform([-1, 0, 0], [1, 0.5, 0.3], size=(50, 3))
    b = rng.uniform([0, -0.2, 0], [2.0, 0.4, 0.6], size=(40, 3))
    g = fit_grid([a, b], 30, padding_cells=3)
    pts = np.concatenate([a, b])
    lo, hi = pts.min(0), pts.max(0)
    assert g.dim == 3
    assert g.spacing == pytest.approx((hi - lo).max() / 30)
    # longest axis: exactly resolution + 2 * padding cells
    longest = int(np.argmax(hi - lo))
    assert g.shape[longest] - 1 == 30 + 6
    # every point at least padding cells inside the box, box centred on the points
    assert np.all(lo - g.origin >= 3 * g.spacing - 1e-9)
    assert np.all(g.upper - hi >= 3 * g.spacing - 1e-9)
    np.testing.assert_allclose((g.origin + g.upper) / 2, (lo + hi) / 2, atol=1e-12)
    # other axes: no more than one cell of slack beyond the padding
    assert np.all((g.upper - g.origin) - (hi - lo) <= (6 + 1) * g.spacing + 1e-9)


def test_extra_points_and_2d_keyframes():
    a = np.array([[0.0, 0.0], [1.0, 0.5]])
    g = fit_grid([a], 10, padding_cells=2, extra_points=[[3.0, 0.2]])
    assert g.dim == 2 and g.spacing == pytest.approx(0.3)
    assert g.contains(np.array([[3.0, 0.2], [0.0, 0.0]]), margin=2 * 0.3 - 1e-9).all()
    g1 = fit_grid(a, 10, padding_cells=0)  # a single array is one keyframe
    assert g1.shape == (11, 6)


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
        # two maps are solved at once: the solver stage counts 1.5 times (see the model)
        assert est["peak"] == est["keyframes"] + int(max(est["sdf"], 1.5 * est["solver"],
                                                         est["inbetween"]))
    ratio = big["nodes"] / small["nodes"]
    assert big["peak"] > small["peak"]
    for stage in ("keyframes", "solver"):  # array sizes: linear in the nodes at most
        assert 0.5 * ratio < big[stage] / small[stage] <= ratio * 1.01
    # the in-between stage's sparse factorisation grows faster than the grid
    assert ratio < big["inbetween"] / small["inbetween"] <= ratio ** (5 / 3) * 1.01
    more = estimate_memory(fit_grid(pts, 32), material_fraction=0.8)
    assert more["solver"] > big["solver"] and more["active_nodes"] > big["active_nodes"]
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
    assert fits in (99, 100)  # the limit was the estimate at resolution 100
    # within the limit: the grid comes back
    assert isinstance(fit_grid(pts, fits, max_bytes=limit, material_fraction=0.3), Grid)
    # nothing fits at all
    with pytest.raises(MemoryLimitError, match="raise the memory limit"):
        fit_grid(pts, 50, max_bytes=1000)
    # without a material fraction the keyframes' box gives one: a grid padded around a
    # box gets a smaller guess (and estimate) than a tight one
    loose = fit_grid(pts, 40, padding_cells=20)
    tight = fit_grid(pts, 40, padding_cells=0)
    from keyframe_implicit.core.gridfit import _box_fraction
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


_MEASURE = r"""
import json, sys, tracemalloc
import numpy as np
from keyframe_implicit.core import estimate_memory, fit_grid, solve_map

out = []
for res in (24, 40):
    c, R = np.array([0.5, 0.5, 0.5]), 0.3
    ax = np.array([1.3, 1 / np.sqrt(1.3), 1 / np.sqrt(1.3)]) * R
    g = fit_grid([np.array([c - 1.3 * R, c + 1.3 * R])], res, padding_cells=4)
    P = g.points()
    phi_a = np.linalg.norm(P - c, axis=-1) - R                    # sphere
    k0 = np.linalg.norm((P - c) / ax, axis=-1)
    k1 = np.linalg.norm((P - c) / ax ** 2, axis=-1)
    phi_b = k0 * (k0 - 1) / np.maximum(k1, 1e-12)                 # equal-volume ellipsoid
    dirs = np.vstack([np.eye(3), -np.eye(3)])
    tracemalloc.start()
    solve_map(phi_a, phi_b, g, c + R * dirs, c + ax * dirs)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    est = estimate_memory(g, material_fraction=float(np.mean(phi_a < 0)))
    out.append(dict(nodes=g.size, peak=peak, solver=est["solver"]))
print(json.dumps(out))
"""


def test_solver_estimate_within_30_percent_of_measured_peak_at_two_sizes():
    """The memory model predicts solve_map's peak (tracemalloc, fresh process) at 33^3 and 49^3."""
    import json
    import pathlib
    import subprocess
    import sys

    root = pathlib.Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", _MEASURE], cwd=root, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    rows = json.loads(run.stdout.strip().splitlines()[-1])
    assert [r["nodes"] for r in rows] == [33 ** 3, 49 ** 3]
    for r in rows:
        assert abs(r["solver"] - r["peak"]) <= 0.3 * r["peak"], r
    assert rows[1]["peak"] > 1.5 * rows[0]["peak"]  # the two sizes really differ


_MEASURE_BAKE = r"""
import json, sys, tracemalloc
import numpy as np
sys.path.insert(0, "tests/core")
from test_pipeline import _sphere_features, rotation, uv_sphere
from keyframe_implicit.core import Keyframe, animate, estimate_memory, mesh_to_sdf

va, fa = uv_sphere(np.zeros(3), 0.3)
off, R = np.array([0.4, 0.1, -0.2]), rotation([0.3, 1.0, 0.2], np.deg2rad(50))
vb = va @ R.T + off
pa, pb = _sphere_features(np.zeros(3), 0.3, R, off)
out = []
for res in (32, 48):
    tracemalloc.start()
    anim = animate([Keyframe(va, fa, 1), Keyframe(vb, fa, 5)], [(pa, pb)], resolution=res)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    frac = float(np.mean(mesh_to_sdf(va, fa, anim.grid) < 0))
    out.append(dict(nodes=anim.grid.size, peak=peak,
                    est=estimate_memory(anim.grid, material_fraction=frac)["peak"]))
print(json.dumps(out))
"""


def test_whole_bake_estimate_within_30_percent_of_measured_animate_peak():
    """Two keyframes through `animate` (distance grids, map, in-betweens, template) at two sizes."""
    import json
    import pathlib
    import subprocess
    import sys

    root = pathlib.Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", _MEASURE_BAKE], cwd=root, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    rows = json.loads(run.stdout.strip().splitlines()[-1])
    for r in rows:
        assert abs(r["est"] - r["peak"]) <= 0.3 * r["peak"], r
    assert rows[1]["nodes"] > 1.5 * rows[0]["nodes"]
