"""The blendshape panel's drag mode: direct manipulation (Lewis and Anjyo 2010) next to the 2005 sliders.

:class:`DragPanel` is :class:`repro.ui.face_panel.BlendshapePanel` with a row to drag vertices; its face is
:meth:`~repro.blendshapes.manipulation.DirectManipulator.solve` from the weights displayed when the drag began.
"""

from __future__ import annotations

import html
import math

import ipywidgets as widgets
import numpy as np

from repro.blendshapes import metrics
from repro.blendshapes.model import AXES
from repro.errors import ModelError, SelectionError
from repro.ui.face_panel import BlendshapePanel

__all__ = ["DRAG_FORMAT", "DragPanel"]

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
