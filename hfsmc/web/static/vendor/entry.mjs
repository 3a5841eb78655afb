// What hfsmc edit's page uses of CodeMirror 6 (bundled into codemirror.js as the global `CM`).
export { EditorView, keymap } from "@codemirror/view";
export { EditorState, Compartment } from "@codemirror/state";
export { basicSetup } from "codemirror";
export { python } from "@codemirror/lang-python";
export { cpp } from "@codemirror/lang-cpp";
export { linter, lintGutter, setDiagnostics } from "@codemirror/lint";
