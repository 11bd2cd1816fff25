"""Signed distance grids from meshes and polygons (issue 3, keyframe_implicit.core.fields.sdf)."""

import numpy as np
import pytest
from scipy import ndimage

from inbetween_cases import make_grid, sd_sphere, sphere_field
from keyframe_implicit.core import Cancelled, Grid, mesh_to_sdf, polygon_to_sdf
from keyframe_implicit.core.fields.mesh import triangulate
from keyframe_implicit.core.fields.triangles import point_triangle_distance
from keyframe_implicit.core.fields.winding import winding_number


# -- test meshes built with numpy --------------------------------------------------
from keyframe_implicit.shapes import icosphere  # noqa: E402

BOX_V = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
# outward quads of the unit box (vertex index = 4x + 2y + z)
BOX_QUADS = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6],
                      [0, 2, 6, 4], [1, 5, 7, 3]])


def box(lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return lo + BOX_V * (hi - lo), BOX_QUADS.copy()


def box_sdf(p, lo, hi):
    c, e = (np.asarray(lo) + hi) / 2, (np.asarray(hi) - lo) / 2
    q = np.abs(p - c) - e
    return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(axis=-1), 0)


def brute_distance(points, v, f):
    """Reference: distance to every triangle, minimum (small inputs only)."""
    P, T = len(points), len(f)
    p = np.repeat(points, T, axis=0)
    t = np.tile(np.arange(T), P)
    d = point_triangle_distance(p, v[f[t, 0]], v[f[t, 1]], v[f[t, 2]])
    return d.reshape(P, T).min(axis=1)


@pytest.fixture(scope="module")
def sphere64():
    v, f = icosphere(5, 0.8)
    g = make_grid(3, 64, -1.0, 1.0)
    stats = {}
    return g, mesh_to_sdf(v, f, g, stats=stats), stats


# -- closed meshes against analytic distance ----------------------------------------
def test_sphere_matches_analytic_distance_in_band_and_sign_everywhere(sphere64):
    g, d, stats = sphere64
    h = g.spacing
    r = sphere_field(g, (0, 0, 0), 0.8)
    band = np.abs(r) <= 3 * h
    assert np.abs(d - r)[band].max() <= 0.02 * h
    # sign everywhere except nodes closer than the chordal error of the 20480-face sphere
    clear = np.abs(r) > 0.01 * h
    assert np.array_equal(np.sign(d[clear]), np.sign(r[clear]))
    # far field is a bound from above, within half a cell
    assert np.all(np.abs(d) >= np.abs(r) - 0.02 * h)
    assert np.abs(d - r).max() <= 0.5 * h
    assert stats["shell_nodes"] == np.count_nonzero(np.abs(d) <= 3 * h)
    assert stats["degenerate_triangles"] == 0 and stats["leaky_regions"] == 0


def test_box_of_twelve_triangles_and_of_quads_match_analytic_box():
    lo, hi = np.array([-0.6, -0.4, -0.5]), np.array([0.5, 0.45, 0.3])
    v, quads = box(lo, hi)
    tris = triangulate(quads, len(v))
    assert tris.shape == (12, 3)
    g = make_grid(3, 64, -1.0, 1.0)
    h = g.spacing
    d_tri = mesh_to_sdf(v, tris, g)
    d_quad = mesh_to_sdf(v, quads, g)
    ref = box_sdf(g.points(), lo, hi)
    band = np.abs(ref) <= 3 * h
    assert np.abs(d_tri - ref)[band].max() <= 0.02 * h
    clear = np.abs(ref) > 1e-9
    assert np.array_equal(np.sign(d_tri[clear]), np.sign(ref[clear]))
    np.testing.assert_allclose(d_quad, d_tri, atol=1e-12)
    assert np.all(np.abs(d_tri) >= np.abs(ref) - 1e-9)  # far field bounds from above


def test_exact_shell_does_not_depend_on_the_chunk_size(monkeypatch):
    """The (node, triangle) pairs of the triangles' boxes are measured a chunk at a
    time, and a chunk may begin and end inside one box: with chunks far smaller than
    any box the distances are the same, and exact in the shell."""
    from keyframe_implicit.core.fields import sdf

    lo, hi = np.array([-0.6, -0.4, -0.5]), np.array([0.5, 0.45, 0.3])
    v, quads = box(lo, hi)
    g = make_grid(3, 40, -1.0, 1.0)
    d = mesh_to_sdf(v, quads, g)
    monkeypatch.setattr(sdf, "_PAIRS", 999)  # a box of these triangles holds ~4,000 pairs
    np.testing.assert_array_equal(mesh_to_sdf(v, quads, g), d)
    ref = box_sdf(g.points(), lo, hi)
    band = np.abs(ref) <= 3 * g.spacing
    assert np.abs(d - ref)[band].max() <= 1e-12


def test_ngon_prism_given_as_ragged_polygons():
    """A hexagonal prism: two 6-gons and six quads in one ragged list."""
    k = 6
    ang = 2 * np.pi * np.arange(k) / k
    ring = np.stack([0.7 * np.cos(ang), 0.7 * np.sin(ang)], axis=1)
    v = np.concatenate([np.c_[ring, np.full(k, -0.4)], np.c_[ring, np.full(k, 0.4)]])
    faces = [list(range(k))[::-1], list(range(k, 2 * k))]
    faces += [[i, (i + 1) % k, k + (i + 1) % k, k + i] for i in range(k)]
    g = make_grid(3, 32, -1.0, 1.0)
    d = mesh_to_sdf(v, faces, g)
    p = g.points()
    # inside the hexagon's inscribed circle and the slab: inside; beyond its circumcircle: outside
    rr = np.linalg.norm(p[..., :2], axis=-1)
    inner = (rr < 0.7 * np.cos(np.pi / k) - 1e-6) & (np.abs(p[..., 2]) < 0.4 - 1e-6)
    outer = (rr > 0.7 + 1e-6) | (np.abs(p[..., 2]) > 0.4 + 1e-6)
    assert np.all(d[inner] < 0) and np.all(d[outer] > 0)
    # top cap: exact distance to the plane z = 0.4 above the inscribed disc
    above = (rr < 0.5) & (p[..., 2] > 0.4) & (p[..., 2] < 0.4 + 3 * g.spacing)
    np.testing.assert_allclose(d[above], p[..., 2][above] - 0.4, atol=1e-9)


@pytest.mark.parametrize("subdivisions, radius, sampled", [(3, 0.45, False), (4, 0.3, True)])
def test_band_distance_is_exact_against_brute_force_on_irregular_mesh(subdivisions, radius,
                                                                       sampled):
    """Mixed triangle sizes (a coarse box next to a noisy sphere): every band node
    finds its closest triangle, whether all triangles are measured over their boxes
    (the sphere's triangles about a cell across) or most of the sphere's (a third of a
    cell) through samples on them and the rest over their boxes."""
    rng = np.random.default_rng(3)
    vs, fs = icosphere(subdivisions, radius, center=(0.1, 0.0, 0.05))
    vs = vs + rng.normal(scale=0.01 / 2 ** (subdivisions - 3), size=vs.shape)
    vb, qb = box((-0.9, -0.8, -0.85), (0.2, 0.1, -0.47))  # disjoint from the sphere
    v = np.concatenate([vs, vb])
    f = np.concatenate([fs, triangulate(qb, len(vb)) + len(vs)])
    g = make_grid(3, 40, -1.0, 1.0)
    stats = {}
    d = mesh_to_sdf(v, f, g, exact_cells=3, stats=stats)
    boxed = stats["boxed_triangles"]
    assert (12 < boxed < len(f) // 2) if sampled else (boxed == len(f))
    idx = np.flatnonzero(np.abs(d).reshape(-1) <= 3 * g.spacing)
    pick = rng.choice(idx, size=400 if not sampled else 200, replace=False)
    ref = brute_distance(g.points().reshape(-1, 3)[pick], v, f)
    np.testing.assert_allclose(np.abs(d.reshape(-1)[pick]), ref, atol=1e-12, rtol=1e-12)
    # outside the band: an upper bound, at most about a cell off
    far = np.flatnonzero(np.abs(d).reshape(-1) > 3 * g.spacing)
    pick = rng.choice(far, size=200 if not sampled else 100, replace=False)
    ref = brute_distance(g.points().reshape(-1, 3)[pick], v, f)
    far_d = np.abs(d.reshape(-1)[pick])
    assert np.all(far_d >= ref - 1e-12) and np.all(far_d <= ref + 1.5 * g.spacing)


# -- open, holed, overlapping ------------------------------------------------------
def test_sphere_with_a_few_faces_removed_keeps_its_sign():
    v, f = icosphere(4, 0.7)
    cen = v[f].mean(axis=1)
    removed = np.argsort(np.linalg.norm(cen - [0, 0, 0.7], axis=1))[:6]
    f_open = np.delete(f, removed, axis=0)
    g = make_grid(3, 40, -1.0, 1.0)
    d = mesh_to_sdf(v, f_open, g)
    p = g.points()
    r = sd_sphere(p, (0, 0, 0), 0.7)
    away = np.linalg.norm(p - [0, 0, 0.7], axis=-1) > 0.2
    clear = away & (np.abs(r) > 0.02)
    assert np.array_equal(np.sign(d[clear]), np.sign(r[clear]))
    labels, n = ndimage.label(d < 0)
    assert n == 1


def test_head_with_two_eye_holes_has_one_connected_inside():
    """A head-like closed surface with two eye holes wider than the band punched
    through into its interior: inside and outside meet through the holes, so the
    region propagation must fall back to winding numbers without flipping signs."""
    v, f = icosphere(4, 0.75)
    v = v * [1.0, 0.85, 1.1]  # egg-shaped head
    cen = v[f].mean(axis=1)
    eyes = np.array([[0.28, 0.72, 0.35], [-0.28, 0.72, 0.35]])
    eyes = eyes / np.linalg.norm(eyes / [1.0, 0.85, 1.1], axis=1)[:, None] * 0.75
    hole = np.zeros(len(f), bool)
    for e in eyes:  # two eyes
        hole |= np.linalg.norm(cen - e, axis=1) < 0.18
    f_open = f[~hole]
    g = make_grid(3, 48, -1.0, 1.0)
    stats = {}
    d = mesh_to_sdf(v, f_open, g, stats=stats)
    assert stats["leaky_regions"] >= 1  # the holes do connect inside and outside
    p = g.points()
    ell = np.linalg.norm(p / [1.0, 0.85, 1.1], axis=-1) - 0.75  # ~ scaled distance
    away = np.min(np.linalg.norm(p[..., None, :] - eyes, axis=-1), axis=-1) > 0.3
    clear = away & (np.abs(ell) > 0.03)
    assert np.array_equal(np.sign(d[clear]), np.sign(ell[clear]))
    labels, n = ndimage.label(d < 0)
    assert n == 1
    # deep inside, right behind the eyes, is still inside
    assert d[tuple(np.rint(g.to_index([0.0, 0.3, 0.15])).astype(int))] < 0


def test_overlapping_closed_meshes_give_their_union():
    v1, f1 = icosphere(3, 0.5, center=(-0.2, 0.0, 0.0))
    v2, f2 = icosphere(3, 0.45, center=(0.25, 0.05, 0.0))
    v = np.concatenate([v1, v2])
    f = np.concatenate([f1, f2 + len(v1)])
    g = make_grid(3, 40, -1.0, 1.0)
    d = mesh_to_sdf(v, f, g)
    p = g.points()
    r1 = sd_sphere(p, [-0.2, 0, 0], 0.5)
    r2 = sd_sphere(p, [0.25, 0.05, 0], 0.45)
    union = np.minimum(r1, r2)
    clear = np.abs(union) > 0.03
    assert np.array_equal(np.sign(d[clear]), np.sign(union[clear]))
    both = (r1 < -0.03) & (r2 < -0.03)
    assert both.sum() > 100 and np.all(d[both] < 0)  # winding number 2 is inside
    # the faces inside the union are not its boundary: distances there follow the union
    h = g.spacing
    assert np.all(np.abs(d[both]) >= np.abs(union[both]) - 2 * h)
    assert np.all(np.abs(d) <= np.abs(union) + 1.5 * h + 0.02)


def test_single_closed_mesh_is_not_overlap_corrected(sphere64):
    assert sphere64[2]["overlap_corrected"] is False


def test_winding_number_hierarchy_matches_exact_sum():
    rng = np.random.default_rng(0)
    v, f = icosphere(4, 0.6)
    f = f[np.linalg.norm(v[f].mean(axis=1) - [0.6, 0, 0], axis=1) > 0.25]  # open it
    q = rng.uniform(-1, 1, size=(500, 3))
    fast = winding_number(v, f, q)
    exact = winding_number(v, f, q, beta=1e9)  # never approximates: all exact solid angles
    assert np.abs(fast - exact).max() < 0.05  # first-order dipoles, beta = 2
    vc, fc = icosphere(3, 0.6)
    w = winding_number(vc, fc, q)
    inside = np.linalg.norm(q, axis=1) < 0.55
    outside = np.linalg.norm(q, axis=1) > 0.65
    assert np.all(np.abs(w[inside] - 1) < 0.05) and np.all(np.abs(w[outside]) < 0.05)


# -- bad input ----------------------------------------------------------------------
def test_degenerate_faces_are_skipped_and_counted():
    v, f = icosphere(2, 0.6)
    g = make_grid(3, 24, -1.0, 1.0)
    ref = mesh_to_sdf(v, f, g)
    v2 = np.concatenate([v, [[0.1, 0.1, 0.1]]])
    extra = np.array([[0, 0, 1], [5, 5, 5], [len(v), len(v), len(v)]])
    stats = {}
    d = mesh_to_sdf(v2, np.concatenate([f, extra]), g, stats=stats)
    assert stats["degenerate_triangles"] == 3
    np.testing.assert_allclose(d, ref, atol=1e-12)


@pytest.mark.parametrize("vertices, faces, words", [
    (np.zeros((4, 3)), np.zeros((0, 3), int), "no faces"),
    (np.zeros((4, 3)), [], "no faces"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]]), [[0, 1, 2]], "NaN"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]), [[0, 1, 2]], "NaN or infinite"),
    (np.eye(3), [[0, 1, 3]], "indices range"),
    (np.eye(3), [[0, -1, 2]], "indices range"),
    (np.eye(3), [[0, 1]], "at least 3"),
    (np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2]]), [[0, 1, 2]], "zero area"),
    (np.zeros((3, 2)), [[0, 1, 2]], "shape (N, 3)"),
    (np.eye(3), [[0, 1.5, 2]], "whole numbers"),
])
def test_bad_meshes_raise_value_errors_that_say_what_is_wrong(vertices, faces, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")):
        mesh_to_sdf(vertices, faces, make_grid(3, 8, -1.0, 1.0))


def test_mesh_on_2d_grid_is_refused():
    v, f = icosphere(1)
    with pytest.raises(ValueError, match="3D grid"):
        mesh_to_sdf(v, f, Grid((0, 0), 0.1, (8, 8)))


def test_progress_reports_and_cancel_stops():
    v, f = icosphere(2, 0.6)
    seen = []
    mesh_to_sdf(v, f, make_grid(3, 16, -1.0, 1.0), progress=lambda x, m: seen.append(x))
    assert seen[-1] == 1.0 and all(b >= a for a, b in zip(seen, seen[1:])) and len(seen) >= 4
    with pytest.raises(Cancelled):
        mesh_to_sdf(v, f, make_grid(3, 16, -1.0, 1.0), cancel=lambda: True)


# -- 2D polygons ----------------------------------------------------------------------
def test_disc_polygon_matches_circle_distance():
    ang = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    R = 0.6
    loop = R * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    g = make_grid(2, 65, -1.0, 1.0)
    d = polygon_to_sdf(loop, g)
    r = sphere_field(g, (0, 0), R)
    sag = R * (1 - np.cos(np.pi / 400))
    assert np.abs(d - r).max() <= sag + 1e-12
    clear = np.abs(r) > sag
    assert np.array_equal(np.sign(d[clear]), np.sign(r[clear]))


@pytest.mark.parametrize("flip_hole", [False, True])
def test_square_with_square_hole_even_odd_any_orientation(flip_hole):
    outer = np.array([[-0.8, -0.8], [0.8, -0.8], [0.8, 0.8], [-0.8, 0.8]])
    hole = np.array([[-0.3, -0.3], [0.3, -0.3], [0.3, 0.3], [-0.3, 0.3]])
    if flip_hole:
        hole = hole[::-1]
    g = make_grid(2, 41, -1.0, 1.0)
    d = polygon_to_sdf([outer, hole], g)
    p = g.points()
    q_out = np.abs(p).max(axis=-1) - 0.8
    q_in = np.abs(p).max(axis=-1) - 0.3
    ref = np.maximum(q_out, -q_in)  # square ring (exact on the axes-aligned Chebyshev metric)
    clear = np.abs(ref) > 1e-9
    assert np.array_equal(np.sign(d[clear]), np.sign(ref[clear]))
    # exact Euclidean distance at a few nodes
    i = tuple(np.rint(g.to_index([0.0, 0.0])).astype(int))
    assert d[i] == pytest.approx(0.3)
    i = tuple(np.rint(g.to_index([0.55, 0.0])).astype(int))
    assert d[i] == pytest.approx(-0.25)
    i = tuple(np.rint(g.to_index([1.0, 1.0])).astype(int))
    assert d[i] == pytest.approx(np.hypot(0.2, 0.2))


def test_nonzero_rule_unions_overlapping_loops_and_needs_opposite_holes():
    a = np.array([[-0.6, -0.3], [0.2, -0.3], [0.2, 0.3], [-0.6, 0.3]])
    b = a + [0.4, 0.0]
    g = make_grid(2, 41, -1.0, 1.0)
    i = tuple(np.rint(g.to_index([0.0, 0.0])).astype(int))  # in both
    assert polygon_to_sdf([a, b], g, rule="nonzero")[i] < 0
    assert polygon_to_sdf([a, b], g, rule="evenodd")[i] > 0
    hole = 0.2 * a[::-1]
    i = tuple(np.rint(g.to_index([-0.04, 0.0])).astype(int))
    assert polygon_to_sdf([a, hole], g, rule="nonzero")[i] > 0


@pytest.mark.parametrize("loops, grid, words", [
    ([], make_grid(2, 8, -1.0, 1.0), "no loops"),
    ([np.array([[0, 0], [1, 0]])], make_grid(2, 8, -1.0, 1.0), "at least 3"),
    ([np.array([[0, 0], [1, np.nan], [0, 1]])], make_grid(2, 8, -1.0, 1.0), "NaN"),
    ([np.zeros((4, 3))], make_grid(2, 8, -1.0, 1.0), r"shape \(N, 2\)"),
    ([np.array([[0, 0], [1, 0], [0, 1]])], make_grid(3, 8, -1.0, 1.0), "2D Grid"),
])
def test_bad_polygons_raise_value_errors(loops, grid, words):
    with pytest.raises(ValueError, match=words):
        polygon_to_sdf(loops, grid)


def test_flipped_normals_and_mesh_larger_than_the_grid():
    v, f = icosphere(4, 0.7, center=(0.6, 0.6, 0.6))  # a quarter of the sphere sticks out
    g = make_grid(3, 32, -1.0, 1.0)
    d = mesh_to_sdf(v, f, g)
    d_flip = mesh_to_sdf(v, f[:, ::-1], g)
    np.testing.assert_allclose(d_flip, d, atol=1e-12)
    r = sphere_field(g, 0.6, 0.7)
    clear = np.abs(r) > 0.01
    assert np.array_equal(np.sign(d[clear]), np.sign(r[clear]))
    assert np.abs(d - r)[np.abs(r) < 2.9 * g.spacing].max() < 0.02 * g.spacing
    assert np.abs(d - r).max() < 0.1 * g.spacing  # far field, near the band too


def test_grid_entirely_inside_a_closed_mesh_is_all_inside():
    v, f = icosphere(3, 5.0)
    g = make_grid(3, 12, -0.5, 0.5)
    d = mesh_to_sdf(v, f, g)
    assert np.all(d < 0)
    pick = np.random.default_rng(0).choice(g.size, 50, replace=False)
    ref = brute_distance(g.points().reshape(-1, 3)[pick], v, f)
    got = np.abs(d.reshape(-1)[pick])
    assert np.all(got >= ref - 1e-9) and np.all(got <= ref + 0.6 * g.spacing)


@pytest.mark.parametrize("rule", ["evenodd", "nonzero"])
def test_polygon_sdf_matches_brute_force_on_a_star_with_a_hole(rule):
    """Distance against every segment, sign against the summed winding angles."""
    k = 11
    ang = np.linspace(0, 2 * np.pi, 2 * k, endpoint=False)
    rad = np.where(np.arange(2 * k) % 2 == 0, 0.85, 0.4)
    star = np.c_[rad * np.cos(ang), rad * np.sin(ang)] + [0.03, -0.02]
    a = np.linspace(0, 2 * np.pi, 7, endpoint=False)
    hole = 0.2 * np.c_[np.cos(a), np.sin(a)][::-1]  # opposite orientation
    g = make_grid(2, 47, -1.0, 1.0)
    d = polygon_to_sdf([star, hole], g, rule=rule)
    P = g.points().reshape(-1, 2)
    A = np.concatenate([star, hole])
    B = np.concatenate([np.roll(star, -1, 0), np.roll(hole, -1, 0)])
    AP = P[:, None] - A[None]
    AB = (B - A)[None]
    t = np.clip(np.sum(AP * AB, -1) / np.sum(AB * AB, -1), 0, 1)
    ref = np.sqrt(np.min(np.sum((AP - t[..., None] * AB) ** 2, -1), axis=1))
    BP = P[:, None] - B[None]
    w = np.rint(np.arctan2(AP[..., 0] * BP[..., 1] - AP[..., 1] * BP[..., 0],
                           np.sum(AP * BP, -1)).sum(axis=1) / (2 * np.pi))
    np.testing.assert_allclose(np.abs(d).reshape(-1), ref, atol=1e-12)
    clear = ref > 1e-9
    assert np.array_equal((d.reshape(-1) < 0)[clear], (w != 0)[clear])
    assert d[tuple(np.rint(g.to_index([0.03, -0.02])).astype(int))] > 0  # the hole


def test_a_misspelt_option_is_refused():
    """A keyword mesh_to_sdf does not take (a typo, or a name it no longer has) is refused."""
    v, f = icosphere(2, 0.4)
    g = make_grid(3, 20, -1.0, 1.0)
    for wrong in ("exact_cels", "band_cells"):
        with pytest.raises(TypeError, match=wrong):
            mesh_to_sdf(v, f, g, **{wrong: 2})
