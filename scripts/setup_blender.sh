#!/usr/bin/env bash
# The environment of `make test-blender`: Blender 5.3 as a Python module (the `bpy` wheel, about 430 MB,
# kept in pip's cache), which needs Python 3.13, in .venv-blender. Safe to re-run.
set -euo pipefail
cd "$(dirname "$0")/.."

BPY_VERSION=5.3.0
find_python313() {
    if [ -n "${PYTHON313:-}" ]; then echo "$PYTHON313"; return 0; fi
    if command -v python3.13 >/dev/null 2>&1 && python3.13 -c "" >/dev/null 2>&1; then command -v python3.13; return 0; fi
    for candidate in "$(pyenv root 2>/dev/null)"/versions/3.13*/bin/python3.13 /usr/local/bin/python3.13 /usr/bin/python3.13; do
        if [ -x "$candidate" ]; then echo "$candidate"; return 0; fi
    done
    return 1
}

if [ ! -x .venv-blender/bin/python ]; then
    if ! python313=$(find_python313); then
        echo "setup_blender: the bpy wheel (Blender $BPY_VERSION) needs Python 3.13, and none was found;" \
             "install it (e.g. pyenv install 3.13) or set PYTHON313 to its interpreter" >&2
        exit 2
    fi
    echo "setup_blender: creating .venv-blender with $python313"
    "$python313" -m venv .venv-blender
fi
.venv-blender/bin/python -m pip install -q "bpy==$BPY_VERSION"
touch .venv-blender/.mistyle-installed
