"""The compiled schema validator (hfsmc/frontend/schema.py: fastjsonschema) that
spares a valid document jsonschema's walk agrees with jsonschema: whatever it
accepts jsonschema accepts, so the diagnostics stay jsonschema's."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings

from hfsmc.errors import Diagnostics, HfsmcError
from hfsmc.frontend import load, schema
from tests.conftest import ROOT, examples
from tests.test_fuzz_frontend import FUZZ, mutated_models, mutated_texts

MODELS = sorted(str(p.relative_to(ROOT)) for p in [
    *examples(), *(ROOT / "examples" / "lib").glob("*.yaml"),
    *(ROOT / "tests" / "invalid").glob("*.yaml"), *(ROOT / "tests" / "invalid").glob("*.xml")])


def _agree(data: Any, stricter: bool = False) -> bool:
    """Both validators' verdicts on ``data`` (asserted equal, or with ``stricter`` the
    compiled one refusing what jsonschema accepts); True when jsonschema says valid."""
    slow = next(iter(schema._validator().iter_errors(data)), None) is None
    fast = schema.surely_valid(data)
    assert fast <= slow if stricter else fast == slow, data
    return slow


def _data(path: str, text: str | None = None) -> Any:
    diags = Diagnostics()
    try:
        doc = load(path, diags, text)
    except HfsmcError:
        return None
    return None if diags.has_errors else doc.data


@pytest.mark.parametrize("path", MODELS)
def test_models_agree(path: str) -> None:
    data = _data(str(ROOT / path))
    if data is not None:
        _agree(data)


def test_examples_are_surely_valid() -> None:
    for path in examples():
        assert schema.surely_valid(_data(str(path))), path


@pytest.mark.parametrize("change", [
    {"hfsm": True}, {"hfsm": 1.0}, {"hfsm": 2}, {"name": "abc\n"}, {"name": "a b"}, {"period": 10.0},
    {"period": True}, {"period": -1}, {"period": "2 s"}, {"language": "rust"}, {"initial": 3},
    {"variables": {"v": {"type": "int"}}}, {"variables": {"v": (1, 2)}}, {"variables": {"v": None}},
    {"parameters": {"p": {"type": "int", "default": None}}}, {"states": {}}, {"extra": 1},
])
def test_edge_values_agree(change: dict[str, Any]) -> None:
    data = {"hfsm": 1, "name": "m", "initial": "A", "states": {"A": None}}
    assert _agree(data)
    # `$` of a pattern is `\\Z` in the compiled validator (jsonschema lets a final newline
    # match): refused there, the document goes through jsonschema, which accepts it.
    _agree({**data, **change}, stricter=change.get("name") == "abc\n")


@settings(FUZZ, max_examples=200)
@given(mutated_models())
def test_structure_mutations_agree(case: tuple[str, str]) -> None:
    data = _data(*case)
    if data is not None:
        _agree(data)


@settings(FUZZ, max_examples=200)
@given(mutated_texts())
def test_text_mutations_agree(case: tuple[str, str]) -> None:
    data = _data(*case)
    if data is not None:
        _agree(data)
