"""Command line: ``python -m keyframe_implicit {bake,farm,demo} ...`` (needs the bpy module).

``bake SCENE.blend --out OUT.blend [--resolution N]``
    Open SCENE.blend, bake its Keyframe Implicit setup (blocking, same code as
    the Bake button) and save the result to OUT.blend. Exit status 0 on
    success, 1 when the bake fails (the message says why and what to do),
    2 on bad arguments.
``farm STAGE ...``
    The bake's stages one at a time, for a render farm (`farm.cli`).
``demo ...``
    Forwarded to ``keyframe_implicit.demo.main(argv)``.

With a real Blender the same bake is::

    blender -b SCENE.blend --python-expr "import bpy; bpy.ops.keyframe_implicit.bake()"

(with the extension enabled; add ``bpy.ops.wm.save_mainfile()`` to keep it).
"""

from __future__ import annotations

import argparse
import os
import sys


def _parser():
    p = argparse.ArgumentParser(prog="python -m keyframe_implicit",
                                description="Keyframe Animation of Implicit Models, headless.")
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("bake", help="bake a .blend file's setup and save the result")
    b.add_argument("scene", help="input .blend with a Keyframe Implicit setup")
    b.add_argument("--out", required=True, help="where to save the baked .blend")
    b.add_argument("--resolution", type=int, default=0,
                   help="grid resolution for this run (default: the scene's setting)")
    sub.add_parser("farm", help="run one stage of the bake, for a render farm", add_help=False)
    sub.add_parser("demo", help="run the demo (arguments are passed on)", add_help=False)
    return p


def check_paths(scene_path=None, out_path=None):
    """ValueError saying what to fix when ``scene_path`` is not a file or the folder of
    ``out_path`` does not exist (None: not checked); before bpy is needed."""
    if scene_path is not None and not os.path.isfile(scene_path):
        raise ValueError(f"No such file: {scene_path!r}: give the path of a .blend file.")
    out_dir = None if out_path is None else os.path.dirname(os.path.abspath(out_path))
    if out_dir is not None and not os.path.isdir(out_dir):
        raise ValueError(f"Output folder {out_dir!r} does not exist: create it first.")


def percent_log(prefix, log=print):
    """A progress callback ``(fraction, message)`` that logs a line ``[prefix] NN% message``
    every 10 percent and at the end."""
    last = [-1]

    def report(fraction, message):
        pct = int(100 * fraction)
        if pct >= last[0] + 10 or pct == 100:
            last[0] = pct
            log(f"[{prefix}] {pct:3d}% {message}")

    return report


def bake_file(scene_path, out_path, resolution=0, log=print):
    """Open ``scene_path``, bake every scene that has keyframes, save to ``out_path``.

    Raises ValueError with a user-facing message on failure.
    """
    if resolution < 0:
        raise ValueError(f"--resolution must be positive, got {resolution}.")
    check_paths(scene_path, out_path)
    from .blender import bake

    for scene, depsgraph in bake.open_file(scene_path):
        report = percent_log(scene.name, log)
        obj = bake.bake_scene(scene, resolution, depsgraph,
                              on_progress=lambda _job, fraction, text: report(fraction, text))
        first, last = obj["kfi_frames"]
        log(f"[{scene.name}] baked '{obj.name}': frames {first}-{last}, "
            f"{len(obj.data.vertices)} vertices")
    bake.save_copy(out_path)
    log(f"saved {out_path}")


def failure_line(what, exc):
    """The line a command prints when ``what`` failed with ``exc``: the text alone for the
    failures that say what happened and what to do in their own words, else with the
    exception's type."""
    from .core.base.progress import Cancelled
    from .worker import WorkerError

    told = isinstance(exc, (ValueError, Cancelled, WorkerError))
    return f"error: {what} failed: {'' if told else f'{type(exc).__name__}: '}{exc}"


def main(argv=None):
    """Run the command line (module docstring) on ``argv``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "demo":
        from . import demo  # written separately; imported only when asked for

        return demo.main(argv[1:])
    if argv and argv[0] == "farm":
        from .farm import cli

        return cli.main(argv[1:])
    args = _parser().parse_args(argv)
    try:
        bake_file(args.scene, args.out, args.resolution)
    except ImportError as exc:
        print(f"error: {exc}: the bake needs the bpy module (pip install bpy) or a real Blender.",
              file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - every failure becomes a message and exit 1
        print(failure_line("bake", exc), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
