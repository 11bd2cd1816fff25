# Sourced by the scripts that run Debian trixie's blender package in a chroot
# (scripts/blender_chroot.sh for the tests, scripts/screenshot_panel.sh for the panel
# screenshots). Defines CHROOT and `ensure_chroot PACKAGE...`. Needs root.
#
# The chroot lives outside the clone ($KFI_CHROOT, default /var/cache/keyframe_implicit/trixie):
# debootstrap --variant=minbase trixie, then apt-get install --no-install-recommends of the
# packages asked for. $CHROOT/.kfi-stamp lists what is installed; a later call with more
# packages installs only the missing ones, so the test and screenshot scripts share one chroot.
# An flock on $CHROOT.lock makes concurrent runs wait for each other instead of racing.
CHROOT="${KFI_CHROOT:-/var/cache/keyframe_implicit/trixie}"
MIRROR="${KFI_DEBIAN_MIRROR:-http://deb.debian.org/debian}"

ensure_chroot() {
  local want=("$@") have missing t0
  mkdir -p "$(dirname "$CHROOT")"
  exec 9>"$CHROOT.lock"
  flock 9
  if [ ! -x "$CHROOT/usr/bin/blender" ]; then
    t0=$(date +%s)
    echo "[trixie_chroot] making the trixie chroot in $CHROOT (first run: a few minutes)" >&2
    command -v debootstrap >/dev/null || { apt-get update -qq && apt-get install -y -qq debootstrap >/dev/null; }
    rm -rf "$CHROOT.tmp"
    debootstrap --variant=minbase trixie "$CHROOT.tmp" "$MIRROR" >/dev/null
    chroot "$CHROOT.tmp" apt-get install -y -qq --no-install-recommends "${want[@]}" >/dev/null
    chroot "$CHROOT.tmp" apt-get clean
    printf '%s\n' "${want[@]}" | sort -u > "$CHROOT.tmp/.kfi-stamp"
    rm -rf "$CHROOT"
    mv "$CHROOT.tmp" "$CHROOT"
    echo "[trixie_chroot] chroot ready in $(( $(date +%s) - t0 )) s" >&2
  else
    have="$(cat "$CHROOT/.kfi-stamp" 2>/dev/null || true)"
    missing=$(printf '%s\n' "${want[@]}" | sort -u | comm -23 - <(printf '%s\n' "$have" | sort -u))
    if [ -n "$missing" ]; then
      echo "[trixie_chroot] installing into $CHROOT:" $missing >&2
      chroot "$CHROOT" apt-get update -qq
      chroot "$CHROOT" apt-get install -y -qq --no-install-recommends $missing >/dev/null
      chroot "$CHROOT" apt-get clean
      printf '%s\n' $have $missing | sort -u > "$CHROOT/.kfi-stamp"
    fi
  fi
  flock -u 9
  exec 9>&-
}
