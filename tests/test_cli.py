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
    tests when they were collected (tests/beside.py), or by this test when it was not (under pytest-xdist:
    the other worker is the second core); either way shared with notebook 00's kernel."""
    from repro.experiments import registry
    from tests.beside import csv_tables, fresh_figures_in_a_process

    names = list(registry())
    assert sum(not registry()[n].timing for n in names) >= 5
    if beside.has("figures"):
        second = beside.figures()
    else:
        second = fresh_figures_in_a_process()
    assert sorted(second) == sorted(names)
    for name in names:
        first = csv_tables(quick_figures(name), registry()[name].timing)
        assert list(first) == list(second[name]), name  # the same tables
        for suffix, a in first.items():
            b = second[name][suffix]
            assert a["columns"] == b["columns"], (name, suffix)
            assert a["csv"] == b["csv"], (name, suffix)


# ---------------------------------------------------------------- bad usage exits 2 (issue 23, section 7)

@pytest.mark.parametrize("argv", [
    ["bench", "retrieval", "--queries", "0"], ["bench", "retrieval", "--queries", "-5"],
    ["bench", "retrieval", "--queries", "x"], ["bench", "retrieval", "--queries", "1000000000000"],
    ["bench", "retrieval", "--factors", "0"], ["bench", "retrieval", "--factors", "1,-1"],
    ["bench", "retrieval", "--factors", "1,,2"], ["bench", "retrieval", "--factors", "1" + "0" * 400], ["bench", "retrieval", "--factors", ""],
    ["bench", "retrieval", "--database", "nope"], ["bench", "prepare", "--factors", "2"],
    ["run", "attenuation_speed", "--out", ""], ["all", "--out", ""], ["bench", "attenuation", "--out", ""],
    ["claims", "--out", ""], ["run", "attenuation_speed", "--out", " "],
    ["run", "attenuation_speed", "--out", "a\0b"], ["run", "attenuation_speed", "--face", ""], ["all", "--face", " "],
    ["app", "face", "--port", "0"], ["app", "face", "--port", "70000"], ["app", "face", "--host", ""],
    ["app", "face", "--host", "0.0.0.0", "--no-token"],
])
def test_bad_usage_exits_2_with_the_usage_line_before_any_work(argv, tmp_path, monkeypatch, capsys):
    """Every bad value of an argument is usage (exit 2, argparse's usage line, one ``repro:`` line),
    checked before anything is computed or written; ``--out ""`` would write into the current folder."""
    from repro.bench import retrieval
    from repro.ui import app

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(retrieval, "bench_retrieval", lambda **kw: pytest.fail("must not run"))
    monkeypatch.setattr(app.subprocess, "Popen", lambda *a, **k: pytest.fail("must not start"))
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: repro {argv[0]}") and err.splitlines()[-1].startswith("repro: ")
    assert "Traceback" not in err
    assert not any(tmp_path.iterdir())


def test_out_naming_an_existing_file_is_bad_usage(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("keep")
    for argv in (["run", "attenuation_speed"], ["bench", "attenuation"], ["claims"]):
        assert cli.main(argv + ["--out", str(f)]) == 2
        err = capsys.readouterr().err
        assert "exists and is a file, not a folder" in err and "Traceback" not in err
    assert f.read_text() == "keep"


@pytest.mark.parametrize("factor", ["100000", "1000000000"])
def test_bench_factors_asking_more_than_the_memory_budget_exit_2_naming_the_factor(factor):
    """``--factors 1000000000`` printed numpy's _ArrayMemoryError traceback asking 67-99 GiB: now the
    estimate from the base database is checked against the budget before anything is built."""
    p = subprocess.run([sys.executable, "-m", "repro", "bench", "retrieval", "--factors", f"1,{factor}",
                        "--database", "synthetic", "--out", "unused-never-created"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 2, p.stderr
    assert f"repro: factor {factor} (the synthetic database" in p.stderr and "GiB" in p.stderr
    assert "budget" in p.stderr and "Traceback" not in p.stderr and "MemoryError" not in p.stderr
    assert p.stdout == ""


def test_library_errors_exit_1_on_one_line(tmp_path, capsys):
    """A ReproError during a run is exit 1 and one ``repro:`` line, never a traceback."""
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"not a glb")
    out = tmp_path / "out"
    assert cli.main(["run", "fig4_axis_selection", "--quick", "--face", str(bad), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "repro:" in err


def test_a_library_error_of_several_lines_is_printed_on_one(monkeypatch, capsys):
    from repro.errors import DataError

    def broken(*a, **k):
        raise DataError("first line\n  second line\n")

    monkeypatch.setattr(cli, "_data", broken)
    assert cli.main(["data", "list"]) == 1
    assert capsys.readouterr().err == "repro: first line; second line\n"


def test_missing_data_while_checking_bench_options_is_exit_1_not_a_traceback(monkeypatch, tmp_path, capsys):
    """Loading a base database for the memory check can fail for want of data: a repro error (1), not usage."""
    from repro.bench import retrieval
    from repro.errors import DataError

    def no_data(*a, **k):
        raise DataError("the cmu-bvh data is missing")

    monkeypatch.setattr(retrieval, "check_bench_arguments", no_data)
    assert cli.main(["bench", "retrieval", "--database", "cmu", "--factors", "1,10", "--out", str(tmp_path)]) == 1
    assert capsys.readouterr().err == "repro: the cmu-bvh data is missing\n"
