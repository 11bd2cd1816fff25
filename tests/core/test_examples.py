"""The example shapes are valid keyframes: closed, outward, equal volume, sensible feature points."""

import numpy as np
import pytest

from keyframe_implicit import examples
from keyframe_implicit.core.surface.extract import loop_area, mesh_volume


@pytest.fixture(scope="module", params=examples.NAMES)
def ex(request):
    return examples.example(request.param)


def _winding_number(vertices, faces, points):
    """Generalised winding number of closed triangle meshes at points (Jacobson et al. 2013)."""
    tri = vertices[faces]                                  # (F, 3, 3)
    d = tri[None, :, :, :] - points[:, None, None, :]      # (P, F, 3, 3)
    n = np.linalg.norm(d, axis=-1)
    a, b, c = d[..., 0, :], d[..., 1, :], d[..., 2, :]
    na, nb, nc = n[..., 0], n[..., 1], n[..., 2]
    det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
    den = (na * nb * nc + np.einsum("pfi,pfi->pf", a, b) * nc
           + np.einsum("pfi,pfi->pf", b, c) * na + np.einsum("pfi,pfi->pf", c, a) * nb)
    return (2.0 * np.arctan2(det, den)).sum(axis=1) / (4.0 * np.pi)


def test_meshes_are_closed_and_consistently_wound(ex):
    for k in ex.keyframes:
        f = np.asarray(k.faces)
        assert f.ndim == 2 and f.shape[1] == 3
        assert f.min() >= 0 and f.max() < len(k.vertices)
        directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        # every directed edge once, and its reverse present: closed 2-manifold, one orientation
        assert len(np.unique(directed, axis=0)) == len(directed)
        fwd = {tuple(e) for e in directed.tolist()}
        assert all((b, a) in fwd for a, b in fwd)
        assert 200 <= len(f) <= 8000  # small enough for tests and the demo


def test_meshes_point_outward(ex):
    for k in ex.keyframes:
        assert mesh_volume(k.vertices, k.faces) > 0.1
        # a point just outside the top-most vertex along +z is outside (winding ~0),
        # the centroid of a thin layer below it is inside
        top = k.vertices[np.argmax(k.vertices[:, 2])]
        w = _winding_number(k.vertices, np.asarray(k.faces),
                            np.array([top + [0, 0, 0.05], top - [0, 0, 0.05]]))
        assert abs(w[0]) < 0.1 and abs(w[1] - 1.0) < 0.1


def test_volumes_equal_across_keyframes(ex):
    v = np.array(ex.volumes)
    assert np.all(np.abs(v / v[0] - 1.0) < 0.02), v


def test_frames_increase_and_one_feature_set_per_segment(ex):
    frames = ex.frames
    assert all(b > a for a, b in zip(frames, frames[1:]))
    assert len(ex.features) == len(ex.keyframes) - 1 == len(ex.feature_names)
    for (pa, pb), names in zip(ex.features, ex.feature_names):
        assert pa.shape == pb.shape and pa.shape[1] == 3
        assert 6 <= len(pa) <= 10 and len(names) == len(pa) == len(set(names))
        # not all on one plane: the 3D RBF needs d + 1 affinely independent points
        assert np.linalg.matrix_rank(pa[1:] - pa[0], tol=1e-6) == 3
        assert np.linalg.matrix_rank(pb[1:] - pb[0], tol=1e-6) == 3


def test_feature_points_lie_inside_or_on_their_keyframes(ex):
    for i, (pa, pb) in enumerate(ex.features):
        for k, pts in ((ex.keyframes[i], pa), (ex.keyframes[i + 1], pb)):
            w = _winding_number(k.vertices, np.asarray(k.faces), pts)
            near = np.min(np.linalg.norm(pts[:, None] - k.vertices[None], axis=-1), axis=1)
            assert np.all((w > 0.5) | (near < 0.1)), (i, w, near)


def test_rigid_example_is_a_rigid_motion():
    ex = examples.rigid()
    a, b = ex.keyframes
    pa, pb = ex.features[0]
    # same pairwise distances between vertices and between feature points
    idx = np.arange(0, len(a.vertices), 37)
    da = np.linalg.norm(a.vertices[idx, None] - a.vertices[None, idx], axis=-1)
    db = np.linalg.norm(b.vertices[idx, None] - b.vertices[None, idx], axis=-1)
    assert np.allclose(da, db)
    assert np.allclose(np.linalg.norm(pa[:, None] - pa[None], axis=-1),
                       np.linalg.norm(pb[:, None] - pb[None], axis=-1))
    assert np.linalg.norm(b.vertices.mean(0) - a.vertices.mean(0)) > 1.0  # it travels


def test_merge_goes_from_two_components_to_one():
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ex = examples.merge()
    counts = []
    for k in ex.keyframes:
        f = np.asarray(k.faces)
        e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
        g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(k.vertices),) * 2)
        counts.append(connected_components(g, directed=False)[0])
    assert counts == [2, 1]


def test_splash_has_four_keyframes_and_the_droplet_falls():
    ex = examples.splash()
    assert len(ex.keyframes) == 4
    tops = [k.vertices[:, 2].max() for k in ex.keyframes]
    assert tops[0] > tops[1] > tops[2] > tops[3]


def test_unknown_names_raise_value_error_with_choices():
    with pytest.raises(ValueError, match="rigid"):
        examples.example("nope")
    with pytest.raises(ValueError, match="merge"):
        examples.example_2d("rigid")


@pytest.mark.parametrize("name", examples.NAMES_2D)
def test_2d_examples_ccw_equal_area_and_features(name):
    ex = examples.example_2d(name)
    assert len(ex.shapes) == len(ex.frames) == len(ex.features) + 1
    for polys in ex.shapes:
        for p in polys:
            assert p.ndim == 2 and p.shape[1] == 2
            assert loop_area(p) > 0  # counter-clockwise
    areas = np.array(ex.areas)
    assert np.all(np.abs(areas / areas[0] - 1.0) < 0.02), areas
    from matplotlib.path import Path

    for i, (pa, pb) in enumerate(ex.features):
        for polys, pts in ((ex.shapes[i], pa), (ex.shapes[i + 1], pb)):
            inside = np.zeros(len(pts), bool)
            for p in polys:
                inside |= Path(p).contains_points(pts, radius=1e-3)
            assert inside.all(), (name, i, pts[~inside])
