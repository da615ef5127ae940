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


def face_images(
    model,
    displacements,
    scalars,
    *,
    selected=None,
    clim=None,
    cmap: str = "YlOrRd",
    window_size=(360, 400),
) -> list:
    """Off-screen renders of ``model`` posed by each displacement, coloured by the matching scalars.

    Parameters
    ----------
    model : BlendshapeModel
    displacements : sequence of (3n,) or (n, 3) arrays
        One pose per panel: vertices ``f0 + d``.
    scalars : sequence of (n,) arrays
        Per-vertex values to colour each panel by (e.g. motion since the selection).
    selected : array of vertex ids, optional
        Drawn as cyan spheres on every panel.
    clim : (lo, hi), optional
        Colour range shared by all panels (default: range of all scalars).

    Returns
    -------
    list of (H, W, 3) uint8 images, one per panel, all with the same camera
    (front view fitted to the neutral face).
    """
    require_render()
    import numpy as np
    import pyvista as pv

    displacements = [np.asarray(d, dtype=float).reshape(-1, 3) for d in displacements]
    scalars = [np.asarray(s, dtype=float).ravel() for s in scalars]
    if clim is None:
        hi = max(float(s.max()) for s in scalars) if scalars else 1.0
        clim = (0.0, hi if hi > 0 else 1.0)
    faces = np.column_stack([np.full(len(model.faces), 3), model.faces]).ravel()
    mesh = pv.PolyData(model.f0.copy(), faces)
    mesh.point_data["value"] = scalars[0] if scalars else np.zeros(model.n_vertices)
    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    try:
        pl.set_background("white")
        pl.add_mesh(mesh, scalars="value", cmap=cmap, clim=clim, smooth_shading=True,
                    show_scalar_bar=False, specular=0.2)
        markers = None
        if selected is not None and len(selected):
            sel = np.asarray(selected, dtype=int)
            markers = pv.PolyData(model.f0[sel].copy())
            size = 0.012 * float(np.ptp(model.f0[:, 1]))
            pl.add_mesh(markers.glyph(geom=pv.Sphere(radius=size), scale=False, orient=False),
                        color="cyan", name="selected")
        pl.view_xy()
        pl.camera.zoom(1.15)
        images = []
        for d, s in zip(displacements, scalars):
            mesh.points = model.f0 + d
            mesh.point_data["value"] = s
            if markers is not None:
                moved = pv.PolyData(model.f0[sel] + d[sel])
                pl.add_mesh(moved.glyph(geom=pv.Sphere(radius=size), scale=False, orient=False),
                            color="cyan", name="selected")
            pl.render()  # pyvista renders a screenshot only once otherwise
            images.append(pl.screenshot(return_img=True).copy())
        return images
    finally:
        pl.close()


def panel_figure(images, titles, *, clim, cmap: str = "YlOrRd", label: str = "", suptitle: str = "", ncols=None):
    """A matplotlib figure of rendered panels with one shared colour bar."""
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    n = len(images)
    ncols = ncols or n
    nrows = -(-n // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(2.6 * ncols + 0.8, 2.9 * nrows + 0.4),
                             squeeze=False, layout="constrained")
    for ax in axes.ravel():
        ax.axis("off")
    for ax, img, title in zip(axes.ravel(), images, titles):
        ax.imshow(img)
        ax.set_title(title, fontsize=8)
    fig.colorbar(ScalarMappable(Normalize(*clim), cmap), ax=axes, shrink=0.7, label=label)
    if suptitle:
        fig.suptitle(suptitle, fontsize=9)
    return fig
