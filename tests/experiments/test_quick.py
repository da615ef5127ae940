"""The quick figures computed once per process and shared across the processes of a run (repro.experiments.quick)."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import pandas as pd
import pytest

from repro.experiments import quick
from repro.experiments.registry import Result

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _tiny(calls: list):
    def func(quick=False):
        import matplotlib.pyplot as plt

        calls.append(quick)

        def draw():
            fig, ax = plt.subplots(figsize=(2, 1.5))
            ax.plot([0, 1], [1, 0])
            return fig

        return Result(pd.DataFrame({"x": [1.5, 2.0], "label": ["a", "b"]}), draw=draw,
                      extra_tables={"more": pd.DataFrame({"y": [3]})})

    return func


@pytest.fixture
def tiny(monkeypatch):
    """A registered figure ``tiny`` that counts its computations; fresh per-process memos."""
    import importlib

    reg = importlib.import_module("repro.experiments.registry")
    calls: list = []
    exp = dataclasses.replace(reg.get("fig4_axis_selection"), name="tiny", func=_tiny(calls))
    monkeypatch.setitem(reg._REGISTRY, "tiny", exp)
    monkeypatch.setattr(quick, "_results", {})
    monkeypatch.setattr(quick, "_pngs", {})
    monkeypatch.delenv(quick.SHARED, raising=False)
    return calls


def _forget(monkeypatch):
    """As a new process would start: nothing memoised."""
    monkeypatch.setattr(quick, "_results", {})
    monkeypatch.setattr(quick, "_pngs", {})


def test_computed_once_per_process_and_drawn_once(tiny):
    a = quick.quick_result("tiny")
    assert quick.quick_result("tiny") is a and tiny == [True]
    png = quick.quick_png("tiny")
    assert png.startswith(PNG_SIGNATURE) and quick.quick_png("tiny") is png


def test_a_shared_entry_is_read_instead_of_computed(tiny, tmp_path, monkeypatch):
    monkeypatch.setenv(quick.SHARED, str(tmp_path))
    first = quick.quick_result("tiny")
    png = quick.quick_png("tiny")
    assert tiny == [True] and len(list(tmp_path.glob("*.pickle"))) == 1
    _forget(monkeypatch)
    again = quick.quick_result("tiny")
    assert tiny == [True], "read from the shared folder, not computed again"
    pd.testing.assert_frame_equal(again.table, first.table)
    pd.testing.assert_frame_equal(again.extra_tables["more"], first.extra_tables["more"])
    assert quick.quick_png("tiny") == png
    redrawn = quick._png(again)  # the stored picture, drawn as the gallery saves it: pixel for pixel
    import io

    import matplotlib.image as mpimg
    import numpy as np

    np.testing.assert_array_equal(mpimg.imread(io.BytesIO(redrawn)), mpimg.imread(io.BytesIO(png)))


def test_an_entry_that_does_not_verify_is_computed_again(tiny, tmp_path, monkeypatch):
    monkeypatch.setenv(quick.SHARED, str(tmp_path))
    quick.quick_result("tiny")
    (pickle_file,) = tmp_path.glob("*.pickle")
    data = bytearray(pickle_file.read_bytes())
    data[-2] ^= 0xFF
    pickle_file.write_bytes(bytes(data))
    _forget(monkeypatch)
    quick.quick_result("tiny")
    assert tiny == [True, True]


@pytest.mark.parametrize("mode", [0o777, 0o770])
def test_a_folder_others_can_write_is_not_trusted(tiny, tmp_path, monkeypatch, mode):
    monkeypatch.setenv(quick.SHARED, str(tmp_path))
    quick.quick_result("tiny")
    os.chmod(tmp_path, mode)
    try:
        assert quick.shared_folder() is None
        _forget(monkeypatch)
        quick.quick_result("tiny")
        assert tiny == [True, True]
    finally:
        os.chmod(tmp_path, 0o700)


def test_no_folder_or_a_file_shares_nothing(tiny, tmp_path, monkeypatch):
    monkeypatch.setenv(quick.SHARED, str(tmp_path / "absent"))
    assert quick.shared_folder() is None
    (tmp_path / "file").write_text("")
    monkeypatch.setenv(quick.SHARED, str(tmp_path / "file"))
    assert quick.shared_folder() is None
    quick.quick_result("tiny")
    assert not (tmp_path / "absent").exists()


def test_the_key_changes_with_the_data_choice_and_the_name(tiny):
    from repro import data

    present = quick.key("fig4_axis_selection")
    assert quick.key("tiny") != present
    try:
        data.choose("embedded", needs=("ict",))
        assert quick.key("fig4_axis_selection") != present or data.missing_reason("ict") is not None
    finally:
        data.choose("auto", needs=("ict",))
    assert quick.key("fig4_axis_selection") == present


def test_an_unknown_figure_is_the_registry_error(tiny):
    from repro.errors import UnknownFigureError

    with pytest.raises(UnknownFigureError):
        quick.quick_result("no_such_figure")


def test_the_test_session_shares_one_folder_with_the_processes_it_starts():
    """tests/conftest.py names a folder of its own; a child process sees it and trusts it."""
    folder = os.environ.get(quick.SHARED)
    assert folder and os.path.isdir(folder)
    code = "from repro.experiments import quick; print(quick.shared_folder())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == folder
