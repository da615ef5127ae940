"""``repro all / run --jobs N``: figures in worker processes, the timing figures alone afterwards (issue 15, item 6)."""

from __future__ import annotations

import importlib
import json
import os

import pytest

from repro import cli
from repro.experiments.registry import run_many

registry_mod = importlib.import_module("repro.experiments.registry")  # (``repro.experiments.registry`` is the function)


@pytest.fixture
def jobs_figures():
    """The figures of tests/jobs_figures.py, registered here (and importable by the spawned workers)."""
    module = importlib.import_module("tests.jobs_figures")
    yield module
    module.unregister()


def _csvs(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.csv"))}


def test_jobs_2_writes_the_same_csvs_and_manifest_entries_as_jobs_1(jobs_figures, tmp_path):
    names = ["zz_jobs_a", "zz_jobs_b", "zz_jobs_speed"]
    one, two = tmp_path / "one", tmp_path / "two"
    assert set(run_many(names, one, jobs=1).values()) == {"ran"}
    seen = []
    status = run_many(names, two, jobs=2, on_result=lambda n, s, p: seen.append((n, s, sorted(x.name for x in p))))
    assert status == {n: "ran" for n in names} and list(status) == names
    assert sorted(seen) == [("zz_jobs_a", "ran", ["zz_jobs_a-more.csv", "zz_jobs_a.csv"]),
                            ("zz_jobs_b", "ran", ["zz_jobs_b.csv"]), ("zz_jobs_speed", "ran", ["zz_jobs_speed.csv"])]
    assert seen[-1][0] == "zz_jobs_speed"  # the timing figure after the others
    a, b = _csvs(one), _csvs(two)
    del a["zz_jobs_speed.csv"], b["zz_jobs_speed.csv"]  # (its pid)
    assert a == b and len(a) == 3
    m1, m2 = (json.loads((d / "manifest.json").read_text()) for d in (one, two))
    assert sorted(m1) == sorted(m2) == sorted(names)
    for name in names:
        written = sorted(p.name for p in two.glob(f"{name}*.csv"))
        assert sorted(f["file"] for f in m2[name]["files"]) == written, name
        if name != "zz_jobs_speed":
            assert m1[name]["files"] == m2[name]["files"], name
    assert not list(two.glob(".*")), "temporary files left"
    # a second run finds them up to date, in the parent, without starting a worker
    assert set(run_many(names, two, jobs=2).values()) == {"cached"}


def test_timing_figures_run_here_and_the_others_in_workers(jobs_figures, tmp_path):
    import pandas as pd

    status = run_many(["zz_jobs_a", "zz_jobs_faces", "zz_jobs_speed"], tmp_path, jobs=2)
    assert set(status.values()) == {"ran"}
    assert pd.read_csv(tmp_path / "zz_jobs_speed.csv").pid.tolist() == [os.getpid()]
    assert pd.read_csv(tmp_path / "zz_jobs_faces.csv").pid.tolist() != [os.getpid()]


def test_the_faces_reach_the_workers(jobs_figures, tmp_path):
    import pandas as pd

    from repro.blendshapes import BlendshapeModel, load_model, write_gltf
    from tests.experiments.test_user_faces import ARKIT

    proc = load_model("procedural")
    keep = [i for i, n in enumerate(proc.names) if n in ARKIT]
    face = BlendshapeModel(proc.f0, proc.D[:, keep], [ARKIT[proc.names[i]] for i in keep], proc.faces, units=proc.units)
    path = write_gltf(face, tmp_path / "my_face.gltf")
    status = run_many(["zz_jobs_a", "zz_jobs_faces"], tmp_path / "out", jobs=2, faces=[path])
    assert set(status.values()) == {"ran"}
    table = pd.read_csv(tmp_path / "out" / "zz_jobs_faces.csv")
    assert table.faces.tolist() == [1] and table.pid.tolist() != [os.getpid()]
    entry = json.loads((tmp_path / "out" / "manifest.json").read_text())["zz_jobs_faces"]
    assert [f["file"] for f in entry["inputs"]["faces"]] == ["my_face.gltf"]
    # without --face, the same worker set-up has none
    run_many(["zz_jobs_a", "zz_jobs_faces"], tmp_path / "plain", jobs=2)
    assert pd.read_csv(tmp_path / "plain" / "zz_jobs_faces.csv").faces.tolist() == [0]


def test_a_failing_figure_in_a_worker_exits_1_with_its_name(jobs_figures, tmp_path, capsys):
    code = cli.main(["run", "zz_jobs_a", "zz_jobs_fails", "zz_jobs_b", "--jobs", "2", "--out", str(tmp_path)])
    assert code == 1
    err = capsys.readouterr().err
    assert "repro: zz_jobs_fails failed: zz_jobs_fails cannot be computed (on purpose)" in err
    assert "1 of 3 failed: zz_jobs_fails" in err
    assert sorted(json.loads((tmp_path / "manifest.json").read_text())) == ["zz_jobs_a", "zz_jobs_b"]


def test_a_dying_worker_fails_only_its_figure_and_leaves_no_temporary_file(jobs_figures, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("ZZ_JOBS_DIE_IN", str(tmp_path))  # it leaves a half-written file, then dies
    code = cli.main(["run", "zz_jobs_a", "zz_jobs_dies", "zz_jobs_b", "-j", "2", "--out", str(tmp_path)])
    assert code == 1
    err = capsys.readouterr().err
    assert "zz_jobs_dies failed: its worker process died" in err and "1 of 3 failed: zz_jobs_dies" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "manifest.json", "zz_jobs_a-more.csv", "zz_jobs_a.csv", "zz_jobs_b.csv"]


@pytest.mark.parametrize("bad", ["-1", "two", "1.5"])
def test_bad_jobs_value_is_a_usage_error(bad, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["all", "--jobs", bad, "--out", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--jobs" in err and "expected" in err and bad.lstrip("-") in err
    assert not any(tmp_path.iterdir())


def test_jobs_0_is_one_per_cpu(jobs_figures, tmp_path, capsys):
    assert cli.main(["run", "zz_jobs_a", "zz_jobs_b", "--jobs", "0", "--out", str(tmp_path)]) == 0
    assert sorted(json.loads((tmp_path / "manifest.json").read_text())) == ["zz_jobs_a", "zz_jobs_b"]


def test_run_many_refuses_a_bad_jobs_value(tmp_path):
    from repro.errors import ReproError

    for bad in (0, -2, 1.5, True, "2"):
        with pytest.raises(ReproError, match="jobs must be a whole number"):
            run_many([], tmp_path, jobs=bad)


_INTERRUPTED = """
import signal
import sys
# Ctrl-C raises KeyboardInterrupt here even when the suite runs from a shell that ignores SIGINT (a
# background job of a non-interactive shell): an ignored SIGINT would be inherited (issue 23, section 1)
signal.signal(signal.SIGINT, signal.default_int_handler)
import tests.jobs_figures
from repro.cli import main
sys.exit(main(["run", "zz_jobs_slow_a", "zz_jobs_slow_b", "zz_jobs_a", "--jobs", "2", "--out", sys.argv[1]]))
"""


@pytest.mark.parametrize("to", ["group", "parent"])
def test_ctrl_c_stops_the_workers_and_leaves_no_partial_file(tmp_path, to):
    """Ctrl-C (SIGINT to the whole foreground process group, as a terminal sends it; or to the parent
    alone, as ``kill -INT`` does) while two workers are half-way through writing: every process ends,
    and no temporary or half-written file stays."""
    import contextlib
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, ZZ_JOBS_SLOW_IN=str(out))
    p = subprocess.Popen([sys.executable, "-c", _INTERRUPTED, str(out)], cwd=Path(__file__).resolve().parents[1],
                         env=env, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 180
        while len(list(tmp_path.glob("started-*"))) < 2:
            assert time.monotonic() < deadline and p.poll() is None, p.communicate()
            time.sleep(0.05)
        assert len(list(out.glob(".zz_jobs_slow_*.tmp"))) == 2  # both half-written
        if to == "group":
            os.killpg(p.pid, signal.SIGINT)
        else:
            os.kill(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=120)
        assert p.returncode != 0 and "KeyboardInterrupt" in err
        for marker in tmp_path.glob("started-*"):
            pid = int(marker.name.split("-")[1])
            for _ in range(100):  # (reaped by the parent before it exited; a moment for the kernel)
                try:
                    os.kill(pid, 0)
                except ProcessLookupError:
                    break
                time.sleep(0.05)
            else:
                pytest.fail(f"worker {pid} still running")
        assert sorted(x.name for x in out.iterdir()) == [], "partial files left"
    finally:  # whatever failed above (after it was checked): nothing of the run outlives the test
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
        p.wait()
