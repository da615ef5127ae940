"""Headless 3D rendering support (pyvista/VTK), imported lazily.

VTK needs an OpenGL: Mesa EGL by default, OSMesa as fallback (Debian packages
``libegl1 libgl1-mesa-dri libosmesa6``).  Without either it *segfaults*, and
``pyvista.system_supports_plotting()`` still says yes, so availability is probed
once in a subprocess (see ``../shared/notes/toolchain.md``).  Figures that need
a render call :func:`require_render`, which raises
:class:`~repro.errors.RenderUnavailableError` with the reason and the cure; the
numbers (CSV) of every figure never depend on rendering.
"""

from __future__ import annotations

import functools
import os
import re
import subprocess
import sys

from repro.errors import RenderUnavailableError

__all__ = ["render_unavailable_reason", "require_render", "configure_headless"]

_PROBE = (
    "import pyvista as pv\n"
    "pl = pv.Plotter(off_screen=True, window_size=(64, 64))\n"
    "pl.add_mesh(pv.Sphere())\n"
    "img = pl.screenshot(return_img=True)\n"
    "assert img.std() > 1, 'blank image'\n"
)

_CURE = "apt-get install -y libegl1 libgl1-mesa-dri libosmesa6 (scripts/setup.sh does this)"


def configure_headless() -> None:
    """Prefer VTK's EGL window when there is no display (skips a failing X attempt and its stderr)."""
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


@functools.cache
def render_unavailable_reason() -> str | None:
    """None when off-screen VTK rendering works here, else why not (probed once, in a subprocess)."""
    configure_headless()
    try:
        p = subprocess.run(
            [sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=120, env=os.environ
        )
    except subprocess.TimeoutExpired:
        return f"VTK render probe timed out; {_CURE}"
    if p.returncode == 0:
        return None
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    hints = [ln for ln in lines if "WARN" in ln or "Error" in ln] or lines[-1:] or ["no output"]
    why = re.sub(r"\x1b\[[0-9;]*m", "", hints[-1].split("|")[-1]).strip()
    return f"VTK off-screen rendering unavailable (exit {p.returncode}: {why}); {_CURE}"


def require_render() -> None:
    """Raise :class:`RenderUnavailableError` unless off-screen rendering works."""
    reason = render_unavailable_reason()
    if reason:
        raise RenderUnavailableError(reason)
