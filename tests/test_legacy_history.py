"""Files from the history of the JdeRobot tools, one per kind of problem (docs/legacy.md).

``tests/legacy/history/`` holds, unchanged, the files of VisualStates' history
(samples, examples, the visualHFSM-3.1 folder) that showed a kind of problem the
corpus did not; ``SOURCES`` names the repository, commit and path of each.
Each converts with a report and no traceback, with as many states and
transitions as the file (counted here in the XML); the ones whose own code is
sound draw and build (Python: byte-compiles; C++: the CMake project, and dnm4
compiles with g++); the three whose code has errors convert with W220 and stay
errors for `check` (`convert --strict` refuses them).
"""

from __future__ import annotations

import py_compile
import re
from pathlib import Path

import pytest
from click.testing import CliRunner, Result
from lxml import etree

from hfsmc.cli import main
from hfsmc.commands.convert import compile_for_convert
from hfsmc.ir import Model
from hfsmc.pipeline import compile_file

ROOT = Path(__file__).resolve().parent.parent
HISTORY = ROOT / "tests" / "legacy" / "history"
FILES = sorted(HISTORY.glob("*.xml"))
# Files whose own code is wrong (the legacy component failed there too).
CODE_ERRORS = {"deneme2": [("E141", 48, 20), ("E141", 48, 25)],
               "kobuki_obstacle_avoidance": [("E141", 5, 35), ("E141", 30, 26), ("E141", 33, 22)],
               "prius_spawn": [("E141", 47, 35)]}
SOUND = [p for p in FILES if p.stem not in CODE_ERRORS]


def rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


def cli(*args: str) -> Result:
    return CliRunner().invoke(main, list(args))


def source_counts(path: Path) -> tuple[int, int]:
    """States and transitions written in the file, whatever its format."""
    root = etree.parse(str(path)).getroot()
    if root.find("SubAutomata/Estado") is not None:  # VisualHFSM 3.x
        return (len(root.findall("SubAutomata/Estado")),
                len(root.findall("SubAutomata/Estado/transiciones/transicion")))
    if root.find("SubAutomata") is not None:  # VisualHFSM 5 layout, either root
        return len(root.findall("SubAutomata/state")), len(root.findall("SubAutomata/transition"))
    top = root.find("state")
    assert top is not None
    inner = [s for s in top.iter("state") if s is not top]
    return len(inner), sum(len(s.findall("transition")) for s in inner)


def counts(model: Model) -> tuple[int, int]:
    return sum(1 for _ in model.states()), sum(len(s.transitions) for s in model.states())


def converted(path: Path, tmp_path: Path) -> Path:
    out = tmp_path / f"{path.stem}.yaml"
    r = cli("convert", rel(path), "-o", str(out))
    assert r.exit_code == 0, r.output
    assert "Traceback" not in r.output and out.is_file()
    return out


def test_every_file_names_its_source() -> None:
    rows = [line.split() for line in (HISTORY / "SOURCES").read_text("utf-8").splitlines()
            if line.strip() and not line.startswith("#")]
    assert sorted(row[0] for row in rows) == [p.name for p in FILES]
    for row in rows:
        assert row[1] in ("JdeRobot/VisualStates", "JdeRobot/base",
                          "JdeRobot/VisualStates-examples"), row
        assert re.fullmatch(r"[0-9a-f]{40}", row[2]), row
        assert row[3].endswith(".xml") and row[4] == "--", row


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_file_converts_with_its_counts(path: Path, tmp_path: Path) -> None:
    r = cli("convert", rel(path), "-o", str(tmp_path / "out.yaml"))
    assert r.exit_code == 0, r.output
    assert "Traceback" not in r.output
    result = compile_for_convert(rel(path))
    assert result.model is not None
    assert counts(result.model) == source_counts(path)
    w220 = [(d.span.line, d.span.col) for d in result.diagnostics if d.code == "W220"]
    assert w220 == [(line, col) for _, line, col in CODE_ERRORS.get(path.stem, [])]
    written = compile_file(str(tmp_path / "out.yaml")).model
    if path.stem not in CODE_ERRORS:
        assert written is not None and counts(written) == source_counts(path)


@pytest.mark.parametrize("stem", sorted(CODE_ERRORS))
def test_code_errors_stay_errors_for_check_and_strict_convert(stem: str, tmp_path: Path
                                                              ) -> None:
    path = HISTORY / f"{stem}.xml"
    found = [(d.code, d.span.line, d.span.col) for d in compile_file(rel(path)).diagnostics
             if d.severity == "error"]
    assert found == CODE_ERRORS[stem]
    assert cli("check", rel(path)).exit_code == 1
    out = tmp_path / "strict.yaml"
    r = cli("convert", "--strict", rel(path), "-o", str(out))
    assert r.exit_code == 1 and not out.exists()
    line, col = CODE_ERRORS[stem][0][1:]
    assert f"{rel(path)}:{line}:{col}: error[E141]" in r.output


@pytest.mark.parametrize("path", SOUND, ids=lambda p: p.stem)
def test_converted_model_draws_and_builds(path: Path, tmp_path: Path) -> None:
    yaml = converted(path, tmp_path)
    r = cli("diagram", str(yaml), "-o", str(tmp_path / "d.svg"))
    assert r.exit_code == 0, r.output
    assert "<svg" in (tmp_path / "d.svg").read_text("utf-8")
    model = compile_file(str(yaml)).model
    assert model is not None
    out = tmp_path / "component"
    r = cli("build", str(yaml), "-t", model.language, "-o", str(out))
    assert r.exit_code == 0, r.output
    if model.language == "python":
        sources = sorted(out.glob("*.py"))
        assert out / f"{model.name}.py" in sources
        for src in sources:
            py_compile.compile(str(src), cfile=str(tmp_path / "x.pyc"), doraise=True)
    else:
        assert (out / "src" / f"{model.name}.cpp").is_file()


def test_cpp_model_without_ros_or_ice_compiles(tmp_path: Path) -> None:
    """dnm4: C++ in the VisualHFSM 5 layout under a <VisualStates> root; g++ takes it."""
    r = cli("check", rel(HISTORY / "dnm4.xml"))
    assert r.exit_code == 0, r.output
    assert "error[" not in r.output


def model_and_diags(stem: str) -> tuple[Model, list[tuple[str, str, str]]]:
    result = compile_for_convert(rel(HISTORY / f"{stem}.xml"))
    assert result.model is not None
    return result.model, [(d.code, f"{d.span.line}:{d.span.col}", d.message)
                          for d in result.diagnostics]


def test_visualhfsm3_states_conditions_and_defaults() -> None:
    model, diags = model_and_diags("ej_dummy")
    assert model.language == "cpp"
    assert [s.path for s in model.states()] == [
        "ChocaGira", "ChocaGira/avanzando", "ChocaGira/parando", "ChocaGira/marcha_atras",
        "ChocaGira/girando", "Vueltas", "Vueltas/aIzquierda", "Vueltas/aDerecha"]
    assert model.root.period_ms == 200 and model.root.initial == "ChocaGira"
    inner = model.find("ChocaGira")
    assert inner is not None and inner.automaton is not None
    assert inner.automaton.initial == "avanzando" and inner.automaton.history
    t = model.find("ChocaGira/avanzando")
    assert t is not None and t.transitions[0].when is not None
    assert t.transitions[0].when.text == "control->ld->distanceData[45] <= 1000.0"
    assert [i.name for i in model.interfaces] == ["control"]
    assert ("W208", "2:13", "no state of sub-automaton 1 is initial: it starts at its first "
            "state, `ChocaGira` (VisualHFSM's generated code named no state to start in)") in diags
    assert [(c, at) for c, at, _ in diags if c == "W207"] == [("W207", "11:1"), ("W207", "12:1")]
    assert [v.name for v in model.variables] == ["i", "v"]

    model, diags = model_and_diags("prueba_navegacion")
    assert [s.path for s in model.states()][:3] == ["default_0", "default_0/default_3",
                                                    "default_0/default_4"]
    assert [(c, at) for c, at, m in diags if c == "W206"][:2] == [("W206", "2:195"),
                                                                 ("W206", "2:518")]
    first = model.find("default_0")
    assert first is not None and first.transitions[0].when is not None
    assert first.transitions[0].when.text == "false"
    assert sum(1 for c, _, m in diags if c == "W208" and "never fired" in m) == 4

    _, diags = model_and_diags("prueba_nuevo_xml_varios_save")
    assert ("W208", "2:13") in [(c, at) for c, at, m in diags if "idPadre" in m]


def test_visualstates_before_timesteps_and_state_functions() -> None:
    model, diags = model_and_diags("deneme2")
    assert model.root.period_ms == 100 and model.root.initial == "state_1"
    assert [(c, at) for c, at, m in diags if c == "W208"] == [("W208", "3:3"), ("W208", "24:5")]

    model, _ = model_and_diags("obstacleAvoidancePython_ice")
    assert model.functions is not None and "def calculate_obstacle():" in model.functions.text
    assert [v.name for v in model.variables] == ["is_obstacle"]
    cond = model.find("move")
    assert cond is not None and cond.transitions[0].when is not None
    assert cond.transitions[0].when.text == "cond_obstacle()"

    model, _ = model_and_diags("dnm7")
    assert [(i.name, i.type, i.url) for i in model.interfaces] == [
        ("myMotors", "ice", "Motors:default -h localhost -p 9001")]


def test_parameters_locals_escapes_and_imports() -> None:
    model, diags = model_and_diags("prius_overtake_params")
    assert [(p.name, p.type, p.default) for p in model.parameters] == [
        ("change_lane_peek_width", "float", 1.7), ("change_lane_peek_width_2", "float", 1.5)]
    # the topic `odom` is read as `ros.odom` now: the local `odom` needs no new name
    assert not [m for c, at, m in diags if "`odom_local`" in m]
    assert model.functions is not None and "odom = (ros.odom or Odometry())\n" in model.functions.text

    model, diags = model_and_diags("BumpAndGoPython")
    assert model.functions is not None
    assert "if val < obstacle_threshold:" in model.functions.text
    assert "import tf" not in [i.text for i in model.imports]  # no tf in ROS 2
    assert ("W221", "62:16") in [(c, at) for c, at, _ in diags]

    model, diags = model_and_diags("prius_in_city")
    assert [(c, at) for c, at, m in diags if "`self.overtake_done`" in m] == [("W208", "548:15")]
    state = model.find("stay_on_road")
    assert state is not None and state.transitions[4].do is not None
    assert state.transitions[4].do.text == "overtake_done = True"

    model, _ = model_and_diags("printSensor")
    assert [i.text for i in model.imports] == ["<iostream>"]


def test_cpp_ros_node_prefix_is_dropped_before_members_only() -> None:
    """VisualStates' C++ ROS code reached the namespace through `node->`; a user's own
    `node->next` stays."""
    text = ('<?xml version="1.0" ?>\n<VisualStates><functions>void calc() {}</functions>'
            "<variables>bool busy = false;</variables>"
            '<state id="0" initial="True"><name>root</name><code></code><timestep>100</timestep>'
            '<state id="1" initial="True"><name>A</name><code>node-&gt;calc();\n'
            "Item* node = head; node-&gt;next = 0;</code><timestep>100</timestep>"
            "<transition id=\"1\"><type>1</type><condition>return node-&gt;busy;</condition>"
            "<name>t</name><destinationid>1</destinationid><code></code></transition>"
            "</state></state></VisualStates>\n")
    result = compile_file("m.xml", text)
    assert result.model is not None, result.diagnostics
    state = result.model.find("A")
    assert state is not None and state.during is not None
    assert state.during.text == "calc();\nItem* node = head; node->next = 0;\n"
    assert state.transitions[0].when is not None and state.transitions[0].when.text == "busy"

