"""The farm job end to end: the command line's stages, the Open Job Description job template
checked, parsed and run whole with ``openjd run`` on the four-keyframe splash, and its
result compared with a bake on one machine, array by array as Blender holds them."""

import json
import os
import pathlib
import subprocess
import sys

import bpy
import numpy as np
import pytest
import yaml
from openjd.model import create_job, decode_job_template

from keyframe_implicit.farm.job_template import PAIRS_PER_TASK

ROOT = pathlib.Path(__file__).resolve().parents[2]
SPLASH = ROOT / "assets" / "splash.blend"
RESOLUTION = 34  # the smallest the splash's feature points allow (one cell apart)
STEPS = ["Prepare", "Maps", "Paths", "Segments", "Assemble"]


def _command(*args, cwd):
    """``python -m keyframe_implicit ARGS`` with this checkout first on the path."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    return subprocess.run([sys.executable, "-m", "keyframe_implicit", *map(str, args)],
                          capture_output=True, text=True, env=env, cwd=cwd)


def _openjd(*args, cwd):
    exe = pathlib.Path(sys.executable).with_name("openjd")
    assert exe.exists(), "openjd-cli is in the test requirements: reinstall the environment"
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, cwd=cwd)


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    """The splash's job directory after ``openjd run`` of its job template, and the run's log."""
    work = tmp_path_factory.mktemp("farm")
    job_dir = work / "job"
    done = _command("farm", "template", job_dir, "--scene", SPLASH, "--resolution", RESOLUTION,
                    cwd=work)
    assert done.returncode == 0, done.stderr
    run = _openjd("run", job_dir / "template.yaml", cwd=work)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return job_dir, run.stdout


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    work = tmp_path_factory.mktemp("local")
    done = _command("bake", SPLASH, "--out", work / "local.blend", "--resolution", RESOLUTION,
                    cwd=work)
    assert done.returncode == 0, done.stderr
    return work / "local.blend"


def _baked_arrays(path):
    """Every array of the bake's output meshes in the .blend ``path``: points, shape keys,
    the velocity attribute, faces."""
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    out = {}
    for me in bpy.data.meshes:
        if not me.name.startswith("KFI"):
            continue
        blocks = me.shape_keys.key_blocks if me.shape_keys else []
        for name, data, prop in ([("co", me.vertices, "co")]
                                 + [(f"key {b.name}", b.data, "co") for b in blocks]):
            out[f"{me.name}: {name}"] = _get(data, prop, np.float32, 3)
        if "velocity" in me.attributes:
            out[f"{me.name}: velocity"] = _get(me.attributes["velocity"].data, "vector",
                                               np.float32, 3)
        out[f"{me.name}: corners"] = _get(me.loops, "vertex_index", np.int32, 1)
    return out


def _get(collection, prop, dtype, width):
    a = np.empty(len(collection) * width, dtype)
    collection.foreach_get(prop, a)
    return a


def test_openjd_run_bakes_exactly_what_one_machine_bakes(job, local):
    job_dir, log = job
    assert "All actions completed successfully" in log
    chunks = [line.split("= ")[-1] for line in log.splitlines() if "Pair(CHUNK[INT]) =" in line]
    assert len(chunks) == -(-3 // PAIRS_PER_TASK)  # the maps of three pairs, in chunks
    for step in STEPS:
        assert f"Running step '{step}'" in log
    farm, alone = _baked_arrays(job_dir / "baked.blend"), _baked_arrays(local)
    assert sorted(farm) == sorted(alone)
    assert any(k.endswith("velocity") for k in farm)  # the splash is a mesh sequence
    for key in alone:
        assert farm[key].shape == alone[key].shape, key
        np.testing.assert_allclose(farm[key], alone[key], rtol=0, atol=1e-6, err_msg=key)


def test_the_template_is_valid_and_has_a_task_per_pair_and_segment(job):
    job_dir, _ = job
    checked = _openjd("check", job_dir / "template.yaml", cwd=job_dir)
    assert checked.returncode == 0 and "passes validation" in checked.stdout
    template = decode_job_template(
        template=yaml.safe_load((job_dir / "template.yaml").read_text()),
        supported_extensions=["TASK_CHUNKING"])
    assert [s.name for s in template.steps] == STEPS
    made = create_job(job_template=template, job_parameter_values={})
    written = (job_dir / "template.yaml").read_text()
    done = _command("farm", "template", job_dir, cwd=job_dir)  # again, from the job's manifest
    assert done.returncode == 0 and (job_dir / "template.yaml").read_text() == written
    tasks = {s.name: s.parameterSpace for s in made.steps}
    pairs = tasks["Maps"].taskParameterDefinitions["Pair"]
    assert list(pairs.range) == [1, 2, 3] and pairs.chunks.defaultTaskCount == PAIRS_PER_TASK
    assert list(tasks["Segments"].taskParameterDefinitions["Segment"].range) == [1, 2, 3]
    assert [d.dependsOn for d in made.steps[3].dependencies] == ["Paths"]


def test_assemble_refuses_the_scene_once_it_has_changed(job, tmp_path):
    job_dir, _ = job
    bpy.ops.wm.open_mainfile(filepath=str(SPLASH), load_ui=False)
    empty = next(o for o in bpy.data.objects if o.type == "EMPTY" and o.name.startswith("KFI"))
    empty.location.x += 0.01
    changed = tmp_path / "changed.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(changed))
    done = _command("farm", "assemble", job_dir, "--out", tmp_path / "out.blend", "--scene",
                    changed, cwd=tmp_path)
    assert done.returncode == 1
    assert "not from this scene as it is now ('splash')" in done.stderr
    assert not (tmp_path / "out.blend").exists()


def test_prepare_refuses_a_scene_the_template_was_not_written_for(tmp_path):
    done = _command("farm", "prepare", SPLASH, tmp_path / "job", "--segments", 2, cwd=tmp_path)
    assert done.returncode == 1
    assert "has 3 segments but the job was written for 2" in done.stderr
    assert not (tmp_path / "job" / "manifest.json").exists()


def test_the_stages_say_what_is_missing(job, tmp_path):
    assert _command("farm", "maps", tmp_path, cwd=tmp_path).returncode == 2  # no --pair
    done = _command("farm", "maps", tmp_path, "--pair", 1, cwd=tmp_path)
    assert done.returncode == 1 and "is not a prepared job directory" in done.stderr
    manifest = json.loads((job[0] / "manifest.json").read_text())
    assert manifest["segments"] == 3 and manifest["frames"] == [1, 9, 15, 25]
