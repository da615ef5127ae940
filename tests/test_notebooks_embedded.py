"""Every notebook runs top to bottom on a fresh clone without data: ``DATA = "embedded"``, an empty data folder.

CI's nbval pass runs the notebooks on the real data (``.ci/run`` sets ``REPRO_DATA_DIR``) and compares
their stored outputs; this runs each one as a fresh clone would (no data folder, no downloads), with the
papermill-style parameter ``DATA`` set right after the cell tagged ``parameters``, and checks that every
cell runs without error and that the notebook says it runs on the embedded data.  The runs start beside
the other tests when the session collects them (tests/beside.py: a kernel per notebook, one at a time,
on the second core) and each test checks its notebook's run.  The outputs are not
compared (they differ from the stored real-data ones by design).  Slow: every notebook is executed.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import nbformat
import pytest

from tests.conftest import REPO

NOTEBOOKS = sorted((REPO / "notebooks").glob("[0-9][0-9]_*.ipynb"))
TIMEOUT = 900  # per cell (a busy 2-core machine)


def _with_parameter(nb, value: str):
    """``nb`` with ``DATA = value`` injected after its cell tagged ``parameters`` (as papermill does)."""
    tagged = [i for i, c in enumerate(nb.cells) if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert len(tagged) == 1, "a notebook needs exactly one cell tagged 'parameters'"
    assert "DATA = " in nb.cells[tagged[0]].source
    cell = nbformat.v4.new_code_cell(f"DATA = {value!r}  # injected by tests/test_notebooks_embedded.py")
    nb.cells.insert(tagged[0] + 1, cell)
    return nb


@pytest.fixture
def fresh_clone(tmp_path, monkeypatch):
    """No data folder, no downloads, cold caches, and the kernel imports this checkout's repro."""
    empty = tmp_path / "no-data"
    empty.mkdir()
    monkeypatch.setenv("REPRO_DATA_DIR", str(empty))
    monkeypatch.setenv("REPRO_OFFLINE", "1")
    monkeypatch.setenv("REPRO_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MPLCONFIGDIR", str(tmp_path / "mpl"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(REPO)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    return empty


def _execute(nb, *, timeout=TIMEOUT):
    from nbclient import NotebookClient

    client = NotebookClient(nb, kernel_name="python3", timeout=timeout, allow_errors=False,
                            resources={"metadata": {"path": str(REPO / "notebooks")}})
    return client.execute()


def _text(cell) -> str:
    out = []
    for o in cell.get("outputs", []):
        if o.get("output_type") == "stream":
            out.append(o.get("text", ""))
        elif "data" in o:
            out.append(o["data"].get("text/plain", "") + o["data"].get("text/markdown", ""))
    return "".join(out)


def _marks(path: Path):
    return [pytest.mark.render] if "pyvista" in path.read_text() else []


@pytest.mark.slow
@pytest.mark.parametrize("path", [pytest.param(p, id=p.stem, marks=_marks(p)) for p in NOTEBOOKS])
def test_notebook_runs_on_the_embedded_data_without_a_data_folder(path, fresh_clone, beside):
    if beside.has(f"notebook-{path.stem}"):  # run beside the tests since collection, set up as fresh_clone is
        done, fresh_clone = beside.notebook(path)  # fails the test, naming the cell, on the first error
    else:
        nb = _with_parameter(nbformat.read(path, as_version=4), "embedded")
        done = _execute(nb)  # raises CellExecutionError, naming the cell, on the first error
    text = "".join(_text(c) for c in done.cells if c.cell_type == "code")
    assert "Data: " in text, "the notebook must say what it runs on"
    assert "Data: real" not in text
    assert "embedded" in text.split("Data: ", 1)[1].splitlines()[0]
    assert not list(fresh_clone.iterdir()), "nothing was downloaded or written into the data folder"
    bars = [c.source.splitlines()[0] for c in done.cells if c.cell_type == "code" and _progress_bars(c)]
    assert not bars, f"progress bars left in the outputs of the cells starting {bars}"


def _progress_bars(cell) -> bool:
    """Whether a cell's outputs hold a tqdm bar (text ``12%|###   | 3/25`` on a stream, or a tqdm widget)."""
    for o in cell.get("outputs", []):
        if o.get("output_type") == "stream" and re.search(r"\d+%\|", o.get("text", "")):
            return True
        if "application/vnd.jupyter.widget-view+json" in o.get("data", {}) and "it/s" in o["data"].get("text/plain", ""):
            return True
    return False


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_stored_outputs_hold_no_progress_bars(path):
    nb = nbformat.read(path, as_version=4)
    bars = [c.source.splitlines()[0] for c in nb.cells if c.cell_type == "code" and _progress_bars(c)]
    assert not bars, f"{path.name}: progress bars stored in the outputs of the cells starting {bars}"


@pytest.mark.parametrize("value, message", [
    ("real", "DATA = 'real' but 1 of the 1 datasets this notebook needs is missing"),
    ("everything", "DATA = 'everything' is not a known choice; expected one of 'auto', 'embedded', 'real'"),
])
def test_a_bad_parameter_or_real_without_data_is_one_clear_error(value, message, fresh_clone):
    from nbclient.exceptions import CellExecutionError

    path = REPO / "notebooks" / "03_retrieval_latency.ipynb"
    nb = _with_parameter(nbformat.read(path, as_version=4), value)
    setup = next(i for i, c in enumerate(nb.cells) if "data.choose(DATA" in c.source)
    nb.cells = nb.cells[: setup + 1]  # up to the cell that resolves DATA
    with pytest.raises(CellExecutionError) as e:
        _execute(nb, timeout=300)
    assert e.value.ename == "DataError" and message in e.value.evalue
