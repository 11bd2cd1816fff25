"""Work kept between bakes (`blender.work_cache`): a re-bake after one Empty moved takes the
distance fields and the other pair's maps from the folder the earlier bake's worker left them
in; Clear Cache empties it."""

import os

import bpy

from keyframe_implicit.blender import bake, features, work_cache

# Three unit spheres: two pairs of four feature points each.
THREE = [("K0", (0, 0, 0), 1.0, 1), ("K1", (1.2, 0, 0), 1.0, 4), ("K2", (1.2, 1.2, 0), 1.0, 7)]


def _bake(scene, kfi):
    job = bake.BakeJob(bake.collect(scene, bpy.context.evaluated_depsgraph_get(), kfi.RES))
    assert job.run() == bake.DONE, job.error_message()
    return job.result


def test_rebake_after_one_empty_moved_solves_only_its_pair_and_clear_cache_empties_it(scene, kfi):
    kfi.build_spheres(THREE)
    first = _bake(scene, kfi)
    folder = work_cache.directory()
    assert first.stats["kept"] == {"distance": 0, "maps": 0}
    assert len(os.listdir(folder)) == 5  # three distance fields, two pairs' maps
    empty = next(p.a for p in features.pairs(scene).values() if p.segment == 1)
    empty.location.x += 0.1 * first.grid.spacing  # within its cell
    again = _bake(scene, kfi)
    assert again.grid == first.grid
    assert again.stats["kept"] == {"distance": 3, "maps": 1}
    assert bpy.ops.keyframe_implicit.clear_cache() == {"FINISHED"}
    assert os.listdir(folder) == []
    assert _bake(scene, kfi).stats["kept"] == {"distance": 0, "maps": 0}


def test_the_folder_is_in_blenders_temporary_directory_not_the_add_on(monkeypatch):
    monkeypatch.undo()  # the folder of its own each test gets (conftest)
    folder = work_cache.directory()
    assert bpy.app.tempdir and folder.startswith(bpy.app.tempdir)
    package = os.path.dirname(os.path.dirname(os.path.abspath(work_cache.__file__)))
    assert os.path.commonpath([os.path.abspath(folder), package]) != package
