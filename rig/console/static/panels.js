// cutlab console: the panels beside the live plot (DRO, per-revolution readouts, XY toolpath,
// spectrum with the lobes' chatter frequency and the detected peak, stability margin, logger
// health). Plain functions called by console.js (loaded after this; they read its state, the
// page's globals, at call time).
"use strict";

// -- the DRO: as the controller reports it, or estimated from the program (drip feed) -------
function fmtNum(v, digits) {
  return v === null || v === undefined || !isFinite(v) ? "-" : Number(v).toFixed(digits);
}

function showDro(m) {
  const p = m.pos_mm || [null, null, null];
  ["x", "y", "z"].forEach((a, i) => ($(`dro-${a}`).textContent = fmtNum(p[i], 3)));
  $("dro-feed").textContent = fmtNum(m.feed_mm_min, 0);
  $("dro-spindle").textContent = fmtNum(m.spindle_rpm, 0);
  const ov = m.overrides_pct;
  $("dro-overrides").textContent = ov
    ? `feed ${ov.feed}%, rapid ${ov.rapid}%, spindle ${ov.spindle}%`
    : "not reported";
  $("dro").classList.toggle("estimated", !!m.estimated);
  $("dro-estimated").classList.toggle("hidden", !m.estimated);
  $("dro-estimated").title = m.source || "";
  window.cutlab.dro = m;
}

// -- per-revolution readouts (the server cuts revolutions as analysis.runs.per_revolution) ---
function showReadouts(r) {
  window.cutlab.readouts = r;
  $("readout-head").textContent = `revolution ${r.rev} at ${r.t_s.toFixed(3)} s (${r.rpm} rpm), ${r.unit}`;
  for (const what of ["mean", "peak", "rms"]) {
    const tr = $(`readout-${what}`);
    tr.dataset.rev = r.rev;
    while (tr.children.length > 1) tr.removeChild(tr.lastChild);
    r.channels.forEach((name, c) => {
      const td = document.createElement("td");
      td.dataset.channel = name;
      td.textContent = `${name} ${r[what][c].toFixed(1)}`;
      tr.appendChild(td);
    });
  }
}

// -- the toolpath, XY: the program (grey), the cut so far (blue), the executing block --------
// (a browsed run: its program, and its executed path as estimated from its run file, in blue)
function shownToolpath() {
  return browsing && browsePath ? browsePath.toolpath : toolpath;
}

function drawToolpath() {
  const cv = $("toolpath");
  const ctx = cv.getContext("2d");
  const W = cv.width, H = cv.height, pad = 10;
  ctx.clearRect(0, 0, W, H);
  const segs = shownToolpath();
  if (!segs.length) return;
  let [x0, x1, y0, y1] = [Infinity, -Infinity, Infinity, -Infinity];
  for (const s of segs) {
    x0 = Math.min(x0, s[2], s[4]); x1 = Math.max(x1, s[2], s[4]);
    y0 = Math.min(y0, s[3], s[5]); y1 = Math.max(y1, s[3], s[5]);
  }
  const k = Math.min((W - 2 * pad) / Math.max(x1 - x0, 1e-6), (H - 2 * pad) / Math.max(y1 - y0, 1e-6));
  const px = (x) => pad + (x - x0) * k;
  const py = (y) => H - pad - (y - y0) * k; // Y up
  const exec = browsing ? -1 : execBlock;
  const seg = (s, color, width) => {
    ctx.strokeStyle = color; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(px(s[2]), py(s[3])); ctx.lineTo(px(s[4]), py(s[5])); ctx.stroke();
  };
  for (const s of segs) seg(s, s[1] === 0 ? "#cfd8dc" : "#90a4ae", 1);
  if (exec >= 0) for (const s of segs) if (s[0] < exec && s[1] !== 0) seg(s, "#1e88e5", 2);
  ctx.lineCap = "round";
  for (const s of segs) {
    if (s[0] !== exec) continue;
    seg(s, "#ff6f00", 4);
    ctx.fillStyle = "#ff6f00"; // a plunge (no XY travel) shows as a dot
    ctx.beginPath(); ctx.arc(px(s[4]), py(s[5]), 3, 0, 2 * Math.PI); ctx.fill();
  }
  ctx.lineCap = "butt";
  const trail = browsing && browsePath ? browsePath.trail : [];
  if (trail.length > 1) {
    ctx.strokeStyle = "#1e88e5"; ctx.lineWidth = 2;
    ctx.beginPath();
    trail.forEach((p, i) => (i ? ctx.lineTo(px(p[1]), py(p[2])) : ctx.moveTo(px(p[1]), py(p[2]))));
    ctx.stroke();
  }
  // the tool: where it is now, or where a browsed run left it
  const p = browsing ? (trail.length ? trail[trail.length - 1].slice(1) : null) : (status.machine || {}).pos_mm;
  if (p) {
    ctx.fillStyle = "#d32f2f";
    ctx.beginPath(); ctx.arc(px(p[0]), py(p[1]), 4, 0, 2 * Math.PI); ctx.fill();
  }
  tpView = { x0, y0, k, pad, W, H, block: exec, executing_color: "#ff6f00", browsed: !!(browsing && browsePath) };
  cv.dataset.block = exec;
}

// -- the live spectrum: per channel, tooth-passing harmonics (grey), chatter frequency (red) --
function drawSpectrum(sp) {
  window.cutlab.spectrum = sp;
  const cv = $("spectrum");
  const ctx = cv.getContext("2d");
  const W = cv.width, H = cv.height, L = 34, B = 18, T = 6;
  ctx.clearRect(0, 0, W, H);
  const fMax = sp.f_hz[sp.f_hz.length - 1] || 1;
  let aMax = 1e-9;
  for (const a of sp.amp) for (const v of a) aMax = Math.max(aMax, v);
  const x = (f) => L + (f / fMax) * (W - L - 4);
  const y = (a) => H - B - (a / aMax) * (H - B - T);
  ctx.font = "10px monospace";
  ctx.fillStyle = "#666";
  ctx.fillText(`${aMax.toFixed(1)} ${sp.unit}`, 0, T + 8);
  ctx.fillText("0", L - 10, H - B);
  ctx.fillText(`${fMax.toFixed(0)} Hz`, W - 48, H - 4);
  if (sp.tooth_hz) {
    ctx.strokeStyle = "#b0bec5";
    ctx.setLineDash([3, 3]);
    for (let h = 1; h * sp.tooth_hz <= fMax; h++) {
      ctx.beginPath(); ctx.moveTo(x(h * sp.tooth_hz), T); ctx.lineTo(x(h * sp.tooth_hz), H - B);
      ctx.stroke();
    }
    ctx.setLineDash([]);
    ctx.fillText(`tooth ${sp.tooth_hz.toFixed(1)} Hz`, L + 2, H - 4);
  }
  $("spectrum-note").textContent = sp.chatter_hz
    ? `chatter ${sp.chatter_hz.toFixed(0)} Hz (lobes)`
    : "chatter frequency: not known (no lobes)";
  showChatter(sp);
  sp.amp.forEach((a, c) => {
    ctx.strokeStyle = COLORS[c % COLORS.length];
    ctx.beginPath();
    a.forEach((v, i) => (i ? ctx.lineTo(x(sp.f_hz[i]), y(v)) : ctx.moveTo(x(sp.f_hz[i]), y(v))));
    ctx.stroke();
  });
  // the lobes' predicted chatter frequency (black, solid), the detected peak (purple, dashed)
  const marks = {};
  const peakHz = sp.peak && sp.peak.peak_hz;
  // (over the traces; the peak first, with a triangle on top: where the two agree, both stay visible)
  for (const [f, colour, dash, key] of [[peakHz, "#7b1fa2", [4, 2], "peak_x"],
                                        [sp.chatter_hz, "#000000", [], "predicted_x"]]) {
    if (!f || f > fMax) continue;
    const xf = Math.round(x(f)) + 0.5; // on a pixel's centre: a crisp line
    ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.setLineDash(dash);
    ctx.beginPath(); ctx.moveTo(xf, T); ctx.lineTo(xf, H - B); ctx.stroke();
    ctx.setLineDash([]); ctx.lineWidth = 1;
    if (key === "peak_x") {
      ctx.fillStyle = colour;
      ctx.beginPath(); ctx.moveTo(xf - 5, T); ctx.lineTo(xf + 5, T); ctx.lineTo(xf, T + 8); ctx.fill();
    }
    marks[key] = xf;
  }
  window.cutlab.spectrumMarks = marks;
}

// -- the lobes at this speed beside the detected peak; the stability margin ------------------
function showChatter(sp) {
  const st = sp.stability || {};
  const pk = sp.peak || {};
  const pred = sp.chatter_hz ? `predicted ${sp.chatter_hz.toFixed(0)} Hz (lobes at ${st.rpm} rpm)` : `predicted: ${st.reason || "not known"}`;
  const det = pk.peak_hz
    ? `detected peak ${pk.peak_hz.toFixed(0)} Hz off the spindle harmonics` +
      (pk.judged ? ` (${pk.chatter ? "chatter" : "no chatter"}: ${(100 * pk.energy_ratio).toFixed(0)} % of the energy, threshold ${(100 * pk.energy_threshold).toFixed(0)} %)` : "")
    : `detected peak: ${pk.reason || "none"}`;
  $("chatter-frequency").textContent = `${pred}; ${det}`;
  const m = $("stability-margin");
  if (st.depth_limit_mm !== undefined) {
    m.textContent = st.depth_limit_mm === null
      ? `depth ${st.depth_mm} mm: stable at every depth searched at ${st.rpm} rpm`
      : `depth ${st.depth_mm} mm of the ${st.depth_limit_mm.toFixed(3)} mm limit at ${st.rpm} rpm: ` +
        `${st.depth_pct.toFixed(0)} % (${st.stable ? "stable" : "the lobes predict chatter"})`;
    m.classList.toggle("flag", st.stable === false);
  } else {
    m.textContent = `stability margin: ${st.reason || "not known"}`;
    m.classList.remove("flag");
  }
}

// -- the logger's health: rate achieved vs configured, samples written (flagged beyond 5 %) --
function showLogger(l) {
  window.cutlab.logger = l;
  const el = $("logger-health");
  if (!l) {
    el.textContent = "-";
    el.dataset.flag = "";
    return;
  }
  const rate = l.achieved_hz === null ? "-" : l.achieved_hz.toFixed(0);
  const wr = l.written_pct === null ? "-" : `${l.written_pct.toFixed(1)} %`;
  el.textContent = `${rate} of ${l.configured_hz} Hz (${l.rate_dev_pct === null ? "-" : (l.rate_dev_pct > 0 ? "+" : "") + l.rate_dev_pct.toFixed(1) + " %"}), ` +
    `${wr} written${l.lost ? `, ${l.lost} samples lost` : ""}` +
    (l.flag ? ` - beyond ${l.tolerance_pct} %: ${l.why}` : l.judged ? ` - within ${l.tolerance_pct} %` : ` (${l.why})`);
  el.dataset.flag = l.judged ? String(l.flag) : "";
  el.classList.toggle("flag", !!l.flag);
}
