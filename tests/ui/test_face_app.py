"""The face app (``repro app face``, ``repro/ui/apps/face.ipynb``): which face it shows (issue 26, item 6).

What runs without data must not depend on a leftover derived cache: the ICT cache is used
only beside the data it came from, so with no data folder the app shows the embedded face
and says so, whatever ``REPRO_CACHE_DIR`` holds.
"""

from __future__ import annotations

import contextlib
import io
import json
import os

import pytest

from repro.blendshapes.faces import ict
from tests.conftest import REPO

APP = REPO / "repro" / "ui" / "apps" / "face.ipynb"


def _run_app_cell() -> tuple[str, dict]:
    """The app's code cell run here: what it prints and its namespace (the panel, the model)."""
    cells = [c for c in json.loads(APP.read_text())["cells"] if c["cell_type"] == "code"]
    assert len(cells) == 1, "the face app is one code cell"
    ns: dict = {}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec("".join(cells[0]["source"]), ns)  # noqa: S102 - the app's own committed cell
    return out.getvalue(), ns


@pytest.fixture
def leftover(tmp_path, monkeypatch):
    """A cache folder, the data folder as staged, and an empty data folder to switch to."""
    monkeypatch.setenv("REPRO_CACHE_DIR", str(tmp_path / "cache"))
    empty = tmp_path / "no-data"
    empty.mkdir()
    ict.load_ict.cache_clear()
    yield os.environ["REPRO_DATA_DIR"], str(empty)
    ict.load_ict.cache_clear()


@pytest.mark.data("ict")
def test_the_ict_cache_is_used_only_beside_its_data(leftover, monkeypatch):
    staged, empty = leftover
    builds = []
    build = ict._build_arrays
    monkeypatch.setattr(ict, "_build_arrays", lambda shapes: builds.append(shapes) or build(shapes))
    first = ict.load_ict(shapes=["browDown_L"])
    assert len(builds) == 1 and list((ict.cache_dir()).glob("ict-*.npz")), "the first load writes the cache"
    # the data folder gone: the cache (and the memo) left behind are not used
    monkeypatch.setenv("REPRO_DATA_DIR", empty)
    with pytest.raises(ict.DataError, match="faces/ict/"):
        ict.load_ict(shapes=["browDown_L"])
    ict.load_ict.cache_clear()
    with pytest.raises(ict.DataError, match="faces/ict/"):
        ict.load_ict(shapes=["browDown_L"])
    assert len(builds) == 1
    # the data back: the cache is read again, nothing rebuilt
    monkeypatch.setenv("REPRO_DATA_DIR", staged)
    ict.load_ict.cache_clear()
    again = ict.load_ict(shapes=["browDown_L"])
    assert len(builds) == 1 and again.n_vertices == first.n_vertices
    assert (again.D == first.D).all()


@pytest.mark.data("ict")
def test_the_face_app_without_data_shows_the_embedded_face_despite_a_leftover_cache(leftover, monkeypatch):
    staged, empty = leftover
    said, ns = _run_app_cell()
    assert said.strip() == "Face: the ICT Face Model." and ns["panel"].model.name == "ict"
    assert [p.name for p in ict.cache_dir().glob("ict-*.npz")], "the ICT start leaves its derived cache"
    ns["panel"].close()
    monkeypatch.setenv("REPRO_DATA_DIR", empty)
    said, ns = _run_app_cell()
    assert ns["panel"].model.name == "procedural", said
    assert said.strip() == "Face: the embedded face (the ICT data are not installed: repro data fetch ict).", said
    ns["panel"].close()
