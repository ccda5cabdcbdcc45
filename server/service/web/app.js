// rangex's operator dashboard: plain JavaScript over rangexd's JSON API and its live event
// stream (/api/events). Views: lanes (tiles, live reject feed, charts of the last hour), a
// fillet (its four images side by side with fragments boxed), records (search, CSV export)
// and calibrations (who uploaded and activated what, when). Served by the fleet view
// (rangexd --fleet, /api/info says "fleet"), the same views cover every server: fillets are
// named SERVER/UID, tiles are grouped by server, and the feed is polled from PostgreSQL.
"use strict";

const view = document.getElementById("view");
const state = { info: null, feed: [], events: null, timers: [] };
const FEED_MAX = 40;

function esc(s) {
  return String(s ?? "").replace(/[&<>"']/g, (c) =>
    ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
}
function fmtTime(ns) {
  return new Date(Number(ns) / 1e6).toLocaleString();
}
const fleet = () => !!(state.info && state.info.fleet);
// A fillet's name in the API's paths: its uid, or SERVER/UID in the fleet view.
function filletKey(f) {
  return fleet() ? `${encodeURIComponent(f.server)}/${f.uid}` : String(f.uid);
}
function pct(x) {
  return (100 * x).toFixed(1) + " %";
}
async function api(path) {
  const r = await fetch(path);
  const body = await r.json();
  if (!r.ok) throw new Error(body.error || r.statusText);
  return body;
}
// Runs f now and every `ms` while the view is shown; a failure is shown, not thrown.
function every(ms, f) {
  const run = () => Promise.resolve().then(f).catch(showError);
  run();
  state.timers.push(setInterval(run, ms));
}
function clearTimers() {
  state.timers.forEach(clearInterval);
  state.timers = [];
}

// ---- the live event stream, kept open across views ----------------------------------------
function connectEvents() {
  const conn = document.getElementById("conn");
  const es = new EventSource("/api/events?decisions=reject,not_inspected");
  state.events = es;
  es.onopen = () => { conn.textContent = "live"; conn.className = "conn live"; };
  es.onerror = () => { conn.textContent = "reconnecting"; conn.className = "conn lost"; };
  es.addEventListener("fillet", (ev) => {
    const f = JSON.parse(ev.data);
    f.shown_ms = Date.now();
    addToFeed([f]);
  });
}

// Newest first, each fillet once (the stored rejects loaded at start and the live ones can
// overlap).
function addToFeed(fillets) {
  const seen = new Set(state.feed.map(filletKey));
  const fresh = fillets.filter((f) => !seen.has(filletKey(f)));
  state.feed = fresh.concat(state.feed)
    .sort((a, b) => fleet() ? b.decided_ns - a.decided_ns : b.uid - a.uid).slice(0, FEED_MAX);
  const list = document.getElementById("feed-list");
  if (!list) return;
  list.innerHTML = "";
  state.feed.forEach((f) => list.append(feedItem(f)));
}

// The latest rejects already stored, so that the feed is not empty when the page opens.
async function loadRecentRejects() {
  const pages = await Promise.all(["reject", "not_inspected"].map((d) =>
    api(`/api/fillets?decision=${d}&newest=1&limit=${FEED_MAX}`)));
  addToFeed(pages.flatMap((p) => p.fillets));
}

function feedItem(f) {
  const li = document.createElement("li");
  li.dataset.uid = f.uid;
  if (f.server) li.dataset.server = f.server;
  li.dataset.decidedNs = f.decided_ns;
  if (f.shown_ms) li.dataset.shownMs = f.shown_ms;  // live: when it arrived
  const bones = f.fragments.filter((g) => g.kind === "bone").length;
  const thumb = f.images.includes("overlay")
    ? `<img alt="fillet ${f.uid}" src="/api/fillets/${filletKey(f)}/images/overlay">`
    : `<div class="noimg muted">no image</div>`;
  li.innerHTML =
    thumb +
    `<div><span class="badge ${esc(f.decision)}">${esc(f.decision.replace("_", " "))}</span> ` +
    `${f.server ? esc(f.server) + " · " : ""}lane ${f.lane} · fillet ${f.lane_fillet}<br>` +
    `<span class="muted">${fmtTime(f.decided_ns)} · ${bones} fragment${bones === 1 ? "" : "s"}` +
    `${f.lagged ? " · " + f.lagged + " missed" : ""}</span></div>`;
  li.addEventListener("click", () => { location.hash = "#/fillet/" + filletKey(f); });
  return li;
}

// ---- lanes: tiles, the reject feed, charts ------------------------------------------------
function lanesView() {
  // The fleet view only reads: a verification run is started on the lane's own server.
  const verify = fleet() ? "" :
    `<form class="search panel verify" id="verify">
       <strong>Verification run</strong>
       <label>lane<input name="lane" type="number" min="0" value="0" required></label>
       <label>test piece<input name="piece" value="2 mm calcified sphere" required></label>
       <label>across the belt, mm<input name="x_mm" type="number" step="0.1" required></label>
       <label>within fillets<input name="fillets" type="number" min="1" placeholder="plant.yaml"></label>
       <button>Start</button><span id="verify-out" class="muted"></span>
     </form>`;
  view.innerHTML =
    `<h2>Lanes</h2><div id="tiles"></div>${verify}
     <div class="row">
       <div class="panel feed"><h2>Rejects, live</h2><ul id="feed-list"></ul></div>
       <div class="panel charts"><h2>Last hour</h2>
         ${fleet() ? "" : `<div class="muted">lines/s (all lanes)</div><canvas id="c-rate"></canvas>`}
         <div class="muted">fillets/min${fleet() ? " (every server)" : ""}: decided (black), rejected (red)</div><canvas id="c-fillets"></canvas>
         ${fleet() ? "" : `<div class="muted">last line to decision, ms: p50 (black), p99 (red)</div><canvas id="c-lat"></canvas>`}
       </div>
     </div>`;
  const list = document.getElementById("feed-list");
  state.feed.forEach((f) => list.append(feedItem(f)));
  if (!fleet()) document.getElementById("verify").addEventListener("submit", startVerification);
  every(1000, refreshTiles);
  every(5000, refreshCharts);
}

// Where the records go when there is a plant-wide database, and how far behind.
function showForwarding(info) {
  const el = document.getElementById("forwarding");
  if (!el || !info) return;
  const f = info.forwarding;
  el.textContent = f ? f.text : "";
  el.title = f && f.error ? f.error : "";
  el.className = f && !f.ok ? "bad" : "";
}

async function refreshTiles() {
  const tiles = document.getElementById("tiles");
  if (!tiles) return;
  const lanes = await api("/api/lanes");
  if (!fleet()) {
    showForwarding(await api("/api/info"));
    tiles.innerHTML = `<div class="tiles">${laneTiles(lanes)}</div>`;
    return;
  }
  // The fleet: one group per server, headed by its state and forwarding lag.
  const servers = await api("/api/servers");
  tiles.innerHTML = servers.map((s) =>
    `<section class="server" data-server="${esc(s.server)}">
       <h3><span class="light ${s.up ? "green" : "red"}" title="${esc(s.state)}"></span>${esc(s.server)}
         <span class="muted">${esc(s.host)} · ${esc(s.state)} · ${s.lag_records
           ? `${s.lag_records} records (${s.lag_seconds.toFixed(0)} s) not yet forwarded` : "forwarding caught up"}
           ${s.warnings.length ? " · " + esc(s.warnings.join("; ")) : ""}</span></h3>
       <div class="tiles">${laneTiles(lanes.filter((l) => l.server === s.server))}</div>
     </section>`).join("");
}

function laneTiles(lanes) {
  return lanes.map((l) =>
    `<div class="tile" data-lane="${l.lane}" data-light="${l.light}">
       <div class="top"><span class="light ${l.light}" title="${esc(l.light_reason)}"></span>lane ${l.lane}</div>
       <dl>
         <dt>lines/s</dt><dd>${l.line_rate.toFixed(0)}</dd>
         <dt>fillets/min</dt><dd>${l.fillets_per_min.toFixed(1)}</dd>
         <dt>rejected</dt><dd>${pct(l.reject_rate)}</dd>
         <dt>not inspected</dt><dd>${pct(l.not_inspected_rate)}</dd>
         <dt>backend</dt><dd>${esc(l.backend)}</dd>
         <dt>calibration</dt><dd title="${esc(l.calibration)}">${esc(l.calibration)}</dd>
         <dt>thresholds</dt><dd title="${esc((l.learned_sensitivity || []).join("; "))}">${
           l.learned_version ? esc(l.learned_version) : "fixed"}</dd>
         ${l.learned_version && l.implied_false_reject_rate >= 0
           ? `<dt>implied false rejects</dt><dd>${pct(l.implied_false_reject_rate)}</dd>` : ""}
         ${l.sensors ? sensorsRow(l.sensors) : ""}
         ${verificationRow(l.verification)}
         ${l.plc ? `<dt>PLC</dt><dd class="${l.plc.startsWith("unreachable") ? "bad" : ""}" title="${esc(l.plc)}">${esc(l.plc)}</dd>` : ""}
       </dl>
       ${(l.learned_sensitivity || []).length
         ? `<div class="sens">${esc(l.learned_sensitivity[0])}</div>` : ""}
       <div class="why">${esc(l.light_reason)}</div>
     </div>`).join("");
}

// Starts a verification run on a lane (the operator role: the server answers 401/403 to
// anyone else, and its message is shown); the lane's tile then shows it running.
async function startVerification(ev) {
  ev.preventDefault();
  const f = new FormData(ev.target);
  const out = document.getElementById("verify-out");
  const body = { piece: f.get("piece"), x_mm: Number(f.get("x_mm")) };
  if (f.get("fillets")) body.fillets = Number(f.get("fillets"));
  out.className = "muted";
  out.textContent = "starting...";
  try {
    const r = await fetch(`/api/lanes/${Number(f.get("lane"))}/verification`, {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
    const answer = await r.json();
    if (!r.ok) throw new Error(answer.error || r.statusText);
    const v = answer.lane.verification;
    out.textContent = `lane ${answer.lane.lane}: ${v.running_piece}, ${v.fillets_left} fillets to go`;
  } catch (e) {
    out.className = "error";
    out.textContent = e.message;
  }
}

// The lane's last verification run (HACCP: a declared test piece found where placed), one
// running, amber when due or failed.
function verificationRow(v) {
  if (!v) return "";
  let text = "none yet";
  if (v.running) text = `running: ${v.running_piece}`;
  else if (v.last) {
    const h = (Date.now() - v.last.unix_ns / 1e6) / 3.6e6;
    text = `${v.last.passed ? "passed" : "FAILED"} ${h < 1 ? Math.round(h * 60) + " min" : h.toFixed(1) + " h"} ago`;
  }
  return `<dt>verified</dt><dd class="${v.overdue ? "bad" : ""}" title="${esc(v.last ? v.last.detail : "")}">${esc(text)}</dd>`;
}

// A lane fed by its own GigE Vision devices: one mark per device (green streaming, red
// otherwise, its error on hover) and the share of lines a device lacked.
function sensorsRow(s) {
  const marks = s.devices.map((d) =>
    `<span class="sensor ${d.state === "streaming" ? "ok" : "bad"}" title="${esc(
      `${d.device} ${d.description}: ${d.state}${d.error ? " - " + d.error : ""}; ` +
      `${d.frames} frames, ${d.incomplete} incomplete, ${d.lost_frames} lost, ` +
      `${d.reconnects} reconnects`)}">${esc(d.role)}</span>`).join(" ");
  const all = s.lines + s.incomplete_lines;
  return `<dt>sensors</dt><dd class="sensors">${marks}</dd>
          <dt>lines missing</dt><dd>${pct(all ? s.incomplete_lines / all : 0)}</dd>`;
}

function chart(id, samples, series, period_s) {
  const c = document.getElementById(id);
  if (!c) return;
  const w = (c.width = c.clientWidth * devicePixelRatio);
  const h = (c.height = c.clientHeight * devicePixelRatio);
  const g = c.getContext("2d");
  g.clearRect(0, 0, w, h);
  if (samples.length < 2) {
    g.fillStyle = "#667085";
    g.font = `${12 * devicePixelRatio}px sans-serif`;
    g.fillText(`collecting (a sample every ${period_s} s)`, 8, h / 2);
    return;
  }
  const t0 = samples[0].t_ns, t1 = samples[samples.length - 1].t_ns;
  let top = 1;
  for (const s of samples) for (const [k] of series) top = Math.max(top, s[k]);
  const pad = 4 * devicePixelRatio;
  g.fillStyle = "#667085";
  g.font = `${11 * devicePixelRatio}px sans-serif`;
  g.fillText(top.toFixed(0), pad, 12 * devicePixelRatio);
  for (const [k, colour] of series) {
    g.strokeStyle = colour;
    g.lineWidth = devicePixelRatio * 1.5;
    g.beginPath();
    samples.forEach((s, i) => {
      const x = pad + ((w - 2 * pad) * (s.t_ns - t0)) / Math.max(1, t1 - t0);
      const y = h - pad - ((h - 2 * pad) * s[k]) / top;
      if (i === 0) g.moveTo(x, y); else g.lineTo(x, y);
    });
    g.stroke();
  }
}

async function refreshCharts() {
  const h = await api("/api/history?minutes=60");
  chart("c-rate", h.samples, [["lines_per_s", "#1d2330"]], h.period_s);
  chart("c-fillets", h.samples, [["fillets_per_min", "#1d2330"], ["rejects_per_min", "#d63b3b"]], h.period_s);
  chart("c-lat", h.samples, [["decision_p50_ms", "#1d2330"], ["decision_p99_ms", "#d63b3b"]], h.period_s);
}

// ---- one fillet: four images side by side, fragments boxed -----------------------------------
async function filletView(server, uid) {
  view.innerHTML = `<h2>Fillet ${server ? esc(server) + " / " : ""}${esc(uid)}</h2><div id="fillet">loading</div>`;
  const f = await api("/api/fillets/" + (server ? encodeURIComponent(server) + "/" : "") + encodeURIComponent(uid));
  const kinds = ["xray", "thickness", "pseudo_xray", "residual", "bone", "fat_share"].filter((k) => f.images.includes(k));
  const names = { xray: "X-ray", thickness: "thickness", pseudo_xray: "pseudo-X-ray", residual: "residual", bone: "bone (dual energy)", fat_share: "fat share" };
  const boxes = (W, H) => f.fragments.map((g) => {
    const l = (100 * Math.max(0, g.col0 - 2)) / W, t = (100 * Math.max(0, g.row0 - 2)) / H;
    const bw = (100 * (g.col1 - g.col0 + 5)) / W, bh = (100 * (g.row1 - g.row0 + 5)) / H;
    return `<div class="box ${esc(g.kind)}" style="left:${l}%;top:${t}%;width:${bw}%;height:${bh}%"></div>`;
  }).join("");
  document.getElementById("fillet").innerHTML =
    `<p><span class="badge ${esc(f.decision)}">${esc(f.decision.replace("_", " "))}</span>
       lane ${f.lane} · fillet ${f.lane_fillet} · ${fmtTime(f.decided_ns)} · calibration ${esc(f.calibration)}
       <br><span class="muted">${esc(f.reason)}</span>
       ${f.kept_by ? `<br><span class="muted">images kept by server ${esc(f.kept_by.server)} (${esc(f.kept_by.state)})</span>` : ""}</p>
     ${kinds.length ? "" : '<p class="muted">No images are kept for passed fillets.</p>'}
     <div class="images">${kinds.map((k) =>
       `<figure data-kind="${k}"><figcaption>${names[k]}</figcaption>
          <div class="frame"><img alt="${names[k]}" src="/api/fillets/${filletKey(f)}/images/${k}"></div></figure>`).join("")}
     </div>
     <h2>Fragments</h2>
     <table><tr><th>kind</th><th>x mm</th><th>y mm</th><th>area mm²</th><th>peak z</th><th>mm of meat</th></tr>
     ${f.fragments.map((g) => `<tr><td>${esc(g.kind)}</td><td>${g.x_mm.toFixed(1)}</td><td>${g.y_mm.toFixed(1)}</td>
       <td>${g.area_mm2.toFixed(2)}</td><td>${g.peak_z.toFixed(1)}</td><td>${g.meat_mm.toFixed(2)}</td></tr>`).join("")}
     </table>`;
  // Boxes go on once each image's size (the fillet's pixels) is known.
  // An image that does not come (its server unreachable, in the fleet view) says why.
  document.querySelectorAll(".frame img").forEach((img) => img.addEventListener("error", async () => {
    let why = "image not available";
    try { why = (await (await fetch(img.src)).json()).error || why; } catch (e) { /* not JSON */ }
    img.replaceWith(Object.assign(document.createElement("p"), { className: "error", textContent: why }));
  }, { once: true }));
  document.querySelectorAll(".frame img").forEach((img) => {
    const place = () => img.insertAdjacentHTML("afterend", boxes(img.naturalWidth, img.naturalHeight));
    if (img.complete && img.naturalWidth) place(); else img.addEventListener("load", place, { once: true });
  });
}

// ---- records: search by time, lane and decision; CSV export ----------------------------------
function recordsView() {
  const lanes = state.info && !fleet() ? Array.from({ length: state.info.lanes }, (_, i) => i) : [];
  view.innerHTML =
    `<h2>Records</h2>
     <form class="search" id="search">
       <label>from<input type="datetime-local" name="from" step="1"></label>
       <label>to<input type="datetime-local" name="to" step="1"></label>
       ${fleet() ? `<label>server<input name="server" placeholder="all"></label>` : ""}
       <label>lane${fleet() ? `<input name="lane" type="number" min="0" placeholder="all">` : `<select name="lane"><option value="">all</option>
         ${lanes.map((l) => `<option>${l}</option>`).join("")}</select>`}</label>
       <label>decision<select name="decision"><option value="">any</option>
         <option>pass</option><option>reject</option><option value="not_inspected">not inspected</option></select></label>
       <button type="submit">Search</button>
       <a class="button" id="csv" href="/api/fillets.csv">Export CSV</a>
     </form>
     <table id="records"><thead><tr>${fleet() ? "<th>server</th>" : ""}<th>uid</th><th>decided</th><th>lane</th><th>fillet</th>
       <th>decision</th><th>fragments</th><th>reason</th></tr></thead><tbody></tbody></table>
     <p><button id="more" hidden>More</button> <span id="count" class="muted"></span></p>`;
  let after = 0, params = "", shown = 0;
  const form = document.getElementById("search");
  const query = () => {
    const q = new URLSearchParams();
    const v = (n) => form.elements[n].value;
    if (v("from")) q.set("from_ns", String(BigInt(new Date(v("from")).getTime()) * 1000000n));
    if (v("to")) q.set("to_ns", String(BigInt(new Date(v("to")).getTime()) * 1000000n));
    if (v("lane") !== "") q.set("lane", v("lane"));
    if (fleet() && v("server")) q.set("server", v("server"));
    if (v("decision")) q.set("decision", v("decision"));
    return q.toString();
  };
  const load = async () => {
    const page = await api(`/api/fillets?limit=200&after=${encodeURIComponent(after)}${params ? "&" + params : ""}`);
    const body = document.querySelector("#records tbody");
    body.insertAdjacentHTML("beforeend", page.fillets.map((f) =>
      `<tr data-uid="${f.uid}">${fleet() ? `<td>${esc(f.server)}</td>` : ""}<td><a href="#/fillet/${filletKey(f)}">${f.uid}</a></td><td>${fmtTime(f.decided_ns)}</td>
         <td>${f.lane}</td><td>${f.lane_fillet}</td><td><span class="badge ${esc(f.decision)}">${esc(f.decision.replace("_", " "))}</span></td>
         <td>${f.fragments.filter((g) => g.kind === "bone").length}</td><td>${esc(f.reason)}</td></tr>`).join(""));
    shown += page.fillets.length;
    after = page.next_after;
    document.getElementById("more").hidden = page.fillets.length < 200;
    document.getElementById("count").textContent = `${shown} fillets`;
  };
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    params = query();
    after = 0;
    shown = 0;
    document.querySelector("#records tbody").innerHTML = "";
    document.getElementById("csv").href = "/api/fillets.csv" + (params ? "?" + params : "");
    load().catch(showError);
  });
  document.getElementById("more").addEventListener("click", () => load().catch(showError));
  load().catch(showError);
}

// ---- calibrations: versions and who did what ------------------------------------------------
async function calibrationsView() {
  view.innerHTML = `<h2>Calibrations</h2><div id="cal">loading</div>`;
  const c = await api("/api/calibrations");
  document.getElementById("cal").innerHTML =
    `<table id="cal-versions"><tr>${fleet() ? "<th>server</th><th>kind</th>" : ""}<th>lane</th><th>id</th><th>uploaded</th><th>active</th><th>solver report</th></tr>
     ${c.versions.map((v) => `<tr>${fleet() ? `<td>${esc(v.server)}</td><td>${esc(v.kind)}</td>` : ""}<td>${v.lane}</td><td>${esc(v.id)}</td><td>${fmtTime(v.uploaded_ns)}</td>
       <td>${v.active ? "active" : ""}</td><td>${v.has_report ? "yes" : "none"}</td></tr>`).join("")}
     </table>
     <h2>History</h2>
     <table id="cal-events"><tr>${fleet() ? "<th>server</th>" : ""}<th>when</th><th>who</th><th>what</th><th>detail</th></tr>
     ${c.events.slice().reverse().map((e) => `<tr>${fleet() ? `<td>${esc(e.server)}</td>` : ""}<td>${fmtTime(e.ts_ns)}</td><td>${esc(e.who)}</td>
       <td>${esc(e.what)}</td><td>${esc(e.detail)}</td></tr>`).join("")}
     </table>`;
}

function showError(e) {
  let p = document.getElementById("error");
  if (!p) {
    view.insertAdjacentHTML("afterbegin", `<p class="error" id="error"></p>`);
    p = document.getElementById("error");
  }
  p.textContent = e.message;
}

function route() {
  clearTimers();
  const h = location.hash || "#/";
  document.querySelectorAll("nav a").forEach((a) => a.classList.toggle("active", a.getAttribute("href") === h));
  const m = h.match(/^#\/fillet\/(?:([A-Za-z0-9._-]+)\/)?(\d+)$/);
  let p;
  if (m) p = filletView(m[1], m[2]);
  else if (h === "#/records") p = recordsView();
  else if (h === "#/calibrations") p = calibrationsView();
  else p = lanesView();
  Promise.resolve(p).catch(showError);
}

async function main() {
  try {
    state.info = await api("/api/info");
    document.getElementById("plant").textContent = fleet()
      ? `${state.info.plant} · fleet of ${state.info.servers} servers · ${state.info.lanes} lanes`
      : `${state.info.plant} · ${state.info.lanes} lanes · ${state.info.backend}`;
    showForwarding(state.info);
  } catch (e) {
    showError(e);
  }
  if (fleet()) {
    // PostgreSQL has no event stream here: the feed is read again every 5 s.
    const conn = document.getElementById("conn");
    conn.textContent = "PostgreSQL";
    conn.className = "conn live";
    conn.title = state.info.database;
    setInterval(() => loadRecentRejects().catch(showError), 5000);
  } else {
    connectEvents();
  }
  loadRecentRejects().catch(showError);
  window.addEventListener("hashchange", route);
  route();
}
main();
