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

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv"
    "$PYTHON" -m venv .venv
fi
# torch first and pinned: an unpinned request would pull the CUDA build.
.venv/bin/python -m pip install -q torch==2.13.0
.venv/bin/python -m pip install -q -e '.[test]'
touch .venv/.mistyle-installed
