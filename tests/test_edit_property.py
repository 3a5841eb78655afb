"""Property tests of the edit engine over every example, every conformance model and
the legacy corpus converted (tests/legacy/golden): random operations change only the
text of what they change, leave a model that loads, and undo gives back the exact
bytes; a rename leaves a model that checks as the original did and differs from it only
on lines that held the name."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hfsmc.edit.session import EditSession
from hfsmc.edit.text import EditError, TextEdit, apply_edits
from hfsmc.edit.xml_ops import XmlOps
from hfsmc.edit.yaml_ops import YamlOps
from hfsmc.errors import Diagnostics, HfsmcError
from hfsmc.frontend import load
from hfsmc.pipeline import compile_file

ROOT = Path(__file__).resolve().parent.parent
FILES = sorted({*ROOT.glob("examples/**/*.yaml"), *ROOT.glob("tests/conformance/*.yaml"),
                *ROOT.glob("tests/legacy/golden/*.yaml")})
MODELS = [p for p in FILES if p.read_text().lstrip().startswith(("hfsm:", "#")) and
          "\nhfsm:" in "\n" + p.read_text()]

XML_SAFE = {"move", "set", "transition", "param", "import", "paste"}  # keep the XSD's rules


def _xml_models() -> list[tuple[Path, str]]:
    """traffic_light.xml, and every example and conformance model that compiles, written as
    XML by `hfsmc convert` (its comments kept as XML comments)."""
    from hfsmc.commands.convert import yaml_comments
    from hfsmc.emit.xml import to_xml

    out = [(p, p.read_text()) for p in sorted(ROOT.glob("examples/**/*.xml"))]
    for p in MODELS:
        if "legacy" in p.parts:
            continue
        r = compile_file(str(p))
        if r.ok and r.model is not None:
            out.append((p.with_suffix(".xml"), to_xml(r.model, yaml_comments(r.lines))))
    return out


XML_MODELS = _xml_models()
APPLIED: list[int] = []  # operations made, over the whole run (see the last test)
SETTINGS = settings(max_examples=40, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


def _ops(o: YamlOps | XmlOps, draw: Any, where: list[tuple[int, int]],
         kinds: list[str] | None = None) -> list[TextEdit]:
    """A random operation's edits; ``where`` gets the text range they must stay in."""
    states = sorted(p for p, e in o.index.elements.items() if e.kind == "state")
    kind = draw(st.sampled_from(["add", "delete", "move", "set", "clear", "transition", "param",
                                 "import", "paste", "wrap"]))
    if kinds is not None:
        kinds.append(kind)
    if not states:
        return o.add_state("", "Fresh", {"final": True})
    s = draw(st.sampled_from(states))
    el = o.index.elements[s]
    text = o.text
    if kind in ("delete", "set", "clear", "transition"):
        # the state's own lines (and the comment lines above it)
        where.append((0, len(text)))
        lo = text.rfind("\n", 0, el.key.start) + 1
        while lo > 0 and text[text.rfind("\n", 0, lo - 1) + 1:lo].lstrip().startswith(("#", "<!--")):
            lo = text.rfind("\n", 0, lo - 1) + 1
        hi = text.find("\n", el.node.end)
        where[-1] = (lo, len(text) if hi < 0 else hi + 1)
    parent = s.rsplit("/", 1)[0] if "/" in s else ""
    if kind == "add":
        return o.add_state(parent, "Fresh", {"entry": "log('x')"})
    if kind == "delete":
        return o.delete_state(s)
    if kind == "move":
        return o.move_state(s, draw(st.integers(0, 5)))
    if kind == "set":
        value = draw(st.sampled_from(["log('a')", "x = 1\ny = 2\n", "a: b", "no", "é ü"]))
        return o.set_state_field(s, draw(st.sampled_from(["entry", "during", "exit"])), value)
    if kind == "clear":
        return o.set_state_field(s, draw(st.sampled_from(["entry", "during", "exit", "history"])), None)
    if kind == "transition":
        return o.add_transition(s, {"to": s.rsplit("/", 1)[-1], "after": "1s"})
    if kind == "param":
        return o.add_declaration("parameter", "fresh_p", {"type": "int", "default": 1})
    if kind == "import":
        return o.add_import("os")
    if kind == "paste":
        return o.paste_state(parent, o.copy_state(s))[0]
    sibs = [p for p in states if (p.rsplit("/", 1)[0] if "/" in p else "") == parent]
    return o.wrap_states(parent, [p.rsplit("/", 1)[-1] for p in sibs[:2]], "Wrapped")


def _kept(before: str, edits: list[TextEdit], where: list[tuple[int, int]]) -> str:
    """``before`` edited; asserts that the edits stay in ``where`` and keep every other byte."""
    for lo, hi in where:  # the edits stay inside the element they are about
        # (the last entry of a block mapping leaves `{}` after its key)
        assert all(lo <= e.start <= e.end <= hi for e in edits if e.new not in (" {}", " []")), \
            (lo, hi, edits)
    after = apply_edits(before, edits)
    pos = 0
    for e in sorted(edits, key=lambda e: e.start):
        assert after.find(before[pos:e.start]) >= 0
        pos = e.end
    assert after.endswith(before[pos:])
    assert after.startswith(before[:min(e.start for e in edits)])
    return after


def _loads(path: Path, text: str) -> None:
    diags = Diagnostics()
    load(str(path), diags, text)  # raises ParseError when the YAML no longer reads


@pytest.mark.slow
@SETTINGS
@given(data=st.data())
def test_random_operations_keep_the_rest_and_undo_exactly(data: st.DataObject) -> None:
    path = data.draw(st.sampled_from(MODELS))
    original = path.read_text()
    s = EditSession(str(path), original)
    for _ in range(data.draw(st.integers(1, 4))):
        before = s.text
        try:
            where: list[tuple[int, int]] = []
            edits = _ops(YamlOps(before), data.draw, where)
        except EditError:
            continue
        if not edits:
            continue
        after = _kept(before, edits, where)
        s.replace(after)
        APPLIED.append(1)
        _loads(path, s.text)
    while s.undo():
        pass
    assert s.text == original


@pytest.mark.slow
@SETTINGS
@given(data=st.data())
def test_a_rename_checks_as_before_and_touches_only_lines_with_the_name(data: st.DataObject) -> None:
    path = data.draw(st.sampled_from(MODELS))
    text = path.read_text()
    o = YamlOps(text)
    states = sorted(p for p in o.index.elements)
    if not states:
        return
    target = data.draw(st.sampled_from(states))
    old = target.rsplit("/", 1)[-1]
    try:
        edits = o.rename(target, "Renamed_" + old)
    except EditError as e:
        assert "anchor" in str(e) or "read-only" in str(e)
        return
    new = apply_edits(text, edits)
    a, b = text.splitlines(), new.splitlines()
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        if x != y:
            assert old in x and y.replace("Renamed_" + old, old) == x
    cwd = os.getcwd()
    try:
        before = compile_file(str(path), text)
        after = compile_file(str(path), new)
    except HfsmcError:
        return
    finally:
        os.chdir(cwd)
    if before.ok:
        assert after.ok, [str(d.span) + d.message for d in after.diagnostics]


def test_the_random_operations_were_made() -> None:
    """Runs after the property test in this file: most drawn operations applied (an
    operation the engine refuses, such as a sibling's name, is skipped)."""
    if not APPLIED:
        test_random_operations_keep_the_rest_and_undo_exactly()
    assert len(APPLIED) >= 40


XML_SYNTAX = {"E002", "E004", "E006"}
XML_SCHEMA = {"E100", "E101", "E102", "E103", "E104"}


@pytest.mark.slow
@SETTINGS
@given(data=st.data())
def test_random_operations_on_xml_keep_the_rest_and_undo_exactly(data: st.DataObject) -> None:
    """The same operations on XML models: the rest kept byte for byte, the text stays
    well-formed XML, operations that cannot break the XSD's rules leave none broken, and
    undo gives back the exact original."""
    path, original = data.draw(st.sampled_from(XML_MODELS))
    s = EditSession(str(path), original)
    for _ in range(data.draw(st.integers(1, 4))):
        before = s.text
        where: list[tuple[int, int]] = []
        kinds: list[str] = []
        try:
            edits = _ops(XmlOps(before), data.draw, where, kinds)
        except EditError:
            continue
        if not edits:
            continue
        after = _kept(before, edits, where)
        had = {d.code for d in s.diagnostics}
        s.replace(after)
        APPLIED_XML.append(1)
        codes = {d.code for d in s.diagnostics}
        assert not codes & XML_SYNTAX, (kinds, [str(d) for d in s.diagnostics])
        if kinds and kinds[0] in XML_SAFE:
            assert not (codes - had) & XML_SCHEMA, (kinds, [d.message for d in s.diagnostics])
    while s.undo():
        pass
    assert s.text == original


@pytest.mark.slow
@SETTINGS
@given(data=st.data())
def test_an_xml_rename_checks_as_before_and_touches_only_lines_with_the_name(
        data: st.DataObject) -> None:
    path, text = data.draw(st.sampled_from(XML_MODELS))
    o = XmlOps(text)
    target = data.draw(st.sampled_from(sorted(o.index.elements)))
    old = target.rsplit("/", 1)[-1]
    new = apply_edits(text, o.rename(target, "Renamed_" + old))
    a, b = text.splitlines(), new.splitlines()
    assert len(a) == len(b) and a != b
    for x, y in zip(a, b, strict=True):
        if x != y:
            assert old in x and y.replace("Renamed_" + old, old) == x
    cwd = os.getcwd()
    try:
        before = compile_file(str(path), text)
        after = compile_file(str(path), new)
    finally:
        os.chdir(cwd)
    if before.ok:
        assert after.ok, [str(d.span) + d.message for d in after.diagnostics]


APPLIED_XML: list[int] = []


def test_the_random_xml_operations_were_made() -> None:
    if not APPLIED_XML:
        test_random_operations_on_xml_keep_the_rest_and_undo_exactly()
    assert len(APPLIED_XML) >= 40 and len(XML_MODELS) >= 10
