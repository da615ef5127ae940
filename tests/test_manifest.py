"""figures/manifest.json under concurrency and damage; ``--out`` that cannot be a folder (issue 9, item 4)."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import pandas as pd
import pytest

from repro import cli
from repro.errors import ReproWarning
from repro.experiments.registry import MANIFEST, Result, experiment, run_many

registry_mod = importlib.import_module("repro.experiments.registry")  # (``repro.experiments.registry`` is the function)
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def fake_figures():
    """Two tiny registered figures (removed again afterwards)."""
    names = ["zz_fake_a", "zz_fake_b"]
    for i, name in enumerate(names):
        experiment(name, f"fake figure {i}", paper="lewis2005", data=())(
            lambda quick=False, i=i: Result(pd.DataFrame({"i": [i], "quick": [quick]})))
    yield names
    for name in names:
        registry_mod._REGISTRY.pop(name, None)


# ------------------------------------------------------------------ concurrency
_WRITER = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    import pandas as pd
    from repro.experiments.registry import Result, experiment, run_many

    tag, out, n, go = sys.argv[1], sys.argv[2], int(sys.argv[3]), Path(sys.argv[4])
    names = []
    for i in range(n):
        name = f"zz_{tag}_{i}"
        experiment(name, "concurrency test", paper="lewis2005", data=())(
            lambda quick=False, i=i: Result(pd.DataFrame({"i": [i]})))
        names.append(name)
    Path(out, f"ready-{tag}").write_text("")
    while not go.exists():
        time.sleep(0.005)
    status = run_many(names, out)
    assert all(s == "ran" for s in status.values()), status
""")


@pytest.mark.parametrize("attempt", range(3))
def test_two_processes_writing_one_manifest_keep_every_entry(tmp_path, attempt):
    out = tmp_path / "figures"
    out.mkdir()
    go = tmp_path / "go"
    n = 12
    procs = [subprocess.Popen([sys.executable, "-c", _WRITER, tag, str(out), str(n), str(go)], cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for tag in ("a", "b")]
    deadline = time.monotonic() + 120
    while not all((out / f"ready-{t}").exists() for t in "ab"):  # both imported: start together
        assert time.monotonic() < deadline and all(p.poll() is None for p in procs), [p.communicate() for p in procs]
        time.sleep(0.01)
    go.write_text("")
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
    manifest = json.loads((out / MANIFEST).read_text())
    want = {f"zz_{t}_{i}" for t in "ab" for i in range(n)}
    assert set(manifest) == want, f"lost: {sorted(want - set(manifest))}"
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith("ready-")) == sorted(
        [f"{name}.csv" for name in want] + [MANIFEST])  # no lock file or temporary left in the folder


# ------------------------------------------------------------------ damaged manifests
@pytest.mark.parametrize("content, kept", [
    ("[]", set()),
    ("null", set()),
    ('{"fig4_axis_selection": 3}', set()),
    ('{"fig4_axis_selection": 3, "zz_other": {"name": "zz_other", "files": []}}', {"zz_other"}),
    ('{"half": {"name": ', set()),
    (b"\xff\xfe not utf-8", set()),
    ('{"deep": ' + "[" * 5000 + "]" * 5000 + "}", set()),  # json recurses per level
])
def test_a_damaged_manifest_is_kept_aside_and_rebuilt_with_a_warning(tmp_path, fake_figures, capsys, content, kept):
    path = tmp_path / MANIFEST
    (path.write_bytes if isinstance(content, bytes) else path.write_text)(content)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert cli.main(["run", fake_figures[0], "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "repro: warning:" in err and "manifest.json" in err and "damaged" in err
    assert not [w for w in caught if issubclass(w.category, ReproWarning)]  # shown by the CLI as one line
    manifest = json.loads(path.read_text())
    assert set(manifest) == {fake_figures[0]} | kept
    backup = tmp_path / (MANIFEST + ".damaged")
    assert backup.read_bytes() == (content if isinstance(content, bytes) else content.encode())


def test_run_many_warns_about_a_damaged_manifest(tmp_path, fake_figures):
    (tmp_path / MANIFEST).write_text('{"zz_fake_b": [1, 2], "zz_keep": {"files": [3]}}')
    with pytest.warns(ReproWarning, match=r"entries that are not objects: 'zz_fake_b'.*1 valid entry"):
        assert run_many(fake_figures[:1], tmp_path) == {"zz_fake_a": "ran"}
    assert set(json.loads((tmp_path / MANIFEST).read_text())) == {"zz_fake_a", "zz_keep"}
    # the rebuilt manifest is healthy: no second warning, and a hand-edited entry just reruns
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (tmp_path / MANIFEST).write_text(json.dumps({"zz_fake_b": {"inputs": 1, "files": [3]}}))
        assert run_many(fake_figures, tmp_path) == {"zz_fake_a": "ran", "zz_fake_b": "ran"}
        assert run_many(fake_figures, tmp_path) == {"zz_fake_a": "cached", "zz_fake_b": "cached"}


# ------------------------------------------------------------------ --out that cannot be a folder
@pytest.mark.parametrize("argv", [["run", "zz_fake_a"], ["all"], ["claims"], ["bench", "attenuation", "--quick"]])
def test_out_naming_a_file_exits_2_with_a_message(tmp_path, fake_figures, capsys, argv):
    afile = tmp_path / "figures.txt"
    afile.write_text("not a folder")
    assert cli.main([*argv, "--out", str(afile)]) == 2
    err = capsys.readouterr().err
    assert f"'{afile}' exists and is a file, not a folder" in err
    assert cli.main([*argv, "--out", str(afile / "sub")]) == 2
    assert "part of its path is a file" in capsys.readouterr().err
    assert afile.read_text() == "not a folder"


def test_out_naming_a_file_has_no_traceback_from_the_command_line(tmp_path):
    afile = tmp_path / "f"
    afile.write_text("")
    p = subprocess.run([sys.executable, "-m", "repro", "run", "fig4_axis_selection", "--out", str(afile / "x")],
                       capture_output=True, text=True, timeout=120, cwd=REPO)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.startswith("repro: --out: output folder") and "part of its path is a file" in p.stderr


def test_library_run_names_the_output_folder_problem(tmp_path, fake_figures):
    from repro.errors import ReproError

    afile = tmp_path / "f"
    afile.write_text("")
    with pytest.raises(ReproError, match="exists and is a file"):
        registry_mod.run(fake_figures[0], afile)
    with pytest.raises(ReproError, match="exists and is a file"):
        run_many(fake_figures, afile)
