#!/usr/bin/env python3
"""Build the installable Blender extension zips (one per platform).

What it does
------------
1. Resolves scipy + scikit-image and their dependencies for every target
   platform and Python version (``pip install --dry-run --report`` with
   ``--platform/--python-version``; nothing is installed), leaving out numpy
   and the other modules Blender's own Python already ships (``BLENDER_SHIPS``).
2. Downloads the missing wheels into a cache outside the clone
   (``KFI_WHEEL_CACHE``, default ``~/.cache/keyframe_implicit/wheels``) with
   ``pip download --no-deps --only-binary=:all:``; re-runs only re-use it.
3. Stages, under ``build/extension/`` (never inside the package), a copy of the
   ``keyframe_implicit`` package (it is the extension's root: its
   ``__init__.py`` registers), ``blender_manifest.toml`` with the ``wheels`` and
   ``platforms`` lists filled in, and ``wheels/*.whl``.
4. Calls Blender's own extension tool, ``blender_ext.py build --split-platforms``
   (shipped inside the bpy module and inside Blender), which writes
   ``dist/keyframe_implicit-<version>-<platform>.zip``, then validates each
   zip with ``blender_ext.py validate``.

Usage (from the clone's root, with a Python that has bpy, e.g. scripts/env.sh's venv)::

    python scripts/build_extension.py                       # all platforms
    python scripts/build_extension.py --platform linux-x64  # one zip
    python scripts/build_extension.py --refresh             # re-resolve versions

Pass ``--blender-ext PATH`` to use another Blender's ``blender_ext.py`` (the tool
runs standalone with any Python >= 3.11).
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import importlib.util
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = "keyframe_implicit"

#: What the zip must carry: the core's dependencies beyond numpy.
REQUIREMENTS = ["scipy>=1.10", "scikit-image>=0.21", "threadpoolctl>=3.1"]

#: Distributions Blender's bundled Python already provides (official builds ship
#: numpy, requests and its dependencies, zstandard and cython in
#: ``<version>/python/lib/python3.x/site-packages``). Bundling a second copy would
#: shadow or conflict with Blender's own, so they are never put in the zip.
BLENDER_SHIPS = {
    "numpy", "requests", "certifi", "charset-normalizer", "idna", "urllib3",
    "zstandard", "cython",
}

#: Blender platform -> pip ``--platform`` tags. The tags are the *oldest* OS the
#: wheels may require; pip also accepts older compatible tags for each.
#: linux: glibc 2.28 (Blender 4.2+ needs it as well); macOS arm64: 12.0, the oldest
#: macOS scipy has ever published arm64 wheels for; macOS x64: 11.0 (Blender's minimum).
PLATFORMS = {
    # Listed explicitly: older pips do not expand a manylinux tag to the older glibcs.
    "linux-x64": [f"manylinux_2_{g}_x86_64" for g in range(28, 16, -1)] + ["manylinux2014_x86_64"],
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_12_0_arm64"],
    "macos-x64": ["macosx_11_0_x86_64"],
}

#: Python versions of the Blender lines served: 3.11 (Blender 4.2 LTS .. 5.0, numpy 1.26)
#: and 3.13 (Blender 5.1 .. 5.3, and distribution builds such as Debian's 4.3). Each
#: resolution is constrained to the oldest numpy of its Blenders (numpy 2.2 in Debian's
#: 4.3; 5.3 ships 2.5), so the chosen scipy / scikit-image support it; scipy's own upper
#: bound must admit the newest, which the zip install test checks on bpy 5.3.
PYTHONS = {
    "3.11": "numpy==1.26.4",
    "3.13": "numpy==2.2.4",
}

_NAME_RE = re.compile(r"[-_.]+")


def canonical(name):
    """PEP 503 normalised distribution name."""
    return _NAME_RE.sub("-", name).lower()


def find_blender_ext():
    """Locate ``blender_ext.py`` (and Blender's ``tags.py``) inside the bpy module.

    Returns
    -------
    (str, str or None)
        Path of ``blender_ext.py`` and of the valid-tags file Blender itself uses.
    """
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit(
            "build_extension: the bpy module is not importable from this Python, so Blender's "
            "extension tool cannot be found. Run with the project's environment "
            "(source scripts/env.sh) or pass --blender-ext PATH/TO/blender_ext.py.")
    hits = []
    for base in spec.submodule_search_locations:
        hits += glob.glob(os.path.join(base, "*", "scripts", "addons_core", "bl_pkg", "cli", "blender_ext.py"))
    if not hits:
        raise SystemExit("build_extension: no blender_ext.py inside the bpy module at "
                         f"{list(spec.submodule_search_locations)}; pass --blender-ext.")
    return sorted(hits)[-1]


def tags_file_for(blender_ext):
    """Blender's list of valid extension tags next to a given ``blender_ext.py``."""
    scripts = pathlib.Path(blender_ext).resolve().parents[3]
    tags = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
    return str(tags) if tags.is_file() else ""


def pip_target_args(platform, python):
    args = ["--only-binary=:all:", "--implementation", "cp", "--python-version", python]
    for tag in PLATFORMS[platform]:
        args += ["--platform", tag]
    return args


def resolve(platform, python, cache, refresh=False):
    """Resolve the wheels one (platform, Python) target needs, without installing.

    Returns
    -------
    list of (name, version, filename)
        Every distribution of the dependency closure of ``REQUIREMENTS`` except
        those in ``BLENDER_SHIPS``. The answer is cached (per requirement set)
        so re-runs need no index access.
    """
    key = hashlib.sha1(json.dumps([REQUIREMENTS, PYTHONS[python], PLATFORMS[platform]]).encode()).hexdigest()[:10]
    memo = cache / "resolved" / f"{platform}-py{python}-{key}.json"
    if memo.is_file() and not refresh:
        return [tuple(x) for x in json.loads(memo.read_text())]
    memo.parent.mkdir(parents=True, exist_ok=True)
    # Per-process scratch files: several builds may share the cache at once.
    with tempfile.TemporaryDirectory(dir=memo.parent) as scratch:
        constraints = pathlib.Path(scratch) / "constraints.txt"
        constraints.write_text(PYTHONS[python] + "\n")
        report = pathlib.Path(scratch) / "report.json"
        cmd = [sys.executable, "-m", "pip", "install", "--dry-run", "--ignore-installed", "--quiet",
               "--report", str(report), "--target", str(pathlib.Path(scratch) / "unused-target"),
               "-c", str(constraints), *pip_target_args(platform, python), *REQUIREMENTS]
        run(cmd, f"resolve {platform} py{python}")
        items = json.loads(report.read_text())["install"]
    picked = []
    for item in items:
        name = canonical(item["metadata"]["name"])
        if name in BLENDER_SHIPS:
            continue
        filename = item["download_info"]["url"].rsplit("/", 1)[1]
        picked.append((name, item["metadata"]["version"], filename))
    picked.sort()
    _write_atomic(memo, json.dumps(picked, indent=1).encode())
    return picked


def download(platform, python, picked, cache):
    """Download the wheels of ``picked`` that are not in the cache yet."""
    store = cache / "files"
    store.mkdir(parents=True, exist_ok=True)
    missing = [(n, v) for n, v, f in picked if not (store / f).is_file()]
    if missing:
        # Download into a private directory, then move each wheel into the store in one
        # step, so a concurrent build never sees a half-written wheel.
        with tempfile.TemporaryDirectory(dir=store.parent) as scratch:
            cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", "-d", scratch,
                   *pip_target_args(platform, python), *[f"{n}=={v}" for n, v in missing]]
            run(cmd, f"download {len(missing)} wheel(s) for {platform} py{python}")
            for got in pathlib.Path(scratch).glob("*.whl"):
                os.replace(got, store / got.name)
    paths = []
    for n, v, f in picked:
        path = store / f
        if not path.is_file():
            raise SystemExit(f"build_extension: pip did not produce {f} for {platform} py{python}; "
                             "run again with --refresh to re-resolve the versions.")
        paths.append(path)
    return paths


def _write_atomic(path, data):
    tmp = path.with_name(f".{path.name}.{os.getpid()}")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def run(cmd, what):
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    # pip warns about the machine's local file:// indexes; keep only the real messages.
    out = "\n".join(line for line in proc.stdout.splitlines() if "is ignored: it is neither" not in line)
    if proc.returncode != 0:
        raise SystemExit(f"build_extension: {what} failed (exit {proc.returncode}):\n{out}\ncommand: {' '.join(cmd)}")
    print(f"[build_extension] {what}: {time.perf_counter() - t0:.1f} s", flush=True)
    return out


def toml_list(values):
    return "[\n" + "".join(f'  "{v}",\n' for v in values) + "]"


def stage(build_dir, platforms, wheels):
    """Copy the package, the manifest (wheels/platforms filled in) and the wheels.

    Returns the staging directory: the extension's root.
    """
    stage_dir = build_dir / "stage"
    if stage_dir.exists():
        shutil.rmtree(stage_dir)
    shutil.copytree(ROOT / PACKAGE, stage_dir,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.pyo"))
    (stage_dir / "wheels").mkdir()
    rel = []
    for w in sorted(set(wheels), key=lambda p: p.name):
        dst = stage_dir / "wheels" / w.name
        try:
            os.link(w, dst)
        except OSError:
            shutil.copy2(w, dst)
        rel.append(f"./wheels/{w.name}")
    text = (ROOT / "blender_manifest.toml").read_text()
    text, n_w = re.subn(r"(?m)^wheels\s*=\s*\[[^\]]*\]", "wheels = " + toml_list(rel), text)
    text, n_p = re.subn(r"(?m)^platforms\s*=\s*\[[^\]]*\]", "platforms = " + toml_list(platforms), text)
    if n_w != 1 or n_p != 1:
        raise SystemExit("build_extension: blender_manifest.toml must have exactly one top-level "
                         "'wheels = [...]' and one 'platforms = [...]' line to fill in.")
    (stage_dir / "blender_manifest.toml").write_text(text)
    return stage_dir


def manifest_version():
    m = re.search(r'(?m)^version\s*=\s*"([^"]+)"', (ROOT / "blender_manifest.toml").read_text())
    return m.group(1)


def build(platforms=None, pythons=None, out_dir=None, build_dir=None, cache=None,
          blender_ext=None, refresh=False, python_exe=None):
    """Build one zip per platform; return ``{platform: zip path}``.

    Parameters
    ----------
    platforms : list of str, optional
        Blender platform names (keys of ``PLATFORMS``); default all.
    pythons : list of str, optional
        Python versions to bundle wheels for (keys of ``PYTHONS``); default all.
    out_dir, build_dir : path, optional
        Where the zips go (default ``dist/``) and the staging area (default
        ``build/extension/``).
    cache : path, optional
        Wheel cache (default ``$KFI_WHEEL_CACHE`` or ``~/.cache/keyframe_implicit/wheels``).
    blender_ext : path, optional
        Blender's ``blender_ext.py``; default: the one inside the bpy module.
    refresh : bool
        Re-resolve versions against the index instead of re-using the cached resolution.
    python_exe : path, optional
        Python that runs ``blender_ext.py`` (default: this one).
    """
    platforms = list(platforms or PLATFORMS)
    pythons = list(pythons or PYTHONS)
    for p in platforms:
        if p not in PLATFORMS:
            raise ValueError(f"unknown platform {p!r}; choose from {sorted(PLATFORMS)}")
    for v in pythons:
        if v not in PYTHONS:
            raise ValueError(f"unsupported Python {v!r}; choose from {sorted(PYTHONS)}")
    out_dir = pathlib.Path(out_dir or ROOT / "dist").resolve()
    build_dir = pathlib.Path(build_dir or ROOT / "build" / "extension").resolve()
    if build_dir == (ROOT / PACKAGE).resolve() or (ROOT / PACKAGE).resolve() in build_dir.parents:
        raise ValueError("the build directory must lie outside the keyframe_implicit package")
    cache = pathlib.Path(cache or os.environ.get("KFI_WHEEL_CACHE")
                         or pathlib.Path.home() / ".cache" / "keyframe_implicit" / "wheels")
    blender_ext = blender_ext or find_blender_ext()
    tags = tags_file_for(blender_ext)

    t0 = time.perf_counter()
    wheels = []
    for platform in platforms:
        for python in pythons:
            picked = resolve(platform, python, cache, refresh=refresh)
            wheels += download(platform, python, picked, cache)
    stage_dir = stage(build_dir, platforms, wheels)

    out_dir.mkdir(parents=True, exist_ok=True)
    version = manifest_version()
    for platform in platforms:
        stale = out_dir / f"{PACKAGE}-{version}-{platform.replace('-', '_')}.zip"
        if stale.exists():
            stale.unlink()
    py = python_exe or sys.executable
    run([py, blender_ext, "build", "--source-dir", str(stage_dir), "--output-dir", str(out_dir),
         "--split-platforms", f"--valid-tags={tags}"], "blender_ext.py build --split-platforms")
    zips = {}
    for platform in platforms:
        found = sorted(out_dir.glob(f"{PACKAGE}-{version}-{platform.replace('-', '_')}.zip"))
        if len(found) != 1:
            raise SystemExit(f"build_extension: expected one zip for {platform} in {out_dir}, found {found}")
        zips[platform] = found[0]
        out = run([py, blender_ext, "validate", f"--valid-tags={tags}", str(found[0])],
                  f"validate {found[0].name}")
        print("   ", out.strip().replace("\n", "\n    "))
    print(f"[build_extension] done in {time.perf_counter() - t0:.1f} s", flush=True)
    for platform, z in zips.items():
        print(f"  {z.relative_to(out_dir.parent) if out_dir.parent in z.parents else z}  "
              f"{z.stat().st_size / 2**20:.1f} MiB")
    return zips


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--platform", action="append", choices=sorted(PLATFORMS),
                    help="build only this platform (repeatable); default: all")
    ap.add_argument("--python", action="append", choices=sorted(PYTHONS),
                    help="bundle wheels only for this Python (repeatable); default: all")
    ap.add_argument("--out", default=None, help="output directory for the zips (default dist/)")
    ap.add_argument("--build-dir", default=None, help="staging directory (default build/extension/)")
    ap.add_argument("--cache", default=None, help="wheel cache (default ~/.cache/keyframe_implicit/wheels)")
    ap.add_argument("--blender-ext", default=None, help="path of Blender's blender_ext.py")
    ap.add_argument("--refresh", action="store_true", help="re-resolve wheel versions against the index")
    args = ap.parse_args(argv)
    try:
        build(args.platform, args.python, args.out, args.build_dir, args.cache,
              args.blender_ext, args.refresh)
    except ValueError as exc:
        raise SystemExit(f"build_extension: {exc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
