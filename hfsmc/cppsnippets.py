"""Checks of C++ snippets that need no compiler, run by every ``hfsmc check``.

A small lexer (comments, string, character and raw string literals,
identifiers, ``.``, ``->``, ``::``, parentheses) finds what g++ would report
far from its cause or not at all:

- ``drone.goto(...)``: ``goto`` is a C++ keyword, so g++ says only "expected
  unqualified-id before 'goto'"; the driver's method is ``go_to`` (E145).
- ``active("A/B")`` with a literal path that names no state: the component
  would throw at run time (E146), and ``done()`` in a state without a
  sub-automaton, where it is always false (W215); see hfsmc/pycheck.py.

Everything else is g++'s business (hfsmc/cxxcheck.py).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

from hfsmc.errors import Diagnostics, Span
from hfsmc.ir import Model
from hfsmc.pycheck import Snippet, check_active_path, check_done, snippets

_TOKEN = re.compile(r"""
    (?P<comment>//[^\n]*|/\*.*?(?:\*/|\Z))
  | (?P<raw>(?:u8|[uUL])?R"(?P<delim>[^()\\\s"]{0,16})\(.*?(?:\)(?P=delim)"|\Z))
  | (?P<string>(?:u8|[uUL])?"(?:[^"\\\n]|\\.)*"?)
  | (?P<char>(?:u8|[uUL])?'(?:[^'\\\n]|\\.)*'?)
  | (?P<ident>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<punct>->|::|[.()])
  | (?P<other>[^\s])
""", re.VERBOSE | re.DOTALL)
_MEMBER = (".", "->", "::")


@dataclass(frozen=True, slots=True)
class Token:
    kind: str  # raw | string | char | ident | punct | other
    text: str
    offset: int  # in the snippet's text


def tokens(text: str) -> Iterator[Token]:
    """The snippet's tokens, comments left out."""
    for m in _TOKEN.finditer(text):
        kind = m.lastgroup
        if kind is None or kind == "comment":
            continue
        if kind == "delim":  # the raw literal's inner group: report the literal
            kind = "raw"
        yield Token(kind, m.group(kind), m.start())


def check_cpp_snippets(model: Model, diags: Diagnostics) -> None:
    """E145, E146 and W215 in every snippet of a C++ model."""
    for sn in snippets(model):
        if "goto" in sn.code.text or "active" in sn.code.text or "done" in sn.code.text:
            _check(model, sn, list(tokens(sn.code.text)), diags)


def _check(model: Model, sn: Snippet, toks: list[Token], diags: Diagnostics) -> None:
    for k, tok in enumerate(toks):
        if tok.kind != "ident":
            continue
        before = toks[k - 1].text if k and toks[k - 1].kind == "punct" else ""
        if tok.text == "goto" and before in (".", "->"):
            obj = toks[k - 2].text + before if k >= 2 and toks[k - 2].kind == "ident" else before
            diags.error("E145", "`goto` is a C++ keyword: the method is `go_to`",
                        _position(sn, tok.offset),
                        f"write `{obj}go_to(north, east, alt)` (docs/cpp.md)")
        elif before in _MEMBER:
            continue
        elif tok.text == "active" and _texts(toks, k + 1, 3)[::2] == ["(", ")"] \
                and toks[k + 2].kind == "string":
            path = _unquote(toks[k + 2].text)
            if path is not None:
                check_active_path(model, sn, path, _position(sn, toks[k + 2].offset), diags)
        elif tok.text == "done" and _texts(toks, k + 1, 2) == ["(", ")"]:
            check_done(model, sn, _position(sn, tok.offset), diags)


def _texts(toks: list[Token], start: int, n: int) -> list[str]:
    return [t.text for t in toks[start:start + n]]


def _unquote(literal: str) -> str | None:
    """The text of a plain "..." literal; None for a literal with escapes (left to run time)."""
    if not (literal.startswith('"') and literal.endswith('"') and len(literal) >= 2):
        return None
    body = literal[1:-1]
    return None if "\\" in body else body


def _position(sn: Snippet, offset: int) -> Span:
    text = sn.code.text
    line = text.count("\n", 0, offset) + 1
    col = offset - (text.rfind("\n", 0, offset) + 1) + 1
    return sn.code.position(line, col)
