"""The one place that reaches a material's shader nodes, on every supported Blender.

Blender 4.x makes a new material without nodes: ``Material.use_nodes`` switches
them on and creates the node tree. From 5.0 every material has its node tree
and ``use_nodes`` is deprecated (reading or setting it warns; it goes away in
6.0). `shader_node_tree` returns the tree on either line and touches
``use_nodes`` only where it still means something.
"""

from __future__ import annotations

import bpy

__all__ = ["NODES_ALWAYS", "shader_node_tree"]

#: The first Blender whose materials always use nodes (``Material.use_nodes`` deprecated).
NODES_ALWAYS = (5, 0, 0)


def shader_node_tree(material: bpy.types.Material) -> bpy.types.ShaderNodeTree:

    """``material``'s shader node tree, its nodes switched on where Blender has that switch.

    Parameters
    ----------
    material : bpy.types.Material

    Returns
    -------
    bpy.types.ShaderNodeTree
    """
    if bpy.app.version < NODES_ALWAYS:
        material.use_nodes = True
    return material.node_tree
