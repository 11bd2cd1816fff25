"""Three keyframes in a chain, one template throughout."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from inbetween_cases import l_centroid, l_shape, make_grid, sphere_field
from keyframe_implicit.core import animate_chain
from keyframe_implicit.core.bake import chain


def _rigid(grid, c, R, t):
    """Map, and the SDF of the L-shape moved by x -> c + t + R (x - c)."""
    x = grid.points()
    return c + t + (x - c) @ R.T, l_shape(c + (x - c - t) @ R)


def test_three_keyframe_chain_passes_through_the_middle_keyframe():
    grid = make_grid(3, 32)
    h = grid.spacing
    c = l_centroid()
    R1 = Rotation.from_rotvec([0.0, 0.0, np.pi / 3]).as_matrix()
    t1 = np.array([0.15, 0.0, 0.0])
    R2 = Rotation.from_rotvec([np.pi / 4, 0.0, 0.0]).as_matrix()
    t2 = np.array([0.0, 0.1, -0.1])
    phi_a = l_shape(grid.points())
    map1, phi_b = _rigid(grid, c, R1, t1)
    c1 = c + t1
    # second segment starts from B: rotate B about its own centroid
    x = grid.points()
    map2 = c1 + t2 + (x - c1) @ R2.T

    def sdf_c(p):  # undo segment 2, then segment 1
        return l_shape(c + (c1 + (p - c1 - t2) @ R2 - c - t1) @ R1)

    phi_c = sdf_c(x)
    res = animate_chain([phi_a, phi_b, phi_c], grid, None, [1, 9, 21], maps=[map1, map2])
    assert res.frames.tolist() == list(range(1, 22))
    n, V, _ = res.vertices.shape
    assert n == 21 and V == res.stats["vertices"] > 100
    assert res.faces.max() < V
    # frame of keyframe B (timeline frame 9) is the template on B's surface
    mid = res.vertices[9 - 1]
    assert np.abs(l_shape(c + (mid - c - t1) @ R1)).mean() <= 0.25 * h
    # last frame on C, first frame on A
    last = res.vertices[-1]
    assert np.abs(sdf_c(last)).mean() <= 0.25 * h
    assert np.abs(l_shape(res.vertices[0])).mean() <= 0.25 * h
    # no jumps, even across the middle keyframe
    assert np.linalg.norm(np.diff(res.vertices, axis=0), axis=2).max() <= 2 * h
    assert max(res.stats["max_abs_phi"]) <= 0.1 * h
    assert len(res.stats["segments"]) == 2


def test_a_chain_gives_its_free_heap_back_between_segments_not_after_the_last(monkeypatch):
    released = []  # segments done when the heap is given back
    grid = make_grid(3, 20)
    phi = l_shape(grid.points())
    monkeypatch.setattr(chain, "release_memory", lambda: released.append(len(done)))
    done = []
    real = chain.Kept.add
    monkeypatch.setattr(chain.Kept, "add", lambda self, *a: (done.append(1), real(self, *a)))
    animate_chain([phi] * 4, grid, None, [1, 3, 5, 7], maps=[grid.points()] * 3, surfaces=False)
    assert released == [1, 2]


def test_chain_refuses_bad_frames_and_missing_features():
    grid = make_grid(2, 12)
    phi = sphere_field(grid, (0, 0), 0.5)
    with pytest.raises(ValueError, match="increasing"):
        animate_chain([phi, phi], grid, None, [5, 5], maps=[grid.points()])
    with pytest.raises(ValueError, match="one per keyframe"):
        animate_chain([phi, phi], grid, None, [1, 2, 3], maps=[grid.points()])
    with pytest.raises(ValueError, match="features"):
        animate_chain([phi, phi], grid, None, [1, 5])
    with pytest.raises(ValueError, match="two keyframes"):
        animate_chain([phi], grid, None, [1])
    with pytest.raises(ValueError, match="integers"):
        animate_chain([phi, phi], grid, None, [1, 2.5], maps=[grid.points()])
    with pytest.raises(ValueError, match=r"one map per segment \(1\), got 2"):
        animate_chain([phi, phi], grid, None, [1, 5], maps=[grid.points()] * 2)
    with pytest.raises(ValueError, match=r"one mesh per keyframe \(2\), got 1"):
        animate_chain([phi, phi], grid, None, [1, 5], maps=[grid.points()],
                      keyframe_meshes=[(np.zeros((3, 3)), np.zeros((1, 3), int))])
    with pytest.raises(ValueError, match="Grid"):
        animate_chain([phi, phi], grid.points(), None, [1, 5], maps=[grid.points()])
