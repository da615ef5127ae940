"""The fighter panel (repro.ui.fighter_panel): orders by method and by button, the parseable numbers,
the simulated user, the character sliders, the filmstrip view, errors shown instead of raised, the
strike animation."""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import RetrievalError
from repro.motion.runtime.fighter import KungFuFighter, character_from


@pytest.fixture(scope="module")
def fighter():
    return KungFuFighter("synthetic", seed=0)


def fresh(fighter, **kw):
    """A new fighter sharing the (expensive) retriever of the module's one."""
    return KungFuFighter(fighter.db, retriever=fighter.retriever, **kw)


@pytest.fixture()
def panel(fighter):
    from repro.ui.fighter_panel import FighterPanel

    p = FighterPanel(fresh(fighter), view=False)
    yield p
    p.close()


def test_panel_kick_and_punch_update_the_numbers(panel):
    from repro.ui.fighter_panel import format_fighter_numbers, parse_fighter_numbers

    assert panel.numbers == {}
    assert "repro-fighter-numbers" in panel.numbers_html._dom_classes
    panel.set_target(0.3, 1.3, 0.2)
    s = panel.kick()
    n = panel.numbers
    assert n["kind"] == "kick" and n["clip"] == s.clip_name and "kick" in n["clip"]
    assert n["d"] == pytest.approx(s.retrieval.d, abs=1e-4)
    assert n["d_qr"] == pytest.approx(s.retrieval.d_qr, abs=1e-4)
    assert n["d_cr"] == pytest.approx(s.retrieval.d_cr, abs=1e-4)
    assert n["hit_error"] < 0.01 and n["reached"] == "yes"
    assert n["budget"] == pytest.approx(1000 / 30, abs=1e-3)
    for k in ("prepare", "search", "load_convert", "adapt", "adapt_per_frame", "first_frame"):
        assert n[k] > 0
    assert n["within_budget"] == ("yes" if s.within_budget else "no")
    assert panel.numbers_text == format_fighter_numbers(s)
    assert panel.numbers_text in panel.numbers_html.value.replace("&gt;", ">")
    # the button does the same as the method
    panel.set_target(0.0, 1.6, 0.0)
    panel.punch_button.click()
    assert panel.numbers["kind"] == "punch" and "punch" in panel.numbers["clip"]
    assert panel.last_strike.kind == "punch"
    assert parse_fighter_numbers(panel.numbers_text)["reached"] == "yes"
    panel.kick_button.click()
    assert panel.numbers["kind"] == "kick"


def test_panel_without_following_reports_unreachable_targets(fighter):
    from repro.ui.fighter_panel import FighterPanel

    p = FighterPanel(fresh(fighter, position=(0.0, -1.4)), view=False, follow=False)
    p.set_target(0.0, 1.7, 1.5)
    s = p.punch()
    assert not s.reached and p.numbers["reached"] == "no" and p.numbers["hit_error"] > 1.0
    p.close()


def test_panel_simulated_user_drives_the_target(panel):
    panel.step_user(30)
    assert panel.user_toggle.value
    np.testing.assert_array_equal(panel.target, panel.user[30])
    assert panel.fighter.time == pytest.approx(1.0)
    assert panel.sliders["x"].value == pytest.approx(panel.user[30][0], abs=0.006)
    panel.play.value = 90  # the Play widget moves the user on
    np.testing.assert_array_equal(panel.target, panel.user[90])
    s = panel.punch()
    np.testing.assert_array_equal(s.target, panel.user[90])
    panel.use_simulated_user(False)
    assert panel.target[0] == panel.sliders["x"].value


def test_panel_character_sliders_change_the_fighter(panel):
    panel.set_character(height=1.5, arm_scale=0.8, leg_scale=1.2)
    ch = panel.fighter.character
    assert ch.size == pytest.approx(1.5, abs=1e-9)
    ref = character_from(1.5, 0.8, 1.2, base=panel.fighter.db.actors[0])
    np.testing.assert_allclose(ch.offsets, ref.offsets)
    panel.sliders["height"].value = 2.0
    assert panel.fighter.character.size == pytest.approx(2.0)
    assert "2.00 m" in panel.status_html.value


def test_panel_view_draws_a_filmstrip_and_parse_rejects_other_text(fighter):
    from repro.ui.fighter_panel import (
        FighterPanel,
        filmstrip_figure,
        key_frames,
        parse_fighter_numbers,
    )

    p = FighterPanel(fresh(fighter), view=True)
    assert p.image_png() == b""
    s = p.punch()
    png = p.image_png()
    assert png.startswith(b"\x89PNG")
    frames = key_frames(s)
    assert frames[0] == 0 and s.tc in frames and frames == sorted(set(frames))
    fig = filmstrip_figure(s)
    assert len(fig.axes) == len(frames)
    with pytest.raises(ValueError):
        filmstrip_figure(s, frames=[s.n_frames])
    for text in ("press kick or punch", "error: boom", p.numbers_text + " | extra: 1"):
        with pytest.raises(ValueError):
            parse_fighter_numbers(text)
    p.close()


def test_panel_callbacks_show_errors_instead_of_raising(panel, monkeypatch):
    def boom(*a, **k):
        raise RetrievalError("no clip for you")

    monkeypatch.setattr(panel.fighter, "order", boom)
    panel.kick_button.click()  # must not raise
    assert panel.numbers_text.startswith("error: no clip for you")
    assert panel.numbers == {}


def test_animation_html_is_a_player(fighter):
    from repro.ui.fighter_panel import animation_html

    f = fresh(fighter)
    f.follow((0, 1.6, 0), 0.0, snap=True)
    s = f.punch((0, 1.6, 0))
    out = animation_html(s, every=8)  # every 8th frame keeps it small
    assert "<script" in out and "animation" in out.lower()




def test_panel_says_the_strike_in_words_with_the_numbers_behind_details(panel):
    """Issue 26, item 7: the readout is plain words; the raw numbers line is behind a "details" toggle."""
    from repro.ui.fighter_panel import fighter_readout

    assert panel.readout_text == "press kick or punch"
    assert panel.numbers_html.layout.display == "none" and not panel.details_toggle.value
    panel.set_target(0.3, 1.3, 0.2)
    s = panel.kick()
    words = panel.readout_text
    assert words == fighter_readout(s)
    assert words.startswith("kick: hit the target (") and "mm off)" in words
    assert f"{s.tc * s.motion.frame_time:.2f} s after the order" in words
    assert f"first frame in {s.timings['first_frame'] * 1e3:.0f} ms" in words and "33 ms budget" in words
    assert "d_qr" not in words and "e-" not in words and "nan" not in words
    assert "<b>kick: hit the target" in panel.readout_html.value
    panel.details_toggle.value = True
    assert panel.numbers_html.layout.display is None
    panel.details_toggle.value = False
    assert panel.numbers_html.layout.display == "none"


def test_readout_of_a_missed_strike_says_by_how_much(fighter):
    from repro.ui.fighter_panel import FighterPanel

    p = FighterPanel(fresh(fighter, position=(0.0, -1.4)), view=False, follow=False)
    p.set_target(0.0, 1.7, 1.5)
    s = p.punch()
    assert not s.reached
    assert p.readout_text.startswith(f"punch: missed the target by {s.hit_error:.2f} m (out of reach)")
    p.close()


def test_character_change_orders_the_last_strike_again_with_the_new_body(fighter):
    """Issue 26, item 9: moving height, arms or legs shows the new fighter at once (the last strike replayed)."""
    from repro.ui.fighter_panel import FighterPanel

    p = FighterPanel(fresh(fighter), view=True)
    p.set_character(height=1.5)  # no strike yet: nothing to replay
    assert p.last_strike is None and p.image_png() == b""
    p.set_target(0.3, 1.3, 0.4)
    first = p.kick()
    png, digest = p.image_png(), p.view3d.digest
    p.sliders["height"].value = 1.9
    again = p.last_strike
    assert again is not first and again.kind == "kick"
    np.testing.assert_array_equal(again.target, first.target)
    assert p.fighter.character.size == pytest.approx(1.9)
    assert p.image_png() != png and p.view3d.digest != digest  # filmstrip and 3D view repainted
    assert p.numbers["kind"] == "kick" and p.readout_text.startswith("kick: ")
    p.close()
