#!/usr/bin/env bash
# The whole test suite: pytest over tests/ and nbval over notebooks/ (see pyproject.toml).
# Installs what is missing first, so it works on a fresh machine too.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/python -m pytest "$@"
