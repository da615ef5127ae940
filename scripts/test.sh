#!/usr/bin/env bash
# The whole test suite: pytest over tests/ and nbval over notebooks/ (see pyproject.toml).
# Installs what is missing first, so it works on a fresh machine too.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# One BLAS thread unless the caller chose: the suite keeps both cores busy (tests beside each other,
# the notebooks' busy load), and a threaded OpenBLAS then fights for them. Measured here under load:
# the ICT face's D @ w 26 ms threaded vs 1.5 ms single; two figure tests 123/88 s vs 110/57 s.
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
# One test process per core (pytest-xdist), each taking a file whole (a module's fixtures built once, a
# notebook's cells in order in one kernel), the longest first (tests/conftest.py).  REPRO_TEST_WORKERS=0 runs everything in one process
# (then the slowest independent runs go beside the tests on the second core: tests/beside.py).
exec .venv/bin/python -m pytest -n "${REPRO_TEST_WORKERS:-auto}" --dist loadfile "$@"
