"""Every registered figure is legible as saved (issue 26, item 5).

Each figure is drawn once, at the size and dpi :func:`repro.io.save_figure` writes it
(``repro run``: 120 dpi, the whole canvas, no ``bbox_inches``), and every text artist that
is actually drawn (tick labels, titles, legends, colour-bar labels, annotations) is checked:
its font is at least 8 pt at the saved size, and its window extent lies inside the canvas
(not cut at the edge).
"""

from __future__ import annotations

import inspect

import pytest

import repro.experiments as experiments
from repro.errors import RenderUnavailableError

#: The smallest legible font at the saved size (about 8 pt at 100 % on a laptop screen).
MIN_POINTS = 8.0
#: repro.io.save_figure's default dpi (checked in test_saved_dpi_is_the_one_drawn).
SAVE_DPI = 120
#: Slack for rounding of the renderer's extents, in pixels.
EDGE_SLACK = 0.5


def _drawn_texts(fig, monkeypatch, dpi):
    """The text artists drawn when ``fig`` is rendered at ``dpi``, and the renderer."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.text import Text

    drawn = []
    original = Text.draw

    def recording_draw(self, renderer):
        if self.get_visible() and self.get_text().strip():
            drawn.append(self)
        return original(self, renderer)

    monkeypatch.setattr(Text, "draw", recording_draw)
    FigureCanvasAgg(fig)
    fig.set_dpi(dpi)
    fig.canvas.draw()
    monkeypatch.undo()
    return drawn, fig.canvas.get_renderer()


@pytest.fixture(scope="module")
def drawn(quick_figures):
    """name -> list of (text, font size in pt, window extent, canvas size) as saved."""
    import matplotlib.pyplot as plt

    out = {}
    mp = pytest.MonkeyPatch()
    for name in experiments.registry():
        result = quick_figures(name)
        if result.draw is None:
            continue
        try:
            fig = result.draw()
        except RenderUnavailableError:
            continue
        try:
            texts, renderer = _drawn_texts(fig, mp, SAVE_DPI)
            w, h = fig.bbox.width, fig.bbox.height
            out[name] = [(t.get_text(), t.get_fontsize(), t.get_window_extent(renderer), (w, h)) for t in texts]
        finally:
            plt.close(fig)
    mp.undo()
    return out


def test_saved_dpi_is_the_one_drawn():
    from repro.io import save_figure

    src = inspect.getsource(save_figure)
    assert f'kw.setdefault("dpi", {SAVE_DPI})' in src
    assert "bbox_inches" not in src  # the whole canvas is saved: clipping is against the canvas


def test_every_figure_was_drawn(drawn):
    assert set(drawn) <= set(experiments.registry())
    assert drawn, "no figure could be drawn"
    for name, texts in drawn.items():
        assert texts, f"{name}: no text drawn"


@pytest.mark.parametrize("name", sorted(experiments.registry()))
def test_text_at_least_8_pt(drawn, name):
    if name not in drawn:
        pytest.skip(f"{name} not drawn here (no drawing, or no OpenGL)")
    small = [(s, round(size, 1)) for s, size, _, _ in drawn[name] if size < MIN_POINTS]
    assert not small, f"{name}: text under {MIN_POINTS} pt: {small[:10]}"


@pytest.mark.parametrize("name", sorted(experiments.registry()))
def test_no_text_cut_at_the_edge(drawn, name):
    if name not in drawn:
        pytest.skip(f"{name} not drawn here (no drawing, or no OpenGL)")
    cut = []
    for s, _, bb, (w, h) in drawn[name]:
        if bb.x0 < -EDGE_SLACK or bb.y0 < -EDGE_SLACK or bb.x1 > w + EDGE_SLACK or bb.y1 > h + EDGE_SLACK:
            cut.append((s, tuple(round(v) for v in (bb.x0, bb.y0, bb.x1, bb.y1)), (round(w), round(h))))
    assert not cut, f"{name}: text cut at the canvas edge: {cut[:10]}"

