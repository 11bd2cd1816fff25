"""Numerical core of keyframe_implicit: pure numpy / scipy / scikit-image (and threadpoolctl
for BLAS's threads), never bpy.

Pipeline (thesis "Keyframe Animation of Implicit Models", 2006), one module per stage:

=====================  ==========================================================
``grid``               `Grid`: the regular grid every field lives on (sec. 2.1)
``sampling``           multilinear sampling of fields at off-grid points
``sdf``                keyframe meshes / polygons -> signed distance grids
``gridfit``            choosing a grid for given keyframes, memory estimate
``rbf``                initial map from feature points (eq. 2.1-2.5)
``terms``              the terms of the objective, eq. 2.6 (one per function)
``constraints``        feature-point constraints C y = d (eq. 2.14-2.20)
``solver``             constrained Gauss-Newton -> `solve_map` (sec. 2.5)
``trajectory``         as-rigid-as-possible trajectories (sec. 3.1)
``transport``          a keyframe's field carried along its trajectories
``levelset``           in-between level sets: two transports blended (eq. 3.4
                       read two-sided, PAPER-NOTES section 8) -> `inbetween`
``isovolume``          the iso-value that keeps an in-between's volume
``surface``            marching cubes / contours -> `extract_surface`
``template``           one mesh tracked through all frames (shape keys)
``chain``              several keyframes in sequence
``pipeline``           meshes + feature points + frames -> per-frame vertices
=====================  ==========================================================

The public names below are imported lazily so that ``import
keyframe_implicit.core`` stays cheap and each stage can be used on its own.
"""

from __future__ import annotations

import importlib

# public name -> module that defines it
_EXPORTS = {
    "Grid": "base.grid",
    "sample": "base.sampling",
    "sample_with_gradient": "base.sampling",
    "cell_weights": "base.sampling",
    "mesh_to_sdf": "fields.sdf",
    "polygon_to_sdf": "fields.polygon",
    "fit_grid": "bake.gridfit",
    "estimate_memory": "bake.memory",
    "MemoryLimitError": "bake.memory",
    "check_memory": "bake.memory",
    "solve_map": "map.solver",
    "MapResult": "map.solver",
    "inbetween": "bake.maps",
    "Inbetween": "motion.levelset",
    "Transport": "motion.transport",
    "extract_surface": "surface.extract",
    "track_template": "surface.template",
    "animate_chain": "bake.chain",
    "animate": "bake.pipeline",
    "Keyframe": "bake.pipeline",
    "Animation": "bake.pipeline",
    "Cancelled": "base.progress",
    "Reporter": "base.progress",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'keyframe_implicit.core' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
