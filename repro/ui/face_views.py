"""The live views of the blendshape panel (Lewis et al. 2005, Section 5): the posed face coloured by motion.

Each view draws ``render(points, motion, selected_vertices)``, the posed vertices, their motion since the
selection and the selected vertices, and returns PNG bytes: :class:`MatplotlibFaceView` (the default, numpy
rasterised over a matplotlib figure) or :class:`PyvistaFaceView` (one off-screen pyvista plotter);
:func:`face_view` picks one by name (``"3d"``: :class:`repro.ui.webview.MeshWebView`, drawn in the browser).
"""

from __future__ import annotations

import io

import numpy as np

from repro.blendshapes.model import BlendshapeModel

__all__ = ["VIEWS", "MatplotlibFaceView", "PyvistaFaceView", "face_view"]

#: The panel's view names: "auto" is pyvista when off-screen rendering works here, else matplotlib.
VIEWS = ("matplotlib", "pyvista", "3d", "auto", "none")


class MatplotlibFaceView:
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


class PyvistaFaceView:
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


def face_view(kind: str, model: BlendshapeModel, clim, cmap: str, size):
    """The view named ``kind`` (one of :data:`VIEWS`; "auto" resolved) and its resolved name; None for "none"."""
    if kind not in VIEWS:
        raise ValueError(f"view must be one of {VIEWS}, got {kind!r}")
    if kind == "auto":
        from repro.ui.render import render_unavailable_reason

        kind = "pyvista" if render_unavailable_reason() is None else "matplotlib"
    if kind == "matplotlib":
        return MatplotlibFaceView(model, clim, cmap, size), kind
    if kind == "pyvista":
        return PyvistaFaceView(model, clim, cmap, size), kind
    if kind == "3d":
        from repro.ui.webview import MeshWebView

        return MeshWebView(model, clim, cmap, size), kind
    return None, kind
