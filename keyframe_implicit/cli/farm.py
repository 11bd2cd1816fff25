"""``python -m keyframe_implicit farm STAGE ...``: the bake's stages one at a time.

    prepare SCENE.blend DIR [--resolution N]   read the scene as Bake does (needs bpy)
    maps DIR --pair I[-J]                      keyframes I -> I+1 (to J -> J+1): their maps
    paths DIR                                  every segment's bends and starting template
    segment DIR --segment I                    keyframes I -> I+1: their frames
    assemble DIR --out OUT.blend [--scene S]   write the result as a local bake (needs bpy)
    template DIR [--scene S.blend]             DIR/template.yaml, an Open Job Description job

``--blender PATH`` runs prepare or assemble inside that Blender (``blender -b``) instead
of importing the bpy module. ``--cache DIR`` (prepare, maps): the folder where the exporting
session's bakes kept their work (`farm.stages.work_cache`); what it holds for exactly the
job's inputs is taken, not computed again. Exit status 0 on success, 1 when the stage fails
(the message says why and what to do), 2 on bad arguments.

The stages themselves are in `farm` (bpy-free) and, for prepare and assemble, in
`blender.farm`, which imports bpy: it is imported in the functions of the stages that read
the .blend, so the others run without bpy.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

from ..farm import stages, store
from ..farm.job_template import JOB_TEMPLATE, write_job_template
from . import check_paths, failure_line, open_file, percent_log, save_copy

__all__ = ["main"]


def _parser():
    p = argparse.ArgumentParser(prog="python -m keyframe_implicit farm",
                                description="The bake's stages, for a render farm.")
    sub = p.add_subparsers(dest="stage", required=True)
    s = sub.add_parser("prepare", help="read a .blend's bake into a job directory")
    s.add_argument("scene")
    s.add_argument("dir")
    s.add_argument("--resolution", type=int, default=0,
                   help="grid resolution (default: the scene's setting)")
    s.add_argument("--segments", type=int, default=None,
                   help="refuse a scene with another number of segments")
    s.add_argument("--blender", default="", help="run inside this Blender executable")
    _cache_argument(s)
    s = sub.add_parser("maps", help="solve keyframe pairs' maps")
    s.add_argument("dir")
    s.add_argument("--pair", type=_pairs, required=True,
                   help="pair I (keyframes I -> I+1), or pairs I-J or I,J,... sharing the "
                        "task's two processes")
    _cache_argument(s)
    s = sub.add_parser("paths", help="every segment's bends and starting template")
    s.add_argument("dir")
    s = sub.add_parser("segment", help="one segment's frames")
    s.add_argument("dir")
    s.add_argument("--segment", type=int, required=True, help="keyframes I -> I+1")
    s = sub.add_parser("assemble", help="write the result into the scene and save it")
    s.add_argument("dir")
    s.add_argument("--out", required=True, help="where to save the baked .blend")
    s.add_argument("--scene", default=None, help="the .blend (default: the one prepared)")
    s.add_argument("--blender", default="", help="run inside this Blender executable")
    s = sub.add_parser("template", help="write DIR/template.yaml (Open Job Description)")
    s.add_argument("dir")
    s.add_argument("--scene", default=None,
                   help="the .blend to write it for (default: the one prepared in DIR)")
    s.add_argument("--resolution", type=int, default=0,
                   help="with --scene: grid resolution (default: the scene's setting)")
    return p


def _cache_argument(parser):
    parser.add_argument("--cache", default="",
                        help="the folder of a session's kept work (empty, or absent here: none)")


def _pairs(text):
    """``I``, ``I-J`` or ``I,J,...`` (an Open Job Description chunk) as a list of ints."""
    numbers = []
    try:
        for part in text.split(","):
            first, _, last = part.partition("-")
            numbers.extend(range(int(first), int(last or first) + 1))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a pair number, a range I-J or a "
                                         "list I,J,...") from None
    return numbers


def _log(prefix):
    return percent_log(prefix, lambda line: print(line, flush=True))


def _in_blender(blender, argv):
    """Run this command line, ``argv``, inside ``blender -b``; its exit status."""
    expr = (f"import sys; from {__package__.rsplit('.', 1)[0]}.__main__ import main; "
            "sys.exit(main(sys.argv[sys.argv.index('--') + 1:]))")
    argv = [a for a in argv if not a.startswith("--blender")]
    return subprocess.call([blender, "-b", "--factory-startup", "--python-use-system-env",
                            "--python-expr", expr, "--", "farm", *argv])


def _prepare(args):
    from ..blender.farm import prepare_scene

    check_paths(args.scene)

    for scene, depsgraph in open_file(args.scene):
        manifest = prepare_scene(scene, depsgraph, args.dir, args.scene, args.resolution,
                                 args.segments, _log("prepare"), args.cache)
        print(f"prepared '{manifest['scene_name']}': {manifest['keyframes']} keyframes, "
              f"frames {manifest['frames'][0]}-{manifest['frames'][-1]}, in {args.dir}")
        return


def _assemble(args):
    from ..blender.farm import assemble_scene

    manifest = store.read_manifest(args.dir)
    scene_path = args.scene or manifest["scene"]
    check_paths(scene_path, args.out)
    for scene, depsgraph in open_file(scene_path):
        if scene.name == manifest["scene_name"]:
            obj = assemble_scene(scene, depsgraph, args.dir, _log("assemble"))
            save_copy(args.out)
            print(f"assembled '{obj.name}' into {args.out}")
            return
    raise store.JobError(f"{scene_path!r} has no scene '{manifest['scene_name']}' with a "
                         "Keyframe Implicit setup: give the .blend the job was prepared from.")


def _job_template(args):
    if args.scene:  # read the scene (as Bake checks it), nothing baked yet
        from ..blender.farm import export_job

        check_paths(args.scene)

        for scene, depsgraph in open_file(args.scene):
            export_job(scene, depsgraph, args.scene, job_dir=args.dir,
                       resolution=args.resolution)
            break
    else:
        m = store.read_manifest(args.dir)
        write_job_template(args.dir, m["scene"], m["segments"], m["resolution"])
    path = os.path.join(args.dir, JOB_TEMPLATE)
    print(f"wrote {path}: run it with 'openjd run {path}'")


def _run(args):
    if args.stage == "prepare":
        _prepare(args)
    elif args.stage == "maps":
        stages.solve_pair(args.dir, args.pair, _log(f"maps {','.join(map(str, args.pair))}"),
                          args.cache)
    elif args.stage == "paths":
        stages.bend_paths(args.dir, _log("paths"))
    elif args.stage == "segment":
        stages.make_segment(args.dir, args.segment, _log(f"segment {args.segment}"))
    elif args.stage == "assemble":
        _assemble(args)
    else:
        _job_template(args)


def main(argv: list[str]) -> int:
    """Run one stage (module docstring); returns the exit status."""
    args = _parser().parse_args(argv)
    if getattr(args, "blender", ""):
        return _in_blender(args.blender, argv)
    try:
        _run(args)
    except ImportError as exc:
        print(f"error: {exc}: prepare and assemble need the bpy module (pip install bpy) or "
              "--blender PATH.", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - every failure becomes a message and exit 1
        print(failure_line(f"farm {args.stage}", exc), file=sys.stderr)
        return 1
    return 0
