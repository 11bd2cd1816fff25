"""Blender side: scene properties, operators, sidebar panel, bake (imports bpy)."""


def register():
    pass


def unregister():
    pass
