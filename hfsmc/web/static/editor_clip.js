// Copy and paste of states (docs/editor.md, "Copy and paste"): Ctrl+C on a selected state
// asks the server for its YAML text (the file's own lines, `Name:` and its body) and puts
// it on the system clipboard; Ctrl+V on the canvas pastes the clipboard's text into the
// automaton shown, through the engine (a name taken gets a number: `Land2`).
"use strict";

let lastCopy = null;  // the last state copied, for the page itself if the clipboard refuses

function copied(msg) {
  lastCopy = msg.text;
  document.body.dataset.copied = msg.path;
  const done = () => say(`copied ${msg.path} as YAML (${msg.text.split("\n").length - 1} lines)`, false);
  if (navigator.clipboard && navigator.clipboard.writeText) {
    navigator.clipboard.writeText(msg.text).then(done, () =>
      say(`copied ${msg.path} for this page only: the browser refused the clipboard`, true));
  } else done();
}

document.addEventListener("keydown", (ev) => {
  if (!model || inEditor(ev) || !(ev.ctrlKey || ev.metaKey) || ev.key.toLowerCase() !== "c") return;
  if (sel && sel.kind === "state") { ev.preventDefault(); send("copy", {path: sel.path}); }
});

document.addEventListener("paste", (ev) => {
  if (!model || inEditor(ev) || model.read_only) return;
  const text = (ev.clipboardData && ev.clipboardData.getData("text/plain")) || lastCopy;
  if (!text) return;
  ev.preventDefault();
  send("paste", {parent: cur, text});
});
