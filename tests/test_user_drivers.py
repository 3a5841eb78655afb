"""A driver of one's own (docs/drivers.md): declared once, read without running it, checked
at the snippet's position, run for real on loopback, recorded, replayed in Python and C++,
and faked from a playback script. examples/udp_gadget is the example."""

from __future__ import annotations

import json
import re
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from hfsmc.drivers import DeclarationError, read_cpp_driver, read_python_driver
from tests.support import ROOT, free_port, hfsmc

GADGET = ROOT / "examples/udp_gadget"


def _copy(tmp: Path) -> Path:
    shutil.copytree(GADGET, tmp / "g", ignore=shutil.ignore_patterns("__pycache__"))
    return tmp / "g"


def test_the_python_and_cpp_declarations_agree() -> None:
    py = read_python_driver((GADGET / "drivers/gadget.py").read_text())
    cpp = read_cpp_driver((GADGET / "drivers/gadget.hpp").read_text())
    assert py.type == cpp.type == "gadget"
    assert py.commands == cpp.commands == ("led", "beep")
    assert [m.signature() for m in py.methods.values()] == \
        [m.signature() for m in cpp.methods.values()]
    assert dict(py.snapshot).keys() == dict(cpp.snapshot).keys()


def test_a_declaration_that_is_not_one_is_said_at_its_line() -> None:
    with pytest.raises(DeclarationError) as e:
        read_python_driver("from hfsmc_driver import Driver, query\n\nclass G(Driver):\n"
                           "    KIND = 'mavlink'\n    SNAPSHOT = {}\n")
    assert e.value.line == 4 and "KIND" in e.value.message
    with pytest.raises(DeclarationError) as e:
        read_cpp_driver("// nothing declared\n")
    assert "declaration block" in e.value.message


@pytest.mark.parametrize(("edit", "expected"), [
    (("gadget.led(True)", "gadget.blink(True)"), r"udp_gadget\.yaml:\d+:\d+: error\[E148\]"),
    (("gadget.beep(100)", "gadget.beep(100, 2)"), r"error\[E149\]: `gadget.beep` takes 1"),
    (("python: drivers/gadget.py", "python: ../gadget.py"), r"error\[E185\].*outside"),
    (("options: {stale: 1.0}", "options: {stael: 1.0}"), r"error\[E186\].*no option `stael`"),
])
def test_check_knows_the_drivers_methods(tmp_path: Path, edit: tuple[str, str],
                                         expected: str) -> None:
    g = _copy(tmp_path)
    model = g / "udp_gadget.yaml"
    text = model.read_text()
    assert edit[0] in text
    model.write_text(text.replace(edit[0], edit[1], 1))
    r = hfsmc("check", str(model))
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert __import__("re").search(expected, r.stdout + r.stderr), r.stdout + r.stderr


def test_drivers_that_disagree_are_refused(tmp_path: Path) -> None:
    g = _copy(tmp_path)
    header = g / "drivers/gadget.hpp"
    header.write_text(header.read_text().replace('"beep(ms):', '"beep(ms, times):'))
    r = hfsmc("check", str(g / "udp_gadget.yaml"))
    out = r.stdout + r.stderr
    assert r.returncode == 1 and "E189" in out and "`beep` differs" in out


def test_a_literal_name_must_be_one_the_option_lists(tmp_path: Path) -> None:
    (tmp_path / "d").mkdir()
    (tmp_path / "d/lamps.py").write_text(
        "from hfsmc_driver import Driver, command\n\n\nclass Lamps(Driver):\n"
        "    KIND = 'lamps'\n    SNAPSHOT = {'on': 0}\n    OPTIONS = {'names': ()}\n\n"
        "    @command(names={'lamp': 'names'})\n    def switch(self, lamp, on):\n"
        "        \"\"\"Switch one lamp.\"\"\"\n")
    (tmp_path / "m.yaml").write_text(
        "hfsm: 1\nname: m\ninterfaces:\n  lamps: {type: driver, python: d/lamps.py, "
        "options: {names: 'red, green'}}\ninitial: A\nstates:\n  A:\n    entry: |\n"
        "      lamps.switch('red', True)\n      lamps.switch('blue', True)\n")
    r = hfsmc("check", str(tmp_path / "m.yaml"))
    assert r.returncode == 1
    out = r.stdout + r.stderr
    assert "m.yaml:10:20: error[E148]: `lamps.switch`: `blue` is not one of" in out, out
    assert out.count("error[") == 1


def _sim(port: int) -> subprocess.Popen[bytes]:
    proc = subprocess.Popen([sys.executable, str(GADGET / "gadget_sim.py"), "--port", str(port),
                             "--period", "2", "--for", "30"], stdout=subprocess.PIPE)
    assert proc.stdout is not None and proc.stdout.readline().startswith(b"gadget on")
    return proc


def _config(tmp: Path, port: int) -> Path:
    c = tmp / "wire.yaml"
    c.write_text(json.dumps({"interfaces": {"gadget": {"url": f"udp:127.0.0.1:{port}"}}}))
    return c


@pytest.mark.timeout(300)
def test_run_record_and_replay_in_python_and_cpp(tmp_path: Path) -> None:
    if shutil.which("g++") is None or shutil.which("cmake") is None:
        pytest.fail("g++ and cmake are needed (make deps)")
    r = hfsmc("build", str(GADGET / "udp_gadget.yaml"), "-o", str(tmp_path / "py"))
    assert r.returncode == 0, r.stderr
    r = hfsmc("build", "-t", "cpp", "--compile", str(GADGET / "udp_gadget_cpp.yaml"),
              "-o", str(tmp_path / "cpp"), timeout=280)
    assert r.returncode == 0, r.stderr
    port = free_port(socket.SOCK_DGRAM)
    sim = _sim(port)
    try:
        for lang, cmd in (("py", [sys.executable, str(tmp_path / "py/udp_gadget.py")]),
                          ("cpp", [str(tmp_path / "cpp/build/udp_gadget_cpp")])):
            run = subprocess.run([*cmd, "--config", str(_config(tmp_path, port)), "--until",
                                  "3s", "--record", str(tmp_path / f"{lang}.mcap")],
                                 capture_output=True, text=True, timeout=60)
            assert run.returncode == 0, run.stderr
            assert f"gadget: readings from udp:127.0.0.1:{port}" in run.stderr
            assert "Near: obstacle near" in run.stdout + run.stderr
    finally:
        sim.kill()
        sim.wait()
        said = sim.stdout.read().decode() if sim.stdout else ""
        if sim.stdout:
            sim.stdout.close()
    assert "LED 1" in said and "BEEP 100" in said
    for rec in ("py", "cpp"):
        for model in ("udp_gadget.yaml", "udp_gadget_cpp.yaml"):
            r = hfsmc("replay", str(tmp_path / f"{rec}.mcap"), "--model", str(GADGET / model),
                      timeout=280)
            assert r.returncode == 0 and ": identical:" in r.stdout, r.stdout + r.stderr


def test_the_fake_answers_from_the_script_and_sends_nothing(tmp_path: Path) -> None:
    r = hfsmc("build", str(GADGET / "udp_gadget.yaml"), "-o", str(tmp_path / "py"))
    assert r.returncode == 0, r.stderr
    play = tmp_path / "play"
    play.mkdir()
    rows = [{"t": 0, "kind": "snapshot", "interface": "gadget",
             "values": {"distance": 2.0, "age": 0.0, "count": 1}},
            {"t": 500_000, "kind": "snapshot", "interface": "gadget",
             "values": {"distance": 0.3, "count": 2}},
            {"t": 1_000_000, "kind": "snapshot", "interface": "gadget",
             "values": {"distance": 1.5, "count": 3}}]
    (play / "inputs.jsonl").write_text("".join(json.dumps(x) + "\n" for x in rows))
    run = subprocess.run([sys.executable, str(tmp_path / "py/udp_gadget.py"), "--playback",
                          str(play), "--until", "2s", "--trace", str(tmp_path / "t.jsonl")],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    sent = [json.loads(x) for x in (play / "commands.jsonl").read_text().splitlines()]
    assert [(c["t"], c["call"], c["args"]) for c in sent] == [
        (0, "led", [False]), (500_000, "led", [True]), (500_000, "beep", [100]),
        (1_000_000, "led", [False])]
    # a field the driver does not have is said at start, with the file
    (play / "inputs.jsonl").write_text(json.dumps({"t": 0, "kind": "snapshot", "interface":
                                                   "gadget", "values": {"range": 1}}) + "\n")
    run = subprocess.run([sys.executable, str(tmp_path / "py/udp_gadget.py"), "--playback",
                          str(play)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "no snapshot field `range`" in run.stderr
    assert "Traceback" not in run.stderr


# -- scenarios (docs/testing.md, "Interfaces of your own") --------------------------------------

def _scenario(tmp: Path, inputs: str, expect: str = "  - stop: until\n",
              model: Path = GADGET / "udp_gadget.yaml") -> Path:
    path = tmp / "sc.yaml"
    path.write_text(f"model: {model}\nuntil: 5s\ninputs:\n{inputs}expect:\n{expect}")
    return path


def _problems(path: Path) -> list[str]:
    from hfsmc.errors import Diagnostics
    from hfsmc.pipeline import compile_file
    from hfsmc.scenario import check_against_model, read_scenario

    diags = Diagnostics()
    sc = read_scenario(str(path), diags)
    assert sc is not None
    result = compile_file(sc.models[0].path)
    assert result.model is not None
    check_against_model(sc, result.model, diags)
    return [f"{d.span.line}:{d.span.col}: {d.code} {d.message}" for d in diags.sorted()]


@pytest.mark.parametrize("model", ["udp_gadget.yaml", "udp_gadget_cpp.yaml"])
def test_a_scenario_scripts_a_drivers_fields_each_of_its_type(tmp_path: Path, model: str) -> None:
    """Checked against the declaration of the model's language (gadget.py, gadget.hpp)."""
    path = _scenario(tmp_path, """\
  gadget:
    - {at: 0s, distanse: 2.0, count: 1.5, led: 1}
    - {at: 1s, distance: fast, mode: 3}
    - {at: 2s, distance: {ramp: [0, 1]}}
    - {from: 2s, to: 3s, count: {ramp: [0, 9]}, distance: {ramp: [0, x]}}
""", "  - command: gadget.blink\n  - command: gadget.led\n    args: [true]\n", GADGET / model)
    assert _problems(path) == [
        "5:16: E195 `distanse` is not a snapshot field of the gadget driver (`gadget`)",
        "5:38: E191 `count` must be an integer, not a number (`1.5`)",
        "5:48: E191 `led` must be true or false, not a number (`1`)",
        "6:26: E191 `distance` must be a number (.nan and .inf are numbers too), not a "
        "string (`fast`)",
        "6:32: E195 `mode` is not a snapshot field of the gadget driver (`gadget`)",
        "7:26: E193 a ramp needs a span: `from: TIME, to: TIME`",
        "8:33: E193 `count` cannot ramp: only numbers and lists of numbers do (its declared "
        "value is an integer)",
        "8:70: E191 `distance` must be a number (.nan and .inf are numbers too), not a "
        "string (`x`)",
        "10:14: E199 `blink` is not a command of a gadget interface",
    ]
    r = hfsmc("test", str(path))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"{path}:5:16: error[E195]: `distanse` is not a snapshot field" in r.stderr
    assert "did you mean `distance`?" in r.stderr


def test_a_drivers_field_may_bear_a_built_in_inputs_name(tmp_path: Path) -> None:
    """`mode` and `position` are a vehicle's inputs; a driver's fields of those names take
    the driver's types, and a vehicle's value for them is refused there."""
    (tmp_path / "d").mkdir()
    (tmp_path / "d/arm.py").write_text(
        "from hfsmc_driver import Driver, query\n\n\nclass Arm(Driver):\n"
        "    KIND = 'arm'\n    SNAPSHOT = {'position': 0.0, 'mode': 0, 'joints': (0.0, 0.0)}\n\n"
        "    @query\n    def position(self):\n        \"\"\"Where.\"\"\"\n"
        "        return self.value('position')\n")
    model = tmp_path / "m.yaml"
    model.write_text("hfsm: 1\nname: m\ninterfaces:\n  arm: {type: driver, python: d/arm.py}\n"
                     "initial: A\nstates:\n  A:\n    transitions:\n"
                     "      - {to: B, when: arm.position() > 0.4}\n  B: {}\n")
    good = _scenario(tmp_path, """\
  arm:
    - {at: 0s, position: 0.1, mode: 3, joints: [0.5, 1]}
    - {from: 1s, to: 2s, position: {ramp: [0.1, 0.9]}, joints: {ramp: [[0, 0], [1, 1]]}}
""", "  - entered: B\n    between: [1.3s, 1.45s]\n", model)
    assert _problems(good) == []
    r = hfsmc("test", str(good), "--keep", str(tmp_path / "runs"))
    assert r.returncode == 0, r.stdout + r.stderr
    rows = [json.loads(x) for x in next((tmp_path / "runs").iterdir()).joinpath(
        "inputs.jsonl").read_text().splitlines()]
    assert rows[0] == {"t": 0, "kind": "snapshot", "interface": "arm",
                       "values": {"position": 0.1, "mode": 3, "joints": [0.5, 1.0]}}
    assert {"t": 1_500_000, "kind": "snapshot", "interface": "arm",
            "values": {"position": 0.5, "joints": [0.5, 0.5]}} in rows
    bad = _scenario(tmp_path, """\
  arm:
    - {at: 0s, position: [0, 0, 1], mode: GUIDED, joints: [0.5, true]}
    - {at: 1s, mode: 9223372036854775808, joints: [%s]}
""" % ("9" * 400), "  - stop: until\n", model)
    assert _problems(bad) == [
        "5:26: E191 `position` must be a number (.nan and .inf are numbers too), not a list",
        "5:43: E191 `mode` must be an integer, not a string (`GUIDED`)",
        "5:65: E191 an item of `joints` must be a number (.nan and .inf are numbers too), "
        "not a boolean",
        "6:22: E191 `mode`: 9223372036854775808 is out of the range of a 64-bit integer",
        f"6:52: E191 an item of `joints`: {'9' * 400} is beyond what a float holds",
    ]


def test_the_gadgets_scenarios_fail_when_the_model_does_otherwise(tmp_path: Path) -> None:
    """examples/udp_gadget/tests pass (tests/test_scenario.py runs them in both languages);
    the same script with `near` at 0.1 m never reaches Near, and says so."""
    sc = (GADGET / "tests/obstacle_near.yaml").read_text().replace(
        "../udp_gadget.yaml", str(GADGET / "udp_gadget.yaml")).replace(
        "  cpp: ../udp_gadget_cpp.yaml\n", "")
    path = tmp_path / "near.yaml"
    path.write_text(sc.replace("until: 7s\n", "until: 7s\nparameters: {near: 0.1}\n"))
    r = hfsmc("test", str(path))
    assert r.returncode == 1, r.stdout + r.stderr
    assert f"{path}::python FAILED" in r.stdout
    assert re.search(r"near\.yaml:\d+:5: expected `Near` entered 1 time\(s\) between 2\.65 s "
                     r"and 2\.75 s\n  got: entered 0 time", r.stdout), r.stdout
    assert re.search(r"expected command gadget\.beep\(100\) 1 time\(s\)\n  got: sent 0 "
                     r"time", r.stdout), r.stdout


def test_a_span_gives_way_to_what_held_before_or_to_the_declared_value(tmp_path: Path) -> None:
    from hfsmc.scenario import load_scenario
    from hfsmc.scenario_inputs import snapshots

    sc = load_scenario(str(_scenario(tmp_path, """\
  gadget:
    - {at: 0s, distance: 2.0}
    - {from: 100ms, to: 200ms, distance: 0.3, led: true}
""")))
    defaults = dict(read_python_driver((GADGET / "drivers/gadget.py").read_text()).snapshot)
    got = [(e["t"] // 1000, e["values"]) for e in snapshots(
        sc, {"gadget": "driver"}, 50_000, {}, drivers={"gadget": defaults})]
    assert got == [(0, {"distance": 2.0}), (100, {"distance": 0.3, "led": True}),
                   (200, {"distance": 2.0, "led": False})]  # led: never set before, its default
