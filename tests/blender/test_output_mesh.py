"""The output mesh copied in through attributes (`output.mesh_steps`) is the mesh Blender
would build itself: same edges, each corner on its own edge, nothing for validate to fix."""

import bpy
import numpy as np

from keyframe_implicit.blender import output
from keyframe_implicit.core.surface.attributes import MeshAttributes
from keyframe_implicit.core.surface.meshdata import MeshData


def _blender_route(positions, polygons):
    """The mesh made per element through ``mesh.vertices`` / ``mesh.loops`` and with
    Blender's own edges (``calc_edges``)."""
    mesh = bpy.data.meshes.new("reference")
    mesh.vertices.add(len(positions))
    mesh.vertices.foreach_set("co", positions.ravel())
    mesh.loops.add(polygons.n_loops)
    mesh.loops.foreach_set("vertex_index", polygons.loop_vertices.astype(np.int32))
    mesh.polygons.add(polygons.n_polygons)
    mesh.polygons.foreach_set("loop_start", polygons.loop_start.astype(np.int32))
    mesh.update(calc_edges=True)
    return mesh


def _corner_pairs(mesh):
    """Per corner, the vertex pair of its edge (sorted), and the set of all edges."""
    ev = np.empty(2 * len(mesh.edges), np.int32)
    mesh.edges.foreach_get("vertices", ev)
    ev = np.sort(ev.reshape(-1, 2), axis=1)
    ce = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("edge_index", ce)
    return ev[ce], {tuple(e) for e in ev}


def test_made_edges_equal_blenders_own(scene):
    rng = np.random.default_rng(3)
    grid = np.arange(36).reshape(6, 6)  # quads of a 5 x 5 sheet, then one fan of an n-gon
    quads = np.stack([grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]], -1).reshape(-1, 4)
    loops = np.concatenate([quads.ravel(), [36, 37, 38, 39, 40, 41], [0, 1, 36]])
    total = np.concatenate([np.full(len(quads), 4), [6, 3]])
    polygons = MeshAttributes(np.concatenate([[0], np.cumsum(total)[:-1]]), total, loops)
    positions = rng.random((42, 3)).astype(np.float32)
    data = MeshData.build(positions, polygons)
    mesh = bpy.data.meshes.new("made")
    output.run_steps(output.mesh_steps(mesh, data))
    ref = _blender_route(positions, polygons)
    got_corners, got_edges = _corner_pairs(mesh)
    want_corners, want_edges = _corner_pairs(ref)
    assert got_edges == want_edges and len(mesh.edges) == len(ref.edges) == 68
    np.testing.assert_array_equal(got_corners, want_corners)
    co = np.empty(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", co)
    np.testing.assert_array_equal(co.reshape(-1, 3), positions)
    lv = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", lv)
    np.testing.assert_array_equal(lv, loops)
    assert [len(p.vertices) for p in mesh.polygons] == list(total)
    assert mesh.validate(verbose=False) is False  # nothing to fix
