"""Interactive panels (ipywidgets) for the papers reproduced in :mod:`repro`.

Lewis et al. 2005, Section 5: "In addition to the usual slider interface, there
would be controls to invoke motion attenuation, select vertices, and adjust the
value of alpha.  Until motion attenuation is turned off, weights would be
automatically transformed as the sliders move."  :class:`BlendshapePanel` is
that interface:

- one ``FloatSlider`` (0..1, step 0.01) per blendshape slider (the paper's
  ``Furrow``, ``SmirkLeft/Right``, ``Wince``, ``SneerLeft/Right``, plus
  ``JawOpen``, ``Blink``, ``BrowUp``, ``MouthStretch`` by default);
- a selection: a ``Dropdown`` of the model's preset regions and x/y/z
  ``Checkbox`` es (``select_vertices(region, axes)``), and a "select now"
  button;
- alpha on a log slider (``FloatLogSlider``, 1e-3..1e6) with a "default"
  checkbox that keeps it at Section 5's default for the current selection
  (``#unselected / #selected`` coordinates);
- an attenuation ``ToggleButton``;
- a live view (matplotlib by default, or one persistent off-screen pyvista
  plotter) coloured by per-vertex motion since the selection, the selected
  vertices in cyan;
- a line of numbers in stable, parseable text (:data:`NUMBERS_FORMAT`), e.g.
  ``selected motion: 0.0837041 | unselected fidelity: 0.546925 | alpha: 335 | attenuation: on``.

The select-now workflow
-----------------------
Switching attenuation on (or pressing "select now") takes the current slider
weights as ``w_base``, the pose to keep.  While attenuation is on, the face
shows ``Attenuator.edit(w_base, w_sliders, selected, alpha)`` =
``w_base + M (w_sliders - w_base)`` with ``M = (P + alpha Q)^-1 P`` (Eq. 3);
changing the region, axes or alpha re-solves from the same ``w_base``.
Switching attenuation off makes the sliders act directly again (the face
shows ``w_sliders``); ``w_base`` stays as the reference of the numbers, so
toggling shows the same session with and without attenuation.

The numbers are those of :func:`repro.blendshapes.scenarios.evaluate`:
``selected motion`` = ``||S (D w - D w_base)||`` and ``unselected fidelity``
= ``1 - ||Sbar (D w - D w_sliders)|| / ||Sbar (D w_sliders - D w_base)||``
(``nan`` while the sliders have not moved since the selection).

Every solve goes through one :class:`~repro.blendshapes.Attenuator` built with
the panel (``D^T D`` once; ``M`` cached per selection and alpha), so a slider
move costs an m x m mat-vec and ``D @ w``.  Bad input typed into the panel
(``alpha <= 0`` or NaN, no axis ticked, a NaN slider value) is shown as an
error in the panel; no widget callback raises.
"""

from __future__ import annotations

import html
import io
import math
import re
import time
from collections.abc import Iterable, Mapping

import ipywidgets as widgets
import numpy as np

from repro.ui.panel import PanelCallbacks
from repro.blendshapes import Attenuator, load_model, metrics, select_vertices
from repro.blendshapes.model import AXES, BlendshapeModel
from repro.errors import AttenuationError, ModelError, SelectionError

__all__ = [
    "BlendshapePanel",
    "blendshape_panel",
    "PAPER_SLIDERS",
    "NUMBERS_FORMAT",
    "parse_numbers",
]

#: The sliders the paper names (Figs. 2-5), and those its scenarios need.
PAPER_SLIDERS = (
    "Furrow", "SmirkLeft", "SmirkRight", "Wince", "SneerLeft", "SneerRight",
    "JawOpen", "Blink", "BrowUp", "MouthStretch",
)

#: The text of the panel's numbers line (plain text; :func:`parse_numbers` reads it back).
NUMBERS_FORMAT = (
    "selected motion: {selected_motion:.6g} | unselected fidelity: {unselected_fidelity:.6g} "
    "| alpha: {alpha:.6g} | attenuation: {attenuation}"
)

#: Exponents (base 10) of the alpha slider's range.
ALPHA_EXPONENTS = (-3.0, 6.0)

VIEWS = ("matplotlib", "pyvista", "3d", "auto", "none")

_NUMBER_FIELDS = {
    "selected motion": "selected_motion",
    "unselected fidelity": "unselected_fidelity",
    "alpha": "alpha",
    "attenuation": "attenuation",
}


def parse_numbers(text: str) -> dict:
    """The panel's numbers line (:data:`NUMBERS_FORMAT`) as a dict of floats (and ``attenuation``).

    ``parse_numbers("selected motion: 0.0837 | unselected fidelity: 0.547 | alpha: 335 | attenuation: on")``
    gives ``{"selected_motion": 0.0837, "unselected_fidelity": 0.547, "alpha": 335.0, "attenuation": "on"}``.
    Raises ``ValueError`` for anything else (e.g. an ``error: ...`` line).
    """
    out = {}
    for part in text.strip().split(" | "):
        m = re.fullmatch(r"([a-z ]+): (\S+)", part.strip())
        if not m or m.group(1) not in _NUMBER_FIELDS:
            raise ValueError(f"not a numbers line of the panel: {text!r}")
        key = _NUMBER_FIELDS[m.group(1)]
        out[key] = m.group(2) if key == "attenuation" else float(m.group(2))
    if set(out) != set(_NUMBER_FIELDS.values()):
        raise ValueError(f"not a numbers line of the panel: {text!r}")
    return out


# ----------------------------------------------------------------------- views
class _MatplotlibView:
    """Front view (x, y) of the posed face: flat-shaded triangles coloured by motion, drawn with Agg.

    One figure per panel, updated in place (vertices and colours of one
    PolyCollection, offsets of one scatter); the picture is the figure's background
    (drawn once) with the triangles rasterised over it by :func:`repro.ui.raster.rasterize`
    and written to PNG; deterministic.
    """

    def __init__(self, model: BlendshapeModel, clim, cmap: str, size):
        import matplotlib as mpl
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.cm import ScalarMappable
        from matplotlib.collections import PolyCollection
        from matplotlib.figure import Figure

        self.model = model
        self.cmap = mpl.colormaps[cmap]
        self.norm = mpl.colors.Normalize(*clim)
        # painter's order: far triangles (small z, the face looks toward +z) first
        depth = model.f0[model.faces].mean(axis=1)[:, 2]
        self.faces = model.faces[np.argsort(depth, kind="stable")]
        light = np.array([0.3, 0.4, 1.0])
        self.light = light / np.linalg.norm(light)
        w, h = size
        dpi = 100
        self.fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi)
        FigureCanvasAgg(self.fig)
        self.ax = self.fig.add_axes((0.0, 0.13, 1.0, 0.87))
        self.ax.set_aspect("equal")
        self.ax.axis("off")
        lo, hi = model.f0.min(axis=0), model.f0.max(axis=0)
        pad = 0.06 * (hi - lo)
        self.ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
        self.ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
        self.poly = PolyCollection(np.zeros((len(self.faces), 3, 2)), antialiaseds=False, linewidths=0.3)
        self.ax.add_collection(self.poly)
        self.markers = self.ax.scatter([], [], s=22, c="cyan", edgecolors="k", linewidths=0.6, zorder=3)
        cax = self.fig.add_axes((0.15, 0.045, 0.7, 0.022))
        cb = self.fig.colorbar(ScalarMappable(self.norm, self.cmap), cax=cax, orientation="horizontal")
        cb.ax.tick_params(labelsize=7)
        cb.ax.xaxis.set_label_position("top")
        cb.set_label(f"motion since the selection ({model.units}); cyan: selected", fontsize=7)
        self._bg = None  # the figure without the face, drawn on the first render

    def _background(self):
        """The figure without the face (axes, colour bar, label) as RGB, drawn once; and data -> pixel."""
        if self._bg is None:
            self.poly.set_visible(False)
            self.markers.set_visible(False)
            self.fig.canvas.draw()
            self._bg = np.asarray(self.fig.canvas.buffer_rgba())[:, :, :3].copy()
            self.poly.set_visible(True)
            self.markers.set_visible(True)
            self._to_pixels = self.ax.transData.get_affine().get_matrix().copy()
        return self._bg

    def render(self, points: np.ndarray, motion: np.ndarray, selected_vertices) -> bytes:
        """The posed face as PNG bytes: the triangles rasterised (numpy) over the cached figure background.

        Same colours as an Agg drawing of the figure's PolyCollection (:meth:`sync_figure`
        puts the last pose into it, e.g. for ``fig.savefig``), about ten times faster on
        the ICT face (``set_verts`` alone builds one Path per triangle: 0.2 s).
        """
        from repro.ui.raster import png_bytes, rasterize, stamp_discs

        T = points[self.faces]
        # smooth (vertex-normal) Lambert shading, averaged over each triangle
        fn = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
        idx = self.faces.ravel()
        vn = np.column_stack([np.bincount(idx, np.repeat(fn[:, k], 3), minlength=len(points)) for k in range(3)])
        vn /= np.linalg.norm(vn, axis=1, keepdims=True) + 1e-300
        shade = (0.35 + 0.65 * np.abs(vn @ self.light))[self.faces].mean(axis=1)
        colours = self.cmap(self.norm(motion[self.faces].mean(axis=1)))
        colours[:, :3] *= shade[:, None]
        sel = np.asarray(selected_vertices if selected_vertices is not None else [], dtype=np.int64)
        self._last = (T[:, :, :2], colours, points[sel, :2] if sel.size else np.zeros((0, 2)))
        bg = self._background()
        H = bg.shape[0]
        M = self._to_pixels
        xy = points[:, :2] @ M[:2, :2].T + M[:2, 2]
        xy[:, 1] = H - xy[:, 1]  # image rows run down
        img = bg.copy()
        rgb = np.clip(np.rint(colours[:, :3] * 255), 0, 255).astype(np.uint8)
        # painter's order as the PolyCollection draws it: later triangles (nearer) on top
        rasterize(xy, self.faces, rgb, np.arange(len(self.faces), dtype=float), img)
        if sel.size:
            stamp_discs(img, xy[sel], 3.25, (0, 255, 255), edge=(0, 0, 0), edge_width=0.85)
        return png_bytes(img)

    def sync_figure(self):
        """Put the last rendered pose into the figure's artists (the live view does not need them); the figure."""
        if getattr(self, "_last", None) is not None:
            verts, colours, marks = self._last
            self.poly.set_verts(verts)
            self.poly.set_facecolors(colours)
            self.poly.set_edgecolors(colours)
            self.markers.set_offsets(marks)
        return self.fig

    def close(self) -> None:
        self.fig.clear()


class _PyvistaView:
    """The same view through ONE persistent off-screen pyvista plotter (points and scalars updated in place)."""

    def __init__(self, model: BlendshapeModel, clim, cmap: str, size):
        from repro.ui.render import require_render

        require_render()
        import pyvista as pv

        pv.vtk_verbosity("error")
        self.pv = pv
        self.model = model
        faces = np.column_stack([np.full(len(model.faces), 3), model.faces]).ravel()
        self.mesh = pv.PolyData(model.f0.copy(), faces)
        self.mesh.point_data["motion"] = np.zeros(model.n_vertices)
        self.markers = pv.PolyData(model.f0[:1].copy())
        self.pl = pv.Plotter(off_screen=True, window_size=list(size))
        self.pl.set_background("white")
        self.pl.add_mesh(self.mesh, scalars="motion", cmap=cmap, clim=list(clim), smooth_shading=True,
                         specular=0.2, scalar_bar_args={"title": f"motion since the selection ({model.units})",
                                                        "title_font_size": 12, "label_font_size": 10,
                                                        "color": "black", "n_labels": 3, "fmt": "%.2g"})
        self.marker_actor = self.pl.add_mesh(self.markers, color="cyan", point_size=9.0,
                                             render_points_as_spheres=True)
        self.pl.view_xy()
        self.pl.camera.zoom(1.1)

    def render(self, points: np.ndarray, motion: np.ndarray, selected_vertices) -> bytes:
        from PIL import Image

        self.mesh.points = points
        self.mesh.point_data["motion"] = motion
        sel = np.asarray(selected_vertices if selected_vertices is not None else [], dtype=np.int64)
        self.marker_actor.SetVisibility(bool(sel.size))
        if sel.size:
            self.markers.copy_from(self.pv.PolyData(points[sel].copy()), deep=True)
        self.pl.render()  # pyvista only renders a screenshot once otherwise
        img = self.pl.screenshot(return_img=True)
        buf = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(img)).save(buf, format="png")
        return buf.getvalue()

    def close(self) -> None:
        self.pl.close()


# ----------------------------------------------------------------------- panel
class BlendshapePanel(PanelCallbacks):
    """Sliders, selection, alpha and attenuation for a blendshape model (Lewis et al. 2005, Section 5).

    Parameters
    ----------
    model : "procedural", "ict" or BlendshapeModel
    sliders : sequence of str, "all", or None
        Slider names (shapes or named combinations of the model).  None: the
        paper's sliders (:data:`PAPER_SLIDERS`) the model has; "all": every
        name the model accepts.
    view : "matplotlib" (default), "pyvista", "3d", "auto" or "none"
        "3d": drawn in the browser (:class:`repro.ui.webview.MeshWebView`; rotate, zoom;
        the kernel sends only the vertex positions and motion per move, no picture).
        "auto" uses pyvista when off-screen rendering works here
        (:func:`repro.ui.render.render_unavailable_reason`), else matplotlib.
    region : str, optional
        Preset region selected at start (default: the model's first region).
    axes : str
        Axes of the region's vertices selected at start ("xyz", "y", ...).
    alpha : float, optional
        Starting alpha; None (default) follows Section 5's default for the selection.
    attenuation : bool
        Start with attenuation on (``w_base`` = the starting sliders).
    values : mapping of slider name to value, optional
        Starting slider values (set before attenuation is switched on).
    clim : (lo, hi)
        Colour range of the view (motion since the selection, model units).
    continuous_update : bool
        Update while a blendshape slider is dragged (True), or on release.
        The alpha slider always updates on release (each new alpha is a new
        solve, and a continuously updating ``FloatLogSlider`` would send back
        its step-snapped value as soon as the browser draws it).
    alpha_on_top : bool
        Put the alpha slider and the numbers line above the sliders.
    defer_view : bool
        In a running kernel, draw the view once the widget messages already queued
        are handled (quick slider moves: the numbers follow every value, the picture
        skips to the last one).  Outside a kernel (or False) every update draws at
        once.  :meth:`image_png` always returns the current picture.

    Attributes
    ----------
    widget : ipywidgets.VBox
        The panel; displaying the :class:`BlendshapePanel` displays it.
    sliders : dict of str to FloatSlider
    region, axis_boxes, select_button, alpha_slider, default_alpha, attenuation, view_image, numbers_html, status_html
        The individual widgets.
    attenuator : Attenuator
        The one cached solver of the panel.
    last_update_seconds : dict
        Wall time of the last update: ``"numbers"`` (weights, Eq. 3 and the
        metrics) and ``"view"`` (drawing).
    """

    def __init__(
        self,
        model="procedural",
        sliders=None,
        view: str = "matplotlib",
        *,
        region: str | None = None,
        axes: str = "xyz",
        alpha: float | None = None,
        attenuation: bool = False,
        values: Mapping[str, float] | None = None,
        clim=(0.0, 1.0),
        cmap: str = "YlOrRd",
        image_size=(360, 420),
        continuous_update: bool = True,
        alpha_on_top: bool = False,
        defer_view: bool = True,
    ):
        if isinstance(model, str):
            model = load_model(model)
        if not isinstance(model, BlendshapeModel):
            raise ModelError(f"model must be a model name or a BlendshapeModel, got {type(model).__name__}")
        if view not in VIEWS:
            raise ValueError(f"view must be one of {VIEWS}, got {view!r}")
        if not model.regions:
            raise ModelError(f"model {model.name!r} has no preset regions to select from")
        self.model = model
        self.attenuator = Attenuator(model)
        self.slider_names = self._slider_names(model, sliders)
        # weights = C @ slider values: one column per slider (named combinations resolved once)
        self._C = np.column_stack([model.weights({s: 1.0}) for s in self.slider_names])
        self._regions = dict(model.regions)
        self._batch_depth = 0
        self._pending = False
        self._internal = False  # set while the panel itself moves a widget
        self.error: str | None = None
        self._numbers: dict = {}
        self._numbers_text = ""
        self.last_update_seconds = {"numbers": float("nan"), "view": float("nan")}
        self.defer_view = bool(defer_view)
        self._view_state = None
        self._render_scheduled = False

        first = region if region is not None else next(iter(self._regions))
        if first not in self._regions:
            raise ModelError(f"unknown region {first!r} of model {model.name!r}; known: {list(self._regions)}")
        axes = self._axes_arg(axes)

        # view
        if view == "auto":
            from repro.ui.render import render_unavailable_reason

            view = "pyvista" if render_unavailable_reason() is None else "matplotlib"
        self.view_kind = view
        self._view = None
        if view == "matplotlib":
            self._view = _MatplotlibView(model, clim, cmap, image_size)
        elif view == "pyvista":
            self._view = _PyvistaView(model, clim, cmap, image_size)
        elif view == "3d":
            from repro.ui.webview import MeshWebView

            self._view = MeshWebView(model, clim, cmap, image_size)
        self._picture_args = (clim, cmap, image_size)
        self._picture_view = None  # a matplotlib view for image_png() when the live view is drawn in the browser

        # widgets
        style = {"description_width": "110px"}
        self.sliders = {
            name: widgets.FloatSlider(value=0.0, min=0.0, max=1.0, step=0.01, description=name,
                                      continuous_update=continuous_update, readout_format=".2f", style=style,
                                      layout=widgets.Layout(width="340px"))
            for name in self.slider_names
        }
        self.region = widgets.Dropdown(options=list(self._regions), value=first, description="region",
                                       layout=widgets.Layout(width="260px"), style={"description_width": "50px"})
        self.axis_boxes = {a: widgets.Checkbox(value=a in axes, description=a, indent=False,
                                               layout=widgets.Layout(width="44px"))
                           for a in AXES}
        self.select_button = widgets.Button(description="select now", icon="crosshairs",
                                            tooltip="make the current slider pose the pose to keep (w_base)")
        self.alpha_slider = widgets.FloatLogSlider(value=1.0, base=10, min=ALPHA_EXPONENTS[0], max=ALPHA_EXPONENTS[1],
                                                   step=0.01, description="alpha", readout_format=".4g",
                                                   # on release only: with continuous updates the browser's
                                                   # slider sends back its step-snapped value as soon as it is
                                                   # drawn (335 -> 10**2.53 = 338.8), moving alpha by itself
                                                   continuous_update=False,
                                                   layout=widgets.Layout(width="560px"),
                                                   style={"description_width": "50px"})
        self.alpha_slider.add_class("repro-alpha")
        self.default_alpha = widgets.Checkbox(value=alpha is None, description="default alpha (Section 5)",
                                              indent=False)
        self.attenuation = widgets.ToggleButton(value=False, description="attenuation", icon="anchor",
                                                tooltip="attenuate the motion of the selected coordinates (Eq. 3)")
        self.attenuation.add_class("repro-attenuation")
        self.reset_button = widgets.Button(description="reset", tooltip="all sliders to 0, attenuation off")
        self.view_image = widgets.Image(format="png", layout=widgets.Layout(
            width=f"{image_size[0]}px", height=f"{image_size[1]}px",
            display="none" if self._view is None or view == "3d" else None))
        self.numbers_html = widgets.HTML()
        self.numbers_html.add_class("repro-numbers")
        self.status_html = widgets.HTML()
        self.status_html.add_class("repro-status")

        # state
        self._alpha = 1.0
        self._sel = None
        self._sel_vertices = None
        self._sel_error: str | None = None
        self._w_base = np.zeros(model.n_shapes)
        self._d_base = np.zeros(3 * model.n_vertices)
        self._weights = np.zeros(model.n_shapes)

        for name, s in self.sliders.items():
            s.observe(self._guarded(self._on_slider), names="value")
        self.region.observe(self._guarded(self._on_selection), names="value")
        for box in self.axis_boxes.values():
            box.observe(self._guarded(self._on_selection), names="value")
        self.select_button.on_click(self._guarded(lambda _b: self.select_now()))
        self.reset_button.on_click(self._guarded(lambda _b: self.reset()))
        self.alpha_slider.observe(self._guarded(self._on_alpha), names="value")
        self.default_alpha.observe(self._guarded(self._on_default), names="value")
        self.attenuation.observe(self._guarded(self._on_attenuation), names="value")

        header = widgets.HTML(
            f"<b>{html.escape(model.name)}</b>: {model.n_vertices:,} vertices, {model.n_shapes} shapes "
            f"({html.escape(model.units)})")
        left = widgets.VBox([header, *self.sliders.values()])
        right = widgets.VBox([self._view.widget if view == "3d" else self.view_image])
        alpha_row = widgets.HBox([self.alpha_slider, self.default_alpha])
        rows = [
            widgets.HBox([left, right]),
            widgets.HBox([self.region, *self.axis_boxes.values(), self.select_button]),
            alpha_row,
            widgets.HBox([self.attenuation, self.reset_button]),
            self.numbers_html,
            self.status_html,
        ]
        if alpha_on_top:  # alpha and its numbers first (the Fig. 5 notebook)
            rows = [alpha_row, self.numbers_html] + [r for r in rows if r not in (alpha_row, self.numbers_html)]
        self.widget = widgets.VBox(rows)
        self.widget.add_class("repro-blendshape-panel")

        with self._batch():
            self._refresh_selection()
            if alpha is not None:
                self.set_alpha(alpha)
            if values:
                self.set_sliders(values)
            if attenuation:
                self.set_attenuation(True)
            self._request_update()

    # ------------------------------------------------------------- helpers
    @staticmethod
    def _slider_names(model: BlendshapeModel, sliders) -> tuple[str, ...]:
        if sliders is None:
            names = tuple(s for s in PAPER_SLIDERS if s in model.slider_names)
            return names or model.names
        if isinstance(sliders, str):
            if sliders != "all":
                raise ModelError(f"sliders must be a list of names, None or 'all', got {sliders!r}")
            return model.slider_names
        names = tuple(str(s) for s in sliders)
        unknown = [s for s in names if s not in model.slider_names]
        if unknown:
            raise ModelError(f"unknown sliders {unknown} for model {model.name!r}; known: {list(model.slider_names)}")
        if not names or len(set(names)) != len(names):
            raise ModelError(f"sliders must be distinct names, at least one, got {list(names)}")
        return names

    @staticmethod
    def _axes_arg(axes) -> str:
        if isinstance(axes, str):
            axes = list(axes)
        axes = [str(a).strip().lower() for a in axes]
        bad = [a for a in axes if a not in AXES]
        if bad:
            raise SelectionError(f"unknown axes {bad}; expected some of 'x', 'y', 'z'")
        return "".join(a for a in AXES if a in axes)

    def _flush(self) -> None:
        if self._pending:
            self._pending = False
            self._update()

    def _request_update(self) -> None:
        if self._batch_depth:
            self._pending = True
        else:
            self._update()

    def _set_widget(self, widget, value) -> None:
        """Move a widget without its callback treating it as a user action."""
        old = self._internal
        self._internal = True
        try:
            widget.value = value
        finally:
            self._internal = old

    # ------------------------------------------------------------ callbacks
    def _on_slider(self, change) -> None:
        self._request_update()

    def _on_selection(self, change) -> None:
        self._refresh_selection()
        self._request_update()

    def _on_alpha(self, change) -> None:
        if self._internal:
            return
        a = change["new"]
        if self._valid_alpha(a) and math.isclose(float(a), self._alpha, rel_tol=1e-9):
            return  # the value we set, echoed back (rounded) by the browser: keep the exact alpha
        if not self._valid_alpha(a):
            self._set_widget(self.alpha_slider, self._alpha)
            raise AttenuationError(f"alpha must be a finite number > 0 (Eq. 2), got {a!r}; kept alpha = {self._alpha:.6g}")
        self._alpha = float(a)
        if self.default_alpha.value:
            self._set_widget(self.default_alpha, False)
        self._request_update()

    def _on_default(self, change) -> None:
        if self._internal:
            return
        if change["new"]:
            self._apply_default_alpha()
        self._request_update()

    def _on_attenuation(self, change) -> None:
        if self._internal:
            return
        if change["new"]:
            self._take_base()
        self._request_update()

    # ------------------------------------------------------------- selection
    def _refresh_selection(self) -> None:
        """Rows of D for the chosen region and axes (or the reason there are none)."""
        axes = "".join(a for a in AXES if self.axis_boxes[a].value)
        self._sel = self._sel_vertices = None
        self._sel_error = None
        if not axes:
            self._sel_error = "no axis selected: tick at least one of x, y, z"
            return
        try:
            verts = np.asarray(self._regions[self.region.value], dtype=np.int64)
            sel = select_vertices(verts, axes, self.model.n_vertices)
            self.attenuator.default_alpha(sel)  # refuses a selection of every coordinate
        except (SelectionError, AttenuationError, ModelError) as exc:
            self._sel_error = str(exc)
            return
        self._sel, self._sel_vertices = sel, np.unique(verts)
        if self.default_alpha.value:
            self._apply_default_alpha()

    def _apply_default_alpha(self) -> None:
        if self._sel is None:
            return
        a = self.attenuator.default_alpha(self._sel)
        self._ensure_alpha_range(a)
        self._alpha = a
        self._set_widget(self.alpha_slider, a)

    def _ensure_alpha_range(self, a: float) -> None:
        e = math.log10(a)
        lo, hi = self.alpha_slider.min, self.alpha_slider.max
        if e < lo or e > hi:
            self.alpha_slider.min = min(lo, math.floor(e))
            self.alpha_slider.max = max(hi, math.ceil(e))

    @staticmethod
    def _valid_alpha(a) -> bool:
        try:
            a = float(a)
        except (TypeError, ValueError):
            return False
        return math.isfinite(a) and a > 0

    def _take_base(self) -> None:
        self._w_base = self._C @ self.slider_values_array()
        self._d_base = self.attenuator.displacement(self._w_base)

    # ---------------------------------------------------------------- update
    def slider_values_array(self) -> np.ndarray:
        """Current slider values, in :attr:`slider_names` order."""
        return np.array([self.sliders[s].value for s in self.slider_names], dtype=np.float64)

    def _compute(self):
        s = self.slider_values_array()
        if not np.isfinite(s).all():
            bad = [n for n, v in zip(self.slider_names, s) if not np.isfinite(v)]
            raise ModelError(f"slider values must be finite numbers; sliders {bad} are not")
        w_target = self._C @ s
        on = bool(self.attenuation.value)
        if self._sel is None:
            return w_target, None, self._sel_error
        w = self.attenuator.edit(self._w_base, w_target, self._sel, self._alpha) if on else w_target
        d = self.attenuator.displacement(w)
        d_target = self.attenuator.displacement(w_target) if on else d
        numbers = {
            "selected_motion": metrics.selected_motion(d, self._sel, self._d_base),
            "unselected_fidelity": _nan_quiet(metrics.unselected_fidelity, d, d_target, self._sel, self._d_base),
            "alpha": float(self._alpha),
            "attenuation": "on" if on else "off",
        }
        return w, (d, numbers), None

    def _update(self) -> None:
        t0 = time.perf_counter()
        try:
            w, result, sel_error = self._compute()
        except Exception as exc:  # noqa: BLE001
            self._show_error(exc)
            return
        self._weights = w
        if result is None:
            d = self.attenuator.displacement(w)
            self.error = sel_error
            self._numbers = {}
            self._numbers_text = f"error: {sel_error}"
        else:
            d, numbers = result
            self.error = None
            self._numbers = numbers
            self._numbers_text = NUMBERS_FORMAT.format(**numbers)
        t1 = time.perf_counter()
        self.last_update_seconds["numbers"] = t1 - t0
        self.numbers_html.value = f"<code>{html.escape(self._numbers_text)}</code>"
        self.status_html.value = self._status()
        if self._view is None:
            self.last_update_seconds["view"] = time.perf_counter() - t1
            return
        self._view_state = (d, self._d_base, self._sel_vertices)
        loop = _kernel_loop() if self.defer_view else None
        if loop is None:
            self._render_view()
        elif not self._render_scheduled:
            # in a kernel: draw once the messages already queued (e.g. quick key presses) are handled,
            # so intermediate slider values are skipped and the last one is always the one drawn
            self._render_scheduled = True
            loop.call_soon(self._guarded(self._render_scheduled_view))

    def _render_scheduled_view(self) -> None:
        if self._render_scheduled:
            self._render_view()

    def _render_view(self) -> None:
        """Draw the state of the last update into the view (and the image widget)."""
        self._render_scheduled = False
        if self._view is None or self._view_state is None:
            return
        t = time.perf_counter()
        d, d_base, sel_vertices = self._view_state
        motion = np.linalg.norm((d - d_base).reshape(-1, 3), axis=1)
        points = self.model.f0 + d.reshape(-1, 3)
        if self.view_kind == "3d":
            self._view.render(points, motion, sel_vertices)  # sent to the page, which draws it
        else:
            self.view_image.value = self._view.render(points, motion, sel_vertices)
        self.last_update_seconds["view"] = time.perf_counter() - t

    def _status(self) -> str:
        if self.error:
            return f'<span style="color:#b00020">error: {html.escape(self.error)}</span>'
        nv, nc = len(self._sel_vertices), len(self._sel)
        base = "neutral" if not np.any(self._w_base) else ", ".join(
            f"{n} {v:g}" for n, v in zip(self.model.names, self._w_base) if v)
        return html.escape(
            f"selection: {self.region.value} ({self.selected_axes}), {nv} vertices, {nc} coordinates; "
            f"default alpha {self.attenuator.default_alpha(self._sel):.6g}; w_base: {base}")

    def _show_error(self, exc: BaseException) -> None:
        msg = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
        self.error = msg
        self._numbers = {}
        self._numbers_text = f"error: {msg}"
        self.numbers_html.value = f"<code>{html.escape(self._numbers_text)}</code>"
        self.status_html.value = f'<span style="color:#b00020">error: {html.escape(msg)}</span>'

    # ------------------------------------------------------------ public API
    @property
    def numbers(self) -> dict:
        """The displayed numbers at full precision: ``selected_motion``, ``unselected_fidelity``, ``alpha``, ``attenuation`` ({} on error)."""
        return dict(self._numbers)

    @property
    def numbers_text(self) -> str:
        """The numbers line as displayed (:data:`NUMBERS_FORMAT`), or ``"error: ..."``."""
        return self._numbers_text

    @property
    def alpha(self) -> float:
        """The alpha in use."""
        return self._alpha

    @property
    def weights(self) -> np.ndarray:
        """The weights of the displayed face (attenuated when attenuation is on)."""
        return self._weights.copy()

    @property
    def slider_weights(self) -> np.ndarray:
        """The weights the sliders ask for (``w_sliders``)."""
        return self._C @ self.slider_values_array()

    @property
    def w_base(self) -> np.ndarray:
        """The pose kept (weights taken by "select now" or by switching attenuation on)."""
        return self._w_base.copy()

    @property
    def selection(self) -> np.ndarray | None:
        """Selected rows of D (row ``3*v + axis``), or None when the selection is unusable."""
        return None if self._sel is None else self._sel.copy()

    @property
    def selected_vertices(self) -> np.ndarray | None:
        return None if self._sel_vertices is None else self._sel_vertices.copy()

    @property
    def selected_axes(self) -> str:
        return "".join(a for a in AXES if self.axis_boxes[a].value)

    def set_sliders(self, values: Mapping[str, float] | None = None, **kw: float) -> None:
        """Set slider values by name (one update); names not on the panel raise ModelError."""
        items = dict(values or {})
        items.update(kw)
        unknown = [k for k in items if k not in self.sliders]
        if unknown:
            raise ModelError(f"no slider {unknown} on this panel; sliders: {list(self.slider_names)}")
        with self._batch():
            for k, v in items.items():
                self.sliders[k].value = v

    def set_selection(self, region: str | None = None, axes: str | Iterable[str] | None = None) -> None:
        """Choose a preset region and/or the selected axes (one update; "" = no axis, shown as an error)."""
        if region is not None and region not in self._regions:
            raise ModelError(f"unknown region {region!r}; known: {list(self._regions)}")
        with self._batch():
            if region is not None:
                self.region.value = region
            if axes is not None:
                axes = self._axes_arg(axes)
                for a in AXES:
                    self.axis_boxes[a].value = a in axes
            self._refresh_selection()
            self._request_update()

    def add_region(self, name: str, vertices, *, select: bool = True) -> None:
        """Add a vertex set to the region chooser (e.g. a scenario's selection) and select it."""
        v = np.unique(np.asarray(vertices, dtype=np.int64).ravel())
        if v.size == 0 or v.min() < 0 or v.max() >= self.model.n_vertices:
            raise SelectionError(f"region {name!r} must list vertex ids in 0..{self.model.n_vertices - 1}")
        self._regions[str(name)] = v
        with self._batch():
            self.region.options = list(self._regions)
            if select:
                self.set_selection(region=str(name))

    def set_alpha(self, alpha) -> bool:
        """Use ``alpha`` (unticks "default"); False, with an error shown in the panel, if it is not > 0."""
        if not self._valid_alpha(alpha):
            self._show_error(AttenuationError(
                f"alpha must be a finite number > 0 (Eq. 2), got {alpha!r}; kept alpha = {self._alpha:.6g}"))
            return False
        a = float(alpha)
        with self._batch():
            self._set_widget(self.default_alpha, False)
            self._ensure_alpha_range(a)
            self._alpha = a
            self._set_widget(self.alpha_slider, a)
            self._request_update()
        return True

    def use_default_alpha(self) -> None:
        """Tick "default": alpha = #unselected / #selected coordinates of the selection (Section 5)."""
        with self._batch():
            self.default_alpha.value = True
            self._apply_default_alpha()
            self._request_update()

    def set_attenuation(self, on: bool) -> None:
        """Switch attenuation on (taking the current sliders as ``w_base``) or off (sliders act directly)."""
        self.attenuation.value = bool(on)

    def select_now(self) -> None:
        """Take the current slider pose as ``w_base``, the pose to keep (Section 5's select step)."""
        with self._batch():
            self._refresh_selection()
            self._take_base()
            self._request_update()

    def reset(self) -> None:
        """All sliders to 0, attenuation off, ``w_base`` = neutral."""
        with self._batch():
            self._set_widget(self.attenuation, False)
            for s in self.sliders.values():
                s.value = 0.0
            self._take_base()
            self._request_update()

    def close(self) -> None:
        """Close the widgets and the view's figure or plotter."""
        for v in (self._view, self._picture_view):
            if v is not None:
                v.close()
        self._view = self._picture_view = None
        for w in [*self.sliders.values(), self.region, *self.axis_boxes.values(), self.select_button,
                  self.alpha_slider, self.default_alpha, self.attenuation, self.reset_button,
                  self.view_image, self.numbers_html, self.status_html, self.widget]:
            w.close()

    def image_png(self) -> bytes:
        """The current view as PNG bytes (empty without a view).

        With ``view="3d"`` (drawn in the browser), the front view drawn here by the
        matplotlib view, same colours.
        """
        if self._render_scheduled:
            self._render_view()
        if self.view_kind == "3d":
            if self._view_state is None:
                return b""
            if self._picture_view is None:
                self._picture_view = _MatplotlibView(self.model, *self._picture_args)
            d, d_base, sel_vertices = self._view_state
            motion = np.linalg.norm((d - d_base).reshape(-1, 3), axis=1)
            return self._picture_view.render(self.model.f0 + d.reshape(-1, 3), motion, sel_vertices)
        return bytes(self.view_image.value)

    @property
    def view_digest(self) -> str | None:
        """With ``view="3d"``: the digest of the last frame sent to the page (its canvas's ``data-drawn``)."""
        if self._render_scheduled:
            self._render_view()
        return getattr(self._view, "digest", None)

    def __repr__(self) -> str:
        return (f"BlendshapePanel({self.model.name!r}, {len(self.slider_names)} sliders, "
                f"view={self.view_kind!r})")

    def _repr_mimebundle_(self, **kwargs):
        bundle = self.widget._repr_mimebundle_(**kwargs)
        if isinstance(bundle, dict):
            bundle["text/plain"] = repr(self)
        return bundle


def _kernel_loop():
    """The running event loop of an IPython kernel we are called from, or None (plain Python, tests)."""
    import asyncio
    import sys

    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        return None
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    return loop if getattr(shell, "kernel", None) is not None else None


def _nan_quiet(func, *args):
    with np.errstate(invalid="ignore", divide="ignore"):
        return func(*args)


def blendshape_panel(model="procedural", sliders=None, view: str = "matplotlib", **kw) -> widgets.Widget:
    """The ipywidgets widget of a :class:`BlendshapePanel` (keep the panel itself to drive it from code)."""
    return BlendshapePanel(model, sliders, view, **kw).widget


# ------------------------------------------------------------------ drag mode
#: The drag line of :class:`DragPanel` (plain text).
DRAG_FORMAT = ("dragged error: {dragged_error:.6g} | pinned motion: {pinned_motion:.6g} | "
               "sliders moved: {n_sliders_moved} | solve: {method}")


class DragPanel(BlendshapePanel):
    """The blendshape panel with a drag mode: direct manipulation (Lewis and Anjyo 2010).

    Everything of :class:`BlendshapePanel`, plus a row to drag vertices: a
    ``Dropdown`` choosing the dragged region (any of the panel's regions; add a
    single vertex with :meth:`add_region`), x/y/z ``FloatSlider`` s moving its
    target (an offset from where the drag started, model units), a "drag"
    ``ToggleButton``, "pin the selection" (the panel's selection is held with
    the 2005 pin while dragging) and "weights in [0, 1]" (bounded solve).

    Switching drag on takes the displayed weights as the start; while it is on
    the face shows :meth:`~repro.blendshapes.manipulation.DirectManipulator.solve`
    from that start (the blendshape sliders are not followed), and the drag
    line (:data:`DRAG_FORMAT`) gives the dragged vertices' distance from their
    targets, the pinned region's largest motion and how many sliders moved.
    Choosing another drag region restarts from the displayed weights.  Errors
    (a pin overlapping the drag, no usable selection to pin) are shown in the panel.

    ``drag_range``: the offset sliders' range, default a fifth of the face's extent.
    """

    def __init__(self, model="procedural", sliders=None, view: str = "matplotlib", *, drag_region: str | None = None,
                 drag_range: float | None = None, **kw):
        from repro.blendshapes.manipulation import DirectManipulator

        self._drag_on = False  # read by _compute during the base panel's first update
        super().__init__(model, sliders, view, **kw)
        self.manipulator = DirectManipulator(self.attenuator)
        extent = float(np.ptp(self.model.f0, axis=0).max()) or 1.0
        r = float(drag_range) if drag_range is not None else extent / 5
        if not (math.isfinite(r) and r > 0):
            raise ModelError(f"drag_range must be a finite number > 0, got {drag_range!r}")
        regions = list(self._regions)
        first = drag_region if drag_region is not None else ("mouth_corners" if "mouth_corners" in regions else regions[0])
        if first not in regions:
            raise ModelError(f"unknown drag region {first!r}; known: {regions}")
        self.drag_region = widgets.Dropdown(options=regions, value=first, description="drag",
                                            layout=widgets.Layout(width="260px"), style={"description_width": "40px"})
        self.offset_sliders = {a: widgets.FloatSlider(value=0.0, min=-r, max=r, step=r / 200, description=f"target {a}",
                                                      readout_format=".3g", layout=widgets.Layout(width="300px"))
                               for a in AXES}
        self.drag_toggle = widgets.ToggleButton(value=False, description="drag", icon="hand-paper-o",
                                                tooltip="drag the chosen vertices; weights follow (Lewis and Anjyo 2010)")
        self.pin_box = widgets.Checkbox(value=True, description="pin the selection", indent=False)
        self.bounded_box = widgets.Checkbox(value=True, description="weights in [0, 1]", indent=False)
        self.drag_html = widgets.HTML()
        self.drag_html.add_class("repro-drag")
        self._drag_text = ""
        self._drag_result = None
        self._drag_w0 = np.zeros(self.model.n_shapes)
        self._drag_vertices = np.zeros(0, dtype=np.int64)
        self._drag_start = np.zeros((0, 3))
        for s in self.offset_sliders.values():
            s.observe(self._guarded(lambda _c: self._request_update()), names="value")
        for box in (self.pin_box, self.bounded_box):
            box.observe(self._guarded(lambda _c: self._request_update()), names="value")
        self.drag_region.observe(self._guarded(self._on_drag_region), names="value")
        self.drag_toggle.observe(self._guarded(self._on_drag_toggle), names="value")
        self.widget.children = (*self.widget.children,
                                widgets.HBox([self.drag_region, self.drag_toggle, self.pin_box, self.bounded_box]),
                                widgets.HBox(list(self.offset_sliders.values())), self.drag_html)

    # ------------------------------------------------------------- drag state
    def _start_drag(self) -> None:
        """The displayed weights become the start; the chosen region's vertices are dragged from where they are."""
        self._drag_w0 = self._weights.copy()
        self._drag_vertices = np.asarray(self._regions[self.drag_region.value], dtype=np.int64)
        self._drag_start = self.manipulator.positions(self._drag_w0, self._drag_vertices)
        for s in self.offset_sliders.values():
            self._set_widget(s, 0.0)

    def _on_drag_toggle(self, change) -> None:
        if self._internal:
            return
        with self._batch():
            if change["new"]:
                self._start_drag()
            self._drag_on = bool(change["new"])
            if not self._drag_on:
                self._drag_result = None
                self._drag_text = ""
                self.drag_html.value = ""
            self._request_update()

    def _on_drag_region(self, change) -> None:
        if self._drag_on:
            with self._batch():
                self._start_drag()
                self._request_update()

    def _compute(self):
        if not getattr(self, "_drag_on", False):
            return super()._compute()
        offset = np.array([self.offset_sliders[a].value for a in AXES], dtype=np.float64)
        pinned = None
        if self.pin_box.value:
            if self._sel is None:
                raise SelectionError(f"nothing to pin: {self._sel_error}")
            pinned = self._sel
        bounds = {"lo": 0.0, "hi": 1.0} if self.bounded_box.value else {}
        r = self.manipulator.solve(self._drag_w0, self._drag_vertices, self._drag_start + offset, pinned,
                                   info=True, **bounds)
        self._drag_result = r
        self._drag_text = DRAG_FORMAT.format(**r._asdict())
        self.drag_html.value = f"<code>{html.escape(self._drag_text)}</code>"
        d = self.attenuator.displacement(r.w)
        numbers = {
            "selected_motion": metrics.selected_motion(d, self._sel, self._d_base) if self._sel is not None else math.nan,
            "unselected_fidelity": math.nan,  # no slider target to be faithful to while dragging
            "alpha": float(self._alpha),
            "attenuation": "drag",
        }
        return r.w, (d, numbers), None

    # ------------------------------------------------------------ public API
    @property
    def drag_text(self) -> str:
        """The drag line as displayed (:data:`DRAG_FORMAT`), "" when drag mode is off."""
        return self._drag_text

    @property
    def drag_result(self):
        """The last :class:`~repro.blendshapes.manipulation.DragResult` (None when drag mode is off)."""
        return self._drag_result

    @property
    def drag_targets(self) -> np.ndarray:
        """Where the dragged vertices are asked to go ((k, 3), model units)."""
        offset = np.array([self.offset_sliders[a].value for a in AXES], dtype=np.float64)
        return self._drag_start + offset

    def set_drag(self, on: bool, region: str | None = None) -> None:
        """Switch drag mode on (from the displayed weights; optionally choosing the region first) or off."""
        if region is not None:
            if region not in self._regions:
                raise ModelError(f"unknown drag region {region!r}; known: {list(self._regions)}")
            self.drag_region.value = region
        self.drag_toggle.value = bool(on)

    def set_target_offset(self, dx: float | None = None, dy: float | None = None, dz: float | None = None) -> None:
        """Move the drag target (offset from where the drag started; one update)."""
        with self._batch():
            for a, v in zip(AXES, (dx, dy, dz)):
                if v is not None:
                    self.offset_sliders[a].value = v
            self._request_update()

    def add_region(self, name: str, vertices, *, select: bool = True) -> None:
        super().add_region(name, vertices, select=select)
        if hasattr(self, "drag_region"):
            self.drag_region.options = list(self._regions)

    def close(self) -> None:
        for w in [self.drag_region, *self.offset_sliders.values(), self.drag_toggle, self.pin_box, self.bounded_box,
                  self.drag_html]:
            w.close()
        super().close()

    def __repr__(self) -> str:
        return super().__repr__().replace("BlendshapePanel(", "DragPanel(", 1)
