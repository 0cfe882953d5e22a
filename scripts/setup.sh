#!/usr/bin/env bash
# One-shot set-up for a fresh machine: a recent libLLVM for Dr.Jit's LLVM backend, then the
# virtual environment with mistyle and its pinned dependencies. Safe to re-run.
set -euo pipefail
cd "$(dirname "$0")/.."

have_recent_llvm() {
    # Dr.Jit 1.5 needs LLVM >= 17 (older ones die with "Cannot select: fminimum").
    if [ -n "${DRJIT_LIBLLVM_PATH:-}" ] && [ -e "$DRJIT_LIBLLVM_PATH" ]; then return 0; fi
    ldconfig -p 2>/dev/null | grep -Eq 'libLLVM(-|\.so\.)(1[7-9]|[2-9][0-9])'
}

if ! have_recent_llvm; then
    echo "setup: installing libllvm19 (Dr.Jit's LLVM backend needs LLVM >= 17)"
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 >/dev/null
fi

have_openvdb_python() {
    # .vdb input and output (mistyle/files/vdb.py) run Debian's OpenVDB module under the system Python:
    # it is built for that interpreter and its numpy 1.x, so it cannot live in the venv.
    if [ -n "${MISTYLE_VDB_PYTHON:-}" ]; then return 0; fi
    /usr/bin/python3 -c "import pyopenvdb" >/dev/null 2>&1 || /usr/bin/python3 -c "import openvdb" >/dev/null 2>&1
}

if ! have_openvdb_python; then
    echo "setup: installing python3-openvdb (for reading and writing .vdb volumes)"
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    # Best effort: everything but .vdb input and output works without it.
    if ! { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq python3-openvdb >/dev/null; }; then
        echo "setup: warning: could not install python3-openvdb; VDB input/output will be unavailable" \
             "(install it by hand, or set MISTYLE_VDB_PYTHON to a Python with the openvdb module)" >&2
    fi
fi

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv"
    "$PYTHON" -m venv .venv
fi
# torch first and pinned: an unpinned request would pull the CUDA build.
.venv/bin/python -m pip install -q torch==2.13.0
.venv/bin/python -m pip install -q -e '.[test]'
touch .venv/.mistyle-installed
