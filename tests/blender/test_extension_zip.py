"""The built extension zip installs, enables and works the way a user installs it.

The test builds the linux-x64 zip with ``scripts/build_extension.py`` (wheels come
from the download cache, so this is quick after the first run), then runs a child
Python with the bpy module whose Blender user profile lives in a temporary
directory (``BLENDER_USER_*`` environment variables): the developer's own
profile is never touched and global add-on state stays out of the other tests.

The child (this file run as a script) installs the zip with Blender's own
``bpy.ops.extensions.package_install_files`` into the ``user_default``
repository, enabling it, and checks that

- the add-on registered from the installed copy (``bl_ext.user_default.keyframe_implicit``),
  with its operators under ``bpy.ops.keyframe_implicit``, and this checkout is not
  importable at all in the child (so an absolute ``import keyframe_implicit`` inside
  the add-on would fail here as it fails in Blender);
- scipy and scikit-image are imported from the wheels Blender unpacked from the zip
  (the copies in the test environment are hidden from the child) without a warning
  about the running numpy (1.26 up to Blender 5.0, 2.x from 5.1), and their compiled
  parts work: a distance transform and marching cubes on a sphere.
"""

import io
import json
import os
import pathlib
import subprocess
import sys
import zipfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]

#: Bake by the installed add-on: two equal spheres, BAKE_CENTERS apart, on BAKE_FRAMES,
#: at a low resolution (this checks the zip, not the method).
BAKE_RESOLUTION = 16
BAKE_RADIUS = 1.0
BAKE_CENTERS = ((-1.2, 0.0, 0.0), (1.2, 0.0, 0.0))
BAKE_FRAMES = (1, 4)


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory):
    return _build_linux_zip(tmp_path_factory.mktemp("zip"))


def _build_linux_zip(tmp_path):
    """Build the linux-x64 zip into ``tmp_path``, or take ``$KFI_EXTENSION_ZIP``.

    A given zip is used only if its package files are byte-identical to this
    checkout's (so a stale zip cannot pass); scripts/blender_chroot.sh passes the
    zip it built, because a distribution Blender's Python may lack pip.
    """
    given = os.environ.get("KFI_EXTENSION_ZIP")
    if given:
        _assert_zip_matches_checkout(pathlib.Path(given))
        return pathlib.Path(given)
    out = tmp_path / "dist"
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "build_extension.py"), "--platform", "linux-x64",
         "--out", str(out), "--build-dir", str(tmp_path / "build")],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout
    zips = sorted(out.glob("keyframe_implicit-*-linux_x64.zip"))
    assert len(zips) == 1, (zips, proc.stdout)
    return zips[0]


def _package_files():
    pkg = ROOT / "keyframe_implicit"
    return {p.relative_to(pkg).as_posix(): p.read_bytes() for p in pkg.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and p.suffix not in (".pyc", ".pyo")}


def _assert_zip_matches_checkout(zip_path):
    with zipfile.ZipFile(zip_path) as z:
        packaged = {n: z.read(n) for n in z.namelist()
                    if not n.endswith("/") and not n.startswith("wheels/") and n != "blender_manifest.toml"}
    mine = _package_files()
    assert sorted(packaged) == sorted(mine), f"{zip_path} does not hold this checkout's package files"
    stale = [n for n in mine if packaged[n] != mine[n]]
    assert not stale, f"{zip_path} is stale: {stale} differ from this checkout; rebuild it"


def _child_command(script, args):
    """Command that runs ``script`` with bpy: this Python, or this Blender if we run inside one."""
    import bpy

    if _in_real_blender():  # the bpy module has no binary
        return [bpy.app.binary_path, "-b", "--factory-startup", "--python-exit-code", "1",
                "--python", str(script), "--", *args]
    return [sys.executable, str(script), *args]


def _bundled_top_level_names(zip_path, python_tag):
    """Top-level import names of the wheels in the zip that serve ``python_tag``."""
    names = set()
    with zipfile.ZipFile(zip_path) as outer:
        for entry in outer.namelist():
            if not entry.endswith(".whl"):
                continue
            py = entry.rsplit("/", 1)[1].split("-")[-3]
            if py not in (python_tag, "py3") and not py.startswith("py3."):
                continue
            with zipfile.ZipFile(io.BytesIO(outer.read(entry))) as whl:
                for member in whl.namelist():
                    top = member.split("/", 1)[0]
                    if top.endswith((".dist-info", ".data", ".libs")):
                        continue
                    names.add(top[:-3] if top.endswith(".py") else top)
    return sorted(names)


def _blender_ext():
    """Blender's own extension tool, from the running bpy module or Blender."""
    import bpy

    path = pathlib.Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    assert path.is_file(), path
    return path


def test_blender_validator_accepts_zip_and_manifest_is_honest(linux_zip):
    import tomllib

    tool = _blender_ext()
    tags = tool.parents[3] / "modules" / "_bpy_internal" / "extensions" / "tags.py"
    proc = subprocess.run([sys.executable, str(tool), "validate",
                           f"--valid-tags={tags}", str(linux_zip)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=120)
    assert proc.returncode == 0 and "Success" in proc.stdout, proc.stdout
    with zipfile.ZipFile(linux_zip) as z:
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
    source = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert source["blender_version_min"] == manifest["blender_version_min"] == "4.2.0"
    # One version everywhere: manifest, package, pyproject.
    init = (ROOT / "keyframe_implicit" / "version.py").read_text()
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert f'__version__ = "{source["version"]}"' in init
    assert manifest["version"] == source["version"] == pyproject["project"]["version"]
    # Files only (the headless bake reads/writes .blend files); never network.
    assert set(manifest["permissions"]) == {"files"}
    assert manifest["build"]["generated"]["platforms"] == ["linux-x64"]
    with zipfile.ZipFile(linux_zip) as z:
        packed = sorted("./" + n for n in z.namelist() if n.endswith(".whl"))
    assert sorted(manifest["build"]["generated"]["wheels"]) == packed


def _in_real_blender():
    import bpy

    return bool(bpy.app.binary_path)


def test_zip_manifest_and_contents(linux_zip):
    zip_path = linux_zip
    with zipfile.ZipFile(zip_path) as z:
        names = z.namelist()
    # The extension's root is the package: its __init__.py, core/ and blender/ at the top.
    assert "__init__.py" in names and "blender_manifest.toml" in names
    assert any(n.startswith("core/") for n in names) and any(n.startswith("blender/") for n in names)
    # Tests, tooling and caches stay out.
    assert not [n for n in names if n.startswith(("tests/", "scripts/", ".ci/", "keyframe_implicit/"))
                or "__pycache__" in n or n.endswith(".pyc")]
    wheels = [n for n in names if n.endswith(".whl")]
    # Only this platform's wheels (or pure-Python ones), for both Python lines, never numpy.
    assert all(("manylinux" in w) or w.endswith("-none-any.whl") for w in wheels), wheels
    for dist in ("scipy", "scikit_image"):
        for tag in ("cp311", "cp313"):
            assert any(w.startswith(f"wheels/{dist}-") and f"-{tag}-" in w for w in wheels), (dist, tag, wheels)
    assert [w for w in wheels if w.startswith("wheels/threadpoolctl-") and w.endswith("-none-any.whl")]
    assert not [w for w in wheels if w.startswith("wheels/numpy-")]
    # Every file of the package is in the zip, unchanged.
    _assert_zip_matches_checkout(zip_path)


def test_zip_installs_enables_and_runs_in_isolated_profile(linux_zip, tmp_path):
    zip_path = linux_zip
    tag = f"cp{sys.version_info[0]}{sys.version_info[1]}"
    hidden = _bundled_top_level_names(zip_path, tag)
    assert {"scipy", "skimage", "threadpoolctl"} <= set(hidden)
    profile = tmp_path / "profile"
    env = {k: v for k, v in os.environ.items() if not k.startswith("BLENDER_")}
    # The checkout must not be importable by the child: only the installed copy is.
    env.pop("PYTHONPATH", None)
    env.update(
        BLENDER_USER_RESOURCES=str(profile),
        BLENDER_USER_CONFIG=str(profile / "config"),
        BLENDER_USER_SCRIPTS=str(profile / "scripts"),
        BLENDER_USER_EXTENSIONS=str(profile / "extensions"),
        BLENDER_USER_DATAFILES=str(profile / "datafiles"),
        KFI_HIDE=json.dumps(hidden),
    )
    result_file = tmp_path / "result.json"
    proc = subprocess.run(
        _child_command(pathlib.Path(__file__).resolve(), [str(zip_path), str(result_file)]),
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-6000:]
    r = json.loads(result_file.read_text())
    ext_dir = str(profile / "extensions")
    assert r["user_extensions"].startswith(ext_dir), r
    assert r["install"] == ["FINISHED"], r
    assert "bl_ext.user_default.keyframe_implicit" in r["addons"], r
    assert r["package_file"].startswith(os.path.join(ext_dir, "user_default", "keyframe_implicit")), r
    assert r["checkout_importable"] is False, r
    for mod in ("scipy", "skimage", "threadpoolctl"):
        assert r["files"][mod].startswith(ext_dir), (mod, r["files"][mod])
    # The bundled wheels accept the numpy of the Blender they run in (numpy 2.x from 5.1).
    assert not [m for m in r["import_warnings"] if "numpy" in m.lower()], r
    # Working compiled wheels: EDT of a point is its distance; marching cubes on a sphere.
    assert abs(r["edt_corner"] - r["edt_expected"]) < 1e-9, r
    assert r["mc_faces"] > 100 and abs(r["mc_mean_radius"] - 10.0) < 0.3, r
    assert r["toplevel_keyframe_implicit"] is False, r
    # The installed add-on bakes: one shape key per frame plus the Basis, and on the
    # first and last frame the output lies on that keyframe's sphere.
    assert r["bake"] == ["FINISHED"] and r["bake_outputs"] == 1, r
    assert r["bake_keys"] == BAKE_FRAMES[1] - BAKE_FRAMES[0] + 2, r
    for err in r["bake_surface_error"]:
        assert err < 0.05 * BAKE_RADIUS, r


# ----------------------------------------------------------------------------
# Child process: runs with the bpy module and an empty temporary Blender profile.

def _child(zip_path, result_file):  # pragma: no cover - runs in a subprocess
    import importlib.machinery
    import importlib.util

    hidden = set(json.loads(os.environ["KFI_HIDE"]))
    venv_dirs = [p for p in sys.path if p.rstrip("/").endswith(("site-packages", "dist-packages"))]

    class HideTestEnvironmentCopies:
        """Import the zip's bundled distributions only from outside the test environment."""

        @staticmethod
        def find_spec(name, path=None, target=None):
            if path is not None or name.split(".")[0] not in hidden:
                return None
            search = [p for p in sys.path if p not in venv_dirs]
            spec = importlib.machinery.PathFinder.find_spec(name, search)
            if spec is None:
                raise ModuleNotFoundError(f"{name} is not installed from the extension's wheels", name=name)
            return spec

    sys.meta_path.insert(0, HideTestEnvironmentCopies)
    # Nothing from the checkout: drop the script's directory and the working directory.
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [p for p in sys.path if p not in ("", ".", here, str(ROOT))]

    import bpy

    r = {"user_extensions": bpy.utils.user_resource("EXTENSIONS")}
    r["install"] = sorted(bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True))
    r["addons"] = sorted(bpy.context.preferences.addons.keys())
    pkg = sys.modules.get("bl_ext.user_default.keyframe_implicit")
    r["package_file"] = getattr(pkg, "__file__", "") or ""
    r["checkout_importable"] = importlib.util.find_spec("keyframe_implicit") is not None
    r["operators"] = sorted(dir(bpy.ops.keyframe_implicit))

    import warnings

    import numpy as np

    # A wheel built for another numpy warns on import (scipy checks its numpy range).
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import scipy
        import scipy.ndimage
        import skimage
        import skimage.measure
        import threadpoolctl
    r["numpy"] = np.__version__
    r["import_warnings"] = [f"{w.category.__name__}: {w.message}" for w in caught]
    r["files"] = {"scipy": scipy.__file__, "skimage": skimage.__file__,
                  "threadpoolctl": threadpoolctl.__file__}
    mask = np.ones((9, 9, 9), bool)
    mask[4, 4, 4] = False
    r["edt_corner"] = float(scipy.ndimage.distance_transform_edt(mask)[0, 0, 0])
    r["edt_expected"] = float(np.sqrt(3 * 16))
    ax = np.arange(-16, 17, dtype=float)
    x, y, z = np.meshgrid(ax, ax, ax, indexing="ij")
    verts, faces, _, _ = skimage.measure.marching_cubes(np.sqrt(x * x + y * y + z * z) - 10.0, 0.0)
    r["mc_faces"] = int(len(faces))
    r["mc_mean_radius"] = float(np.linalg.norm(verts - 16.0, axis=1).mean())
    r.update(_child_bake(bpy, np))
    r["toplevel_keyframe_implicit"] = "keyframe_implicit" in sys.modules
    pathlib.Path(result_file).write_text(json.dumps(r, indent=1))


def _child_bake(bpy, np):  # pragma: no cover - runs in a subprocess
    """Two spheres set up and baked through the installed add-on's operators only."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    dirs = np.array([[0, 0, 1], [0, 0, -1], [0, 1, 0], [0, -1, 0]], float)
    for center, frame in zip(BAKE_CENTERS, BAKE_FRAMES):
        bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=BAKE_RADIUS,
                                             location=center)
        scene.frame_set(frame)
        bpy.ops.keyframe_implicit.add_keyframe()
    pa, pb = (np.asarray(c) + BAKE_RADIUS * dirs for c in BAKE_CENTERS)
    for a, b in zip(pa, pb):
        bpy.ops.keyframe_implicit.add_feature_pair(segment=0, location_a=tuple(a), location_b=tuple(b))
    before = set(bpy.data.objects)
    try:
        res = sorted(bpy.ops.keyframe_implicit.bake(resolution=BAKE_RESOLUTION))
    except RuntimeError as exc:  # the operator reported an error
        res = [str(exc)]
    out = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    r = {"bake": res, "bake_outputs": len(out)}
    if len(out) != 1 or out[0].data.shape_keys is None:
        r.update(bake_keys=0, bake_surface_error=[])
        return r
    obj = out[0]
    r["bake_keys"] = len(obj.data.shape_keys.key_blocks)
    errors = []
    for center, frame in zip(BAKE_CENTERS, BAKE_FRAMES):
        scene.frame_set(frame)
        ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = ev.to_mesh()
        co = np.empty(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", co)
        ev.to_mesh_clear()
        world = co.reshape(-1, 3) @ np.array(obj.matrix_world)[:3, :3].T + np.array(obj.matrix_world)[:3, 3]
        errors.append(float(np.abs(np.linalg.norm(world - np.asarray(center), axis=1) - BAKE_RADIUS).mean()))
    r["bake_surface_error"] = errors
    return r


if __name__ == "__main__":
    _args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    _child(_args[0], _args[1])
