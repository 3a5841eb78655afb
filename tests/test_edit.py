"""The edit engine (hfsmc/edit, docs/editing.md): what each operation writes into
examples/follow_colors/follow_colors.yaml, shown as diffs (tests/golden/edit/;
`python tests/test_edit.py --regen` rewrites them), and its refusals, undo/redo,
diagnostics by element and the conflict with a file changed on disk."""

from __future__ import annotations

import difflib
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from hfsmc.edit.session import Conflict, EditSession
from hfsmc.edit.text import EditError, TextEdit, apply_edits
from hfsmc.edit.xml_ops import XmlOps
from hfsmc.edit.yaml_ops import YamlOps
from hfsmc.emit.xml import to_xml
from hfsmc.pipeline import compile_file
from tests.support import library_and_users

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "examples" / "follow_colors" / "follow_colors.yaml"
GOLDEN = ROOT / "tests" / "golden" / "edit"

Op = Callable[[YamlOps], list[TextEdit]]
OPS: dict[str, Op] = {
    "rename_state": lambda o: o.rename("Mission", "Flight"),
    "rename_nested_state": lambda o: o.rename("Mission/FollowRed", "FollowCrimson"),
    "rename_anchored_state": lambda o: o.rename("Mission/FollowGreen/Track", "Chase"),
    "rename_variable": lambda o: o.rename_declaration("variable", "stages", "steps"),
    "rename_parameter": lambda o: o.rename_declaration("parameter", "altitude", "height"),
    "add_state": lambda o: o.add_state("", "Hover", {"entry": "drone.hold()",
                                                      "transitions": [{"to": "Land", "after": "5s"}]}),
    "add_state_in_composite": lambda o: o.add_state("Mission", "Wait", {}, 0),
    "add_first_child": lambda o: o.add_state("Done", "Rest", {"final": True}),
    "delete_state": lambda o: o.delete_state("LinkLost"),
    "move_state": lambda o: o.move_state("Done", 0),
    "add_transition": lambda o: o.add_transition("LinkLost", {"to": "Land", "when": "now() > 600"}),
    "delete_transition": lambda o: o.delete_transition("Mission", 0),
    "move_transition": lambda o: o.move_transition("Mission", 1, 0),
    "set_snippet_block": lambda o: o.set_state_field("Land", "entry", "log('landing')\nlog('now')\n"),
    "set_snippet_line": lambda o: o.set_state_field("Mission/FollowGreen", "during",
                                                    'seen = blob("green") or seen'),
    "clear_snippet": lambda o: o.set_state_field("LinkLost", "entry", None),
    "set_period": lambda o: o.set_state_field("", "period", "20ms"),
    "add_parameter": lambda o: o.add_declaration("parameter", "speed", {"type": "float", "default": 1.0}),
    "remove_variable": lambda o: o.remove_declaration("variable", "frames"),
    "add_interface": lambda o: o.add_declaration("interface", "gimbal", {"type": "mavlink",
                                                                          "url": "udpin:127.0.0.1:14560"}),
    "add_import": lambda o: o.add_import("os"),
    "remove_import": lambda o: o.remove_import("cv2"),
    "wrap_states": lambda o: o.wrap_states("", ["LinkLost", "Land"], "Ending"),
    "paste_state": lambda o: o.paste_state("", o.copy_state("LinkLost"))[0],
}


def diff_of(name: str) -> str:
    text = MODEL.read_text()
    new = apply_edits(text, OPS[name](YamlOps(text)))
    return "".join(difflib.unified_diff(text.splitlines(True), new.splitlines(True),
                                        "follow_colors.yaml", f"follow_colors.yaml ({name})", n=1))


@pytest.mark.parametrize("name", sorted(OPS))
def test_golden_edit(name: str) -> None:
    assert diff_of(name) == (GOLDEN / f"{name}.diff").read_text()


def test_renamed_and_edited_model_checks_clean() -> None:
    for name in ("rename_state", "rename_nested_state", "rename_anchored_state", "rename_variable",
                 "rename_parameter", "add_parameter", "move_state", "paste_state"):
        s = EditSession(str(MODEL), MODEL.read_text())
        s.apply(OPS[name])
        assert not [d for d in s.check() if d.severity == "error"], name


def test_state_shared_through_an_alias_is_edited_at_its_anchor() -> None:
    o = YamlOps(MODEL.read_text())
    with pytest.raises(EditError, match=r"anchor &follow .*edit it at the anchor"):
        o.rename("Mission/FollowBlue/Track", "Chase")


def test_states_inside_used_files_are_read_only() -> None:
    o = YamlOps(MODEL.read_text())
    with pytest.raises(EditError, match=r"no state or region `TakeOff/Airborne`"):
        o.rename("TakeOff/Airborne", "Up")
    idx = o.index
    assert any(r.target == "TakeOff/Airborne" and r.via == "active" for r in idx.refs)


@pytest.mark.parametrize("bad", ["1x", "a-b", "", "a b"])
def test_rename_refuses_bad_names(bad: str) -> None:
    with pytest.raises(EditError, match="not a valid state name"):
        YamlOps(MODEL.read_text()).rename("Done", bad)


def test_rename_refuses_a_sibling_name() -> None:
    with pytest.raises(EditError, match="`Land` already exists"):
        YamlOps(MODEL.read_text()).rename("Done", "Land")


def test_an_edit_that_breaks_the_model_is_made_and_diagnosed_by_element() -> None:
    s = EditSession(str(MODEL), MODEL.read_text())
    s.apply(lambda o: o.set_state_field("LinkLost", "during", "undefined_name()"))
    s.apply(lambda o: o.delete_state("Done"))
    keyed = s.by_element()
    assert any(d.code == "E141" for d in keyed["LinkLost"]), keyed
    assert any("Done" in d.message for ds in keyed.values() for d in ds)
    assert s.undo() and s.undo()
    assert s.text == MODEL.read_text()
    assert s.redo() and "undefined_name" in s.text


def test_undo_redo_are_exact_texts() -> None:
    original = MODEL.read_text()
    s = EditSession(str(MODEL), original)
    s.apply(OPS["wrap_states"])
    wrapped = s.text
    s.apply(OPS["add_import"])
    assert s.undo() and s.text == wrapped
    assert s.undo() and s.text == original
    assert not s.undo()
    assert s.redo() and s.text == wrapped


def test_a_file_changed_on_disk_under_unsaved_edits_is_a_conflict(tmp_path: Path) -> None:
    p = tmp_path / "m.yaml"
    p.write_text(MODEL.read_text().replace("../lib/", str(ROOT / "examples" / "lib") + "/"))
    s = EditSession.open(str(p))
    s.apply(OPS["add_import"])
    p.write_text(p.read_text() + "# someone else\n")
    with pytest.raises(Conflict, match="changed on disk"):
        s.save()
    assert p.read_text().endswith("# someone else\n")
    s.save(force=True)
    assert "numpy as np, os]" in p.read_text()


def test_flow_and_empty_collections() -> None:
    text = "hfsm: 1\nname: m\ninitial: A\nstates: {A: {final: true}}\n"
    o = YamlOps(text)
    new = apply_edits(text, o.add_state("", "B", {"final": True}))
    assert new == "hfsm: 1\nname: m\ninitial: A\nstates: {A: {final: true}, B: {final: true}}\n"
    o = YamlOps(new)
    assert apply_edits(new, o.move_state("B", 0)).endswith("states: {B: {final: true}, A: {final: true}}\n")
    assert apply_edits(new, o.delete_state("A")).endswith("states: {B: {final: true}}\n")
    text2 = "hfsm: 1\nname: m\nimports: []\ninitial: A\nstates:\n  A:\n    final: true"
    o = YamlOps(text2)
    assert "imports: [math]\n" in apply_edits(text2, o.add_import("math"))
    assert apply_edits(text2, o.add_state("", "B")).endswith("    final: true\n  B: {}")
    assert apply_edits(text2, o.delete_state("A")).endswith("states: {}")


def test_strings_are_quoted_when_plain_would_change_them() -> None:
    text = "hfsm: 1\nname: m\ninitial: A\nstates:\n  A: {final: true}\n"
    o = YamlOps(text)
    for value, written in (("no", '"no"'), ("010", '"010"'), ("a: b", '"a: b"'), ("x # y", '"x # y"'),
                           ("5s", "5s"), ("log(1)", "log(1)")):
        assert f"description: {written}\n" in apply_edits(text, o.set_state_field("", "description", value))


XML = ROOT / "examples" / "traffic_light" / "traffic_light.xml"
XmlOp = Callable[[XmlOps], list[TextEdit]]
# The same operations on the XML model (tests/golden/edit/xml/); those marked `invalid`
# make a model that is diagnosed (SPEC 8.1: made all the same).
XML_OPS: dict[str, XmlOp] = {
    "rename_state": lambda o: o.rename("Amber", "Yellow"),
    "rename_variable": lambda o: o.rename_declaration("variable", "count", "laps"),
    "rename_parameter": lambda o: o.rename_declaration("parameter", "cycles", "rounds"),
    "add_state": lambda o: o.add_state("", "Hover", {"entry": "log('hover')",
                                                      "transitions": [{"to": "Night", "after": "5s"}]}),
    "add_first_child": lambda o: o.add_state("Red", "Walk", {"final": True}),
    "delete_state": lambda o: o.delete_state("Night"),
    "move_state": lambda o: o.move_state("Night", 0),
    "add_transition": lambda o: o.add_transition("Amber", {"to": "Night", "when": "count > 9"}),
    "delete_transition": lambda o: o.delete_transition("Red", 0),
    "move_transition": lambda o: o.move_transition("Red", 1, 0),
    "set_snippet_block": lambda o: o.set_state_field("Amber", "entry", "log('a')\nlog('b < c')\n"),
    "set_snippet_line": lambda o: o.set_state_field("Night", "entry", 'log("night")'),
    "set_transition_field": lambda o: o.set_field(("states", "Red", "transitions", 1, "after"), "7s"),
    "clear_snippet": lambda o: o.set_state_field("Green", "during", None),
    "set_period": lambda o: o.set_state_field("", "period", "20ms"),
    "set_parameter_default": lambda o: o.set_field(("parameters", "cycles", "default"), 6),
    "add_parameter": lambda o: o.add_declaration("parameter", "speed", {"type": "float", "default": 1.0}),
    "remove_variable": lambda o: o.remove_declaration("variable", "button"),
    "add_interface": lambda o: o.add_declaration("interface", "gimbal", {"type": "mavlink",
                                                                          "url": "udpin:127.0.0.1:14560"}),
    "add_import": lambda o: o.add_import("math"),
    "wrap_states": lambda o: o.wrap_states("", ["Amber", "Red"], "Stopping"),
    "paste_state": lambda o: o.paste_state("", o.copy_state("Amber"))[0],
    "paste_yaml_state": lambda o: o.paste_state("", YamlOps(MODEL.read_text()).copy_state("LinkLost"))[0],
}
XML_INVALID = {"delete_state", "wrap_states", "paste_yaml_state"}  # Night named; no drone here


def xml_golden_diff(name: str) -> str:
    text = XML.read_text()
    new = apply_edits(text, XML_OPS[name](XmlOps(text)))
    return "".join(difflib.unified_diff(text.splitlines(True), new.splitlines(True),
                                        "traffic_light.xml", f"traffic_light.xml ({name})", n=1))


@pytest.mark.parametrize("name", sorted(XML_OPS))
def test_xml_golden_edit(name: str) -> None:
    assert xml_golden_diff(name) == (GOLDEN / "xml" / f"{name}.diff").read_text()
    text = XML.read_text()
    new = apply_edits(text, XML_OPS[name](XmlOps(text)))
    errors = [d for d in compile_file(str(XML), new).diagnostics if d.severity == "error"]
    assert bool(errors) == (name in XML_INVALID), [d.message for d in errors]


def test_xml_has_every_operation_of_yaml() -> None:
    public = {n for n in dir(YamlOps) if not n.startswith("_") and callable(getattr(YamlOps, n))}
    assert public - {"automaton"} <= set(dir(XmlOps))


@pytest.mark.parametrize("ops", [YamlOps, XmlOps])
def test_refusals_are_one_line_on_both_formats(ops: type[YamlOps] | type[XmlOps]) -> None:
    o = ops((MODEL if ops is YamlOps else XML).read_text())
    state = "Done" if ops is YamlOps else "Night"
    sibling = "Land" if ops is YamlOps else "Red"
    for call, message in (
            (lambda: o.rename(state, "1x"), "not a valid state name"),
            (lambda: o.rename(state, sibling), f"`{sibling}` already exists"),
            (lambda: o.delete_state("Nowhere"), "no state or region `Nowhere`"),
            (lambda: o.remove_import("nothing_like_it"), "no import `nothing_like_it`"),
            (lambda: o.rename_declaration("variable", "nope", "x"), "no variable `nope`"),
            (lambda: o.paste_state("", "- not a state"), "not one state")):
        with pytest.raises(EditError, match=message) as e:
            call()
        assert "\n" not in str(e.value)


def test_xml_snippets_keep_their_style() -> None:
    """Code with `<` goes in CDATA where the file already uses CDATA, escaped otherwise;
    a snippet whose whitespace the XML form would change is written verbatim."""
    text = XML.read_text().replace("<when>button</when>", "<when><![CDATA[button and 1 < 2]]></when>")
    new = apply_edits(text, XmlOps(text).set_state_field("Amber", "exit", "log(1 < 2)"))
    assert "<exit><![CDATA[log(1 < 2)]]></exit>" in new
    new = apply_edits(text, XmlOps(text).set_state_field("Amber", "exit", "  x = 1\n  y = 2"))
    assert '<exit verbatim="true">  x = 1\n  y = 2</exit>' in new
    from hfsmc.errors import Diagnostics
    from hfsmc.frontend import load

    data = load(str(XML), Diagnostics(), new).data
    assert data["states"]["Amber"]["exit"] == "  x = 1\n  y = 2"


def regenerate() -> None:
    (GOLDEN / "xml").mkdir(parents=True, exist_ok=True)
    for name in OPS:
        (GOLDEN / f"{name}.diff").write_text(diff_of(name))
    for name in XML_OPS:
        (GOLDEN / "xml" / f"{name}.diff").write_text(xml_golden_diff(name))


if __name__ == "__main__" and "--regen" in sys.argv:
    regenerate()


def xml_diff(edit: Callable[[XmlOps], list[TextEdit]]) -> str:
    text = XML.read_text()
    new = apply_edits(text, edit(XmlOps(text)))
    assert not [d for d in compile_file(str(XML), new).diagnostics if d.severity == "error"], new
    return "".join(x for x in difflib.unified_diff(text.splitlines(True), new.splitlines(True), n=0)
                   if x[:1] in "+-" and x[:3] not in ("+++", "---"))


def test_xml_operations_keep_the_formatting() -> None:
    assert xml_diff(lambda o: o.rename("Amber", "Yellow")) == (
        '-      <transition name="button" to="Amber">\n'
        '+      <transition name="button" to="Yellow">\n'
        '-    <state name="Amber">\n'
        '+    <state name="Yellow">\n')
    assert xml_diff(lambda o: o.rename("Green", "Go")).count("Go") == 3  # name, initial, to
    assert xml_diff(lambda o: o.set_state_field("Amber", "exit", 'log("x < y")')) == (
        '+      <exit>log("x &lt; y")</exit>\n')
    assert xml_diff(lambda o: o.set_state_field("", "period", "50ms")) == (
        '-  <automaton period="100ms" initial="Green">\n'
        '+  <automaton period="50ms" initial="Green">\n')
    assert xml_diff(lambda o: o.add_state("", "Off", {"final": True})) == (
        '+    <state name="Off" final="true"/>\n')
    moved = xml_diff(lambda o: o.move_state("Night", 0))
    assert moved == '+    <state name="Night" final="true"/>\n-    <state name="Night" final="true"/>\n'
    text = XML.read_text()
    deleted = apply_edits(text, XmlOps(text).delete_state("Amber"))
    assert '<state name="Amber">' not in deleted and deleted.count("\n") == text.count("\n") - 6
    assert apply_edits(deleted, XmlOps(deleted).set_state_field("Night", "entry", "log('n')")).count(
        "<entry>log('n')</entry>") == 1


def test_xml_session_renames_and_undoes() -> None:
    s = EditSession(str(XML), XML.read_text())
    s.apply(lambda o: o.rename("Red", "Stop"))
    assert 'name="Stop"' in s.text and not [d for d in s.diagnostics if d.severity == "error"]
    assert s.undo() and s.text == XML.read_text()


def test_merge_keeps_everything_and_unshares_an_alias_that_differs() -> None:
    import copy

    from hfsmc.edit.merge import merge_into
    from hfsmc.errors import Diagnostics
    from hfsmc.frontend.yaml import load_yaml

    text = MODEL.read_text()
    data = load_yaml("m.yaml", text, Diagnostics()).data
    assert merge_into(text, data) == text
    new = copy.deepcopy(data)
    new["states"]["Mission"]["states"]["FollowBlue"]["states"]["Track"]["during"] = "steer(seen, 2)"
    merged = merge_into(text, new)
    assert load_yaml("m.yaml", merged, Diagnostics()).data == new
    assert merged.count("*follow") == 2 and "steer(seen, 2)" in merged
    a, b = text.splitlines(), merged.splitlines()
    assert a[:a.index("        states: *follow")] == b[:a.index("        states: *follow")]


def test_a_library_state_renamed_is_renamed_in_the_models_that_use_it(tmp_path: Path) -> None:
    from hfsmc.edit.library import model_files, rename_in_users

    lib, user, xml = library_and_users(tmp_path)
    before = {p: p.read_text() for p in (user, xml)}
    found = rename_in_users(lib, "Airborne", "InAir", model_files(tmp_path))
    assert sorted(found.edits) == sorted([str(user), str(xml)]) and found.message() is None
    for p in (user, xml):
        new = apply_edits(before[p], found.edits[str(p)])
        changed = [(a, b) for a, b in zip(before[p].splitlines(), new.splitlines(), strict=True) if a != b]
        assert len(changed) == 1 and changed[0][1] == changed[0][0].replace("/Airborne", "/InAir")
    lib_new = apply_edits(lib.read_text(), YamlOps(lib.read_text()).rename("Airborne", "InAir"))
    lib.write_text(lib_new)
    for p in (user, xml):
        p.write_text(apply_edits(before[p], found.edits[str(p)]))
        assert not [d for d in compile_file(str(p)).diagnostics if d.severity == "error"], p
    # a model that cannot be written is named with the position, not changed
    lib.write_text(lib_new.replace("InAir", "Airborne"))
    for p in (user, xml):
        p.write_text(before[p])
    xml.chmod(0o444)
    found = rename_in_users(lib, "Airborne", "InAir", model_files(tmp_path))
    assert list(found.edits) == [str(user)]
    line = before[xml].splitlines().index(next(x for x in before[xml].splitlines() if "Up/Airborne" in x)) + 1
    assert f"{xml}:{line}:" in str(found.message())
    assert xml.read_text() == before[xml]


def test_xml_declaration_fields_are_attributes_escaped_in_the_files_quote() -> None:
    from hfsmc.errors import Diagnostics
    from hfsmc.frontend import load

    for text in (XML.read_text(), XML.read_text().replace('"', "'")):
        value = 'say "hi" <now> & \'then\''
        new = apply_edits(text, XmlOps(text).set_field(("parameters", "cycles", "description"), value))
        assert load(str(XML), Diagnostics(), new).data["parameters"]["cycles"]["description"] == value
        assert len(new.splitlines()) == len(text.splitlines())


WRAP_MODEL = """\
hfsm: 1
name: m
language: python
initial: A
states:
  A:
    initial: A1
    states:
      A1:
        transitions:
          - {to: A2, after: 1s}
      A2: {}
    transitions:
      - {to: B, when: 'active("A/A2")'}
  B:
    during: |
      if active("A/A1"):
          pass
    transitions:
      - {to: C, after: 1s}
  C:
    final: true
    entry: |
      print(active("B"), active("C"))
"""


@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_wrap_rewrites_the_active_paths_through_the_wrapped_states(tmp_path: Path,
                                                                      suffix: str) -> None:
    """Literal active() paths inside the wrapped states and outside them gain the new level;
    the others are untouched."""
    path = tmp_path / f"m{suffix}"
    if suffix == ".yaml":
        path.write_text(WRAP_MODEL)
    else:
        (tmp_path / "m.yaml").write_text(WRAP_MODEL)
        r = compile_file(str(tmp_path / "m.yaml"))
        assert r.model is not None
        path.write_text(to_xml(r.model))
    s = EditSession(str(path), path.read_text())
    s.apply(lambda o: o.wrap_states("", ["A", "B"], "W"))
    assert 'active("W/A/A2")' in s.text and 'active("W/A/A1")' in s.text
    assert 'active("W/B"), active("C")' in s.text
    assert '"A/' not in s.text.replace('"W/A/', "")
    # Nothing about active() is diagnosed: only the transition that now crosses a level.
    codes = sorted(d.code for ds in s.by_element().values() for d in ds if d.severity == "error")
    assert codes == ["E133"], s.by_element()


def test_an_xml_string_written_with_entities_is_a_string_to_a_rename() -> None:
    """`&quot;speed is&quot;` is a string in the snippet: the variable's rename leaves it."""
    text = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<hfsm version="1" name="q" language="python">\n'
        '  <variable name="speed" type="float" init="0.0"/>\n'
        '  <automaton initial="A">\n'
        '    <state name="A">\n'
        "      <entry>log(&quot;speed is&quot;, speed, 'speed')</entry>\n"
        '      <during><![CDATA[print("&quot;", speed)]]></during>\n'
        '      <transition to="B" after="1s"/>\n'
        '    </state>\n'
        '    <state name="B" final="true"/>\n'
        '  </automaton>\n'
        '</hfsm>\n')
    out = apply_edits(text, XmlOps(text).rename_declaration("variable", "speed", "velocity"))
    assert "<entry>log(&quot;speed is&quot;, velocity, 'speed')</entry>" in out
    assert '<during><![CDATA[print("&quot;", velocity)]]></during>' in out
