"""The notebooks' widget panels in a real browser: JupyterLab + headless Chromium (Playwright).

Each test copies a committed notebook into the module's JupyterLab folder (see
``conftest.py``), opens it, runs all cells, then moves a widget the way a user does and
reads back what the page shows.  Screenshots: ``test-artifacts/browser/``.
"""

from __future__ import annotations

import math
import time

import pytest

from tests.browser.conftest import STEP_TIMEOUT
from tests.conftest import REPO

pytestmark = pytest.mark.browser

NOTEBOOKS = REPO / "notebooks"
BLENDSHAPE_NB = NOTEBOOKS / "02_alpha_sweep.ipynb"
FIGHTER_NB = NOTEBOOKS / "05_kungfu_fighter.ipynb"


def wait_for_numbers(nb, selector, parse, predicate, what: str, timeout: float = STEP_TIMEOUT):
    """Poll the numbers line until ``predicate(parse(text))`` holds; the parsed numbers."""
    deadline = time.monotonic() + timeout
    text = ""
    while True:
        text = nb.text(selector)
        try:
            numbers = parse(text)
        except ValueError:
            numbers = None
        if numbers is not None and predicate(numbers):
            return numbers
        if time.monotonic() > deadline:
            nb.screenshot("timeout-" + "".join(c if c.isalnum() else "-" for c in what))
            pytest.fail(f"waited {timeout:.0f} s for {what}; the numbers line shows {text!r}", pytrace=False)
        time.sleep(0.1)


def wait_image_change(nb, selector: str, old_src: str | None, timeout: float = STEP_TIMEOUT) -> str:
    """Wait until the image's ``src`` (an ipywidgets Image: a new blob URL per value) differs from ``old_src``."""
    nb.page.wait_for_function("([sel, old]) => { const e = document.querySelector(sel); return e && e.src && e.src !== old; }",
                              arg=[selector, old_src], timeout=timeout * 1000)
    return nb.page.locator(selector).get_attribute("src")


def expected_fig5_numbers(alpha: float) -> dict:
    """What the notebook's panel must show at ``alpha``, computed here by the library."""
    from repro.blendshapes import load_model
    from repro.ui.face_panel import BlendshapePanel

    panel = BlendshapePanel(load_model("procedural"), view="none", region="under_left_eye", attenuation=True)
    panel.set_sliders(Wince=0.7, SneerLeft=0.7, SneerRight=0.7)
    panel.set_alpha(alpha)
    numbers = panel.numbers
    panel.close()
    return numbers


def assert_numbers_match(shown: dict, alpha: float) -> None:
    want = expected_fig5_numbers(alpha)
    for key in ("selected_motion", "unselected_fidelity"):
        assert shown[key] == pytest.approx(want[key], rel=1e-4), (key, shown, want)


@pytest.mark.render  # the notebook renders with pyvista
@pytest.mark.data("ict")  # and compares with the ICT face
def test_alpha_slider_in_the_fig5_panel(open_notebook):
    from repro.ui.face_panel import parse_numbers

    nb = open_notebook(BLENDSHAPE_NB)
    nb.run_all()
    panel, numbers_sel = ".repro-blendshape-panel", ".repro-blendshape-panel .repro-numbers"
    handle = nb.page.locator(".repro-blendshape-panel .repro-alpha .noUi-handle")
    handle.scroll_into_view_if_needed()
    nb.page.wait_for_selector(numbers_sel)

    # the notebook's last cell leaves the panel at the default alpha of the Fig. 5 selection
    start = wait_for_numbers(nb, numbers_sel, parse_numbers, lambda n: n["alpha"] == 335, "alpha 335")
    assert start["attenuation"] == "on"
    assert_numbers_match(start, 335.0)
    start_src = nb.page.locator(f"{panel} img").get_attribute("src")
    nb.screenshot("1-start", panel)
    nb.step("panel at alpha 335")

    # drag the alpha handle to the right (larger alpha) and release
    box = handle.bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    nb.page.mouse.move(x, y)
    nb.page.mouse.down()
    nb.page.mouse.move(x + 60, y, steps=12)
    nb.page.mouse.up()
    up = wait_for_numbers(nb, numbers_sel, parse_numbers, lambda n: n["alpha"] != 335, "alpha to change after the drag")
    assert up["alpha"] > 1.5 * 335, f"dragging the alpha handle right should raise alpha: {start} -> {up}"
    assert up["selected_motion"] < start["selected_motion"], f"larger alpha, less selected motion: {start} -> {up}"
    assert up["attenuation"] == "on"
    # the slider's value is 10**exponent, the exponent on the slider's 0.01 grid
    assert math.log10(up["alpha"]) == pytest.approx(round(math.log10(up["alpha"]), 2), abs=1e-4)
    assert_numbers_match(up, up["alpha"])
    wait_image_change(nb, f"{panel} img", start_src)  # the face is redrawn
    nb.screenshot("2-after-drag", panel)
    nb.step(f"dragged: alpha {up['alpha']:g}")

    # three ArrowLeft presses on the focused handle: alpha down by 10**0.03, each press one update
    handle.focus()
    for _ in range(3):
        nb.page.keyboard.press("ArrowLeft")
    target = up["alpha"] / 10**0.03
    down = wait_for_numbers(nb, numbers_sel, parse_numbers, lambda n: n["alpha"] == pytest.approx(target, rel=1e-4),
                            f"alpha {target:.6g} after 3 x ArrowLeft")
    assert down["selected_motion"] > up["selected_motion"], f"smaller alpha, more selected motion: {up} -> {down}"
    assert_numbers_match(down, down["alpha"])
    nb.screenshot("3-after-arrows", panel)
    nb.step(f"3 x ArrowLeft: alpha {down['alpha']:g}")


def test_kick_button_in_the_fighter_panel(open_notebook):
    from repro.ui.fighter_panel import parse_fighter_numbers

    nb = open_notebook(FIGHTER_NB)
    nb.run_all()
    panel, numbers_sel = ".repro-fighter-panel", ".repro-fighter-panel .repro-fighter-numbers"
    nb.page.wait_for_selector(numbers_sel, state="attached")
    nb.page.locator(f"{panel} .repro-fighter-details").click()  # the raw numbers line, behind "details"
    nb.page.wait_for_selector(numbers_sel, state="visible")
    nb.page.locator(f"{panel} .repro-fighter-kick").scroll_into_view_if_needed()
    image = f"{panel} img.repro-fighter-filmstrip"
    src = nb.page.locator(image).get_attribute("src")
    nb.screenshot("1-start", panel)

    # punch first, so that the kick that follows is visibly a new order from the browser
    nb.page.locator(f"{panel} .repro-fighter-punch").click()
    punch = wait_for_numbers(nb, numbers_sel, parse_fighter_numbers,
                             lambda n: n["kind"] == "punch", "the punch order")
    src = wait_image_change(nb, image, src)  # the filmstrip of the punch
    nb.screenshot("2-after-punch", panel)
    nb.step(f"punch: {punch['clip']}")
    nb.page.locator(f"{panel} .repro-fighter-kick").click()
    kick = wait_for_numbers(nb, numbers_sel, parse_fighter_numbers,
                            lambda n: n["kind"] == "kick", "the kick order")
    wait_image_change(nb, image, src)  # the filmstrip of the kick
    nb.screenshot("3-after-kick", panel)
    nb.step(f"kick: {kick['clip']}")

    # the notebook's fighter uses the synthetic database, whose clip names carry their kind
    assert "punch" in punch["clip"] and "kick" in kick["clip"], (punch, kick)

    # the 3D view (drawn by the page's script, in JupyterLab as in Voila) shows the kick sent for this order
    import base64

    from repro.ui.webview import unpack

    frame = f"{panel} img.repro-webview-frame"
    canvas = f"{panel} canvas.repro-webview-canvas"
    data = base64.b64decode(nb.page.evaluate("""async (sel) => {
        const buf = new Uint8Array(await (await fetch(document.querySelector(sel).src)).arrayBuffer());
        let s = ''; for (let i = 0; i < buf.length; i += 0x8000) s += String.fromCharCode.apply(null, buf.subarray(i, i + 0x8000));
        return btoa(s); }""", frame))
    head, _ = unpack(data)
    assert head["strike"] == "kick" and head["clip"] == kick["clip"], head
    nb.page.wait_for_function("([sel, d]) => document.querySelector(sel).dataset.painted === d",
                              arg=[canvas, head["digest"]], timeout=STEP_TIMEOUT * 1000)
    nb.screenshot("4-3d-view", canvas)

    for n in (punch, kick):
        assert n["clip"] and n["clip"] != "-", n  # a clip was chosen
        assert n["d"] == pytest.approx(n["d_qr"] + n["d_cr"], abs=2e-4), n  # d = d_qr + d_cr (Section 3.3)
        stages = ("prepare", "search", "load_convert", "adapt", "adapt_per_frame", "first_frame")
        assert all(math.isfinite(n[k]) and n[k] > 0 for k in stages), n  # every stage timed, in ms
        assert n["first_frame"] >= n["search"], n
        assert n["budget"] == pytest.approx(1000 / 30, abs=1e-3), n  # "less than 1/30s"
        assert n["within_budget"] == ("yes" if n["first_frame"] <= n["budget"] else "no"), n
        assert n["reached"] in ("yes", "no"), n
