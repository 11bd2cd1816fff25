"""The live preview's frames (`core.bake.preview`): each the bake's own mesh on that frame,
at the preview's resolutions, to 1e-6 h whatever order the frames are asked in; distance grids
and the other pairs' maps kept while one pair's feature points move.
"""

import numpy as np
import pytest

from inbetween_cases import moving_growing_sphere
from keyframe_implicit.core import Cancelled, animate
from keyframe_implicit.core.bake.options import BakeOptions
from keyframe_implicit.core.bake.preview import PREVIEW_RESOLUTION, Preview


def _same_mesh(got, want, h, tolerance=1e-6):
    assert got[1].shape == want[1].shape and np.array_equal(got[1], want[1])
    assert np.abs(got[0] - want[0]).max() <= tolerance * h


@pytest.mark.parametrize("interpolation", [None, ["linear", "ease", "linear"]])
def test_every_frame_is_the_bake_at_the_preview_resolution(interpolation):
    keyframes, feats = moving_growing_sphere()
    preview = Preview()
    figures = preview.solve(keyframes, feats,
                            BakeOptions(resolution=48, key_interpolation=interpolation))
    assert figures["resolution"] == PREVIEW_RESOLUTION
    anim = animate(keyframes, feats, resolution=figures["resolution"],
                   motion_resolution=figures["motion_resolution"],
                   key_interpolation=interpolation)
    assert anim.stats["grid_shape"] == figures["grid_shape"]
    assert anim.stats.get("motion_grid_shape") == figures["motion_grid_shape"]
    h = anim.grid.spacing
    scrubbed = [7, 2, 5, 0, 9, 3, 1, 8, 4, 6]  # every frame, keyframe frames included
    assert sorted(scrubbed) == anim.frames.tolist()
    for f in scrubbed:
        _same_mesh(preview.frame(f), anim.surfaces[f], h)
    # before the first keyframe and after the last: those keyframes' frames
    _same_mesh(preview.frame(-3), anim.surfaces[0], h)
    _same_mesh(preview.frame(20), anim.surfaces[-1], h)


def test_moved_feature_keeps_the_distance_grids_and_matches_a_new_bake():
    preview = Preview()
    keyframes, feats = moving_growing_sphere()
    first = preview.solve(keyframes, feats)
    assert first["distance_grids_kept"] == 0
    before = preview.frame(2)
    keyframes, feats = moving_growing_sphere(shift=0.03)
    again = preview.solve(keyframes, feats)
    assert again["distance_grids_kept"] == 3 and again["grid_shape"] == first["grid_shape"]
    assert first["maps_kept"] == 0 and again["maps_kept"] == 1  # the other pair's maps
    anim = animate(keyframes, feats, resolution=again["resolution"],
                   motion_resolution=again["motion_resolution"])
    after = preview.frame(2)
    _same_mesh(after, anim.surfaces[2], anim.grid.spacing)
    assert after[0].shape != before[0].shape or np.abs(after[0] - before[0]).max() > 1e-4


def test_cancelled_solve_leaves_nothing_solved_and_bad_input_is_refused():
    preview = Preview()
    keyframes, feats = moving_growing_sphere()
    with pytest.raises(Cancelled):
        preview.solve(keyframes, feats, cancel=lambda: True)
    assert not preview.solved
    with pytest.raises(RuntimeError, match="solve first"):
        preview.frame(1)
    with pytest.raises(ValueError, match="strictly increasing"):
        preview.solve([keyframes[0], keyframes[0]], feats[:1])


def test_feature_points_closer_than_a_cell_raise_the_preview_resolution():
    keyframes, feats = moving_growing_sphere()
    feats[0][0][1] = feats[0][0][0] + (0.0, 0.025, 0.0)  # under one cell of the 32-cell grid
    with pytest.raises(ValueError, match="less than one grid cell"):
        animate(keyframes, feats, resolution=PREVIEW_RESOLUTION)
    preview = Preview()
    figures = preview.solve(keyframes, feats, BakeOptions(resolution=64))
    assert PREVIEW_RESOLUTION < figures["resolution"] < 64
    anim = animate(keyframes, feats, resolution=figures["resolution"],
                   motion_resolution=figures["motion_resolution"])
    assert anim.stats["grid_shape"] == figures["grid_shape"]
    _same_mesh(preview.frame(2), anim.surfaces[2], anim.grid.spacing)
    with pytest.raises(ValueError, match="less than one grid cell"):  # the bake's refusal
        preview.solve(keyframes, feats, BakeOptions(resolution=PREVIEW_RESOLUTION))
