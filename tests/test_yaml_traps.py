"""What YAML does that a robotics engineer does not expect (docs/quoting.md).

Tags, anchors and aliases that eat a snippet's `!`, `&&` or `*` (E105), tags
hfsmc does not define (E106), keys indented as states (E107, W213), YAML 1.1
spellings (W210, W211), durations without a unit (W212, E110) and syntax
errors explained at the line that is wrong.  The bad models of tests/invalid/
cover one case each; these tests cover the variants, the warnings and what
must stay quiet.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hfsmc.errors import Diagnostics
from hfsmc.frontend import load
from hfsmc.ir_builder import literal_traps
from hfsmc.pipeline import Result, compile_file

HEAD = "hfsm: 1\nname: m\n"
CPP = "hfsm: 1\nname: m\nlanguage: cpp\n"
TWO = "initial: A\nstates:\n  A:\n    transitions:\n      - to: B\n{t}  B: {{final: true}}\n"


def comp(body: str, head: str = HEAD, name: str = "m.yaml") -> Result:
    return compile_file(name, text=head + body)


def codes(r: Result, prefix: str = "") -> list[tuple[str, int, int]]:
    return [(d.code, d.span.line, d.span.col) for d in r.diagnostics if d.code.startswith(prefix)]


def transition(*lines: str) -> str:
    """TWO with these lines in A's transition to B (the first is on line 8 after HEAD)."""
    return TWO.format(t="".join(f"        {x}\n" for x in lines))


# ---------------------------------------------------------------------------
# E105: a tag, an anchor or an alias on a snippet


@pytest.mark.parametrize(("line", "col"), [
    ("when: !armed", 15),
    ("when: &a x", 15),
    ("when: *a", 15),
    ("do: !!str x = 1", 13),
])
def test_property_on_transition_snippet(line: str, col: int) -> None:
    r = comp(transition("after: 1s", line), head="hfsm: 1\nname: m\nx: &a 1\n")
    assert ("E105", 10, col) in codes(r), r.diagnostics
    assert r.model is None


@pytest.mark.parametrize("key", ["entry", "during", "exit"])
def test_property_on_state_snippet(key: str) -> None:
    r = comp(f"initial: A\nstates:\n  A:\n    {key}: !done()\n    final: true\n")
    assert codes(r) == [("E105", 6, len(key) + 7)]
    assert "quote the whole" in r.diagnostics[0].message


@pytest.mark.parametrize("key", ["functions", "on_shutdown"])
def test_property_on_root_snippet(key: str) -> None:
    r = comp(f"{key}: &f x = 1\ninitial: A\nstates: {{A: {{final: true}}}}\n")
    assert codes(r) == [("E105", 3, len(key) + 3)]


def test_the_message_shows_what_was_lost_and_the_quoted_fix() -> None:
    r = comp(transition("when: !drone.armed() && drone.altitude() < 0.3"), head=CPP)
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E105", 9, 15)
    assert "`!drone.armed()` as a tag and `&&` as an anchor" in d.message
    assert "the snippet would be left as `drone.altitude() < 0.3`" in d.notes
    assert "write: when: '!drone.armed() && drone.altitude() < 0.3'   (docs/quoting.md)" in d.notes


def test_block_snippet_with_anchor_is_refused_without_a_quoting_hint() -> None:
    r = comp("functions: &f |\n  x = 1\ninitial: A\nstates: {A: {final: true}}\n")
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E105", 3, 12)
    assert "remove it" in d.message


def test_alias_followed_by_code_is_a_snippet_error_not_a_parse_error() -> None:
    r = comp(transition("after: 1s", "do: *p = 1;"), head=CPP)
    assert codes(r) == [("E105", 10, 13)]


def test_cpp_init_is_a_snippet_python_init_is_a_literal() -> None:
    body = "variables:\n  a: {type: int, init: &one 1}\n  b: {type: int, init: *one}\n" \
           "initial: A\nstates: {A: {final: true}}\n"
    assert codes(comp(body, head=CPP)) == [("E105", 5, 24), ("E105", 6, 24)]
    assert comp(body).ok  # Python: YAML anchors on literals are YAML's business


def test_anchors_and_merges_elsewhere_stay_allowed() -> None:
    body = "parameters:\n  a: &p {type: int, default: 1}\n  b: *p\ninitial: A\nstates:\n" \
           "  A: &leaf\n    <<: {during: log('walking')}\n    final: true\n  B: *leaf\n"
    r = comp(body)
    assert r.ok, r.diagnostics


def test_quoted_snippets_are_untouched() -> None:
    r = comp(transition("when: '!done() and True'"), head=CPP)
    assert not codes(r, "E1"), r.diagnostics


def test_the_quoted_forms_of_docs_quoting_read_back_as_the_code() -> None:
    text = (CPP + "initial: A\nstates:\n  A:\n    entry: |\n      *target = 1;\n      if (!a && b) c();\n"
            "    transitions:\n      - to: A\n        when: '!drone.armed() && drone.altitude() < 0.3'\n"
            "        do: 'log(''landing: '' + x)'\n")
    doc = load("m.yaml", Diagnostics(), text)
    a = doc.data["states"]["A"]
    assert a["entry"] == "*target = 1;\nif (!a && b) c();\n"
    assert a["transitions"][0]["when"] == "!drone.armed() && drone.altitude() < 0.3"
    assert a["transitions"][0]["do"] == "log('landing: ' + x)"
    assert doc.span(("states", "A", "transitions", 0, "when")).col == 16  # inside the quote


# ---------------------------------------------------------------------------
# E106: tags hfsmc does not define


def test_unknown_tags_anywhere() -> None:
    body = "variables:\n  a: !meters 3\n  b: !!python/tuple [1, 2]\n" \
           "!key c: 1\ninitial: A\nstates: {A: {final: true}}\n"
    r = comp(body)
    assert codes(r) == [("E106", 4, 6), ("E106", 5, 6), ("E106", 6, 1)]
    assert "`!!python/tuple`" in r.diagnostics[1].message


def test_core_tags_are_allowed() -> None:
    r = comp("variables:\n  a: !!str 010\n  b: !!float 3\n  c: ! plain\n"
             "initial: A\nstates: {A: {final: true}}\n")
    assert r.ok and not r.diagnostics, r.diagnostics


# ---------------------------------------------------------------------------
# empty values, a missing root initial


def test_empty_value_is_reported_at_its_key() -> None:
    r = comp("initial: A\nstates:\n  A:\n    entry:\n    final: true\n")
    assert codes(r) == [("E101", 6, 5)]
    assert r.diagnostics[0].message.startswith("`entry` is empty")


def test_missing_root_initial_lists_the_states_at_the_first_key() -> None:
    r = compile_file("m.yaml", text="# a model\n\nhfsm: 1\nname: m\nstates: {A: {}, B: {final: true}}\n")
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E102", 3, 1)
    assert d.notes == ("its states: A, B",)


def test_missing_root_initial_in_xml_lists_the_states_at_the_automaton() -> None:
    text = ('<hfsm version="1" name="m">\n  <automaton period="100ms">\n'
            '    <state name="A"/>\n    <state name="B" final="true"/>\n  </automaton>\n</hfsm>\n')
    r = compile_file("m.xml", text=text)
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E102", 2, 3)
    assert d.notes == ("its states: A, B",)


# ---------------------------------------------------------------------------
# E107 / W213: a key indented as a state


def test_states_key_indented_as_a_state() -> None:
    body = "initial: A\nstates:\n  A:\n    initial: In\n  states:\n    In: {final: true}\n"
    r = comp(body)
    assert codes(r) == [("E107", 7, 3)], r.diagnostics  # the E100s under it would only confuse
    assert r.diagnostics[0].notes == ("to make it a key of `A`, start `states` at column 5, under `initial`",)


def test_nested_state_named_like_a_key() -> None:
    body = "initial: A\nstates:\n  A:\n    initial: B\n    states:\n      B:\n        entry: x = 1\n" \
           "      entry: y = 2\n"
    r = comp(body)
    assert codes(r) == [("E107", 10, 7)]
    assert "a state of `A`" in r.diagnostics[0].message


def test_valid_state_named_like_a_key_is_a_warning() -> None:
    r = comp("initial: A\nstates:\n  A:\n  final:\n")
    assert ("W213", 6, 3) in codes(r), r.diagnostics
    assert not any(d.severity == "error" and d.code in ("E107", "E101") for d in r.diagnostics)


def test_xml_states_named_like_keys_are_just_names() -> None:
    text = ('<hfsm version="1" name="m">\n  <automaton initial="entry">\n'
            '    <state name="entry"><transition to="final" after="1s"/></state>\n'
            '    <state name="final" final="true"/>\n  </automaton>\n</hfsm>\n')
    r = compile_file("m.xml", text=text)
    assert r.ok and not r.diagnostics, r.diagnostics


# ---------------------------------------------------------------------------
# W210 / W211: YAML 1.1 spellings


def test_yaml11_booleans_in_variables() -> None:
    body = "variables:\n  armed: no\n  flags: [on, 'off', Yes]\n  s: {type: str, init: y}\n" \
           "  l: {type: list, init: [n]}\ninitial: A\nstates: {A: {final: true}}\n"
    r = comp(body)
    assert codes(r) == [("W210", 4, 10), ("W210", 5, 11), ("W210", 5, 22), ("W210", 7, 26)]
    assert r.ok
    d = r.diagnostics[0]
    assert "not the boolean false" in d.message
    assert d.notes == ("write `false` for a boolean, or 'no' in quotes to keep the string",)


def test_yaml11_boolean_declared_bool_is_an_error_with_the_fix() -> None:
    r = comp("parameters:\n  armed: {type: bool, default: off}\ninitial: A\nstates: {A: {final: true}}\n")
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E101", 4, 32)
    assert "write `false`" in d.notes[0]


@pytest.mark.parametrize(("value", "warned"), [
    ("010", True), ("-0755", True), ("09", True), ("+012", True),
    ("07", False), ("0", False), ("10", False), ("0o10", False), ("0x10", False), ("010.5", False),
])
def test_leading_zero_integers(value: str, warned: bool) -> None:
    r = comp(f"parameters:\n  n: {{type: float, default: {value}}}\ninitial: A\nstates: {{A: {{final: true}}}}\n")
    assert codes(r, "W") == ([("W211", 4, 29)] if warned else []), r.diagnostics


def test_leading_zero_message() -> None:
    r = comp("variables:\n  mode: 0644\ninitial: A\nstates: {A: {final: true}}\n")
    [d] = r.diagnostics
    assert d.message == "`0644` is 644 here, not octal 420 as YAML 1.1 and C read it"
    assert d.notes == ("write `644`, or `0o644` for octal 420",)


def test_xml_values_are_checked_alike() -> None:
    text = ('<hfsm version="1" name="m">\n  <parameter name="a" type="int" default="010"/>\n'
            '  <parameter name="b" type="bool" default="yes"/>\n'
            '  <automaton initial="A" period="100"><state name="A" final="true"/></automaton>\n</hfsm>\n')
    r = compile_file("m.xml", text=text)
    assert codes(r) == [("W211", 2, 43), ("E101", 3, 44), ("W212", 4, 34)], r.diagnostics
    assert "write `true`" in r.diagnostics[1].notes[0]


def test_literal_traps_checks_any_path_a_later_with_binding_names() -> None:
    text = HEAD + "x-with:\n  Sub: {armed: no, mask: 0777}\ninitial: A\nstates: {A: {final: true}}\n"
    diags = Diagnostics()
    doc = load("m.yaml", diags, text)
    literal_traps(doc, ("x-with", "Sub"), None, diags)
    assert [(d.code, d.span.line, d.span.col) for d in diags] == [("W210", 4, 16), ("W211", 4, 26)]


# ---------------------------------------------------------------------------
# W212 / E110: durations


@pytest.mark.parametrize(("lines", "found"), [
    (("after: 5",), [("W212", 8, 16)]),
    (("after: '250'",), [("W212", 8, 17)]),
    (("after: 0",), []),
    (("after: 5ms",), []),
    (("after: 2s",), []),
])
def test_bare_number_durations(lines: tuple[str, ...], found: list[tuple[str, int, int]]) -> None:
    r = comp(transition(*lines))
    assert codes(r) == found, r.diagnostics
    if found:
        assert r.ok
        assert r.diagnostics[0].notes[0].startswith("write `")


def test_bare_number_period_keeps_its_meaning() -> None:
    r = comp("period: 20\ninitial: A\nstates: {A: {final: true}}\n")
    assert codes(r) == [("W212", 3, 9)]
    assert r.model is not None and r.model.root.period_ms == 20


@pytest.mark.parametrize(("value", "hint"), [("0.1", "100ms"), ("2.5", "2.5s"), ("0.25", "250ms")])
def test_fractional_number_suggests_a_unit(value: str, hint: str) -> None:
    r = comp(transition(f"after: {value}"))
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E110", 8, 16)
    assert d.notes == (f"if it means seconds, write `{hint}`",)


def test_legacy_imports_keep_bare_numbers_quietly() -> None:
    for path in sorted(Path("tests/legacy/corpus").glob("*/*.xml"))[:2]:
        r = compile_file(str(path))
        assert not codes(r, "W21"), r.diagnostics


# ---------------------------------------------------------------------------
# syntax errors in words, at the line that is wrong


def syntax(text: str) -> tuple[str, int, int, str, tuple[str, ...]]:
    r = compile_file("m.yaml", text=text)
    [d] = r.diagnostics
    return d.code, d.span.line, d.span.col, d.message, d.notes


def test_quote_closed_only_on_a_later_line() -> None:
    code, line, col, message, notes = syntax(
        "hfsm: 1\nname: m\ninitial: A\nstates:\n  A:\n    entry: 'log(hi)\n    exit: 'log(bye)'\n")
    assert (code, line, col) == ("E002", 6, 12)
    assert "not closed on its line" in message and "line 7" in message
    assert any(n.startswith("the YAML parser says:") for n in notes)


def test_tab_in_indentation() -> None:
    code, line, col, message, _ = syntax("hfsm: 1\nname: m\nstates:\n\tA: {}\n")
    assert (code, line, col) == ("E002", 4, 1)
    assert message == "a tab in the indentation: YAML indents with spaces only"


def test_character_that_cannot_start_a_value() -> None:
    code, line, col, message, _ = syntax("hfsm: 1\nname: m\ndescription: @home\n")
    assert (code, line, col) == ("E002", 3, 14)
    assert message.startswith("`@` cannot start a value")


def test_key_at_no_level_names_the_levels_around_it() -> None:
    code, line, col, message, notes = syntax(
        "hfsm: 1\nname: m\ninitial: A\nstates:\n  A:\n      entry: x = 1\n    exit: y = 2\n")
    assert (code, line, col) == ("E002", 7, 5)
    assert message == "`exit` at column 5 lines up with no key or list item above it: its indentation is wrong"
    assert notes[0] == ("the keys and items above start at column 7 (`entry`, line 6), column 3 (`A`, "
                        "line 5): line it up with one of them")


def test_list_item_at_no_level() -> None:
    code, line, col, message, _ = syntax(
        HEAD + "initial: A\nstates:\n  A:\n    transitions:\n      - {to: A, after: 1s}\n"
        "       - {to: A, after: 2s}\n")
    assert (code, line, col) == ("E002", 8, 8)
    assert message.startswith("this list item at column 8 lines up with no key")


def test_key_under_the_dash_of_a_list_item() -> None:
    code, line, col, message, _ = syntax(
        HEAD + "initial: A\nstates:\n  A:\n    transitions:\n      - to: A\n      after: 1s\n")
    assert (code, line, col) == ("E002", 8, 7)
    assert message == ("`after` lines up with the `-` of the list item on line 7: a key of that item "
                       "starts at column 9, a new item with `- `")


def test_transitions_written_as_a_mapping_says_to_start_items_with_a_dash() -> None:
    r = comp("initial: A\nstates:\n  A:\n    transitions:\n      to: A\n      after: 1s\n")
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E101", 7, 7)
    assert d.notes == ("each transition is a list item: start it with `- ` (`- to: B`)",)


def test_block_line_indented_less_than_the_first_one() -> None:
    code, line, col, message, _ = syntax(
        HEAD + "initial: A\nstates:\n  A:\n    entry: |\n        led = True\n      count = 1\n"
        "    final: true\n")
    assert (code, line, col) == ("E002", 8, 7)
    assert message == ("this line is indented less than the first line of the `entry` block "
                       "(line 7, column 9), so the block ends above it")


def test_first_key_of_the_document_indented() -> None:
    code, line, col, message, _ = syntax("# a model\n hfsm: 1\nname: m\n")
    assert (code, line, col) == ("E002", 2, 2)
    assert message.startswith("`hfsm` is indented")


def test_bracket_inside_a_flow_mapping() -> None:
    code, line, col, message, _ = syntax(
        HEAD + "initial: A\nstates:\n  A: {transitions: [{to: A, when: a[0] > 1}]}\n")
    assert (code, line, col) == ("E002", 5, 40)
    assert message.startswith("YAML cannot read `>` here, inside a `{...}` or `[...]`: quote code")
    code, line, col, message, _ = syntax(
        HEAD + "initial: A\nstates:\n  A: {transitions: [{to: A, when: x >= a[r}]}\n")
    assert (code, line, col) == ("E002", 5, 41)
    assert message.startswith("YAML cannot read `[` here, inside a `{...}` or `[...]` that ends with `}`")


def test_quoted_key_never_closed_on_its_line() -> None:
    code, line, col, message, _ = syntax(
        HEAD + "initial: A\nstates:\n  A:\n    \"    transitions:\n      - {to: A, when: \"x\"}\n")
    assert (code, line, col) == ("E002", 6, 5)
    assert message == 'this `"` is not closed on its line: YAML reads on to the `"` on line 7'


def test_colon_inside_a_value_suggests_the_quoted_value() -> None:
    code, line, col, _, notes = syntax("hfsm: 1\nname: m\ndescription: mode: homing\n")
    assert (code, line, col) == ("E002", 3, 18)
    assert notes[0] == "write: description: 'mode: homing'"


def test_every_colon_inside_a_value_is_reported_in_one_run() -> None:
    """Three unquoted `: ` in a model: one run names the three, each with its fix, at its
    own place; an error of another kind after them is not guessed at."""
    r = comp("description: mode: homing\ninitial: A\nstates:\n  A:\n    entry: log: x\n"
             "    transitions:\n      - to: B\n        when: ready: now\n  B: {final: true}\n")
    assert codes(r) == [("E002", 3, 18), ("E002", 7, 15), ("E002", 10, 20)]
    assert [d.notes[0] for d in r.diagnostics] == [
        "write: description: 'mode: homing'", "write: entry: 'log: x'", "write: when: 'ready: now'"]
    # another syntax error below the first: said only once the colon is fixed
    r = comp("description: mode: homing\ninitial: A\nstates:\n  A: {final: true\n")
    assert codes(r) == [("E002", 3, 18)]


@pytest.mark.parametrize(("value", "what"), [
    ("- x", "a list entry"), ("? x", "a complex mapping key"), ("> 3", "a folded block"),
    ("| x", "a literal block"), ("`x`", None), ("%x", None), ("ready ? a : b", None),
])
def test_indicators_at_the_start_of_a_snippet(value: str, what: str | None) -> None:
    code, line, col, message, _ = syntax(HEAD + transition(f"when: {value}"))
    if value.startswith("ready"):
        assert (code, line, col) == ("E002", 8, 25)
        assert message.startswith("`: ` inside a value that is not quoted")
        return
    assert (code, line, col) == ("E002", 8, 15)
    assert message.startswith(f"`{value[0]}` ")
    if what is not None:
        assert what in message


def test_comma_in_flow_mapping_code_says_why() -> None:
    r = comp("variables: {a: 1, b: 2}\ninitial: A\nstates:\n  A: {transitions: [{to: A, when: max(a, b) > 1}]}\n")
    [d] = r.diagnostics
    assert (d.code, d.span.line, d.span.col) == ("E100", 6, 42)
    assert "a `,` ends a value" in d.notes[-1]


def test_unclosed_flow_list_is_reported_at_its_bracket() -> None:
    code, line, col, message, _ = syntax(
        "hfsm: 1\nname: m\ninitial: A\nstates:\n  A: {transitions: [{to: A, after: 1s}\n  B: {}\n")
    assert (code, line, col) == ("E002", 5, 20)
    assert "never closed" in message


# ---------------------------------------------------------------------------
# the examples stay clean


def test_examples_raise_none_of_these_warnings() -> None:
    examples = [p / f"{p.name}.yaml" for p in sorted(Path("examples").iterdir())
                if (p / f"{p.name}.yaml").is_file()]
    assert examples
    for path in examples:
        r = compile_file(str(path))
        assert r.ok and not codes(r, "W21"), (path, r.diagnostics)
