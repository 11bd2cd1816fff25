"""What the surface stage makes of every frame, as one frozen object (`SurfaceOptions`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

__all__ = ["SurfaceOptions", "OUTPUTS"]

#: What `SurfaceOptions.output` takes: "auto" (`quality.choose_output` picks after the
#: bake) or one output.
OUTPUTS = ("auto", "shape_keys", "mesh_sequence")


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
    output : {"auto", "shape_keys", "mesh_sequence"}
        With ``surfaces``, the output the frames are made for, and so what they measure
        and keep (`measured`, `keeps_meshes`): "auto" (default) both outputs, the shape
        keys' figures to choose by (`quality.choose_output`) and the mesh sequence with
        its figures and velocities for when it is chosen; "shape_keys" the tracked
        template's figures alone, measured against the frame's own surface, which is not
        kept; "mesh_sequence" the frame's own mesh with its velocities and figures, and the
        template's, which say on which frames it ships the artist's mesh, tracked
        (`chain.tracked_frames`). The output set in the panel is made either way; the other
        one is then not there to pick.
    """

    coverage: bool = True
    surfaces: bool = True
    levelsets: bool = False
    output: str = "auto"

    def __post_init__(self) -> None:
        if self.output not in OUTPUTS:
            raise ValueError(f"output must be one of {', '.join(map(repr, OUTPUTS))}; "
                             f"got {self.output!r}.")

    @property
    def measured(self) -> tuple[str, ...]:
        """The outputs whose quality figures each frame measures (`quality.frame_quality`)."""
        return ("shape_keys",) if self.output == "shape_keys" else ("shape_keys", "mesh_sequence")

    @property
    def keeps_meshes(self) -> bool:
        """Whether each frame's own mesh and its velocities are kept (the mesh sequence)."""
        return self.surfaces and self.output != "shape_keys"

    @classmethod
    def names(cls) -> frozenset:
        """The keyword names these options take."""
        return frozenset(f.name for f in dataclasses.fields(cls))
