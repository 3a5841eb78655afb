"""The YAML front end, the IR builder and the passes, through compile_file."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from hfsmc.durations import format_us, parse_us
from hfsmc.ir import Model
from hfsmc.pipeline import Result, compile_file

HEAD = "hfsm: 1\nname: m\n"


def comp(body: str, head: str = HEAD) -> Result:
    return compile_file("m.yaml", text=head + body)


def codes(r: Result) -> list[tuple[str, int, int]]:
    return [(d.code, d.span.line, d.span.col) for d in r.diagnostics]


def model(body: str) -> Model:
    r = comp(body)
    assert r.model is not None, r.diagnostics
    return r.model


NESTED = """\
period: 200ms
initial: Outer
states:
  Outer:
    initial: Mid
    states:
      Mid:
        period: 20ms
        initial: Leaf
        states:
          Leaf: {during: "x = 1"}
      Other: {}
    transitions: [{to: Outer, after: 1s}]
"""


def test_periods_are_inherited() -> None:
    m = model(NESTED)
    outer = m.find("Outer")
    mid = m.find("Outer/Mid")
    assert m.root.period_ms == 200 and m.root.period_written
    assert outer is not None and outer.automaton is not None
    assert outer.automaton.period_ms == 200 and not outer.automaton.period_written
    assert mid is not None and mid.automaton is not None and mid.automaton.period_ms == 20
    assert [s.path for s in m.states()] == ["Outer", "Outer/Mid", "Outer/Mid/Leaf", "Outer/Other"]


def test_default_root_period_is_100ms() -> None:
    assert model("initial: A\nstates: {A: {final: true}}\n").root.period_ms == 100


def test_ir_is_frozen_and_equality_ignores_spans() -> None:
    a = model(NESTED)
    b = compile_file("elsewhere.yaml", text=HEAD + "\n\n" + NESTED).model
    assert a == b
    assert a.root.states[0].span != b.root.states[0].span
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.name = "other"  # type: ignore[misc]
    assert a != model(NESTED.replace("20ms", "30ms"))


def test_block_snippet_positions() -> None:
    body = """\
initial: A
states:
  A:
    final: true
    during: |
      a = 1
      b = a +
"""
    assert codes(comp(body)) == [("E140", 9, 14)]


def test_quoted_snippet_column() -> None:
    r = comp('initial: A\nstates:\n  A: {entry: "y = nope", final: true}\n')
    assert codes(r) == [("E141", 5, 19)]


def test_cross_level_target_names_where_it_is() -> None:
    r = comp(NESTED.replace("[{to: Outer, after: 1s}]", "[{to: Leaf, after: 1s}]"))
    (d,) = [d for d in r.diagnostics if d.code == "E133"]
    assert (d.span.line, d.span.col) == (15, 24)
    assert "Outer/Mid/Leaf" in d.notes[0]


def test_foreign_initial() -> None:
    r = comp(NESTED.replace("initial: Mid", "initial: Leaf"))
    assert ("E131", 7, 14) in codes(r)


def test_helpers_imports_functions_are_known() -> None:
    body = """\
imports: [math, numpy as np, "from os import path as p"]
interfaces: {drone: {type: mavlink, url: "udpin:127.0.0.1:14550"}}
parameters: {alt: {type: float, default: 3}}
variables: {v: 0}
functions: |
  def helper(k):
      global v
      v = k + math.pi
initial: A
states:
  A:
    entry: helper(alt); log(str(np)); p.join("a")
    during: "v = elapsed() + now() + (1 if done() else 0) + active('A')"
    transitions: [{to: A, when: drone.armed() and v > 0}, {to: A, after: 1s, do: shutdown()}]
"""
    r = comp(body)
    assert r.ok, r.diagnostics
    assert r.model is not None and r.model.parameters[0].default == 3.0


def test_parameter_writes_refused_even_in_functions() -> None:
    body = """\
parameters: {alt: {type: float, default: 3}}
functions: |
  def f():
      global alt
      alt = 1
  def g():
      alt = 2
      return [alt for alt in range(3)]
initial: A
states:
  A: {entry: "alt += 1", final: true}
"""
    assert [c for c in codes(comp(body)) if c[0] == "E142"] == [("E142", 7, 7), ("E142", 13, 15)]


def test_structure_errors_all_reported() -> None:
    body = """\
on_interrupt: Nowhere
initial: A
states:
  A:
    final: true
    transitions: [{to: A, after: 1s}]
  B:
    final: true
    initial: C
    states: {C: {}}
  D:
    period: 10ms
  E:
    transitions: [{to: A}]
"""
    got = {c[0] for c in codes(comp(body))}
    assert {"E136", "E134", "E135", "E138", "E137"} <= got


def test_flow_warnings() -> None:
    body = """\
initial: A
on_interrupt: Stuck
states:
  A: {transitions: [{to: B, when: "True"}, {to: C, when: "1 > 0"}]}
  B: {}
  C: {final: true}
  Island: {final: true}
  Stuck: {}
"""
    r = comp(body)
    assert r.ok
    got = {(d.code, d.span.line) for d in r.diagnostics}
    assert got == {("W203", 6), ("W202", 7), ("W201", 9), ("W202", 10), ("W204", 10)}


def test_language_cpp_skips_python_checks() -> None:
    r = comp("language: cpp\ninitial: A\nstates: {A: {entry: 'int x = 1;', final: true}}\n")
    assert r.ok, r.diagnostics


def test_yaml_alias_bomb_refused_fast() -> None:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9)]
    r = comp("\n".join(lines) + "\n")
    assert codes(r) == [("E006", 1, 1)]


def test_deep_nesting_refused() -> None:
    text = HEAD + "x: " + "[" * 3000 + "]" * 3000 + "\n"
    r = compile_file("deep.yaml", text=text)
    assert [d.code for d in r.diagnostics] == ["E006"]


def test_non_mapping_document() -> None:
    assert codes(compile_file("l.yaml", text="- a\n- b\n")) == [("E005", 1, 1)]


@given(st.integers(min_value=0, max_value=10**12))
@example(123_456_700_000)  # more significant digits than a float's %g shows
@example(1)
def test_durations_round_trip(us: int) -> None:
    assert parse_us(format_us(us)) == us


@pytest.mark.parametrize(("text", "us"), [("250ms", 250_000), ("2s", 2_000_000), ("1.5s", 1_500_000),
                                          ("2m", 120_000_000), (450, 450_000), ("0.5ms", 500)])
def test_duration_spellings(text: str | int, us: int) -> None:
    assert parse_us(text) == us


@pytest.mark.parametrize("bad", ["2 sec", "-5ms", "1e3ms", "", "ms", True, 1.5, "0.0000001s"])
def test_bad_durations(bad: object) -> None:
    assert parse_us(bad) is None


def _many_states(n: int, bad: int) -> str:
    lines = ["variables: {v: 0}", "initial: S0", "states:"]
    for i in range(n):
        entry = "v = missing_name + 1" if i == bad else f"v = v + {i}"
        lines.append(f"  S{i}: {{entry: '{entry}', transitions: [{{to: S{(i + 1) % n}, after: 1s}}]}}")
    return "\n".join(lines) + "\n"


def test_undefined_name_found_past_chunk_boundaries() -> None:
    """Snippets are checked in chunks; positions stay exact in every chunk."""
    r = comp(_many_states(350, bad=237))
    assert codes(r) == [("E141", 6 + 237, 22)]


def test_snippets_checked_one_by_one_when_a_chunk_does_not_parse(monkeypatch: pytest.MonkeyPatch) -> None:
    from hfsmc import pycheck

    real = pycheck._joined

    def picky(group: list[pycheck.Snippet], variables: list[str]) -> object:
        return None if len(group) > 1 else real(group, variables)

    monkeypatch.setattr(pycheck, "_joined", picky)
    r = comp(_many_states(30, bad=17))
    assert codes(r) == [("E141", 6 + 17, 21)]


def test_undefined_name_suggests_a_model_name() -> None:
    r = comp("parameters: {speed: {type: float, default: 1}}\ninitial: A\n"
             "states:\n  A: {during: 'x = speeed', final: true}\n")
    (d,) = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E141", 6, 20)
    assert d.notes == ("did you mean `speed`?",)
