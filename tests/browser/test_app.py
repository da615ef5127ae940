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
        self.log = ARTIFACTS / f"app-{which}.log"
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
    import tempfile

    from playwright.sync_api import sync_playwright

    pw = sync_playwright().start()
    ctx = pw.chromium.launch_persistent_context(tempfile.mkdtemp(prefix="repro-app-chromium-"),
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


def test_face_app_slider_moves_redraw_and_the_last_value_is_drawn(app, page):
    from repro.ui.face_panel import BlendshapePanel

    a = app("face")
    page.goto(a.url, wait_until="domcontentloaded")
    img = ".repro-blendshape-panel img"
    page.wait_for_selector(img, timeout=START_TIMEOUT * 1000)
    page.wait_for_function("(s) => { const e = document.querySelector(s); return e && e.src; }", arg=img)
    page.screenshot(path=str(ARTIFACTS / "app-face-1-start.png"))
    slider = page.locator(".repro-blendshape-panel .widget-slider", has_text="JawOpen")
    handle = slider.locator(".noUi-handle")
    handle.scroll_into_view_if_needed()
    page.evaluate(WATCH_JS, img)
    handle.focus()

    # single presses: each one a new picture; latency from the key press to the painted picture
    latencies = []
    src = page.locator(img).get_attribute("src")
    for _ in range(8):
        n = len(page.evaluate("(s) => window.__paints[s]", img))
        page.keyboard.press("ArrowRight")
        paints = _new_paint(page, img, n)
        key_t = page.evaluate("() => window.__inputs[window.__inputs.length - 1]")
        latencies.append(paints[-1]["t"] - key_t)
        time.sleep(0.3)  # let the user rest between presses
    assert page.locator(img).get_attribute("src") != src, "slider moves must change the picture"

    # ten quick presses: intermediate values may be skipped, the last one must be drawn
    for _ in range(10):
        page.keyboard.press("ArrowRight", delay=0)
    want_value = 0.18
    model = _face_model()
    ref = BlendshapePanel(model, view="matplotlib")
    ref.set_sliders(JawOpen=want_value)
    want = ref.image_png()
    ref.close()
    deadline = time.monotonic() + STEP_TIMEOUT
    while True:
        readout = slider.locator(".widget-readout").inner_text().strip()
        shown = _image_bytes(page, img)
        if readout == f"{want_value:.2f}" and shown == want:
            break
        if time.monotonic() > deadline:
            page.screenshot(path=str(ARTIFACTS / "app-face-2-last-value.png"))
            (ARTIFACTS / "app-face-shown.png").write_bytes(shown)
            (ARTIFACTS / "app-face-wanted.png").write_bytes(want)
            pytest.fail(f"after 18 presses the slider shows {readout!r} and the picture is "
                        f"{'the' if shown == want else 'not the'} face of JawOpen = {want_value}", pytrace=False)
        time.sleep(0.2)
    paints = page.evaluate("(s) => window.__paints[s]", img)
    page.screenshot(path=str(ARTIFACTS / "app-face-2-after.png"))
    print(f"\nbench app face ({model.name}, {model.n_vertices} vertices): slider press -> painted picture "
          f"p50 {_p50(latencies):.0f} ms (min {min(latencies):.0f}, max {max(latencies):.0f}, n={len(latencies)}); "
          f"10 quick presses gave {len(paints) - 8} pictures, the last one the value stopped on")


def test_fighter_app_orders_play_a_strike(app, page):
    from repro.ui.fighter_panel import parse_fighter_numbers

    a = app("fighter")
    page.goto(a.url, wait_until="domcontentloaded")
    film, anim = "img.repro-fighter-filmstrip", "img.repro-fighter-animation"
    numbers = ".repro-fighter-panel .repro-fighter-numbers"
    page.wait_for_selector(numbers, timeout=START_TIMEOUT * 1000)
    page.wait_for_function("(s) => { const e = document.querySelector(s); return e && e.src; }", arg=anim,
                           timeout=START_TIMEOUT * 1000)
    page.screenshot(path=str(ARTIFACTS / "app-fighter-1-start.png"))
    page.evaluate(WATCH_JS, film)
    page.evaluate(WATCH_JS.replace("window.__inputs = [];", ""), anim)
    # the icon buttons of the simulated user's player carry words
    labels = page.evaluate("""() => [...document.querySelectorAll('.repro-fighter-play button')].map(
        b => getComputedStyle(b, '::after').content)""")
    assert any("play" in t for t in labels) and any("stop" in t for t in labels), labels

    latencies = []
    for kind in ("punch", "kick", "punch", "kick"):
        n_film = len(page.evaluate("(s) => window.__paints[s]", film))
        n_anim = len(page.evaluate("(s) => window.__paints[s]", anim))
        page.locator(f".repro-fighter-panel .repro-fighter-{kind}").click()
        paints = _new_paint(page, film, n_film)
        click_t = page.evaluate("() => window.__inputs[window.__inputs.length - 1]")
        latencies.append(paints[n_film]["t"] - click_t)
        _new_paint(page, anim, n_anim)  # then the strike plays
        text = page.locator(numbers).inner_text().strip()
        shown = parse_fighter_numbers(text)
        assert shown["kind"] == kind and kind in shown["clip"], shown
        apng = _image_bytes(page, anim)
        assert apng.startswith(b"\x89PNG") and b"acTL" in apng[:200], "the strike is an animated PNG"
        n_frames = int.from_bytes(apng[apng.index(b"acTL") + 4:][:4], "big")
        assert n_frames > 5, n_frames
    page.screenshot(path=str(ARTIFACTS / "app-fighter-2-after.png"))
    print(f"\nbench app fighter: order click -> painted filmstrip p50 {_p50(latencies):.0f} ms "
          f"(min {min(latencies):.0f}, max {max(latencies):.0f}, n={len(latencies)}); animation {n_frames} frames")
