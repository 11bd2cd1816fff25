"""Fixtures for the Blender-side tests (bpy module or a real ``blender -b``).

Every test gets an empty factory scene with the add-on registered from the
checkout; helpers build keyframe scenes through the add-on's operators. Every
test fails if this checkout's code used a deprecated Blender API
(`failing_on_blender_deprecations`).
"""

import contextlib
import hashlib
import os
import pathlib
import re
import textwrap
import warnings

import bpy
import numpy as np
import pytest

import keyframe_implicit

# Low grid resolution keeps the real core fast; figures in the assertions are
# relative to the grid spacing h the bake used.
RES = 20

ROOT = pathlib.Path(__file__).resolve().parents[2]

#: bpy words its deprecations with the Blender version that drops the API, e.g.
#: "'Material.use_nodes' is expected to be removed in Blender 6.0".
_BLENDER_VERSION_IN_TEXT = re.compile(r"\bBlender \d+\.\d+")


def blender_deprecations(caught):
    """The warnings among ``caught`` that are Blender-API deprecations used by this checkout.

    One counts when it is a (pending) DeprecationWarning, its text names a Blender version
    (as bpy's deprecations do) and it is attributed to a file of this checkout (bpy attributes
    it to the line that used the API). Deprecations inside other packages (scikit-image on a
    newer numpy, Blender's own scripts) are not this project's code and stay plain warnings.
    """
    root = os.path.realpath(ROOT) + os.sep
    return [w for w in caught
            if issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning))
            and _BLENDER_VERSION_IN_TEXT.search(str(w.message))
            and os.path.realpath(w.filename).startswith(root)]


@contextlib.contextmanager
def failing_on_blender_deprecations():
    """Fail if the code inside used a deprecated Blender API; pass other warnings on to pytest.

    Warnings are recorded rather than turned into errors, so a deprecation inside an operator
    or a bake thread cannot be swallowed by the code that catches errors there.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    found = blender_deprecations(caught)
    for w in caught:
        if w not in found:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    if found:
        pytest.fail("deprecated Blender API used (change it in the helper of that API, see "
                    "keyframe_implicit/blender/__init__.py):\n" + "\n".join(
                        f"  {w.filename}:{w.lineno}: {w.message}" for w in found), pytrace=False)


@pytest.fixture(autouse=True)
def no_blender_deprecations():
    with failing_on_blender_deprecations():
        yield


@pytest.fixture(autouse=True)
def own_work_cache(tmp_path_factory, monkeypatch):
    """Each test's bakes keep their work (`blender.work_cache`) in a folder of its own: a bake
    never takes what an earlier test's left (not in ``tmp_path``, which tests list)."""
    from keyframe_implicit.blender import work_cache

    folder = str(tmp_path_factory.mktemp("work_cache"))
    monkeypatch.setattr(work_cache, "directory", lambda: folder)


@pytest.fixture
def scene():
    keyframe_implicit.unregister()
    # Factory *scene* only: read_factory_settings would also reset the preferences, and in a
    # real Blender that disables the installed extension and deletes its scipy/scikit-image
    # wheels from the extensions' site-packages (Blender keeps that folder in sync).
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True, load_ui=False)
    keyframe_implicit.register()
    yield bpy.context.scene
    keyframe_implicit.unregister()


def add_sphere(name, location, radius=1.0):
    """A UV sphere made with Blender's own operator (becomes the active object)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=radius,
                                         location=location)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.name = name
    return obj


def sphere_points(center, radius):
    """Four feature points on a sphere (poles, +y, -x side)."""
    c = np.asarray(center, float)
    dirs = np.array([[0, 0, 1], [0, 0, -1], [0, 1, 0], [-1, 0, 0]], float)
    return c + radius * dirs


def build_spheres(specs, *, pairs=True):
    """Keyframes from (name, center, radius, frame) through the operators only; returns objects."""
    objs = []
    for name, center, radius, frame in specs:
        obj = add_sphere(name, center, radius)
        bpy.context.scene.frame_set(frame)
        assert bpy.ops.keyframe_implicit.add_keyframe() == {"FINISHED"}
        objs.append(obj)
    if pairs:
        for seg in range(len(specs) - 1):
            pa = sphere_points(specs[seg][1], specs[seg][2])
            pb = sphere_points(specs[seg + 1][1], specs[seg + 1][2])
            for a, b in zip(pa, pb):
                assert bpy.ops.keyframe_implicit.add_feature_pair(
                    segment=seg, location_a=tuple(a), location_b=tuple(b)) == {"FINISHED"}
    bpy.context.scene.frame_set(specs[0][3])
    return objs


def mesh_hash(mesh):
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    return hashlib.sha256(co.tobytes()).hexdigest()


def snapshot():
    """Names of every data-block kind a bake may create, plus hashes of all meshes' vertices."""
    d = bpy.data
    return {
        "objects": sorted(o.name for o in d.objects),
        "meshes": sorted(m.name for m in d.meshes),
        "collections": sorted(c.name for c in d.collections),
        "actions": sorted(a.name for a in d.actions),
        "shape_keys": sorted(k.name for k in d.shape_keys),
        "materials": sorted(m.name for m in d.materials),
        "node_groups": sorted(g.name for g in d.node_groups),
        "mesh_hashes": {m.name: mesh_hash(m) for m in d.meshes},
        "matrices": {o.name: tuple(map(tuple, o.matrix_world)) for o in d.objects},
        "output": (bpy.context.scene.keyframe_implicit.output_object.name
                   if bpy.context.scene.keyframe_implicit.output_object else None),
    }


def evaluated_arrays(obj):
    """World-space vertices and triangles of ``obj`` as evaluated on the current frame."""
    dg = bpy.context.evaluated_depsgraph_get()
    ob = obj.evaluated_get(dg)
    me = ob.to_mesh()
    try:
        me.calc_loop_triangles()
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        tri = np.empty(len(me.loop_triangles) * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tri)
    finally:
        ob.to_mesh_clear()
    m = np.array(ob.matrix_world)
    return co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3], tri.reshape(-1, 3)


def volume(verts, tris):
    """Enclosed volume of a closed triangle mesh (divergence theorem)."""
    a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


@pytest.fixture
def in_worker(tmp_path, monkeypatch):
    """``in_worker(source)``: run Python ``source`` at the start of the bake's worker processes
    this test starts (a monkeypatch in this process cannot reach them).

    The worker is a fresh Python that inherits this process's ``PYTHONPATH`` after its own
    folders; Python imports a ``sitecustomize`` module found there at start-up, so the test
    writes one. Inside, this package is ``keyframe_implicit``.
    """
    def install(source):
        (tmp_path / "sitecustomize.py").write_text(textwrap.dedent(source))
        monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
            [str(tmp_path), *filter(None, [os.environ.get("PYTHONPATH")])]))

    return install


@pytest.fixture
def kfi():
    """The helpers above, for test modules (conftest modules are not importable by name)."""
    import types

    return types.SimpleNamespace(
        RES=RES, add_sphere=add_sphere, sphere_points=sphere_points, build_spheres=build_spheres,
        mesh_hash=mesh_hash, snapshot=snapshot, evaluated_arrays=evaluated_arrays, volume=volume,
        blender_deprecations=blender_deprecations,
        failing_on_blender_deprecations=failing_on_blender_deprecations,
    )
