"""The 3D view drawn in the browser (repro.ui.webview): its messages, what the panels send to it.

What the page draws is checked in tests/browser/test_app.py (the canvas's digest, the
picture turning and zooming); here: the bytes the kernel sends.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from repro.errors import ReproError


def test_pack_unpack_round_trip_aligned_and_deterministic():
    from repro.ui.webview import pack, unpack

    arrays = {"a": np.arange(5, dtype=np.float32), "b": np.array([1, -2, 3], dtype=np.int16),
              "c": np.array([7], dtype=np.uint8), "d": np.arange(3, dtype=np.uint32), "e": np.zeros(0, np.float32)}
    data = pack({"kind": "x", "n": 3}, arrays)
    assert data == pack({"kind": "x", "n": 3}, arrays)
    head, back = unpack(data)
    assert head == {"kind": "x", "n": 3}
    assert set(back) == set(arrays)
    for k, a in arrays.items():
        np.testing.assert_array_equal(back[k], a)
        assert back[k].dtype == a.dtype.newbyteorder("<")
    # every array at a 4-byte aligned offset (the page reads them as typed-array views)
    import json

    n = int.from_bytes(data[4:8], "little")
    specs = json.loads(data[8:8 + n])["arrays"]
    assert all(off % 4 == 0 for _, _, off, _ in specs) and len(data) % 4 == 0


def test_pack_and_unpack_refuse_bad_input():
    from repro.ui.webview import pack, unpack

    with pytest.raises(ReproError, match="float64"):
        pack({}, {"x": np.zeros(3)})
    with pytest.raises(ReproError, match="not a view message"):
        unpack(b"\x89PNG....")


@pytest.fixture(scope="module")
def face():
    from repro.blendshapes import load_model

    return load_model("procedural")


def test_face_panel_3d_sends_the_pose_quantised(face):
    from repro.ui.face_panel import BlendshapePanel
    from repro.ui.webview import QUANT_RANGE, unpack

    panel = BlendshapePanel(face, view="3d", region="under_left_eye")
    static, s_arrays = unpack(panel._view.static.value)
    assert static["kind"] == "mesh" and static["n_vertices"] == face.n_vertices
    np.testing.assert_array_equal(s_arrays["faces"].reshape(-1, 3), face.faces)
    assert s_arrays["lut"].size == 256 * 3
    assert "motion since the selection" in static["bar_label"]

    panel.set_sliders(JawOpen=0.6, Blink=0.3)
    digest = panel.view_digest
    head, arrays = unpack(panel._view.frame.value)
    assert head["digest"] == digest and head["static_id"] == static["id"]
    # positions back within half a quantisation step
    lo, hi = face.f0.min(axis=0), face.f0.max(axis=0)
    step = static["step"]
    assert step == pytest.approx(QUANT_RANGE * float(((hi - lo) / 2).max()) / 32767)
    points = face.f0 + panel.attenuator.displacement(panel.weights).reshape(-1, 3)
    decoded = arrays["pos"].reshape(-1, 3) * step + (lo + hi) / 2
    assert np.abs(decoded - points).max() <= step / 2 + 1e-12
    # motion since the selection (w_base neutral) on the colour range 0..1, as 0..255
    motion = np.linalg.norm((points - face.f0), axis=1)
    assert np.abs(arrays["motion"] / 255 - np.clip(motion, 0, 1)).max() <= 0.5 / 255 + 1e-9
    np.testing.assert_array_equal(arrays["selected"], np.unique(face.regions["under_left_eye"]))

    # a new pose, a new digest; the same pose again, the same bytes
    first = bytes(panel._view.frame.value)
    panel.set_sliders(JawOpen=0.2)
    assert panel.view_digest != digest
    panel.set_sliders(JawOpen=0.6)
    assert bytes(panel._view.frame.value) == first
    # the picture for notebooks and tests: the matplotlib view of the same pose
    ref = BlendshapePanel(face, view="matplotlib", region="under_left_eye", values={"JawOpen": 0.6, "Blink": 0.3})
    assert panel.image_png() == ref.image_png()
    # the live view is the canvas, not a picture sent per move
    assert panel.view_image.layout.display == "none"
    assert panel._view.widget in panel.widget.children[0].children[1].children
    ref.close()
    panel.close()


def _page_rotation(yaw: float, pitch: float) -> np.ndarray:
    """webview.js's ``rotation()``: R = Rx(pitch) Ry(yaw), rows the screen's right, up and toward-the-viewer."""
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    return np.array([[cy, 0, sy], [sp * sy, cp, -sp * cy], [-cp * sy, sp, cp * cy]])


def test_face_view_camera_holds_the_whole_face_turned_any_way(face):
    """Issue 26, item 6: the camera fits the face's bounding sphere, so no turn cuts the forehead (or chin) off."""
    from repro.ui.webview import FIT_MARGIN, MeshWebView, bounding_radius, unpack

    view = MeshWebView(face, (0.0, 1.0), "YlOrRd", (360, 420))
    head, _ = unpack(view.static.value)
    W, Hv = 360, 420 - head["bar_height"]
    s = head["fit"] * min(W, Hv)  # pixels per model unit at zoom 1, as the page computes it
    # the sphere: about the centre the page turns the face around, holding the rest face and every shape at 1
    D = face.D.reshape(face.n_vertices, 3, face.n_shapes)
    poses = np.stack([face.f0] + [face.f0 + D[:, :, k] for k in range(face.n_shapes)]) - view.centre
    r = bounding_radius(face, view.centre)
    assert np.linalg.norm(poses, axis=2).max() == pytest.approx(r, rel=1e-12)
    assert s * r * 2 * FIT_MARGIN == pytest.approx(min(W, Hv))
    for yaw in np.linspace(-math.pi, math.pi, 13):
        for pitch in np.linspace(-1.5, 1.5, 7):  # the page's pitch limits
            P = poses @ _page_rotation(yaw, pitch).T
            x, y = W / 2 + s * P[..., 0], Hv / 2 - s * P[..., 1]
            assert x.min() >= 0 and x.max() <= W and y.min() >= 0 and y.max() <= Hv, (yaw, pitch)
    # and the front view still uses the view: the face at rest spans most of its height
    front = s * np.ptp(face.f0[:, 1])
    assert front > 0.6 * Hv, front
    view.close()


def test_face_panel_3d_nan_pose_does_not_break_the_message(face):
    from repro.ui.webview import mesh_frame, unpack

    pts = face.f0.copy()
    pts[0] = np.nan
    data = mesh_frame(pts, np.full(face.n_vertices, np.nan), None, centre=np.zeros(3), step=1e-3, clim=(0, 1),
                      static_id="s")
    _, a = unpack(data)
    assert a["pos"][:3].tolist() == [0, 0, 0] and int(a["motion"].max()) == 0 and a["selected"].size == 0


@pytest.fixture(scope="module")
def fighter():
    from repro.motion.runtime.fighter import KungFuFighter

    return KungFuFighter("synthetic", seed=0)


def test_fighter_panel_sends_each_strike_to_the_3d_view(fighter):
    from repro.motion.runtime.fighter import KungFuFighter
    from repro.ui.fighter_panel import FighterPanel
    from repro.ui.strike_view import StrikeCamera, scene_geometry
    from repro.ui.webview import unpack

    panel = FighterPanel(KungFuFighter(fighter.db, retriever=fighter.retriever))
    assert panel.view3d is not None
    panel.set_target(0.3, 1.3, 0.4)
    s = panel.kick()
    head, a = unpack(panel.view3d.frame.value)
    assert head["kind"] == "strike" and head["strike"] == "kick" and head["clip"] == s.clip_name
    assert head["digest"] == panel.view3d.digest
    F = s.n_frames
    g = scene_geometry(s)
    assert head["n_frames"] == F and head["tc"] == s.tc
    np.testing.assert_allclose(a["adapted"].reshape(F, -1, 2, 3), g["adapted"], atol=1e-6)
    np.testing.assert_allclose(a["original"].reshape(F, -1, 2, 3), g["original"], atol=1e-6)
    np.testing.assert_allclose(a["hit"].reshape(F, 3), s.hit_positions(), atol=1e-6)
    np.testing.assert_allclose(a["target"], s.target, atol=1e-6)
    assert head["fps"] == pytest.approx(1 / s.motion.frame_time)
    # the page's first camera is the filmstrip's: rows of Rx(pitch) Ry(yaw) = the camera's right and up
    cam = StrikeCamera(s, root=g["root"])
    y, p = head["yaw"], head["pitch"]
    np.testing.assert_allclose([math.cos(y), 0, math.sin(y)], cam.right, atol=1e-9)
    np.testing.assert_allclose([math.sin(p) * math.sin(y), math.cos(p), -math.sin(p) * math.cos(y)], cam.up,
                               atol=1e-9)
    first = head["digest"]
    panel.punch()
    assert unpack(panel.view3d.frame.value)[0]["digest"] != first
    assert panel.image_png().startswith(b"\x89PNG")  # the filmstrip stays
    panel.close()

    quiet = FighterPanel(KungFuFighter(fighter.db, retriever=fighter.retriever), view3d=False)
    assert quiet.view3d is None
    quiet.close()
    assert FighterPanel(KungFuFighter(fighter.db, retriever=fighter.retriever), view=False).view3d is None


def test_the_viewer_script_is_shipped_and_started_once():
    from repro.ui.webview import WebView, script

    js = script()
    assert "window.reproWebview" in js and "RPV1" in js
    v = WebView(100, 80)
    markup = v.html.value
    assert "<canvas" in markup and 'onload="' in markup and "document.createElement(&#x27;script&#x27;)" in markup
    assert "repro-webview-box" in v.widget._dom_classes
    v.close()
