#!/usr/bin/env bash
# Test the extension in a real `blender -b`: Debian trixie's blender package
# (Blender 4.3, Python 3.13, numpy 2.2) in a chroot. Needs root (debootstrap, chroot).
#
#   scripts/blender_chroot.sh [pytest args]     # default: -q tests
#
# 1. Makes the chroot once, or reuses it (scripts/trixie_chroot.sh): $KFI_CHROOT (default
#    /var/cache/keyframe_implicit/trixie, outside the clone): debootstrap --variant=minbase
#    trixie, then apt-get install --no-install-recommends blender python3-numpy python3-pytest
#    and an EGL/Mesa GL driver (numpy is what Blender's own builds bundle, Debian packages it
#    separately; without a GL driver Workbench/EEVEE renders abort Blender).
#    No scipy, scikit-image or threadpoolctl in the chroot: those come from the zip's wheels.
# 2. Builds the linux-x64 zip (scripts/build_extension.py, with the project venv).
#    Test-only requirements (requirements-dev.txt minus bpy, numpy, scipy, scikit-image,
#    threadpoolctl and pytest) are installed as cp313 wheels into a directory of their own.
# 3. Copies the checkout and the zip into the chroot, with a fresh HOME (an empty Blender
#    profile), installs the zip with Blender's own
#      blender --command extension install-file -r user_default -e ZIP
#    and checks in a normal start-up that the add-on is enabled and that scipy,
#    scikit-image and threadpoolctl load from the unpacked cp313 wheels.
# 4. Runs the tests in that Blender through tests/blender_runner.py, with another fresh HOME;
#    scipy, scikit-image and threadpoolctl come from a copy of the site-packages Blender
#    unpacked from the zip's wheels in step 3 (KFI_TEST_SITE): Blender itself deletes its
#    unpacked copy when the tests' factory resets leave the extension disabled.
# Exit status: non-zero on any failure, else pytest's.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# libegl1 + Mesa: a GL driver (software llvmpipe here) for Workbench/EEVEE renders in -b.
PACKAGES="blender python3-numpy python3-pytest libegl1 libegl-mesa0 libgl1-mesa-dri"
log() { echo "[blender_chroot] $*" >&2; }

if [ "$(id -u)" != 0 ]; then
  log "needs root (debootstrap and chroot); run it as root or with sudo."
  exit 2
fi

# ---- 1. the chroot -------------------------------------------------------------------
source "$ROOT/scripts/trixie_chroot.sh"
ensure_chroot $PACKAGES

# ---- 2. the zip, installed with Blender's own CLI (step 3) -------------------------------
make_run_dir
install_zip "$ROOT"
# Test-only dependencies of requirements-dev.txt that neither Blender, the zip nor the
# chroot provide (e.g. matplotlib), as cp313 wheels for the chroot's Python, with the
# chroot's numpy as a constraint and numpy itself removed again (Debian's stays in use).
(
  source "$ROOT/scripts/env.sh"
  reqs=$(grep -v -E '^\s*(#|$)' "$ROOT/requirements-dev.txt" \
         | grep -v -i -E '^(bpy|numpy|scipy|scikit-image|threadpoolctl|pytest)\b' || true)
  if [ -n "$reqs" ]; then
    echo "numpy==$(chroot "$CHROOT" python3 -c 'import numpy; print(numpy.__version__)')" > "$run/numpy-pin.txt"
    python -m pip install --quiet --no-warn-conflicts --target "$run/testdeps" --only-binary=:all: --implementation cp \
      --python-version 3.13 --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
      --platform manylinux2014_x86_64 -c "$run/numpy-pin.txt" $reqs 2>&1 | grep -v 'is ignored: it is neither' >&2 || true
    rm -rf "$run/testdeps"/numpy "$run/testdeps"/numpy-* "$run/testdeps"/numpy.libs "$run/testdeps/bin"
    [ -n "$(ls -A "$run/testdeps" 2>/dev/null)" ] || { log "installing the test-only requirements failed: $reqs"; exit 1; }
  fi
)

# ---- 3. the checkout, and a check of the installed extension ----------------------------
mkdir -p "$run/src"
tar -C "$ROOT" --exclude=./.git --exclude=./dist --exclude=./build --exclude=./out \
    --exclude='__pycache__' --exclude='.pytest_cache' -cf - . | tar -C "$run/src" -xf -
in_chroot blender -b --python-exit-code 1 --python-expr '
import sys, bpy, addon_utils
name = "bl_ext.user_default.keyframe_implicit"
assert name in bpy.context.preferences.addons, "extension not enabled after install-file"
import numpy, scipy, skimage, skimage.measure, threadpoolctl
ext = bpy.utils.user_resource("EXTENSIONS")
for m in (scipy, skimage, threadpoolctl):
    assert m.__file__.startswith(ext), (m.__name__, m.__file__, "not from the extension wheels")
print("[blender_chroot] enabled:", name, "| Python", sys.version.split()[0], "| numpy", numpy.__version__,
      "| scipy", scipy.__version__, "| scikit-image", skimage.__version__,
      "| threadpoolctl", threadpoolctl.__version__, "(from the zip wheels)")
' 2>&1 | grep -E '^\[blender_chroot\]|Error|error' >&2

# ---- 4. the tests in that Blender --------------------------------------------------------
site=( "$run"/home/.config/blender/*/extensions/.local/lib/python3*/site-packages )
[ -d "${site[0]}" ] || { log "no unpacked wheels under $run/home after install-file"; exit 1; }
cp -a "${site[0]}" "$run/testsite"
mkdir -p "$run/home-tests"
export KFI_HOME="$inside/home-tests"
KFI_TEST_SITE="$inside/testsite"
[ -d "$run/testdeps" ] && KFI_TEST_SITE="$KFI_TEST_SITE:$inside/testdeps"
set +e
[ $# -gt 0 ] || set -- -q tests
in_chroot KFI_EXTENSION_ZIP="$inside/dist/$zip_name" KFI_TEST_SITE="$KFI_TEST_SITE" \
  /bin/sh -c 'cd "$0" && exec blender -b --factory-startup --python-exit-code 1 \
  -P tests/blender_runner.py -- -p no:cacheprovider "$@"' "$inside/src" "$@"
code=$?
set -e
log "pytest exit code in Blender: $code"
exit $code
