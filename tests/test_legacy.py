"""Legacy VisualStates / VisualHFSM files (docs/legacy.md): import, positions, bad input, fuzz.

The corpus (``tests/legacy/corpus/``, copies of ``../shared/corpus/``) are real
files written by the JdeRobot tools.  Each converts; its state and transition
counts match the XML (counted here, independently of the importer); its
diagram renders with Graphviz; the Python ones build into a component whose
files byte-compile (the C++ ones are checked and drawn only: the C++ back end
is not there yet); its YAML and report match the golden files in
``tests/legacy/golden/`` (``python tests/test_legacy.py --regen`` rewrites them,
or call :func:`regenerate`); legacy → YAML → XML → YAML gives an equal IR.

Bad files (``tests/legacy/invalid/``, ``EXPECTED``: ``FILE CODE LINE:COL``) each
give their positioned diagnostic through the command line, and mutated corpus
files give diagnostics, never a traceback.
"""

from __future__ import annotations

import json
import os
import py_compile
import re
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner, Result
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lxml import etree

from hfsmc.cli import main
from hfsmc.commands.convert import legacy_report
from hfsmc.emit.xml import to_xml
from hfsmc.emit.yaml import to_yaml
from hfsmc.errors import CODES, Diagnostic
from hfsmc.frontend.legacy.code import Mapped, block, edit, guess_language
from hfsmc.ir import Model
from hfsmc.pipeline import Result as Compiled
from hfsmc.pipeline import compile_file

ROOT = Path(__file__).resolve().parent.parent
LEGACY = ROOT / "tests" / "legacy"
CORPUS = LEGACY / "corpus"
GOLDEN = LEGACY / "golden"
INVALID = LEGACY / "invalid"
SHARED = ROOT.parent / "shared" / "corpus"  # where the corpus lives, beside the repo

CORPUS_FILES = sorted(CORPUS.glob("*/*.xml"))
PYTHON_FILES = ["goforward", "kobuki_bump_and_go", "prius_overtake", "robot_arm"]
CPP_FILES = ["obstacle_avoidance_cpp", "wallFollowercpp"]


def rel(path: Path) -> str:
    return str(path.relative_to(ROOT))


def compiled(path: Path) -> Compiled:
    return compile_file(rel(path))


def model_of(path: Path) -> Model:
    result = compiled(path)
    assert result.ok and result.model is not None, short(result.diagnostics)
    return result.model


def short(diags: list[Diagnostic]) -> str:
    return "\n".join(f"  {d.span}: {d.severity}[{d.code}]: {d.message}" for d in diags) or "  (none)"


def cli(*args: str) -> Result:
    return CliRunner().invoke(main, list(args))


def comp(text: str, name: str = "m.xml") -> Compiled:
    return compile_file(name, text)


# ---------------------------------------------------------------------------
# golden files


def golden_texts(path: Path) -> dict[Path, str]:
    """The converted YAML and the report (diagnostics, then the convert notes)."""
    result = compiled(path)
    assert result.model is not None, short(result.diagnostics)
    report = "".join(f"{d.span}: {d.severity}[{d.code}]: {d.message}\n"
                     for d in result.diagnostics)
    report += "".join(f"{line}\n" for line in legacy_report(result))
    return {GOLDEN / f"{path.stem}.yaml": to_yaml(result.model),
            GOLDEN / f"{path.stem}.report.txt": report}


def regenerate() -> list[Path]:
    """Rewrite the golden files whose content changed; the ones rewritten."""
    here = Path.cwd()
    os.chdir(ROOT)  # spans in the reports are relative to the repository
    try:
        GOLDEN.mkdir(exist_ok=True)
        changed: list[Path] = []
        for path in CORPUS_FILES:
            for out, text in golden_texts(path).items():
                if not out.exists() or out.read_text("utf-8") != text:
                    out.write_text(text, "utf-8")
                    changed.append(out)
        return changed
    finally:
        os.chdir(here)


# ---------------------------------------------------------------------------
# the corpus


def test_corpus_is_the_shared_one() -> None:
    """The copies are the issue's files, unchanged; a file added there is missed here."""
    names = sorted(rel(p).removeprefix("tests/legacy/corpus/") for p in CORPUS_FILES)
    assert names == sorted(f"{k}/{s}.xml" for k, stems in
                           (("visualhfsm", ["goforward", "wallFollowercpp"]),
                            ("visualstates", ["kobuki_bump_and_go", "obstacle_avoidance_cpp",
                                              "prius_overtake", "robot_arm"])) for s in stems)
    if SHARED.is_dir():
        shared = sorted(str(p.relative_to(SHARED)) for p in SHARED.glob("*/*.xml"))
        assert shared == names
        for name in names:
            assert (SHARED / name).read_bytes() == (CORPUS / name).read_bytes(), name


def source_counts(path: Path) -> tuple[int, int]:
    """States and transitions, counted in the XML itself (the root state excluded)."""
    root = etree.parse(str(path)).getroot()
    if root.tag == "VisualStates":
        top = root.find("state")
        assert top is not None
        states = [s for s in top.iter("state") if s is not top]
        return len(states), sum(len(s.findall("transition")) for s in states)
    return len(root.findall("SubAutomata/state")), len(root.findall("SubAutomata/transition"))


@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: p.stem)
def test_corpus_file_converts_with_its_counts(path: Path) -> None:
    result = compiled(path)
    assert result.ok, short(result.diagnostics)
    assert {d.code for d in result.diagnostics} <= {"W202", "W205", "W206", "W207", "W208",
                                                    "W221"}
    model = model_of(path)
    n_states = sum(1 for _ in model.states())
    n_transitions = sum(len(s.transitions) for s in model.states())
    assert (n_states, n_transitions) == source_counts(path)
    assert model.language == ("cpp" if path.stem in CPP_FILES else "python")
    assert result.document is not None
    assert any(f"{n_states} states, {n_transitions} transitions" in m
               for _, m in result.document.notes)


@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: p.stem)
def test_corpus_golden(path: Path) -> None:
    for out, text in golden_texts(path).items():
        assert out.exists(), f"missing {out}: run `python tests/test_legacy.py --regen`"
        assert text == out.read_text("utf-8"), (
            f"{out} is stale: run `python tests/test_legacy.py --regen` and review the diff")


@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: p.stem)
def test_corpus_diagram_renders(path: Path, tmp_path: Path) -> None:
    out = tmp_path / f"{path.stem}.svg"
    r = cli("diagram", rel(path), "-o", str(out))
    assert r.exit_code == 0, r.output
    svg = out.read_text("utf-8")
    assert "<svg" in svg
    for state in model_of(path).states():
        assert f">{state.name}<" in svg, state.name


@pytest.mark.parametrize("stem", PYTHON_FILES)
def test_python_corpus_builds_and_byte_compiles(stem: str, tmp_path: Path) -> None:
    path = next(p for p in CORPUS_FILES if p.stem == stem)
    r = cli("build", rel(path), "-t", "python", "-o", str(tmp_path / stem))
    assert r.exit_code == 0, r.output
    sources = sorted((tmp_path / stem).glob("*.py"))
    assert tmp_path / stem / f"{stem}.py" in sources
    for src in sources:
        py_compile.compile(str(src), cfile=str(tmp_path / "out.pyc"), doraise=True)


@pytest.mark.parametrize("stem", CPP_FILES)
def test_cpp_corpus_builds_its_cmake_project(stem: str, tmp_path: Path) -> None:
    """A C++ legacy model builds with -t cpp (its code uses ROS/ICE interfaces, so it does
    not compile: `hfsmc check` points at the legacy line, see test_legacy_history)."""
    path = next(p for p in CORPUS_FILES if p.stem == stem)
    assert cli("check", "--no-cxx", rel(path)).exit_code == 0
    r = cli("build", rel(path), "-t", "cpp", "-o", str(tmp_path / stem))
    assert r.exit_code == 0, r.output
    assert (tmp_path / stem / "src" / f"{stem}.cpp").is_file()
    assert (tmp_path / stem / "CMakeLists.txt").is_file()


@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: p.stem)
def test_round_trip_yaml_xml_yaml(path: Path, tmp_path: Path) -> None:
    legacy = model_of(path)
    first = tmp_path / "first.yaml"
    first.write_text(to_yaml(legacy), "utf-8")
    from_yaml = compile_file(str(first)).model
    assert from_yaml is not None
    xml = tmp_path / "m.xml"
    xml.write_text(to_xml(from_yaml), "utf-8")
    from_xml = compile_file(str(xml)).model
    assert from_xml is not None
    again = tmp_path / "again.yaml"
    again.write_text(to_yaml(from_xml), "utf-8")
    last = compile_file(str(again)).model
    assert legacy == from_yaml == from_xml == last


def test_convert_prints_the_report(tmp_path: Path) -> None:
    path = CORPUS / "visualstates" / "prius_overtake.xml"
    out = tmp_path / "prius.yaml"
    r = cli("convert", rel(path), "-o", str(out))
    assert r.exit_code == 0, r.output
    lines = r.stderr.splitlines()
    head = lines.index(f"{rel(path)}: VisualStates file read as a version-1 model:")
    assert lines[-1] == f"wrote {out}: 8 states, 6 transitions"
    report = "\n".join(lines[head:])
    for words in ("8 states, 6 transitions, as in the source", "language: python",
                  "period: 100ms", "history: false", "cond_detect_car",
                  "not carried over: ROS buildDependencies rospy, prius_msgs, sensor_msgs",
                  "`import time` added"):
        assert words in report, words
    assert "warning[W205]" in r.stderr and "warning[W206]" in r.stderr
    assert out.read_text("utf-8").startswith("# yaml-language-server: $schema=")
    xml = tmp_path / "prius.xml"
    r = cli("convert", rel(path), "-o", str(xml))
    assert r.exit_code == 0 and r.stderr.splitlines()[-1].startswith(f"wrote {xml}: 8 states")
    assert compile_file(str(xml)).model == model_of(path)


def test_ros_topics_become_one_ros2_interface_said_at_their_positions() -> None:
    result = compiled(CORPUS / "visualstates" / "kobuki_bump_and_go.xml")
    assert result.ok and not [d for d in result.diagnostics if d.code == "W205"]
    model = result.model
    assert model is not None
    [ros] = model.interfaces
    assert ros.name == "ros" and ros.type == "ros2"
    d = [(d.code, d.span.line, d.span.col) for d in result.diagnostics]
    # tf's euler_from_quaternion (line 51) is hfsmc's helper now
    assert ("W221", 51, 16) in d
    assert model.functions is not None
    text = model.functions.text
    assert "laserData = (ros.turtlebotROS_laser_scan or LaserScan())" in text
    assert "euler_from_quaternion(e_q)[2]" in text and "tf." not in text
    assert "def turtlebotROS_mobile_base_commands_velocity(msg):\n    ros.publish(" in text
    assert "tf" not in [i.text for i in model.imports]


def test_runtime_error_points_into_the_legacy_file(tmp_path: Path) -> None:
    """An ICE interface fails when used; the traceback shows the legacy file's lines."""
    path = CORPUS / "visualhfsm" / "goforward.xml"
    r = cli("build", rel(path), "-o", str(tmp_path / "c"))
    assert r.exit_code == 0, r.output
    run = subprocess.run([sys.executable, "-I", "-S", str(tmp_path / "c" / "goforward.py"),
                          "--clock", "virtual", "--until", "1s"], capture_output=True, text=True,
                         timeout=60, stdin=subprocess.DEVNULL)
    assert run.returncode == 1, run.stderr
    assert f"{rel(path)}:2:177: error: RuntimeError: interface `KobukiMotors`" in run.stderr
    assert "cannot drive them" in run.stderr
    assert f"{rel(path)}:5 in functions" in run.stderr  # inside calculate_obstacle
    for runtime in ("hfsmc_runtime.py", "hfsmc_main.py", "hfsmc_load.py", "hfsmc_trace.py",
                    "hfsmc_traceback.py"):
        assert runtime not in run.stderr  # the stop has no traceback of its own


# ---------------------------------------------------------------------------
# what the mapping does, on small files

VS_HEAD = '<?xml version="1.0" ?>\n<VisualStates>\n'


def vs_state(uid: int, name: str, code: str = "", initial: bool = False, inner: str = "",
             timestep: int = 100, namespace: str = "", transitions: str = "") -> str:
    return (f'<state id="{uid}" initial="{initial}"><name>{name}</name><code>{code}</code>'
            f"<timestep>{timestep}</timestep>{namespace}{transitions}{inner}</state>\n")


def vs_transition(dest: int, condition: str | None = None, time: int | None = None,
                  code: str = "", name: str = "t") -> str:
    kind = f"<type>1</type><condition>{condition}</condition>" if condition is not None \
        else f"<type>0</type><time>{time}</time>"
    return (f"<transition id=\"{dest}\">{kind}<name>{name}</name>"
            f"<destinationid>{dest}</destinationid><code>{code}</code></transition>")


def vs_file(states: str, top: str = "", root_namespace: str = "", timestep: int = 100) -> str:
    return (VS_HEAD + top + f'<state id="0" initial="True"><name>root</name><code></code>'
            f"<timestep>{timestep}</timestep>{root_namespace}{states}</state>\n</VisualStates>\n")


def ok(text: str, name: str = "m.xml") -> tuple[Model, Compiled]:
    result = comp(text, name)
    assert result.ok and result.model is not None, short(result.diagnostics)
    return result.model, result


def when(model: Model, path: str, index: int = 0) -> str:
    state = model.find(path)
    assert state is not None
    code = state.transitions[index].when
    assert code is not None
    return code.text


def test_conditions_expression_return_and_function_body() -> None:
    gns = "<global_namespace><functions></functions><variables>self.n = 0</variables>" \
        "</global_namespace>"
    transitions = (vs_transition(2, "return self.globalNamespace.n &gt; 3")
                   + vs_transition(2, "x = self.globalNamespace.n * 2\nreturn x &gt; 5",
                                   name="twice")
                   + vs_transition(2, "self.globalNamespace.n == 7", name="bare"))
    text = vs_file(vs_state(1, "A", "self.globalNamespace.n += 1", True, transitions=transitions)
                   + vs_state(2, "B"), top=gns)
    model, result = ok(text)
    assert when(model, "A", 0) == "n > 3"
    assert when(model, "A", 1) == "cond_twice()"
    assert when(model, "A", 2) == "n == 7"
    assert model.functions is not None
    assert "def cond_twice():\n    x = n * 2\n    return x > 5" in model.functions.text
    w208 = [d for d in result.diagnostics if d.code == "W208"]
    assert len(w208) == 1 and "never fired" in w208[0].message
    assert model.variables[0].name == "n"
    a = model.find("A")
    assert a is not None and a.during is not None and a.during.text == "n += 1"


def test_namespaces_flatten_with_renames_globals_and_statements() -> None:
    gns = ("<global_namespace><functions>def bump(self, k):\n\tself.count = self.count + k\n"
           "\tself.seen = True</functions><variables>self.count = 0\nself.min = 3\n"
           "self.img = [0] * 4\nself.log = 'x'</variables></global_namespace>")
    local = ("<namespace><functions>def bump(self):\n\tself.count += 1</functions>"
             "<variables>self.count = 10</variables></namespace>")
    inner = vs_state(2, "In", "self.namespace.bump()\nself.globalNamespace.bump(self.globalNamespace.min)"
                     "\nself.globalNamespace.img = None", True)
    text = vs_file(vs_state(1, "Outer", "", True, inner=inner, namespace=local), top=gns)
    model, result = ok(text)
    names = {v.name: v.init for v in model.variables}
    assert names == {"count": 0, "min_": 3, "log_": "x", "Outer_count": 10}
    fn = model.functions
    assert fn is not None
    assert "def bump(k):\n\tglobal count, seen\n\tcount = count + k\n\tseen = True" in fn.text
    assert "def Outer_bump():\n\tglobal Outer_count\n\tOuter_count += 1" in fn.text
    assert "img = [0] * 4" in fn.text and "seen = None" in fn.text
    during = model.find("Outer/In")
    assert during is not None and during.during is not None
    assert during.during.text == "global img\nOuter_bump()\nbump(min_)\nimg = None\n"
    renamed = {d.message.split("`")[1] for d in result.diagnostics if d.code == "W206"}
    assert renamed == {"min", "log", "bump", "count"}


def test_local_names_meeting_model_names_are_renamed() -> None:
    """A bare name was a local in legacy code: one that is now a module-level name too is
    renamed NAME_local, every use of it with it (`odom = self.odom` must run)."""
    gns = ("<global_namespace><functions>def f(self):\n\tcount = 1\n\treturn self.count + count"
           "</functions><variables>self.count = 0\nself.größe = 2</variables></global_namespace>")
    code = "count = 5\nself.globalNamespace.größe = count"
    model, result = ok(vs_file(vs_state(1, "A", code, True), top=gns))
    w206 = [(str(d.span), d.message) for d in result.diagnostics
            if d.code == "W206" and "local name" in d.message]
    assert [span for span, _ in w206] == ["m.xml:4:2", "m.xml:6:178"]
    assert all("`count`, a local name" in m and "`count_local`" in m for _, m in w206)
    assert [v.name for v in model.variables] == ["count", "gr__e"]
    assert any(d.code == "W206" and "ASCII" in d.message for d in result.diagnostics)
    state = model.find("A")
    assert state is not None and state.during is not None
    assert state.during.text == "count_local = 5\ngr__e = count_local\n"
    assert model.functions is not None and \
        "\tcount_local = 1\n\treturn count + count_local" in model.functions.text


def test_periods_and_history() -> None:
    inner = vs_state(2, "X", "", True) + vs_state(3, "Y", "")
    text = vs_file(vs_state(1, "Fast", "", True, inner=inner, timestep=20)
                   + vs_state(4, "Same", "", False, inner=vs_state(5, "Z", "", True), timestep=250),
                   timestep=250)
    model, _ = ok(text)
    assert model.root.period_ms == 250
    fast, same = model.find("Fast"), model.find("Same")
    assert fast is not None and fast.automaton is not None and same is not None
    assert same.automaton is not None
    assert (fast.automaton.period_ms, fast.automaton.period_written) == (20, True)
    assert (same.automaton.period_ms, same.automaton.period_written) == (250, False)
    assert not fast.automaton.history
    assert all(s.automaton.history for s in model_of(
        CORPUS / "visualhfsm" / "wallFollowercpp.xml").states() if s.automaton is not None)


def test_names_made_identifiers_and_unique() -> None:
    text = vs_file(vs_state(1, "go left", "", True, transitions=vs_transition(2, time=100))
                   + vs_state(2, "2nd", transitions=vs_transition(3, time=100))
                   + vs_state(3, "2nd"))
    model, result = ok(text, "my-robot.xml")
    assert [s.name for s in model.root.states] == ["go_left", "_2nd", "_2nd_2"]
    assert model.name == "my_robot"
    assert [t.target for s in model.root.states for t in s.transitions] == ["_2nd", "_2nd_2"]
    assert sum(d.code == "W206" for d in result.diagnostics) == 3


def test_older_visualstates_jderobot_interfaces_and_root_functions() -> None:
    config = ('<config type="0"><interfaces><interface><serverType>1</serverType>'
              "<name>motors</name><topic></topic><proxyName>Motors</proxyName><ip>localhost</ip>"
              "<port>9999</port><interfaceName>Motors</interfaceName></interface></interfaces>"
              "</config><functions>def go(self):\n\tself.interfaces.motors.sendV(self.v)"
              "</functions><variables>self.v = 0.2</variables>")
    text = vs_file(vs_state(1, "A", "self.interfaces.go()", True), top=config)
    model, result = ok(text)
    assert [(i.name, i.type, i.url) for i in model.interfaces] == [
        ("motors", "ice", "Motors:default -h localhost -p 9999")]
    assert model.functions is not None and "def go():\n\tmotors.sendV(v)" in model.functions.text
    a = model.find("A")
    assert a is not None and a.during is not None and a.during.text == "go()"
    assert [d.code for d in result.diagnostics].count("W205") == 1


def test_jderobot_interface_served_over_ros_is_a_ros_topic() -> None:
    config = ('<config type="0"><interfaces><interface><serverType>2</serverType>'
              "<name>cam</name><topic>/camera/image</topic><proxyName></proxyName><ip></ip>"
              "<port></port><interfaceName>Camera</interfaceName></interface></interfaces>"
              "</config>")
    model, result = ok(vs_file(vs_state(1, "A", "img = self.interfaces.cam.getImage()", True),
                               top=config))
    assert [(i.name, i.type, i.url, dict(i.options)) for i in model.interfaces] == [
        ("cam", "ros_topic", "/camera/image", {"interface": "Camera", "server": "2"})]
    w205 = [d for d in result.diagnostics if d.code == "W205"]
    assert len(w205) == 1 and w205[0].span.line == 3


def test_older_ros_topics_named_as_the_code_uses_them() -> None:
    config = ("<config type=\"1\"><buildDependencies/><runDependencies/><topics>"
              "<topic id=\"0\"><name>/robot/cmd_vel</name><type>geometry_msgs/Twist</type>"
              "<opType>Publish</opType></topic><topic id=\"1\"><name>/robot/scan</name>"
              "<type>sensor_msgs/LaserScan</type><opType>Subscribe</opType></topic></topics>"
              "</config>")
    code = "msg = Twist()\nmsg.linear.x = len(self.rosNode.robot_scan.ranges)\n" \
        "self.rosNode.publishrobot_cmd_vel(msg)"
    model, _ = ok(vs_file(vs_state(1, "A", code, True), top=config))
    assert [i.name for i in model.interfaces] == ["ros"]
    assert model.functions is not None
    assert "def publishrobot_cmd_vel(msg):" in model.functions.text
    state = model.find("A")
    assert state is not None and state.during is not None
    assert "len((ros.robot_scan or LaserScan()).ranges)" in state.during.text
    assert [i.text for i in model.imports] == ["from geometry_msgs.msg import Twist",
                                               "from sensor_msgs.msg import LaserScan"]


def test_root_code_root_transitions_and_unknown_elements_are_warned() -> None:
    text = vs_file(vs_state(1, "A", "", True), top="<extra>1</extra>").replace(
        "<code></code><timestep>100</timestep>",
        "<code>print(1)</code><timestep>100</timestep>" + vs_transition(1, time=5), 1)
    _, result = ok(text)
    w207 = [d.message for d in result.diagnostics if d.code == "W207"]
    assert len(w207) == 3
    assert any("`<extra>`" in m for m in w207) and any("root state's code" in m for m in w207)


@pytest.mark.parametrize(("root", "expected"), [
    # no <timestep> anywhere: a file from before timesteps (100 ms), not a missing one
    ("<VisualStates><state/></VisualStates>", [("E102", "m.xml:2:15")]),
    ("<VisualHFSM/>", [("E102", "m.xml:2:1")]),
    ("<VisualStates/>", [("E102", "m.xml:2:1")]),
])
def test_empty_legacy_roots_are_read_not_refused(root: str, expected: list[tuple[str, str]]
                                                 ) -> None:
    """The legacy roots go to their front end (they were E005 before it existed)."""
    result = comp(f'<?xml version="1.0"?>\n{root}\n')
    assert [(d.code, str(d.span)) for d in result.diagnostics] == expected


def test_child_code_is_never_read_for_its_parent() -> None:
    result = compiled(INVALID / "vs_missing_code.xml")
    assert [(d.code, d.span.line) for d in result.diagnostics if d.severity == "error"] == [
        ("E102", 25)]


def test_cpp_declarations_become_typed_variables() -> None:
    ns = ("<namespace><functions>void step() {\n\tcount++;\n}</functions><variables>"
          "int count = 0;\nfloat gain = 0.5f;\ndouble k = 1e-3;\nstd::string tag;\n"
          "float ratio = 1.0 / 3;\n</variables></namespace>")
    text = vs_file(vs_state(1, "A", "stateNamespace-&gt;step();", True), root_namespace=ns)
    model, _ = ok(text)
    assert model.language == "cpp"
    assert {v.name: (v.type, v.init) for v in model.variables} == {
        "count": ("int", 0), "gain": ("float", 0.5), "k": ("double", "1e-3"),
        "tag": ("std::string", "{}")}
    assert model.functions is not None and "float ratio = 1.0 / 3;" in model.functions.text
    a = model.find("A")
    assert a is not None and a.during is not None and a.during.text == "step();"


def test_language_guess() -> None:
    assert guess_language([("self.x = 1", False), ("return self.x", True)])[0] == "python"
    assert guess_language([("int x = 1;", False), ("return x > 0;", True)])[0] == "cpp"
    assert guess_language([])[0] == "python"


def test_mapped_text_keeps_positions() -> None:
    m = Mapped("  \n    self.a = 1\n      b\n", tuple((1, c) for c in range(1, 28)))
    b = block(m)
    assert b.text == "self.a = 1\n  b"
    assert b.pos[0] == (1, 8) and b.pos[b.text.index("b")] == (1, 25)
    e = edit(b, [(0, 5, Mapped.synth("", b.pos[0]))])
    assert e.text == "a = 1\n  b" and e.pos[0] == (1, 13)
    assert e.segments()[0] == (0, 1, 13)


# ---------------------------------------------------------------------------
# bad files

_LINE = re.compile(r"^(?P<file>\S+)\s+(?P<code>[EW]\d{3})\s+(?P<line>\d+):(?P<col>\d+)\s*$")


def expected() -> list[tuple[str, str, int, int]]:
    out = []
    for raw in (INVALID / "EXPECTED").read_text("utf-8").splitlines():
        if raw.strip() and not raw.startswith("#"):
            m = _LINE.match(raw.strip())
            assert m, raw
            out.append((m["file"], m["code"], int(m["line"]), int(m["col"])))
    return out


CASES = expected()


def test_every_bad_file_is_listed() -> None:
    listed = [c[0] for c in CASES]
    assert sorted(listed) == sorted(p.name for p in INVALID.glob("*.xml"))
    assert len(set(listed)) == len(listed)
    assert {c[1] for c in CASES} <= CODES.keys()


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_file_gives_its_diagnostic(case: tuple[str, str, int, int]) -> None:
    name, code, line, col = case
    path = f"tests/legacy/invalid/{name}"
    r = cli("check", "--format", "json", path)
    assert r.exit_code == 1, r.output
    assert "Traceback" not in r.output and "internal error" not in r.output
    diags = json.loads(r.stdout)
    assert any(d["code"] == code and (d["line"], d["col"]) == (line, col) and d["file"] == path
               for d in diags), f"expected {code} at {line}:{col}; got:\n{r.stdout}"
    text = cli("check", path)
    assert text.exit_code == 1 and "Traceback" not in text.output
    assert f"{path}:{line}:{col}: error[{code}]" in text.stderr


# ---------------------------------------------------------------------------
# fuzz: mutated corpus files give diagnostics, never a crash

# the corpus and the files of the tools' history (tests/legacy/history: VisualHFSM 3.x too)
_TEXTS = {p.name: p.read_text("utf-8")
          for p in [*CORPUS_FILES, *sorted((LEGACY / "history").glob("*.xml"))]}
_GARBAGE = ["", "0", "-1", "99", "x y", "&lt;", "self.", "1e999", "True", "None", "\t\n", "é",
            "return", "state", "12abc"]


@st.composite
def mutated(draw: st.DrawFn) -> str:
    name = draw(st.sampled_from(sorted(_TEXTS)))
    root = etree.fromstring(_TEXTS[name].encode("utf-8"))
    for _ in range(draw(st.integers(1, 4))):
        elements = list(root.iter(etree.Element))
        el = elements[draw(st.integers(0, len(elements) - 1))]
        parent = el.getparent()
        op = draw(st.sampled_from(["delete", "duplicate", "rename", "text", "truncate", "swap",
                                   "attribute", "move"]))
        if op == "delete" and parent is not None:
            parent.remove(el)
        elif op == "duplicate" and parent is not None:
            parent.insert(parent.index(el), etree.fromstring(etree.tostring(el)))
        elif op == "rename":
            el.tag = draw(st.sampled_from(["state", "transition", "code", "name", "namespace",
                                           "SubAutomata", "trans", "x", "Estado", "hijo",
                                           "transicion", "idSub", "parameters", "timestep"]))
        elif op == "text":
            el.text = draw(st.sampled_from(_GARBAGE))
        elif op == "truncate" and el.text:
            el.text = el.text[:draw(st.integers(0, len(el.text)))]
        elif op == "swap":
            other = elements[draw(st.integers(0, len(elements) - 1))]
            el.text, other.text = other.text, el.text
        elif op == "attribute":
            el.set(draw(st.sampled_from(["id", "idFather", "initial", "type", "estado_inicial",
                                         "name"])),
                   draw(st.sampled_from(_GARBAGE)))
        elif op == "move" and parent is not None:
            target = elements[draw(st.integers(0, len(elements) - 1))]
            if el not in target.iterancestors() and el is not target:
                target.append(el)
    text = etree.tostring(root, encoding="unicode")
    if draw(st.booleans()):
        text = text[:draw(st.integers(0, len(text)))]
    return text


@settings(max_examples=150, derandomize=True, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_fuzzed_corpus_gives_only_diagnostics(text: str) -> None:
    result = compile_file("fuzz.xml", text)  # any exception here fails the test
    lines = max(1, len(text.splitlines()))
    for d in result.diagnostics:
        assert d.code in CODES, d
        assert d.span.file == "fuzz.xml"
        assert d.span.line >= 1 and d.span.line <= lines + 1 and d.span.col >= 1, d
    if result.ok:
        assert result.model is not None
        compile_file("again.yaml", to_yaml(result.model))


if __name__ == "__main__":
    if sys.argv[1:] != ["--regen"]:
        sys.exit("usage: python tests/test_legacy.py --regen   (rewrite tests/legacy/golden/)")
    for written in regenerate():
        print(f"updated {written.relative_to(ROOT)}")
