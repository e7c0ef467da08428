// modbot station: the page's side. It receives the station's state over the WebSocket (ten
// looks a second), draws it, and sends the operator's commands. No library, nothing fetched
// from elsewhere.
"use strict";

const $ = (sel) => document.querySelector(sel);
const token = new URLSearchParams(location.search).get("token");
const view = {
  canCommand: false,
  state: null,
  pose: null,        // {x, y, heading}
  trail: [],         // past poses
  alerts: [],        // {x, y}: where the robot was at each alert the log holds
  boxSeen: false,    // the box the building map does not know, once the robot was near
  map: null,
  history: {},       // "module.item" -> [numbers]
  arm: null,         // {link: [[per look] per joint], demand: [...]}: the bus bridge's joints
  nextId: 1,
  restarts: {},
};
window.station = view; // for the browser tests and the curious

const HISTORY = 300;

function connect() {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws` +
    (token ? `?token=${encodeURIComponent(token)}` : "");
  const ws = new WebSocket(url);
  view.ws = ws;
  ws.onopen = () => { setPill("#link", "live", "good"); };
  ws.onclose = (e) => {
    setPill("#link", `closed${e.reason ? ": " + e.reason : ""}`, "bad");
    view.closeReason = e.reason;
    setTimeout(connect, 1000);
  };
  ws.onmessage = (e) => {
    const m = JSON.parse(e.data);
    if (m.type === "hello") {
      view.canCommand = m.can_command;
      $("#domain").textContent = `domain ${m.domain}`;
      setPill("#mode", m.can_command ? "commanding" : "read-only", m.can_command ? "good" : "warn");
      document.body.dataset.mode = m.can_command ? "commanding" : "read-only";
    } else if (m.type === "state") {
      view.state = m;
      view.stateAt = Date.now();
      render(m);
    } else if (m.type === "answer") {
      answered(m);
    }
  };
}

function setPill(sel, text, kind) {
  const el = $(sel);
  el.hidden = false;
  el.textContent = text;
  el.className = "pill" + (kind ? " " + kind : "");
}

function send(msg) {
  if (view.ws && view.ws.readyState === WebSocket.OPEN) view.ws.send(JSON.stringify(msg));
}

// A command; its answer comes back with the same id.
function call(module, method, args) {
  const id = view.nextId++;
  const li = document.createElement("li");
  li.dataset.id = id;
  li.textContent = `${module}.${method}(${args.join(", ")}) …`;
  $("#answers").prepend(li);
  send({ op: "call", id, module, method, args });
  return id;
}

function answered(m) {
  const li = document.querySelector(`#answers li[data-id="${m.id}"]`);
  if (!li) return;
  li.textContent = li.textContent.replace(/ …$/, "") + (m.ok ? ` → ${m.text}` : ` failed: ${m.text}`);
  li.className = m.ok ? "ok" : "err";
  li.dataset.ok = m.ok;
}

function fmtUs(x) { return x == null ? "–" : x < 1000 ? `${x.toFixed(1)} µs` : `${(x / 1000).toFixed(2)} ms`; }
function fmtAge(ms) { return ms == null ? "–" : ms < 10_000 ? `${ms} ms ago` : `${(ms / 1000).toFixed(1)} s ago`; }
function fmtNs(x) { return fmtUs(x / 1000); }

// Each part of the page is drawn on its own: one that fails (says why in the problems line and
// in view.errors) does not stop the others.
function render(s) {
  const errors = [];
  for (const part of [renderModules, renderRobotAndGrid, renderArm, renderBoards, renderMap, renderEvents]) {
    try {
      part(s);
    } catch (e) {
      errors.push(`${part.name}: ${e.message || e}`);
    }
  }
  view.errors = errors;
  const lines = [];
  if (s.problems.length) lines.push("not answered in the last look: " + s.problems.join("; "));
  if (errors.length) lines.push("the page could not draw: " + errors.join("; "));
  $("#problems").textContent = lines.join(" · ");
}

function renderModules(s) {
  const stop = $("#system-stop");
  stop.hidden = !s.supervised;
  stop.disabled = !view.canCommand;
  const body = $("#modules tbody");
  const running = s.modules.filter((m) => m.state === "running").length;
  $("#module-count").textContent = `${s.modules.length} modules, ${running} running${s.supervised ? "" : " (no supervisor)"}` +
    ` · looked at in ${s.look_ms} ms · ${s.pages} page${s.pages === 1 ? "" : "s"} watching`;
  const seen = new Set();
  for (const m of s.modules) {
    seen.add(m.name);
    let tr = body.querySelector(`tr[data-module="${m.name}"]`);
    if (!tr) {
      tr = document.createElement("tr");
      tr.dataset.module = m.name;
      tr.innerHTML = "<td></td>".repeat(13) + "<td><button data-action=\"toggle\"></button> <button data-action=\"stats\">stats</button>" +
        " <button data-action=\"upgrade\" title=\"a new process of its program takes it over, live\">upgrade</button></td>";
      tr.querySelector('[data-action="toggle"]').onclick = () =>
        call(m.name, tr.dataset.active === "false" ? "activate" : "deactivate", []);
      tr.querySelector('[data-action="stats"]').onclick = () => call(m.name, "stats", []);
      // A live upgrade (docs/upgrade.md): the supervisor starts the module's program anew and
      // the new process takes the running one over; the row shows the new pid and count.
      tr.querySelector('[data-action="upgrade"]').onclick = () => call("supervisor", "upgrade", [m.name]);
      body.appendChild(tr);
    }
    const before = view.restarts[m.name];
    if (before !== undefined && m.restarts > before) {
      tr.classList.remove("flash");
      void tr.offsetWidth; // restart the animation
      tr.classList.add("flash");
    }
    view.restarts[m.name] = m.restarts;
    tr.dataset.state = m.state;
    tr.dataset.active = m.active === null ? "" : String(m.active);
    const cells = tr.children;
    const values = [m.addr, m.name, m.state, m.active === null ? "?" : m.active ? "yes" : "no", m.pid || "–",
      m.restarts, m.upgrades, fmtAge(m.heartbeat_age_ms), m.last_exit || "–", m.counters.dropped, m.counters.rejected, m.calls,
      `${fmtUs(m.latency_p50_us)} / ${fmtUs(m.latency_p99_us)}`];
    values.forEach((v, i) => { if (cells[i].textContent !== String(v)) cells[i].textContent = v; });
    cells[2].className = `state-${m.state}`;
    const toggle = tr.querySelector('[data-action="toggle"]');
    toggle.textContent = m.active === false ? "activate" : "deactivate";
    toggle.dataset.module = m.name;
    toggle.disabled = !view.canCommand || m.state !== "running";
    tr.querySelector('[data-action="stats"]').disabled = !view.canCommand || m.state !== "running";
    const upgrade = tr.querySelector('[data-action="upgrade"]');
    upgrade.hidden = !s.supervised || m.name === "supervisor" || m.name === "coordinator";
    upgrade.disabled = !view.canCommand || m.state !== "running";
  }
  for (const tr of [...body.children]) if (!seen.has(tr.dataset.module)) tr.remove();
  // The command form's suggestions.
  const names = s.modules.map((m) => m.name).join(",");
  if ($("#module-names").dataset.names !== names) {
    $("#module-names").dataset.names = names;
    $("#module-names").innerHTML = s.modules.map((m) => `<option value="${m.name}">`).join("");
    const select = $("#bb-module");
    const chosen = select.value;
    select.innerHTML = '<option value="">(choose)</option>' +
      s.modules.map((m) => `<option${m.name === chosen ? " selected" : ""}>${m.name}</option>`).join("");
  }
  const chosenModule = s.modules.find((m) => m.name === $("#call-module").value);
  const methods = chosenModule ? chosenModule.methods.join(",") : "";
  if ($("#method-names").dataset.methods !== methods) {
    $("#method-names").dataset.methods = methods;
    const all = (chosenModule ? chosenModule.methods : []).concat(["activate", "deactivate", "stats", "describe"]);
    $("#method-names").innerHTML = all.map((n) => `<option value="${n}">`).join("");
  }
}

function renderRobotAndGrid(s) {
  if (s.robot) setPill("#robot", `robot ${s.robot}`, s.robot.startsWith("operational") ? "good" : "bad");
  else $("#robot").hidden = true;
  // The operator's reset: offered while the robot is stopped, answered when done or refused.
  const reset = $("#robot-reset");
  reset.hidden = !s.robot || !s.bus || s.robot.startsWith("operational");
  reset.disabled = !view.canCommand;
  if (!reset.onclick) reset.onclick = () => { if (view.state && view.state.bus) call(view.state.bus, "reset", []); };
  const g = s.grid;
  $("#grid").hidden = !g;
  if (!g) { $("#grid-state").hidden = true; return; }
  $("#switch-form button").disabled = !view.canCommand;
  setPill("#grid-state", `grid ${g.state}`, g.state.startsWith("running") ? "good" : g.state.startsWith("fault") ? "bad" : "warn");
  $("#grid-summary").textContent = `${g.state}${g.fault ? ": " + g.fault : ""} · tick ${g.ticks} · missed ${g.missed} · ` +
    `${g.rate_hz.toFixed(0)} Hz · tick error p50 ${fmtNs(g.tick_err_p50)} p99 ${fmtNs(g.tick_err_p99)}`;
  const a = g.assembly;
  $("#assembly").hidden = !a;
  if (a) {
    const text = `assembly ${a.name}, generation ${a.generation} · switch: ${a.switch}`;
    if ($("#assembly").textContent !== text) $("#assembly").textContent = text;
    $("#assembly").dataset.generation = a.generation;
    $("#assembly").dataset.name = a.name;
    const history = a.history.map((h) => `<li>${escapeHtml(h)}</li>`).join("");
    if ($("#switches").innerHTML !== history) $("#switches").innerHTML = history;
  }
  // Rebuilt only when a number changed: a page that redraws less costs its machine less.
  const rows = g.components.map((c) =>
    `<tr data-component="${c.name}"><td>${c.name}</td><td>${c.host}</td><td>${c.period}</td><td>${c.policy}</td>` +
    `<td>${c.releases}</td><td>${c.overruns}</td><td>${c.late}</td><td>${c.stale}</td>` +
    `<td>${fmtNs(c.exec_p50)} / ${fmtNs(c.exec_p99)}</td></tr>`).join("");
  const body = $("#components tbody");
  if (body.dataset.rows !== rows) { body.dataset.rows = rows; body.innerHTML = rows; }
}

// Numbers as scrolling plots, arrays as bars, of the module chosen above.
function renderBoards(s) {
  for (const [module, items] of Object.entries(s.blackboards)) {
    for (const [item, v] of Object.entries(items)) {
      if (typeof v !== "number") continue;
      const key = `${module}.${item}`;
      const h = view.history[key] || (view.history[key] = []);
      h.push(v);
      if (h.length > HISTORY) h.shift();
    }
  }
  const module = $("#bb-module").value;
  const box = $("#bb-items");
  if (!module) { box.innerHTML = ""; return; }
  const items = s.blackboards[module];
  if (!items) { box.textContent = "waiting for the blackboard…"; return; }
  if (box.dataset.module !== module) { box.innerHTML = ""; box.dataset.module = module; }
  for (const [item, v] of Object.entries(items)) {
    let div = box.querySelector(`[data-item="${item}"]`);
    if (!div) {
      div = document.createElement("div");
      div.className = "plot";
      div.dataset.item = item;
      div.innerHTML = `<span></span><canvas width="260" height="90"></canvas>`;
      box.appendChild(div);
    }
    const label = div.querySelector("span");
    const canvas = div.querySelector("canvas");
    if (typeof v === "number") {
      label.textContent = `${item} = ${v.toPrecision(6)}`;
      canvas.hidden = false;
      drawLine(canvas, view.history[`${module}.${item}`] || []);
    } else if (Array.isArray(v)) {
      label.textContent = `${item} [${v.length}]`;
      canvas.hidden = false;
      drawBars(canvas, v);
    } else {
      label.textContent = `${item} = ${v && typeof v === "object" ? `${v.bytes} bytes` : v}`;
      canvas.hidden = true;
    }
  }
}

function drawLine(canvas, h) {
  drawLines(canvas, [[h, "#2a6fdb"]]);
}

function drawBars(canvas, v) {
  const c = canvas.getContext("2d");
  c.clearRect(0, 0, canvas.width, canvas.height);
  const finite = v.filter((x) => x !== null);
  const m = Math.max(1e-9, ...finite.map(Math.abs));
  const w = canvas.width / Math.max(1, v.length);
  const mid = canvas.height / 2;
  c.fillStyle = "#2a6fdb";
  v.forEach((x, i) => {
    if (x === null) return;
    const hgt = (x / m) * (mid - 2);
    c.fillRect(i * w + 1, hgt >= 0 ? mid - hgt : mid, Math.max(1, w - 2), Math.abs(hgt));
  });
  c.strokeStyle = "#0003";
  c.beginPath(); c.moveTo(0, mid); c.lineTo(canvas.width, mid); c.stroke();
}

// The arm: each joint's link position (measured) and demand position (commanded) over the
// last looks, and the following error between them.
function renderArm(s) {
  const bb = Object.values(s.blackboards).find((b) =>
    Array.isArray(b["robot.link_position"]) && Array.isArray(b["robot.demand_position"]));
  $("#arm").hidden = !bb;
  if (!bb) return;
  const link = bb["robot.link_position"], demand = bb["robot.demand_position"];
  const n = link.length;
  if (!view.arm || view.arm.link.length !== n) {
    view.arm = { link: Array.from({ length: n }, () => []), demand: Array.from({ length: n }, () => []) };
    $("#joints").innerHTML = link.map((_, j) =>
      `<div class="plot" data-joint="${j}"><span></span><canvas width="260" height="90"></canvas></div>`).join("");
  }
  let worst = 0;
  for (let j = 0; j < n; j++) {
    const l = view.arm.link[j], d = view.arm.demand[j];
    l.push(link[j]); d.push(demand[j]);
    if (l.length > HISTORY) { l.shift(); d.shift(); }
    const err = link[j] !== null && demand[j] !== null ? demand[j] - link[j] : null;
    if (err !== null) worst = Math.max(worst, Math.abs(err));
    const div = $(`#joints [data-joint="${j}"]`);
    div.querySelector("span").textContent =
      `joint ${j + 1}: link ${fmt(link[j])} rad, demand ${fmt(demand[j])}, following ${fmt(err)}`;
    drawLines(div.querySelector("canvas"), [[d, "#9aa3ad"], [l, "#2a6fdb"]]);
  }
  $("#arm-summary").textContent = `worst following error ${fmt(worst)} rad`;
}

function fmt(x) { return x === null || x === undefined ? "–" : x.toFixed(4); }

// Several series on one scale: [[numbers, colour], ...].
function drawLines(canvas, series) {
  const c = canvas.getContext("2d");
  c.clearRect(0, 0, canvas.width, canvas.height);
  const all = series.flatMap(([h]) => h.filter((x) => x !== null));
  if (!all.length) return;
  let lo = Math.min(...all), hi = Math.max(...all);
  if (hi - lo < 1e-6) { lo -= 0.1; hi += 0.1; }
  for (const [h, colour] of series) {
    c.strokeStyle = colour;
    c.beginPath();
    h.forEach((x, i) => {
      if (x === null) return;
      const px = (i / (HISTORY - 1)) * canvas.width;
      const py = canvas.height - 4 - ((x - lo) / (hi - lo)) * (canvas.height - 8);
      i === 0 ? c.moveTo(px, py) : c.lineTo(px, py);
    });
    c.stroke();
  }
}

// MOSER's building, the robot, its path, the sonar's rays and the alerts.
function renderMap(s) {
  const mob = s.blackboards.mobility;
  if (!mob || typeof mob.x !== "number") { $("#map-view").hidden = true; return; }
  $("#map-view").hidden = false;
  if (!view.map) {
    // Asked once; asked again a second later if that failed.
    if (!view.mapAsked) {
      view.mapAsked = true;
      fetch("api/map")
        .then((r) => (r.ok ? r.json() : Promise.reject(new Error(`HTTP ${r.status}`))))
        .then((m) => { view.map = m; })
        .catch((e) => {
          view.mapError = `${e.message || e}`;
          setTimeout(() => { view.mapAsked = false; }, 1000);
        });
    }
    return;
  }
  const pose = { x: mob.x, y: mob.y, heading: mob.heading || 0 };
  const last = view.trail[view.trail.length - 1];
  if (!last || Math.hypot(last.x - pose.x, last.y - pose.y) > 0.05) view.trail.push(pose);
  if (view.trail.length > 2000) view.trail.shift();
  view.pose = pose;
  view.alerts = s.events.filter((e) => e.kind === "alert" && e.at).map((e) => ({ x: e.at[0], y: e.at[1] }));
  const m = view.map;
  for (const b of m.boxes) {
    if (!b.on_map && pointRectDist(pose, b.rect) < 3) view.boxSeen = true;
  }
  const hl = s.blackboards.high_level;
  $("#robot-pose").textContent = `robot at (${pose.x.toFixed(2)}, ${pose.y.toFixed(2)}) heading ${pose.heading.toFixed(0)}°` +
    (hl && hl.state ? ` · ${hl.state}` : "");
  const pose_el = $("#robot-pose");
  pose_el.dataset.x = pose.x.toFixed(3);
  pose_el.dataset.y = pose.y.toFixed(3);

  const canvas = $("#map");
  const c = canvas.getContext("2d");
  const [x0, y0, x1, y1] = m.bounds;
  const k = Math.min((canvas.width - 20) / (x1 - x0), (canvas.height - 20) / (y1 - y0));
  const X = (x) => 10 + (x - x0) * k;
  const Y = (y) => canvas.height - 10 - (y - y0) * k;
  c.clearRect(0, 0, canvas.width, canvas.height);
  c.font = "11px system-ui";
  c.fillStyle = "#5a6472";
  for (const r of m.rooms) {
    c.fillText(r.name, X(r.rect[0]) + 4, Y(r.rect[3]) + 13);
    c.beginPath(); c.arc(X(r.patrol_point[0]), Y(r.patrol_point[1]), 2.5, 0, 7); c.fill();
  }
  for (const b of m.boxes) {
    if (!b.on_map && !view.boxSeen) continue;
    c.fillStyle = b.on_map ? "#c9ced6" : "#f2a65a";
    c.fillRect(X(b.rect[0]), Y(b.rect[3]), (b.rect[2] - b.rect[0]) * k, (b.rect[3] - b.rect[1]) * k);
  }
  c.strokeStyle = "#1d232b";
  c.lineWidth = 3;
  c.beginPath();
  for (const w of m.walls) { c.moveTo(X(w[0]), Y(w[1])); c.lineTo(X(w[2]), Y(w[3])); }
  c.stroke();
  c.lineWidth = 1;
  // The sonar's rays, all around the robot.
  const nav = s.blackboards.nav_sonar;
  if (nav && Array.isArray(nav.ranges)) {
    const n = nav.ranges.length;
    c.strokeStyle = "#2a6fdb55";
    c.beginPath();
    nav.ranges.forEach((r, i) => {
      if (r === null) return;
      const a = (pose.heading + (-180 + (360 * i) / n)) * Math.PI / 180;
      c.moveTo(X(pose.x), Y(pose.y));
      c.lineTo(X(pose.x + r * Math.cos(a)), Y(pose.y + r * Math.sin(a)));
    });
    c.stroke();
  }
  c.strokeStyle = "#1f7a3f";
  c.beginPath();
  view.trail.forEach((p, i) => (i ? c.lineTo(X(p.x), Y(p.y)) : c.moveTo(X(p.x), Y(p.y))));
  c.stroke();
  for (const a of view.alerts) {
    c.fillStyle = "#a12a2a";
    c.beginPath(); c.arc(X(a.x), Y(a.y), 9, 0, 7); c.fill();
    c.fillStyle = "#fff"; c.fillText("!", X(a.x) - 2, Y(a.y) + 4);
  }
  const h = (pose.heading * Math.PI) / 180;
  c.fillStyle = "#1d232b";
  c.beginPath();
  c.moveTo(X(pose.x + 0.5 * Math.cos(h)), Y(pose.y + 0.5 * Math.sin(h)));
  c.lineTo(X(pose.x + 0.3 * Math.cos(h + 2.4)), Y(pose.y + 0.3 * Math.sin(h + 2.4)));
  c.lineTo(X(pose.x + 0.3 * Math.cos(h - 2.4)), Y(pose.y + 0.3 * Math.sin(h - 2.4)));
  c.closePath();
  c.fill();
}

function pointRectDist(p, r) {
  const dx = Math.max(r[0] - p.x, 0, p.x - r[2]);
  const dy = Math.max(r[1] - p.y, 0, p.y - r[3]);
  return Math.hypot(dx, dy);
}

function renderEvents(s) {
  const ol = $("#events");
  const last = s.events.length ? s.events[s.events.length - 1] : null;
  const key = last ? `${s.events.length}:${last.t_ms}:${last.text}` : "";
  if (ol.dataset.key === key) return;
  ol.dataset.key = key;
  ol.innerHTML = s.events.slice().reverse().map((e) =>
    `<li class="${e.kind}" data-kind="${e.kind}">${(e.t_ms / 1000).toFixed(1)} s · ${escapeHtml(e.text)}</li>`).join("");
}

function escapeHtml(t) {
  return t.replace(/[&<>"]/g, (ch) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[ch]));
}

// Stopping the whole system asks first.
$("#system-stop").onclick = () => {
  const domain = view.state ? view.state.domain : "this";
  if (confirm(`Stop every module of the system in domain '${domain}'?`)) call("supervisor", "down", []);
};

$("#switch-form").onsubmit = (e) => {
  e.preventDefault();
  call("coordinator", "switch", [$("#switch-name").value.trim()]);
};

$("#call-form").onsubmit = (e) => {
  e.preventDefault();
  const args = $("#call-args").value.split(",").map((a) => a.trim()).filter((a) => a !== "");
  call($("#call-module").value.trim(), $("#call-method").value.trim(), args);
};

// The chosen module's blackboard is watched as long as the page shows it.
setInterval(() => {
  const chosen = $("#bb-module").value;
  if (chosen) send({ op: "watch", modules: [chosen] });
}, 2000);
$("#bb-module").onchange = () => {
  const chosen = $("#bb-module").value;
  if (chosen) send({ op: "watch", modules: [chosen] });
};

connect();
