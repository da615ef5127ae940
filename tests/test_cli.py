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
        "attenuation_speed-scaling.csv", "attenuation_speed.csv", "attenuation_speed.png"]
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
