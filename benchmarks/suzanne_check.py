"""Suzanne with a UV checker and two materials turning 90 degrees with a slight squash (bpy).

Used by bench_artist_mesh.py (figures, renders) and by the Blender tests (assertions).
`build` makes the scene through the add-on's operators, `bake` runs it, `figures` measures
the result and `render` renders one frame with Cycles (emission shading: no lights, no
noise, the same pixels for the same geometry and UVs).
"""

import math
import os

import bpy
import numpy as np

from keyframe_implicit.blender.materials import shader_node_tree

SQUASH = (1.05, 1.05, 0.9)
FRAMES = (1, 13)


def checker_material(name, colour):
    """Emission of a checker texture read through the active UV map."""
    mat = bpy.data.materials.new(name)
    tree = shader_node_tree(mat)
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    coords = nodes.new("ShaderNodeTexCoord")
    checker = nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 12.0
    checker.inputs["Color1"].default_value = (*colour, 1.0)
    checker.inputs["Color2"].default_value = (0.95, 0.95, 0.95, 1.0)
    emit = nodes.new("ShaderNodeEmission")
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(coords.outputs["UV"], checker.inputs["Vector"])
    links.new(checker.outputs["Color"], emit.inputs["Color"])
    links.new(emit.outputs["Emission"], out.inputs["Surface"])
    return mat


def build(scene, resolution=40):
    """Keyframe A: Suzanne (UV map, checker materials red and, on its right side, blue,
    sharp edges on the brow); keyframe B: the same mesh turned 90 degrees about z and
    squashed. Returns (A, B)."""
    bpy.ops.mesh.primitive_monkey_add(size=2.0, location=(0, 0, 0), calc_uvs=True)
    a = bpy.context.active_object
    a.name = "Suzanne_A"
    mesh = a.data
    mesh.materials.append(checker_material("Checker Red", (0.8, 0.1, 0.1)))
    mesh.materials.append(checker_material("Checker Blue", (0.1, 0.2, 0.8)))
    centre = np.empty(3 * len(mesh.polygons), np.float32)
    mesh.polygons.foreach_get("center", centre)
    mesh.polygons.foreach_set("material_index", (centre.reshape(-1, 3)[:, 0] > 0.3).astype(np.int32))
    mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), bool))
    co = np.empty(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    ev = np.empty(2 * len(mesh.edges), np.int32)
    mesh.edges.foreach_get("vertices", ev)
    ev = ev.reshape(-1, 2)
    brow = np.all(co[ev][:, :, 2] > 0.4, axis=1) & np.all(co[ev][:, :, 1] < -0.5, axis=1)
    mesh.edges.foreach_set("use_edge_sharp", brow)
    mesh.edges.foreach_set("use_seam", np.all(co[ev][:, :, 0] > 0.6, axis=1))
    b = bpy.data.objects.new("Suzanne_B", mesh.copy())
    a.users_collection[0].objects.link(b)
    b.rotation_euler = (0.0, 0.0, math.radians(90))
    b.scale = SQUASH
    b.location = (0.3, 0.0, 0.0)
    bpy.context.view_layer.update()
    mb = np.array(b.matrix_world)
    x, y, z = co.T
    mid = np.abs(x) < 0.02
    picks = [np.argmin(x), np.argmax(x), np.argmin(np.where(mid, z, np.inf)),
             np.argmax(np.where(mid, z, -np.inf)), np.argmax(np.where(mid, y, -np.inf)),
             np.argmin(np.where(mid & (z < 0.3) & (z > -0.5), y, np.inf))]
    pa = co[picks].astype(float)
    pb = pa @ mb[:3, :3].T + mb[:3, 3]
    for obj, frame in zip((a, b), FRAMES):
        scene.frame_set(frame)
        bpy.ops.keyframe_implicit.add_keyframe(object_name=obj.name, frame=frame)
    for pta, ptb in zip(pa, pb):
        bpy.ops.keyframe_implicit.add_feature_pair(segment=0, location_a=tuple(pta),
                                                   location_b=tuple(ptb))
    scene.frame_set(FRAMES[0])
    scene.keyframe_implicit.resolution = resolution
    return a, b


def bake(scene, mode="AUTO"):
    from keyframe_implicit.blender import bake as bake_mod

    scene.keyframe_implicit.output_mode = mode
    return bake_mod.bake_scene(scene)


def evaluated(obj, frame):
    """World vertices (V, 3) float32, triangles, loop vertices, loop UVs and polygon
    material indices of ``obj`` evaluated on ``frame``."""
    scene = bpy.context.scene
    scene.frame_set(frame)
    dg = bpy.context.evaluated_depsgraph_get()
    ob = obj.evaluated_get(dg)
    me = ob.to_mesh()
    try:
        me.calc_loop_triangles()
        co = np.empty(3 * len(me.vertices), np.float32)
        me.vertices.foreach_get("co", co)
        tri = np.empty(3 * len(me.loop_triangles), np.int32)
        me.loop_triangles.foreach_get("vertices", tri)
        tri_loops = np.empty(3 * len(me.loop_triangles), np.int32)
        me.loop_triangles.foreach_get("loops", tri_loops)
        lv = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("vertex_index", lv)
        uv = np.zeros(2 * len(me.loops), np.float32)
        if me.uv_layers.active is not None:
            me.uv_layers.active.uv.foreach_get("vector", uv)
        mat = np.empty(len(me.polygons), np.int32)
        me.polygons.foreach_get("material_index", mat)
        names = [m.name if m else "" for m in me.materials]
    finally:
        ob.to_mesh_clear()
    m = np.array(ob.matrix_world, dtype=np.float32)
    co = co.reshape(-1, 3)
    if not np.allclose(m, np.eye(4)):
        co = (co @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
    return dict(co=co, tris=tri.reshape(-1, 3), tri_loops=tri_loops.reshape(-1, 3), lv=lv,
                uv=uv.reshape(-1, 2), material=mat, names=names)


def uv_agreement(out, key):
    """|UV error| per loop of ``out`` on ``key`` (dicts of `evaluated`, same loops: the
    result built from keyframe A and keyframe B, a copy of A's mesh): each loop's vertex is
    read on ``key`` in a triangle of the loop's own polygon there (barycentric, clipped), so
    both sides of a seam read their own UVs; the error is that UV against the loop's."""
    from keyframe_implicit.core.surface.attributes import barycentric

    tri_of_loop = np.empty(len(key["lv"]), np.int64)
    tri_of_loop[key["tri_loops"].reshape(-1)] = np.repeat(np.arange(len(key["tris"])), 3)
    tri = tri_of_loop[np.arange(len(out["lv"]))]
    corners = key["co"][key["tris"][tri]].astype(float)
    bary = barycentric(out["co"][out["lv"]].astype(float), *corners.transpose(1, 0, 2))
    uv = np.einsum("pk,pkd->pd", bary, key["uv"][key["tri_loops"][tri]])
    return np.linalg.norm(uv - out["uv"], axis=1)


def pixels(path):
    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(h, w, 4)


def render(scene, frame, path, size=160):
    """Cycles, 4 samples, emission only, transparent film: the frame as (H, W, 4) floats."""
    r = scene.render
    r.engine = "CYCLES"
    scene.cycles.samples = 4
    scene.cycles.seed = 0
    scene.cycles.use_denoising = False  # emission needs none, and not every build has one
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    r.film_transparent = True
    r.image_settings.file_format = "PNG"
    if scene.camera is None:
        cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        scene.collection.objects.link(cam)
        cam.location = (0.4, -7.0, 0.6)
        cam.rotation_euler = (math.radians(88), 0.0, 0.0)
        scene.camera = cam
    scene.frame_set(frame)
    r.filepath = path
    bpy.ops.render.render(write_still=True)
    return pixels(path)


def report(renders=None, resolution=40):
    """Print the Suzanne figures for both outputs: render difference on the first keyframe
    frame, UV agreement on every frame, materials kept, frame A exact, frame B's distance to
    B's mesh; with ``renders`` (a folder) the first, middle and last frames are saved there."""
    from keyframe_implicit.core.surface.quality import mesh_distance

    for mode in ("SHAPE_KEYS", "MESH_SEQUENCE"):
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True, load_ui=False)
        import keyframe_implicit

        keyframe_implicit.register()
        scene = bpy.context.scene
        a, b = build(scene, resolution)
        obj = bake(scene, mode)
        h = obj["kfi_stats"]["spacing"]
        src = {FRAMES[0]: evaluated(a, FRAMES[0]), FRAMES[1]: evaluated(b, FRAMES[1])}
        first, last = evaluated(obj, FRAMES[0]), evaluated(obj, FRAMES[1])
        exact_a = len(first["co"]) == len(src[FRAMES[0]]["co"]) and \
            np.array_equal(first["co"], src[FRAMES[0]]["co"])
        to_b = mesh_distance(last["co"].astype(float), src[FRAMES[1]]["co"].astype(float),
                             src[FRAMES[1]]["tris"]).max() / h
        uv_kf = [np.mean(uv_agreement(evaluated(obj, f), s) <= 0.01) if
                 len(evaluated(obj, f)["lv"]) == len(s["lv"]) else np.nan for f, s in src.items()]
        mats = sorted(set(np.unique(last["material"]).tolist()))
        print(f"Suzanne {resolution} cells, {mode.lower()}: frame A exact {exact_a}, frame B to "
              f"B's mesh max {to_b:.3f} h, UVs within 0.01 on keyframe frames "
              f"{', '.join(f'{100 * u:.1f} %' for u in uv_kf)}, materials on frame B {mats}, "
              f"slots {last['names']}", flush=True)
        if mode == "SHAPE_KEYS":
            a.hide_render = b.hide_render = True
            tmp = renders or bpy.app.tempdir
            result = render(scene, FRAMES[0], os.path.join(tmp, "suzanne_result_first.png"))
            if renders:
                mid = (FRAMES[0] + FRAMES[1]) // 2
                render(scene, mid, os.path.join(renders, "suzanne_result_middle.png"))
                render(scene, FRAMES[1], os.path.join(renders, "suzanne_result_last.png"))
            obj.hide_render, a.hide_render = True, False
            original = render(scene, FRAMES[0], os.path.join(tmp, "suzanne_original_first.png"))
            diff = np.abs(result - original)[..., :3].mean()
            print(f"  render on frame {FRAMES[0]}: mean pixel difference to the original "
                  f"{100 * diff:.3f} %", flush=True)
