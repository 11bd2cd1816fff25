"""The artist's own mesh as the template: exact keyframes, attributes kept, sub-cell detail kept."""

import numpy as np
import pytest

from keyframe_implicit import shapes
from keyframe_implicit.core import Keyframe, animate, animate_chain, fit_grid, mesh_to_sdf
from keyframe_implicit.core.surface.attributes import (MeshAttributes, closest_points, concatenate,
                                               transfer)
from keyframe_implicit.core.surface.quality import mesh_distance
from keyframe_implicit.core.fields.mesh import triangulate


def rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def uv_sphere(n_lat, radius=1.0, bump=None):
    """`keyframe_implicit.shapes.uv_sphere` with its attributes.

    Returns vertices, polygons (list), and MeshAttributes with a UV map (a seam at phi = 0)
    and two materials (faces with x > 0 use slot 1)."""
    v, polys = shapes.uv_sphere(n_lat, radius, bump)
    total = np.array([len(p) for p in polys])
    loops = np.concatenate(polys)
    attrs = MeshAttributes(np.concatenate([[0], np.cumsum(total)[:-1]]), total, loops)
    # UVs: (phi / 2pi, 1 - theta / pi), the seam where a face wraps past phi = 2pi
    x = v[loops]
    u = np.arctan2(x[:, 1], x[:, 0]) % (2 * np.pi) / (2 * np.pi)
    poly = np.repeat(np.arange(len(polys)), total)
    wraps = np.zeros(len(polys), bool)
    np.logical_or.at(wraps, poly, u > 0.75)
    u = np.where(wraps[poly] & (u < 0.25), u + 1.0, u)
    vv = 1.0 - np.arccos(np.clip(x[:, 2] / np.linalg.norm(x, axis=1), -1, 1)) / np.pi
    attrs.uv_maps["UVMap"] = np.stack([u, vv], 1).astype(np.float32)
    centre = np.add.reduceat(x, attrs.loop_start) / total[:, None]
    attrs.material_index = (centre[:, 0] > 0).astype(np.int64)
    attrs.material_names = ["Red", "Blue"]
    return v, polys, attrs


def test_fan_triangles_match_triangulate():
    v, polys, attrs = uv_sphere(6)
    ours, theirs = attrs.triangles(), triangulate(polys, len(v))  # the same fans, other order
    np.testing.assert_array_equal(np.unique(ours, axis=0), np.unique(theirs, axis=0))
    assert len(ours) == len(theirs)


def test_closest_points_land_on_the_mesh_with_barycentrics():
    rng = np.random.default_rng(0)
    v, polys, attrs = uv_sphere(12)
    tris = attrs.triangles()
    p = rng.normal(size=(500, 3))
    q, tri, bary = closest_points(p, v, tris)
    np.testing.assert_allclose(np.einsum("pk,pkd->pd", bary, v[tris[tri]]), q, atol=1e-9)
    assert mesh_distance(q, v, tris).max() < 1e-6
    # nearer than any vertex
    d_vert = np.min(np.linalg.norm(p[:, None] - v[None], axis=2), axis=1)
    assert np.all(np.linalg.norm(q - p, axis=1) <= d_vert + 1e-12)


def test_transfer_reads_uvs_and_materials_at_the_source_points():
    v, polys, attrs = uv_sphere(24)
    coarse_v, coarse_polys, coarse = uv_sphere(7)
    faces = coarse.triangles()
    out = transfer(attrs, v, coarse_v, faces)
    uv = out.uv_maps["UVMap"].reshape(-1, 3, 2)
    x = coarse_v[faces]
    # no triangle spans the seam: its corners' u differ by far less than the seam's jump
    # (at the poles the test's own map squeezes a whole row of u into one vertex)
    body = np.all(np.abs(x[..., 2]) < 0.8, axis=1)
    assert np.ptp(uv[..., 0], axis=1)[body].max() < 0.3
    # away from the seam and the poles the UVs are the sphere's (phi / 2pi, 1 - theta / pi)
    u_true = np.arctan2(x[..., 1], x[..., 0]) % (2 * np.pi) / (2 * np.pi)
    far = (np.abs(x[..., 2]) < 0.8) & (u_true > 0.05) & (u_true < 0.95)
    assert np.abs(uv[..., 0] - u_true)[far].max() < 0.01
    centre_x = x.mean(axis=1)[:, 0]
    clear = np.abs(centre_x) > 0.2
    np.testing.assert_array_equal(out.material_index[clear], (centre_x[clear] > 0).astype(int))


def test_transfer_of_a_mesh_with_nothing_varying_needs_no_source_points():
    v, polys, attrs = uv_sphere(12)
    coarse_v, _, coarse = uv_sphere(5)
    attrs.uv_maps.clear()
    attrs.material_index = np.ones(attrs.n_polygons, np.int64)  # one material: slot 1
    nowhere = np.full_like(coarse_v, np.nan)  # would fail any closest-point search
    out = transfer(attrs, v, nowhere, coarse.triangles())
    assert out.n_polygons == len(coarse.triangles()) and not out.uv_maps
    assert np.all(out.material_index == 1) and out.material_names == ["Red", "Blue"]
    attrs.material_index[0] = 0  # two materials: read at the source points again
    out = transfer(attrs, v, coarse_v, coarse.triangles())
    assert set(np.unique(out.material_index)) <= {0, 1}


def test_concatenate_offsets_polygons_and_fills_what_a_part_lacks():
    v_a, polys_a, a = uv_sphere(4)
    a.colors["Col"] = ("POINT", "FLOAT_COLOR", np.full((len(v_a), 4), 0.5, np.float32))
    a.edges = np.array([[0, 1], [1, 2]])
    a.seams = np.array([True, False])
    v_b, _, b = uv_sphere(3)
    b.uv_maps.clear()
    b.material_index = None
    b.custom_normals = np.tile(np.float32([0, 0, 1]), (b.n_loops, 1))
    out = concatenate([a, b], [len(v_a), len(v_b)])
    out.check(len(v_a) + len(v_b))
    n_loop = a.n_loops
    # the same polygons, the second part's loops and vertices moved past the first's
    np.testing.assert_array_equal(out.loop_start, np.r_[a.loop_start, b.loop_start + n_loop])
    np.testing.assert_array_equal(out.loop_vertices, np.r_[a.loop_vertices,
                                                           b.loop_vertices + len(v_a)])
    np.testing.assert_array_equal(out.triangles()[:len(a.triangles())], a.triangles())
    np.testing.assert_array_equal(out.triangles()[len(a.triangles()):],
                                  b.triangles() + len(v_a))
    # attributes only one part has: that part's values, the neutral value on the other
    np.testing.assert_array_equal(out.uv_maps["UVMap"][:n_loop], a.uv_maps["UVMap"])
    assert not out.uv_maps["UVMap"][n_loop:].any()
    np.testing.assert_array_equal(out.material_index, np.r_[a.material_index,
                                                            np.zeros(b.n_polygons, int)])
    domain, _, col = out.colors["Col"]
    assert domain == "POINT" and col.shape == (len(v_a) + len(v_b), 4)
    assert np.all(col[:len(v_a)] == 0.5) and not col[len(v_a):].any()
    assert not out.custom_normals[:n_loop].any() and np.all(out.custom_normals[n_loop:, 2] == 1)
    assert out.smooth is None and out.material_names == ["Red", "Blue"]
    np.testing.assert_array_equal(out.edges, a.edges)
    np.testing.assert_array_equal(out.seams, [True, False])
    assert out.sharp_edges is None
    a.colors["Col"] = ("CORNER", "FLOAT_COLOR", np.zeros((a.n_loops, 4), np.float32))
    b.colors["Col"] = ("POINT", "FLOAT_COLOR", np.zeros((len(v_b), 4), np.float32))
    with pytest.raises(ValueError, match="Col"):
        concatenate([a, b], [len(v_a), len(v_b)])


@pytest.fixture(scope="module")
def squash_bake():
    """A UV sphere turning 90 degrees with a slight squash, three keyframes (a chain)."""
    v, polys, attrs = uv_sphere(20)
    squash = np.diag([1.05, 1.05, 0.9])
    vb = (v @ rot_z(np.pi / 2).T) @ squash.T + [0.4, 0.0, 0.0]
    vc = v + [0.8, 0.2, 0.0]
    fa = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1]])
    fb = (fa @ rot_z(np.pi / 2).T) @ squash.T + [0.4, 0.0, 0.0]
    fc = fa + [0.8, 0.2, 0.0]
    kfs = [Keyframe(v.astype(np.float32), polys, 1, "A", attrs), Keyframe(vb, polys, 7, "B"),
           Keyframe(vc, polys, 11, "C")]
    return kfs, animate(kfs, [(fa, fb), (fb, fc)], resolution=20)


def test_keyframe_frames_are_the_artists_mesh(squash_bake):
    kfs, an = squash_bake
    h = an.grid.spacing
    assert an.attributes is kfs[0].attributes
    np.testing.assert_array_equal(an.faces, kfs[0].attributes.triangles())
    assert an.vertices.dtype == np.float32
    assert np.array_equal(an.vertices[0], kfs[0].vertices)  # bit for bit
    for kf in kfs[1:]:
        i = kf.frame - an.frames[0]
        d = mesh_distance(an.vertices[i], kf.vertices, triangulate(kf.faces, len(kf.vertices)))
        assert d.max() <= 0.05 * h
    q = an.stats["quality"]["shape_keys"]
    assert max(q[kf.frame - 1]["keyframe_max"] for kf in kfs) < 0.5


def test_grid_template_is_still_available(squash_bake):
    kfs, an = squash_bake
    grid = animate(kfs[:2], [(np.zeros((0, 3)), np.zeros((0, 3)))], resolution=12,
                   template="grid", surfaces=False)
    assert grid.attributes is None
    assert not np.array_equal(grid.vertices[0][: len(kfs[0].vertices)], kfs[0].vertices)
    with pytest.raises(ValueError, match="template"):
        animate(kfs[:2], [(np.zeros((0, 3)), np.zeros((0, 3)))], template="marching")


def test_bumps_under_two_cells_survive_a_rigid_turn():
    """Bumps of amplitude 0.3 h and wavelength 2 h turning rigidly keep >= 80 % at mid-way."""
    res = 12
    h = fit_grid([np.array([[-1.0, -1, -1], [1, 1, 1]])], res, padding_cells=4).spacing
    k = np.pi / h  # wavelength 2 h along the surface of the unit sphere

    def bump(t, p):
        return 0.3 * h * np.sin(k * t) * np.sin(np.round(k * np.sin(t)) * p)
    v, polys, _ = uv_sphere(int(np.ceil(np.pi / (2 * h) * 8)), bump=bump)
    tris = triangulate(polys, len(v))
    grid = fit_grid([v], res, padding_cells=4)
    turn = rot_z(np.pi / 2)
    phis = [mesh_to_sdf(v, tris, grid), mesh_to_sdf(v @ turn.T, tris, grid)]
    mapped = grid.points() @ turn.T
    kept = {}
    for kind, extra in (("detail", dict(keyframe_meshes=[(v, tris), (v @ turn.T, tris)])),
                        ("zero set", {})):
        ch = animate_chain(phis, grid, None, [1, 9], maps=[mapped], coverage=False,
                           surfaces=False, template=(v, tris), **extra)
        r = np.linalg.norm(ch.vertices[4], axis=1)
        r0 = np.linalg.norm(v, axis=1)
        kept[kind] = np.dot(r - r.mean(), r0 - r0.mean()) / np.dot(r0 - r0.mean(), r0 - r0.mean())
        if kind == "detail":
            assert np.array_equal(ch.vertices[0], v)
            expected = v @ rot_z(np.pi / 4).T
            assert np.linalg.norm(ch.vertices[4] - expected, axis=1).mean() < 0.1 * h
    assert kept["detail"] >= 0.8
    assert kept["zero set"] < 0.5  # pulled onto the grid's zero set, the bumps flatten


def test_posed_copies_land_vertex_for_vertex(squash_bake):
    kfs, an = squash_bake
    for kf in kfs[1:]:  # B and C are A's mesh moved: each vertex ends on its own counterpart
        np.testing.assert_allclose(an.vertices[kf.frame - an.frames[0]], kf.vertices, atol=1e-6)


def test_same_vertex_count_alone_is_not_a_posed_copy():
    from keyframe_implicit.core.surface.template import same_vertices

    v, _, _ = uv_sphere(12)
    rng = np.random.default_rng(1)
    h = 0.1
    near = v + rng.normal(scale=0.2 * h, size=v.shape)  # slid a fifth of a cell
    assert same_vertices(near, v, h)
    assert not same_vertices(near, v[rng.permutation(len(v))], h)  # renumbered
    assert not same_vertices(near[:-1], v[:-1] * 1.0 + [0, 0, 1.0], h)  # far away
    assert not same_vertices(near, v[:-1], h)  # another vertex count


def test_mesh_sequence_shows_each_keyframe_mesh_on_its_frame(squash_bake):
    kfs, an = squash_bake
    for kf in kfs:
        i = kf.frame - an.frames[0]
        v, tris = an.surfaces[i]
        np.testing.assert_allclose(v, kf.vertices, atol=1e-6)
        np.testing.assert_array_equal(tris, triangulate(kf.faces, len(kf.vertices)))
        assert len(an.velocities[i]) == len(v)
        q = an.stats["quality"]["mesh_sequence"][i]
        assert q["keyframe_max"] < 1e-6
    assert an.surface_attributes(0) is kfs[0].attributes
    b = an.surface_attributes(kfs[1].frame - an.frames[0])  # B has no attributes: its polygons
    assert b.n_polygons == len(triangulate(kfs[1].faces, len(kfs[1].vertices)))
    mid = an.surface_attributes(3)  # an in-between: transferred from A
    assert mid.n_loops == 3 * len(an.surfaces[3][1]) and "UVMap" in mid.uv_maps


def test_concatenate_renumbers_each_parts_material_slots():
    v, _, a = uv_sphere(4)
    _, _, b = uv_sphere(4)
    b.material_names = ["Blue", "Green"]
    out = concatenate([a, b], [len(v), len(v)])
    assert out.material_names == ["Red", "Blue", "Green"]
    names = np.array(out.material_names)[out.material_index]
    np.testing.assert_array_equal(names[:a.n_polygons], np.array(a.material_names)[a.material_index])
    np.testing.assert_array_equal(names[a.n_polygons:], np.array(b.material_names)[b.material_index])
