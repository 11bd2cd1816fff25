"""`motion.tension.fill_creases`: a crease where parts meet fills, nothing else moves."""

import numpy as np

from benchmark_modules import load
from keyframe_implicit.core import Grid
from keyframe_implicit.core.motion.components import component_labels
from keyframe_implicit.core.motion.tension import fill_creases
from keyframe_implicit.core.surface.extract import extract_surface

cm = load("contact_metrics")

H = 0.05
GRID = Grid(origin=(-1.0, -1.0, -1.0), spacing=H, shape=(41, 41, 41))


W = 2 * H  # the transports' truncation: far outside, the field is W


def ball(centre, radius):
    return np.minimum(np.linalg.norm(GRID.points() - np.asarray(centre), axis=-1) - radius, W)


def meeting_of(a, b, reach=W - H / 2):
    """Where both fields are under ``reach``: where the two parts meet."""
    return (a < reach) & (b < reach)


def test_no_tension_or_no_meeting_leaves_the_field_as_it_is():
    a, b = ball((-0.3, 0, 0), 0.35), ball((0.3, 0, 0), 0.35)
    field = np.minimum(a, b)
    assert fill_creases(field, meeting_of(a, b), GRID, 0.0) is field
    assert fill_creases(field, None, GRID, 1.0) is field
    assert fill_creases(field, np.zeros(field.shape, bool), GRID, 1.0) is field


def test_the_crease_where_two_balls_meet_rounds_and_a_ball_elsewhere_stays():
    a, b = ball((-0.3, 0, -0.3), 0.35), ball((0.3, 0, -0.3), 0.35)
    far = ball((0.0, 0.0, 0.6), 0.25)
    field = np.minimum(np.minimum(a, b), far)
    filled = fill_creases(field, meeting_of(a, b), GRID, 1.0)
    before = cm.neck_fold(*extract_surface(field, GRID), H)[1]
    after = cm.neck_fold(*extract_surface(filled, GRID), H)[1]
    assert before > 90.0 and after < 45.0, (before, after)
    assert np.all(filled <= field)  # only ever adds material
    near_far = far < 0.1
    np.testing.assert_array_equal(filled[near_far], field[near_far])
    assert fill_creases(field, meeting_of(a, b), GRID, 1.0, weight=0.0) is field


def test_parts_that_have_not_met_are_not_joined():
    a, b = ball((-0.3, 0, 0), 0.27), ball((0.3, 0, 0), 0.27)  # a gap of 1.2 cells
    field = np.minimum(a, b)
    filled = fill_creases(field, meeting_of(a, b), GRID, 1.0)
    assert component_labels(filled)[1] == 2
    near = np.abs(field) < 4 * H  # the surfaces and a few cells around them stay
    np.testing.assert_array_equal(filled[near], field[near])
