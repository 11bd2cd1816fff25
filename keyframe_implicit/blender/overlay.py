"""The one place that draws with the ``gpu`` module: the live preview's mesh over the 3D view.

The mesh is drawn shaded, as a batch of the builtin ``SMOOTH_COLOR`` shader with one colour
per vertex (a light from above and in front, from the vertex normals), depth-tested
against the scene and half transparent, so the keyframe objects stay visible through it.
The same calls work on every supported Blender (4.2 .. 5.3). Where drawing is unavailable
(the bpy module or ``blender -b`` without ``gpu.init``), `batch` returns None and the
preview keeps only the mesh: `available` says which.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import gpu
    from numpy.typing import ArrayLike

__all__ = ["available", "batch", "draw", "COLOR", "STALE_COLOR"]

#: The preview's colour (linear RGB: an orange apart from Blender's default greys and the
#: selection's) and opacity.
COLOR = (1.0, 0.45, 0.1, 0.55)
#: The colour of a preview whose inputs were edited since it was solved: a fainter grey,
#: until the new solve's frame replaces it.
STALE_COLOR = (0.6, 0.6, 0.6, 0.4)
#: Direction the light comes from (world space, normalised below).
_LIGHT = np.array([0.3, -0.5, 0.8])


def _shader() -> gpu.types.GPUShader | None:
    """The builtin shader, or None where drawing is unavailable."""
    import gpu

    try:
        return gpu.shader.from_builtin("SMOOTH_COLOR")
    except SystemError:  # background mode without a GPU context
        return None


def available() -> bool:
    """Whether this Blender can draw (a GPU context exists)."""
    return _shader() is not None


def vertex_colors(vertices: ArrayLike, triangles: ArrayLike,
                  color: tuple[float, float, float, float] = COLOR) -> np.ndarray:
    """(V, 4) float32 colours: ``color`` lit by `_LIGHT` along each vertex's normal (the
    area-weighted sum of its triangles' normals), both sides lit alike."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    face = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    corners = t.ravel()
    normals = np.stack([np.bincount(corners, np.repeat(face[:, k], 3), minlength=len(v))
                        for k in range(3)], axis=1)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals /= np.where(length > 0, length, 1.0)
    light = _LIGHT / np.linalg.norm(_LIGHT)
    shade = 0.35 + 0.65 * np.abs(normals @ light)
    colors = np.empty((len(v), 4), dtype=np.float32)
    colors[:, :3] = shade[:, None] * np.asarray(color[:3])
    colors[:, 3] = color[3]
    return colors


def batch(vertices: np.ndarray, triangles: np.ndarray,
          color: tuple[float, float, float, float] = COLOR,
          ) -> tuple[gpu.types.GPUShader, gpu.types.GPUBatch] | None:
    """(shader, batch) drawing the mesh in ``color``, or None where drawing is unavailable."""
    shader = _shader()
    if shader is None or len(triangles) == 0:
        return None
    from gpu_extras.batch import batch_for_shader

    colors = vertex_colors(vertices, triangles, color)
    return shader, batch_for_shader(shader, "TRIS", {"pos": vertices, "color": colors},
                                    indices=triangles)


def draw(shader_batch: tuple[gpu.types.GPUShader, gpu.types.GPUBatch]) -> None:

    """Draw a `batch` in the current view (a ``POST_VIEW`` draw handler)."""
    import gpu

    shader, drawn = shader_batch
    gpu.state.depth_test_set("LESS_EQUAL")
    gpu.state.blend_set("ALPHA")
    shader.bind()
    drawn.draw(shader)
    gpu.state.blend_set("NONE")
    gpu.state.depth_test_set("NONE")
