// A parallel state's canvas (docs/editor.md, "Regions"): its regions drawn as lanes, one
// below the other in their order (the order of ticks, entries and exits), each with its
// period and a sketch of its states (the initial one marked, final ones thick).
// Double-click a lane (or select it, Enter) to enter the region's sub-automaton; a
// state's chip opens the region with that state selected. R adds a region.
"use strict";

const LANE_H = 96, LANE_W = 760, CHIP_W = 104, CHIP_H = 30;

function lanes(svg, auto) {
  const owner = cur;
  const regions = auto.states;
  const timers = (model.settings && model.settings.automata) || {};
  const box = el("g", {id: "lanes"}, svg);
  regions.forEach((name, i) => {
    const path = prefix(owner) + name;
    const y = 20 + i * (LANE_H + 12);
    const g = el("g", {class: "state lane", "data-path": path, transform: `translate(20,${y})`}, box);
    const bad = worst(problemsOf(path, null));
    if (bad) g.classList.add(bad);
    if (sel && sel.kind === "state" && sel.path === path) g.classList.add("selected");
    el("rect", {class: "body", width: LANE_W, height: LANE_H, rx: 6}, g);
    el("rect", {class: "head", width: 120, height: LANE_H, rx: 6}, g);
    el("text", {class: "lane-name", x: 60, y: LANE_H / 2 - 8}, g).textContent = name;
    const t = timers[path] || {};
    el("text", {class: "lane-info", x: 60, y: LANE_H / 2 + 10}, g).textContent =
      (t.period ? t.period : "parent's period") + (t.history === "true" ? ", history" : "");
    const inner = model.automata[path] || {states: [], initial: null};
    const per = Math.max(1, Math.floor((LANE_W - 150) / (CHIP_W + 16)));
    inner.states.forEach((s, j) => {
      const sp = path + "/" + s;
      const info = model.states[sp] || {};
      const x = 140 + (j % per) * (CHIP_W + 16) + 10, cy = j < per ? 14 : 52;
      const c = el("g", {class: "chip", "data-path": sp, transform: `translate(${x},${cy})`}, g);
      if (info.final) c.classList.add("final");
      if (worst(problemsOf(sp, null))) c.classList.add(worst(problemsOf(sp, null)));
      el("rect", {width: CHIP_W, height: CHIP_H, rx: 9}, c);
      el("text", {x: CHIP_W / 2, y: CHIP_H / 2}, c).textContent = s.length > 13 ? s.slice(0, 12) + "…" : s;
      if (inner.initial === s) el("circle", {class: "initial", cx: -6, cy: CHIP_H / 2, r: 4}, c);
      c.addEventListener("dblclick", (ev) => {
        ev.stopPropagation();
        open(path);
        select({kind: "state", path: sp});
      });
    });
    if (!inner.states.length) el("text", {class: "lane-info empty", x: 150, y: LANE_H / 2}, g)
      .textContent = "no state yet: double-click to enter, then N";
    const tip = el("title", {}, g);
    tip.textContent = problemsOf(path, null).map((d) => `${d.code}: ${d.message}`).join("\n") ||
      `region ${name}: double-click to edit its states`;
    g.addEventListener("mousedown", (ev) => { ev.stopPropagation(); $("canvas").focus(); select({kind: "state", path}); });
    g.addEventListener("dblclick", (ev) => { ev.stopPropagation(); open(path); });
  });
  const h = 40 + regions.length * (LANE_H + 12);
  svg.setAttribute("viewBox", `0 0 ${LANE_W + 40} ${Math.max(400, h)}`);
  svg.style.height = Math.max(400, h) + "px";
}
