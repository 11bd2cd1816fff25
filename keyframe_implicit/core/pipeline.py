"""Meshes + feature points + timeline frames -> one tracked mesh per frame.

This is the single entry point the Blender layer calls: it chooses a grid,
turns each keyframe mesh into a signed distance grid, solves the volume map
of every adjacent pair, and tracks one template mesh through all frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Keyframe", "Animation", "animate"]


@dataclass
class Keyframe:
    """One keyframe: a mesh in world space on a timeline frame.

    vertices : (V, 3) float array, world coordinates.
    faces : sequence of index sequences (triangles or polygons), or an (F, k) int array.
    frame : int, the timeline frame this shape must be matched on.
    """

    vertices: np.ndarray
    faces: object
    frame: int


@dataclass
class Animation:
    """Result of `animate`.

    frames : (n,) int array, every timeline frame from the first keyframe's to the last's.
    vertices : (n, V, 3) float32 array, the template's vertex positions on each frame.
    faces : (F, 3) int array, the template's triangles (the same on every frame).
    grid : the `Grid` used.
    stats : dict of figures (timings, solver iterations, volumes, uncovered area, ...).
    """

    frames: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    grid: object
    stats: dict = field(default_factory=dict)


def animate(keyframes, features, *, resolution=48, weights=None, progress=None, cancel=None,
            **options):
    """Bake a sequence of keyframes into one tracked mesh per timeline frame.

    Parameters
    ----------
    keyframes : sequence of `Keyframe`, at least two, frames strictly increasing.
    features : sequence of (points_a, points_b) pairs, one per segment (keyframe i -> i+1);
        (N, 3) arrays in world units, row j of points_a pairs with row j of points_b.
    resolution : int, grid cells along the longest side of the keyframes' bounding box.
    weights : dict with optional keys "volume", "rigidity", "levelset" (eq. 2.6).
    progress : callable(fraction, message), optional.
    cancel : callable() -> bool, optional; when it returns True, `Cancelled` is raised.

    Returns
    -------
    Animation
    """
    raise NotImplementedError("animate() lands with the in-between stage")
