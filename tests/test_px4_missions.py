"""Issue 29 items 4 and 5 on `hfsmc sim --autopilot px4`: monitor_area flies unchanged (with
examples/lib's take-off and landing), and the stop paths not covered by tests/test_px4.py (a
snippet error, a lost link at the landing) end landed and disarmed, in lockstep
(docs/worlds.md#simulated-time), as on ArduPilot (tests/test_missions.py,
tests/test_monitor_area.py)."""

from __future__ import annotations

import json
import math
import re
import shutil
import signal
from pathlib import Path

import pytest

from tests import test_missions, test_monitor_area
from tests.conftest import ROOT
from tests.support import FOLLOW, fired_into, flight, wait_for_line
from tests.test_missions import LANGUAGES
from tests.test_monitor_area import MODEL, MONITOR, STAGES

PX4 = ("--autopilot", "px4", "--source-port", "0")
cpp_follow_colors = test_missions.cpp_follow_colors  # the fixtures: the C++ twins compiled
cpp_monitor_area = test_monitor_area.cpp_monitor_area


# The components to fly, by language (None: flight() builds the Python one).
mission = test_missions.mission
monitor = test_monitor_area.monitor


@pytest.mark.slow
@pytest.mark.parametrize("monitor", LANGUAGES, indirect=True)
def test_monitor_area_finds_the_victims_and_lands_home_on_px4(
        tmp_path: Path, monitor: list[str] | None) -> None:
    """The ArduPilot mission, not a line changed, on PX4: its take-off and landing are
    examples/lib's (takeoff.yaml: NAV_TAKEOFF, AUTO.TAKEOFF then Hold; land.yaml: NAV_LAND,
    AUTO.LAND, PX4's own disarm), its stages fly by velocity targets (OFFBOARD, the driver's
    stream), its altitude region corrects as on ArduPilot."""
    truth_log = tmp_path / "truth.jsonl"
    with flight(tmp_path, *PX4, "--truth-log", str(truth_log), model=MODEL,
                world=MONITOR / "world.yaml", command=monitor,
                component_args=test_monitor_area.CORRECTING_BAND, lockstep=True) as f:
        status = f.component.wait(timeout=900)  # PX4's 366 messages/s, on a shared machine
        f.sim.wait(timeout=30)  # the truth written at its exit, after the disarm
        truth = f.truth()
        log = (f.folder / "component.log").read_text()
        assert status == 0, log[-3000:]
        assert f.sim.returncode == 0, (f.folder / "sim.log").read_text()[-3000:]
        trace = f.trace
    assert trace[-1] == {"t": trace[-1]["t"], "ev": "stop", "reason": "final"}
    stages = [t.removeprefix(STAGES) for t in fired_into(trace)
              if t.startswith(STAGES) and t.count("/") == STAGES.count("/")]
    assert stages == ["MonitorArea", "BackToRoad", "TurnRound", "FollowRoadBack", "GoHome",
                      "OverHome"], stages
    # examples/lib's take-off and landing on PX4: paths continue into them.
    assert [t for t in fired_into(trace) if not t.startswith("Flight/")] == [
        "TakeOff/Climb", "TakeOff/Airborne", "Flight", "Land", "Land/Landed", "Done"]
    report = json.loads((f.folder / "report.json").read_text())
    assert report["stages"] == ["takeoff", "road", "accident", "back at the road",
                                "road back", "home", "landing", "landed"]
    assert "drone: PX4 vehicle 1/1" in log and "drone: land accepted" in log
    assert "drone: set_mode GUIDED (OFFBOARD) accepted" in log

    # The victims, and landed and disarmed (PX4's COM_DISARM_LAND) at the take-off point.
    test_monitor_area.found_the_victims_and_landed_home(report, truth)

    # The altitude kept within its band between take-off and landing.
    altitude = test_monitor_area.flight_altitude()
    altitudes = test_monitor_area.flying_altitudes(trace, truth_log)
    assert len(altitudes) > 100, len(altitudes)
    worst = max(abs(a - altitude) for a in altitudes)
    assert worst <= test_monitor_area.BAND, (worst, altitudes)
    corrections = fired_into(trace).count("Flight/Altitude/Correcting")
    assert report["altitude_corrections"] == corrections
    assert test_monitor_area.held_while_correcting(trace) == corrections
    print(f"monitor_area on PX4: {report['time_s']} s "
          f"({test_missions.mission_seconds(trace)} s from take-off), "
          f"altitude within {worst:.2f} m of {altitude} m, {corrections} corrections")


def raising_follow_colors(tmp_path: Path) -> Path:
    """follow_colors with one line more: the first stage's entry raises once the vehicle is
    airborne and flying to green (examples/lib copied beside it, as its `use:` wants)."""
    shutil.copytree(ROOT / "examples" / "lib", tmp_path / "lib")
    (tmp_path / "app").mkdir()
    model = tmp_path / "app" / "follow_colors.yaml"
    text = (FOLLOW / "follow_colors.yaml").read_text()
    entry = 'entry: reached(1, "green")'
    assert text.count(entry) == 1
    model.write_text(text.replace(entry, entry + '; raise RuntimeError("boom in flight")'))
    return model


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_snippet_error_in_flight_lands_and_disarms(tmp_path: Path, autopilot: str) -> None:
    """A snippet raises in the air: the error is said at its line, the stop (reason `error`)
    goes through on_interrupt to examples/lib's Land, and the vehicle ends landed and
    disarmed, exit status 1, on both autopilots."""
    args = PX4 if autopilot == "px4" else ()
    with flight(tmp_path, *args, model=raising_follow_colors(tmp_path), lockstep=True) as f:
        status = f.component.wait(timeout=600)
        f.sim.wait(timeout=30)  # it stops with its component, the truth written
        truth = f.truth()
        log = (f.folder / "component.log").read_text()
        assert status == 1, log[-3000:]
    errors = [r for r in f.trace if r["ev"] == "error"]
    assert [(r["state"], r["snippet"]) for r in errors] == [("Mission/FollowGreen", "entry")]
    assert [(r["reason"], r["to"]) for r in f.trace if r["ev"] == "interrupt"] == [
        ("error", "Land")]
    assert [r["state"] for r in f.trace if r["ev"] == "enter"][-4:] == [
        "Land", "Land/Landing", "Land/Landed", "Done"]
    assert f.trace[-1]["ev"] == "stop" and f.trace[-1]["reason"] == "error"
    assert "follow_colors.yaml:115:37: error: RuntimeError: boom in flight" in log
    assert truth["armed"] is False and truth["landed"] is True, truth
    assert "WARNING: ARMED" not in log and "drone: land accepted" in log
    assert 'File "' not in log  # the model's lines, not Python's


@pytest.mark.parametrize("mission", LANGUAGES, indirect=True)
def test_a_link_lost_at_the_landing_lands_once_it_is_back_on_px4(
        tmp_path: Path, mission: list[str] | None) -> None:
    """tests/test_missions.py's lost link on PX4: the link drops in the mission (SIGUSR1 to
    the simulator: both ways), so the driver's setpoints stop reaching PX4 (its failsafe:
    OFFBOARD left for POSCTL); Ctrl+C sends the component to Land, whose land command goes
    nowhere; examples/lib/land sends it again, saying why, until the link is back: PX4
    lands in AUTO.LAND and disarms, nothing is left armed. In lockstep at 5 times real
    time."""
    with flight(tmp_path, *PX4, "--speedup", "5", command=mission, lockstep=True) as f:
        f.wait_for("enter", "state", "Mission/FollowGreen/Track", timeout=120)
        wait_for_line(f.folder / "component.log", r"set_mode GUIDED \(OFFBOARD\) accepted",
                      f.component, timeout=60)  # flying on the driver's stream
        f.sim.send_signal(signal.SIGUSR1)  # the link drops
        f.wait_for("enter", "state", "LinkLost", timeout=30)
        f.component.send_signal(signal.SIGINT)  # on_interrupt: Land, into the void
        again = f.wait_for("log", "state", "Land/Landing", timeout=30)
        f.sim.send_signal(signal.SIGUSR1)  # the link comes back
        status = f.component.wait(timeout=300)
        f.sim.wait(timeout=30)  # it stops with its component, the truth written
        truth = f.truth()
        log = (f.folder / "component.log").read_text()
        sim_log = (f.folder / "sim.log").read_text()
        assert status == 130, log[-3000:]
    # The mode the driver saw last: OFFBOARD's heartbeat may or may not have come before the
    # drop (the signal comes in real time).
    assert re.fullmatch(r"still armed in (TAKEOFF|GUIDED) \(land: timeout, link lost\): "
                        r"sending land again", str(again["msg"])), again
    # PX4's own failsafe while the link was down (no setpoint reached it), then its landing.
    assert re.search(r"failsafe: no setpoint for 1\.\d s\n.*mode POSCTL\n", sim_log), sim_log
    assert re.search(r"link restored \(SIGUSR1\)\n(.*\n)*.*mode AUTO\.LAND\n(.*\n)*.*"
                     r"disarmed \(landed\)", sim_log), sim_log
    enters = [r["state"] for r in f.trace if r["ev"] == "enter"]
    assert enters[-3:] == ["Land/Landing", "Land/Landed", "Done"], enters
    assert enters.count("Land/Landing") >= 2  # sent again at least once
    assert "drone: land: no acknowledgement in 3 s" in log and "land accepted" in log
    assert truth["armed"] is False and truth["landed"] is True, truth
    assert "WARNING: ARMED" not in log


@pytest.mark.slow
@pytest.mark.parametrize(("autopilot", "language"), [
    ("ardupilot", "python"), ("px4", "python"),
    pytest.param("px4", "cpp", marks=pytest.mark.timeout(test_missions.CPP_BUILD_TIMEOUT + 300))])
def test_a_link_that_never_comes_back_is_said_loudly_at_the_stop(
        tmp_path: Path, autopilot: str, language: str, request: pytest.FixtureRequest) -> None:
    """The link drops for good in the mission (in simulated time: `--drop-link-after`), then
    --time-limit sends the component to Land: its land commands go nowhere, over and over,
    until follow_colors' interrupt_timeout (60 s) stops it (reason `timeout`, status 1).
    The component cannot know how the vehicle ends: it says so at the stop (`WARNING: ARMED
    ... link lost`). What the vehicle does is its autopilot's: PX4's OFFBOARD-loss failsafe
    (POSCTL with no RC) sinks it to the ground, where its land detector disarms it;
    ArduPilot (no GCS failsafe set) holds in GUIDED, armed."""
    args = PX4 if autopilot == "px4" else ()
    command = request.getfixturevalue("cpp_follow_colors") if language == "cpp" else None
    with flight(tmp_path, *args, "--drop-link-after", "16", "--drop-link-for", "1000",
                command=command, lockstep=True, component_args=("--time-limit", "20s")) as f:
        status = f.component.wait(timeout=600)
        f.sim.wait(timeout=30)
        truth = f.truth()
        log = (f.folder / "component.log").read_text()
        sim_log = (f.folder / "sim.log").read_text()
        assert status == 1, log[-3000:]
    enters = [r["state"] for r in f.trace if r["ev"] == "enter"]
    assert enters.index("Mission/FollowGreen/Track") < enters.index("LinkLost"), enters
    assert [(r["reason"], r["to"]) for r in f.trace if r["ev"] == "interrupt"] == [
        ("time_limit", "Land")]
    assert f.trace[-1]["ev"] == "stop" and f.trace[-1]["reason"] == "timeout"
    resent = [str(r["msg"]) for r in f.trace if r["ev"] == "log" and r["state"] == "Land/Landing"]
    assert len(resent) >= 10 and all("link lost): sending land again" in m for m in resent)
    warning = re.search(r"drone: WARNING: ARMED in (\w+) at [\d.]+ m \(link lost \d+ s ago\) "
                        r"as the component stops: nothing lands the vehicle now", log)
    assert warning is not None, log[-3000:]
    if autopilot == "px4":
        assert truth["armed"] is False and truth["landed"] is True, truth
        assert re.search(r"link dropped \(--drop-link-after\)\n.*failsafe: no setpoint for "
                         r"1\.\d s\n.*mode POSCTL\n.*landed at .*\n.*land detector: landed\n"
                         r".*disarmed \(landed\)\n", sim_log), sim_log
    else:
        assert truth["armed"] is True and truth["landed"] is False, truth
        assert truth["mode"] == "GUIDED", truth


LIB_MISSION = """\
hfsm: 1
name: lib_mission
language: python
interfaces:
  drone: {{type: mavlink}}
parameters:
  report: {{type: str, default: ""}}
period: 50ms
initial: TakeOff
states:
  TakeOff:
    use: {lib}/takeoff.yaml
    with: {{altitude: 3.0, ready_timeout: 30, climb_timeout: 30}}
    transitions:
      - {{to: Pause, when: active("TakeOff/Airborne")}}
      - {{to: Land, when: active("TakeOff/TimedOut")}}
      - {{to: Done, when: active("TakeOff/NotReady")}}
  Pause:
    use: {lib}/hold.yaml
    with: {{duration: 5.0}}
    transitions: [{{to: Land, when: done()}}]
  Land:
    use: {lib}/land.yaml
    transitions: [{{to: Done, when: done()}}]
  Done: {{final: true}}
"""


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_lib_behaviours_fly_on_both_autopilots(tmp_path: Path, autopilot: str) -> None:
    """examples/lib's take-off, hold and land, used by one small mission (tests/test_lib.py's,
    there against a fake vehicle), flown in the simulator on each autopilot in lockstep:
    up to 3 m, 5 s held in place, landed and disarmed where it held."""
    model = tmp_path / "lib_mission.yaml"
    model.write_text(LIB_MISSION.format(lib=ROOT / "examples" / "lib"))
    truth_log = tmp_path / "truth.jsonl"
    args = PX4 if autopilot == "px4" else ()
    with flight(tmp_path, *args, "--truth-log", str(truth_log), model=model,
                lockstep=True) as f:
        status = f.component.wait(timeout=300)
        f.sim.wait(timeout=30)
        truth = f.truth()
        log = (f.folder / "component.log").read_text()
        assert status == 0, log[-3000:]
    assert [r["state"] for r in f.trace if r["ev"] == "enter"] == [
        "TakeOff", "TakeOff/WaitReady", "TakeOff/Climb", "TakeOff/Airborne",
        "Pause", "Pause/Holding", "Pause/Held", "Land", "Land/Landing", "Land/Landed", "Done"]
    assert f.trace[-1]["ev"] == "stop" and f.trace[-1]["reason"] == "final"
    assert not [r for r in f.trace if r["ev"] == "log"]  # no command sent again, no timeout
    at = {r["state"]: int(str(r["t"])) / 1000 for r in f.trace if r["ev"] == "enter"}
    lines = [json.loads(line) for line in truth_log.read_text().splitlines()]
    held = [x for x in lines if at["Pause/Holding"] + 1.0 <= x["time"] <= at["Pause/Held"]]
    assert len(held) >= 8, len(held)
    start = held[0]["position"]
    for x in held:  # held in place: within 0.3 m of where it was a second into the hold
        assert math.dist((x["position"]["north"], x["position"]["east"]),
                         (start["north"], start["east"])) < 0.3, x
        assert abs(x["altitude"] - 3.0) < 0.4, x
    assert truth["armed"] is False and truth["landed"] is True, truth
    landing = truth["landing"]
    assert isinstance(landing, dict)
    assert math.dist((landing["north"], landing["east"]), (start["north"], start["east"])) < 0.5
    assert "drone: takeoff accepted" in log and "drone: land accepted" in log
    assert "WARNING: ARMED" not in log


@pytest.mark.parametrize(("drop_at", "language"), [
    ("13.8", "python"), ("15.5", "python"),
    pytest.param("13.8", "cpp", marks=pytest.mark.timeout(test_missions.CPP_BUILD_TIMEOUT + 300))])
def test_after_a_lost_link_the_driver_never_fights_px4s_failsafe(
        tmp_path: Path, drop_at: str, language: str, request: pytest.FixtureRequest) -> None:
    """The link drops for 5 s just after PX4 accepted OFFBOARD: at 13.8 s before any
    HEARTBEAT said OFFBOARD (PX4 sends one a second), at 15.5 s after one did. Either way
    PX4's failsafe takes the vehicle to POSCTL while no setpoint reaches it, and when the
    link is back the driver sees that PX4 left OFFBOARD by itself: it stops its stream, says
    so, and never asks for OFFBOARD again unless the model does (follow_colors does not:
    the vehicle sinks in POSCTL until --time-limit lands it)."""
    command = request.getfixturevalue("cpp_follow_colors") if language == "cpp" else None
    with flight(tmp_path, *PX4, "--drop-link-after", drop_at, "--drop-link-for", "5",
                command=command, lockstep=True, component_args=("--time-limit", "30s")) as f:
        status = f.component.wait(timeout=300)
        f.sim.wait(timeout=30)
        truth = f.truth()
        log = (f.folder / "component.log").read_text()
        sim_log = (f.folder / "sim.log").read_text()
        assert status == 124, log[-3000:]
    modes = re.findall(r"\] mode (\S+)\n", sim_log)
    assert modes[:4] == ["AUTO.TAKEOFF", "OFFBOARD", "POSCTL", "AUTO.LAND"], sim_log
    # The simulated PX4 sends its HEARTBEAT 0.02 s past each second: one said OFFBOARD
    # before the drop in the second case only.
    switched = re.search(r"\[ *([\d.]+) s\] mode OFFBOARD\n", sim_log)
    assert switched is not None
    said = math.floor(float(drop_at) - 0.02) + 0.02 > float(switched[1])
    assert said == (drop_at == "15.5"), (switched[1], drop_at)
    assert "drone: PX4 left OFFBOARD for POSCTL (a failsafe or a pilot)" in log, log
    back = log.index("drone: link back")
    assert "switching to OFFBOARD" not in log[back:], log
    assert truth["armed"] is False and truth["landed"] is True, truth
