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



TWO = [("KA", (0.0, 0.0, 0.0), 1.0, 1), ("KB", (1.5, 0.0, 0.0), 1.0, 7)]


def _tagged_volumes():
    from keyframe_implicit.blender.output import VOLUME_TAG

    return [o for o in bpy.data.objects if o.get(VOLUME_TAG)]


def test_bake_with_volume_export_writes_a_playing_vdb_sequence(scene, kfi, tmp_path):
    vdb, reason = volumes.openvdb_module()
    if vdb is None:
        assert bpy.app.version < (4, 4), "Blender 4.4+ ships openvdb: " + reason
        pytest.skip(reason)
    kfi.build_spheres(TWO)
    settings = scene.keyframe_implicit
    settings.volume_export = True
    settings.volume_directory = str(tmp_path) + "/"
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    out = settings.output_object
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == [f"KFI_Animation_{f:04d}.vdb" for f in range(1, 8)]
    [vol] = _tagged_volumes()
    assert vol.parent == out and vol.users_collection == out.users_collection
    assert vol.data.frame_duration == 7 and vol.data.is_sequence
    # frame 4's file: the voxels inside hold about the volume of the unit sphere
    grid = vdb.read(str(tmp_path / files[3]), volumes.GRID_NAME)
    h = grid.transform.voxelSize()[0]
    lo, hi = grid.evalActiveVoxelBoundingBox()
    arr = np.zeros(np.array(hi) - np.array(lo) + 1, np.float32)
    grid.copyToArray(arr, ijk=lo)
    assert abs((arr < 0).sum() * h ** 3 / (4 / 3 * np.pi) - 1) < 0.15
    scene.frame_set(4)
    vol.data.grids.load()
    assert vol.data.grids.is_loaded and vol.data.grids[0].name == volumes.GRID_NAME
    # a second bake replaces the volume with the mesh
    assert bpy.ops.keyframe_implicit.bake(resolution=kfi.RES) == {"FINISHED"}
    assert [v.parent for v in _tagged_volumes()] == [settings.output_object]
    assert len(bpy.data.volumes) == 1


def test_volume_export_into_an_unsaved_files_folder_is_refused_before_baking(scene, kfi):
    if volumes.openvdb_module()[0] is None:
        settings = scene.keyframe_implicit
        settings.volume_export = True
        assert "turn OpenVDB Volume off" in volumes.problem(settings)
        return
    kfi.build_spheres(TWO)
    settings = scene.keyframe_implicit
    settings.volume_export = True
    assert settings.volume_directory.startswith("//") and not bpy.data.filepath
    state = kfi.snapshot()
    from keyframe_implicit.blender import bake

    with pytest.raises(ValueError, match="save the file or pick an absolute folder"):
        bake.bake_scene(scene, resolution=kfi.RES)
    assert kfi.snapshot() == state
