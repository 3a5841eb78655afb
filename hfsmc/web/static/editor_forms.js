// hfsmc edit's forms (docs/editor.md, "Forms"), shown in the side panel when nothing is
// selected: the timer (the shown automaton's period and history, the root's interrupt
// settings), parameters, variables, interfaces, imports and functions. A field is sent
// when it changes (Enter, or leaving it); the server checks every value.
"use strict";

const DECLS = [["parameter", "parameters", "Parameters", ["type", "default"]],
  ["variable", "variables", "Variables", ["type", "init"]],
  ["interface", "interfaces", "Interfaces", ["type", "url"]]];

function h(tag, attrs, parent, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k.startsWith("data-") || k === "class" || k === "placeholder" || k === "title") e.setAttribute(k, v);
    else e[k] = v;
  }
  if (text !== undefined) e.textContent = text;
  if (parent) parent.appendChild(e);
  return e;
}

// A text input sent on change: `value` "" clears when the field may be cleared.
function entry(parent, value, attrs, sent) {
  const i = h("input", {value: value === null || value === undefined ? "" : value, ...attrs}, parent);
  i.onchange = () => sent(i.value);
  i.onkeydown = (ev) => { if (ev.key === "Escape") $("canvas").focus(); };
  return i;
}

function modelForms(box, fresh) {
  if (!model || !model.settings) return;
  if (!fresh && box.contains(document.activeElement) && document.activeElement !== box) return;
  box.textContent = "";
  const st = model.settings;
  const f = h("div", {id: "forms"}, box);
  h("p", {class: "hint"}, f, "Select a state or an arrow to edit it. The model:");
  if (model.read_only) return;

  // the timer: the automaton shown
  const auto = st.automata[cur] || {period: null, history: null};
  const where = cur || model.file;
  h("h3", {}, f, "Timer: " + where);
  const t = h("div", {class: "row"}, f);
  h("label", {}, t, "period");
  entry(t, auto.period, {"data-setting": "period", placeholder: cur ? "the parent's" : "100ms"},
    (v) => send("set_automaton", {state: cur, key: "period", value: v}));
  if (cur && model.states[cur] && !model.states[cur].regions) {
    const lab = h("label", {}, t, " history ");
    const c = h("input", {type: "checkbox", checked: auto.history === "true", "data-setting": "history"}, lab);
    c.onchange = () => send("set_automaton", {state: cur, key: "history", value: c.checked});
  }
  if (cur && model.states[cur] && model.states[cur].kind === "state" &&
      (model.states[cur].regions || !model.automata[cur])) {
    const b = h("button", {id: "add-region", title: "A parallel region in this state (R)"}, t, "Add region");
    b.onclick = () => addRegion(cur);
  }
  if (!cur) {
    for (const k of ["on_interrupt", "interrupt_timeout"]) {
      const r = h("div", {class: "row"}, f);
      h("label", {}, r, k);
      entry(r, st.root[k], {"data-setting": k}, (v) => send("set_setting", {key: k, value: v}));
    }
  }

  for (const [kind, section, title, keys] of DECLS) {
    h("h3", {}, f, title);
    const table = h("table", {class: "decls", "data-section": section}, f);
    for (const row of st[section]) {
      const tr = h("tr", {"data-decl": `${kind}:${row.name}`}, table);
      entry(h("td", {}, tr), row.name, {"data-key": "name"}, (v) => {
        if (v && v !== row.name) send("rename_declaration", {kind, name: row.name, new: v});
      });
      for (const k of keys) {
        entry(h("td", {}, tr), row[k], {"data-key": k, placeholder: k}, (v) =>
          send("set_declaration", {kind, name: row.name, key: k, value: v === "" && k !== "init" &&
            k !== "default" ? null : v}));
      }
      const x = h("button", {title: `delete the ${kind} ${row.name}`, class: "del"}, h("td", {}, tr), "✕");
      x.onclick = () => send("delete_declaration", {kind, name: row.name});
    }
    const add = h("tr", {class: "add", "data-add": kind}, table);
    const inputs = ["name", ...keys].map((k) => h("input", {placeholder: k, "data-key": k}, h("td", {}, add)));
    const b = h("button", {title: `add a ${kind}`}, h("td", {}, add), "+");
    const go = () => {
      const [name, type, value] = inputs.map((i) => i.value.trim());
      if (!name) return;
      send("add_declaration", {kind, name, type: type || null, value: value || null});
      document.activeElement.blur();  // the forms are drawn again with the new row
    };
    b.onclick = go;
    for (const i of inputs) i.onkeydown = (ev) => { if (ev.key === "Enter") go(); };
  }

  h("h3", {}, f, model.language === "cpp" ? "Includes" : "Imports");
  const ul = h("div", {class: "imports"}, f);
  st.imports.forEach((line, index) => {
    const r = h("div", {class: "row", "data-import": index}, ul);
    entry(r, line, {}, (v) => send(v.trim() ? "set_import" : "delete_import", {index, line: v}));
    const x = h("button", {class: "del", title: "delete this import"}, r, "✕");
    x.onclick = () => send("delete_import", {index});
  });
  const r = h("div", {class: "row add"}, ul);
  const line = h("input", {placeholder: model.language === "cpp" ? "<cmath>" : "numpy as np", id: "add-import"}, r);
  line.onkeydown = (ev) => {
    if (ev.key === "Enter" && line.value.trim()) { send("add_import", {line: line.value}); line.blur(); }
  };

  for (const k of ["functions", "on_shutdown"]) {
    h("h3", {}, f, k);
    const a = h("textarea", {rows: k === "functions" ? 8 : 3, spellcheck: false, "data-setting": k}, f);
    a.value = st.root[k] || "";
    a.onchange = () => send("set_setting", {key: k, value: a.value});
    a.onkeydown = (ev) => { if (ev.key === "Escape") $("canvas").focus(); };
  }
}

function addRegion(state) {
  const g = document.querySelector(`g.state[data-path="${CSS.escape(state)}"]`) || $("canvas");
  const r = g.getBoundingClientRect();
  ask(r.left + 90, r.top + 30, "", (name) => send("add_region", {state, name}));
}
