"""Property tests of the front end: no model text, however broken, crashes hfsmc.

Two mutators start from the valid examples: (a) text edits (characters, lines,
tokens, unicode, truncation, YAML tags, anchors and merge keys) and (b) edits
of the model as data (keys, value types, state names, transition targets),
dumped back to YAML.  Whatever comes out, :func:`hfsmc.pipeline.compile_file`
must return diagnostics, never raise; every diagnostic has a known code and a
position inside the text, whose line is the one shown under it; and a result
with errors has no model.

The runs are derandomized and keep no example database, so CI is reproducible.
"""

from __future__ import annotations

import copy
import io
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ruamel.yaml import YAML

from hfsmc.errors import CODES, render_json, render_text
from hfsmc.pipeline import Result, compile_file
from tests.conftest import examples

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted(str(p.relative_to(ROOT)) for p in examples())
TEXTS = {p: (ROOT / p).read_text("utf-8") for p in EXAMPLES}

FUZZ = settings(max_examples=400, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

Draw = Callable[[st.SearchStrategy[Any]], Any]


def numbered_lines(text: str) -> list[str]:
    """Lines as YAML and XML number them: only CR, LF and CRLF end a line."""
    lines = re.split(r"\r\n|\r|\n", text)
    return lines[:-1] if lines and not lines[-1] else lines


def check_result(path: str, text: str) -> Result:
    """compile_file never raises; its diagnostics are well formed and positioned."""
    result = compile_file(path, text=text)
    lines = numbered_lines(text)
    for d in result.diagnostics:
        assert d.code in CODES, d
        assert d.severity in ("error", "warning"), d
        assert d.message.strip(), d
        assert d.span.file == path, d
        assert d.span.line >= 1 and d.span.col >= 1, d
        assert d.span.line <= len(lines) + 1, f"{d} is past the end of a {len(lines)}-line text"
        if d.span.line <= len(lines):
            # The line printed under the diagnostic is the line its position means.
            shown = result.lines[d.span.line - 1] if d.span.line <= len(result.lines) else None
            assert shown == lines[d.span.line - 1], f"{d}: shows {shown!r}"
    has_errors = any(d.severity == "error" for d in result.diagnostics)
    assert (result.model is None) == has_errors, result.diagnostics
    assert result.ok == (not has_errors)
    # Rendering must not fail on whatever text and positions came out.
    render_text(result.diagnostics, {path: result.lines})
    render_json(result.diagnostics)
    return result


def test_examples_compile_cleanly() -> None:
    """The starting points of the mutators are valid models."""
    assert EXAMPLES, "no examples/*/*.yaml"
    for path, text in TEXTS.items():
        result = check_result(path, text)
        assert result.ok, [str(d) for d in result.diagnostics]


# ---------------------------------------------------------------------------
# (a) text mutations

_YAML_CHARS = ":{}[]-,#&*!|>'\"%@`? \t\n"
_WORDS = ["", " ", ":", ": ", "- ", "{", "}", "[", "]", "\t", "\n", "#", "&a", "*a", "!!int",
          "'", '"', "|", ">", "~", "null", "true", "yes", "0", "-1", "1.5", "2 sec", "0.5ms",
          "hfsm", "states", "initial", "to", "when", "after", "final", "elapsed()", "(", ")",
          "<<: ", "<<: *a", "\x00", "\ufeff", "\u2028", "\x85", "\r", "\x0c", "é", "🚁"]
# Any code point that UTF-8 can carry (no lone surrogates), control characters included.
_ANY_TEXT = st.text(alphabet=st.characters(codec="utf-8"), min_size=1, max_size=8)
_SMALL_TEXT = st.one_of(
    st.sampled_from(_WORDS),
    st.text(alphabet=_YAML_CHARS + "abcXYZ_019", min_size=1, max_size=10),
    _ANY_TEXT,
)
_TOKEN = re.compile(r"\w+|[^\w\s]")


def _pos(draw: Draw, text: str) -> int:
    return int(draw(st.integers(0, len(text))))


def delete_chars(draw: Draw, text: str) -> str:
    i = _pos(draw, text)
    return text[:i] + text[i + draw(st.integers(1, 20)):]


def duplicate_chars(draw: Draw, text: str) -> str:
    i = _pos(draw, text)
    j = min(len(text), i + draw(st.integers(1, 30)))
    return text[:j] + text[i:j] + text[j:]


def insert_text(draw: Draw, text: str) -> str:
    i = _pos(draw, text)
    return text[:i] + str(draw(_SMALL_TEXT)) + text[i:]


def insert_unicode(draw: Draw, text: str) -> str:
    i = _pos(draw, text)
    return text[:i] + str(draw(_ANY_TEXT)) + text[i:]


def truncate(draw: Draw, text: str) -> str:
    return text[:_pos(draw, text)]


def _line_op(op: Callable[[Draw, list[str], int], list[str]]) -> Callable[[Draw, str], str]:
    def mutate(draw: Draw, text: str) -> str:
        lines = text.split("\n")
        i = draw(st.integers(0, len(lines) - 1))
        return "\n".join(op(draw, lines, i))

    mutate.__name__ = op.__name__
    return mutate


@_line_op
def delete_line(draw: Draw, lines: list[str], i: int) -> list[str]:
    return lines[:i] + lines[i + 1:]


@_line_op
def duplicate_line(draw: Draw, lines: list[str], i: int) -> list[str]:
    return lines[:i + 1] + lines[i:]


@_line_op
def swap_lines(draw: Draw, lines: list[str], i: int) -> list[str]:
    j = draw(st.integers(0, len(lines) - 1))
    out = list(lines)
    out[i], out[j] = out[j], out[i]
    return out


@_line_op
def move_line(draw: Draw, lines: list[str], i: int) -> list[str]:
    out = list(lines)
    line = out.pop(i)
    out.insert(draw(st.integers(0, len(out))), line)
    return out


@_line_op
def reindent_line(draw: Draw, lines: list[str], i: int) -> list[str]:
    body = lines[i].lstrip(" ")
    indent = draw(st.sampled_from(["", " ", "  ", "   ", "    ", "        ", "\t", "  \t"]))
    return [*lines[:i], indent + body, *lines[i + 1:]]


@_line_op
def insert_line(draw: Draw, lines: list[str], i: int) -> list[str]:
    new = draw(st.one_of(st.sampled_from(lines), _SMALL_TEXT))
    return [*lines[:i], new, *lines[i:]]


_VALUE_LINE = re.compile(r"^(?P<key>\s*(?:- )?[\w-]+:[ ]+)(?P<value>[^\s|>].*)$")
_TAGS = ["!!int ", "!!float ", "!!bool ", "!!str ", "!!null ", "!!binary ", "!!timestamp ",
         "!!set ", "!!seq ", "!!map ", "!custom ", "&a ", "&b ", "*a #"]


@_line_op
def tag_value(draw: Draw, lines: list[str], i: int) -> list[str]:
    """Explicit tags, anchors and aliases on a `key: value` line."""
    m = _VALUE_LINE.match(lines[i])
    if m is None:
        return lines
    return [*lines[:i], m["key"] + draw(st.sampled_from(_TAGS)) + m["value"], *lines[i + 1:]]


@_line_op
def merge_key(draw: Draw, lines: list[str], i: int) -> list[str]:
    """A YAML merge key (`<<:`) at the indentation of a mapping's key."""
    line = lines[i]
    indent = line[:len(line) - len(line.lstrip(" "))]
    value = draw(st.sampled_from(["*a", "*b", "{}", "{final: true}", '{entry: log("x")}',
                                  "{transitions: []}", "[*a, *b]", "{x: 1}"]))
    return [*lines[:i], f"{indent}<<: {value}", *lines[i:]]


def replace_token(draw: Draw, text: str) -> str:
    tokens = list(_TOKEN.finditer(text))
    if not tokens:
        return text
    m = draw(st.sampled_from(tokens))
    other = st.sampled_from([t.group() for t in tokens])  # e.g. one state name for another
    return text[:m.start()] + str(draw(st.one_of(other, _SMALL_TEXT))) + text[m.end():]


TEXT_MUTATIONS = [delete_chars, duplicate_chars, insert_text, insert_unicode, truncate,
                  delete_line, duplicate_line, swap_lines, move_line, reindent_line,
                  insert_line, replace_token, tag_value, merge_key]


@st.composite
def mutated_texts(draw: Draw) -> tuple[str, str]:
    path = draw(st.sampled_from(EXAMPLES))
    text = TEXTS[path]
    for _ in range(draw(st.integers(1, 4))):
        text = draw(st.sampled_from(TEXT_MUTATIONS))(draw, text)
    return path, text


@FUZZ
@given(mutated_texts())
def test_text_mutations_give_diagnostics_not_crashes(case: tuple[str, str]) -> None:
    check_result(*case)


# ---------------------------------------------------------------------------
# (b) structure mutations

Node = dict[str, Any] | list[Any]
_VALUES: list[Any] = [None, True, False, 0, -1, 7, 1.5, "", "x y", "Ghost", "2 sec", "-5ms",
                      "0.5ms", "15.5ms", "100ms", "my-state", "2nd", "not a (python", [], {},
                      ["a", 1], {"a": 1}, {"to": "Ghost"}, [{"to": "Ghost", "after": "1s"}]]
_NAMES = st.one_of(
    st.sampled_from(["Ghost", "Done", "2nd", "my-state", "", "class", "None", "hfsm", "a b"]),
    st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True),
)


def _load(text: str) -> Any:
    return YAML(typ="safe", pure=True).load(text)


def _dump(data: Any) -> str:
    y = YAML(typ="safe", pure=True)
    y.default_flow_style = False
    y.allow_unicode = True
    buf = io.StringIO()
    y.dump(data, buf)
    return buf.getvalue()


def _slots(node: Any) -> list[tuple[Node, Any]]:
    """Every (container, key or index) in the tree, depth first."""
    out: list[tuple[Node, Any]] = []
    stack = [node]
    while stack:
        n = stack.pop()
        if isinstance(n, dict):
            for k, v in n.items():
                out.append((n, k))
                stack.append(v)
        elif isinstance(n, list):
            for i, v in enumerate(n):
                out.append((n, i))
                stack.append(v)
    return out


def _state_maps(data: Any) -> list[dict[str, Any]]:
    """Every `states` mapping (the root's and the sub-automata's)."""
    return [c[k] for c, k in _slots({"": data})
            if k == "states" and isinstance(c, dict) and isinstance(c[k], dict) and c[k]]


def _region_maps(data: Any) -> list[dict[str, Any]]:
    """Every `regions` mapping (a state's parallel regions)."""
    return [c[k] for c, k in _slots({"": data})
            if k == "regions" and isinstance(c, dict) and isinstance(c[k], dict) and c[k]]


def _transitions(data: Any) -> list[dict[str, Any]]:
    return [t for c, k in _slots({"": data})
            if k == "transitions" and isinstance(c, dict) and isinstance(c[k], list)
            for t in c[k] if isinstance(t, dict)]


def delete_key(draw: Draw, data: Any) -> None:
    slots = [(c, k) for c, k in _slots(data) if isinstance(c, dict)]
    if slots:
        c, k = draw(st.sampled_from(slots))
        del c[k]


def change_value(draw: Draw, data: Any) -> None:
    slots = _slots(data)
    if slots:
        c, k = draw(st.sampled_from(slots))
        c[k] = copy.deepcopy(draw(st.sampled_from(_VALUES)))


def add_key(draw: Draw, data: Any) -> None:
    maps = [data, *(c[k] for c, k in _slots(data) if isinstance(c[k], dict))]
    target = draw(st.sampled_from(maps))
    key = draw(st.sampled_from(["transition", "inital", "final", "period", "states", "initial",
                                "history", "on_interrupt", "when", "to", "after", "entry",
                                "interrupt_timeout", "hfsm", "regions"]))
    target[key] = copy.deepcopy(draw(st.sampled_from(_VALUES)))


def rename_state(draw: Draw, data: Any) -> None:
    """Rename a state or a region."""
    maps = _state_maps(data) + _region_maps(data)
    if not maps:
        return
    states = draw(st.sampled_from(maps))
    old = draw(st.sampled_from(list(states)))
    new = draw(_NAMES)
    items = [(new if k == old else k, v) for k, v in states.items()]
    states.clear()
    states.update(items)


def retarget(draw: Draw, data: Any) -> None:
    trans = _transitions(data)
    if not trans:
        return
    everywhere = [name for m in _state_maps(data) for name in m]
    t = draw(st.sampled_from(trans))
    t["to"] = draw(st.one_of(st.sampled_from(everywhere or ["Ghost"]), _NAMES))


def nest_state(draw: Draw, data: Any) -> None:
    """Copy a state into another state, which becomes (or stays) composite."""
    maps = _state_maps(data)
    if not maps:
        return
    src = draw(st.sampled_from(maps))
    name = draw(st.sampled_from(list(src)))
    hosts = [s for m in maps for s in m.values() if isinstance(s, dict)]
    if not hosts:
        return
    host = draw(st.sampled_from(hosts))
    children = host.setdefault("states", {})
    if isinstance(children, dict):
        children[name] = copy.deepcopy(src[name])
        if draw(st.booleans()):
            host["initial"] = name


def make_regions(draw: Draw, data: Any) -> None:
    """Copy a composite state's sub-automaton into one to three regions, dropping it or not."""
    hosts = [s for m in _state_maps(data) for s in m.values()
             if isinstance(s, dict) and isinstance(s.get("states"), dict) and s["states"]]
    if not hosts:
        return
    host = draw(st.sampled_from(hosts))
    sub = {k: host[k] for k in ("initial", "period", "history", "states") if k in host}
    names = draw(st.lists(_NAMES, min_size=1, max_size=3))
    host["regions"] = {name: copy.deepcopy(sub) for name in names}
    if draw(st.booleans()):
        for k in sub:
            del host[k]


def make_final(draw: Draw, data: Any) -> None:
    hosts = [s for m in _state_maps(data) for s in m.values() if isinstance(s, dict)]
    if hosts:
        draw(st.sampled_from(hosts))["final"] = True


DATA_MUTATIONS = [delete_key, change_value, add_key, rename_state, retarget, nest_state,
                  make_final, make_regions]


@st.composite
def mutated_models(draw: Draw) -> tuple[str, str]:
    path = draw(st.sampled_from(EXAMPLES))
    data = _load(TEXTS[path])
    for _ in range(draw(st.integers(1, 3))):
        draw(st.sampled_from(DATA_MUTATIONS))(draw, data)
    return path, _dump(data)


@pytest.mark.parametrize("path", EXAMPLES)
def test_dumped_examples_stay_valid(path: str) -> None:
    """Load + dump alone changes nothing hfsmc cares about (so (b) tests the mutations)."""
    assert check_result(path, _dump(_load(TEXTS[path]))).ok


@FUZZ
@given(mutated_models())
def test_structure_mutations_give_diagnostics_not_crashes(case: tuple[str, str]) -> None:
    check_result(*case)
