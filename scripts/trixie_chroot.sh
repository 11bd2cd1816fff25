# Sourced by the scripts that run Debian trixie's blender package in a chroot
# (scripts/blender_chroot.sh for the tests; scripts/screenshot_panel.sh and
# scripts/window_stall.sh for a real window). Defines CHROOT, `ensure_chroot PACKAGE...` and
# the helpers below. Needs root.
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

# A run directory inside the chroot, removed on exit: $run outside, $inside as the chroot
# sees it.
make_run_dir() {
  run="$(mktemp -d "$CHROOT/tmp/kfi-run.XXXXXX")"
  inside="/tmp/$(basename "$run")"
  trap 'rm -rf "$run"' EXIT
}

# Run a command in the chroot with a clean environment; HOME is $KFI_HOME or $inside/home
# (an empty Blender profile), extra variables come as NAME=value arguments before it.
in_chroot() {
  chroot "$CHROOT" /usr/bin/env -i HOME="${KFI_HOME:-$inside/home}" PATH=/usr/sbin:/usr/bin:/sbin:/bin \
    LANG=C.UTF-8 "$@"
}

# Build the linux-x64 zip of the checkout $1 into $run/dist ($zip_name) and install it into
# $inside/home with Blender's own tool, as a user would:
#   blender --command extension install-file -r user_default -e ZIP
install_zip() {
  local root="$1"
  (
    source "$root/scripts/env.sh"
    cd "$root"
    python scripts/build_extension.py --platform linux-x64 --out "$run/dist" --build-dir "$run/build" >&2
  )
  zip_name="$(cd "$run/dist" && ls keyframe_implicit-*-linux_x64.zip)"
  mkdir -p "$run/home"
  echo "[trixie_chroot] $(in_chroot blender --version 2>/dev/null | head -1), installing $zip_name" >&2
  KFI_HOME="$inside/home" in_chroot blender --command extension install-file -r user_default \
    -e "$inside/dist/$zip_name" >&2
}

# The packages of `windowed_blender`: Blender, Xvfb, xauth, xwd and Mesa's software GL.
WINDOW_PACKAGES="blender python3-numpy libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 libglx-mesa0 xvfb xauth x11-apps"

# Run the checkout $1's scripts/$2 in a real Blender window: 1280x800 on a 24-bit virtual
# display, Mesa's llvmpipe for OpenGL. The script and scripts/blender_window.py are copied into
# $run; the helper is found through PYTHONPATH, which Blender reads with --python-use-system-env.
# Further arguments go to the script.
# A windowed Blender on assets/merge.blend, run as a user runs it: the chroot with the window
# packages, a fresh run folder with the extension zip installed, merge.blend and an empty out/;
# then windowed_blender with SCRIPT and the scene, out/ and ARGS. Its pictures are in "$run/out".
windowed_merge() {
  local root="$1" script="$2"
  shift 2
  ensure_chroot $WINDOW_PACKAGES
  make_run_dir
  install_zip "$root"
  cp "$root/assets/merge.blend" "$run/"
  mkdir -p "$run/out"
  windowed_blender "$root" "$script" "$inside/merge.blend" "$inside/out" "$@"
}

windowed_blender() {
  local root="$1" script="$2"
  shift 2
  cp "$root/scripts/blender_window.py" "$root/scripts/$script" "$run/"
  in_chroot PYTHONPATH="$inside" xvfb-run -a -s "-screen 0 1280x800x24" \
    blender --window-geometry 0 0 1280 800 --no-window-focus --python-use-system-env \
    --python-exit-code 1 --python "$inside/$script" -- "$@"
}
