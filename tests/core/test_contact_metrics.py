"""The contact measures of benchmarks/contact_metrics.py on shapes whose answer is known,
and the neck measure on today's merge, which it must find creased."""

import numpy as np
import pytest

from benchmark_modules import load
from keyframe_implicit.core import Grid, animate_chain
from keyframe_implicit.core.surface.extract import extract_surface

cm = load("contact_metrics")
cases = load("cases")

H = 0.05
GRID = Grid(origin=(-1.0, -1.0, -1.0), spacing=H, shape=(41, 41, 41))


def box_field(centre, half, grid=GRID):
    return cases.sd_box(grid.points(), centre, half)


def ball_field(centre, radius, grid=GRID):
    return np.linalg.norm(grid.points() - np.asarray(centre), axis=-1) - radius


def cube(centre=(0.0, 0.0, 0.0), side=1.0, inward=False):
    """A closed cube of 12 triangles, normals outward (or inward)."""
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    faces = faces[:, ::-1] if inward else faces
    return (corners - 0.5) * side + np.asarray(centre), faces


def corner_of_a_room():
    """A floor (z = 0, x in [0, 1]) and a wall (x = 0, z in [0, 1]) meeting at a concave
    right angle along y, normals into the room (the material below and behind)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [0, 1, 1]], float)
    floor = [(0, 1, 2), (0, 2, 3)]  # normal +z
    wall = [(0, 3, 5), (0, 5, 4)]  # normal +x
    return v, np.array(floor + wall)


def test_a_concave_right_angle_folds_90_degrees():
    v, f = corner_of_a_room()
    folds = cm.fold_angles(v, f)
    assert folds.shape == (1,) and folds[0] == pytest.approx(90.0)
    # the same edge seen from the other side is convex: no concave fold
    assert cm.fold_angles(v, f[:, ::-1]).size == 0
    assert cm.neck_fold(v, f, H) == pytest.approx((90.0, 90.0))


def test_a_cube_has_no_concave_fold():
    v, f = cube()
    assert cm.fold_angles(v, f).size == 0
    assert cm.neck_fold(v, f, H) == (0.0, 0.0)


def test_where_two_balls_meet_the_fold_is_sharp_and_a_ball_is_smooth():
    crease = np.minimum(ball_field((-0.25, 0, 0), 0.3), ball_field((0.25, 0, 0), 0.3))
    assert cm.neck_fold(*extract_surface(crease, GRID), H)[0] > 90.0
    assert cm.neck_fold(*extract_surface(ball_field((0, 0, 0), 0.4), GRID), H)[1] < 30.0


def test_pieces_count_parts_bubbles_and_holes():
    outer, outer_f = cube(side=1.0)
    inner, inner_f = cube(side=0.5, inward=True)
    far, far_f = cube(centre=(3, 0, 0), side=0.5)
    v = np.vstack([outer, inner, far])
    f = np.vstack([outer_f, inner_f + 8, far_f + 16])
    pieces = cm.mesh_pieces(v, f)
    assert len(pieces.outer) == 2 and len(pieces.bubbles) == 1
    assert np.sort(pieces.volumes) == pytest.approx([-0.125, 0.125, 1.0])
    torus = np.hypot(np.hypot(GRID.points()[..., 0], GRID.points()[..., 1]) - 0.5,
                     GRID.points()[..., 2]) - 0.2
    assert cm.mesh_pieces(*extract_surface(torus, GRID)).genus.tolist() == [1]
    assert cm.mesh_pieces(outer, outer_f).genus.tolist() == [0]


def test_contact_is_the_first_frame_within_a_cell():
    frames = []
    for gap in (4.0, 2.0, 0.8, 0.0):  # in cells; the last one merged
        x = 0.3 + gap * H / 2
        field = np.minimum(ball_field((-x, 0, 0), 0.3), ball_field((x, 0, 0), 0.3))
        frames.append(extract_surface(field, GRID))
    assert cm.contact_frame(frames, 2, H) == 2
    assert cm.contact_frame(frames[:2], 2, H) is None


def test_a_rigid_path_turns_at_constant_speed():
    a = np.array([[0.5, 0, 0], [-0.5, 0, 0], [0, 0.2, 0], [0, -0.2, 0.1]])
    turn = cases.rotation((0, 0, 1), np.pi / 2)
    motion, miss = cm.rigid_path(a, a @ turn.T + [0.1, 0, 0])
    R, t = motion(0.5)
    assert miss < 1e-12
    assert R == pytest.approx(cases.rotation((0, 0, 1), np.pi / 4))
    centroid = a.mean(axis=0)
    assert R @ centroid + t == pytest.approx(centroid + [0.05, 0, 0])
    assert cm.rigid_path(a, 1.5 * a)[1] > 0.1  # a stretch is no rigid motion


POOL = ((0.0, 0.0, -0.5), (0.7, 0.7, 0.2))  # top at z = -0.3
DROP = ((0.0, 0.0, 0.3), 0.2)


def _pool_and_drop(dent, where=(0.0, 0.0), drop_z=0.3):
    """The pool with its top lowered by ``dent`` within 0.1 of ``where``, and the drop."""
    v, f = extract_surface(np.minimum(box_field(*POOL), ball_field((0, 0, drop_z), DROP[1])), GRID)
    top = (np.abs(v[:, 2] + 0.3) < 1e-6) & (np.hypot(v[:, 0] - where[0], v[:, 1] - where[1]) < 0.1)
    v = v.copy()
    v[top, 2] -= dent
    return v, f


def test_pre_contact_movement_reads_a_dent_under_the_drop_only():
    phi_a = np.minimum(box_field(*POOL), ball_field(*DROP))
    fields, centroids = cm.part_fields(phi_a, GRID)
    pool = int(np.argmin(centroids[:, 2]))
    still = lambda s: (np.eye(3), np.zeros(3))  # noqa: E731
    paths = [still if k == pool else None for k in range(2)]
    carried = [lambda s, c=c: c for c in centroids]
    reaches = [DROP[1] + 2 * H] * 2
    dented = [_pool_and_drop(0.0), _pool_and_drop(0.6 * H)]
    worst, follow = cm.pre_contact_movement(dented, [0.0, 0.5], GRID, fields, centroids, paths,
                                            carried, H, reaches)
    assert worst[pool] == pytest.approx(0.6, abs=0.01)
    assert np.isnan(worst[1 - pool]) and follow[pool] < 0.1
    # the same dent in a far corner of the pool is not under the drop
    far = [_pool_and_drop(0.6 * H, where=(0.5, 0.5))]
    worst, _ = cm.pre_contact_movement(far, [0.5], GRID, fields, centroids, paths, carried, H,
                                       reaches)
    assert worst[pool] == pytest.approx(0.0, abs=0.01)


def test_stillness_reads_how_far_an_agreed_surface_moved():
    phi_a = np.minimum(box_field(*POOL), ball_field(*DROP))
    phi_b = np.minimum(box_field(*POOL), ball_field((0, 0, -0.2), 0.2))
    features = (np.array([[0.0, 0.0, 0.3], [0.5, 0.5, -0.5]]), np.array([[0.0, 0.0, -0.2],
                                                                         [0.5, 0.5, -0.5]]))
    v_a, f_a = extract_surface(phi_a, GRID)
    pts = cm.agreement_points(v_a, phi_a, phi_b, GRID, features, H, reading=(v_a, f_a))
    assert len(pts) > 100
    # all on the pool, none on its top near where the drop lands (its bottom agrees)
    assert np.all(np.abs(cases.sd_box(pts, *POOL)) < 1e-6)
    on_top = pts[:, 2] > -0.31
    assert on_top.any() and np.all(np.hypot(pts[on_top, 0], pts[on_top, 1]) > 0.2 + 5 * H)
    raised = extract_surface(box_field(POOL[0], np.array(POOL[1]) + 0.4 * H), GRID)
    assert cm.stillness([(v_a, f_a), raised], pts, H) == pytest.approx(0.4, abs=0.02)
    assert cm.stillness([(v_a, f_a)], pts, H) == pytest.approx(0.0, abs=1e-6)


@pytest.fixture(scope="module")
def merges():
    """The merge of two balls (32^3, 13 frames) as clay (surface tension 0) and as the
    default liquid: (frames of each, the clay's contact frame, h)."""
    case = cases.make_case("merge", 32)
    h = case.grid.spacing
    out = []
    for tension in (0.0, None):
        extra = {} if tension is None else {"surface_tension": tension}
        anim = animate_chain(case.fields, case.grid, case.features, [1, 13], processes=1,
                             **extra)
        out.append([(np.asarray(v, float), f) for v, f in anim.surfaces])
    contact = cm.contact_frame(out[0], 2, h)
    assert contact is not None and 0 < contact < len(out[0]) - 3
    return out, contact, h


def test_the_neck_measure_finds_the_clay_merge_creased(merges):
    # as clay the frame after contact folds by more than 45 degrees, so a neck bound of
    # 45 degrees cannot pass on it vacuously
    (clay, _), contact, h = merges
    assert cm.neck_fold(*clay[contact + 1], h)[1] > 45.0
    assert cm.neck_fold(*clay[0], h)[1] < 45.0  # two balls apart: no crease


def test_a_liquid_merge_rounds_its_neck_and_moves_nothing_before_contact(merges):
    (clay, liquid), contact, h = merges
    for k in range(contact):  # before the balls touch the frames are the clay's
        assert np.abs(liquid[k][0] - clay[k][0]).max() < 0.01 * h, k
    assert cm.contact_frame(liquid, 2, h) == contact
    folds = [cm.neck_fold(*frame, h)[1] for frame in liquid[contact + 3:]]  # from the third
    assert max(folds) <= 45.0, folds
