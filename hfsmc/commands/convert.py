"""``hfsmc convert``: YAML ↔ XML (and legacy XML → version 1).

The writers are hfsmc/emit/yaml.py (a new YAML file; an existing one is edited by the
edit engine, hfsmc/edit/merge.py, which changes only the text of what changed) and hfsmc/emit/xml.py (the comments of a YAML source carried over).
"""

from __future__ import annotations

import os
import re
from dataclasses import replace
from pathlib import Path

from hfsmc.emit.yaml import to_yaml
from hfsmc.errors import Diagnostic, UsageError
from hfsmc.fsutil import write_atomic
from hfsmc.ir import Automaton, Model, State
from hfsmc.pipeline import Result, compile_file


def convert_model(result: Result, out: Path) -> list[str]:
    """Write ``result``'s model to ``out`` in the format its suffix names; report lines."""
    assert result.model is not None
    model, moved = relocate_uses(result.model, out)
    suffix = out.suffix.lower()
    if suffix in (".yaml", ".yml"):
        existing = None
        if out.exists():
            try:
                existing = out.read_text("utf-8")
            except (OSError, UnicodeDecodeError):
                existing = None
        if existing is not None and _is_model(existing):
            from hfsmc.edit.merge import merge_into
            from hfsmc.edit.text import EditError
            from hfsmc.emit.data import model_to_data

            data = model_to_data(model)
            if "\nlanguage:" not in "\n" + existing and data.get("language") == "python":
                del data["language"]  # the default, which the user left out
            try:
                text = merge_into(existing, data)
            except EditError as e:
                raise UsageError(f"{out}: cannot be edited in place ({e}); write another file") from None
        else:
            existing = None
            text = to_yaml(model, out)
        how = "edited in place" if existing is not None else "wrote"
    elif suffix == ".xml":
        from hfsmc.emit.xml import to_xml

        doc = result.document
        text = to_xml(model, yaml_comments(result.lines) if doc is not None and
                      doc.format == "yaml" else ())
        how = "wrote"
    else:
        raise UsageError(f"{out}: the output's name must end in .yaml, .yml or .xml")
    write_atomic(out, text)
    n_states = sum(1 for _ in model.states())
    n_trans = sum(len(s.transitions) for s in model.states())
    report = [*legacy_report(result), f"{how} {out}: {n_states} states, {n_trans} transitions"]
    if moved:
        report.append(f"{out}: `use` paths written from its folder: {', '.join(dict.fromkeys(moved))}")
    return report


def _is_model(text: str) -> bool:
    """Whether ``text`` is a YAML model (a mapping) that an edit can go into."""
    from hfsmc.errors import Diagnostics, HfsmcError
    from hfsmc.frontend.yaml import load_yaml

    try:
        return isinstance(load_yaml("<out>", text, Diagnostics()).data, dict)
    except HfsmcError:
        return False


def relocate_uses(model: Model, out: Path) -> tuple[Model, list[str]]:
    """The model with each relative `use` path of its own states rewritten from ``out``'s
    folder, so that the converted file finds the same used files (`use` paths are relative
    to the file that writes them); and the paths rewritten, as `old -> new`."""
    src, dst = Path(model.file).parent, out.parent
    if src.resolve() == dst.resolve():
        return model, []
    moved: list[str] = []

    def automaton(a: Automaton) -> Automaton:
        if a.instance is not None:  # a used file's own uses are written in that file
            written = a.instance.written
            if os.path.isabs(written):
                return a
            new = Path(os.path.relpath(src / written, dst)).as_posix()
            moved.append(f"{written} -> {new}")
            return replace(a, instance=replace(a.instance, written=new))
        return replace(a, states=tuple(state(s) for s in a.states))

    def state(s: State) -> State:
        return replace(s, automata=tuple(automaton(a) for a in s.automata)) if s.automata else s

    return replace(model, root=automaton(model.root)), moved


_BLOCK_START = re.compile(r"(?:^|[:-][ \t])[ \t]*[|>][0-9+-]*[ \t]*$")


def yaml_comments(lines: list[str]) -> list[tuple[int, str]]:
    """(line, text) of each comment of a YAML file, for the XML writer.

    Lines inside block scalars (`|`, `>`) are code or text, not comments; the
    editor hint on the first line is left out (the XML names its own schema).
    The comments above the first key (the file's header) get line 0: they go
    before the first element.
    """
    out: list[tuple[int, str]] = []
    block: int | None = None  # indentation of the key that opened a block scalar
    header = True
    for n, line in enumerate(lines, 1):
        body = line.rstrip("\r\n")
        stripped = body.lstrip(" ")
        indent = len(body) - len(stripped)
        if block is not None:
            if not stripped.strip() or indent > block:
                continue
            block = None
        cut = 0 if stripped.startswith("#") else _comment_start(body)
        if cut is not None:
            text = body[indent + 1 if cut == 0 else cut + 1:].strip()
            if text and not (n == 1 and text.startswith("yaml-language-server:")):
                out.append((0 if header and cut == 0 else n, text))
        if cut != 0 and stripped.strip():
            header = False
        if _BLOCK_START.search(body if cut is None else body[:indent if cut == 0 else cut]):
            block = indent
    return out


def _comment_start(line: str) -> int | None:
    """Index of the `#` that starts a comment after some YAML on ``line``, if any."""
    quote = ""
    for k, ch in enumerate(line):
        if quote:
            if ch == quote and (quote == "'" or line[k - 1] != "\\"):
                quote = ""
        elif ch in "'\"" and (k == 0 or line[k - 1] in " \t:[{,-"):
            quote = ch
        elif ch == "#" and k > 0 and line[k - 1] in " \t":
            return k
    return None


# Problems in the code of a legacy file (a name the file never imported, a syntax error):
# `convert` still writes the model and reports them as warnings, so that the user fixes
# them in the new file; `check` and `build` stay strict (docs/legacy.md).
def compile_for_convert(path: str, strict: bool = False) -> Result:
    """``path`` compiled for ``convert``: as ``check`` does, except that a legacy file whose
    only errors are in its code gives its model, those errors reported as W220."""
    result = compile_file(path)
    doc = result.document
    if strict or doc is None or doc.format not in ("visualstates", "visualhfsm") \
            or not result.errors_only_in_snippets:
        return result
    kept = [d if d.severity != "error" else Diagnostic(
        "W220", f"{d.message} ({d.code}: the converted model keeps it; fix it there)", d.span,
        "warning", d.notes) for d in result.diagnostics]
    return Result(path, result.structure, kept, result.lines, doc, result.notes)


def legacy_report(result: Result) -> list[str]:
    """What the import of a legacy file mapped, and how (docs/legacy.md); nothing for other files."""
    doc = result.document
    if doc is None or not doc.notes:
        return []
    kind = {"visualstates": "VisualStates", "visualhfsm": "VisualHFSM"}.get(doc.format, doc.format)
    return [f"{result.path}: {kind} file read as a version-1 model:",
            *(f"  {span}: {message}" for span, message in doc.notes)]
