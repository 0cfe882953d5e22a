#!/usr/bin/env bash
# What `make test-browser` needs beyond `make setup`: Debian's Chromium (Playwright drives it; no
# browser is downloaded) and the `browser` extra (Playwright for Python). Safe to re-run.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ ! -x /usr/bin/chromium ]; then
    echo "setup_browser: installing Debian's chromium"
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi
.venv/bin/python -m pip install -q -e '.[browser]'
