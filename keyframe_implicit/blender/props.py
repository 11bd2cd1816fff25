"""Scene settings: ``bpy.types.Scene.keyframe_implicit``.

One `KFI_Settings` per scene holds the ordered keyframe list, the grid
resolution, the objective weights of thesis eq. 2.6 (see
``keyframe_implicit/core/terms.py``), the output options and a pointer to the
baked output object, so that baking again replaces that object and only it.
"""

import bpy
from bpy.props import (
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from ..core.solver import DEFAULT_WEIGHTS


def _is_mesh(_self, obj):
    return obj is not None and obj.type == "MESH"


class KFI_Keyframe(bpy.types.PropertyGroup):
    """One keyframe: a mesh object and the timeline frame its shape must be matched on."""

    object: PointerProperty(
        name="Object",
        type=bpy.types.Object,
        poll=_is_mesh,
        description="Mesh object whose (evaluated, world-space) shape is this keyframe",
    )
    frame: IntProperty(name="Frame", default=1, description="Timeline frame of this keyframe")


class KFI_Settings(bpy.types.PropertyGroup):
    """Setup of one bake: keyframes, grid, weights and output."""

    keyframes: CollectionProperty(type=KFI_Keyframe, name="Keyframes")
    active_keyframe_index: IntProperty(name="Active Keyframe", default=0, min=0)
    resolution: IntProperty(
        name="Resolution",
        default=48,
        min=8,
        max=512,
        soft_max=128,
        description="Grid cells along the longest side of the keyframes' bounding box "
        "(memory and time grow with its cube)",
    )
    # Weights of the three terms of thesis eq. 2.6 (core/terms.py).
    volume_weight: FloatProperty(
        name="Volume", default=DEFAULT_WEIGHTS["volume"], min=0.0, soft_max=100.0,
        description="Weight of the volume term (det F - 1)^2: keeps the volume of every part",
    )
    rigidity_weight: FloatProperty(
        name="Rigidity", default=DEFAULT_WEIGHTS["rigidity"], min=0.0, soft_max=100.0,
        description="Weight of the rigidity term ||F^T F - I||^2: rigid parts move rigidly",
    )
    levelset_weight: FloatProperty(
        name="Level Set", default=DEFAULT_WEIGHTS["levelset"], min=0.0, soft_max=100.0,
        description="Weight of the level-set term: the mapped surface of keyframe A lands on keyframe B",
    )
    output_collection: StringProperty(
        name="Collection",
        default="Keyframe Implicit",
        description="Collection the baked object is put in (created if missing)",
    )
    output_name: StringProperty(
        name="Name", default="KFI Animation", description="Name of the baked object"
    )
    output_mode: EnumProperty(
        name="Output",
        items=(
            ("AUTO", "Auto", "Shape keys when every frame of the tracked mesh is clean, "
             "a mesh sequence otherwise (the bake report says which and why)"),
            ("SHAPE_KEYS", "Shape Keys", "One mesh with a shape key per frame: vertices keep "
             "their identity (UVs, morph-target export) but cannot change topology"),
            ("MESH_SEQUENCE", "Mesh Sequence", "Each frame's own surface (topology free, with "
             "velocities for motion blur), switched by Geometry Nodes"),
        ),
        default="AUTO",
        description="How the baked frames are stored",
    )
    output_object: PointerProperty(
        name="Output",
        type=bpy.types.Object,
        description="The baked object; Bake replaces it (and nothing else)",
    )

    def weights(self):
        """The weights as the core expects them (``animate(weights=...)``)."""
        return {
            "volume": float(self.volume_weight),
            "rigidity": float(self.rigidity_weight),
            "levelset": float(self.levelset_weight),
        }


classes = (KFI_Keyframe, KFI_Settings)


def register_properties():
    bpy.types.Scene.keyframe_implicit = PointerProperty(type=KFI_Settings)


def unregister_properties():
    del bpy.types.Scene.keyframe_implicit
