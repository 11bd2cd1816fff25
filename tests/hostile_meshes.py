"""Keyframe meshes as artists leave them, generated (hypothesis), and the bake's verdict on each.

`hostile_meshes` draws a base shape -- a sphere, an open plane, a closed flat "pillow" --
and then spoils it the ways a scene does: subsets of faces flipped, loose vertices near and
far, holes punched, parts duplicated or overlapping (also inside out, which cancels), zero-area
faces, and a scale from 1e-4 to 1e4. `core_bakes` is what the bake makes of one: whether its
distance grid on the bake's grid has an inside, the fact every other check must agree with.
"""

import numpy as np
from hypothesis import strategies as st

from keyframe_implicit.core.bake.checks import checked_mesh
from keyframe_implicit.core.bake.gridfit import fit_grid
from keyframe_implicit.core.bake.keyframe import Keyframe
from keyframe_implicit.core.fields.mesh import triangulate
from keyframe_implicit.core.fields.sdf import mesh_to_sdf
from keyframe_implicit.shapes import icosphere

SPHERE = icosphere(2, radius=1.0)


def _plane(n=6):
    """An open square of n x n quads (2 triangles each) in z = 0, side 2."""
    t = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(t, t, indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + n + 1, i.ravel() + n + 2, i.ravel() + 1
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def _pillow():
    """A closed surface with no volume: the plane and its reversed copy on the same vertices."""
    v, f = _plane()
    return v, np.concatenate([f, f[:, ::-1]])


BASES = {"sphere": SPHERE, "plane": _plane(), "pillow": _pillow()}


@st.composite
def hostile_meshes(draw):
    """(vertices (V, 3), triangles (T, 3), what) of one spoilt keyframe mesh; ``what`` lists
    what was done to it, for the failure message."""
    base = draw(st.sampled_from(sorted(BASES)))
    v, f = (a.copy() for a in BASES[base])
    what = [base]
    if draw(st.booleans()):  # a duplicate part: moved, overlapping, or on the original
        shift = draw(st.sampled_from([0.0, 0.5, 3.0]))
        inside_out = draw(st.booleans())
        f = np.concatenate([f, (f[:, ::-1] if inside_out else f) + len(v)])
        v = np.concatenate([v, v + [shift, 0.0, 0.0]])
        what.append(f"duplicate shifted {shift}" + (" inside out" if inside_out else ""))
    n_holes = draw(st.integers(0, 6))
    if n_holes:  # holes punched: faces deleted
        gone = draw(st.lists(st.integers(0, len(f) - 1), min_size=n_holes, max_size=n_holes))
        f = np.delete(f, gone, axis=0)
        what.append(f"{len(set(gone))} faces deleted")
    flip = draw(st.sampled_from(["none", "some", "upper half", "all"]))
    if flip != "none":  # a bad import or a partial Flip
        centre = v[f].mean(axis=1)
        mask = {"some": np.arange(len(f)) % draw(st.integers(2, 7)) == 0,
                "upper half": centre[:, 2] > 0, "all": np.ones(len(f), bool)}[flip]
        f = np.where(mask[:, None], f[:, ::-1], f)
        what.append(f"faces flipped: {flip}")
    n_degenerate = draw(st.integers(0, 3))
    if n_degenerate:  # zero-area faces: a corner on top of another (collapsed edges)
        corners = v[f[:n_degenerate][:, [0, 1, 1]]].reshape(-1, 3)
        f = np.concatenate([f, len(v) + np.arange(3 * n_degenerate).reshape(-1, 3)])
        v = np.concatenate([v, corners])
        what.append(f"{n_degenerate} zero-area faces")
    loose = draw(st.sampled_from([None, 0.3, 50.0]))
    if loose is not None:  # left over from editing: near (inside the box) or far away
        v = np.concatenate([v, [[loose, 0.1, 0.2]]])
        what.append(f"loose vertex at x={loose}")
    scale = 10.0 ** draw(st.integers(-4, 4))
    what.append(f"scale {scale:g}")
    return v * scale, f, ", ".join(what)


def grid_has_inside(vertices, faces, resolution=48):
    """Whether the distance grid of this keyframe, on the grid a bake of it fits (its faces'
    box, as `pipeline.animate` fits it), has a node inside; False for faces it refuses."""
    v = np.asarray(vertices, dtype=float)
    try:
        tris = triangulate(faces, len(v))
        grid = fit_grid([v[np.unique(tris)]], resolution)
        return bool(np.any(mesh_to_sdf(v, tris, grid) < 0))
    except ValueError:
        return False


def core_bakes(vertices, faces, resolution=48):
    """The core's verdict on this keyframe: it passes the core's own check before the grid
    (`checks.checked_mesh`) and its distance grid has an inside (`grid_has_inside`)."""
    try:
        checked_mesh(0, Keyframe(vertices, faces, 1, "Generated"))
    except ValueError:
        return False
    return grid_has_inside(vertices, faces, resolution)
