# Sourced by scripts/test and scripts/demo: make (once) and activate the project's
# virtual environment with bpy 5.0.1 and the core's dependencies.
# The project itself is not installed into it: commands run from the clone's root,
# so the code under test is always this clone's. The environment lives outside the
# clone so fresh clones reuse it:
#   KFI_VENV          (default ~/.cache/keyframe_implicit/venv-bpy50)
#   KFI_REQUIREMENTS  (default requirements-dev.txt; .ci/run uses requirements-bpy42.txt
#                      with KFI_VENV=~/.cache/keyframe_implicit/venv-bpy42 for Blender 4.2 LTS)
#   KFI_PYTHON        (a python3.11 executable; default: python3.11 or python3 on PATH)
# The environment is rebuilt when the requirements file changes.
set -euo pipefail
KFI_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
KFI_VENV="${KFI_VENV:-$HOME/.cache/keyframe_implicit/venv-bpy50}"
KFI_PY="${KFI_PYTHON:-$(command -v python3.11 || command -v python3)}"
if ! "$KFI_PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
  echo "keyframe_implicit needs Python 3.11 (the bpy wheel is built for it); found $("$KFI_PY" --version)." >&2
  echo "Set KFI_PYTHON to a python3.11 executable." >&2
  exit 2
fi
stamp="$KFI_VENV/.kfi-stamp"
KFI_REQUIREMENTS="${KFI_REQUIREMENTS:-$KFI_ROOT/requirements-dev.txt}"
want="$(cat "$KFI_REQUIREMENTS" | sha1sum | cut -c1-12)"
if [ ! -x "$KFI_VENV/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "[env] setting up $KFI_VENV from $(basename "$KFI_REQUIREMENTS") (first run downloads bpy, ~400 MB)" >&2
  if [ -e "$KFI_VENV" ] && [ ! -e "$KFI_VENV/pyvenv.cfg" ] && [ -n "$(ls -A "$KFI_VENV")" ]; then
    echo "$KFI_VENV exists and is not a virtual environment; set KFI_VENV to a new directory." >&2
    exit 2
  fi
  "$KFI_PY" -m venv --clear "$KFI_VENV"
  "$KFI_VENV/bin/python" -m pip install -q --upgrade pip >&2
  "$KFI_VENV/bin/python" -m pip install -q -r "$KFI_REQUIREMENTS" >&2
  echo "$want" > "$stamp"
fi
export PATH="$KFI_VENV/bin:$PATH"
export PYTHONPATH="$KFI_ROOT${PYTHONPATH:+:$PYTHONPATH}"
