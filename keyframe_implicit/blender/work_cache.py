"""Where the bakes keep their work on disk (`core.bake.cache.WorkCache`), and clearing it.

Each bake runs in a worker process of its own: its distance grids and maps are kept on disk,
under a key of exactly their inputs, so the next bake's worker finds those an edit left as
they were (one Empty moved: only its pair's maps are solved again). The folder is in
Blender's temporary directory of this session (`bpy.app.tempdir`, which Blender removes when
it quits), never in the add-on's folder, and holds at most `core.bake.cache.DISK_BYTES`. The
live preview's worker keeps its own in memory (`preview.clear_cache` clears it).
"""

from __future__ import annotations

import os
import tempfile

import bpy

from ..core.bake.cache import WorkCache

__all__ = ["directory", "clear"]

#: The folder's name in Blender's temporary directory.
FOLDER = "keyframe_implicit_cache"


def directory() -> str:
    """The folder the bakes' workers keep their work in (made by the first that keeps any)."""
    return os.path.join(bpy.app.tempdir or tempfile.gettempdir(), FOLDER)


def clear() -> int:
    """Remove every result kept in `directory`; the bytes freed."""
    return WorkCache(directory()).clear()
