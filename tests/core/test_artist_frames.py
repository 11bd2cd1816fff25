"""The artist's mesh on every frame one mesh can follow: the frames of a mesh sequence
before a topology change are the tracked template, with the artist's polygons and UVs."""

import numpy as np
import pytest

from keyframe_implicit.core import Keyframe, animate
from keyframe_implicit.core.bake.chain import tracked_frames
from keyframe_implicit.core.surface.extract import surface_topology
from keyframe_implicit.core.surface.meshdata import FRAME_ATTRIBUTE, MESH_SEQUENCE

from test_artist_template import uv_sphere


def frame_meshes(data, n):
    """Per frame of a mesh sequence's `MeshData`: (vertex count, loop vertices from 0, UVs)."""
    poly, which = data.polygons, data.face_ints[FRAME_ATTRIBUTE]
    uv = poly.uv_maps.get("UVMap")
    out, first = [], 0
    for i in range(n):
        loops = np.concatenate([np.arange(poly.loop_start[p], poly.loop_start[p] + poly.loop_total[p])
                                for p in np.flatnonzero(which == i)])
        last = int(poly.loop_vertices[loops].max()) + 1
        out.append((last - first, poly.loop_vertices[loops] - first,
                    None if uv is None else uv[loops]))
        first = last
    return out


@pytest.fixture(scope="module")
def merge_bake():
    """Two UV spheres (two materials, a UV map) that meet half-way and end as one ball of
    their volume."""
    v, polys, attrs = uv_sphere(10, 0.3)
    n = len(v)
    both = np.vstack([v - [0.45, 0, 0], v + [0.45, 0, 0]])
    polys2 = list(polys) + [np.asarray(p) + n for p in polys]
    from keyframe_implicit.core.surface.attributes import concatenate
    attrs2 = concatenate([attrs, attrs], [n, n])
    big, big_polys, _ = uv_sphere(14, 0.3 * 2 ** (1 / 3))
    dirs = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]]) * 0.15
    fa = np.vstack([dirs - [0.45, 0, 0], dirs + [0.45, 0, 0]])
    fb = np.vstack([dirs - [0.16, 0, 0], dirs + [0.16, 0, 0]])
    kfs = [Keyframe(both, polys2, 1, "balls", attrs2), Keyframe(big, big_polys, 17, "ball")]
    return kfs, animate(kfs, [(fa, fb)], resolution=24)


def test_frames_before_contact_are_the_artists_mesh(merge_bake):
    kfs, an = merge_bake
    attrs = kfs[0].attributes
    topo = an.stats["topology"]
    contact = next(i for i, t in enumerate(topo) if t[0] < topo[0][0])
    assert an.stats["output"] == "mesh_sequence" and contact >= 4
    frames = frame_meshes(an.output_mesh(MESH_SEQUENCE), len(an.frames))
    tracked = an.stats["tracked_frames"]
    assert tracked == contact  # every frame before contact
    for i, (count, loops, uv) in enumerate(frames[:tracked]):
        assert count == len(kfs[0].vertices)
        np.testing.assert_array_equal(loops, attrs.loop_vertices)
        np.testing.assert_array_equal(uv, attrs.uv_maps["UVMap"])
        q = an.stats["quality"]["mesh_sequence"][i]
        assert 0.97 <= q["area_ratio"] <= 1.03 and q["inverted_fraction"] <= 0.005
    for count, _, _ in frames[contact:-1]:  # from the contact on, each frame's own surface
        assert count != len(kfs[0].vertices)
    assert f"frames 1-{tracked}" in an.stats["output_reason"]


def test_tracked_frames_move_with_the_template(merge_bake):
    _, an = merge_bake
    data = an.output_mesh(MESH_SEQUENCE)
    n = len(an.vertices[0])
    velocity = data.point_vectors["velocity"]
    np.testing.assert_allclose(velocity[n:2 * n], 0.5 * (an.vertices[2] - an.vertices[0]),
                               atol=1e-6)
    np.testing.assert_allclose(data.positions[n:2 * n], an.vertices[1])


def test_the_switch_is_at_the_topology_change_or_the_first_fold():
    frames = np.arange(1, 7)
    clean = {"area_ratio": 1.0, "inverted_fraction": 0.0, "coverage": 1.0}
    topo = [(2, 4)] * 4 + [(1, 2)] * 2
    assert tracked_frames(frames, [dict(clean) for _ in frames], topo).tolist() == [
        True] * 4 + [False] * 2
    folded = [dict(clean) for _ in frames]
    folded[2]["inverted_fraction"] = 0.02
    assert tracked_frames(frames, folded, topo).sum() == 2
    behind = [dict(clean, coverage=0.9) for _ in frames]  # the surface reaching ahead
    assert tracked_frames(frames, behind, topo).sum() == 4
    assert tracked_frames(frames, [dict(clean, area_ratio=1.1) for _ in frames], topo).sum() == 4


def test_surface_topology_counts_pieces_and_holes():
    v, polys, attrs = uv_sphere(8, 0.3)
    tris = attrs.triangles()
    assert surface_topology(v, tris) == (1, 2)
    two = surface_topology(np.vstack([v, v + 1]), np.vstack([tris, tris + len(v)]))
    assert two == (2, 4)
