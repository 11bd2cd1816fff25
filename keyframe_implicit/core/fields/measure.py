"""A keyframe mesh measured the way the distance field reads it (`read_mesh`): its faces
only (loose vertices are no part of the surface), cleaned and oriented as `mesh` makes
them, its volume taken where the winding number (`winding`) reads inside when holes leave
no other. It is the one measure both the bake's checks and the Blender panel judge a
keyframe by.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .mesh import check_vertices, clean_triangles, orient_faces, triangulate
from .winding import WindingTree

__all__ = ["MeshReading", "read_mesh", "VOLUME_SHARE"]

#: A surface encloses no volume when its volume is below this share of the cube on its
#: faces' largest side: a plane, a closed sheet folded onto itself, a part cancelled by an
#: inside-out copy of itself. Real solids enclose far more (a sphere 0.52, a 1:100 slab 0.01).
VOLUME_SHARE = 1e-6


@dataclass(frozen=True)
class MeshReading:
    """A keyframe mesh as the distance field reads it (`read_mesh`).

    Attributes
    ----------
    triangles : int
        Triangles of non-zero area (0: nothing to measure).
    volume : float
        |Volume| the triangles enclose once each connected part faces one way
        (`orient_faces`). With holes, where a volume depends on the point it is taken
        about, or when the parts' volumes cancel in sum, the volume where the winding
        number reads inside as the distance field does, sampled (`_inside_volume`).
    extent : float
        The largest side of the faces' bounding box (what the bake's grid spans).
    open_edges, shared_edges : int
        Triangle edges with one triangle (on a hole) and with three or more (non-manifold).
    reoriented : int
        Triangles that faced the other way from the rest of their part (read flipped).
    non_orientable : int
        Triangles of parts without a consistent inside and outside.
    loose : int
        Vertices of no face: no part of the surface, ignored.
    loose_reach : float
        How far the farthest loose vertex lies outside the faces' bounding box (0 inside).
    """

    triangles: int
    volume: float = 0.0
    extent: float = 0.0
    open_edges: int = 0
    shared_edges: int = 0
    reoriented: int = 0
    non_orientable: int = 0
    loose: int = 0
    loose_reach: float = 0.0

    @property
    def encloses_volume(self) -> bool:
        """Whether the distance field finds an inside (`VOLUME_SHARE` of the faces' box)."""
        return self.triangles > 0 and self.volume > VOLUME_SHARE * self.extent ** 3


def read_mesh(vertices: ArrayLike,
              faces: ArrayLike | Sequence[Sequence[int]]) -> MeshReading:
    """Measure a keyframe mesh as the bake reads it: faces only, cleaned and oriented.

    Parameters
    ----------
    vertices : (V, 3) float array_like
    faces : (F, k) int array_like or sequence of polygons

    Returns
    -------
    MeshReading

    Raises
    ------
    ValueError
        What `check_vertices` and `triangulate` refuse (no faces, bad indices, NaN).
    """
    v = check_vertices(vertices)
    tris = triangulate(faces, len(v))
    used = np.zeros(len(v), dtype=bool)
    used[tris.reshape(-1)] = True
    on_faces = v[used]
    lo, hi = on_faces.min(axis=0), on_faces.max(axis=0)
    loose = v[~used]
    reach = float(np.max(np.maximum(lo - loose, loose - hi).max(axis=1).clip(0))) if len(loose) else 0.0
    counts = dict(extent=float((hi - lo).max()), loose=len(loose), loose_reach=reach)
    stats = {}
    try:
        tris = clean_triangles(v, tris, stats)
    except ValueError:
        return MeshReading(0, **counts)
    tris, reoriented, non_orientable = orient_faces(v, tris)
    open_edges, shared_edges = _edge_counts(tris)
    a, b, c = (v[tris[:, k]] - on_faces.mean(axis=0) for k in range(3))
    volume = abs(float(np.einsum("ij,ij->", a, np.cross(b, c)))) / 6.0
    if open_edges or not volume > VOLUME_SHARE * counts["extent"] ** 3:
        volume = _inside_volume(v, tris, lo, hi)  # holes; parts that cancel only in sum
    return MeshReading(len(tris), volume, open_edges=open_edges, shared_edges=shared_edges,
                       reoriented=reoriented, non_orientable=non_orientable, **counts)


def _inside_volume(v, tris, lo, hi, cells=16):
    """Volume of the faces' box where the winding number reads inside (|w| >= 0.5, as the
    distance field does), sampled at the centres of about ``cells`` cells along its longest
    side: the volume of an open surface (holes bridged as the distance field bridges them),
    or of one whose parts' volumes cancel in sum although they do not cancel in space (a
    copy turned inside out beside the original, not on top of it)."""
    side = hi - lo
    if not np.all(side > 0):
        return 0.0  # a flat box holds no volume
    n = np.maximum(1, np.ceil(side / side.max() * cells)).astype(int)
    axes = [lo[k] + (np.arange(n[k]) + 0.5) * side[k] / n[k] for k in range(3)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = np.abs(WindingTree(v, tris)(points)) >= 0.5
    return float(np.prod(side) * inside.mean())


def _edge_counts(tris):
    """(open edges, edges of 3+ triangles) of triangles."""
    a, b = tris.reshape(-1), tris[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(a, b) * (int(tris.max()) + 1) + np.maximum(a, b)  # one number per edge
    _, count = np.unique(key, return_counts=True)
    return int(np.sum(count == 1)), int(np.sum(count > 2))
