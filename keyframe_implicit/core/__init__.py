"""Numerical core of keyframe_implicit: pure numpy / scipy / scikit-image (and threadpoolctl
for BLAS's threads), never bpy.

The method (thesis "Keyframe Animation of Implicit Models", 2006; corrected equations
and what goes beyond the thesis in docs/method.md), one sub-package per stage:

=============  =================================================================
``fields``     keyframe meshes -> signed distance grids (sec. 2.1)
``map``        volume map by constrained Gauss-Newton on eq. 2.6 (ch. 2)
``motion``     as-rigid-as-possible trajectories, transports, in-betweens (ch. 3)
``surface``    level sets -> tracked meshes, attributes, quality, output mesh
``bake``       the whole bake: `animate`, its options (`BakeOptions`), chains, grid and
               memory, map scheduling, the live preview
``base``       the grid and the numerics every stage shares
=============  =================================================================

Imports run one way: ``bake`` uses the stages, each stage uses ``base`` (and
``surface`` the triangle kernel of ``fields``, ``motion`` the volumes and marching cubes
of ``surface``), and no module imports another's private name.

The public names below are imported lazily so that ``import
keyframe_implicit.core`` stays cheap and each stage can be used on its own.
"""

from __future__ import annotations

import importlib
from typing import Any

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
    "MapResult": "map.result",
    "inbetween": "bake.maps",
    "Inbetween": "motion.levelset",
    "Transport": "motion.transport",
    "extract_surface": "surface.extract",
    "track_template": "surface.template",
    "animate_chain": "bake.chain",
    "animate": "bake.pipeline",
    "bake": "bake.pipeline",
    "BakeOptions": "bake.options",
    "WorkCache": "bake.cache",
    "Keyframe": "bake.keyframe",
    "Animation": "bake.animation",
    "Cancelled": "base.progress",
    "Reporter": "base.progress",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'keyframe_implicit.core' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
