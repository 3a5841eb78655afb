// hfsmc view --web: the page's connection and its messages. It draws what the server's
// bridge says (docs/web.md): a "model" (structure and SVG), a "state" (everything, on
// connect), then "delta"s and "status"es. What is active is decided by the bridge; this
// page only shows it. The parts it hands the messages to are in window.hfsmcView
// (page.js, loaded first; index.html loads this one last) and window.hfsmcRos2 (ros2.js).
"use strict";

(function (hv) {
  const RETRY_MAX_MS = 5000;  // the page's own reconnection to the web view server
  const {$, view, dirty, setTime} = hv;
  let socket = null;

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
    hv.drawPicture(msg.svg, msg.problem);
    hv.showTabs();
    hv.buildTree();
    hv.showActive(true, true);
    view.replay = msg.replay || null;
    $("hv-replay").hidden = !view.replay;
    if (view.replay) $("hv-timeline").max = String(view.replay.end);
    hv.showVariablesAll({});
    hv.showFeeds(msg.feeds || {});
    window.hfsmcRos2.show((msg.feeds || {}).ros2 || []);
  }

  // -- messages ------------------------------------------------------------------------
  function onState(msg) {
    setTime(msg.t);
    view.active = new Map(msg.active.map((a) => [a.state, a.since]));
    view.variables = msg.variables || {};
    view.transitions = msg.transitions || [];
    view.logs = msg.logs || [];
    view.stopped = !!msg.stop;
    hv.showStatus(msg.status, msg.note);
    hv.showOverruns(msg.overruns || 0);
    hv.showRate(msg.sim_rate);
    hv.showActive(true);
    hv.showVariablesAll({});
    hv.showTransitions();
    hv.showLogs();
    if (msg.replay) hv.onReplay(msg.replay);
  }

  // A replay's commands (replay.js); the server throws away whatever else a page sends.
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
    if ("overruns" in msg) hv.showOverruns(msg.overruns);
    if ("sim_rate" in msg) hv.showRate(msg.sim_rate);
    if ("stop" in msg) view.stopped = !!msg.stop;
    if (moved) { dirty.active = true; dirty.focus = true; }
    hv.later();
  }

  function onMessage(ev) {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    if (!msg || typeof msg !== "object") return;
    if (msg.type === "model") showModel(msg);
    else if (msg.type === "state") onState(msg);
    else if (msg.type === "delta") onDelta(msg);
    else if (msg.type === "replay") hv.onReplay(msg);
    else if (msg.type === "vehicle") hv.onVehicle(msg);
    else if (msg.type === "frame") hv.onFrame(msg);
    else if (msg.type === "ros2") window.hfsmcRos2.onRos2(msg);
    else if (msg.type === "driver") hv.onDriver(msg);
    else if (msg.type === "scan") window.hfsmcRos2.onScan(msg);
    else if (msg.type === "trail") window.hfsmcRos2.onTrail(msg);
    else if (msg.type === "world") window.hfsmcRos2.onWorld(msg);
    else if (msg.type === "status") {
      setTime(msg.t);
      hv.showStatus(msg.status, msg.note);
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
      hv.showStatus("offline", ev.code === 1008
        ? "this page fell behind and was dropped by the web view; reconnecting"
        : "the web view server is gone; reconnecting");
      setTimeout(connect, retry);
      retry = Math.min(retry * 2, RETRY_MAX_MS);
      // Refused before it opened: a web view started again has a new token (docs/web.md, Trust).
      if (!opened) {
        fetch("app.css", {cache: "no-store"}).then((r) => {
          if (r.status === 403) {
            hv.showStatus("offline", "this page's token is not accepted (the web view was started " +
              "again?): open the URL hfsmc view printed");
          }
        }, () => {});
      }
    };
  }

  window.addEventListener("DOMContentLoaded", () => {
    hv.startDiagram();
    hv.startReplay();
    setInterval(hv.tick, 100);
    connect();
  });

  Object.assign(hv, {send});
})(window.hfsmcView);
