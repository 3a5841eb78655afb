"""`use` and `with` in the front end (docs/model.md: use): the instance's automaton, its
paths and periods, its bindings, diagnostics inside used files with where they are used
from, and convert round trips.  The bad models of tests/invalid/use_* cover each code at
the using file; here are those whose position is in the used file."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from hfsmc import cli
from hfsmc.emit.ir_text import dump
from hfsmc.errors import Diagnostic
from hfsmc.ir import Model
from hfsmc.pipeline import Result, compile_file

CLIMB = """\
hfsm: 1
name: climb
parameters:
  altitude: {type: float, default: 3.0}
  label: {type: str, default: climb}
interfaces:
  drone: {type: mavlink}
variables: {n: 0}
initial: Arm
states:
  Arm:
    entry: log(label, altitude)
    transitions: [{to: Up, after: 200ms}]
  Up:
    during: n += 1
    initial: Slow
    states:
      Slow: {transitions: [{to: Fast, when: n > 2}]}
      Fast:
        period: 20ms
        initial: F
        states: {F: {final: true}}
    transitions: [{to: Top, when: active("Up/Fast")}]
  Top: {final: true}
"""

HOLD_XML = """\
<?xml version="1.0" encoding="UTF-8"?>
<hfsm version="1" name="hold">
  <parameter name="seconds" type="float" default="1.5"/>
  <parameter name="on" type="bool" default="true"/>
  <automaton initial="Wait" period="250ms">
    <state name="Wait">
      <transition to="Done" after="1s"/>
    </state>
    <state name="Done" final="true"/>
  </automaton>
</hfsm>
"""

MAIN = """\
hfsm: 1
name: mission
period: 50ms
parameters:
  climb_alt: {type: int, default: 7}
interfaces:
  drone: {type: mavlink}
  other: {type: mavlink}
initial: TakeOff
states:
  TakeOff:
    use: lib/climb.yaml
    with: {altitude: 5, label: $$cash, drone: other}
    transitions: [{to: Again, when: done()}]
  Again:
    use: lib/climb.yaml
    with: {altitude: $climb_alt}
    transitions: [{to: Hold, when: active("Again/Top")}]
  Hold:
    use: lib/hold.xml
    with: {seconds: 2, on: false}
    transitions: [{to: End, when: done()}]
  End: {final: true}
"""


def write(tmp: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (tmp / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp / name).write_text(text, encoding="utf-8")


def ok(path: Path) -> Model:
    result = compile_file(str(path))
    assert result.ok and result.model is not None, show(result.diagnostics)
    assert not result.diagnostics, show(result.diagnostics)
    return result.model


def show(diags: list[Diagnostic]) -> str:
    return "\n".join(f"{d.span}: {d.code} {d.message} {d.notes}" for d in diags) or "(none)"


def found(result: Result) -> list[tuple[str, str]]:
    return [(d.code, str(d.span)) for d in result.diagnostics]


def mission(tmp: Path) -> Model:
    write(tmp, {"lib/climb.yaml": CLIMB, "lib/hold.xml": HOLD_XML, "main.yaml": MAIN})
    return ok(tmp / "main.yaml")


def test_instance_paths_continue_the_using_state(tmp_path: Path) -> None:
    model = mission(tmp_path)
    paths = [s.path for s in model.states()]
    assert paths[:8] == ["TakeOff", "TakeOff/Arm", "TakeOff/Up", "TakeOff/Up/Slow", "TakeOff/Up/Fast",
                         "TakeOff/Up/Fast/F", "TakeOff/Top", "Again"]
    assert [s.path for s in model.own_states()] == ["TakeOff", "Again", "Hold", "End"]
    assert model.find("Again/Up/Fast/F") is not None
    auto = model.automaton_at("TakeOff")
    assert auto is not None and auto.instance is not None
    assert auto.owner == "TakeOff" and auto.region is None
    assert model.automaton_at("TakeOff/Up/Fast") is not None
    # spans stay in the used file
    climb = str(tmp_path / "lib" / "climb.yaml")
    arm = model.find("TakeOff/Arm")
    assert arm is not None and (arm.span.file, arm.span.line, arm.span.col) == (climb, 11, 3)


def test_two_instances_share_one_build_of_the_file(tmp_path: Path) -> None:
    model = mission(tmp_path)
    a, b = model.automaton_at("TakeOff"), model.automaton_at("Again")
    assert a is not None and b is not None and a.instance and b.instance
    assert a.instance.model is b.instance.model  # built once per compile
    used = a.instance.model
    assert [s.path for s in used.states()][:3] == ["Arm", "Up", "Up/Slow"]  # its own paths
    assert a.instance.written == "lib/climb.yaml"
    assert a.instance.file == str(tmp_path / "lib" / "climb.yaml")
    assert (a.instance.span.line, a.instance.span.col) == (12, 10)


def test_periods_inherited_as_any_sub_automaton(tmp_path: Path) -> None:
    model = mission(tmp_path)
    periods = {a.path: (a.period_ms, a.period_written) for a in model.automata()}
    assert periods["TakeOff"] == (50, False)  # the used root writes none: its container's
    assert periods["TakeOff/Up"] == (50, False)
    assert periods["TakeOff/Up/Fast"] == (20, True)
    assert periods["Hold"] == (250, True)  # the used root's own period
    # on its own, the used file's root has the default period
    auto = model.automaton_at("TakeOff")
    assert auto is not None and auto.instance is not None
    assert auto.instance.model.root.period_ms == 100


def test_bindings(tmp_path: Path) -> None:
    model = mission(tmp_path)
    take, again, hold = (model.automaton_at(p) for p in ("TakeOff", "Again", "Hold"))
    assert take and take.instance and again and again.instance and hold and hold.instance
    got = {b.name: (b.kind, b.value, b.source) for b in take.instance.bindings}
    assert got == {"altitude": ("parameter", 5.0, None), "label": ("parameter", "$cash", None),
                   "drone": ("interface", None, "other")}
    assert isinstance(got["altitude"][1], float)
    assert again.instance.binding("altitude").source == "climb_alt"  # an int param for a float
    assert again.instance.binding("label").value == "climb"  # left unbound: its default
    assert again.instance.binding("drone").source == "drone"  # the same name
    assert {b.name: b.value for b in hold.instance.bindings} == {"seconds": 2.0, "on": False}


def test_nested_use_and_xml_using_yaml(tmp_path: Path) -> None:
    write(tmp_path, {"lib/climb.yaml": CLIMB, "lib/hold.xml": HOLD_XML, "main.yaml": MAIN,
                     "outer/top.xml": """\
<?xml version="1.0" encoding="UTF-8"?>
<hfsm version="1" name="top">
  <interface name="drone" type="mavlink"/>
  <interface name="other" type="mavlink"/>
  <automaton initial="M">
    <state name="M" use="../main.yaml">
      <with name="climb_alt" value="9"/>
      <transition to="Z"><when>done()</when></transition>
    </state>
    <state name="Z" final="true"/>
  </automaton>
</hfsm>
"""})
    model = ok(tmp_path / "outer" / "top.xml")
    assert model.find("M/TakeOff/Up/Fast/F") is not None
    assert model.find("M/Hold/Wait") is not None
    periods = {a.path: a.period_ms for a in model.automata()}
    assert periods["M"] == 50 and periods["M/TakeOff"] == 50 and periods["M/Hold"] == 250
    inner = model.automaton_at("M/TakeOff")
    assert inner is not None and inner.instance is not None  # the nested instance kept
    assert inner.instance.written == "lib/climb.yaml"  # relative to the file that writes it
    outer = model.automaton_at("M")
    assert outer is not None and outer.instance is not None
    assert outer.instance.binding("climb_alt").value == 9


def test_used_file_is_checked_with_its_own_names(tmp_path: Path) -> None:
    # climb's snippets use `n`, `label`, `altitude`: names the using model lacks; and the
    # using model's snippets do not see them either
    write(tmp_path, {"lib/climb.yaml": CLIMB, "main.yaml": """\
hfsm: 1
name: m
interfaces: {drone: {type: mavlink}}
initial: A
states:
  A:
    use: lib/climb.yaml
    transitions: [{to: B, when: done() and n > 0}]
  B: {final: true}
"""})
    result = compile_file(str(tmp_path / "main.yaml"))
    assert found(result) == [("E141", f"{tmp_path / 'main.yaml'}:8:44")], show(result.diagnostics)


def test_errors_in_a_used_file_once_with_every_use(tmp_path: Path) -> None:
    bad = CLIMB.replace("during: n += 1", "during: m += 1").replace(
        "name: climb\n", "name: climb\non_shutdown: log('x')\n")
    write(tmp_path, {"lib/climb.yaml": bad, "main.yaml": """\
hfsm: 1
name: m
interfaces: {drone: {type: mavlink}}
initial: A
states:
  A:
    use: lib/climb.yaml
    transitions: [{to: B, when: done()}]
  B:
    use: lib/climb.yaml
    transitions: [{to: C, when: done()}]
  C: {final: true}
"""})
    result = compile_file(str(tmp_path / "main.yaml"))
    assert not result.ok and result.model is None
    lib = tmp_path / "lib" / "climb.yaml"
    main = tmp_path / "main.yaml"
    assert found(result) == [("E174", f"{lib}:3:1"), ("E141", f"{lib}:16:13")]
    for d in result.diagnostics:
        assert d.notes[-1] == f"used from {main}:7:10, {main}:10:10"
    text = CliRunner().invoke(cli.main, ["check", str(main)]).stderr
    assert f"{lib}:16:13: error[E141]: undefined name `m`" in text
    assert "    during: m += 1\n" in text and "            ^\n" in text  # the used file's line


def test_warnings_of_a_used_file_once(tmp_path: Path) -> None:
    lib = CLIMB.replace("  Top: {final: true}\n", "  Top: {final: true}\n  Lost: {final: true}\n")
    write(tmp_path, {"lib/climb.yaml": lib, "main.yaml": MAIN.replace("lib/hold.xml", "lib/climb.yaml")
                     .replace("with: {seconds: 2, on: false}", "with: {altitude: 1}")})
    result = compile_file(str(tmp_path / "main.yaml"))
    assert result.ok
    assert found(result) == [("W201", f"{tmp_path / 'lib' / 'climb.yaml'}:25:3")], show(result.diagnostics)


def test_cycle_names_the_chain_at_the_use_that_closes_it(tmp_path: Path) -> None:
    write(tmp_path, {
        "a.yaml": "hfsm: 1\nname: a\ninitial: S\nstates:\n  S: {use: lib/b.yaml, transitions: "
                  "[{to: T, when: done()}]}\n  T: {final: true}\n",
        "lib/b.yaml": "hfsm: 1\nname: b\ninitial: S\nstates:\n  S:\n    use: ../a.yaml\n"
                      "    transitions: [{to: T, after: 1s}]\n  T: {final: true}\n"})
    a, b = str(tmp_path / "a.yaml"), str(tmp_path / "lib" / "b.yaml")
    result = compile_file(a)
    cycles = [d for d in result.diagnostics if d.code == "E175"]
    assert [str(d.span) for d in cycles] == [f"{b}:6:10"], show(result.diagnostics)
    assert cycles[0].message == f"`use` cycle: {a} -> {b} -> {tmp_path / 'lib' / '../a.yaml'}"
    assert cycles[0].notes[-1] == f"used from {a}:5:12"


def test_using_state_structure_still_checked(tmp_path: Path) -> None:
    write(tmp_path, {"lib/climb.yaml": CLIMB, "main.yaml": """\
hfsm: 1
name: m
interfaces: {drone: {type: mavlink}}
initial: A
states:
  A: {use: lib/climb.yaml}
"""})
    result = compile_file(str(tmp_path / "main.yaml"))
    assert found(result) == [("W202", f"{tmp_path / 'main.yaml'}:6:3")], show(result.diagnostics)


def test_dump_ir_shows_the_instance(tmp_path: Path) -> None:
    text = dump(mission(tmp_path))
    assert "      automaton TakeOff period 50ms (inherited) initial Arm\n" \
           "        use 'lib/climb.yaml' = " in text
    assert "          with parameter altitude = 5.0 @13:22\n" in text
    assert "          with parameter label = '$cash' @13:32\n" in text
    assert "          with interface drone = other @13:47\n" in text
    assert "        state TakeOff/Up/Fast/F final" in text
    assert "          with parameter altitude = $climb_alt @17:22\n" in text


def test_convert_keeps_use_as_written_both_ways(tmp_path: Path) -> None:
    model = mission(tmp_path)
    runner = CliRunner()
    for src, out in (("main.yaml", "m.xml"), ("m.xml", "m2.yaml")):
        r = runner.invoke(cli.main, ["convert", str(tmp_path / src), "-o", str(tmp_path / out)])
        assert r.exit_code == 0, r.output
    xml = (tmp_path / "m.xml").read_text("utf-8")
    assert '<state name="TakeOff" use="lib/climb.yaml">' in xml
    assert '<with name="label" value="$$cash"/>' in xml
    assert '<with name="altitude" value="$climb_alt"/>' in xml
    assert "Slow" not in xml  # the used file is not copied in
    yaml = (tmp_path / "m2.yaml").read_text("utf-8")
    assert "    use: lib/climb.yaml\n    with:\n      altitude: 5.0\n      label: $$cash\n" \
           "      drone: other\n" in yaml
    assert ok(tmp_path / "m.xml") == model
    assert ok(tmp_path / "m2.yaml") == model


def test_a_used_model_has_no_stopping_keys(tmp_path: Path) -> None:
    lib = CLIMB.replace("initial: Arm\n", "initial: Arm\non_interrupt: Top\ninterrupt_timeout: 5s\n"
                        "time_limit: 1m\n")
    write(tmp_path, {"lib/climb.yaml": lib, "lib/hold.xml": HOLD_XML, "main.yaml": MAIN})
    result = compile_file(str(tmp_path / "main.yaml"))
    climb = tmp_path / "lib" / "climb.yaml"
    assert found(result) == [("E174", f"{climb}:10:1"), ("E174", f"{climb}:11:1"),
                             ("E174", f"{climb}:12:1")], show(result.diagnostics)
    main = tmp_path / "main.yaml"
    assert all(d.notes[-1] == f"used from {main}:12:10, {main}:16:10" for d in result.diagnostics)


def test_a_legacy_file_is_not_a_model_to_use(tmp_path: Path) -> None:
    legacy = Path("tests/legacy/corpus/visualstates").glob("*.xml")
    write(tmp_path, {"lib/old.xml": next(iter(sorted(legacy))).read_text("utf-8"),
                     "main.yaml": "hfsm: 1\nname: m\ninitial: A\nstates:\n  A: {use: lib/old.xml, "
                                  "transitions: [{to: B, after: 1s}]}\n  B: {final: true}\n"})
    result = compile_file(str(tmp_path / "main.yaml"))
    assert found(result) == [("E172", f"{tmp_path / 'main.yaml'}:5:12")], show(result.diagnostics)
    assert "convert it first" in result.diagnostics[0].notes[0]


MISSING_USE = """\
hfsm: 1
name: m
language: {language}
initial: A
states:
  A:
    use: lib/nowhere.yaml
    transitions:
      - {{to: B, when: {when}}}
  B: {{final: true}}
"""


def test_a_use_that_failed_is_said_once(tmp_path: Path) -> None:
    """done() in the using state and active() paths below it would only repeat the error."""
    for language, when in (("python", 'done() or active("A/Climb")'),
                           ("cpp", 'done() || active("A/Climb")')):
        path = tmp_path / f"{language}.yaml"
        path.write_text(MISSING_USE.format(language=language, when=f"'{when}'"), "utf-8")
        r = compile_file(str(path))
        assert [(d.code, str(d.span)) for d in r.diagnostics] == [("E170", f"{path}:7:10")], \
            r.diagnostics
    # a path that leads nowhere else is still an error
    path.write_text(MISSING_USE.format(language="python", when="'active(\"B/Climb\")'"), "utf-8")
    r = compile_file(str(path))
    assert sorted(d.code for d in r.diagnostics) == ["E146", "E170"], r.diagnostics
