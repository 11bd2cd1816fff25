"""OpenVDB export of the in-between level sets (blender/volumes.py)."""

import bpy
import numpy as np
import pytest

from keyframe_implicit.blender import volumes
from keyframe_implicit.core import Grid


def test_written_level_sets_read_back_with_the_same_values(scene, tmp_path):
    vdb, reason = volumes.openvdb_module()
    if vdb is None:
        assert bpy.app.version < (4, 4), "Blender 4.4+ ships openvdb: " + reason
        pytest.skip(reason)
    grid = Grid(origin=(-1.0, 0.5, 2.0), spacing=0.1, shape=(12, 10, 8))
    x = grid.points()
    fields = [np.linalg.norm(x - c, axis=-1) - 0.3 for c in ((-0.5, 0.9, 2.3), (-0.4, 0.9, 2.4))]
    fields = [np.minimum(f, 0.4).astype(np.float32) for f in fields]
    paths = volumes.write_sequence(str(tmp_path), "KFI", [3, 4], fields, grid)
    for path, field in zip(paths, fields):
        back = vdb.read(path, volumes.GRID_NAME)
        assert back.gridClass == vdb.GridClass.LEVEL_SET
        arr = np.zeros(grid.shape, np.float32)
        back.copyToArray(arr, ijk=(0, 0, 0))
        assert np.array_equal(arr, field)
        # node (i, j, k) sits at origin + h (i, j, k) in world space
        xyz = back.transform.indexToWorld((3, 2, 1))
        assert np.allclose(xyz, np.asarray(grid.origin) + 0.1 * np.array([3, 2, 1]))
    coll = bpy.data.collections.new("Volumes")
    bpy.context.scene.collection.children.link(coll)
    obj = volumes.add_volume_object(coll, "KFI Volume", paths, 3)
    assert obj.type == "VOLUME" and obj.data.is_sequence and obj.data.frame_duration == 2
    bpy.context.scene.frame_set(4)
    obj.data.grids.load()
    assert obj.data.grids.is_loaded and obj.data.grids[0].name == volumes.GRID_NAME
