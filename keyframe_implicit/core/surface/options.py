"""What the surface stage makes of every frame, as one frozen object (`SurfaceOptions`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

__all__ = ["SurfaceOptions"]


@dataclass(frozen=True)
class SurfaceOptions:
    """What each frame yields besides the tracked template's vertices (docs/method.md,
    sections 7 and 9).

    Attributes
    ----------
    coverage : bool
        Measure the area of the frame's surface the template misses (one marching cubes
        per frame).
    surfaces : bool
        3D only: keep the frame's own surface (marching cubes of its level set, or the
        keyframe's own mesh on a keyframe's frame) with its vertices' velocities, and
        measure both outputs against it (`quality.frame_quality`).
    levelsets : bool
        Keep the frame's level set (float32), e.g. for a volume export.
    """

    coverage: bool = True
    surfaces: bool = True
    levelsets: bool = False

    @classmethod
    def names(cls) -> frozenset:
        """The keyword names these options take."""
        return frozenset(f.name for f in dataclasses.fields(cls))
