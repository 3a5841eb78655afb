// The page without a mouse (docs/editor.md, "Keys"): arrows select the nearest state in
// their direction; A draws an arrow from the selected state (arrows or typing pick its
// target, Enter adds it, Escape cancels); E goes to the selection's first field, Escape
// back to the canvas; Enter on a simple state enters it (its first state makes it a
// composite); R adds a region. And a `use`d state opens its file in a tab of its own.
"use strict";

let aim = null;  // drawing an arrow from the keyboard: {from, to, typed}

// A state that can be entered though it has no sub-automaton yet (a simple state).
function enterable(path) {
  const s = model && model.states[path];
  return !!s && s.kind === "state" && !s.use && !s.final && !s.regions;
}

function openTab(path) {
  const key = model.tabs && model.tabs[path];
  if (!key) { say(`${path}: its file is not one this editor can open`, true); return; }
  const link = document.createElement("a");  // (editor.js's open() hides window.open)
  link.href = "/?file=" + encodeURIComponent(key);
  link.target = "_blank";
  link.click();
}

// The shapes of the canvas one can select: the states (or a parallel state's lanes).
function shapes() {
  return [...document.querySelectorAll("#canvas g.state")].map((g) => {
    const r = g.getBoundingClientRect();
    return {path: g.dataset.path, x: r.left + r.width / 2, y: r.top + r.height / 2};
  });
}

// The nearest shape from `path` in the arrow key's direction (the first one from none).
function nearest(path, key) {
  const all = shapes();
  const at = all.find((s) => s.path === path);
  if (!at) return all.length ? all[0].path : null;
  const [dx, dy] = {ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1]}[key];
  let best = null, score = Infinity;
  for (const s of all) {
    const ax = s.x - at.x, ay = s.y - at.y;
    const along = ax * dx + ay * dy;
    if (s.path === path || along <= 0) continue;
    const d = along + 2 * Math.abs(ax * dy - ay * dx);
    if (d < score) { best = s.path; score = d; }
  }
  return best;
}

function aimAt(to) {
  aim.to = to;
  const old = $("rubber");
  if (old) old.remove();
  for (const g of document.querySelectorAll("g.state.target")) g.classList.remove("target");
  const g = document.querySelector(`#canvas g.state[data-path="${CSS.escape(to)}"]`);
  if (g) g.classList.add("target");
  const a = center(aim.from), b = center(to);
  el("path", {id: "rubber", d: aim.from === to ? `M${a[0] - 20},${a[1] - 25} C${a[0] - 30},${a[1] - 80} ${a[0] + 30},${a[1] - 80} ${a[0] + 10},${a[1] - 25}`
    : `M${a[0]},${a[1]} L${b[0]},${b[1]}`, stroke: "#1a55c0", "stroke-dasharray": "4 3", fill: "none",
    "marker-end": "url(#arrow)", "pointer-events": "none"}, $("canvas"));
  say(`arrow from ${baseName(aim.from)} to ${baseName(to)}: arrows or type a name to change, Enter adds it, Escape cancels`, false);
}

function endAim() {
  aim = null;
  const old = $("rubber");
  if (old) old.remove();
  for (const g of document.querySelectorAll("g.state.target")) g.classList.remove("target");
}

// Arrow mode takes every key first (capture), so that N or Del do not act meanwhile.
window.addEventListener("keydown", (ev) => {
  if (!aim || !model) return;
  ev.preventDefault();
  ev.stopPropagation();
  const names = (model.automata[cur] || {states: []}).states;
  if (ev.key === "Escape") { endAim(); say("", false); }
  else if (ev.key === "Enter") {
    const from = aim.from, to = baseName(aim.to);
    endAim();
    say("", false);
    want = {kind: "edge", state: from, index: model.states[from].transitions.length};
    send("add_transition", {state: from, to});
  } else if (ev.key.startsWith("Arrow")) {
    const next = nearest(aim.to, ev.key);
    if (next) aimAt(next);
  } else if (ev.key === "Tab") {
    const i = names.indexOf(baseName(aim.to));
    aimAt(prefix(cur) + names[(i + (ev.shiftKey ? names.length - 1 : 1)) % names.length]);
  } else if (ev.key === "Backspace" || ev.key.length === 1) {
    aim.typed = ev.key === "Backspace" ? aim.typed.slice(0, -1) : aim.typed + ev.key;
    const hit = names.find((n) => n.toLowerCase().startsWith(aim.typed.toLowerCase()));
    if (hit) aimAt(prefix(cur) + hit);
    else say(`no state here starts with "${aim.typed}"`, true);
  }
}, true);

document.addEventListener("keydown", (ev) => {
  if (!model || aim || inEditor(ev) || ev.ctrlKey || ev.metaKey || ev.altKey) return;
  const auto = model.automata[cur];
  if (ev.key.startsWith("Arrow")) {
    ev.preventDefault();
    const from = sel && sel.kind === "state" ? sel.path : sel && sel.kind === "edge" ? sel.state : null;
    const next = nearest(from, ev.key);
    if (next) select({kind: "state", path: next});
  } else if (ev.key.toLowerCase() === "a" && sel && sel.kind === "state" && auto && !auto.regions &&
             !model.read_only) {
    ev.preventDefault();
    aim = {from: sel.path, to: sel.path, typed: ""};
    aimAt(sel.path);
  } else if (ev.key.toLowerCase() === "e" && sel) {
    const first = document.querySelector(sel.kind === "edge" ? '#panel [data-field="when"] .cm-content'
      : "#panel .cm-content, #panel .field input");
    if (first) { ev.preventDefault(); first.focus(); }
  } else if (ev.key.toLowerCase() === "r" && !model.read_only) {
    const at = auto && auto.regions ? cur : sel && sel.kind === "state" ? sel.path : null;
    if (at) { ev.preventDefault(); addRegion(at); }
  } else if (ev.key === "Enter" && sel && sel.kind === "state" && !model.automata[sel.path]) {
    if (enterable(sel.path)) open(sel.path);
    else if (model.states[sel.path] && model.states[sel.path].use) openTab(sel.path);
  } else if (ev.key === "Tab" && auto && auto.states.length) {
    ev.preventDefault();  // Tab cycles through the states of the canvas
    const names = auto.states;
    const i = sel && sel.kind === "state" ? names.indexOf(baseName(sel.path)) : -1;
    select({kind: "state", path: prefix(cur) + names[(i + (ev.shiftKey ? names.length - 1 : 1)) % names.length]});
  }
});

// Escape in the side panel's editors: back to the canvas, the selection kept.
document.addEventListener("keydown", (ev) => {
  if (ev.key === "Escape" && ev.target.closest && ev.target.closest("#panel")) $("canvas").focus();
});
