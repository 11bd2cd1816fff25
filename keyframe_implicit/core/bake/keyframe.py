"""One keyframe as the bake takes it: a mesh in world space on a timeline frame."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike

    from ..surface.attributes import MeshAttributes

__all__ = ["Keyframe"]


@dataclass
class Keyframe:
    """One keyframe: a mesh in world space on a timeline frame.

    vertices : (V, 3) float array, world coordinates.
    faces : sequence of index sequences (triangles or polygons), or an (F, k) int array.
    frame : int, the timeline frame this shape must be matched on.
    name : str, optional; the object's name, used in messages about this keyframe.
    attributes : `attributes.MeshAttributes`, optional; the mesh's polygons, UV maps,
        colours, materials, sharp and seam edges, custom normals. On the first keyframe they
        make the artist's own mesh the shape-keyed result.
    """

    vertices: np.ndarray
    faces: ArrayLike | Sequence[Sequence[int]]
    frame: int
    name: str = ""
    attributes: MeshAttributes | None = None
