# Sourced by scripts/test and scripts/demo: make (once) and activate the project's virtual
# environment: Blender as a Python module (bpy), numpy, scipy, scikit-image, pytest.
# The project itself is not installed into it: commands run from the clone's root, so the code
# under test is always this clone's. The environment lives outside the clone, so fresh clones
# reuse it. bpy is published for two Pythons only, and the Python found picks the Blender line:
#   Python 3.13 -> bpy 5.3   (numpy 2)    requirements-bpy53.txt  ~/.cache/keyframe_implicit/venv-bpy53
#   Python 3.11 -> bpy 5.0.1 (numpy 1.26) requirements-dev.txt    ~/.cache/keyframe_implicit/venv-bpy50
# The Python is the machine's python3 if it is one of these, else python3.13, else python3.11
# (first on PATH, then among pyenv's installed versions).
# Overrides:
#   KFI_PYTHON        a Python executable, or just a version: 3.13 or 3.11
#   KFI_REQUIREMENTS  another requirements file, e.g. requirements-bpy42.txt (4.2 LTS, Python 3.11)
#   KFI_VENV          where the environment lives; default venv-<line> beside the others, the
#                     line taken from the file name (requirements-bpy42.txt -> venv-bpy42)
# The environment is rebuilt when its requirements file or its Python's version changes.
set -euo pipefail
KFI_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
KFI_CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/keyframe_implicit"

kfi_python_version() {  # "3.13" for a Python executable that runs, else nothing
  "$1" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || true
}

kfi_find_python() {  # a runnable python<version>, from PATH or pyenv's installed versions
  local want="$1" root c
  root="$(pyenv root 2>/dev/null || true)"
  # A pyenv shim is on PATH even when the version it names is not selected; it then fails
  # to run, so every candidate is run, not just looked up.
  for c in "python$want" ${root:+"$root"/versions/"$want".*/bin/python"$want"}; do
    if [ "$(kfi_python_version "$c")" = "$want" ]; then
      command -v "$c"
      return 0
    fi
  done
  return 1
}

case "${KFI_PYTHON:-}" in
  "")
    case "$(kfi_python_version python3)" in
      3.11 | 3.13) KFI_PY="$(command -v python3)" ;;
      *) KFI_PY="$(kfi_find_python 3.13 || kfi_find_python 3.11 || true)" ;;
    esac ;;
  [0-9].[0-9]*) KFI_PY="$(kfi_find_python "$KFI_PYTHON" || true)" ;;
  *) KFI_PY="$KFI_PYTHON" ;;
esac
KFI_PY_VERSION="$(kfi_python_version "${KFI_PY:-python3}")"
case "$KFI_PY_VERSION" in
  3.13) kfi_default_requirements="$KFI_ROOT/requirements-bpy53.txt" ;;
  3.11) kfi_default_requirements="$KFI_ROOT/requirements-dev.txt" ;;
  *)
    cat >&2 <<EOF
keyframe_implicit runs Blender as a Python module (bpy), which is published for two Pythons:
  Python 3.13 -> bpy 5.3   (the current Blender; Debian 13's python3)
  Python 3.11 -> bpy 5.0.1
Found ${KFI_PYTHON:+for KFI_PYTHON=$KFI_PYTHON: }${KFI_PY_VERSION:+Python $KFI_PY_VERSION at }${KFI_PY:-no python3.13, python3.11 or suitable python3}.
Install Python 3.13 (or 3.11), for example with
  pyenv install 3.13                      (Linux, macOS: https://github.com/pyenv/pyenv)
  sudo apt install python3.13 python3.13-venv
                                          (Debian 13; Ubuntu 24.04 first needs
                                           sudo add-apt-repository ppa:deadsnakes/ppa)
  the installer from https://www.python.org/downloads/
then run this again; if it is not on PATH, set KFI_PYTHON=/path/to/python3.13.
EOF
    exit 2 ;;
esac
KFI_REQUIREMENTS="${KFI_REQUIREMENTS:-$kfi_default_requirements}"
kfi_line="$(basename "$KFI_REQUIREMENTS" .txt)"
kfi_line="${kfi_line#requirements-}"
[ "$kfi_line" != dev ] || kfi_line=bpy50   # requirements-dev.txt is the bpy 5.0.1 line
KFI_VENV="${KFI_VENV:-$KFI_CACHE/venv-$kfi_line}"

# One process at a time builds an environment; the others wait and then reuse it.
mkdir -p "$(dirname "$KFI_VENV")"
exec {kfi_lock}>"$KFI_VENV.lock"   # a free descriptor: callers may hold locks of their own
command -v flock >/dev/null && flock "$kfi_lock"
stamp="$KFI_VENV/.kfi-stamp"
want="$(sha1sum < "$KFI_REQUIREMENTS" | cut -c1-12)"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] \
   || [ "$(kfi_python_version "$KFI_VENV/bin/python")" != "$KFI_PY_VERSION" ]; then
  echo "[env] setting up $KFI_VENV from $(basename "$KFI_REQUIREMENTS") with Python $KFI_PY_VERSION" \
       "(first run downloads bpy, ~400 MB)" >&2
  if [ -e "$KFI_VENV" ] && [ ! -e "$KFI_VENV/pyvenv.cfg" ] && [ -n "$(ls -A "$KFI_VENV")" ]; then
    echo "$KFI_VENV exists and is not a virtual environment; set KFI_VENV to a new directory." >&2
    exit 2
  fi
  "$KFI_PY" -m venv --clear "$KFI_VENV"
  "$KFI_VENV/bin/python" -m pip install -q --upgrade pip >&2
  "$KFI_VENV/bin/python" -m pip install -q -r "$KFI_REQUIREMENTS" >&2
  echo "$want" > "$stamp"
fi
exec {kfi_lock}>&-
export PATH="$KFI_VENV/bin:$PATH"
export PYTHONPATH="$KFI_ROOT${PYTHONPATH:+:$PYTHONPATH}"
