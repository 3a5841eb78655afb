// hfsmc view --web: the page. It draws what the server's bridge says (docs/web.md):
// a "model" (structure and SVG), a "state" (everything, on connect), then "delta"s
// and "status"es. What is active is decided by the bridge; this page only shows it.
"use strict";

(function () {
  const FIRED_MS = 1500;      // how long the transition just taken stays highlighted
  const RETRY_MAX_MS = 5000;  // the page's own reconnection to the web view server
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
  let socket = null;

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
    if (dirty.active) showActive(dirty.focus, dirty.full);
    if (dirty.transitions) showTransitions();
    if (dirty.logs) showLogs();
    if (dirty.variables) updateVariables(dirty.changed);
    if (dirty.fired.length) fired(dirty.fired);
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

  // -- the model: the picture and the tree ---------------------------------------------
  function showModel(msg) {
    view.structure = msg.structure || {states: [], variables: [], automata: []};
    $("hv-name").textContent = view.structure.name || "component";
    document.title = (view.structure.name || "component") + " · hfsmc view";
    $("hv-autofocus").checked = msg.autofocus !== false;
    view.regionsOf = new Map();
    for (const a of view.structure.automata || []) {
      if (!a.region) continue;
      if (!view.regionsOf.has(a.owner)) view.regionsOf.set(a.owner, []);
      view.regionsOf.get(a.owner).push(a.owner + "/" + a.region);
    }
    view.composites = new Set(view.structure.states.filter((st) => st.composite).map((st) => st.path));
    for (const paths of view.regionsOf.values()) for (const p of paths) view.composites.add(p);
    view.order = new Map(view.structure.states.map((s, i) => [s.path, i]));
    view.pictures = new Map([["", msg.svg]]);
    view.tab = "";
    view.problem = msg.problem;
    drawPicture(msg.svg, msg.problem);
    showTabs();
    buildTree();
    showActive(true, true);
    view.replay = msg.replay || null;
    $("hv-replay").hidden = !view.replay;
    if (view.replay) $("hv-timeline").max = String(view.replay.end);
    showVariablesAll({});
    showFeeds(msg.feeds || {});
    window.hfsmcRos2.show((msg.feeds || {}).ros2 || []);
  }

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
    showActive(true, true);
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

  // -- the tree: fold and unfold composite states -----------------------------------------
  function fold(path) {
    if (view.folded.has(path)) view.folded.delete(path);
    else view.folded.add(path);
    for (const [p, li] of view.rows) {
      const parts = p.split("/");
      let away = false;
      for (let i = 1; i < parts.length; i++) {
        if (view.folded.has(parts.slice(0, i).join("/"))) { away = true; break; }
      }
      li.classList.toggle("hv-folded-away", away);
      const f = li.querySelector(".hv-fold");
      if (f) f.textContent = view.folded.has(p) ? "▸" : "▾";
    }
  }

  // A region's row: [Watch] and its period, above its states; lit with its state.
  function regionRow(path, automaton) {
    const li = el("li", "hv-region");
    li.dataset.path = path;
    li.style.paddingLeft = (4 + 16 * (path.split("/").length - 1)) + "px";
    const f = el("span", "hv-fold", view.folded.has(path) ? "▸" : "▾");
    f.title = "fold or unfold";
    f.addEventListener("click", () => fold(path));
    li.append(f, el("span", "hv-name", "[" + automaton.region + "]"));
    const note = [typeof automaton.period_ms === "number" ? automaton.period_ms + " ms" : "",
                  automaton.history ? "history" : ""].filter((x) => x).join(" ");
    if (note) li.append(el("span", "hv-note", note));
    const open = el("span", "hv-open", "open");
    open.title = "draw this region alone";
    open.addEventListener("click", () => openSub(path));
    li.append(open);
    li._hvTime = li.appendChild(el("span", "hv-time"));
    return li;
  }

  function buildTree() {
    const tree = $("hv-tree");
    tree.replaceChildren();
    view.rows.clear();
    const automata = view.structure.automata || [];
    // A sub-automaton's period under its path: the owner's, or OWNER/REGION for a region.
    const periods = new Map(automata.map((a) => [a.region ? a.owner + "/" + a.region : a.owner, a.period_ms]));
    const regions = new Map(automata.filter((a) => a.region).map((a) => [a.owner + "/" + a.region, a]));
    // A state whose sub-automaton is used from another file -> that file, as written.
    const uses = new Map(automata.filter((a) => a.use && !a.region).map((a) => [a.owner, String(a.use)]));
    for (const st of view.structure.states || []) {
      // The regions a state is the first of: their rows come first, outermost first.
      const parts = st.path.split("/");
      for (let i = 2; i < parts.length; i++) {
        const r = parts.slice(0, i).join("/");
        if (regions.has(r) && !view.rows.has(r)) {
          const li = regionRow(r, regions.get(r));
          tree.appendChild(li);
          view.rows.set(r, li);
        }
      }
      const depth = st.path.split("/").length - 1;
      const li = el("li");
      li.dataset.path = st.path;
      li.style.paddingLeft = (4 + 16 * depth) + "px";
      if (st.final) li.classList.add("hv-final");
      const composite = view.composites.has(st.path);
      const f = el("span", "hv-fold", composite ? (view.folded.has(st.path) ? "▸" : "▾") : "");
      if (composite) {
        f.title = "fold or unfold";
        f.addEventListener("click", () => fold(st.path));
      }
      li.append(f, el("span", "hv-mark"), el("span", "hv-name", st.path.split("/").pop()));
      if (uses.has(st.path)) {
        const use = el("span", "hv-use", "· " + uses.get(st.path));
        use.title = "its sub-automaton is used from " + uses.get(st.path);
        li.append(use);
      }
      if (view.regionsOf.has(st.path)) li.append(el("span", "hv-note", "‖ " + view.regionsOf.get(st.path).length + " regions"));
      if (st.composite && periods.has(st.path)) {
        li.append(el("span", "hv-note", periods.get(st.path) + " ms"));
      }
      if (composite) {
        const open = el("span", "hv-open", "open");
        open.title = "draw its sub-automaton alone";
        open.addEventListener("click", () => openSub(st.path));
        li.append(open);
      }
      li._hvTime = li.appendChild(el("span", "hv-time"));
      tree.appendChild(li);
      view.rows.set(st.path, li);
    }
    view.folded = new Set([...view.folded].filter((p) => view.composites.has(p)));
    if (view.folded.size) { const p = [...view.folded][0]; view.folded.delete(p); fold(p); }
  }

  // -- what is active ------------------------------------------------------------------
  // Touch only the elements and rows whose state changed since the last pass; `full`
  // after a new drawing or tree, whose elements know nothing yet.
  function showActive(focus, full) {
    const mark = (path, on) => {
      const g = view.elements.get(path);
      if (g && !g.classList.contains("edge")) g.classList.toggle("hv-active", on);
      const li = view.rows.get(path);
      if (li) {
        li.classList.toggle("hv-active", on);
        if (!on) li._hvTime.textContent = "";
      }
      // A parallel state's regions are active with it: every one lit at once.
      for (const r of view.regionsOf.get(path) || []) {
        const rg = view.elements.get(r);
        if (rg) rg.classList.toggle("hv-active", on);
        const rli = view.rows.get(r);
        if (rli) rli.classList.toggle("hv-active", on);
      }
    };
    if (full) {
      for (const g of view.elements.values()) g.classList.remove("hv-active");
      for (const li of view.rows.values()) { li.classList.remove("hv-active"); li._hvTime.textContent = ""; }
      view.shown.clear();
    }
    for (const path of view.shown) {
      if (!view.active.has(path)) { mark(path, false); view.shown.delete(path); }
    }
    for (const path of view.active.keys()) {
      if (!view.shown.has(path)) { mark(path, true); view.shown.add(path); }
    }
    tick();
    if (focus && $("hv-autofocus").checked) autofocus();
  }

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

  // -- the lists beside the picture -----------------------------------------------------
  function showVariablesAll(changed) {
    const body = $("hv-vars").tBodies[0];
    body.replaceChildren();
    if (view.replay && !view.replay.variables) {
      const tr = el("tr", "hv-hint");
      const td = el("td", "", "the trace has no variable records: no variables in replay");
      td.colSpan = 2;
      tr.appendChild(td);
      body.appendChild(tr);
    }
    const names = (view.structure && view.structure.variables) || [];
    const all = [...names, ...Object.keys(view.variables).filter((n) => !names.includes(n))];
    view.varRows.clear();
    for (const name of all) {
      const tr = el("tr");
      tr.dataset.name = name;
      if (name in changed) tr.classList.add("hv-changed");
      const value = el("td", "", name in view.variables ? view.variables[name] : "–");
      tr.append(el("td", "", name), value);
      body.appendChild(tr);
      view.varRows.set(name, value);
    }
  }

  // The same names as drawn: only the values that changed are written.
  function updateVariables(changed) {
    const names = (view.structure && view.structure.variables) || [];
    const all = [...names, ...Object.keys(view.variables).filter((n) => !names.includes(n))];
    if (all.length !== view.varRows.size || !all.every((n) => view.varRows.has(n))) {
      showVariablesAll(changed);
      return;
    }
    for (const [name, cell] of view.varRows) {
      const on = name in changed;
      if (on) cell.textContent = name in view.variables ? view.variables[name] : "–";
      cell.parentNode.classList.toggle("hv-changed", on);
    }
  }

  function showTransitions() {
    const list = $("hv-transitions");
    list.replaceChildren();
    for (const tr of view.transitions.slice().reverse()) {
      const li = el("li");
      li.append(el("span", "hv-t", seconds(tr.t)),
        document.createTextNode(tr.from + " → " + tr.to + (tr.name ? "  (" + tr.name + ")" : "")));
      list.appendChild(li);
    }
  }

  function showLogs() {
    const list = $("hv-logs");
    list.replaceChildren();
    for (const lg of view.logs.slice().reverse()) {
      const li = el("li", lg.error ? "hv-error" : "");
      const where = lg.state ? "[" + lg.state + "] " : "";
      li.append(el("span", "hv-t", seconds(lg.t)),
        document.createTextNode(where + (lg.error ? "error in " + lg.error : lg.msg)));
      list.appendChild(li);
    }
  }

  function showStatus(status, note) {
    view.status = status;
    document.body.dataset.status = status;
    $("hv-status").textContent = status;
    const banner = $("hv-banner");
    banner.hidden = status === "connected" || status === "replay";
    banner.textContent = note || "";
  }

  // --clock sim: the time shown is the simulator's, and how fast it runs (null: the real
  // or virtual clock, nothing shown).
  function showRate(rate) {
    view.rate = typeof rate === "number" && isFinite(rate) ? rate : null;
    const r = $("hv-rate");
    r.hidden = view.rate === null;
    r.textContent = view.rate === null ? "" : "simulated, " + view.rate.toFixed(1) + "× real time";
    if (view.rate === null) delete document.body.dataset.simRate;
    else document.body.dataset.simRate = String(view.rate);
  }

  function showOverruns(n) {
    const o = $("hv-overruns");
    if (o.textContent === "overruns " + n) return;
    o.textContent = "overruns " + n;
    o.classList.toggle("hv-some", n > 0);
  }

  // The clock and the times in state run on between messages.
  // -- the vehicle panel and the camera's frames (monitor minor version 1) ---------------
  function showFeeds(feeds) {
    const vehicles = feeds.vehicle || [], cameras = feeds.camera || [];
    const drivers = $("hv-drivers");
    drivers.hidden = (feeds.driver || []).length === 0;
    for (const t of [...drivers.querySelectorAll("table")]) t.remove();
    const vbox = $("hv-vehicles"), cbox = $("hv-cameras");
    vbox.hidden = vehicles.length === 0;
    cbox.hidden = cameras.length === 0;
    for (const t of [...vbox.querySelectorAll("table")]) t.remove();
    for (const f of [...cbox.querySelectorAll("figure")]) f.remove();
    for (const name of vehicles) {
      const table = el("table", "hv-vehicle");
      table.dataset.name = name;
      if (vehicles.length > 1) table.appendChild(el("caption", "", name));
      const body = table.appendChild(el("tbody"));
      for (const [key, label] of [["mode", "mode"], ["armed", "armed"], ["altitude", "altitude"],
                                  ["position", "position"], ["velocity", "velocity"],
                                  ["battery", "battery"], ["link", "link"]]) {
        const tr = el("tr");
        tr.dataset.key = key;
        tr.append(el("th", "", label), el("td", "", "–"));
        body.appendChild(tr);
      }
      vbox.appendChild(table);
    }
    for (const name of cameras) {
      const fig = el("figure", "hv-camera");
      fig.dataset.name = name;
      const img = el("img");
      img.alt = "the latest frame of " + name;
      fig.append(img, el("figcaption", "", name + ": no frame yet (a snippet has not read one)"));
      cbox.appendChild(fig);
    }
  }

  function fixed(x, digits) { return typeof x === "number" ? x.toFixed(digits) : "–"; }
  function onVehicle(msg) {
    const table = [...document.querySelectorAll("#hv-vehicles table")].find((t) => t.dataset.name === msg.name);
    if (!table) return;
    const cell = (key) => table.querySelector('tr[data-key="' + key + '"] td');
    const three = (v, unit) => v ? "N " + fixed(v[0], 2) + "  E " + fixed(v[1], 2) + "  D " + fixed(v[2], 2) + " " + unit : "–";
    cell("mode").textContent = msg.mode || "–";
    cell("armed").textContent = msg.armed ? "ARMED" : "disarmed";
    cell("armed").className = msg.armed ? "hv-armed" : "";
    cell("altitude").textContent = typeof msg.altitude === "number" ? fixed(msg.altitude, 2) + " m" : "–";
    cell("altitude").dataset.value = typeof msg.altitude === "number" ? String(msg.altitude) : "";
    cell("position").textContent = three(msg.position, "m");
    cell("velocity").textContent = three(msg.velocity, "m/s");
    cell("battery").textContent = typeof msg.battery === "number" ? msg.battery + " %" : "–";
    const age = typeof msg.link_age === "number" ? fixed(msg.link_age, 1) + " s ago" : "never";
    cell("link").textContent = msg.connected ? "heartbeat " + age : "lost (heartbeat " + age + ")";
    cell("link").className = msg.connected ? "" : "hv-lost";
  }

  // A user driver's snapshot (monitor minor 4): one small table per interface, its
  // fields in the declaration's order; text only (textContent), whatever the driver says.
  function onDriver(msg) {
    if (!Array.isArray(msg.fields)) return;
    const box = $("hv-drivers");
    let table = [...box.querySelectorAll("table")].find((t) => t.dataset.name === msg.name);
    if (!table) {
      table = el("table", "hv-driver");
      table.dataset.name = msg.name;
      table.appendChild(el("caption", "", ""));
      table.appendChild(el("tbody"));
      box.appendChild(table);
      box.hidden = false;
    }
    table.querySelector("caption").textContent =
      msg.kind + " " + msg.name + (msg.live === false ? " (playback)" : "");
    const body = table.querySelector("tbody");
    const rows = new Map([...body.querySelectorAll("tr")].map((tr) => [tr.dataset.key, tr]));
    for (const f of msg.fields) {
      let tr = rows.get(f.name);
      if (!tr) {
        tr = el("tr");
        tr.dataset.key = f.name;
        tr.append(el("th", "", f.name), el("td", "", ""));
        body.appendChild(tr);
        rows.set(f.name, tr);
      }
      const v = f.value;
      tr.querySelector("td").textContent = v === null || v === undefined ? "–"
        : typeof v === "number" ? String(Number(v.toPrecision(6))) : String(v);
    }
  }

  function onFrame(msg) {
    const fig = [...document.querySelectorAll("#hv-cameras figure")].find((f) => f.dataset.name === msg.name);
    if (!fig || typeof msg.jpeg !== "string") return;
    fig.querySelector("img").src = "data:image/jpeg;base64," + msg.jpeg;
    fig.dataset.t = String(msg.t);
    fig.querySelector("figcaption").textContent =
      msg.name + ": t " + seconds(msg.t) + " s, " + msg.width + "×" + msg.height;
  }

  function tick() {
    const t = now();
    $("hv-clock").textContent = "t " + seconds(t) + " s";
    for (const [path, since] of view.active) {
      const li = view.rows.get(path);
      if (li) li._hvTime.textContent = seconds(Math.max(t - since, 0)) + " s";
    }
    if (view.lit.size) unlight();
  }

  // -- messages ------------------------------------------------------------------------
  function onState(msg) {
    setTime(msg.t);
    view.active = new Map(msg.active.map((a) => [a.state, a.since]));
    view.variables = msg.variables || {};
    view.transitions = msg.transitions || [];
    view.logs = msg.logs || [];
    view.stopped = !!msg.stop;
    showStatus(msg.status, msg.note);
    showOverruns(msg.overruns || 0);
    showRate(msg.sim_rate);
    showActive(true);
    showVariablesAll({});
    showTransitions();
    showLogs();
    if (msg.replay) onReplay(msg.replay);
  }

  // A replay's position, playing or not, and speed: the bridge's, shared by every page.
  function onReplay(r) {
    view.playing = !!r.playing;
    $("hv-play").textContent = r.playing ? "pause" : "play";
    const line = $("hv-timeline");
    line.max = String(r.end);
    if (document.activeElement !== line || r.playing) line.value = String(r.t);
    $("hv-position").textContent = seconds(r.t) + " / " + seconds(r.end) + " s";
    document.body.dataset.position = String(r.t);
    const speed = $("hv-speed");
    if (document.activeElement !== speed && Number(speed.value) !== r.speed) {
      if (![...speed.options].some((o) => Number(o.value) === r.speed)) {
        speed.appendChild(el("option", "", r.speed + "×")).value = String(r.speed);
      }
      speed.value = String(r.speed);
    }
  }

  function send(command) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(command));
  }

  function onDelta(msg) {
    setTime(msg.t);
    let moved = false;
    for (const path of msg.exit || []) { view.active.delete(path); moved = true; }
    for (const a of msg.enter || []) { view.active.set(a.state, a.since); moved = true; }
    // Keep the active states outermost first, as the structure lists them.
    if (moved && view.structure) {
      const order = view.order;
      view.active = new Map([...view.active].sort((a, b) =>
        (order.get(a[0]) ?? 1e9) - (order.get(b[0]) ?? 1e9)));
    }
    if (msg.fired) {
      view.transitions = view.transitions.concat(msg.fired).slice(-8);
      dirty.transitions = true;
      dirty.fired = dirty.fired.concat(msg.fired);
    }
    if (msg.logs) {
      view.logs = view.logs.concat(msg.logs).slice(-8);
      dirty.logs = true;
    }
    if (msg.variables) {
      for (const k of Object.keys(msg.variables)) {
        if (view.variables[k] !== msg.variables[k]) dirty.changed[k] = true;
      }
      view.variables = msg.variables;
      dirty.variables = true;
    }
    if ("overruns" in msg) showOverruns(msg.overruns);
    if ("sim_rate" in msg) showRate(msg.sim_rate);
    if ("stop" in msg) view.stopped = !!msg.stop;
    if (moved) { dirty.active = true; dirty.focus = true; }
    later();
  }

  function onMessage(ev) {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    if (!msg || typeof msg !== "object") return;
    if (msg.type === "model") showModel(msg);
    else if (msg.type === "state") onState(msg);
    else if (msg.type === "delta") onDelta(msg);
    else if (msg.type === "replay") onReplay(msg);
    else if (msg.type === "vehicle") onVehicle(msg);
    else if (msg.type === "frame") onFrame(msg);
    else if (msg.type === "ros2") window.hfsmcRos2.onRos2(msg);
    else if (msg.type === "driver") onDriver(msg);
    else if (msg.type === "scan") window.hfsmcRos2.onScan(msg);
    else if (msg.type === "trail") window.hfsmcRos2.onTrail(msg);
    else if (msg.type === "world") window.hfsmcRos2.onWorld(msg);
    else if (msg.type === "status") {
      setTime(msg.t);
      showStatus(msg.status, msg.note);
    }
  }

  let retry = 250;
  function connect() {
    const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
    socket = ws;
    let opened = false;
    ws.onopen = () => { retry = 250; opened = true; };
    ws.onmessage = onMessage;
    ws.onclose = (ev) => {
      showStatus("offline", ev.code === 1008
        ? "this page fell behind and was dropped by the web view; reconnecting"
        : "the web view server is gone; reconnecting");
      setTimeout(connect, retry);
      retry = Math.min(retry * 2, RETRY_MAX_MS);
      // Refused before it opened: a web view started again has a new token (docs/web.md, Trust).
      if (!opened) {
        fetch("app.css", {cache: "no-store"}).then((r) => {
          if (r.status === 403) {
            showStatus("offline", "this page's token is not accepted (the web view was started " +
              "again?): open the URL hfsmc view printed");
          }
        }, () => {});
      }
    };
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

  window.addEventListener("DOMContentLoaded", () => {
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
    $("hv-play").addEventListener("click", () => send({do: view.playing ? "pause" : "play"}));
    $("hv-next").addEventListener("click", () => send({do: "next"}));
    $("hv-previous").addEventListener("click", () => send({do: "previous"}));
    $("hv-speed").addEventListener("change", () => send({do: "speed", speed: Number($("hv-speed").value)}));
    $("hv-timeline").addEventListener("input", () => send({do: "seek", t: Number($("hv-timeline").value)}));
    setInterval(tick, 100);
    connect();
  });
})();
