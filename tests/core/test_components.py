"""Each component of an in-between keeps the volume of the material arriving in it
(`motion.components`, `motion.isovolume.component_iso_values`; docs/method.md, section 13)."""

import numpy as np
import pytest
from scipy import ndimage

from inbetween_cases import make_grid, sd_sphere, unequal_balls
from keyframe_implicit.core import inbetween
from keyframe_implicit.core.motion.isovolume import component_iso_values
from keyframe_implicit.core.motion.components import (_fitted_shares, component_labels,
                                                      component_volumes)

FRAMES = np.linspace(0.0, 1.0, 13)
BOUND = 0.02  # the bound: every component within 2 % of its own volume while apart


def _volumes_by_x(field, grid):
    """The volumes of ``field``'s components, ordered by their centroids' x."""
    labels, count = component_labels(field)
    x = [c[0] for c in ndimage.center_of_mass(labels > 0, labels, range(1, count + 1))]
    return component_volumes(field, grid, labels, count)[np.argsort(x)]


def _worst_part_error(ib, grid, own):
    """Largest |V_p / V_own - 1| over the frames with as many components as ``own`` (the
    keyframe whose components are apart), and how many such frames there were."""
    reference = _volumes_by_x(own, grid)
    errors = [np.abs(v / reference - 1.0).max()
              for v in (_volumes_by_x(ib.levelset(s), grid) for s in FRAMES)
              if len(v) == len(reference)]
    return max(errors), len(errors)


@pytest.fixture(scope="module")
def balls():
    return unequal_balls(40)


@pytest.mark.parametrize("direction", ["merge", "split"])
def test_unequal_parts_keep_their_own_volume_while_apart(balls, direction):
    g, phi_a, phi_b, fa, fb = balls
    if direction == "merge":
        ib, own = inbetween(phi_a, phi_b, g, fa, fb), phi_a
    else:
        ib, own = inbetween(phi_b, phi_a, g, fb, fa), phi_a
    worst, frames = _worst_part_error(ib, g, own)
    assert frames >= 4  # the components are apart for a good component of the segment
    assert worst <= BOUND, f"a component's volume is off by {worst:.1%} while apart"


def test_one_iso_value_for_the_total_fails_the_part_bound(balls):
    """The same measure fails the same bound when one iso-value holds the total only:
    the bound above is not passed vacuously."""
    g, phi_a, phi_b, fa, fb = balls
    ib = inbetween(phi_a, phi_b, g, fa, fb, volume_per_component=False)
    worst, frames = _worst_part_error(ib, g, phi_a)
    assert frames >= 4
    assert worst > 2 * BOUND


def test_component_iso_values_give_each_part_its_target_and_leave_far_nodes():
    g = make_grid(3, 40, -1.0, 1.0)
    P = g.points()
    field = np.minimum(sd_sphere(P, (-0.45, 0, 0), 0.25), sd_sphere(P, (0.4, 0, 0), 0.3))
    labels, count = component_labels(field)
    before = component_volumes(field, g, labels, count)
    targets = before * np.array([1.06, 0.96])  # one component grows, the other shrinks
    out = field.copy()
    iso_values, err = component_iso_values(out, g, labels, targets)
    after = component_volumes(out, g, labels, count)
    np.testing.assert_allclose(after, targets, rtol=2e-3)
    assert iso_values[0] > 0 > iso_values[1]  # grown outward, shrunk inward
    far = field > 6 * g.spacing
    np.testing.assert_array_equal(out[far], field[far])


def test_fitted_shares_take_both_keyframes_component_volumes_on_a_tree():
    """A merge (two components of A -> one of B): each atom's share is its A component's, whatever
    the backward map's estimate says."""
    from_a = np.array([0.26, 0.74])  # A's two components, each wholly in B's one component
    from_b = np.array([0.32, 0.68])  # B's component, shared out by a torn backward map
    share = _fitted_shares(from_a, from_b, (2, 1))
    np.testing.assert_allclose(share, from_a, atol=1e-12)
    # a split is the same tree seen from B
    np.testing.assert_allclose(_fitted_shares(from_b, from_a, (1, 2)), from_a, atol=1e-12)
