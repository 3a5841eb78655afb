// hfsmc edit's page (docs/editor.md): one sub-automaton at a time on an SVG canvas, the
// state tree, CodeMirror editors for snippets and conditions, problems on what they are
// about. The server holds the edit session; this page sends it operations by name.
"use strict";

const SVG = "http://www.w3.org/2000/svg";
const W = 140, H = 50;  // a state's box
const $ = (id) => document.getElementById(id);
let model = null;      // the server's last "model" message
let cur = "";          // the automaton shown: its owner's path ("" the root)
let sel = null;        // {kind: "state", path} | {kind: "edge", state, index}
let ws = null;
let drag = null;       // a state being moved or a transition being drawn
const editors = {};    // field -> {view, key}
let panelFor = null;   // what the side panel was built for
let want = null;       // the selection asked for, made once the server's model has it
const placed = {};     // positions the page gave new states, until the server has them

function send(op, args) {
  if (ws && ws.readyState === 1) ws.send(JSON.stringify({op, args: args || {}}));
}
const prefix = (owner) => (owner ? owner + "/" : "");
const parentOf = (path) => (path.includes("/") ? path.slice(0, path.lastIndexOf("/")) : "");
const baseName = (path) => path.slice(path.lastIndexOf("/") + 1);
function el(tag, attrs, parent) {
  const e = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}
function problemsOf(state, transition) {
  return (model ? model.diagnostics : []).filter(
    (d) => !d.other && d.state === state && (transition === undefined || d.transition === transition));
}
function worst(list) {
  return list.some((d) => d.severity === "error") ? "error" : list.length ? "warning" : "";
}
function say(text, error) {
  const m = $("message");
  m.hidden = !text;
  m.textContent = text || "";
  m.className = error ? "error" : "";
}

// ----- the connection
function connect() {
  const tab = new URLSearchParams(location.search).get("file");  // a used file's tab
  ws = new WebSocket(`ws://${location.host}/ws` + (tab ? "?file=" + encodeURIComponent(tab) : ""));
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "error") { want = null; say(msg.message, true); return; }
    if (msg.type === "clipboard") { copied(msg); return; }  // editor_clip.js
    if (msg.type !== "model") { EditorLive.take(msg); return; }  // live, run_log, note
    model = msg;
    for (const [p, xy] of Object.entries(placed)) {
      const at = model.positions[p];
      if (!(p in model.states) && !want) delete placed[p];
      else if (at && Math.hypot(at[0] - xy[0], at[1] - xy[1]) < 1) delete placed[p];
    }
    if (want && (want.kind === "state" ? want.path in model.states : model.states[want.state] &&
        model.states[want.state].transitions[want.index])) { sel = want; want = null; }
    if (!(cur in model.automata) && !enterable(cur)) cur = "";
    if (sel && sel.kind === "state" && !(sel.path in model.states)) sel = null;
    if (sel && sel.kind === "edge" && !(model.states[sel.state] &&
        model.states[sel.state].transitions[sel.index])) sel = null;
    if (msg.message) say(msg.message, false);
    else if (msg.layout_problem) say(msg.layout_problem, true);
    render();
  };
  ws.onclose = () => say("the editor's server is gone: start hfsmc edit again", true);
}

// ----- drawing
function render() {
  document.body.dataset.ready = "1";
  $("file").textContent = model.file + (model.read_only ? " (read-only)" : "");
  const st = $("status");
  st.textContent = model.dirty ? "unsaved" : "saved";
  st.className = model.dirty ? "dirty" : "";
  $("undo").disabled = !model.can_undo;
  $("redo").disabled = !model.can_redo;
  $("save").disabled = !model.dirty || model.read_only;
  $("up").disabled = cur === "";
  $("conflict").hidden = !model.conflict;
  $("conflict-text").textContent = model.conflict ?
    `${model.file} changed on disk while you have unsaved edits: not saved over. ` : "";
  crumbs(); tree(); canvas(); panel(); problems();
  EditorLive.paint();
}

function crumbs() {
  const nav = $("crumbs");
  nav.textContent = "";
  const parts = cur ? cur.split("/") : [];
  const add = (label, path) => {
    const a = document.createElement("a");
    a.textContent = label;
    a.dataset.path = path;
    a.onclick = () => open(path);
    nav.appendChild(a);
  };
  add(model.file.replace(/\.[^.]*$/, ""), "");
  parts.forEach((p, i) => add(p, parts.slice(0, i + 1).join("/")));
}

const folded = new Set();  // the composites whose subtree the tree hides (▸), until unfolded

function tree() {
  const root = $("tree");
  root.textContent = "";
  const q = $("search").value.trim().toLowerCase();
  const build = (owner, ul) => {
    for (const name of (model.automata[owner] || {states: []}).states) {
      const path = prefix(owner) + name;
      const li = document.createElement("li");
      const span = document.createElement("span");
      span.textContent = name;
      span.dataset.path = path;
      if (sel && sel.kind === "state" && sel.path === path) span.classList.add("current");
      if (worst(problemsOf(path)) === "error") span.classList.add("bad");
      if (q && !path.toLowerCase().includes(q)) span.classList.add("hidden");
      span.onclick = () => { sel = {kind: "state", path}; open(owner); };
      const inner = model.automata[path];
      if (inner) {  // a composite: ▾ folds its subtree, ▸ unfolds it (a search shows all)
        const fold = document.createElement("b");
        fold.className = "fold";
        fold.dataset.fold = path;
        fold.textContent = folded.has(path) ? "▸" : "▾";
        fold.onclick = () => { folded.has(path) ? folded.delete(path) : folded.add(path); tree(); };
        li.appendChild(fold);
      }
      li.appendChild(span);
      ul.appendChild(li);
      if (inner && (q || !folded.has(path))) {
        const sub = document.createElement("ul");
        li.appendChild(sub);
        build(path, sub);
      }
    }
  };
  build("", root);
}

function center(path) { return placed[path] || model.positions[path] || [80, 80]; }

// Where the segment from the centre of box a towards point p leaves the box.
function border(c, p) {
  const dx = p[0] - c[0], dy = p[1] - c[1];
  if (!dx && !dy) return c;
  const t = Math.min(Math.abs((W / 2) / (dx || 1e-9)), Math.abs((H / 2) / (dy || 1e-9)));
  return [c[0] + dx * t, c[1] + dy * t];
}

function canvas() {
  const svg = $("canvas");
  svg.textContent = "";
  const defs = el("defs", {}, svg);
  const marker = el("marker", {id: "arrow", viewBox: "0 0 10 10", refX: 9, refY: 5,
    markerWidth: 8, markerHeight: 8, orient: "auto-start-reverse"}, defs);
  el("path", {d: "M0,0 L10,5 L0,10 z", fill: "#444"}, marker);
  const auto = model.automata[cur] || (enterable(cur) ? {states: [], initial: null} : null);
  if (!auto) return;
  if (auto.regions) { lanes(svg, auto); return; }  // editor_lanes.js
  const names = auto.states;
  let maxX = 600, maxY = 400;
  const edges = el("g", {id: "edges"}, svg);
  const nodes = el("g", {id: "states"}, svg);
  const labels = el("g", {id: "labels"}, svg);  // above the states: always readable, clickable
  const pairs = {};
  for (const name of names) {
    const path = prefix(cur) + name;
    const s = model.states[path];
    s.transitions.forEach((t, i) => {
      if (!names.includes(t.to)) return;
      const key = [name, t.to].sort().join("\u0000");
      const n = (pairs[key] = (pairs[key] || 0) + 1);
      const back = name !== t.to && model.states[prefix(cur) + t.to].transitions.some((u) => u.to === name);
      drawEdge(edges, labels, path, i, t, center(path), center(prefix(cur) + t.to), n, name === t.to, back);
    });
  }
  for (const name of names) {
    const path = prefix(cur) + name;
    const [x, y] = center(path);
    maxX = Math.max(maxX, x + W); maxY = Math.max(maxY, y + H + 40);
    drawState(nodes, path, model.states[path], x, y, auto.initial === name);
  }
  place(labels, names.map((name) => {
    const [x, y] = center(prefix(cur) + name);
    return {x: x - W / 2, y: y - H / 2, width: W, height: H};
  }));
  const all = labels.getBBox(), minX = Math.min(0, all.x - 4);
  maxX = Math.max(maxX, all.x + all.width + 4);
  svg.setAttribute("viewBox", `${minX} 0 ${maxX - minX} ${maxY}`);
  svg.style.height = Math.max(400, maxY) + "px";
}

// Each arrow's label goes at the middle of its arrow unless it would cover a state or a
// label placed before it: then a little before or after the middle, the first place clear.
function place(labels, boxes) {
  for (const text of labels.querySelectorAll("text")) {
    const k = text.curve;
    if (k) {
      const at = (t) => [0, 1].map((j) => (1 - t) ** 2 * k.p[j] + 2 * (1 - t) * t * k.c[j] + t * t * k.q[j]);
      for (const t of [0.5, 0.38, 0.62, 0.28, 0.72, 0.5]) {
        const [x, y] = at(t);
        text.setAttribute("x", x + 4 * k.side);
        text.setAttribute("y", y);
        if (!boxes.some((o) => overlap(o, text.getBBox()))) break;
      }
    }
    boxes.push(text.getBBox());
  }
}

function overlap(a, b) {
  return a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height && b.y < a.y + a.height;
}

function drawState(g0, path, s, x, y, initial) {
  const g = el("g", {class: "state", "data-path": path, transform: `translate(${x - W / 2},${y - H / 2})`}, g0);
  const bad = worst(problemsOf(path, null));
  if (bad) g.classList.add(bad);
  if (s.final) g.classList.add("final");
  if (s.composite || s.use) g.classList.add("composite");
  if (sel && sel.kind === "state" && sel.path === path) g.classList.add("selected");
  el("rect", {class: "body", width: W, height: H, rx: 14}, g);
  if (s.composite || s.use) el("rect", {class: "inner", x: 4, y: 4, width: W - 8, height: H - 8, rx: 10}, g);
  if (s.final) el("circle", {cx: W - 12, cy: 12, r: 4, fill: "#222"}, g);
  const label = el("text", {x: W / 2, y: s.use ? H / 2 - 6 : H / 2}, g);
  label.textContent = s.name;
  if (s.use) el("text", {class: "use", x: W / 2, y: H / 2 + 11}, g).textContent = "use " + baseName(s.use);
  if (initial) {
    el("circle", {class: "initial", cx: -26, cy: H / 2, r: 6}, g);
    el("path", {d: `M-20,${H / 2} L-2,${H / 2}`, stroke: "#222", "marker-end": "url(#arrow)"}, g);
  }
  const handle = el("circle", {class: "handle", cx: W, cy: H / 2, r: 6}, g);
  const tip = el("title", {}, g);
  tip.textContent = problemsOf(path, null).map((d) => `${d.code}: ${d.message}`).join("\n") || s.name;
  g.addEventListener("mousedown", (ev) => startDrag(ev, path, ev.target === handle || ev.shiftKey));
  g.addEventListener("dblclick", (ev) => {
    ev.stopPropagation();
    if (s.composite && !s.use) open(path);
    else if (s.use) openTab(path);  // editor_keys.js
  });
}

// back: an arrow also goes the other way between the two states; the two curves bulge to
// opposite sides, and the label of the one bulging left is written leftwards, off the other.
function drawEdge(g0, labels, state, i, t, a, b, n, self, back) {
  const g = el("g", {class: "edge", "data-state": state, "data-index": i}, g0);
  const lg = el("g", {class: "edge", "data-state": state, "data-index": i}, labels);
  const bad = worst(problemsOf(state, i));
  const chosen = sel && sel.kind === "edge" && sel.state === state && sel.index === i;
  for (const x of [g, lg]) {
    if (bad) x.classList.add(bad);
    if (chosen) x.classList.add("selected");
  }
  let d, lx, ly, side = 1;  // side: the label runs right (1) or left (-1) of its point
  let cx, cy, p, q;  // the curve of an arrow between two states
  if (self) {
    const x = a[0] + W / 2 - 10 * n, y = a[1] - H / 2;
    d = `M${x - 20},${y} C${x - 30},${y - 50 - 12 * n} ${x + 30},${y - 50 - 12 * n} ${x + 10},${y}`;
    lx = x - 10; ly = y - 42 - 12 * n;
  } else {
    const bend = (n - 1) * 28 + 14;
    const mx = (a[0] + b[0]) / 2, my = (a[1] + b[1]) / 2;
    const len = Math.hypot(b[0] - a[0], b[1] - a[1]) || 1;
    cx = mx - (b[1] - a[1]) / len * bend; cy = my + (b[0] - a[0]) / len * bend;
    p = border(a, [cx, cy]); q = border(b, [cx, cy]);
    d = `M${p[0]},${p[1]} Q${cx},${cy} ${q[0]},${q[1]}`;
    lx = (p[0] + 2 * cx + q[0]) / 4; ly = (p[1] + 2 * cy + q[1]) / 4;
    if (back && cx < mx - 1) side = -1;
  }
  el("path", {class: "line", d, "marker-end": "url(#arrow)"}, g);
  el("path", {class: "hit", d}, g);
  const guard = t.when ? `[${t.when}]` : t.after ? `after ${t.after}` : "";
  const label = el("text", {x: lx + 4 * side, y: ly, "text-anchor": side < 0 ? "end" : "start"}, lg);
  if (!self) label.curve = {p, c: [cx, cy], q, side};  // where along its arrow it may go (place())
  label.textContent = `${i + 1}. ${t.name ? t.name + " " : ""}${guard}`.slice(0, 60);
  const tip = el("title", {}, g);
  tip.textContent = problemsOf(state, i).map((x) => `${x.code}: ${x.message}`).join("\n") ||
    `${baseName(state)} → ${t.to} ${guard}`;
  for (const x of [g, lg]) {
    x.addEventListener("mousedown", (ev) => { ev.stopPropagation(); select({kind: "edge", state, index: i}); });
  }
}

function svgPoint(ev) {
  const svg = $("canvas");
  const pt = svg.createSVGPoint();
  pt.x = ev.clientX; pt.y = ev.clientY;
  const p = pt.matrixTransform(svg.getScreenCTM().inverse());
  return [p.x, p.y];
}

function startDrag(ev, path, connecting) {
  ev.preventDefault();
  ev.stopPropagation();
  $("canvas").focus();
  sel = {kind: "state", path};  // drawn when the button is released (the shapes stay meanwhile)
  delete placed[path];  // the drag's position is the one that counts now
  drag = {path, connecting, from: svgPoint(ev), moved: false, line: null};
  if (connecting) {
    const c = center(path);
    drag.line = el("path", {d: `M${c[0]},${c[1]}`, stroke: "#1a55c0", "stroke-dasharray": "4 3",
      "marker-end": "url(#arrow)", id: "rubber", "pointer-events": "none"}, $("canvas"));
  }
}

document.addEventListener("mousemove", (ev) => {
  if (!drag) return;
  const p = svgPoint(ev);
  const c = center(drag.path);
  if (drag.connecting) {
    drag.line.setAttribute("d", `M${c[0]},${c[1]} L${p[0]},${p[1]}`);
    return;
  }
  const dx = p[0] - drag.from[0], dy = p[1] - drag.from[1];
  if (!drag.moved && Math.hypot(dx, dy) < 3) return;
  drag.moved = true;
  drag.from = p;
  model.positions[drag.path] = [c[0] + dx, c[1] + dy];
  canvas();
});

document.addEventListener("mouseup", (ev) => {
  if (!drag) return;
  const d = drag;
  drag = null;
  marks();
  if (d.connecting) {
    d.line.remove();
    const g = ev.target.closest && ev.target.closest("g.state");
    if (g) send("add_transition", {state: d.path, to: baseName(g.dataset.path)});
  } else if (d.moved) {
    const [x, y] = model.positions[d.path];
    send("move", {state: d.path, x, y});
  }
});

// ----- navigation, selection
function open(path) {
  if (!(path in model.automata) && !enterable(path)) return;
  cur = path;
  render();
}
function select(what) {
  sel = what;
  marks();
}
// The selection shown without drawing again (a double-click's two clicks hit the same shapes).
function marks() {
  for (const g of document.querySelectorAll("g.state")) {
    g.classList.toggle("selected", !!sel && sel.kind === "state" && sel.path === g.dataset.path);
  }
  for (const g of document.querySelectorAll("g.edge")) {
    g.classList.toggle("selected", !!sel && sel.kind === "edge" && sel.state === g.dataset.state &&
      sel.index === Number(g.dataset.index));
  }
  for (const s of document.querySelectorAll("#tree span")) {
    s.classList.toggle("current", !!sel && sel.kind === "state" && sel.path === s.dataset.path);
  }
  panel();
}

$("canvas").addEventListener("mousedown", (ev) => {
  if (ev.target === $("canvas")) select(null);
});
$("canvas").addEventListener("dblclick", (ev) => {
  if (ev.target.closest("g.state") || ev.target.closest("g.edge") || model.read_only) return;
  const p = svgPoint(ev);
  ask(ev.clientX, ev.clientY, "", (name) => {
    send("add_state", {parent: cur, name});
    send("move", {state: prefix(cur) + name, x: p[0], y: p[1]});
    placed[prefix(cur) + name] = [p[0], p[1]];
    want = {kind: "state", path: prefix(cur) + name};
  });
});

// The inline name box, for a new state and a rename.
function ask(clientX, clientY, value, done) {
  const box = $("inline");
  const r = $("canvas-box").getBoundingClientRect();
  box.style.left = (clientX - r.left - 70) + "px";
  box.style.top = (clientY - r.top - 12) + "px";
  box.value = value;
  box.hidden = false;
  box.focus();
  box.select();
  box.onkeydown = (ev) => {
    if (ev.key === "Enter" && box.value.trim()) { box.hidden = true; $("canvas").focus(); done(box.value.trim()); }
    else if (ev.key === "Escape") { box.hidden = true; $("canvas").focus(); }
    ev.stopPropagation();
  };
  box.onblur = () => { box.hidden = true; };
}

function inEditor(ev) {
  return ev.target.closest && (ev.target.closest(".cm-editor") || ["INPUT", "TEXTAREA"].includes(ev.target.tagName));
}
document.addEventListener("keydown", (ev) => {
  if (!model) return;
  const mod = ev.ctrlKey || ev.metaKey;
  if (mod && ev.key.toLowerCase() === "s") { ev.preventDefault(); send("save"); return; }
  if (inEditor(ev)) return;
  if (mod && ev.key.toLowerCase() === "z" && !ev.shiftKey) { ev.preventDefault(); send("undo"); }
  else if (mod && (ev.key.toLowerCase() === "y" || ev.key.toLowerCase() === "z")) { ev.preventDefault(); send("redo"); }
  else if (ev.key === "Delete" && sel) {
    if (sel.kind === "state") send("delete_state", {path: sel.path});
    else send("delete_transition", {state: sel.state, index: sel.index});
  } else if (ev.key === "F2" && sel && sel.kind === "state") {
    ev.preventDefault();
    const g = document.querySelector(`g.state[data-path="${CSS.escape(sel.path)}"]`);
    const r = g.getBoundingClientRect();
    const path = sel.path;
    ask(r.left + r.width / 2, r.top + r.height / 2, baseName(path), (name) => {
      if (name !== baseName(path)) send("rename", {path, new: name});
    });
  } else if (ev.key.toLowerCase() === "n" && !mod && !model.read_only) {
    // a new state from the keyboard: below the lowest one, named in the box
    ev.preventDefault();
    const names = (model.automata[cur] || {states: []}).states;  // [] in a simple state entered
    const y = Math.max(40, ...names.map((n) => center(prefix(cur) + n)[1])) + 90;
    const x = names.length ? center(prefix(cur) + names[names.length - 1])[0] : 120;
    const r = $("canvas").getBoundingClientRect();
    ask(r.left + 120, r.top + 60, "", (name) => {
      send("add_state", {parent: cur, name});
      send("move", {state: prefix(cur) + name, x, y});
      placed[prefix(cur) + name] = [x, y];
      want = {kind: "state", path: prefix(cur) + name};
    });
  } else if (ev.key === "Backspace" && cur) { ev.preventDefault(); open(parentOf(cur)); }
  else if (ev.key === "Enter" && sel && sel.kind === "state" && model.automata[sel.path]) open(sel.path);
});

$("up").onclick = () => open(parentOf(cur));
$("undo").onclick = () => send("undo");
$("redo").onclick = () => send("redo");
$("save").onclick = () => send("save");
$("reload").onclick = () => send("reload");
$("search").oninput = () => tree();
$("search").onkeydown = (ev) => {
  if (ev.key !== "Enter") return;
  const hit = document.querySelector("#tree span:not(.hidden)");
  if (hit) hit.click();
};
window.addEventListener("beforeunload", (ev) => {
  if (model && model.dirty) { ev.preventDefault(); ev.returnValue = ""; }
});

// ----- the side panel: a state's snippets, a transition's fields
function panel() {
  const box = $("panel");
  const key = sel ? JSON.stringify(sel) : "";
  if (key !== panelFor) {
    panelFor = key;
    box.textContent = "";
    for (const k of Object.keys(editors)) {
      if (editors[k].view) editors[k].view.destroy();
      if (editors[k].pending) {  // typed just before another selection: sent now, not lost
        clearTimeout(editors[k].pending);
        editors[k].flush();
      }
      delete editors[k];
    }
    if (!sel) return modelForms(box, true);  // editor_forms.js
    const title = document.createElement("h3");
    box.appendChild(title);
    const at = sel;  // what the fields edit, even when sent after another selection
    if (at.kind === "state" && model.states[at.path].kind === "region") {
      title.textContent = "Region " + at.path + " (double-click it to see its states)";
    } else if (at.kind === "state") {
      title.textContent = "State " + at.path;
      for (const f of ["entry", "during", "exit"]) field(box, f, true,
        (v) => send("set_state_field", {state: at.path, key: f, value: v}));
    } else {
      title.textContent = `Transition ${at.index + 1} of ${at.state}`;
      for (const f of ["name", "to", "when", "after", "do"]) field(box, f, f === "when" || f === "do",
        (v) => send("set_transition_field", {state: at.state, index: at.index, key: f, value: v}));
      const row = document.createElement("p");
      for (const [label, to] of [["Earlier", -1], ["Later", 1]]) {
        const b = document.createElement("button");
        b.textContent = label;
        b.onclick = () => {
          const n = model.states[at.state].transitions.length;
          if (at.index + to < 0 || at.index + to >= n) return;
          send("move_transition", {state: at.state, index: at.index, to: at.index + to});
          sel = {kind: "edge", state: at.state, index: at.index + to};
        };
        row.appendChild(b);
      }
      box.appendChild(row);
    }
  }
  if (!sel) return modelForms(box, false);
  let here = $("here");
  if (!here) {
    here = document.createElement("ul");
    here.id = "here";
    box.appendChild(here);
  }
  here.textContent = "";
  for (const d of sel.kind === "state" ? problemsOf(sel.path, null) : problemsOf(sel.state, sel.index)) {
    const li = document.createElement("li");
    li.className = d.severity;
    li.textContent = `${d.code} line ${d.line}: ${d.message}` + (d.notes.length ? ` (${d.notes.join("; ")})` : "");
    here.appendChild(li);
  }
  const data = sel.kind === "state" ? model.states[sel.path] :
    model.states[sel.state].transitions[sel.index];
  for (const [f, ed] of Object.entries(editors)) {
    const value = data[f] || "";
    if (ed.view) {
      if (!ed.view.hasFocus && ed.view.state.doc.toString() !== value && !ed.pending) {
        ed.quiet = true;
        ed.view.dispatch({changes: {from: 0, to: ed.view.state.doc.length, insert: value}});
        ed.quiet = false;
      }
    } else if (document.activeElement !== ed.input && !ed.pending) ed.input.value = value;
  }
  EditorLive.lint(editors, sel);
}

function field(box, f, code, change) {
  const div = document.createElement("div");
  div.className = "field";
  div.dataset.field = f;
  const label = document.createElement("label");
  label.textContent = f;
  div.appendChild(label);
  box.appendChild(div);
  const ed = {pending: null};
  const later = (v) => {
    clearTimeout(ed.pending);
    ed.flush = () => { ed.pending = null; change(v); };
    ed.pending = setTimeout(ed.flush, 300);
  };
  if (code && window.CM) {
    const lang = model.language === "cpp" ? CM.cpp() : CM.python();
    ed.view = new CM.EditorView({parent: div, state: CM.EditorState.create({doc: "",
      extensions: [CM.basicSetup, lang, ...EditorLive.extensions(), CM.EditorView.updateListener.of((u) => {
        if (u.docChanged && !ed.quiet) later(u.state.doc.toString());
      })]})});
  } else {
    ed.input = document.createElement("input");
    ed.input.oninput = () => later(ed.input.value);
    div.appendChild(ed.input);
  }
  editors[f] = ed;
}

function problems() {
  const ul = $("problems");
  ul.textContent = "";
  for (const d of model.diagnostics) {
    const li = document.createElement("li");
    li.className = d.severity;
    const where = d.other ? baseName(d.file) : (d.state || model.file) +
      (d.transition !== null && d.transition !== undefined ? ` → ${d.transition + 1}` : "");
    li.textContent = `${d.code} ${where}: ${d.message}`;
    li.onclick = () => {
      if (d.other || !d.state) return;
      cur = model.states[d.state] ? model.states[d.state].parent : "";
      select(d.transition !== null ? {kind: "edge", state: d.state, index: d.transition} :
        {kind: "state", path: d.state});
    };
    ul.appendChild(li);
  }
  if (!model.diagnostics.length) ul.innerHTML = "<li>none</li>";
}

document.addEventListener("DOMContentLoaded", connect);  // after editor_*.js
