// hfsmc view --web: what the page knows and when it is redrawn. `window.hfsmcView` is
// shared by the page's scripts (index.html loads this one first): the view's data, the
// redraw of at most once per animation frame, the clock, and small text helpers. The
// other scripts add their parts to it: app.js (the connection and the messages),
// diagram.js, states.js, lists.js, status.js, feeds.js, replay.js.
"use strict";

window.hfsmcView = (function () {
  const $ = (id) => document.getElementById(id);

  const view = {
    structure: null,
    elements: new Map(),   // SVG id (state path, PATH#N, ...) -> element
    rows: new Map(),       // state path -> tree row
    active: new Map(),     // active path -> entry time (ms)
    variables: {},
    transitions: [],
    logs: [],
    t: 0,
    tAt: performance.now(),  // when t was received: the clock runs on from it
    rate: null,  // --clock sim: simulated seconds per real second; null on other clocks
    status: "connecting",
    stopped: false,
    whole: null,           // the diagram's own viewBox [x, y, w, h]
    box: null,             // the viewBox shown now
    svg: null,
    pictures: new Map(),   // drawings open as tabs: "" (the whole automaton) or a composite's path -> SVG text
    tab: "",               // the drawing shown
    problem: null,         // why the whole drawing is not the model's
    composites: new Set(), // paths of the composite states and of the regions (each drawable alone)
    regionsOf: new Map(),  // a parallel state's path -> its regions' paths (OWNER/REGION), in order
    folded: new Set(),     // composite states folded in the tree
    dragged: false,        // the last mouse press panned (then it is no click)
    replay: null,          // a replay's trace: {trace, end, fires, variables}
    playing: false,
    order: new Map(),      // state path -> its place in the structure (outermost first)
    shown: new Set(),      // paths drawn active now (the DOM), against view.active (the data)
    lit: new Map(),        // transition elements highlighted now -> when the highlight ends
    varRows: new Map(),    // variable name -> its row's value cell
  };
  const hv = {$, view};

  // -- one DOM pass per animation frame ------------------------------------------------
  // Messages only change `view` and note what is to redraw; the page is redrawn at most
  // once per frame, whatever number of deltas arrived in it (docs/web.md, "Figures").
  const dirty = {active: false, focus: false, full: false, transitions: false, logs: false,
                 variables: false, changed: {}, fired: []};
  let frame = 0, fallback = 0;
  function later() {
    if (frame) return;
    frame = requestAnimationFrame(flush);
    // A hidden tab gets no frames: draw anyway, seldom.
    fallback = setTimeout(flush, 250);
  }
  function flush() {
    if (frame) cancelAnimationFrame(frame);
    clearTimeout(fallback);
    frame = 0;
    if (dirty.active) hv.showActive(dirty.focus, dirty.full);
    if (dirty.transitions) hv.showTransitions();
    if (dirty.logs) hv.showLogs();
    if (dirty.variables) hv.updateVariables(dirty.changed);
    if (dirty.fired.length) hv.fired(dirty.fired);
    Object.assign(dirty, {active: false, focus: false, full: false, transitions: false, logs: false,
                          variables: false, changed: {}, fired: []});
    tick();
  }

  // -- text helpers ------------------------------------------------------------------
  function seconds(ms) { return (ms / 1000).toFixed(3); }
  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function now() {
    if (view.status !== "connected" || view.stopped) return view.t;
    // On the simulator's clock (--clock sim) time runs at its rate, not at the wall clock's.
    return view.t + (performance.now() - view.tAt) * (view.rate === null ? 1 : view.rate);
  }
  function setTime(t) { view.t = t; view.tAt = performance.now(); }

  // The clock and the times in state run on between messages.
  function tick() {
    const t = now();
    $("hv-clock").textContent = "t " + seconds(t) + " s";
    for (const [path, since] of view.active) {
      const li = view.rows.get(path);
      if (li) li._hvTime.textContent = seconds(Math.max(t - since, 0)) + " s";
    }
    if (view.lit.size) hv.unlight();
  }

  return Object.assign(hv, {dirty, later, seconds, el, setTime, tick});
})();
