"""``repro app face|fighter``: the command line, the port check, the shipped notebooks (no server started here).

The apps themselves are driven in a browser by ``tests/browser/test_app.py``.
"""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
from pathlib import Path

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
    # a port out of range is bad usage: exit 2 with the usage line (issue 23 section 7; it was 1)
    assert cli.main(["app", "fighter", "--host", "a" * 300, "--port", "8866"]) == 1  # was idna's UnicodeError
    assert "is not a valid host name" in capsys.readouterr().err
    assert cli.main(["app", "fighter", "--port", "70000"]) == 2
    err = capsys.readouterr().err
    assert "--port must be a number in 1..65535" in err and err.startswith("usage: repro app")


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
        def __init__(self, cmd, env=None, **kw):
            seen["cmd"] = cmd
            seen["env"] = env

        def wait(self):
            return 0

        def poll(self):
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
    # with the token (the default) repro opens the browser on the URL with the token (Voila's opener drops it)
    opened = []
    monkeypatch.setattr(app, "_open_when_listening", lambda url, *a, **k: opened.append(url))
    assert cli.main(["app", "face", "--port", str(free)]) == 0
    assert "--Voila.open_browser=False" in seen["cmd"] and len(opened) == 1 and "?token=" in opened[0]
    assert cli.main(["app", "face", "--port", str(free), "--no-token"]) == 0
    assert "--Voila.open_browser=True" in seen["cmd"] and len(opened) == 1
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


class _FakeVoila:
    seen: dict = {}

    def __init__(self, cmd, env=None, **kw):
        _FakeVoila.seen = {"cmd": cmd, "env": env}

    def wait(self):
        return 0

    def poll(self):
        return 0


def _free_port(host="127.0.0.1") -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def test_app_is_served_with_a_token_printed_once_inside_the_url(monkeypatch, capsys):
    """Issue 23 section 7: the page and its kernel answer only with a generated token (as JupyterLab)."""
    monkeypatch.setattr(app.subprocess, "Popen", _FakeVoila)
    monkeypatch.setenv("JUPYTER_TOKEN", "inherited")
    monkeypatch.setenv("JUPYTER_TOKEN_FILE", "/nonexistent")
    port = _free_port()
    assert cli.main(["app", "fighter", "--port", str(port), "--no-browser"]) == 0
    out = capsys.readouterr().out
    m = re.search(rf"http://127\.0\.0\.1:{port}/\?token=([A-Za-z0-9_-]+)", out)
    assert m is not None and len(m.group(1)) >= 40 and out.count(m.group(1)) == 1
    env, cmd = _FakeVoila.seen["env"], _FakeVoila.seen["cmd"]
    assert env["JUPYTER_TOKEN"] == m.group(1) and "JUPYTER_TOKEN_FILE" not in env
    assert "--Voila.auto_token=True" in cmd and not any(m.group(1) in c for c in cmd)  # not on the command line
    assert cli.main(["app", "fighter", "--port", str(port), "--no-browser"]) == 0
    assert m.group(1) not in capsys.readouterr().out  # a fresh token each time


def test_app_without_token_only_on_loopback(monkeypatch, capsys):
    monkeypatch.setattr(app.subprocess, "Popen", _FakeVoila)
    for host in ("0.0.0.0", "::", "8.8.8.8", "no-such-host.invalid"):
        _FakeVoila.seen = {}
        assert cli.main(["app", "face", "--host", host, "--no-token", "--no-browser"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("usage: repro app") and "--no-token is only allowed on a loopback address" in err
        assert _FakeVoila.seen == {}
    with pytest.raises(app.AppError, match="only allowed on a loopback address"):
        app.run_app("face", "0.0.0.0", _free_port(), no_browser=True, token=False)
    monkeypatch.setenv("JUPYTER_TOKEN", "inherited")
    port = _free_port()
    assert cli.main(["app", "face", "--port", str(port), "--no-token", "--no-browser"]) == 0
    assert f"http://127.0.0.1:{port}/ " in capsys.readouterr().out
    assert "--Voila.auto_token=False" in _FakeVoila.seen["cmd"] and "JUPYTER_TOKEN" not in _FakeVoila.seen["env"]


def test_app_on_every_interface_is_warned_about(monkeypatch, capsys):
    monkeypatch.setattr(app.subprocess, "Popen", _FakeVoila)
    port = _free_port("0.0.0.0")
    assert cli.main(["app", "face", "--host", "0.0.0.0", "--port", str(port), "--no-browser"]) == 0
    captured = capsys.readouterr()
    assert "repro: warning: --host 0.0.0.0 is not a loopback address" in captured.err
    assert f"http://0.0.0.0:{port}/?token=" in captured.out
    assert cli.main(["app", "face", "--port", str(_free_port()), "--no-browser"]) == 0
    assert "warning" not in capsys.readouterr().err  # loopback: no warning


def test_app_empty_host_is_a_usage_error(monkeypatch, capsys):
    monkeypatch.setattr(app.subprocess, "Popen", lambda *a, **k: pytest.fail("must not start"))
    assert cli.main(["app", "face", "--host", ""]) == 2  # Voila would listen on every interface
    assert "--host must name an address" in capsys.readouterr().err
    with pytest.raises(app.AppError, match="host must name an address"):
        app.run_app("face", "", _free_port())


@pytest.mark.parametrize("host, loopback", [("127.0.0.1", True), ("127.1.2.3", True), ("::1", True), ("[::1]", False),
                                            ("localhost", True), ("0.0.0.0", False), ("::", False), ("", False),
                                            ("8.8.8.8", False), ("no-such-host.invalid", False), (None, False)])
def test_is_loopback(host, loopback):
    assert app.is_loopback(host) is loopback


def test_the_real_app_refuses_requests_without_its_token(tmp_path):
    """Voila for real (``repro app``): ``/`` and the kernels API without the token redirect to the login
    page, with a wrong one too; with the token the API answers 200 (the page itself is the browser
    tests' job: a GET of it runs the notebook)."""
    import signal
    import time
    import urllib.error
    import urllib.request

    port = _free_port()
    log = tmp_path / "app.log"

    class NoRedirect(urllib.request.HTTPRedirectHandler):
        def redirect_request(self, *a, **k):
            return None

    opener = urllib.request.build_opener(NoRedirect)

    def status(path):
        try:
            with opener.open(f"http://127.0.0.1:{port}{path}", timeout=60) as r:
                return r.status, ""
        except urllib.error.HTTPError as e:
            return e.code, e.headers.get("Location", "")

    with open(log, "wb") as out:
        proc = subprocess.Popen([sys.executable, "-m", "repro", "app", "fighter", "--port", str(port), "--no-browser"],
                                stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        for _ in range(600):  # until Voila listens (no timing asserted: the loop only bounds a broken start)
            assert proc.poll() is None, log.read_text()
            try:
                socket.create_connection(("127.0.0.1", port), timeout=2).close()
                break
            except OSError:
                time.sleep(0.3)
        token = re.search(r"\?token=([A-Za-z0-9_-]+)", log.read_text()).group(1)
        code, where = status("/")
        assert code in (302, 403) and (code == 403 or "/login" in where)
        for path in ("/api/kernels", "/api/kernels?token=wrong", "/?token=wrong"):
            code, where = status(path)
            assert code in (302, 403) and (code == 403 or "/login" in where), path
        code, where = status(f"/api/kernels?token={token}")  # accepted: Voila sends it on to its files
        assert code == 200 or (code == 302 and "/login" not in where), (code, where)
        # killing `repro app` alone (not its group) stops Voila too: nothing keeps serving
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
        voila = [int(c) for c in children.read_text().split()] if children.exists() else []
        assert voila or not children.exists(), "repro app started no Voila"
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=20)
        for pid in voila:
            for _ in range(300):  # bounded wait for Voila to stop its kernel and exit (PR_SET_PDEATHSIG: SIGTERM)
                if not Path(f"/proc/{pid}").exists() or "Z" in Path(f"/proc/{pid}/stat").read_text().split()[2]:
                    break
                time.sleep(0.2)
            else:
                pytest.fail(f"Voila (pid {pid}) still runs after its repro app was killed")
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


@pytest.mark.parametrize("which", sorted(app.APPS))
def test_app_starts_from_a_preheated_kernel_with_its_own_template_and_loading_line(which):
    """Issue 26, item 11: a kernel runs the notebook before the first visit; the page says what it prepares."""
    cmd = app.voila_command(which, "127.0.0.1", 9123)
    assert "--VoilaConfiguration.preheat_kernel=True" in cmd and "--VoilaConfiguration.default_pool_size=1" in cmd
    assert f"--VoilaKernelManager.fill_delay={app.REFILL_DELAY}" in cmd
    assert f"--VoilaConfiguration.template={app.TEMPLATE}" in cmd
    assert cmd[cmd.index("--VoilaConfiguration.resources") + 1] == f"repro_loading={app.LOADING[which]}"
    assert app.LOADING[which].startswith(f"Preparing the {which}")


def test_app_template_is_found_through_the_app_environment_and_links_no_cdn(monkeypatch):
    from voila.paths import collect_template_paths

    env = app.app_environment({"JUPYTER_PATH": "/elsewhere"})
    assert env["JUPYTER_PATH"].split(os.pathsep) == [str(app.JUPYTER_DIR), "/elsewhere"]
    monkeypatch.setenv("JUPYTER_PATH", env["JUPYTER_PATH"])
    paths = collect_template_paths(["voila", "nbconvert"], app.TEMPLATE, prune=True)
    ours = app.JUPYTER_DIR / "voila" / "templates" / app.TEMPLATE
    assert paths[0] == str(ours) and any(p.endswith("voila/templates/lab") for p in paths)
    # the links the template drops are the lab template's, verbatim (a newer Voila that changes them fails here)
    lab = next(p for p in paths if p.endswith("voila/templates/lab"))
    links = re.findall(r'<link rel="stylesheet" href="https?://[^"]+" type="text/css" />',
                       (Path(lab) / "index.html.j2").read_text())
    ours_text = (ours / "index.html.j2").read_text()
    assert links and all(f"replace('{link}', '')" in ours_text for link in links)
