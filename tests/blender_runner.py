"""Run the test suite inside a real Blender.

Usage (from anywhere; arguments after ``--`` go to pytest, default ``tests``)::

    blender -b --factory-startup --python-exit-code 1 -P tests/blender_runner.py -- -q tests/blender

What this runner does to Blender's Python, and nothing more:

- puts the checkout's root first on ``sys.path`` so the tests import this
  checkout's ``keyframe_implicit`` (the add-on itself never changes ``sys.path``);
- puts the directories of ``$KFI_TEST_SITE`` (``os.pathsep``-separated) right after
  it: where the tests' third-party modules live when that Blender has none of its own;
  both also go into ``PYTHONPATH`` for Python subprocesses of the tests;
- makes ``pytest`` importable if Blender's Python lacks it: from
  ``$KFI_PYTEST_DIR`` if set, else by ``pip install --target`` into
  ``~/.cache/keyframe_implicit/pytest-py3XX`` once (Blender's official builds bundle
  pip; distribution builds can use their ``python3-pytest`` package instead).

scipy and scikit-image must be importable in that Blender. Installing the
extension zip (``blender --command extension install-file -r user_default -e ZIP``)
unpacks its wheels into the user extensions' ``site-packages``, which Blender puts on
``sys.path`` at startup, but Blender also removes them again as soon as the
preferences no longer enable the extension, which is what the Blender-side tests'
factory resets do. So copy that ``site-packages`` elsewhere and pass it as
``KFI_TEST_SITE`` (scripts/blender_chroot.sh does exactly this).

The process exits with pytest's exit code (5 when no test was collected).
"""

import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _ensure_pytest():
    try:
        import pytest  # noqa: F401
        return
    except ImportError:
        pass
    target = os.environ.get("KFI_PYTEST_DIR") or str(
        pathlib.Path.home() / ".cache" / "keyframe_implicit"
        / f"pytest-py{sys.version_info[0]}{sys.version_info[1]}")
    if target not in sys.path:
        sys.path.append(target)
    try:
        import pytest  # noqa: F401
        return
    except ImportError:
        pass
    print(f"[blender_runner] installing pytest into {target} with Blender's Python", flush=True)
    python = sys.executable
    proc = subprocess.run([python, "-m", "pip", "install", "--quiet", "--target", target, "pytest>=7"])
    if proc.returncode != 0:
        raise SystemExit(
            f"[blender_runner] pytest is not importable in this Blender and '{python} -m pip install "
            f"--target {target} pytest' failed; install pytest for Blender's Python "
            "(e.g. the python3-pytest package of a distribution Blender) or set KFI_PYTEST_DIR.")
    import importlib
    importlib.invalidate_caches()


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    extra = [p for p in os.environ.get("KFI_TEST_SITE", "").split(os.pathsep) if p]
    for path in extra:
        if not os.path.isdir(path):
            raise SystemExit(f"[blender_runner] KFI_TEST_SITE entry {path!r} is not a directory.")
    sys.path[:0] = [str(ROOT), *extra]
    # The same for Python subprocesses the tests start with sys.executable.
    os.environ["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT), *extra, *filter(None, [os.environ.get("PYTHONPATH")])])
    _ensure_pytest()
    import bpy
    import pytest

    print(f"[blender_runner] Blender {bpy.app.version_string} ({bpy.app.binary_path}), "
          f"Python {sys.version.split()[0]}, checkout {ROOT}", flush=True)
    os.chdir(ROOT)
    code = int(pytest.main(argv or ["tests"]))
    # Blender exits with the code given to sys.exit from a -P script.
    sys.exit(code)


if __name__ == "__main__":
    main()
