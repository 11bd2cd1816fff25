"""Export Farm Job in the panel: the job template written beside the saved .blend, with a
copy of it, Prepare and Maps pointed at the work this session kept; refused, with the
reason on the button, before the file is saved; the scene untouched."""

import json

import bpy

from keyframe_implicit.blender import farm, work_cache


def _setup(kfi):
    kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (1.5, 0, 0), 1, 5),
                       ("C", (3.0, 0, 0), 1, 9)])


def test_export_writes_the_job_beside_the_saved_file(scene, kfi, tmp_path):
    _setup(kfi)
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    before = kfi.snapshot()
    assert bpy.ops.keyframe_implicit.export_farm_job() == {"FINISHED"}
    job = tmp_path / "shot_farm"
    assert job == tmp_path / farm.job_dir_of(str(path))
    text = (job / "template.yaml").read_text()
    assert 'specificationVersion: "jobtemplate-2023-09"' in text
    assert text.count('range: "1-2"') == 2  # a task per pair and per segment
    assert 'default: "shot.blend"' in text and (job / "shot.blend").read_bytes() == path.read_bytes()
    assert f'default: {bpy.app.binary_path!r}'.replace("'", '"') in text  # the Blender stages
    # Prepare and Maps take what this session's bakes kept
    assert f"default: {json.dumps(work_cache.directory())}" in text
    assert text.count("--cache={{Param.WorkCache}}") == 2
    assert kfi.snapshot() == before


def test_export_waits_for_a_saved_file(scene, kfi, tmp_path):
    _setup(kfi)
    assert not bpy.ops.keyframe_implicit.export_farm_job.poll()  # never saved
    assert not (tmp_path / "shot_farm").exists()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    assert bpy.ops.keyframe_implicit.export_farm_job.poll()
