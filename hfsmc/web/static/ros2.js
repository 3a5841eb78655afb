// hfsmc view --web: a ros2 interface's topics and its map (docs/web.md, "ROS 2 topics
// and the map"). app.js hands it the messages: ros2 (about 4 a second), trail (on
// connecting), scan (each new laser scan) and world (with --world). The map is drawn in
// the odom frame: x to the right, y up, one scale for both.
"use strict";

window.hfsmcRos2 = (function () {
  const STALE_S = 2.0;       // a topic whose latest message is older is shown stale
  const TRAIL_STEP_M = 0.02; // as the bridge keeps the trail
  const TRAIL_MAX = 4000;
  const HIT_CELL_M = 0.05;   // past scans' points, one per cell of this side
  const HITS_MAX = 30000;
  const ROBOT_RADIUS_M = 0.176;
  const maps = new Map();    // interface name -> what is drawn for it

  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function num(x, digits) { return typeof x === "number" ? x.toFixed(digits) : "–"; }

  function show(names) {
    const box = document.getElementById("hv-ros2");
    box.hidden = names.length === 0;
    for (const s of [...box.querySelectorAll(".hv-ros2")]) s.remove();
    maps.clear();
    for (const name of names) {
      const part = el("div", "hv-ros2");
      part.dataset.name = name;
      const head = el("div", "hv-ros2-node", name + ": waiting for the node");
      const table = el("table", "hv-topics");
      table.appendChild(el("tbody"));
      const canvas = el("canvas", "hv-map");
      canvas.width = 632; canvas.height = 520;  // drawn at twice the size shown: sharp
      canvas.hidden = true;
      const caption = el("div", "hv-map-caption", "");
      caption.hidden = true;
      part.append(head, table, canvas, caption);
      box.appendChild(part);
      maps.set(name, {head, table, canvas, caption, trail: [], pose: null, scan: null,
                      world: null, hits: new Map()});
    }
  }

  function row(m, key, cells, title, state) {
    const body = m.table.tBodies[0];
    let tr = body.querySelector('tr[data-key="' + key + '"]');
    if (!tr) {
      tr = el("tr");
      tr.dataset.key = key;
      for (let i = 0; i < cells.length; i++) tr.appendChild(el("td"));
      body.appendChild(tr);
    }
    cells.forEach((c, i) => { if (tr.cells[i].textContent !== c) tr.cells[i].textContent = c; });
    tr.title = title;
    tr.className = state;
  }

  function onRos2(msg) {
    const m = maps.get(msg.name);
    if (!m) return;
    const ns = (msg.namespace || "/").replace(/\/$/, "");
    m.head.textContent = msg.name + " · node " + ns + "/" + msg.node + " · domain " + msg.domain +
      " · " + msg.distro;
    for (const s of msg.subscriptions) {
      const state = s.dropped ? "hv-bad" : (!s.count || !s.publishers) ? "hv-bad"
        : (s.age !== null && s.age > STALE_S) ? "hv-stale" : "";
      row(m, "s/" + s.name, ["← " + s.name, num(s.rate, 1) + " Hz",
                             s.age === null ? "never" : num(s.age, 2) + " s",
                             "n " + s.count,
                             s.publishers + " pub" + (s.dropped ? ", " + s.dropped + " dropped" : "")],
          s.topic + "  " + s.type + " (subscription: rate, age of the latest, count, matched publishers)",
          state);
      if (s.pose && !m.pose) m.canvas.hidden = m.caption.hidden = false;
      if (s.pose && m.pose !== s.pose) addPose(m, s.pose);
    }
    for (const p of msg.publications) {
      row(m, "p/" + p.name, ["→ " + p.name, num(p.rate, 1) + " Hz", "", "n " + p.count,
                             p.subscribers + " sub"],
          p.topic + "  " + p.type + " (publication: rate, count, matched subscribers)",
          p.subscribers ? "" : "hv-bad");
    }
    if (m.pose) draw(m);
  }

  function addPose(m, pose) {
    m.pose = pose;
    const last = m.trail[m.trail.length - 1];
    if (!last || Math.hypot(pose.x - last[0], pose.y - last[1]) >= TRAIL_STEP_M) {
      m.trail.push([pose.x, pose.y]);
      if (m.trail.length > TRAIL_MAX) m.trail.splice(0, m.trail.length - TRAIL_MAX);
    }
  }

  function onTrail(msg) {
    const m = maps.get(msg.name);
    if (!m || !Array.isArray(msg.points)) return;
    m.trail = msg.points.slice(-TRAIL_MAX);
  }

  // A scan's points in the odom frame, from the pose it was taken from (the monitor's,
  // else the latest): the laser is taken at the base's centre (no TF is read).
  function onScan(msg) {
    const m = maps.get(msg.name);
    if (!m || !m.pose) return;
    const {x, y, yaw} = msg.pose || m.pose;
    const c = Math.cos(yaw || 0), s = Math.sin(yaw || 0);
    const points = [];
    msg.ranges.forEach((r, i) => {
      if (typeof r !== "number") return;
      const a = msg.angle_min + i * msg.angle_increment;
      const px = r * Math.cos(a), py = r * Math.sin(a);
      points.push([x + c * px - s * py, y + s * px + c * py]);
    });
    for (const p of points) {
      const key = Math.round(p[0] / HIT_CELL_M) + "," + Math.round(p[1] / HIT_CELL_M);
      if (m.hits.size < HITS_MAX) m.hits.set(key, p);
    }
    m.scan = points;
    draw(m);
  }

  function onWorld(msg) {
    const m = maps.get(msg.name);
    if (!m) return;
    m.world = msg;
    if (m.pose) draw(m);
  }

  function bounds(m) {
    const b = {x0: Infinity, y0: Infinity, x1: -Infinity, y1: -Infinity};
    const add = (p) => {
      b.x0 = Math.min(b.x0, p[0]); b.x1 = Math.max(b.x1, p[0]);
      b.y0 = Math.min(b.y0, p[1]); b.y1 = Math.max(b.y1, p[1]);
    };
    if (m.world) {
      for (const w of m.world.walls) w.forEach(add);
      for (const box of m.world.boxes) box.forEach(add);
    }
    if (!m.world || b.x0 === Infinity) {
      m.trail.forEach(add);
      for (const p of m.hits.values()) add(p);
    }
    add([m.pose.x - 1.5, m.pose.y - 1.5]);
    add([m.pose.x + 1.5, m.pose.y + 1.5]);
    return b;
  }

  function draw(m) {
    const cv = m.canvas, ctx = cv.getContext("2d");
    const W = cv.width, H = cv.height, pad = 24;
    const b = bounds(m);
    const k = Math.min((W - 2 * pad) / (b.x1 - b.x0), (H - 2 * pad) / (b.y1 - b.y0));
    const ox = (W - k * (b.x1 - b.x0)) / 2, oy = (H - k * (b.y1 - b.y0)) / 2;
    const X = (x) => ox + (x - b.x0) * k, Y = (y) => H - oy - (y - b.y0) * k;
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, W, H);
    // A grid of metres.
    ctx.strokeStyle = "#eef0f3"; ctx.lineWidth = 1;
    for (let gx = Math.ceil(b.x0); gx <= b.x1; gx++) { ctx.beginPath(); ctx.moveTo(X(gx), 0); ctx.lineTo(X(gx), H); ctx.stroke(); }
    for (let gy = Math.ceil(b.y0); gy <= b.y1; gy++) { ctx.beginPath(); ctx.moveTo(0, Y(gy)); ctx.lineTo(W, Y(gy)); ctx.stroke(); }
    let walls = 0;
    if (m.world) {
      ctx.strokeStyle = "#5a6070"; ctx.lineWidth = 4;
      for (const w of m.world.walls) {
        ctx.beginPath();
        w.forEach((p, i) => (i ? ctx.lineTo(X(p[0]), Y(p[1])) : ctx.moveTo(X(p[0]), Y(p[1]))));
        ctx.stroke();
        walls += w.length - 1;
      }
      ctx.fillStyle = "#b9bfcb";
      for (const box of m.world.boxes) {
        ctx.beginPath();
        box.forEach((p, i) => (i ? ctx.lineTo(X(p[0]), Y(p[1])) : ctx.moveTo(X(p[0]), Y(p[1]))));
        ctx.closePath(); ctx.fill();
      }
    }
    // What past scans saw (the walls appear as the robot drives), then the latest scan.
    ctx.fillStyle = "#90a4c8";
    for (const p of m.hits.values()) ctx.fillRect(X(p[0]) - 1.5, Y(p[1]) - 1.5, 3, 3);
    ctx.strokeStyle = "#1565c0"; ctx.lineWidth = 2.5;
    ctx.beginPath();
    m.trail.forEach((p, i) => (i ? ctx.lineTo(X(p[0]), Y(p[1])) : ctx.moveTo(X(p[0]), Y(p[1]))));
    ctx.stroke();
    ctx.fillStyle = "#d32f2f";
    for (const p of m.scan || []) { ctx.beginPath(); ctx.arc(X(p[0]), Y(p[1]), 3, 0, 2 * Math.PI); ctx.fill(); }
    // The odom frame's origin, where the robot started.
    ctx.strokeStyle = "#667"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(X(0) - 8, Y(0)); ctx.lineTo(X(0) + 8, Y(0));
    ctx.moveTo(X(0), Y(0) - 8); ctx.lineTo(X(0), Y(0) + 8); ctx.stroke();
    // The robot: its disc and its heading.
    const {x, y} = m.pose, yaw = m.pose.yaw || 0, r = Math.max(ROBOT_RADIUS_M * k, 6);
    ctx.fillStyle = "rgba(76, 175, 80, 0.85)"; ctx.strokeStyle = "#1b5e20"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(X(x), Y(y), r, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(X(x), Y(y));
    ctx.lineTo(X(x) + 1.6 * r * Math.cos(yaw), Y(y) - 1.6 * r * Math.sin(yaw)); ctx.stroke();
    // A 1 m scale.
    ctx.strokeStyle = "#1d2330"; ctx.fillStyle = "#1d2330"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(12, H - 12); ctx.lineTo(12 + k, H - 12); ctx.stroke();
    ctx.font = "20px sans-serif"; ctx.fillText("1 m", 16 + k, H - 8);
    Object.assign(cv.dataset, {x: String(x), y: String(y), yaw: String(yaw),
                               trail: String(m.trail.length), scan: String((m.scan || []).length),
                               hits: String(m.hits.size), walls: String(walls)});
    m.caption.textContent = "odom frame: x " + num(x, 2) + " m, y " + num(y, 2) + " m, yaw " +
      num(yaw * 180 / Math.PI, 0) + "°" + (typeof m.pose.v === "number" ? ", " + num(m.pose.v, 2) + " m/s" : "") +
      (m.world ? " · walls of " + m.world.file.split("/").pop() + " (" + m.world.robot + "'s start at the origin)" : "") +
      (m.world && m.world.note ? " · " + m.world.note : "");
  }

  return {show, onRos2, onTrail, onScan, onWorld};
})();
