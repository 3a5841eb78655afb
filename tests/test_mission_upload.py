"""Missions and the geofence of the mavlink interface (docs/interfaces.md, "Missions"): the
Python driver uploading to `hfsmc sim` as ArduPilot and as PX4 (MISSION_ITEM_INT protocol),
flying it in AUTO, a refused upload as a result, the fence breached and acted on; and the
simulator's side of the protocol stepped by hand (retries, refusals)."""

from __future__ import annotations

import dataclasses
import math
import signal
import socket
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from hfsmc.sim import missions, px4
from hfsmc.sim.autopilot import Autopilot, parse_datagram
from hfsmc.sim.telemetry import latlon
from hfsmc.sim.vehicle import Body
from hfsmc.sim.world import World
from tests.conftest import ROOT
from tests.support import free_port, python_vehicle, simulator, until_snapshot

pytestmark = pytest.mark.timeout(300)
HOME = World().home


def _ll(north: float, east: float) -> tuple[float, float]:
    lat, lon = latlon(HOME, north, east)
    return lat / 1e7, lon / 1e7


@pytest.fixture(params=("ardupilot", "px4"))
def vehicle(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[Any, str]]:
    """The Python driver (templates/python) on a simulator in real time, flying at 5 m."""
    with python_vehicle(tmp_path, request.param, "2") as v:
        yield v, request.param


_until = until_snapshot


def _airborne(v: Any) -> None:
    assert _until(v, lambda: v.ready() and not math.isnan(v.home()[0]), 30)
    v.set_mode("GUIDED")
    v.arm()
    v.takeoff(5.0)
    assert _until(v, lambda: v.altitude() > 4.5, 40)


def test_a_mission_is_uploaded_flown_in_auto_and_lands(vehicle: tuple[Any, str],
                                                        capfd: pytest.CaptureFixture[str]
                                                        ) -> None:
    v, _ = vehicle
    assert _until(v, lambda: v.ready() and not math.isnan(v.home()[0]), 30)
    v.upload_mission([(*_ll(1.0, 1.0), 5.0)] * 1001)  # more than the vehicle holds
    assert v.last_ack("upload_mission") == "pending"
    assert _until(v, lambda: v.last_ack("upload_mission") == "failed", 10)
    assert v.mission_progress() == (0, 0)
    with pytest.raises(ValueError, match=r"latitude 95 is out of range .*point 1\)"):
        v.upload_mission([(*_ll(1.0, 1.0), 5.0), (95.0, 0.0, 5.0)])
    with pytest.raises(ValueError, match="end `home` is not hold, land or rtl"):
        v.upload_mission([], end="home")
    _airborne(v)
    points = [(*_ll(8.0, 0.0), 6.0, math.pi / 2), (*_ll(8.0, 8.0), 5.0), (*_ll(0.0, 8.0), 5.0)]
    v.upload_mission(points, end="land")
    assert _until(v, lambda: v.last_ack("upload_mission") == "accepted", 10)
    assert v.mission_progress() == (0, 3)
    v.set_mode("AUTO")
    assert _until(v, lambda: v.mode() == "AUTO", 5)
    assert _until(v, lambda: v.mission_progress()[0] >= 1, 40)
    assert v.distance_to(8.0, 0.0) < 3.0
    assert _until(v, lambda: v.mission_progress() == (3, 3), 60)
    assert _until(v, lambda: not v.armed(), 90)
    assert v.distance_to(0.0, 8.0) < 1.0 and v.altitude() < 0.5
    err = capfd.readouterr().err
    assert "drone: upload_mission NO_SPACE" in err
    assert "drone: upload_mission accepted" in err


def test_a_goto_outside_the_fence_is_ignored_or_breaches(vehicle: tuple[Any, str],
                                                         capfd: pytest.CaptureFixture[str]
                                                         ) -> None:
    v, autopilot = vehicle
    _airborne(v)
    with pytest.raises(ValueError, match="at least 3 vertices, not 2"):
        v.upload_fence([_ll(-20, -20), _ll(20, 20)])
    v.upload_fence([_ll(-20, -20), _ll(-20, 20), _ll(20, 20), _ll(20, -20)])
    assert _until(v, lambda: v.last_ack("upload_fence") == "accepted", 10)
    v.enable_fence()
    assert _until(v, lambda: v.last_ack("enable_fence") == "accepted", 5)
    v.set_mode("GUIDED")
    lat, lon = _ll(40.0, 0.0)
    v.goto_location(lat, lon, 5.0)
    if autopilot == "ardupilot":  # Copter ignores a destination outside the fence
        assert not _until(v, lambda: v.distance_to(0.0, 0.0) > 3.0, 4)
        assert not v.fence_breached()
        v.enable_fence(False)
        assert _until(v, lambda: v.last_ack("enable_fence") == "accepted", 5)
    else:  # PX4 flies it, breaches, and holds (GF_ACTION 2)
        assert _until(v, v.fence_breached, 30)
        assert _until(v, lambda: v.mode() == "HOLD", 5)
        assert 20.0 < v.position()[0] < 30.0
        v.enable_fence(False)
        assert _until(v, lambda: v.last_ack("enable_fence") == "unsupported", 5)
        assert v.armed()  # it holds outside the fence, still flying
    err = capfd.readouterr().err
    assert "is outside the fence" in err


class Bench:
    """An autopilot and its body in this process, stepped by hand; what it sends kept."""

    def __init__(self, cls: type[Autopilot]) -> None:
        world = dataclasses.replace(World(), seed=3)
        self.body = Body(world.vehicle, world.seed)
        self.sent: list[Any] = []
        self.ap = cls(world, self.body, lambda d: self.sent.extend(parse_datagram(d)),
                      boot_time=0.5)
        self.gcs = M.MAVLink(None, 255, 190)

    def send(self, name: str, *args: Any) -> None:
        msg = getattr(self.gcs, f"{name}_encode")(*args)
        self.ap.receive(msg.pack(self.gcs))

    def steps(self, seconds: float) -> None:
        end = self.body.t + seconds
        while self.body.t < end:
            self.ap.step()

    def of(self, kind: str) -> list[Any]:
        return [m for m in self.sent if m.get_type() == kind]


@pytest.mark.parametrize("cls", (Autopilot, px4.Px4))
def test_the_vehicle_asks_again_then_cancels_and_refuses_bad_items(cls: type[Autopilot]
                                                                   ) -> None:
    bench = Bench(cls)
    bench.send("mission_count", 1, 1, 2, 0)
    bench.steps(0.1)
    assert [m.seq for m in bench.of("MISSION_REQUEST_INT")] == [0]
    bench.steps(missions.REQUEST_RETRY_S * (missions.RETRIES + 1) + 0.1)
    assert [m.seq for m in bench.of("MISSION_REQUEST_INT")] == [0] * (missions.RETRIES + 1)
    assert [m.type for m in bench.of("MISSION_ACK")] == [M.MAV_MISSION_OPERATION_CANCELLED]
    bench.sent.clear()
    lat, lon = latlon(HOME, 5.0, 5.0)
    bench.send("mission_count", 1, 1, 2, 0)
    for seq, command in enumerate((M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_DO_DIGICAM_CONTROL)):
        bench.send("mission_item_int", 1, 1, seq, 6, command, 0, 1, 0, 0, 0, 0, lat, lon, 5.0,
                   0)
    assert [m.type for m in bench.of("MISSION_ACK")] == [M.MAV_MISSION_UNSUPPORTED]
    bench.sent.clear()
    bench.send("mission_count", 1, 1, 2, 0)
    for seq in (0, 1):
        bench.send("mission_item_int", 1, 1, seq, 6, 16, 0, 1, 0, 0, 0, 0, 91 * 10 ** 7, lon,
                   5.0, 0)
    want = M.MAV_MISSION_INVALID_PARAM5_X  # ArduPilot's item 0 is home: the second refused
    assert [m.type for m in bench.of("MISSION_ACK")] == [want]
    assert bench.ap.missions.plans[missions.MISSION] == []  # a refused upload stores nothing
    bench.sent.clear()
    bench.send("mission_count", 1, 1, 3, 1)  # a polygon of 3 saying it has 4 vertices
    for seq in range(3):
        bench.send("mission_item_int", 1, 1, seq, 6, 5001, 0, 1, 4, 0, 0, 0, lat + seq * 1000,
                   lon, 0.0, 1)
    assert [m.type for m in bench.of("MISSION_ACK")] == [M.MAV_MISSION_INVALID_PARAM1]


def test_px4_offboard_loss_is_a_failsafe_the_model_sees(tmp_path: Path,
                                                        capfd: pytest.CaptureFixture[str]
                                                        ) -> None:
    """The link cut (SIGUSR1 to the simulator) while PX4 flies OFFBOARD: failsafe() says
    link_lost, PX4's own failsafe takes over (POSCTL); when the link is back failsafe()
    says offboard_lost until the model asks for a mode."""
    sys.path.insert(0, str(ROOT / "templates" / "python"))
    import hfsmc_mavlink  # type: ignore[import-not-found]
    port = free_port(socket.SOCK_DGRAM)
    try:
        with simulator(tmp_path, port, "--no-camera", "--boot-time", "2", "--autopilot", "px4",
                       "--source-port", "0") as sim:
            v = hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {})
            try:
                _airborne(v)
                v.set_mode("GUIDED")
                assert _until(v, lambda: v.mode() == "GUIDED", 10)
                assert v.failsafe() == ""
                sim.send_signal(signal.SIGUSR1)  # the link down
                assert _until(v, lambda: v.failsafe() == "link_lost", 10)
                sim.send_signal(signal.SIGUSR1)  # back
                assert _until(v, lambda: v.failsafe() == "offboard_lost", 10)
                assert v.mode() == "POSCTL"  # PX4's text went out while the link was down
                v.land()
                v.snapshot()
                assert v.failsafe() == ""
                assert _until(v, lambda: v.mode() == "LAND", 10)
            finally:
                v.close()
    finally:
        sys.path.remove(str(ROOT / "templates" / "python"))
    err = capfd.readouterr().err
    assert "drone: PX4 left OFFBOARD for POSCTL" in err


def test_the_hooks_mode_numbers_are_the_autopilots() -> None:
    from hfsmc.sim import autopilot
    from hfsmc.sim import mission_hooks as hooks
    assert (hooks.PX4_HOLD, hooks.PX4_RTL, hooks.PX4_LAND) == (px4.HOLD, px4.RTL, px4.LAND)
    assert (hooks.AUTO, hooks.AP_RTL, hooks.AP_LAND, hooks.AP_BRAKE) == (
        autopilot.AUTO, autopilot.RTL, autopilot.LAND, autopilot.BRAKE)


@pytest.mark.parametrize(("cls", "params", "mode"), [
    (Autopilot, {"FENCE_ENABLE": 1}, "RTL"), (Autopilot, {"FENCE_ENABLE": 1,
                                                          "FENCE_ACTION": 2}, "LAND"),
    (px4.Px4, {}, "AUTO.LOITER"), (px4.Px4, {"GF_ACTION": 3}, "AUTO.RTL")])
def test_a_breach_does_what_the_autopilots_parameter_says(cls: type[Autopilot],
                                                          params: dict[str, float],
                                                          mode: str) -> None:
    bench = Bench(cls)
    bench.ap.set_params(params)
    bench.send("mission_count", 1, 1, 4, 1)
    for seq, (n, e) in enumerate(((-10, -10), (-10, 10), (10, 10), (10, -10))):
        lat, lon = latlon(HOME, n, e)
        bench.send("mission_item_int", 1, 1, seq, 6, 5001, 0, 1, 4, 0, 0, 0, lat, lon, 0.0, 1)
    assert [m.type for m in bench.of("MISSION_ACK")] == [M.MAV_MISSION_ACCEPTED]
    bench.steps(1.0)
    guided = px4.HOLD if cls is px4.Px4 else 4
    assert bench.ap.set_mode(guided)
    assert bench.ap._cmd_arm((1, 0, 0, 0, 0, 0, 0)) == M.MAV_RESULT_ACCEPTED
    bench.body.goto(0.0, 0.0, -5.0)
    bench.steps(8.0)
    assert not bench.ap.missions.breached and not bench.body.landed
    bench.body.goto(25.0, 0.0, -5.0)  # the body flown out (a pilot, a wind), not a target
    end = bench.body.t + 20
    while not bench.ap.missions.breached:
        assert bench.body.t < end, "never breached"
        bench.ap.step()
    assert 10.0 < bench.body.north < 11.0
    assert bench.ap.mode_name == mode
    assert [m.breach_status for m in bench.of("FENCE_STATUS")][-1] == 1


def test_a_breach_ends_when_the_fence_is_turned_off() -> None:
    """FENCE_STATUS says the breach is over when ArduPilot's fence is turned off, though
    no status comes while it is off."""
    bench = Bench(Autopilot)
    bench.ap.set_params({"FENCE_ENABLE": 1, "FENCE_ACTION": 0})
    bench.send("mission_count", 1, 1, 1, 1)
    lat, lon = latlon(HOME, 50.0, 0.0)
    bench.send("mission_item_int", 1, 1, 0, 6, 5003, 0, 1, 10.0, 0, 0, 0, lat, lon, 0.0, 1)
    bench.steps(1.0)
    assert bench.ap.set_mode(4)
    assert bench.ap._cmd_arm((1, 0, 0, 0, 0, 0, 0)) == M.MAV_RESULT_ACCEPTED
    bench.steps(0.1)  # armed at home, 40 m outside the circle: breached, reported only
    assert bench.ap.missions.breached and bench.ap.mode_name == "GUIDED"
    bench.sent.clear()
    bench.send("command_long", 1, 1, M.MAV_CMD_DO_FENCE_ENABLE, 0, 0, 0, 0, 0, 0, 0, 0)
    bench.steps(2.5)
    assert [m.breach_status for m in bench.of("FENCE_STATUS")] == [0]
