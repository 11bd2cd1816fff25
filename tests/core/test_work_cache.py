"""Work kept by content (`core.bake.cache`): a re-bake solves only what an edit changed,
counted by the map solver's calls, and gives what a bake from scratch gives."""

import dataclasses

import numpy as np
import pytest

from inbetween_cases import moving_growing_sphere
from keyframe_implicit.core import animate
from keyframe_implicit.core.bake import pipeline
from keyframe_implicit.core.bake.cache import WorkCache, content_key
from keyframe_implicit.core.bake.options import BakeOptions
from keyframe_implicit.core.map import solver

RESOLUTION = 24


@pytest.fixture
def solves(monkeypatch):
    """The map solver's calls in this process, counted."""
    calls = []
    solve = solver.solve_map

    def counted(*args, **kwargs):
        calls.append(args[3][0].tolist())  # the first feature point: which map it is
        return solve(*args, **kwargs)

    monkeypatch.setattr(solver, "solve_map", counted)
    return calls


def _bake(shift=0.0, cache=None, interpolation=None):
    keyframes, feats = moving_growing_sphere(shift, moved=(1, 0))
    return animate(keyframes, feats, resolution=RESOLUTION, key_interpolation=interpolation,
                   surfaces=False, coverage=False, cache=cache)


def test_one_empty_moved_solves_exactly_its_pairs_maps_and_bakes_as_from_scratch(solves):
    keyframes, feats = moving_growing_sphere()
    moved = 0.2 * pipeline.plan_bake(keyframes, feats, BakeOptions(resolution=RESOLUTION)).grid.spacing
    plans = [pipeline.plan_bake(*moving_growing_sphere(s, moved=(1, 0)), BakeOptions(resolution=RESOLUTION)) for s in (0, moved)]
    assert plans[0].grid == plans[1].grid  # within a cell: the lattice keeps the grid
    cache = WorkCache()
    _bake(cache=cache)
    assert len(solves) == 4  # two pairs, each both ways
    solves.clear()
    again = _bake(moved, cache)
    assert len(solves) == 2  # the moved pair's two maps, nothing else
    assert {tuple(p) for p in solves} == {tuple(feats[1][0][0] + (moved, 0, 0)),
                                          tuple(feats[1][1][0])}
    assert cache.counts["distance"] == {"hits": 3, "misses": 3}
    assert again.stats["kept"] == {"distance": 3, "maps": 1}
    solves.clear()
    fresh = _bake(moved)
    assert len(solves) == 4
    h = fresh.grid.spacing
    assert np.abs(again.vertices - fresh.vertices).max() <= 1e-6 * h


def test_interpolation_changed_solves_no_map(solves):
    cache = WorkCache()
    _bake(cache=cache)
    solves.clear()
    eased = _bake(cache=cache, interpolation=["linear", "ease", "linear"])
    assert solves == []
    fresh = _bake(interpolation=["linear", "ease", "linear"])
    assert np.abs(eased.vertices - fresh.vertices).max() <= 1e-6 * fresh.grid.spacing


def test_cache_is_bounded_in_memory_and_on_disk_and_cleared(tmp_path):
    cache = WorkCache(tmp_path / "cache", memory_bytes=3000, disk_bytes=5000)
    blocks = {content_key("maps", i): np.full(100, float(i)) for i in range(8)}  # ~900 B each
    for key, block in blocks.items():
        cache.put(key, block)
    assert cache.memory_used <= 3000 and cache.disk_used() <= 5000
    assert 0 < len(list((tmp_path / "cache").iterdir())) < 8
    last = list(blocks)[-1]
    got = cache.get(last)
    np.testing.assert_array_equal(got, blocks[last])
    got[:] = -1  # a copy: the kept result is unchanged
    np.testing.assert_array_equal(cache.get(last), blocks[last])
    other = WorkCache(tmp_path / "cache")  # another process: finds it on disk
    np.testing.assert_array_equal(other.get(last), blocks[last])
    assert cache.get(content_key("maps", "never")) is None
    assert cache.get(list(blocks)[0]) is None  # the oldest went first
    assert cache.clear() > 0
    assert cache.memory_used == 0 and cache.disk_used() == 0 and other.get(last) is not None
    assert WorkCache(tmp_path / "cache").get(last) is None
    disk_only = WorkCache(tmp_path / "cache", memory_bytes=0)  # a worker's: it bakes once
    disk_only.put(last, blocks[last])
    assert disk_only.memory_used == 0
    np.testing.assert_array_equal(disk_only.get(last), blocks[last])


def test_keys_follow_exactly_their_inputs():
    a = np.arange(6.0).reshape(2, 3)
    assert content_key("maps", a, "x") == content_key("maps", a.copy(), "x")
    assert content_key("maps", a, "x") != content_key("maps", a + 1e-12, "x")
    assert content_key("maps", a, "x") != content_key("distance", a, "x")
    assert content_key("maps", a.astype(np.float32)) != content_key("maps", a)
    # options read field by field: an array among them by its values, not its short repr
    big = np.zeros(5000)
    changed = big.copy()
    changed[2500] = 1.0
    options = BakeOptions().map
    assert content_key("maps", options) == content_key("maps", BakeOptions().map)
    assert (content_key("maps", dataclasses.replace(options, initial=big))
            != content_key("maps", dataclasses.replace(options, initial=changed)))
    assert content_key("maps", options) != content_key(
        "maps", dataclasses.replace(options, weights={**options.weights, "volume": 29.0}))
