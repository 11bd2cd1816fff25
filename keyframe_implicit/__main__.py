"""Command line: ``python -m keyframe_implicit {bake,farm,demo} ...`` (needs the bpy module).

``bake SCENE.blend --out OUT.blend [--resolution N]``
    Open SCENE.blend, bake its Keyframe Implicit setup (blocking, same code as
    the Bake button) and save the result to OUT.blend. Exit status 0 on
    success, 1 when the bake fails (the message says why and what to do),
    2 on bad arguments (`cli.bake`).
``farm STAGE ...``
    The bake's stages one at a time, for a render farm (`cli.farm`).
``demo ...``
    Bake an example scene, save it, render a contact sheet (`cli.demo`).

This module only reads the command's name and hands the rest of the arguments to its
module's ``main`` in `keyframe_implicit.cli`.

With a real Blender the same bake is::

    blender -b SCENE.blend --python-expr "import bpy; bpy.ops.keyframe_implicit.bake()"

(with the extension enabled; add ``bpy.ops.wm.save_mainfile()`` to keep it).
"""

from __future__ import annotations

import argparse
import sys

COMMANDS = ("bake", "farm", "demo")


def _parser():
    """The commands, for ``--help`` and for a command line that names none of them."""
    p = argparse.ArgumentParser(prog="python -m keyframe_implicit",
                                description="Keyframe Animation of Implicit Models, headless.")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("bake", help="bake a .blend file's setup and save the result", add_help=False)
    sub.add_parser("farm", help="run one stage of the bake, for a render farm", add_help=False)
    sub.add_parser("demo", help="run the demo (arguments are passed on)", add_help=False)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the command line (module docstring) on ``argv``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in COMMANDS:
        _parser().parse_args(argv)  # --help, or a usage error: exits
    if argv[0] == "bake":  # only the command asked for is imported
        from .cli import bake as command
    elif argv[0] == "farm":
        from .cli import farm as command
    else:
        from .cli import demo as command
    return command.main(argv[1:])


if __name__ == "__main__":
    sys.exit(main())
