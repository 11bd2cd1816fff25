"""The panel refuses exactly the keyframes the bake cannot bake, and says why in words an
artist can act on: its verdict, read from a Blender mesh (`scene_io.read_mesh`,
`validate.mesh_problems`), against the core's on generated meshes (tests/hostile_meshes.py).
benchmarks/bench_panel_agreement.py runs the same comparison on 500 meshes."""

import bpy
import numpy as np
from hypothesis import HealthCheck, given, settings

from hostile_meshes import SPHERE, core_bakes, hostile_meshes
from keyframe_implicit.blender import bake, scene_io, validate

FIXED = settings(derandomize=True, database=None, deadline=None, max_examples=30,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                        HealthCheck.function_scoped_fixture])


def mesh_object(name, vertices, faces):
    """A mesh object in the scene with exactly these vertices and faces."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in vertices], [], [tuple(int(i) for i in t) for t in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def panel_refuses(obj):
    """Whether the panel's checks of ``obj`` as a keyframe block the bake."""
    dg = bpy.context.evaluated_depsgraph_get()
    return any(severity == validate.ERROR
               for severity, _ in validate.mesh_problems(scene_io.read_mesh(obj, dg)))


@FIXED
@given(mesh=hostile_meshes())
def test_panel_refuses_exactly_what_the_core_cannot_bake(scene, mesh):
    v, f, what = mesh
    obj = mesh_object("Generated", v, f)
    try:  # the core judges the mesh as a bake reads it from Blender (float32 coordinates)
        read = scene_io.mesh_arrays(obj, bpy.context.evaluated_depsgraph_get())
        assert panel_refuses(obj) == (not core_bakes(*read)), what
    finally:
        bpy.data.meshes.remove(obj.data)


def _sweep_case(kfi, spoil):
    """Two spheres as keyframes (tests/blender/conftest.py), the first one spoilt."""
    a, _ = kfi.build_spheres([("KeyA", (0.0, 0.0, 0.0), 0.25, 1), ("KeyB", (1.0, 0.0, 0.0), 0.25, 9)])
    spoil(a.data)
    a.data.update()
    bpy.context.view_layer.update()
    return a


def _upper_half_inward(mesh):
    for poly in mesh.polygons:
        if poly.center.z > 0:
            poly.flip()


def _loose_vertex_far(mesh):
    mesh.vertices.add(1)
    mesh.vertices[-1].co = (50.0, 0.0, 0.0)


def test_sphere_wound_inward_on_its_upper_half_bakes_with_a_warning(scene, kfi):
    _sweep_case(kfi, _upper_half_inward)
    found = validate.problems(scene)
    assert not validate.errors(found), [p.message for p in found]
    [warning] = [p.message for p in found if "inward" in p.message]
    assert warning.startswith("Keyframe 1 'KeyA' has ") and "Recalculate Outside" in warning
    assert "reads it correctly" in warning
    notes = []
    out = bake.bake_scene(scene, kfi.RES, notes=notes)
    assert out is not None and any("faced the wrong way" in n for n in notes), notes


def test_sphere_with_a_loose_vertex_far_away_bakes_with_a_warning(scene, kfi):
    _sweep_case(kfi, _loose_vertex_far)
    found = validate.problems(scene)
    assert not validate.errors(found), [p.message for p in found]
    [warning] = [p.message for p in found if "loose" in p.message]
    assert warning.startswith("Keyframe 1 'KeyA' has 1 loose vertex (in no face), up to 49.8 "
                              "units outside its faces: the bake ignores it"), warning
    out = bake.bake_scene(scene, kfi.RES)
    extent = np.ptp(np.array([v.co for v in out.data.vertices]), axis=0)
    assert extent.max() < 2.0  # the far vertex was no part of the grid or the result


def test_the_two_sweep_cases_are_judged_as_the_core_judges_them(scene):
    v, f = SPHERE
    upper = v[f].mean(axis=1)[:, 2] > 0
    cases = {"Inward": (v, np.where(upper[:, None], f[:, ::-1], f)),
             "Loose": (np.concatenate([v * 0.25, [[50.0, 0.0, 0.0]]]), f)}
    for name, (cv, cf) in cases.items():
        assert core_bakes(cv, cf) and not panel_refuses(mesh_object(name, cv, cf)), name
