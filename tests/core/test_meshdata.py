"""The output mesh as Blender's arrays (`core.surface.meshdata`): edges made outside Blender."""

import numpy as np
import pytest

from keyframe_implicit.core.surface.attributes import MeshAttributes
from keyframe_implicit.core.surface.meshdata import (MESH_SEQUENCE, SHAPE_KEYS, MeshData, output_mesh,
                                             polygon_edges)
from keyframe_implicit.core import Animation


def _polygons(rng, n_vertices, n_polygons):
    """Random polygons of 3-6 distinct corners each (many share sides: few vertices)."""
    total = rng.integers(3, 7, n_polygons)
    loops = np.concatenate([rng.choice(n_vertices, k, replace=False) for k in total])
    start = np.concatenate([[0], np.cumsum(total)[:-1]])
    return start, total, loops


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_polygon_edges_are_every_side_once_and_each_corner_starts_its_own(seed):
    rng = np.random.default_rng(seed)
    start, total, loops = _polygons(rng, 12, 40)
    edges, corner_edges = polygon_edges(start, total, loops)
    sides = set()
    for s, t in zip(start, total):  # the brute-force reference: every polygon side, unordered
        ring = list(loops[s:s + t])
        for a, b in zip(ring, ring[1:] + ring[:1]):
            sides.add((min(a, b), max(a, b)))
            c = s + ring.index(a)
            assert sorted(edges[corner_edges[c]]) == sorted((a, b))
    assert edges.dtype == np.int32 and corner_edges.dtype == np.int32
    assert {tuple(e) for e in edges} == sides and len(edges) == len(sides)
    assert np.all(edges[:, 0] < edges[:, 1])


def test_edge_flags_follow_their_vertex_pair_onto_the_new_edges():
    quad_pair = MeshAttributes(np.array([0, 4]), np.array([4, 4]),
                               np.array([0, 1, 2, 3, 1, 4, 5, 2]))
    quad_pair.edges = np.array([[2, 1], [4, 5], [0, 3]])  # the artist's order and direction
    quad_pair.sharp_edges = np.array([True, False, False])
    quad_pair.seams = np.array([False, True, True])
    data = MeshData.build(np.zeros((6, 3)), quad_pair)
    pairs = [tuple(e) for e in data.edges]
    assert len(pairs) == 7
    assert [pairs[i] for i in np.flatnonzero(data.sharp_edges)] == [(1, 2)]
    assert sorted(pairs[i] for i in np.flatnonzero(data.seams)) == [(0, 3), (4, 5)]


def _animation(frames=3):
    """Three frames of a tetrahedron moving along x, one with a degenerate triangle."""
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    surfaces = [(tet + [k, 0, 0], faces) for k in range(frames)]
    surfaces[1] = (surfaces[1][0], np.vstack([faces, [[1, 1, 2]]]))
    return Animation(frames=np.arange(1, frames + 1), vertices=np.stack([v for v, _ in surfaces]),
                     faces=faces, grid=None, surfaces=surfaces,
                     velocities=[np.full((4, 3), k, dtype=np.float32) for k in range(frames)])


def test_sequence_lays_the_frames_end_to_end_with_their_frame_and_velocity():
    anim = _animation()
    data = output_mesh(anim, MESH_SEQUENCE)
    assert data.positions.shape == (12, 3) and data.polygons.n_polygons == 12  # degenerate dropped
    np.testing.assert_array_equal(data.face_ints["kfi_frame"], np.repeat([0, 1, 2], 4))
    np.testing.assert_array_equal(data.point_vectors["velocity"][:, 0], np.repeat([0, 1, 2], 4))
    assert len(data.edges) == 18  # six a tetrahedron, none shared between frames
    frame_of_vertex = data.edges // 4
    assert np.all(frame_of_vertex[:, 0] == frame_of_vertex[:, 1])
    assert anim.output_mesh(MESH_SEQUENCE) is anim.output_mesh(MESH_SEQUENCE)  # made once
    keys = output_mesh(anim, SHAPE_KEYS)
    np.testing.assert_array_equal(keys.positions, anim.vertices[0])
    assert keys.polygons.n_polygons == 4 and len(keys.edges) == 6


def test_a_sequence_without_surfaces_says_to_choose_shape_keys():
    anim = _animation()
    anim.surfaces = []
    with pytest.raises(ValueError, match="choose Shape Keys"):
        output_mesh(anim, MESH_SEQUENCE)
