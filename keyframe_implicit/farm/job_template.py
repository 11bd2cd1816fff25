"""The bake as an Open Job Description job template (``jobtemplate-2023-09``).

Steps, each a command of this package's farm command line (`cli.farm`):

    Prepare -> Maps (a task per keyframe pair) -> Paths -> Segments (a task per segment)
    -> Assemble

Maps' tasks are run in chunks of ``PairsPerTask`` pairs (the ``TASK_CHUNKING`` extension):
a chunk shares its pairs' maps between the task's two processes, each taking the next map
when it is free, as the local bake does; one pair alone leaves a core idle while its
longer map ends (benchmarks/README.md, "Render farm").

Paths is one short task between the two parallel steps: a segment's paths bend with its
neighbours' maps (docs/method.md, section 12), and a segment starts from the tracked mesh
where the one before it ended. Job parameters: the .blend, the job directory, the output
.blend, the resolution, the Python that runs the stages and its PYTHONPATH, optionally
a Blender executable for the two stages that read and write the .blend (empty: the Python
imports the bpy module), and the folder where the exporting session's bakes kept their work
(``WorkCache``: Prepare and Maps take what it holds for the job's inputs where that folder
exists, as when ``openjd run`` runs beside the Blender that wrote the job).
``openjd run DIR/template.yaml`` runs the whole job with the defaults written here;
``deadline bundle submit DIR`` sends it to AWS Deadline Cloud. The job directory is
self-contained: it holds a copy of the .blend (Open Job Description resolves a path's
default inside the job template's folder).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from typing import Any

from ..worker import python_path as worker_path

__all__ = ["job_template", "write_job_template", "to_yaml", "JOB_TEMPLATE"]

JOB_TEMPLATE = "template.yaml"
#: Default of the job parameter PairsPerTask (module docstring).
PAIRS_PER_TASK = 3
_PACKAGE = __package__.rsplit(".", 1)[0].rsplit(".", 1)[-1]  # as `python -m` names it


def _stage(*args):
    """The onRun action of a step that runs ``farm`` with ``args``."""
    return {"actions": {"onRun": {"command": "{{Param.Python}}",
                                  "args": ["-m", _PACKAGE, "farm", *args]}}}


def _tasks(name, count, chunk=None):
    """A parameter space of one task per number 1..``count``, run ``chunk`` (a job
    parameter's name) at a time when given."""
    task = {"name": name, "type": "INT", "range": f"1-{count}"}
    if chunk is not None:
        task.update(type="CHUNK[INT]", chunks={"defaultTaskCount": f"{{{{Param.{chunk}}}}}",
                                               "rangeConstraint": "CONTIGUOUS"})
    return {"taskParameterDefinitions": [task]}


def job_template(job_dir: str, blend_path: str, segments: int, resolution: int,
                 python: str | None = None, python_path: str | None = None,
                 blender: str = "", cache: str = "") -> dict[str, Any]:
    """The job template as a dict (see the module docstring)."""
    job_dir = os.path.abspath(job_dir)
    params = [
        # a PATH's default lies in the job template's folder, the job directory
        dict(name="BlendFile", type="PATH", objectType="FILE", dataFlow="IN",
             default=os.path.basename(blend_path),
             description="The scene to bake (a copy of the scene the job was written for)."),
        dict(name="JobDir", type="PATH", objectType="DIRECTORY", dataFlow="OUT",
             default=".", description="Where the stages keep their files."),
        dict(name="OutputFile", type="PATH", objectType="FILE", dataFlow="OUT",
             default="baked.blend", description="The baked .blend."),
        dict(name="Resolution", type="INT", default=int(resolution), minValue=4,
             maxValue=1024, description="Grid cells along the keyframes' longest side."),
        dict(name="PairsPerTask", type="INT", default=PAIRS_PER_TASK, minValue=1,
             description="Keyframe pairs whose maps one task of Maps solves, sharing its "
                         "two processes."),
        dict(name="Python", type="STRING", default=python or sys.executable,
             description="The Python that runs the stages (with the bpy module, unless "
                         "Blender is set)."),
        dict(name="PythonPath", type="STRING", default=python_path or worker_path(),
             description="PYTHONPATH of the stages: the folder holding the add-on, and its "
                         "numpy, scipy and scikit-image."),
        dict(name="Blender", type="STRING", default=blender or "", minLength=0,
             description="A Blender executable for Prepare and Assemble (empty: Python "
                         "imports bpy)."),
        dict(name="WorkCache", type="STRING", default=cache or "", minLength=0,
             description="The folder of the work the exporting session kept, which Prepare "
                         "and Maps take from where it exists (empty: none)."),
    ]
    pair, segment = "{{Task.Param.Pair}}", "{{Task.Param.Segment}}"
    steps = [
        dict(name="Prepare", script=_stage(
            "prepare", "{{Param.BlendFile}}", "{{Param.JobDir}}", "--resolution",
            "{{Param.Resolution}}", "--segments", str(int(segments)),
            "--blender={{Param.Blender}}", "--cache={{Param.WorkCache}}")),
        dict(name="Maps", dependencies=[{"dependsOn": "Prepare"}],
             parameterSpace=_tasks("Pair", segments, chunk="PairsPerTask"),
             script=_stage("maps", "{{Param.JobDir}}", "--pair", pair,
                           "--cache={{Param.WorkCache}}")),
        dict(name="Paths", dependencies=[{"dependsOn": "Maps"}],
             script=_stage("paths", "{{Param.JobDir}}")),
        dict(name="Segments", dependencies=[{"dependsOn": "Paths"}],
             parameterSpace=_tasks("Segment", segments),
             script=_stage("segment", "{{Param.JobDir}}", "--segment", segment)),
        dict(name="Assemble", dependencies=[{"dependsOn": "Segments"}],
             script=_stage("assemble", "{{Param.JobDir}}", "--out", "{{Param.OutputFile}}",
                           "--scene", "{{Param.BlendFile}}", "--blender={{Param.Blender}}")),
    ]
    return {
        "specificationVersion": "jobtemplate-2023-09",
        "extensions": ["TASK_CHUNKING"],
        "name": "Keyframe Implicit bake",
        "parameterDefinitions": params,
        "jobEnvironments": [{"name": "KeyframeImplicit",
                             "variables": {"PYTHONPATH": "{{Param.PythonPath}}"}}],
        "steps": steps,
    }


def to_yaml(value: object, indent: int = 0) -> str:
    """``value`` (dicts, lists, strings, numbers) as block YAML; strings double-quoted."""
    pad = " " * indent
    if isinstance(value, dict):
        lines = []
        for key, item in value.items():
            if isinstance(item, (dict, list)) and item:
                lines.append(f"{pad}{key}:\n{to_yaml(item, indent + 2)}")
            else:
                lines.append(f"{pad}{key}: {json.dumps(item)}")
        return "\n".join(lines)
    if isinstance(value, list):
        lines = []
        for item in value:
            body = to_yaml(item, indent + 2) if isinstance(item, (dict, list)) else (
                " " * (indent + 2) + json.dumps(item))
            lines.append(f"{pad}- {body[indent + 2:]}")
        return "\n".join(lines)
    return pad + json.dumps(value)


def write_job_template(job_dir: str, blend_path: str, segments: int, resolution: int,
                       **kwargs: str | None) -> str:
    """Write DIR/template.yaml (`job_template`'s keywords); returns its path."""
    os.makedirs(job_dir, exist_ok=True)
    copy = os.path.join(job_dir, os.path.basename(blend_path))
    if not os.path.exists(copy) or not os.path.samefile(blend_path, copy):
        shutil.copyfile(blend_path, copy)  # the job's input: a farm sends the bundle whole
    path = os.path.join(job_dir, JOB_TEMPLATE)
    with open(path, "w") as f:
        f.write(to_yaml(job_template(job_dir, blend_path, segments, resolution, **kwargs))
                + "\n")
    return path
