"""Hostile inputs through `animate`: a correct result or a ValueError that says what to fix.

Each test reproduces a defect of a hostile-input sweep: feature arrays of the wrong width were
reshaped, feature points almost on top of each other sent the output flying, a stray far point
gave a misleading "close the mesh", loose vertices stretched the grid, and messages named
neither the keyframe nor the element at fault.
"""

import time

import numpy as np
import pytest

from inbetween_cases import sphere_field
from keyframe_implicit.core import Keyframe, animate
from keyframe_implicit.core.bake.checks import CLOSE_HOLES, FACE_OUTWARD, THICKEN
from keyframe_implicit.shapes import icosphere

RES = 16


def _spheres(shift=1.0, name_a="Ball", name_b="Ball.001"):
    v, f = icosphere(2, radius=0.5)
    return [Keyframe(v, f, 1, name_a), Keyframe(v + (shift, 0, 0), f, 5, name_b)]


def _features(shift=1.0):
    pa = 0.5 * np.array([[0, 0, 1], [0, 0, -1], [0, 1, 0], [-1, 0, 0]], float)
    return pa, pa + (shift, 0, 0)


def _check_result(anim, kfs):
    """A correct result: finite, on the grid, the keyframes' frames on the keyframes."""
    verts = anim.vertices
    assert np.all(np.isfinite(verts))
    g = anim.grid
    assert np.all(g.contains(verts, margin=-g.spacing))
    for kf in (kfs[0], kfs[-1]):
        on = verts[int(kf.frame - anim.frames[0])]
        centre = np.mean(kf.vertices[np.unique(kf.faces)], axis=0)
        r = np.linalg.norm(on - centre, axis=1)
        assert abs(np.median(r) - 0.5) < 0.5 * g.spacing, kf.frame


@pytest.mark.parametrize("shape", [(4, 2), (6, 2), (3, 4), (2, 3, 1)])
def test_feature_arrays_must_be_n_by_3(shape):
    pa = 0.3 * np.random.default_rng(1).random(shape) - 0.15  # distinct points inside the ball
    with pytest.raises(ValueError, match=r"must have shape \(N, 3\).*" + re_shape(shape)):
        animate(_spheres(), [(pa, pa)], resolution=RES)


def re_shape(shape):
    return r"\(" + r", ".join(str(s) for s in shape) + r",?\)"


@pytest.mark.parametrize("gap", [0.001, 0.01])
def test_feature_points_closer_than_a_cell_with_different_targets_are_refused(gap):
    pa, pb = _features()
    pa = np.vstack([pa, pa[0] + (gap, 0, 0)])
    pb = np.vstack([pb, pb[0] + (0, 0.3, -0.4)])
    names = [[(f"KFI 0.{j} A", f"KFI 0.{j} B") for j in range(5)]]
    with pytest.raises(ValueError) as err:
        animate(_spheres(), [(pa, pb)], resolution=RES, feature_names=names)
    msg = str(err.value)
    assert "'KFI 0.0 A'" in msg and "'KFI 0.4 A'" in msg and "keyframe 1" in msg, msg
    assert "one grid cell" in msg and "partners" in msg
    # without names, the points are named by row and keyframe
    with pytest.raises(ValueError, match="feature point 1 of keyframes 1 → 2 .*feature point 5"):
        animate(_spheres(), [(pa, pb)], resolution=RES)


def test_far_feature_point_is_refused_naming_its_empty():
    pa, pb = _features()
    pb = pb.copy()
    pb[2] = (1000.0, 0.0, 0.0)  # an Empty left far away
    names = [[(f"KFI 0.{j} A", f"KFI 0.{j} B") for j in range(4)]]
    with pytest.raises(ValueError) as err:
        animate(_spheres(), [(pa, pb)], resolution=RES, feature_names=names)
    msg = str(err.value)
    assert "'KFI 0.2 B'" in msg and "keyframe 2" in msg and "close the mesh" not in msg, msg


def test_loose_far_vertex_is_ignored_and_counted():
    kfs = _spheres()
    v, f = kfs[0].vertices, kfs[0].faces
    kfs[0] = Keyframe(np.vstack([v, [[50.0, 0.0, 0.0]]]), f, 1, "Ball")
    anim = animate(kfs, [_features()], resolution=RES)
    assert anim.grid.upper[0] < 5.0  # the box holds the faces, not the stray vertex
    assert anim.stats["loose_vertices"] == [1, 0]
    notes = anim.stats["notes"]
    assert any("Keyframe 1 ('Ball', frame 1)" in n and "1 loose vert" in n for n in notes), notes
    _check_result(anim, kfs)


@pytest.fixture
def started_helper():
    """A helper process that has started: it makes the last keyframe's distance grid even
    on these small grids, which take less time than a process takes to start."""
    from keyframe_implicit.core.base.parallel import Helper

    with Helper(preload=()) as helper:
        while not helper.ready():
            time.sleep(0.01)
        yield helper


@pytest.mark.parametrize("processes", [1, 2])  # 2: keyframe 2's distance grid in the helper
def test_reoriented_faces_are_reported(processes, started_helper):
    kfs = _spheres()
    f = kfs[1].faces.copy()
    f[::2] = f[::2, ::-1]
    kfs[1] = Keyframe(kfs[1].vertices, f, 5, "Ball.001")
    helper = started_helper if processes == 2 else None
    anim = animate(kfs, [_features()], resolution=RES, processes=processes, helper=helper)
    notes = [n for n in anim.stats["notes"] if "Keyframe 2 ('Ball.001', frame 5)" in n]
    assert len(notes) == 1 and notes[0].endswith(f"read flipped; {FACE_OUTWARD}."), anim.stats["notes"]
    _check_result(anim, kfs)


def test_nan_vertex_names_the_keyframe_and_the_vertex():
    kfs = _spheres()
    v = kfs[1].vertices.copy()
    v[7] = np.nan
    kfs[1] = Keyframe(v, kfs[1].faces, 5, "Ball.001")
    with pytest.raises(ValueError) as err:
        animate(kfs, [_features()], resolution=RES)
    msg = str(err.value)
    assert msg.startswith("Keyframe 2 ('Ball.001', frame 5)") and "vertex 7" in msg, msg
    assert "extra points" not in msg


def test_keyframes_far_apart_are_not_told_to_close_the_mesh():
    kfs = _spheres(shift=100.0)  # 100 sizes apart: each keyframe is a few cells on the grid
    with pytest.raises(ValueError) as err:
        animate(kfs, [tuple(np.zeros((0, 3)) for _ in range(2))], resolution=RES)
    msg = str(err.value)
    # the first ball's centre, the world origin, is a node of every lattice: the second ball
    # (100 sizes along x, between nodes) is the first keyframe with no node inside
    assert "close the mesh" not in msg.lower() and "Keyframe 2 ('Ball.001', frame 5)" in msg, msg
    assert "far apart" in msg and "raise the resolution" in msg


def test_open_mesh_is_told_to_close_it():
    kfs = _spheres()
    sheet = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], float)
    kfs[0] = Keyframe(sheet, [[0, 1, 2, 3]], 1, "Sheet")  # a flat open square
    with pytest.raises(ValueError, match="Keyframe 1 \\('Sheet', frame 1\\) is open \\(4 open edges\\)") as err:
        animate(kfs, [tuple(np.zeros((0, 3)) for _ in range(2))], resolution=RES)
    # what to fix in the mesh's own terms; where an application does it is the application's
    assert str(err.value).endswith(f"encloses no volume: {CLOSE_HOLES}, or {THICKEN}.")


def test_the_core_names_no_menu_of_blender():
    """The bpy-free core words what is wrong and what to fix in geometry terms: no message of
    it names a Blender menu ("Mesh > ...") or modifier; the Blender side adds those."""
    import pathlib
    import re

    core = pathlib.Path(__file__).parents[2] / "keyframe_implicit" / "core"
    menu = re.compile(r"""["'][^"'\n]*(\b[A-Z][a-z]+ > [A-Z]|Solidify|Edit Mode)""")
    found = [f"{path.name}:{n}: {line.strip()}" for path in sorted(core.rglob("*.py"))
             for n, line in enumerate(path.read_text().splitlines(), start=1) if menu.search(line)]
    assert not found, "\n".join(found)


def test_thin_mesh_whose_distance_grid_the_helper_makes_is_named_too(started_helper):
    kfs = _spheres()
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (0.05, 0.051)])
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    kfs[1] = Keyframe(corners + (2.0, 0.0, 0.0), quads, 5, "Slab")  # closed, thinner than a cell
    with pytest.raises(ValueError, match="Keyframe 2 \\('Slab', frame 5\\).*thinner than a cell"):
        animate(kfs, [tuple(np.zeros((0, 3)) for _ in range(2))], resolution=RES, processes=2,
                helper=started_helper)


@pytest.mark.parametrize("gap", [0.001, 0.01])
def test_initial_map_stays_on_the_grid_with_near_duplicate_features(gap):
    """The guard on the RBF start: whatever the features, the material is not sent off the grid."""
    from keyframe_implicit.core import Grid
    from keyframe_implicit.core.map.rbf import initial_map

    n = 24
    g = Grid((-1.0, -1.0, -1.0), 2.0 / n, (n + 1,) * 3)
    phi = sphere_field(g, (0, 0, 0), 0.5)
    pa, pb = _features(shift=0.0)
    pa = np.vstack([pa, pa[0] + (gap, 0, 0)])
    pb = np.vstack([pb, pb[0] + (0, 0.3, -0.4)])
    m = initial_map(phi, phi, g, pa, pb)
    material = m.mapped[phi < 0]
    assert np.all(np.isfinite(material))
    assert np.all(g.contains(material, margin=-0.25 * 2.0)), np.abs(material).max()
