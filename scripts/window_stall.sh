#!/usr/bin/env bash
# How long Blender's main loop stalls during a bake, in a real window: bakes assets/merge.blend
# with the modal operator at each resolution given (default: the scene's own, and 64; 0 is the
# scene's own) and prints the gaps between the main loop's turns (scripts/window_stall.py
# says how they are measured), with a screenshot of the window half-way through each bake in
# OUTDIR (default: a temporary folder, printed). Needs root (chroot).
#
#   scripts/window_stall.sh [-o OUTDIR] [RESOLUTION ...]
#
# The same Blender as scripts/screenshot_panel.sh: Debian trixie's blender (4.3) in the chroot
# of scripts/trixie_chroot.sh under Xvfb with Mesa's software GL, the extension zip built from
# this checkout and installed with Blender's own tool. Software GL draws far slower than a
# graphics card and shares the CPU with the bake, so the figures are an upper bound of what an
# artist's machine shows; run it by hand, not in CI (a few minutes), on a quiet machine when
# the figures are to be compared.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT=""
if [ "${1:-}" = -o ]; then OUT="$2"; shift 2; fi
OUT="$(mkdir -p "${OUT:=$(mktemp -d /tmp/window_stall.XXXXXX)}" && cd "$OUT" && pwd)"
[ $# -gt 0 ] || set -- 0 64
[ "$(id -u)" = 0 ] || { echo "[window_stall] needs root (chroot)" >&2; exit 2; }

source "$ROOT/scripts/trixie_chroot.sh"
windowed_merge "$ROOT" window_stall.py "$@"
cp "$run"/out/*.png "$OUT/"
echo "[window_stall] screenshots in $OUT" >&2
