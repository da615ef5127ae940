// The client-side 3D view of repro.ui.webview: a <canvas> drawn in the page, rotated and zoomed there.
// The kernel sends geometry through two hidden ipywidgets Image widgets (their bytes reach the page as
// blob: URLs): "static" (the mesh's triangles and colour map, sent once) and "frame" (per update: quantized
// vertex positions and motion, or a whole strike).  Frames are read in order and only the newest is drawn.
// Layout of a message: "RPV1", uint32 LE header length, JSON header, arrays at 4-byte aligned offsets.
// The face view also sends the user's vertex picks to the kernel (repro.ui.face_picking): a click adds the nearest
// visible vertex, a drag brushes (in pick mode, or with Shift), "c" or Delete clears; each message is written into
// the view's hidden text widget, whose "change" event ipywidgets sends on.
(function () {
  "use strict";
  const VERSION = 4;
  const BRUSH = 9, CLICK = 14, SEND_MS = 90;  // brush radius, click reach (px), brush messages at most this often
  if (window.reproWebview && window.reproWebview.version >= VERSION) return;
  const TYPES = { f4: Float32Array, i2: Int16Array, u1: Uint8Array, u4: Uint32Array };

  function parse(buf) {
    const bytes = new Uint8Array(buf);
    if (String.fromCharCode(bytes[0], bytes[1], bytes[2], bytes[3]) !== "RPV1") throw new Error("not a view message");
    const n = new DataView(buf).getUint32(4, true);
    const head = JSON.parse(new TextDecoder().decode(bytes.subarray(8, 8 + n)));
    head.a = {};
    for (const [name, dtype, offset, length] of head.arrays) head.a[name] = new TYPES[dtype](buf, offset, length);
    return head;
  }

  class View {
    constructor(box, root) {
      this.box = box;
      this.root = root;
      this.canvas = root.querySelector("canvas");
      this.ctx = this.canvas.getContext("2d");
      this.note = root.querySelector(".repro-webview-note");
      this.data = { static: null, frame: null };
      this.seq = { static: 0, frame: 0 };
      this.yaw = 0; this.pitch = 0; this.zoom = 1;
      this.playing = true; this.f = 0; this.t0 = 0;
      this.pending = false;
      this.picking = false; this.proj = null; this.outbox = new Set(); this.marks = []; this.seqPick = 0;
      for (const which of ["static", "frame"]) {
        const img = box.querySelector("img.repro-webview-" + which);
        new MutationObserver(() => this.load(img, which)).observe(img, { attributes: true, attributeFilter: ["src"] });
        if (img.getAttribute("src")) this.load(img, which);
      }
      this.interact();
    }

    async load(img, which) {
      const src = img.getAttribute("src");
      if (!src) return;
      const token = ++this.seq[which];
      let d;
      try { d = parse(await (await fetch(src)).arrayBuffer()); } catch (e) { return; }  // a newer one replaced it
      if (token !== this.seq[which]) return;
      const old = this.data[which];
      this.data[which] = d;
      if (which === "frame" && d.kind === "strike" && (!old || old.digest !== d.digest)) {
        this.f = 0; this.t0 = performance.now();
        if (!old || old.camera_id !== d.camera_id) this.setCamera(d);
      }
      if (which === "static" && d.kind === "mesh" && !old) this.setCamera(d);
      if (which === "frame" && d.kind === "mesh") this.marks = this.marks.filter((m) => m.seq > (d.picks || 0));
      this.draw("data");
    }

    setCamera(d) { this.yaw = d.yaw || 0; this.pitch = d.pitch || 0; this.zoom = 1; this.home = [this.yaw, this.pitch]; }

    interact() {
      const c = this.canvas;
      let drag = null, stroke = null;
      c.addEventListener("pointerdown", (e) => {
        c.setPointerCapture(e.pointerId); c.focus({ preventScroll: true });
        if (this.picking !== e.shiftKey && this.proj) stroke = { x: e.clientX, y: e.clientY, brushing: false };
        else drag = [e.clientX, e.clientY, this.yaw, this.pitch];
      });
      c.addEventListener("pointermove", (e) => {
        if (stroke) {  // a drag in pick mode brushes, from where it began
          if (!stroke.brushing && Math.hypot(e.clientX - stroke.x, e.clientY - stroke.y) > 3) {
            stroke.brushing = true; this.brush(stroke.x, stroke.y);
          }
          if (stroke.brushing) this.brush(e.clientX, e.clientY);
          return;
        }
        if (!drag) return;
        this.yaw = drag[2] + (e.clientX - drag[0]) * 0.01;
        this.pitch = Math.max(-1.5, Math.min(1.5, drag[3] + (e.clientY - drag[1]) * 0.01));
        this.moved = true;
        this.schedule();
      });
      const end = (e) => {
        if (stroke && !stroke.brushing && e.type === "pointerup") this.pickNearest(e.clientX, e.clientY);
        if (stroke) this.send();
        drag = null; stroke = null;
      };
      c.addEventListener("pointerup", end); c.addEventListener("pointercancel", end);
      c.addEventListener("keydown", (e) => {
        if (!this.proj || !["c", "C", "Delete", "Backspace"].includes(e.key)) return;
        e.preventDefault(); e.stopPropagation(); this.clearPicks();
      });
      c.addEventListener("wheel", (e) => { e.preventDefault(); this.zoomBy(e.deltaY < 0 ? 1.15 : 1 / 1.15); }, { passive: false });
      c.addEventListener("dblclick", () => this.front());
      const on = (act, f) => { const b = this.root.querySelector(`[data-act="${act}"]`); if (b) b.addEventListener("click", f); };
      on("front", () => this.front());
      on("zoom-in", () => this.zoomBy(1.25));
      on("zoom-out", () => this.zoomBy(1 / 1.25));
      on("pick", (e) => {
        this.picking = !this.picking;
        e.target.setAttribute("aria-pressed", String(this.picking));
        e.target.style.fontWeight = this.picking ? "bold" : "";
        c.style.cursor = this.picking ? "crosshair" : "grab";
      });
      on("clear", () => this.clearPicks());
      on("play", (e) => {
        this.playing = !this.playing;
        e.target.textContent = this.playing ? "pause" : "play";
        if (this.playing) { this.t0 = performance.now() - this.f / this.fps(); this.schedule(); }
      });
    }

    // ---------------------------------------------------------------- picking
    // the vertex ids drawn under a page point: nearest (click) or all within the brush, on the side facing the viewer
    canvasXY(cx, cy) {
      const r = this.canvas.getBoundingClientRect();
      return [(cx - r.left) * this.canvas.width / r.width, (cy - r.top) * this.canvas.height / r.height];
    }
    visible(i) {
      const P = this.proj, x = P.X[i], y = P.Y[i];
      if (!(x >= 0 && y >= 0 && x < P.W && y < P.Hv)) return false;
      return P.Z[i] >= P.zbuf[(y | 0) * P.W + (x | 0)] - P.tolz;
    }
    within(cx, cy, r) {
      const P = this.proj, [x, y] = this.canvasXY(cx, cy), out = [];
      for (let i = 0; i < P.X.length; i++) {
        const d = (P.X[i] - x) ** 2 + (P.Y[i] - y) ** 2;
        if (d <= r * r && this.visible(i)) out.push([d, i]);
      }
      return out;
    }
    pickNearest(cx, cy) {
      const hits = this.within(cx, cy, CLICK);
      if (!hits.length) return;
      hits.sort((a, b) => a[0] - b[0]);
      this.addPicks([hits[0][1]]);
    }
    brush(cx, cy) {
      this.addPicks(this.within(cx, cy, BRUSH).map((h) => h[1]));
      if (!this.sendTimer) this.sendTimer = setTimeout(() => { this.sendTimer = null; this.send(); }, SEND_MS);
    }
    addPicks(ids) {
      const fresh = ids.filter((i) => !this.outbox.has(i));
      fresh.forEach((i) => this.outbox.add(i));
      this.drawMarks(fresh);  // at once, before the kernel's frame draws them as the selection
    }
    nextSeq() { this.seqPick = Math.max(this.seqPick + 1, Date.now()); return this.seqPick; }
    message(text) {
      const input = this.box.querySelector(".repro-webview-picks input");
      if (!input) return false;
      input.value = text;
      input.dispatchEvent(new Event("change", { bubbles: true }));
      this.canvas.dataset.pickSent = text.split(" ")[0];  // a frame whose "picks" is this one has drawn them all
      return true;
    }
    send() {
      if (!this.outbox.size) return;
      const seq = this.nextSeq(), ids = [...this.outbox];
      this.outbox.clear();
      if (this.message(`${seq} add ${ids.join(" ")}`)) this.marks.push({ seq, ids });
    }
    clearPicks() {
      this.outbox.clear(); this.marks = [];
      this.message(`${this.nextSeq()} clear`);
    }
    drawMarks(ids) {
      const ctx = this.ctx, P = this.proj;
      if (!P) return;
      ctx.fillStyle = "cyan"; ctx.strokeStyle = "black"; ctx.lineWidth = 0.85;
      for (const i of ids) { ctx.beginPath(); ctx.arc(P.X[i], P.Y[i], 3.25, 0, 2 * Math.PI); ctx.fill(); ctx.stroke(); }
    }

    front() { [this.yaw, this.pitch] = this.home || [0, 0]; this.zoom = 1; this.moved = true; this.schedule(); }
    zoomBy(k) { this.zoom = Math.max(0.3, Math.min(12, this.zoom * k)); this.moved = true; this.schedule(); }
    fps() { const d = this.data.frame; return d && d.fps ? d.fps : 30; }

    schedule() {
      if (this.pending || !this.canvas.isConnected) return;  // a view no longer shown stops
      this.pending = true;
      requestAnimationFrame(() => { this.pending = false; this.draw(this.moved ? "view" : "tick"); this.moved = false; });
    }

    rotation() {
      const cy = Math.cos(this.yaw), sy = Math.sin(this.yaw), cp = Math.cos(this.pitch), sp = Math.sin(this.pitch);
      // R = Rx(pitch) Ry(yaw): rows are the screen's right, up and toward-the-viewer axes in world coordinates
      return [cy, 0, sy, sp * sy, cp, -sp * cy, -cp * sy, sp, cp * cy];
    }

    // reason: "data" (a new message from the kernel), "view" (the user turned or zoomed), "tick" (animation)
    draw(reason) {
      const F = this.data.frame;
      if (!F) return;
      const t0 = performance.now();
      if (F.kind === "mesh") {
        const S = this.data.static;
        if (!S || S.id !== F.static_id) return;
        this.drawMesh(S, F);
      } else if (F.kind === "strike") {
        this.drawStrike(F);
      }
      const ms = performance.now() - t0;
      if (reason !== "tick") {  // tell whoever listens (the browser tests) once the picture is on screen
        const digest = F.digest;
        if (reason === "data") this.canvas.dataset.drawn = digest;
        requestAnimationFrame(() => {
          if (reason === "data") this.canvas.dataset.painted = digest;
          this.canvas.dispatchEvent(new CustomEvent("repro-painted", { bubbles: true, detail: { digest, reason, draw_ms: ms, t: performance.now() } }));
        });
      }
    }

    // ------------------------------------------------------------------ mesh
    drawMesh(S, F) {
      const ctx = this.ctx, W = this.canvas.width, H = this.canvas.height, barH = S.bar_height;
      const Hv = H - barH;
      const faces = S.a.faces, lut = S.a.lut, n = S.n_vertices, t = faces.length / 3;
      const q = F.a.pos, mot = F.a.motion, sel = F.a.selected;
      const R = this.rotation();
      const s = this.zoom * S.fit * Math.min(W, Hv);
      const cx = W / 2, cy = Hv / 2, step = S.step;
      const X = new Float32Array(n), Y = new Float32Array(n), Z = new Float32Array(n);
      for (let i = 0; i < n; i++) {
        const x = q[3 * i] * step, y = q[3 * i + 1] * step, z = q[3 * i + 2] * step;
        X[i] = cx + s * (R[0] * x + R[1] * y + R[2] * z);
        Y[i] = cy - s * (R[3] * x + R[4] * y + R[5] * z);
        Z[i] = R[6] * x + R[7] * y + R[8] * z;
      }
      // smooth (vertex-normal) Lambert shading with a light fixed to the camera, averaged per triangle
      const nx = new Float32Array(n), ny = new Float32Array(n), nz = new Float32Array(n);
      for (let k = 0; k < t; k++) {
        const a = faces[3 * k], b = faces[3 * k + 1], c = faces[3 * k + 2];
        const ux = X[b] - X[a], uy = Y[a] - Y[b], uz = (Z[b] - Z[a]) * s;
        const vx = X[c] - X[a], vy = Y[a] - Y[c], vz = (Z[c] - Z[a]) * s;
        const fx = uy * vz - uz * vy, fy = uz * vx - ux * vz, fz = ux * vy - uy * vx;
        nx[a] += fx; ny[a] += fy; nz[a] += fz; nx[b] += fx; ny[b] += fy; nz[b] += fz; nx[c] += fx; ny[c] += fy; nz[c] += fz;
      }
      const L = S.light, shade = new Float32Array(n);
      for (let i = 0; i < n; i++) {
        const len = Math.hypot(nx[i], ny[i], nz[i]) || 1;
        shade[i] = 0.35 + 0.65 * Math.abs((nx[i] * L[0] + ny[i] * L[1] + nz[i] * L[2]) / len);
      }
      const img = ctx.createImageData(W, Hv);
      const px = new Uint32Array(img.data.buffer);
      px.fill(0xffffffff);
      const zbuf = new Float32Array(W * Hv).fill(-Infinity);
      for (let k = 0; k < t; k++) {
        const a = faces[3 * k], b = faces[3 * k + 1], c = faces[3 * k + 2];
        const x0 = X[a], y0 = Y[a], x1 = X[b], y1 = Y[b], x2 = X[c], y2 = Y[c];
        const area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0);
        if (!(area !== 0)) continue;
        const sg = area > 0 ? 1 : -1;
        const minx = Math.max(0, Math.ceil(Math.min(x0, x1, x2) - 0.5)), maxx = Math.min(W - 1, Math.floor(Math.max(x0, x1, x2) - 0.5));
        const miny = Math.max(0, Math.ceil(Math.min(y0, y1, y2) - 0.5)), maxy = Math.min(Hv - 1, Math.floor(Math.max(y0, y1, y2) - 0.5));
        if (minx > maxx || miny > maxy || (maxx - minx + 1) * (maxy - miny + 1) > 65536) continue;
        const depth = (Z[a] + Z[b] + Z[c]) / 3;
        const m = (mot[a] + mot[b] + mot[c]) / 3 | 0, sh = (shade[a] + shade[b] + shade[c]) / 3;
        const col = 0xff000000 | ((lut[3 * m + 2] * sh) << 16) | ((lut[3 * m + 1] * sh) << 8) | (lut[3 * m] * sh);
        const tol = 1e-6 * Math.abs(area);
        for (let py = miny; py <= maxy; py++) {
          const yc = py + 0.5;
          for (let pxi = minx; pxi <= maxx; pxi++) {
            const xc = pxi + 0.5;
            const e0 = sg * ((x1 - x0) * (yc - y0) - (y1 - y0) * (xc - x0));
            const e1 = sg * ((x2 - x1) * (yc - y1) - (y2 - y1) * (xc - x1));
            const e2 = sg * ((x0 - x2) * (yc - y2) - (y0 - y2) * (xc - x2));
            if (e0 >= -tol && e1 >= -tol && e2 >= -tol) {
              const o = py * W + pxi;
              if (depth > zbuf[o]) { zbuf[o] = depth; px[o] = col; }
            }
          }
        }
      }
      ctx.putImageData(img, 0, 0);
      // the selected vertices (cyan), where they are not hidden behind the face
      ctx.fillStyle = "cyan"; ctx.strokeStyle = "black"; ctx.lineWidth = 0.85;
      const tolz = 0.02 * S.extent;
      for (let j = 0; j < sel.length; j++) {
        const i = sel[j], xi = X[i], yi = Y[i];
        const o = Math.min(Hv - 1, Math.max(0, yi | 0)) * W + Math.min(W - 1, Math.max(0, xi | 0));
        if (Z[i] < zbuf[o] - tolz) continue;
        ctx.beginPath(); ctx.arc(xi, yi, 3.25, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
      }
      this.proj = { X, Y, Z, zbuf, W, Hv, tolz };
      // picks the kernel has not drawn yet (sent, or still being brushed)
      this.drawMarks([...this.marks.flatMap((m) => m.ids), ...this.outbox].filter((i) => this.visible(i)));
      this.colourBar(S, W, Hv, barH);
    }

    colourBar(S, W, top, h) {
      const ctx = this.ctx;
      ctx.fillStyle = "white"; ctx.fillRect(0, top, W, h);
      const x0 = Math.round(0.12 * W), bw = Math.round(0.76 * W), y0 = top + 22, bh = 10;
      const lut = S.a.lut;
      for (let i = 0; i < bw; i++) {
        const m = Math.round((i / (bw - 1)) * 255);
        ctx.fillStyle = `rgb(${lut[3 * m]},${lut[3 * m + 1]},${lut[3 * m + 2]})`;
        ctx.fillRect(x0 + i, y0, 1, bh);
      }
      ctx.strokeStyle = "#444"; ctx.lineWidth = 1; ctx.strokeRect(x0 + 0.5, y0 + 0.5, bw - 1, bh - 1);
      ctx.fillStyle = "#222"; ctx.font = "12px sans-serif"; ctx.textAlign = "center"; ctx.textBaseline = "alphabetic";
      ctx.fillText(S.bar_label, W / 2, y0 - 6);
      ctx.textBaseline = "top";
      const [lo, hi] = S.clim;
      for (const f of [0, 0.5, 1]) ctx.fillText(String(+(lo + f * (hi - lo)).toPrecision(3)), x0 + f * (bw - 1), y0 + bh + 3);
    }

    // ---------------------------------------------------------------- strike
    drawStrike(D) {
      const ctx = this.ctx, W = this.canvas.width, H = this.canvas.height;
      const nF = D.n_frames;
      if (this.playing) {  // the strike at its own rate; the last frame held, then again
        const el = (performance.now() - this.t0) / 1000, cycle = nF / D.fps + D.hold;
        this.f = Math.min(nF - 1, Math.floor((el % cycle) * D.fps));
      }
      const f = this.f, R = this.rotation(), C = D.centre;
      const top = 26, Hv = H - top - 22;
      const s = this.zoom * Math.min(W, Hv) / (2 * D.radius);
      const P = (arr, i) => {
        const x = arr[3 * i] - C[0], y = arr[3 * i + 1] - C[1], z = arr[3 * i + 2] - C[2];
        return [W / 2 + s * (R[0] * x + R[1] * y + R[2] * z), top + Hv / 2 - s * (R[3] * x + R[4] * y + R[5] * z)];
      };
      ctx.fillStyle = "white"; ctx.fillRect(0, 0, W, H);
      ctx.lineCap = "round";
      const lines = (arr, first, count, colour, width) => {
        ctx.strokeStyle = colour; ctx.lineWidth = width; ctx.beginPath();
        for (let k = first; k < first + count; k++) {
          const [ax, ay] = P(arr, 2 * k), [bx, by] = P(arr, 2 * k + 1);
          ctx.moveTo(ax, ay); ctx.lineTo(bx, by);
        }
        ctx.stroke();
      };
      const circle = (arr, i, r, fill, stroke, width) => {
        const [x, y] = P(arr, i);
        ctx.beginPath(); ctx.arc(x, y, Math.max(1, r * s), 0, 2 * Math.PI);
        ctx.fillStyle = fill; ctx.fill(); ctx.strokeStyle = stroke; ctx.lineWidth = width; ctx.stroke();
      };
      const a = D.a;
      lines(a.floor, 0, a.floor.length / 6, "#dbdbdb", 1);
      if (D.n_original) {
        lines(a.original, f * D.n_original, D.n_original, "#9e9e9e", 1.6);
        circle(a.original_head, f, D.head_r, "white", "#9e9e9e", 1.6);
      }
      circle(a.target, 0, D.target_r, "rgba(26,26,128,0.12)", "navy", 1.3);
      lines(a.adapted, f * D.n_bones, D.n_bones, "#1f77b4", 3);
      circle(a.head, f, D.head_r, "#cfe3f5", "#1f77b4", 2.2);
      ctx.strokeStyle = "#d62728"; ctx.lineWidth = 1.4; ctx.setLineDash([5, 4]); ctx.beginPath();
      for (let i = 0; i <= f; i++) { const [x, y] = P(a.hit, i); if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y); }
      ctx.stroke(); ctx.setLineDash([]);
      const [hx, hy] = P(a.hit, f);
      ctx.fillStyle = "#d62728"; ctx.beginPath(); ctx.arc(hx, hy, 3.5, 0, 2 * Math.PI); ctx.fill();
      ctx.fillStyle = "#222"; ctx.font = "13px sans-serif"; ctx.textAlign = "left"; ctx.textBaseline = "top";
      const label = f === D.tc ? " (contact)" : (f === 0 ? " (order)" : "");
      ctx.fillText(`${D.strike}, t = ${(f / D.fps).toFixed(2)} s${label}`, 8, 6);
      ctx.font = "12px sans-serif"; ctx.textBaseline = "bottom";
      ctx.fillText("blue: adapted   grey: retrieved clip   circle: target   red: hit path", 8, H - 4);
      if (this.playing) this.schedule();
    }
  }

  window.reproWebview = {
    version: VERSION,
    parse,
    View,
    // called by the view's markup when the page shows it: wait for the widget box, then draw
    attach(marker) {
      let tries = 0;
      const go = () => {
        const box = marker.closest(".repro-webview-box");
        const ready = box && box.querySelector("img.repro-webview-static") && box.querySelector("img.repro-webview-frame");
        if (!ready) { if (tries++ < 1200) setTimeout(go, 25); return; }
        if (!box.reproView) box.reproView = new View(box, marker.closest(".repro-webview"));
      };
      go();
    },
  };
})();
