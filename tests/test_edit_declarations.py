"""The edit engine's declaration operations (hfsmc/edit/declarations.py, docs/editing.md):
a field of a parameter, a variable or an interface set, a short variable given a type, an
import changed or deleted in place, a form's text read as the declared type; each on
examples/follow_colors/follow_colors.yaml, shown as the lines it removes and adds."""

from __future__ import annotations

import difflib
from collections.abc import Callable
from pathlib import Path

import pytest

from hfsmc.edit import declarations as decl
from hfsmc.edit.text import EditError, TextEdit, apply_edits
from hfsmc.edit.yaml_ops import YamlOps

MODEL = Path(__file__).resolve().parent.parent / "examples" / "follow_colors" / "follow_colors.yaml"


def lines(op: Callable[[YamlOps], list[TextEdit]]) -> tuple[list[str], list[str]]:
    text = MODEL.read_text()
    after = apply_edits(text, op(YamlOps(text)))
    d = list(difflib.unified_diff(text.splitlines(), after.splitlines(), lineterm="", n=0))
    return ([x[1:] for x in d if x[0] == "-" and not x.startswith("---")],
            [x[1:] for x in d if x[0] == "+" and not x.startswith("+++")])


@pytest.mark.parametrize(("op", "removed", "added"), [
    (lambda o: decl.set_declaration_field(o, "parameter", "altitude", "default", 5.0),
     ["  altitude: {type: float, default: 4.0}       # m above home while following"],
     ["  altitude: {type: float, default: 5.0}       # m above home while following"]),
    (lambda o: decl.set_declaration_field(o, "variable", "frames", "init", 7),
     ["  frames: 0"], ["  frames: 7"]),
    (lambda o: decl.set_declaration_field(o, "variable", "frames", "type", "int"),
     ["  frames: 0"], ["  frames: {type: int, init: 0}"]),
    (lambda o: decl.set_declaration_field(o, "variable", "seen", "init", [1, 2]),
     ["  seen: {type: list, init: []}      # the tracked colour's blob: [dx, dy, area] or []"],
     ["  seen: {type: list, init: [1, 2]}      # the tracked colour's blob: [dx, dy, area] or []"]),
    (lambda o: decl.set_declaration_field(o, "interface", "drone", "url", "udpin:0.0.0.0:14550"),
     ['  drone: {type: mavlink, url: "udpin:127.0.0.1:14550"}'],
     ['  drone: {type: mavlink, url: "udpin:0.0.0.0:14550"}']),
    (lambda o: decl.set_import(o, 1, "cv2 as cv"),
     ["imports: [json, cv2, numpy as np]"], ["imports: [json, cv2 as cv, numpy as np]"]),
    (lambda o: decl.delete_import(o, 0),
     ["imports: [json, cv2, numpy as np]"], ["imports: [cv2, numpy as np]"]),
])
def test_declaration_edits_change_only_their_line(op: Callable[[YamlOps], list[TextEdit]],
                                                  removed: list[str], added: list[str]) -> None:
    assert lines(op) == (removed, added)


@pytest.mark.parametrize(("text", "declared", "value"), [
    ("5", "float", 5.0), ("0x10", "int", 16), ("True", "bool", True), (" 3 ", "str", " 3 "),
    ("[1, 2]", "list", [1, 2]), ("green", None, "green"), ("", None, ""), ("2", None, 2),
    ("{a: [b", None, "{a: [b"),
])
def test_a_form_value_is_read_as_its_declared_type(text: str, declared: str | None,
                                                   value: object) -> None:
    got = decl.literal(text, declared)
    assert got == value and type(got) is type(value)


@pytest.mark.parametrize(("op", "said"), [
    (lambda o: decl.set_declaration_field(o, "variable", "nope", "init", 1), "no variable `nope`"),
    (lambda o: decl.set_declaration_field(o, "variable", "frames", "states", 1), "not a field"),
    (lambda o: decl.set_declaration_field(o, "parameter", "gain", "type", None), "needs its `type`"),
    (lambda o: decl.set_declaration_field(o, "states", "x", "type", "int"), "no kind"),
    (lambda o: decl.set_import(o, 3, "os"), "no import number 4"),
    (lambda o: decl.set_import(o, 0, "  "), "not empty"),
    (lambda o: decl.delete_import(o, -1), "no import number 0"),
    (lambda o: decl.literal("many", "int"), "not an int"),
    (lambda o: decl.literal("yes", "bool"), "not a bool"),
])
def test_refusals_are_one_line(op: Callable[[YamlOps], object], said: str) -> None:
    with pytest.raises(EditError, match=said) as e:
        op(YamlOps(MODEL.read_text()))
    assert "\n" not in str(e.value)
