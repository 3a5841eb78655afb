// hfsmc view --web: the diagram. The SVG drawn by the server, its tabs (a composite
// state's sub-automaton drawn alone), the transitions just taken lit, and the pan, zoom
// and autofocus of the view box. Part of window.hfsmcView (page.js).
"use strict";

(function (hv) {
  const FIRED_MS = 1500;      // how long the transition just taken stays highlighted
  const {$, view, el} = hv;

  // -- the picture ---------------------------------------------------------------------
  function drawPicture(svgText, problem) {
    const pane = $("hv-diagram");
    pane.replaceChildren();
    view.elements.clear();
    view.lit.clear();
    view.svg = null;
    if (problem) pane.appendChild(el("p", "hv-hint", problem));
    if (!svgText) return;
    const doc = new DOMParser().parseFromString(svgText, "image/svg+xml");
    const svg = doc.documentElement;
    if (svg.nodeName !== "svg") {
      pane.appendChild(el("p", "hv-hint", "the diagram could not be read"));
      return;
    }
    svg.removeAttribute("width");
    svg.removeAttribute("height");
    svg.setAttribute("preserveAspectRatio", "xMidYMid meet");
    const node = document.importNode(svg, true);
    pane.appendChild(node);
    view.svg = node;
    // Ids as dot wrote them; the first element of a kind wins (graphviz's own ids such as
    // "graph0" or "a_X" never have the node, cluster or edge class).
    for (const g of node.querySelectorAll("g.node, g.cluster, g.edge")) {
      if (g.id && !view.elements.has(g.id)) view.elements.set(g.id, g);
      if (!g.classList.contains("edge") && view.composites.has(g.id) && g.id !== view.tab) {
        g.classList.add("hv-composite");  // a click opens its sub-automaton
      }
    }
    const vb = (node.getAttribute("viewBox") || "0 0 100 100").split(/[\s,]+/).map(Number);
    view.whole = vb;
    setBox(vb.slice());
  }

  // -- sub-automata: each drawn alone in its own tab, coloured like the whole ---------------
  function showTabs() {
    const nav = $("hv-tabs");
    nav.replaceChildren();
    nav.hidden = view.pictures.size < 2;
    for (const path of view.pictures.keys()) {
      const b = el("button", "hv-tab" + (path === view.tab ? " hv-current" : ""), path || "whole automaton");
      b.type = "button";
      b.dataset.path = path;
      b.addEventListener("click", () => selectTab(path));
      if (path) {
        const x = el("span", "hv-close", "×");
        x.title = "close this sub-automaton";
        x.addEventListener("click", (ev) => { ev.stopPropagation(); closeTab(path); });
        b.appendChild(x);
      }
      nav.appendChild(b);
    }
  }

  function selectTab(path) {
    if (!view.pictures.has(path)) path = "";
    view.tab = path;
    drawPicture(view.pictures.get(path), path ? null : view.problem);
    showTabs();
    hv.showActive(true, true);
  }

  function closeTab(path) {
    view.pictures.delete(path);
    if (view.tab === path) selectTab("");
    else showTabs();
  }

  // Open the composite state's sub-automaton alone (VisualHFSM's "Open Subautomaton"),
  // drawn by the server as `hfsmc diagram --state PATH` draws it.
  async function openSub(path) {
    if (!view.pictures.has(path)) {
      let text = null;
      try {
        const r = await fetch("sub?state=" + encodeURIComponent(path));
        if (r.ok) text = await r.text();
      } catch (e) { text = null; }
      if (text === null) return;
      view.pictures.set(path, text);
    }
    selectTab(path);
  }

  function clicked(ev) {
    if (view.dragged) return;
    const g = ev.target.closest && ev.target.closest("g.hv-composite");
    if (g) openSub(g.id);
  }

  // -- the transitions just taken -------------------------------------------------------
  // The highlight is a plain style (no animation), so taking a transition again only
  // pushes its end back; the clock's pass (tick) ends the highlights that are due.
  function fired(list) {
    const until = performance.now() + FIRED_MS;
    for (const tr of list) {
      const id = tr.from + "#" + tr.index;
      for (const key of [id, id + ":head", id + ":label"]) {
        const g = view.elements.get(key);
        if (!g) continue;
        if (!view.lit.has(g)) g.classList.add("hv-fired");
        view.lit.set(g, until);
      }
    }
  }

  function unlight() {
    const t = performance.now();
    for (const [g, until] of view.lit) {
      if (until <= t) { g.classList.remove("hv-fired"); view.lit.delete(g); }
    }
  }

  // -- pan, zoom and autofocus -----------------------------------------------------------
  function setBox(b) {
    view.box = b;
    if (view.svg) view.svg.setAttribute("viewBox", b.map((x) => x.toFixed(2)).join(" "));
  }

  // A client point in the SVG's viewBox coordinates.
  function toSvg(x, y) {
    const p = view.svg.createSVGPoint();
    p.x = x; p.y = y;
    return p.matrixTransform(view.svg.getScreenCTM().inverse());
  }

  function manual() { $("hv-autofocus").checked = false; }

  function zoom(ev) {
    if (!view.svg) return;
    ev.preventDefault();
    const f = Math.exp(Math.max(-1, Math.min(1, ev.deltaY / 300)));
    const p = toSvg(ev.clientX, ev.clientY);
    const [x, y, w, h] = view.box;
    const nw = Math.min(Math.max(w * f, view.whole[2] / 50), view.whole[2] * 4);
    const k = nw / w;
    setBox([p.x - (p.x - x) * k, p.y - (p.y - y) * k, w * k, h * k]);
    manual();
  }

  let drag = null;
  function down(ev) {
    if (!view.svg || ev.button !== 0) return;
    drag = {x: ev.clientX, y: ev.clientY, box: view.box.slice(), moved: false};
    $("hv-diagram").classList.add("hv-dragging");
  }
  function move(ev) {
    if (!drag) return;
    const r = view.svg.getBoundingClientRect();
    const scale = Math.max(drag.box[2] / r.width, drag.box[3] / r.height);
    const dx = (ev.clientX - drag.x) * scale, dy = (ev.clientY - drag.y) * scale;
    if (Math.abs(dx) + Math.abs(dy) > 0) drag.moved = true;
    setBox([drag.box[0] - dx, drag.box[1] - dy, drag.box[2], drag.box[3]]);
    if (drag.moved) manual();
  }
  function up() {
    view.dragged = !!(drag && drag.moved);
    drag = null;
    $("hv-diagram").classList.remove("hv-dragging");
  }

  // Keep the deepest active states in view (one per region: the innermost drawn active
  // states): pan to them when they are (partly) outside, and zoom out when they do not fit.
  function autofocus() {
    if (!view.svg || !view.active.size) return;
    const drawn = [...view.active.keys()].filter((p) => view.elements.has(p));
    const deepest = drawn.filter((p) => !drawn.some((q) => q.startsWith(p + "/")));
    let a = null, b = null;
    for (const path of deepest) {
      const box = svgBox(view.elements.get(path));
      if (!box) continue;
      a = a ? {x: Math.min(a.x, box[0].x), y: Math.min(a.y, box[0].y)} : box[0];
      b = b ? {x: Math.max(b.x, box[1].x), y: Math.max(b.y, box[1].y)} : box[1];
    }
    if (!a || !b) return;
    const [x, y, w, h] = view.box;
    const m = Math.min(Math.max(b.x - a.x, b.y - a.y) * 0.25, Math.min(w, h) * 0.05);
    const inside = a.x - m >= x && a.y - m >= y && b.x + m <= x + w && b.y + m <= y + h;
    if (inside) return;
    const k = Math.max(1, (b.x - a.x + 2 * m) / w, (b.y - a.y + 2 * m) / h);
    const nw = w * k, nh = h * k;
    setBox([(a.x + b.x) / 2 - nw / 2, (a.y + b.y) / 2 - nh / 2, nw, nh]);
  }

  // An element's box in the drawing's own (viewBox) coordinates. Those never change for
  // a drawing, so each element is measured once (one layout) and remembered: following
  // the active state then reads no layout at all.
  function svgBox(g) {
    if (g._hvBox) return g._hvBox;
    const r = g.getBoundingClientRect();
    if (!r.width && !r.height) return null;
    const a = toSvg(r.left, r.top), b = toSvg(r.right, r.bottom);
    g._hvBox = [{x: a.x, y: a.y}, {x: b.x, y: b.y}];
    return g._hvBox;
  }

  function fit() {
    if (view.whole) setBox(view.whole.slice());
  }

  // The diagram's own controls (the page's start, in app.js, calls this once).
  function startDiagram() {
    const pane = $("hv-diagram");
    pane.addEventListener("wheel", zoom, {passive: false});
    pane.addEventListener("mousedown", down);
    pane.addEventListener("click", clicked);
    window.addEventListener("mousemove", move);
    window.addEventListener("mouseup", up);
    $("hv-fit").addEventListener("click", () => { fit(); manual(); });
    $("hv-autofocus").addEventListener("change", () => {
      if ($("hv-autofocus").checked) autofocus();
    });
  }

  Object.assign(hv, {drawPicture, showTabs, openSub, fired, unlight, autofocus, startDiagram});
})(window.hfsmcView);
