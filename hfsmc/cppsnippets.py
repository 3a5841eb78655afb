"""Checks of C++ snippets that need no compiler (a lowering pass: check, build, run).

A small lexer (comments, string, character and raw string literals, numbers,
identifiers, ``.``, ``->``, ``::``, brackets) finds what g++ would report far
from its cause or not at all:

- ``drone.goto(...)``: ``goto`` is a C++ keyword, so g++ says only "expected
  unqualified-id before 'goto'"; the driver's method is ``go_to`` (E145).
- ``active("A/B")`` with a literal path that names no state: the component
  would throw at run time (E146), and ``done()`` in a state without a
  sub-automaton, where it is always false (W215); see hfsmc/pycheck.py.
- a bracket the snippet leaves open, or closes without opening (E147): g++
  would see it only in the generated code after the snippet, and then report
  errors in the snippets that follow.
- ``robot.age("scn")`` on a ``ros2`` interface, a literal name that the interface
  does not declare (E148): the component would throw at run time.

Everything else is g++'s business (hfsmc/cxxcheck.py).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from difflib import get_close_matches

from hfsmc.errors import Diagnostics, Span
from hfsmc.ir import Model
from hfsmc.pycheck import Snippet, check_active_path, check_done, snippets

_TOKEN = re.compile(r"""
    (?P<comment>//[^\n]*|/\*.*?(?:\*/|\Z))
  | (?P<raw>(?:u8|[uUL])?R"(?P<delim>[^()\\\s"]{0,16})\(.*?(?:\)(?P=delim)"|\Z))
  | (?P<string>(?:u8|[uUL])?"(?:[^"\\\n]|\\.)*"?)
  | (?P<char>(?:u8|[uUL])?'(?:[^'\\\n]|\\.)*')
  | (?P<number>\.?[0-9](?:[eEpP][+-]|[A-Za-z0-9_.'])*)
  | (?P<ident>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<punct>->|::|[.()])
  | (?P<other>[^\s])
""", re.VERBOSE | re.DOTALL)
_MEMBER = (".", "->", "::")
_PAIRS = {"{": "}", "(": ")", "[": "]"}


@dataclass(frozen=True, slots=True)
class Token:
    kind: str  # raw | string | char | number | ident | punct | other
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
    """E145, E146, E147, E148 and W215 in every snippet of a C++ model."""
    ros2 = _ros2_names(model)
    for sn in snippets(model):
        text = sn.code.text
        toks: list[Token] | None = None
        if any(text.count(a) != text.count(b) for a, b in _PAIRS.items()):
            toks = list(tokens(text))  # only then: most snippets are balanced
            _check_brackets(sn, toks, diags)
        if "goto" in text or "active" in text or "done" in text:
            toks = toks if toks is not None else list(tokens(text))
            _check(model, sn, toks, diags)
        if ros2 and any(name in text for name in ros2):
            _check_ros2_names(ros2, sn, toks if toks is not None else list(tokens(text)), diags)


# A ros2 interface's methods whose first argument names a subscription or a publication.
_ROS2_NAMES = {"age": "subscribe", "count": "subscribe", "publishers": "subscribe",
               "malformed": "subscribe", "subscribers": "publish", "publish": "publish"}


def _ros2_names(model: Model) -> dict[str, dict[str, tuple[str, ...]]]:
    return {i.name: {"subscribe": tuple(t.name for t in i.ros2.subscribe),
                     "publish": tuple(t.name for t in i.ros2.publish)}
            for i in model.interfaces if i.ros2 is not None}


def _check_ros2_names(ros2: dict[str, dict[str, tuple[str, ...]]], sn: Snippet,
                      toks: list[Token], diags: Diagnostics) -> None:
    """E148 for ``robot.age("scn")`` when `scn` is not among the interface's names."""
    for k in range(len(toks) - 4):
        iface, dot, method, paren, arg = toks[k:k + 5]
        if (iface.kind != "ident" or iface.text not in ros2 or dot.text not in (".", "->")
                or method.text not in _ROS2_NAMES or paren.text != "(" or arg.kind != "string"
                or (k and toks[k - 1].text in _MEMBER)):
            continue
        name = _unquote(arg.text)
        option = _ROS2_NAMES[method.text]
        names = ros2[iface.text][option]
        if name is None or name in names:
            continue
        near = get_close_matches(name, names, 1)
        diags.error("E148", f"`{iface.text}.{method.text}`: `{name}` is not one of the "
                    f"interface's `{option}` ({', '.join(names) or 'none declared'})",
                    _position(sn, arg.offset),
                    f"did you mean `{near[0]}`?" if near
                    else f"declare it in the interface's `{option}`")


def _check_brackets(sn: Snippet, toks: list[Token], diags: Diagnostics) -> None:
    """E147 for a bracket the snippet leaves open or closes without opening: g++ would
    report it in the generated code after the snippet, or in the next snippets."""
    if any(line.lstrip().startswith("#") for line in sn.code.text.split("\n")):
        return  # preprocessor branches may each hold half a pair
    closers = {b: a for a, b in _PAIRS.items()}
    stack: list[Token] = []
    for tok in toks:
        if tok.kind not in ("punct", "other"):
            continue
        if tok.text in _PAIRS:
            stack.append(tok)
        elif tok.text in closers:
            if stack and stack[-1].text == closers[tok.text]:
                stack.pop()
                continue
            what = (f"`{tok.text}` closes `{stack[-1].text}`" if stack
                    else f"`{tok.text}` closes nothing")
            diags.error("E147", f"{what} in {sn.kind}{_of(sn)}", _position(sn, tok.offset))
            return
    if stack:
        tok = stack[-1]
        diags.error("E147", f"`{tok.text}` is not closed in {sn.kind}{_of(sn)}",
                    _position(sn, tok.offset),
                    f"each snippet closes its own brackets: add `{_PAIRS[tok.text]}`")


def _of(sn: Snippet) -> str:
    return f" of `{sn.where}`" if sn.where else ""


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
