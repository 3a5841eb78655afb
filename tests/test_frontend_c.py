"""The libyaml path of the YAML front end (hfsmc/frontend/yaml_c.py) reads every
document it takes exactly as the ruamel.yaml path does: same data, same
positions, same diagnostics, same IR; and it hands to ruamel.yaml every document
it does not read as ruamel does (syntax errors, tags, merge keys...)."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings

import hfsmc.frontend.yaml as front
from hfsmc.errors import Diagnostics, ParseError
from hfsmc.frontend import read_text, yaml_c
from hfsmc.frontend.source import Document
from hfsmc.frontend.yaml import load_yaml_with
from hfsmc.pipeline import Result, compile_file
from tests.conftest import ROOT, examples
from tests.test_fuzz_frontend import FUZZ, mutated_texts

pytestmark = pytest.mark.skipif(not yaml_c.AVAILABLE, reason="PyYAML with libyaml is not installed")

MODELS = sorted(str(p.relative_to(ROOT)) for p in [
    *examples(), *(ROOT / "examples" / "lib").glob("*.yaml"), *(ROOT / "tests" / "invalid").glob("*.yaml")])


def _load(path: str, text: str, parser: front.Parser) -> tuple[Any, str]:
    """Everything the front end hands on (or the parse error's text), and who read it."""
    diags = Diagnostics()
    try:
        doc, used = load_yaml_with(path, text, diags, parser)
    except ParseError as e:
        return ("error", str(e)), "error"
    return (doc.data, doc.spans, doc.key_spans, doc.cont_cols, doc.segments, doc.yaml11,
            [str(d) for d in diags]), used


def _compile(path: str, monkeypatch: pytest.MonkeyPatch, parser: str) -> Result:
    with monkeypatch.context() as m:
        if parser == "ruamel":
            m.setattr(front, "load_c", lambda doc, text: "the test asks for ruamel.yaml")
        return compile_file(path)


@pytest.mark.parametrize("path", MODELS)
def test_both_parsers_give_the_same_ir_and_diagnostics(path: str, monkeypatch: pytest.MonkeyPatch) -> None:
    try:
        text = read_text(path)
    except ParseError:  # refused before any parser sees it (E001)
        text = ""
    if text:
        ruamel, _ = _load(path, text, "ruamel")
        fast, _ = _load(path, text, "auto")
        assert fast == ruamel
    slow = _compile(path, monkeypatch, "ruamel")
    quick = _compile(path, monkeypatch, "auto")
    assert [str(d) for d in quick.diagnostics] == [str(d) for d in slow.diagnostics]
    assert [d.notes for d in quick.diagnostics] == [d.notes for d in slow.diagnostics]
    assert quick.model == slow.model


def test_examples_are_read_by_libyaml() -> None:
    """Anchors and aliases (examples/follow_colors) stay on the fast path."""
    for p in examples():
        path = str(p.relative_to(ROOT))
        if path.endswith(".yaml"):
            _, used = _load(path, read_text(path), "auto")
            assert used == "libyaml", path


ALIASES = """\
hfsm: 1
name: a
initial: A
states:
  A:
    entry: &e 'x = 1'
    transitions: &t
      - {to: B, after: 1s}
    states: &s
      S1: {entry: "y = 0010", transitions: [{to: S2, when: "yes"}]}
      S2:
        during: >
          z = 1
          + 2
  B:
    transitions: *t
    states: *s
"""


@pytest.mark.parametrize("text, reason", [
    (ALIASES, "an anchor or an alias on a snippet"),
    (ALIASES.replace("&e ", ""), None),
    ("hfsm: 1\nname: !!str a\n", "a tag"),
    ("hfsm: 1\nname: ! a\n", "a tag"),
    ("%YAML 1.1\n---\nhfsm: 1\n", "a directive, a tab, a BOM or a NEL/LS/PS character"),
    ("hfsm: 1\nname: a\nname: b\n", "a duplicate key"),
    ("hfsm: 1\n1: a\n", "a key that is not a string"),
    ("hfsm: 1\nx: &a {y: 1}\nz:\n  <<: *a\n", "a plain scalar resolved to tag:yaml.org,2002:merge"),
    ("hfsm: 1\nname:\n", "an empty value"),
    ("hfsm: 1\nname: [a\n", "libyaml found an error"),
    ("hfsm: 1\n---\nhfsm: 1\n", "more than one document"),
    ("a: &x [1, *x]\n", "an alias to an anchor not closed yet"),
    ("a: 2020-13-45\n", "a value that cannot be constructed"),
    ("a: " + "[" * 150 + "]" * 150 + "\n", "deep nesting"),
    ("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"a{i}: &a{i} [{', '.join(['*a' if i == 1 else f'*a{i - 1}'] * 10)}]\n" for i in range(1, 7)),
     "too many values through aliases"),
])
def test_what_goes_to_ruamel(text: str, reason: str | None) -> None:
    fast, used = _load("m.yaml", text, "auto")
    ruamel, _ = _load("m.yaml", text, "ruamel")
    assert used == ("libyaml" if reason is None else f"ruamel: {reason}") or used == "error"
    if reason is not None:
        with pytest.raises(RuntimeError, match=reason.split(" or ")[0]):
            load_yaml_with("m.yaml", text, Diagnostics(), "libyaml")
    assert fast == ruamel


def test_deep_nesting_does_not_crash_libyaml() -> None:
    """libyaml's own composer recurses once per level (a segfault at 100,000 levels);
    the event reader gives up at MAX_C_DEPTH instead."""
    text = "a: " + "[" * 200_000 + "]" * 200_000 + "\n"
    # Either way the document goes to ruamel.yaml. In two full runs of the suite on a loaded
    # machine libyaml itself reported an error before the hundredth level (not seen alone).
    assert yaml_c.load_c(Document("m.yaml", "yaml", [text]), text) in (
        "deep nesting", "libyaml found an error")


def test_without_pyyaml_everything_goes_to_ruamel(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(yaml_c, "AVAILABLE", False)
    path = "examples/traffic_light/traffic_light.yaml"
    _, used = _load(path, read_text(path), "auto")
    assert used == "ruamel: PyYAML with libyaml is not installed"
    assert compile_file(path).ok


def test_scalars_resolve_as_yaml_1_2() -> None:
    text = ("a: [1, 010, 0o10, 0x1F, 1_000, 1.5, .inf, 1e3, true, True, yes, no, on, ~, null, "
            "2020-01-02, '1', \"2\", 1:20, 0b101, +1, -.5]\n")
    fast, used = _load("m.yaml", text, "auto")
    assert used == "libyaml"
    assert fast == _load("m.yaml", text, "ruamel")[0]
    assert fast[0]["a"][:4] == [1, 10, 8, 31]
    assert fast[5] == {("a", 1): "010", ("a", 10): "yes", ("a", 11): "no", ("a", 12): "on"}


@settings(FUZZ, max_examples=100)
@given(mutated_texts())
def test_mutated_examples_read_alike(case: tuple[str, str]) -> None:
    path, text = case
    fast, _ = _load(path, text, "auto")
    assert fast == _load(path, text, "ruamel")[0]

