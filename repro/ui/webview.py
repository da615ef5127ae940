"""A 3D view drawn in the browser (rotate, zoom) for the panels: the kernel sends geometry, the page draws it.

Why client-side: a kernel-drawn picture costs a render, a PNG encoding and a round
trip per change (about 0.1-0.2 s on the ICT face), and rotating it would cost the same
per mouse move.  Here the kernel sends only what changed (the face's vertex positions
and motion as int16/uint8, ~66 KB for the ICT face; or a whole strike once), and a
small script (``webview.js``, plain canvas 2D: no WebGL, so it also draws in a browser
without a GPU) rasterises the triangles with a depth buffer, or draws the skeletons,
and redraws by itself when the user drags (rotate), scrolls (zoom) or double-clicks
(front view).

Transport without a custom widget (none can be installed here: no anywidget, no lab
extension): two hidden ``ipywidgets.Image`` widgets carry the bytes (the page turns
each value into a ``blob:`` URL that the script fetches): ``static`` (the mesh's
triangles and colour map, sent once) and ``frame`` (each update).  The script is started
by an ``onload`` handler of a 1-pixel image in an ``ipywidgets.HTML`` (``innerHTML``
does not run ``<script>`` tags, but it does run event handlers; the handler adds the
script to the page once); it runs the same in JupyterLab and in Voilà.  The canvas notes the ``digest`` of the frame it drew in
``data-drawn`` (and ``data-painted`` a frame later, with a ``repro-painted`` event), so a
test can tell which frame is on screen.  The face view also carries the user's vertex picks
the other way: the script writes them into a hidden ``ipywidgets.Text`` (``picks``) and fires its
``change`` event, which sends the value to the kernel (:mod:`repro.ui.face_picking`).

Message layout (:func:`pack` / :func:`unpack`): ``b"RPV1"``, uint32 little-endian header
length, a JSON header (with ``arrays``: name, dtype, byte offset, length), then the
arrays, little-endian, each at a 4-byte aligned offset.
"""

from __future__ import annotations

import hashlib
import html
import json
import math
from functools import lru_cache
from pathlib import Path

import ipywidgets as widgets
import numpy as np

from repro.errors import ReproError

__all__ = ["MeshWebView", "StrikeWebView", "WebView", "bounding_radius", "mesh_frame", "pack", "strike_scene", "unpack"]

MAGIC = b"RPV1"
_DTYPES = {"f4": np.float32, "i2": np.int16, "u1": np.uint8, "u4": np.uint32}
#: Quantisation of the face's positions: int16 over +-QUANT_RANGE times the rest pose's half extent.
QUANT_RANGE = 1.5
#: The face's bounding sphere fills the view's smaller side up to this factor (a 6 % margin all round).
FIT_MARGIN = 1.06
#: A 1-pixel GIF whose ``onload`` starts the script.
_PIXEL = "data:image/gif;base64,R0lGODlhAQABAIAAAP///wAAACH5BAEAAAAALAAAAAABAAEAAAICRAEAOw=="


@lru_cache(maxsize=1)
def script() -> str:
    """The viewer's JavaScript (``webview.js`` next to this module)."""
    return Path(__file__).with_name("webview.js").read_text(encoding="utf-8")


def pack(header: dict, arrays: dict) -> bytes:
    """One message: ``header`` (JSON-able) and named arrays (dtypes f4, i2, u1, u4) as bytes."""
    blobs, specs = [], []
    for name, a in arrays.items():
        a = np.asarray(a)
        code = next((k for k, t in _DTYPES.items() if a.dtype == t), None)
        if code is None:
            raise ReproError(f"view message array {name!r} has dtype {a.dtype}; expected one of "
                             f"{[np.dtype(t).name for t in _DTYPES.values()]}")
        blobs.append(np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<")).tobytes())
        specs.append([name, code, 0, int(a.size)])
    text = b""
    while True:  # the offsets depend on the header's length, which depends on the offsets: until stable
        pos = 8 + len(text)
        pos += -pos % 4
        for spec, blob in zip(specs, blobs):
            spec[2] = pos
            pos += len(blob) + (-len(blob) % 4)
        new = json.dumps(dict(header, arrays=specs), separators=(",", ":")).encode()
        if new == text:
            break
        text = new
    out = bytearray(MAGIC + len(text).to_bytes(4, "little") + text)
    out += b"\0" * (-len(out) % 4)
    for blob in blobs:
        out += blob + b"\0" * (-len(blob) % 4)
    return bytes(out)


def unpack(data: bytes) -> tuple[dict, dict]:
    """:func:`pack` read back: the header and the arrays (numpy)."""
    data = bytes(data)
    if data[:4] != MAGIC:
        raise ReproError(f"not a view message: starts with {data[:4]!r}, not {MAGIC!r}")
    n = int.from_bytes(data[4:8], "little")
    head = json.loads(data[8:8 + n])
    arrays = {}
    for name, code, offset, length in head.pop("arrays"):
        arrays[name] = np.frombuffer(data, dtype=np.dtype(_DTYPES[code]).newbyteorder("<"), count=length, offset=offset)
    return head, arrays


def _digest(*parts: bytes) -> str:
    h = hashlib.sha1()
    for p in parts:
        h.update(p)
    return h.hexdigest()[:16]


class WebView:
    """The widget of a client-side view: a canvas (``width`` x ``height`` px), its buttons, and the two carriers."""

    def __init__(self, width: int, height: int, *, buttons=("front view", "zoom +", "zoom −"), play: bool = False,
                 note: str = "drag: rotate · wheel: zoom · double-click: front view"):
        acts = {"front view": ("front", ""), "zoom +": ("zoom-in", ""), "zoom −": ("zoom-out", ""),
                "pick": ("pick", "pick mode: a click adds the vertex under it, a drag brushes (Shift: in either mode)"),
                "clear": ("clear", "clear the picked vertices (key c)")}
        btn = "".join(f'<button type="button" data-act="{acts[b][0]}" title="{html.escape(acts[b][1])}" '
                      f'class="repro-webview-button">{html.escape(b)}</button>' for b in buttons)
        if play:
            btn = '<button type="button" data-act="play" class="repro-webview-button">pause</button>' + btn
        # the script goes into a <script> element (global scope: code in the handler itself would run inside
        # the handler's with-like scope chain, where every global lookup is slow, ~30x slower drawing)
        start = ("if (!window.reproWebview) { const s = document.createElement('script'); "
                 f"s.textContent = {json.dumps(script())}; document.head.appendChild(s); }} "
                 "window.reproWebview.attach(this);")
        self.html = widgets.HTML(
            # as wide as the canvas (and its border): the buttons and the note wrap below it, not widen the column
            f'<div class="repro-webview" style="display:inline-block;width:{int(width) + 2}px">'
            f'<canvas width="{int(width)}" height="{int(height)}" class="repro-webview-canvas" tabindex="0" '
            f'data-lm-suppress-shortcuts="true" '  # its keys (c: clear picks) are not JupyterLab's shortcuts
            f'style="width:{int(width)}px;height:{int(height)}px;touch-action:none;cursor:grab;'
            f'border:1px solid #ddd"></canvas>'
            f'<div style="font-size:12px;display:flex;gap:6px;align-items:center;flex-wrap:wrap">{btn}'
            f'<span class="repro-webview-note" style="color:#555">{html.escape(note)}</span></div>'
            f'<img alt="" width="1" height="1" style="display:none" src="{_PIXEL}" '
            f'onload="{html.escape(start, quote=True)}"></div>')
        self.static = widgets.Image(format="x-repro-view", layout=widgets.Layout(display="none"))
        self.static.add_class("repro-webview-static")
        self.frame = widgets.Image(format="x-repro-view", layout=widgets.Layout(display="none"))
        self.frame.add_class("repro-webview-frame")
        self.widget = widgets.Box([self.html, self.static, self.frame])
        self.widget.add_class("repro-webview-box")
        self.digest: str | None = None

    def close(self) -> None:
        for w in (*self.widget.children, self.widget):  # the canvas, the carriers (and a view's own widgets)
            w.close()


# ------------------------------------------------------------------------ face
class MeshWebView(WebView):
    """The posed face in the browser, same colours as the panel's matplotlib view (front view first).

    :meth:`render` sends the vertex positions (int16: ``QUANT_RANGE`` times the rest
    pose's half extent over 32767 steps: 6.6e-4 cm on the ICT face) and the motion (uint8
    over ``clim``); the triangles, the colour map and the colour bar's label go once.

    The camera is fitted to the face's bounding sphere (:func:`bounding_radius`, about the
    centre the page turns the face around), with a :data:`FIT_MARGIN`: at zoom 1 the face,
    at rest or with any one shape at full weight, stays whole in the view however it is
    turned (a fit to the front view's box cut the forehead off once the face was tilted).
    """

    def __init__(self, model, clim, cmap: str, size, *, units: str | None = None):
        import matplotlib as mpl

        w, h = size
        self.bar_height = 56
        super().__init__(w, h, buttons=("front view", "zoom +", "zoom −", "pick", "clear"),
                         note="drag: rotate · wheel: zoom · double-click: front · pick or Shift: click adds, "
                              "drag brushes · c: clear")
        # the page's picks to the kernel (repro.ui.face_picking): the canvas writes them into this text field
        self.picks = widgets.Text(layout=widgets.Layout(display="none"))
        self.picks.add_class("repro-webview-picks")
        self.widget.children = (*self.widget.children, self.picks)
        self.picks_seq = 0  # the last pick message handled, sent with each frame
        self.model = model
        f0 = np.asarray(model.f0, dtype=np.float64)
        lo, hi = f0.min(axis=0), f0.max(axis=0)
        self.centre = (lo + hi) / 2
        half = (hi - lo) / 2
        self.extent = float(half.max()) or 1.0
        self.step = QUANT_RANGE * self.extent / 32767
        self.clim = (float(clim[0]), float(clim[1]))
        self.radius = bounding_radius(model, self.centre)
        # pixels per model unit over min(w, h - bar): the sphere's diameter, with the margin, spans the view
        fit = 1.0 / (2 * FIT_MARGIN * self.radius)
        lut = np.clip(np.rint(mpl.colormaps[cmap](np.linspace(0, 1, 256))[:, :3] * 255), 0, 255).astype(np.uint8)
        faces = np.ascontiguousarray(model.faces, dtype=np.uint32)
        self.static_id = _digest(faces.tobytes(), lut.tobytes(), repr((self.clim, w, h)).encode())
        light = np.array([0.3, 0.4, 1.0])
        header = {
            "kind": "mesh", "id": self.static_id, "n_vertices": int(model.n_vertices), "step": self.step,
            "fit": fit, "extent": self.extent,
            "clim": list(self.clim), "bar_height": self.bar_height, "light": (light / np.linalg.norm(light)).tolist(),
            "bar_label": f"motion since the selection ({units or model.units}); cyan: selected",
        }
        self.static.value = pack(header, {"faces": faces.ravel(), "lut": lut.ravel()})

    def frame_bytes(self, points: np.ndarray, motion: np.ndarray, selected_vertices) -> bytes:
        """The frame message of a pose (what :meth:`render` sends)."""
        return mesh_frame(points, motion, selected_vertices, centre=self.centre, step=self.step, clim=self.clim,
                          static_id=self.static_id, picks=self.picks_seq)

    def render(self, points: np.ndarray, motion: np.ndarray, selected_vertices) -> str:
        """Send the pose to the page; the frame's digest (the canvas's ``data-drawn`` once drawn)."""
        data = self.frame_bytes(points, motion, selected_vertices)
        self.digest = unpack(data)[0]["digest"]
        self.frame.value = data
        return self.digest


def bounding_radius(model, centre) -> float:
    """The radius about ``centre`` of a sphere holding the rest face and each shape at full weight (model units)."""
    f0 = np.asarray(model.f0, dtype=np.float64) - centre
    D = np.asarray(model.D, dtype=np.float64).reshape(model.n_vertices, 3, -1)  # row 3*v + axis
    # |f0 + d_k|^2 per vertex and shape, without an (n, 3, k) array of posed points
    sq = (f0 ** 2).sum(axis=1)[:, None] + 2 * np.einsum("vi,vik->vk", f0, D) + np.einsum("vik,vik->vk", D, D)
    r = math.sqrt(max(float((f0 ** 2).sum(axis=1).max()), float(sq.max()) if sq.size else 0.0))
    return r or 1.0


def mesh_frame(points, motion, selected_vertices, *, centre, step, clim, static_id, picks: int = 0) -> bytes:
    """A face frame: int16 positions about ``centre`` in ``step`` units, uint8 motion over ``clim``, selected ids
    (and ``picks``, the last pick message of the page drawn in it; not part of the digest)."""
    q = np.rint((np.asarray(points, dtype=np.float64) - centre) / step)
    q = np.clip(np.nan_to_num(q, nan=0.0), -32767, 32767).astype(np.int16)
    lo, hi = clim
    m = np.nan_to_num((np.asarray(motion, dtype=np.float64) - lo) / ((hi - lo) or 1.0), nan=0.0)
    m = np.clip(np.rint(m * 255), 0, 255).astype(np.uint8)
    sel = np.asarray(selected_vertices if selected_vertices is not None else [], dtype=np.uint32)
    digest = _digest(q.tobytes(), m.tobytes(), sel.tobytes(), static_id.encode())
    return pack({"kind": "mesh", "static_id": static_id, "digest": digest, "picks": int(picks)},
                {"pos": q.ravel(), "motion": m, "selected": sel})


# ---------------------------------------------------------------------- strike
def strike_scene(strike, *, head_radius: float = 0.1, hold: float = 0.8) -> bytes:
    """A whole strike as one frame message: bones per frame (adapted and retrieved), heads, target, hit path, floor.

    The camera starts as :class:`repro.ui.strike_view.StrikeCamera` (the fighter seen from
    its left, the strike going right); the page plays the frames at the database rate and
    holds the last one ``hold`` seconds.
    """
    from repro.ui.strike_view import StrikeCamera, scene_geometry

    g = scene_geometry(strike, head_radius)
    cam = StrikeCamera(strike, root=g["root"])
    r, up = cam.right, cam.up
    yaw = math.atan2(r[2], r[0])
    # pitch so that the rotation's second row, (sin p sin y, cos p, -sin p cos y), is the camera's up
    pitch = math.atan2(up[0] * math.sin(yaw) - up[2] * math.cos(yaw), up[1])
    pts = np.vstack([g["adapted"].reshape(-1, 3), g["original"].reshape(-1, 3), g["target"][None]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    lo[1] = min(lo[1], 0.0)
    centre = (lo + hi) / 2
    radius = 0.5 * float(np.linalg.norm(hi - lo)) * 0.85 + max(g["head_r"], head_radius)
    arrays = {
        "adapted": g["adapted"].astype(np.float32).ravel(),
        "original": g["original"].astype(np.float32).ravel(),
        "head": g["head"].astype(np.float32).ravel(),
        "original_head": g["original_head"].astype(np.float32).ravel(),
        "hit": g["hit"].astype(np.float32).ravel(),
        "target": np.asarray(strike.target, dtype=np.float32),
        "floor": g["floor"].astype(np.float32).ravel(),
    }
    digest = _digest(*(a.tobytes() for a in arrays.values()), strike.kind.encode())
    F = int(strike.n_frames)
    header = {
        "kind": "strike", "digest": digest, "n_frames": F, "n_bones": int(g["adapted"].shape[1]),
        "n_original": int(g["original"].shape[1]), "head_r": float(g["head_r"]), "target_r": float(head_radius),
        "fps": float(1.0 / strike.motion.frame_time), "tc": int(strike.tc), "hold": float(hold),
        "centre": centre.tolist(), "radius": radius, "yaw": yaw, "pitch": pitch,
        "camera_id": _digest(np.round([yaw, pitch], 2).tobytes()),
        "strike": strike.kind, "clip": strike.clip_name,
    }
    return pack(header, arrays)


class StrikeWebView(WebView):
    """A strike played in the browser (rotate, zoom, pause), sent as one message per order."""

    def __init__(self, width: int = 480, height: int = 400, *, head_radius: float = 0.1):
        super().__init__(width, height, play=True)
        self.head_radius = float(head_radius)
        self.static.value = pack({"kind": "none", "id": "-"}, {})

    def show(self, strike) -> str:
        """Send ``strike`` to the page; its digest (the canvas's ``data-drawn`` once its first frame is drawn)."""
        data = strike_scene(strike, head_radius=self.head_radius)
        self.digest = unpack(data)[0]["digest"]
        self.frame.value = data
        return self.digest
