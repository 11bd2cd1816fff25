"""keyframe_implicit: physically plausible in-betweens of implicit keyframes, for Blender.

The package has two halves:

- ``keyframe_implicit.core``: the numerical method (numpy/scipy/scikit-image, no bpy);
- ``keyframe_implicit.blender``: the thin Blender layer (operators, panel, bake).

``register()`` / ``unregister()`` below are what Blender calls when the
extension is enabled; they also work when the package is imported from a
source checkout with the ``bpy`` module. They import the Blender side themselves: importing
the package (the worker processes and the command line do) imports no bpy.
"""

from __future__ import annotations

from .version import __version__

__all__ = ["__version__", "register", "unregister"]


def register() -> None:
    """Register the add-on's properties, operators, panels and handlers with Blender."""
    from . import blender

    blender.register()


def unregister() -> None:
    """Remove what `register` added, in reverse order."""
    from . import blender

    blender.unregister()
