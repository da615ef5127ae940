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
  button; with ``view="3d"``, vertices picked on the face (:mod:`repro.ui.face_picking`);
- alpha on a log slider (``FloatLogSlider``, 1e-3..1e6) with a "default"
  checkbox that keeps it at Section 5's default for the current selection
  (``#unselected / #selected`` coordinates);
- an attenuation ``ToggleButton``;
- a live view (matplotlib by default, or one persistent off-screen pyvista
  plotter) coloured by per-vertex motion since the selection, the selected
  vertices in cyan;
- the numbers in words (:func:`face_readout`), and behind "details" a line of them in stable,
  parseable text (:data:`NUMBERS_FORMAT`), e.g.
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
import math
import time
from collections.abc import Iterable, Mapping

import ipywidgets as widgets
import numpy as np

from repro.blendshapes import Attenuator, load_model, metrics, select_vertices
from repro.blendshapes.model import AXES, BlendshapeModel
from repro.blendshapes.scenarios import PAPER_SLIDERS, default_sliders
from repro.errors import AttenuationError, ModelError, SelectionError
# the numbers line and its words, defined beside the panel and part of its interface (callers read the line back)
from repro.ui.face_readout import NOT_APPLICABLE, NUMBERS_FORMAT, face_readout, format_numbers, parse_numbers
from repro.ui.face_picking import PICKED, VertexPicks
from repro.ui.face_views import VIEWS, MatplotlibFaceView, face_view
from repro.ui.panel import PanelCallbacks

__all__ = [
    "BlendshapePanel", "blendshape_panel", "PAPER_SLIDERS",
    "NUMBERS_FORMAT", "NOT_APPLICABLE", "face_readout", "format_numbers", "parse_numbers",
]

#: Exponents (base 10) of the alpha slider's range.
ALPHA_EXPONENTS = (-3.0, 6.0)


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
    region, axis_boxes, select_button, alpha_slider, default_alpha, attenuation, view_image, readout_html, details,
    numbers_html, status_html
        The individual widgets.
    picks : repro.ui.face_picking.VertexPicks
        The vertices picked (the region ``"picked on the face"``).
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
        model = self._model_arg(model)
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
        first = region if region is not None else next(iter(self._regions))
        if first not in self._regions:
            raise ModelError(f"unknown region {first!r} of model {model.name!r}; known: {list(self._regions)}")
        axes = self._axes_arg(axes)
        self._init_state(defer_view)
        self._view, self.view_kind = face_view(view, model, clim, cmap, image_size)
        self.picks = VertexPicks(model.n_vertices)  # the vertices the user picked (repro.ui.face_picking)
        if self.view_kind == "3d":  # picked on the view in the browser: their region is offered from the start
            self._regions[PICKED] = self.picks.vertices
        self._picture_args = (clim, cmap, image_size)
        self._picture_view = None  # a matplotlib view for image_png() when the live view is drawn in the browser
        self._make_widgets(first, axes, alpha is None, continuous_update, image_size)
        self._observe_widgets()
        self.widget = self._layout(alpha_on_top)
        with self._batch():
            self._refresh_selection()
            if alpha is not None:
                self.set_alpha(alpha)
            if values:
                self.set_sliders(values)
            if attenuation:
                self.set_attenuation(True)
            self._request_update()

    # ---------------------------------------------------------- construction
    @staticmethod
    def _model_arg(model) -> BlendshapeModel:
        if isinstance(model, str):
            model = load_model(model)
        if not isinstance(model, BlendshapeModel):
            raise ModelError(f"model must be a model name or a BlendshapeModel, got {type(model).__name__}")
        return model

    def _init_state(self, defer_view) -> None:
        """The panel's state before any widget: no batch open, no selection, neutral weights."""
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
        self._alpha = 1.0
        self._sel = None
        self._sel_vertices = None
        self._sel_error: str | None = None
        n = self.model.n_shapes
        self._w_base = np.zeros(n)
        self._d_base = np.zeros(3 * self.model.n_vertices)
        self._weights = np.zeros(n)

    def _make_widgets(self, region: str, axes: str, default_alpha: bool, continuous_update: bool, image_size) -> None:
        """Section 5's controls: the sliders, the selection, alpha and its default, attenuation, the view, the numbers."""
        style = {"description_width": "110px"}
        self.sliders = {
            name: widgets.FloatSlider(value=0.0, min=0.0, max=1.0, step=0.01, description=name,
                                      continuous_update=continuous_update, readout_format=".2f", style=style,
                                      layout=widgets.Layout(width="340px"))
            for name in self.slider_names
        }
        self.region = widgets.Dropdown(options=list(self._regions), value=region, description="region",
                                       layout=widgets.Layout(width="260px"), style={"description_width": "50px"})
        self.axis_boxes = {a: widgets.Checkbox(value=a in axes, description=a, indent=False,
                                               layout=widgets.Layout(width="44px"))
                           for a in AXES}
        self.select_button = widgets.Button(description="select now", icon="crosshairs",
                                            tooltip="make the current slider pose the pose to keep (w_base)")
        self.alpha_slider = widgets.FloatLogSlider(value=1.0, base=10, min=ALPHA_EXPONENTS[0], max=ALPHA_EXPONENTS[1],
                                                   step=0.01, description="alpha", readout=False,
                                                   # on release only: with continuous updates the browser's
                                                   # slider sends back its step-snapped value as soon as it is
                                                   # drawn (335 -> 10**2.53 = 338.8), moving alpha by itself
                                                   continuous_update=False,
                                                   layout=widgets.Layout(width="560px"),
                                                   style={"description_width": "50px"})
        self.alpha_slider.add_class("repro-alpha")
        # alpha's value beside its slider, written as the numbers line writes it (the slider's own readout,
        # d3's ".6g", pads zeros: 4703.50 beside "alpha: 4703.5")
        self.alpha_value = widgets.HTML(layout=widgets.Layout(width="64px"))
        self.alpha_value.add_class("repro-alpha-value")
        self.default_alpha = widgets.Checkbox(value=default_alpha, description="default alpha (Section 5)",
                                              indent=False)
        self.attenuation = widgets.ToggleButton(value=False, description="attenuation", icon="anchor",
                                                tooltip="attenuate the motion of the selected coordinates (Eq. 3)")
        self.attenuation.add_class("repro-attenuation")
        self.reset_button = widgets.Button(description="reset", tooltip="all sliders to 0, attenuation off")
        self.view_image = widgets.Image(format="png", layout=widgets.Layout(
            width=f"{image_size[0]}px", height=f"{image_size[1]}px",
            display="none" if self._view is None or self.view_kind == "3d" else None))
        # the raw numbers behind "details" (issue 26, item 7); the words (readout_html) stay in view
        self.details = widgets.ToggleButton(value=False, description="details", tooltip="show the numbers line")
        self.details.add_class("repro-face-details")
        self.numbers_html = widgets.HTML(layout=widgets.Layout(display="none"))
        self.numbers_html.add_class("repro-numbers")
        self.readout_html = widgets.HTML()  # the numbers in words (face_readout)
        self.readout_html.add_class("repro-face-readout")
        self.status_html = widgets.HTML()
        self.status_html.add_class("repro-status")

    def _observe_widgets(self) -> None:
        for s in self.sliders.values():
            s.observe(self._guarded(self._on_slider), names="value")
        self.region.observe(self._guarded(self._on_selection), names="value")
        for box in self.axis_boxes.values():
            box.observe(self._guarded(self._on_selection), names="value")
        self.select_button.on_click(self._guarded(lambda _b: self.select_now()))
        self.reset_button.on_click(self._guarded(lambda _b: self.reset()))
        self.alpha_slider.observe(self._guarded(self._on_alpha), names="value")
        self.default_alpha.observe(self._guarded(self._on_default), names="value")
        self.attenuation.observe(self._guarded(self._on_attenuation), names="value")
        self.details.observe(lambda c: setattr(self.numbers_html.layout, "display", None if c["new"] else "none"),
                             names="value")
        if self.view_kind == "3d":
            self._view.picks.observe(self._guarded(self._on_pick), names="value")

    def _layout(self, alpha_on_top: bool) -> widgets.VBox:
        """The panel: the shape sliders, the view and the controls (selection, alpha, attenuation, numbers) side
        by side; with ``alpha_on_top``, alpha and the numbers above the sliders and the view, the rest below."""
        model = self.model
        header = widgets.HTML(
            f"<b>{html.escape(model.name)}</b>: {model.n_vertices:,} vertices, {model.n_shapes} shapes "
            f"({html.escape(model.units)})")
        left = widgets.VBox([header, *self.sliders.values()])
        right = widgets.VBox([self._view.widget if self.view_kind == "3d" else self.view_image])
        if not alpha_on_top:
            # three columns (shapes, view, the selection and alpha): the whole panel fits a 1280x720 screen
            # (issue 26, item 8); on a narrower page the third column wraps below the view
            self.alpha_slider.layout.width = "262px"
            controls = widgets.VBox([
                self.region, widgets.HBox([*self.axis_boxes.values(), self.select_button]),
                widgets.HBox([self.alpha_slider, self.alpha_value]), self.default_alpha,
                widgets.HBox([self.attenuation, self.reset_button]),
                self.readout_html, self.details, self.numbers_html, self.status_html,
            ], layout=widgets.Layout(width="330px", margin="0 0 0 8px"))
            panel = widgets.VBox([widgets.HBox([left, right, controls], layout=widgets.Layout(flex_flow="row wrap"))])
            panel.add_class("repro-blendshape-panel")
            return panel
        self.details.value = True  # the Fig. 5 layout: alpha and its numbers on top, shown
        alpha_row = widgets.HBox([self.alpha_slider, self.alpha_value, self.default_alpha])
        rows = [
            widgets.HBox([left, right]),
            widgets.HBox([self.region, *self.axis_boxes.values(), self.select_button]),
            alpha_row,
            widgets.HBox([self.attenuation, self.reset_button, self.details]),
            self.numbers_html,
            self.status_html,
        ]
        # alpha and its numbers first (the Fig. 5 notebook)
        rows = [alpha_row, self.readout_html, self.numbers_html] + [
            r for r in rows if r not in (alpha_row, self.numbers_html)]
        panel = widgets.VBox(rows)
        panel.add_class("repro-blendshape-panel")
        return panel

    # ------------------------------------------------------------- helpers
    @staticmethod
    def _slider_names(model: BlendshapeModel, sliders) -> tuple[str, ...]:
        if sliders is None:
            return default_sliders(model) or model.names
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

    def _on_pick(self, change) -> None:
        """A pick message of the page (click, brush stroke or clear), applied once."""
        pick = self.picks.take(change["new"])
        if pick is None:
            return
        self._view.picks_seq = pick.seq  # the next frame tells the page this pick is drawn
        if pick.action == "clear":
            self.clear_picks()
        else:
            self.pick_vertices(pick.vertices)

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
        if self.region.value == PICKED and not self.picks.vertices.size:
            self._sel_error = "no vertex picked: click the face in pick mode (or Shift-click), or choose a region"
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
            self._numbers_text = format_numbers(numbers)
        t1 = time.perf_counter()
        self.last_update_seconds["numbers"] = t1 - t0
        self.numbers_html.value = f"<code>{html.escape(self._numbers_text)}</code>"
        self.alpha_value.value = f"{float(self._alpha):.6g}"
        self.readout_html.value = ("" if result is None else html.escape(
            face_readout(self._numbers, self.region.value, len(self._sel_vertices), self.model.units)))
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
            if self.region.value == PICKED and not self.picks.vertices.size:  # cleared: a state, not an error
                return html.escape(self.error)
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
        self.readout_html.value = ""
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

    def pick_vertices(self, vertices) -> None:
        """Add vertices to the picked selection and select it (one update), as a click or brush on the 3D view does.

        The picked selection is the region :data:`~repro.ui.face_picking.PICKED`; picking while another
        region is selected starts it from that region's vertices (the cyan ones), so a pick adds to what is shown.
        """
        with self._batch():
            start = None
            if self.region.value != PICKED:
                start = self._sel_vertices if self._sel_vertices is not None else ()
            self.picks.add(vertices, start)
            self._select_picked()

    def clear_picks(self) -> None:
        """Empty the picked selection and select it: nothing is selected until vertices are picked (one update)."""
        with self._batch():
            self.picks.clear()
            self._select_picked()

    @property
    def picked_vertices(self) -> np.ndarray:
        """The picked vertex ids (sorted)."""
        return self.picks.vertices.copy()

    def _select_picked(self) -> None:
        self._regions[PICKED] = self.picks.vertices
        if PICKED not in self.region.options:
            self.region.options = list(self._regions)
        self.set_selection(region=PICKED)

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
                  self.alpha_slider, self.default_alpha, self.attenuation, self.reset_button, self.details,
                  self.alpha_value, self.view_image, self.readout_html, self.numbers_html, self.status_html, self.widget]:
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
                self._picture_view = MatplotlibFaceView(self.model, *self._picture_args)
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
