// cutlab live console: plain JS, no build step. Talks to /ws (frames, status, commands) and
// /api/* (finished runs). Every value shown comes from the server (the machine state is the one
// read back from the controller, never the button pressed).
"use strict";

const $ = (id) => document.getElementById(id);

// The session's token: printed with the address (?token=...), kept for this tab, sent with every
// request and websocket (the server refuses data and commands without it). It is taken out of the
// address bar so a screenshot or a shared link does not carry it.
const TOKEN = (() => {
  const url = new URL(location.href);
  const t = url.searchParams.get("token");
  if (t) {
    sessionStorage.setItem("cutlab-token", t);
    url.searchParams.delete("token");
    history.replaceState(null, "", url.pathname + url.search + url.hash);
    return t;
  }
  return sessionStorage.getItem("cutlab-token") || ""; // else the server's cookie answers
})();
const COLORS = ["#1e88e5", "#e53935", "#43a047", "#8e24aa", "#fb8c00", "#00897b"];
const WINDOW_S = 10;

let ws = null;
let frames = 0;
let meta = null;
let status = {};
let plot = null;
let plotChannels = "";
let bins = { t: [], min: [], max: [] };
let bands = [];
let execBlock = -1;
let drawnBlock = -1; // the executing block shaded in the plot as last drawn
let browsing = null; // run file being browsed, or null: live
let browseSpans = [];
let programKey = "";
let eventsKey = "";
let liveState = { live: false, alive: false, ended: "" };
let serverGone = false; // the server said it stops (or the campaign ended): no reconnecting
let lostSince = null;
const RECONNECT_FOR_MS = 120000; // then the page says the server is gone and stops trying
let paused = false; // the live plot holds still (zoom, scroll-back); samples keep coming
let toolpath = []; // [block, kind, x0, y0, x1, y1] per segment, from the run info
let browsePath = null; // a browsed run's {toolpath, trail, source} (rig.console.run_path)
let tpView = null; // the toolpath canvas's transform (mm -> px), for tests and screenshots
const view3d = new View3D($("toolpath3d"), $("tp3d-legend"));
$("tp3d-colour").onchange = (e) => view3d.setColourBy(e.target.value);
$("tp3d-reset").onclick = () => view3d.reset();
const latencies = []; // sample-to-screen, ms, the last LAT_N frames with new samples
const latencyParts = []; // [server ms, page ms] of the same frames
const LAT_N = 250;
window.cutlab = {
  latencies,
  latencyParts,
  readouts: null,
  dro: null,
  toolpath: () => tpView,
  view3d: () => view3d.state(),
  project3d: (x, y, z) => view3d.project(x, y, z),
  trail: () => view3d.trail,
  logger: null,
  toolpathSegments: () => shownToolpath(),
  browsePath: () => browsePath,
  status: () => status,
  latest: () => (bins.t.length ? bins.t[bins.t.length - 1] : null), // run clock s
  view: null, // the zoomed or whole-run view, while paused
};

function fmtS(s) {
  if (s === null || s === undefined || !isFinite(s)) return "-";
  s = Math.max(0, Math.round(s));
  const m = Math.floor(s / 60);
  return m ? `${m} min ${s % 60} s` : `${s} s`;
}

function plotWidth() {
  return Math.max(300, $("plot").clientWidth || 900);
}

// -- the plot: min/max per pixel, one band per channel, NC blocks as shaded spans ------------
function drawBands(u) {
  const spans = browsing ? browseSpans : bands;
  if (!spans.length) return;
  const ctx = u.ctx;
  const { left, top, width, height } = u.bbox;
  const [x0, x1] = [u.scales.x.min, u.scales.x.max];
  ctx.save();
  ctx.font = `${11 * devicePixelRatio}px monospace`;
  spans.forEach((s, i) => {
    const [blk, t0, t1raw] = s;
    const t1 = t1raw === null ? x1 : t1raw;
    if (t1 < x0 || t0 > x1) return;
    const a = u.valToPos(Math.max(t0, x0), "x", true);
    const b = u.valToPos(Math.min(t1, x1), "x", true);
    const exec = !browsing && blk === execBlock;
    ctx.fillStyle = exec ? "rgba(255,193,7,0.25)" : i % 2 ? "rgba(0,0,0,0.04)" : "rgba(0,0,0,0.0)";
    ctx.fillRect(a, top, Math.max(1, b - a), height);
    ctx.fillStyle = "rgba(0,0,0,0.25)";
    ctx.fillRect(a, top, 1, height);
    if (b - a > 24 * devicePixelRatio) {
      ctx.fillStyle = "#555";
      ctx.fillText(String(blk), a + 3, top + 12 * devicePixelRatio);
    }
  });
  ctx.restore();
}

function makePlot(channels, unit) {
  const key = channels.join(",") + unit;
  if (plot && plotChannels === key) return;
  if (plot) plot.destroy();
  plotChannels = key;
  const series = [{ label: "t, s" }];
  const bandsOpt = [];
  channels.forEach((name, c) => {
    const color = COLORS[c % COLORS.length];
    series.push({ label: `${name} max, ${unit}`, stroke: color, width: 1 });
    series.push({ label: `${name} min, ${unit}`, stroke: color, width: 1 });
    bandsOpt.push({ series: [1 + 2 * c, 2 + 2 * c], fill: color + "55" });
  });
  plot = new uPlot(
    {
      width: plotWidth(),
      height: 360,
      series,
      bands: bandsOpt,
      scales: { x: { time: false } },
      axes: [{ label: "run clock, s" }, { label: unit }],
      hooks: { drawClear: [drawBands], setSelect: [onSelect] },
      cursor: { drag: { x: true, y: false, setScale: false } },
      legend: { live: false },
    },
    [[]].concat(channels.flatMap(() => [[], []])),
    $("plot"),
  );
}

// -- zoom (drag across the plot), pause, scroll back over the whole run: the server sends min and
// max per pixel, or the samples themselves once the view holds no more than two a pixel ------
function onSelect(u) {
  if (u.select.width < 5) return;
  const t0 = u.posToVal(u.select.left, "x");
  const t1 = u.posToVal(u.select.left + u.select.width, "x");
  u.setSelect({ left: 0, top: 0, width: 0, height: 0 }, false);
  zoomTo(t0, t1);
}

async function zoomTo(t0, t1) {
  const q = new URLSearchParams({ px: String(plotWidth()) });
  if (browsing) q.set("file", browsing);
  else {
    q.set("live", "1");
    setPaused(true);
  }
  if (t0 !== undefined) q.set("t0", t0);
  if (t1 !== undefined) q.set("t1", t1);
  try {
    const tr = await getJSON(`/api/trace?${q}`);
    makePlot(tr.channels, tr.unit);
    setPlotData(tr.t, tr.min, tr.max);
    window.cutlab.view = { t0, t1, raw: tr.raw, n: tr.n, t: tr.t, min: tr.min, max: tr.max,
                           run: tr.run ?? null };
    $("view-note").textContent = tr.raw
      ? `${tr.n} samples, as recorded`
      : `min and max per pixel of ${tr.n} samples`;
  } catch (e) {
    $("view-note").textContent = `cannot show that: ${e.message}`;
  }
}

function setPaused(on) {
  paused = on;
  $("pause").textContent = on ? "Follow live" : "Pause";
  if (!on) {
    $("view-note").textContent = "";
    window.cutlab.view = null;
    if (meta && !browsing) {
      makePlot(meta.channels, "N");
      setPlotData(bins.t, bins.min, bins.max);
    }
  }
}

$("pause").onclick = () => setPaused(!paused && !browsing);
$("scroll-back").onclick = () => zoomTo();

function setPlotData(t, mins, maxs) {
  if (!plot) return;
  const data = [t];
  for (let c = 0; c < mins.length; c++) data.push(maxs[c], mins[c]);
  plot.setData(data);
}

// -- live bins: a bin may come again (it was still growing): the newer one wins --------------
function addBins(b) {
  if (!b.t.length) return;
  const first = b.t[0];
  let keep = bins.t.length;
  while (keep > 0 && bins.t[keep - 1] >= first - 1e-9) keep--;
  bins.t = bins.t.slice(0, keep).concat(b.t);
  for (let c = 0; c < b.min.length; c++) {
    bins.min[c] = (bins.min[c] || []).slice(0, keep).concat(b.min[c]);
    bins.max[c] = (bins.max[c] || []).slice(0, keep).concat(b.max[c]);
  }
  const tEnd = bins.t[bins.t.length - 1];
  let drop = 0;
  while (drop < bins.t.length && bins.t[drop] < tEnd - WINDOW_S) drop++;
  if (drop) {
    bins.t = bins.t.slice(drop);
    bins.min = bins.min.map((a) => a.slice(drop));
    bins.max = bins.max.map((a) => a.slice(drop));
  }
}

// -- the program view ------------------------------------------------------------------------
function showProgram(lines, name) {
  const key = name + ":" + lines.length;
  if (key === programKey) return;
  programKey = key;
  $("program-name").textContent = name || "";
  const ol = $("program");
  ol.innerHTML = "";
  for (const [block, line, text] of lines) {
    const li = document.createElement("li");
    li.value = line;
    li.dataset.block = block;
    li.textContent = text;
    ol.appendChild(li);
  }
}

function highlightBlock(ol, block) {
  let hit = null;
  for (const li of ol.children) {
    const on = Number(li.dataset.block) === block;
    li.classList.toggle("exec", on);
    if (on) hit = li;
  }
  if (hit) scrollWithin(ol, hit);
}

// The list's own scroll, not the window's (scrollIntoView scrolled the whole page to the program
// on every status, 25 a second: the operator could not keep the 3-D view or the spectrum in sight)
function scrollWithin(list, item) {
  const r = item.getBoundingClientRect(), o = list.getBoundingClientRect();
  if (r.top < o.top) list.scrollTop -= o.top - r.top;
  else if (r.bottom > o.bottom) list.scrollTop += r.bottom - o.bottom;
}

// -- status ----------------------------------------------------------------------------------
function showStatus(s) {
  status = s || {};
  $("campaign").textContent = `cutlab console: ${s.campaign || ""}`;
  $("run-progress").textContent = s.runs ? `${s.run}/${s.runs}` : "-";
  $("run-name").textContent = s.run_name || "";
  $("elapsed").textContent = fmtS(s.elapsed_s);
  $("remaining").textContent = fmtS(s.remaining_s);
  $("phase").textContent = s.phase || "";
  const m = s.machine;
  if (m) {
    const st = $("machine-state");
    st.textContent = m.state || "-";
    st.className = "state " + (m.state || "").split(":")[0];
    showDro(m);
    $("source").textContent = m.source ? `(${m.source})` : "";
  }
  // the adaptive loop (rig.adaptive): its target beside the force it judged, the overrides
  const ad = s.adaptive;
  $("adaptive").textContent = ad
    ? `${ad.mode}, ${ad.state}: target ${ad.target_force_n} N, last revolution ` +
      `${ad.force_n === null ? "-" : ad.force_n} N, feed ${ad.feed_pct}%, spindle ` +
      `${ad.spindle_pct}%` + (ad.hold ? `; held: ${ad.hold}` : "")
    : "off";
  const str = s.stream;
  if (str) {
    $("protocol").textContent = str.protocol || "";
    $("sent").textContent = str.sent;
    $("acked").textContent = str.acknowledged;
    $("executing").textContent = str.executing;
    $("executed").textContent = str.executed;
    $("done").textContent = `${str.blocks_done}/${str.blocks_total}`;
  }
  if (s.executing_block !== undefined) {
    execBlock = s.executing_block;
    $("executing-block").textContent = execBlock;
    highlightBlock($("program"), execBlock);
  }
  if (s.bands) bands = s.bands;
  showEvents(s.events || []);
  drawToolpath();
  // the tool stays where it was last reported (between runs, after the end: nothing reported)
  const pos = (s.machine || {}).pos_mm;
  if (pos) view3d.setPosition(pos); // the live one's, shown when not browsing
  if (s.logger !== undefined) showLogger(s.logger);
  updateControls();
  if (s.command && s.command.seq) {
    $("cmd-note").textContent = `${s.command.cmd}: ${s.command.message}`;
  }
}

// -- sample-to-screen latency: the frame's newest block came into the ring at written_ms (the
// server's wall clock, this computer's); the frame is on screen at the next animation frame --
function noteLatency(writtenMs, sentMs) {
  requestAnimationFrame(() => {
    const now = Date.now();
    const ms = now - writtenMs;
    if (!(ms >= 0 && ms < 60000)) return;
    latencies.push(ms);
    // the server's part (ring to websocket) and the rest (network, page, paint)
    latencyParts.push([sentMs - writtenMs, now - sentMs]);
    if (latencies.length > LAT_N) latencies.shift();
    if (latencyParts.length > LAT_N) latencyParts.shift();
    if (latencies.length % 5 === 0) {
      const q = [...latencies].sort((a, b) => a - b);
      const at = (f) => q[Math.min(q.length - 1, Math.floor(f * q.length))];
      $("latency").textContent = `p50 ${at(0.5).toFixed(0)} ms, p95 ${at(0.95).toFixed(0)} ms`;
      $("latency").title = `${q.length} frames`;
    }
  });
}

// -- the buttons act only when they mean something ------------------------------------------
function updateControls() {
  const c = status.controls || {};
  const live = !browsing && liveState.live && liveState.alive && !liveState.ended && !serverGone;
  for (const cmd of ["hold", "resume", "abort"]) $(cmd).disabled = !(live && c[cmd]);
  $("mode").textContent = browsing || !live ? "browse" : "live";
  if (liveState.ended || serverGone) {
    $("machine-state").textContent = "ended";
    $("machine-state").className = "state ended";
  }
}

function showEvents(events) {
  const last = events[events.length - 1];
  const key = events.length + ":" + (last ? last.wall : "");
  if (key === eventsKey) return;
  eventsKey = key;
  const ul = $("events");
  ul.innerHTML = "";
  for (const e of events) {
    const li = document.createElement("li");
    li.className = e.kind;
    const t = e.t_s === null ? "" : ` t=${e.t_s.toFixed(3)} s`;
    li.textContent = `run ${e.run}${t} ${e.kind}: ${e.message}`;
    ul.appendChild(li);
  }
  ul.scrollTop = ul.scrollHeight;
}

function showLive(live) {
  liveState = live;
  const el = $("ended");
  const until = live.until
    ? `; this console stays until ${new Date(live.until * 1000).toLocaleTimeString()}`
    : "";
  if (!live.live) {
    el.textContent = "no campaign running here: browse its runs";
  } else if (live.ended === "gone") {
    el.textContent =
      "the campaign process has ended without closing (killed or crashed); the last state is " +
      `shown, its runs can be browsed${until}`;
  } else if (live.ended === "closed") {
    const ph = status.phase ? ` (${status.phase})` : "";
    el.textContent = `the campaign has ended${ph}: browse its runs${until}`;
  }
  el.classList.toggle("hidden", live.live && !live.ended);
  updateControls();
}

// -- run history across campaigns (the run catalogue if there is one) ----------------------
async function showHistory() {
  try {
    const h = await getJSON("/api/history");
    $("history-source").textContent = h.source ? `(${h.source})` : "";
    const ul = $("history");
    ul.innerHTML = "";
    for (const c of h.campaigns) {
      const li = document.createElement("li");
      const st = Object.entries(c.statuses).map(([k, v]) => `${v} ${k || "?"}`).join(", ");
      li.textContent = `${c.campaign}: ${c.runs} runs${st ? " (" + st + ")" : ""}`;
      if (c.this) li.classList.add("this");
      ul.appendChild(li);
    }
    window.cutlab.history = h;
  } catch (e) {
    $("history-source").textContent = `(not shown: ${e.message})`;
  }
}

function showRuns(runs) {
  const ul = $("runs");
  ul.innerHTML = "";
  for (const r of runs) {
    const li = document.createElement("li");
    li.textContent = `${r.file}: ${r.status}${r.reason ? " (" + r.reason.slice(0, 60) + ")" : ""}`;
    li.title = r.reason || "";
    li.onclick = () => browse(r.file);
    ul.appendChild(li);
  }
}

// -- the websocket ---------------------------------------------------------------------------
function onMessage(ev) {
  const msg = JSON.parse(ev.data);
  if (msg.type === "error") {
    $("cmd-note").textContent = `the console dropped a message: ${msg.message}`;
    return;
  }
  if (msg.type === "bye") {
    serverGone = true;
    return;
  }
  if (msg.type === "cmd") {
    $("cmd-note").textContent = `${msg.cmd}: ${msg.message}; waiting for the machine's state`;
    return;
  }
  if (msg.type !== "frame") return;
  frames += 1;
  $("frame-count").textContent = frames;
  if (msg.live) showLive(msg.live);
  if (msg.runs) {
    showRuns(msg.runs);
    showHistory();
  }
  if (msg.meta) {
    meta = msg.meta;
    if (msg.reset) {
      bins = { t: [], min: [], max: [] };
      window.cutlab.readouts = null;
    }
    showProgram(meta.program || [], meta.program_name || meta.name || "");
    if (meta.toolpath) {
      toolpath = meta.toolpath;
      view3d.setPlanned(toolpath);
    }
    if (!browsing) makePlot(meta.channels, "N");
  }
  if (msg.trail) view3d.setTrail(msg.trail.points, msg.trail.reset);
  if (msg.status) showStatus(msg.status);
  if (msg.bins) addBins(msg.bins);
  if (msg.readouts) showReadouts(msg.readouts);
  if (msg.spectrum && !paused) drawSpectrum(msg.spectrum);
  // Redrawn only for new samples or a new executing block: a software-rendered redraw of the
  // plot is most of the page's cost, and a loaded computer's browser falls behind on it.
  const fresh = msg.bins && msg.bins.written_ms;
  if (!browsing && !paused && plot && (fresh || msg.meta || execBlock !== drawnBlock)) {
    drawnBlock = execBlock;
    setPlotData(bins.t, bins.min, bins.max);
  }
  if (msg.bins && msg.bins.t.length && msg.bins.written_ms) noteLatency(msg.bins.written_ms, msg.bins.sent_ms);
}

function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const q = TOKEN ? `?token=${encodeURIComponent(TOKEN)}` : "";
  ws = new WebSocket(`${proto}://${location.host}/ws${q}`);
  ws.onopen = () => {
    lostSince = null;
    $("overlay").classList.add("hidden");
    ws.send(JSON.stringify({ type: "hello", px: plotWidth(), window_s: WINDOW_S }));
  };
  ws.onmessage = onMessage;
  ws.onclose = () => {
    if (serverGone || liveState.ended) {
      // the campaign ended and its server went after it: say so, once, and stop trying
      serverGone = true;
      const el = $("ended");
      el.textContent =
        "the campaign has ended and its console server has stopped: `cutlab console FOLDER` " +
        "browses its runs";
      el.classList.remove("hidden");
      updateControls();
      return;
    }
    lostSince = lostSince || Date.now();
    if (Date.now() - lostSince > RECONNECT_FOR_MS) {
      $("overlay-text").textContent =
        "The console server is not answering (stopped?); reload the page to try again";
      $("overlay").classList.remove("hidden");
      return;
    }
    $("overlay").classList.remove("hidden");
    setTimeout(connect, 1000);
  };
}

// -- commands: confirmation first, then the state read back shows what happened --------------
const QUESTIONS = {
  hold: "Feed hold now? The axes stop; the spindle keeps turning.",
  resume: "Resume (cycle start)? The cut continues where it stopped.",
  abort: "Abort the run and end the campaign? Feed hold, then the program is stopped.",
};

function ask(cmd) {
  const dlg = $("confirm");
  $("confirm-text").textContent = QUESTIONS[cmd];
  $("confirm-yes").onclick = () => {
    dlg.close();
    if (ws && ws.readyState === WebSocket.OPEN) {
      ws.send(JSON.stringify({ type: "cmd", cmd }));
      $("cmd-note").textContent = `${cmd}: sending ...`;
    } else {
      $("cmd-note").textContent = `${cmd}: not sent, no connection`;
    }
  };
  $("confirm-no").onclick = () => dlg.close();
  dlg.showModal();
}

for (const cmd of ["hold", "resume", "abort"]) $(cmd).onclick = () => ask(cmd);

// -- finished runs: the whole trace, then block by block -------------------------------------
async function getJSON(url) {
  const r = await fetch(url, { headers: TOKEN ? { Authorization: `Bearer ${TOKEN}` } : {} });
  const j = await r.json();
  if (!r.ok) throw new Error(j.error || r.statusText);
  return j;
}

async function showTrace(file, t0, t1) {
  const q = new URLSearchParams({ file, px: String(plotWidth()) });
  if (t0 !== undefined) q.set("t0", t0);
  if (t1 !== undefined && t1 !== null) q.set("t1", t1);
  const tr = await getJSON(`/api/trace?${q}`);
  makePlot(tr.channels, tr.unit);
  setPlotData(tr.t, tr.min, tr.max);
}

async function browse(file) {
  try {
    const run = await getJSON(`/api/run?file=${encodeURIComponent(file)}`);
    browsing = file;
    updateControls();
    browseSpans = run.blocks.filter((b) => b.t0 !== null).map((b) => [b.block, b.t0, b.t1]);
    $("browse").classList.remove("hidden");
    $("browse-name").textContent = file;
    $("browse-info").textContent =
      `${run.status}${run.reason ? ": " + run.reason : ""}; ${run.duration_s.toFixed(2)} s, ` +
      `${run.rate_hz} Hz, ${run.events.length} events`;
    const ol = $("browse-blocks");
    ol.innerHTML = "";
    for (const b of run.blocks) {
      const li = document.createElement("li");
      li.value = b.line;
      li.dataset.block = b.block;
      li.textContent = b.text;
      li.onclick = () => {
        highlightBlock(ol, b.block);
        showTrace(file, b.t0, b.t1);
      };
      ol.appendChild(li);
    }
    showBrowsePath(run.path);
    const ev = $("browse-events");
    ev.innerHTML = "";
    for (const e of run.events) {
      const li = document.createElement("li");
      li.className = e.kind;
      li.textContent = `${e.t_s === null ? "" : "t=" + e.t_s.toFixed(3) + " s "}${e.kind}: ${e.message}`;
      ev.appendChild(li);
    }
    await showTrace(file);
  } catch (e) {
    $("browse-info").textContent = `cannot open ${file}: ${e.message}`;
    $("browse").classList.remove("hidden");
  }
}

// a browsed run's toolpath in both views (from its run file), or the live run's again (null)
function showBrowsePath(path) {
  browsePath = path || null;
  const last = browsePath && browsePath.trail.length ? browsePath.trail[browsePath.trail.length - 1] : null;
  view3d.show(browsePath && { planned: browsePath.toolpath, trail: browsePath.trail,
                              pos: last ? last.slice(1, 4) : null });
  $("toolpath-source").textContent = browsePath ? `(browsed run: ${browsePath.source})` : "";
  drawToolpath();
}

$("browse-live").onclick = () => {
  browsing = null;
  showBrowsePath(null);
  paused = false;
  setPaused(false);
  updateControls();
  $("browse").classList.add("hidden");
  if (meta) {
    plotChannels = "";
    makePlot(meta.channels, "N");
    setPlotData(bins.t, bins.min, bins.max);
  }
};

window.addEventListener("resize", () => plot && plot.setSize({ width: plotWidth(), height: 360 }));
makePlot(["Fx", "Fy", "Fz"], "N");
updateControls();
connect();
