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

import dataclasses
import functools
import os
import re
import subprocess
import sys

from repro.errors import RenderUnavailableError

__all__ = ["render_unavailable_reason", "require_render", "configure_headless"]

_PROBE = (
    # dies with the process that probes, however it ends (as repro run's workers do with theirs)
    "import sys\n"
    "from repro.processes import die_with_parent\n"
    "die_with_parent(int(sys.argv[1]))\n"
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
            [sys.executable, "-c", _PROBE, str(os.getpid())], capture_output=True, text=True, timeout=120,
            env=os.environ,
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
    n = len(images)
    return panel_grid(images, titles, ["scale"] * n, {"scale": ColourScale(clim, cmap, label)},
                      ncols=ncols or n, suptitle=suptitle)


@dataclasses.dataclass(frozen=True)
class ColourScale:
    """The colours of a set of panels (:func:`panel_grid`): range, colour map, the bar's label and side."""

    clim: tuple
    cmap: str = "YlOrRd"
    label: str = ""
    location: str = "right"


def panel_grid(images, titles, scales, colour_scales, *, ncols: int, suptitle: str = "",
               panel_size=(2.6, 2.9), fontsize: float = 8.0):
    """Rendered panels in a grid of ``ncols`` columns, each set of panels with a colour bar of its own.

    Parameters
    ----------
    images : sequence of (H, W, 3) images or None
        Row by row; None leaves the slot empty, its title then written inside it as a note.
    titles : sequence of str
        One per slot (drawn at ``fontsize`` points).
    scales : sequence of hashable
        One per slot: the key in ``colour_scales`` of the panel's colours.
    colour_scales : mapping of key to :class:`ColourScale`
        One colour bar each, beside the panels that use it (keep them a rectangle of the grid:
        a row, a column, a block).
    """
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    from repro.errors import ArgumentError

    n = len(images)
    if not (len(titles) == len(scales) == n):
        raise ArgumentError(f"{n} images, {len(titles)} titles and {len(scales)} scales: one of each per slot")
    missing = {k for k, img in zip(scales, images) if img is not None} - set(colour_scales)
    if missing:
        raise ArgumentError(f"panels use colour scales {sorted(map(str, missing))} that colour_scales does not define")
    nrows = -(-n // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(panel_size[0] * ncols + 0.9, panel_size[1] * nrows + 0.4),
                             squeeze=False, layout="constrained")
    fig.get_layout_engine().set(w_pad=0.06, h_pad=0.06)  # a margin the colour bars' labels stay inside
    for ax in axes.ravel():
        ax.axis("off")
    users: dict = {}
    for ax, img, title, key in zip(axes.ravel(), images, titles, scales):
        if img is None:
            ax.text(0.5, 0.5, title, ha="center", va="center", fontsize=fontsize, transform=ax.transAxes)
            continue
        ax.imshow(img)
        ax.set_title(title, fontsize=fontsize)
        users.setdefault(key, []).append(ax)
    for key, axs in users.items():
        sc = colour_scales[key]
        bar = fig.colorbar(ScalarMappable(Normalize(*sc.clim), sc.cmap), ax=axs, shrink=0.8,
                           location=sc.location, aspect=15 if len(axs) <= ncols else 20)
        bar.set_label(sc.label, fontsize=fontsize + 1)
        bar.ax.tick_params(labelsize=fontsize)
    if suptitle:
        fig.suptitle(suptitle, fontsize=fontsize + 1)
    return fig


def skeleton_images(
    panels,
    edges,
    *,
    colors,
    bone_radius=0.018,
    joint_radius=0.026,
    targets=None,
    target_color="#1f4fe0",
    target_radius=0.05,
    paths=None,
    path_colors=None,
    path_radius=0.006,
    floor: bool = True,
    window_size=(340, 460),
    camera=None,
    azimuth: float = 40.0,
    elevation: float = 14.0,
    zoom: float = 1.0,
) -> list:
    """Off-screen renders of stick figures (tubes for bones, spheres for joints) with target spheres.

    Coordinates are y-up (x lateral, z forward), in metres.

    Parameters
    ----------
    panels : sequence of sequences of (n, 3) arrays
        One entry per panel; each is the skeletons drawn together in it (e.g. the
        original and the adapted pose), drawn in ``colors``' order.
    edges : sequence of (a, b) joint index pairs
        The bones, shared by every skeleton.
    colors : sequence of colours
        One per skeleton of a panel (the same in every panel).
    bone_radius, joint_radius : float or sequence of floats (one per skeleton)
        Tube and joint-sphere radii (m).
    targets : sequence of (3,) points or None, optional
        One per panel (None: no target on that panel), drawn as a sphere of
        ``target_radius`` in ``target_color``.
    paths : sequence of sequences of (m, 3) polylines, optional
        One entry per panel, each a list of polylines (e.g. the hit point's
        trajectory) drawn as thin tubes in ``path_colors``.
    floor : bool
        Draw a light floor plane at y = 0 under everything.
    camera : (position, focal_point, view_up), optional
        Default: a perspective three-quarter view (``azimuth`` degrees from the +z
        axis towards +x, ``elevation`` degrees up) fitted to all panels at once.

    Returns
    -------
    list of (H, W, 3) uint8 images, one per panel, all with the same camera, so
    sizes compare across panels.
    """
    require_render()
    import pyvista as pv

    scene = _Skeletons(panels, edges, colors, bone_radius, joint_radius, targets, paths, path_colors)
    points = scene.points()
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = max(scene.bone_r + scene.joint_r + [target_radius])
    if camera is None:
        camera = _fitted_camera(points, lo, hi, pad, azimuth, elevation, window_size)
    configure_headless()
    with pv.vtk_verbosity("error"):
        pl = pv.Plotter(off_screen=True, window_size=list(window_size), lighting="three lights")
        try:
            pl.set_background("white")
            pl.enable_anti_aliasing("msaa")
            if floor:
                _add_floor(pl, lo, hi, pad)
            images = []
            for i in range(len(scene.panels)):
                scene.draw(pl, i, target_color, target_radius, path_radius)
                pl.camera_position = camera
                if zoom != 1.0:
                    pl.camera.zoom(zoom)
                pl.render()  # pyvista renders a screenshot only once otherwise
                images.append(pl.screenshot(return_img=True).copy())
            return images
        finally:
            pl.close()


class _Skeletons:
    """What :func:`skeleton_images` draws: per panel its skeletons, target and paths, checked."""

    def __init__(self, panels, edges, colors, bone_radius, joint_radius, targets, paths, path_colors):
        import numpy as np

        self.panels = [[np.asarray(P, dtype=float).reshape(-1, 3) for P in skels] for skels in panels]
        self.edges = np.asarray(edges, dtype=int).reshape(-1, 2)
        self.colors = list(colors)
        self.n_sk = max((len(s) for s in self.panels), default=0)
        if len(self.colors) < self.n_sk:
            raise ValueError(f"{len(self.colors)} colours for panels of {self.n_sk} skeletons")

        def per_skeleton(value):
            return list(value) if np.ndim(value) else [float(value)] * len(self.colors)

        self.bone_r, self.joint_r = per_skeleton(bone_radius), per_skeleton(joint_radius)
        self.targets = list(targets) if targets is not None else [None] * len(self.panels)
        self.paths = ([[np.asarray(q, dtype=float).reshape(-1, 3) for q in ps] for ps in paths]
                      if paths is not None else None)
        self.path_colors = list(path_colors) if path_colors is not None else self.colors
        if len(self.targets) != len(self.panels) or (self.paths is not None and len(self.paths) != len(self.panels)):
            raise ValueError("targets and paths need one entry per panel")
        self.n_paths = max((len(p) for p in self.paths), default=0) if self.paths is not None else 0

    def points(self):
        """Everything any panel draws, as (n, 3) points: one camera and floor fit them all."""
        import numpy as np

        pts = [P for s in self.panels for P in s]
        pts += [np.asarray(t, float).reshape(1, 3) for t in self.targets if t is not None]
        pts += [q for ps in self.paths for q in ps] if self.paths is not None else []
        return np.vstack(pts) if pts else np.zeros((1, 3))

    def draw(self, pl, i: int, target_color, target_radius: float, path_radius: float) -> None:
        """Panel ``i`` in the plotter, in place of the previous panel's actors."""
        import numpy as np
        import pyvista as pv

        for k in range(self.n_sk):
            for part in ("bones", "joints"):
                pl.remove_actor(f"skeleton{k}_{part}")
        for k, P in enumerate(self.panels[i]):
            lines = np.column_stack([np.full(len(self.edges), 2), self.edges]).ravel()
            bones = pv.PolyData(P.copy(), lines=lines).tube(radius=self.bone_r[k], n_sides=14, capping=True)
            joints = pv.PolyData(P.copy()).glyph(geom=pv.Sphere(radius=self.joint_r[k], theta_resolution=14,
                                                                phi_resolution=10), scale=False, orient=False)
            pl.add_mesh(bones, color=self.colors[k], smooth_shading=True, specular=0.2, name=f"skeleton{k}_bones")
            pl.add_mesh(joints, color=self.colors[k], smooth_shading=True, specular=0.2, name=f"skeleton{k}_joints")
        pl.remove_actor("target")
        if self.targets[i] is not None:
            pl.add_mesh(pv.Sphere(radius=target_radius, center=np.asarray(self.targets[i], float).ravel()),
                        color=target_color, smooth_shading=True, specular=0.3, name="target")
        for k in range(self.n_paths):
            pl.remove_actor(f"path{k}")
        for k, q in enumerate(self.paths[i] if self.paths is not None else []):
            if len(q) >= 2:
                pl.add_mesh(pv.Spline(q, max(2, 4 * len(q))).tube(radius=path_radius, n_sides=8),
                            color=self.path_colors[k % len(self.path_colors)], name=f"path{k}")


def _fitted_camera(pts, lo, hi, pad: float, azimuth: float, elevation: float, window_size) -> list:
    """A perspective three-quarter view (``azimuth`` degrees from +z towards +x, ``elevation`` up) in which
    ``pts``, the floor under them and a margin ``pad`` around them just fit: (position, focal point, view up)."""
    import numpy as np

    az, el = np.radians(azimuth), np.radians(elevation)
    back = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])  # towards the camera
    right = np.cross((0.0, 1.0, 0.0), back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    fl_lo, fl_hi = lo - 2 * pad, hi + 2 * pad  # the floor's extent too
    corners = np.array([[x, 0.0, z] for x in (fl_lo[0], fl_hi[0]) for z in (fl_lo[2], fl_hi[2])])
    fit = np.vstack([pts, corners, pts + pad * up, pts - pad * up, pts + pad * right, pts - pad * right])
    # perspective fit (VTK's default view angle: 30 degrees vertically), iterated a few times:
    # distance so the farthest-out point just fits, then re-centre on the projected extent
    tan_v = np.tan(np.radians(15.0))
    tan_h = tan_v * window_size[0] / window_size[1]
    centre = (fit.min(axis=0) + fit.max(axis=0)) / 2
    for _ in range(8):
        r = fit - centre
        w, u, v = r @ back, r @ right, r @ up
        dist = float(np.max(w + np.maximum(np.abs(u) / tan_h, np.abs(v) / tan_v)))
        pu, pv_ = u / (dist - w), v / (dist - w)
        centre = centre + dist * ((pu.max() + pu.min()) / 2 * right + (pv_.max() + pv_.min()) / 2 * up)
    r = fit - centre
    w = r @ back
    dist = 1.03 * float(np.max(w + np.maximum(np.abs(r @ right) / tan_h, np.abs(r @ up) / tan_v)))
    return [tuple(centre + dist * back), tuple(centre), tuple(up)]


def _add_floor(pl, lo, hi, pad: float) -> None:
    """A light, unshaded floor plane at y = 0, ``2 pad`` beyond the extent ``lo``..``hi`` in x and z."""
    import pyvista as pv

    a, b = lo[[0, 2]] - 2 * pad, hi[[0, 2]] + 2 * pad
    plane = pv.Plane(center=((a[0] + b[0]) / 2, 0.0, (a[1] + b[1]) / 2), direction=(0, 1, 0),
                     i_size=b[1] - a[1], j_size=b[0] - a[0])
    pl.add_mesh(plane, color="#ebebeb", lighting=False, name="floor")  # flat: no shading
