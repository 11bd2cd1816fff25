"""Headless CLI: ``python -m keyframe_implicit bake SCENE --out OUT [--resolution N]``."""

import os
import subprocess
import sys

import bpy

from keyframe_implicit.__main__ import main
from keyframe_implicit.cli.bake import bake_file

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_cli_bakes_a_saved_scene(scene, kfi, tmp_path):
    kfi.build_spheres([("A", (0, 0, 0), 1, 1), ("B", (1.5, 0, 0), 1, 4)])
    src = tmp_path / "setup.blend"
    out = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(src))
    lines = []
    bake_file(str(src), str(out), kfi.RES, log=lines.append)
    assert out.is_file()
    assert any("baked 'KFI Animation': frames 1-4" in line for line in lines)
    bpy.ops.wm.open_mainfile(filepath=str(out))
    result = bpy.context.scene.keyframe_implicit.output_object
    assert result is not None and len(result.data.shape_keys.key_blocks) == 5
    assert result["kfi_stats"]["resolution"] == kfi.RES


def test_cli_main_reports_setup_errors(scene, tmp_path, capsys):
    src = tmp_path / "empty.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(src))
    assert main(["bake", str(src), "--out", str(tmp_path / "o.blend")]) == 1
    err = capsys.readouterr().err
    assert "has no Keyframe Implicit setup" in err and "sidebar" in err
    assert not (tmp_path / "o.blend").exists()


def test_cli_bad_paths_and_arguments_exit_nonzero(tmp_path, capsys):
    assert main(["bake", str(tmp_path / "nope.blend"), "--out", str(tmp_path / "o.blend")]) == 1
    assert "No such file" in capsys.readouterr().err
    src = tmp_path / "x.blend"
    src.write_bytes(b"")
    assert main(["bake", str(src), "--out", str(tmp_path / "missing" / "o.blend")]) == 1
    assert "does not exist: create it first" in capsys.readouterr().err


def test_cli_entry_point_usage_error_in_a_subprocess(tmp_path):
    # `python -m keyframe_implicit` itself (argument errors need neither bpy nor the core)
    proc = subprocess.run([sys.executable, "-m", "keyframe_implicit", "bake"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "--out" in proc.stderr
