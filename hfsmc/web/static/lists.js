// hfsmc view --web: the lists beside the diagram: the variables, the last transitions
// and the log. Part of window.hfsmcView (page.js).
"use strict";

(function (hv) {
  const {$, view, el, seconds} = hv;

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

  Object.assign(hv, {showVariablesAll, updateVariables, showTransitions, showLogs});
})(window.hfsmcView);
