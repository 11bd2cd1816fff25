"""Build the example scenes in assets/ deterministically, through the add-on's own operators.

Run from the repository root with the bpy module of the OLDEST supported Blender (4.2 LTS),
so that every supported Blender opens the files (a .blend saved by 5.0 has a new header that
4.x cannot read; newer versions read older files)::

    KFI_PYTHON=3.11 KFI_REQUIREMENTS=requirements-bpy42.txt \
        bash -c 'source scripts/env.sh && python assets/make_assets.py'      # every scene
    ... python assets/make_assets.py bend rigid                               # some scenes

Each scene is made in an empty file: the keyframe meshes (from `keyframe_implicit.examples`,
or Blender's monkey for "suzanne") are added as mesh objects in a collection "Keyframes",
registered with ``keyframe_implicit.add_keyframe(object_name=..., frame=...)``, and their
feature points are created with ``keyframe_implicit.add_feature_pair(segment=i,
location_a=..., location_b=..., name=...)`` (world coordinates). The timeline runs from the
first keyframe's frame to the last's; a camera frames every keyframe, a sun lights them,
and keyframe A carries a material (the bake copies it to its result).

Visibility: the keyframe objects are hidden from renders: they are set-up data, like a rig's
control shapes, and what renders is the baked object. The scene opens on its first keyframe
with only that keyframe and its feature Empties shown (the others overlap it; Alt+H or the
outliner shows them), so the artist sees one shape, not all of them on top of each other.
The demo also hides them in the viewport of the baked file so pressing play shows the
result alone.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import bpy  # noqa: E402
from mathutils import Matrix, Vector  # noqa: E402

from keyframe_implicit import examples  # noqa: E402
from keyframe_implicit.blender import materials  # noqa: E402

SCENES = ("rigid", "merge", "bend", "splash", "suzanne")

# base colour of each scene's material (linear RGB)
COLOURS = {
    "rigid": (0.80, 0.33, 0.10),
    "merge": (0.10, 0.45, 0.80),
    "bend": (0.25, 0.60, 0.20),
    "splash": (0.05, 0.35, 0.75),
    "suzanne": (0.75, 0.55, 0.20),
}
# grid resolution stored in each scene (the bake's default for it)
RESOLUTIONS = {"rigid": 40, "merge": 40, "bend": 40, "splash": 40, "suzanne": 40}


def ensure_registered():
    """Register the add-on from this checkout once (classes survive file resets)."""
    if not hasattr(bpy.types.Scene, "keyframe_implicit"):
        import keyframe_implicit

        keyframe_implicit.register()


def new_file():
    """An empty file with the add-on registered (same start state for every scene)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ensure_registered()
    return bpy.context.scene


def add_mesh_object(name, vertices, faces, collection):
    """A mesh object with world-space `vertices` (V, 3) and triangles `faces` (F, 3)."""
    vertices = np.asarray(vertices, dtype=np.float32)
    faces = np.asarray(faces, dtype=np.int32)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", vertices.ravel())
    mesh.loops.add(faces.size)
    mesh.loops.foreach_set("vertex_index", faces.ravel())
    mesh.polygons.add(len(faces))
    mesh.polygons.foreach_set("loop_start", np.arange(0, faces.size, 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(len(faces), 3, dtype=np.int32))
    mesh.polygons.foreach_set("use_smooth", np.ones(len(faces), dtype=bool))
    mesh.update()
    mesh.validate()
    obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(obj)
    return obj


def make_material(name, colour):
    mat = bpy.data.materials.new(name)
    mat.diffuse_color = (*colour, 1.0)  # viewport / Workbench colour
    mat.roughness = 0.45
    nodes = materials.shader_node_tree(mat).nodes
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is not None:
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Roughness"].default_value = 0.45
    return mat


def world_points(obj):
    """World-space vertex positions of a mesh object, (V, 3)."""
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float64)
    obj.data.vertices.foreach_get("co", co)
    m = np.array(obj.matrix_world)
    co = co.reshape(-1, 3)
    return co @ m[:3, :3].T + m[:3, 3]


def frame_camera(scene, points, direction=(0.55, -1.0, 0.5), lens=50.0, margin=1.12):
    """Add a camera looking along -`direction` at `points` (N, 3), as close as they all fit.

    The distance is solved per point in the camera's basis: a point at (u, v) across and w
    towards the camera needs distance D >= w + |u| / tan(half fov x) (same for y).
    """
    pts = np.asarray(points, float)
    centre = 0.5 * (pts.min(0) + pts.max(0))
    d = Vector(direction).normalized()
    rot = d.to_track_quat("Z", "Y")  # camera looks along its -Z: place it on +direction
    basis = np.array(rot.to_matrix())  # columns: camera x, y, z in world
    rel = (pts - centre) @ basis
    data = bpy.data.cameras.new("Camera")
    data.lens = lens
    data.sensor_fit = "HORIZONTAL"
    aspect = scene.render.resolution_y / scene.render.resolution_x
    tx = (data.sensor_width / 2) / lens
    ty = tx * aspect
    dist = max(np.max(rel[:, 2] + np.abs(rel[:, 0]) / tx), np.max(rel[:, 2] + np.abs(rel[:, 1]) / ty))
    dist = float(dist) * margin
    cam = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(cam)
    cam.location = Vector(centre) + d * dist
    cam.rotation_euler = rot.to_euler()
    data.clip_start = 0.05
    data.clip_end = max(100.0, 4 * dist)
    scene.camera = cam
    return cam


def setup_look(scene):
    """Sun, world colour, Workbench settings for quick headless renders (material colours)."""
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(40), math.radians(10), math.radians(30))
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("World")
    world.color = (0.8, 0.8, 0.82)
    scene.world = world
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = 480
    scene.render.resolution_y = 360
    scene.render.resolution_percentage = 100
    scene.render.fps = 24
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "MATERIAL"
    shading.show_shadows = False
    shading.show_cavity = False
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Standard"


def _suzanne():
    """Monkey head (open mesh with holes) at the origin and a second pose: turned and lifted.

    Keyframe B shares nothing with A's data: it is a copy of the mesh on an object whose
    transform turns it 50 degrees about z, tips it 20 degrees back and lifts it; the bake
    reads both in world space. Pairs: ear tips, chin, nose, crown, back, both brows.
    """
    bpy.ops.mesh.primitive_monkey_add(size=2.0, location=(0, 0, 0))
    a = bpy.context.object
    a.name = "Suzanne_A"
    for poly in a.data.polygons:
        poly.use_smooth = True
    co = world_points(a)
    x, y, z = co.T
    mid = np.abs(x) < 0.02
    picks = {
        "ear_left": np.argmin(x),
        "ear_right": np.argmax(x),
        "chin": np.argmin(np.where(mid, z, np.inf)),
        "nose": np.argmin(np.where(mid & (z < 0.3) & (z > -0.5), y, np.inf)),
        "crown": np.argmax(np.where(mid, z, -np.inf)),
        "back": np.argmax(np.where(mid, y, -np.inf)),
        "brow_left": np.argmin(np.where(x < -0.1, y, np.inf)),
        "brow_right": np.argmin(np.where(x > 0.1, y, np.inf)),
    }
    b = bpy.data.objects.new("Suzanne_B", a.data.copy())
    a.users_collection[0].objects.link(b)
    b.location = (1.8, 0.6, 1.0)
    b.rotation_euler = (math.radians(-20), 0.0, math.radians(50))
    bpy.context.view_layer.update()
    names = list(picks)
    pa = co[[picks[n] for n in names]]
    mb = np.array(b.matrix_world)
    pb = pa @ mb[:3, :3].T + mb[:3, 3]
    return [a, b], [1, 25], [(pa, pb)], [names]


def build(name):
    """Build scene `name` (one of SCENES) in a fresh file; returns the scene."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}: choose one of {', '.join(SCENES)}")
    scene = new_file()
    scene.name = name
    keys = bpy.data.collections.new("Keyframes")
    scene.collection.children.link(keys)
    if name == "suzanne":
        # the monkey operator adds to the active collection: make it "Keyframes"
        bpy.context.view_layer.active_layer_collection = \
            bpy.context.view_layer.layer_collection.children["Keyframes"]
        objs, frames, features, feature_names = _suzanne()
    else:
        ex = examples.example(name)
        objs = [add_mesh_object(f"{name}_{chr(65 + i)}", k.vertices, k.faces, keys)
                for i, k in enumerate(ex.keyframes)]
        frames, features, feature_names = ex.frames, ex.features, ex.feature_names

    for obj in objs:
        obj.hide_render = True
    objs[0].data.materials.append(make_material(f"{name}_material", COLOURS[name]))
    for obj, frame in zip(objs, frames):
        bpy.ops.keyframe_implicit.add_keyframe(object_name=obj.name, frame=int(frame))
    for seg, ((pa, pb), names) in enumerate(zip(features, feature_names)):
        for a, b, n in zip(pa, pb, names):
            bpy.ops.keyframe_implicit.add_feature_pair(
                segment=seg, location_a=tuple(float(t) for t in a),
                location_b=tuple(float(t) for t in b), name=n)

    settings = scene.keyframe_implicit
    if hasattr(settings, "resolution"):
        settings.resolution = RESOLUTIONS[name]
    scene.frame_start = int(frames[0])
    scene.frame_end = int(frames[-1])
    scene.frame_set(int(frames[0]))
    setup_look(scene)
    frame_camera(scene, np.vstack([world_points(o) for o in objs]))
    show_first_keyframe(scene, objs)
    frame_timelines()
    return scene


def show_first_keyframe(scene, objs):
    """Hide every keyframe object but the first, with the feature Empties on them."""
    hidden = set(objs[1:])
    for obj in scene.objects:
        if obj in hidden or (obj.type == "EMPTY" and obj.parent in hidden):
            obj.hide_set(True)


def frame_timelines():
    """Frame every timeline and dope sheet of the file on the scene's frame range, as Home
    does in the window: the factory layout shows frames 0-250."""
    window = bpy.context.window_manager.windows[0]
    for screen in bpy.data.screens:
        for area in screen.areas:
            if area.type != "DOPESHEET_EDITOR":
                continue
            region = next(r for r in area.regions if r.type == "WINDOW")
            with bpy.context.temp_override(window=window, screen=screen, area=area,
                                           region=region):
                bpy.ops.action.view_all()


def save(path):
    """Save the current file compressed, without a UI thumbnail or relative-path surprises."""
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(path), compress=True, relative_remap=False,
                                check_existing=False)


def main(argv=None):
    names = list(argv if argv is not None else sys.argv[1:]) or list(SCENES)
    for name in names:
        build(name)
        path = os.path.join(HERE, f"{name}.blend")
        save(path)
        print(f"[assets] {name}: {os.path.getsize(path) / 1024:.0f} KiB -> {path}", flush=True)


if __name__ == "__main__":
    main()
