// hfsmc edit's live side (docs/editor.md): the running component's active states lit on
// the canvas and in the tree (editing paused meanwhile), Build and run with its log and
// Stop, and the problems in the code editors' gutters. editor.js calls the hooks below.
"use strict";

window.EditorLive = (() => {
  const $ = (id) => document.getElementById(id);
  let live = null;      // the server's last "live" message
  let ui = null;
  const LOG_KEEP = 2000;

  function send(op) {
    if (ws && ws.readyState === 1) ws.send(JSON.stringify({op, args: {}}));
  }

  function button(id, text, title, onclick) {
    const b = document.createElement("button");
    b.id = id; b.textContent = text; b.title = title; b.onclick = onclick;
    return b;
  }

  function setup() {
    if (ui) return ui;
    const header = document.querySelector("header");
    const run = button("run", "Build and run", "Run the saved model as `hfsmc run` does, " +
      "its states lit here (one run at a time)", () => send("run_start"));
    const stop = button("stop", "Stop", "Ctrl+C the run (on_interrupt); again: kill it",
      () => send("run_stop"));
    header.appendChild(run);
    header.appendChild(stop);
    const bar = document.createElement("div");
    bar.id = "live";
    bar.hidden = true;
    const text = document.createElement("span");
    text.id = "live-text";
    const watch = button("live-watch", "Show the component", "Light its states again " +
      "(editing paused)", () => send("live_watch"));
    const resume = button("live-resume", "Resume editing", "Drop the overlay and edit again",
      () => send("live_resume"));
    bar.append(text, resume, watch);
    $("message").before(bar);
    const box = document.createElement("section");
    box.id = "runbox";
    box.hidden = true;
    const h = document.createElement("h3");
    h.textContent = "Run log";
    const pre = document.createElement("pre");
    pre.id = "runlog";
    box.append(h, pre);
    $("right").appendChild(box);
    ui = {run, stop, bar, text, watch, resume, box, pre};
    return ui;
  }

  // ----- messages
  function take(msg) {
    setup();
    if (msg.type === "note") { say(msg.message, false); return; }
    if (msg.type === "run_log") { lines(msg); return; }
    live = msg;
    const u = ui;
    const r = live.run;
    u.run.disabled = !!(r && r.running);
    u.stop.disabled = !(r && r.running);
    u.stop.textContent = r && r.running && r.stopping ? "Kill" : "Stop";
    u.watch.hidden = live.on || !live.can_watch;
    u.resume.hidden = !live.on;
    u.bar.hidden = !live.on && !live.can_watch;
    u.bar.className = live.on ? (live.status === "connected" ? "on" : "gone") : "off";
    document.body.classList.toggle("paused", !!live.on);
    if (!live.on) {
      u.text.textContent = "Editing. The component is not shown.";
    } else if (live.status === "connected") {
      u.text.textContent = `Showing ${live.target}: ${live.active.length ? "its active states are lit" : "no state active"}` +
        `${live.stopped ? " (it stopped)" : ""}. Editing is paused. `;
    } else {
      u.text.textContent = `The component ${live.target} is gone (${live.note}). ` +
        "Editing is paused. ";
    }
    paint();
  }

  function lines(msg) {
    const u = setup();
    if (msg.reset) u.pre.textContent = "";
    if (msg.reset && !msg.lines.length) return;
    u.box.hidden = false;
    const stick = u.pre.scrollTop + u.pre.clientHeight >= u.pre.scrollHeight - 4;
    for (const l of msg.lines) {
      const div = document.createElement("div");
      div.className = l.stream;
      div.textContent = l.text;
      u.pre.appendChild(div);
    }
    while (u.pre.childElementCount > LOG_KEEP) u.pre.firstChild.remove();
    if (stick) u.pre.scrollTop = u.pre.scrollHeight;
  }

  // ----- the overlay: called after every drawing
  function paint() {
    const lit = new Set(live && live.on ? live.active : []);
    for (const g of document.querySelectorAll("g.state")) {
      g.classList.toggle("active", lit.has(g.dataset.path));
    }
    for (const s of document.querySelectorAll("#tree span")) {
      s.classList.toggle("active", lit.has(s.dataset.path));
    }
  }

  // ----- problems in the code editors' gutters
  function extensions() {
    return window.CM && CM.lintGutter ? [CM.lintGutter()] : [];
  }

  // editors: field -> {view}; sel: what the panel edits; the model's diagnostics placed
  // by the server in their snippet (`field`, `at`: [line, col]).
  function lint(editors, sel) {
    if (!window.CM || !CM.setDiagnostics || !sel || !model) return;
    const state = sel.kind === "state" ? sel.path : sel.state;
    const index = sel.kind === "state" ? null : sel.index;
    for (const [f, ed] of Object.entries(editors)) {
      if (!ed.view) continue;
      const doc = ed.view.state.doc;
      const found = [];
      for (const d of model.diagnostics) {
        if (d.other || d.state !== state || d.transition !== index || d.field !== f || !d.at) continue;
        const line = doc.line(Math.min(Math.max(d.at[0], 1), doc.lines));
        const from = Math.min(line.from + d.at[1] - 1, line.to);
        found.push({from, to: Math.max(from, line.to), severity: d.severity === "error" ? "error" : "warning",
          message: `${d.code}: ${d.message}` + (d.notes && d.notes.length ? ` (${d.notes.join("; ")})` : "")});
      }
      const key = JSON.stringify(found);
      if (ed.linted === key) continue;
      ed.linted = key;
      ed.view.dispatch(CM.setDiagnostics(ed.view.state, found));
    }
  }

  return {take, paint, extensions, lint};
})();
