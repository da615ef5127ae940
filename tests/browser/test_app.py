"""The teaching apps (``repro app face|fighter``, Voilà) in headless Chromium (Playwright).

Each test starts the app as a subprocess on a free port (its own process group, always
killed at the end), opens it, moves a widget the way a user does and checks what the page
then paints.  Latencies (input event -> new picture decoded and painted, measured in the
page) are printed, benchmark style, never asserted; what is asserted is correctness:
the picture finally drawn is the one of the last value the user stopped on.
"""

from __future__ import annotations

import base64
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import time

import pytest

from tests.browser.conftest import (
    ARTIFACTS,
    CHROMIUM,
    CHROMIUM_ARGS,
    browser_unavailable_reason,
)
from tests.conftest import REPO

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: Bound of the app's start (kernel start, the notebook run: the ICT face or the fighter's database).
START_TIMEOUT = 240.0
STEP_TIMEOUT = 60.0

# In the page: the time of every key press / pointer press (capture phase, before the widget sees it), and the
# time each watched <img> got a new src *painted* (decoded, then the next animation frame).
WATCH_JS = """(sel) => {
  window.__inputs = [];
  const note = e => window.__inputs.push(performance.now());
  document.addEventListener('keydown', note, true);
  document.addEventListener('pointerdown', note, true);
  window.__paints = window.__paints || {};
  const img = document.querySelector(sel);
  window.__paints[sel] = [];
  new MutationObserver(() => {
    const src = img.src;
    img.decode().then(() => requestAnimationFrame(() =>
      window.__paints[sel].push({t: performance.now(), src: src}))).catch(() => {});
  }).observe(img, {attributes: true, attributeFilter: ['src']});
}"""

FETCH_JS = """async (sel) => {
  const img = document.querySelector(sel);
  const buf = new Uint8Array(await (await fetch(img.src)).arrayBuffer());
  let s = ''; for (let i = 0; i < buf.length; i += 0x8000) s += String.fromCharCode.apply(null, buf.subarray(i, i + 0x8000));
  return btoa(s);
}"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class App:
    def __init__(self, which: str):
        self.port = _free_port()
        self.url = f"http://127.0.0.1:{self.port}/"
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        self.log = ARTIFACTS / f"app-{which}-{self.port}.log"  # one per app: two test processes may each start one
        with open(self.log, "wb") as out:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "repro", "app", which, "--port", str(self.port), "--no-browser"],
                cwd=REPO, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                start_new_session=True, env=self._env())
        deadline = time.monotonic() + STEP_TIMEOUT
        while True:
            if self.proc.poll() is not None:
                pytest.fail(f"repro app {which} exited with {self.proc.returncode}:\n{self.tail()}", pytrace=False)
            try:  # listening (a GET of the page would run the notebook: Voila executes it per request)
                socket.create_connection(("127.0.0.1", self.port), timeout=2).close()
                break
            except OSError:
                if time.monotonic() > deadline:
                    self.stop()
                    pytest.fail(f"repro app {which} did not answer in {STEP_TIMEOUT:.0f} s:\n{self.tail()}",
                                pytrace=False)
                time.sleep(0.3)
        # the app answers only with its token, printed once inside the URL (issue 23, section 7)
        found = re.search(rf"http://127\.0\.0\.1:{self.port}/\?token=[A-Za-z0-9_-]+", self.log.read_text())
        if found is None:
            self.stop()
            pytest.fail(f"repro app {which} printed no URL with its token:\n{self.tail()}", pytrace=False)
        self.url = found.group(0)

    @staticmethod
    def _env() -> dict:
        """This environment, with this checkout first on the path of the app's kernel too.

        (Voilà starts the kernel in the notebook's folder, so without it the kernel would
        import whichever ``repro`` is installed, not the one under test.)
        """
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
        return env

    def tail(self, n: int = 30) -> str:
        return "\n".join(self.log.read_text(errors="replace").splitlines()[-n:])

    def stop(self) -> None:
        """SIGTERM the app's process group (repro, Voilà, the kernel), SIGKILL after 15 s."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)  # whatever of the group is left (the kernel)
        except (ProcessLookupError, PermissionError):
            pass
        self.proc.wait(timeout=15)


@pytest.fixture
def page(request):
    if (why := browser_unavailable_reason()) is not None:
        pytest.skip(why)
    import shutil
    import tempfile

    from playwright.sync_api import sync_playwright

    pw = sync_playwright().start()
    profile = tempfile.mkdtemp(prefix="repro-app-chromium-")  # removed at the end
    ctx = pw.chromium.launch_persistent_context(profile,
                                                executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS,
                                                viewport={"width": 1400, "height": 1000})
    ctx.set_default_timeout(STEP_TIMEOUT * 1000)
    pg = ctx.new_page()
    try:
        yield pg
    finally:
        try:
            pg.screenshot(path=str(ARTIFACTS / f"app-{request.node.name}-end.png"))
        except Exception:  # noqa: BLE001
            pass
        ctx.close()
        pw.stop()
        shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture
def app(request):
    apps = []

    def start(which):
        a = App(which)
        apps.append(a)
        return a

    yield start
    for a in apps:
        a.stop()


def _new_paint(page, sel, n_before, timeout=STEP_TIMEOUT):
    page.wait_for_function("([sel, n]) => window.__paints[sel].length > n", arg=[sel, n_before],
                           timeout=timeout * 1000)
    return page.evaluate("(sel) => window.__paints[sel]", sel)


def _image_bytes(page, sel) -> bytes:
    return base64.b64decode(page.evaluate(FETCH_JS, sel))


def _p50(xs):
    return statistics.median(xs) if xs else float("nan")


def _face_model():
    from repro.blendshapes import load_model
    from repro.errors import DataError

    try:
        return load_model("ict")
    except DataError:
        return load_model("procedural")


# The client-side view (repro.ui.webview): every picture it puts on screen, with the digest of the frame drawn.
WATCH_CANVAS_JS = """() => {
  window.__inputs = window.__inputs || [];
  if (!window.__watching) {
    const note = e => window.__inputs.push(performance.now());
    document.addEventListener('keydown', note, true);
    document.addEventListener('pointerdown', note, true);
    document.addEventListener('pointermove', e => { if (e.buttons) note(e); }, true);
    window.__watching = true;
  }
  window.__canvas = [];
  document.addEventListener('repro-painted', e => window.__canvas.push(e.detail));
}"""
CANVAS = "canvas.repro-webview-canvas"


def _canvas_paints(page, reason=None):
    paints = page.evaluate("() => window.__canvas")
    return [p for p in paints if reason is None or p["reason"] == reason]


def _wait_canvas_paint(page, n_before, reason="data", timeout=STEP_TIMEOUT):
    page.wait_for_function("([n, r]) => window.__canvas.filter(p => p.reason === r).length > n",
                           arg=[n_before, reason], timeout=timeout * 1000)
    return _canvas_paints(page, reason)


def _pixels(page) -> str:
    return page.evaluate(f"() => document.querySelector('{CANVAS}').toDataURL()")


def test_face_app_slider_moves_redraw_and_the_last_value_is_drawn(app, page):
    """Slider presses -> the face redrawn in the page (client-side view), the last value drawn; turn and zoom."""
    from repro.ui.face_panel import BlendshapePanel

    a = app("face")
    page.goto(a.url, wait_until="domcontentloaded")
    page.wait_for_selector(CANVAS, timeout=START_TIMEOUT * 1000)
    page.wait_for_function(f"() => document.querySelector('{CANVAS}').dataset.painted", timeout=STEP_TIMEOUT * 1000)
    page.screenshot(path=str(ARTIFACTS / "app-face-1-start.png"))
    slider = page.locator(".repro-blendshape-panel .widget-slider", has_text="JawOpen")
    handle = slider.locator(".noUi-handle")
    handle.scroll_into_view_if_needed()
    page.evaluate(WATCH_CANVAS_JS)
    handle.focus()

    # single presses: each one a new picture; latency from the key press to the painted picture
    latencies = []
    before = _pixels(page)
    for _ in range(8):
        n = len(_canvas_paints(page, "data"))
        page.keyboard.press("ArrowRight")
        paints = _wait_canvas_paint(page, n)
        key_t = page.evaluate("() => window.__inputs[window.__inputs.length - 1]")
        latencies.append(paints[-1]["t"] - key_t)
        time.sleep(0.3)  # let the user rest between presses
    assert _pixels(page) != before, "slider moves must change the picture"

    # ten quick presses: intermediate values may be skipped, the last one must be drawn
    n_quick = len(_canvas_paints(page, "data"))
    for _ in range(10):
        page.keyboard.press("ArrowRight", delay=0)
    want_value = 0.18
    model = _face_model()
    ref = BlendshapePanel(model, view="3d")
    ref.set_sliders(JawOpen=want_value)
    want = ref.view_digest
    ref_frame = bytes(ref._view.frame.value)
    ref.close()
    deadline = time.monotonic() + STEP_TIMEOUT
    while True:
        readout = slider.locator(".widget-readout").inner_text().strip()
        painted = page.evaluate(f"() => document.querySelector('{CANVAS}').dataset.painted")
        if readout == f"{want_value:.2f}" and painted == want:
            break
        if time.monotonic() > deadline:
            page.screenshot(path=str(ARTIFACTS / "app-face-2-last-value.png"))
            pytest.fail(f"after 18 presses the slider shows {readout!r} and the canvas shows frame {painted!r}, "
                        f"not the face of JawOpen = {want_value} ({want!r})", pytrace=False)
        time.sleep(0.2)
    # what the page drew from is the kernel's frame for that value, byte for byte
    assert _image_bytes(page, "img.repro-webview-frame") == ref_frame
    n_pictures = len(_canvas_paints(page, "data")) - n_quick
    page.screenshot(path=str(ARTIFACTS / "app-face-2-after.png"))

    # turn the face (drag on the canvas) and zoom (wheel): drawn in the page, no kernel round trip
    box = page.locator(CANVAS).bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 3
    front = _pixels(page)
    turn = []
    page.mouse.move(x, y)
    page.mouse.down()
    for k in range(1, 9):
        n = len(_canvas_paints(page, "view"))
        page.mouse.move(x + 12 * k, y + 2 * k)
        paints = _wait_canvas_paint(page, n, "view")
        turn.append(paints[-1]["t"] - page.evaluate("() => window.__inputs[window.__inputs.length - 1]"))
    page.mouse.up()
    turned = _pixels(page)
    assert turned != front, "dragging the face must turn it"
    page.screenshot(path=str(ARTIFACTS / "app-face-3-turned.png"))
    n = len(_canvas_paints(page, "view"))
    page.mouse.wheel(0, -240)
    _wait_canvas_paint(page, n, "view")
    assert _pixels(page) != turned, "the wheel must zoom"
    n = len(_canvas_paints(page, "view"))
    page.mouse.dblclick(x, y)
    _wait_canvas_paint(page, n, "view")
    assert _pixels(page) == front, "a double-click must bring back the front view"
    assert page.evaluate(f"() => document.querySelector('{CANVAS}').dataset.painted") == want  # still that face
    print(f"\nbench app face ({model.name}, {model.n_vertices} vertices, client-side view): slider press -> painted "
          f"picture p50 {_p50(latencies):.0f} ms (min {min(latencies):.0f}, max {max(latencies):.0f}, "
          f"n={len(latencies)}); 10 quick presses gave {n_pictures} pictures, the last one the value stopped on; "
          f"drag -> turned picture p50 {_p50(turn):.0f} ms (n={len(turn)})")


def test_fighter_app_orders_play_a_strike(app, page):
    """Orders -> the strike first drawn in the page's 3D view (then the filmstrip); it plays; turn it."""
    from repro.ui.fighter_panel import parse_fighter_numbers

    a = app("fighter")
    page.goto(a.url, wait_until="domcontentloaded")
    film = "img.repro-fighter-filmstrip"
    numbers = ".repro-fighter-panel .repro-fighter-numbers"
    page.wait_for_selector(numbers, state="attached", timeout=START_TIMEOUT * 1000)
    page.wait_for_function(f"() => {{ const c = document.querySelector('{CANVAS}'); return c && c.dataset.painted; }}",
                           timeout=START_TIMEOUT * 1000)
    page.wait_for_function("(s) => { const e = document.querySelector(s); return e && e.src; }", arg=film)
    page.screenshot(path=str(ARTIFACTS / "app-fighter-1-start.png"))
    page.evaluate(WATCH_CANVAS_JS)
    page.evaluate(WATCH_JS.replace("window.__inputs = [];", ""), film)
    # the readout says the strike in words; the raw numbers line is behind the details toggle
    assert not page.locator(numbers).is_visible()
    page.locator(".repro-fighter-panel .repro-fighter-details").click()
    page.wait_for_selector(numbers, state="visible")
    # the icon buttons of the simulated user's player carry words, not cut off
    labels = page.evaluate("""() => [...document.querySelectorAll('.repro-fighter-play button')].map(
        b => [getComputedStyle(b, '::after').content, b.scrollWidth <= b.clientWidth + 1])""")
    assert any("play" in t for t, _ in labels) and any("stop" in t for t, _ in labels), labels
    assert all(fits for _, fits in labels), f"a player button's label is cut off: {labels}"

    first, film_lat = [], []
    for kind in ("punch", "kick", "punch", "kick"):
        n_canvas = len(_canvas_paints(page, "data"))
        n_film = len(page.evaluate("(s) => window.__paints[s]", film))
        page.locator(f".repro-fighter-panel .repro-fighter-{kind}").click()
        paints = _wait_canvas_paint(page, n_canvas)
        click_t = page.evaluate("() => window.__inputs[window.__inputs.length - 1]")
        first.append(paints[n_canvas]["t"] - click_t)
        film_paints = _new_paint(page, film, n_film)
        film_lat.append(film_paints[n_film]["t"] - click_t)
        text = page.locator(numbers).inner_text().strip()
        shown = parse_fighter_numbers(text)
        assert shown["kind"] == kind and kind in shown["clip"], shown
        words = page.locator(".repro-fighter-panel .repro-fighter-readout").inner_text().strip()
        assert words.startswith(f"{kind}: "), words
        # the frame drawn is the strike the kernel sent for this order
        from repro.ui.webview import unpack

        head, _ = unpack(_image_bytes(page, "img.repro-webview-frame"))
        assert head["strike"] == kind and head["clip"] == shown["clip"], (head["clip"], shown)
        assert page.evaluate(f"() => document.querySelector('{CANVAS}').dataset.painted") == head["digest"]
        n_frames = head["n_frames"]
        assert n_frames > 5, n_frames
    # it plays: the picture changes by itself
    shots = {_pixels(page)}
    for _ in range(5):
        time.sleep(0.15)
        shots.add(_pixels(page))
    assert len(shots) > 2, "the strike must play in the 3D view"
    # turn it
    page.locator(".repro-webview [data-act=play]").click()  # pause
    box = page.locator(CANVAS).bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    still = _pixels(page)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 90, y + 10, steps=6)
    page.mouse.up()
    time.sleep(0.1)
    assert _pixels(page) != still, "dragging must turn the 3D view"
    page.screenshot(path=str(ARTIFACTS / "app-fighter-2-after.png"))
    print(f"\nbench app fighter: order click -> first painted picture (3D view) p50 {_p50(first):.0f} ms "
          f"(min {min(first):.0f}, max {max(first):.0f}, n={len(first)}); -> painted filmstrip p50 "
          f"{_p50(film_lat):.0f} ms; strike {n_frames} frames")
