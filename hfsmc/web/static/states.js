// hfsmc view --web: the states. The tree of the model's states (fold and unfold a
// composite, open its sub-automaton) and what is active, lit on the tree and on the
// diagram alike. Part of window.hfsmcView (page.js).
"use strict";

(function (hv) {
  const {$, view, el} = hv;

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
    open.addEventListener("click", () => hv.openSub(path));
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
        open.addEventListener("click", () => hv.openSub(st.path));
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
    hv.tick();
    if (focus && $("hv-autofocus").checked) hv.autofocus();
  }

  Object.assign(hv, {buildTree, showActive});
})(window.hfsmcView);
