"""The teaching apps: each paper's panel as a web page without code (Voilà on a small notebook).

``repro app face`` serves ``repro/ui/apps/face.ipynb`` (the blendshape panel on the ICT
face when its data are present, else the embedded face), ``repro app fighter`` serves
``repro/ui/apps/fighter.ipynb`` (the kung-fu fighter panel, strikes animated).  The
notebooks ship inside the package, so the command works from an installed ``repro`` as
well as from a clone.

- ``--host`` defaults to the loopback address (``127.0.0.1``): the app is not reachable
  from other machines unless asked (``--host 0.0.0.0``).
- The port is checked before Voilà starts: a taken port is one clear error (Voilà would
  otherwise silently move to another one).
- A browser is opened only when there is a display to open it on (and not with
  ``--no-browser``); on a headless machine the command prints the address to open.
"""

from __future__ import annotations

import errno
import os
import socket
import subprocess
import sys
from pathlib import Path

from repro.errors import ReproError

__all__ = [
    "APPS",
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "AppError",
    "app_environment",
    "app_notebook",
    "has_display",
    "port_problem",
    "run_app",
    "voila_command",
]

APPS = {
    "face": "Lewis et al. 2005: sliders, selection, alpha and attenuation on a blendshape face",
    "fighter": "Pronost et al.: order kicks and punches at a target, watch the adapted strike",
}
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8866
APPS_DIR = Path(__file__).with_name("apps")


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


def has_display() -> bool:
    """Whether a browser window could be opened here (a desktop, or X/Wayland on Linux)."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def voila_command(which: str, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *,
                  open_browser: bool = False) -> list[str]:
    """The command line that serves app ``which`` (Voilà, this Python)."""
    nb = app_notebook(which)
    return [
        sys.executable, "-m", "voila", str(nb),
        f"--Voila.ip={host}", f"--port={port}", "--Voila.port_retries=0",
        f"--Voila.open_browser={bool(open_browser)}",
        "--show_tracebacks=True",
    ]


def app_environment(base=None) -> dict:
    """The environment of Voilà and its kernel: this one, with one BLAS thread unless the user chose.

    The panels' products are small (the ICT face's ``D @ w``: 28,227 x 57), and a
    multi-threaded OpenBLAS spends longer waking its threads than multiplying: on a busy
    2-core machine 26 ms per product, against 1.5 ms with one thread (measured).
    """
    env = dict(os.environ if base is None else base)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def run_app(which: str, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, no_browser: bool = False) -> int:
    """Serve app ``which`` until interrupted (Ctrl-C); the exit status of Voilà (0 after Ctrl-C)."""
    import importlib.util

    nb = app_notebook(which)
    if (why := port_problem(host, port)) is not None:
        raise AppError(why)
    if importlib.util.find_spec("voila") is None:
        raise AppError("Voilà is not installed: pip install voila (it is a dependency of repro)")
    open_browser = not no_browser and has_display()
    url = f"http://{'[' + host + ']' if ':' in host else host}:{port}/"
    print(f"repro app {which}: {APPS[which]}", flush=True)
    print(f"serving {nb.name} with Voilà at {url}"
          + ("" if open_browser else " (open it in a browser)") + "; Ctrl-C to stop", flush=True)
    proc = subprocess.Popen(voila_command(which, host, port, open_browser=open_browser), env=app_environment())
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
