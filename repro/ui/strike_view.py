"""Drawing a strike (Pronost et al., Fig. 10): the retrieved clip, the adapted motion and the target.

A fixed orthographic camera beside the fighter (:class:`StrikeCamera`) projects the
skeletons to 2D, so each picture is a few matplotlib line collections and circles whose
data are updated in place (no 3D axes rebuilt per order):

- :class:`FilmstripView`: key frames side by side, one persistent figure (the panel
  redraws it per order in a few tens of milliseconds);
- :func:`strike_animation`: a ``matplotlib.animation.FuncAnimation`` of every frame
  (``.to_jshtml()`` for a notebook player), :func:`animation_html` its HTML and
  :func:`animation_png` an animated PNG (APNG) that a browser plays by itself (the app).

The adapted skeleton is blue with a head, the unadapted one (the clip retrieved, placed
and blended, before the constraint solver) grey, the target a navy circle of
``head_radius`` around the stored head position, the hit point's path so far dashed red.
"""

from __future__ import annotations

import io
import math

import numpy as np

from repro.motion.body.roles import find_roles

__all__ = [
    "FilmstripView", "StrikeCamera", "animation_html", "animation_png", "key_frames", "scene_geometry",
    "strike_animation",
]

ADAPTED, ORIGINAL, TARGET, PATH = "tab:blue", "0.62", "navy", "tab:red"


def key_frames(strike, n: int = 5) -> list[int]:
    """``n`` frames of a strike from the order to the contact, plus one after it (distinct, sorted)."""
    F, tc = strike.n_frames, strike.tc
    before = np.linspace(0, tc, max(2, n - 1)).round().astype(int).tolist()
    after = min(F - 1, tc + max(1, (F - 1 - tc) // 2))
    return sorted(set(before + [after]))


def _segments(motion, g, e):
    """(frames, bones, 2 ends, 3) bone segments of a motion (joints to parents, End Sites to theirs)."""
    par = np.asarray(motion.parents)
    j = np.flatnonzero(par >= 0)
    a = np.concatenate([g[:, par[j]], g[:, np.asarray(motion.end_site_parents)]], axis=1)
    b = np.concatenate([g[:, j], e], axis=1)
    return np.stack([a, b], axis=2)


def _head(motion, g, e):
    """(frames, 3) centre and radius (m) of a head drawn on the skeleton (the head joint to its End Site)."""
    try:
        h = list(motion.joint_names).index(find_roles(motion.joint_names, motion.parents)["head"])
    except Exception:  # noqa: BLE001 - no head role: the topmost joint of the rest pose
        h = int(np.argmax(g[0, :, 1]))
    ends = [k for k, p in enumerate(motion.end_site_parents) if p == h]
    top = e[:, ends[0]] if ends else g[:, h] + np.array([0.0, 0.2, 0.0])
    length = float(np.linalg.norm(top[0] - g[0, h]))
    r = float(np.clip(0.55 * length, 0.07, 0.14))
    return g[:, h] + (top - g[:, h]) * 0.5, r


class StrikeCamera:
    """An orthographic view from the fighter's left, a little from the front and above (y up).

    ``project(P)`` maps world points (..., 3) to (..., 2) screen coordinates in metres.
    """

    def __init__(self, strike, *, elevation: float = 12.0, turn: float = 20.0, root=None):
        root = strike.motion.global_positions()[0, 0] if root is None else np.asarray(root, dtype=float)
        d = strike.target - root
        facing = math.atan2(d[0], d[2])
        f = np.array([math.sin(facing), 0.0, math.cos(facing)])  # the fighter faces the target
        side = np.cross([0.0, 1.0, 0.0], f)  # the fighter's left
        t = math.radians(turn)
        right = math.cos(t) * f - math.sin(t) * side  # the strike goes to the right of the picture
        back = np.cross(right, [0.0, 1.0, 0.0])
        back /= np.linalg.norm(back)
        e = math.radians(elevation)
        back = math.cos(e) * back + math.sin(e) * np.array([0.0, 1.0, 0.0])
        self.right = right / np.linalg.norm(right)
        self.up = np.cross(back, self.right)
        self.basis = np.column_stack([self.right, self.up])

    def project(self, P) -> np.ndarray:
        return np.asarray(P, dtype=float) @ self.basis


class _Scene:
    """The artists of one strike picture in one 2D axes (floor, target, two skeletons, heads, hit path)."""

    def __init__(self, ax, *, lw: float = 2.4):
        from matplotlib.collections import LineCollection
        from matplotlib.patches import Circle

        self.ax = ax
        ax.set_aspect("equal")
        ax.set_axis_off()
        self.floor = LineCollection([], colors="0.86", linewidths=0.7, zorder=0)
        self.original = LineCollection([], colors=ORIGINAL, linewidths=lw * 0.6, capstyle="round", zorder=1)
        self.adapted = LineCollection([], colors=ADAPTED, linewidths=lw, capstyle="round", zorder=3)
        for c in (self.floor, self.original, self.adapted):
            ax.add_collection(c)
        self.original_head = Circle((0, 0), 0.1, facecolor="white", edgecolor=ORIGINAL, linewidth=lw * 0.6, zorder=1)
        self.head = Circle((0, 0), 0.1, facecolor="#cfe3f5", edgecolor=ADAPTED, linewidth=lw * 0.8, zorder=3)
        self.target = Circle((0, 0), 0.1, facecolor=(0.1, 0.1, 0.5, 0.12), edgecolor=TARGET, linewidth=1.2,
                             zorder=2)
        for p in (self.original_head, self.head, self.target):
            ax.add_patch(p)
        (self.path,) = ax.plot([], [], "--", color=PATH, linewidth=1.1, zorder=4)
        (self.hit,) = ax.plot([], [], "o", color=PATH, markersize=4, zorder=5)
        # y given: no automatic title placement (which lays out the hidden axes' ticks each draw)
        self.title = ax.set_title("", fontsize=10, y=1.0, pad=3)

    def artists(self):
        return [self.original, self.adapted, self.original_head, self.head, self.path, self.hit, self.title]


def scene_geometry(strike, head_radius: float = 0.1) -> dict:
    """A strike in world coordinates (metres), forward kinematics once: what every view of it draws.

    Keys: ``adapted`` / ``original`` (F, bones, 2, 3) bone segments, ``head`` /
    ``original_head`` (F, 3) head centres, ``head_r`` (m), ``hit`` (F, 3) the hit point,
    ``target`` (3,), ``floor`` (lines, 2, 3) a 0.5 m grid on the floor around the fighter,
    ``root`` (3,) the root at frame 0.
    """
    g, e = strike.motion.global_positions(), strike.motion.end_site_positions()
    go, eo = strike.original.global_positions(), strike.original.end_site_positions()
    hc, head_r = _head(strike.motion, g, e)
    oc, _ = _head(strike.original, go, eo)
    c = (g.reshape(-1, 3).min(axis=0) + g.reshape(-1, 3).max(axis=0)) / 2
    half = 0.5 * float(max(np.ptp(g[..., 0]), np.ptp(g[..., 2]))) + 0.6
    step = 0.5
    xs = np.arange(math.ceil((c[0] - half) / step), math.floor((c[0] + half) / step) + 1) * step
    zs = np.arange(math.ceil((c[2] - half) / step), math.floor((c[2] + half) / step) + 1) * step
    lines = [[(x, 0.0, c[2] - half), (x, 0.0, c[2] + half)] for x in xs]
    lines += [[(c[0] - half, 0.0, z), (c[0] + half, 0.0, z)] for z in zs]
    return {
        "adapted": _segments(strike.motion, g, e), "original": _segments(strike.original, go, eo),
        "head": hc, "original_head": oc, "head_r": head_r, "hit": np.asarray(strike.hit_positions(), dtype=float),
        "target": np.asarray(strike.target, dtype=float), "floor": np.array(lines).reshape(-1, 2, 3),
        "root": g[0, 0].copy(), "centre": c,
    }


class _Geometry:
    """A strike projected once: segments, heads, hit path, target and the limits every picture shares."""

    def __init__(self, strike, head_radius: float, camera: StrikeCamera | None = None):
        self.strike = strike
        w = scene_geometry(strike, head_radius)
        cam = camera or StrikeCamera(strike, root=w["root"])
        self.adapted = cam.project(w["adapted"])
        self.original = cam.project(w["original"])
        self.head_r = w["head_r"]
        self.head, self.original_head = cam.project(w["head"]), cam.project(w["original_head"])
        self.hit = cam.project(w["hit"])
        self.target = cam.project(w["target"])
        self.target_r = head_radius
        pts = np.vstack([self.adapted.reshape(-1, 2), self.original.reshape(-1, 2), self.target[None]])
        c = w["centre"]
        self.floor = cam.project(w["floor"]) if len(w["floor"]) else np.zeros((0, 2, 2))
        pad = max(self.head_r, head_radius) + 0.06
        lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
        lo[1] = min(lo[1], cam.project(np.array([c[0], 0.0, c[2]]))[1] - 0.05)
        self.lo, self.hi = lo, hi
        self.fps = 1.0 / strike.motion.frame_time

    def draw(self, scene: _Scene, f: int, title: str | None = None, original: bool = True) -> None:
        scene.floor.set_segments(self.floor)
        scene.adapted.set_segments(self.adapted[f])
        scene.original.set_segments(self.original[f] if original else [])
        scene.original_head.set_visible(original)
        scene.original_head.center, scene.original_head.radius = tuple(self.original_head[f]), self.head_r
        scene.head.center, scene.head.radius = tuple(self.head[f]), self.head_r
        scene.target.center, scene.target.radius = tuple(self.target), self.target_r
        scene.path.set_data(self.hit[: f + 1, 0], self.hit[: f + 1, 1])
        scene.hit.set_data([self.hit[f, 0]], [self.hit[f, 1]])
        if title is None:
            s = self.strike
            label = " (contact)" if f == s.tc else (" (order)" if f == 0 else "")
            title = f"t = {f / self.fps:+.2f} s{label}"
        scene.title.set_text(title)
        scene.ax.set_xlim(self.lo[0], self.hi[0])
        scene.ax.set_ylim(self.lo[1], self.hi[1])


def _title(strike) -> str:
    return (f"{strike.kind}: {strike.clip_name}; hit error at contact {1000 * strike.hit_error:.1f} mm"
            f" ({'reached' if strike.reached else 'NOT reached'}; unadapted clip misses by "
            f"{100 * strike.unadapted_error:.1f} cm)")


class FilmstripView:
    """One persistent filmstrip figure: :meth:`render` redraws it for a strike (artists updated in place)."""

    def __init__(self, n: int = 5, *, width: float = 11.0, dpi: int = 90, head_radius: float = 0.1):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.n, self.head_radius = int(n), float(head_radius)
        self.fig = Figure(figsize=(width, width / self.n * 1.3 + 0.5), dpi=dpi)
        FigureCanvasAgg(self.fig)
        axes = [self.fig.add_subplot(1, self.n, k + 1) for k in range(self.n)]
        self.scenes = [_Scene(ax) for ax in axes]
        self.fig.subplots_adjust(left=0.005, right=0.995, bottom=0.0, top=0.86, wspace=0.02)
        self.suptitle = self.fig.suptitle("", fontsize=10.5)

    def draw(self, strike, frames=None, *, title: str | None = None, original: bool = True):
        """Put ``strike`` (its key frames, or ``frames``) into the figure; the figure."""
        frames = key_frames(strike, self.n) if frames is None else [int(f) for f in frames]
        F = strike.n_frames
        if not frames or min(frames) < 0 or max(frames) >= F:
            raise ValueError(f"frames must be in [0, {F - 1}], got {frames}")
        if len(frames) > self.n:
            raise ValueError(f"{len(frames)} frames for a filmstrip of {self.n} panels")
        geo = _Geometry(strike, self.head_radius)
        for k, scene in enumerate(self.scenes):
            scene.ax.set_visible(k < len(frames))
            if k < len(frames):
                geo.draw(scene, frames[k], original=original)
        self.suptitle.set_text(_title(strike) if title is None else title)
        return self.fig

    def render(self, strike, frames=None, **kw) -> bytes:
        """PNG bytes of :meth:`draw` (Agg, then a fast zlib level)."""
        from repro.ui.raster import png_bytes

        self.draw(strike, frames, **kw)
        self.fig.canvas.draw()
        return png_bytes(np.asarray(self.fig.canvas.buffer_rgba())[:, :, :3])


def _animation_figure(strike, size: float, dpi: int, head_radius: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(size, size * 0.8), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 0.9))
    scene = _Scene(ax)
    geo = _Geometry(strike, head_radius)
    return fig, scene, geo


def _frame_title(strike, geo, f) -> str:
    label = " contact" if f == strike.tc else ""
    return f"{strike.kind}, t = {f / geo.fps:+.2f} s{label}"


def strike_animation(strike, *, every: int = 1, head_radius: float = 0.1, size: float = 5.0, dpi: int = 80,
                     original: bool = True):
    """A ``FuncAnimation`` of the strike at the database rate (every ``every``-th frame).

    Call ``.to_jshtml()`` for a notebook player (or ``.save(...)``); the figure is not
    attached to pyplot.
    """
    from matplotlib.animation import FuncAnimation

    every = max(1, int(every))
    fig, scene, geo = _animation_figure(strike, size, dpi, head_radius)
    frames = list(range(0, strike.n_frames, every))
    if frames[-1] != strike.n_frames - 1:
        frames.append(strike.n_frames - 1)

    def update(f):
        geo.draw(scene, f, title=_frame_title(strike, geo, f), original=original)
        return scene.artists()

    update(frames[0])
    anim = FuncAnimation(fig, update, frames=frames, interval=1000.0 * strike.motion.frame_time * every, blit=False)
    anim.repro_frames = frames
    return anim


def animation_html(strike, *, every: int = 1, head_radius: float = 0.1, **kw) -> str:
    """The strike as a ``matplotlib.animation`` JavaScript player (HTML string; embeds every frame)."""
    return strike_animation(strike, every=every, head_radius=head_radius, **kw).to_jshtml(default_mode="once")


def animation_frames(strike, *, every: int = 1, head_radius: float = 0.1, size: float = 5.0, dpi: int = 80,
                     original: bool = True):
    """The strike's frames as RGB arrays; (frame numbers, images).

    One figure: the static part (floor, target) is drawn once and kept (blitting); per
    frame only the skeletons, heads, hit path and title are drawn over it.
    """
    fig, scene, geo = _animation_figure(strike, size, dpi, head_radius)
    every = max(1, int(every))
    frames = list(range(0, strike.n_frames, every))
    if frames[-1] != strike.n_frames - 1:
        frames.append(strike.n_frames - 1)
    geo.draw(scene, frames[0], title="", original=original)
    moving = scene.artists()
    for a in moving:
        a.set_animated(True)
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    images = []
    for f in frames:
        geo.draw(scene, f, title=_frame_title(strike, geo, f), original=original)
        canvas.restore_region(background)
        for a in moving:
            fig.draw_artist(a)
        images.append(np.asarray(canvas.buffer_rgba())[:, :, :3].copy())
    return frames, images


def animation_png(strike, *, every: int = 2, loop: int = 0, hold: float = 0.8, **kw) -> bytes:
    """The strike as an animated PNG (APNG; a browser ``<img>`` plays it, ``loop=0``: forever).

    The last frame is held ``hold`` seconds before the animation starts again.
    """
    from PIL import Image

    _, images = animation_frames(strike, every=every, **kw)
    ms = 1000.0 * strike.motion.frame_time * max(1, int(every))
    durations = [round(ms)] * len(images)
    durations[-1] = round(ms + 1000.0 * hold)
    pil = [Image.fromarray(im) for im in images]
    buf = io.BytesIO()
    pil[0].save(buf, format="png", save_all=True, append_images=pil[1:], duration=durations, loop=int(loop),
                compress_level=1)
    return buf.getvalue()
