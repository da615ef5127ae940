"""The kung-fu fighter panel (ipywidgets) and its figures, Pronost et al. Sections 3-4.

:class:`FighterPanel` plays the supervisor's keyboard and the user's tracked head of the
paper's experiment (Section 4, figure 1):

- target sliders ``x``, ``z`` (the 3 m x 3 m area, metres) and ``y`` (the head height);
- the fighter's morphology, which "the supervisor can change [...] and immediately
  visualizes the result" (Section 3.1): height (1.2-2.2 m), arm and leg proportions
  (±25 %);
- "kick" and "punch" buttons: the order (:meth:`repro.motion.runtime.fighter.KungFuFighter.order`:
  retrieval, conversion, adaptation, each stage timed);
- a "simulated user" toggle: the target then comes from
  :func:`repro.motion.runtime.fighter.simulated_user` (a ``Play`` widget, or the "step" button,
  walks through it; the fighter follows the head as in the paper);
- a filmstrip of the strike (:func:`filmstrip_figure`: a few key frames of the stick
  figure reaching the target sphere; the unadapted motion in grey, as the paper's Fig.
  10 shows the modified posture over the original);
- the strike said in words (:func:`fighter_readout`, CSS class ``repro-fighter-readout``),
  e.g. "kick: hit the target (0 mm off), 0.53 s after the order; first frame in 20 ms
  (within the 33 ms budget); the retrieved clip alone missed by 12 cm", readable on a
  projector;
- behind a "details" toggle, the line of numbers in stable, parseable text
  (:data:`FIGHTER_NUMBERS_FORMAT`, CSS class ``repro-fighter-numbers``), read back by
  :func:`parse_fighter_numbers`, e.g.
  ``order: kick | clip: actor2_kick_round_right_high | d: 0.0690 | d_qr: 0.0412 |
  d_cr: 0.0278 | hit error: 7.8e-11 m | reached: yes | prepare: 3.656 ms | search:
  0.284 ms | load+convert: 3.149 ms | adapt: 5.689 ms | adapt per frame: 0.082 ms |
  first frame: 12.778 ms | budget: 33.333 ms | within budget: yes``.

The fighter answers every control: a change of height, arms or legs orders the last
strike again (same kind, same target) with the new body, so the 3D view, the filmstrip and
the readouts show the new fighter at once.  The panel's first screen fits 1280 x 720
(controls in two columns beside the 3D view, the filmstrip below).

:func:`animation_html` renders a strike as a ``matplotlib.animation`` JavaScript player
(notebooks), :func:`animation_png` as an animated PNG that the browser plays by itself
(the panel with ``animate=True``, the app); both from :mod:`repro.ui.strike_view`.
Everything is drawn with matplotlib's Agg
backend and is deterministic for a given strike.  No widget callback raises: errors are
shown in the panel.
"""

from __future__ import annotations

import html

import ipywidgets as widgets
import numpy as np

from repro.ui.panel import PanelCallbacks, parse_numbers_line
from repro.ui.strike_view import FilmstripView, animation_html, animation_png, key_frames
from repro.motion.runtime.fighter import AREA, KungFuFighter, Strike, character_from, simulated_user

__all__ = [
    "FighterPanel",
    "FIGHTER_NUMBERS_FORMAT",
    "format_fighter_numbers",
    "fighter_readout",
    "parse_fighter_numbers",
    "filmstrip_figure",
    "key_frames",
    "animation_html",
    "animation_png",
    "numbers_html",
    "readout_html",
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


def _distance(metres: float) -> str:
    """A distance for a reader: millimetres under 10 cm, centimetres under 1 m, else metres."""
    if metres < 0.1:
        return f"{1000 * metres:.0f} mm"
    return f"{100 * metres:.0f} cm" if metres < 1.0 else f"{metres:.2f} m"


def fighter_readout(strike: Strike) -> str:
    """A strike in plain words (the panel's readout; the raw numbers are :func:`format_fighter_numbers`).

    Whether the strike reached the target and how far off it landed (the hit error at the
    contact, Pronost et al. Section 3.4), when it lands, whether the first adapted frame was
    ready within the reaction budget (1/30 s, Section 4) and how far the retrieved clip alone
    would have missed, e.g. "kick: hit the target (0 mm off), 0.53 s after the order; first
    frame in 20 ms (within the 33 ms budget); the retrieved clip alone missed by 12 cm".
    """
    t = strike.timings["first_frame"] * 1e3
    budget = strike.budget_s * 1e3
    when = f"{strike.tc * strike.motion.frame_time:.2f} s after the order"
    verdict = (f"hit the target ({_distance(strike.hit_error)} off), {when}" if strike.reached
               else f"missed the target by {_distance(strike.hit_error)} (out of reach), {when}")
    return (f"{strike.kind}: {verdict}; first frame in {t:.0f} ms "
            f"({'within' if strike.within_budget else 'over'} the {budget:.0f} ms budget); "
            f"the retrieved clip alone missed by {_distance(strike.unadapted_error)}")


def parse_fighter_numbers(text: str) -> dict:
    """The numbers line back as a dict: floats (metres, milliseconds) and the text fields.

    Keys: ``kind, clip, d, d_qr, d_cr, hit_error, reached, prepare, search,
    load_convert, adapt, adapt_per_frame, first_frame, budget, within_budget``.  Raises
    ``ValueError`` for anything else (e.g. ``"error: ..."`` or the text shown before the
    first order).
    """
    return parse_numbers_line(text, _FIELDS, _TEXT_FIELDS, pattern=r"([a-z_+ ]+): (\S+)(?: (m|ms))?",
                              panel="the fighter panel")


# ----------------------------------------------------------------------- drawing
def filmstrip_figure(strike: Strike, frames=None, *, n: int = 5, head_radius: float = 0.1, width: float = 11.0,
                     title: str | None = None, original: bool = True):
    """Key frames of a strike side by side: the stick figure reaching the target (Fig. 10).

    Each panel is the same fixed side view (:class:`repro.ui.strike_view.StrikeCamera`)
    of one frame: the adapted skeleton (blue, with a head), the unadapted one (grey,
    thinner; the clip retrieved, placed and blended, before the constraint solver), the
    target (a navy circle of ``head_radius`` metres around the stored head position) and
    the hit point's path so far (dashed).  Titles give the time from the order.

    Returns
    -------
    matplotlib.figure.Figure
        Not attached to pyplot (draw it with ``display(fig)`` or save it).
    """
    frames = key_frames(strike, n) if frames is None else [int(f) for f in frames]
    F = strike.n_frames
    if not frames or min(frames) < 0 or max(frames) >= F:
        raise ValueError(f"frames must be in [0, {F - 1}], got {frames}")
    view = FilmstripView(len(frames), width=width, head_radius=head_radius)
    return view.draw(strike, frames, title=title, original=original)


def numbers_html(text: str) -> str:
    """The numbers line as HTML: each ``name: value unit`` kept on one line, breaks only between fields.

    The text the browser shows (``innerText``) is ``text`` itself, so
    :func:`parse_fighter_numbers` reads the page as it reads the panel; the whole line
    is also the element's tooltip (``title``).
    """
    parts = [f'<span style="white-space:nowrap">{html.escape(p)}</span>' for p in text.split(" | ")]
    return f'<code style="white-space:normal" title="{html.escape(text)}">' + " | ".join(parts) + "</code>"


def readout_html(text: str) -> str:
    """The readout as HTML: the verdict (up to the first ";") in bold, the rest plain; its text is ``text``."""
    head, sep, rest = text.partition(";")
    return f"<b>{html.escape(head)}</b>{html.escape(sep + rest)}"


#: Labels for the icon-only buttons of the ``Play`` widget (play/pause, stop, loop) and the panel's layout.
PANEL_CSS = """<style>
.repro-fighter-play { width: auto !important; flex: none; }
.repro-fighter-play button { width: auto !important; min-width: max-content; overflow: visible !important;
  text-overflow: clip !important; padding: 0 8px; flex: none; }
.repro-fighter-play button:nth-of-type(1)::after { content: " play / pause"; }
.repro-fighter-play button:nth-of-type(2)::after { content: " stop"; }
.repro-fighter-play button:nth-of-type(3)::after { content: " loop"; }
.repro-fighter-numbers code { font-size: 12px; line-height: 1.5; }
.repro-fighter-readout { font-size: 16px; line-height: 1.4; }
.repro-fighter-readout b { font-size: 18px; }
.repro-fighter-panel button.repro-fighter-kick, .repro-fighter-panel button.repro-fighter-punch {
  font-size: 16px; font-weight: bold; height: 40px; }
.repro-fighter-panel img { max-width: 100%; height: auto; }
</style>"""


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
    view3d : bool, default True
        Also play each strike in a 3D view drawn in the browser
        (:class:`repro.ui.webview.StrikeWebView`: rotate, zoom, pause), sent before the
        filmstrip is drawn: the first picture of an order.
    animate : bool, default False
        After the filmstrip, also play the strike as an animation (an animated PNG in
        :attr:`animation`, drawn after the filmstrip is shown; about half a second more
        of kernel time per order).
    user_seed, user_duration : int, float
        The simulated user's trajectory (:func:`simulated_user` at 30 Hz).

    Attributes
    ----------
    widget : ipywidgets.VBox
        The panel (class ``repro-fighter-panel``); displaying the panel displays it.
    sliders : dict
        ``x``, ``y``, ``z``, ``height``, ``arm_scale``, ``leg_scale``.
    kick_button, punch_button, follow_box, user_toggle, play, step_button, image, readout_html, details_toggle,
    numbers_html, status_html
    fighter : KungFuFighter
    last_strike : Strike or None
    """

    def __init__(self, fighter: KungFuFighter | None = None, *, target=(0.0, 1.65, 0.0), follow: bool = True,
                 view: bool = True, view3d: bool = True, animate: bool = False, user_seed: int = 0, user_duration: float = 20.0):
        self.fighter = fighter if fighter is not None else KungFuFighter()
        self.view = bool(view)
        self.animate = bool(animate)
        self.view3d = None
        if view and view3d:
            from repro.ui.webview import StrikeWebView

            self.view3d = StrikeWebView()
        self._filmstrip: FilmstripView | None = None
        self.user = simulated_user(user_seed, user_duration, 30.0)
        self._user_index = 0
        self.last_strike: Strike | None = None
        self.error: str | None = None
        self._numbers_text = "press kick or punch"
        self._readout_text = "press kick or punch"
        self._batch_depth = 0
        self._pending_character = False
        self._make_sliders(target)
        self._make_controls(follow)
        self._connect()
        self.widget = self._layout()
        self._show()

    # ------------------------------------------------------------- the widgets
    def _make_sliders(self, target) -> None:
        """The target (the user's head) and the fighter's morphology (the supervisor's choice)."""
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

    def _make_controls(self, follow: bool) -> None:
        """The order buttons, the simulated user's controls, the pictures and the readouts."""
        self.kick_button = widgets.Button(description="kick", tooltip="order a kick at the target")
        self.kick_button.add_class("repro-fighter-kick")
        self.punch_button = widgets.Button(description="punch", tooltip="order a punch at the target")
        self.punch_button.add_class("repro-fighter-punch")
        self.follow_box = widgets.Checkbox(value=bool(follow), description="follow the target", indent=False)
        self.user_toggle = widgets.ToggleButton(value=False, description="simulated user",
                                                tooltip="drive the target from a simulated user's head")
        self.user_toggle.add_class("repro-fighter-user")
        self.play = widgets.Play(value=0, min=0, max=len(self.user) - 1, step=3, interval=100,
                                 description="the user", tooltip="play the simulated user's head")
        self.play.add_class("repro-fighter-play")
        self.step_button = widgets.Button(description="step 1 s", tooltip="advance the simulated user by one second")
        for b in (self.kick_button, self.punch_button):
            b.layout = widgets.Layout(width="120px")
        self.image = widgets.Image(format="png", layout=widgets.Layout(
            width="990px", max_width="100%", display=None if self.view else "none"))
        self.image.add_class("repro-fighter-filmstrip")
        self.animation = widgets.Image(format="png", layout=widgets.Layout(
            width="400px", display=None if self.view and self.animate else "none"))
        self.animation.add_class("repro-fighter-animation")
        self.readout_html = widgets.HTML(layout=widgets.Layout(width="100%"))
        self.readout_html.add_class("repro-fighter-readout")
        self.details_toggle = widgets.ToggleButton(value=False, description="details",
                                                   tooltip="show the raw numbers (distances, timings)")
        self.details_toggle.add_class("repro-fighter-details")
        self.numbers_html = widgets.HTML(layout=widgets.Layout(display="none"))
        self.numbers_html.add_class("repro-fighter-numbers")
        self.status_html = widgets.HTML()
        self.status_html.add_class("repro-fighter-status")

    def _connect(self) -> None:
        for k in ("x", "y", "z"):
            self.sliders[k].observe(self._guarded(self._on_target), names="value")
        for k in ("height", "arm_scale", "leg_scale"):
            self.sliders[k].observe(self._guarded(self._on_character), names="value")
        self.kick_button.on_click(self._guarded(lambda _b: self.kick()))
        self.punch_button.on_click(self._guarded(lambda _b: self.punch()))
        self.user_toggle.observe(self._guarded(self._on_user_toggle), names="value")
        self.play.observe(self._guarded(self._on_play), names="value")
        self.step_button.on_click(self._guarded(lambda _b: self.step_user(30)))
        self.details_toggle.observe(self._guarded(self._on_details), names="value")

    def _layout(self) -> widgets.VBox:
        """The first screen (1280 x 720): the sliders, the orders and the readouts beside the 3D view; below, the
        filmstrip (and the animation)."""
        sliders = widgets.VBox([
            widgets.HTML("<b>target (the user's head)</b>"),
            self.sliders["x"], self.sliders["y"], self.sliders["z"], self.follow_box,
            widgets.HTML("<b>fighter (supervisor's choice)</b>"),
            self.sliders["height"], self.sliders["arm_scale"], self.sliders["leg_scale"],
        ], layout=widgets.Layout(flex="0 0 auto"))
        orders = widgets.VBox([
            widgets.HBox([self.kick_button, self.punch_button]),
            self.readout_html,
            widgets.HBox([self.user_toggle, self.step_button]),
            self.play,
            self.status_html,
            self.details_toggle,
            self.numbers_html,
        ], layout=widgets.Layout(flex="1 1 0", min_width="280px", max_width="420px"))
        top = widgets.HBox([sliders, orders, *([self.view3d.widget] if self.view3d else [])],
                           layout=widgets.Layout(align_items="flex-start", flex_flow="row wrap"))
        # the animation only where asked: without it the panel shows one picture (one <img>) below the view
        box = widgets.VBox([
            top,
            *([self.animation] if self.animate else []),
            self.image,
            widgets.HTML(PANEL_CSS),
        ])
        box.add_class("repro-fighter-panel")
        return box

    # ------------------------------------------------------------- helpers
    def _flush(self) -> None:
        if self._pending_character:
            self._pending_character = False
            self._apply_character()

    def _show_error(self, exc: BaseException) -> None:
        msg = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
        self.error = msg
        self._numbers_text = f"error: {msg}"
        self.numbers_html.value = numbers_html(self._numbers_text)
        self._readout_text = f"error: {msg}"
        self.readout_html.value = f'<span style="color:#b00020">error: {html.escape(msg)}</span>'
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
        self.numbers_html.value = numbers_html(self._numbers_text)
        self.readout_html.value = readout_html(self._readout_text)
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
        """The new body; the last strike ordered again with it (same kind, same target): shown at once."""
        s = self.sliders
        self.fighter.set_character(character_from(s["height"].value, s["arm_scale"].value, s["leg_scale"].value,
                                                  base=self.fighter.db.actors[0]))
        self.error = None
        if self.last_strike is not None:
            self.order(self.last_strike.kind)
        else:
            self._show()

    def _on_details(self, change) -> None:
        self.numbers_html.layout.display = None if change["new"] else "none"

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
    def readout_text(self) -> str:
        """The strike in words as displayed (:func:`fighter_readout`), ``"error: ..."`` or the prompt."""
        return self._readout_text

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
        self._readout_text = fighter_readout(strike)
        self._show()
        if self.view:
            if self.view3d is not None:
                self.view3d.show(strike)  # sent first: the page draws it while the filmstrip is drawn here
            if self._filmstrip is None:
                self._filmstrip = FilmstripView()
            self.image.value = self._filmstrip.render(strike)  # sent to the browser now
            if self.animate:
                self.animation.value = animation_png(strike)
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

    def animation_png(self) -> bytes:
        """The animation shown (APNG bytes; empty unless ``animate``)."""
        return bytes(self.animation.value)

    def close(self) -> None:
        for w in [*self.sliders.values(), self.kick_button, self.punch_button, self.follow_box, self.user_toggle,
                  self.play, self.step_button, self.image, self.animation, self.readout_html, self.details_toggle,
                  self.numbers_html, self.status_html, self.widget]:
            w.close()
        if self.view3d is not None:
            self.view3d.close()

    def __repr__(self) -> str:
        return f"FighterPanel({self.fighter!r})"

    def _repr_mimebundle_(self, **kwargs):
        bundle = self.widget._repr_mimebundle_(**kwargs)
        if isinstance(bundle, dict):
            bundle["text/plain"] = repr(self)
        return bundle

