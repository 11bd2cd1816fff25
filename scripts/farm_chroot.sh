#!/usr/bin/env bash
# The farm job as an artist makes it in a real Blender: Debian trixie's Blender 4.3 in the
# project's chroot (scripts/trixie_chroot.sh), the extension zip installed with Blender's own
# CLI, assets/splash.blend saved into a fresh folder, Export Farm Job pressed there
# (bpy.ops.keyframe_implicit.export_farm_job in `blender -b`), and the job it wrote run whole
# with `openjd run` inside the chroot: its core stages under the Python the job template names
# (Blender's), its Prepare and Assemble under the Blender it names. Needs root.
#
#   scripts/farm_chroot.sh [RESOLUTION]     # default 34
#
# Prints the openjd run's summary and the baked file's output object; exit status openjd's.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
RES="${1:-34}"
source "$ROOT/scripts/trixie_chroot.sh"
ensure_chroot blender python3-numpy libegl1 libegl-mesa0 libgl1-mesa-dri
make_run_dir
install_zip "$ROOT"
# openjd-cli (pure Python) for the chroot's Python 3.13, in a folder of its own
(
  source "$ROOT/scripts/env.sh"
  python -m pip install --quiet --target "$run/openjd" --only-binary=:all: --implementation cp \
    --python-version 3.13 --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 "openjd-cli>=0.8" 2>&1 | grep -v 'is ignored: it is neither' >&2 || true
)
mkdir -p "$run/shot"
cp "$ROOT/assets/splash.blend" "$run/shot/splash.blend"
in_chroot blender -b "$inside/shot/splash.blend" --python-exit-code 1 --python-expr "
import bpy
bpy.context.scene.keyframe_implicit.resolution = $RES
bpy.ops.wm.save_mainfile()
assert bpy.ops.keyframe_implicit.export_farm_job() == {'FINISHED'}
" >&2
echo "[farm_chroot] job template written by Export Farm Job:" >&2
grep -A2 -E 'name: "(Python|PythonPath|Blender)"' "$run/shot/splash_farm/template.yaml" | grep default >&2
set +e
in_chroot PYTHONPATH="$inside/openjd" python3 -c "import sys; from openjd.cli import main; sys.exit(main())" \
  run "$inside/shot/splash_farm/template.yaml" > "$run/openjd.log" 2>&1
code=$?
set -e
grep -E "Running step|Duration|Chunks run|Session ended|error|Error" "$run/openjd.log" | tail -20
[ "$code" = 0 ] && in_chroot blender -b "$inside/shot/splash_farm/baked.blend" --python-expr "
import bpy
o = bpy.context.scene.keyframe_implicit.output_object
print('[farm_chroot] baked:', o.name, len(o.data.vertices), 'vertices,', o.get('kfi_report'))
" 2>&1 | grep farm_chroot
exit $code
