"""Scene settings: ``bpy.types.Scene.keyframe_implicit``.

One `KFI_Settings` per scene holds the ordered keyframe list, the grid
resolution, the objective weights of thesis eq. 2.6 (see
``keyframe_implicit/core/map/terms.py``; the panel calls them Volume, Rigidity and
Shape Match), the output options, a pointer to the baked output object, so that
baking again replaces that object and only it, and whether the keyframes are
shown over it (`result_view`).

What belongs to the session and not to the file, whether the live preview runs
(`preview`), is `KFI_Session`, ``bpy.types.WindowManager.keyframe_implicit``.
"""

from collections.abc import Callable

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from ..core.bake.options import BakeOptions
from ..core.map.options import default_weights


def _is_mesh(_self: "KFI_Keyframe", obj: bpy.types.Object | None) -> bool:
    return obj is not None and obj.type == "MESH"


#: What runs when a setting with a side effect changes, by property name ("input": every
#: other setting the bake reads, which the live preview follows). The modules that
#: act on a setting fill it in when the add-on registers (`blender.register`), so the
#: settings, which every other module reads, import none of them. A handler gets the
#: property group that changed (`KFI_Settings`, `KFI_Session`, or the `KFI_Keyframe`
#: whose ``object`` was picked) and the context.
ON_CHANGE: dict[str, Callable[[bpy.types.PropertyGroup, bpy.types.Context], None]] = {}


def _on_change(*names: str) -> Callable[[bpy.types.PropertyGroup, bpy.types.Context], None]:
    """The ``update`` callback of a setting: the handlers `ON_CHANGE` holds for ``names``,
    in order."""
    def update(group: bpy.types.PropertyGroup, context: bpy.types.Context) -> None:
        for name in names:
            handler = ON_CHANGE.get(name)
            if handler is not None:
                handler(group, context)

    return update


#: The highest Resolution and Motion Resolution the fields take: far above what any
#: computer's memory allows, so the limit a setting meets is the memory's, which the panel
#: states (`limits`), never a silent clamp.
MAX_RESOLUTION = 4096


def _set_motion_auto(settings: "KFI_Settings", auto: bool) -> None:
    """Motion Resolution Auto on (0) or off: then Resolution, until its `ON_CHANGE`
    handler puts in the value Auto chooses for these keyframes."""
    if auto:
        settings.motion_resolution = 0
    elif settings.motion_resolution == 0:
        settings.motion_resolution = settings.resolution


class KFI_Keyframe(bpy.types.PropertyGroup):
    """One keyframe: a mesh object and the timeline frame its shape must be matched on."""

    object: PointerProperty(
        name="Object",
        type=bpy.types.Object,
        poll=_is_mesh,
        description="Mesh object whose (evaluated, world-space) shape is this keyframe",
        update=_on_change("object", "input"),
    )
    frame: IntProperty(name="Frame", default=1, description="Timeline frame of this keyframe",
                       update=_on_change("input"))
    interpolation: EnumProperty(
        name="Interpolation",
        items=(
            ("SMOOTH", "Smooth", "The motion flows through this keyframe without a jump in "
             "speed or direction (a natural start or end on the first and last keyframe)",
             "IPO_BEZIER", 0),
            ("LINEAR", "Linear", "The motion turns a corner here: each side moves at its own "
             "constant pace", "IPO_LINEAR", 1),
            ("EASE", "Ease", "The motion slows to rest on this keyframe and starts again "
             "from rest", "IPO_EASE_IN_OUT", 2),
        ),
        default="SMOOTH",
        description="How the motion passes this keyframe",
        update=_on_change("input"),
    )
    surface_tension: FloatProperty(
        name="Surface Tension", default=1.0, min=0.0, soft_max=2.0, step=10,
        description="How parts join where they meet, from this keyframe to the next: 0 as "
                    "clay pressed together (a sharp crease where they touch), 1 as a liquid "
                    "(the neck rounds off within a few frames), more for rounder. A part "
                    "that splits thins the same way",
        update=_on_change("input"),
    )
    display_type: StringProperty(
        name="Display As", default="", options={"HIDDEN"},
        description="The object's own viewport display type while the bake shows it as a wireframe",
    )


class KFI_Settings(bpy.types.PropertyGroup):
    """Setup of one bake: keyframes, grid, weights and output."""

    keyframes: CollectionProperty(type=KFI_Keyframe, name="Keyframes")
    active_keyframe_index: IntProperty(name="Active Keyframe", default=0, min=0)
    resolution: IntProperty(
        name="Resolution",
        default=BakeOptions.resolution,
        min=8,
        max=MAX_RESOLUTION,
        soft_max=128,
        description="How much detail the shapes keep: grid cells along the longest side of "
        "the keyframes' bounding box. Memory and time grow with its cube: the line below "
        "says how much memory it needs, and Bake waits for a resolution that fits",
        update=_on_change("input"),
    )
    motion_resolution: IntProperty(
        name="Motion Resolution",
        default=0,
        min=0,
        max=MAX_RESOLUTION,
        soft_max=128,
        description="How much detail the motion keeps: the grid the movement is worked out "
        "on, in cells across the keyframes' longest side, like Resolution (equal to it: the "
        "motion at full detail). Raise it when thin parts move together that should move "
        "apart. 0 is Auto",
        update=_on_change("input"),
    )
    motion_auto: BoolProperty(
        name="Auto", get=lambda self: self.motion_resolution == 0, set=_set_motion_auto,
        description="Let the bake choose how much detail the motion keeps, for speed; "
        "shapes keep the full Resolution either way",
        update=_on_change("motion_auto"),
    )
    # Weights of the three terms of thesis eq. 2.6 (core/map/terms.py), in an artist's words.
    volume_weight: FloatProperty(
        name="Volume", default=default_weights()["volume"], min=0.0, soft_max=100.0,
        description="How strictly every part keeps its volume while it moves. Raise it when "
        "in-betweens shrink or swell (thesis eq. 2.6: the volume term (det F - 1)^2)",
        update=_on_change("input"),
    )
    rigidity_weight: FloatProperty(
        name="Rigidity", default=default_weights()["rigidity"], min=0.0, soft_max=100.0,
        description="How stiffly the parts move, without stretching or shearing. Raise it when "
        "in-betweens look rubbery; lower it for soft, fluid shapes (thesis eq. 2.6: the "
        "rigidity term ||F^T F - I||^2)",
        update=_on_change("input"),
    )
    levelset_weight: FloatProperty(
        name="Shape Match", default=default_weights()["levelset"], min=0.0, soft_max=100.0,
        description="How closely the first keyframe's shape is pulled onto the next one's. "
        "Raise it when parts of the motion miss the next keyframe's shape (thesis eq. 2.6: "
        "the level-set matching term)",
        update=_on_change("input"),
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
    volume_export: BoolProperty(
        name="OpenVDB Volume", default=False,
        description="Also write the in-between level sets as a .vdb sequence (one file per "
        "frame) with a Volume object that plays it, for Houdini and volume workflows",
    )
    volume_directory: StringProperty(
        name="Folder", subtype="DIR_PATH", default="//kfi_volumes/",
        description="Where the .vdb files go; '//' is the folder of the saved .blend",
    )
    show_keyframes: BoolProperty(
        name="Show Keyframes", default=False,
        description="Show the keyframe objects as wireframes over the baked result, to compare "
        "them (they stay out of renders)",
        update=_on_change("show_keyframes"),
    )
    show_all_problems: BoolProperty(
        name="All Problems", default=False,
        description="List every problem found, not only the first ones",
    )
    show_report_details: BoolProperty(
        name="Figures", default=False,
        description="The figures behind the bake report, each explained",
    )

    def motion(self) -> int | None:
        """The Motion Resolution as the core expects it: None for automatic."""
        return int(self.motion_resolution) or None

    def weights(self) -> dict[str, float]:
        """The weights as the core expects them (``animate(weights=...)``)."""
        return {
            "volume": float(self.volume_weight),
            "rigidity": float(self.rigidity_weight),
            "levelset": float(self.levelset_weight),
        }


class KFI_Session(bpy.types.PropertyGroup):
    """The add-on's state in this Blender session, not in the file.

    It lives on the window manager, where Blender keeps what belongs to the session: its
    properties are neither saved in the .blend nor part of the undo history. The live
    preview is a worker process and a draw handler of this session, so its toggle is here:
    a saved file, the farm's assembled one too, never carries it, and undo and redo never
    turn it on or off behind the preview's back. The window manager outlives a file load
    that keeps the UI, so a loaded file turns it off (`preview.on_load_post`).
    """

    live_preview: BoolProperty(
        name="Live Preview", default=False,
        description="Show the in-between on the current frame over the 3D view, solved on a "
        "coarse grid and updated as keyframes and feature points move (nothing is added to "
        "the scene; it stays off in saved files)",
        update=_on_change("live_preview"),
    )


classes = (KFI_Keyframe, KFI_Settings, KFI_Session)


def register_properties() -> None:
    """Give every scene its ``keyframe_implicit`` settings and the session its state."""
    bpy.types.Scene.keyframe_implicit = PointerProperty(type=KFI_Settings)
    bpy.types.WindowManager.keyframe_implicit = PointerProperty(type=KFI_Session)


def unregister_properties() -> None:
    """Remove the scenes' ``keyframe_implicit`` settings and the session's state."""
    del bpy.types.WindowManager.keyframe_implicit
    del bpy.types.Scene.keyframe_implicit
