#!/usr/bin/env bash
# Install everything repro needs, on a fresh Debian machine with Python >= 3.11 and pip:
#  - system libraries for headless 3D rendering (Mesa EGL, OSMesa fallback; see ../shared/notes/toolchain.md)
#  - Debian's Chromium (/usr/bin/chromium), which the browser tests (tests/browser) drive through
#    Playwright; about 500 MB the first time, a quick dpkg check afterwards.  Playwright's own browser
#    download (`playwright install`) is never used.
#  - a virtual environment .venv with repro and its dev extra (pytest, nbval, hypothesis, playwright, ...)
# Safe to run again: it installs only what is missing or changed.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}

SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO=sudo
apt_install() {
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

if command -v dpkg >/dev/null 2>&1; then
  missing=()
  for p in libegl1 libgl1-mesa-dri libosmesa6 libxrender1 chromium chromium-driver; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  "$PY" -c "import ensurepip" >/dev/null 2>&1 || missing+=("python3-venv")
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing system packages: ${missing[*]}"
    apt_install "${missing[@]}"
  fi
fi

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$PY" -m venv .venv
fi

# reinstall only when the project's dependency list changed
stamp=.venv/.repro-installed
want=$(sha256sum pyproject.toml | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup: installing repro and its dependencies into .venv"
  pip_quiet() { .venv/bin/python -m pip "$@" 2>&1 | { grep -v "is ignored: it is neither" || true; }; return "${PIPESTATUS[0]}"; }
  pip_quiet install -q --upgrade pip
  pip_quiet install -q -e '.[dev]'
  echo "$want" > "$stamp"
fi

# the project's IPython kernel configuration (no first-use messages in notebook outputs)
mkdir -p .venv/etc/ipython
cmp -s scripts/ipython/ipython_kernel_config.py .venv/etc/ipython/ipython_kernel_config.py \
  || cp scripts/ipython/ipython_kernel_config.py .venv/etc/ipython/ipython_kernel_config.py
