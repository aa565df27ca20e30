//! The review as one self-contained HTML page: the data as a JSON blob in a
//! `<script type="application/json">`, an inline script that draws it as SVG (map, timeline,
//! charts, keyframes with their boxes) and the tables. Keyframes are embedded as `data:`
//! URIs; the page loads nothing from anywhere (no CDN, no fonts, no images by URL).
//!
//! Stable element ids for tests and readers: `#summary`, `#map`, `#timeline`, `#tracks`,
//! `#health`, `#keyframes` and, with the truth, `#truth`. When the script has drawn
//! everything it sets `data-rendered="ok"` on `<body>`; a script error sets `data-error`.

use super::{Review, KEYFRAMES_DIR};
use std::path::Path;

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        let sextets = [(n >> 18) & 63, (n >> 12) & 63, (n >> 6) & 63, n & 63];
        let keep = chunk.len() + 1;
        for (i, s) in sextets.iter().enumerate() {
            if i < keep {
                out.push(char::from(ABC[*s as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Reads the review's keyframes from the flight's `keyframes/` into `data:` URIs; an
/// unreadable one stays `None` (the page says so) and is logged.
pub fn embed_keyframes(review: &mut Review, flight_dir: &Path) {
    for k in &mut review.keyframes {
        // The name comes from the record: only a plain file name is read.
        if k.file.contains(['/', '\\']) || k.file.starts_with('.') {
            tracing::warn!(file = %k.file, "keyframe name is not a plain file name; skipped");
            continue;
        }
        let path = flight_dir.join(KEYFRAMES_DIR).join(&k.file);
        match std::fs::read(&path) {
            Ok(bytes) => k.data_uri = Some(format!("data:image/jpeg;base64,{}", base64(&bytes))),
            Err(e) => tracing::warn!(path = %path.display(), error = %e, "keyframe unreadable"),
        }
    }
}

/// JSON for a `<script type="application/json">`: `<`, `>` and `&` escaped so that no
/// string in the data can close the element.
fn script_json(review: &Review) -> Result<String, serde_json::Error> {
    Ok(serde_json::to_string(review)?
        .replace('<', "\\u003c")
        .replace('>', "\\u003e")
        .replace('&', "\\u0026"))
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The page.
pub fn page(review: &Review) -> Result<String, serde_json::Error> {
    let title = escape(&format!(
        "mgmot flight review: {} (system {})",
        review.flight.started_utc, review.flight.system_id
    ));
    Ok(TEMPLATE
        .replace("__TITLE__", &title)
        .replace("__STYLE__", STYLE)
        .replace("__SCRIPT__", SCRIPT)
        .replace("__DATA__", &script_json(review)?))
}

const TEMPLATE: &str = r##"<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>__TITLE__</title>
<style>__STYLE__</style>
</head>
<body>
<script>
window.onerror = function (msg, src, line, col) {
  document.body.dataset.error = String(msg) + " (line " + line + ":" + col + ")";
};
</script>
<header><h1>__TITLE__</h1><div id="summary"></div><div id="warnings"></div></header>
<nav>
<a href="#map-section">Map</a> · <a href="#timeline-section">Timeline</a> ·
<a href="#tracks-section">Tracks</a> · <a href="#health-section">Telemetry</a> ·
<a href="#keyframes-section">Keyframes</a> <span id="truth-link"></span>
</nav>
<section id="map-section"><h2>Map</h2>
<div class="controls"><button id="play" type="button">▶ Play</button>
<input id="slider" type="range" min="0" max="0" step="0.01" value="0">
<span id="clock"></span></div>
<div id="map"></div><div id="legend"></div></section>
<section id="timeline-section"><h2>Timeline</h2><div id="timeline"></div></section>
<section id="tracks-section"><h2>Tracks</h2><div id="tracks"></div></section>
<section id="truth-section" hidden><h2>Error against the simulator's truth</h2><div id="truth-slot"></div></section>
<section id="health-section"><h2>Telemetry health</h2><div id="health"></div></section>
<section id="keyframes-section"><h2>Keyframes</h2><div id="keyframes"></div></section>
<footer>Written by <code>mgmot review</code>. Local map frame: metres north/east of the
water under the first pose; lat/lon WGS84. Uncertainty: horizontal 1σ (DRMS).</footer>
<script type="application/json" id="review-data">__DATA__</script>
<script>__SCRIPT__</script>
</body>
</html>
"##;

const STYLE: &str = r##"
body { font-family: system-ui, sans-serif; margin: 0 1.5em 2em; color: #1d2430; background: #fafbfc; }
h1 { font-size: 1.35em; margin: .6em 0 .3em; }
h2 { font-size: 1.15em; border-bottom: 1px solid #ccd; padding-bottom: .2em; margin-top: 1.4em; }
nav { margin: .4em 0; font-size: .95em; }
#summary { font-size: .92em; line-height: 1.45; }
.warn { background: #fff1d6; border: 1px solid #e0a030; padding: .4em .7em; margin: .3em 0; border-radius: 4px; }
.bad { background: #fde2e1; border-color: #d04040; }
.controls { display: flex; gap: .8em; align-items: center; margin-bottom: .4em; }
#slider { flex: 1; }
#clock { font-family: ui-monospace, monospace; min-width: 22em; }
#map svg { width: 100%; height: 620px; background: #dfeaf3; border: 1px solid #aab; }
#legend { font-size: .85em; margin-top: .3em; }
.swatch { display: inline-block; width: .9em; height: .9em; border-radius: 2px; vertical-align: middle; margin-right: .25em; }
table { border-collapse: collapse; font-size: .88em; margin: .4em 0; }
th, td { border: 1px solid #ccd; padding: .25em .5em; text-align: left; vertical-align: top; }
th { background: #eef1f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.mono { font-family: ui-monospace, monospace; white-space: nowrap; }
.charts { display: flex; flex-wrap: wrap; gap: 1em; }
.chart { background: #fff; border: 1px solid #ccd; }
.chart text, #timeline text { font-size: 11px; fill: #333; }
#keyframes { display: flex; flex-wrap: wrap; gap: .8em; }
#keyframes figure { margin: 0; width: 420px; }
#keyframes svg { width: 420px; background: #223; }
#keyframes figcaption { font-size: .8em; }
.muted { color: #667; }
footer { margin-top: 2em; font-size: .8em; color: #667; }
"##;

const SCRIPT: &str = r##"
"use strict";
(function () {
const D = JSON.parse(document.getElementById("review-data").textContent);
const NS = "http://www.w3.org/2000/svg";
const PALETTE = ["#e6194b", "#3cb44b", "#4363d8", "#f58231", "#911eb4", "#42d4f4", "#f032e6",
  "#9a6324", "#469990", "#800000", "#808000", "#000075", "#bfef45", "#fabed4"];
const STATE_COLOR = { detected: null, coasting: "#f2c14e", lost: "#c9ced6" };
const byId = {};
D.tracks.forEach(function (t, i) { t.color = PALETTE[i % PALETTE.length]; byId[t.id] = t; });

function el(name, attrs, parent) {
  const e = document.createElementNS(NS, name);
  for (const k in attrs) { e.setAttribute(k, attrs[k]); }
  if (parent) { parent.appendChild(e); }
  return e;
}
function h(name, attrs, parent, text) {
  const e = document.createElement(name);
  for (const k in (attrs || {})) { e.setAttribute(k, attrs[k]); }
  if (text !== undefined) { e.textContent = text; }
  if (parent) { parent.appendChild(e); }
  return e;
}
function fmt(x, d) { return (x === null || x === undefined || !isFinite(x)) ? "–" : x.toFixed(d); }
function dm(deg, pos, neg) {
  const hemi = deg < 0 ? neg : pos;
  const a = Math.abs(deg);
  let d = Math.floor(a);
  let m = (a - d) * 60;
  if (Math.round(m * 1000) >= 60000) { d += 1; m = 0; }
  return d + "°" + (m < 10 ? "0" : "") + m.toFixed(3) + "'" + hemi;
}
function utcAt(t) {
  if (!D.flight.span_utc) { return ""; }
  const t0 = Date.parse(D.flight.span_utc[0]);
  return new Date(t0 + t * 1000).toISOString().replace(".000Z", "Z");
}
function text(parent, x, y, s, attrs) {
  const e = el("text", Object.assign({ x: x, y: y }, attrs || {}), parent);
  e.textContent = s;
  return e;
}

// ---------- summary and warnings ----------
(function summary() {
  const f = D.flight;
  const s = document.getElementById("summary");
  const lines = [
    ["Flight folder", f.dir],
    ["Recording started (UTC)", f.started_utc],
    ["Frames", f.frames + (f.span_utc ? " from " + f.span_utc[0] + " to " + f.span_utc[1] + " (" + fmt(f.duration_s, 1) + " s)" : "")],
    ["Tracks", D.tracks.length + " (after " + D.merges.length + " ReID merge" + (D.merges.length === 1 ? "" : "s") + ")"],
    ["Contact repairs", D.exchanges.length === 0 ? "none" : D.exchanges.map(function (e) { return "ids " + e.ids[0] + " and " + e.ids[1] + " swapped " + fmt(e.since_t, 1) + "–" + fmt(e.t, 1) + " s"; }).join("; ")],
    ["Detector", f.detector],
    ["mgmot", f.mgmot_version + ", camera HFOV " + f.hfov_deg + "° (footprints)"],
  ];
  if (f.origin) { lines.push(["Map origin", f.origin[0].toFixed(6) + ", " + f.origin[1].toFixed(6) + "  (" + dm(f.origin[0], "N", "S") + " " + dm(f.origin[1], "E", "W") + ")"]); }
  const t = h("table", {}, s);
  lines.forEach(function (l) { const r = h("tr", {}, t); h("th", {}, r, l[0]); h("td", {}, r, l[1]); });
  const w = document.getElementById("warnings");
  if (!f.clean_end) { h("div", { class: "warn bad", id: "unclean" }, w, "The run did not end cleanly: frames.ndjson has no end record (a crash, a power loss or a recording still in progress). What was recorded up to then is shown."); }
  if (f.frames === 0) { h("div", { class: "warn bad", id: "empty" }, w, "This flight has no frame records: nothing was tracked (the camera or the detector may never have delivered a frame)."); }
  if (f.bad_lines > 0) { h("div", { class: "warn" }, w, f.bad_lines + " line(s) of frames.ndjson could not be read and were skipped."); }
  f.gaps.forEach(function (g) { h("div", { class: "warn" }, w, "Recording stopped " + g[0] + " and resumed " + g[1] + " (" + g[2] + "): " + g[3] + " frame records lost."); });
  if (!D.health.tlog_clean) { h("div", { class: "warn" }, w, "flight.tlog ends with a packet cut short (the run did not close it)."); }
  if (D.truth) { document.getElementById("truth-link").innerHTML = ' · <a href="#truth-section">Truth</a>'; }
})();

// ---------- map ----------
const duration = Math.max(D.flight.duration_s, 0);
const slider = document.getElementById("slider");
slider.max = String(duration);
const map = (function buildMap() {
  const box = document.getElementById("map");
  const svg = el("svg", { id: "map-svg", preserveAspectRatio: "xMidYMid meet" }, box);
  const pts = [];
  D.map.forEach(function (f) { if (f.drone) { pts.push(f.drone); } f.footprint.forEach(function (p) { pts.push(p); }); });
  D.tracks.forEach(function (t) { t.points.forEach(function (p) { if (p.ne) { pts.push(p.ne); } }); });
  if (D.truth) { D.truth.objects.forEach(function (o) { o.path.forEach(function (p) { pts.push(p); }); }); }
  if (pts.length === 0) { pts.push([0, 0]); }
  let minN = Infinity, maxN = -Infinity, minE = Infinity, maxE = -Infinity;
  pts.forEach(function (p) { minN = Math.min(minN, p[0]); maxN = Math.max(maxN, p[0]); minE = Math.min(minE, p[1]); maxE = Math.max(maxE, p[1]); });
  let span = Math.max(maxN - minN, maxE - minE, 20);
  const pad = span * 0.08;
  minN -= pad; maxN += pad; minE -= pad; maxE += pad;
  span = Math.max(maxN - minN, maxE - minE);
  // Wider than tall on screen: give east more room.
  const w = Math.max(maxE - minE, (maxN - minN) * 1.6), hgt = maxN - minN;
  const cE = (minE + maxE) / 2;
  const x0 = cE - w / 2;
  svg.setAttribute("viewBox", x0 + " " + (-maxN) + " " + w + " " + hgt);
  const u = span / 120; // one "unit" of marker size (m)
  const gGrid = el("g", { id: "graticule" }, svg);
  const gFoot = el("g", { id: "footprints" }, svg);
  const gTruth = el("g", { id: "truth-paths" }, svg);
  const gPath = el("g", { id: "drone-path" }, svg);
  const gTracks = el("g", { id: "track-paths" }, svg);
  const gNow = el("g", { id: "now" }, svg);

  // graticule (lat/lon lines, equirectangular about the origin: exact to well under a metre over a few km)
  if (D.flight.origin) {
    const lat0 = D.flight.origin[0], lon0 = D.flight.origin[1];
    const mLat = 111132.954 - 559.822 * Math.cos(2 * lat0 * Math.PI / 180) + 1.175 * Math.cos(4 * lat0 * Math.PI / 180);
    const mLon = 111412.84 * Math.cos(lat0 * Math.PI / 180) - 93.5 * Math.cos(3 * lat0 * Math.PI / 180);
    const steps = [1 / 60000, 2 / 60000, 5 / 60000, 1 / 6000, 2 / 6000, 5 / 6000, 1 / 600, 2 / 600, 5 / 600, 1 / 60, 2 / 60, 5 / 60, 1 / 6, 1];
    function pick(metres) { for (const s of steps) { if (s * metres * 6 >= Math.max(w, hgt)) { return s; } } return 1; }
    const sLat = pick(mLat), sLon = pick(mLon);
    const latMin = lat0 + minN / mLat, latMax = lat0 + maxN / mLat;
    const lonMin = lon0 + x0 / mLon, lonMax = lon0 + (x0 + w) / mLon;
    const fs = hgt / 45;
    for (let la = Math.ceil(latMin / sLat) * sLat; la <= latMax; la += sLat) {
      const n = (la - lat0) * mLat;
      el("line", { x1: x0, x2: x0 + w, y1: -n, y2: -n, stroke: "#8aa", "stroke-width": 0.6, "vector-effect": "non-scaling-stroke", "stroke-dasharray": "4 4" }, gGrid);
      text(gGrid, x0 + fs * 0.3, -n - fs * 0.25, dm(la, "N", "S"), { "font-size": fs, fill: "#567" });
    }
    for (let lo = Math.ceil(lonMin / sLon) * sLon; lo <= lonMax; lo += sLon) {
      const e = (lo - lon0) * mLon;
      el("line", { x1: e, x2: e, y1: -maxN, y2: -minN, stroke: "#8aa", "stroke-width": 0.6, "vector-effect": "non-scaling-stroke", "stroke-dasharray": "4 4" }, gGrid);
      text(gGrid, e + fs * 0.2, -minN - fs * 0.4, dm(lo, "E", "W"), { "font-size": fs, fill: "#567" });
    }
    // scale bar
    const nice = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000];
    let bar = nice[0];
    for (const b of nice) { if (b <= w / 5) { bar = b; } }
    const bx = x0 + w - bar - fs, by = -minN - fs * 1.6;
    el("line", { x1: bx, x2: bx + bar, y1: by, y2: by, stroke: "#123", "stroke-width": 3, "vector-effect": "non-scaling-stroke" }, gGrid);
    text(gGrid, bx, by - fs * 0.4, bar + " m", { "font-size": fs, fill: "#123" });
    text(gGrid, x0 + w - fs * 1.5, -maxN + fs * 1.5, "N↑", { "font-size": fs * 1.2, fill: "#123" });
  }

  // every footprint, faint: what the camera covered
  // At most 50 of them: a browser keeps 8 bits of opacity, so fainter ones would vanish.
  const fpStep = Math.max(1, Math.ceil(D.map.length / 50));
  const fpCount = Math.ceil(D.map.length / fpStep);
  // Where every drawn footprint overlaps, the blue reaches 40 %: a coverage density.
  const fpAlpha = Math.max(1 - Math.pow(0.6, 1 / Math.max(fpCount, 1)), 0.01);
  D.map.forEach(function (f, i) {
    if (i % fpStep !== 0 || f.footprint.length < 3) { return; }
    el("polygon", { points: f.footprint.map(function (p) { return p[1] + "," + (-p[0]); }).join(" "), fill: "#2a6fb0", "fill-opacity": fpAlpha, stroke: "none" }, gFoot);
  });
  const nowFoot = el("polygon", { id: "footprint-now", points: "", fill: "#2a6fb0", "fill-opacity": 0.18, stroke: "#2a6fb0", "stroke-width": 1.5, "vector-effect": "non-scaling-stroke" }, gFoot);

  if (D.truth) {
    D.truth.objects.forEach(function (o) {
      if (o.path.length < 1) { return; }
      el("polyline", { points: o.path.map(function (p) { return p[1] + "," + (-p[0]); }).join(" "), fill: "none", stroke: "#333", "stroke-width": 1.2, "stroke-dasharray": "3 3", "vector-effect": "non-scaling-stroke" }, gTruth);
      const last = o.path[o.path.length - 1];
      text(gTruth, last[1] + u, -last[0] + u * 2.5, "true " + o.object_id, { "font-size": u * 2.2, fill: "#333" });
    });
  }

  const drone = D.map.filter(function (f) { return f.drone; });
  el("polyline", { points: drone.map(function (f) { return f.drone[1] + "," + (-f.drone[0]); }).join(" "), fill: "none", stroke: "#555", "stroke-width": 1.5, "vector-effect": "non-scaling-stroke" }, gPath);
  const droneNow = el("circle", { id: "drone-now", r: u * 1.3, fill: "#fff", stroke: "#000", "stroke-width": 2, "vector-effect": "non-scaling-stroke" }, gNow);

  const trackEls = D.tracks.map(function (t) {
    const pts = t.points.filter(function (p) { return p.ne; });
    el("polyline", { points: pts.map(function (p) { return p.ne[1] + "," + (-p.ne[0]); }).join(" "), fill: "none", stroke: t.color, "stroke-opacity": 0.25, "stroke-width": 2, "vector-effect": "non-scaling-stroke" }, gTracks);
    const upto = el("polyline", { points: "", fill: "none", stroke: t.color, "stroke-width": 2.5, "vector-effect": "non-scaling-stroke" }, gTracks);
    const ring = el("circle", { r: 1, fill: t.color, "fill-opacity": 0.15, stroke: t.color, "stroke-width": 1, "vector-effect": "non-scaling-stroke", visibility: "hidden" }, gNow);
    const dot = el("circle", { class: "track-now", r: u, fill: t.color, stroke: "#fff", "stroke-width": 1.5, "vector-effect": "non-scaling-stroke", visibility: "hidden" }, gNow);
    const label = text(gNow, 0, 0, String(t.id), { "font-size": u * 2.6, fill: t.color, "font-weight": "bold", visibility: "hidden" });
    return { t: t, pts: pts, upto: upto, ring: ring, dot: dot, label: label };
  });

  function lastIndexAtOrBefore(arr, t) {
    let lo = 0, hi = arr.length - 1, ans = -1;
    while (lo <= hi) { const m = (lo + hi) >> 1; if (arr[m].t <= t + 1e-9) { ans = m; lo = m + 1; } else { hi = m - 1; } }
    return ans;
  }
  function update(t) {
    const i = lastIndexAtOrBefore(D.map, t);
    const f = i >= 0 ? D.map[i] : null;
    nowFoot.setAttribute("points", f && f.footprint.length >= 3 ? f.footprint.map(function (p) { return p[1] + "," + (-p[0]); }).join(" ") : "");
    if (f && f.drone) { droneNow.setAttribute("cx", f.drone[1]); droneNow.setAttribute("cy", -f.drone[0]); droneNow.setAttribute("visibility", "visible"); }
    else { droneNow.setAttribute("visibility", "hidden"); }
    trackEls.forEach(function (e) {
      const j = lastIndexAtOrBefore(e.pts, t);
      if (j < 0) { e.upto.setAttribute("points", ""); ["dot", "ring", "label"].forEach(function (k) { e[k].setAttribute("visibility", "hidden"); }); return; }
      e.upto.setAttribute("points", e.pts.slice(0, j + 1).map(function (p) { return p.ne[1] + "," + (-p.ne[0]); }).join(" "));
      const p = e.pts[j];
      const stale = t - p.t > 1.0;
      e.dot.setAttribute("cx", p.ne[1]); e.dot.setAttribute("cy", -p.ne[0]);
      e.dot.setAttribute("fill-opacity", stale ? 0.35 : 1);
      e.ring.setAttribute("cx", p.ne[1]); e.ring.setAttribute("cy", -p.ne[0]);
      e.ring.setAttribute("r", Math.max(p.h_std_m || 0, 0.01));
      e.label.setAttribute("x", p.ne[1] + u * 1.3); e.label.setAttribute("y", -p.ne[0] - u * 1.3);
      ["dot", "ring", "label"].forEach(function (k) { e[k].setAttribute("visibility", "visible"); });
    });
  }
  const legend = document.getElementById("legend");
  D.tracks.forEach(function (t) { const s = h("span", {}, legend); h("span", { class: "swatch", style: "background:" + t.color }, s); s.appendChild(document.createTextNode("track " + t.id + " (" + t.class + ")  ")); });
  h("span", { class: "muted" }, legend, " — grey line: drone; blue: camera footprint (now, and faintly all frames); circle: 1σ uncertainty" + (D.truth ? "; dashed: true object paths" : ""));
  return { update: update };
})();

// ---------- timeline ----------
const timeline = (function buildTimeline() {
  const box = document.getElementById("timeline");
  const rows = [];
  D.tracks.forEach(function (t) { t.ids.slice().sort(function (a, b) { return a - b; }).forEach(function (id) { rows.push({ track: t, id: id }); }); });
  const rowH = 22, left = 190, right = 20, top = 24, W = 1100;
  const H = top + Math.max(rows.length, 1) * rowH + 30;
  const svg = el("svg", { id: "timeline-svg", viewBox: "0 0 " + W + " " + H, width: "100%", style: "max-width:" + W + "px;background:#fff;border:1px solid #ccd" }, box);
  const span = Math.max(duration, 1e-3);
  const X = function (t) { return left + (W - left - right) * t / span; };
  const rowOf = {};
  rows.forEach(function (r, i) { rowOf[r.id] = i; });
  // axis
  const tick = [1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600].find(function (s) { return span / s <= 12; }) || 3600;
  for (let t = 0; t <= span + 1e-9; t += tick) {
    el("line", { x1: X(t), x2: X(t), y1: top - 4, y2: H - 26, stroke: "#e3e6ea" }, svg);
    text(svg, X(t) - 8, H - 10, t + " s");
  }
  rows.forEach(function (r, i) {
    const y = top + i * rowH;
    text(svg, 6, y + 15, "id " + r.id + (r.id !== r.track.id ? " → " + r.track.id : "") + " · " + r.track.class);
    r.track.segments.filter(function (s) { return s.id === r.id; }).forEach(function (s) {
      const color = STATE_COLOR[s.state] || r.track.color;
      const rect = el("rect", { class: "seg seg-" + s.state, x: X(s.t0), y: y + 4, width: Math.max(X(s.t1) - X(s.t0), 2), height: rowH - 8, fill: color, rx: 2 }, svg);
      el("title", {}, rect).textContent = "id " + r.id + ": " + s.state + " " + fmt(s.t0, 1) + "–" + fmt(s.t1, 1) + " s";
    });
  });
  D.merges.forEach(function (m) {
    const a = rowOf[m.new_id], b = rowOf[m.merged_into_id];
    if (a === undefined || b === undefined) { return; }
    const x = X(m.t), ya = top + a * rowH + rowH / 2, yb = top + b * rowH + rowH / 2;
    const p = el("path", { class: "merge", d: "M" + x + "," + ya + " C" + (x + 30) + "," + ya + " " + (x + 30) + "," + yb + " " + x + "," + yb, fill: "none", stroke: "#222", "stroke-width": 1.5, "marker-end": "url(#arrow)" }, svg);
    el("title", {}, p).textContent = "ReID merge at " + fmt(m.t, 1) + " s: id " + m.new_id + " is id " + m.merged_into_id;
  });
  D.exchanges.forEach(function (e) {
    const a = rowOf[e.ids[0]], b = rowOf[e.ids[1]];
    if (a === undefined || b === undefined) { return; }
    const ya = top + a * rowH + rowH / 2, yb = top + b * rowH + rowH / 2;
    const r = el("rect", { class: "exchange", x: X(e.since_t), y: Math.min(ya, yb) - 4, width: Math.max(X(e.t) - X(e.since_t), 2), height: Math.abs(yb - ya) + 8, fill: "none", stroke: "#c00", "stroke-width": 1.2, "stroke-dasharray": "4 3" }, svg);
    el("title", {}, r).textContent = "Contact repair at " + fmt(e.t, 1) + " s: ids " + e.ids[0] + " and " + e.ids[1] + " followed each other's object from " + fmt(e.since_t, 1) + " s (sent so); their own from then on";
  });
  const defs = el("defs", {}, svg);
  const mk = el("marker", { id: "arrow", viewBox: "0 0 10 10", refX: 9, refY: 5, markerWidth: 6, markerHeight: 6, orient: "auto" }, defs);
  el("path", { d: "M0,0 L10,5 L0,10 z", fill: "#222" }, mk);
  if (rows.length === 0) { text(svg, left, top + 15, "no tracks"); }
  const cursor = el("line", { id: "timeline-cursor", x1: X(0), x2: X(0), y1: top - 8, y2: H - 26, stroke: "#c00", "stroke-width": 1.5 }, svg);
  svg.addEventListener("click", function (ev) {
    const r = svg.getBoundingClientRect();
    const x = (ev.clientX - r.left) * W / r.width;
    setTime(Math.min(Math.max((x - left) / (W - left - right) * span, 0), duration));
  });
  const lg = h("div", { class: "muted" }, box);
  lg.innerHTML = 'Bars: <span class="swatch" style="background:#4363d8"></span>detected (track colour) <span class="swatch" style="background:#f2c14e"></span>coasting (absent ≤ 2 s) <span class="swatch" style="background:#c9ced6"></span>lost (absent longer); arrows: ReID merges (new id → the old id it is); dashed red boxes: contact repairs (the two ids were swapped over that span). Click to move the map\'s time.';
  return { update: function (t) { cursor.setAttribute("x1", X(t)); cursor.setAttribute("x2", X(t)); } };
})();

function setTime(t) {
  slider.value = String(t);
  document.getElementById("clock").textContent = "t = " + t.toFixed(1) + " s   " + utcAt(t);
  map.update(t);
  timeline.update(t);
}
slider.addEventListener("input", function () { stop(); setTime(parseFloat(slider.value)); });
let timer = null;
const play = document.getElementById("play");
function stop() { if (timer) { clearInterval(timer); timer = null; play.textContent = "▶ Play"; } }
play.addEventListener("click", function () {
  if (timer) { stop(); return; }
  let t = parseFloat(slider.value);
  if (t >= duration) { t = 0; }
  const speed = Math.max(duration / 30, 1); // a whole flight in about 30 s, at least real time
  play.textContent = "❚❚ Pause";
  timer = setInterval(function () {
    t += speed * 0.05;
    if (t >= duration) { t = duration; stop(); }
    setTime(t);
  }, 50);
});
setTime(duration);

// ---------- track table ----------
(function trackTable() {
  const box = document.getElementById("tracks");
  if (D.tracks.length === 0) { h("p", {}, box, "No confirmed tracks in this flight."); return; }
  const day = D.flight.span_utc ? D.flight.span_utc[0].slice(0, 10) : "";
  const allSameDay = D.tracks.every(function (k) { return k.first_utc.slice(0, 10) === day && k.last_utc.slice(0, 10) === day; });
  const when = function (u) { return allSameDay ? u.slice(11) : u.replace("T", " "); };
  const t = h("table", { id: "tracks-table" }, box);
  const head = h("tr", {}, t);
  ["Track", "Class", "First seen (UTC" + (allSameDay ? " " + day : "") + ")", "Last seen", "Last position (lat, lon)", "±1σ (m)", "Distance travelled (m)", "Drift (m/s @ °T)", "Frames", "Ids"].forEach(function (c) { h("th", {}, head, c); });
  D.tracks.forEach(function (k) {
    const r = h("tr", { id: "track-row-" + k.id }, t);
    const c0 = h("td", {}, r); h("span", { class: "swatch", style: "background:" + k.color }, c0); c0.appendChild(document.createTextNode(String(k.id)));
    h("td", {}, r, k.class);
    h("td", { class: "mono" }, r, when(k.first_utc));
    h("td", { class: "mono" }, r, when(k.last_utc));
    const pos = h("td", { class: "mono" }, r);
    if (k.last_lat_lon) {
      h("div", {}, pos, k.last_lat_lon[0].toFixed(6) + ", " + k.last_lat_lon[1].toFixed(6));
      h("div", {}, pos, k.last_dm);
      if (k.last_fix_utc !== k.last_utc) { h("div", { class: "muted" }, pos, "fix at " + when(k.last_fix_utc)); }
    } else { pos.textContent = "not geolocated"; }
    h("td", { class: "num" }, r, fmt(k.last_h_std_m, 1));
    h("td", { class: "num" }, r, fmt(k.distance_m, 1));
    h("td", { class: "num mono" }, r, k.drift_mps === null ? "–" : fmt(k.drift_mps, 2) + " @ " + fmt(k.drift_course_deg, 0).padStart(3, "0") + "°");
    h("td", { class: "num" }, r, String(k.frames));
    h("td", {}, r, k.ids.join(", "));
  });
  h("p", { class: "muted" }, box, "Drift: the tracker's velocity at the last fix (course: towards, degrees true). Distance: path length over the geolocated positions.");
})();

// ---------- charts ----------
function niceStep(range, n) {
  const raw = Math.max(range, 1e-9) / n;
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 5, 10]) { if (m * p >= raw) { return m * p; } }
  return 10 * p;
}
function chart(parent, opts) {
  const W = opts.width || 520, H = opts.height || 180, L = 52, R = 12, T = 22, B = 30;
  const svg = el("svg", { class: "chart", viewBox: "0 0 " + W + " " + H, width: W, height: H }, parent);
  if (opts.id) { svg.setAttribute("id", opts.id); }
  text(svg, L, 14, opts.title, { "font-weight": "bold" });
  const all = [];
  opts.series.forEach(function (s) { s.points.forEach(function (p) { all.push(p); }); });
  if (all.length === 0) { text(svg, L, H / 2, "no data"); return svg; }
  const dataX0 = Math.min.apply(null, all.map(function (p) { return p[0]; }));
  let x0 = opts.xmin !== undefined ? Math.min(opts.xmin, dataX0) : dataX0;
  let x1 = opts.xmax !== undefined ? opts.xmax : Math.max.apply(null, all.map(function (p) { return p[0]; }));
  let y0 = opts.ymin !== undefined ? opts.ymin : Math.min.apply(null, all.map(function (p) { return p[1]; }));
  let y1 = Math.max.apply(null, all.map(function (p) { return p[1]; }));
  if (x1 <= x0) { x1 = x0 + 1; }
  if (y1 <= y0) { y1 = y0 + 1; }
  y1 += (y1 - y0) * 0.05;
  const X = function (x) { return L + (W - L - R) * (x - x0) / (x1 - x0); };
  const Y = function (y) { return H - B - (H - T - B) * (y - y0) / (y1 - y0); };
  el("rect", { x: L, y: T, width: W - L - R, height: H - T - B, fill: "none", stroke: "#bbb" }, svg);
  for (let i = 0; i <= 4; i++) {
    const y = y0 + (y1 - y0) * i / 4;
    el("line", { x1: L, x2: W - R, y1: Y(y), y2: Y(y), stroke: "#eee" }, svg);
    text(svg, 4, Y(y) + 4, Math.abs(y1 - y0) < 5 ? y.toFixed(2) : y.toFixed(0));
  }
  const xs = niceStep(x1 - x0, 6);
  for (let x = Math.ceil(x0 / xs) * xs; x <= x1 + 1e-9; x += xs) { text(svg, X(x) - 8, H - 12, String(Math.round(x * 100) / 100)); }
  text(svg, W - R - 14, H - 2, opts.xunit || "s", { fill: "#667" });
  opts.series.forEach(function (s) {
    if (s.step) {
      const pts = []; let prev = null;
      s.points.forEach(function (p) { if (prev) { pts.push(X(p[0]) + "," + Y(prev[1])); } pts.push(X(p[0]) + "," + Y(p[1])); prev = p; });
      el("polyline", { points: pts.join(" "), fill: "none", stroke: s.color, "stroke-width": 1.5 }, svg);
    } else if (s.dots) {
      s.points.forEach(function (p) { el("circle", { cx: X(p[0]), cy: Y(p[1]), r: 2, fill: s.color }, svg); });
    } else {
      el("polyline", { points: s.points.map(function (p) { return X(p[0]) + "," + Y(p[1]); }).join(" "), fill: "none", stroke: s.color, "stroke-width": 1.5 }, svg);
    }
  });
  (opts.hlines || []).forEach(function (hl) {
    if (hl.y < y0 || hl.y > y1) { return; }
    el("line", { x1: L, x2: W - R, y1: Y(hl.y), y2: Y(hl.y), stroke: hl.color, "stroke-dasharray": "4 3" }, svg);
    text(svg, W - R - 80, Y(hl.y) - 3, hl.label, { fill: hl.color });
  });
  return svg;
}

// ---------- telemetry health ----------
(function health() {
  const H = D.health;
  const box = document.getElementById("health");
  const p = h("p", {}, box);
  p.textContent = H.packets + " MAVLink packets in flight.tlog over " + fmt(H.tlog_span_s, 1) + " s" + (H.undecoded ? " (" + H.undecoded + " not decoded)" : "") + "; " + H.gaps.length + " silence(s) of the autopilot longer than 1 s; " + H.dropped_total + " camera frames dropped (inference busy); " + H.timesync.length + " TIMESYNC round trips" + (H.timesync.length ? " (first offset " + fmt(H.timesync[0].offset_ms / 1000, 3) + " s)" : "") + ".";
  const charts = h("div", { class: "charts" }, box);
  const ts = H.timesync;
  if (ts.length > 0) {
    const o0 = ts[0].offset_ms;
    chart(charts, { id: "timesync-chart", title: "TIMESYNC offset (autopilot − companion), change since the first (ms)", xmin: 0, xmax: duration || undefined, series: [{ color: "#4363d8", dots: true, points: ts.map(function (x) { return [x.t, x.offset_ms - o0]; }) }] });
    chart(charts, { id: "rtt-chart", title: "TIMESYNC round trip (ms)", xmin: 0, xmax: duration || undefined, ymin: 0, series: [{ color: "#f58231", dots: true, points: ts.map(function (x) { return [x.t, x.rtt_ms]; }) }] });
  } else {
    h("p", { class: "warn" }, box, "No TIMESYNC round trips in flight.tlog: the frame times could not be checked against the autopilot's clock.");
  }
  chart(charts, { id: "dropped-chart", title: "Camera frames dropped (cumulative)", xmin: 0, ymin: 0, series: [{ color: "#e6194b", step: true, points: H.dropped }] });
  const t = h("table", { id: "rates-table" }, box);
  const hr = h("tr", {}, t);
  ["From", "Message", "Packets", "Rate (Hz)"].forEach(function (c) { h("th", {}, hr, c); });
  H.rates.slice().sort(function (a, b) { return a.from === b.from ? b.count - a.count : (a.from < b.from ? -1 : 1); }).forEach(function (r) {
    const row = h("tr", {}, t);
    h("td", {}, row, r.from); h("td", { class: "mono" }, row, r.name); h("td", { class: "num" }, row, String(r.count)); h("td", { class: "num" }, row, fmt(r.rate_hz, 2));
  });
  if (H.gaps.length > 0) {
    const g = h("table", { id: "gaps-table" }, box);
    const gh = h("tr", {}, g); ["Autopilot silent from (s)", "UTC", "for (s)"].forEach(function (c) { h("th", {}, gh, c); });
    H.gaps.forEach(function (x) { const r = h("tr", {}, g); h("td", { class: "num" }, r, fmt(x.t, 1)); h("td", { class: "mono" }, r, utcAt(x.t)); h("td", { class: "num" }, r, fmt(x.duration_s, 2)); });
  }
})();

// ---------- keyframes ----------
(function keyframes() {
  const box = document.getElementById("keyframes");
  if (D.keyframes.length === 0) { h("p", {}, box, "No keyframes were recorded in this flight."); return; }
  if (D.keyframes_recorded > D.keyframes.length) { h("p", { class: "muted", style: "width:100%" }, box, D.keyframes.length + " of " + D.keyframes_recorded + " keyframes shown (evenly spaced)."); }
  D.keyframes.forEach(function (k) {
    const fig = h("figure", {}, box);
    const svg = el("svg", { viewBox: "0 0 " + k.width_px + " " + k.height_px, class: "keyframe" }, fig);
    if (k.data_uri) { el("image", { href: k.data_uri, x: 0, y: 0, width: k.width_px, height: k.height_px, preserveAspectRatio: "none" }, svg); }
    else { text(svg, 20, 60, "image " + k.file + " could not be read", { fill: "#fff", "font-size": 40 }); }
    const s = k.width_px / 420;
    k.boxes.forEach(function (b) {
      const tr = b.track_id !== null ? byId[b.track_id] : null;
      const color = tr ? tr.color : "#ffffff";
      el("rect", { x: b.xywh[0], y: b.xywh[1], width: b.xywh[2], height: b.xywh[3], fill: "none", stroke: color, "stroke-width": 2 * s, "stroke-dasharray": tr ? "" : (4 * s) + " " + (3 * s) }, svg);
      if (tr) { text(svg, b.xywh[0], b.xywh[1] - 3 * s, b.track_id + " " + b.class + " " + b.score.toFixed(2), { fill: color, "font-size": 11 * s, "font-weight": "bold", stroke: "#000", "stroke-width": 0.4 * s }); }
    });
    h("figcaption", {}, fig, k.file + " · t = " + k.t.toFixed(1) + " s · " + k.utc + " · " + k.boxes.filter(function (b) { return b.track_id !== null; }).length + " track(s); dashed white: detections no track reported");
  });
})();

// ---------- truth ----------
(function truth() {
  if (!D.truth) { return; }
  const T = D.truth;
  const sec = document.getElementById("truth-section");
  sec.hidden = false;
  const box = h("div", { id: "truth" }, document.getElementById("truth-slot"));
  h("p", {}, box, "Each geolocated report matched to the nearest true object within " + T.radius_m + " m at its frame's time: " + T.matched + " matched, " + T.unmatched + " unmatched" + (T.untimed ? ", " + T.untimed + " without a time in the truth" : "") + (T.retimed ? " (" + T.retimed + " timed by the companion's clock: their autopilot time was missing or ambiguous over a reboot)" : "") + ". Over all matched reports: median " + fmt(T.overall.median_m, 2) + " m, p95 " + fmt(T.overall.p95_m, 2) + " m, max " + fmt(T.overall.max_m, 2) + " m.");
  const t = h("table", { id: "truth-table" }, box);
  const hr = h("tr", {}, t);
  ["True object", "Class", "Tracks", "Reports", "Median (m)", "p95 (m)", "Max (m)"].forEach(function (c) { h("th", {}, hr, c); });
  T.objects.forEach(function (o) {
    const r = h("tr", {}, t);
    h("td", {}, r, String(o.object_id)); h("td", {}, r, o.class);
    h("td", {}, r, o.track_ids.length ? o.track_ids.join(", ") : "never reported");
    h("td", { class: "num" }, r, String(o.stats.n));
    h("td", { class: "num" }, r, o.stats.n ? fmt(o.stats.median_m, 2) : "–");
    h("td", { class: "num" }, r, o.stats.n ? fmt(o.stats.p95_m, 2) : "–");
    h("td", { class: "num" }, r, o.stats.n ? fmt(o.stats.max_m, 2) : "–");
  });
  const charts = h("div", { class: "charts" }, box);
  T.objects.filter(function (o) { return o.samples.length > 0; }).forEach(function (o) {
    const ids = o.track_ids;
    chart(charts, { width: 360, height: 160, title: "True object " + o.object_id + " (" + o.class + "): error (m)", xmin: 0, xmax: duration || undefined, ymin: 0,
      series: ids.map(function (id) { return { color: byId[id] ? byId[id].color : "#333", dots: true, points: o.samples.filter(function (s) { return s.track_id === id; }).map(function (s) { return [s.t, s.error_m]; }) }; }),
      hlines: [{ y: o.stats.median_m, color: "#666", label: "median" }] });
  });
})();

document.body.dataset.rendered = "ok";
})();
"##;
