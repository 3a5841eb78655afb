"""`hfsmc test`: scenario files read with positions (E190-E199), scripted inputs compiled
into a playback folder, expectations checked against a run, the report and JUnit XML; the
examples' scenarios (follow_colors' link loss, monitor_area's altitude watch...) run in
Python and in C++ (one build per C++ model, shared by the module), and scenarios that must
fail do, with the expectation's line and the record that broke it."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hfsmc.errors import Diagnostics, HfsmcError
from hfsmc.pipeline import compile_file
from hfsmc.scenario import Scenario, check_against_model, grid_us, load_scenario, read_scenario
from hfsmc.scenario_check import Run, check, read_records
from hfsmc.scenario_inputs import snapshots
from tests.support import ROOT

FOLLOW = ROOT / "examples/follow_colors/follow_colors.yaml"
FOLLOW_TESTS = ROOT / "examples/follow_colors/tests"
MONITOR_TESTS = ROOT / "examples/monitor_area/tests"
LIB_TESTS = ROOT / "examples/lib/tests"  # the library's behaviours alone (land through a lost link)
WAYPOINTS_TESTS = ROOT / "examples/waypoints/tests"  # PX4's OFFBOARD-loss failsafe
# Ground robots on ROS 2: Python models (their C++ twin: tests/test_scenario_ros2.py)
ROS2_TESTS = [ROOT / "examples/bump_and_go/tests", ROOT / "examples/stop_at_wall/tests"]
GADGET_TESTS = ROOT / "examples/udp_gadget/tests"  # a user's driver (docs/drivers.md)
EXAMPLES = (sorted(FOLLOW_TESTS.glob("*.yaml")) + sorted(MONITOR_TESTS.glob("*.yaml"))
            + sorted(LIB_TESTS.glob("*.yaml")) + sorted(GADGET_TESTS.glob("*.yaml"))
            + sorted(WAYPOINTS_TESTS.glob("*.yaml"))
            + [p for d in ROS2_TESTS for p in sorted(d.glob("*.yaml"))])
CPP_EXAMPLES = [p for p in EXAMPLES if p.parent not in (*ROS2_TESTS, WAYPOINTS_TESTS)]


def write(folder: Path, text: str, name: str = "sc.yaml") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def hfsmc_test(*args: str, cache: Path, timeout: float = 900) -> subprocess.CompletedProcess[str]:
    """`hfsmc test ARGS`, its components built into ``cache`` (XDG_CACHE_HOME)."""
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    return subprocess.run([sys.executable, "-m", "hfsmc", "test", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def diagnostics(path: Path) -> list[str]:
    """`file:line:col: code` of every problem of a scenario, against follow_colors."""
    diags = Diagnostics()
    try:
        sc = read_scenario(str(path), diags)
    except HfsmcError as e:
        return [f"{d.span}: {d.code}" for d in e.diagnostics]
    if sc is not None:
        result = compile_file(str(FOLLOW))
        assert result.model is not None
        check_against_model(sc, result.model, diags)
    return [f"{d.span}: {d.code}" for d in diags.sorted()]


# -- reading ------------------------------------------------------------------------------------

BAD = f"""\
model: {FOLLOW}
until: 40
inputs:
  drone:
    - {{at: 0s, conected: true}}
    - {{from: 5s, to: 2s, altitude: 3}}
    - {{at: 1s, altitude: {{ramp: [0, 3]}}}}
    - {{at: 2s, mode: 3}}
    - {{at: 2s, acks: {{arm: acepted}}}}
  cam:
    - {{at: 0s, rate: 5}}
expect:
  - entered: Mision/FollowGreen
  - command: drone.lnad
  - stop: finished
  - entred: X
  - log: x
    befor: 3s
  - log_matches: "("
  - active: Mission
  - not_entered: Done
    between: [20s, 10s]
parameters: {{alt: 3, altitude: high}}
"""


def test_every_mistake_of_a_scenario_is_reported_at_its_position(tmp_path: Path) -> None:
    path = write(tmp_path, BAD)
    p = str(path)
    assert diagnostics(path) == [
        f"{p}:2:8: E193",    # until: 40 (no unit)
        f"{p}:5:16: E190",   # conected
        f"{p}:6:22: E193",   # to before from
        f"{p}:7:26: E193",   # a ramp outside a span
        f"{p}:8:22: E191",   # mode: 3
        f"{p}:9:28: E193",   # acepted
        f"{p}:10:3: E195",   # no interface cam
        f"{p}:13:14: E197",  # Mision/FollowGreen
        f"{p}:14:14: E199",  # drone.lnad
        f"{p}:15:11: E193",  # finished
        f"{p}:16:5: E190",   # entred
        f"{p}:18:5: E190",   # befor
        f"{p}:19:19: E193",  # a bad regex
        f"{p}:20:5: E192",   # active without at
        f"{p}:22:14: E193",  # a window that ends before it starts
        f"{p}:23:14: E196",  # no parameter alt
        f"{p}:23:22: E196",  # altitude: high
    ]


def test_scenario_errors_print_like_a_compiler_and_exit_2(tmp_path: Path) -> None:
    path = write(tmp_path, f"model: {FOLLOW}\nexpect:\n  - entered: Mision\n")
    r = hfsmc_test(str(path), cache=tmp_path / "cache", timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"{path}:3:14: error[E197]: the model has no state `Mision`\n"
                               "    - entered: Mision\n"
                               "               ^\n"
                               "  note: did you mean `Mission`?\n"), r.stderr
    assert "no scenario was run" in r.stderr and "Traceback" not in r.stderr
    assert r.stdout == ""


def test_a_picture_opencv_cannot_read_is_an_error_at_its_line(tmp_path: Path) -> None:
    (tmp_path / "bad.png").write_bytes(b"not a picture")
    path = write(tmp_path, f"model: {FOLLOW}\nuntil: 5s\ninputs:\n  camera:\n"
                           "    - {at: 0s, image: bad.png}\n")
    r = hfsmc_test(str(path), cache=tmp_path / "cache", timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"{path}:5:23: error[E198]: `{tmp_path}/bad.png` is not an image OpenCV can read" in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize(("text", "code", "where"), [
    ("until: 10s\n", "E192", "1:1"),                                   # no model
    ("model: nowhere.yaml\n", "E194", "1:8"),
    (f"model: {{cpp: {FOLLOW}}}\n", "E194", "1:14"),                  # a python model as cpp
    (f"model: {FOLLOW}\nlanguages: [cpp]\n", "E194", "2:13"),          # no cpp model given
    (f"model: {FOLLOW}\ninputs:\n  camera:\n    - {{at: 0s, image: no.png}}\n", "E198", "4:23"),
    (f"model: {FOLLOW}\nexpect:\n  - trace: no.jsonl\n", "E198", "3:12"),
    (f"model: {FOLLOW}\ninputs:\n  camera:\n    - {{at: 0s, armed: true}}\n", "E195", "4:16"),
    (f"model: {FOLLOW}\nmodel: {FOLLOW}\n", "E003", "2:1"),           # duplicate key
    (f"model: {FOLLOW}\nexpect: [\n", "E002", "3:1"),
])
def test_one_mistake(tmp_path: Path, text: str, code: str, where: str) -> None:
    path = write(tmp_path, text)
    found = diagnostics(path)
    assert f"{path}:{where}: {code}" in found, found


def test_a_scenario_reads_into_frozen_values_with_positions() -> None:
    sc = load_scenario(str(FOLLOW_TESTS / "link_loss.yaml"))
    assert [m.language for m in sc.models] == ["python", "cpp"]
    assert sc.languages == ("python", "cpp") and sc.until_us == 40_000_000
    lost = next(e for e in sc.inputs if any(s.field == "connected" and s.value is False
                                            for s in e.settings))
    assert (lost.start_us, lost.end_us) == (20_000_000, 25_000_000)
    assert str(lost.span).endswith("link_loss.yaml:23:7")
    x = next(x for x in sc.expect if x.kind == "entered" and x.subject == "LinkLost")
    assert (x.after_us, x.before_us) == (22_000_000, 22_050_000)
    with pytest.raises(AttributeError):
        x.subject = "Mission"  # type: ignore[misc]


# -- inputs -------------------------------------------------------------------------------------

def _scenario(tmp_path: Path, inputs: str, until: str = "1s") -> Scenario:
    (tmp_path / "pic.png").write_bytes((FOLLOW_TESTS / "images/green.png").read_bytes())
    return load_scenario(str(write(tmp_path, f"model: {FOLLOW}\nuntil: {until}\ninputs:\n{inputs}")))


def test_spans_ramps_and_the_link_become_snapshots_on_the_grid(tmp_path: Path) -> None:
    sc = _scenario(tmp_path, """\
  drone:
    - {at: 0s, connected: true, altitude: 0}
    - {from: 100ms, to: 300ms, altitude: {ramp: [0, 2]}}
    - {from: 400ms, to: 550ms, connected: false, mode: LAND}
""", until="700ms")
    got = [(e["t"] // 1000, e["values"]) for e in snapshots(sc, {"drone": "mavlink"}, 50_000, {})]
    assert got == [
        (0, {"heartbeat_age": 0.0, "vehicle": True, "altitude": 0.0}),
        (150, {"altitude": 0.5}),
        (200, {"altitude": 1.0}),
        (250, {"altitude": 1.5}),
        (300, {"altitude": 2.0}),  # the ramp's end holds after it
        (400, {"mode": "LAND"}),  # heartbeats stop: their age grows from 0
        (450, {"heartbeat_age": 0.05}),
        (500, {"heartbeat_age": 0.1}),
        (550, {"heartbeat_age": 0.0, "mode": ""}),  # the span ends: what held before comes back
    ]


def test_a_mode_set_in_a_span_comes_back_and_acks_merge(tmp_path: Path) -> None:
    sc = _scenario(tmp_path, """\
  drone:
    - {at: 0s, mode: STABILIZE, acks: {arm: pending}}
    - {at: 100ms, acks: {takeoff: accepted}}
    - {from: 200ms, to: 300ms, mode: LAND, acks: {arm: denied}}
""", until="400ms")
    got = [(e["t"] // 1000, e["values"]) for e in snapshots(sc, {"drone": "mavlink"}, 50_000, {})]
    assert got == [
        (0, {"mode": "STABILIZE", "acks": {"arm": "pending"}}),
        (100, {"acks": {"arm": "pending", "takeoff": "accepted"}}),
        (200, {"mode": "LAND", "acks": {"arm": "denied", "takeoff": "accepted"}}),
        (300, {"mode": "STABILIZE", "acks": {"arm": "pending", "takeoff": "accepted"}}),
    ]


def test_camera_frames_arrive_at_their_rate_and_grow_old_after(tmp_path: Path) -> None:
    sc = _scenario(tmp_path, """\
  camera:
    - {from: 0s, to: 200ms, image: pic.png, rate: 10}
""", until="300ms")
    frames = {str(tmp_path / "pic.png"): "frame1.png"}
    got = [(e["t"] // 1000, e["values"]) for e in snapshots(sc, {"camera": "camera"}, 50_000, frames)]
    assert got == [
        (0, {"count": 1, "age": 0.0, "frame": "frame1.png"}),
        (50, {"age": 0.05}),
        (100, {"count": 2, "age": 0.0, "frame": "frame1.png"}),
        (150, {"age": 0.05}),
        (200, {"age": 0.1}),  # no frame after the span: the last one grows old
        (250, {"age": 0.15}),
        (300, {"age": 0.2}),
    ]


def test_the_grid_is_the_gcd_of_the_periods() -> None:
    follow = compile_file(str(FOLLOW)).model
    monitor = compile_file(str(ROOT / "examples/monitor_area/monitor_area.yaml")).model
    assert follow is not None and monitor is not None
    assert grid_us([follow]) == 50_000 and grid_us([monitor]) == 50_000


# -- checking -----------------------------------------------------------------------------------

TRACE = """\
{"t":0,"ev":"start","name":"m"}
{"t":0,"ev":"enter","state":"A"}
{"t":1500,"ev":"fire","from":"A","to":"B","index":0}
{"t":1500,"ev":"exit","state":"A"}
{"t":1500,"ev":"enter","state":"B"}
{"t":1500,"ev":"log","state":"B","msg":"in B at 1.5 s"}
{"t":3000,"ev":"stop","reason":"until"}
"""
COMMANDS = '{"t":1500000,"interface":"drone","call":"set_velocity","args":[1.0,0.0,0.5,0.0]}\n'


def _check(tmp_path: Path, expect: str) -> list[tuple[int, str, tuple[str, ...]]]:
    path = write(tmp_path, f"model: {FOLLOW}\nuntil: 3s\nexpect:\n{expect}")
    sc = load_scenario(str(path))
    run = Run(read_records(TRACE), read_records(COMMANDS), "trace.jsonl", 0)
    return [(f.expectation.span.line if f.expectation else 0, f.message, f.records)
            for f in check(sc, run)]


def test_expectations_that_hold(tmp_path: Path) -> None:
    assert _check(tmp_path, """\
  - {entered: B, between: [1.5s, 1.5s]}
  - {not_entered: A, after: 1s}
  - {active: B, at: 1.5s}
  - {active: A, at: 1.4s}
  - {log: in B}
  - {log_matches: '^in B at \\d\\.\\d s$', count: 1}
  - {command: drone.set_velocity, args: [1, 0, 0.5000000001, 0]}
  - {stop: until, before: 3s}
  - {error: any, count: 0}
""") == []


def test_each_broken_expectation_names_the_record_that_broke_it(tmp_path: Path) -> None:
    assert _check(tmp_path, """\
  - {entered: B, before: 1s}
  - {entered: C}
  - {not_entered: B}
  - {active: A, at: 2s}
  - {log: nowhere}
  - {command: drone.set_velocity, args: [2, 0, 0, 0]}
  - {command: drone.land}
  - {stop: final}
  - {entered: B, count: 2}
""") == [
        (4, "entered only outside the window",
         ('trace.jsonl:5: {"t":1500,"ev":"enter","state":"B"}',)),
        (5, "no such record: the run stopped (until) at 3 s",
         ('trace.jsonl:7: {"t":3000,"ev":"stop","reason":"until"}',)),
        (6, "entered", ('trace.jsonl:5: {"t":1500,"ev":"enter","state":"B"}',)),
        (7, "not active then: its last record before that time",
         ('trace.jsonl:4: {"t":1500,"ev":"exit","state":"A"}',)),
        (8, "no such record: the run stopped (until) at 3 s",
         ('trace.jsonl:7: {"t":3000,"ev":"stop","reason":"until"}',)),
        # a command's time in ms too, as the trace's (the file itself counts us)
        (9, "sent only with other arguments",
         ("commands.jsonl:1: at 1500 ms: drone.set_velocity(1.0, 0.0, 0.5, 0.0)",)),
        (10, "no such record: the run stopped (until) at 3 s",
         ('trace.jsonl:7: {"t":3000,"ev":"stop","reason":"until"}',)),
        (11, "the run stopped otherwise", ('trace.jsonl:7: {"t":3000,"ev":"stop","reason":"until"}',)),
        (12, "entered 1 time(s) in that window, not 2",
         ('trace.jsonl:5: {"t":1500,"ev":"enter","state":"B"}',)),
    ]


def test_an_exact_trace_ignores_the_components_name_only(tmp_path: Path) -> None:
    (tmp_path / "same.jsonl").write_text(TRACE.replace('"name":"m"', '"name":"m_cpp"'))
    (tmp_path / "other.jsonl").write_text(TRACE.replace('"t":1500,"ev":"log"', '"t":1550,"ev":"log"'))
    assert _check(tmp_path, "  - trace: same.jsonl\n") == []
    assert _check(tmp_path, "  - trace: other.jsonl\n") == [
        (4, f"first difference at {tmp_path}/other.jsonl:6",
         ('expected: {"t":1550,"ev":"log","state":"B","msg":"in B at 1.5 s"}',
          'trace.jsonl:6: {"t":1500,"ev":"log","state":"B","msg":"in B at 1.5 s"}'))]


def test_deeply_nested_json_in_a_trace_fails_the_scenario_not_the_run(tmp_path: Path) -> None:
    """Nesting past what Python's json reads (RecursionError), in the expected trace or in
    the run's: the expectation fails, the run's trace ends there; nothing crashes."""
    deep = "[" * 100_000 + "]" * 100_000
    lines = TRACE.splitlines()
    (tmp_path / "deep.jsonl").write_text("\n".join([*lines[:5], deep, *lines[6:]]) + "\n")
    [(line, message, _)] = _check(tmp_path, "  - trace: deep.jsonl\n")
    assert (line, message) == (4, f"first difference at {tmp_path}/deep.jsonl:6")
    assert len(read_records("\n".join([*lines[:3], '{"t":5,"x":' + deep + "}", *lines[3:]]))) == 3


def test_a_run_without_stop_or_with_an_error_fails_by_itself(tmp_path: Path) -> None:
    path = write(tmp_path, f"model: {FOLLOW}\nuntil: 3s\n")
    sc = load_scenario(str(path))
    cut = [*TRACE.splitlines()[:5], '{"t":1500,"ev":"error","state":"B","snippet":"entry"}']
    fails = check(sc, Run(read_records("\n".join(cut)), [], "trace.jsonl", -9))
    assert [f.message for f in fails] == [
        "the run has no `stop` record: the component ended abnormally (exit status -9)",
        "an error in a snippet (an `error` expectation allows it)"]


# -- runs ---------------------------------------------------------------------------------------

MUST_FAIL = """\
name: must fail
model: {model}
until: 30s
inputs:
  drone:
    - {{at: 0s, connected: true, altitude: 0, position: [0, 0, 0], velocity: [0, 0, 0], yaw: 0.0}}
    - {{at: 1s, ready: true}}
    - {{from: 1.5s, to: 5.5s, altitude: {{ramp: [0, 4]}}}}
    - {{from: 20s, to: 25s, connected: false}}
expect:
  - entered: LinkLost
    before: 21s
  - not_entered: LinkLost
  - command: drone.land
  - stop: final
"""


def _failures_of(out: str, path: Path, language: str) -> None:
    """The report of MUST_FAIL: each expectation at its line, the record that broke it."""
    assert f"{path}::{language} FAILED\n" in out
    body = out.split("FAILURES", 1)[1]
    assert f"{path}:11:5: expected `LinkLost` entered by 21 s\n" \
           "  got: entered only outside the window\n" \
           "    trace.jsonl:" in body
    assert re.search(r'trace\.jsonl:\d+: \{"t":22000,"ev":"enter","state":"LinkLost"\}', body)
    assert f"{path}:13:5: expected `LinkLost` never entered\n  got: entered\n" in body
    assert f"{path}:14:5: expected command drone.land\n" \
           "  got: no such record: the run stopped (until) at 30 s\n" in body
    assert f"{path}:15:5: expected the run stops (final)\n  got: the run stopped otherwise\n" in body
    assert re.search(r"=+ 1 failed in [0-9.]+s =+\n(\(--keep DIR keeps each run's [^\n]*\)\n)?$", out)


def _junit(path: Path) -> list[tuple[str, str, str | None]]:
    """(classname, name, failure message) of each test case, parsed back."""
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    suite = root.find("testsuite")
    assert suite is not None
    cases = suite.findall("testcase")
    assert suite.get("tests") == str(len(cases))
    assert suite.get("failures") == str(sum(c.find("failure") is not None for c in cases))
    out = []
    for c in cases:
        f = c.find("failure")
        out.append((c.get("classname", ""), c.get("name", ""), None if f is None else f.get("message")))
    return out


def test_the_examples_pass_in_python_and_a_wrong_scenario_fails(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    report = tmp_path / "junit.xml"
    runs = tmp_path / "examples"
    # The examples' folder: its scenarios are found as pytest finds tests (its tests folders).
    r = hfsmc_test("-t", "python", "--junit", str(report), "--keep", str(runs),
                   str(ROOT / "examples"), cache=cache)
    assert r.returncode == 0, r.stdout + r.stderr
    for sc in EXAMPLES:
        assert f"{sc}::python PASSED\n" in r.stdout
    assert re.search(rf"=+ {len(EXAMPLES)} passed in [0-9.]+s =+\n$", r.stdout)
    cases = _junit(report)
    assert ("examples.follow_colors.tests.link_loss", "link lost mid-mission[python]", None) in cases
    assert ("examples.monitor_area.tests.altitude_watch", "altitude watch[python]", None) in cases
    assert len(cases) == len(EXAMPLES)

    bad = write(tmp_path, MUST_FAIL.format(model=FOLLOW))
    r = hfsmc_test("--junit", str(report), "--keep", str(tmp_path / "runs"), str(bad), cache=cache)
    assert r.returncode == 1, r.stdout + r.stderr
    _failures_of(r.stdout, bad, "python")
    [(_, name, message)] = _junit(report)
    assert name == "must fail[python]"
    assert message == "expected `LinkLost` entered by 21 s: entered only outside the window"
    kept = next((tmp_path / "runs").iterdir())
    assert {"inputs.jsonl", "trace.jsonl", "commands.jsonl", "stderr.txt"} <= {p.name for p in kept.iterdir()}
    first = json.loads((kept / "inputs.jsonl").read_text().splitlines()[0])
    assert first == {"t": 0, "kind": "snapshot", "interface": "drone",
                     "values": {"heartbeat_age": 0.0, "vehicle": True, "altitude": 0.0,
                                "position": [0.0, 0.0, 0.0], "velocity": [0.0, 0.0, 0.0], "yaw": 0.0}}


    # A recording is a scenario: the altitude watch's run, recorded from its playback folder,
    # passes when its replay is identical; a file that is no recording is an error (exit 2).
    kept = next(p for p in runs.iterdir() if "altitude_watch" in p.name)
    component = next((cache / "hfsmc/run").glob("monitor_area-*")) / "monitor_area.py"
    recording = tmp_path / "altitude.mcap"
    subprocess.run([sys.executable, str(component), "--playback", str(kept), "--clock", "virtual",
                    "--until", "35s", "--record", str(recording)], cwd=kept, capture_output=True,
                   timeout=120, check=True)
    # No model beside it: the code it carries runs only when asked (tests/test_replay_trust.py
    # replays recordings against the model beside them).
    flight = ROOT / "examples/follow_colors/flight.mcap"  # a simulated flight, recorded
    r = hfsmc_test(str(recording), cache=cache)
    assert r.returncode == 2 and r.stdout.startswith(f"{recording}::python ERROR\n"), r.stdout
    r = hfsmc_test("--allow-recorded-code", str(recording), str(flight), cache=cache)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.startswith(f"{recording}::python PASSED\n{flight}::python PASSED\n")
    # A file that is no recording errs alone: the scenario beside it runs.
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"no recording")
    r = hfsmc_test(str(garbage), str(EXAMPLES[0]), "-t", "python", cache=cache)
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stdout.startswith(f"{EXAMPLES[0]}::python PASSED\n{garbage}::python ERROR\n")
    assert (f"{garbage}: cannot be replayed: not an MCAP file (a recording is written by a "
            "component's --record FILE)") in r.stdout


@pytest.mark.timeout(1800)
def test_the_examples_pass_in_cpp_and_a_wrong_scenario_fails(tmp_path: Path) -> None:
    """One build per C++ model (follow_colors_cpp, monitor_area_cpp), shared by every run."""
    from tests.cppbuild import CppBuildError, need_toolchain

    try:
        need_toolchain()
    except CppBuildError as e:
        pytest.fail(str(e))
    cache = tmp_path / "cache"
    report = tmp_path / "junit.xml"
    r = hfsmc_test("-t", "cpp", "--junit", str(report), *map(str, CPP_EXAMPLES), cache=cache,
                   timeout=1700)
    assert r.returncode == 0, r.stdout + r.stderr
    for sc in CPP_EXAMPLES:
        assert f"{sc}::cpp PASSED\n" in r.stdout
    assert [c[2] for c in _junit(report)] == [None] * len(CPP_EXAMPLES)

    cpp_model = ROOT / "examples/follow_colors_cpp/follow_colors_cpp.yaml"
    bad = write(tmp_path, MUST_FAIL.format(model=cpp_model))
    r = hfsmc_test(str(bad), cache=cache, timeout=600)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "built follow_colors_cpp" not in r.stderr  # the build above is reused
    _failures_of(r.stdout, bad, "cpp")
