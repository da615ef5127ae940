"""How scripts/test.sh splits the suite between its processes (pytest-xdist; tests/conftest.py ``work_unit``)."""

from __future__ import annotations

import re
from pathlib import Path

from tests.conftest import EMBEDDED_RUN, QUICK_FIGURE_FILES, work_unit

REPO = Path(__file__).resolve().parents[1]


def test_the_quick_figure_files_are_the_test_files_that_read_the_quick_figures():
    reading = sorted(p.relative_to(REPO).as_posix() for p in (REPO / "tests").rglob("test_*.py")
                     if re.search(r"\bquick_figures\b", p.read_text()) and p.name != "test_work_units.py")
    assert reading == sorted(QUICK_FIGURE_FILES)


def test_a_notebooks_cells_stay_together_and_each_embedded_run_is_its_own_unit():
    cells = [f"notebooks/02_alpha_sweep.ipynb::Cell {k}" for k in range(5)]
    assert {work_unit(c) for c in cells} == {"notebooks/02_alpha_sweep.ipynb"}
    runs = [f"{EMBEDDED_RUN}{stem}]" for stem in ("00_overview", "03_retrieval_latency")]
    assert len({work_unit(r) for r in runs}) == 2
    assert work_unit("tests/test_notebooks_embedded.py::test_stored_outputs_hold_no_progress_bars[00_overview]") \
        == "tests/test_notebooks_embedded.py"
    assert {work_unit(f"{f}::test_x") for f in QUICK_FIGURE_FILES} == {"quick figures"}
    assert work_unit("tests/test_data.py::test_x[a::b]") == "tests/test_data.py"
