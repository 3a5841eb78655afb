"""Issue 29 items 4 and 5 on `hfsmc sim --autopilot px4`: monitor_area flies unchanged (with
examples/lib's take-off and landing), and the stop paths not covered by tests/test_px4.py (a
snippet error, a lost link at the landing) end landed and disarmed, in lockstep
(docs/worlds.md#simulated-time), as on ArduPilot (tests/test_missions.py,
tests/test_monitor_area.py)."""

from __future__ import annotations

import json
import math
import shutil
import signal
from pathlib import Path

import pytest

from tests import test_missions, test_monitor_area
from tests.conftest import ROOT
from tests.support import FOLLOW, fired_into, flight
from tests.test_missions import LANGUAGES
from tests.test_monitor_area import MODEL, MONITOR, STAGES

PX4 = ("--autopilot", "px4", "--source-port", "0")
cpp_follow_colors = test_missions.cpp_follow_colors  # the fixtures: the C++ twins compiled
cpp_monitor_area = test_monitor_area.cpp_monitor_area


@pytest.fixture
def px4_monitor(request: pytest.FixtureRequest) -> list[str] | None:
    """monitor_area to fly on PX4, by language (None: flight() builds the Python one)."""
    if request.param == "python":
        return None
    command: list[str] = request.getfixturevalue("cpp_monitor_area")
    return command


@pytest.fixture
def px4_follow(request: pytest.FixtureRequest) -> list[str] | None:
    """follow_colors to fly on PX4, by language (None: flight() builds the Python one)."""
    if request.param == "python":
        return None
    command: list[str] = request.getfixturevalue("cpp_follow_colors")
    return command


@pytest.mark.slow
@pytest.mark.parametrize("px4_monitor", LANGUAGES, indirect=True)
def test_monitor_area_finds_the_victims_and_lands_home_on_px4(
        tmp_path: Path, px4_monitor: list[str] | None) -> None:
    """The ArduPilot mission, not a line changed, on PX4: its take-off and landing are
    examples/lib's (takeoff.yaml: NAV_TAKEOFF, AUTO.TAKEOFF then Hold; land.yaml: NAV_LAND,
    AUTO.LAND, PX4's own disarm), its stages fly by velocity targets (OFFBOARD, the driver's
    stream), its altitude region corrects as on ArduPilot."""
    truth_log = tmp_path / "truth.jsonl"
    with flight(tmp_path, *PX4, "--truth-log", str(truth_log), model=MODEL,
                world=MONITOR / "world.yaml", command=px4_monitor,
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

    # At least 4 of the 5 victims, each recorded once, within 1.5 m of the truth.
    victims = truth["victims"]
    assert isinstance(victims, list) and len(victims) == 5
    found = [(v["north"], v["east"]) for v in report["victims"]]
    for v in victims:
        assert sum(math.dist((v["north"], v["east"]), p) <= 2.0 for p in found) <= 1, found
    near = [v for v in victims
            if any(math.dist((v["north"], v["east"]), p) <= 1.5 for p in found)]
    assert len(near) >= 4, (found, victims)

    # Landed and disarmed (PX4's COM_DISARM_LAND) at the take-off point.
    assert truth["armed"] is False and truth["landed"] is True
    landing, takeoff = truth["landing"], truth["takeoff"]
    assert isinstance(landing, dict) and isinstance(takeoff, dict)
    assert math.dist((landing["north"], landing["east"]),
                     (takeoff["north"], takeoff["east"])) < 2.0
    assert math.dist((report["landing"]["north"], report["landing"]["east"]),
                     (landing["north"], landing["east"])) < 0.5

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
