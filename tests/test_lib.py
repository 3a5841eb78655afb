"""examples/lib's reusable behaviours (take-off, hold, land) used by one small mission and
flown against the fake vehicle of test_drivers (MAVLink over UDP on 127.0.0.1, real clock,
a few seconds each): every outcome of the take-off, the hold's duration, the landing's end.
The whole missions fly them in the simulator (tests/test_missions.py); here each final
state is reached on purpose, and the C++ twins are checked alone."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT
from tests.support import free_port
from tests.test_drivers import GUIDED, MAV, FakeVehicle

LIB = ROOT / "examples/lib"

pytestmark = pytest.mark.timeout(120)

MISSION = """\
hfsm: 1
name: lib_mission
language: python
interfaces:
  drone: {{type: mavlink, url: "udpin:127.0.0.1:{port}"}}
period: 50ms
initial: TakeOff
states:
  TakeOff:
    use: {lib}/takeoff.yaml
    with: {{altitude: 2.0, ready_timeout: 3, climb_timeout: 1.5}}
    transitions:
      - {{to: Pause, when: active("TakeOff/Airborne")}}
      - {{to: Land, when: active("TakeOff/TimedOut")}}
      - {{to: Done, when: active("TakeOff/NotReady")}}
  Pause:
    use: {lib}/hold.yaml
    with: {{duration: 0.5}}
    transitions: [{{to: Land, when: done()}}]
  Land:
    use: {lib}/land.yaml
    transitions: [{{to: Done, when: done()}}]
  Done: {{final: true}}
"""


def fly(tmp_path: Path, fake_args: dict[str, object],
        answers: dict[int, int | None] | None = None) -> tuple[list[dict[str, object]],
                                                                FakeVehicle]:
    """Build the mission, fly it against a fake vehicle: its trace and the vehicle."""
    port = free_port(socket.SOCK_DGRAM)
    model = tmp_path / "lib_mission.yaml"
    model.write_text(MISSION.format(port=port, lib=LIB))
    out = tmp_path / "component"
    r = subprocess.run([sys.executable, "-m", "hfsmc", "build", str(model), "-o", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    fake = FakeVehicle(port, **fake_args)  # type: ignore[arg-type]
    fake.answers.update(answers or {})
    try:
        run = subprocess.run([sys.executable, str(out / "lib_mission.py"), "--until", "20s",
                              "--trace", "-"], capture_output=True, text=True, timeout=60,
                             stdin=subprocess.DEVNULL)
    finally:
        fake.close()
    assert run.returncode == 0, run.stderr
    records = [json.loads(line) for line in run.stdout.splitlines()]
    assert records[-1]["ev"] == "stop" and records[-1]["reason"] == "final", records[-3:]
    return records, fake


def entered(records: list[dict[str, object]]) -> list[object]:
    return [r["state"] for r in records if r["ev"] == "enter"]


def commands(fake: FakeVehicle) -> list[int]:
    return [m.command for m in fake.commands() if m.command != MAV.MAV_CMD_SET_MESSAGE_INTERVAL]


def test_take_off_hold_and_land(tmp_path: Path) -> None:
    records, fake = fly(tmp_path, {"ready_after": 0.3, "ekf_flags": MAV.EKF_ATTITUDE})
    assert entered(records) == [
        "TakeOff", "TakeOff/WaitReady", "TakeOff/Climb", "TakeOff/Airborne",
        "Pause", "Pause/Holding", "Pause/Held", "Land", "Land/Landing", "Land/Landed", "Done"]
    assert commands(fake) == [MAV.MAV_CMD_DO_SET_MODE, MAV.MAV_CMD_COMPONENT_ARM_DISARM,
                              MAV.MAV_CMD_NAV_TAKEOFF, MAV.MAV_CMD_NAV_LAND]
    takeoff = fake.commands(MAV.MAV_CMD_NAV_TAKEOFF)[0]
    assert fake.commands(MAV.MAV_CMD_DO_SET_MODE)[0].param2 == GUIDED and takeoff.param7 == 2.0
    # The hold: a zero velocity target, then final once `duration` has passed.
    targets = fake.messages("SET_POSITION_TARGET_LOCAL_NED")
    assert targets and (targets[0].vx, targets[0].vy, targets[0].vz) == (0.0, 0.0, 0.0)
    at = {r["state"]: int(str(r["t"])) for r in records if r["ev"] == "enter"}
    assert at["Pause/Held"] - at["Pause/Holding"] >= 500
    assert not fake.armed and fake.alt == 0.0  # Landed: disarmed on the ground
    assert not [r for r in records if r["ev"] == "log"]


def test_never_ready_arms_nothing(tmp_path: Path) -> None:
    records, fake = fly(tmp_path, {"ekf_flags": MAV.EKF_ATTITUDE})  # no position: never ready
    assert entered(records) == ["TakeOff", "TakeOff/WaitReady", "TakeOff/NotReady", "Done"]
    assert commands(fake) == []
    at = {r["state"]: int(str(r["t"])) for r in records if r["ev"] == "enter"}
    assert at["TakeOff/NotReady"] >= 3000
    assert [(r["state"], r["msg"]) for r in records if r["ev"] == "log"] == [
        ("TakeOff/WaitReady", "the vehicle never became ready")]


def test_climb_timeout_lands(tmp_path: Path) -> None:
    """The vehicle refuses to take off: armed on the ground, the mission lands and disarms."""
    records, fake = fly(tmp_path, {}, {MAV.MAV_CMD_NAV_TAKEOFF: MAV.MAV_RESULT_DENIED})
    assert entered(records) == ["TakeOff", "TakeOff/WaitReady", "TakeOff/Climb",
                                "TakeOff/TimedOut", "Land", "Land/Landing", "Land/Landed", "Done"]
    at = {r["state"]: int(str(r["t"])) for r in records if r["ev"] == "enter"}
    assert at["TakeOff/TimedOut"] - at["TakeOff/Climb"] >= 1500
    assert [(r["state"], r["msg"]) for r in records if r["ev"] == "log"] == [
        ("TakeOff/Climb", "take-off timed out (set_mode: accepted, arm: accepted, takeoff: denied)")]
    assert commands(fake)[-1] == MAV.MAV_CMD_NAV_LAND and not fake.armed


def test_each_behaviour_checks_alone() -> None:
    """Each file alone, as `make examples` checks them: the Python ones, and hold_cpp (the
    C++ take-off and landing are checked, and flown, as follow_colors_cpp uses them)."""
    files = sorted(LIB.glob("*.yaml"))
    assert [f.name for f in files] == ["hold.yaml", "hold_cpp.yaml", "land.yaml", "land_cpp.yaml",
                                       "takeoff.yaml", "takeoff_cpp.yaml"]
    files = [f for f in files if f.name in ("hold.yaml", "land.yaml", "takeoff.yaml",
                                            "hold_cpp.yaml")]
    r = subprocess.run([sys.executable, "-m", "hfsmc", "check", "--strict", *map(str, files)],
                       capture_output=True, text=True, timeout=300)
    assert (r.returncode, r.stdout, r.stderr) == (0, "", "")
