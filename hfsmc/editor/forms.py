"""The page's forms (VisualHFSM's Timer, Variables, Libraries and Config dialogs): what
they show of the model (its parameters, variables, interfaces, imports, functions, the
root's settings, each sub-automaton's period and history) and the operations they send,
each checked here before it reaches the engine (docs/editor.md, "Forms")."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from hfsmc.edit import declarations as decl
from hfsmc.edit.text import EditError
from hfsmc.edit.yaml_ops import SECTIONS, YamlOps

ROOT_KEYS = ("period", "interrupt_timeout", "on_interrupt", "functions", "on_shutdown")
AUTOMATON_KEYS = ("period", "history")

PAGE_SCRIPTS = ("editor_forms", "editor_clip", "editor_lanes", "editor_keys")  # static/*.js
Arg = Callable[..., Any]  # the server's argument checker: arg(args, name, kind, optional)


def shown(value: Any) -> str | None:
    """A value as a form shows it (and :func:`decl.literal` reads it back)."""
    if value is None:
        return None
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


def settings(data: Any) -> dict[str, Any]:
    """What the forms show of the model ``data`` (as the front end read it)."""
    data = data if isinstance(data, dict) else {}
    out: dict[str, Any] = {"root": {k: shown(data.get(k)) for k in ROOT_KEYS}}
    for kind, section in SECTIONS.items():
        raw = data.get(section) if isinstance(data.get(section), dict) else {}
        rows = []
        for name, spec in raw.items():
            if isinstance(spec, dict):
                rows.append({"name": str(name), "short": False,
                             **{k: shown(spec.get(k)) for k in decl.FIELDS[kind]}})
            else:
                value = "init" if kind == "variable" else "default"
                rows.append({"name": str(name), "short": True, "type": None, value: shown(spec)})
        out[section] = rows
    imports = data.get("imports")
    out["imports"] = [str(x) for x in imports] if isinstance(imports, list) else []
    automata: dict[str, dict[str, str | None]] = {}
    _automata(data, "", automata)
    out["automata"] = automata
    return out


def _automata(body: dict[str, Any], path: str, out: dict[str, dict[str, str | None]]) -> None:
    out[path] = {k: shown(body.get(k)) for k in AUTOMATON_KEYS}
    for group in ("states", "regions"):
        kids = body.get(group)
        if isinstance(kids, dict):
            for name, sub in kids.items():
                if isinstance(sub, dict):
                    _automata(sub, (path + "/" if path else "") + str(name), out)


def _kind(a: dict[str, Any], arg: Arg) -> str:
    kind = arg(a, "kind", str)
    if kind not in SECTIONS:
        raise EditError(f"no kind of declaration `{kind}` (parameter, variable, interface)")
    return str(kind)


def _optional_text(a: dict[str, Any], arg: Arg) -> str | None:
    value = arg(a, "value", str, optional=True)
    return None if value is None or value == "" else str(value)


def _declaration(kind: str, type_: str | None, value: str | None) -> Any:
    """A new declaration's body from the add form's type and value."""
    if kind == "interface":
        if not type_:
            raise EditError("an interface needs a type (mavlink, camera, ...)")
        return {"type": type_, "url": value} if value else {"type": type_}
    if kind == "parameter":
        if not type_:
            raise EditError("a parameter needs a type (bool, int, float, str)")
        return {"type": type_, "default": decl.literal(value or "", type_)} if value is not None \
            else {"type": type_}
    if not type_:
        return decl.literal(value or "0", None)
    return {"type": type_, "init": decl.literal(value or "", type_)}


def operation(op: str, a: dict[str, Any], arg: Arg) -> Callable[[YamlOps], Any] | None:
    """The engine's operation a form asks for, its arguments checked; None when ``op`` is
    not a form's."""
    if op == "set_setting":
        key, value = arg(a, "key", str), arg(a, "value", str, optional=True)
        if key not in ROOT_KEYS:
            raise EditError(f"`{key}` is not a setting of the model the page edits")
        return lambda o: o.set_state_field("", key, value if value not in (None, "") else None)
    if op == "set_automaton":
        state, key = arg(a, "state", str), arg(a, "key", str)
        if key == "history":
            flag = arg(a, "value", bool, optional=True)
            return lambda o: o.set_state_field(state, "history", flag)
        if key != "period":
            raise EditError(f"`{key}` is not a field of a sub-automaton the page edits")
        period = _optional_text(a, arg)
        return lambda o: o.set_state_field(state, "period", period)
    if op == "add_declaration":
        kind, name = _kind(a, arg), arg(a, "name", str)
        type_, value = arg(a, "type", str, optional=True), arg(a, "value", str, optional=True)
        body = _declaration(kind, type_ or None, value)
        return lambda o: o.add_declaration(kind, name, body)
    if op == "delete_declaration":
        kind, name = _kind(a, arg), arg(a, "name", str)
        return lambda o: o.remove_declaration(kind, name)
    if op == "rename_declaration":
        kind, name, new = _kind(a, arg), arg(a, "name", str), arg(a, "new", str)
        return lambda o: o.rename_declaration(kind, name, new)
    if op == "set_declaration":
        kind, name, key = _kind(a, arg), arg(a, "name", str), arg(a, "key", str)
        text = arg(a, "value", str, optional=True)
        if key not in decl.FIELDS[kind]:
            raise EditError(f"`{key}` is not a field of a {kind} the page edits")

        def setting(o: YamlOps) -> Any:
            value: Any = text
            if key == "type":
                value = text or None
            elif text is not None:
                value = decl.literal(text, decl.declared_type(o, kind, name))
            return decl.set_declaration_field(o, kind, name, key, value)
        return setting
    if op == "add_import":
        line = arg(a, "line", str).strip()
        if not line:
            raise EditError("an import is one line: `numpy as np`, `<cmath>`")
        return lambda o: o.add_import(line)
    if op == "set_import":
        index, line = arg(a, "index", int), arg(a, "line", str)
        return lambda o: decl.set_import(o, index, line)
    if op == "delete_import":
        index = arg(a, "index", int)
        return lambda o: decl.delete_import(o, index)
    if op == "add_region":
        state, name = arg(a, "state", str), arg(a, "name", str)
        if not state:
            raise EditError("the root has states, not regions: add the region to a state")
        return lambda o: o.add_region(state, name)
    return None
