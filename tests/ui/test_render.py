"""Headless rendering: the subprocess probe, and a real off-screen render where GL exists."""

import subprocess
import sys

import pytest

from repro.ui import render
from repro.errors import RenderUnavailableError


@pytest.mark.render
def test_offscreen_render_in_a_subprocess_gives_a_real_image():
    code = (
        "import pyvista as pv, numpy as np\n"
        "pl = pv.Plotter(off_screen=True, window_size=(120, 90))\n"
        "pl.add_mesh(pv.Sphere(), scalars=np.linspace(0, 1, pv.Sphere().n_points))\n"
        "img = pl.screenshot(return_img=True)\n"
        "print(img.shape, float(img.std()), len(np.unique(img.reshape(-1, img.shape[-1]), axis=0)))\n"
    )
    render.configure_headless()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    shape, std, colours = p.stdout.strip().rsplit(" ", 2)
    assert shape.startswith("(90, 120") and float(std) > 5 and int(colours) > 50


def test_probe_failure_becomes_a_reason_and_an_error(monkeypatch):
    """A VTK that segfaults (no GL) must give a readable reason, never take pytest down."""
    monkeypatch.setattr(render, "_PROBE", "import os, sys\nsys.stderr.write('WARN| Failed to load EGL\\n')\nos.abort()\n")
    render.render_unavailable_reason.cache_clear()
    try:
        reason = render.render_unavailable_reason()
        assert reason and "Failed to load EGL" in reason and "libosmesa6" in reason
        with pytest.raises(RenderUnavailableError, match="unavailable"):
            render.require_render()
    finally:
        render.render_unavailable_reason.cache_clear()


@pytest.mark.render
@pytest.mark.slow
def test_rejected_alternatives_legend_is_legible_at_100_percent():
    """``ra.draw()`` (notebook 01): a 14-inch figure, so its text must be large to read in a notebook column."""
    import repro.experiments as E

    ra = E.get("rejected_alternatives").func(quick=True)
    fig = ra.draw()
    legends = [lg for sub in fig.subfigs for lg in sub.legends] + [ax.get_legend() for ax in fig.axes
                                                                   if ax.get_legend() is not None]
    assert legends, "the methods need a legend"
    sizes = [t.get_fontsize() for lg in legends for t in lg.get_texts()]
    assert min(sizes) >= 10, sizes
    assert min(ax.title.get_fontsize() for ax in fig.axes if ax.get_title()) >= 9
