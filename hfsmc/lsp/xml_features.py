"""What the language server adds for the markup of XML models: completion of element
and attribute names where the XSD allows them, and hover with their documentation.

The text being typed often does not parse: the elements open at the cursor are found
by a tolerant scan of the tags before it."""

from __future__ import annotations

import json
import re
from functools import cache
from pathlib import Path
from typing import Any

from lsprotocol import types

from hfsmc.frontend.xml import _grammar
from hfsmc.resources import schema_file

_TAG = re.compile(r"<!--.*?(?:-->|\Z)|<!\[CDATA\[.*?(?:\]\]>|\Z)|<\?.*?(?:\?>|\Z)"
                  r"|<(/?)([A-Za-z_][\w.:-]*)((?:[^<>\"']|\"[^\"]*\"|'[^']*')*)(>|\Z)", re.S)
_OPEN_TAG = re.compile(r"<([A-Za-z_][\w.:-]*)((?:\s+[^\s=<>]+\s*=\s*(?:\"[^\"]*\"|'[^']*'))*)\s+([\w:]*)\Z")
_NEW_ELEMENT = re.compile(r"<([\w:]*)\Z")
_NAME_AT = re.compile(r"[\w:]+")
# The YAML form's documentation of each element's keys (the JSON schema's $defs).
_CONTEXT = {"hfsm": "root", "rootAutomaton": "root", "automaton": "state", "state": "state",
            "transition": "transition", "region": "region", "parameter": "parameter",
            "variable": "variable", "interface": "interface", "with": "with"}


@cache
def _docs(context: str) -> dict[str, str]:
    s: dict[str, Any] = json.loads(Path(str(schema_file("hfsm.schema.json"))).read_text("utf-8"))
    props = s["properties"] if context == "root" else s["$defs"].get(context, {}).get("properties", {})
    return {k: str(v.get("description", "")) for k, v in props.items()}


def _open_types(text: str, end: int) -> list[str]:
    """The XSD types of the elements open at offset ``end`` (outermost first)."""
    grammar = _grammar()
    stack: list[tuple[str, str]] = []  # (tag, type)
    for m in _TAG.finditer(text, 0, end):
        if m.group(2) is None or not m.group(4) or m.group(3).rstrip().endswith("/"):
            continue
        tag = m.group(2)
        if m.group(1):
            while stack and stack[-1][0] != tag:
                stack.pop()  # an element left open while typing
            if stack:
                stack.pop()
            continue
        parent = stack[-1][1] if stack else None
        if parent is None:
            kind = "hfsm" if tag == "hfsm" else ""
        else:
            t = grammar.types.get(parent)
            kind = t.children.get(tag, "") if t is not None else ""
        stack.append((tag, kind))
    return [k for _, k in stack]


def _doc(kind: str, name: str) -> str:
    context = _CONTEXT.get(kind)
    return _docs(context).get(name, "") if context else ""


def completion(text: str, offset: int) -> list[types.CompletionItem] | None:
    """Attribute names inside a start tag, element names after `<`; None elsewhere."""
    grammar = _grammar()
    head = text[max(0, offset - 2000):offset]
    m = _OPEN_TAG.search(head)
    if m:
        kinds = _open_types(text, offset - len(m.group(0)))
        parent = grammar.types.get(kinds[-1]) if kinds else None
        kind = (parent.children.get(m.group(1), "") if parent else
                "hfsm" if m.group(1) == "hfsm" else "")
        t = grammar.types.get(kind)
        if t is None:
            return []
        present = set(re.findall(r"([^\s=]+)\s*=", m.group(2)))
        return [types.CompletionItem(a, kind=types.CompletionItemKind.Property,
                                     documentation=_doc(kind, a) or None, insert_text=f'{a}="')
                for a in t.attributes if a not in present]
    m = _NEW_ELEMENT.search(head)
    if m:
        kinds = _open_types(text, offset - len(m.group(0)))
        t = grammar.types.get(kinds[-1]) if kinds else None
        return [types.CompletionItem(c, kind=types.CompletionItemKind.Class,
                                     documentation=_doc(kinds[-1], c) or None)
                for c in (t.children if t is not None else ())]
    return None


def hover(text: str, offset: int) -> tuple[str, int, int] | None:
    """The documentation of the element or attribute name under ``offset`` (markdown,
    and the name's range)."""
    s = offset
    while s > 0 and re.match(r"[\w:]", text[s - 1]):
        s -= 1
    m = _NAME_AT.match(text, s)
    if m is None or m.end() < offset:
        return None
    name = m.group()
    if s > 0 and text[s - 1] in "</":
        kinds = _open_types(text, s - (2 if text[s - 1] == "/" else 1))
        doc = _doc(kinds[-1], name) if kinds else ""
        if not doc and name in ("automaton", "region", "state", "transition"):
            doc = _docs("state").get({"automaton": "states", "region": "regions",
                                      "state": "states", "transition": "transitions"}[name], "")
        return (f"`<{name}>`: {doc}", s, m.end()) if doc else None
    if text[m.end():m.end() + 3].lstrip().startswith("="):
        lt = text.rfind("<", 0, s)
        tag = _NAME_AT.match(text, lt + 1) if lt >= 0 else None
        if tag is None or ">" in text[lt:s]:
            return None
        kinds = _open_types(text, lt)
        parent = _grammar().types.get(kinds[-1]) if kinds else None
        kind = parent.children.get(tag.group(), "") if parent else "hfsm" if tag.group() == "hfsm" else ""
        doc = _doc(kind, name)
        return (f"`{name}`: {doc}", s, m.end()) if doc else None
    return None
