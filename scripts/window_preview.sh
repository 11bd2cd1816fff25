#!/usr/bin/env bash
# The live preview in a real window: for assets/merge.blend, bend.blend and splash.blend (or
# the scenes named), how long from releasing a dragged feature Empty to the updated preview
# on screen, from a frame key to that frame's preview, and how long the main loop is held
# (scripts/window_preview.py says how each is measured). Screenshots go to OUTDIR (default:
# a temporary folder, printed). Needs root (chroot).
#
#   scripts/window_preview.sh [-o OUTDIR] [--viewport-aa=OFF] [SCENE ...]   # SCENE: merge, ...
#
# The window is scripts/window_stall.sh's: Debian trixie's blender (4.3) in the chroot of
# scripts/trixie_chroot.sh under Xvfb with Mesa's software GL, the extension zip built from
# this checkout and installed with Blender's own tool; the input events come from xdotool in
# the chroot. Software GL draws far slower than a graphics card, so the figures are an upper
# bound of what an artist's machine shows. Run it by hand (a few minutes per scene).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT=""
if [ "${1:-}" = -o ]; then OUT="$2"; shift 2; fi
AA=()
case "${1:-}" in --viewport-aa=*) AA=("$1"); shift ;; esac
OUT="$(mkdir -p "${OUT:=$(mktemp -d /tmp/window_preview.XXXXXX)}" && cd "$OUT" && pwd)"
[ $# -gt 0 ] || set -- merge bend splash
[ "$(id -u)" = 0 ] || { echo "[window_preview] needs root (chroot)" >&2; exit 2; }

source "$ROOT/scripts/trixie_chroot.sh"
ensure_chroot $WINDOW_PACKAGES xdotool
make_run_dir
install_zip "$ROOT"
mkdir -p "$run/out"
scenes=()
for name in "$@"; do
  cp "$ROOT/assets/$name.blend" "$run/"
  scenes+=("$inside/$name.blend")
done
windowed_blender "$ROOT" window_preview.py "$inside/out" "${AA[@]}" "${scenes[@]}"
cp "$run"/out/*.png "$OUT/"
echo "[window_preview] screenshots in $OUT" >&2
