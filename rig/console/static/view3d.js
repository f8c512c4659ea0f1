// cutlab console: the 3-D toolpath view. A hand-written orthographic projection on a 2-D canvas
// (no 3-D library is vendored, and the page must work offline): the planned path (the program as
// the controller runs it, grey; rapids lighter), the executed path (the machine's reported or
// estimated positions, coloured by force or feed) and the tool where it is now (red, with its
// axis). Drag to rotate, wheel to zoom, double-click to reset.
"use strict";

// viridis, 5 stops: low values dark blue, high yellow (the tool's red stays apart)
const V3D_STOPS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
const V3D_BINS = 16; // executed segments are stroked in this many colours (one path each)
const V3D_TOOL = "#d50000";
const V3D_MIN_MS = 200; // redrawn at most 5 times a second (software rendering is dear)

function v3dColour(f) {
  const x = Math.min(1, Math.max(0, f)) * (V3D_STOPS.length - 1);
  const i = Math.min(V3D_STOPS.length - 2, Math.floor(x));
  const t = x - i;
  const c = V3D_STOPS[i].map((a, k) => Math.round(a + t * (V3D_STOPS[i + 1][k] - a)));
  return `rgb(${c[0]},${c[1]},${c[2]})`;
}

class View3D {
  constructor(canvas, legend) {
    this.cv = canvas;
    this.legend = legend;
    // what is shown: the live run's paths, or a browsed run's (show()); live updates go on
    // into the live ones meanwhile
    this.live = { planned: [], trail: [], pos: null };
    this.d = this.live;
    this.colourBy = "force";
    this.reset();
    this.lastDraw = 0;
    this.pending = false;
    this.frames = 0;
    this._wire();
  }

  reset() {
    this.yaw = (-35 * Math.PI) / 180;
    this.pitch = (55 * Math.PI) / 180; // 0: seen from above; 90: from the side
    this.zoom = 1;
    this.request(true);
  }

  _wire() {
    let drag = null;
    this.cv.addEventListener("mousedown", (e) => (drag = [e.clientX, e.clientY]));
    window.addEventListener("mouseup", () => (drag = null));
    window.addEventListener("mousemove", (e) => {
      if (!drag) return;
      this.rotate((e.clientX - drag[0]) * 0.01, (e.clientY - drag[1]) * 0.01);
      drag = [e.clientX, e.clientY];
    });
    this.cv.addEventListener("wheel", (e) => {
      e.preventDefault();
      this.zoomBy(e.deltaY < 0 ? 1.2 : 1 / 1.2);
    }, { passive: false });
    this.cv.addEventListener("dblclick", () => this.reset());
  }

  rotate(dYaw, dPitch) {
    this.yaw += dYaw;
    this.pitch = Math.min(Math.PI / 2, Math.max(0, this.pitch + dPitch));
    this.request(true);
  }

  zoomBy(f) {
    this.zoom = Math.min(50, Math.max(0.2, this.zoom * f));
    this.request(true);
  }

  get planned() { return this.d.planned; } // [block, kind, x0, y0, x1, y1, z0, z1]
  get trail() { return this.d.trail; } // [t, x, y, z, feed, force]
  get pos() { return this.d.pos; } // [x, y, z] mm

  // the live run's paths (drawn while they are the ones shown)
  setPlanned(segs) {
    this.live.planned = segs || [];
    if (this.d === this.live) { this._fit = null; this.request(); }
  }
  setTrail(points, reset) {
    if (reset) this.live.trail = points.slice();
    else for (const p of points) this.live.trail.push(p);
    if (this.d === this.live) this.request();
  }
  setPosition(p) {
    const q = this.live.pos;
    const same = p && q && p[0] === q[0] && p[1] === q[1] && p[2] === q[2];
    this.live.pos = p && p.length >= 3 && p[2] !== null ? p.slice(0, 3) : null;
    if (!same && this.d === this.live) this.request();
  }
  // a browsed run's paths ({planned, trail, pos}), or null: the live run's again
  show(data) {
    this.d = data || this.live;
    this._fit = null;
    this.request(true);
  }
  setColourBy(what) { this.colourBy = what; this.request(true); }

  // -- a redraw now (interaction) or at most every V3D_MIN_MS (data) --------------------------
  request(now) {
    if (now) return this.draw();
    if (this.pending) return;
    this.pending = true;
    const wait = Math.max(0, V3D_MIN_MS - (performance.now() - this.lastDraw));
    setTimeout(() => requestAnimationFrame(() => { this.pending = false; this.draw(); }), wait);
  }

  // the box the view fits: the planned path (else the executed one)
  _box() {
    if (this._fit && this._fit.n === this.planned.length + (this.planned.length ? 0 : this.trail.length)) return this._fit;
    let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    const add = (x, y, z) => {
      [x, y, z].forEach((v, k) => { if (v !== null && isFinite(v)) { lo[k] = Math.min(lo[k], v); hi[k] = Math.max(hi[k], v); } });
    };
    for (const s of this.planned) { add(s[2], s[3], s[6]); add(s[4], s[5], s[7]); }
    if (!this.planned.length) for (const p of this.trail) add(p[1], p[2], p[3]);
    if (!isFinite(lo[0])) { lo = [0, 0, 0]; hi = [1, 1, 1]; }
    const c = lo.map((a, k) => (a + hi[k]) / 2);
    const r = Math.max(1e-3, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
    this._fit = { c, r, n: this.planned.length + (this.planned.length ? 0 : this.trail.length) };
    return this._fit;
  }

  // mm -> canvas px (also for tests and screenshots: window.cutlab.project3d)
  project(x, y, z) {
    const { c, r } = this._box();
    const W = this.cv.width, H = this.cv.height;
    const s = (0.45 * Math.min(W, H) * this.zoom) / r;
    const dx = x - c[0], dy = y - c[1], dz = z - c[2];
    const cy = Math.cos(this.yaw), sy = Math.sin(this.yaw);
    const xr = cy * dx - sy * dy, yr = sy * dx + cy * dy;
    const up = yr * Math.cos(this.pitch) + dz * Math.sin(this.pitch);
    return [W / 2 + s * xr, H / 2 - s * up];
  }

  _range() {
    const k = this.colourBy === "feed" ? 4 : 5;
    let lo = Infinity, hi = -Infinity;
    for (const p of this.trail) if (p[k] !== null && isFinite(p[k])) { lo = Math.min(lo, p[k]); hi = Math.max(hi, p[k]); }
    return isFinite(lo) ? [k, lo, hi] : [k, null, null];
  }

  draw() {
    this.lastDraw = performance.now();
    const ctx = this.cv.getContext("2d");
    ctx.clearRect(0, 0, this.cv.width, this.cv.height);
    const P = (x, y, z) => this.project(x, y, z);
    // planned: rapids light and dashed, feeds grey
    for (const rapid of [true, false]) {
      ctx.strokeStyle = rapid ? "#cfd8dc" : "#90a4ae";
      ctx.setLineDash(rapid ? [3, 3] : []);
      ctx.lineWidth = 1;
      ctx.beginPath();
      for (const s of this.planned) {
        if ((s[1] === 0) !== rapid) continue;
        const a = P(s[2], s[3], s[6]), b = P(s[4], s[5], s[7]);
        ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]);
      }
      ctx.stroke();
    }
    ctx.setLineDash([]);
    // executed, coloured by the value at each segment's end
    const [k, lo, hi] = this._range();
    const paths = Array.from({ length: V3D_BINS + 1 }, () => []);
    for (let i = 1; i < this.trail.length; i++) {
      const v = this.trail[i][k];
      const bin = v === null || lo === null ? V3D_BINS : Math.min(V3D_BINS - 1, Math.floor(((v - lo) / Math.max(hi - lo, 1e-9)) * V3D_BINS));
      paths[bin].push(i);
    }
    ctx.lineWidth = 2.5;
    ctx.lineCap = "round";
    paths.forEach((idx, bin) => {
      if (!idx.length) return;
      ctx.strokeStyle = bin === V3D_BINS ? "#546e7a" : v3dColour((bin + 0.5) / V3D_BINS);
      ctx.beginPath();
      for (const i of idx) {
        const p = this.trail[i - 1], q = this.trail[i];
        const a = P(p[1], p[2], p[3]), b = P(q[1], q[2], q[3]);
        ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]);
      }
      ctx.stroke();
    });
    ctx.lineCap = "butt";
    // the tool: its axis up from the tip, the tip
    if (this.pos) {
      const [x, y, z] = this.pos;
      const tip = P(x, y, z), top = P(x, y, z + 0.25 * this._box().r);
      ctx.strokeStyle = V3D_TOOL; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.moveTo(tip[0], tip[1]); ctx.lineTo(top[0], top[1]); ctx.stroke();
      ctx.fillStyle = V3D_TOOL;
      ctx.beginPath(); ctx.arc(tip[0], tip[1], 5, 0, 2 * Math.PI); ctx.fill();
    }
    const unit = k === 4 ? "mm/min" : "N";
    if (this.legend) {
      this.legend.textContent = lo === null
        ? `executed path: ${this.trail.length} points, no ${this.colourBy} yet`
        : `executed path coloured by ${this.colourBy}: dark ${lo.toFixed(0)} to yellow ${hi.toFixed(0)} ${unit} (${this.trail.length} points)`;
    }
    this.frames += 1;
    this.cv.dataset.frames = this.frames;
  }

  state() {
    return { yaw: this.yaw, pitch: this.pitch, zoom: this.zoom, W: this.cv.width, H: this.cv.height,
             colourBy: this.colourBy, pos: this.pos, planned: this.planned.length,
             shown: this.d === this.live ? "live" : "browsed",
             trail: this.trail.length, frames: this.frames, tool_colour: V3D_TOOL,
             range: this._range().slice(1) };
  }
}

window.View3D = View3D;
