"""``python -m keyframe_implicit bake SCENE.blend --out OUT.blend [--resolution N]``.

Open SCENE.blend, bake its Keyframe Implicit setup (blocking, same code as the Bake
button: `blender.bake.bake_scene`) and save the result to OUT.blend. Exit status 0 on
success, 1 when the bake fails (the message says why and what to do), 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from . import check_paths, failure_line, open_file, percent_log, save_copy

__all__ = ["bake_file", "main"]


def _parser():
    p = argparse.ArgumentParser(prog="python -m keyframe_implicit bake")
    p.add_argument("scene", help="input .blend with a Keyframe Implicit setup")
    p.add_argument("--out", required=True, help="where to save the baked .blend")
    p.add_argument("--resolution", type=int, default=0,
                   help="grid resolution for this run (default: the scene's setting)")
    return p


def bake_file(scene_path: str, out_path: str, resolution: int = 0,
              log: Callable[[str], object] = print) -> None:
    """Open ``scene_path``, bake every scene that has keyframes, save to ``out_path``.

    Raises ValueError with a user-facing message on failure.
    """
    if resolution < 0:
        raise ValueError(f"--resolution must be positive, got {resolution}.")
    check_paths(scene_path, out_path)
    from ..blender import bake  # imports bpy: only now, once the paths are checked

    for scene, depsgraph in open_file(scene_path):
        report = percent_log(scene.name, log)
        obj = bake.bake_scene(scene, resolution, depsgraph,
                              on_progress=lambda _job, fraction, text: report(fraction, text))
        first, last = obj["kfi_frames"]
        log(f"[{scene.name}] baked '{obj.name}': frames {first}-{last}, "
            f"{len(obj.data.vertices)} vertices")
    save_copy(out_path)
    log(f"saved {out_path}")


def main(argv: list[str]) -> int:
    """Bake a file (module docstring) as ``argv`` says; returns the exit status."""
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
