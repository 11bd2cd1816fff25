"""The job directory: each stage's output is one file, written whole or not at all.

Every file is a ``.npz`` of plain arrays (read with ``allow_pickle=False``) beside a JSON
tree that names them, so a job directory can come from another machine without running
anything it holds. Classes are rebuilt only from this package's own list (`_classes`).

A file carries the fingerprint of the inputs ``prepare`` read (`fingerprint`); a stage
refuses a file made for other inputs, and the manifest (`read_manifest`) refuses a
directory written by another version of the add-on.

The classes are imported when a file is first written or read (`_classes`): they import
the core's bake, which the command line's ``--help`` and the manifest's readers do without.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..version import __version__

__all__ = ["save", "load", "fingerprint", "write_manifest", "read_manifest", "JobError",
           "FORMAT"]

#: The job directory's layout version: a directory of another layout is refused.
FORMAT = 2
MANIFEST = "manifest.json"


class JobError(ValueError):
    """A job directory that cannot be used as it is: the text names the file and the
    command that makes it again."""


def _classes():
    """The classes a job file may hold, by name: {name: (class, fields of an object)}."""
    from ..core.bake.options import BakeOptions
    from ..core.bake.keyframe import Keyframe
    from ..core.bake.pipeline import BakePlan
    from ..core.base.grid import Grid
    from ..core.map.options import MapOptions
    from ..core.map.result import MapResult
    from ..core.map.tear import Tear
    from ..core.motion.options import MotionOptions
    from ..core.motion.spline import Bend
    from ..core.surface.attributes import MeshAttributes
    from ..core.surface.options import SurfaceOptions

    def fields(obj):
        return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj) if f.init}

    table = {cls.__name__: (cls, fields)
             for cls in (BakePlan, Keyframe, Grid, MapResult, MeshAttributes, BakeOptions,
                         MapOptions, MotionOptions, SurfaceOptions)}
    table["Bend"] = (Bend, lambda b: {"start": b.start, "end": b.end})
    table["Tear"] = (Tear, lambda t: {"piece": t.piece, "crack": t.crack, "target": t.target,
                                      "crack_material": t.stats["crack_material"]})
    return table


def _encode(obj, arrays, classes):
    """``obj`` as a JSON-able tree; its arrays appended to ``arrays``."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, float, np.integer, np.floating, np.bool_)):
        return obj.item() if isinstance(obj, np.generic) else obj
    if isinstance(obj, np.ndarray):
        arrays.append(np.ascontiguousarray(obj))
        return {"$array": len(arrays) - 1}
    if isinstance(obj, (list, tuple)):
        items = [_encode(v, arrays, classes) for v in obj]
        return items if isinstance(obj, list) else {"$tuple": items}
    if isinstance(obj, dict):
        return {"$dict": [[_encode(k, arrays, classes), _encode(v, arrays, classes)]
                          for k, v in obj.items()]}
    name = type(obj).__name__
    if name in classes and isinstance(obj, classes[name][0]):
        return {"$class": name, "fields": _encode(classes[name][1](obj), arrays, classes)}
    raise TypeError(f"a job file cannot hold a {type(obj).__module__}.{name}")


def _decode(tree, arrays, classes):
    if isinstance(tree, list):
        return [_decode(v, arrays, classes) for v in tree]
    if not isinstance(tree, dict):
        return tree
    if "$array" in tree:
        return arrays[f"a{tree['$array']}"]
    if "$tuple" in tree:
        return tuple(_decode(v, arrays, classes) for v in tree["$tuple"])
    if "$dict" in tree:
        return {_decode(k, arrays, classes): _decode(v, arrays, classes)
                for k, v in tree["$dict"]}
    return classes[tree["$class"]][0](**_decode(tree["fields"], arrays, classes))


def _tree(obj):
    arrays = []
    return json.dumps(_encode(obj, arrays, _classes())), arrays


def fingerprint(obj: object) -> str:
    """A hex digest of ``obj``'s content: its tree and every array's type, shape and bytes."""
    text, arrays = _tree(obj)
    h = hashlib.sha256(text.encode())
    for a in arrays:
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def save(path: str, obj: object) -> None:
    """Write ``obj`` to ``path`` (a .npz) whole: written beside it, then moved in place, so
    a task stopped half way leaves the old file or none, and a rerun replaces it."""
    text, arrays = _tree(obj)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".npz", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, tree=np.array(text), **{f"a{i}": a for i, a in enumerate(arrays)})
        os.chmod(tmp, 0o644)  # as a plain file would be: other farm users read it
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def load(path: str) -> Any:
    """The object `save` wrote to ``path``."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k != "tree"}
        return _decode(json.loads(str(z["tree"])), arrays, _classes())


def write_manifest(job_dir: str, manifest: Mapping[str, Any]) -> None:
    """Write DIR/manifest.json: ``manifest`` plus the layout and the add-on's version."""
    data = dict(manifest, format=FORMAT, version=__version__)
    path = os.path.join(job_dir, MANIFEST)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(data, f, indent=2)
    os.replace(tmp, path)


def read_manifest(job_dir: str) -> dict[str, Any]:
    """DIR/manifest.json, or `JobError` when there is none or another version wrote it."""
    path = os.path.join(job_dir, MANIFEST)
    if not os.path.isfile(path):
        raise JobError(f"{job_dir!r} is not a prepared job directory (no {MANIFEST}): run "
                       f"'farm prepare SCENE.blend {job_dir}' first.")
    with open(path) as f:
        data = json.load(f)
    if data.get("format") != FORMAT or data.get("version") != __version__:
        raise JobError(f"{job_dir!r} was prepared by Keyframe Implicit {data.get('version')} "
                       f"(job format {data.get('format')}); this is {__version__} (format "
                       f"{FORMAT}): run 'farm prepare' again into an empty directory.")
    return data
