"""The kung-fu fighter panel (ipywidgets) and its figures, Pronost et al. Sections 3-4.

:class:`FighterPanel` plays the supervisor's keyboard and the user's tracked head of the
paper's experiment (Section 4, figure 1):

- target sliders ``x``, ``z`` (the 3 m x 3 m area, metres) and ``y`` (the head height);
- the fighter's morphology, which "the supervisor can change [...] and immediately
  visualizes the result" (Section 3.1): height (1.2-2.2 m), arm and leg proportions
  (±25 %);
- "kick" and "punch" buttons: the order (:meth:`repro.motion.fighter.KungFuFighter.order`:
  retrieval, conversion, adaptation, each stage timed);
- a "simulated user" toggle: the target then comes from
  :func:`repro.motion.fighter.simulated_user` (a ``Play`` widget, or the "step" button,
  walks through it; the fighter follows the head as in the paper);
- a filmstrip of the strike (:func:`filmstrip_figure`: a few key frames of the stick
  figure reaching the target sphere; the unadapted motion in grey, as the paper's Fig.
  10 shows the modified posture over the original);
- a line of numbers in stable, parseable text (:data:`FIGHTER_NUMBERS_FORMAT`, CSS class
  ``repro-fighter-numbers``), read back by :func:`parse_fighter_numbers`, e.g.
  ``order: kick | clip: actor2_kick_round_right_high | d: 0.0690 | d_qr: 0.0412 |
  d_cr: 0.0278 | hit error: 7.8e-11 m | reached: yes | prepare: 3.656 ms | search:
  0.284 ms | load+convert: 3.149 ms | adapt: 5.689 ms | adapt per frame: 0.082 ms |
  first frame: 12.778 ms | budget: 33.333 ms | within budget: yes``.

:func:`animation_html` renders a strike as a ``matplotlib.animation`` JavaScript player,
only when asked (it embeds every frame).  Everything is drawn with matplotlib's Agg
backend and is deterministic for a given strike.  No widget callback raises: errors are
shown in the panel.
"""

from __future__ import annotations

import html
import io
import math
import re

import ipywidgets as widgets
import numpy as np

from repro.ui.panel import PanelCallbacks
from repro.motion.fighter import AREA, KungFuFighter, Strike, character_from, simulated_user

__all__ = [
    "FighterPanel",
    "FIGHTER_NUMBERS_FORMAT",
    "format_fighter_numbers",
    "parse_fighter_numbers",
    "filmstrip_figure",
    "key_frames",
    "animation_html",
]

#: The panel's numbers line (times in milliseconds, distances in metres).
FIGHTER_NUMBERS_FORMAT = (
    "order: {kind} | clip: {clip} | d: {d:.4f} | d_qr: {d_qr:.4f} | d_cr: {d_cr:.4f} | hit error: {hit_error:.3g} m "
    "| reached: {reached} | prepare: {prepare:.3f} ms | search: {search:.3f} ms | load+convert: {load_convert:.3f} ms "
    "| adapt: {adapt:.3f} ms | adapt per frame: {adapt_per_frame:.3f} ms | first frame: {first_frame:.3f} ms "
    "| budget: {budget:.3f} ms | within budget: {within_budget}"
)

_FIELDS = {
    "order": "kind", "clip": "clip", "d": "d", "d_qr": "d_qr", "d_cr": "d_cr", "hit error": "hit_error",
    "reached": "reached", "prepare": "prepare", "search": "search", "load+convert": "load_convert",
    "adapt": "adapt", "adapt per frame": "adapt_per_frame", "first frame": "first_frame", "budget": "budget",
    "within budget": "within_budget",
}
_TEXT_FIELDS = {"kind", "clip", "reached", "within_budget"}


def format_fighter_numbers(strike: Strike) -> str:
    """The numbers line of a strike (:data:`FIGHTER_NUMBERS_FORMAT`)."""
    r, t = strike.retrieval, strike.timings
    return FIGHTER_NUMBERS_FORMAT.format(
        kind=strike.kind, clip=r.name, d=r.d, d_qr=r.d_qr, d_cr=r.d_cr, hit_error=strike.hit_error,
        reached="yes" if strike.reached else "no", prepare=t["prepare"] * 1e3, search=t["search"] * 1e3,
        load_convert=t["load_convert"] * 1e3, adapt=t["adapt"] * 1e3, adapt_per_frame=t["adapt_per_frame"] * 1e3,
        first_frame=t["first_frame"] * 1e3, budget=strike.budget_s * 1e3,
        within_budget="yes" if strike.within_budget else "no")


def parse_fighter_numbers(text: str) -> dict:
    """The numbers line back as a dict: floats (metres, milliseconds) and the text fields.

    Keys: ``kind, clip, d, d_qr, d_cr, hit_error, reached, prepare, search,
    load_convert, adapt, adapt_per_frame, first_frame, budget, within_budget``.  Raises
    ``ValueError`` for anything else (e.g. ``"error: ..."`` or the text shown before the
    first order).
    """
    out = {}
    for part in text.strip().split(" | "):
        m = re.fullmatch(r"([a-z_+ ]+): (\S+)(?: (m|ms))?", part.strip())
        if not m or m.group(1) not in _FIELDS:
            raise ValueError(f"not a numbers line of the fighter panel: {text!r}")
        key = _FIELDS[m.group(1)]
        out[key] = m.group(2) if key in _TEXT_FIELDS else float(m.group(2))
    if set(out) != set(_FIELDS.values()):
        raise ValueError(f"not a numbers line of the fighter panel: {text!r}")
    return out


# ----------------------------------------------------------------------- drawing
def key_frames(strike: Strike, n: int = 5) -> list[int]:
    """``n`` frames of a strike from the order to the contact, plus one after it (distinct, sorted)."""
    F, tc = strike.n_frames, strike.tc
    before = np.linspace(0, tc, max(2, n - 1)).round().astype(int).tolist()
    after = min(F - 1, tc + max(1, (F - 1 - tc) // 2))
    return sorted(set(before + [after]))


def _bones(motion, f):
    g = motion.global_positions()[f]
    e = motion.end_site_positions()[f]
    segs = [(g[p], g[j]) for j, p in enumerate(motion.parents) if p >= 0]
    segs += [(g[p], e[k]) for k, p in enumerate(motion.end_site_parents)]
    return np.array(segs)


def _sphere(ax, centre, radius, color):
    u, v = np.mgrid[0:2 * np.pi:16j, 0:np.pi:9j]
    ax.plot_wireframe(centre[0] + radius * np.cos(u) * np.sin(v), centre[2] + radius * np.sin(u) * np.sin(v),
                      centre[1] + radius * np.cos(v), color=color, linewidth=0.5)


def _floor(ax, c, half, step: float = 0.5):
    """Grid lines on the floor (y = 0) every ``step`` metres."""
    xs = np.arange(math.ceil((c[0] - half) / step), math.floor((c[0] + half) / step) + 1) * step
    zs = np.arange(math.ceil((c[2] - half) / step), math.floor((c[2] + half) / step) + 1) * step
    for x in xs:
        ax.plot([x, x], [c[2] - half, c[2] + half], [0, 0], color="0.85", linewidth=0.6)
    for z in zs:
        ax.plot([c[0] - half, c[0] + half], [z, z], [0, 0], color="0.85", linewidth=0.6)


def filmstrip_figure(strike: Strike, frames=None, *, n: int = 5, head_radius: float = 0.1, width: float = 11.0,
                     title: str | None = None, original: bool = True):
    """Key frames of a strike side by side: the stick figure reaching the target sphere.

    Each panel is a 3D view (matplotlib ``mplot3d``, a fixed camera beside the fighter)
    of one frame: the adapted skeleton (blue), the unadapted one (grey, thin; the clip
    retrieved, placed and blended, before the constraint solver), the target (a blue
    sphere of ``head_radius`` metres around the stored head position) and the hit
    point's path so far (dashed).  Titles give the time from the order.

    Returns
    -------
    matplotlib.figure.Figure
        Not attached to pyplot (draw it with ``display(fig)`` or save it).
    """
    from matplotlib.figure import Figure

    frames = key_frames(strike, n) if frames is None else [int(f) for f in frames]
    F = strike.n_frames
    if not frames or min(frames) < 0 or max(frames) >= F:
        raise ValueError(f"frames must be in [0, {F - 1}], got {frames}")
    fig = Figure(figsize=(width, width / len(frames) * 1.3 + 0.5), dpi=90)
    g = strike.motion.global_positions()
    hit = strike.hit_positions()
    X = strike.target
    pts = np.concatenate([g.reshape(-1, 3), X[None]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c = (lo + hi) / 2
    half = max(float((hi - lo)[[0, 2]].max()) / 2, float(hi[1]) / 2, 0.5) + 0.05
    fps = 1.0 / strike.motion.frame_time
    # look at the fighter from its left side, a little from the front
    facing = math.degrees(math.atan2(X[0] - g[0, 0, 0], X[2] - g[0, 0, 2]))
    azim = -facing + 20.0
    for k, f in enumerate(frames):
        ax = fig.add_subplot(1, len(frames), k + 1, projection="3d")
        if original:
            for a, b in _bones(strike.original, f):
                ax.plot([a[0], b[0]], [a[2], b[2]], [a[1], b[1]], color="0.7", linewidth=1.0)
        for a, b in _bones(strike.motion, f):
            ax.plot([a[0], b[0]], [a[2], b[2]], [a[1], b[1]], color="tab:blue", linewidth=2.0)
        _sphere(ax, X, head_radius, "navy")
        ax.plot(hit[: f + 1, 0], hit[: f + 1, 2], hit[: f + 1, 1], "--", color="tab:red", linewidth=1.0)
        ax.scatter([hit[f, 0]], [hit[f, 2]], [hit[f, 1]], color="tab:red", s=12)
        _floor(ax, c, half)
        ax.set_xlim(c[0] - half, c[0] + half)
        ax.set_ylim(c[2] - half, c[2] + half)
        ax.set_zlim(0.0, 2 * half)
        ax.set_box_aspect((1, 1, 1), zoom=1.35)
        ax.view_init(elev=12, azim=azim)
        ax.set_axis_off()
        label = " (contact)" if f == strike.tc else (" (order)" if f == 0 else "")
        ax.set_title(f"t = {f / fps:+.2f} s{label}", fontsize=9)
    if title is None:
        title = (f"{strike.kind}: {strike.clip_name}; hit error at contact {1000 * strike.hit_error:.1f} mm"
                 f" ({'reached' if strike.reached else 'NOT reached'}; unadapted clip misses by "
                 f"{100 * strike.unadapted_error:.1f} cm)")
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.0, top=0.88, wspace=0.0)
    return fig


def animation_html(strike: Strike, *, every: int = 1, head_radius: float = 0.1) -> str:
    """The strike as a ``matplotlib.animation`` JavaScript player (HTML string; embeds every frame)."""
    from matplotlib.animation import FuncAnimation
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.0, 4.0), dpi=72)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    frames = list(range(0, strike.n_frames, max(1, int(every))))
    g = strike.motion.global_positions()
    X = strike.target
    lo, hi = g.reshape(-1, 3).min(axis=0), g.reshape(-1, 3).max(axis=0)
    c = (lo + hi) / 2
    half = max(float((hi - lo)[[0, 2]].max()) / 2, float(hi[1]) / 2, 0.5) + 0.05
    facing = math.degrees(math.atan2(X[0] - g[0, 0, 0], X[2] - g[0, 0, 2]))

    def draw(f):
        ax.cla()
        for a, b in _bones(strike.motion, f):
            ax.plot([a[0], b[0]], [a[2], b[2]], [a[1], b[1]], color="tab:blue", linewidth=2.0)
        _sphere(ax, X, head_radius, "navy")
        _floor(ax, c, half)
        ax.set_xlim(c[0] - half, c[0] + half)
        ax.set_ylim(c[2] - half, c[2] + half)
        ax.set_zlim(0.0, 2 * half)
        ax.set_box_aspect((1, 1, 1), zoom=1.35)
        ax.view_init(elev=12, azim=-facing + 20.0)
        ax.set_axis_off()
        ax.set_title(f"{strike.kind}, frame {f}" + (" (contact)" if f == strike.tc else ""), fontsize=9)
        return []

    anim = FuncAnimation(fig, draw, frames=frames, interval=1000.0 * strike.motion.frame_time * max(1, int(every)),
                         blit=False)
    return anim.to_jshtml(default_mode="once")


def _png(fig) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


# ----------------------------------------------------------------------- panel
class FighterPanel(PanelCallbacks):
    """Target sliders, morphology sliders, kick / punch buttons, a simulated user, a filmstrip and numbers.

    Parameters
    ----------
    fighter : KungFuFighter, optional
        Default: a new one on the synthetic database (its one-time cost, a few seconds
        the first time in a process).
    target : (x, y, z), default (0, 1.65, 0)
        Starting target (metres).
    follow : bool, default True
        Before each order the fighter steps to striking distance of the target, facing
        it (:meth:`KungFuFighter.follow` with ``snap=True``), as the paper's fighter
        follows the user; False orders from where it stands (targets may be out of
        reach: best effort, "reached: no").
    view : bool, default True
        Draw the filmstrip after each order (False: numbers only, faster).
    user_seed, user_duration : int, float
        The simulated user's trajectory (:func:`simulated_user` at 30 Hz).

    Attributes
    ----------
    widget : ipywidgets.VBox
        The panel (class ``repro-fighter-panel``); displaying the panel displays it.
    sliders : dict
        ``x``, ``y``, ``z``, ``height``, ``arm_scale``, ``leg_scale``.
    kick_button, punch_button, follow_box, user_toggle, play, step_button, image, numbers_html, status_html
    fighter : KungFuFighter
    last_strike : Strike or None
    """

    def __init__(self, fighter: KungFuFighter | None = None, *, target=(0.0, 1.65, 0.0), follow: bool = True,
                 view: bool = True, user_seed: int = 0, user_duration: float = 20.0):
        self.fighter = fighter if fighter is not None else KungFuFighter()
        self.view = bool(view)
        self.user = simulated_user(user_seed, user_duration, 30.0)
        self._user_index = 0
        self.last_strike: Strike | None = None
        self.error: str | None = None
        self._numbers_text = "press kick or punch"
        self._batch_depth = 0
        self._pending_character = False
        (x0, x1), (y0, y1), (z0, z1) = AREA
        style = {"description_width": "90px"}
        lay = widgets.Layout(width="330px")

        def fs(desc, v, lo, hi, step=0.01, fmt=".2f"):
            return widgets.FloatSlider(value=v, min=lo, max=hi, step=step, description=desc, readout_format=fmt,
                                       continuous_update=False, style=style, layout=lay)

        ch = self.fighter.character
        self.sliders = {
            "x": fs("target x (m)", float(target[0]), x0, x1),
            "y": fs("target y (m)", float(target[1]), 0.5, 2.2),
            "z": fs("target z (m)", float(target[2]), z0, z1),
            "height": fs("height (m)", round(ch.size, 2), 1.2, 2.2),
            "arm_scale": fs("arms", 1.0, 0.75, 1.25),
            "leg_scale": fs("legs", 1.0, 0.75, 1.25),
        }
        for k in ("x", "y", "z"):
            self.sliders[k].add_class(f"repro-fighter-target-{k}")
        self.kick_button = widgets.Button(description="kick", tooltip="order a kick at the target")
        self.kick_button.add_class("repro-fighter-kick")
        self.punch_button = widgets.Button(description="punch", tooltip="order a punch at the target")
        self.punch_button.add_class("repro-fighter-punch")
        self.follow_box = widgets.Checkbox(value=bool(follow), description="follow the target", indent=False)
        self.user_toggle = widgets.ToggleButton(value=False, description="simulated user",
                                                tooltip="drive the target from a simulated user's head")
        self.user_toggle.add_class("repro-fighter-user")
        self.play = widgets.Play(value=0, min=0, max=len(self.user) - 1, step=3, interval=100,
                                 description="play the user")
        self.step_button = widgets.Button(description="step 1 s", tooltip="advance the simulated user by one second")
        self.image = widgets.Image(format="png", layout=widgets.Layout(width="880px",
                                                                       display=None if self.view else "none"))
        self.numbers_html = widgets.HTML()
        self.numbers_html.add_class("repro-fighter-numbers")
        self.status_html = widgets.HTML()
        self.status_html.add_class("repro-fighter-status")

        for k in ("x", "y", "z"):
            self.sliders[k].observe(self._guarded(self._on_target), names="value")
        for k in ("height", "arm_scale", "leg_scale"):
            self.sliders[k].observe(self._guarded(self._on_character), names="value")
        self.kick_button.on_click(self._guarded(lambda _b: self.kick()))
        self.punch_button.on_click(self._guarded(lambda _b: self.punch()))
        self.user_toggle.observe(self._guarded(self._on_user_toggle), names="value")
        self.play.observe(self._guarded(self._on_play), names="value")
        self.step_button.on_click(self._guarded(lambda _b: self.step_user(30)))

        self.widget = widgets.VBox([
            widgets.HBox([
                widgets.VBox([widgets.HTML("<b>target (the user's head)</b>"),
                              self.sliders["x"], self.sliders["y"], self.sliders["z"], self.follow_box]),
                widgets.VBox([widgets.HTML("<b>fighter (supervisor's choice)</b>"),
                              self.sliders["height"], self.sliders["arm_scale"], self.sliders["leg_scale"]]),
            ]),
            widgets.HBox([self.kick_button, self.punch_button, self.user_toggle, self.play, self.step_button]),
            self.numbers_html,
            self.status_html,
            self.image,
        ])
        self.widget.add_class("repro-fighter-panel")
        self._show()

    # ------------------------------------------------------------- helpers
    def _flush(self) -> None:
        if self._pending_character:
            self._pending_character = False
            self._apply_character()

    def _show_error(self, exc: BaseException) -> None:
        msg = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
        self.error = msg
        self._numbers_text = f"error: {msg}"
        self.numbers_html.value = f"<code>{html.escape(self._numbers_text)}</code>"
        self.status_html.value = f'<span style="color:#b00020">error: {html.escape(msg)}</span>'

    def _status(self) -> str:
        f = self.fighter
        ch = f.character
        t = self.target
        src = f"simulated user, t = {self._user_index / 30.0:.2f} s" if self.user_toggle.value else "sliders"
        return html.escape(
            f"fighter {ch.size:.2f} m (arms {ch.arm_length:.3f} m, legs {ch.leg_length:.3f} m) at "
            f"({f.position[0]:.2f}, {f.position[1]:.2f}), striking distance {f.striking_distance:.2f} m; "
            f"target ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f}) from {src}")

    def _show(self) -> None:
        self.numbers_html.value = f"<code>{html.escape(self._numbers_text)}</code>"
        self.status_html.value = self._status()

    # ------------------------------------------------------------- callbacks
    def _on_target(self, change) -> None:
        self.error = None
        self._show()

    def _on_character(self, change) -> None:
        if self._batch_depth:
            self._pending_character = True
        else:
            self._apply_character()

    def _apply_character(self) -> None:
        s = self.sliders
        self.fighter.set_character(character_from(s["height"].value, s["arm_scale"].value, s["leg_scale"].value,
                                                  base=self.fighter.db.actors[0]))
        self.error = None
        self._show()

    def _on_user_toggle(self, change) -> None:
        if change["new"]:
            self._goto_user(self.play.value)
        self._show()

    def _on_play(self, change) -> None:
        if self.user_toggle.value:
            self._goto_user(int(change["new"]))

    def _goto_user(self, index: int) -> None:
        """Move the simulated user to sample ``index``; the fighter follows tick by tick."""
        index = int(np.clip(index, 0, len(self.user) - 1))
        if index < self._user_index:  # replay from the start
            self._user_index = 0
        for i in range(self._user_index + 1, index + 1):
            self.fighter.follow(self.user[i], 1.0 / 30.0)
        self._user_index = index
        head = self.user[index]
        with self._batch():
            for k, v in zip("xyz", head):
                lo, hi = self.sliders[k].min, self.sliders[k].max
                self.sliders[k].value = float(np.clip(round(float(v), 2), lo, hi))
        self._head = np.array(head, dtype=float)
        self._show()

    # ------------------------------------------------------------- public API
    @property
    def target(self) -> np.ndarray:
        """The current target: the simulated head when the toggle is on, else the sliders."""
        if self.user_toggle.value and hasattr(self, "_head"):
            return self._head.copy()
        return np.array([self.sliders[k].value for k in "xyz"], dtype=float)

    @property
    def numbers_text(self) -> str:
        """The numbers line as displayed (:data:`FIGHTER_NUMBERS_FORMAT`), ``"error: ..."`` or the prompt."""
        return self._numbers_text

    @property
    def numbers(self) -> dict:
        """:func:`parse_fighter_numbers` of the line ({} before the first order or on error)."""
        try:
            return parse_fighter_numbers(self._numbers_text)
        except ValueError:
            return {}

    def set_target(self, x: float, y: float, z: float) -> None:
        """Move the target sliders (the simulated user is switched off)."""
        with self._batch():
            self.user_toggle.value = False
            for k, v in zip("xyz", (x, y, z)):
                self.sliders[k].value = float(v)
        self._show()

    def set_character(self, height: float | None = None, arm_scale: float | None = None,
                      leg_scale: float | None = None) -> None:
        """Change the fighter's height (m) and proportions (one update)."""
        with self._batch():
            for k, v in (("height", height), ("arm_scale", arm_scale), ("leg_scale", leg_scale)):
                if v is not None:
                    self.sliders[k].value = float(v)

    def use_simulated_user(self, on: bool = True) -> None:
        """Drive the target from the simulated user (``on``) or from the sliders."""
        self.user_toggle.value = bool(on)

    def step_user(self, samples: int = 30) -> None:
        """Advance the simulated user by ``samples`` (1/30 s each), switching it on."""
        if not self.user_toggle.value:
            self.user_toggle.value = True
        self.play.value = int(min(self.play.max, self._user_index + int(samples)))

    def order(self, kind: str) -> Strike | None:
        """Order a kick or a punch at the current target; the strike, or None (error shown) on failure."""
        try:
            target = self.target
            if self.follow_box.value:
                self.fighter.follow(target, 0.0, snap=True)
            strike = self.fighter.order(kind, target)
        except ValueError as exc:
            self._show_error(exc)
            return None
        self.last_strike = strike
        self.error = None
        self._numbers_text = format_fighter_numbers(strike)
        self._show()
        if self.view:
            fig = filmstrip_figure(strike)
            self.image.value = _png(fig)
        return strike

    def kick(self) -> Strike | None:
        """Press "kick"."""
        return self.order("kick")

    def punch(self) -> Strike | None:
        """Press "punch"."""
        return self.order("punch")

    def image_png(self) -> bytes:
        """The filmstrip shown (PNG bytes; empty before the first order or with ``view=False``)."""
        return bytes(self.image.value)

    def close(self) -> None:
        for w in [*self.sliders.values(), self.kick_button, self.punch_button, self.follow_box, self.user_toggle,
                  self.play, self.step_button, self.image, self.numbers_html, self.status_html, self.widget]:
            w.close()

    def __repr__(self) -> str:
        return f"FighterPanel({self.fighter!r})"

    def _repr_mimebundle_(self, **kwargs):
        bundle = self.widget._repr_mimebundle_(**kwargs)
        if isinstance(bundle, dict):
            bundle["text/plain"] = repr(self)
        return bundle

