"""The bake's stages run one by one over a job directory (`keyframe_implicit.farm`): the
assembled result is the local bake's, a rerun writes the same frames, and what a stage
cannot use is refused with the command that makes it."""

import json
import os
import shutil

import numpy as np
import pytest

from benchmark_modules import load
from keyframe_implicit.core import Grid
from keyframe_implicit.core.bake.cache import WorkCache
from keyframe_implicit.core.bake.options import BakeOptions
from keyframe_implicit.core.bake.pipeline import bake
from keyframe_implicit.core.map.tear import Tear
from keyframe_implicit.core.motion.spline import Bend
from keyframe_implicit.core.surface.attributes import MeshAttributes
from keyframe_implicit.farm import stages, store

bench = load("bench_smooth")
RESOLUTION = 20
SOURCE = {"scene": "arc.blend", "scene_name": "arc"}


def _arguments(resolution=RESOLUTION, **options):
    kfs, feats = bench.ball_arc((1, 5, 9))  # three keyframes: the paths bend at the middle
    return dict(keyframes=kfs, features=feats,
                options=BakeOptions.from_keywords(resolution=resolution, **options))


def _run_all(job_dir, arguments):
    stages.prepare(arguments, "AUTO", job_dir, SOURCE)
    for i in (1, 2):
        stages.solve_pair(job_dir, i)
    stages.bend_paths(job_dir)
    for i in (1, 2):
        stages.make_segment(job_dir, i)


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    job_dir = str(tmp_path_factory.mktemp("job"))
    _run_all(job_dir, _arguments())
    return job_dir


@pytest.fixture
def job_copy(job, tmp_path):
    return shutil.copytree(job, tmp_path / "job")


def test_the_assembled_bake_is_the_local_bake_on_every_frame(job):
    local = bake(**_arguments(processes=2))
    farm = stages.assemble(job)
    np.testing.assert_array_equal(farm.frames, local.frames)
    np.testing.assert_allclose(farm.vertices, local.vertices, rtol=0, atol=1e-6)
    assert len(farm.surfaces) == len(local.surfaces) == 9
    for (fv, ff), (lv, lf), f_vel, l_vel in zip(farm.surfaces, local.surfaces,
                                                farm.velocities, local.velocities):
        np.testing.assert_array_equal(ff, lf)
        np.testing.assert_allclose(fv, lv, rtol=0, atol=1e-6)
        np.testing.assert_allclose(f_vel, l_vel, rtol=0, atol=1e-6)
    assert farm.stats["output"] == local.stats["output"]
    kind = farm.stats["output"]
    np.testing.assert_allclose(farm.output_mesh(kind).positions,
                               local.output_mesh(kind).positions, rtol=0, atol=1e-6)


def test_the_paths_bend_through_the_middle_keyframe(job):
    files = stages.JobFiles(job)
    first, second = (store.load(files.paths(i)) for i in (1, 2))
    # per segment, the forward and the backward transport's bends
    assert all(isinstance(b, Bend) for paths in (first, second) for b in paths["bends"])
    assert np.abs(first["bends"][0].end).max() > 0 and np.abs(second["bends"][0].start).max() > 0
    # the second segment starts where the first one's template ends, on keyframe 2
    local = bake(**_arguments(surfaces=False, coverage=False))
    np.testing.assert_allclose(second["start"], local.vertices[4], rtol=0, atol=1e-6)


def test_rerunning_a_segment_writes_the_same_frames(job_copy):
    path = stages.JobFiles(job_copy).segment(2)
    before = store.load(path)
    stages.make_segment(str(job_copy), 2)
    after = store.load(path)
    assert store.fingerprint(after["records"]) == store.fingerprint(before["records"])
    np.testing.assert_array_equal(after["frames"], before["frames"])


def test_assemble_names_the_missing_segment_and_its_command(job_copy):
    os.remove(stages.JobFiles(job_copy).segment(2))
    with pytest.raises(store.JobError, match=r"lacks the frames of segment 2 of 2: run "
                                             r"'farm segment .* --segment 2'"):
        stages.assemble(str(job_copy))


def test_files_made_for_other_inputs_are_refused(job_copy):
    stages.prepare(_arguments(RESOLUTION + 2), "AUTO", str(job_copy), SOURCE)
    with pytest.raises(store.JobError, match=r"pair_1.npz' was made for other inputs .* run "
                                             r"'farm maps .* --pair 1' again"):
        stages.bend_paths(str(job_copy))


def test_a_directory_of_another_version_or_none_is_refused(job_copy, tmp_path):
    manifest = job_copy / "manifest.json"
    data = json.loads(manifest.read_text())
    manifest.write_text(json.dumps(dict(data, version="0.0.1")))
    with pytest.raises(store.JobError, match=r"prepared by Keyframe Implicit 0.0.1"):
        stages.solve_pair(str(job_copy), 1)
    with pytest.raises(store.JobError, match=r"not a prepared job directory .*'farm prepare"):
        stages.solve_pair(str(tmp_path), 1)


def test_pairs_solved_in_one_task_are_the_pairs_solved_one_by_one(job_copy):
    files = stages.JobFiles(job_copy)
    alone = [store.load(files.pair(i))["maps"] for i in (1, 2)]
    for i in (1, 2):
        os.remove(files.pair(i))
    stages.solve_pair(str(job_copy), [1, 2])  # shared by this process and a helper
    for i, (res, back, _) in zip((1, 2), alone):
        shared, shared_back, _ = store.load(files.pair(i))["maps"]
        np.testing.assert_array_equal(shared.mapped, res.mapped)
        np.testing.assert_array_equal(shared_back.mapped, back.mapped)


def test_prepare_and_maps_take_the_work_the_session_kept(job, tmp_path, monkeypatch):
    kept = str(tmp_path / "kept")
    os.mkdir(kept)
    bake(**_arguments(processes=2), cache=WorkCache(kept))  # the session's Bake keeps its work
    caches = []
    real = stages.work_cache
    monkeypatch.setattr(stages, "work_cache", lambda d: caches.append(real(d)) or caches[-1])
    job_dir = str(tmp_path / "job")
    stages.prepare(_arguments(), "AUTO", job_dir, SOURCE, cache_dir=kept)
    stages.solve_pair(job_dir, [1, 2], cache_dir=kept)
    assert caches[0].counts["distance"] == {"hits": 3, "misses": 0}  # three keyframes' grids
    assert caches[1].counts["maps"] == {"hits": 2, "misses": 0}  # both pairs: nothing solved
    taken, solved = stages.JobFiles(job_dir), stages.JobFiles(job)
    for i in (1, 2):  # what the job would have solved itself
        kept_maps, own = (store.load(f.pair(i))["maps"][:2] for f in (taken, solved))
        for a, b in zip(kept_maps, own):
            np.testing.assert_array_equal(a.mapped, b.mapped)
    assert real(str(tmp_path / "not here")) is None and real("") is None


@pytest.mark.parametrize("text,pairs", [("2", [2]), ("1-3", [1, 2, 3]), ("1,3", [1, 3]),
                                        ("4-4", [4])])
def test_pairs_are_read_as_open_job_description_writes_a_chunk(text, pairs):
    from keyframe_implicit.cli.farm import _parser

    assert _parser().parse_args(["maps", "DIR", "--pair", text]).pair == pairs


def test_a_pair_out_of_range_is_refused(job):
    with pytest.raises(store.JobError, match=r"--pair must be from 1 to 2 .* got 3"):
        stages.solve_pair(job, 3)


def test_bad_input_is_refused_before_any_file_is_written(tmp_path):
    arguments = _arguments()
    arguments["features"] = arguments["features"][:1]
    with pytest.raises(ValueError, match="feature"):
        stages.prepare(arguments, "AUTO", str(tmp_path), SOURCE)
    assert os.listdir(tmp_path) == []


def test_the_store_keeps_classes_keys_and_types_and_holds_no_pickle(tmp_path):
    grid = Grid((0.0, 1.0, 2.0), 0.5, (3, 4, 5))
    attrs = MeshAttributes.from_triangles([[0, 1, 2]])
    tear = Tear(np.arange(6).reshape(2, 3), np.ones((1, 2), bool), [2, 1], 0.25)
    value = {0: (np.float32(1.5), [True, None, "x"]), "g": grid, "a": attrs,
             "b": Bend(np.ones((2, 3)), np.zeros((2, 3))), "t": tear}
    store.save(tmp_path / "v.npz", value)
    back = store.load(tmp_path / "v.npz")
    assert back[0] == (1.5, [True, None, "x"]) and back["g"] == grid
    np.testing.assert_array_equal(back["a"].loop_vertices, attrs.loop_vertices)
    np.testing.assert_array_equal(back["b"].start, np.ones((2, 3)))
    assert back["t"].stats == tear.stats and back["t"].target.tolist() == [2, 1]
    with np.load(tmp_path / "v.npz", allow_pickle=False) as z:
        assert all(z[k].dtype != object for k in z.files)
    with pytest.raises(TypeError, match="cannot hold a builtins.set"):
        store.save(tmp_path / "w.npz", {1, 2})
    assert not (tmp_path / "w.npz").exists()


def test_blender_stages_run_inside_the_blender_given(monkeypatch):
    from keyframe_implicit.cli import farm as cli

    calls = []
    monkeypatch.setattr(cli.subprocess, "call", lambda argv: calls.append(argv) or 0)
    assert cli.main(["prepare", "s.blend", "job", "--resolution", "40",
                     "--blender=/opt/blender/blender"]) == 0
    (argv,) = calls
    assert argv[:4] == ["/opt/blender/blender", "-b", "--factory-startup",
                        "--python-use-system-env"]
    assert argv[argv.index("--"):] == ["--", "farm", "prepare", "s.blend", "job",
                                       "--resolution", "40"]
