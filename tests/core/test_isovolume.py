"""The iso-value that gives an in-between its volume (`isovolume`)."""

import numpy as np
import pytest

from inbetween_cases import sphere_field
from keyframe_implicit.core import Grid
from keyframe_implicit.core.motion.isovolume import _gradient_norm, volume_iso_value
from keyframe_implicit.core.surface.extract import enclosed_volume


@pytest.mark.parametrize("shape", [(7, 2, 5), (9, 6, 8), (11, 4)])
def test_gradient_at_nodes_is_numpys_gradient_there(shape):
    f = np.random.default_rng(2).standard_normal(shape)
    grid = Grid(origin=(0.0,) * len(shape), spacing=0.3, shape=shape)
    want = np.sqrt(sum(g * g for g in np.gradient(f, grid.spacing))).reshape(-1)
    nodes = np.arange(f.size)[::2]  # inside and on every face
    np.testing.assert_array_equal(_gradient_norm(f, grid, nodes), want[nodes])


def test_offset_gives_the_volume_of_the_sphere_it_asks_for():
    g = Grid(origin=(-1.0, -1.0, -1.0), spacing=2.0 / 47, shape=(48, 48, 48))
    f = sphere_field(g, (0, 0, 0), 0.5)
    v = enclosed_volume(f, g)
    grown = enclosed_volume(f - 0.03, g)  # the surface 0.03 further out: about 0.7 cells
    iso_value, err = volume_iso_value(f, g, grown)
    assert abs(err) <= 1e-3
    assert abs(iso_value - 0.03) < 0.1 * g.spacing
    assert volume_iso_value(f, g, v) == (0.0, 0.0)


def test_a_truncated_fields_plateau_is_not_read_and_gives_the_same_offset(monkeypatch):
    """A two-sided in-between is truncated a few cells out (the value where no transport
    reached, 1.9 cells in the benchmark's morph), under the search's reach: its plateau is
    outside at any shift below it, so only the nodes under it are read, and the offset is
    the one of the untruncated field."""
    from keyframe_implicit.core.motion import isovolume

    g = Grid(origin=(-1.0, -1.0, -1.0), spacing=2.0 / 47, shape=(48, 48, 48))
    f = sphere_field(g, (0, 0, 0), 0.5)
    cut = np.minimum(f, 1.9 * g.spacing)
    target = enclosed_volume(f - 0.03, g)
    read = []
    real = isovolume._gradient_norm
    monkeypatch.setattr(isovolume, "_gradient_norm",
                        lambda field, grid, nodes: read.append(len(nodes)) or real(field, grid, nodes))
    iso_value_cut, err_cut = volume_iso_value(cut, g, target)
    assert sum(read) == np.count_nonzero((cut < cut.max()) & (cut > -5 * g.spacing)) < 0.1 * cut.size
    iso_value, err = volume_iso_value(f, g, target)
    assert abs(err_cut) <= 1e-3 and abs(iso_value_cut - iso_value) < 0.01 * g.spacing
    # a volume only a shift past the plateau could give: the shift stops half a cell under it
    huge = enclosed_volume(f - 2.5 * g.spacing, g)
    iso_value_far, _ = volume_iso_value(cut, g, huge)
    assert iso_value_far <= 1.4 * g.spacing + 1e-12
