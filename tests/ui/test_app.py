"""``repro app face|fighter``: the command line, the port check, the shipped notebooks (no server started here).

The apps themselves are driven in a browser by ``tests/browser/test_app.py``.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import pytest

from repro import cli
from repro.ui import app


@pytest.fixture
def taken_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    try:
        yield s.getsockname()[1]
    finally:
        s.close()


def test_app_on_a_taken_port_is_one_clear_error_before_voila_starts(taken_port, capsys, monkeypatch):
    started = []
    monkeypatch.setattr(app.subprocess, "Popen", lambda *a, **k: started.append(a))
    assert cli.main(["app", "face", "--port", str(taken_port)]) == 1
    err = capsys.readouterr().err
    assert f"port {taken_port} on 127.0.0.1 is already in use" in err and "--port" in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert started == []  # Voila never started


def test_app_bad_host_and_port_are_clear_errors(capsys, monkeypatch):
    monkeypatch.setattr(app.subprocess, "Popen", lambda *a, **k: pytest.fail("must not start"))
    assert cli.main(["app", "fighter", "--host", "no-such-host.invalid", "--port", "8866"]) == 1
    assert "--host 'no-such-host.invalid' is not a known address" in capsys.readouterr().err
    assert cli.main(["app", "fighter", "--port", "70000"]) == 1
    assert "--port must be a number in 1..65535" in capsys.readouterr().err


def test_app_unknown_name_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["app", "teapot"])
    assert e.value.code == 2
    assert "invalid choice: 'teapot'" in capsys.readouterr().err


def test_app_command_line_listens_where_asked_and_never_moves_port():
    cmd = app.voila_command("fighter", "127.0.0.1", 9123)
    assert cmd[:3] == [sys.executable, "-m", "voila"] and cmd[3].endswith("fighter.ipynb")
    assert "--Voila.ip=127.0.0.1" in cmd and "--port=9123" in cmd
    assert "--Voila.port_retries=0" in cmd  # a taken port fails instead of silently serving elsewhere
    assert "--Voila.open_browser=False" in cmd


def test_app_defaults_to_loopback_and_no_browser_without_a_display(monkeypatch, capsys, tmp_path):
    args = cli._parser().parse_args(["app", "face"])
    assert args.host == "127.0.0.1" and args.port == 8866 and not args.no_browser
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(app.sys, "platform", "linux")
    assert not app.has_display()
    seen = {}

    class FakeVoila:
        def __init__(self, cmd, env=None):
            seen["cmd"] = cmd
            seen["env"] = env

        def wait(self):
            return 0

    monkeypatch.setattr(app.subprocess, "Popen", FakeVoila)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        free = s.getsockname()[1]
    assert cli.main(["app", "face", "--port", str(free)]) == 0
    out = capsys.readouterr().out
    assert f"http://127.0.0.1:{free}/" in out and "open it in a browser" in out
    assert "--Voila.open_browser=False" in seen["cmd"]
    # the app's kernel gets one BLAS thread unless the user chose (small products, see app_environment)
    assert seen["env"]["OPENBLAS_NUM_THREADS"] == os.environ.get("OPENBLAS_NUM_THREADS", "1")
    assert app.app_environment({"OPENBLAS_NUM_THREADS": "4"})["OPENBLAS_NUM_THREADS"] == "4"
    monkeypatch.setenv("DISPLAY", ":0")
    assert cli.main(["app", "face", "--port", str(free)]) == 0
    assert "--Voila.open_browser=True" in seen["cmd"]
    assert cli.main(["app", "face", "--port", str(free), "--no-browser"]) == 0
    assert "--Voila.open_browser=False" in seen["cmd"]


@pytest.mark.parametrize("which", sorted(app.APPS))
def test_app_notebooks_ship_with_the_package_and_hold_no_outputs(which):
    nb = json.loads(app.app_notebook(which).read_text())
    assert nb["metadata"]["kernelspec"]["name"] == "python3"
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert code and all(not c.get("outputs") for c in code)
    import tomllib
    from pathlib import Path

    pyproject = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())
    assert "ui/apps/*.ipynb" in pyproject["tool"]["setuptools"]["package-data"]["repro"]
    assert any(d.startswith("voila") for d in pyproject["project"]["dependencies"])


def test_app_notebook_of_an_unknown_app_raises():
    with pytest.raises(app.AppError, match="unknown app 'teapot'"):
        app.app_notebook("teapot")


def test_app_help_lists_the_command():
    p = subprocess.run([sys.executable, "-m", "repro", "app", "--help"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "--port" in p.stdout and "--host" in p.stdout and "--no-browser" in p.stdout
