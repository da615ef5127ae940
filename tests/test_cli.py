"""The repro command: list, run, unknown names, data list; and atomic output."""

import subprocess
import sys

import pandas as pd
import pytest

from repro import cli
from repro.experiments import registry
from repro.io import atomic_path, write_text


def test_list_names_every_registered_figure(capsys):
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    for name in registry():
        assert name in out


def test_unknown_figure_exits_2_with_a_clear_message(capsys, tmp_path):
    assert cli.main(["run", "no_such_figure", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "unknown figure 'no_such_figure'" in err and "attenuation_speed" in err
    assert not any(tmp_path.iterdir())


def test_python_dash_m_repro_is_the_same_command():
    p = subprocess.run([sys.executable, "-m", "repro", "list"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "attenuation_speed" in p.stdout


def test_run_writes_png_and_csv(tmp_path, capsys):
    assert cli.main(["run", "attenuation_speed", "--quick", "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "attenuation_speed.csv")
    assert {"new selection + solve", "slider move (cached selection)"} == set(table["measurement"])
    assert (table["ratio"] > 0).all() and (table["n_vertices"] >= 2016).all()
    png = (tmp_path / "attenuation_speed.png").read_bytes()
    assert png.startswith(b"\x89PNG")
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "attenuation_speed-scaling.csv", "attenuation_speed.csv", "attenuation_speed.png", "manifest.json"]
    scaling = pd.read_csv(tmp_path / "attenuation_speed-scaling.csv")
    assert set(scaling.sweep) == {"vertices", "shapes"} and (scaling.selection_speedup > 0).all()


def test_data_list(capsys):
    assert cli.main(["data", "list"]) == 0
    out = capsys.readouterr().out
    for name in ("ict", "cmu-bvh", "cmu-asfamc", "bandai"):
        assert name in out
    assert cli.main(["data", "fetch", "nope"]) == 2


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path):
    target = write_text(tmp_path / "out.csv", "old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("writer crashed")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_manifest_records_provenance_and_reruns_only_what_changed(tmp_path, capsys, quick_figures, monkeypatch):
    import json

    quick_figures.serve(monkeypatch, "fig4_axis_selection")  # the plumbing: test_run_writes_png_and_csv runs for real
    out = str(tmp_path)
    assert cli.main(["run", "fig4_axis_selection", "--quick", "--out", out]) == 0
    entry = json.loads((tmp_path / "manifest.json").read_text())["fig4_axis_selection"]
    assert entry["function"] == "repro.experiments.lewis.fig4_axis_selection.fig4_axis_selection"
    assert "notebooks/01_blendshape_interference.ipynb" in entry["notebooks"]
    assert {f["file"] for f in entry["files"]} >= {"fig4_axis_selection.csv"}
    assert entry["inputs"]["versions"]["numpy"] and len(entry["inputs"]["code_sha256"]) == 64
    assert "ict" in entry["data"]
    capsys.readouterr()
    assert cli.main(["run", "fig4_axis_selection", "--quick", "--out", out]) == 0
    assert "up to date" in capsys.readouterr().out
    (tmp_path / "fig4_axis_selection.csv").write_text("tampered")  # a changed output is rebuilt
    assert cli.main(["run", "fig4_axis_selection", "--quick", "--out", out]) == 0
    assert "up to date" not in capsys.readouterr().out
    assert (tmp_path / "fig4_axis_selection.csv").read_text() != "tampered"
    assert cli.main(["run", "fig4_axis_selection", "--quick", "--force", "--out", out]) == 0
    assert "up to date" not in capsys.readouterr().out


def test_two_runs_give_identical_csvs_except_timing_columns(quick_figures, beside):
    """Two runs write the same CSV bytes: whole tables for figures without wall-clock numbers, and
    every non-timing column for the timing figures (nbval and reviewers rely on it).

    The first run is the session's (``quick_figures``, computed earlier in this process by the
    tests that read it), the second a fresh one: in a process of its own, started beside the
    tests when they were collected (tests/beside.py; in this test when it was not)."""
    from repro.experiments import registry
    from tests.beside import csv_tables

    names = list(registry())
    assert sum(not registry()[n].timing for n in names) >= 5
    if beside.has("figures"):
        second = beside.figures()
    else:
        second = {n: csv_tables(registry()[n].func(quick=True), registry()[n].timing) for n in names}
    assert sorted(second) == sorted(names)
    for name in names:
        first = csv_tables(quick_figures(name), registry()[name].timing)
        assert list(first) == list(second[name]), name  # the same tables
        for suffix, a in first.items():
            b = second[name][suffix]
            assert a["columns"] == b["columns"], (name, suffix)
            assert a["csv"] == b["csv"], (name, suffix)
