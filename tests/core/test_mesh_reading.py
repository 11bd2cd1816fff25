"""The keyframe measure the bake and the Blender panel share (`fields.measure.read_mesh`)
against the bake's own distance grids, on generated meshes as artists leave them."""

import numpy as np
from hypothesis import HealthCheck, given, settings

from hostile_meshes import SPHERE, grid_has_inside, hostile_meshes
from keyframe_implicit.core.fields.measure import read_mesh

FIXED = settings(derandomize=True, database=None, deadline=None, max_examples=25,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@FIXED
@given(hostile_meshes())
def test_a_surface_encloses_volume_where_the_distance_grid_has_an_inside(mesh):
    v, f, what = mesh
    s = read_mesh(v, f)
    inside = grid_has_inside(v, f)
    if s.encloses_volume:
        assert inside, what
    else:  # only a sheet flat in its box gets grid nodes "inside" (a one-cell slab about it)
        lo, hi = v[np.unique(f)].min(axis=0), v[np.unique(f)].max(axis=0)
        assert not inside or np.min(hi - lo) == 0, what


def test_reading_of_the_two_sweep_cases():
    v, f = SPHERE
    upper = v[f].mean(axis=1)[:, 2] > 0
    s = read_mesh(v, np.where(upper[:, None], f[:, ::-1], f))  # the upper half wound inward
    assert s.encloses_volume and s.reoriented == int(upper.sum()) and s.loose == 0
    assert abs(s.volume - read_mesh(v, f).volume) < 1e-9
    s = read_mesh(np.concatenate([v, [[50.0, 0.0, 0.0]]]), f)  # one loose vertex far away
    assert s.encloses_volume and s.loose == 1 and abs(s.loose_reach - 49.0) < 1e-9
    assert abs(s.extent - 2.0) < 1e-9  # the faces' box, as the bake's grid spans it


def test_parts_that_cancel_only_in_sum_still_enclose_volume():
    v, f = SPHERE
    beside = read_mesh(np.concatenate([v, v + [0.5, 0, 0]]), np.concatenate([f, f[:, ::-1] + len(v)]))
    on_top = read_mesh(np.concatenate([v, v]), np.concatenate([f, f[:, ::-1] + len(v)]))
    assert beside.encloses_volume and not on_top.encloses_volume
