"""Random valid models (sub-automata and parallel regions nested) survive YAML → XML → YAML
with an equal IR; a hand-written model with nested regions goes both ways."""

from __future__ import annotations

import io
from collections.abc import Callable
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ruamel.yaml import YAML

from hfsmc.emit.ir_text import dump
from hfsmc.emit.xml import to_xml
from hfsmc.emit.yaml import _styled, to_yaml
from hfsmc.pipeline import compile_file

IDENT = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True)
# Printable text with quotes, markup characters and non-ASCII, as code may hold.
TEXT = st.text(st.characters(codec="utf-8", exclude_categories=("Cs", "Cc")), max_size=12)
DURATION = st.sampled_from(["1ms", "50ms", "100ms", "1s", "1.5s", "2m", 250, "0.5ms"])
PERIOD = st.sampled_from(["1ms", "20ms", "100ms", "1s", 40])


@st.composite
def snippets(draw: st.DrawFn, kind: str) -> str:
    """Valid code using the model's variables x (int) and s (str)."""
    s = draw(TEXT)
    if kind == "when":
        return draw(st.sampled_from([f"x > {draw(st.integers(-5, 5))}", "True", "s == " + repr(s),
                                     "elapsed() > 0.5 and not done()", "x < 3 or s != '<&>'"]))
    lines = draw(st.lists(st.sampled_from([
        "x = x + 1", f"s = {s!r}", "log(s)", "if x > 2:\n    x = 0", 'log("a < b & \\"c\\"")',
        "s = '''tri\nple'''", "x = 1  # comment ]]> <!-- -->",
    ]), min_size=1, max_size=3))
    return "\n".join(lines)


# What writes a snippet of a kind (`entry`, `when`, ...): `snippets` unless a test needs other code.
Code = Callable[[str], st.SearchStrategy[str]]


@st.composite
def states(draw: st.DrawFn, depth: int, code: Code = snippets) -> dict[str, Any]:
    names = draw(st.lists(IDENT, min_size=1, max_size=4, unique=True))
    out: dict[str, Any] = {}
    for name in names:
        node: dict[str, Any] = {}
        for kind in ("entry", "during", "exit"):
            if draw(st.booleans()):
                node[kind] = draw(code(kind))
        if depth > 0 and draw(st.booleans()):
            if draw(st.integers(0, 2)) == 0:  # parallel regions, each a sub-automaton
                regions = draw(st.lists(IDENT, min_size=2, max_size=2, unique=True))
                node["regions"] = {r: draw(automata(depth - 1, code)) for r in regions}
            else:
                node.update(draw(automata(depth - 1, code)))
        elif draw(st.booleans()):
            node["final"] = True
        if not node.get("final"):
            trans = []
            for _ in range(draw(st.integers(0, 3))):
                t: dict[str, Any] = {"to": draw(st.sampled_from(names))}
                if draw(st.booleans()):
                    t["when"] = draw(code("when"))
                if "when" not in t or draw(st.booleans()):
                    t["after"] = draw(DURATION)
                if draw(st.booleans()):
                    t["do"] = draw(code("do"))
                if draw(st.booleans()):
                    t["name"] = draw(TEXT)
                trans.append(t)
            if trans:
                node["transitions"] = trans
        out[name] = node
    return out


@st.composite
def automata(draw: st.DrawFn, depth: int, code: Code = snippets) -> dict[str, Any]:
    """A sub-automaton or a region: states, initial, and maybe period and history."""
    node: dict[str, Any] = {"states": draw(states(depth, code))}
    node["initial"] = draw(st.sampled_from(sorted(node["states"])))
    if draw(st.booleans()):
        node["period"] = draw(PERIOD)
    if draw(st.booleans()):
        node["history"] = draw(st.booleans())
    return node


@st.composite
def models(draw: st.DrawFn) -> dict[str, Any]:
    root = draw(states(2))
    m: dict[str, Any] = {"hfsm": 1, "name": draw(IDENT), "language": "python"}
    if draw(st.booleans()):
        m["description"] = draw(TEXT)
    m["imports"] = draw(st.lists(st.sampled_from(["math", "json as j", "from os import path"]),
                                 unique=True, max_size=2))
    m["parameters"] = {"p": {"type": "float", "default": draw(st.floats(-1e6, 1e6, allow_nan=False))},
                       "q": {"type": "str", "default": draw(TEXT)}}
    m["variables"] = {"x": draw(st.integers(-10**6, 10**6)), "s": draw(TEXT),
                      "l": {"type": "list", "init": draw(st.lists(st.integers(), max_size=3))},
                      "d": {"type": "dict", "init": {"k": draw(TEXT)}}}
    if draw(st.booleans()):
        m["functions"] = "def f():\n    return x\n"
    if draw(st.booleans()):
        m["on_interrupt"] = draw(st.sampled_from(sorted(root)))
        if draw(st.booleans()):
            m["interrupt_timeout"] = draw(DURATION)
    if draw(st.booleans()):
        m["period"] = draw(PERIOD)
    m["initial"] = draw(st.sampled_from(sorted(root)))
    m["states"] = root
    return m


def dump_yaml(data: dict[str, Any]) -> str:
    buf = io.StringIO()
    YAML(typ="rt").dump(_styled(data), buf)
    return buf.getvalue()


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(models())
def test_yaml_xml_yaml_equal_ir(data: dict[str, Any]) -> None:
    first = compile_file("m.yaml", text=dump_yaml(data))
    assert first.model is not None, first.diagnostics
    xml = to_xml(first.model)
    second = compile_file("m.xml", text=xml)
    assert second.model is not None, (second.diagnostics, xml)
    assert second.model == first.model
    third = compile_file("m2.yaml", text=to_yaml(second.model))
    assert third.model == first.model, third.diagnostics


def test_cpp_initializers_survive_xml() -> None:
    """C++ variables keep their initializer as C++ text in every format."""
    text = """\
hfsm: 1
name: cppish
language: cpp
imports: ["<vector>"]
variables:
  speed: {type: double, init: 0.5}
  ready: {type: bool, init: false}
  path: {type: "std::vector<int>", init: [1, 2, 3]}
  n: 3
initial: A
states:
  A: {entry: "speed = 1.0;", final: true}
"""
    first = compile_file("c.yaml", text=text)
    assert first.model is not None, first.diagnostics
    inits = {v.name: v.init for v in first.model.variables}
    assert inits == {"speed": "0.5", "ready": False, "path": "{1, 2, 3}", "n": 3}
    second = compile_file("c.xml", text=to_xml(first.model))
    assert second.model == first.model, second.diagnostics


NESTED = """\
hfsm: 1
name: nested
variables: {n: 0}
initial: Mission
states:
  Mission:
    entry: log("in")
    regions:
      Nav:
        period: 50ms
        initial: Go
        states:
          Go:
            initial: Climb
            history: true
            states:
              Climb: {transitions: [{to: Cruise, after: 1s}]}
              Cruise: {during: "n += 1"}
            transitions: [{to: Back, when: n > 3}]
          Back: {final: true}
      Watch:
        initial: Sensors
        states:
          Sensors:
            regions:
              Gps: {initial: Fix, states: {Fix: {final: true}}}
              Battery: {period: 1s, initial: Ok, history: true, states: {Ok: {final: true}}}
    transitions:
      - {to: Done, when: done()}
  Done: {final: true}
"""


def test_nested_regions_yaml_xml_yaml() -> None:
    """A region whose state has a sub-automaton, and regions inside a region's state."""
    first = compile_file("n.yaml", text=NESTED)
    assert first.model is not None and first.diagnostics == [], first.diagnostics
    xml = to_xml(first.model)
    second = compile_file("n.xml", text=xml)
    assert second.model == first.model, (second.diagnostics, xml)
    third = compile_file("n2.yaml", text=to_yaml(second.model))
    assert third.model == first.model, third.diagnostics
    sensors = first.model.find("Mission/Watch/Sensors")
    assert sensors is not None and [a.region for a in sensors.automata] == ["Gps", "Battery"]
    assert [a.path for a in first.model.automata()] == [
        "", "Mission/Nav", "Mission/Nav/Go", "Mission/Watch", "Mission/Watch/Sensors/Gps",
        "Mission/Watch/Sensors/Battery"]


def test_nested_regions_xml_yaml_xml() -> None:
    model = compile_file("n.yaml", text=NESTED).model
    assert model is not None
    xml = to_xml(model)
    assert '<region name="Battery" period="1s" initial="Ok" history="true">' in xml
    first = compile_file("n.xml", text=xml)
    assert first.model is not None and first.diagnostics == [], first.diagnostics
    second = compile_file("n.yaml", text=to_yaml(first.model))
    assert second.model == first.model, second.diagnostics
    assert to_xml(second.model) == xml


def test_dump_ir_shows_regions() -> None:
    """`hfsmc check --dump-ir`: a region is `region NAME of OWNER`, its states' paths hold it."""
    model = compile_file("n.yaml", text=NESTED).model
    assert model is not None
    lines = [line.strip() for line in dump(model).splitlines()]
    assert "region Nav of Mission period 50ms initial Go" in lines
    assert "automaton Mission/Nav/Go period 50ms (inherited) initial Climb history" in lines
    assert "region Watch of Mission period 100ms (inherited) initial Sensors" in lines
    assert "region Battery of Mission/Watch/Sensors period 1000ms initial Ok history" in lines
    assert "state Mission/Watch/Sensors/Gps/Fix final @26:44" in lines
    regions = [line for line in lines if line.startswith("region ")]
    assert [r.split()[1] for r in regions] == ["Nav", "Watch", "Gps", "Battery"]
