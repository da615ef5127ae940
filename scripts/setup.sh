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

# Python packages: by default exactly the locked versions (hash-checked), the ones the suite passes with;
# REPRO_UNPINNED=1 installs the newest versions pyproject.toml allows instead (to try them).
# Reinstalled only when the dependency list, the lock or the choice changed.
LOCK=requirements/lock-py311-linux.txt
unpinned=${REPRO_UNPINNED:-0}
locked_platform='import platform, sys
libc, version = platform.libc_ver()
sys.exit(not ((3, 11, 5) <= sys.version_info < (3, 12) and platform.system() == "Linux"
              and platform.machine() in ("x86_64", "aarch64") and libc == "glibc"
              and tuple(map(int, version.split("."))) >= (2, 28)))'
if [ "$unpinned" != 1 ] && ! .venv/bin/python -c "$locked_platform"; then
  echo "setup: $LOCK is for CPython 3.11.5+ on Linux (glibc 2.28+, x86_64 or aarch64); installing unpinned versions here (its header says how to lock another platform)"
  unpinned=1
fi
stamp=.venv/.repro-installed
want=$(cat pyproject.toml "$LOCK" | sha256sum | cut -d' ' -f1)-unpinned=$unpinned
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  # pip's output minus one notice that says nothing to act on (this machine's extra package indexes that
  # do not exist); errors and every other warning stay visible.
  pip_quiet() {
    .venv/bin/python -m pip "$@" 2>&1 | { grep -v 'is ignored: it is neither a file nor a directory' || true; }
    return "${PIPESTATUS[0]}"
  }
  if [ "$unpinned" = 1 ]; then
    echo "setup: installing repro and the newest versions of its dependencies into .venv (REPRO_UNPINNED=1)"
    pip_quiet install -q --upgrade pip
    pip_quiet install -q -e '.[dev]'
  else
    echo "setup: installing the locked versions ($LOCK) and repro into .venv"
    # uv installs the lock hash-checked as pip does, about four times faster (requirements/uv.txt: itself
    # pinned and hash-checked); --native-tls: the machine's certificates, as pip's; --compile-bytecode as
    # pip does (under PYTHONDONTWRITEBYTECODE, set on this machine kind, every process would otherwise compile
    # every module it imports: the suite took 6 min 50 s instead of 5 min 19 s).  pip where uv cannot be had
    # or cannot install (uv reads neither pip.conf nor PIP_INDEX_URL: a machine with its own package index).
    if pip_quiet install -q --require-hashes -r requirements/uv.txt && [ -x .venv/bin/uv ] \
       && .venv/bin/uv pip install --quiet --native-tls --compile-bytecode --python .venv/bin/python \
            --require-hashes -r "$LOCK"; then
      :
    else
      echo "setup: uv could not install the lock (above); installing it with pip instead (slower)"
      pip_quiet install -q --require-hashes -r "$LOCK"
    fi
    pip_quiet install -q --no-deps --no-build-isolation -e .
  fi
  echo "$want" > "$stamp"
fi

# repro's own modules compiled (only what changed since the last time): each of the suite's many processes
# (notebook kernels, workers, the CLI) then reads them instead of compiling them again where
# PYTHONDONTWRITEBYTECODE keeps Python from writing them itself (about 0.25 s a process here)
.venv/bin/python -m compileall -q -j 0 repro

# the project's IPython kernel configuration (no first-use messages in notebook outputs)
mkdir -p .venv/etc/ipython
cmp -s scripts/ipython/ipython_kernel_config.py .venv/etc/ipython/ipython_kernel_config.py \
  || cp scripts/ipython/ipython_kernel_config.py .venv/etc/ipython/ipython_kernel_config.py
