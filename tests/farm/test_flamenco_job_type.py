"""The Flamenco job type compiled by node with a stand-in for Flamenco's ``author`` API: the
same stages, in the same order, as the Open Job Description job template. (No Flamenco
Manager runs here; this checks the script's syntax and the task graph it builds.)"""

import json
import pathlib
import shutil
import subprocess

import pytest

from keyframe_implicit.farm import job_template

SCRIPT = (pathlib.Path(job_template.__file__).parent / "flamenco" / "keyframe_implicit_bake.js")

HARNESS = """
const fs = require("fs"), vm = require("vm");
const tasks = [];
const author = {
  Task: (name, type) => {
    const t = {name, type, commands: [], deps: []};
    t.addCommand = (c) => t.commands.push(c);
    t.addDependency = (d) => t.deps.push(d.name);
    return t;
  },
  Command: (name, parameters) => ({name, parameters}),
};
const job = {settings: JSON.parse(process.argv[2]), addTask: (t) => tasks.push(t)};
const context = {author, job, String};
vm.createContext(context);
vm.runInContext(fs.readFileSync(process.argv[1], "utf8") + "\\ncompileJob(job);", context);
console.log(JSON.stringify({tasks, settings: vm.runInContext("JOB_TYPE", context).settings}));
"""


def _compile(settings):
    node = shutil.which("node")
    assert node, "node (Node.js) checks the Flamenco job type: install it (apt install nodejs)"
    done = subprocess.run([node, "-e", HARNESS, "--", str(SCRIPT), json.dumps(settings)],
                          capture_output=True, text=True)
    return done


def test_the_job_type_compiles_into_the_stages_with_their_dependencies():
    settings = {"blendfile": "/shots/splash.blend", "job_dir": "/shots/splash_farm",
                "output_file": "/shots/splash_baked.blend", "resolution": 64, "segments": 3,
                "pairs_per_task": 1}
    done = _compile(settings)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    tasks = {t["name"]: t for t in out["tasks"]}
    assert list(tasks) == ["prepare", "maps-1", "maps-2", "maps-3", "paths", "segment-1",
                           "segment-2", "segment-3", "assemble"]
    assert tasks["maps-2"]["deps"] == ["prepare"]
    assert tasks["paths"]["deps"] == ["maps-1", "maps-2", "maps-3"]
    assert tasks["assemble"]["deps"] == ["segment-1", "segment-2", "segment-3"]
    command = tasks["segment-2"]["commands"][0]
    assert command["name"] == "blender-render"
    args = command["parameters"]["args"]
    assert args[args.index("--") + 1:] == ["farm", "segment", "/shots/splash_farm",
                                          "--segment", "2"]
    prepare = tasks["prepare"]["commands"][0]["parameters"]["args"]
    assert prepare[-4:] == ["--resolution", "64", "--segments", "3"]
    assert {s["key"] for s in out["settings"]} == {"blendfile", "job_dir", "output_file",
                                                   "resolution", "pairs_per_task", "segments"}


@pytest.mark.parametrize("chunk,maps", [(2, {"maps-1-2": "1-2", "maps-3": "3"}),
                                        (3, {"maps-1-3": "1-3"}), (5, {"maps-1-3": "1-3"})])
def test_maps_tasks_take_pairs_per_task_pairs_as_the_job_template_chunks_them(chunk, maps):
    settings = {"blendfile": "s.blend", "job_dir": "d", "output_file": "o.blend",
                "resolution": 48, "segments": 3, "pairs_per_task": chunk}
    done = _compile(settings)
    assert done.returncode == 0, done.stderr
    tasks = {t["name"]: t for t in json.loads(done.stdout)["tasks"]}
    made = {name: t["commands"][0]["parameters"]["args"][-1] for name, t in tasks.items()
            if name.startswith("maps")}
    assert made == maps
    assert tasks["paths"]["deps"] == list(maps)


def test_a_scene_without_a_pair_of_keyframes_is_refused():
    done = _compile({"blendfile": "a.blend", "job_dir": "d", "output_file": "o.blend",
                     "resolution": 48, "segments": 0})
    assert done.returncode != 0 and "at least 1" in done.stderr
