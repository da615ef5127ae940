"""JupyterLab in a real (headless) browser, for the widget tests of this folder.

- ``@pytest.mark.browser`` tests need Debian's Chromium (``/usr/bin/chromium``, apt
  ``chromium``) and the ``playwright`` package (the ``dev`` extra); both are installed by
  ``scripts/setup.sh``.  Playwright's own browser download (``playwright install``) is
  never used.  Without them the tests are skipped with the reason, or, with
  ``REPRO_REQUIRE_BROWSER=1`` (CI), the run stops with an error instead.
- ``lab``: one JupyterLab server per test module, on 127.0.0.1 and a free port, serving a
  temporary folder (the tests copy the committed notebooks there, so checkpoints and
  autosaves never touch the repository).  It inherits this process's environment
  (``REPRO_DATA_DIR``, ``REPRO_OFFLINE``, ...), so its kernels see the same data; its
  Lab settings, workspaces and runtime files live in the temporary folder too.
  Stopped after the module's last test: kernels shut down through the REST API, the server
  by SIGTERM (SIGKILL after a grace period), and any child process still alive killed by pid.
- ``browser``: one headless Chromium (Playwright, ``executable_path=/usr/bin/chromium``)
  per test module with a fresh profile; each test opens its own page (and its own Lab
  workspace, so it does not restore another test's notebook).
- Screenshots, the server's log and each test's step times go to
  ``test-artifacts/browser/`` (gitignored).
"""

from __future__ import annotations

import importlib.util
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.conftest import REPO

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = REPO / "test-artifacts" / "browser"
#: Bound of every single wait (server start, page load, running a notebook, a widget update), seconds.
STEP_TIMEOUT = 60.0
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
]


def browser_unavailable_reason() -> str | None:
    """Why the browser tests cannot run here, or None."""
    missing = []
    if not (CHROMIUM.is_file() and os.access(CHROMIUM, os.X_OK)):
        missing.append(f"{CHROMIUM} is missing (Debian package chromium; scripts/setup.sh installs it)")
    if importlib.util.find_spec("playwright") is None:
        missing.append("the Python package playwright is missing (the dev extra; scripts/setup.sh installs it)")
    return "; ".join(missing) or None


def pytest_configure(config):
    config.addinivalue_line("markers", "browser: drives JupyterLab in headless Chromium (Playwright)")


def pytest_collection_modifyitems(config, items):
    browser_items = [i for i in items if i.get_closest_marker("browser")]
    if not browser_items:
        return
    reason = browser_unavailable_reason()
    if reason is None:
        return
    if os.environ.get("REPRO_REQUIRE_BROWSER") == "1":
        raise pytest.UsageError(f"REPRO_REQUIRE_BROWSER=1 but {reason}")
    for item in browser_items:
        item.add_marker(pytest.mark.skip(reason=f"browser test: {reason}"))


# ------------------------------------------------------------------ server
def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Lab:
    """A running JupyterLab server."""

    url: str  # http://127.0.0.1:PORT
    token: str
    root: Path  # the folder it serves
    proc: subprocess.Popen
    log: Path

    def api(self, method: str, path: str, timeout: float = 10.0):
        req = urllib.request.Request(f"{self.url}{path}", method=method,
                                     headers={"Authorization": f"token {self.token}"})
        with urllib.request.urlopen(req, timeout=timeout) as r:
            body = r.read()
        return json.loads(body) if body else None

    def page_url(self, notebook: str, workspace: str) -> str:
        # one workspace per test: a page does not restore the notebooks another test opened
        return f"{self.url}/lab/workspaces/{workspace}/tree/{notebook}?token={self.token}"

    def add_notebook(self, src: Path) -> str:
        """Copy a committed notebook into the served folder; its name there."""
        shutil.copy2(src, self.root / src.name)
        return src.name

    def shutdown_kernels(self) -> None:
        try:
            for s in self.api("GET", "/api/sessions"):
                self.api("DELETE", f"/api/sessions/{s['id']}", timeout=STEP_TIMEOUT)
        except (OSError, urllib.error.URLError, ValueError):
            pass

    def log_tail(self, n: int = 40) -> str:
        try:
            return "\n".join(self.log.read_text(errors="replace").splitlines()[-n:])
        except OSError:
            return ""


def _stop(proc: subprocess.Popen, children) -> None:
    """SIGTERM the server (it shuts its kernels down), SIGKILL after 15 s; then kill any child left, by pid."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=15)
    for c in children:
        try:
            if c.is_running():
                c.kill()
        except Exception:  # noqa: BLE001 - gone already
            pass


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    if browser_unavailable_reason():  # only reached when collection did not skip (e.g. a direct call)
        pytest.skip(browser_unavailable_reason())
    import psutil

    base = tmp_path_factory.mktemp("jupyterlab")
    root, home = base / "root", base / "home"
    root.mkdir()
    settings = home / "settings" / "@jupyterlab" / "apputils-extension"
    settings.mkdir(parents=True)
    # no "Would you like to receive official Jupyter news?" toast over the notebook
    (settings / "notification.jupyterlab-settings").write_text(
        json.dumps({"fetchNews": "false", "checkForUpdates": False}))
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    token = secrets.token_hex(16)
    port = _free_port()
    log = ARTIFACTS / f"jupyterlab-{port}.log"  # one per server: two test processes may each run one
    env = dict(os.environ)  # REPRO_DATA_DIR, REPRO_OFFLINE, ... reach the kernels
    env.update({
        "JUPYTERLAB_SETTINGS_DIR": str(home / "settings"),
        "JUPYTERLAB_WORKSPACES_DIR": str(home / "workspaces"),
        "JUPYTER_RUNTIME_DIR": str(home / "runtime"),
        "PYDEVD_DISABLE_FILE_VALIDATION": "1",
    })
    cmd = [
        sys.executable, "-m", "jupyterlab", "--no-browser", "--allow-root", "--ip=127.0.0.1", f"--port={port}",
        "--ServerApp.port_retries=0",  # fail rather than silently move to another port
        f"--IdentityProvider.token={token}", f"--ServerApp.root_dir={root}",
        "--LabApp.expose_app_in_browser=True",  # window.jupyterapp
        "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate",
    ]
    with open(log, "wb") as out:
        proc = subprocess.Popen(cmd, cwd=root, env=env, stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT)
    server = Lab(f"http://127.0.0.1:{port}", token, root, proc, log)
    children = []
    try:
        deadline = time.monotonic() + STEP_TIMEOUT
        while True:
            if proc.poll() is not None:
                pytest.fail(f"JupyterLab exited with code {proc.returncode}:\n{server.log_tail()}", pytrace=False)
            try:
                server.api("GET", "/api/status", timeout=2)
                break
            except (OSError, urllib.error.URLError):
                if time.monotonic() > deadline:
                    pytest.fail(f"JupyterLab did not answer within {STEP_TIMEOUT:.0f} s:\n{server.log_tail()}",
                                pytrace=False)
                time.sleep(0.2)
        yield server
    finally:
        server.shutdown_kernels()
        try:
            children = psutil.Process(proc.pid).children(recursive=True)
        except psutil.Error:
            children = []
        _stop(proc, children)


# ----------------------------------------------------------------- browser
@pytest.fixture(scope="module")
def browser(lab, tmp_path_factory):
    """A headless Chromium (persistent context with a fresh profile), closed after the module's last test."""
    from playwright.sync_api import sync_playwright

    pw = sync_playwright().start()
    try:
        context = pw.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("chromium-profile")), executable_path=str(CHROMIUM), headless=True,
            args=CHROMIUM_ARGS, viewport={"width": 1400, "height": 1000})
        try:
            context.set_default_timeout(STEP_TIMEOUT * 1000)
            yield context
        finally:
            context.close()
    finally:
        pw.stop()


class NotebookPage:
    """A notebook opened in JupyterLab in its own browser page."""

    def __init__(self, lab: Lab, context, notebook: str, name: str):
        self.lab, self.name, self.notebook = lab, name, notebook
        self.t0 = time.monotonic()
        self.steps: list[str] = []
        self.page = context.new_page()
        self.console: list[str] = []
        self.page.on("console", lambda m: self.console.append(f"{m.type}: {m.text}"))
        self.page.goto(lab.page_url(notebook, name), wait_until="domcontentloaded")
        self.page.wait_for_selector(".jp-Notebook .jp-Cell")
        self.page.wait_for_function("() => window.jupyterapp && window.jupyterapp.shell.currentWidget"
                                    " && window.jupyterapp.shell.currentWidget.sessionContext")
        self.step("notebook open")

    def step(self, what: str) -> None:
        """Note the time since the page was opened (written to ``<name>-steps.txt``)."""
        self.steps.append(f"{time.monotonic() - self.t0:7.2f} s  {what}")

    def run_all(self, timeout: float = STEP_TIMEOUT) -> None:
        """Run all cells (``notebook:run-all-cells``) and wait until they are done; fail on a cell error."""
        result = self.page.evaluate(
            """async (ms) => {
                const app = window.jupyterapp;
                const nb = app.shell.currentWidget;
                const timeout = new Promise(r => setTimeout(() => r('timeout'), ms));
                const ready = await Promise.race([nb.sessionContext.ready.then(() => 'ready'), timeout]);
                if (ready !== 'ready') return 'kernel not ready';
                const ok = await Promise.race([app.commands.execute('notebook:run-all-cells'), timeout]);
                return ok === 'timeout' ? 'timeout' : (ok === false ? 'cell error' : 'ok');
            }""",
            timeout * 1000,
        )
        if result != "ok":
            self.screenshot("failed-run-all")
            errors = self.page.locator(".jp-OutputArea-output[data-mime-type='application/vnd.jupyter.stderr']")
            texts = [t for t in errors.all_inner_texts() if "Error" in t or "Traceback" in t]
            pytest.fail(f"{self.notebook}: running all cells: {result} (limit {timeout:.0f} s)\n"
                        + "\n".join(texts)[-3000:], pytrace=False)
        self.step("all cells run")

    def text(self, selector: str) -> str:
        return self.page.locator(selector).inner_text().strip()

    def wait_text_change(self, selector: str, old: str, timeout: float = STEP_TIMEOUT) -> str:
        """Wait until the element's text differs from ``old`` (and is not empty); the new text."""
        self.page.wait_for_function(
            """([sel, old]) => { const e = document.querySelector(sel);
                                 const t = e ? e.innerText.trim() : '';
                                 return t !== '' && t !== old; }""",
            arg=[selector, old], timeout=timeout * 1000)
        return self.text(selector)

    def screenshot(self, step: str, selector: str | None = None) -> Path:
        path = ARTIFACTS / f"{self.name}-{step}.png"
        try:
            if selector:
                self.page.locator(selector).screenshot(path=str(path), timeout=10_000)
            else:
                self.page.screenshot(path=str(path), timeout=10_000)
        except Exception:  # noqa: BLE001 - a screenshot must not hide the real failure
            pass
        return path

    def close(self) -> None:
        try:  # shut the kernel down (bounded: the server kills a kernel that does not stop)
            self.page.evaluate("""() => Promise.race([
                window.jupyterapp.shell.currentWidget.sessionContext.shutdown(),
                new Promise(r => setTimeout(r, 15000))])""")
        except Exception:  # noqa: BLE001
            pass
        self.page.close()
        self.step("closed")
        (ARTIFACTS / f"{self.name}-steps.txt").write_text("\n".join(self.steps) + "\n")


@pytest.fixture
def open_notebook(lab, browser, request):
    """``open_notebook(path)``: copy the notebook into the server's folder and open it in a new page."""
    pages = []

    def _open(src: Path) -> NotebookPage:
        name = lab.add_notebook(src)
        nb = NotebookPage(lab, browser, name, request.node.name.removeprefix("test_"))
        pages.append(nb)
        return nb

    yield _open
    failed = getattr(request.node, "rep_call", None) is not None and request.node.rep_call.failed
    for nb in pages:
        if failed:
            nb.screenshot("failure")
        nb.close()
    lab.shutdown_kernels()


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    rep = yield
    if rep.when == "call":
        item.rep_call = rep
    return rep
