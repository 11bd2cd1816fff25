"""The demo command: bakes a scene, writes a shape-keyed .blend and a contact sheet that shows motion."""

import os

import bpy
import numpy as np
import pytest

from keyframe_implicit.cli import demo


def _read_png(path):
    return demo._read_png(path)[:, :, :3]


def test_sheet_frames_keep_ends_and_keyframes_and_the_count():
    assert demo.sheet_frames(1, 25, 12, [1, 25]) == sorted(set(demo.sheet_frames(1, 25, 12, [1, 25])))
    f = demo.sheet_frames(1, 25, 12, [1, 9, 15, 25])
    assert len(f) == 12 and {1, 9, 15, 25} <= set(f) and f == sorted(f)
    assert demo.sheet_frames(1, 5, 12, [1, 5]) == [1, 2, 3, 4, 5]


def test_compose_places_tiles_row_by_row_and_frames_keyframes():
    tiles = [np.full((4, 6, 4), v, dtype=np.float32) for v in (0.1, 0.2, 0.3)]
    sheet = demo.compose(tiles, 2, keyed={2}, gap=3, border=1)
    assert sheet.shape == (2 * 7 + 3, 2 * 9 + 3, 4)
    assert np.allclose(sheet[3:7, 3:9, 0], 0.1) and np.allclose(sheet[3:7, 12:18, 0], 0.2)
    assert np.allclose(sheet[10:14, 3:9, 0], 0.3)
    assert np.allclose(sheet[9, 3:9], demo.KEY_BORDER)      # border above the keyframe tile
    assert np.allclose(sheet[2, 3:9, :3], demo.BACKGROUND[:3])  # none above an in-between


def test_bad_arguments_say_what_to_fix(capsys):
    with pytest.raises(SystemExit) as exc:
        demo.parse_args(["--resolution", "4"])
    assert exc.value.code == 2 and "--resolution" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        demo.parse_args(["--scene", "teapot"])
    with pytest.raises(SystemExit):
        demo.parse_args(["--tile", "big"])


def test_demo_writes_a_baked_blend_and_a_sheet_that_shows_motion(tmp_path, capsys):
    tile = (120, 90)
    code = demo.main(["--scene", "bend", "--out", str(tmp_path), "--resolution", "16",
                      "--frames", "6", "--tile", f"{tile[0]}x{tile[1]}"])
    out = capsys.readouterr().out
    assert code == 0, out
    for stage in ("1/4", "2/4", "3/4", "4/4"):
        assert f"[demo] {stage}" in out
    blend, png = tmp_path / "bend.blend", tmp_path / "bend.png"
    assert blend.exists() and png.exists()

    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    scene = bpy.context.scene
    baked = [o for o in scene.objects if o.get("kfi_output")]
    assert len(baked) == 1
    n_frames = scene.frame_end - scene.frame_start + 1
    if baked[0]["kfi_output_kind"] == "shape_keys":  # the Auto output (blender/output.py)
        assert len(baked[0].data.shape_keys.key_blocks) == 1 + n_frames
    else:
        frame = baked[0].data.attributes["kfi_frame"]  # every frame in the object's own mesh
        index = np.empty(len(frame.data), np.int32)
        frame.data.foreach_get("value", index)
        assert np.array_equal(np.unique(index), np.arange(n_frames))
        assert baked[0].modifiers["Frame Switch"].node_group is not None
    assert not baked[0].hide_render

    sheet = _read_png(str(png))
    gap = 10
    cols = 4
    frames = demo.sheet_frames(scene.frame_start, scene.frame_end, 6, [scene.frame_start, scene.frame_end])
    rows = -(-len(frames) // cols)
    assert sheet.shape[:2] == (rows * (tile[1] + gap) + gap, cols * (tile[0] + gap) + gap)
    tiles = [sheet[gap + r * (tile[1] + gap):gap + r * (tile[1] + gap) + tile[1],
                   gap + c * (tile[0] + gap):gap + c * (tile[0] + gap) + tile[0]]
             for r, c in (divmod(n, cols) for n in range(len(frames)))]
    for t in tiles:  # something is drawn on every tile: not one flat colour
        assert t.std() > 0.03
    # the object moves: first and last tiles differ, and so does each tile from the next
    assert np.abs(tiles[0] - tiles[-1]).mean() > 0.01
    assert all(np.abs(a - b).mean() > 1e-3 for a, b in zip(tiles, tiles[1:]))
