"""New YAML text for a value, in a given style and at a given indentation.

What is inserted takes the style of its siblings (SPEC 8.1): the callers in
:mod:`hfsmc.edit.yaml_splice` pick the style from the text around; this module
only writes it.  A plain scalar is written plain only when it reads back as the
same string in YAML 1.2 and 1.1 alike (so neither `check` nor a YAML 1.1 tool reads
`no` or `010` otherwise)."""

from __future__ import annotations

import json
import re
from typing import Any

import yaml

from hfsmc.frontend.source import YAML11_BOOLS
from hfsmc.frontend.yaml_c import resolves_to_str

_PLAIN_SAFE = re.compile(r"[A-Za-z0-9_$(.+-][^\n]*\Z")
_FLOW_SPECIAL = re.compile(r"[,\[\]{}]")


def plain_ok(s: str, flow: bool) -> bool:
    """Whether ``s`` can be written as a plain scalar and read back as this string."""
    if not s or s != s.strip() or s in YAML11_BOOLS or "\n" in s or " #" in s or ": " in s \
            or s.endswith(":") or not _PLAIN_SAFE.match(s):
        return False
    if flow and _FLOW_SPECIAL.search(s):
        return False
    try:
        back = yaml.safe_load(("{k: %s}" if flow else "k: %s") % s)
    except yaml.YAMLError:
        return False
    if back != {"k": s}:
        return False
    return resolves_to_str(s)


def quoted(s: str, quote: str) -> str:
    if quote == "'" and "\n" not in s and all(c.isprintable() for c in s):
        return "'" + s.replace("'", "''") + "'"
    return json.dumps(s, ensure_ascii=False)


def is_multiline(s: str) -> bool:
    return "\n" in s


def block_scalar(s: str, indent: int, nl: str) -> str:
    """``s`` as a literal block (`|`, or `|-` without a final line break), from its
    indicator to its last line's end (no final break)."""
    head = "|" if s.endswith("\n") else "|-"
    body = s[:-1] if s.endswith("\n") else s
    if body.startswith(" ") or body.startswith("\n"):
        head = head[0] + str(2) + head[1:]
    pad = " " * indent
    lines = [(pad + ln) if ln.strip() else "" for ln in body.split("\n")]
    return head + nl + nl.join(lines)


def scalar(value: Any, hint: str, flow: bool, indent: int, nl: str) -> str:
    """A scalar's text: ``hint`` is the style wanted ("" plain, `'`, `"`, `|`)."""
    if value is None:
        return "null"
    if value is True or value is False:
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    s = str(value)
    if is_multiline(s) or hint in ("|", ">"):
        if not flow:
            return block_scalar(s, indent, nl)
        return quoted(s, '"')
    if hint in ("'", '"'):
        return quoted(s, hint)
    if plain_ok(s, flow):
        return s
    return quoted(s, '"')


def flow(value: Any, hint: str = "") -> str:
    """``value`` in flow style on one line."""
    if isinstance(value, dict):
        if not value:
            return "{}"
        return "{" + ", ".join(f"{key(k)}: {flow(v, hint)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(flow(v, hint) for v in value) + "]"
    return scalar(value, hint if hint in ("'", '"') else "", True, 0, "\n")


def key(k: Any) -> str:
    s = str(k)
    return s if plain_ok(s, True) else quoted(s, '"')


def fits_flow(value: Any, width: int = 88) -> bool:
    """Short and made of scalars one level down: written as a flow mapping or list."""
    if isinstance(value, dict):
        ok = all(not isinstance(v, (dict, list)) or not v for v in value.values())
    elif isinstance(value, list):
        ok = all(not isinstance(v, (dict, list)) for v in value)
    else:
        return True
    if not ok:
        return False
    try:
        text = flow(value)
    except ValueError:
        return False
    return len(text) <= width and "\n" not in text


def after_key(value: Any, indent: int, step: int, nl: str, hint: str = "",
              prefer_flow: bool = False) -> str:
    """The text that follows ``key:`` for ``value`` in block context; ``indent`` is the
    key's column, ``step`` the file's indentation step."""
    if isinstance(value, (dict, list)):
        if not value or (prefer_flow and fits_flow(value)):
            return " " + flow(value, hint)
        if isinstance(value, list):
            return nl + block(value, indent + step, step, nl, hint)
        return nl + block(value, indent + step, step, nl, hint)
    return " " + scalar(value, hint, False, indent + step, nl)


def block(value: Any, indent: int, step: int, nl: str, hint: str = "") -> str:
    """A mapping or a list in block style at ``indent`` (no final line break)."""
    pad = " " * indent
    lines: list[str] = []
    if isinstance(value, dict):
        for k, v in value.items():
            lines.append(pad + key(k) + ":" + after_key(v, indent, step, nl, hint, prefer_flow=False))
    else:
        for v in value:
            if isinstance(v, dict) and fits_flow(v):
                lines.append(pad + "- " + flow(v, hint))
            elif isinstance(v, dict) and v:
                inner = block(v, indent + 2, step, nl, hint)
                lines.append(pad + "- " + inner[indent + 2:])
            elif isinstance(v, (dict, list)):
                lines.append(pad + "- " + flow(v, hint))
            else:
                lines.append(pad + "- " + scalar(v, hint, False, indent + 2, nl))
    return nl.join(lines)
