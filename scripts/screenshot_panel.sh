#!/usr/bin/env bash
# Screenshots of the sidebar panel in a real Blender window, before, during and after a bake
# of assets/merge.blend, into docs/images/ (or $1). Needs root (chroot).
#
#   scripts/screenshot_panel.sh [OUTDIR]
#
# Debian trixie's blender (4.3) in the chroot of scripts/trixie_chroot.sh, plus Xvfb, xauth,
# xwd and Mesa's software GL (about 1 GB more on first use). The zip is built from this checkout
# and installed with Blender's own `blender --command extension install-file`, into an empty
# profile; then scripts/screenshot_panel.py drives a normal (windowed) Blender under Xvfb:
# merge.blend with the default UI, the sidebar opened on the "Keyframe Implicit" tab at its
# default width, the display grabbed with xwd before, during and after the bake, and the sidebar cut out
# of each. It takes a few minutes (the bake runs on the CPU next to a software-GL window),
# so it is run by hand, not in CI; look at the pictures it writes.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$(mkdir -p "${1:-$ROOT/docs/images}" && cd "${1:-$ROOT/docs/images}" && pwd)"
[ "$(id -u)" = 0 ] || { echo "[screenshot_panel] needs root (chroot)" >&2; exit 2; }

source "$ROOT/scripts/trixie_chroot.sh"
windowed_merge "$ROOT" screenshot_panel.py
cp "$run"/out/*.png "$OUT/"
ls -l "$run"/out/*.png >&2
