"""The teaching apps: each paper's panel as a web page without code (Voilà on a small notebook).

``repro app face`` serves ``repro/ui/apps/face.ipynb`` (the blendshape panel on the ICT
face when its data are present, else the embedded face), ``repro app fighter`` serves
``repro/ui/apps/fighter.ipynb`` (the kung-fu fighter panel, strikes animated).  The
notebooks ship inside the package, so the command works from an installed ``repro`` as
well as from a clone.

- ``--host`` defaults to the loopback address (``127.0.0.1``): the app is not reachable
  from other machines unless asked (``--host 0.0.0.0``, which is warned about on stderr).
- The page and its kernel (which runs code) answer only with an access token, generated
  with :func:`secrets.token_urlsafe` and printed once inside the URL, as JupyterLab does
  (``http://127.0.0.1:8866/?token=...``).  It reaches Voilà through ``JUPYTER_TOKEN`` in
  its environment (read by jupyter_server's identity provider with ``--Voila.auto_token``),
  not its command line, which other users of the machine can read.  ``token=False``
  (``--no-token``) only on a loopback address.
- The port is checked before Voilà starts: a taken port is one clear error (Voilà would
  otherwise silently move to another one).
- A browser is opened only when there is a display to open it on (and not with
  ``--no-browser``); on a headless machine the command prints the address to open.
- The page starts fast and stays offline: Voilà keeps one kernel that has already run the
  app's notebook (its preheated kernel pool, ``preheat_kernel``), so a visit gets the
  finished page instead of waiting for the notebook to run (the pool is refilled
  :data:`REFILL_DELAY` seconds after a visit, not while the page sets itself up).  The page
  is Voilà's "lab" template without its links to a CDN (:data:`TEMPLATE`, in
  ``repro/ui/apps/voila/templates``, found through ``JUPYTER_PATH``), and while the notebook
  runs it says what is being prepared (:data:`LOADING`).
"""

from __future__ import annotations

import errno
import functools
import ipaddress
import os
import secrets
import signal
import socket
import subprocess
import sys
from pathlib import Path

from repro.errors import ReproError
from repro.processes import parent_death_signal

__all__ = [
    "APPS",
    "LOADING",
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "AppError",
    "app_environment",
    "app_notebook",
    "has_display",
    "is_loopback",
    "port_problem",
    "run_app",
    "voila_command",
]

APPS = {
    "face": "Lewis et al. 2005: sliders, selection, alpha and attenuation on a blendshape face",
    "fighter": "Pronost et al.: order kicks and punches at a target, watch the adapted strike",
}
#: What each app's page says under its spinner while the notebook runs (a cold start; a preheated one is ready).
LOADING = {
    "face": "Preparing the face: starting Python and loading the face model (the ICT Face Model when its data "
            "are installed, else the embedded face).",
    "fighter": "Preparing the fighter: starting Python, building its motion database and adapting a first kick.",
}
#: Seconds after a visit before the preheated kernel pool starts the next kernel (Voilà's ``fill_delay``,
#: default 1 s: the new kernel's run then competes for the CPU with the page's first paint).
REFILL_DELAY = 3.0
#: The Voilà template of the apps (in ``JUPYTER_DIR``/voila/templates).
TEMPLATE = "repro"
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8866
APPS_DIR = Path(__file__).with_name("apps")
#: A Jupyter data folder of the apps' own (put first on ``JUPYTER_PATH``): the Voilà template.
JUPYTER_DIR = APPS_DIR


class AppError(ReproError):
    """The app cannot start (unknown app, port taken, Voilà missing)."""


def app_notebook(which: str) -> Path:
    """The notebook of app ``which`` ("face" or "fighter")."""
    if which not in APPS:
        raise AppError(f"unknown app {which!r}; known: {', '.join(APPS)}")
    path = APPS_DIR / f"{which}.ipynb"
    if not path.is_file():
        raise AppError(f"the app notebook {path} is missing (a broken install?)")
    return path


def port_problem(host: str, port: int) -> str | None:
    """Why Voilà could not listen on ``host:port`` (taken, not an address of this machine ...), or None."""
    if not isinstance(port, int) or not 1 <= port <= 65535:
        return f"--port must be a number in 1..65535, got {port!r}"
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        return f"--host {host!r} is not a known address ({exc.strerror})"
    except UnicodeError:  # a name idna cannot encode (a label over 63 characters, ...)
        return f"--host {host[:80]!r}{'...' if len(host) > 80 else ''} is not a valid host name"
    family, _, _, _, addr = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:
        try:
            s.bind(addr)
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                return (f"port {port} on {host} is already in use (another app or server?); "
                        f"choose another with --port, e.g. --port {port + 1}")
            return f"cannot listen on {host}:{port}: {exc.strerror or exc}"
    return None


def is_loopback(host: str) -> bool:
    """Whether every address ``host`` names is a loopback one (``127.0.0.1``, ``::1``, ``localhost``).

    An unknown name, or one that also resolves to another address, is not.
    """
    if not isinstance(host, str) or not host.strip():
        return False  # "" makes a server listen on every interface
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        return False
    try:
        return bool(infos) and all(ipaddress.ip_address(i[4][0].split("%")[0]).is_loopback for i in infos)
    except ValueError:
        return False


def new_token() -> str:
    """A fresh access token for one app (:func:`secrets.token_urlsafe`, 32 random bytes)."""
    return secrets.token_urlsafe(32)


def has_display() -> bool:
    """Whether a browser window could be opened here (a desktop, or X/Wayland on Linux)."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def voila_command(which: str, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *,
                  open_browser: bool = False, token: bool = True) -> list[str]:
    """The command line that serves app ``which`` (Voilà, this Python).

    ``token``: Voilà asks for the token that :func:`app_environment` puts in ``JUPYTER_TOKEN``
    (``--Voila.auto_token=True``: without it Voilà serves everyone).  One preheated kernel
    (``preheat_kernel``, pool of 1) runs the notebook before the first visit; the page uses
    the apps' template (:data:`TEMPLATE`, found through :func:`app_environment`'s
    ``JUPYTER_PATH``) with the app's :data:`LOADING` line.
    """
    nb = app_notebook(which)
    return [
        sys.executable, "-m", "voila", str(nb),
        f"--Voila.ip={host}", f"--port={port}", "--Voila.port_retries=0",
        f"--Voila.open_browser={bool(open_browser)}",
        f"--Voila.auto_token={bool(token)}",
        "--show_tracebacks=True",
        f"--VoilaConfiguration.template={TEMPLATE}",
        "--VoilaConfiguration.resources", f"repro_loading={LOADING[which]}",
        "--VoilaConfiguration.preheat_kernel=True", "--VoilaConfiguration.default_pool_size=1",
        f"--VoilaKernelManager.fill_delay={REFILL_DELAY}",
    ]


def app_environment(base=None, *, token: str | None = None) -> dict:
    """The environment of Voilà and its kernel: this one, with one BLAS thread unless the user chose,
    ``JUPYTER_TOKEN`` = ``token`` (removed when None: an inherited one is not the app's), and
    :data:`JUPYTER_DIR` first on ``JUPYTER_PATH`` (where Voilà finds the apps' template).

    The panels' products are small (the ICT face's ``D @ w``: 28,227 x 57), and a
    multi-threaded OpenBLAS spends longer waking its threads than multiplying: on a busy
    2-core machine 26 ms per product, against 1.5 ms with one thread (measured).
    """
    env = dict(os.environ if base is None else base)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env.pop("JUPYTER_TOKEN_FILE", None)
    env["JUPYTER_PATH"] = os.pathsep.join([str(JUPYTER_DIR), *filter(None, [env.get("JUPYTER_PATH")])])
    if token is None:
        env.pop("JUPYTER_TOKEN", None)
    else:
        env["JUPYTER_TOKEN"] = token
    return env


def run_app(which: str, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, no_browser: bool = False,
            token: bool = True) -> int:
    """Serve app ``which`` until interrupted (Ctrl-C); the exit status of Voilà (0 after Ctrl-C).

    ``token`` (default): a fresh access token, printed once inside the URL; ``False`` only on a
    loopback ``host`` (:class:`AppError` otherwise).  A ``host`` that is not loopback is warned
    about on stderr: the app's kernel runs code for whoever holds the URL.
    """
    import importlib.util

    nb = app_notebook(which)
    if not isinstance(host, str) or not host.strip():
        raise AppError(f"host must name an address, got {host!r} (an empty one listens on every interface)")
    if not isinstance(token, bool):
        raise AppError(f"token must be True or False, got {token!r}")
    loopback = is_loopback(host)
    if not token and not loopback:
        raise AppError(f"serving without a token is only allowed on a loopback address, not {host!r}")
    if (why := port_problem(host, port)) is not None:
        raise AppError(why)
    if importlib.util.find_spec("voila") is None:
        raise AppError("Voilà is not installed: pip install voila (it is a dependency of repro)")
    if not loopback:
        print(f"repro: warning: --host {host} is not a loopback address: the app (whose kernel runs code) is "
              "reachable from other machines by whoever holds its URL and token", file=sys.stderr, flush=True)
    secret = new_token() if token else None
    want_browser = not no_browser and has_display()
    url = f"http://{'[' + host + ']' if ':' in host else host}:{port}/" + (f"?token={secret}" if secret else "")
    print(f"repro app {which}: {APPS[which]}", flush=True)
    print(f"serving {nb.name} with Voilà at {url}"
          + ("" if want_browser else " (open it in a browser)") + "; Ctrl-C to stop", flush=True)
    # with a token the browser is opened here, on the URL with the token (Voilà's own opener drops it)
    # Voila ends with this process however it ends: SIGTERM here stops it as Ctrl-C does, and
    # Linux sends it SIGTERM (it then shuts its kernel down) should this process be killed
    previous = _terminate_on_sigterm()
    try:
        proc = subprocess.Popen(voila_command(which, host, port, open_browser=want_browser and not secret,
                                              token=bool(secret)), env=app_environment(token=secret),
                                preexec_fn=functools.partial(parent_death_signal, signal.SIGTERM)
                                if sys.platform.startswith("linux") else None)
        if want_browser and secret:
            _open_when_listening(url, host, port, proc)
        return _serve(proc)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _terminate_on_sigterm():
    """SIGTERM raises KeyboardInterrupt (the Ctrl-C path stops Voila); the previous handler, or None
    when not on the main thread (signals cannot be handled there)."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    return signal.signal(signal.SIGTERM, interrupt)


def _serve(proc) -> int:
    """Wait for Voila; on Ctrl-C (or SIGTERM) stop it, SIGKILL after 15 s; its exit status (0 after Ctrl-C)."""
    try:
        return proc.wait()
    except KeyboardInterrupt:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        return 0


def _open_when_listening(url: str, host: str, port: int, proc, timeout: float = 120.0) -> None:
    """Open ``url`` in a browser once Voilà accepts connections on ``host:port`` (a daemon thread)."""
    import threading
    import time
    import webbrowser

    def wait_then_open():
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                with socket.create_connection((host, port), timeout=1.0):
                    break
            except OSError:
                time.sleep(0.25)
        else:
            return
        webbrowser.open(url)

    threading.Thread(target=wait_then_open, name="repro-app-browser", daemon=True).start()
