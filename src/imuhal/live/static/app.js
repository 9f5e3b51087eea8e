// imuhal live view: draws what the server sends over server-sent events (GET /events).
// Read-only: the page only ever issues GET requests (the EventSource and its own files).
// window.imuhalState is what the page displays, for tests and for curious users.
"use strict";

const HISTORY_S = 60;      // vario history span (s)
const SENSOR_S = 20;       // raw sensor plot span (s)
const NO_DATA_S = 2;       // no message for this long (wall s): the view is stale
const BRINGUP_S = 10;      // a bring-up check watches this long (s of pipeline time)
const AXIS_COLORS = ["#ff6b6b", "#5dd36b", "#5aa9ff"];

const S = {
  connected: false, status: "connecting", messages: 0, seq: null, t_s: null,
  ahrs: null, roll_deg: null, pitch_deg: null, heading_deg: null,
  vario: null, climb_m_s: null, altitude_m: null,
  truth: null, errors: null, health: {}, warnings: [],
  bringup: { active: null, prompt: "", results: {} },
  sensors: {}, lastMessageWall: 0, ended: false,
};
window.imuhalState = S;

const $ = (id) => document.getElementById(id);
const hist = { vertical: [], sensors: {} };
let last = null;
const altOffsets = {};

function fmt(x, digits, signed) {
  if (x === null || x === undefined || !isFinite(x)) return "\u2013";
  const s = x.toFixed(digits);
  return signed && x >= 0 ? "+" + s : s;
}

function wrap180(a) { return ((a + 540) % 360) - 180; }

function connect() {
  const es = new EventSource("events");
  es.onopen = () => { S.connected = true; };
  es.onerror = () => { S.connected = false; setStatus(); };
  es.onmessage = (ev) => {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    S.messages += 1;
    S.lastMessageWall = performance.now() / 1000;
    receive(msg);
  };
}

function choose(select, names, current) {
  const have = Array.from(select.options).map((o) => o.value).join(",");
  if (have !== names.join(",")) {
    select.replaceChildren(...names.map((n) => new Option(n, n)));
  }
  if (current && names.includes(current)) select.value = current;
  return select.value || null;
}

function receive(msg) {
  last = msg;
  S.seq = msg.seq; S.t_s = msg.t_s; S.ended = msg.ended; S.warnings = msg.warnings;
  // The run's end: its summary stays on the page after the server has gone.
  $("summary-card").hidden = !(msg.ended && msg.summary);
  $("summary").textContent = msg.summary ? msg.summary.join("\n") : "";
  const board = msg.board || {};
  $("board").textContent = (board.profile || "pipeline") +
    (board.scenario ? " \u2014 emulated, scenario " + board.scenario : "");
  $("clock").textContent = msg.t_s === null ? "" : "t = " + msg.t_s.toFixed(1) + " s";

  const ahrsNames = Object.keys(msg.attitude);
  S.ahrs = choose($("ahrs-select"), ahrsNames, S.ahrs);
  const att = S.ahrs ? msg.attitude[S.ahrs] : null;
  S.roll_deg = att ? att.roll_deg : null;
  S.pitch_deg = att ? att.pitch_deg : null;
  S.heading_deg = att ? att.heading_deg : null;
  S.attitude_t_s = att ? att.t_s : null;

  const varioNames = Object.keys(msg.vertical);
  S.vario = choose($("vario-select"), varioNames, S.vario);
  const vert = S.vario ? msg.vertical[S.vario] : null;
  S.climb_m_s = vert ? vert.climb_m_s : null;
  S.altitude_m = vert ? vert.altitude_m : null;
  S.vertical_t_s = vert ? vert.t_s : null;
  // The estimate is a pressure altitude; the scenario's truth is height above its origin.
  // The truth is shown shifted to agree at the first comparison: errors are in altitude gained.
  S.truth = msg.truth ? { ...msg.truth } : null;
  if (S.truth && S.altitude_m !== null) {
    const key = S.vario;
    if (!(key in altOffsets)) altOffsets[key] = S.altitude_m - S.truth.altitude_m;
    S.truth.altitude_m += altOffsets[key];
  }
  if (vert) pushHistory(hist.vertical, [vert.t_s, vert.climb_m_s, vert.altitude_m,
    S.truth ? S.truth.climb_m_s : null, S.truth ? S.truth.altitude_m : null],
    HISTORY_S);

  S.errors = msg.truth ? {
    roll_deg: S.roll_deg === null ? null : wrap180(S.roll_deg - msg.truth.roll_deg),
    pitch_deg: S.pitch_deg === null ? null : S.pitch_deg - msg.truth.pitch_deg,
    heading_deg: S.heading_deg === null ? null : wrap180(S.heading_deg - msg.truth.heading_deg),
    climb_m_s: S.climb_m_s === null ? null : S.climb_m_s - msg.truth.climb_m_s,
    altitude_m: S.altitude_m === null ? null : S.altitude_m - S.truth.altitude_m,
  } : null;

  S.health = msg.health;
  S.sensors = msg.sensors;
  for (const [dev, channels] of Object.entries(msg.sensors)) {
    for (const [ch, entry] of Object.entries(channels)) {
      if (ch === "temperature" || entry.value === null) continue;
      const key = dev + "/" + ch;
      const buf = hist.sensors[key] || (hist.sensors[key] = []);
      const v = Array.isArray(entry.value) ? entry.value : [entry.value];
      pushHistory(buf, [entry.value_t_s, ...v], SENSOR_S);
    }
  }
  bringup(msg.bringup);
  draw();
}

function pushHistory(buf, point, span) {
  if (buf.length && point[0] < buf[buf.length - 1][0]) buf.length = 0;  // a new run
  if (buf.length && point[0] === buf[buf.length - 1][0]) buf[buf.length - 1] = point;
  else buf.push(point);
  while (buf.length && point[0] - buf[0][0] > span) buf.shift();
}

// ---------------------------------------------------------------------------- drawing
function draw() {
  setStatus();
  drawHorizon($("horizon"), S.roll_deg, S.pitch_deg, S.heading_deg);
  $("roll").textContent = fmt(S.roll_deg, 1, true);
  $("pitch").textContent = fmt(S.pitch_deg, 1, true);
  $("heading").textContent = fmt(S.heading_deg, 0);
  $("climb").textContent = fmt(S.climb_m_s, 2, true);
  $("altitude").textContent = fmt(S.altitude_m, 1);
  drawVarioBar($("vario-bar"), S.climb_m_s, S.truth ? S.truth.climb_m_s : null);
  const vh = hist.vertical;
  drawPlot($("climb-plot"), "climb", "m/s", HISTORY_S, [
    { label: S.vario || "estimate", color: "#ffd24a", pts: vh.map((p) => [p[0], p[1]]) },
    ...(S.truth ? [{ label: "truth", color: "#9aa5b1", dash: true,
                     pts: vh.filter((p) => p[3] !== null).map((p) => [p[0], p[3]]) }] : []),
  ]);
  drawPlot($("alt-plot"), "altitude", "m", HISTORY_S, [
    { label: S.vario || "estimate", color: "#5aa9ff", pts: vh.map((p) => [p[0], p[2]]) },
    ...(S.truth ? [{ label: "truth", color: "#9aa5b1", dash: true,
                     pts: vh.filter((p) => p[4] !== null).map((p) => [p[0], p[4]]) }] : []),
  ]);
  drawTruth();
  drawHealth();
  drawSensors();
  const h = $("horizon");
  h.dataset.rollDeg = fmt(S.roll_deg, 2); h.dataset.pitchDeg = fmt(S.pitch_deg, 2);
  h.dataset.headingDeg = fmt(S.heading_deg, 2);
  $("vario-bar").dataset.climbMS = fmt(S.climb_m_s, 3);
}

function drawHorizon(c, roll, pitch, heading) {
  const g = c.getContext("2d");
  const w = c.width, hgt = c.height, cx = w / 2, cy = (hgt - 40) / 2, r = Math.min(cx, cy) - 4;
  const pxPerDeg = r / 45;
  g.clearRect(0, 0, w, hgt);
  g.save();
  g.beginPath(); g.arc(cx, cy, r, 0, 2 * Math.PI); g.clip();
  if (roll === null) {
    g.fillStyle = "#333"; g.fillRect(0, 0, w, hgt);
  } else {
    g.translate(cx, cy);
    g.rotate(-roll * Math.PI / 180);     // roll right: the horizon turns counter-clockwise
    g.translate(0, pitch * pxPerDeg);    // nose up: the horizon drops
    g.fillStyle = "#3a7bd5"; g.fillRect(-2 * w, -4 * hgt, 4 * w, 4 * hgt);
    g.fillStyle = "#8a5a2b"; g.fillRect(-2 * w, 0, 4 * w, 4 * hgt);
    g.strokeStyle = "#fff"; g.fillStyle = "#fff"; g.lineWidth = 2;
    g.beginPath(); g.moveTo(-2 * w, 0); g.lineTo(2 * w, 0); g.stroke();
    g.lineWidth = 1; g.font = "11px sans-serif"; g.textAlign = "left"; g.textBaseline = "middle";
    for (let p = -80; p <= 80; p += 10) {
      if (p === 0) continue;
      const y = -p * pxPerDeg, half = p % 20 === 0 ? 40 : 22;
      g.beginPath(); g.moveTo(-half, y); g.lineTo(half, y); g.stroke();
      if (p % 20 === 0) g.fillText(p + "\u00b0", half + 4, y);
    }
  }
  g.restore();
  // Roll scale (deg) and pointer, fixed to the aircraft.
  g.save(); g.translate(cx, cy);
  g.strokeStyle = "#fff"; g.fillStyle = "#fff"; g.lineWidth = 1.5;
  g.font = "10px sans-serif"; g.textAlign = "center"; g.textBaseline = "bottom";
  for (const a of [-60, -45, -30, -20, -10, 0, 10, 20, 30, 45, 60]) {
    const t = (a - 90) * Math.PI / 180, l = a % 30 === 0 ? 12 : 7;
    g.beginPath(); g.moveTo(Math.cos(t) * r, Math.sin(t) * r);
    g.lineTo(Math.cos(t) * (r - l), Math.sin(t) * (r - l)); g.stroke();
  }
  if (roll !== null) {
    const t = (-roll - 90) * Math.PI / 180;
    g.fillStyle = "#ffd24a";
    g.beginPath(); g.moveTo(Math.cos(t) * (r - 14), Math.sin(t) * (r - 14));
    g.lineTo(Math.cos(t + 0.06) * (r - 26), Math.sin(t + 0.06) * (r - 26));
    g.lineTo(Math.cos(t - 0.06) * (r - 26), Math.sin(t - 0.06) * (r - 26)); g.fill();
  }
  g.strokeStyle = "#ffd24a"; g.lineWidth = 4;   // the aircraft symbol
  g.beginPath(); g.moveTo(-60, 0); g.lineTo(-18, 0); g.lineTo(-8, 10); g.stroke();
  g.beginPath(); g.moveTo(60, 0); g.lineTo(18, 0); g.lineTo(8, 10); g.stroke();
  g.beginPath(); g.arc(0, 0, 3, 0, 2 * Math.PI); g.fill();
  g.fillStyle = "#ccc"; g.font = "10px sans-serif"; g.textBaseline = "top";
  g.fillText("roll, pitch: deg", 0, r * 0.55);
  g.restore();
  // Heading tape (deg, clockwise from north).
  const ty = hgt - 34;
  g.fillStyle = "#222"; g.fillRect(0, ty, w, 34);
  if (heading !== null) {
    g.save(); g.beginPath(); g.rect(0, ty, w, 34); g.clip();
    g.strokeStyle = "#ccc"; g.fillStyle = "#eee"; g.font = "11px sans-serif";
    g.textAlign = "center"; g.textBaseline = "top";
    const pxPer = w / 120;
    for (let a = Math.floor((heading - 60) / 5) * 5; a <= heading + 60; a += 5) {
      const x = cx + (a - heading) * pxPer, n = ((a % 360) + 360) % 360;
      g.beginPath(); g.moveTo(x, ty); g.lineTo(x, ty + (n % 30 === 0 ? 10 : 5)); g.stroke();
      if (n % 30 === 0) {
        const label = { 0: "N", 90: "E", 180: "S", 270: "W" }[n] || String(n);
        g.fillText(label, x, ty + 12);
      }
    }
    g.restore();
    g.fillStyle = "#ffd24a";
    g.beginPath(); g.moveTo(cx, ty + 8); g.lineTo(cx - 6, ty); g.lineTo(cx + 6, ty); g.fill();
  }
  g.fillStyle = "#aaa"; g.font = "10px sans-serif"; g.textAlign = "right";
  g.textBaseline = "bottom"; g.fillText("heading, deg", w - 4, hgt - 1);
}

function drawVarioBar(c, climb, truthClimb) {
  const g = c.getContext("2d"), w = c.width, h = c.height;
  const top = 14, bottom = h - 24, mid = (top + bottom) / 2, span = 5;  // +-5 m/s
  const y = (v) => mid - Math.max(-span, Math.min(span, v)) / span * (mid - top);
  g.clearRect(0, 0, w, h);
  g.fillStyle = "#222"; g.fillRect(36, top, 26, bottom - top);
  if (climb !== null) {
    g.fillStyle = climb >= 0 ? "#2fa84f" : "#d63b3b";
    const yy = y(climb); g.fillRect(36, Math.min(mid, yy), 26, Math.abs(yy - mid));
  }
  if (truthClimb !== null) {
    g.strokeStyle = "#fff"; g.lineWidth = 2; g.setLineDash([4, 3]);
    g.beginPath(); g.moveTo(32, y(truthClimb)); g.lineTo(66, y(truthClimb)); g.stroke();
    g.setLineDash([]);
  }
  g.fillStyle = "#ccc"; g.strokeStyle = "#888"; g.font = "10px sans-serif";
  g.textAlign = "right"; g.textBaseline = "middle";
  for (let v = -span; v <= span; v++) {
    g.beginPath(); g.moveTo(30, y(v)); g.lineTo(36, y(v)); g.stroke();
    if (v % 1 === 0) g.fillText((v > 0 ? "+" : "") + v, 28, y(v));
  }
  g.textAlign = "center"; g.textBaseline = "top"; g.fillText("m/s", 49, 0);
  g.font = "bold 13px sans-serif"; g.fillStyle = "#fff"; g.textBaseline = "bottom";
  g.fillText(fmt(climb, 1, true), 49, h - 4);
}

function niceStep(range) {
  const raw = range / 4, mag = Math.pow(10, Math.floor(Math.log10(raw)));
  const n = raw / mag;
  return (n < 1.5 ? 1 : n < 3.5 ? 2 : n < 7.5 ? 5 : 10) * mag;
}

function fit(c) {
  // Draw at the size the layout gives the canvas, so text stays readable on any screen.
  const w = Math.round(c.clientWidth);
  if (w > 50 && c.width !== w) c.width = w;
}

function drawPlot(c, title, unit, span, series) {
  fit(c);
  const g = c.getContext("2d"), w = c.width, h = c.height;
  const L = 48, R = 8, T = 16, B = 20;
  g.clearRect(0, 0, w, h);
  const all = series.flatMap((s) => s.pts);
  const tEnd = all.length ? Math.max(...all.map((p) => p[0])) : 0;
  let lo = Infinity, hi = -Infinity;
  for (const p of all) { if (p[1] !== null && isFinite(p[1])) { lo = Math.min(lo, p[1]); hi = Math.max(hi, p[1]); } }
  if (!isFinite(lo)) { lo = -1; hi = 1; }
  const minSpan = unit === "Pa" ? 20 : unit === "rad/s" ? 0.2 : unit === "uT" ? 10 : 1;
  if (hi - lo < minSpan) { const m = (hi + lo) / 2; lo = m - minSpan / 2; hi = m + minSpan / 2; }
  const pad = (hi - lo) * 0.08; lo -= pad; hi += pad;
  const X = (t) => L + (t - (tEnd - span)) / span * (w - L - R);
  const Y = (v) => T + (hi - v) / (hi - lo) * (h - T - B);
  g.strokeStyle = "#2c3640"; g.fillStyle = "#9aa5b1"; g.font = "11px sans-serif"; g.lineWidth = 1;
  const step = niceStep(hi - lo);
  g.textAlign = "right"; g.textBaseline = "middle";
  for (let v = Math.ceil(lo / step) * step; v <= hi; v += step) {
    g.beginPath(); g.moveTo(L, Y(v)); g.lineTo(w - R, Y(v)); g.stroke();
    g.fillText(Math.abs(v) < step / 1e6 ? "0" : +v.toPrecision(4) + "", L - 4, Y(v));
  }
  g.textAlign = "center"; g.textBaseline = "top";
  const tStep = span >= 40 ? 10 : 5;
  for (let s = 0; s <= span; s += tStep) {
    const x = X(tEnd - s);
    g.beginPath(); g.moveTo(x, T); g.lineTo(x, h - B); g.stroke();
    g.fillText(s === 0 ? "now" : "-" + s, x, h - B + 3);
  }
  g.textAlign = "left"; g.fillText("time, s", 2, h - B + 3);
  g.textAlign = "left"; g.fillStyle = "#e6e9ec"; g.fillText(title + ", " + unit, 4, 2);
  let lx = L + 90;
  for (const s of series) {
    g.strokeStyle = s.color; g.lineWidth = 1.5; g.setLineDash(s.dash ? [4, 3] : []);
    g.beginPath();
    let started = false;
    for (const p of s.pts) {
      if (p[1] === null || !isFinite(p[1])) { started = false; continue; }
      if (!started) { g.moveTo(X(p[0]), Y(p[1])); started = true; } else g.lineTo(X(p[0]), Y(p[1]));
    }
    g.stroke(); g.setLineDash([]);
    g.fillStyle = s.color; g.fillText(s.label, lx, 2); lx += g.measureText(s.label).width + 12;
  }
}

function drawTruth() {
  const card = $("truth-card");
  if (!S.truth) { card.hidden = true; return; }
  card.hidden = false;
  $("scenario").textContent = last && last.board.scenario ? "(" + last.board.scenario + ")" : "";
  const rows = [["roll", "deg", "roll_deg", 1], ["pitch", "deg", "pitch_deg", 1],
    ["heading", "deg", "heading_deg", 1], ["climb", "m/s", "climb_m_s", 2],
    ["altitude, truth aligned at start", "m", "altitude_m", 2]];
  const est = { roll_deg: S.roll_deg, pitch_deg: S.pitch_deg, heading_deg: S.heading_deg,
    climb_m_s: S.climb_m_s, altitude_m: S.altitude_m };
  $("truth-table").tBodies[0].replaceChildren(...rows.map(([name, unit, key, d]) => {
    const tr = document.createElement("tr");
    for (const text of [name + " (" + unit + ")", fmt(est[key], d, true),
      fmt(S.truth[key], d, true), fmt(S.errors[key], d, true)]) {
      const td = document.createElement("td"); td.textContent = text; tr.appendChild(td);
    }
    return tr;
  }));
}

function learnedText(l) {
  // the hard iron learned in flight (imuhal.calibration.hard_iron): value +- std, uT
  if (!l.hard_iron_ut || !l.std_ut) return "hard iron: learning (" + l.readings + " readings)";
  const fit = l.hard_iron_ut.map((v, i) => fmt(v, 1) + "\u00b1" + fmt(l.std_ut[i], 1)).join(", ");
  return "hard iron " + (l.converged ? "applied" : "learning") + ": (" + fit + ") \u00b5T, " +
    l.readings + " readings";
}

function learnedAccelText(l) {
  // the accelerometer offset learned in flight (imuhal.calibration.accel_in_flight):
  // value +- std per body axis, mg
  if (!l.offset_mg || !l.std_mg) return "accel offset: learning (not started)";
  const fit = l.offset_mg.map((v, i) => fmt(v, 1) + "\u00b1" + fmt(l.std_mg[i], 1)).join(", ");
  const axes = ["x", "y", "z"].filter((a, i) => l.learned_axes[i]).join("");
  return "accel offset " + (l.converged ? "applied" : axes ? "applied on " + axes : "learning") +
    ": (" + fit + ") mg, " + l.updates + " measurements";
}

function drawHealth() {
  const body = $("health-table").tBodies[0];
  body.replaceChildren(...Object.entries(S.health).map(([name, h]) => {
    const tr = document.createElement("tr");
    const bad = h.stale || h.faulty;
    tr.className = bad ? "bad" : "good";
    tr.dataset.device = name; tr.dataset.stale = h.stale; tr.dataset.faulty = h.faulty;
    const rates = Object.keys({ ...h.configured_hz, ...h.achieved_hz })
      .filter((ch) => ch !== "temperature" || h.configured_hz[ch])
      .map((ch) => ch + " " + fmt(h.achieved_hz[ch], 0) + "/" +
        (h.configured_hz[ch] ? h.configured_hz[ch] : "?")).join(", ");
    const flags = Object.entries(h.flagged).map(([k, n]) => k + " " + n).join(", ") || "none";
    let status = h.stale ? "STALE" : h.faulty ? "FAULT: " + h.problems.join("; ") : "ok";
    if (h.learned) status += "; " + learnedText(h.learned);
    if (h.learned_accel) status += "; " + learnedAccelText(h.learned_accel);
    for (const text of [name + (h.driver ? " (" + h.driver + ")" : ""), rates || "\u2013",
      flags, String(h.bus_errors + (h.device_errors ? " + " + h.device_errors + " device" : "")),
      status]) {
      const td = document.createElement("td"); td.textContent = text; tr.appendChild(td);
    }
    return tr;
  }));
  $("warnings").replaceChildren(...S.warnings.map((w) => {
    const li = document.createElement("li"); li.textContent = w; return li;
  }));
}

function plotOrder(dev, ch) {
  const d = Object.keys(S.health).indexOf(dev);
  const k = ["accel", "gyro", "mag", "pressure"].indexOf(ch);
  return String(d < 0 ? 99 : d).padStart(2, "0") + String(k < 0 ? 9 : k) + dev + ch;
}

function drawSensors() {
  const box = $("sensor-plots");
  for (const [key, buf] of Object.entries(hist.sensors)) {
    const [dev, ch] = key.split("/");
    let c = document.getElementById("plot-" + key);
    if (!c) {
      const div = document.createElement("div"); div.className = "sensor";
      const h3 = document.createElement("h3"); h3.textContent = dev + " \u2014 " + ch;
      c = document.createElement("canvas"); c.id = "plot-" + key; c.className = "plot";
      c.width = 380; c.height = 150;
      div.append(h3, c); div.dataset.order = plotOrder(dev, ch); box.appendChild(div);
      // Devices in the profile's order, then accel, gyro, mag, pressure.
      const sorted = Array.from(box.children).sort((a, b) => a.dataset.order.localeCompare(b.dataset.order));
      box.replaceChildren(...sorted);
    }
    const entry = (S.sensors[dev] || {})[ch] || {};
    const unit = entry.unit || "";
    const n = buf.length ? buf[0].length - 1 : 0;
    const series = n === 3
      ? ["x", "y", "z"].map((a, i) => ({ label: a, color: AXIS_COLORS[i], pts: buf.map((p) => [p[0], p[i + 1]]) }))
      : [{ label: ch, color: "#ffd24a", pts: buf.map((p) => [p[0], p[1]]) }];
    drawPlot(c, ch, unit, SENSOR_S, series);
  }
}

// ---------------------------------------------------------------------------- bring-up
function bringup(b) {
  if (!b) return;
  const box = $("bringup-buttons");
  if (!box.childElementCount) {
    for (const m of b.motions) {
      const btn = document.createElement("button");
      btn.type = "button"; btn.textContent = m.label; btn.dataset.motion = m.key;
      btn.addEventListener("click", () => startCheck(m));
      box.appendChild(btn);
    }
  }
  const act = S.bringup.active;
  if (!act) return;
  if (act.start_t_s === null) act.start_t_s = S.t_s;
  if (S.t_s - act.start_t_s > BRINGUP_S) { finishCheck(); return; }
  // Only windows that begin after the button was pressed: an earlier motion is not this one.
  if (b.window_start_t_s === null || b.window_start_t_s < act.start_t_s) return;
  for (const v of b.verdicts[act.key] || []) {
    const key = v.device + "/" + v.channel;
    const prev = S.bringup.results[key];
    if (!prev || v.angle_deg > prev.angle_deg) S.bringup.results[key] = v;
  }
  showResults();
}

function startCheck(m) {
  S.bringup.active = { key: m.key, label: m.label, start_t_s: S.t_s };
  S.bringup.results = {};
  S.bringup.prompt = "Now " + m.prompt + ".";
  for (const btn of $("bringup-buttons").children) btn.classList.toggle("active", btn.dataset.motion === m.key);
  $("bringup-prompt").textContent = S.bringup.prompt;
  showResults();
}

function finishCheck() {
  const act = S.bringup.active;
  S.bringup.active = null;
  for (const btn of $("bringup-buttons").children) btn.classList.remove("active");
  const res = Object.values(S.bringup.results);
  const fails = res.filter((v) => v.ok === false).length, passes = res.filter((v) => v.ok === true).length;
  S.bringup.prompt = "'" + act.label + "': " + (fails ? fails + " sensor(s) WRONG" :
    passes ? "every sensor that could see it agrees: mounts right" : "no clear motion seen; try again");
  $("bringup-prompt").textContent = S.bringup.prompt;
}

function showResults() {
  $("bringup-results").replaceChildren(...Object.values(S.bringup.results).map((v) => {
    const li = document.createElement("li");
    li.className = v.ok === true ? "pass" : v.ok === false ? "fail" : "unknown";
    li.textContent = (v.ok === true ? "\u2713 " : v.ok === false ? "\u2717 " : "? ") + v.message;
    return li;
  }));
}

// ---------------------------------------------------------------------------- status
function setStatus() {
  const now = performance.now() / 1000;
  let status = "live";
  if (!S.messages) status = "connecting";
  else if (S.ended) status = "ended";
  else if (!S.connected || now - S.lastMessageWall > NO_DATA_S) status = "disconnected";
  else if (last && last.age_s !== null && last.age_s > NO_DATA_S) status = "stale";
  S.status = status;
  document.body.dataset.status = status;
  $("status").textContent = { live: "live", connecting: "connecting", ended: "run ended",
    disconnected: "no data from the server", stale: "pipeline stalled" }[status];
}

setInterval(setStatus, 500);
connect();
